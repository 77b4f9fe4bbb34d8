"""The earthshine look-up tables' build: their nodes, the build, its validation and the cache.

Each table (:class:`~straylight.sources.earthshine_table.EarthshineLUT` for the sunlit Earth,
:class:`~straylight.sources.earthshine_table.MoonlitLUT` for the moonlit Earth) holds the direct
Earth-cap sum of :class:`~straylight.sources.offfield.OffFieldModel` (compiled,
:mod:`straylight.sources.earthshine_kernel`) at its nodes (:class:`LUTSettings`,
:class:`MoonlitSettings`).  The build runs one scene (the satellite's radius and the lamp's
zenith angle, every line of sight of it) per task, in threads, with a progress bar; then it
validates the table against the direct sum at random off-node points and records the largest
error as a fraction of the total, which ``models.earthshine.method: auto`` weighs against the
tolerance.  A table is built once per model and machine: it is cached under a digest of
everything it depends on (:func:`load_or_build`, :func:`load_or_build_moonlit`).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from straylight.errors import InputError
from straylight.sky.frames import telescope_frame
from straylight.sky.vectors import unit
from straylight.sources.bodies import MOON_APOGEE_KM, MOON_MEAN_DISTANCE_KM, MOON_PERIGEE_KM
from straylight.sources.earthshine_table import EarthshineLUT, MoonlitLUT
from straylight.sources.photometry import AU_KM
from straylight.util.io import cache_dir

__all__ = [
    "LUT_FORMAT",
    "MOONLIT_FORMAT",
    "LUT_BUILD_SECONDS_PER_NODE",
    "MOONLIT_LUT_BUILD_SECONDS_PER_NODE",
    "LOS_RISE_WIDTH_DEG",
    "LUTSettings",
    "MoonlitSettings",
    "build_earthshine_lut",
    "build_moonlit_lut",
    "sun_coefficients_direct",
    "mirror_symmetric",
    "cache_path",
    "lut_key",
    "moonlit_key",
    "load_or_build",
    "load_or_build_moonlit",
]

# -- the sunlit Earth ---------------------------------------------------------------------------
#: bumped whenever the table's content or layout changes: part of the cache key
LUT_FORMAT = 5

#: The tables' build, in seconds on one core per (node, door state): the sunlit table's nodes
#: each sum the full Earth grid, the moonlit table's its coarse grid (8 x 16 blocks).  The build
#: is announced with the time they give, and ``straylight plan`` quotes it; a table records its
#: own build time (``build_seconds``), and ``bench/pipeline.py --cold`` times both in a run.
LUT_BUILD_SECONDS_PER_NODE = 0.028e-3
MOONLIT_LUT_BUILD_SECONDS_PER_NODE = 0.006e-3


@dataclass(frozen=True)
class LUTSettings:
    """Node spacing (deg).  The Sun's zenith angle is sampled at ``sun_zenith_step_deg`` where the
    terminator crosses the visible cap (60 deg to the cap's edge) and 2.5 times coarser above;
    beyond the cap's edge the cap is dark (one node at 180).  The line of sight's zenith angle at
    ``los_zenith_step_deg`` above the limb and 2.5 times coarser below it (never observable).

    Attributes
    ----------
    sun_zenith_step_deg, los_zenith_step_deg, azimuth_step_deg : float
        Node steps, deg, each within [0.05, 30].
    n_radius : int
        Radius nodes between the orbit's extremes (1: one node at the mean radius).

    Raises
    ------
    InputError
        When a step is outside [0.05, 30] deg or ``n_radius`` < 1.
    """

    # the defaults validate within the table's share of the tolerance with the default PST (the
    # build's validation, in the products' models record; figures in docs/performance.md); a
    # coarser azimuth step cuts the peaks near 0 and 180 deg
    sun_zenith_step_deg: float = 0.5
    los_zenith_step_deg: float = 1.0
    azimuth_step_deg: float = 2.5
    n_radius: int = 1  # radius nodes between the orbit's extremes (1: a circular orbit)

    def __post_init__(self):
        for k in ("sun_zenith_step_deg", "los_zenith_step_deg", "azimuth_step_deg"):
            v = getattr(self, k)
            if not 0.05 <= v <= 30.0:
                raise InputError(f"models.earthshine.lut.{k} = {v}: must be within [0.05, 30] deg")
        if self.n_radius < 1:
            raise InputError(f"models.earthshine.lut.n_radius = {self.n_radius}: needs >= 1")

    def node_count(self, radius_km: float, earth_radius_km: float, symmetric: bool = True) -> int:
        """Nodes of the table (per door state); ``symmetric``: the instrument mirror-symmetric
        about the Sun's vertical plane (:func:`mirror_symmetric`: azimuth 0-180 deg, else 0-360).

        Parameters
        ----------
        radius_km : float
            The orbit's smallest geocentric radius, km (sets the cap's edge).
        earth_radius_km : float
            The Earth's radius, km.
        symmetric : bool
            Whether the azimuth runs over 0-180 deg only.

        Returns
        -------
        int
        """
        zs, zl, az = self.nodes(radius_km, earth_radius_km, symmetric)
        return zs.size * zl.size * az.size * self.n_radius

    def nodes(self, radius_km: float, earth_radius_km: float, symmetric: bool):
        """(sun zenith, line-of-sight zenith, azimuth) node arrays, deg.

        Parameters
        ----------
        radius_km : float
            The orbit's smallest geocentric radius, km (sets the cap's edge).
        earth_radius_km : float
            The Earth's radius, km.
        symmetric : bool
            Whether the azimuth runs over 0-180 deg only (else 0-360).

        Returns
        -------
        sun_zenith_deg, los_zenith_deg, azimuth_deg : ndarray
            Ascending node arrays, deg.
        """
        cap = np.degrees(
            np.arccos(earth_radius_km / radius_km)
        )  # the cap's edge beyond nadir, = limb depression
        hs, hl, ha = self.sun_zenith_step_deg, self.los_zenith_step_deg, self.azimuth_step_deg

        zs = np.unique(np.r_[_steps(0.0, 60.0, 2.5 * hs), _steps(60.0, 90.0 + cap + hs, hs), 180.0])
        limb = 90.0 + cap
        # the aperture plane meets the Earth's edge at a line-of-sight zenith angle of ``cap``:
        # there the direct earthshine starts from 0 (nothing enters from behind the plane) and
        # grows steeply, so the nodes are 4 times finer over the first degrees of that rise
        rise = _steps(max(cap - 0.5, 0.0), cap + LOS_RISE_WIDTH_DEG, hl / 4.0)
        zl = np.unique(np.r_[_steps(0.0, limb, hl), rise, _steps(limb, 180.0, 2.5 * hl)])
        az = _steps(0.0, 180.0 if symmetric else 360.0, ha)
        return zs, zl, az


#: deg above the zenith angle where the Earth's edge crosses the aperture plane over which the
#: line-of-sight nodes are finer: the coefficients rise steeply there, and the regular nodes
#: alone err by a large part of the total (docs/performance.md)
LOS_RISE_WIDTH_DEG = 6.0


def _steps(a: float, b: float, h: float) -> np.ndarray:
    """Nodes from a to b (both included) at most h apart, evenly spaced."""
    n = max(int(np.ceil((b - a) / h - 1e-9)), 1)
    return np.linspace(a, b, n + 1)


def _asinh_scale(direct: dict, door: dict) -> float:
    """The tables' asinh scale: the 1st percentile of their positive values (linear below it,
    logarithmic above)."""
    positive = np.concatenate([v[v > 0] for v in list(direct.values()) + list(door.values())])
    return float(np.percentile(positive, 1)) if positive.size else 1e-30


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
    off : OffFieldModel
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
            sat[idx[0]],
            sun[idx[0]],
            _NO_MOON_KM,
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
    (:meth:`OffFieldModel.lamp_bound_one_scene`), (nodes,)."""
    L, A = (v.ravel() for v in np.meshgrid(los_zenith_rad, azimuth_rad, indexing="ij"))
    sat, sun, los = _local_scene(np.full(L.size, r_km), np.full(L.size, sun_zenith_rad), L, A)
    frame = telescope_frame(los, sun - sat)
    n_states = len(off.door_states_deg)
    d, g = off.earthshine_scene_sums(
        sat[0],
        sun[0],
        _NO_MOON_KM,
        frame,
        earth_radius_km,
        np.broadcast_to(np.arange(n_states), (L.size, n_states)),
        with_moon=False,
    )
    bound = off.lamp_bound_one_scene(sat[0], unit(sun[0]), los, earth_radius_km)
    return d[:, :, 0], g[:, :, 0], bound


