rule observability:
    """(time, pixel) observability and violated constraints over the footprint."""
    input:
        config=CONFIG_PATH,
        ephemeris=f"{RESULTS}/ephemeris.zarr",
        mask=f"{RESULTS}/footprint.fits",
    output:
        directory(f"{RESULTS}/observability.zarr"),
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/observability.log",
    script:
        "../../scripts/observability.py"
