"""The sunlit Earth's look-up table: its build, its validation and its cache.

The table (:class:`~straylight.sources.earthshine.sunlit_table.EarthshineLUT`) holds the direct
Earth-cap sum of :class:`~straylight.sources.earthshine.engine.EarthGrid` (compiled,
:mod:`straylight.sources.earthshine.kernel`) at its nodes
(:class:`~straylight.sources.earthshine.nodes.LUTSettings`).  The build runs one scene (the
satellite's radius and the Sun's zenith angle, every line of sight of it) per task, in threads,
then validates the table against the direct sum at random off-node points and records the
largest error as a fraction of the total, which ``models.earthshine.method: auto`` weighs
against the tolerance (the steps the moonlit Earth's table shares:
:func:`~straylight.sources.earthshine.table.build_lamp_table`).  A table is built once
per model and machine: it is cached under a digest of everything it depends on
(:func:`load_or_build`).
"""

from __future__ import annotations

import numpy as np

from straylight.errors import InputError
from straylight.sky.frames import telescope_frame
from straylight.sky.vectors import unit
from straylight.sources.earthshine.nodes import (
    LUT_BUILD_SECONDS_PER_NODE,
    LUTSettings,
    _cached,
    cache_path,
    lut_key,
    mirror_symmetric,
)
from straylight.sources.earthshine.sums import Bodies
from straylight.sources.earthshine.sunlit_table import EarthshineLUT
from straylight.sources.earthshine.table import TableScenes, build_lamp_table
from straylight.sources.photometry import AU_KM

__all__ = [
    "build_earthshine_lut",
    "build_speed_factor",
    "sun_coefficients_direct",
    "load_or_build",
]


def _local_scene(R, Z, L, A):
    """Satellite, Sun (km) and line of sight in the local frame: vertical +x, Sun in the x-y plane."""
    sat = np.stack([R, 0 * R, 0 * R], axis=-1)
    sun = AU_KM * np.stack([np.cos(Z), np.sin(Z), 0 * Z], axis=-1)
    los = np.stack([np.cos(L), np.sin(L) * np.cos(A), np.sin(L) * np.sin(A)], axis=-1)
    return sat, sun, los


def sun_coefficients_direct(off, R, Z, L, A, state, earth_radius_km):
    """Direct sums in the local frame (vertical +x, the Sun in the x-y plane): radius R (km),
    Sun zenith Z, line-of-sight zenith L and azimuth A (rad), one door state.

    Parameters
    ----------
    off : EarthGrid
        The off-field transfer and Earth grid.
    R : ndarray, shape (n,)
        Satellite geocentric radius, km.
    Z, L, A : ndarray, shape (n,)
        Sun zenith, line-of-sight zenith and azimuth from the Sun's, rad.
    state : float
        The door state (opening), deg, one of ``off.door_states_deg``.
    earth_radius_km : float
        The Earth's radius, km.

    Returns
    -------
    direct_sun, door_sun : ndarray, shape (n,)
        e-/s/pix per photon s-1 m-2 of the Sun, outside the field.
    """
    sat, sun, los = _local_scene(R, Z, L, A)
    d_out, g_out = np.empty(R.size), np.empty(R.size)
    state_index = sorted(off.door_states_deg).index(state)
    # samples sharing a (radius, Sun zenith) share one scene: one cap grid, dark blocks dropped
    groups = {}
    for i, key in enumerate(zip(R.tolist(), Z.tolist())):
        groups.setdefault(key, []).append(i)
    for idx in groups.values():
        idx = np.asarray(idx)
        frame = telescope_frame(los[idx], sun[idx] - sat[idx])
        d, g = off.earthshine_scene_sums(
            Bodies(sat[idx[0]], sun[idx[0]], _NO_MOON_KM),
            frame,
            earth_radius_km,
            np.full((idx.size, 1), state_index),
            with_moon=False,
        )
        d_out[idx], g_out[idx] = d[:, 0, 0], g[:, 0, 0]
    return d_out, g_out


#: a Moon far away, for sums that leave the Moon out (its position must still be finite)
_NO_MOON_KM = np.array([0.0, 0.0, -1e9])


