rule background_init:
    """Lay down background.zarr: coordinates, attributes and chunk layout, no data."""
    input:
        config=CONFIG_PATH,
        mask=f"{RESULTS}/footprint.fits",
        stars=f"{RESULTS}/stars_csst.parquet",
    output:
        f"{RESULTS}/background_blocks/init.json",
    params:
        store=f"{RESULTS}/background.zarr",
    # processes for the earthshine table's build, when the campaign needs one that is not cached
    # (lowered to --cores by Snakemake; the SLURM profile can raise it)
    threads: 2
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/background_init.log",
    script:
        "../../scripts/background_init.py"


rule background_block:
    """One time block of the cube: Dask computes the pixel blocks, each written to its region."""
    input:
        f"{RESULTS}/background_blocks/init.json",
        config=CONFIG_PATH,
        stars=f"{RESULTS}/stars_csst.parquet",
    output:
        f"{RESULTS}/background_blocks/block_{{block}}.json",
    params:
        store=f"{RESULTS}/background.zarr",
    # 2 Dask workers per time block; Snakemake lowers it to --cores, runs several blocks at once
    # on bigger machines, and the SLURM profile raises it (set-threads)
    threads: 2
    resources:
        mem_mb=4000,
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/background_block_{{block}}.log",
    script:
        "../../scripts/background_block.py"


rule background:
    """All time blocks done: consolidate the store's metadata and summarise the run."""
    input:
        expand(f"{RESULTS}/background_blocks/block_{{block}}.json", block=TIME_BLOCKS),
    output:
        f"{RESULTS}/background_summary.json",
    params:
        store=f"{RESULTS}/background.zarr",
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/background.log",
    script:
        "../../scripts/background_finalize.py"
