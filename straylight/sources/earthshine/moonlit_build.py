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

import numpy as np

from straylight.sources.body_magnitudes import MOON_APOGEE_KM, MOON_MEAN_DISTANCE_KM, MOON_PERIGEE_KM
from straylight.sources.earthshine.moonlit_table import MoonlitLUT
from straylight.sources.earthshine.nodes import (
    MOONLIT_LUT_BUILD_SECONDS_PER_NODE,
    MoonlitSettings,
    _cached,
    cache_path,
    mirror_symmetric,
    moonlit_key,
)
from straylight.sources.earthshine.table import build_lamp_table

__all__ = [
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


def _moon_coefficients_direct(off, R, D, Zm, L, A, P, state, earth_radius_km, grid):
    """(direct_moon, door_moon) of the moonlit Earth on the Earth-cap ``grid``, per unit lunar
    irradiance at the Earth, for scenes in the local frame (rad, km), one door state (or,
    ``state`` None, every door state: arrays (samples, door states ascending)); samples sharing
    (R, D, Zm) share one cap grid."""
    n_states = len(off.door_states_deg)
    sel = np.arange(n_states) if state is None else np.array([sorted(off.door_states_deg).index(state)])
    d_out, g_out = np.empty((R.size, sel.size)), np.empty((R.size, sel.size))
    groups = {}
    for i, key in enumerate(zip(R.tolist(), D.tolist(), Zm.tolist())):
        groups.setdefault(key, []).append(i)
    es = off.cap_settings(grid)
    for idx in groups.values():
        idx = np.asarray(idx)
        sat, moon, frame = _moonlit_scene(R[idx], D[idx], Zm[idx], L[idx], A[idx], P[idx])
        d, g = off.earthshine_scene_sums(
            sat[0],
            moon[0],
            moon[0],
            frame,
            earth_radius_km,
            np.broadcast_to(sel, (idx.size, sel.size)),
            with_sun=False,
            s=es,
        )
        d_out[idx], g_out[idx] = d[:, :, 1], g[:, :, 1]
    return (d_out[:, 0], g_out[:, 0]) if state is not None else (d_out, g_out)


def build_moonlit_lut(
    off,
    earth_radius_km: float,
    radius_range_km: tuple[float, float],
    settings: MoonlitSettings = MoonlitSettings(),
    grid: tuple[int, int] = (8, 16),
    floor: float = 0.0,
    moon_max: float = 0.0,
    dark_limb_min_deg: float = 30.0,
    n_validation: int = 400,
    workers: int = 1,
) -> MoonlitLUT:
    """The moonlit Earth's table on the Earth-cap ``grid``: tabulate, then validate at
    ``n_validation`` random points whose line of sight is at least ``dark_limb_min_deg`` above
    the limb (any Moon, roll, radius in the orbit's range and Moon distance from perigee to
    apogee): the largest |table - direct| x moon_max /
    (direct x moon_max + floor), with ``moon_max`` the brightest lunar irradiance (full Moon
    at perigee) and ``floor`` the darkest sky, both per unit solar irradiance at 1 AU: an
    error as a fraction of the total, at full Moon (a pessimistic one).

    Parameters
    ----------
    off : EarthGrid
        The off-field transfer and Earth grid.
    earth_radius_km : float
        The Earth's radius, km.
    radius_range_km : tuple of (float, float)
        The orbit's smallest and largest geocentric radius, km (built at their mean).
    settings : MoonlitSettings
        The node steps.
    grid : tuple of (int, int)
        (n_gamma, n_psi) of the coarse Earth-cap grid.
    floor : float
        The darkest sky, e-/s/pix per photon s-1 m-2 of the Sun at 1 AU; 0: no validation
        (the error is then NaN).
    moon_max : float
        The brightest Moon's irradiance over the Sun's at 1 AU, dimensionless.
    dark_limb_min_deg : float
        The dark-limb avoidance angle, deg.
    n_validation : int
        Validation points.
    workers : int
        Threads.

    Returns
    -------
    MoonlitLUT
        With ``validation_max_rel_error`` (a fraction of the total) and ``build_seconds``.
    """
    symmetric = mirror_symmetric(off)
    r0 = 0.5 * (radius_range_km[0] + radius_range_km[1])
    zm, zl, az, roll = settings.nodes(float(radius_range_km[0]), earth_radius_km, symmetric)
    Zm, L, A, P = (
        v.ravel() for v in np.meshgrid(*(np.radians(v) for v in (zm, zl, az, roll)), indexing="ij")
    )
    # built at the Moon's mean distance; the validation draws perigee to apogee, so the
    # parallax this ignores is inside the validated error
    R, D = np.full(Zm.size, r0), np.full(Zm.size, MOON_MEAN_DISTANCE_KM)
    per_zm = zl.size * az.size * roll.size  # nodes of one Moon zenith are contiguous: one scene
    tasks = [
        (off, R[p], D[p], Zm[p], L[p], A[p], P[p], None, earth_radius_km, tuple(grid))
        for p in (slice(i * per_zm, (i + 1) * per_zm) for i in range(zm.size))
    ]
    shape = (zm.size, zl.size, az.size, roll.size)

    def make(direct, door, scale, results):
        return MoonlitLUT(zm, zl, az, roll, direct, door, symmetric, scale, tuple(int(g) for g in grid))

    rng = np.random.default_rng(20261122)
    n = n_validation
    limb = 90.0 + np.degrees(np.arccos(earth_radius_km / radius_range_km[0]))
    vr = rng.uniform(radius_range_km[0], radius_range_km[1], n)
    vd = rng.uniform(MOON_PERIGEE_KM, MOON_APOGEE_KM, n)
    vz, vl = (
        np.radians(rng.uniform(0.0, 180.0, n)),
        np.radians(rng.uniform(0.0, max(limb - dark_limb_min_deg, 1.0), n)),
    )
    va, vp = np.radians(rng.uniform(0.0, 360.0, n)), np.radians(rng.uniform(0.0, 360.0, n))
    sat_v, moon_v, frame_v = _moonlit_scene(vr, vd, vz, vl, va, vp)

    def error_at(lut, state):
        d_ref, g_ref = _moon_coefficients_direct(off, vr, vd, vz, vl, va, vp, state, earth_radius_km, grid)
        d_t, g_t = lut.coefficients(sat_v, moon_v, frame_v, np.full(n, state))
        return np.abs((d_t + g_t) - (d_ref + g_ref)) * moon_max / ((d_ref + g_ref) * moon_max + floor)

    return build_lamp_table(
        off, _moon_coefficients_direct, tasks, shape, "moonlit-Earth table", make, error_at, floor, workers
    )


def load_or_build_moonlit(
    off,
    earth_radius_km,
    radius_range_km,
    settings: MoonlitSettings,
    grid,
    floor: float,
    moon_max: float,
    dark_limb_min_deg: float = 30.0,
    log=None,
    workers: int = 1,
):
    """The moonlit table for these inputs from the cache, built and stored there if missing.

    Parameters
    ----------
    off, earth_radius_km, radius_range_km, settings, grid, floor, moon_max, dark_limb_min_deg, workers
        As for :func:`build_moonlit_lut`.
    log : logging.Logger, optional
        Announces a build as a warning; None: silent.

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
    key = moonlit_key(
        off, earth_radius_km, radius_range_km, settings, grid, floor, moon_max, dark_limb_min_deg
    )
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
        lambda: build_moonlit_lut(
            off,
            earth_radius_km,
            radius_range_km,
            settings,
            grid,
            floor,
            moon_max,
            dark_limb_min_deg,
            workers=workers,
        ),
        log,
        expected,
        workers,
    )
