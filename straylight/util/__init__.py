"""Small utilities with no physics: grid interpolation for the hot loops (``gridinterp``), atomic
product writes, file digests and the table cache's folder (``io``), the worker processes' environment
and Dask clients (``daskutil``).  Imports nothing of straylight but ``errors``."""
