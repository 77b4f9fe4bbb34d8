"""Detector images: the stray light of bright stars in and near the field painted on a CSST
detector (PSF core, BRDF scattering halo, ghosts), with an optional uniform background.

Internal: not part of the public API (``straylight.__all__``); its modules may change between
releases.  Users make images with ``straylight image``.
"""

__all__: list[str] = []
