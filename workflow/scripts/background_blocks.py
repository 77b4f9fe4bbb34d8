"""Snakemake adapter: rule `background_blocks` -> a group of time blocks of background.zarr.

The body is guarded by __main__: the pool's worker processes are spawned and re-import the main
module, which must then not run the job again.

SIGTERM or SIGINT (Snakemake stopping, a Ctrl-C, Snakemake's death: _common.die_with_snakemake)
stops the job cleanly: its workers killed, the queued regions cancelled, no time block marked done
that is not (a block's sentinel is written after all its regions), exit status 128 + the
signal's number.  A re-run redoes the unfinished blocks.
"""

import os
import sys
from pathlib import Path


def main(snakemake):
    sys.path.insert(0, str(Path(snakemake.scriptdir)))
    from _common import die_with_snakemake

    from straylight.execution import stop_on_signals

    die_with_snakemake()  # before the workers start: none is left behind by a killed Snakemake
    with stop_on_signals() as stopping:
        _run(snakemake, stopping)


def _run(snakemake, stopping):
    """The job's body; ``stopping``: the list of pools whose workers a SIGTERM or SIGINT kills."""
    from contextlib import nullcontext

    from straylight.cube.layout import CubeStores

    stores = CubeStores(snakemake.params.store, snakemake.params.obs_store, snakemake.params.lim_store)
    stars_path = snakemake.input.stars
    scheduler = (snakemake.config.get("compute") or {}).get("dask_scheduler")
    workers = int(snakemake.threads)
    if workers > 1 and not scheduler:
        # the pool's workers start first: they load the campaign and build the model while this
        # process imports and loads its own
        from straylight.cube.executors import start_region_workers

        starting = start_region_workers(
            workers, dict(snakemake.config), snakemake.input.config, stores, stars_path
        )
    else:
        starting = nullcontext()
    with starting as pool:
        if pool is not None:
            stopping.append(pool)
            for _ in range(workers):
                pool.submit(os.getpid)  # a process is spawned at a task's submission
        from _common import campaign, setup_logging

        from straylight.cube.executors import Execution
        from straylight.cube.footprint import footprint_from_store
        from straylight.cube.run import run_time_blocks
        from straylight.util.io import write_json_atomic

        log = setup_logging(snakemake)
        c = campaign(snakemake)
        fp = footprint_from_store(snakemake.params.store)  # the skeleton background_init laid down
        blocks = list(snakemake.params.blocks)
        done_dir = Path(snakemake.output[0]).parent
        reports = run_time_blocks(
            c,
            fp,
            stores,
            blocks,
            done_dir,
            stars_path,
            Execution(workers, scheduler_address=scheduler, pool=pool),
            log=log,
        )
    write_json_atomic({"blocks": [r.__dict__ for r in reports]}, snakemake.output[0])
    n = sum(r.samples for r in reports)
    log.info("time blocks %d-%d: %d samples", blocks[0], blocks[-1], n)


if __name__ == "__main__":
    from straylight.execution import Stopped

    try:
        main(snakemake)  # noqa: F821 - injected by Snakemake
    except Stopped as stop:
        import logging

        from straylight.execution import exit_without_teardown

        logging.getLogger(f"straylight.{snakemake.rule}").error(  # noqa: F821
            "%s: workers stopped, unfinished time blocks not marked done; re-run to resume", stop
        )
        exit_without_teardown(128 + stop.signum)
    from _common import end_job

    end_job()
