"""Benchmark: the star catalog's conversion speed, and the off-field star term's error against
cost as the magnitude limit of the directly summed stars varies (reference: every star, G <= 12).

At 400 random observable (time, pointing) samples of the default campaign, for each limit:
the largest star-term deficit relative to the total background, and the cost per sample (all
bands).  Prints the table and writes bench/results/stars.json.

Run:  OMP_NUM_THREADS=1 python bench/stars.py
"""
from __future__ import annotations

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
    from straylight.catalog import TemplatePhotometry, build_catalog, make_catalog, select_templates
    from straylight.components import ComponentModel, StarTable
    from straylight.config import load_campaign
    from straylight.hipparcos import hipparcos_stars
    from straylight.sed import load_pickles

    c = load_campaign()
    cm = ComponentModel(c)
    responses = {b: cm.band(b).response for b in c.bands}
    out = {}

    # conversion stage: template matching + magnitudes, per star (templates precomputed)
    tp = TemplatePhotometry(select_templates(load_pickles(), ("V", "IV", "III")), responses)
    hip = hipparcos_stars()
    reps = 5
    t0 = time.perf_counter()
    for _ in range(reps):
        build_catalog(hip, responses, photometry=tp)
    dt = (time.perf_counter() - t0) / reps
    out["conversion_stars_per_s_per_core"] = len(hip["ra"]) / dt
    print(f"conversion: {len(hip['ra'])} stars in {dt:.3f} s = {out['conversion_stars_per_s_per_core']:.3g} stars/s/core")

    cols, _ = make_catalog(responses)
    sc, los, g = random_samples(c, 4000, seed=5)
    obs = np.flatnonzero(g["observable"])[:400]
    sat, los = sc.satellite_km[obs], los[obs]
    bodies = {k: v[obs] for k, v in sc.bodies_km.items()}
    g = {k: v[obs] for k, v in g.items()}
    bands = list(c.bands)
    mags = np.array([cols[f"mag_{b}"] for b in bands])

    def run(limit):
        keep = np.any(mags <= limit, axis=0)
        m = np.where(mags <= limit, mags, np.inf)[:, keep]
        st = StarTable(cols["ra"][keep], cols["dec"][keep], {b: m[i] for i, b in enumerate(bands)})
        best = np.inf
        for _ in range(3):  # best of three
            t0 = time.perf_counter()
            res = cm.evaluate(sat, bodies, los, g, bands, st)
            best = min(best, time.perf_counter() - t0)
        return res, best, int(keep.sum())

    cm.evaluate(sat, bodies, los, g, bands)  # warm up: door tables and bands are built on first use
    base, t_base, _ = run(-99.0)  # no stars: the cost of everything else
    ref, t_ref, n_ref = run(99.0)
    rows = []
    for limit in (2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 99.0):
        res, dt, ns = run(limit)
        err = max(float(np.max((ref[b]["stars"] - res[b]["stars"]) / ref[b]["total"])) for b in bands)
        share = max(float(np.max(ref[b]["stars"] / ref[b]["total"])) for b in bands)
        rows.append({"mag_limit": limit, "stars": ns, "max_rel_error_of_total": err,
                     "star_cost_ms_per_sample": (dt - t_base) / len(obs) * 1e3})
        print(f"limit {limit:5.1f}: {ns:6d} stars, max error {err:.2e} of the total, "
              f"star term {(dt - t_base) / len(obs) * 1e3:.3f} ms/sample (rest {t_base / len(obs) * 1e3:.3f})")
    out["offfield_star_limit"] = rows
    out["max_star_share_of_total"] = share
    out["samples"] = int(len(obs))
    print(f"largest share of the total from all stars at these samples: {share:.2e}")
    write_results("stars", out)


if __name__ == "__main__":
    main()
