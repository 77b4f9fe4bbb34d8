"""Benchmark: full CSST detector (9216 x 9232) stray-light image with ~1000 stars, one core.

Prints the render time for each far-field binning and the error of the binned far field against
the exact (far_bin = 1) reference measured on a 1024 x 1024 cut-out; writes
bench/results/image.json.  Run:  OMP_NUM_THREADS=1 python bench/image.py
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


def main():
    from straylight.config import load_campaign
    from straylight.image.detector import Aim, DetectorOptics, RenderSettings, Stars, render_detector
    from straylight.image.focal_plane import FocalPlane, focal_plane_from_instrument, pointing_wcs
    from straylight.optics.ghosts import ghost_model_from_instrument
    from straylight.optics.scatter import scatter_model_from_instrument

    c = load_campaign()
    fp = focal_plane_from_instrument(c.instrument_settings)
    sc = scatter_model_from_instrument(c.instrument_settings)
    gh = ghost_model_from_instrument(c.instrument_settings, "g")
    sun = np.array([1.0, 0.0, 0.0])
    rng = np.random.default_rng(7)
    w = pointing_wcs(150.0, 30.0, sun, fp, 12)
    n_stars = 1000
    # stars over the detector and 1000 px around it (stars just off the chip scatter onto it)
    xs = rng.uniform(-1000, fp.nx + 1000, n_stars)
    ys = rng.uniform(-1000, fp.ny + 1000, n_stars)
    ra, dec = w.pixel_to_world_values(xs, ys)
    flux = 10 ** rng.uniform(3, 8, n_stars)  # e-/s: G ~ 7-19 in g
    results = {"detector_px": [fp.ny, fp.nx], "n_stars": n_stars, "full_detector": {}, "cutout_error": {}}
    aim = Aim(150.0, 30.0, sun, 12)
    for rn, b in ((128, 16), (128, 8), (64, 8)):
        t0 = time.perf_counter()
        r = render_detector(
            aim,
            Stars(ra, dec, flux),
            DetectorOptics(fp, sc, gh, 3.9),
            RenderSettings(far_bin=b, near_radius_px=rn),
        )
        dt = time.perf_counter() - t0
        results["full_detector"][f"near_{rn}_far_bin_{b}_s"] = dt
        print(f"full detector, near {rn} px, far_bin {b:2d}: {dt:6.1f} s, {len(r.stars['x_pix'])} stars used")
        del r
    # accuracy of the binned far field: 1024 x 1024 cut-out, exact reference far_bin = 1
    n = 1024
    fps = FocalPlane(n, n, fp.pixel_scale_arcsec, fp.pixel_size_mm, fp.columns, fp.rows, fp.gap_px)
    ws = pointing_wcs(150.0, 30.0, sun, fps, 12)
    xs2, ys2 = rng.uniform(-300, n + 300, 50), rng.uniform(-300, n + 300, 50)
    ra2, dec2 = ws.pixel_to_world_values(xs2, ys2)
    f2 = 10 ** rng.uniform(3, 8, 50)
    kw = dict(size_override=(n, n))
    for rn in (64, 128):
        ref = render_detector(
            aim,
            Stars(ra2, dec2, f2),
            DetectorOptics(fp, sc, None, 3.9),
            RenderSettings(far_bin=1, near_radius_px=rn, margin_arcsec=40.0),
            **kw,
        ).image_e_per_s_per_pix.astype(float)
        for b in (16, 8, 4, 2):
            t0 = time.perf_counter()
            im = render_detector(
                aim,
                Stars(ra2, dec2, f2),
                DetectorOptics(fp, sc, None, 3.9),
                RenderSettings(far_bin=b, near_radius_px=rn, margin_arcsec=40.0),
                **kw,
            ).image_e_per_s_per_pix.astype(float)
            dt = time.perf_counter() - t0
            rel = np.abs(im - ref) / ref
            results["cutout_error"][f"near_{rn}_far_bin_{b}"] = {
                "max_rel_error": float(rel.max()),
                "p99_rel_error": float(np.percentile(rel, 99)),
                "time_s": dt,
            }
            print(
                f"cut-out near {rn:3d} px far_bin {b:2d}: max rel error {rel.max():.2e}, "
                f"99th pct {np.percentile(rel, 99):.2e}, {dt:.2f} s"
            )
    write_results("image", results)


if __name__ == "__main__":
    main()
