"""Snakemake adapter: rule `stars_ingest` -> one Gaia file's stars, quarantine and summary."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821 - injected by Snakemake
from _common import campaign, end_job, setup_logging  # noqa: E402

from straylight.catalog.gaia import ingest_file, write_parquet  # noqa: E402
from straylight.util.io import write_json_atomic  # noqa: E402

log = setup_logging(snakemake)  # noqa: F821
c = campaign(snakemake)  # noqa: F821
res = ingest_file(snakemake.input.gaia, float(c.settings.stars.g_limit_mag))  # noqa: F821
write_parquet(res.stars, snakemake.output.stars, {"source_file": str(snakemake.input.gaia)})  # noqa: F821
write_parquet(res.quarantine, snakemake.output.quarantine)  # noqa: F821
write_json_atomic(res.summary, snakemake.output.summary)  # noqa: F821
log.info(
    "%s: %d rows, %d kept, %d fainter than the limit, %d quarantined %s",
    res.summary["file"],
    res.summary["rows"],
    res.summary["kept"],
    res.summary["fainter_than_limit"],
    res.summary["quarantined"],
    res.summary["quarantine_reasons"],
)
end_job()
