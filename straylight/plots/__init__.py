"""Figures of a campaign's products for the report.

* :mod:`~straylight.plots.maps` - all-sky Mollweide maps of every component and the total per
  band at chosen times, and the limiting-magnitude maps;
* :mod:`~straylight.plots.series` - time series of chosen pointings over the first orbit and the
  whole campaign;
* :mod:`~straylight.plots.report` - the depth table and the report's first page;
* :mod:`~straylight.plots.overlays` - what the maps draw over the data: the ecliptic, the Galactic
  plane, the Sun;
* :mod:`~straylight.plots.common` - what they share: magnitudes, colour scales, saving.

Maps are in the cube's HEALPix frame (ICRS), RA increasing to the left; pixels outside the footprint
are light grey.  Values are shown as AB mag/arcsec2 (brighter = smaller), the unit planners compare
with sky tables; depths as AB mag.

Internal: not part of the public API (``straylight.__all__``); the workflow's report rules call
it.
"""

__all__: list[str] = []
