rule ephemeris:
    """Campaign time grid to Zarr: DE405 body positions, satellite orbit, Sun/Moon geometry."""
    input:
        config=CONFIG_PATH,
    output:
        directory(f"{RESULTS}/ephemeris.zarr"),
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/ephemeris.log",
    script:
        "../scripts/ephemeris.py"
