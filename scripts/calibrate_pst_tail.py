"""Calibrate the default PST's large-angle tail over the satellite's sunlit orbital phases
(seed paper sect. 3.3; straylight.paper.tail_calibration).

Runs the paper's earthshine scenario (2026-01-01 00:50 UTC) at a grid of orbital phases (the
ascending node and the argument of latitude, the campaign's altitude and inclination), finds
the tail (log10 PST at 90 deg) at which the median crossing over the sunlit phases is the
paper's 70 deg, and prints the rule, the tail, the crossings' percentiles, each phase's own
tail's percentiles (the envelope's range) and the default orbit's phase's crossing.  Writes
the numbers to a JSON file and a figure beside it (crossing against the phase and the Sun's
zenith angle; earthshine against the limb angle per phase with HST's curve).

HST's level at 20 deg comes from the instrument's ``pst.tail_calibration``, or from
``--hst-curve`` (the WFC3 Instrument Handbook's fig. 9.2 digitised, CSV
``limb_angle_deg, v_mag_per_arcsec2``; not bundled) when given.

Usage::

    python scripts/calibrate_pst_tail.py \\
        --hst-curve /work/shared/data/hst_sky/wfc3_earthshine_v_vs_limb_angle.csv \\
        --out docs/img/pst_tail_calibration.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np


def _jsonable(v):
    """``v`` with arrays as lists and non-finite floats as strings ("inf", "nan"); keys
    starting with "_" (the arrays kept for figures) left out."""
    if isinstance(v, dict):
        return {str(k): _jsonable(x) for k, x in v.items() if not str(k).startswith("_")}
    if isinstance(v, (np.ndarray, list, tuple)):
        return [_jsonable(x) for x in np.asarray(v).tolist()]
    if isinstance(v, (float, np.floating)):
        return float(v) if np.isfinite(v) else str(float(v))
    if isinstance(v, np.integer):
        return int(v)
    return v


def _checks(s: dict, level: float, hst_curve) -> dict:
    """The independent checks of the earthshine's shape at the solution (none sets a parameter;
    straylight.paper.earthshine_checks)."""
    from straylight.paper.earthshine_checks import limb_profile, sect1_figures, shape_against_hst
    from straylight.paper.scenarios import read_hst_curve

    prof = limb_profile(s["_crossings"]["bins"], 0.0, 120.0)
    out = {
        "limb_profile": {k: v.tolist() for k, v in prof.items()},
        "sect1": sect1_figures(prof, s["crossing_deg"], level),
    }
    if hst_curve:
        out["hst_shape"] = shape_against_hst(prof, *read_hst_curve(hst_curve))
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--config", default=None, help="campaign config (default config/config.yaml)")
    p.add_argument(
        "--hst-curve", default=None, help="HST earthshine curve CSV (its value at 20 deg is the level)"
    )
    p.add_argument("--raan-step", type=float, default=45.0, help="ascending node step, deg")
    p.add_argument("--u-step", type=float, default=10.0, help="argument of latitude step, deg")
    p.add_argument("--nside", type=int, default=10, help="HEALPix resolution of the pointings")
    p.add_argument("--tails", default="-9.0,-9.75,-10.5", help="tails computed (log10 PST at 90 deg), commas")
    p.add_argument("--out", default="results/pst_tail_calibration.json", help="JSON; the PNG goes beside it")
    args = p.parse_args(argv)

    from straylight.config import load_campaign
    from straylight.errors import StraylightError
    from straylight.paper.scenarios import HST_BRIGHT_LIMB_LIMIT_DEG, PhaseSampling, read_hst_curve
    from straylight.paper.tail_calibration import calibrate_tail, default_phase_crossing
    from straylight.paper.tail_figure import plot_tail_calibration

    try:
        campaign = load_campaign(args.config)
        cal = campaign.instrument_settings.pst.tail_calibration
        level = cal.hst_earthshine_v_mag_per_arcsec2.value
        target = cal.crossing_limb_angle_deg.value
        if args.hst_curve:
            angle, mag = read_hst_curve(args.hst_curve)
            level = float(np.interp(HST_BRIGHT_LIMB_LIMIT_DEG, angle, mag))
        try:
            tails = [float(x) for x in args.tails.split(",")]
        except ValueError:
            raise ValueError(f"--tails: {args.tails!r} is not a comma-separated list of numbers") from None
    except (StraylightError, ValueError) as exc:
        print(f"calibrate_pst_tail: {exc}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    try:
        s = calibrate_tail(
            campaign, level, target, PhaseSampling(args.raan_step, args.u_step, args.nside, tails)
        )
    except StraylightError as exc:  # the tails do not bracket the target
        print(f"calibrate_pst_tail: {exc}", file=sys.stderr)
        return 2
    d = default_phase_crossing(campaign, level, s["tail_log10_at_90deg"], nside=args.nside)
    d_before = default_phase_crossing(
        campaign, level, campaign.instrument_settings.pst.tail_log10_at_90deg.value, nside=args.nside
    )
    s["default_phase"] = d
    s["default_phase_at_configured_tail"] = d_before
    s["configured_tail_log10_at_90deg"] = campaign.instrument_settings.pst.tail_log10_at_90deg.value
    s["checks"] = _checks(s, level, args.hst_curve)
    s["seconds"] = round(time.perf_counter() - t0, 1)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(_jsonable(s), indent=1) + "\n")
    plot_tail_calibration(s, out.with_suffix(".png"), args.hst_curve, d)
    pc, pt = s["crossing_percentiles_deg"], s["phase_tail_percentiles"]
    print(f"rule: {s['rule']}")
    print(
        f"phases: {s['n_phases']} (raan step {args.raan_step:g} deg x u step {args.u_step:g} deg), "
        f"{s['n_sunlit']} sunlit; pointings: HEALPix nside {args.nside}, |Dec| <= 75 deg; fewest per "
        f"10-deg bin below 90 deg: {s['min_pointings_per_bin']} (median {s['median_pointings_per_bin']:g})"
    )
    print(f"median crossing by tail: {s['median_crossing_by_tail']}")
    print(
        f"tail: log10 PST(90 deg) = {s['tail_log10_at_90deg']:.2f}; "
        f"median crossing {s['median_crossing_deg']:.1f} deg"
    )
    print(
        "crossings over sunlit phases (deg; inf: never): " + ", ".join(f"{k} {v:.1f}" for k, v in pc.items())
    )
    print(
        f"phases that never cross: {s['never_crossing']} of {s['n_sunlit']}; "
        f"latest crossing (a figure, sets nothing): {s['latest_crossing_deg']:.1f} deg"
    )
    print(f"checks (set nothing): {json.dumps(_jsonable(s['checks']))}")
    for name, v in s["variants"].items():
        print(
            f"variant {name}: median crossing {v['median_crossing_deg']:.1f} deg, "
            f"never {v['never_crossing']}; "
            + ", ".join(f"{k} {x:.1f}" for k, x in v["crossing_percentiles_deg"].items())
        )
    print("each phase's own tail (dex): " + ", ".join(f"{k} {v:.2f}" for k, v in pt.items()))
    print(
        f"default orbit's phase (raan {d['raan_deg']:.1f}, u {d['arg_latitude_deg']:.1f} deg, Sun zenith "
        f"{d['sun_zenith_deg']:.1f} deg): crossing {d['crossing_deg']:.1f} deg at the new tail, "
        f"{d_before['crossing_deg']:.1f} deg at the configured {s['configured_tail_log10_at_90deg']:.2f}"
    )
    print(f"{out}, {out.with_suffix('.png')} ({s['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