def _run_scenes(fn, tasks: list, workers: int, what: str, log=None) -> list:
    """fn(*task) for every task (a scene each), in ``workers`` threads (the sums are compiled
    and release the GIL), with a progress bar on standard error once it runs for more than a
    few seconds.  Each task's result does not depend on the threads, so the table is the same
    byte for byte whatever ``workers`` is."""
    from concurrent.futures import ThreadPoolExecutor

    from tqdm import tqdm

    results = [None] * len(tasks)
    import sys

    tty = sys.stderr.isatty()
    with tqdm(
        total=len(tasks),
        desc=what,
        unit="scene",
        delay=3.0,
        mininterval=1.0 if tty else 60.0,
        leave=not tty,
        file=sys.stderr,
    ) as bar:
        if workers <= 1 or len(tasks) <= 1:
            for i, t in enumerate(tasks):
                results[i] = fn(*t)
                bar.update()
        else:
            from concurrent.futures import as_completed

            with ThreadPoolExecutor(max_workers=workers) as ex:
                futures = {ex.submit(fn, *t): i for i, t in enumerate(tasks)}
                try:
                    for f in as_completed(futures):
                        results[futures[f]] = f.result()
                        bar.update()
                except BaseException:  # Ctrl-C or a failed scene: the queued scenes are not run
                    for f in futures:
                        f.cancel()
                    raise
    return results


