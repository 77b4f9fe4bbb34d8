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
- ``sunlit_earth``: the sunlit Earth (direct and via the door), its direct sum or its table.
- ``moonlit_earth``: the moonlit Earth on the table's path (skipped on a bound, else a coarse
  grid, tabulated or summed).
- ``earthshine_table``: the sunlit Earth's table, read and looked up (and the moonlit bound).
- ``moonlit_table``: the moonlit Earth's table, read and looked up.
- ``earthshine_table_lookup``: what the two tables share (coordinates, interpolation, files).
- ``earthshine_table_nodes``: the two tables' nodes and cache keys.
- ``earthshine_table_build``, ``moonlit_table_build``: each table's build, validation against
  the direct sum and cache.
- ``offfield``: what the off-field sources share: the transfer (Se Sp PST x pixel area) and the
  Earth-grid sum (the sunlit and moonlit Earth summed directly over the visible cap), which it
  inherits from ``offfield_cap`` (the Earth grid's settings, the cap grid and its bound) and
  ``offfield_earthshine`` (the sums).
- ``photometry``: band photometry (solar and AB irradiances, magnitudes per arcsec2).
- ``context``: the campaign's instrument as every source sees it, and the batch of samples.

Solar-spectrum sources (the Sun, Moon, planets, both Earths) give band-independent rates, in
e-/s/pix per photon s-1 m-2 of the Sun at 1 AU (or of their lamp), that each band's solar
photon irradiance turns into e-/s/pix; the model does that product and the sum in one compiled
pass.  The error a skip or a table may add is the fidelity policy's
(:class:`straylight.model.FidelityPolicy`), handed to each source; sources never import
``straylight.model``.

Imports ``straylight.sky``, ``straylight.config``, ``straylight.optics``, ``straylight.catalog`` (star
tables) and ``straylight.util``; never ``straylight.model`` or a layer above it.
"""
