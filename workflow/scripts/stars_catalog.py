"""Snakemake adapter: rule `stars_catalog` -> stars_csst.parquet, stars_csst.fits and a summary."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821 - injected by Snakemake
import pyarrow.parquet as pq  # noqa: E402
from _common import campaign as campaign_from_snakemake  # noqa: E402
from _common import end_job, setup_logging

from straylight.catalog.campaign_catalog import catalog_for_campaign, write_catalog  # noqa: E402
from straylight.util.io import write_json_atomic  # noqa: E402

log = setup_logging(snakemake)  # noqa: F821
campaign = campaign_from_snakemake(snakemake)  # noqa: F821
gaia = None
if snakemake.input.gaia:  # noqa: F821
    t = pq.read_table(snakemake.input.gaia[0])  # noqa: F821
    gaia = {k: t[k].to_numpy() for k in t.column_names}
columns, summary, meta = catalog_for_campaign(campaign, gaia)
write_catalog(columns, snakemake.output.parquet, meta)  # noqa: F821
write_catalog(columns, snakemake.output.fits, meta)  # noqa: F821
write_json_atomic(summary, snakemake.output.summary)  # noqa: F821
rt = summary["round_trip_bp_rp_mag"]
log.info(
    "%d stars %s; template BP-RP round trip median %.3f p90 %.3f p99 %.3f mag",
    summary["stars"],
    summary["by_source"],
    rt["median_abs_bp_rp_mag"],
    rt["p90_abs_bp_rp_mag"],
    rt["p99_abs_bp_rp_mag"],
)
end_job()