def mirror_symmetric(off) -> bool:
    """PST(theta, phi) == PST(theta, -phi) and the door shade likewise (sampled check).

    Parameters
    ----------
    off : OffFieldModel
        The off-field transfer and Earth grid.

    Returns
    -------
    bool
    """
    th = np.r_[np.linspace(0.0, 89.0, 90), np.linspace(91.0, 180.0, 90)][:, None]  # 90: grazing, noise
    ph = np.linspace(0.0, 360.0, 73)[None, :]
    if not np.allclose(off.pst(th, ph), off.pst(th, 360.0 - ph), rtol=1e-9):
        return False
    return all(
        np.allclose(off.door_factor(th, ph, s), off.door_factor(th, 360.0 - ph, s), atol=1e-9)
        for s in off.door_states_deg
    )


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
    :class:`OffFieldModel`), then validate:
    at ``n_validation`` random points where a line of sight is observable (``avoidance_deg``:
    the minimum angles from the dark limb, the bright limb and the Sun, as the campaign's
    constraints) the largest |table - direct| / (direct + floor), with ``floor`` the darkest
    sky background in the same units (so the error is a fraction of the total, and a
    pessimistic one).  ``workers`` threads share the scenes (one per core; the sums are
    compiled, :mod:`straylight.sources.earthshine_kernel`).

    Parameters
    ----------
    off : OffFieldModel
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
    import time

    t_start = time.perf_counter()
    s = settings
    symmetric = mirror_symmetric(off)
    off._kernel_tables  # the door's tables once, before the threads share them
    rr = (
        np.linspace(radius_range_km[0], radius_range_km[1], s.n_radius)
        if s.n_radius > 1
        else np.array([0.5 * (radius_range_km[0] + radius_range_km[1])])
    )
    zs, zl, az = s.nodes(float(rr.min()), earth_radius_km, symmetric)
    shape = (rr.size, zs.size, zl.size, az.size)
    # one task per (radius, Sun zenith) scene: its cap grid once, every door state at once
    tasks = [
        (off, float(r), float(z), np.radians(zl), np.radians(az), earth_radius_km)
        for r in rr
        for z in np.radians(zs)
    ]
    results = _run_scenes(_sunlit_scene, tasks, workers, "earthshine table")
    ascending = sorted(off.door_states_deg)
    direct, door = {}, {}
    for state in off.door_states_deg:
        j = ascending.index(state)
        direct[state] = np.stack([res[0][:, j] for res in results]).reshape(shape)
        door[state] = np.stack([res[1][:, j] for res in results]).reshape(shape)
    # moonlit-Earth bound over (radius, Moon zenith, line-of-sight zenith): the PST at its
    # maximum over phi, Sp = 1, maximised over the azimuth nodes
    bound = np.stack([res[2] for res in results]).reshape(shape).max(axis=-1)
    moon_door = (
        max(
            off.earthshine.door_reflectance * float(np.sum(w)) * off.pixel_area_m2
            for _, _, w in off._door_weights.values()
        )
        * off.earthshine.albedo
    )
    scale = _asinh_scale(direct, door)
    lut = EarthshineLUT(rr, zs, zl, az, direct, door, bound, moon_door, symmetric, scale)
    # validation at random off-node points of the observable region
    vr, vz, vl, va = _observable_points(rr, earth_radius_km, symmetric, n_validation, avoidance_deg)
    errs = []
    for state in off.door_states_deg:
        d_ref, g_ref = sun_coefficients_direct(off, vr, *np.radians([vz, vl, va]), state, earth_radius_km)
        sat_v, sun_v, los_v = _local_scene(vr, *np.radians([vz, vl, va]))
        d_t, g_t = lut.sun_coefficients(sat_v, sun_v, los_v, np.full(n_validation, state))
        errs.append(np.abs((d_t + g_t) - (d_ref + g_ref)) / (d_ref + g_ref + floor))
    lut.validation_max_rel_error = float(np.max(errs)) if floor > 0 else float("nan")
    lut.build_seconds = time.perf_counter() - t_start
    return lut