def _sunlit_scene(
    off, r_km: float, sun_zenith_rad: float, los_zenith_rad, azimuth_rad, earth_radius_km: float
):
    """One (radius, Sun zenith) scene of the sunlit table over every (line-of-sight zenith,
    azimuth) node (flattened, zenith-major): (direct, door) per unit solar irradiance, (nodes,
    door states ascending), and the moonlit Earth's direct bound with the Moon where the Sun is
    (:meth:`EarthGrid.lamp_bound_one_scene`), (nodes,)."""
    L, A = (v.ravel() for v in np.meshgrid(los_zenith_rad, azimuth_rad, indexing="ij"))
    sat, sun, los = _local_scene(np.full(L.size, r_km), np.full(L.size, sun_zenith_rad), L, A)
    frame = telescope_frame(los, sun - sat)
    n_states = len(off.door_states_deg)
    d, g = off.earthshine_scene_sums(
        Bodies(sat[0], sun[0], _NO_MOON_KM),
        frame,
        earth_radius_km,
        np.broadcast_to(np.arange(n_states), (L.size, n_states)),
        with_moon=False,
    )
    bound = off.lamp_bound_one_scene(sat[0], unit(sun[0]), los, earth_radius_km)
    return d[:, :, 0], g[:, :, 0], bound


def _observable_points(rr, earth_radius_km, symmetric, n, avoidance_deg):
    """N random (radius, Sun zenith, line-of-sight zenith, azimuth) points (deg) whose line of
    sight meets the dark-limb, bright-limb and Sun avoidance angles (rejection sampling)."""
    from straylight.sky.limb import limb_geometry
    from straylight.sky.vectors import angle_between_deg

    dark_min, bright_min, sun_min = (float(a) for a in avoidance_deg)
    rng = np.random.default_rng(20261122)
    limb = 90.0 + np.degrees(np.arccos(earth_radius_km / rr.min()))
    kept = []
    while sum(len(k[0]) for k in kept) < n:
        m = 4 * n
        p = (
            rng.uniform(rr.min(), rr.max(), m),
            rng.uniform(0.0, 180.0, m),
            rng.uniform(0.0, max(limb - dark_min, 1.0), m),
            rng.uniform(0.0, 180.0 if symmetric else 360.0, m),
        )
        sat, sun, los = _local_scene(p[0], *np.radians(p[1:]))
        lg = limb_geometry(sat, los, sun, earth_radius_km)
        ok = (
            (lg.dark_limb_angle_deg >= dark_min)
            & (lg.bright_limb_angle_deg >= bright_min)
            & (angle_between_deg(los, sun - sat) >= sun_min)
        )
        if not ok.any() and not kept:
            raise InputError(
                f"earthshine table validation: no observable line of sight with avoidance angles "
                f"{avoidance_deg} deg"
            )
        kept.append(tuple(v[ok] for v in p))
    return tuple(np.concatenate([k[i] for k in kept])[:n] for i in range(4))


def _radius_nodes_km(radius_range_km, n_radius: int) -> np.ndarray:
    """The table's geocentric radius nodes, km: ``n_radius`` across the range, or its middle."""
    if n_radius > 1:
        return np.linspace(radius_range_km[0], radius_range_km[1], n_radius)
    return np.array([0.5 * (radius_range_km[0] + radius_range_km[1])])


def _moon_door_factor(off) -> float:
    """The largest door factor over the door states times the albedo: reflectance x sum of the
    door's weights x pixel area (m2) x albedo, the moonlit door term's bound per unit irradiance."""
    return (
        max(
            off.earthshine.door_reflectance * float(np.sum(w)) * off.pixel_area_m2
            for _, _, w in off._door_weights.values()
        )
        * off.earthshine.albedo
    )


