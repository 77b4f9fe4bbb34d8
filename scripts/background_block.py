"""Snakemake adapter: rule `background_block` -> one time block of background.zarr (Dask).

The body is guarded by __main__: Dask's worker processes are spawned and re-import the main
module, which must then not run the job again.
"""
import sys
from pathlib import Path


def main(snakemake):
    sys.path.insert(0, str(Path(snakemake.scriptdir)))
    from _common import campaign, setup_logging

    from straylight.cube import run_time_block
    from straylight.daskutil import dask_client
    from straylight.footprint import footprint_from_config
    from straylight.io import write_json_atomic

    log = setup_logging(snakemake)
    c = campaign(snakemake)
    fp = footprint_from_config(c.config["footprint"], c.path.parent)
    block = int(snakemake.wildcards.block)
    with dask_client(c.config.get("compute", {}).get("dask_scheduler"), snakemake.threads,
                     snakemake.resources.mem_mb) as client:
        report = run_time_block(c, fp, snakemake.params.store, block, client, log=log,
                                stars_path=snakemake.input.stars)
    write_json_atomic(report.__dict__, snakemake.output[0])
    log.info("time block %d: %d samples in %.1f s (%.0f samples/s)", block, report.samples, report.seconds,
             report.samples / report.seconds)


if __name__ == "__main__":
    main(snakemake)  # noqa: F821 - injected by Snakemake
