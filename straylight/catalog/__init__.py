"""Bright stars in the seven CSST bands: the Gaia DR2 ingest, the Hipparcos default, the SED
templates and the catalog build by template matching and synthetic photometry.

Imports ``straylight.optics.bandpass`` for the bands; nothing of the survey.

Internal: not part of the public API (``straylight.__all__``); its modules may change between
releases.  Users build a catalog with ``straylight catalog`` and read it as a table.
"""

__all__: list[str] = []
