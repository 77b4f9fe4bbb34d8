"""Snakemake adapter: rule `plots` -> results/<name>/plots/*.png."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821 - injected by Snakemake
from _common import campaign, setup_logging  # noqa: E402

from straylight.plots import campaign_figures  # noqa: E402

log = setup_logging(snakemake)  # noqa: F821
c = campaign(snakemake)  # noqa: F821
for p in campaign_figures(snakemake.params.store, snakemake.input.limits, c, snakemake.output[0]):  # noqa: F821
    log.info("wrote %s", p)
