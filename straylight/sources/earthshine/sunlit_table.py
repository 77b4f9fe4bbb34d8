"""The sunlit Earth's look-up table, read and interpolated at samples.

The sunlit-Earth coefficients of :meth:`EarthGrid.earthshine_coefficients` (direct through
the PST and via the door, per unit solar irradiance) depend on the scene only through
four quantities, because the problem is symmetric under rotation about the local vertical:

* the satellite's geocentric distance r (one node for a circular orbit),
* the Sun's zenith angle at the sub-satellite point, z_sun (0-180 deg),
* the line of sight's zenith angle at the satellite, zeta (0-180 deg),
* the line of sight's azimuth from the Sun's about the vertical, A (0-180 deg when the PST and
  the door are mirror-symmetric about the Sun's plane, phi -> -phi, as the default is; else
  0-360 deg),

and on the door state, one table per state (:class:`EarthshineLUT`), interpolated linearly in
asinh(c / c_scale) (logarithmic for the large values, linear near zero, so the terminator
interpolates without the log's bias).  The in-field term (the line of sight hitting the Earth)
is not tabulated: it is one ray per sample and jumps at the limb, so it is evaluated directly.

The moonlit-Earth coefficients are bounded (:meth:`EarthshineLUT.moon_bound`: the cap fully lit,
PST at its azimuthal maximum, door fully open), skipped where the bound is below their share of
the tolerance, and elsewhere taken from a table of their own
(:class:`~straylight.sources.earthshine.moonlit_table.MoonlitLUT`).

The table is built with the direct method's Earth-cap grid, validated against the direct sum
and cached by :mod:`straylight.sources.earthshine.sunlit_build`; this module holds the table
object and its look-up (the coordinates and interpolation it shares with the moonlit Earth's
table: :mod:`straylight.sources.earthshine.lookup`; its file and dark runs:
:class:`~straylight.sources.earthshine.table.LampTable`).

Validity: the Sun is taken at infinity (its direction from the satellite and from the Earth's
centre differ by < 3e-6 rad).  Errors against the direct sum: bench/run.py (knob
``earthshine_lut``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from straylight.sky.runs import rows_at, scene_rows
from straylight.sky.vectors import dot, norm, unit, unit_xyz
from straylight.sources.earthshine.lookup import (
    _asinh_grids,
    _lamp_coordinates,
    _per_door_state,
)
from straylight.sources.earthshine.table import LampTable
from straylight.util.kernel_cache import njit

__all__ = ["EarthshineLUT"]


@njit(cache=True, nogil=True)
def _moon_bound_kernel(los, index, up, cos_limit, zi, table, neg_cos_nodes, door_bound, out):
    """:meth:`EarthshineLUT.moon_bound` per sample, in cosines (no arccos): the cosine c of the
    line of sight's zenith angle against the vertical ``up`` of its scene run ``index``;
    infinite where c is not above ``cos_limit`` (the cosine of the limb's zenith angle less
    1 deg: within 1 deg of the limb or below it; NaN too), else 1.2 x the largest of ``table``
    at the Moon zenith nodes zi - 1, zi and the two line-of-sight zenith nodes either side (the
    first node whose cosine is not above c, found in ``neg_cos_nodes``, the nodes' negated
    cosines, increasing), plus ``door_bound``."""
    last = neg_cos_nodes.size - 1
    for p in range(los.shape[0]):
        q = index[p]
        lx, ly, lz = unit_xyz(los[p, 0], los[p, 1], los[p, 2])
        c = min(max(up[q, 0] * lx + up[q, 1] * ly + up[q, 2] * lz, -1.0), 1.0)
        if not c > cos_limit[q]:
            out[p] = np.inf
            continue
        i = min(max(np.searchsorted(neg_cos_nodes, -c), 1), last)
        z0, z1 = zi[q] - 1, zi[q]
        out[p] = (
            1.2 * max(max(table[z0, i - 1], table[z0, i]), max(table[z1, i - 1], table[z1, i])) + door_bound
        )


@dataclass
class EarthshineLUT(LampTable):
    """The sunlit Earth's coefficients (direct through the PST and via the door, per unit solar
    irradiance, outside the field) tabulated over (radius, Sun zenith, line-of-sight zenith,
    azimuth from the Sun) per door state and interpolated linearly in asinh(c / scale), with the
    moonlit Earth's bound (:meth:`moon_bound`).  Built and validated by
    :func:`~straylight.sources.earthshine.sunlit_build.build_earthshine_lut`."""

    radius_km: np.ndarray
    sun_zenith_deg: np.ndarray
    los_zenith_deg: np.ndarray
    azimuth_deg: np.ndarray
    direct: dict  # door state -> array (R, Z, L, A), e-/s/pix per (photon s-1 m-2) of the Sun
    door: dict
    moon_direct_bound: np.ndarray  # (R, Z, L): PST at its maximum over phi, Sp = 1, max over azimuth
    moon_door_bound: float  # door path with the cap fully lit
    symmetric: bool
    scale: float  # asinh scale of the interpolation
    validation_max_rel_error: float = float("nan")  # against the direct sum: see build_earthshine_lut
    build_seconds: float = float("nan")

    FILE_ARRAYS = ("radius_km", "sun_zenith_deg", "los_zenith_deg", "azimuth_deg", "moon_direct_bound")
    FILE_META = {
        "moon_door_bound": float,
        "symmetric": bool,
        "scale": float,
        "validation_max_rel_error": float,
        "build_seconds": float,
    }
    WHAT = "earthshine"
    DARK_ZENITH = "dark_sun_zenith_deg"

    # -- evaluation -----------------------------------------------------------------------------
    def _interpolators(self):
        if not hasattr(self, "_interp"):
            axes = (self.sun_zenith_deg, self.los_zenith_deg, self.azimuth_deg)
            if self.radius_km.size > 1:
                axes = (self.radius_km,) + axes

            # the axes span every coordinate's whole range; one radius: no radius axis
            self._interp = _asinh_grids(
                axes, self.direct, self.door, self.scale, drop_first=self.radius_km.size == 1
            )
        return self._interp

    def coordinates(self, sat_km, sun_km, los, runs=None):
        """(r, z_sun, zeta, A) of samples; arrays of the samples' shape; ``runs``: the samples'
        scene runs when known.

        Parameters
        ----------
        sat_km, sun_km : ndarray, shape (..., 3)
            Geocentric ICRS positions of the satellite and the Sun, km.
        los : ndarray, shape (..., 3)
            Lines of sight, ICRS unit vectors.
        runs : SceneRuns, optional
            The samples' scene runs; None: found here.

        Returns
        -------
        r_km, z_sun_deg, zeta_deg, azimuth_deg : ndarray, shape (...)
            The satellite's geocentric distance (km), the Sun's zenith angle, the line of
            sight's zenith angle and its azimuth from the Sun's (folded to 0-180 when the table
            is symmetric), deg.
        """
        return _lamp_coordinates(sat_km, sun_km, los, self.symmetric, runs=runs)

    def sun_coefficients(self, sat_km, sun_km, los, opening_deg, runs=None):
        """(direct_sun, door_sun) per unit solar irradiance, excluding the in-field term;
        ``runs``: the samples' scene runs when known.  Samples whose Sun zenith angle lies
        beyond :attr:`dark_sun_zenith_deg` (no sunlit Earth in view: every table node from there
        on is 0, so the interpolation gives exactly 0) get 0 without a look-up: a low orbit's
        night side, ~40 % of its samples.

        Parameters
        ----------
        sat_km, sun_km : ndarray, shape (..., 3)
            Geocentric ICRS positions of the satellite and the Sun, km.
        los : ndarray, shape (..., 3)
            Lines of sight, ICRS unit vectors.
        opening_deg : array_like
            Each sample's door opening, deg.
        runs : SceneRuns, optional
            The samples' scene runs; None: found here.

        Returns
        -------
        direct_sun, door_sun : ndarray, shape (...)
            e-/s/pix per photon s-1 m-2 of the Sun at the satellite, >= 0.
        """
        sat, sun, los = np.broadcast_arrays(
            np.asarray(sat_km, float), np.asarray(sun_km, float), np.asarray(los, float)
        )
        shape = los.shape[:-1]
        op = np.broadcast_to(np.asarray(opening_deg, float), shape)
        rows = scene_rows(sat, sun, runs=runs)
        dark_run = self.dark_runs(rows)
        if not np.any(dark_run):
            return self._sun_lookup(sat, sun, los, op, rows)
        lit = np.flatnonzero(~np.take(dark_run, rows.index))
        direct, door = np.zeros(shape), np.zeros(shape)
        if lit.size:
            d, g = self._sun_lookup(
                *(rows_at(v, shape, lit) for v in (sat, sun, los)), op.reshape(-1)[lit], rows.at(lit)
            )
            direct.reshape(-1)[lit], door.reshape(-1)[lit] = d, g
        return direct, door

    def _sun_lookup(self, sat, sun, los, opening_deg, runs):
        """:meth:`sun_coefficients` by look-up at every sample."""
        r, z_sun, zeta, a = self.coordinates(sat, sun, los, runs)
        shape = z_sun.shape
        # one flat array per axis, as the grid reads them (no (samples, axes) stack to copy)
        coords = [v.ravel() for v in (z_sun, zeta, a)]
        if self.radius_km.size > 1:
            coords.insert(0, np.clip(r, self.radius_km[0], self.radius_km[-1]).ravel())
        return _per_door_state(self._interpolators(), coords, opening_deg, shape, self.scale)

    @cached_property
    def dark_sun_zenith_deg(self) -> float:
        """The Sun zenith angle beyond which the table is 0, deg (every node from there on is 0)."""
        return self._dark_zenith_deg(self.sun_zenith_deg, axis=1)

    def moon_bound(self, sat_km, moon_km, los, earth_radius_km: float, runs=None):
        """Upper bound of direct_moon + door_moon per unit lunar irradiance at the Earth: the
        larger of the four neighbouring (Moon zenith, line-of-sight zenith) nodes (largest
        radius node), x 1.2 for the azimuth between nodes; infinite for a line of sight less
        than 1 deg above the limb or below it (there a grid block can sit next to the field
        edge, where the PST jumps, and no table bounds it).  ``runs``: the samples' scene runs
        when known.

        Parameters
        ----------
        sat_km, moon_km : ndarray, shape (..., 3)
            Geocentric ICRS positions of the satellite and the Moon, km.
        los : ndarray, shape (..., 3)
            Lines of sight, ICRS unit vectors.
        earth_radius_km : float
            The Earth's radius, km.
        runs : SceneRuns, optional
            The samples' scene runs; None: found here.

        Returns
        -------
        ndarray, shape (...)
            The bound, e-/s/pix per photon s-1 m-2 of the Moon at the Earth (inf where none).
        """
        sat, moon, los = np.broadcast_arrays(
            np.asarray(sat_km, float), np.asarray(moon_km, float), np.asarray(los, float)
        )
        shape = los.shape[:-1]
        if not hasattr(self, "_moon_bound_table"):
            # (Z, L), the worst radius
            self._moon_bound_table = np.ascontiguousarray(self.moon_direct_bound.max(axis=0))
        # the satellite's and the Moon's parts once per run of samples sharing them (a cube's time step)
        rows = scene_rows(sat, moon, runs=runs)
        (sat_r, moon_r), index = rows.vectors, rows.index
        r = norm(sat_r)
        up = sat_r / r[:, None]
        z_moon = np.degrees(np.arccos(np.clip(dot(up, unit(moon_r)), -1, 1)))
        limb = 90.0 + np.degrees(np.arccos(np.clip(earth_radius_km / r, -1, 1)))
        zi = np.clip(np.searchsorted(self.sun_zenith_deg, z_moon), 1, self.sun_zenith_deg.size - 1)
        out = np.empty(index.size)
        _moon_bound_kernel(
            np.ascontiguousarray(los.reshape(-1, 3)),
            np.ascontiguousarray(index, dtype=np.intp),
            np.ascontiguousarray(up),
            np.cos(np.radians(limb - 1.0)),
            zi,
            self._moon_bound_table,
            -np.cos(np.radians(self.los_zenith_deg)),
            float(self.moon_door_bound),
            out,
        )
        return out.reshape(shape)
