"""The assumption envelope's members and ends (straylight.paper.envelope_members; docs/pst.md):
joint (tail, door reflectance, body radius) that keep the paper's median crossing within the
tolerance, ranked by their earthshine in the observable sky.

Usage::

    python scripts/envelope_members.py \\
        --hst-curve /work/shared/data/hst_sky/wfc3_earthshine_v_vs_limb_angle.csv \\
        --out docs/img/envelope_members.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--config", default=None, help="campaign config (default config/config.yaml)")
    p.add_argument(
        "--hst-curve", default=None, help="HST earthshine curve CSV (its value at 20 deg is the level)"
    )
    p.add_argument("--tolerance", type=float, default=5.0, help="tolerance on the median crossing, deg")
    p.add_argument("--doors", default="0.014,0.02,0.05", help="door reflectances, commas")
    p.add_argument("--bodies", default="1.0,1.5,2.1", help="body radii (m), commas")
    p.add_argument("--raan-step", type=float, default=60.0)
    p.add_argument("--u-step", type=float, default=10.0)
    p.add_argument("--nside", type=int, default=8)
    p.add_argument("--tails", default="-8.5,-9.25,-10.0,-10.75,-11.5")
    p.add_argument("--out", default="results/envelope_members.json")
    args = p.parse_args(argv)

    from straylight.config import load_campaign
    from straylight.errors import StraylightError
    from straylight.paper.envelope_members import envelope_members
    from straylight.paper.scenarios import HST_BRIGHT_LIMB_LIMIT_DEG, PhaseSampling, read_hst_curve

    try:
        campaign = load_campaign(args.config)
        cal = campaign.instrument_settings.pst.tail_calibration
        level, target = cal.hst_earthshine_v_mag_per_arcsec2.value, cal.crossing_limb_angle_deg.value
        if args.hst_curve:
            angle, mag = read_hst_curve(args.hst_curve)
            level = float(np.interp(HST_BRIGHT_LIMB_LIMIT_DEG, angle, mag))
        nums = lambda s: [float(x) for x in s.split(",")]  # noqa: E731
        doors, bodies, tails = nums(args.doors), nums(args.bodies), nums(args.tails)
    except (StraylightError, ValueError) as exc:
        print(f"envelope_members: {exc}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    sampling = PhaseSampling(args.raan_step, args.u_step, args.nside, tails)
    s = envelope_members(campaign, level, target, args.tolerance, doors, bodies, sampling)
    s["seconds"] = round(time.perf_counter() - t0, 1)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(s, indent=1) + "\n")
    for m in s["members"]:
        print(m)
    print("pessimistic:", s["pessimistic"])
    print("optimistic:", s["optimistic"])
    print(f"{out} ({s['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
