"""Peak memory of :func:`straylight.sky_background` on many random (time, direction) pairs.

Each case runs in a fresh process under ``/usr/bin/time -v`` (its maximum resident set size):
the default SkyModel is built (tables from the cache) and warmed on 1000 pairs, then ``--pairs``
random pairs (times over a day, directions uniform on the sphere) are evaluated in one call.
Printed and written to bench/results/api_memory.json, per case: the process's peak RSS, its RSS
before the samples were made (imports, tables, a warm call), the returned table's size, and the
load average before and after.

Run:  python bench/api_memory.py              (2,000,000 pairs: band g, then all seven bands)
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import write_results  # noqa: E402

CHILD = """
import json, sys, time
import numpy as np
import astropy.units as u
from astropy.coordinates import SkyCoord
from astropy.time import Time
import straylight

def rss(key):
    for line in open("/proc/self/status"):
        if line.startswith(key + ":"):
            return int(line.split()[1]) * 1024

n, bands, dtype = int(sys.argv[1]), sys.argv[2].split(",") if sys.argv[2] != "all" else None, sys.argv[3]
sky = straylight.SkyModel()
t0 = Time("2026-01-01T00:00:00", scale="utc")
sky.background(t0 + np.arange(1000) * u.min, SkyCoord(150.0, 30.0, unit="deg"), bands=bands)
base = rss("VmHWM")
rng = np.random.default_rng(1)
t = t0 + rng.uniform(0, 86400, n) * u.s
c = SkyCoord(rng.uniform(0, 360, n), np.degrees(np.arcsin(rng.uniform(-1, 1, n))), unit="deg")
w = time.perf_counter()
table = sky.background(t, c, bands=bands, dtype=dtype)
wall = time.perf_counter() - w
size = sum(col.nbytes for col in table.itercols() if not hasattr(col, "jd1"))
size += table["time"].jd1.nbytes + table["time"].jd2.nbytes
print(json.dumps({"rss_before_bytes": base, "table_bytes": int(size), "rows": len(table),
                  "columns": len(table.colnames), "wall_s": wall}))
"""


def load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def run_case(n: int, bands: str, dtype: str) -> dict:
    before = load()
    proc = subprocess.run(
        ["/usr/bin/time", "-v", sys.executable, "-c", CHILD, str(n), bands, dtype],
        capture_output=True,
        text=True,
        check=True,
    )
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    peak = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", proc.stderr).group(1)) * 1024
    return {
        "pairs": n,
        "bands": bands,
        "dtype": dtype,
        "peak_rss_gb": round(peak / 1e9, 3),
        "rss_before_gb": round(out["rss_before_bytes"] / 1e9, 3),
        "table_gb": round(out["table_bytes"] / 1e9, 3),
        "beyond_table_and_before_gb": round((peak - out["rss_before_bytes"] - out["table_bytes"]) / 1e9, 3),
        "wall_s": round(out["wall_s"], 1),
        "load_before": before,
        "load_after": load(),
    }


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=2_000_000, help="random pairs in one call (default 2e6)")
    ap.add_argument("--cases", default="g:float64,all:float64,all:float32", help="bands:dtype,...")
    args = ap.parse_args(argv)
    cases = []
    for case in args.cases.split(","):
        bands, dtype = case.split(":")
        r = run_case(args.pairs, bands, dtype)
        print(
            f"{r['pairs']} pairs, bands {bands}, {dtype}: peak RSS {r['peak_rss_gb']} GB "
            f"(before the call {r['rss_before_gb']} GB, table {r['table_gb']} GB, "
            f"the rest {r['beyond_table_and_before_gb']} GB), {r['wall_s']} s, "
            f"load {r['load_before']} -> {r['load_after']}",
            flush=True,
        )
        cases.append(r)
    results = {"cases": cases, "cpu_count": os.cpu_count()}
    write_results("api_memory", results)
    return results


if __name__ == "__main__":
    main()
