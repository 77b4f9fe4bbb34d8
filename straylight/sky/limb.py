"""The Earth seen from the satellite: its limb and what it hides, vectorised over samples.

Conventions (the paper, sections 2.3 and 3.1):

* Earth limb angle: angle of the line of sight (LOS) above the Earth's limb as seen from the
  satellite, negative when the LOS hits the Earth (spherical Earth of radius ``earth_radius_km``).
* Earth blockage of a source (paper, section 3.1): blocked when both (1) the angle between the
  source direction and the satellite's position vector exceeds 90 deg and (2) the ray from the
  satellite towards the source passes closer than one Earth radius to the Earth's centre.

Vectors are Cartesian, GCRS/ICRS axes, last axis of length 3, broadcast over the leading axes
(:mod:`straylight.sky.vectors`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from straylight.errors import InputError
from straylight.sky.runs import SceneRuns, scene_rows
from straylight.sky.vectors import any_perpendicular_xyz, dot, norm, unit, unit_xyz

__all__ = ["LimbGeometry", "earth_blocks", "limb_geometry"]


def earth_blocks(satellite_km: np.ndarray, direction: np.ndarray, earth_radius_km: float) -> np.ndarray:
    """The paper's two-condition Earth-blockage test (section 3.1).

    Parameters
    ----------
    satellite_km : satellite position, km, (..., 3), geocentric.
    direction : direction towards the source (any length), (..., 3).
    earth_radius_km : radius of the spherical Earth, km.

    Returns
    -------
    bool array: True where the Earth hides the source.
    """
    sat, u = np.broadcast_arrays(np.asarray(satellite_km, dtype=float), unit(direction))
    behind = dot(u, sat) < 0.0  # angle to the position vector > 90 deg
    miss_distance = norm(np.cross(sat, u))
    return behind & (miss_distance < earth_radius_km)


@dataclass
class LimbGeometry:
    """Earth-limb quantities for each sample (degrees unless stated)."""

    earth_limb_angle_deg: np.ndarray  # LOS elevation above the limb; < 0 when the LOS hits the Earth
    zenith_angle_deg: np.ndarray  # angle between LOS and local zenith at the satellite
    limb_is_bright: np.ndarray  # nearest limb point sunlit
    bright_limb_angle_deg: np.ndarray  # angle LOS -> nearest sunlit limb point (180 if none)
    dark_limb_angle_deg: np.ndarray  # angle LOS -> nearest dark limb point (180 if none)


def limb_geometry(
    satellite_km: np.ndarray,
    los: np.ndarray,
    sun_km: np.ndarray,
    earth_radius_km: float,
    runs: SceneRuns | None = None,
) -> LimbGeometry:
    """Earth limb geometry for lines of sight ``los`` from ``satellite_km``.

    The limb is the circle of tangent points; seen from the satellite it lies at angle
    rho = arcsin(Re / |r|) from nadir.  A limb point P is sunlit when P . (S - P) > 0, S the
    geocentric Sun.  Along the limb, parametrised by the azimuth psi about nadir measured from
    the LOS side, P . S - Re^2 = A + B cos(psi - psi_s), so the sunlit arc is found in closed
    form and the nearest sunlit and dark limb points follow from the arc ends (the angle from
    the LOS to a limb point grows monotonically with |psi|).

    Validity: spherical Earth, no atmosphere (refraction and the ~100 km airglow layer are not
    modelled).  When the satellite is below the surface, InputError.
    """
    r = np.asarray(satellite_km, dtype=float)
    los = np.asarray(los, dtype=float)
    r, los, sun = np.broadcast_arrays(r, los, np.asarray(sun_km, dtype=float))
    shape = los.shape[:-1]
    # what depends on the satellite and the Sun alone, once per run of samples that share them
    # (a survey cube's time step)
    rows = scene_rows(r, sun, runs=runs)
    (scene_r, scene_sun), index = rows.vectors, rows.index
    per_scene = _limb_scene(scene_r, scene_sun, earth_radius_km)
    out = np.empty((5, index.size))
    _limb_kernel(
        np.ascontiguousarray(los.reshape(-1, 3)),
        index,
        np.ascontiguousarray(scene_sun),
        *(np.ascontiguousarray(v) for v in per_scene),
        out,
    )
    return LimbGeometry(
        earth_limb_angle_deg=out[0].reshape(shape),
        zenith_angle_deg=out[1].reshape(shape),
        limb_is_bright=(out[2] > 0.0).reshape(shape),
        bright_limb_angle_deg=out[3].reshape(shape),
        dark_limb_angle_deg=out[4].reshape(shape),
    )


@njit(cache=True, nogil=True)
def _limb_kernel(los, index, sun, nadir, rho, tangent_len, cr, sr, a_term, out):
    """:func:`limb_geometry` per sample: ``los`` (N, 3) lines of sight (any length; zero or NaN
    ones count as zero vectors, as :func:`unit` makes them), ``index`` (N,) each sample's row of
    the scene quantities (:func:`_limb_scene`, and the geocentric ``sun``, km).  ``out`` (5, N):
    limb angle, zenith angle, nearest limb point lit (1/0), bright and dark limb angles (deg).

    One pass per sample with two transcendental calls (the angle from nadir, the angle to the
    arc's end) where the vectorised form took nine: the azimuth psi_s of the Sun about nadir
    enters only through cos and |sin| (s1 / h, |s2| / h), and the nearer terminator point,
    min over +- of |psi_s +- w| wrapped to [0, pi], has cos(psi_s) cos(w) + |sin(psi_s)| sin(w)
    with cos(w) = -A / B."""
    deg = 180.0 / np.pi
    for p in range(los.shape[0]):
        q = index[p]
        lx, ly, lz = unit_xyz(los[p, 0], los[p, 1], los[p, 2])
        nx, ny, nz = nadir[q, 0], nadir[q, 1], nadir[q, 2]
        cx, cy, cz = ly * nz - lz * ny, lz * nx - lx * nz, lx * ny - ly * nx
        sin_g = np.sqrt(cx * cx + cy * cy + cz * cz)
        cos_g = lx * nx + ly * ny + lz * nz
        gamma = np.arctan2(sin_g, cos_g)
        gamma_deg = gamma * deg
        limb_deg = gamma_deg - rho[q] * deg
        # the limb's azimuth origin: towards the line of sight, or the Sun where the line of
        # sight is along the vertical, or a fixed perpendicular where that too is (perpendicular_towards)
        sx, sy, sz = sun[q, 0], sun[q, 1], sun[q, 2]
        tx, ty, tz = (lx, ly, lz) if sin_g > 1e-12 else unit_xyz(sx, sy, sz)
        tn = tx * nx + ty * ny + tz * nz
        px, py, pz = tx - tn * nx, ty - tn * ny, tz - tn * nz
        pn = np.sqrt(px * px + py * py + pz * pz)
        if not pn > 1e-9:
            px, py, pz, pn = any_perpendicular_xyz(nx, ny, nz)
        e1x, e1y, e1z = px / pn, py / pn, pz / pn
        e2x, e2y, e2z = ny * e1z - nz * e1y, nz * e1x - nx * e1z, nx * e1y - ny * e1x
        s1 = e1x * sx + e1y * sy + e1z * sz
        s2 = e2x * sx + e2y * sy + e2z * sz
        h = np.sqrt(s1 * s1 + s2 * s2)
        cos_psi, sin_psi_abs = (s1 / h, abs(s2) / h) if h > 0.0 else (1.0, 0.0)
        a = a_term[q]
        b = tangent_len[q] * sr[q] * h
        lit = a + b * cos_psi > 0.0
        if b > 0.0:
            c = -a / b
        elif a < 0.0:
            c = 2.0
        elif a > 0.0:
            c = -2.0
        elif a == 0.0:
            c = 0.0
        else:
            c = np.nan
        nearest = abs(limb_deg)
        out[0, p] = limb_deg
        out[1, p] = 180.0 - gamma_deg
        out[2, p] = 1.0 if lit else 0.0
        # the whole limb lit (c <= -1) or dark (c >= 1): no arc end, no arccos (most time steps)
        if (c <= -1.0) if lit else (c >= 1.0):
            out[3, p], out[4, p] = (nearest, 180.0) if lit else (180.0, nearest)
            continue
        cc = min(max(c, -1.0), 1.0)
        cos_end = cos_psi * cc + sin_psi_abs * np.sqrt(1.0 - cc * cc)
        # cos and sin of gamma from its own arctangent's arguments (a zero line of sight: from
        # gamma itself, 0 or 180 deg as the zero's sign gives it)
        gn = np.sqrt(sin_g * sin_g + cos_g * cos_g)
        cg, sg = (cos_g / gn, sin_g / gn) if gn > 0.0 else (np.cos(gamma), np.sin(gamma))
        to_end = np.arccos(min(max(cr[q] * cg + sr[q] * sg * cos_end, -1.0), 1.0)) * deg
        out[3, p], out[4, p] = (nearest, to_end) if lit else (to_end, nearest)


def _limb_scene(r, sun, earth_radius_km):
    """:func:`limb_geometry`'s quantities of the satellite ``r`` and the Sun ``sun`` alone (km,
    (..., 3)): nadir, the limb's angle rho from nadir (rad), the tangent length (km), cos and sin
    of rho, and A of P . S - Re^2 = A + B cos(psi - psi_s)."""
    dist = norm(r)
    if np.any(dist <= earth_radius_km):
        raise InputError(
            f"satellite position is inside the Earth (|r| = {float(dist.min()):.1f} km "
            f"<= Earth radius {earth_radius_km} km)"
        )
    nadir = -r / dist[..., None]
    rho = np.arcsin(earth_radius_km / dist)
    tangent_len = np.sqrt(np.maximum(dist**2 - earth_radius_km**2, 0.0))
    cr, sr = np.cos(rho), np.sin(rho)
    a_term = dot(r, sun) + tangent_len * cr * dot(nadir, sun) - earth_radius_km**2
    return nadir, rho, tangent_len, cr, sr, a_term
