rule observability:
    """(time, pixel) observability and violated constraints over the footprint: written by the
    cube's workers beside the background (rule background_blocks), published here whole."""
    input:
        summary=f"{RESULTS}/background_summary.json",
        config=CONFIG_PATH,
    output:
        directory(f"{RESULTS}/observability.zarr"),
    params:
        obs_store=OBSERVABILITY_WORK_STORE,
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/observability.log",
    script:
        "../../scripts/observability.py"
