"""The earthshine look-up tables, read and interpolated at samples.

The sunlit-Earth coefficients of :meth:`OffFieldModel.earthshine_coefficients` (direct through
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
the tolerance, and elsewhere taken from a table of their own (:class:`MoonlitLUT`), which runs
over one angle more, the telescope's roll: it is set by the Sun, not by the Moon.

The tables are built with the direct method's Earth-cap grid, validated against the direct sum
and cached by :mod:`straylight.sources.earthshine_table_build`; this module holds the table
objects, their files (``save``, ``load``) and the look-up.

Validity: the Sun is taken at infinity (its direction from the satellite and from the Earth's
centre differ by < 3e-6 rad).  Errors against the direct sum: bench/run.py (knob
``earthshine_lut``).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np
from numba import njit

from straylight.errors import InputError
from straylight.optics.door import door_state_index
from straylight.sky.runs import rows_at, scene_rows
from straylight.sky.vectors import any_perpendicular_xyz, dot, norm, unit, unit_xyz
from straylight.util.gridinterp import LinearGrid

__all__ = ["EarthshineLUT", "MoonlitLUT"]


def _asinh_grids(axes, direct: dict, door: dict, scale: float, drop_first: bool = False) -> tuple:
    """(door states ascending, one LinearGrid of asinh(c / scale) on ``axes`` whose channels are
    each state's direct and door terms in turn): a sample's cell is located once whatever its
    state; ``drop_first``: the tables' first axis has one node."""
    states = sorted(direct)
    v = np.arcsinh(np.stack([np.stack([direct[s], door[s]], axis=-1) for s in states], axis=-2) / scale)
    v = v.reshape(v.shape[:-2] + (2 * len(states),))
    return states, LinearGrid(
        axes, v[0] if drop_first else v, channel_group=2
    )  # read a state's pair at a time


def _per_door_state(interpolator: tuple, coords, opening_deg, shape, scale: float):
    """(direct, door) at ``coords`` (flat arrays) from :func:`_asinh_grids`' grid of asinh(c /
    scale), each sample from its own door state's channels; a sample with no allowed state
    (opening 0) takes the narrowest, one with an opening that is no state gets 0; clipped at 0."""
    states, grid = interpolator
    op = np.broadcast_to(np.asarray(opening_deg, float), shape).ravel()
    state_of, known = door_state_index(states, op)
    both = grid(*coords, channel=np.where(known, state_of, 0), group=2).reshape(op.size, 2)
    both = np.maximum(scale * np.sinh(both), 0.0)
    if not np.all(known):
        both[~known] = 0.0
    return both[:, 0].reshape(shape), both[:, 1].reshape(shape)


def _save_tables(path, axes: dict, direct: dict, door: dict, meta: dict) -> None:
    """Axes, per-door-state tables and metadata to one .npz, atomically (concurrent builders
    never share a temporary)."""
    p = Path(path)
    tmp = p.with_name(f"{p.stem}.{os.getpid()}.partial.npz")
    arrays = dict(axes)
    for s in direct:
        arrays[f"direct_{s:g}"] = direct[s]
        arrays[f"door_{s:g}"] = door[s]
    np.savez(tmp, meta=np.array(json.dumps({"states": [float(s) for s in direct], **meta})), **arrays)
    tmp.replace(p)


def _load_tables(path, what: str):
    """(arrays, metadata, direct, door) of a table :func:`_save_tables` wrote; InputError naming
    the file when it is not one."""
    try:
        z = np.load(path, allow_pickle=False)
        meta = json.loads(str(z["meta"]))
        states = meta["states"]
        return z, meta, {s: z[f"direct_{s:g}"] for s in states}, {s: z[f"door_{s:g}"] for s in states}
    except (OSError, KeyError, ValueError) as exc:
        raise InputError(f"{path}: not a valid {what} look-up table ({exc}); delete it to rebuild") from exc


def _dark_lamp_zenith_deg(zenith_nodes_deg, tables, axis: int) -> float:
    """The lamp zenith angle beyond which ``tables`` (each with the lamp's zenith angle along
    ``axis``) are 0: the first node of the all-zero slabs that run to the axis' end, in every
    table, plus 1e-6 deg, so that a point within rounding of that node (which the cell finder
    may place in the cell below) is still looked up; inf when the last slab is not 0.
    Beyond it the interpolation gives exactly 0 and no look-up is needed."""
    nonzero = np.zeros(zenith_nodes_deg.size, bool)
    for table in tables:
        nonzero |= np.any(
            np.moveaxis(np.asarray(table), axis, 0).reshape(zenith_nodes_deg.size, -1) != 0, axis=1
        )
    lit = np.flatnonzero(nonzero)
    first = 0 if lit.size == 0 else int(lit[-1]) + 1
    return float(zenith_nodes_deg[first]) + 1e-6 if first < zenith_nodes_deg.size else float("inf")


def _lamp_zenith_deg(sat_km, lamp_km) -> np.ndarray:
    """The lamp's zenith angle (deg) seen from the satellite's vertical: the angle between the
    geocentric satellite and lamp (Sun or Moon) directions, (..., 3) -> (...)."""
    return np.degrees(np.arccos(np.clip(dot(unit(sat_km), unit(lamp_km)), -1.0, 1.0)))


def _beyond_dark_zenith(rows, dark_zenith_deg: float) -> np.ndarray:
    """Per run of ``rows`` (scene runs of (satellite, lamp)): whether the lamp's zenith angle
    lies beyond ``dark_zenith_deg`` (:func:`_dark_lamp_zenith_deg`: the table is 0 there)."""
    return _lamp_zenith_deg(rows.vectors[0], rows.vectors[1]) > dark_zenith_deg


def _lamp_coordinates(sat_km, lamp_km, los, symmetric: bool, frame_xy=None, runs=None):
    """The tables' coordinates of samples: (radius km, the lamp's zenith angle, the line of
    sight's zenith angle, its azimuth from the lamp's about the vertical, and with ``frame_xy``
    (the telescope frame's x and y axes, (..., 3)) the roll), deg, arrays of the samples' shape.
    ``lamp_km``: the geocentric Sun or Moon.  The azimuth is folded to [0, 180] when
    ``symmetric`` (the instrument mirror-symmetric about the lamp's vertical plane; the roll then
    changes sign with it), else wrapped to [0, 360); the roll is wrapped to [0, 360).

    The satellite's and the lamp's parts (the vertical, the lamp's zenith angle, its horizontal
    direction) once per run of samples that share them (a cube's time step), the rest per sample:
    the vectors' components in one compiled pass (:func:`_los_components_kernel`), the angles
    from them in numpy.  ``runs``: the samples' scene runs when known
    (:class:`~straylight.sky.runs.SceneRuns`)."""
    sat, lamp, los = np.broadcast_arrays(
        np.asarray(sat_km, float), np.asarray(lamp_km, float), np.asarray(los, float)
    )
    shape = los.shape[:-1]
    rows = scene_rows(sat, lamp, runs=runs)
    (sat_r, lamp_r), index = rows.vectors, rows.index
    r = norm(sat_r)
    up = unit(sat_r)
    lamp_u = unit(lamp_r)
    z_lamp = _lamp_zenith_deg(sat_r, lamp_r)
    lamp_h = lamp_u - dot(lamp_u, up)[:, None] * up  # its horizontal part
    with_roll = frame_xy is not None
    # the components in one compiled pass, the angles in numpy (its SIMD arccos and arctan2 are
    # several times the compiled loop's libm calls here)
    comp = np.empty((5 if with_roll else 3, index.size))
    xy = (
        [np.ascontiguousarray(np.broadcast_to(a, shape + (3,)).reshape(-1, 3), dtype=float) for a in frame_xy]
        if with_roll
        else [np.zeros((0, 3))] * 2
    )
    _los_components_kernel(
        np.ascontiguousarray(los.reshape(-1, 3)),
        *xy,
        np.ascontiguousarray(index, dtype=np.intp),
        np.ascontiguousarray(up),
        np.ascontiguousarray(lamp_h),
        np.ascontiguousarray(np.cross(up, lamp_h)),
        comp,
    )
    deg = 180.0 / np.pi
    zenith = np.arccos(comp[0])
    zenith *= deg
    azimuth = np.arctan2(comp[1], comp[2])
    azimuth *= deg
    mirrored = azimuth < 0.0
    out = [zenith, azimuth]
    if with_roll:
        roll = np.arctan2(comp[3], comp[4])
        roll *= deg
        if symmetric:  # the mirror image about the lamp's vertical plane: (A, roll) -> (-A, -roll)
            np.negative(roll, out=roll, where=mirrored)
        np.add(roll, 360.0, out=roll, where=roll < 0.0)
        out.append(roll)
    if symmetric:
        np.abs(azimuth, out=azimuth)
    else:
        np.add(azimuth, 360.0, out=azimuth, where=mirrored)
    return (r[index].reshape(shape), z_lamp[index].reshape(shape)) + tuple(v.reshape(shape) for v in out)


@njit(cache=True, nogil=True)
def _los_components_kernel(los, x, y, index, up, lamp_h, up_x_lamp_h, out):
    """:func:`_lamp_coordinates`' arguments per sample, into ``out`` (3 or 5, N): the cosine of
    the line of sight's zenith angle (clipped to [-1, 1]); the azimuth's arctangent arguments
    los . (up x h), los . h (h the lamp's horizontal direction; = (h x los_h) . up, h . los_h,
    los_h the line of sight's horizontal part); and, where ``x`` and ``y`` are given, the roll's,
    -up_ref . y, up_ref . x: the angle from the upward direction in the line of sight's vertical
    plane (up projected across the line of sight) to the frame's x axis about the line of sight;
    along the vertical, where up_ref vanishes, celestial north projected (else +X:
    geometry.perpendicular_towards).  Lines of sight of any length (normalised here; zero or NaN
    ones count as zero vectors, as unit makes them)."""
    roll = x.shape[0] > 0
    for p in range(los.shape[0]):
        q = index[p]
        lx, ly, lz = unit_xyz(los[p, 0], los[p, 1], los[p, 2])
        ux, uy, uz = up[q, 0], up[q, 1], up[q, 2]
        c = lx * ux + ly * uy + lz * uz
        out[0, p] = min(max(c, -1.0), 1.0)
        out[1, p] = lx * up_x_lamp_h[q, 0] + ly * up_x_lamp_h[q, 1] + lz * up_x_lamp_h[q, 2]
        out[2, p] = lx * lamp_h[q, 0] + ly * lamp_h[q, 1] + lz * lamp_h[q, 2]
        if roll:
            px, py, pz = ux - c * lx, uy - c * ly, uz - c * lz
            if not np.sqrt(px * px + py * py + pz * pz) > 1e-9:
                px, py, pz, _ = any_perpendicular_xyz(lx, ly, lz)
            out[3, p] = -(px * y[p, 0] + py * y[p, 1] + pz * y[p, 2])
            out[4, p] = px * x[p, 0] + py * x[p, 1] + pz * x[p, 2]


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
class EarthshineLUT:
    """The sunlit Earth's coefficients (direct through the PST and via the door, per unit solar
    irradiance, outside the field) tabulated over (radius, Sun zenith, line-of-sight zenith,
    azimuth from the Sun) per door state and interpolated linearly in asinh(c / scale), with the
    moonlit Earth's bound (:meth:`moon_bound`).  Built and validated by
    :func:`~straylight.sources.earthshine_table_build.build_earthshine_lut`."""

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
        """The Sun zenith angle beyond which the table is 0, deg (:func:`_dark_lamp_zenith_deg`)."""
        return _dark_lamp_zenith_deg(
            self.sun_zenith_deg, (*self.direct.values(), *self.door.values()), axis=1
        )

    def dark_runs(self, rows) -> np.ndarray:
        """Per run of ``rows`` (scene runs of (satellite, Sun)): no sunlit Earth in view, the
        table 0 (beyond :attr:`dark_sun_zenith_deg`).

        Parameters
        ----------
        rows : SceneRuns
            Scene runs of (satellite, Sun) positions, km.

        Returns
        -------
        ndarray of bool, shape (runs,)
        """
        return _beyond_dark_zenith(rows, self.dark_sun_zenith_deg)

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

    # -- storage --------------------------------------------------------------------------------
    def save(self, path) -> None:
        """Write the table to ``path``.

        Parameters
        ----------
        path : str or Path
            The .npz file, written atomically (its axes, one direct and one door table per door
            state, and the metadata as JSON).
        """
        _save_tables(
            path,
            {
                "radius_km": self.radius_km,
                "sun_zenith_deg": self.sun_zenith_deg,
                "los_zenith_deg": self.los_zenith_deg,
                "azimuth_deg": self.azimuth_deg,
                "moon_direct_bound": self.moon_direct_bound,
            },
            self.direct,
            self.door,
            {
                "moon_door_bound": self.moon_door_bound,
                "symmetric": self.symmetric,
                "scale": self.scale,
                "validation_max_rel_error": self.validation_max_rel_error,
                "build_seconds": self.build_seconds,
            },
        )

    @classmethod
    def load(cls, path) -> "EarthshineLUT":
        """Read a table :meth:`save` wrote.

        Parameters
        ----------
        path : str or Path
            A .npz file :meth:`save` wrote.

        Returns
        -------
        EarthshineLUT

        Raises
        ------
        InputError
            When the file cannot be read or is not such a table.
        """
        z, meta, direct, door = _load_tables(path, "earthshine")
        return cls(
            z["radius_km"],
            z["sun_zenith_deg"],
            z["los_zenith_deg"],
            z["azimuth_deg"],
            direct,
            door,
            z["moon_direct_bound"],
            float(meta["moon_door_bound"]),
            bool(meta["symmetric"]),
            float(meta["scale"]),
            float(meta["validation_max_rel_error"]),
            float(meta["build_seconds"]),
        )


@dataclass
class MoonlitLUT:
    """The moonlit Earth's coefficients (direct and via the door, per unit lunar irradiance at
    the Earth, outside the field) on the coarse Earth-cap ``grid`` the direct path sums
    (models.earthshine.moonlit_grid), tabulated over (Moon zenith, line-of-sight zenith,
    azimuth from the Moon, roll) per door state and interpolated linearly in asinh(c / scale).
    The satellite's radius and the Moon's distance are fixed at the orbit's mean and the
    Moon's mean; the validation draws both over their ranges.  Built and validated by
    :func:`~straylight.sources.earthshine_table_build.build_moonlit_lut`."""

    moon_zenith_deg: np.ndarray
    los_zenith_deg: np.ndarray
    azimuth_deg: np.ndarray
    roll_deg: np.ndarray
    direct: dict  # door state -> (Zm, L, A, P)
    door: dict
    symmetric: bool
    scale: float
    grid: tuple
    validation_max_rel_error: float = float("nan")
    build_seconds: float = float("nan")

    def _interpolators(self):
        if not hasattr(self, "_interp"):
            axes = (self.moon_zenith_deg, self.los_zenith_deg, self.azimuth_deg, self.roll_deg)
            self._interp = _asinh_grids(axes, self.direct, self.door, self.scale)
        return self._interp

    @cached_property
    def dark_moon_zenith_deg(self) -> float:
        """The Moon zenith angle beyond which the table is 0, deg (:func:`_dark_lamp_zenith_deg`)."""
        return _dark_lamp_zenith_deg(
            self.moon_zenith_deg, (*self.direct.values(), *self.door.values()), axis=0
        )

    def dark_runs(self, rows) -> np.ndarray:
        """Per run of ``rows`` (scene runs of (satellite, Moon)): no moonlit Earth in view, the
        table 0 (beyond :attr:`dark_moon_zenith_deg`).

        Parameters
        ----------
        rows : SceneRuns
            Scene runs of (satellite, Moon) positions, km.

        Returns
        -------
        ndarray of bool, shape (runs,)
        """
        return _beyond_dark_zenith(rows, self.dark_moon_zenith_deg)

    def coordinates(self, sat_km, moon_km, frame, runs=None):
        """(Moon zenith, line-of-sight zenith, azimuth from the Moon, roll) of samples, deg;
        ``runs``: the samples' scene runs when known.

        Parameters
        ----------
        sat_km, moon_km : ndarray, shape (..., 3)
            Geocentric ICRS positions of the satellite and the Moon, km.
        frame : TelescopeFrame
            The samples' telescope frames, axes (..., 3).
        runs : SceneRuns, optional
            The samples' scene runs; None: found here.

        Returns
        -------
        z_moon_deg, zeta_deg, azimuth_deg, roll_deg : ndarray, shape (...)
            Angles, deg.
        """
        return _lamp_coordinates(sat_km, moon_km, frame.z, self.symmetric, (frame.x, frame.y), runs)[1:]

    def coefficients(self, sat_km, moon_km, frame, opening_deg, runs=None):
        """(direct_moon, door_moon) per unit lunar irradiance at the Earth, outside the field;
        ``runs``: the samples' scene runs when known.

        Parameters
        ----------
        sat_km, moon_km : ndarray, shape (..., 3)
            Geocentric ICRS positions of the satellite and the Moon, km.
        frame : TelescopeFrame
            The samples' telescope frames, axes (..., 3).
        opening_deg : array_like
            Each sample's door opening, deg.
        runs : SceneRuns, optional
            The samples' scene runs; None: found here.

        Returns
        -------
        direct_moon, door_moon : ndarray, shape (...)
            e-/s/pix per photon s-1 m-2 of the Moon at the Earth, >= 0.
        """
        zm, zeta, a, roll = self.coordinates(sat_km, moon_km, frame, runs)
        shape = zm.shape
        return _per_door_state(
            self._interpolators(), [v.ravel() for v in (zm, zeta, a, roll)], opening_deg, shape, self.scale
        )

    def save(self, path) -> None:
        """Write the table to ``path``.

        Parameters
        ----------
        path : str or Path
            The .npz file, written atomically (its axes, one direct and one door table per door
            state, and the metadata as JSON).
        """
        _save_tables(
            path,
            {
                "moon_zenith_deg": self.moon_zenith_deg,
                "los_zenith_deg": self.los_zenith_deg,
                "azimuth_deg": self.azimuth_deg,
                "roll_deg": self.roll_deg,
            },
            self.direct,
            self.door,
            {
                "symmetric": self.symmetric,
                "scale": self.scale,
                "grid": list(self.grid),
                "validation_max_rel_error": self.validation_max_rel_error,
                "build_seconds": self.build_seconds,
            },
        )

    @classmethod
    def load(cls, path) -> "MoonlitLUT":
        """Read a table :meth:`save` wrote.

        Parameters
        ----------
        path : str or Path
            A .npz file :meth:`save` wrote.

        Returns
        -------
        MoonlitLUT

        Raises
        ------
        InputError
            When the file cannot be read or is not such a table.
        """
        z, meta, direct, door = _load_tables(path, "moonlit-Earth")
        return cls(
            z["moon_zenith_deg"],
            z["los_zenith_deg"],
            z["azimuth_deg"],
            z["roll_deg"],
            direct,
            door,
            bool(meta["symmetric"]),
            float(meta["scale"]),
            tuple(meta["grid"]),
            float(meta["validation_max_rel_error"]),
            float(meta["build_seconds"]),
        )
