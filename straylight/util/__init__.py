"""Small utilities with no physics: grid interpolation for the hot loops (``gridinterp``), atomic
product writes, file digests and the table cache's folder (``io``), the worker processes' environment,
pools and exit, and Dask clients (``daskutil``), healpy without its plotting functions
(``healpix``).  Imports nothing of straylight but ``errors``."""
