"""Snakemake adapter: rule `plots` -> results/<name>/plots/*.png.

The body is guarded by __main__: the figures' worker processes are spawned and re-import the
main module, which must then not run the job again.
"""
import sys
from pathlib import Path


def main(snakemake):
    sys.path.insert(0, str(Path(snakemake.scriptdir)))
    from _common import campaign, setup_logging

    from straylight.plots import campaign_figures

    log = setup_logging(snakemake)
    c = campaign(snakemake)
    for p in campaign_figures(snakemake.params.store, snakemake.input.limits, c, snakemake.output[0],
                              workers=snakemake.threads):
        log.info("wrote %s", p)


if __name__ == "__main__":
    main(snakemake)  # noqa: F821 - injected by Snakemake
