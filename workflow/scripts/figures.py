"""Snakemake adapter: rules `sky_maps` -> results/<name>/sky/*.png and `time_series` ->
results/<name>/series/*.png (the background cube's figures, one process each)."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821 - injected by Snakemake
from _common import campaign, end_job, setup_logging  # noqa: E402

from straylight.plots.maps import sky_map_figures  # noqa: E402
from straylight.plots.series import time_series_figures  # noqa: E402

log = setup_logging(snakemake)  # noqa: F821
draw = {"sky_maps": sky_map_figures, "time_series": time_series_figures}[snakemake.rule]  # noqa: F821
for p in draw(snakemake.params.store, campaign(snakemake), snakemake.output[0]):  # noqa: F821
    log.info("wrote %s", p)
end_job()
