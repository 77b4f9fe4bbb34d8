"""The planners' tools: per-pointing tables (``pointings``), a target's visibility and many
targets' (``visibility``, ``targets``, ``target_names``, ``bright_targets``), the scheduling
tables (``scheduling``), a campaign's cost before it runs (``plan``, ``sizes``) and the
exposure-time calculator (``exposure_time``).
"""
