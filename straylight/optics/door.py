"""The aperture door and its blockage factor Sp(theta, phi) (seed paper sects. 2.2, 3.1).

Geometry (telescope frame, z = line of sight, +x towards the Sun = the door's hinge side): the
aperture is the disc of radius R at z = 0; the door is a flat rectangle of length L and width W
hinged on the line x = R (parallel to y) at the aperture rim.  Closed it lies over the aperture;
opened by an angle alpha it points along (-cos alpha, 0, sin alpha), i.e. at 135 deg it leans
out over the Sun side and shades the aperture from low Sun.

Door length: the paper states that open to 135 deg the door blocks the Sun beyond 65 deg
off-axis (and open to 105 deg, between 50 and 65 deg).  A ray grazing the door's top edge and the
far rim of the aperture fixes L:  tan(65 deg) = cot(45 deg) + 2R / (L sin 45 deg), so
L = 2R / ((tan 65 - 1) sin 45) = 2.472 R.  With this L the 105 deg door blocks the Sun from
47.9 deg, consistent with the paper's 50-65 deg rule.  W = L (assumption: a square door).

Sp(direction) is the fraction of the aperture NOT shaded by the door: rays from a grid of
aperture points (``n_aperture`` points, a knob) towards the source are tested against the door
rectangle.  A source behind the aperture plane (theta > 90 deg) cannot light the aperture:
Sp = 0 there, so nothing reaches the focal plane directly from behind the telescope (seed paper
sect. 2.2: with the axis near the zenith, earthshine enters through the door).  Tables over
(theta, phi) are precomputed per door state for speed.

The telescope's body shades the door: the door's inner face is lit only by directions whose ray
from the door point does not pass through the body, a solid cylinder of radius ``body_radius_m``
about the axis from the aperture plane down to ``body_length_m`` below it (:meth:`Door.body_hits`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from straylight.config import InstrumentSettings, instrument_settings
from straylight.errors import ConfigError
from straylight.sky.vectors import wrap_360_deg
from straylight.util.gridinterp import LinearGrid
from straylight.util.kernel_cache import njit

__all__ = [
    "door_length_from_paper",
    "aperture_points",
    "Door",
    "DoorTable",
    "behind_aperture_plane",
    "door_state_index",
    "door_from_instrument",
]


def door_length_from_paper(
    aperture_radius_m: float, opening_deg: float = 135.0, sun_cutoff_deg: float = 65.0
) -> float:
    """Door length L so that, opened to ``opening_deg``, it just hides the whole aperture from a
    source at ``sun_cutoff_deg`` off axis in the door's azimuth.

    Parameters
    ----------
    aperture_radius_m : float
        The aperture's radius, m.
    opening_deg : float, optional
        The door's opening angle, deg (default 135).
    sun_cutoff_deg : float, optional
        The off-axis angle at which the door just hides the aperture, deg (default 65).
    """
    beta = np.radians(180.0 - opening_deg)  # door elevation above the aperture plane
    denom = (np.tan(np.radians(sun_cutoff_deg)) - 1.0 / np.tan(beta)) * np.sin(beta)
    if denom <= 0:
        raise ConfigError(f"door: opening {opening_deg} deg cannot hide the Sun at {sun_cutoff_deg} deg")
    return 2.0 * aperture_radius_m / denom


def aperture_points(radius_m: float, n: int) -> np.ndarray:
    """N points (x, y) uniformly covering the aperture disc: a sunflower (Vogel) spiral of n/2
    points and its mirror image y -> -y, so that the door's shade keeps the mirror symmetry of
    the real door about the Sun's plane (phi -> -phi; a bare spiral broke it by up to 0.16 in
    Sp, and the earthshine look-up table relies on it).  n = 1: the centre.

    Parameters
    ----------
    radius_m : float
        The aperture's radius, m.
    n : int
        Number of points.
    """
    if n < 1:
        raise ConfigError(f"door: n_aperture = {n} must be >= 1")
    if n == 1:
        return np.zeros((1, 2))
    half = n // 2
    k = np.arange(half) + 0.5
    r = radius_m * np.sqrt(k / half)
    a = k * np.pi * (3.0 - np.sqrt(5.0))
    pts = np.stack([r * np.cos(a), r * np.sin(a)], axis=-1)
    out = np.concatenate([pts, pts * [1.0, -1.0]])
    return np.concatenate([out, [[0.0, 0.0]]]) if n % 2 else out


@dataclass(frozen=True)
class Door:
    """The aperture door of one instrument (see the module doc for the geometry).

    Parameters
    ----------
    aperture_radius_m : float
        Aperture radius R, m.
    length_m, width_m : float
        The door's length L (from the hinge) and width W, m; each at least 2 R.
    n_aperture : int
        Aperture points whose rays are tested against the door (accuracy knob).
    body_radius_m, body_length_m : float
        The telescope body below the aperture plane, a solid cylinder about the axis, m (0: none).
    """

    aperture_radius_m: float
    length_m: float
    width_m: float
    n_aperture: int = 256
    #: the telescope body below the aperture plane, a solid cylinder about the axis (m); 0: none
    body_radius_m: float = 0.0
    body_length_m: float = 0.0

    def __post_init__(self):
        if not (self.length_m > 0 and self.width_m > 0):
            raise ConfigError(f"door: length {self.length_m} m and width {self.width_m} m must be > 0")
        if self.body_radius_m < 0 or self.body_length_m < 0:
            raise ConfigError(
                f"door_geometry: body radius {self.body_radius_m} m and length {self.body_length_m} m "
                "must be >= 0"
            )
        if self.width_m < 2 * self.aperture_radius_m or self.length_m < 2 * self.aperture_radius_m:
            raise ConfigError(
                f"door: {self.length_m:.3f} x {self.width_m:.3f} m cannot close over an aperture of diameter "
                f"{2 * self.aperture_radius_m:.3f} m"
            )

    def plate(self, opening_deg: float):
        """Hinge point, unit vector along the door (from the hinge), unit vector along the hinge.

        Parameters
        ----------
        opening_deg : float
            The door's opening angle, deg.
        """
        a = np.radians(opening_deg)
        hinge = np.array([self.aperture_radius_m, 0.0, 0.0])
        along = np.array([-np.cos(a), 0.0, np.sin(a)])
        return hinge, along, np.array([0.0, 1.0, 0.0])

    def unshaded_fraction(self, directions: np.ndarray, opening_deg: float) -> np.ndarray:
        """Sp: fraction of the aperture that sees along ``directions`` (unit vectors, telescope
        frame, (..., 3)) past the door opened to ``opening_deg``.  Directions below the aperture
        plane (z <= 0) cannot reach the aperture: Sp = 0 there.

        Parameters
        ----------
        directions : ndarray
            Unit directions in the telescope frame, shape (..., 3).
        opening_deg : float
            The door's opening angle, deg.
        """
        d = np.asarray(directions, dtype=float)
        shape = d.shape[:-1]
        d = d.reshape(-1, 3)
        hinge, along, axis = self.plate(opening_deg)
        normal = np.cross(along, axis)
        pts = aperture_points(self.aperture_radius_m, self.n_aperture)
        p = np.concatenate([pts, np.zeros((pts.shape[0], 1))], axis=1)  # (M, 3)
        # the hit point p + t d on the plate's plane, in the plate's coordinates (u along the
        # door from the hinge, v along the hinge): (p - hinge) . e + t (d . e), outer sums
        # instead of (n, M, 3) arrays
        num = (hinge - p) @ normal  # (M,)
        p_along, p_axis = (p - hinge) @ along, (p - hinge) @ axis  # (M,)
        out = np.empty(d.shape[0])
        for start in range(0, d.shape[0], 4096):
            dd = d[start : start + 4096]  # (n, 3)
            with np.errstate(divide="ignore", invalid="ignore"):
                t = num[None, :] / (dd @ normal)[:, None]  # (n, M)
                u = p_along[None, :] + t * (dd @ along)[:, None]
                v = p_axis[None, :] + t * (dd @ axis)[:, None]
            blocked = (
                (t > 0) & (u >= 0) & (u <= self.length_m) & (np.abs(v) <= self.width_m / 2) & np.isfinite(t)
            )
            frac = 1.0 - blocked.mean(axis=1)
            out[start : start + 4096] = np.where(dd[:, 2] > 0, frac, 0.0)
        return out.reshape(shape)

    def body_hits(self, points_m: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Whether the ray from each point (M, 3) along each direction (N, 3) (unit vectors,
        telescope frame, m) passes through the body: (N, M) bool.  The body is the solid cylinder
        x^2 + y^2 < body_radius^2, -body_length < z < 0; no body (radius or length 0): all False.

        Parameters
        ----------
        points_m : ndarray
            Ray origins in the telescope frame, m, shape (M, 3).
        directions : ndarray
            Unit directions in the telescope frame, shape (N, 3).
        """
        p = np.asarray(points_m, float)
        d = np.asarray(directions, float)
        if self.body_radius_m <= 0 or self.body_length_m <= 0:
            return np.zeros((d.shape[0], p.shape[0]), bool)
        dx, dy, dz = (d[:, k][:, None] for k in range(3))
        px, py, pz = (p[:, k][None, :] for k in range(3))
        # the ray's parameter interval inside the slab -L < z < 0 (t > 0: away from the point)
        with np.errstate(divide="ignore", invalid="ignore"):
            t1, t2 = (0.0 - pz) / dz, (-self.body_length_m - pz) / dz
        inside_slab = (pz < 0.0) & (pz > -self.body_length_m)
        z_lo = np.where(dz != 0.0, np.minimum(t1, t2), np.where(inside_slab, -np.inf, np.inf))
        z_hi = np.where(dz != 0.0, np.maximum(t1, t2), np.where(inside_slab, np.inf, -np.inf))
        # and inside the infinite cylinder: a t^2 + b t + c < 0
        a = dx * dx + dy * dy
        b = 2.0 * (px * dx + py * dy)
        c = px * px + py * py - self.body_radius_m**2
        disc = b * b - 4.0 * a * c
        with np.errstate(divide="ignore", invalid="ignore"):
            root = np.sqrt(np.maximum(disc, 0.0))
            r_lo = np.where(a > 0, (-b - root) / (2.0 * a), np.where(c < 0, -np.inf, np.inf))
            r_hi = np.where(a > 0, (-b + root) / (2.0 * a), np.where(c < 0, np.inf, -np.inf))
        r_ok = np.where(a > 0, disc > 0, c < 0)
        lo = np.maximum(np.maximum(z_lo, r_lo), 0.0)
        hi = np.minimum(z_hi, r_hi)
        return r_ok & (hi > lo)

    def table(
        self, opening_deg: float, theta_step_deg: float = 1.0, phi_step_deg: float = 2.0
    ) -> "DoorTable":
        """Sp(theta, phi) of the door open to ``opening_deg`` tabulated over theta 0-90 deg and
        phi 0-360 deg.

        Parameters
        ----------
        opening_deg : float
            The door's opening angle, deg.
        theta_step_deg, phi_step_deg : float
            The table's steps in off-axis angle and azimuth, deg.

        Returns
        -------
        DoorTable
            The unshaded fraction (0-1) on the (theta, phi) grid, interpolated bilinearly.
        """
        theta = np.arange(0.0, 90.0 + theta_step_deg / 2, theta_step_deg)
        phi = np.arange(0.0, 360.0 + phi_step_deg / 2, phi_step_deg)
        # the 90 deg row is the limit from above the aperture plane: exactly in the plane the
        # ray-plate intersection is 0/0 and its rounding broke the table's mirror symmetry
        th, ph = np.meshgrid(np.radians(np.minimum(theta, 90.0 - 1e-6)), np.radians(phi), indexing="ij")
        dirs = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=-1)
        return DoorTable(theta, phi, self.unshaded_fraction(dirs, opening_deg))


