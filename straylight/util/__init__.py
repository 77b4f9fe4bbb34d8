"""Small utilities with no physics: grid interpolation for the hot loops (``gridinterp``), atomic
product writes, file digests and the table cache's folder (``io``), healpy without its plotting
functions (``healpix``).  The worker processes and Dask clients (execution policy) are
``straylight.execution``, a layer above.  Imports nothing of straylight but ``errors``."""
