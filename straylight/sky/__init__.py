"""Where things are: time scales, the DE405 ephemeris, the telescope's orbit, vector arithmetic,
the telescope frame, the Earth's limb, runs of samples that share a scene, and the observing
geometry of (time, pointing) samples with the survey constraints.

Imports nothing of straylight but ``straylight.errors``; knows nothing of light, nor of the
campaign's configuration: callers pass the orbit, the Earth's radius and the constraints.

Internal: not part of the public API (``straylight.__all__``), which re-exports what users
need of it (:class:`~straylight.DE405`, :func:`~straylight.scene`,
:func:`~straylight.sample_geometry`); its modules may change between releases.
"""

__all__: list[str] = []
