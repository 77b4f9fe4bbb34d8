"""Observing geometry, vectorised over (time, pointing).

All functions take Cartesian vectors in GCRS/ICRS axes with the last axis of length 3 and
broadcast over the leading axes, so a (T, 1, 3) satellite position against (1, P, 3) pointing
vectors gives (T, P) results, and (N, 3) against (N, 3) gives N paired samples.

Conventions (the paper, sections 2.3 and 3.1):

* Angles between vectors use ``atan2(|a x b|, a . b)``, accurate at 0 and 180 deg.
* Earth limb angle: angle of the line of sight (LOS) above the Earth's limb as seen from the
  satellite, negative when the LOS hits the Earth (spherical Earth of radius ``earth_radius_km``).
* Telescope frame: +Z along the LOS; +X towards the Sun's projection on the focal plane,
  which is where the aperture door stands ("opens ... aligned with the solar azimuth"); the
  spacecraft rolls to keep it so.  Any direction has off-axis angle theta in [0, 180] and
  azimuth phi in [0, 360) from +X towards +Y = Z x X.  The Sun is always at phi = 0.
* Earth blockage of a source (paper, section 3.1): blocked when both (1) the angle between the
  source direction and the satellite's position vector exceeds 90 deg and (2) the ray from the
  satellite towards the source passes closer than one Earth radius to the Earth's centre.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from straylight.errors import InputError

#: Violation bit flags, in the order of :data:`VIOLATION_NAMES`.
VIOLATION_NAMES = ("sun", "moon", "bright_limb", "dark_limb", "earth_occultation")
VIOLATION_BITS = {name: 1 << i for i, name in enumerate(VIOLATION_NAMES)}


def violation_mask_attrs() -> dict:
    """CF attributes of a violated-constraint bit mask: ``flag_masks`` with the bits and
    ``flag_meanings`` with their names, blank-separated in the same order (CF 1.11 sect. 3.5)."""
    return {"units": "1", "long_name": "violated-constraint bit mask (0 = no constraint violated)",
            "flag_masks": np.array(list(VIOLATION_BITS.values()), dtype=np.uint8),
            "flag_meanings": " ".join(VIOLATION_BITS)}

_EPS = 1e-12


# -- vector helpers ---------------------------------------------------------------------------
def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dot product over the last axis (of length 3), broadcasting."""
    a, b = np.asarray(a), np.asarray(b)
    if a.shape[-1] != 3 or b.shape[-1] != 3:  # every caller's vectors are 3-vectors
        raise ValueError(f"dot: expected 3-vectors, got shapes {a.shape} and {b.shape}")
    # three products and two sums: 2x faster than einsum on (N, 3) arrays
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def norm(a: np.ndarray) -> np.ndarray:
    return np.sqrt(dot(a, a))


def unit(a: np.ndarray) -> np.ndarray:
    """Unit vectors along the last axis (a zero vector stays zero)."""
    n = norm(a)[..., None]
    return np.divide(a, n, out=np.zeros(np.broadcast(a, n).shape), where=n > 0)


def wrap_360_deg(angle_deg) -> np.ndarray:
    """``np.mod(angle_deg, 360.0)``, the same values (-0.0 may stay -0.0), without its slow
    floating-point modulo where every angle already lies within (-360, 360) deg (an arctan2's,
    or one already wrapped: then only its negatives move, by 360)."""
    a = np.asarray(angle_deg, dtype=float)
    if a.size and a.min() > -360.0 and a.max() < 360.0:  # NaN fails both: np.mod below
        return a if a.min() >= 0.0 else np.where(a < 0.0, a + 360.0, a)
    return np.mod(a, 360.0)


