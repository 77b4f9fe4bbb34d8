"""How the products store their variables on disk: Zarr v3 codecs, skeletons, the chunk writer
and reader (``zarr_io``), and the bit rounding of their floats with its recorded bound
(``bitround``).
"""
