rule limits:
    """limits.zarr: the 5-sigma limits the cube's workers wrote to the limits store (every time
    block done), published with the per-pixel campaign summaries added; the summaries as HEALPix
    maps (maps/), their figures and the depth table (depth/)."""
    input:
        parts=CUBE_PARTS,
        config=CONFIG_PATH,
    output:
        limits=directory(f"{RESULTS}/limits.zarr"),
        maps=directory(f"{RESULTS}/maps"),
        depth=report(directory(f"{RESULTS}/depth"), patterns=["{name}.png", "{name}.csv"],
                     caption="../report/plots.rst", category="Maps and time series", labels={"figure": "{name}"}),
    params:
        lim_store=LIMITS_WORK_STORE,
    # processes of the per-pixel summaries (common.smk; lowered to --cores by Snakemake)
    threads: LIMITS_PROCESSES
    # before the sky maps: provenance waits for it (common.smk: FIGURE_PRIORITY)
    priority: FIGURE_PRIORITY["limits"]
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/limits.log",
    script:
        "../scripts/limits.py"


rule provenance:
    """Config, software versions, input and output checksums of the campaign."""
    input:
        config=CONFIG_PATH,
        limits=f"{RESULTS}/limits.zarr",
        maps=f"{RESULTS}/maps",
        summary=f"{RESULTS}/background_summary.json",
        ephemeris=f"{RESULTS}/ephemeris.zarr",
        footprint=f"{RESULTS}/footprint.fits",
        stars=f"{RESULTS}/stars_csst.parquet",
        observability=f"{RESULTS}/observability.zarr",
    output:
        report(f"{RESULTS}/provenance.json", caption="../report/provenance.rst", category="Provenance"),
    params:
        store=f"{RESULTS}/background.zarr",
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/provenance.log",
    script:
        "../scripts/provenance.py"
