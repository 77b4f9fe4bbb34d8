"""The sunlit and moonlit Earth (seed paper sect. 3.2): the Earth grid, its compiled kernel, the
look-up tables and the two sources."""
