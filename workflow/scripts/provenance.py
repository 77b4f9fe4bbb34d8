"""Snakemake adapter: rule `provenance` -> provenance.json (config, code, run, checksums)."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821 - injected by Snakemake
from _common import campaign, end_job, setup_logging  # noqa: E402

from straylight.cube.provenance import provenance_record  # noqa: E402
from straylight.util.io import write_json_atomic  # noqa: E402

log = setup_logging(snakemake)  # noqa: F821
c = campaign(snakemake)  # noqa: F821
outputs = {
    "background.zarr": snakemake.params.store,  # noqa: F821
    "limits.zarr": snakemake.input.limits,  # noqa: F821
    "maps": snakemake.input.maps,  # noqa: F821
    "ephemeris.zarr": snakemake.input.ephemeris,  # noqa: F821
    "footprint.fits": snakemake.input.footprint,  # noqa: F821
    "stars_csst.parquet": snakemake.input.stars,  # noqa: F821
    "observability.zarr": snakemake.input.observability,  # noqa: F821
    "sky_compact.zarr": snakemake.input.compact,  # noqa: F821
}
# paths relative to the results folder (provenance.json's), the workflow's as straylight:workflow/...
rec = provenance_record(
    c,
    {},
    outputs,
    results=Path(snakemake.output[0]).parent,  # noqa: F821
    run=snakemake.params.run,
    workflow_dir=Path(snakemake.scriptdir).parent,
)  # noqa: F821
write_json_atomic(rec, snakemake.output[0])  # noqa: F821
log.info(
    "code %s (%s %s%s); run: %s",
    rec["source"]["version"],
    rec["source"]["from"],
    rec["source"]["commit"],
    ", uncommitted changes" if rec["source"]["dirty"] else "",
    " ".join(rec["run"]["command"]),
)
for k, v in rec["outputs_sha256"].items():
    log.info("%-16s sha256 %s", k, v)
end_job()
