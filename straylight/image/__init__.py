"""Detector images: the stray light of bright stars in and near the field painted on a CSST
detector (PSF core, BRDF scattering halo, ghosts), with an optional uniform background.
"""
