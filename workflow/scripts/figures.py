"""Snakemake adapter: rules `sky_maps` -> results/<name>/sky/*.png and `time_series` ->
results/<name>/series/*.png (the background cube's figures, one process each)."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821 - injected by Snakemake
from _common import campaign, end_job, setup_logging  # noqa: E402

from straylight.plots.maps import sky_map_figures  # noqa: E402
from straylight.plots.series import time_series_figures  # noqa: E402

log = setup_logging(snakemake)  # noqa: F821
if snakemake.rule == "time_series":  # noqa: F821 - the first orbit through the model, with the stars
    paths = time_series_figures(
        snakemake.params.store,  # noqa: F821
        campaign(snakemake),  # noqa: F821
        snakemake.output[0],  # noqa: F821
        stars_path=snakemake.input.stars,  # noqa: F821
    )
else:
    paths = sky_map_figures(snakemake.params.store, campaign(snakemake), snakemake.output[0])  # noqa: F821
for p in paths:
    log.info("wrote %s", p)
end_job()
