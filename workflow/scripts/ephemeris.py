"""Snakemake adapter: rule `ephemeris` -> ephemeris.zarr."""

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821 - injected by Snakemake
from _common import campaign, end_job, setup_logging  # noqa: E402

from straylight.cube.products import ephemeris_dataset  # noqa: E402
from straylight.storage.zarr_io import write_zarr_atomic  # noqa: E402

log = setup_logging(snakemake)  # noqa: F821
t0 = time.perf_counter()
c = campaign(snakemake)  # noqa: F821
ds = ephemeris_dataset(c)
write_zarr_atomic(ds, snakemake.output[0])  # noqa: F821
log.info(
    "ephemeris: %d times x %d bodies in %.2f s", ds.sizes["time"], ds.sizes["body"], time.perf_counter() - t0
)
end_job()