@dataclass(frozen=True)
class DoorTable:
    """Precomputed Sp(theta, phi) for one door state over theta 0-90 deg.

    Beyond 90 deg the source is behind the aperture plane and cannot light the aperture: Sp = 0
    (as :meth:`Door.unshaded_fraction`), so the direct path takes nothing from there whatever
    the PST's values behind the plane; light from there reaches the aperture only via the door."""

    theta_deg: np.ndarray
    phi_deg: np.ndarray
    values: np.ndarray

    @cached_property
    def _interp(self):
        return LinearGrid((self.theta_deg, self.phi_deg), self.values)

    @staticmethod
    def coordinates(theta_deg, phi_deg):
        """The table's (theta, phi) of directions: theta clipped to 0-90 deg, phi wrapped to
        0-360 deg (the caller zeroes theta > 90 deg: :func:`behind_aperture_plane`).

        Parameters
        ----------
        theta_deg : array_like
            Off-axis angles, deg.
        phi_deg : array_like
            Azimuths, deg.
        """
        th, ph = np.broadcast_arrays(np.asarray(theta_deg, float), np.asarray(phi_deg, float))
        return np.clip(th, 0.0, 90.0), wrap_360_deg(ph)

    def __call__(self, theta_deg, phi_deg) -> np.ndarray:
        """Sp at directions ``theta_deg`` (off axis) and ``phi_deg`` (azimuth), deg, broadcast
        together: the unshaded fraction of the aperture, 0-1, of their broadcast shape (0 behind
        the aperture plane, theta > 90 deg)."""
        th = np.asarray(theta_deg, float)
        return np.where(behind_aperture_plane(th), 0.0, self._interp(*self.coordinates(th, phi_deg)))


