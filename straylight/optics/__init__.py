"""The path of light through the telescope: the point source transmission PST(theta, phi), the aperture
door and its blockage Sp, the band throughputs, BRDF scattering by the mirrors and the ghosts.

Imports ``straylight.sky`` (angles in the telescope frame) and ``straylight.util``; never a source.

Internal: not part of the public API (``straylight.__all__``); its modules may change between
releases.
"""

__all__: list[str] = []
