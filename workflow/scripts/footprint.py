"""Snakemake adapter: rule `footprint` -> footprint.fits, plan.json."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821 - injected by Snakemake
from _common import campaign, end_job, setup_logging  # noqa: E402

from straylight.cube.products import footprint_products, write_footprint_fits  # noqa: E402
from straylight.util.io import write_json_atomic  # noqa: E402

log = setup_logging(snakemake)  # noqa: F821
c = campaign(snakemake)  # noqa: F821
fp, plan = footprint_products(c)
write_footprint_fits(fp, snakemake.output.mask)  # noqa: F821
write_json_atomic(plan, snakemake.output.plan)  # noqa: F821
log.info(
    "footprint: %d pixels at nside %d, %.0f deg2; %d time blocks x %d pixel blocks",
    plan["n_pixels"],
    plan["nside"],
    plan["area_deg2"],
    len(plan["time_blocks"]),
    len(plan["pixel_blocks"]),
)
end_job()