def behind_aperture_plane(theta_deg) -> np.ndarray:
    """Whether directions at ``theta_deg`` off axis lie behind the aperture plane (theta > 90
    deg; NaN: False), where Sp = 0.

    Parameters
    ----------
    theta_deg : array_like
        Off-axis angles, deg.
    """
    with np.errstate(invalid="ignore"):
        return np.asarray(theta_deg, float) > 90.0


def door_state_index(states_deg, opening_deg):
    """(index into the ascending ``states_deg`` of each sample's door state, whether it is one):
    an opening <= 0 (no state allowed) takes the narrowest state; an opening that is no state
    (or NaN) is flagged False (its index is then meaningless).  One compiled pass instead of
    numpy's searchsorted, where and compare (faster; docs/performance.md), as every sample's
    door is looked up several times per evaluation.

    Parameters
    ----------
    states_deg : ndarray
        The door's opening angles, deg, ascending.
    opening_deg : array_like
        Each sample's opening angle, deg (<= 0: no state allowed).
    """
    states = np.ascontiguousarray(states_deg, dtype=float)
    if states.ndim != 1 or states.size == 0:
        raise ValueError(f"door states must be a non-empty 1-d sequence, got {states_deg!r}")
    op = np.asarray(opening_deg, float)
    flat = np.ascontiguousarray(op.ravel())
    index, known = np.empty(flat.size, np.intp), np.empty(flat.size, np.bool_)
    _door_state_kernel(states, flat, index, known)
    return index.reshape(op.shape), known.reshape(op.shape)


