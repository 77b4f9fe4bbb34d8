"""The moonlit Earth's look-up table: its build, its validation and its cache.

The table (:class:`~straylight.sources.earthshine.moonlit_table.MoonlitLUT`) holds the direct sum of
:class:`~straylight.sources.earthshine.engine.EarthGrid` on the coarse Earth-cap grid at its nodes
(:class:`~straylight.sources.earthshine.nodes.MoonlitSettings`), built one Moon zenith
angle per task in threads as the sunlit Earth's table is
(:func:`~straylight.sources.earthshine.table.build_lamp_table`), validated against the direct sum at random
points (any Moon, roll, radius and Moon distance) and cached under a digest of everything it
depends on (:func:`load_or_build_moonlit`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from straylight.sources.body_magnitudes import MOON_APOGEE_KM, MOON_MEAN_DISTANCE_KM, MOON_PERIGEE_KM
from straylight.sources.earthshine.moonlit_table import MoonlitLUT
from straylight.sources.earthshine.nodes import (
    MOONLIT_LUT_BUILD_SECONDS_PER_NODE,
    MoonlitInputs,
    _cached,
    cache_path,
    mirror_symmetric,
    moonlit_key,
)
from straylight.sources.earthshine.sums import Bodies
from straylight.sources.earthshine.table import TableScenes, build_lamp_table

__all__ = [
    "MoonlitPoints",
    "build_moonlit_lut",
    "load_or_build_moonlit",
]


def _moonlit_scene(R, D, Zm, L, A, P):
    """Satellite and Moon (km) and the telescope frame in the local frame (vertical +x, the Moon
    in the x-y plane): radius R, Moon distance D (km), Moon zenith Zm, line-of-sight zenith L,
    azimuth A and roll P (rad)."""
    from straylight.sky.frames import TelescopeFrame

    sat = np.stack([R, 0 * R, 0 * R], axis=-1)
    moon = D[..., None] * np.stack([np.cos(Zm), np.sin(Zm), 0 * Zm], axis=-1)
    los = np.stack([np.cos(L), np.sin(L) * np.cos(A), np.sin(L) * np.sin(A)], axis=-1)
    up_ref = np.stack(
        [np.sin(L), -np.cos(L) * np.cos(A), -np.cos(L) * np.sin(A)], axis=-1
    )  # upward, in the vertical plane
    x = np.cos(P)[..., None] * up_ref + np.sin(P)[..., None] * np.cross(los, up_ref)
    return sat, moon, TelescopeFrame(x=x, y=np.cross(los, x), z=los)


class MoonlitPoints(NamedTuple):
    """Scenes in the local frame of the moonlit table (vertical +x, the Moon in the x-y plane)."""

    radius_km: np.ndarray
    """The satellite's geocentric radius, km."""
    moon_distance_km: np.ndarray
    """The Moon's geocentric distance, km."""
    moon_zenith_rad: np.ndarray
    los_zenith_rad: np.ndarray
    azimuth_rad: np.ndarray
    """The line of sight's azimuth from the Moon's vertical plane, rad."""
    roll_rad: np.ndarray

    def at(self, index) -> MoonlitPoints:
        """The scenes at ``index`` (a slice or an index array)."""
        return MoonlitPoints(*(v[index] for v in self))


def _moon_coefficients_direct(off, points: MoonlitPoints, state, earth_radius_km, grid):
    """(direct_moon, door_moon) of the moonlit Earth on the Earth-cap ``grid``, per unit lunar
    irradiance at the Earth, for scenes in the local frame (rad, km), one door state (or,
    ``state`` None, every door state: arrays (samples, door states ascending)); samples sharing
    (radius, Moon distance, Moon zenith) share one cap grid."""
    R, D, Zm = points.radius_km, points.moon_distance_km, points.moon_zenith_rad
    n_states = len(off.door_states_deg)
    sel = np.arange(n_states) if state is None else np.array([sorted(off.door_states_deg).index(state)])
    d_out, g_out = np.empty((R.size, sel.size)), np.empty((R.size, sel.size))
    groups = {}
    for i, key in enumerate(zip(R.tolist(), D.tolist(), Zm.tolist())):
        groups.setdefault(key, []).append(i)
    es = off.cap_settings(grid)
    for idx in groups.values():
        idx = np.asarray(idx)
        sat, moon, frame = _moonlit_scene(*points.at(idx))
        d, g = off.earthshine_scene_sums(
            Bodies(sat[0], moon[0], moon[0]),
            frame,
            earth_radius_km,
            np.broadcast_to(sel, (idx.size, sel.size)),
            with_sun=False,
            s=es,
        )
        d_out[idx], g_out[idx] = d[:, :, 1], g[:, :, 1]
    return (d_out[:, 0], g_out[:, 0]) if state is not None else (d_out, g_out)


