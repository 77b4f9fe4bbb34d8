"""The cube's geometry compiled: the library's numba kernels against the numpy forms
they replaced, timed side by side on one core for one production region of the default
campaign (72 steps x 660 pixels, 47,520 samples), with their largest differences.

- the Earth limb (geometry.limb_geometry, _limb_kernel): the numpy form took nine
  transcendental calls per sample; the kernel takes the angle from nadir's arctangent and,
  only where the terminator crosses the limb, one arccos (the Sun's azimuth about nadir enters
  through its cosine and |sine|);
- the Sun's and the Moon's off-axis angle and azimuth (TelescopeFrame.theta_phi_runs_deg):
  the direction's components in the frame compiled (_frame_components_kernel, each sample's
  direction read from its time step instead of a gathered (bodies, samples, 3) array), the two
  arctangents in numpy.

numpy runs its transcendental functions vectorised (SIMD) where a compiled loop calls libm
one value at a time (on this machine numpy's arctan2 took 2.2 ns a value, the compiled loop's
21 ns), so compiling pays only where it removes calls or passes: this machine read the limb's
formulas compiled one for one 1.1x and the bodies' angles compiled on gathered directions
0.7-0.9x (earlier versions of this script); the limb 3.4-4.0x (fewer calls); the bodies'
angles with the arctangents in the compiled loop 1.3x, with them in numpy 4.3x.

Writes bench/results/compiled_geometry.json.

    python bench/compiled_geometry.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))
from _results import write_results  # noqa: E402
from knobs.common import timed  # noqa: E402  (its warm-up call is where numba compiles)


def best_seconds(fn) -> float:
    return timed(fn, repeats=7)[1]


def limb_numpy(r, los, sun, earth_radius_km):
    """geometry.limb_geometry as it was in numpy (ca4022e): (limb, zenith, lit, bright, dark)."""
    from straylight.sky.limb import _limb_scene
    from straylight.sky.runs import scene_runs
    from straylight.sky.vectors import dot, norm, perpendicular_towards, unit

    los = unit(los)
    runs = scene_runs(r, sun)
    scene = tuple(runs.expand(v) for v in _limb_scene(*runs.vectors, earth_radius_km))
    nadir, rho, tangent_len, cr, sr, a_term = scene[0], *scene[2:7]
    sin_gamma = norm(np.cross(los, nadir))
    gamma_deg = np.degrees(np.arctan2(sin_gamma, dot(los, nadir)))
    limb_angle = gamma_deg - np.degrees(rho)
    e1 = perpendicular_towards(nadir, np.where((sin_gamma > 1e-12)[..., None], los, sun))
    e2 = np.cross(nadir, e1)
    s1, s2 = dot(e1, sun), dot(e2, sun)
    b_term = tangent_len * sr * np.hypot(s1, s2)
    psi_sun = np.arctan2(s2, s1)
    lit = a_term + b_term * np.cos(psi_sun) > 0.0
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        c = np.where(b_term > 0, -a_term / np.where(b_term > 0, b_term, 1.0), np.sign(-a_term) * 2.0)
    half_width = np.arccos(np.clip(c, -1.0, 1.0))

    def wrapped(psi):
        return np.abs((psi + np.pi) % (2 * np.pi) - np.pi)

    psi_end = np.minimum(wrapped(psi_sun - half_width), wrapped(psi_sun + half_width))
    g = np.radians(gamma_deg)
    to_end = np.degrees(np.arccos(np.clip(cr * np.cos(g) + sr * np.sin(g) * np.cos(psi_end), -1.0, 1.0)))
    nearest = np.abs(limb_angle)
    bright = np.where(lit, nearest, np.where(c >= 1.0, 180.0, to_end))
    dark = np.where(~lit, nearest, np.where(c <= -1.0, 180.0, to_end))
    return limb_angle, 180.0 - gamma_deg, lit, bright, dark


def theta_phi_numpy(frame, d):
    """TelescopeFrame.theta_phi_deg as it was in numpy, on gathered directions d (B, N, 3)."""
    from straylight.sky.vectors import dot

    dx, dy, dz = dot(d, frame.x), dot(d, frame.y), dot(d, frame.z)
    theta = np.degrees(np.arctan2(np.hypot(dx, dy), dz))
    phi = np.degrees(np.arctan2(dy, dx))
    phi = np.where(phi < 0.0, phi + 360.0, phi)
    return theta, np.where(phi >= 360.0, 0.0, phi)


def main() -> int:
    from straylight.config import load_campaign
    from straylight.cube.footprint import footprint_from_config
    from straylight.cube.layout import cube_chunks
    from straylight.sky.frames import telescope_frame
    from straylight.sky.limb import limb_geometry
    from straylight.sky.observing import scene
    from straylight.sky.runs import scene_runs
    from straylight.sky.vectors import radec_to_unit, unit

    campaign = load_campaign()
    fp = footprint_from_config(campaign.settings.footprint)
    ch = cube_chunks(campaign, len(campaign.times), int(fp.pixels.size))
    nt, npix = int(ch["time"]), int(ch["pixel"])
    sc = scene(campaign.orbit, campaign.times[:nt])
    step = np.repeat(np.arange(nt), npix)
    sat, sun, moon = sc.satellite_km[step], sc.bodies_km["sun"][step], sc.bodies_km["moon"][step]
    los = np.tile(radec_to_unit(fp.ra_deg[:npix], fp.dec_deg[:npix]), (nt, 1))
    re_km = campaign.earth.radius_km
    n = los.shape[0]

    t_np = best_seconds(lambda: limb_numpy(sat, los, sun, re_km))
    t_nb = best_seconds(lambda: limb_geometry(sat, los, sun, re_km))
    ref = limb_numpy(sat, los, sun, re_km)
    lg = limb_geometry(sat, los, sun, re_km)
    got = (
        lg.earth_limb_angle_deg,
        lg.zenith_angle_deg,
        lg.limb_is_bright,
        lg.bright_limb_angle_deg,
        lg.dark_limb_angle_deg,
    )
    # the numpy form's bright-limb angle is the nearest sunlit limb point's; the kernel's, the
    # nearest sunlit point of the disc: the same where the LOS is off the disc and its nearest
    # limb point lit, never larger elsewhere
    same = np.asarray(lg.limb_is_bright) & (lg.earth_limb_angle_deg > 0)
    got = got[:3] + (np.where(same, got[3], ref[3]),) + got[4:]
    assert np.all(lg.bright_limb_angle_deg <= ref[3] + 1e-9)
    limb_diff = max(
        float(np.max(np.abs(np.asarray(a, float) - np.asarray(b, float)))) for a, b in zip(got, ref)
    )

    frame = telescope_frame(los, sun - sat)
    runs = scene_runs(sat, sun, moon)
    d_run = unit(np.stack(runs.vectors[1:]) - runs.vectors[0])
    tp_np = best_seconds(lambda: theta_phi_numpy(frame, d_run[:, runs.index]))
    tp_nb = best_seconds(lambda: frame.theta_phi_runs_deg(d_run, runs.index, (n,)))
    theta, phi = theta_phi_numpy(frame, d_run[:, runs.index])
    theta_c, phi_c = frame.theta_phi_runs_deg(d_run, runs.index, (n,))
    dphi = np.abs(phi_c - phi)
    tp_diff = max(float(np.max(np.abs(theta_c - theta))), float(np.max(np.minimum(dphi, 360.0 - dphi))))

    parts = {
        "limb_geometry": {
            "samples": n,
            "numpy_seconds": t_np,
            "numba_seconds": t_nb,
            "numba_ns_per_sample": t_nb / n * 1e9,
            "speedup": t_np / t_nb,
            "max_abs_difference_deg": limb_diff,
        },
        "bodies_theta_phi": {
            "samples": n,
            "bodies": 2,
            "numpy_seconds": tp_np,
            "numba_seconds": tp_nb,
            "numba_ns_per_body_sample": tp_nb / (2 * n) * 1e9,
            "speedup": tp_np / tp_nb,
            "max_abs_difference_deg": tp_diff,
        },
    }
    for name, v in parts.items():
        print(
            f"{name}: numpy {v['numpy_seconds'] * 1e3:.2f} ms, compiled {v['numba_seconds'] * 1e3:.2f} ms "
            f"({v['speedup']:.1f}x) for {n} samples; largest difference {v['max_abs_difference_deg']:.1e} deg"
        )
    import numba

    write_results("compiled_geometry", {"numba": numba.__version__, "numpy": np.__version__, **parts})
    return 0


if __name__ == "__main__":
    sys.exit(main())
