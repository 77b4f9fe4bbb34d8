"""Snakemake adapter: rule `background_init` -> background.zarr skeleton + init.json.

A fresh store has no time block done: the blocks' sentinels beside init.json are removed first."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821 - injected by Snakemake
from _common import campaign, setup_logging  # noqa: E402

from straylight.survey.cube import clear_block_sentinels, cube_chunks, init_store  # noqa: E402
from straylight.survey.footprint import footprint_from_config  # noqa: E402
from straylight.util.io import write_json_atomic  # noqa: E402

log = setup_logging(snakemake)  # noqa: F821
c = campaign(snakemake)  # noqa: F821
fp = footprint_from_config(c.config["footprint"], c.path.parent)
cleared = clear_block_sentinels(Path(snakemake.output[0]).parent)  # noqa: F821
if cleared:
    log.info("removed %d time-block sentinels of an earlier store", cleared)
init_store(c, fp, snakemake.params.store, snakemake.input.stars, build_workers=snakemake.threads)  # noqa: F821
chunks = cube_chunks(c, len(c.times), fp.pixels.size)
write_json_atomic({"store": snakemake.params.store, "times": len(c.times), "pixels": int(fp.pixels.size),  # noqa: F821
                   "bands": c.bands, "chunks": chunks}, snakemake.output[0])  # noqa: F821
log.info("background.zarr initialised: %d times x %d pixels x %d bands, chunks %s",
         len(c.times), fp.pixels.size, len(c.bands), chunks)
