"""Snakemake adapter: rule `background_blocks` -> a group of time blocks of background.zarr.

The body is guarded by __main__: the pool's worker processes are spawned and re-import the main
module, which must then not run the job again.
"""
import sys
from pathlib import Path


def main(snakemake):
    sys.path.insert(0, str(Path(snakemake.scriptdir)))
    from _common import campaign, setup_logging

    from straylight.survey.cube import run_time_blocks
    from straylight.survey.footprint import footprint_from_config
    from straylight.util.io import write_json_atomic

    log = setup_logging(snakemake)
    c = campaign(snakemake)
    fp = footprint_from_config(c.config["footprint"], c.path.parent)
    blocks = list(snakemake.params.blocks)
    done_dir = Path(snakemake.output[0]).parent
    reports = run_time_blocks(c, fp, snakemake.params.store, blocks, done_dir, workers=snakemake.threads,
                              scheduler_address=(c.config.get("compute") or {}).get("dask_scheduler"), log=log,
                              stars_path=snakemake.input.stars, obs_store=snakemake.params.obs_store,
                              lim_store=snakemake.params.lim_store)
    write_json_atomic({"blocks": [r.__dict__ for r in reports]}, snakemake.output[0])
    n = sum(r.samples for r in reports)
    log.info("time blocks %d-%d: %d samples", blocks[0], blocks[-1], n)


if __name__ == "__main__":
    main(snakemake)  # noqa: F821 - injected by Snakemake
