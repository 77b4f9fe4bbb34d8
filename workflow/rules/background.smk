rule background_init:
    """Lay down background.zarr and the observability and limits stores the cube's workers fill:
    coordinates, attributes and chunk layout, no data."""
    input:
        config=CONFIG_PATH,
        mask=f"{RESULTS}/footprint.fits",
        stars=f"{RESULTS}/stars_csst.parquet",
        ephemeris=f"{RESULTS}/ephemeris.zarr",
    output:
        f"{WORK}/background_blocks/init.json",
    params:
        store=f"{RESULTS}/background.zarr",
        obs_store=OBSERVABILITY_WORK_STORE,
        lim_store=LIMITS_WORK_STORE,
    # one process: with the earthshine table and the faint-star map kept on disk (every run after
    # the first of a model and footprint) the step is one process's work, and a core it does not
    # use runs the small jobs beside it.  A table or map it must compute takes the run's cores
    # (build_processes: the table's threads, the map's processes; workflow/scripts/background_init.py);
    # the SLURM profile raises the threads instead.
    threads: 1
    resources:
        build_processes=INIT_BUILD_PROCESSES,
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/background_init.log",
    script:
        "../scripts/background_init.py"


rule background_blocks:
    """A group of time blocks of the cube (all of them by default): a pool of worker processes,
    started once, computes their pixel blocks, each written to its region of background.zarr, of
    the observability store (the same geometry) and of the limits store (the limits of the
    computed total); a time block's sentinel
    (background_blocks/block_<i>.json) marks it done, so a re-run redoes only unfinished ones."""
    input:
        f"{WORK}/background_blocks/init.json",
        config=CONFIG_PATH,
        stars=f"{RESULTS}/stars_csst.parquet",
    output:
        f"{WORK}/background_blocks/part_{{part}}.json",
    params:
        store=f"{RESULTS}/background.zarr",
        obs_store=OBSERVABILITY_WORK_STORE,
        lim_store=LIMITS_WORK_STORE,
        blocks=lambda wildcards: CUBE_JOBS[int(wildcards.part)],
    # worker processes of the job's pool; Snakemake lowers it to --cores, and the SLURM profile
    # raises it (set-threads)
    threads: 2
    resources:
        mem_mb=4000,
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/background_blocks_{{part}}.log",
    script:
        "../scripts/background_blocks.py"


rule background:
    """All time blocks done: consolidate background.zarr's metadata, summarise the run, and
    publish the observability store the cube's workers filled as observability.zarr (the
    (time, pixel) observability and violated constraints over the footprint)."""
    input:
        CUBE_PARTS,
    output:
        summary=f"{WORK}/background_summary.json",
        observability=directory(f"{RESULTS}/observability.zarr"),
    params:
        store=f"{RESULTS}/background.zarr",
        obs_store=OBSERVABILITY_WORK_STORE,
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/background.log",
    script:
        "../scripts/background_finalize.py"
