"""The Earth seen from the satellite: its limb and what it hides, vectorised over samples.

Conventions (the paper, sections 1, 2.1, 3.1 and 3.3):

* Earth limb angle: angle of the line of sight (LOS) above the solid Earth's limb as seen from
  the satellite, negative when the LOS hits the Earth (spherical Earth of radius
  ``earth_radius_km``).
* Earth blockage of a source (paper, section 3.1): blocked when both (1) the angle between the
  source direction and the satellite's position vector exceeds 90 deg and (2) the ray from the
  satellite towards the source passes closer than one Earth radius to the Earth's centre.
* Bright and dark limb: the paper keeps pointings "80 deg from Earth's bright limb, and 30 deg
  from Earth's dark limb" (sect. 1), and compares CSST with HST, which "restricts observations
  within sunlit regions to angles greater than 20 deg from Earth's bright limb" (sect. 3.3);
  the bright limb is the edge of the "Earth bright" region the earthshine comes from (table 1),
  "the Earth's bright regions illuminated by the Sun" (sect. 2.2, item 5).  The paper gives no
  formula.  Here the bright-limb angle is the smallest angle between the LOS and any sunlit
  point of the visible Earth's disc (0 when the LOS itself meets a sunlit point): for a LOS off
  the Earth it is reached on the edge of the sunlit region, the sunlit part of the limb or the
  terminator across the disc, whichever is nearer.  The dark-limb angle is the angle to the
  nearest dark point of the limb (the paper's 30 deg keeps the airglow of the limb away,
  sect. 2.1).
* The limb is seen at the top of an atmosphere ``limb_height_km`` above the surface: the disc's
  edge lies at arcsin((Re + h) / |r|) from nadir.  A point of that sphere counts as sunlit when
  the surface below it (along the radius) is: the lit air above the shadow's edge beyond the
  terminator (twilight) is not counted as bright.

Vectors are Cartesian, GCRS/ICRS axes, last axis of length 3, broadcast over the leading axes
(:mod:`straylight.sky.vectors`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from straylight.errors import InputError
from straylight.sky.runs import SceneRuns, scene_rows
from straylight.sky.vectors import any_perpendicular_xyz, dot, norm, unit, unit_xyz
from straylight.util.kernel_cache import njit

__all__ = ["LimbGeometry", "earth_blocks", "limb_geometry"]

#: points of the terminator's visible arc scanned per sample before the golden-section refinement
#: (the cosine of the angle from the line of sight has at most two maxima along the circle, one
#: of them at an end of the arc where it is not inside it)
_TERMINATOR_SCAN = 16
#: golden-section steps after the scan: the bracket (two scan steps, at most 4 pi / 15 rad, a
#: few degrees from a low orbit) shrinks by 0.618 a step, to < 1e-4 of a step; the angle, at a
#: maximum of its cosine, moves by its square
_TERMINATOR_REFINE = 20


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

    earth_limb_angle_deg: np.ndarray  # LOS elevation above the solid Earth's limb; < 0 when the LOS hits it
    zenith_angle_deg: np.ndarray  # angle between LOS and local zenith at the satellite
    limb_is_bright: np.ndarray  # nearest point of the (atmosphere's) limb sunlit
    bright_limb_angle_deg: np.ndarray  # angle LOS -> nearest sunlit point of the disc (180 if none)
    dark_limb_angle_deg: np.ndarray  # angle LOS -> nearest dark limb point (180 if none)


def limb_geometry(
    satellite_km: np.ndarray,
    los: np.ndarray,
    sun_km: np.ndarray,
    earth_radius_km: float,
    runs: SceneRuns | None = None,
    limb_height_km: float = 0.0,
) -> LimbGeometry:
    """Earth limb geometry for lines of sight ``los`` from ``satellite_km``.

    The limb is the circle of tangent points on the sphere of radius Ra = Re + h (h =
    ``limb_height_km``); seen from the satellite it lies at angle rho = arcsin(Ra / |r|) from
    nadir.  A point P of that sphere is sunlit when the surface point below it is, P . S > Re Ra
    (Re P / Ra . (S - Re P / Ra) > 0, S the geocentric Sun).  Along the limb, parametrised by
    the azimuth psi about nadir measured from the LOS side, P . S - Re Ra = A + B cos(psi -
    psi_s), so the sunlit arc is found in closed form and the nearest sunlit and dark limb
    points follow from the arc ends (the angle from the LOS to a limb point grows monotonically
    with |psi|).  The sunlit points of the disc inside the limb are bounded by the terminator,
    the circle where the plane P . S = Re Ra cuts the sphere; the angle from the LOS to its
    visible arc is found by a scan of the arc and a golden-section refinement.

    Parameters
    ----------
    satellite_km : (..., 3) geocentric satellite position, km.
    los : (..., 3) lines of sight (any length).
    sun_km : (..., 3) geocentric Sun, km.
    earth_radius_km : radius of the spherical Earth Re, km.
    runs : the samples' scene runs when the caller knows them (:class:`SceneRuns`).
    limb_height_km : height h of the limb (the top of the atmosphere) above the surface, km.

    Returns
    -------
    LimbGeometry
        Arrays of the samples' broadcast shape: ``earth_limb_angle_deg`` (above the solid
        Earth's limb, deg), ``zenith_angle_deg`` (deg), ``limb_is_bright`` (bool),
        ``bright_limb_angle_deg`` and ``dark_limb_angle_deg`` (deg, 180 where there is none).

    Validity: spherical Earth; refraction not modelled.  When the satellite is not above the
    limb's sphere, InputError.
    """
    r = np.asarray(satellite_km, dtype=float)
    los = np.asarray(los, dtype=float)
    r, los, sun = np.broadcast_arrays(r, los, np.asarray(sun_km, dtype=float))
    shape = los.shape[:-1]
    # what depends on the satellite and the Sun alone, once per run of samples that share them
    # (a survey cube's time step)
    rows = scene_rows(r, sun, runs=runs)
    (scene_r, scene_sun), index = rows.vectors, rows.index
    per_scene = _limb_scene(scene_r, scene_sun, earth_radius_km, float(limb_height_km))
    out = np.empty((5, index.size))
    _limb_kernel(
        np.ascontiguousarray(los.reshape(-1, 3)),
        index,
        np.ascontiguousarray(scene_r),
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
def _limb_kernel(
    los, index, sat, sun, nadir, rho_solid, rho, tangent_len, cr, sr, a_term, lit_min, hit_c, term, out
):
    """:func:`limb_geometry` per sample: ``los`` (N, 3) lines of sight (any length; zero or NaN
    ones count as zero vectors, as :func:`unit` makes them), ``index`` (N,) each sample's row of
    the scene quantities (:func:`_limb_scene`, and the geocentric satellite ``sat`` and ``sun``,
    km).  ``out`` (5, N): limb angle, zenith angle, nearest limb point lit (1/0), bright and
    dark limb angles (deg).

    One pass per sample with two transcendental calls (the angle from nadir, the angle to the
    arc's end) where the vectorised form took nine: the azimuth psi_s of the Sun about nadir
    enters only through cos and |sin| (s1 / h, |s2| / h), and the nearer terminator point,
    min over +- of |psi_s +- w| wrapped to [0, pi], has cos(psi_s) cos(w) + |sin(psi_s)| sin(w)
    with cos(w) = -A / B.  The terminator inside the disc is searched only where it can be
    nearer than the limb: the nearest limb point dark, or the LOS on a dark point of the disc."""
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
        out[0, p] = gamma_deg - rho_solid[q] * deg
        out[1, p] = 180.0 - gamma_deg
        out[2, p] = 1.0 if lit else 0.0
        # the whole limb lit (c <= -1) or dark (c >= 1): no arc end, no arccos (most time steps)
        if (c <= -1.0) if lit else (c >= 1.0):
            bright, dark = (nearest, 180.0) if lit else (180.0, nearest)
        else:
            cc = min(max(c, -1.0), 1.0)
            cos_end = cos_psi * cc + sin_psi_abs * np.sqrt(1.0 - cc * cc)
            # cos and sin of gamma from its own arctangent's arguments (a zero line of sight: from
            # gamma itself, 0 or 180 deg as the zero's sign gives it)
            gn = np.sqrt(sin_g * sin_g + cos_g * cos_g)
            cg, sg = (cos_g / gn, sin_g / gn) if gn > 0.0 else (np.cos(gamma), np.sin(gamma))
            to_end = np.arccos(min(max(cr[q] * cg + sr[q] * sg * cos_end, -1.0), 1.0)) * deg
            bright, dark = (nearest, to_end) if lit else (to_end, nearest)
        out[4, p] = dark
        # the sunlit disc: off the disc with the nearest limb point lit, that point is the
        # nearest sunlit point of the disc; on the disc, the LOS's own point may be lit
        search = not lit
        if limb_deg < 0.0:
            rx, ry, rz = sat[q, 0], sat[q, 1], sat[q, 2]
            rl = rx * lx + ry * ly + rz * lz
            t = -rl - np.sqrt(max(rl * rl - hit_c[q], 0.0))
            if (rx + t * lx) * sx + (ry + t * ly) * sy + (rz + t * lz) * sz > lit_min[q]:
                bright = 0.0
                search = False
            else:
                search = True
        if search and term[q, 0] >= 0.0:
            bright = min(bright, _terminator_angle_deg(lx, ly, lz, term[q]))
        out[3, p] = bright


@njit(cache=True, nogil=True)
def _terminator_angle_deg(lx, ly, lz, tq):
    """Smallest angle (deg) between the unit LOS (lx, ly, lz) and the directions from the
    satellite to the terminator's visible arc, P(t) - r = w0 + rt (cos t e1 + sin t e2) for
    |t| <= T, with |P(t) - r|^2 = b0 - bq cos t.  ``tq``: (T, b0, bq, w0 (3), rt e1 (3),
    rt e2 (3)) of :func:`_limb_scene`.  A scan of the arc, then golden-section steps about its
    best point (the cosine of the angle has at most two maxima along a circle)."""
    half, b0, bq = tq[0], tq[1], tq[2]
    a0 = lx * tq[3] + ly * tq[4] + lz * tq[5]
    a1 = lx * tq[6] + ly * tq[7] + lz * tq[8]
    a2 = lx * tq[9] + ly * tq[10] + lz * tq[11]
    n = _TERMINATOR_SCAN
    step = 2.0 * half / (n - 1)
    cs, ss = np.cos(-half), np.sin(-half)
    cd, sd = np.cos(step), np.sin(step)
    best, best_j = -2.0, 0
    for j in range(n):
        v = (a0 + a1 * cs + a2 * ss) / np.sqrt(max(b0 - bq * cs, 1e-300))
        if v > best:
            best, best_j = v, j
        cs, ss = cs * cd - ss * sd, ss * cd + cs * sd  # rotate by one step
    lo = -half + step * max(best_j - 1, 0)
    hi = -half + step * min(best_j + 1, n - 1)
    g = 0.5 * (np.sqrt(5.0) - 1.0)
    x1, x2 = hi - g * (hi - lo), lo + g * (hi - lo)
    f1 = (a0 + a1 * np.cos(x1) + a2 * np.sin(x1)) / np.sqrt(max(b0 - bq * np.cos(x1), 1e-300))
    f2 = (a0 + a1 * np.cos(x2) + a2 * np.sin(x2)) / np.sqrt(max(b0 - bq * np.cos(x2), 1e-300))
    for _ in range(_TERMINATOR_REFINE):
        if f1 > f2:
            hi, x2, f2 = x2, x1, f1
            x1 = hi - g * (hi - lo)
            f1 = (a0 + a1 * np.cos(x1) + a2 * np.sin(x1)) / np.sqrt(max(b0 - bq * np.cos(x1), 1e-300))
        else:
            lo, x1, f1 = x1, x2, f2
            x2 = lo + g * (hi - lo)
            f2 = (a0 + a1 * np.cos(x2) + a2 * np.sin(x2)) / np.sqrt(max(b0 - bq * np.cos(x2), 1e-300))
    best = max(best, f1, f2)
    return np.arccos(min(max(best, -1.0), 1.0)) * 180.0 / np.pi


def _limb_scene(r, sun, earth_radius_km, limb_height_km=0.0):
    """:func:`limb_geometry`'s quantities of the satellite ``r`` and the Sun ``sun`` alone (km,
    (..., 3)) and the limb's height (km): nadir, the solid Earth's limb angle from nadir (rad),
    the limb's angle rho from nadir (rad), the tangent length (km), cos and sin of rho, A of
    P . S - Re Ra = A + B cos(psi - psi_s), the sunlit test's threshold Re Ra (km2), |r|^2 -
    Ra^2 (km2), and the terminator's visible arc (..., 12): its half-width T (rad; -1 where
    none of it is visible), b0, bq (km2), w0 (km, 3), rt e1 and rt e2 (km, 3 each) of
    :func:`_terminator_angle_deg`."""
    dist = norm(r)
    ra = earth_radius_km + limb_height_km
    if limb_height_km < 0.0 or np.any(dist <= ra):
        raise InputError(
            f"satellite position is not above the limb (|r| = {float(dist.min()):.1f} km, Earth radius "
            f"{earth_radius_km} km + limb height {limb_height_km} km; the height must be >= 0)"
        )
    nadir = -r / dist[..., None]
    rho_solid = np.arcsin(earth_radius_km / dist)
    rho = np.arcsin(ra / dist)
    tangent_len = np.sqrt(np.maximum(dist**2 - ra**2, 0.0))
    cr, sr = np.cos(rho), np.sin(rho)
    lit_min = np.full(dist.shape, earth_radius_km * ra)
    a_term = dot(r, sun) + tangent_len * cr * dot(nadir, sun) - lit_min
    # the terminator: the plane P . s = k (s the Sun's unit vector) cuts the sphere Ra in a
    # circle of centre k s and radius rt; e1 along r's part across s, so that P . r = k (r . s)
    # + rt q cos t (q = |that part|), and the arc is visible where P . r > Ra^2
    dsun = norm(sun)
    s = sun / dsun[..., None]
    k = lit_min / dsun
    rt = np.sqrt(np.maximum(ra**2 - k**2, 0.0))
    rs = dot(r, s)
    across = r - rs[..., None] * s
    q = norm(across)
    fallback = np.cross(s, np.where(np.abs(s[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]))
    e1 = unit(np.where((q > 1e-9)[..., None], across, fallback))
    e2 = np.cross(s, e1)
    w0 = k[..., None] * s - r
    with np.errstate(divide="ignore", invalid="ignore"):
        cmin = np.where(rt * q > 0.0, (ra**2 - k * rs) / (rt * q), np.where(k * rs > ra**2, -2.0, 2.0))
    half = np.where(cmin < 1.0, np.arccos(np.clip(cmin, -1.0, 1.0)), -1.0)
    term = np.concatenate(
        [
            half[..., None],
            (dot(w0, w0) + rt**2)[..., None],
            (2.0 * rt * q)[..., None],
            w0,
            rt[..., None] * e1,
            rt[..., None] * e2,
        ],
        axis=-1,
    )
    hit_c = dist**2 - ra**2
    return nadir, rho_solid, rho, tangent_len, cr, sr, a_term, lit_min, hit_c, term