def angle_between_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle in degrees between vectors a and b (any lengths), stable at 0 and 180 deg."""
    a, b = np.broadcast_arrays(a, b)
    return np.degrees(np.arctan2(norm(np.cross(a, b)), dot(a, b)))


def radec_to_unit(ra_deg, dec_deg, field: str = "pointing") -> np.ndarray:
    """Unit vectors (..., 3) for RA/Dec in degrees; NaN or |Dec| > 90 raise InputError."""
    ra = np.asarray(ra_deg, dtype=float)
    dec = np.asarray(dec_deg, dtype=float)
    if not np.all(np.isfinite(ra)):
        raise InputError(f"{field}: RA must be finite, got {ra_deg!r}")
    if not np.all(np.isfinite(dec)) or np.any(np.abs(dec) > 90.0):
        raise InputError(f"{field}: Dec must be finite and within [-90, 90] deg, got {dec_deg!r}")
    ra_r, dec_r = np.radians(ra), np.radians(dec)
    cd = np.cos(dec_r)
    return np.stack([cd * np.cos(ra_r), cd * np.sin(ra_r), np.sin(dec_r)], axis=-1)


def _any_perpendicular(v: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to each v (celestial north projected, else +X projected)."""
    north = np.array([0.0, 0.0, 1.0])
    p = north - dot(v, north)[..., None] * v
    alt = np.array([1.0, 0.0, 0.0]) - v[..., :1] * v
    use_alt = (norm(p) < 1e-6)[..., None]
    return unit(np.where(use_alt, alt, p))


@njit(cache=True, nogil=True)
def unit_xyz(x, y, z):
    """:func:`unit` of one 3-vector inside a compiled kernel, the same arithmetic: a zero or
    NaN vector gives the zero vector."""
    n = np.sqrt(x * x + y * y + z * z)
    if n > 0.0:
        return x / n, y / n, z / n
    return 0.0, 0.0, 0.0


@njit(cache=True, nogil=True)
def any_perpendicular_xyz(vx, vy, vz):
    """:func:`_any_perpendicular` of one unit vector inside a compiled kernel, the same
    arithmetic: (px, py, pz, length), not yet normalised."""
    px, py, pz = 0.0 - vz * vx, 0.0 - vz * vy, 1.0 - vz * vz
    n = np.sqrt(px * px + py * py + pz * pz)
    if n < 1e-6:
        px, py, pz = 1.0 - vx * vx, 0.0 - vx * vy, 0.0 - vx * vz
        n = np.sqrt(px * px + py * py + pz * pz)
    return px, py, pz, n


