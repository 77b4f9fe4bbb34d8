"""Benchmark: background-cube throughput in (time, pointing) samples per second per core, the
speed-up from 1 to 2 worker processes, and the read time of the two access patterns of the
cube's chunking (one pointing over all times; the whole sky at one time).

The cube is computed as rule background_blocks computes it (cube.run_time_blocks: a pool of
worker processes, each building the model once): the figure is the marginal rate, two more time
blocks' samples over the extra time a run of three blocks takes against a run of one, so the
workers' start-up is not in it.  Prints the figures and writes
bench/results/background.json.  Run:  python bench/background.py
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")


sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import write_results  # noqa: E402


def main():
    import xarray as xr

    from straylight.config import campaign_from_dict, load_campaign
    from straylight.cube.executors import Execution
    from straylight.cube.footprint import footprint_from_config
    from straylight.cube.run import run_time_blocks
    from straylight.cube.store import init_store

    base = load_campaign()
    raw = base.config_mapping()
    raw["campaign"].update(end="2026-01-01T06:00:00", time_block_hours=2)  # 3 blocks of 24 times
    raw["footprint"].update(pixel_block_size=330)  # 4 regions per block
    c = campaign_from_dict(raw, base.path)
    fp = footprint_from_config(c.settings.footprint)
    block_samples = len(c.times) // 3 * fp.pixels.size
    results = {"samples": 2 * block_samples, "bands": len(c.bands)}
    tmp = Path(tempfile.mkdtemp())
    try:
        for workers in (1, 2):
            seconds = {}
            for blocks in ([0], [0, 1, 2]):
                store = tmp / f"bg{workers}_{len(blocks)}.zarr"
                init_store(c, fp, store)
                t0 = time.perf_counter()
                run_time_blocks(
                    c,
                    fp,
                    store,
                    blocks,
                    tmp / f"done{workers}_{len(blocks)}",
                    execution=Execution(workers=workers),
                )
                seconds[len(blocks)] = time.perf_counter() - t0
            extra_s = seconds[3] - seconds[1]  # the two extra blocks
            rate = 2 * block_samples / extra_s
            results[f"workers_{workers}"] = {
                "seconds": extra_s,
                "samples_per_s": rate,
                "samples_per_s_per_core": rate / workers,
            }
            print(
                f"{workers} worker(s): {2 * block_samples} samples x {len(c.bands)} bands in {extra_s:.1f} s "
                f"= {rate:.0f} samples/s ({rate / workers:.0f} per core)"
            )
        results["speedup_1_to_2_workers"] = (
            results["workers_2"]["samples_per_s"] / results["workers_1"]["samples_per_s"]
        )
        print(f"speed-up 1 -> 2 workers: {results['speedup_1_to_2_workers']:.2f}")
        # access patterns on the default campaign's cube if it exists
        cube = Path(base.path).parent.parent / "results" / base.name / "background.zarr"
        if cube.exists():
            ds = xr.open_zarr(cube)
            t0 = time.perf_counter()
            ds["total"].isel(pixel=500).values
            t_series = time.perf_counter() - t0
            ds = xr.open_zarr(cube)
            t0 = time.perf_counter()
            ds["total"].isel(time=100).values
            t_sky = time.perf_counter() - t0
            results["read_one_pointing_all_times_s"] = t_series
            results["read_whole_sky_one_time_s"] = t_sky
            results["chunks"] = dict(zip(ds["total"].dims, ds["total"].encoding["chunks"]))
            print(
                f"default cube {results['chunks']}: one pointing over the campaign {t_series * 1e3:.0f} ms, "
                f"whole sky at one time {t_sky * 1e3:.0f} ms"
            )
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    write_results("background", results)


if __name__ == "__main__":
    main()