@njit(cache=True, nogil=True)
def _door_state_kernel(states, opening, index, known):
    """:func:`door_state_index` per sample: the first state >= the opening (the last if none;
    a short linear scan: a door has a few states), known where it equals the opening."""
    last = states.size - 1
    for p in range(opening.size):
        x = opening[p]
        if x <= 0:
            index[p] = 0
            known[p] = True
            continue
        i = 0
        while i < last and states[i] < x:
            i += 1
        index[p] = i
        known[p] = states[i] == x


def door_from_instrument(instrument: InstrumentSettings | dict) -> Door:
    """The instrument's door (its ``door_geometry`` and aperture): without a length, the one
    :func:`door_length_from_paper` gives for the aperture; without a width, a square plate.
    ``instrument``: its typed settings, or its mapping
    (:func:`~straylight.config.instrument.instrument_settings`).

    Parameters
    ----------
    instrument : InstrumentSettings or dict
        The instrument's typed settings, or its mapping.
    """
    inst = instrument_settings(instrument)
    g = inst.door_geometry
    r = inst.telescope.aperture_diameter_m.value / 2.0
    length = g.length_m.value if g.length_m is not None else door_length_from_paper(r)
    width = g.width_m.value if g.width_m is not None else length
    return Door(
        aperture_radius_m=r,
        length_m=length,
        width_m=width,
        n_aperture=int(g.n_aperture.value),
        body_radius_m=g.body_radius_m.value,
        body_length_m=g.body_length_m.value,
    )
