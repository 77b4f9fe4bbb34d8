"""Benchmark: DE405 positions per second per core, and geometry samples per second per core.

Prints the figures and writes bench/results/ephemeris.json.  Run with one thread
(the numbers are per core):  OMP_NUM_THREADS=1 python bench/ephemeris.py
"""

from __future__ import annotations

import os
import platform
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import write_results  # noqa: E402


def best_of(fn, repeat=3):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main():
    from straylight.config import load_campaign
    from straylight.sky.ephemeris import BODIES, DE405
    from straylight.sky.geometry import observing_geometry
    from straylight.sky.observing import scene
    from straylight.sky.timeutil import utc_to_tdb_jd
    from straylight.sky.vectors import radec_to_unit

    eph = DE405()
    n = 1_000_000
    # a campaign-like grid: one year at ~31 s cadence, sorted times
    jd = 2461041.5 + np.linspace(0.0, 365.25, n)
    eph.positions_tdb(jd[:1000])  # warm the memory maps
    t_all = best_of(lambda: eph.positions_tdb(jd, bodies=BODIES))
    t_sun = best_of(lambda: eph.positions_tdb(jd, bodies=["sun"]))
    rng = np.random.default_rng(0)
    jd_random = rng.uniform(2433282.5, 2488069.5, n)
    eph.positions_tdb(jd_random, bodies=["moon"])
    t_rand = best_of(lambda: eph.positions_tdb(jd_random, bodies=["moon"]))

    from astropy.time import Time

    # a fresh Time each call: astropy caches a converted scale on the object
    t_conv = best_of(lambda: utc_to_tdb_jd(Time(jd, format="jd", scale="utc")), repeat=2)

    c = load_campaign()
    times = c.times
    sc = scene(c.orbit, times)
    rng = np.random.default_rng(1)
    n_pt = 4000
    ra, dec = rng.uniform(0, 360, n_pt), np.degrees(np.arcsin(rng.uniform(-1, 1, n_pt)))
    los = radec_to_unit(ra, dec)[None]
    sat = sc.satellite_km[:, None]
    bodies = {k: v[:, None] for k, v in sc.bodies_km.items()}
    t_geo = best_of(lambda: observing_geometry(sat, bodies, los, c.earth.radius_km, c.constraints), repeat=2)
    n_geo = len(times) * n_pt

    results = {
        "machine": {"platform": platform.platform(), "processor": platform.processor(), "cores_used": 1},
        "de405_body_positions_per_s_per_core_all_bodies": n * len(BODIES) / t_all,
        "de405_times_per_s_per_core_all_bodies": n / t_all,
        "de405_positions_per_s_per_core_sun_only": n / t_sun,
        "de405_positions_per_s_per_core_moon_random_times": n / t_rand,
        "utc_to_tdb_conversions_per_s": n / t_conv,
        "geometry_samples_per_s_per_core_all_bodies": n_geo / t_geo,
        "geometry_grid": [len(times), n_pt],
    }
    for k, v in results.items():
        print(f"{k:55s} {v:.3e}" if isinstance(v, float) else f"{k:55s} {v}")
    write_results("ephemeris", results)


if __name__ == "__main__":
    main()
