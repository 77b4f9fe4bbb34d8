"""Snakemake adapter: rule `background` -> consolidated metadata and a run summary table."""
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821 - injected by Snakemake
from _common import setup_logging  # noqa: E402

import zarr  # noqa: E402

from straylight.io import write_json_atomic  # noqa: E402

log = setup_logging(snakemake)  # noqa: F821
zarr.consolidate_metadata(snakemake.params.store)  # noqa: F821
blocks = [json.loads(Path(p).read_text()) for p in snakemake.input]  # noqa: F821
total_s = sum(b["seconds"] for b in blocks)
total_n = sum(b["samples"] for b in blocks)
log.info("%-10s %12s %8s %10s", "time block", "pixel blocks", "samples", "seconds")
for b in blocks:
    log.info("%-10d %12d %8d %10.1f", b["time_block"], b["pixel_blocks"], b["samples"], b["seconds"])
log.info("%-10s %12s %8d %10.1f  (%.0f samples/s wall)", "total", "", total_n, total_s, total_n / max(total_s, 1e-9))
write_json_atomic({"blocks": blocks, "samples": total_n, "seconds": total_s}, snakemake.output[0])  # noqa: F821