# -- the moonlit Earth --------------------------------------------------------------------------
#: bumped whenever the moonlit table's content or layout changes: part of its cache key
MOONLIT_FORMAT = 3


@dataclass(frozen=True)
class MoonlitSettings:
    """Node spacing (deg) of the moonlit Earth's table.  Its coefficients depend on one angle
    more than the sunlit Earth's: the telescope's roll is set by the Sun, not by the lamp, so
    the table runs over the Moon's zenith angle at the satellite, the line of sight's zenith
    angle, its azimuth from the Moon's about the vertical, and the roll (the angle about the
    line of sight from its upward vertical to the telescope's +x axis).  The defaults validate
    within the moonlit grid's share of the tolerance at full Moon (:func:`build_moonlit_lut`;
    figures in docs/performance.md, measured by bench/run.py moonlit_grid).

    Attributes
    ----------
    moon_zenith_step_deg, los_zenith_step_deg, azimuth_step_deg, roll_step_deg : float
        Node steps, deg, each within [0.5, 45].

    Raises
    ------
    InputError
        When a step is outside [0.5, 45] deg.
    """

    moon_zenith_step_deg: float = 5.0
    los_zenith_step_deg: float = 4.0
    azimuth_step_deg: float = 10.0
    roll_step_deg: float = 15.0

    def __post_init__(self):
        for k in ("moon_zenith_step_deg", "los_zenith_step_deg", "azimuth_step_deg", "roll_step_deg"):
            v = getattr(self, k)
            if not 0.5 <= v <= 45.0:
                raise InputError(f"models.earthshine.moonlit_lut.{k} = {v}: must be within [0.5, 45] deg")

    def nodes(self, radius_km: float, earth_radius_km: float, symmetric: bool):
        """(Moon zenith, line-of-sight zenith, azimuth, roll) node arrays, deg.  Beyond the cap's
        edge plus one step the Moon lights none of the visible cap (one node at 180).

        Parameters
        ----------
        radius_km : float
            The orbit's smallest geocentric radius, km (sets the cap's edge).
        earth_radius_km : float
            The Earth's radius, km.
        symmetric : bool
            Whether the azimuth runs over 0-180 deg only (else 0-360).

        Returns
        -------
        moon_zenith_deg, los_zenith_deg, azimuth_deg, roll_deg : ndarray
            Ascending node arrays, deg.
        """
        cap = np.degrees(np.arccos(earth_radius_km / radius_km))

        hz, hl = self.moon_zenith_step_deg, self.los_zenith_step_deg
        zm = np.unique(np.r_[_steps(0.0, min(90.0 + cap + hz, 180.0), hz), 180.0])
        limb = 90.0 + cap
        # the aperture plane meets the Earth's edge at a line-of-sight zenith angle of ``cap``:
        # there the direct earthshine starts from 0 (nothing enters from behind the plane) and
        # grows steeply, so the nodes are 4 times finer over the first degrees of that rise
        rise = _steps(max(cap - 0.5, 0.0), cap + LOS_RISE_WIDTH_DEG, hl / 4.0)
        zl = np.unique(np.r_[_steps(0.0, limb, hl), rise, _steps(limb, 180.0, 2.5 * hl)])
        az = _steps(0.0, 180.0 if symmetric else 360.0, self.azimuth_step_deg)
        roll = _steps(0.0, 360.0, self.roll_step_deg)
        return zm, zl, az, roll


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
    es = replace(off.earthshine, n_gamma=int(grid[0]), n_psi=int(grid[1]))
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
    off : OffFieldModel
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
    import time

    t_start = time.perf_counter()
    symmetric = mirror_symmetric(off)
    off._kernel_tables  # the door's tables once, before the threads share them
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
    results = _run_scenes(_moon_coefficients_direct, tasks, workers, "moonlit-Earth table")
    shape = (zm.size, zl.size, az.size, roll.size)
    ascending = sorted(off.door_states_deg)
    direct, door = {}, {}
    for state in off.door_states_deg:
        j = ascending.index(state)
        direct[state] = np.concatenate([res[0][:, j] for res in results]).reshape(shape)
        door[state] = np.concatenate([res[1][:, j] for res in results]).reshape(shape)
    scale = _asinh_scale(direct, door)
    lut = MoonlitLUT(zm, zl, az, roll, direct, door, symmetric, scale, tuple(int(g) for g in grid))
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
    errs = []
    for state in off.door_states_deg:
        d_ref, g_ref = _moon_coefficients_direct(off, vr, vd, vz, vl, va, vp, state, earth_radius_km, grid)
        d_t, g_t = lut.coefficients(sat_v, moon_v, frame_v, np.full(n, state))
        errs.append(np.abs((d_t + g_t) - (d_ref + g_ref)) * moon_max / ((d_ref + g_ref) * moon_max + floor))
    lut.validation_max_rel_error = float(np.max(errs)) if floor > 0 else float("nan")
    lut.build_seconds = time.perf_counter() - t_start
    return lut


