"""Snakemake adapter: rule `limits` -> limits.zarr, maps/ (the HEALPix maps) and depth/ (the
limit maps' figures and the depth table).

The cube's workers wrote every sample's limit to the limits work store; this step computes the
per-pixel summaries from it (streamed over pixel blocks on the job's processes), publishes the
store with them as limits.zarr, and writes the maps and their figures.  The body is guarded by
__main__: the pool's worker processes are spawned and re-import the main module, which must then
not run the job again."""

import sys
from pathlib import Path


def main(snakemake):
    sys.path.insert(0, str(Path(snakemake.scriptdir)))
    import numpy as np
    import xarray as xr
    from _common import campaign, setup_logging

    from straylight.cube.layout import LIMITS_REGION_VARIABLES
    from straylight.cube.store import publish_work_store
    from straylight.limits.budget import BUDGET_VARIABLES
    from straylight.limits.cube import store_limit_summaries, write_limit_maps
    from straylight.limits.envelope import ENVELOPE_VARIABLES
    from straylight.plots.envelope import envelope_figures
    from straylight.plots.report import limit_figures
    from straylight.util.io import atomic_path

    log = setup_logging(snakemake)
    summaries = store_limit_summaries(snakemake.params.lim_store, workers=snakemake.threads)
    # the envelope's and the budget's per-sample limits stay in the work store: the product keeps
    # their medians
    per_sample = [name for name, _ in (*ENVELOPE_VARIABLES.values(), *BUDGET_VARIABLES.values())]
    publish_work_store(snakemake.params.lim_store, snakemake.output.limits, summaries, drop=per_sample)
    # the maps and the log from the per-pixel summaries just written (small: pixel x band)
    with xr.open_zarr(snakemake.output.limits, consolidated=True, chunks=None) as written:
        ds = written.drop_vars(list(LIMITS_REGION_VARIABLES), errors="ignore").load()
    with atomic_path(snakemake.output.maps) as tmp:
        maps = write_limit_maps(ds, tmp, end=campaign(snakemake).settings.campaign.end)
    with atomic_path(snakemake.output.depth) as tmp:
        figures = limit_figures(snakemake.output.limits, campaign(snakemake), tmp)
        figures += envelope_figures(ds, snakemake.params.store, campaign(snakemake), tmp)
    for b in ds["band"].values:
        best = ds["limiting_mag_best"].sel(band=b).values
        seen = best[np.isfinite(best)]  # NaN: never observable
        if seen.size:
            log.info(
                "band %-4s: deepest limit %.2f, median of pixel bests %.2f mag (AB)",
                b,
                seen.max(),
                np.median(seen),
            )
        else:
            log.info("band %-4s: no observable pixel", b)
    log.info("wrote %d HEALPix maps and %s", len(maps), ", ".join(p.name for p in figures))


if __name__ == "__main__":
    main(snakemake)  # noqa: F821 - injected by Snakemake
    from _common import end_job

    end_job()
