"""Snakemake adapter: rule `background` -> consolidated metadata, a run summary table, and
observability.zarr (the store the cube's workers filled region by region beside the background,
published whole)."""

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821 - injected by Snakemake
import zarr  # noqa: E402
from _common import end_job, setup_logging  # noqa: E402

from straylight.cube.store import publish_work_store  # noqa: E402
from straylight.util.io import write_json_atomic  # noqa: E402

log = setup_logging(snakemake)  # noqa: F821
zarr.consolidate_metadata(snakemake.params.store)  # noqa: F821
blocks = [b for p in snakemake.input for b in json.loads(Path(p).read_text())["blocks"]]  # noqa: F821
total_s = sum(b["seconds"] for b in blocks)
total_n = sum(b["samples"] for b in blocks)
log.info("%-10s %12s %8s %10s", "time block", "pixel blocks", "samples", "seconds")
for b in blocks:
    log.info("%-10d %12d %8d %10.1f", b["time_block"], b["pixel_blocks"], b["samples"], b["seconds"])
log.info(
    "%-10s %12s %8d %10.1f  (seconds from each block's first region to its last, blocks overlap)",
    "total",
    "",
    total_n,
    total_s,
)
write_json_atomic({"blocks": blocks, "samples": total_n, "seconds": total_s}, snakemake.output.summary)  # noqa: F821
publish_work_store(snakemake.params.obs_store, snakemake.output.observability)  # noqa: F821
log.info("published %s", snakemake.output.observability)  # noqa: F821
end_job()
