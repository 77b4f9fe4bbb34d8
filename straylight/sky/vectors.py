"""Vector arithmetic on Cartesian 3-vectors, vectorised over samples.

Every function takes vectors in GCRS/ICRS axes with the last axis of length 3 and broadcasts over
the leading axes, so a (T, 1, 3) satellite position against (1, P, 3) pointing vectors gives
(T, P) results, and (N, 3) against (N, 3) gives N paired samples.  Angles between vectors use
``atan2(|a x b|, a . b)``, accurate at 0 and 180 deg (the paper, sections 2.3 and 3.1).  The
``*_xyz`` functions are the same arithmetic on one vector, for compiled kernels.
"""

from __future__ import annotations

import numpy as np

from straylight.errors import InputError
from straylight.util.kernel_cache import njit

__all__ = [
    "angle_between_deg",
    "any_perpendicular_xyz",
    "dot",
    "norm",
    "perpendicular_towards",
    "radec_to_unit",
    "unit",
    "unit_xyz",
    "wrap_360_deg",
]


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dot product over the last axis (of length 3), broadcasting.

    Parameters
    ----------
    a : ndarray
        Vectors, shape (..., 3).
    b : ndarray
        Vectors, shape (..., 3), broadcastable with ``a``.
    """
    a, b = np.asarray(a), np.asarray(b)
    if a.shape[-1] != 3 or b.shape[-1] != 3:  # every caller's vectors are 3-vectors
        raise ValueError(f"dot: expected 3-vectors, got shapes {a.shape} and {b.shape}")
    # three products and two sums: faster than einsum on (N, 3) arrays
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def norm(a: np.ndarray) -> np.ndarray:
    """Euclidean norm over the last axis (of length 3), broadcasting.

    Parameters
    ----------
    a : ndarray, shape (..., 3)
        Vectors, any unit.

    Returns
    -------
    ndarray, shape (...)
        Their lengths, in the unit of ``a``.
    """
    return np.sqrt(dot(a, a))


def unit(a: np.ndarray) -> np.ndarray:
    """Unit vectors along the last axis (a zero vector stays zero).

    Parameters
    ----------
    a : ndarray
        Vectors, shape (..., 3), any unit.
    """
    n = norm(a)[..., None]
    return np.divide(a, n, out=np.zeros(np.broadcast(a, n).shape), where=n > 0)


def wrap_360_deg(angle_deg) -> np.ndarray:
    """``np.mod(angle_deg, 360.0)``, the same values (-0.0 may stay -0.0), without its slow
    floating-point modulo where every angle already lies within (-360, 360) deg (an arctan2's,
    or one already wrapped: then only its negatives move, by 360).

    Parameters
    ----------
    angle_deg : array_like
        Angles, deg.
    """
    a = np.asarray(angle_deg, dtype=float)
    if a.size and a.min() > -360.0 and a.max() < 360.0:  # NaN fails both: np.mod below
        return a if a.min() >= 0.0 else np.where(a < 0.0, a + 360.0, a)
    return np.mod(a, 360.0)


def angle_between_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle in degrees between vectors a and b (any lengths), stable at 0 and 180 deg.

    Parameters
    ----------
    a : ndarray
        Vectors, shape (..., 3), any length.
    b : ndarray
        Vectors, shape (..., 3), broadcastable with ``a``.
    """
    a, b = np.broadcast_arrays(a, b)
    return np.degrees(np.arctan2(norm(np.cross(a, b)), dot(a, b)))


def radec_to_unit(ra_deg, dec_deg, field: str = "pointing") -> np.ndarray:
    """Unit vectors (..., 3) for RA/Dec in degrees; NaN or |Dec| > 90 raise InputError.

    Parameters
    ----------
    ra_deg : array_like
        Right ascension, deg.
    dec_deg : array_like
        Declination, deg, within [-90, 90].
    field : str, optional
        The input's name in an error message (default ``"pointing"``).
    """
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
    NaN vector gives the zero vector.

    Parameters
    ----------
    x, y, z : float
        The vector's components, any unit.
    """
    n = np.sqrt(x * x + y * y + z * z)
    if n > 0.0:
        return x / n, y / n, z / n
    return 0.0, 0.0, 0.0


@njit(cache=True, nogil=True)
def any_perpendicular_xyz(vx, vy, vz):
    """:func:`_any_perpendicular` of one unit vector inside a compiled kernel, the same
    arithmetic: (px, py, pz, length), not yet normalised.

    Parameters
    ----------
    vx, vy, vz : float
        The unit vector's components.
    """
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

    Parameters
    ----------
    v : ndarray
        Unit vectors, shape (..., 3).
    target : ndarray
        Vectors towards which the result points, shape (..., 3), broadcastable with ``v``.
    """
    v, target = np.broadcast_arrays(v, unit(target))
    p = target - dot(target, v)[..., None] * v
    degenerate = ~(norm(p) > 1e-9)  # NaN counts as degenerate
    if not np.any(degenerate):  # the fallback is rare: computed only when needed
        return unit(p)
    return np.where(degenerate[..., None], _any_perpendicular(v), unit(p))
