"""Bright stars in the seven CSST bands: the Gaia DR2 ingest, the Hipparcos default, the SED
templates and the catalog build by template matching and synthetic photometry.

Imports ``straylight.optics.bandpass`` for the bands; nothing of the survey.
"""
