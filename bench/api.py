"""Benchmark of the Python API as a scheduler uses it: straylight.SkyModel and sky_background.

Prints and writes bench/results/api.json:

* a fresh process's first answer: ``python -c`` importing straylight, building the SkyModel of
  the default config (its earthshine tables read from the cache) and asking for one pointing,
  wall seconds from the command to the answer (the tables are built first if they are not
  cached, and that build is reported on its own);
* a warm single call: the median of ``--calls`` one-pointing calls, all bands and one band;
* many random (time, pointing) pairs in one call: ``--pairs`` pairs over a day, samples/s;
* the CPU seconds of each timed part beside its wall seconds (the machine's other load moves
  the wall time more than the CPU time).

Run:  python bench/api.py            (tables built first if not cached)
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import write_results  # noqa: E402

FIRST_CALL = """
import time
t0 = time.perf_counter()
import straylight
from astropy.coordinates import SkyCoord
from astropy.time import Time
sky = straylight.SkyModel()
row = sky.background(Time("2026-01-01T00:30:00"), SkyCoord(150.0, 30.0, unit="deg"))
print(time.perf_counter() - t0, time.process_time())
"""


def timed(fn):
    """(result, wall seconds, CPU seconds of this process) of fn()."""
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w0, time.process_time() - c0


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=200, help="warm single calls timed (default 200)")
    ap.add_argument("--pairs", type=int, default=100_000, help="random pairs in one call (default 100000)")
    args = ap.parse_args(argv)

    import astropy.units as u
    from astropy.coordinates import SkyCoord
    from astropy.time import Time

    import straylight

    sky, build_wall, build_cpu = timed(straylight.SkyModel)  # builds the tables if not cached
    proc = subprocess.run([sys.executable, "-c", FIRST_CALL], capture_output=True, text=True, check=True)
    first_wall, first_cpu = (float(x) for x in proc.stdout.split())

    t0, where = Time("2026-01-01T00:30:00"), SkyCoord(150.0, 30.0, unit="deg")
    sky.background(t0, where)  # warm
    single = {}
    for label, bands in (("all_bands", None), ("one_band", ["g"])):
        walls = []
        for i in range(args.calls):
            _, w, _ = timed(lambda: sky.background(t0 + i * u.min, where, bands=bands))
            walls.append(w)
        single[label] = {
            "median_ms": 1e3 * float(np.median(walls)),
            "p90_ms": 1e3 * float(np.percentile(walls, 90)),
        }

    rng = np.random.default_rng(1)
    n = args.pairs
    times = t0 + rng.uniform(0.0, 1.0, n) * u.day
    coords = SkyCoord(
        rng.uniform(0.0, 360.0, n), np.degrees(np.arcsin(rng.uniform(-1.0, 1.0, n))), unit="deg"
    )
    table, pairs_wall, pairs_cpu = timed(lambda: sky.background(times, coords))
    assert len(table) == n

    result = {
        "skymodel_build_in_this_process": {
            "wall_s": build_wall,
            "cpu_s": build_cpu,
            "note": "includes the tables' build when they were not cached",
        },
        "fresh_process_first_answer": {
            "wall_s": first_wall,
            "cpu_s": first_cpu,
            "what": "python -c: import straylight, SkyModel(), one pointing, tables cached",
        },
        "warm_single_call": single,
        "random_pairs": {
            "pairs": n,
            "wall_s": pairs_wall,
            "cpu_s": pairs_cpu,
            "samples_per_s": n / pairs_wall,
            "what": "uniform times over a day, uniform on the sky, all bands, one call",
        },
        "earthshine": table.meta["models"].get("earthshine", {}).get("method"),
    }
    print(
        f"SkyModel in this process: {build_wall:.1f} s wall, {build_cpu:.1f} CPU-s "
        "(tables built if not cached)"
    )
    print(f"fresh process, first answer: {first_wall:.2f} s wall ({first_cpu:.2f} CPU-s), tables cached")
    for label, rec in single.items():
        print(f"warm single call, {label}: median {rec['median_ms']:.1f} ms, p90 {rec['p90_ms']:.1f} ms")
    print(
        f"{n:,} random pairs in one call: {pairs_wall:.2f} s wall ({pairs_cpu:.2f} CPU-s) = "
        f"{n / pairs_wall:,.0f} samples/s; earthshine path: {result['earthshine']}"
    )
    write_results("api", result)
    return result


if __name__ == "__main__":
    main()