def build_earthshine_lut(
    off,
    earth_radius_km: float,
    radius_range_km: tuple[float, float],
    settings: LUTSettings = LUTSettings(),
    floor: float = 0.0,
    n_validation: int = 400,
    avoidance_deg: tuple = (30.0, 80.0, 50.0),
    workers: int = 1,
) -> EarthshineLUT:
    """The sunlit Earth's table: tabulate ``off.earthshine_coefficients`` (an
    :class:`~straylight.sources.earthshine.engine.EarthGrid`), then validate:
    at ``n_validation`` random points where a line of sight is observable (``avoidance_deg``:
    the minimum angles from the dark limb, the bright limb and the Sun, as the campaign's
    constraints) the largest |table - direct| / (direct + floor), with ``floor`` the darkest
    sky background in the same units (so the error is a fraction of the total, and a
    pessimistic one).  ``workers`` threads share the scenes (one per core; the sums are
    compiled, :mod:`straylight.sources.earthshine.kernel`).

    Parameters
    ----------
    off : EarthGrid
        The off-field transfer and Earth grid.
    earth_radius_km : float
        The Earth's radius, km.
    radius_range_km : tuple of (float, float)
        The orbit's smallest and largest geocentric radius, km.
    settings : LUTSettings
        The node steps.
    floor : float
        The darkest sky, e-/s/pix per photon s-1 m-2 of the Sun at 1 AU; 0: no validation
        (the error is then NaN).
    n_validation : int
        Validation points.
    avoidance_deg : tuple of float
        Dark-limb, bright-limb and Sun avoidance angles, deg.
    workers : int
        Threads.

    Returns
    -------
    EarthshineLUT
        With ``validation_max_rel_error`` (a fraction of the total) and ``build_seconds``.

    Raises
    ------
    InputError
        When no line of sight is observable with ``avoidance_deg``.
    """
    s = settings
    symmetric = mirror_symmetric(off)
    rr = _radius_nodes_km(radius_range_km, s.n_radius)
    zs, zl, az = s.nodes(float(rr.min()), earth_radius_km, symmetric)
    shape = (rr.size, zs.size, zl.size, az.size)
    # one task per (radius, Sun zenith) scene: its cap grid once, every door state at once
    tasks = [
        (off, float(r), float(z), np.radians(zl), np.radians(az), earth_radius_km)
        for r in rr
        for z in np.radians(zs)
    ]
    moon_door = _moon_door_factor(off)

    def make(direct, door, scale, results):
        # moonlit-Earth bound over (radius, Moon zenith, line-of-sight zenith): the PST at its
        # maximum over phi, Sp = 1, maximised over the azimuth nodes
        bound = np.stack([res[2] for res in results]).reshape(shape).max(axis=-1)
        return EarthshineLUT(rr, zs, zl, az, direct, door, bound, moon_door, symmetric, scale)

    # validation at random off-node points of the observable region
    vr, vz, vl, va = _observable_points(rr, earth_radius_km, symmetric, n_validation, avoidance_deg)
    sat_v, sun_v, los_v = _local_scene(vr, *np.radians([vz, vl, va]))

    def error_at(lut, state):
        d_ref, g_ref = sun_coefficients_direct(off, vr, *np.radians([vz, vl, va]), state, earth_radius_km)
        d_t, g_t = lut.sun_coefficients(sat_v, sun_v, los_v, np.full(n_validation, state))
        return np.abs((d_t + g_t) - (d_ref + g_ref)) / (d_ref + g_ref + floor)

    scenes = TableScenes(_sunlit_scene, tasks, shape, "earthshine table")
    return build_lamp_table(off, scenes, make, error_at, floor, workers)


def load_or_build(
    off,
    earth_radius_km,
    radius_range_km,
    settings: LUTSettings,
    floor: float,
    log=None,
    avoidance_deg: tuple = (30.0, 80.0, 50.0),
    workers: int = 1,
):
    """The table for these inputs from the cache, built (by ``workers`` threads) and stored
    there if missing.

    Parameters
    ----------
    off, earth_radius_km, radius_range_km, settings, floor, avoidance_deg, workers
        As for :func:`build_earthshine_lut`.
    log : logging.Logger, optional
        Announces a build as a warning; None: silent.

    Returns
    -------
    lut : EarthshineLUT
    path : Path
        Its cache file.

    Raises
    ------
    InputError
        When the cached file is not a valid table, or the build's validation finds no
        observable line of sight.
    """
    key = lut_key(off, earth_radius_km, radius_range_km, settings, floor, avoidance_deg)
    expected = (
        LUT_BUILD_SECONDS_PER_NODE
        * settings.node_count(radius_range_km[0], earth_radius_km, mirror_symmetric(off))
        * len(off.door_states_deg)
    )
    if log is not None and not cache_path("earthshine_lut", key).exists():  # this machine, now
        expected *= build_speed_factor(off, earth_radius_km, radius_range_km, settings, workers)
    return _cached(
        "earthshine_lut",
        key,
        "earthshine",
        EarthshineLUT.load,
        lambda: build_earthshine_lut(
            off,
            earth_radius_km,
            radius_range_km,
            settings,
            floor,
            avoidance_deg=avoidance_deg,
            workers=workers,
        ),
        log,
        expected,
        workers,
    )