# -- the cache ------------------------------------------------------------------------------------
def cache_path(prefix: str, key: str) -> Path:
    """Where the table ``prefix`` with digest ``key`` is cached (it may not exist yet).

    Parameters
    ----------
    prefix : str
        The table's kind (``"earthshine_lut"``, ``"moonlit_lut"``).
    key : str
        Its digest (:func:`lut_key`, :func:`moonlit_key`).

    Returns
    -------
    Path
        ``<cache dir>/<prefix>_<key>.npz``.
    """
    return cache_dir() / f"{prefix}_{key}.npz"


def _digest(prefix: str, off, items: tuple) -> str:
    """16 hex digits of sha256 over ``prefix``, the PST, the door and Earth settings, and ``items``."""
    h = hashlib.sha256(prefix.encode())
    h.update(np.ascontiguousarray(off.pst.values).tobytes())
    h.update(
        np.ascontiguousarray(off.pst.theta_deg).tobytes() + np.ascontiguousarray(off.pst.phi_deg).tobytes()
    )
    h.update(
        repr(
            (off.door, off.door_states_deg, off.pixel_area_m2, off.field_radius_deg, off.earthshine) + items
        ).encode()
    )
    return h.hexdigest()[:16]


def lut_key(
    off,
    earth_radius_km,
    radius_range_km,
    settings: LUTSettings,
    floor: float = 0.0,
    avoidance_deg: tuple = (30.0, 80.0, 50.0),
) -> str:
    """Digest of everything the table depends on (PST, door, cap grid, albedo, radii, nodes).

    Parameters
    ----------
    off, earth_radius_km, radius_range_km, settings, floor, avoidance_deg
        As for :func:`build_earthshine_lut` (radii in km, floor in e-/s/pix per photon s-1 m-2
        of the Sun at 1 AU, angles in deg).

    Returns
    -------
    str
        16 hex digits.
    """
    return _digest(
        f"format {LUT_FORMAT}",
        off,
        (
            round(earth_radius_km, 6),
            tuple(round(r, 3) for r in radius_range_km),
            settings,
            f"{floor:.6g}",
            tuple(float(a) for a in avoidance_deg),
        ),
    )


