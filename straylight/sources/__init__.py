"""The sources of background light, one module each, every one asked the same thing by the
background model (:class:`straylight.model.BackgroundModel`): its e-/s/pixel in each band for a
batch of samples (:class:`~straylight.sources.context.Samples`), and, for those skipped where
the scene's brighter light swamps them, the upper bound the skip is decided on.

- ``zodiacal``: zodiacal light in the field (Leinert 1998 table), never skipped.
- ``bodies``: the Sun (never skipped), the Moon (skipped on a PST bound), and the Sun, Moon and
  planets inside the field, which the background leaves out (imaged as point sources).
- ``planets``: the planets (skipped on a PST bound, like the Moon).
- ``body_magnitudes``: the Moon's and planets' brightness laws and the Moon's distances.
- ``stars``: off-field catalog stars, the bright ones pair by pair (skipped per sky cell on a
  bound), the faint ones as a smoothed map.
- ``earthshine``: the sunlit and moonlit Earth, a package: the Earth grid (``grid``, ``sums``,
  the compiled ``kernel``), the Earth's band albedos (``albedo``), the look-up tables (``table``,
  their base; ``sunlit_table``, ``moonlit_table``, their builds and shared ``lookup`` and
  ``nodes``), the one engine both sources wrap (``engine``) and the two sources (``sunlit``,
  ``moonlit``).
- ``offfield``: the off-field transfer every source outside the field goes through (Se Sp PST x
  pixel area).
- ``photometry``: band photometry (solar and AB irradiances, magnitudes per arcsec2).
- ``context``: the base, importing no source: the batch of samples, the ``Source`` protocol, and
  the campaign's instrument as every source sees it (the zodiacal floor passed in).

Solar-spectrum sources (the Sun, Moon, planets, both Earths) give band-independent rates, in
e-/s/pix per photon s-1 m-2 of the Sun at 1 AU (or of their lamp), that each band's solar
photon irradiance turns into e-/s/pix; the model does that product and the sum in one compiled
pass.  The error a skip or a table may add is the fidelity policy's
(:class:`straylight.model.FidelityPolicy`), handed to each source; sources never import
``straylight.model``.

Imports ``straylight.sky``, ``straylight.config``, ``straylight.optics``, ``straylight.catalog`` (star
tables) and ``straylight.util``; never ``straylight.model`` or a layer above it.
"""
