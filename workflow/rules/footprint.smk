rule footprint:
    """HEALPix survey footprint (latitude cuts or a user mask) and the block plan."""
    input:
        config=CONFIG_PATH,
    output:
        mask=f"{RESULTS}/footprint.fits",
        plan=f"{RESULTS}/plan.json",
    conda:
        "../envs/straylight.yaml"
    log:
        f"{LOGS}/footprint.log",
    script:
        "../scripts/footprint.py"
