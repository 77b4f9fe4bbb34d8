"""The sunlit and moonlit Earth (seed paper sect. 3.2): the Earth grid, its compiled kernel, the
look-up tables and the two sources.

- ``grid``: the Earth grid's settings and the cap grid (blocks, lighting, the door's view, the
  cap bound); ``sums``: the Earth-grid sums; ``kernel``: their compiled kernel.
- ``albedo``: the Earth's band albedos over the grey one.
- ``table``: the tables' base (:class:`~straylight.sources.earthshine.table.LampTable`) and shared
  build; ``lookup``, ``nodes``: their shared coordinates, nodes and cache keys;
  ``sunlit_table``, ``sunlit_build``, ``moonlit_table``, ``moonlit_build``: the two tables.
- ``engine``: :class:`~straylight.sources.earthshine.engine.EarthGrid` (the grid over the
  off-field transfer) and :class:`~straylight.sources.earthshine.engine.Earthshine`, the one
  engine both sources wrap.
- ``sunlit``, ``moonlit``: the sources,
  :class:`~straylight.sources.earthshine.sunlit.SunlitEarth` and
  :class:`~straylight.sources.earthshine.moonlit.MoonlitEarth`.
"""
