"""From the model to the survey's products: the footprint and time grid, background cubes, 5-sigma
limits, observability and scheduling tables, per-pointing tables, the plan's cost, storage codecs
and provenance.

May import everything below it (util, sky, config, optics, catalog, sources, model); nothing imports it
but the CLI, the API and its SkyModel, the plots, the paper reproductions and ``workflow/scripts/``.
"""
