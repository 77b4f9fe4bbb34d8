"""Benchmark: cost per (time, pointing) sample of the off-field terms, and the earthshine
error against cost as the Earth-grid knob varies (reference: 96 x 192 blocks).

Prints the figures and writes bench/results/offfield.json.  Run:  OMP_NUM_THREADS=1 python bench/offfield.py
"""

from __future__ import annotations

import copy
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import write_results  # noqa: E402
from _samples import random_samples  # noqa: E402


def main():
    from straylight.config import load_campaign
    from straylight.model import BackgroundModel
    from straylight.sky.frames import telescope_frame
    from straylight.sources.earthshine.grid import EarthshineSettings
    from straylight.sources.photometry import BandPhotometry

    c = load_campaign()
    cm = BackgroundModel(c)
    n = 400
    sc, los, g = random_samples(c, n, seed=11)
    cm.evaluate(
        sc.satellite_km[:2],
        {k: v[:2] for k, v in sc.bodies_km.items()},
        los[:2],
        {k: v[:2] for k, v in g.items()},
        ["g"],
    )  # warm up (door tables)
    t0 = time.perf_counter()
    out = cm.evaluate(sc.satellite_km, sc.bodies_km, los, g, ["g"])
    t_all = time.perf_counter() - t0
    off = cm.earth_grid
    frame = telescope_frame(los, sc.bodies_km["sun"] - sc.satellite_km)
    phot = BandPhotometry(cm.context.band("g"))
    sun_irr = np.full(n, phot.sun_at_1au_photons_s_m2)
    moon_irr = sun_irr * 10 ** (-0.4 * 14.0)
    results = {"samples": n, "band": "g", "all_terms_s_per_sample_one_band": t_all / n, "earthshine": {}}
    t0 = time.perf_counter()
    off.transfer.point_source(
        sun_irr, g["sun_angle_deg"], g["sun_phi_deg"], g["sun_earth_blocked"], g["door_opening_deg"]
    )
    results["point_source_s_per_sample"] = (time.perf_counter() - t0) / n

    def earthshine(ng, npsi):
        o = copy.copy(off)
        o.earthshine = EarthshineSettings(n_gamma=ng, n_psi=npsi)
        o.__dict__.pop("_door_weights", None)
        t = time.perf_counter()
        a, b = o.earthshine_terms(
            sc.satellite_km,
            sc.bodies_km["sun"],
            sc.bodies_km["moon"],
            frame,
            g["door_opening_deg"],
            sun_irr,
            moon_irr,
            c.earth.radius_km,
        )
        return a + b, (time.perf_counter() - t) / n

    ref, t_ref = earthshine(96, 192)
    results["earthshine"]["reference_96x192_s_per_sample"] = t_ref
    zodi = out["g"]["zodiacal"]
    limb = g["earth_limb_angle_deg"]
    for ng, npsi in ((6, 12), (12, 24), (24, 48), (48, 96)):
        val, t = earthshine(ng, npsi)
        rel = np.abs(val - ref) / np.maximum(ref, 1e-300)
        rel_bg = np.abs(val - ref) / (ref + zodi)  # error as a fraction of earthshine + zodiacal light
        row = {"s_per_sample": t}
        for label, sel in (
            ("all", np.ones(n, bool)),
            ("limb_gt_10deg", limb > 10),
            ("limb_gt_30deg", limb > 30),
            ("observable", g["observable"]),
        ):
            if sel.any():
                row[label] = {
                    "max_rel_error": float(rel[sel].max()),
                    "median_rel_error": float(np.median(rel[sel])),
                    "max_error_over_background": float(rel_bg[sel].max()),
                    "n": int(sel.sum()),
                }
        results["earthshine"][f"{ng}x{npsi}"] = row
        print(
            f"earthshine grid {ng:3d} x {npsi:3d}: {t * 1e3:6.2f} ms/sample; "
            f"median rel error {row['all']['median_rel_error']:.1e}; "
            f"max error / (earthshine + zodiacal): all {row['all']['max_error_over_background']:.1e}, "
            f"limb>10 {row['limb_gt_10deg']['max_error_over_background']:.1e}, "
            f"limb>30 {row['limb_gt_30deg']['max_error_over_background']:.1e}"
            + (
                f", observable {row['observable']['max_error_over_background']:.1e}"
                if "observable" in row
                else ""
            )
        )
    print(
        f"reference 96 x 192: {t_ref * 1e3:.2f} ms/sample; "
        f"point source: {results['point_source_s_per_sample'] * 1e6:.1f} us/sample; "
        f"all terms, one band: {t_all / n * 1e3:.2f} ms/sample"
    )
    write_results("offfield", results)


if __name__ == "__main__":
    main()
