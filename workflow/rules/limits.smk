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
                     caption="../report/plots.rst", category="1. Depth: table and maps", labels={"figure": "{name}"}),
    params:
        lim_store=LIMITS_WORK_STORE,
        # the cube (complete once every part is): the envelope's sensitivity chart reads it
        store=f"{RESULTS}/background.zarr",
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


import sys

from straylight.cube.provenance import snakemake_run as _snakemake_run

try:
    _RUN_CORES = workflow.cores
except WorkflowError:  # no --cores: a cluster run, whose jobs have their own
    _RUN_CORES = None
#: the command line and cores provenance.json records: Snakemake's main process's, also in the
#: jobs a cluster executor starts (passed on through the environment)
PROVENANCE_RUN = _snakemake_run(sys.argv, _RUN_CORES, workflow.is_main_process)


rule provenance:
    """Config, software versions, the code's commit, the run's command line and cores, input and
    output checksums of the campaign."""
    input:
        config=CONFIG_PATH,
        limits=f"{RESULTS}/limits.zarr",
        maps=f"{RESULTS}/maps",
        summary=f"{WORK}/background_summary.json",
        ephemeris=f"{RESULTS}/ephemeris.zarr",
        footprint=f"{RESULTS}/footprint.fits",
        stars=f"{RESULTS}/stars_csst.parquet",
        observability=f"{RESULTS}/observability.zarr",
        compact=f"{RESULTS}/sky_compact.zarr",
    output:
        report(f"{RESULTS}/provenance.json", caption="../report/provenance.rst", category="5. Provenance"),
    params:
        store=f"{RESULTS}/background.zarr",
        # a RunInfo: not compared with the last run's params (a resumed or dry run keeps the record)
        run=PROVENANCE_RUN,
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/provenance.log",
    script:
        "../scripts/provenance.py"