#: a measured speed factor is reused this long while the load average stays within
#: :data:`PROBE_LOAD_CHANGE` of the one it was measured at (s; runnable processes)
PROBE_MAX_AGE_S = 900.0
PROBE_LOAD_CHANGE = 0.5
#: scenes the probe runs per worker thread (the table has ~150; each ~1 s on a core)
PROBE_SCENES_PER_WORKER = 2


def build_speed_factor(
    off, earth_radius_km, radius_range_km, settings: LUTSettings | None, workers: int
) -> float:
    """The tables' build time on this machine now against :data:`LUT_BUILD_SECONDS_PER_NODE`
    on ``workers`` free cores (> 1: slower, or fewer cores free): a few of the sunlit table's
    scenes, spread over its Sun zenith angles, run in ``workers`` threads as the build runs
    them (a few seconds), their wall time against the figure's.  Kept in the table cache
    (``speed_probe.json``) and reused for :data:`PROBE_MAX_AGE_S` while the load average stays
    within :data:`PROBE_LOAD_CHANGE`; 1.0 when it cannot be measured.

    Parameters
    ----------
    off, earth_radius_km, radius_range_km, settings
        As for :func:`build_earthshine_lut` (radii in km; settings None: the default nodes).
    workers : int
        Threads the build runs on.

    Returns
    -------
    float
        Measured wall time over the figure's on ``workers`` cores (dimensionless).
    """
    import json
    import os
    import time
    from concurrent.futures import ThreadPoolExecutor

    from straylight.util.io import cache_dir, write_json_atomic

    workers = max(int(workers), 1)
    path = cache_dir() / "speed_probe.json"
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else 0.0
    try:
        kept = json.loads(path.read_text())
    except (OSError, ValueError):
        kept = {}
    entry = kept.get(str(workers))
    if (
        isinstance(entry, dict)
        and 0 <= time.time() - entry.get("time", 0) < PROBE_MAX_AGE_S
        and abs(load - entry.get("load", -99)) < PROBE_LOAD_CHANGE
    ):
        return float(entry["factor"])
    settings = LUTSettings() if settings is None else settings
    rr = np.array([0.5 * (radius_range_km[0] + radius_range_km[1])])
    zs, zl, az = settings.nodes(float(radius_range_km[0]), earth_radius_km, mirror_symmetric(off))
    zl, az = np.radians(zl), np.radians(az)
    k = min(PROBE_SCENES_PER_WORKER * workers, zs.size)
    picks = np.radians(zs[np.linspace(0, zs.size - 1, k).round().astype(int)])
    off._kernel_tables  # noqa: B018  (the door's tables once, before the threads share them)
    for z in picks[[0, -1]]:  # compiled (a day-side and a night-side scene, a few nodes) before timing
        _sunlit_scene(
            off,
            float(rr[0]),
            float(z),
            zl[:: max(1, zl.size // 8)],
            az[:: max(1, az.size // 8)],
            earth_radius_km,
        )

    def timed(z):  # each scene's wall time in its thread (its share of the cores under the load)
        t0 = time.perf_counter()
        _sunlit_scene(off, float(rr[0]), float(z), zl, az, earth_radius_km)
        return time.perf_counter() - t0

    with ThreadPoolExecutor(max_workers=workers) as ex:
        durations = list(ex.map(timed, picks))
    # the build keeps every thread busy with ~150 scenes: its wall is the scenes' summed time over
    # the threads (not the probe's own wall, where a thread waits for the slowest scene)
    wall = float(np.sum(durations)) / workers
    nodes = k * zl.size * az.size * len(off.door_states_deg)
    factor = wall / (LUT_BUILD_SECONDS_PER_NODE * nodes / workers)
    if not np.isfinite(factor) or factor <= 0:
        return 1.0
    kept[str(workers)] = {"factor": factor, "time": time.time(), "load": load, "wall_s": wall, "scenes": k}
    try:
        write_json_atomic(kept, path)
    except OSError:
        pass  # a read-only cache: measured again next time
    return factor
