"""5-sigma point-source limiting magnitudes: the limit of one background (``point_source``), at
the assumption envelope's ends (``envelope``), with the depth error budget (``budget``), and
limits.zarr's dataset and per-pixel summaries from a stored background (``cube``).
"""
