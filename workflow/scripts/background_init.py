"""Snakemake adapter: rule `background_init` -> background.zarr skeleton, the observability and
limits stores' skeletons (filled by the cube's workers) + init.json.

A fresh store has no time block done: the blocks' sentinels beside init.json are removed first,
and the three stores are laid down afresh (no chunk of an earlier run is kept).
The body is guarded by __main__: the faint-star map's worker processes are spawned and
re-import the main module, which must then not run the job again."""

import dataclasses
import sys
from pathlib import Path


def main(snakemake):
    sys.path.insert(0, str(Path(snakemake.scriptdir)))
    import xarray as xr
    from _common import campaign, setup_logging

    from straylight.cube.footprint import footprint_from_config
    from straylight.cube.layout import cube_chunks
    from straylight.cube.run import clear_block_sentinels
    from straylight.cube.store import init_observability_store, init_store
    from straylight.execution import available_cores
    from straylight.util.io import write_json_atomic

    log = setup_logging(snakemake)
    c = campaign(snakemake)
    # the footprint rule's mask (its product, this rule's input): the same pixels, without
    # recomputing the latitude cuts
    fp = footprint_from_config(
        dataclasses.replace(c.settings.footprint, mask_file=str(Path(snakemake.input.mask).resolve()))
    )
    cleared = clear_block_sentinels(Path(snakemake.output[0]).parent)
    if cleared:
        log.info("removed %d time-block sentinels of an earlier store", cleared)
    with xr.open_zarr(snakemake.input.ephemeris, chunks=None) as ephem:  # read at once: no dask
        init_observability_store(c, fp, ephem.load(), snakemake.params.obs_store)
    # threads for an earthshine table, processes for a faint-star map, not kept on disk: the job's threads
    # where a profile raises them (SLURM), else the run's cores, at most the CPUs it may run on
    threads = int(snakemake.threads)
    cores = int(getattr(snakemake.resources, "build_processes", 1))
    build_workers = threads if threads > 1 else min(available_cores(), cores)
    init_store(
        c,
        fp,
        snakemake.params.store,
        snakemake.input.stars,
        build_workers=build_workers,
        limits_store=snakemake.params.lim_store,
    )
    chunks = cube_chunks(c, len(c.times), fp.pixels.size)
    write_json_atomic(
        {
            "store": snakemake.params.store,
            "times": len(c.times),
            "pixels": int(fp.pixels.size),
            "bands": c.bands,
            "chunks": chunks,
        },
        snakemake.output[0],
    )
    log.info(
        "background.zarr initialised: %d times x %d pixels x %d bands, chunks %s",
        len(c.times),
        fp.pixels.size,
        len(c.bands),
        chunks,
    )


if __name__ == "__main__":
    main(snakemake)  # noqa: F821 - injected by Snakemake
    from _common import end_job

    end_job()
