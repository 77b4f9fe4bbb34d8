rule sky_maps:
    """Sky-map pages of the background cube: every component, the total and the observability
    as Mollweide maps per band at the report's map times."""
    input:
        parts=CUBE_PARTS,
        config=CONFIG_PATH,
    output:
        report(directory(f"{RESULTS}/sky"), patterns=["{name}.png"], caption="../report/plots.rst",
               category="2. Sky background maps", labels={"figure": "{name}"}),
    params:
        store=f"{RESULTS}/background.zarr",
    priority: FIGURE_PRIORITY["sky_maps"]
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/sky_maps.log",
    script:
        "../scripts/figures.py"


rule time_series:
    """Time series of the report's pointings: total and components per band over the first orbit
    (the model every minute, with the star catalog) and the whole campaign (the cube)."""
    input:
        parts=CUBE_PARTS,
        config=CONFIG_PATH,
        stars=f"{RESULTS}/stars_csst.parquet",
    output:
        report(directory(f"{RESULTS}/series"), patterns=["{name}.png"], caption="../report/plots.rst",
               category="3. Time series", labels={"figure": "{name}"}),
    params:
        store=f"{RESULTS}/background.zarr",
    priority: FIGURE_PRIORITY["time_series"]
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/time_series.log",
    script:
        "../scripts/figures.py"


# a few milliseconds of work: on a cluster, not worth a job of its own
localrules:
    report_front,
    bench_charts,


rule report_front:
    """The report's first page: the campaign, its depth table and thumbnails of the figures."""
    input:
        depth=f"{RESULTS}/depth",
        sky=f"{RESULTS}/sky",
        series=f"{RESULTS}/series",
        config=CONFIG_PATH,
    output:
        f"{RESULTS}/summary.rst",
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/report_front.log",
    script:
        "../scripts/report_front.py"


rule bench_charts:
    """The speed-against-accuracy charts of bench/run.py, when they have been made."""
    input:
        charts=lambda wildcards: sorted(str(p) for p in Path(workflow.basedir).parent.joinpath("bench", "results").glob("pareto_*.png")),
    # off the products' critical path: run when a core is free
    priority: -1
    output:
        report(directory(f"{WORK}/bench_charts"), patterns=["{name}.png"], caption="../report/bench.rst",
               category="6. Speed against accuracy"),
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/bench_charts.log",
    # a shell command, not a run block: a run block starts a Python process with Snakemake in it
    shell:
        "mkdir -p {output:q} && for f in {input.charts:q}; do cp \"$f\" {output:q}/; done > {log:q} 2>&1"
