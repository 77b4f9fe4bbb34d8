"""How much a compiled per-sample kernel would buy (issue #7): the ten bodies' off-axis angle
and azimuth in the telescope frame (TelescopeFrame.theta_phi_deg: an arctan2 for theta, one for
phi, per body and sample), written once in numpy (what runs) and once as a numba loop over
samples of the same formulas, timed side by side on one core for one cube batch (12 steps x
1320 pixels of the default campaign, 15,840 samples).

It stays here, as a measurement, not in the library: on a machine whose numpy vectorises its
transcendental functions (SIMD) it loses (2026-11 development machine: 0.7-0.8x; an earlier
one: 1.8-2.4x).  The Earth limb was measured here too (the same formulas compiled: 1.1x on
that machine); it is now compiled in the library (geometry._limb_kernel) with two
transcendental calls per sample instead of nine (the Sun's azimuth about nadir enters only
through its cosine and |sine|), 3.1 -> 1.4 ms per batch.  numba pays where the work is gathers,
branches or many numpy passes per transcendental call, not where it is the calls themselves.
Writes bench/results/compiled_geometry.json.

    python bench/compiled_geometry.py
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))
from _results import write_results  # noqa: E402
from run import timed  # noqa: E402  (its warm-up call is where numba compiles)


def best_seconds(fn) -> float:
    return timed(fn, repeats=7)[1]


def kernels():
    import numba

    @numba.njit(cache=False)
    def theta_phi(x, y, z, d, out):
        """TelescopeFrame.theta_phi_deg for bodies d (B, N, 3) in frames (N, 3): out (B, N, 2)."""
        for k in range(d.shape[0]):
            for i in range(d.shape[1]):
                dx = d[k, i, 0] * x[i, 0] + d[k, i, 1] * x[i, 1] + d[k, i, 2] * x[i, 2]
                dy = d[k, i, 0] * y[i, 0] + d[k, i, 1] * y[i, 1] + d[k, i, 2] * y[i, 2]
                dz = d[k, i, 0] * z[i, 0] + d[k, i, 1] * z[i, 1] + d[k, i, 2] * z[i, 2]
                phi = math.degrees(math.atan2(dy, dx))
                phi = phi + 360.0 if phi < 0.0 else phi
                out[k, i, 0] = math.degrees(math.atan2(math.hypot(dx, dy), dz))
                out[k, i, 1] = 0.0 if phi >= 360.0 else phi

    return theta_phi


def main() -> int:
    try:
        import numba
    except ImportError:
        print("numba is not installed (a straylight dependency): pip install -e . first")
        return 0
    from straylight.config import load_campaign
    from straylight.footprint import footprint_from_config
    from straylight.geometry import radec_to_unit, telescope_frame, unit
    from straylight.sky import scene

    campaign = load_campaign()
    fp = footprint_from_config(campaign.config["footprint"])
    times = campaign.times[0:24 * 12:24]
    sc = scene(campaign, times)
    npix = fp.pixels.size
    sat = np.repeat(sc.satellite_km, npix, axis=0)
    los = np.tile(radec_to_unit(fp.ra_deg, fp.dec_deg), (len(times), 1))
    sun = np.repeat(sc.bodies_km["sun"], npix, axis=0)
    n = los.shape[0]
    theta_phi_nb = kernels()

    frame = telescope_frame(los, sun - sat)
    d = np.stack([np.repeat(unit(sc.bodies_km[b] - sc.satellite_km), npix, axis=0) for b in sc.bodies_km])
    out_tp = np.empty(d.shape[:2] + (2,))
    x, y, z = (np.ascontiguousarray(a) for a in (frame.x, frame.y, frame.z))
    tp_np = best_seconds(lambda: frame.theta_phi_deg(d))
    tp_nb = best_seconds(lambda: theta_phi_nb(x, y, z, d, out_tp))
    theta, phi = frame.theta_phi_deg(d)
    dphi = np.abs(out_tp[..., 1] - phi)
    tp_diff = max(float(np.max(np.abs(out_tp[..., 0] - theta))), float(np.max(np.minimum(dphi, 360.0 - dphi))))

    parts = {"bodies_theta_phi": {"samples": n, "bodies": int(d.shape[0]), "numpy_seconds": tp_np,
                                  "numba_seconds": tp_nb, "numba_ns_per_body_sample": tp_nb / d[..., 0].size * 1e9,
                                  "speedup": tp_np / tp_nb, "max_abs_difference_deg": tp_diff}}
    for name, v in parts.items():
        print(f"{name}: numpy {v['numpy_seconds'] * 1e3:.2f} ms, numba {v['numba_seconds'] * 1e3:.2f} ms "
              f"({v['speedup']:.1f}x) for {n} samples; largest difference {v['max_abs_difference_deg']:.1e} deg")
    write_results("compiled_geometry", {"numba": numba.__version__, "numpy": np.__version__, **parts})
    return 0


if __name__ == "__main__":
    sys.exit(main())
