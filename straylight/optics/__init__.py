"""The path of light through the telescope: the point source transmission PST(theta, phi), the aperture
door and its blockage Sp, the band throughputs, BRDF scattering by the mirrors and the ghosts.

Imports ``straylight.sky`` (angles in the telescope frame) and ``straylight.util``; never a source.
"""
