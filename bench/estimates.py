"""`straylight plan`'s wall-time estimate against the measured `straylight run`, tables cached.

For a campaign config (default: 3 days at nside 32 from the default config), in a fresh folder:
the estimate `straylight plan` prints (:func:`straylight.planning.plan.estimated_cost` scaled by
:func:`straylight.planning.plan.probed_speed_factor`, the probe measured anew), then
`straylight run --cores N` timed wall to wall with its CPU seconds (the run's processes), and
the load average before and after each.  Printed and written to bench/results/estimates.json
(one entry per ``--label``, kept across runs: e.g. ``--label load0`` on an idle machine and
``--label load2`` with two busy loops beside it).

Run:  python bench/estimates.py --label load0
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import write_results  # noqa: E402

DAYS3 = (
    'campaign: {name: days3, start: "2026-01-01T00:00:00", end: "2026-01-04T00:00:00"}\n'
    "footprint: {nside: 32}\n"
)


def load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def estimate(config: Path, cores: int) -> dict:
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
        subprocess.run([str(straylight), "run", str(config), "--cores", str(cores)], cwd=tmp, check=True)
        wall = time.perf_counter() - t0
        c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (c1.ru_utime - c0.ru_utime) + (c1.ru_stime - c0.ru_stime)
    return {"wall_s": round(wall, 1), "cpu_s": round(cpu, 1), "load_before": before, "load_after": load()}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", type=Path, default=None, help="campaign config (default: 3 days, nside 32)")
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--label", default="run", help="name of this measurement in the JSON")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="estimates-cfg-") as tmp:
        config = args.config.resolve() if args.config else Path(tmp) / "days3.yaml"
        if args.config is None:
            config.write_text(DAYS3)
        est = estimate(config, args.cores)
        measured = run(config, args.cores)
    ratio = est["estimate_wall_s"] / measured["wall_s"]
    entry = {"config": str(args.config or "3 days at nside 32"), "cores": args.cores, "plan": est}
    entry.update(run=measured, estimate_over_actual=round(ratio, 3), cpu_count=os.cpu_count())
    print(
        f"{args.label}: plan {est['estimate_wall_s']} s (x{est['speed_factor']}, load {est['load_before']}), "
        f"run {measured['wall_s']} s wall, {measured['cpu_s']} CPU-s (load {measured['load_before']} -> "
        f"{measured['load_after']}): estimate / actual {ratio:.2f}"
    )
    path = Path(__file__).resolve().parent / "results" / "estimates.json"
    results = json.loads(path.read_text()) if path.exists() else {}
    results[args.label] = entry
    write_results("estimates", results)
    return results


if __name__ == "__main__":
    main()
