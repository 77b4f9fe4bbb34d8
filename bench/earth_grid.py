"""The default Earth grid against the converged one, over observable samples spread across a year.

Random times uniform over the year from the default campaign's start, random lines of sight
uniform on the sky, the first ``--samples`` observable ones; the background model with the
earthshine summed directly (``models.earthshine.method: direct``) on the configured Earth grid
and on a 96 x 192 grid (everything else the default), no stars (so the totals are a little
lower than the products' and the fractions a little larger).  Per band: the largest and the
99th-percentile |total(grid) - total(96 x 192)| / total(96 x 192), and the samples where the
aperture plane cuts the cap (the earthshine's worst case).

Writes bench/results/earth_grid.json.

    python bench/earth_grid.py [--samples 520] [--grid 24 48] [--chunk 20]
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))
from _results import write_results  # noqa: E402

REFERENCE_GRID = (96, 192)


def year_samples(campaign, n: int, seed: int = 20261127):
    """``n`` observable (time, line of sight) samples, times uniform over a year."""
    import astropy.units as u
    from astropy.time import Time

    from straylight.sky.geometry import observing_geometry
    from straylight.sky.observing import scene
    from straylight.sky.vectors import radec_to_unit

    rng = np.random.default_rng(seed)
    m = 12 * n
    start = Time(campaign.settings.campaign.start, scale="utc")
    sc = scene(campaign.orbit, start + np.sort(rng.uniform(0.0, 365.25, m)) * u.day)
    los = radec_to_unit(rng.uniform(0, 360, m), np.degrees(np.arcsin(rng.uniform(-1, 1, m))))
    g = observing_geometry(sc.satellite_km, sc.bodies_km, los, campaign.earth.radius_km, campaign.constraints)
    obs = np.flatnonzero(g["observable"])[:n]
    return (
        sc.satellite_km[obs],
        {k: v[obs] for k, v in sc.bodies_km.items()},
        los[obs],
        {k: v[obs] for k, v in g.items()},
        sc.times[obs],
    )


def model_with_grid(campaign, grid, split=None, tail=None):
    from straylight.config import campaign_from_dict
    from straylight.model import BackgroundModel

    raw = campaign.config_mapping()
    raw["models"]["earthshine"]["method"] = "direct"
    cm = BackgroundModel(campaign_from_dict(raw, campaign.path))
    off = cm.earth_grid
    es = off.earthshine
    if grid is not None:
        es = replace(es, n_gamma=int(grid[0]), n_psi=int(grid[1]))
    if split is not None:
        es = replace(es, cut_block_split=int(split))
    pst = off.pst
    if tail is not None:  # the embedded PST with this tail (log10 at 90 deg)
        from straylight.optics.pst import load_pst

        pst = load_pst(None, off.field_radius_deg, float(tail))
    transfer = replace(off.transfer, pst=pst)
    cm.context.__dict__["offfield"] = transfer  # before any source reads them
    cm.source("sunlit_earth").engine.__dict__["grid"] = replace(off, transfer=transfer, earthshine=es)
    return cm


def totals(cm, sat, bodies, los, g, bands, chunk):
    out = {b: [] for b in bands}
    for lo in range(0, len(los), chunk):
        sl = slice(lo, lo + chunk)
        r = cm.evaluate(
            sat[sl], {k: v[sl] for k, v in bodies.items()}, los[sl], {k: v[sl] for k, v in g.items()}, bands
        )
        for b in bands:
            out[b].append(np.asarray(r[b]["total"], float))
    return {b: np.concatenate(v) for b, v in out.items()}


def errors(got, ref, bands, g, times):
    """Per band and worst over bands: max, p99 and median of |got - ref| / ref, and the worst
    sample's geometry."""
    out = {"bands": {}}
    worst = np.zeros(len(times))
    for b in bands:
        rel = np.abs(got[b] - ref[b]) / ref[b]
        worst = np.maximum(worst, rel)
        out["bands"][b] = {
            "max": float(rel.max()),
            "p99": float(np.percentile(rel, 99)),
            "median": float(np.median(rel)),
        }
    i = int(np.argmax(worst))
    out["worst"] = {
        "max": float(worst.max()),
        "p99": float(np.percentile(worst, 99)),
        "sample": {
            "time": times[i].isot,
            "earth_limb_angle_deg": float(g["earth_limb_angle_deg"][i]),
            "bright_limb_angle_deg": float(g["bright_limb_angle_deg"][i]),
            "sun_angle_deg": float(g["sun_angle_deg"][i]),
            "door_opening_deg": float(g["door_opening_deg"][i]),
        },
    }
    return out


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--samples", type=int, default=520)
    ap.add_argument("--grid", type=int, nargs=2, default=None, help="n_gamma n_psi (default: the config's)")
    ap.add_argument(
        "--split", type=int, nargs="+", default=[None], help="cut_block_split values (default: the config's)"
    )
    ap.add_argument("--reference-split", type=int, default=1, help="cut_block_split of the reference")
    ap.add_argument(
        "--pst-tail", type=float, default=None, help="log10 PST at 90 deg (default: the instrument's)"
    )
    ap.add_argument("--chunk", type=int, default=20)
    a = ap.parse_args()

    from straylight.config import load_campaign

    campaign = load_campaign()
    bands = list(campaign.bands)
    sat, bodies, los, g, times = year_samples(campaign, a.samples)
    ref_cm = model_with_grid(campaign, REFERENCE_GRID, a.reference_split, a.pst_tail)
    t0 = time.perf_counter()
    ref = totals(ref_cm, sat, bodies, los, g, bands, a.chunk)
    out = {
        "samples": int(len(los)),
        "months_covered": int(np.unique(np.floor((times.mjd - times.mjd.min()) / 30.44)).size),
        "pst_tail_log10_at_90deg": float(
            a.pst_tail
            if a.pst_tail is not None
            else campaign.instrument_settings.pst.tail_log10_at_90deg.value
        ),
        "reference_grid": list(REFERENCE_GRID),
        "reference_cut_block_split": a.reference_split,
        "reference_seconds": time.perf_counter() - t0,
        "runs": [],
    }
    for split in a.split:
        cm = model_with_grid(campaign, a.grid, split, a.pst_tail)
        t0 = time.perf_counter()
        got = totals(cm, sat, bodies, los, g, bands, a.chunk)
        es = cm.earth_grid.earthshine
        run = {
            "grid": [es.n_gamma, es.n_psi],
            "cut_block_split": es.cut_block_split,
            "seconds": time.perf_counter() - t0,
        }
        run.update(errors(got, ref, bands, g, times))
        out["runs"].append(run)
        print(run, flush=True)
    out["loadavg"] = Path("/proc/loadavg").read_text().split()[:3]
    write_results(f"earth_grid_tail{out['pst_tail_log10_at_90deg']:g}", out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
