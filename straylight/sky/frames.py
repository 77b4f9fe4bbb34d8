"""The telescope frame: its axes for each sample and the directions of bodies in it.

Convention (the paper, section 2.3): +Z along the line of sight (LOS); +X towards the Sun's
projection on the focal plane, which is where the aperture door stands ("opens ... aligned with
the solar azimuth"); the spacecraft rolls to keep it so.  Any direction has off-axis angle theta
in [0, 180] and azimuth phi in [0, 360) from +X towards +Y = Z x X.  The Sun is always at phi = 0.

Vectors are Cartesian, GCRS/ICRS axes, last axis of length 3, broadcast over the leading axes
(:mod:`straylight.sky.vectors`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from straylight.sky.vectors import any_perpendicular_xyz, unit_xyz
from straylight.util.kernel_cache import njit

__all__ = ["TelescopeFrame", "telescope_frame"]


@dataclass
class TelescopeFrame:
    """Orthonormal axes (..., 3) of the telescope: z = LOS, x towards the Sun (door side)."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray

    def theta_phi_deg(self, direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Off-axis angle theta in [0, 180] and azimuth phi in [0, 360) of a direction, deg.

        Parameters
        ----------
        direction : ndarray
            Unit directions (ICRS axes), shape (..., 3) broadcastable with the frame's axes.
        """
        d = np.asarray(direction, dtype=float)
        if d.ndim == 1:  # one direction for every frame (a body seen from a cube time step)
            shape = self.z.shape[:-1]
            d_run, index = d[None, None, :], np.zeros(int(np.prod(shape)), np.intp)
        else:
            shape = np.broadcast_shapes(d.shape, self.x.shape, self.y.shape, self.z.shape)[:-1]
            d_run, index = np.broadcast_to(d, shape + (3,)).reshape(1, -1, 3), np.arange(int(np.prod(shape)))
        theta, phi = self.theta_phi_runs_deg(d_run, index, shape)
        return theta[0], phi[0]

    def theta_phi_runs_deg(
        self, d_run: np.ndarray, index: np.ndarray, shape: tuple
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`theta_phi_deg` of bodies whose directions are given per run of samples: unit
        ``d_run`` (B, R, 3), ``index`` (N,) each sample's run, ``shape`` the samples' shape (N
        samples, the frames broadcast to it); (theta, phi) of shape (B,) + shape.  The direction's
        components in the frame in one compiled pass (:func:`_frame_components_kernel`, which
        reads each sample's direction from its run rather than a gathered (B, N, 3) array), the
        arctangents in numpy (its SIMD arctan2 is faster than the compiled loop's libm call).

        Parameters
        ----------
        d_run : ndarray
            Unit directions of B bodies per run of samples (ICRS axes), shape (B, R, 3).
        index : ndarray of int
            Each sample's run, shape (N,).
        shape : tuple of int
            The samples' shape (N samples; the frame's axes broadcast to it).
        """
        frames = [
            np.ascontiguousarray(np.broadcast_to(a, tuple(shape) + (3,)).reshape(-1, 3), dtype=float)
            for a in (self.x, self.y, self.z)
        ]
        comp = np.empty((d_run.shape[0], 4, index.size))
        _frame_components_kernel(
            *frames,
            np.ascontiguousarray(d_run, dtype=float),
            np.ascontiguousarray(index, dtype=np.intp),
            comp,
        )
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

    Parameters
    ----------
    los : ndarray
        Unit lines of sight (ICRS axes), shape (..., 3).
    sun_direction : ndarray
        Unit direction to the Sun from the telescope (ICRS axes), broadcastable with ``los``.
    """
    los, sun_direction = np.broadcast_arrays(
        np.asarray(los, dtype=float), np.asarray(sun_direction, dtype=float)
    )
    shape = los.shape
    axes = np.empty((3,) + shape)
    _frame_kernel(
        np.ascontiguousarray(los.reshape(-1, 3)),
        np.ascontiguousarray(sun_direction.reshape(-1, 3)),
        axes.reshape(3, -1, 3),
    )
    return TelescopeFrame(x=axes[0], y=axes[1], z=axes[2])


@njit(cache=True, nogil=True)
def _frame_kernel(los, sun_direction, axes):
    """:func:`telescope_frame` per sample, into ``axes`` (3, N, 3) = x, y, z: the arithmetic of
    z = unit(los), x = perpendicular_towards(z, sun_direction), y = z x x, operation for
    operation (the same numbers), in one pass instead of a numpy pass per operation."""
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
