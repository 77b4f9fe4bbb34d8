"""Snakemake adapter: rule `observability` -> observability.zarr (streamed: one cube chunk at a time)."""
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821 - injected by Snakemake
from _common import campaign, setup_logging  # noqa: E402

import xarray as xr  # noqa: E402

from straylight.survey.cube import cube_chunks  # noqa: E402
from straylight.survey.storage import write_zarr_atomic  # noqa: E402
from straylight.survey.products import footprint_products, observability_dataset  # noqa: E402

log = setup_logging(snakemake)  # noqa: F821
t0 = time.perf_counter()
c = campaign(snakemake)  # noqa: F821
fp, _ = footprint_products(c)
with xr.open_zarr(snakemake.input.ephemeris) as ephem:  # noqa: F821
    chunks = cube_chunks(c, ephem.sizes["time"], fp.pixels.size)
    ds = observability_dataset(c, ephem.load(), fp, chunks=chunks)
write_zarr_atomic(ds, snakemake.output[0], storage=c.config["storage"])  # noqa: F821
with xr.open_zarr(snakemake.output[0]) as written:  # noqa: F821 - read back, not computed again
    frac = float(written["observable"].mean())
log.info("observability: %d times x %d pixels, observable fraction %.3f, %.2f s",
         ds.sizes["time"], ds.sizes["pixel"], frac, time.perf_counter() - t0)
