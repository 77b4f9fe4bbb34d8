rule sky_compact:
    """sky_compact.zarr: the total background per band in AB mag/arcsec2, quantised to
    storage.compact_mag_step, with the observability, for schedulers (straylight.SkyMaps) and
    distribution; its error against background.zarr measured and recorded in its attributes."""
    input:
        summary=f"{WORK}/background_summary.json",
        config=CONFIG_PATH,
    output:
        directory(f"{RESULTS}/sky_compact.zarr"),
    params:
        store=f"{RESULTS}/background.zarr",
    threads: 2
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/sky_compact.log",
    script:
        "../scripts/sky_compact.py"