def perpendicular_towards(v: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Unit vector perpendicular to unit v pointing towards target's projection.

    Where target is (anti)parallel to v the projection vanishes and a fixed perpendicular
    (celestial north projected) is used instead, so the result is always finite.
    """
    v, target = np.broadcast_arrays(v, unit(target))
    p = target - dot(target, v)[..., None] * v
    degenerate = ~(norm(p) > 1e-9)  # NaN counts as degenerate
    if not np.any(degenerate):  # the fallback is rare: computed only when needed
        return unit(p)
    return np.where(degenerate[..., None], _any_perpendicular(v), unit(p))


# -- Earth ------------------------------------------------------------------------------------
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
    satellite_km: np.ndarray, los: np.ndarray, sun_km: np.ndarray, earth_radius_km: float,
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
    _limb_kernel(np.ascontiguousarray(los.reshape(-1, 3)), index, np.ascontiguousarray(scene_sun),
                 *(np.ascontiguousarray(v) for v in per_scene), out)
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
        # the whole limb lit (c <= -1) or dark (c >= 1): no arc end, no arccos (76 % of the
        # default day's time steps)
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


# -- telescope frame --------------------------------------------------------------------------
@dataclass
class TelescopeFrame:
    """Orthonormal axes (..., 3) of the telescope: z = LOS, x towards the Sun (door side)."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray

    def theta_phi_deg(self, direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Off-axis angle theta in [0, 180] and azimuth phi in [0, 360) of a direction, deg."""
        d = np.asarray(direction, dtype=float)
        if d.ndim == 1:  # one direction for every frame (a body seen from a cube time step)
            shape = self.z.shape[:-1]
            d_run, index = d[None, None, :], np.zeros(int(np.prod(shape)), np.intp)
        else:
            shape = np.broadcast_shapes(d.shape, self.x.shape, self.y.shape, self.z.shape)[:-1]
            d_run, index = np.broadcast_to(d, shape + (3,)).reshape(1, -1, 3), np.arange(int(np.prod(shape)))
        theta, phi = self.theta_phi_runs_deg(d_run, index, shape)
        return theta[0], phi[0]

    def theta_phi_runs_deg(self, d_run: np.ndarray, index: np.ndarray, shape: tuple) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`theta_phi_deg` of bodies whose directions are given per run of samples: unit
        ``d_run`` (B, R, 3), ``index`` (N,) each sample's run, ``shape`` the samples' shape (N
        samples, the frames broadcast to it); (theta, phi) of shape (B,) + shape.  The direction's
        components in the frame in one compiled pass (:func:`_frame_components_kernel`, which
        reads each sample's direction from its run rather than a gathered (B, N, 3) array), the
        arctangents in numpy (its SIMD arctan2 is ~10x the compiled loop's libm call here)."""
        frames = [np.ascontiguousarray(np.broadcast_to(a, tuple(shape) + (3,)).reshape(-1, 3), dtype=float)
                  for a in (self.x, self.y, self.z)]
        comp = np.empty((d_run.shape[0], 4, index.size))
        _frame_components_kernel(*frames, np.ascontiguousarray(d_run, dtype=float),
                                 np.ascontiguousarray(index, dtype=np.intp), comp)
        deg = 180.0 / np.pi
        theta = np.arctan2(comp[:, 0], comp[:, 1])
        theta *= deg
        phi = np.arctan2(comp[:, 2], comp[:, 3])
        phi *= deg
        np.add(phi, 360.0, out=phi, where=phi < 0.0)
        phi[phi >= 360.0] = 0.0  # -1e-15 + 360 rounds to 360.0
        return theta.reshape((-1,) + tuple(shape)), phi.reshape((-1,) + tuple(shape))


@njit(cache=True, nogil=True)
def _frame_components_kernel(x, y, z, d_run, index, out):
    """Each body b's direction d = d_run[b, index[p]] in sample p's frame, into ``out`` (B, 4, N):
    sqrt((d . x)^2 + (d . y)^2) (hypot's value to rounding: unit vectors neither overflow nor
    underflow), d . z, d . y, d . x (theta = atan2 of the first two, phi of the last two)."""
    for b in range(d_run.shape[0]):
        for p in range(x.shape[0]):
            q = index[p]
            d0, d1, d2 = d_run[b, q, 0], d_run[b, q, 1], d_run[b, q, 2]
            dx = d0 * x[p, 0] + d1 * x[p, 1] + d2 * x[p, 2]
            dy = d0 * y[p, 0] + d1 * y[p, 1] + d2 * y[p, 2]
            out[b, 0, p] = np.sqrt(dx * dx + dy * dy)
            out[b, 1, p] = d0 * z[p, 0] + d1 * z[p, 1] + d2 * z[p, 2]
            out[b, 2, p] = dy
            out[b, 3, p] = dx


def telescope_frame(los: np.ndarray, sun_direction: np.ndarray) -> TelescopeFrame:
    """Telescope frame with the roll set by the Sun (door facing it).

    With the Sun exactly on or opposite the LOS the roll is undefined; the +X axis then falls
    back to celestial north projected on the focal plane, so the frame is always finite.
    """
    los, sun_direction = np.broadcast_arrays(np.asarray(los, dtype=float), np.asarray(sun_direction, dtype=float))
    shape = los.shape
    axes = np.empty((3,) + shape)
    _frame_kernel(np.ascontiguousarray(los.reshape(-1, 3)), np.ascontiguousarray(sun_direction.reshape(-1, 3)),
                  axes.reshape(3, -1, 3))
    return TelescopeFrame(x=axes[0], y=axes[1], z=axes[2])


@njit(cache=True, nogil=True)
def _frame_kernel(los, sun_direction, axes):
    """:func:`telescope_frame` per sample, into ``axes`` (3, N, 3) = x, y, z: the arithmetic of
    z = unit(los), x = perpendicular_towards(z, sun_direction), y = z x x, operation for
    operation (the same numbers), in one pass instead of ~40 numpy passes."""
    for p in range(los.shape[0]):
        zx, zy, zz = unit_xyz(los[p, 0], los[p, 1], los[p, 2])
        tx, ty, tz = unit_xyz(sun_direction[p, 0], sun_direction[p, 1], sun_direction[p, 2])
        d = tx * zx + ty * zy + tz * zz
        px, py, pz = tx - d * zx, ty - d * zy, tz - d * zz
        n = np.sqrt(px * px + py * py + pz * pz)
        if not n > 1e-9:  # the Sun on or opposite the line of sight
            px, py, pz, n = any_perpendicular_xyz(zx, zy, zz)
        px, py, pz = (px / n, py / n, pz / n) if n > 0.0 else (0.0, 0.0, 0.0)
        axes[0, p, 0], axes[0, p, 1], axes[0, p, 2] = px, py, pz
        axes[1, p, 0], axes[1, p, 1], axes[1, p, 2] = zy * pz - zz * py, zz * px - zx * pz, zx * py - zy * px
        axes[2, p, 0], axes[2, p, 1], axes[2, p, 2] = zx, zy, zz


# -- constraints ------------------------------------------------------------------------------
@dataclass(frozen=True)
class DoorState:
    opening_deg: float
    sun_angle_min_deg: float
    min_inclusive: bool


@dataclass(frozen=True)
class Constraints:
    """Avoidance angles (deg) and door rules from the instrument config."""

    sun_min_deg: float
    moon_min_deg: float
    bright_limb_min_deg: float
    dark_limb_min_deg: float
    door_states: tuple[DoorState, ...]

    def door_opening_deg(self, sun_angle_deg: np.ndarray) -> np.ndarray:
        """Door opening angle for the Sun's off-axis angle; 0 where no state is allowed.

        States are tried from the widest opening down; a state is allowed when the Sun is
        beyond its minimum angle (``>`` or ``>=`` as the state says).
        """
        s = np.asarray(sun_angle_deg, dtype=float)
        out = np.zeros_like(s)
        for state in sorted(self.door_states, key=lambda d: d.opening_deg):  # widest last wins
            ok = s >= state.sun_angle_min_deg if state.min_inclusive else s > state.sun_angle_min_deg
            out = np.where(ok, state.opening_deg, out)
        return out

    def violations(
        self,
        sun_angle_deg,
        moon_angle_deg,
        bright_limb_angle_deg,
        dark_limb_angle_deg,
        earth_limb_angle_deg,
    ) -> np.ndarray:
        """Bit mask of violated constraints (see :data:`VIOLATION_BITS`); 0 = observable.

        Each constraint is violated strictly below its threshold: a pointing exactly at the
        avoidance angle is allowed (the paper gives minimum angles).
        """
        flags = np.zeros(np.broadcast(sun_angle_deg, moon_angle_deg).shape, dtype=np.uint8)
        flags |= np.where(np.asarray(sun_angle_deg) < self.sun_min_deg, VIOLATION_BITS["sun"], 0).astype(np.uint8)
        flags |= np.where(np.asarray(moon_angle_deg) < self.moon_min_deg, VIOLATION_BITS["moon"], 0).astype(np.uint8)
        flags |= np.where(
            np.asarray(bright_limb_angle_deg) < self.bright_limb_min_deg, VIOLATION_BITS["bright_limb"], 0
        ).astype(np.uint8)
        flags |= np.where(
            np.asarray(dark_limb_angle_deg) < self.dark_limb_min_deg, VIOLATION_BITS["dark_limb"], 0
        ).astype(np.uint8)
        flags |= np.where(
            np.asarray(earth_limb_angle_deg) <= 0.0, VIOLATION_BITS["earth_occultation"], 0
        ).astype(np.uint8)
        return flags


def violation_names(flags: int) -> list[str]:
    """Names of the constraints set in one violation bit mask."""
    return [name for name in VIOLATION_NAMES if int(flags) & VIOLATION_BITS[name]]


# -- the whole geometry of a sample ------------------------------------------------------------
def moon_phase(sun_km: np.ndarray, moon_km: np.ndarray, observer_km: np.ndarray):
    """Lunar phase angle (Sun-Moon-observer, deg; 0 = full) and illuminated fraction.

    The illuminated fraction of the disc is k = (1 + cos(alpha)) / 2 (Meeus 1998, eq. 48.1).
    Also returns the elongation Sun-observer-Moon (deg; 180 at full Moon, the paper's "phase").
    """
    alpha = angle_between_deg(sun_km - moon_km, observer_km - moon_km)
    fraction = 0.5 * (1.0 + np.cos(np.radians(alpha)))
    elongation = angle_between_deg(sun_km - observer_km, moon_km - observer_km)
    return alpha, fraction, elongation


@dataclass(frozen=True)
class SceneRuns:
    """Samples grouped into runs of consecutive samples that share a scene (the same 3-vectors):
    ``vectors``, each (R, 3), once per run; ``index``, (N,), each flattened sample's run;
    ``shape``, the samples' shape; ``starts``, (R,), each run's first flattened sample.

    A caller that knows its samples' runs (a cube region: one per time step, :meth:`steps`)
    passes them as ``runs=`` to the functions that would otherwise find them again by reading
    every sample's vectors (:func:`scene_rows`: 0.1-0.2 ms a call on a region's 47,520
    samples, twelve calls an evaluation); :meth:`of` then reads any vectors' rows at the runs'
    starts, and :meth:`at` restricts the runs to a subset of the samples."""

    vectors: tuple
    index: np.ndarray
    shape: tuple
    starts: np.ndarray

    @classmethod
    def steps(cls, n_steps: int, per_step: int) -> "SceneRuns":
        """Runs of ``per_step`` consecutive samples each, ``n_steps`` of them (a cube region's
        time steps, each over its pixels), with no vectors yet (:meth:`of` reads them)."""
        return cls((), np.repeat(np.arange(n_steps), per_step), (n_steps * per_step,),
                   np.arange(n_steps) * per_step)

    @property
    def count(self) -> int:
        return int(self.starts.size)

    def of(self, *vectors_km) -> "SceneRuns":
        """These runs with ``vectors_km`` (broadcastable to the samples' shape + (3,)) read at
        each run's first sample.  The caller vouches that each vector is the same within a run
        (this is not checked: checking is the scan the runs are passed to avoid).  ValueError
        for vectors of another shape."""
        vs = np.broadcast_arrays(*(np.asarray(v, float) for v in vectors_km))
        if int(np.prod(vs[0].shape[:-1])) != self.index.size or vs[0].shape[-1] != 3:
            raise ValueError(f"scene runs of {self.index.size} samples given vectors of shape {vs[0].shape}")
        return SceneRuns(tuple(np.take(v.reshape(-1, 3), self.starts, axis=0) for v in vs), self.index,
                         vs[0].shape[:-1], self.starts)

    def at(self, samples) -> "SceneRuns":
        """The runs of the flattened samples ``samples`` (increasing indices), as a flat
        sample set of their own, with no vectors yet (:meth:`of` reads them)."""
        run = self.index[np.asarray(samples, dtype=np.intp)]
        new = np.empty(run.size, bool)
        new[:1] = True
        np.not_equal(run[1:], run[:-1], out=new[1:])
        return SceneRuns((), np.cumsum(new) - 1, (run.size,), np.flatnonzero(new))

    def expand(self, per_run) -> np.ndarray:
        """Values per run, (R, ...), to values per sample, shape + (...) (read-only: one run is
        broadcast, not copied)."""
        per_run = np.asarray(per_run)
        if self.count == 1:
            return np.broadcast_to(per_run[0], self.shape + per_run.shape[1:])
        # np.take: 4x numpy's fancy indexing for rows of several values (72 runs to 47,520 samples)
        return np.take(per_run, self.index, axis=0).reshape(self.shape + per_run.shape[1:])


def scene_runs(*vectors_km, runs: SceneRuns | None = None) -> SceneRuns | None:
    """The samples' runs of shared 3-vectors: a survey cube's time step shares the satellite, the
    Sun and the Moon, so a batch of whole steps is one run per step, and a scene quantity
    (a body's direction, the Earth hiding a star) is computed once per run.  None where that
    would not save work: a single sample, or more runs than half the samples.  ``runs``: the
    samples' runs when the caller knows them (:class:`SceneRuns`; not found again)."""
    vs = np.broadcast_arrays(*(np.asarray(v, float) for v in vectors_km))
    shape = vs[0].shape[:-1]
    flat = [v.reshape(-1, 3) for v in vs]
    n = flat[0].shape[0]
    if vs[0].ndim < 2 or n < 2:
        return None
    if runs is not None:
        return None if runs.count > n // 2 else runs.of(*vs)
    new = np.zeros(n, bool)
    new[0] = True
    for f in flat:
        # read-only, said explicitly: numpy warns when numba asks a broadcast view whether it is writeable
        f.flags.writeable = False
        _mark_changed_rows(f, new)
    starts = np.flatnonzero(new)
    if starts.size > n // 2:
        return None
    return SceneRuns(tuple(f[starts].copy() for f in flat), np.cumsum(new) - 1, shape, starts)


@njit(cache=True, nogil=True)
def _mark_changed_rows(f, new):
    """new[i] |= row i of ``f`` (N, 3) differs from row i - 1 (NaN differs from everything);
    rows already marked are not compared (one pass instead of numpy's four per vector)."""
    for i in range(1, f.shape[0]):
        if not new[i] and (f[i, 0] != f[i - 1, 0] or f[i, 1] != f[i - 1, 1] or f[i, 2] != f[i - 1, 2]):
            new[i] = True


def scene_rows(*vectors_km, runs: SceneRuns | None = None) -> SceneRuns:
    """The broadcastable 3-vectors' :func:`scene_runs`, or, where that finds none, every sample
    a run of its own: one form for the code that computes scene quantities per run and reads
    them per sample (``vectors``, ``index``, ``expand``) whatever the samples.  ``runs``: the
    samples' runs when the caller knows them (:class:`SceneRuns`; read, not found again)."""
    if runs is not None:
        return runs.of(*vectors_km)
    vs = np.broadcast_arrays(*(np.asarray(v, float) for v in vectors_km))
    shape = vs[0].shape[:-1]
    n = int(np.prod(shape))
    return scene_runs(*vs) or SceneRuns(tuple(v.reshape(-1, 3) for v in vs), np.arange(n), shape, np.arange(n))


def rows_at(vectors, shape, index) -> np.ndarray:
    """The 3-vectors ``vectors`` (broadcast to ``shape`` + (3,)) at the flat sample indices
    ``index``, (len(index), 3): by np.take, 3-5x numpy's boolean or fancy indexing of (N, 3)
    rows (47,520 rows: 0.12 against 0.43-0.66 ms)."""
    return np.take(np.broadcast_to(np.asarray(vectors, float), tuple(shape) + (3,)).reshape(-1, 3), index, axis=0)


def tiled_period(vectors, runs: SceneRuns | None) -> int | None:
    """L when the 3-vectors ``vectors`` (..., 3; flattened, N rows) are their first L rows
    repeated once per scene run of ``runs`` (a cube batch: the same lines of sight at every
    time step), checked exactly, so that what depends on them alone is computed on L rows and
    tiled; else None."""
    if runs is None or runs.count < 2:
        return None
    flat = np.asarray(vectors).reshape(-1, 3)
    period = flat.shape[0] // runs.count
    if period * runs.count != flat.shape[0]:
        return None
    blocks = flat.reshape(runs.count, period, 3)
    return period if np.array_equal(blocks, np.broadcast_to(blocks[:1], blocks.shape)) else None


def shared_vectors(*vectors_km):
    """The 3-vectors as single vectors when every sample shares each of them (one scene, as a
    survey cube's time step), else None (also for a single sample)."""
    runs = scene_runs(*vectors_km)
    return None if runs is None or runs.count > 1 else tuple(v[0] for v in runs.vectors)


def body_geometry(
    satellite_km: np.ndarray, bodies_km: dict[str, np.ndarray], frame: TelescopeFrame, earth_radius_km: float,
    runs: SceneRuns | None = None,
) -> dict[str, np.ndarray]:
    """Each body's off-axis angle, azimuth and Earth test in the telescope ``frame`` (see
    :func:`observing_geometry`): ``<body>_angle_deg``, ``<body>_phi_deg`` and
    ``<body>_earth_blocked``, arrays of the samples' shape.  ``runs``: the samples' scene runs
    when known (:class:`SceneRuns`)."""
    sat = np.asarray(satellite_km, dtype=float)
    # a cube time step shares the satellite and the bodies: each body's direction once per step
    return _body_geometry(bodies_km, frame, earth_radius_km, scene_rows(sat, *bodies_km.values(), runs=runs))


def _body_geometry(bodies_km, frame, earth_radius_km, rows: SceneRuns) -> dict[str, np.ndarray]:
    """:func:`body_geometry` with the samples' ``scene_rows(satellite, *bodies_km.values())``:
    every body's direction and Earth test once per run, then all bodies' angles in one pass."""
    d_run = unit(np.stack(rows.vectors[1:]) - rows.vectors[0])  # (bodies, runs, 3)
    shape = np.broadcast_shapes(rows.shape, frame.z.shape[:-1])
    index = rows.index if shape == rows.shape else np.broadcast_to(rows.index.reshape(rows.shape), shape).ravel()
    blocked_run = earth_blocks(rows.vectors[0], d_run, earth_radius_km)  # (bodies, runs)
    blocked = np.take(blocked_run, index, axis=1).reshape((len(bodies_km),) + shape)  # np.take: ~8x [:, index]
    theta, phi = frame.theta_phi_runs_deg(d_run, index, shape)
    out: dict[str, np.ndarray] = {}
    for i, name in enumerate(bodies_km):
        out[f"{name}_angle_deg"] = theta[i]  # = off-axis angle theta in the telescope frame
        out[f"{name}_phi_deg"] = phi[i]
        out[f"{name}_earth_blocked"] = blocked[i]
    return out


def observing_geometry(
    satellite_km: np.ndarray,
    bodies_km: dict[str, np.ndarray],
    los: np.ndarray,
    earth_radius_km: float,
    constraints: Constraints,
    frame: TelescopeFrame | None = None,
    runs: SceneRuns | None = None,
) -> dict[str, np.ndarray]:
    """Every geometric quantity the stray-light physics needs, for broadcastable samples.

    Parameters
    ----------
    satellite_km : (..., 3) geocentric satellite position, km.
    bodies_km : body name -> (..., 3) geocentric position, km (must include 'sun' and 'moon').
    los : (..., 3) unit line-of-sight vectors.
    earth_radius_km : spherical Earth radius, km.
    constraints : avoidance angles and door rules.
    frame : the samples' ``telescope_frame(los, sun - satellite)`` when the caller already has
        it (it is then not computed again).
    runs : the samples' scene runs when the caller knows them (:class:`SceneRuns`, e.g. a cube
        region's time steps): runs of samples that share the satellite and every body.

    Returns
    -------
    dict of arrays of the broadcast sample shape: angles in deg (``*_deg``), booleans, the
    door opening (deg, 0 = not allowed), the violation bit mask and ``observable``.
    For every body: ``<body>_angle_deg`` (from the LOS, = the off-axis angle theta),
    ``<body>_phi_deg`` (azimuth in the telescope frame) and ``<body>_earth_blocked``.
    """
    sat = np.asarray(satellite_km, dtype=float)
    sun = bodies_km["sun"]
    if frame is None:
        frame = telescope_frame(los, sun - sat)
    limb = limb_geometry(sat, frame.z, sun, earth_radius_km, runs=runs)
    rows = scene_rows(sat, *bodies_km.values(), runs=runs)
    out = _body_geometry(bodies_km, frame, earth_radius_km, rows)
    names = list(bodies_km)
    alpha, fraction, elongation = (rows.expand(v) for v in moon_phase(
        rows.vectors[1 + names.index("sun")], rows.vectors[1 + names.index("moon")], rows.vectors[0]))
    shape = out["sun_angle_deg"].shape
    out["moon_phase_angle_deg"] = np.broadcast_to(alpha, shape)
    out["moon_illuminated_fraction"] = np.broadcast_to(fraction, shape)
    out["moon_elongation_deg"] = np.broadcast_to(elongation, shape)
    out["earth_limb_angle_deg"] = limb.earth_limb_angle_deg
    out["zenith_angle_deg"] = limb.zenith_angle_deg
    out["limb_is_bright"] = limb.limb_is_bright
    out["bright_limb_angle_deg"] = limb.bright_limb_angle_deg
    out["dark_limb_angle_deg"] = limb.dark_limb_angle_deg
    out["door_opening_deg"] = constraints.door_opening_deg(out["sun_angle_deg"])
    flags = constraints.violations(
        out["sun_angle_deg"],
        out["moon_angle_deg"],
        limb.bright_limb_angle_deg,
        limb.dark_limb_angle_deg,
        limb.earth_limb_angle_deg,
    )
    out["violations"] = flags
    out["observable"] = (flags == 0) & (out["door_opening_deg"] > 0)
    return out