def _validation_points(inputs: MoonlitInputs, n: int) -> MoonlitPoints:
    """``n`` random scenes whose line of sight is at least the dark-limb angle above the limb:
    any Moon, roll, radius in the orbit's range and Moon distance from perigee to apogee."""
    radius_range_km = inputs.radius_range_km
    rng = np.random.default_rng(20261122)
    limb = 90.0 + np.degrees(np.arccos(inputs.earth_radius_km / radius_range_km[0]))
    vr = rng.uniform(radius_range_km[0], radius_range_km[1], n)
    vd = rng.uniform(MOON_PERIGEE_KM, MOON_APOGEE_KM, n)
    vz, vl = (
        np.radians(rng.uniform(0.0, 180.0, n)),
        np.radians(rng.uniform(0.0, max(limb - inputs.dark_limb_min_deg, 1.0), n)),
    )
    va, vp = np.radians(rng.uniform(0.0, 360.0, n)), np.radians(rng.uniform(0.0, 360.0, n))
    return MoonlitPoints(vr, vd, vz, vl, va, vp)


def build_moonlit_lut(inputs: MoonlitInputs, n_validation: int = 400, workers: int = 1) -> MoonlitLUT:
    """The moonlit Earth's table on the Earth-cap ``inputs.grid``: tabulate, then validate at
    ``n_validation`` random points whose line of sight is at least ``inputs.dark_limb_min_deg``
    above the limb (any Moon, roll, radius in the orbit's range and Moon distance from perigee
    to apogee): the largest |table - direct| x moon_max / (direct x moon_max + floor), with
    ``moon_max`` the brightest lunar irradiance (full Moon at perigee) and ``floor`` the darkest
    sky, both per unit solar irradiance at 1 AU: an error as a fraction of the total, at full
    Moon (a pessimistic one).  The table is built at the radius range's middle.

    Parameters
    ----------
    inputs : MoonlitInputs
        The Earth grid, the Earth's radius, the orbit's radius range, the node steps, the coarse
        grid, the floor (0: no validation, the error is then NaN), the brightest Moon and the
        dark-limb angle.
    n_validation : int
        Validation points.
    workers : int
        Threads.

    Returns
    -------
    MoonlitLUT
        With ``validation_max_rel_error`` (a fraction of the total) and ``build_seconds``.
    """
    off, earth_radius_km, radius_range_km, settings, grid = inputs[:5]
    floor, moon_max = inputs.floor, inputs.moon_max
    symmetric = mirror_symmetric(off)
    r0 = 0.5 * (radius_range_km[0] + radius_range_km[1])
    zm, zl, az, roll = settings.nodes(float(radius_range_km[0]), earth_radius_km, symmetric)
    Zm, L, A, P = (
        v.ravel() for v in np.meshgrid(*(np.radians(v) for v in (zm, zl, az, roll)), indexing="ij")
    )
    # built at the Moon's mean distance; the validation draws perigee to apogee, so the
    # parallax this ignores is inside the validated error
    nodes = MoonlitPoints(np.full(Zm.size, r0), np.full(Zm.size, MOON_MEAN_DISTANCE_KM), Zm, L, A, P)
    per_zm = zl.size * az.size * roll.size  # nodes of one Moon zenith are contiguous: one scene
    tasks = [
        (off, nodes.at(p), None, earth_radius_km, tuple(grid))
        for p in (slice(i * per_zm, (i + 1) * per_zm) for i in range(zm.size))
    ]
    shape = (zm.size, zl.size, az.size, roll.size)

    def make(direct, door, scale, results):
        return MoonlitLUT(zm, zl, az, roll, direct, door, symmetric, scale, tuple(int(g) for g in grid))

    n = n_validation
    points = _validation_points(inputs, n)
    sat_v, moon_v, frame_v = _moonlit_scene(*points)

    def error_at(lut, state):
        d_ref, g_ref = _moon_coefficients_direct(off, points, state, earth_radius_km, grid)
        d_t, g_t = lut.coefficients(sat_v, moon_v, frame_v, np.full(n, state))
        return np.abs((d_t + g_t) - (d_ref + g_ref)) * moon_max / ((d_ref + g_ref) * moon_max + floor)

    scenes = TableScenes(_moon_coefficients_direct, tasks, shape, "moonlit-Earth table")
    return build_lamp_table(off, scenes, make, error_at, floor, workers)


def load_or_build_moonlit(inputs: MoonlitInputs, log=None, workers: int = 1):
    """The moonlit table for these inputs from the cache, built and stored there if missing.

    Parameters
    ----------
    inputs : MoonlitInputs
        As for :func:`build_moonlit_lut`.
    log : logging.Logger, optional
        Announces a build as a warning; None: silent.
    workers : int
        Threads.

    Returns
    -------
    lut : MoonlitLUT
    path : Path
        Its cache file.

    Raises
    ------
    InputError
        When the cached file is not a valid table.
    """
    off, earth_radius_km, radius_range_km, settings = inputs[:4]
    key = moonlit_key(*inputs)
    nodes = settings.node_count(float(radius_range_km[0]), earth_radius_km, mirror_symmetric(off))
    expected = MOONLIT_LUT_BUILD_SECONDS_PER_NODE * nodes * len(off.door_states_deg)
    if log is not None and not cache_path("moonlit_lut", key).exists():  # this machine, now
        from straylight.sources.earthshine.sunlit_build import build_speed_factor

        expected *= build_speed_factor(off, earth_radius_km, radius_range_km, None, workers)
    return _cached(
        "moonlit_lut",
        key,
        "moonlit-Earth",
        MoonlitLUT.load,
        lambda: build_moonlit_lut(inputs, workers=workers),
        log,
        expected,
        workers,
    )
