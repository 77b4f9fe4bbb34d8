"""Snakemake adapter: rule `report_front` -> results/<name>/summary.rst, the report's first page
(the depth table written with the limit maps, thumbnails of the figures)."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821 - injected by Snakemake
from _common import end_job, setup_logging  # noqa: E402

from straylight.plots.report import DEPTH_TABLE, read_depth_table, write_report_front  # noqa: E402

log = setup_logging(snakemake)  # noqa: F821
rows = read_depth_table(Path(snakemake.input.depth, DEPTH_TABLE))  # noqa: F821
# the workflow's config, validated and resolved by its parse (workflow/rules/common.smk): no
# Campaign (its time grid) is needed for the page
path = write_report_front(
    rows,
    dict(snakemake.config),
    snakemake.output[0],  # noqa: F821
    [snakemake.input.depth, snakemake.input.sky, snakemake.input.series],
)  # noqa: F821
log.info("wrote %s", path)
end_job()
