rule scheduling:
    """Scheduling tables (CSV + PNG): Moon avoidance angle per lunar phase and band, bright-limb
    elevation per solar geometry and band, exposure-time factor under stray light."""
    input:
        config=CONFIG_PATH,
    # off the products' critical path: run when a core is free (Snakemake's default priority is 0)
    priority: -1
    output:
        report(directory(f"{RESULTS}/scheduling"), patterns=["{name}.png", "{name}.csv"],
               caption="../report/scheduling.rst", category="4. Scheduling tables", labels={"table": "{name}"}),
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/scheduling.log",
    script:
        "../scripts/scheduling.py"
