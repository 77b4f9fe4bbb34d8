rule plots:
    """Report figures: Mollweide maps per component and band, time series, limit maps."""
    input:
        summary=f"{RESULTS}/background_summary.json",
        limits=f"{RESULTS}/limits.zarr",
        config=CONFIG_PATH,
    output:
        report(directory(f"{RESULTS}/plots"), patterns=["{name}.png", "{name}.csv"], caption="../report/plots.rst",
               category="Maps and time series", labels={"figure": "{name}"}),
    params:
        store=f"{RESULTS}/background.zarr",
    # processes drawing the figures (Snakemake lowers it to --cores)
    threads: 2
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/plots.log",
    script:
        "../../scripts/plots.py"


rule bench_charts:
    """The speed-against-accuracy charts of bench/run.py, when they have been made."""
    input:
        charts=lambda wildcards: sorted(str(p) for p in Path(workflow.basedir, "bench", "results").glob("pareto_*.png")),
    # off the products' critical path: run when a core is free
    priority: -1
    output:
        report(directory(f"{RESULTS}/bench_charts"), patterns=["{name}.png"], caption="../report/bench.rst",
               category="Speed against accuracy"),
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/bench_charts.log",
    # a shell command, not a run block: a run block starts a Python process with Snakemake in it
    shell:
        "mkdir -p {output:q} && for f in {input.charts:q}; do cp \"$f\" {output:q}/; done > {log:q} 2>&1"
