"""Snakemake adapter: rule `limits` -> limits.zarr and maps/*.fits (streamed over the cube's chunks)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821 - injected by Snakemake
from _common import campaign, setup_logging  # noqa: E402

import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402

from straylight.survey.storage import write_zarr_atomic  # noqa: E402
from straylight.util.io import atomic_path  # noqa: E402
from straylight.survey.limits import limits_dataset, write_limit_maps  # noqa: E402

log = setup_logging(snakemake)  # noqa: F821
c = campaign(snakemake)  # noqa: F821
with xr.open_zarr(snakemake.params.store, consolidated=True) as bg:  # noqa: F821
    write_zarr_atomic(limits_dataset(c, bg), snakemake.output.limits, storage=c.config["storage"])  # noqa: F821
# the maps and the log from the per-pixel summaries just written (small: pixel x band)
with xr.open_zarr(snakemake.output.limits, consolidated=True) as written:  # noqa: F821
    ds = written.drop_vars(["limiting_mag", "observable"]).load()
with atomic_path(snakemake.output.maps) as tmp:  # noqa: F821
    maps = write_limit_maps(ds, tmp)
for b in ds["band"].values:
    best = ds["limiting_mag_best"].sel(band=b).values
    seen = best[np.isfinite(best)]  # NaN: never observable
    if seen.size:
        log.info("band %-4s: deepest limit %.2f, median of pixel bests %.2f mag (AB)", b, seen.max(), np.median(seen))
    else:
        log.info("band %-4s: no observable pixel", b)
log.info("wrote %d HEALPix maps", len(maps))
