"""`straylight plan`'s wall-time estimate against the measured `straylight run`, wall to wall.

For each campaign size, in a fresh folder: the estimate `straylight plan` gives
(:func:`straylight.planning.plan.estimated_cost` scaled by
:func:`straylight.planning.plan.probed_speed_factor`, the probe measured anew), then
`straylight run --cores N` timed wall to wall with its CPU seconds (the run's processes), and
the load average before and after each.  ``--load K`` starts K busy loops (one process each)
for the whole measurement, so "load 2 on 2 cores" is reproducible; ``--cold`` points
STRAYLIGHT_CACHE at an empty folder, so the estimate includes the tables' build and the run
builds them (a fresh machine).  Printed and written to bench/results/estimates.json, one entry
per label and size, kept across runs.

Sizes: day16 (1 day, nside 16), days3 (3 days, nside 32), month32 (31 days, nside 32); all
from the default config otherwise.

Run:  python bench/estimates.py --sizes day16,days3,month32 --load 0
      python bench/estimates.py --sizes day16,days3 --load 2
      python bench/estimates.py --sizes day16 --cold
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import write_results  # noqa: E402

SIZES = {
    "day16": ("2026-01-01T00:00:00", "2026-01-02T00:00:00", 16),
    "days3": ("2026-01-01T00:00:00", "2026-01-04T00:00:00", 32),
    "month32": ("2026-01-01T00:00:00", "2026-02-01T00:00:00", 32),
}


def config_text(size: str) -> str:
    start, end, nside = SIZES[size]
    return f'campaign: {{name: {size}, start: "{start}", end: "{end}"}}\nfootprint: {{nside: {nside}}}\n'


def load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def _busy() -> None:  # one runnable process for the load generator
    while True:
        pass


def estimate(config: Path, cores: int) -> dict:
    """`plan`'s figures in a subprocess-free call (the same functions `straylight plan` calls)."""
    from straylight.config import load_campaign
    from straylight.cube.footprint import footprint_from_config
    from straylight.planning.plan import estimated_cost, probed_speed_factor
    from straylight.util.io import cache_dir

    (cache_dir() / "speed_probe.json").unlink(missing_ok=True)  # measured now, not reused
    campaign = load_campaign(config)
    fp = footprint_from_config(campaign.settings.footprint, campaign.path.parent)
    before = load()
    factor = probed_speed_factor(campaign, cores)
    probe = json.loads((cache_dir() / "speed_probe.json").read_text()).get(str(cores), {})
    cost = estimated_cost(campaign, fp, None, factor, cores)
    return {
        "estimate_wall_s": round(cost["wall_seconds"], 1),
        "fixed_s": round(cost["fixed_seconds"], 1),
        "samples_s": round(cost["samples_seconds"], 1),
        "table_build_s_one_core": round(cost["table_build_seconds"], 1),
        "samples": cost["samples"],
        "speed_factor": round(factor, 3),
        "probe": {k: probe.get(k) for k in ("wall_s", "scenes", "load")},
        "load_before": before,
        "load_after": load(),
    }


def run(config: Path, cores: int) -> dict:
    straylight = Path(sys.executable).with_name("straylight")
    with tempfile.TemporaryDirectory(prefix="estimates-") as tmp:
        before, c0 = load(), resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run(
            [str(straylight), "run", str(config), "--cores", str(cores)],
            cwd=tmp,
            check=True,
            stdout=subprocess.DEVNULL,
        )
        wall = time.perf_counter() - t0
        c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (c1.ru_utime - c0.ru_utime) + (c1.ru_stime - c0.ru_stime)
    return {"wall_s": round(wall, 1), "cpu_s": round(cpu, 1), "load_before": before, "load_after": load()}


def measure(size: str, cores: int, tmp: Path) -> dict:
    config = tmp / f"{size}.yaml"
    config.write_text(config_text(size))
    est = estimate(config, cores)
    measured = run(config, cores)
    ratio = est["estimate_wall_s"] / measured["wall_s"]
    entry = {"size": size, "cores": cores, "plan": est, "run": measured}
    return entry | {"estimate_over_actual": round(ratio, 3)}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="days3", help=f"comma-separated, of {', '.join(SIZES)}")
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--load", type=int, default=0, help="busy-loop processes beside the measurement")
    ap.add_argument("--cold", action="store_true", help="an empty table cache (the tables are built)")
    ap.add_argument("--label", default=None, help="name in the JSON (default: load<K>[-cold])")
    args = ap.parse_args(argv)
    sizes = [s for s in args.sizes.split(",") if s]
    unknown = [s for s in sizes if s not in SIZES]
    if unknown:
        ap.error(f"unknown size {unknown[0]!r}; choose from {', '.join(SIZES)}")
    label = args.label or f"load{args.load}" + ("-cold" if args.cold else "")
    path = Path(__file__).resolve().parent / "results" / "estimates.json"
    results = json.loads(path.read_text()) if path.exists() else {}
    busy = [mp.Process(target=_busy, daemon=True) for _ in range(args.load)]
    for p in busy:
        p.start()
    try:
        with tempfile.TemporaryDirectory(prefix="estimates-cfg-") as tmp:
            for size in sizes:
                if args.cold:
                    os.environ["STRAYLIGHT_CACHE"] = str(Path(tmp) / f"cache-{size}")
                entry = measure(size, args.cores, Path(tmp))
                entry.update(busy_loops=args.load, cold=args.cold, cpu_count=os.cpu_count())
                results.setdefault(label, {})[size] = entry
                est, got = entry["plan"], entry["run"]
                print(
                    f"{label} {size}: plan {est['estimate_wall_s']} s (x{est['speed_factor']}, "
                    f"tables {est['table_build_s_one_core']} core-s, load {est['load_before'][0]}), "
                    f"run {got['wall_s']} s wall, {got['cpu_s']} CPU-s (load {got['load_before'][0]} -> "
                    f"{got['load_after'][0]}): estimate / actual {entry['estimate_over_actual']:.2f}",
                    flush=True,
                )
                write_results("estimates", results)
    finally:
        for p in busy:
            p.terminate()
    return results


if __name__ == "__main__":
    main()
