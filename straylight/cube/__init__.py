"""The background cube and its products: the footprint and time grid, the cube's layout, one
region's values, its stores, the run of time blocks and where the regions run (executors), the
observability and geometry products, the compact sky and its reader (:class:`SkyMaps`), and the
products' provenance.

May import the layers below it (through ``limits`` and ``storage``); nothing imports it but the
planning layer, the CLI, the API and its SkyModel, the plots and ``workflow/scripts/``.
"""
