GAIA_FILES = [
    f if f.startswith("/") else str(Path(CONFIG_PATH).parent / f)
    for f in config.get("stars", {}).get("gaia_files", [])
]


rule stars_ingest:
    """One Gaia DR2 file: stars brighter than the G limit, and the quarantined rows with reasons."""
    input:
        gaia=lambda w: GAIA_FILES[int(w.index)],
        config=CONFIG_PATH,
    output:
        stars=f"{WORK}/stars/gaia_{{index}}.parquet",
        quarantine=f"{WORK}/stars/gaia_{{index}}_quarantine.parquet",
        summary=f"{WORK}/stars/gaia_{{index}}_summary.json",
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/stars_ingest_{{index}}.log",
    script:
        "../scripts/stars_ingest.py"


rule stars_gaia:
    """All ingested files merged (duplicates across files quarantined), with a summary."""
    input:
        stars=expand(f"{WORK}/stars/gaia_{{index}}.parquet", index=range(len(GAIA_FILES))),
        summaries=expand(f"{WORK}/stars/gaia_{{index}}_summary.json", index=range(len(GAIA_FILES))),
    output:
        stars=f"{RESULTS}/stars_gaia.parquet",
        summary=f"{WORK}/stars_gaia_summary.json",
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/stars_gaia.log",
    script:
        "../scripts/stars_merge.py"


rule stars_catalog:
    """The CSST-band star catalog: Gaia stars (if any) plus Hipparcos, templates and synthetic photometry."""
    input:
        gaia=[f"{RESULTS}/stars_gaia.parquet"] if GAIA_FILES else [],
        config=CONFIG_PATH,
    output:
        parquet=f"{RESULTS}/stars_csst.parquet",
        fits=f"{RESULTS}/stars_csst.fits",
        summary=f"{WORK}/stars_csst_summary.json",
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/stars_catalog.log",
    script:
        "../scripts/stars_catalog.py"
