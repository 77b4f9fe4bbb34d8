# straylight: CSST stray-light and sky-background pipeline.
# Run:  snakemake --cores 2            (default campaign: config/config.yaml)
#       snakemake --cores 2 --configfile my_campaign.yaml
from pathlib import Path

from snakemake.utils import min_version

min_version("8.0")


configfile: "config/config.yaml"

# validated (with the schema's defaults) in workflow/rules/common.smk, errors naming the file
# that set the key, and relative paths resolved against that file


include: "workflow/rules/common.smk"
include: "workflow/rules/ephemeris.smk"
include: "workflow/rules/footprint.smk"
include: "workflow/rules/background.smk"
include: "workflow/rules/limits.smk"
include: "workflow/rules/stars.smk"
include: "workflow/rules/scheduling.smk"
include: "workflow/rules/figures.smk"


# the report's first page: the campaign's depth table and thumbnails written by rule report_front
# once it has run (snakemake --report), else the generic description
_REPORT_FRONT = Path(RESULTS, "summary.rst").resolve()


report: str(_REPORT_FRONT) if _REPORT_FRONT.exists() else "workflow/report/workflow.rst"


rule all:
    default_target: True
    input:
        f"{RESULTS}/ephemeris.zarr",
        f"{RESULTS}/footprint.fits",
        f"{RESULTS}/plan.json",
        f"{RESULTS}/observability.zarr",
        f"{RESULTS}/background_summary.json",
        f"{RESULTS}/limits.zarr",
        f"{RESULTS}/provenance.json",
        f"{RESULTS}/stars_csst.parquet",
        f"{RESULTS}/scheduling",
        f"{RESULTS}/depth",
        f"{RESULTS}/sky",
        f"{RESULTS}/series",
        f"{RESULTS}/summary.rst",
        f"{RESULTS}/bench_charts",
        [f"{RESULTS}/stars_gaia.parquet"] if config.get("stars", {}).get("gaia_files") else [],
