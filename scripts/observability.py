"""Snakemake adapter: rule `observability` -> observability.zarr, the store the cube's workers
filled region by region beside the background (the same geometry), published whole."""
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821 - injected by Snakemake
from _common import setup_logging  # noqa: E402

import xarray as xr  # noqa: E402

from straylight.survey.cube import publish_observability  # noqa: E402

log = setup_logging(snakemake)  # noqa: F821
t0 = time.perf_counter()
publish_observability(snakemake.params.obs_store, snakemake.output[0])  # noqa: F821
with xr.open_zarr(snakemake.output[0]) as written:  # noqa: F821 - read back, not computed again
    frac = float(written["observable"].mean())
    sizes = dict(written.sizes)
log.info("observability: %d times x %d pixels, observable fraction %.3f, %.2f s",
         sizes["time"], sizes["pixel"], frac, time.perf_counter() - t0)
