"""The bright limb's definition and the limb's height against observability.

The observable fraction (``observing_geometry``'s ``observable``: every avoidance angle met and
the door allowed) over the footprint's pixels and the campaign's times, for

- ``limb_point``: the bright-limb angle to the nearest sunlit point of the limb, solid Earth
  (the definition before; ``straylight/sky/limb.py`` of a git revision, ``--before``);
- ``disc_h<H>``: the angle to the nearest sunlit point of the Earth's disc, the limb at H km
  (0, 50, 100; ``avoidance.limb_height_km``),

for the default day and a month (30 days from the default start, 5-min cadence) at nside 32,
and random times over a year (every pixel at each).  Also: the largest amount by which the
nearest sunlit point of the disc is closer than the nearest sunlit limb point.

Writes bench/results/bright_limb.json.

    python bench/bright_limb.py [--before REV] [--nside 32] [--days 30] [--year-times 2000]
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))
from _results import write_results  # noqa: E402

HEIGHTS_KM = (0.0, 50.0, 100.0)


def old_limb_module(rev: str):
    """``straylight/sky/limb.py`` as it was at git revision ``rev``, imported on its own."""
    text = subprocess.run(
        ["git", "-C", str(ROOT), "show", f"{rev}:straylight/sky/limb.py"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    path = Path(tempfile.mkdtemp()) / "limb_before.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location("limb_before", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def fractions(sc, los, re_km, constraints, old):
    """Observable samples (count) per variant, and the disc-vs-limb gap (deg), over the scene's
    times (one day at a time) against every line of sight."""
    from straylight.sky.geometry import observing_geometry

    counts = {"limb_point": 0, **{f"disc_h{h:g}": 0 for h in HEIGHTS_KM}}
    gap_max, n = 0.0, 0
    for lo in range(0, len(sc.times), 288):
        sl = slice(lo, lo + 288)
        sat = sc.satellite_km[sl, None, :]
        bodies = {k: v[sl, None, :] for k, v in sc.bodies_km.items()}
        for h in HEIGHTS_KM:
            k = dataclasses.replace(constraints, limb_height_km=h)
            g = observing_geometry(sat, bodies, los[None], re_km, k)
            counts[f"disc_h{h:g}"] += int(g["observable"].sum())
            if h == 0.0:
                base = g
        n += base["observable"].size
        lg = old.limb_geometry(sat, los[None], bodies["sun"], re_km)
        flags = constraints.violations(
            base["sun_angle_deg"],
            base["moon_angle_deg"],
            lg.bright_limb_angle_deg,
            lg.dark_limb_angle_deg,
            lg.earth_limb_angle_deg,
        )
        counts["limb_point"] += int(((flags == 0) & (base["door_opening_deg"] > 0)).sum())
        above = base["earth_limb_angle_deg"] > 0
        gap = np.where(above, lg.bright_limb_angle_deg - base["bright_limb_angle_deg"], 0.0)
        gap_max = max(gap_max, float(np.max(np.where(lg.bright_limb_angle_deg < 180.0, gap, 0.0))))
    return {k: v / n for k, v in counts.items()}, n, gap_max


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--before", default="HEAD", help="git revision of the limb-point definition")
    ap.add_argument("--nside", type=int, default=32)
    ap.add_argument("--days", type=float, default=30.0)
    ap.add_argument("--year-times", type=int, default=2000)
    a = ap.parse_args()

    from astropy.time import Time

    from straylight.config import load_campaign
    from straylight.cube.footprint import footprint_from_config
    from straylight.sky.observing import scene
    from straylight.sky.vectors import radec_to_unit

    old = old_limb_module(a.before)
    campaign = load_campaign()
    fp = footprint_from_config({**campaign.config_mapping()["footprint"], "nside": a.nside})
    los = radec_to_unit(fp.ra_deg, fp.dec_deg)
    re_km, k = campaign.earth.radius_km, campaign.constraints
    start = Time(campaign.settings.campaign.start, scale="utc")
    out = {
        "nside": a.nside,
        "pixels": int(los.shape[0]),
        "before": a.before,
        "limb_height_km_default": k.limb_height_km,
    }
    runs = {
        "day": start + np.arange(288) * 300.0 / 86400.0,
        "month": start + np.arange(int(a.days * 288)) * 300.0 / 86400.0,
        "year_random": start + np.sort(np.random.default_rng(20261127).uniform(0.0, 365.25, a.year_times)),
    }
    for name, times in runs.items():
        t0 = time.perf_counter()
        sc = scene(campaign.orbit, times)
        frac, n, gap = fractions(sc, los, re_km, k, old)
        out[name] = {
            "times": len(times),
            "samples": n,
            "observable_fraction": frac,
            "max_disc_closer_deg": gap,
            "seconds": time.perf_counter() - t0,
        }
        print(name, out[name], flush=True)
    out["loadavg"] = Path("/proc/loadavg").read_text().split()[:3]
    write_results("bright_limb", out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
