"""Snakemake adapter: rule `scheduling` -> results/<name>/scheduling/*.csv, *.png."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821 - injected by Snakemake
from _common import campaign, end_job, setup_logging  # noqa: E402

from straylight.model import BackgroundModel  # noqa: E402
from straylight.planning.scheduling import write_tables  # noqa: E402

log = setup_logging(snakemake)  # noqa: F821
c = campaign(snakemake)  # noqa: F821
fraction = float(c.settings.scheduling.fraction_of_zodiacal)
for p in write_tables(BackgroundModel(c), snakemake.output[0], fraction):  # noqa: F821
    log.info("wrote %s", p)
end_job()
