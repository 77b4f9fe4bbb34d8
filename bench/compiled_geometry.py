"""How much a compiled per-sample kernel would buy (issue #7): the cube's geometry, written
once in numpy (straylight.geometry, what runs) and once as a numba loop over samples of the
same formulas, timed side by side on one core for one cube batch (12 steps x 1320 pixels of
the default campaign, 15,840 samples).

Two parts, the largest of the geometry in the cube's line profile:
- the Earth limb (geometry.limb_geometry): ~12 transcendental calls per sample;
- the ten bodies' off-axis angle and azimuth in the telescope frame (TelescopeFrame.theta_phi_deg):
  an arctan2 for theta, one for phi, per body and sample.

numba has been a dependency of straylight since it compiled the table look-ups and the star
pairs (gridinterp, components).  These two kernels stay here, as measurements, not in the
library: on a machine whose numpy vectorises its transcendental functions (SIMD) they gain
little or lose (2026-11 development machine: limb 1.1x, bodies' angles 0.7x; an earlier one:
2.3-3.5x and 1.8-2.4x), and with the planets' angles computed only where they can count the
limb and the bodies' angles are ~6 % and ~4 % of a cube batch (py-spy, evaluate mode).
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
    def limb(r, los, sun, re, out):
        """geometry.limb_geometry's formulas, one sample at a time; out[:, 0..4] = limb angle,
        zenith angle, nearest limb point lit, bright and dark limb angles (deg)."""
        for i in range(r.shape[0]):
            rx, ry, rz = r[i, 0], r[i, 1], r[i, 2]
            lx, ly, lz = los[i, 0], los[i, 1], los[i, 2]
            sx, sy, sz = sun[i, 0], sun[i, 1], sun[i, 2]
            dist = math.sqrt(rx * rx + ry * ry + rz * rz)
            nx, ny, nz = -rx / dist, -ry / dist, -rz / dist
            rho = math.asin(re / dist)
            cx, cy, cz = ly * nz - lz * ny, lz * nx - lx * nz, lx * ny - ly * nx
            cn = math.sqrt(cx * cx + cy * cy + cz * cz)
            g = math.atan2(cn, lx * nx + ly * ny + lz * nz)
            limb_deg = math.degrees(g) - math.degrees(rho)
            tx, ty, tz = (lx, ly, lz) if cn > 1e-12 else (sx, sy, sz)
            tn = tx * nx + ty * ny + tz * nz
            px, py, pz = tx - tn * nx, ty - tn * ny, tz - tn * nz
            pn = math.sqrt(px * px + py * py + pz * pz)
            e1x, e1y, e1z = px / pn, py / pn, pz / pn
            e2x, e2y, e2z = ny * e1z - nz * e1y, nz * e1x - nx * e1z, nx * e1y - ny * e1x
            tl = math.sqrt(max(dist * dist - re * re, 0.0))
            cr, sr = math.cos(rho), math.sin(rho)
            a = rx * sx + ry * sy + rz * sz + tl * cr * (nx * sx + ny * sy + nz * sz) - re * re
            s1, s2 = e1x * sx + e1y * sy + e1z * sz, e2x * sx + e2y * sy + e2z * sz
            b = tl * sr * math.hypot(s1, s2)
            psi_s = math.atan2(s2, s1)
            lit = a + b * math.cos(psi_s) > 0.0
            c = -a / b if b > 0 else (2.0 if a < 0 else (-2.0 if a > 0 else 0.0))
            hw = math.acos(min(max(c, -1.0), 1.0))
            p1 = abs((psi_s - hw + math.pi) % (2 * math.pi) - math.pi)
            p2 = abs((psi_s + hw + math.pi) % (2 * math.pi) - math.pi)
            ca = cr * math.cos(g) + sr * math.sin(g) * math.cos(min(p1, p2))
            to_end = math.degrees(math.acos(min(max(ca, -1.0), 1.0)))
            nearest = abs(limb_deg)
            out[i, 0], out[i, 1], out[i, 2] = limb_deg, 180.0 - math.degrees(g), 1.0 if lit else 0.0
            if lit:
                out[i, 3], out[i, 4] = nearest, (180.0 if c <= -1.0 else to_end)
            else:
                out[i, 3], out[i, 4] = (180.0 if c >= 1.0 else to_end), nearest

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

    return limb, theta_phi


def main() -> int:
    try:
        import numba
    except ImportError:
        print("numba is not installed (a straylight dependency): pip install -e . first")
        return 0
    from straylight.config import load_campaign
    from straylight.footprint import footprint_from_config
    from straylight.geometry import limb_geometry, radec_to_unit, telescope_frame, unit
    from straylight.sky import scene

    campaign = load_campaign()
    fp = footprint_from_config(campaign.config["footprint"])
    times = campaign.times[0:24 * 12:24]
    sc = scene(campaign, times)
    npix = fp.pixels.size
    sat = np.repeat(sc.satellite_km, npix, axis=0)
    los = np.tile(radec_to_unit(fp.ra_deg, fp.dec_deg), (len(times), 1))
    sun = np.repeat(sc.bodies_km["sun"], npix, axis=0)
    re_km = campaign.earth.radius_km
    n = los.shape[0]
    limb_nb, theta_phi_nb = kernels()

    out_limb = np.empty((n, 5))
    t_np = best_seconds(lambda: limb_geometry(sat, los, sun, re_km))
    t_nb = best_seconds(lambda: limb_nb(sat, los, sun, re_km, out_limb))
    ref = limb_geometry(sat, los, sun, re_km)
    ref_cols = (ref.earth_limb_angle_deg, ref.zenith_angle_deg, ref.limb_is_bright.astype(float),
                ref.bright_limb_angle_deg, ref.dark_limb_angle_deg)
    limb_diff = max(float(np.max(np.abs(out_limb[:, j] - col))) for j, col in enumerate(ref_cols))

    frame = telescope_frame(los, sun - sat)
    d = np.stack([np.repeat(unit(sc.bodies_km[b] - sc.satellite_km), npix, axis=0) for b in sc.bodies_km])
    out_tp = np.empty(d.shape[:2] + (2,))
    x, y, z = (np.ascontiguousarray(a) for a in (frame.x, frame.y, frame.z))
    tp_np = best_seconds(lambda: frame.theta_phi_deg(d))
    tp_nb = best_seconds(lambda: theta_phi_nb(x, y, z, d, out_tp))
    theta, phi = frame.theta_phi_deg(d)
    dphi = np.abs(out_tp[..., 1] - phi)
    tp_diff = max(float(np.max(np.abs(out_tp[..., 0] - theta))), float(np.max(np.minimum(dphi, 360.0 - dphi))))

    parts = {"limb_geometry": {"samples": n, "numpy_seconds": t_np, "numba_seconds": t_nb,
                               "numba_ns_per_sample": t_nb / n * 1e9, "speedup": t_np / t_nb,
                               "max_abs_difference_deg": limb_diff},
             "bodies_theta_phi": {"samples": n, "bodies": int(d.shape[0]), "numpy_seconds": tp_np,
                                  "numba_seconds": tp_nb, "numba_ns_per_body_sample": tp_nb / d[..., 0].size * 1e9,
                                  "speedup": tp_np / tp_nb, "max_abs_difference_deg": tp_diff}}
    for name, v in parts.items():
        print(f"{name}: numpy {v['numpy_seconds'] * 1e3:.2f} ms, numba {v['numba_seconds'] * 1e3:.2f} ms "
              f"({v['speedup']:.1f}x) for {n} samples; largest difference {v['max_abs_difference_deg']:.1e} deg")
    write_results("compiled_geometry", {"numba": numba.__version__, "numpy": np.__version__, **parts})
    return 0


if __name__ == "__main__":
    sys.exit(main())
