"""The sources of background light, each giving its e-/s/pixel per band for a batch of samples:
zodiacal light, the Sun, the Moon and the planets, off-field stars, and the sunlit and moonlit Earth
(its direct sum and its tables side by side).

Imports ``straylight.sky``, ``straylight.optics`` and ``straylight.util``; never ``straylight.survey``.
"""
