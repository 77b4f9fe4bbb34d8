"""Where things are: time scales, the DE405 ephemeris, the telescope's orbit, the telescope frame and
the Earth's limb, and the observing geometry of (time, pointing) samples with the survey constraints.

Imports only ``straylight.errors`` and ``straylight.config``'s types; knows nothing of light.
"""