def moonlit_key(
    off,
    earth_radius_km,
    radius_range_km,
    settings: MoonlitSettings,
    grid,
    floor: float,
    moon_max: float,
    dark_limb_min_deg: float,
) -> str:
    """Digest of everything the moonlit table depends on.

    Parameters
    ----------
    off, earth_radius_km, radius_range_km, settings, grid, floor, moon_max, dark_limb_min_deg
        As for :func:`build_moonlit_lut` (radii in km, floor in e-/s/pix per photon s-1 m-2 of
        the Sun at 1 AU, moon_max dimensionless, angle in deg).

    Returns
    -------
    str
        16 hex digits.
    """
    return _digest(
        f"moonlit format {MOONLIT_FORMAT}",
        off,
        (
            round(earth_radius_km, 6),
            tuple(round(r, 3) for r in radius_range_km),
            settings,
            tuple(int(g) for g in grid),
            f"{floor:.6g}",
            f"{moon_max:.6g}",
            float(dark_limb_min_deg),
        ),
    )


def _cached(
    prefix: str, key: str, what: str, load, build, log, expected_cpu_s: float | None = None, workers: int = 1
):
    """load(path) of the cached table ``prefix_key.npz``, else build(), saved there.  A build is
    announced once, as a warning (so a command with no logging set up shows it too), with its
    expected time from ``expected_cpu_s`` (seconds on one core) over ``workers`` cores."""
    path = cache_path(prefix, key)
    if path.exists():
        return load(path), path
    if log is not None:
        eta = (
            f", ~{expected_cpu_s / max(workers, 1):.0f} s on {workers} core{'s' if workers > 1 else ''}"
            if expected_cpu_s
            else ""
        )
        log.warning(
            "building the %s look-up table once%s; later runs read it from %s", what, eta, path.parent
        )
    lut = build()
    path.parent.mkdir(parents=True, exist_ok=True)
    lut.save(path)
    return lut, path


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
    nodes = int(
        np.prod(
            [
                a.size
                for a in settings.nodes(float(radius_range_km[0]), earth_radius_km, mirror_symmetric(off))
            ]
        )
    )
    expected = MOONLIT_LUT_BUILD_SECONDS_PER_NODE * nodes * len(off.door_states_deg)
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
