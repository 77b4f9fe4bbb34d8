"""Earthshine from a precomputed look-up table (issue #7, fast path).

The sunlit-Earth coefficients of :meth:`OffFieldModel.earthshine_coefficients` (direct through
the PST and via the door, per unit solar irradiance) depend on the scene only through
four quantities, because the problem is symmetric under rotation about the local vertical:

* the satellite's geocentric distance r (one node for a circular orbit),
* the Sun's zenith angle at the sub-satellite point, z_sun (0-180 deg),
* the line of sight's zenith angle at the satellite, zeta (0-180 deg),
* the line of sight's azimuth from the Sun's about the vertical, A (0-180 deg when the PST and
  the door are mirror-symmetric about the Sun's plane, phi -> -phi, as the default is; else
  0-360 deg),

and on the door state, one table per state.  The table is built once with the same Earth-cap
grid as the direct method and interpolated linearly in asinh(c / c_scale) (logarithmic for the
large values, linear near zero, so the terminator interpolates without the log's bias).  The
in-field term (the line of sight hitting the Earth) is not tabulated: it is one ray per sample
and jumps at the limb, so it is evaluated directly.

The moonlit-Earth coefficients are bounded (:meth:`EarthshineLUT.moon_bound`: the cap fully lit,
PST at its azimuthal maximum, door fully open), skipped where the bound is below their share of
the tolerance, and elsewhere taken from a table of their own (:class:`MoonlitLUT`), which runs
over one angle more, the telescope's roll: it is set by the Sun, not by the Moon.

Validity: the Sun is taken at infinity (its direction from the satellite and from the Earth's
centre differ by < 3e-6 rad).  Errors against the direct sum: bench/run.py (knob
``earthshine_lut``).
"""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path

import numpy as np
from numba import njit

from straylight.optics.door import door_state_index
from straylight.errors import InputError
from straylight.sky.geometry import any_perpendicular_xyz, unit_xyz, dot, norm, rows_at, scene_rows, telescope_frame, unit
from straylight.util.gridinterp import LinearGrid
from straylight.util.io import cache_dir
from straylight.sources.bodies import MOON_APOGEE_KM, MOON_MEAN_DISTANCE_KM, MOON_PERIGEE_KM
from straylight.sources.photometry import AU_KM

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
    ``los_zenith_step_deg`` above the limb and 2.5 times coarser below it (never observable)."""

    # with the default PST these steps validate within 0.5 % of the total (the build's validation,
    # recorded in the products' models record); 5 deg in azimuth cuts the peaks near 0 and 180
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
        about the Sun's vertical plane (:func:`mirror_symmetric`: azimuth 0-180 deg, else 0-360)."""
        zs, zl, az = self.nodes(radius_km, earth_radius_km, symmetric)
        return zs.size * zl.size * az.size * self.n_radius

    def nodes(self, radius_km: float, earth_radius_km: float, symmetric: bool):
        """(sun zenith, line-of-sight zenith, azimuth) node arrays, deg."""
        cap = np.degrees(np.arccos(earth_radius_km / radius_km))  # the cap's edge beyond nadir, = limb depression
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
#: line-of-sight nodes are finer: 2-deg nodes alone erred by up to 22 % of the total there
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


def _asinh_grids(axes, direct: dict, door: dict, scale: float, drop_first: bool = False) -> tuple:
    """(door states ascending, one LinearGrid of asinh(c / scale) on ``axes`` whose channels are
    each state's direct and door terms in turn): a sample's cell is located once whatever its
    state; ``drop_first``: the tables' first axis has one node."""
    states = sorted(direct)
    v = np.arcsinh(np.stack([np.stack([direct[s], door[s]], axis=-1) for s in states], axis=-2) / scale)
    v = v.reshape(v.shape[:-2] + (2 * len(states),))
    return states, LinearGrid(axes, v[0] if drop_first else v, channel_group=2)  # read a state's pair at a time


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


def cache_path(prefix: str, key: str) -> Path:
    """Where the table ``prefix`` with digest ``key`` is cached (it may not exist yet)."""
    return cache_dir() / f"{prefix}_{key}.npz"


def _cached(prefix: str, key: str, what: str, load, build, log, expected_cpu_s: float | None = None,
            workers: int = 1):
    """load(path) of the cached table ``prefix_key.npz``, else build(), saved there.  A build is
    announced once, as a warning (so a command with no logging set up shows it too), with its
    expected time from ``expected_cpu_s`` (seconds on one core) over ``workers`` cores."""
    path = cache_path(prefix, key)
    if path.exists():
        return load(path), path
    if log is not None:
        eta = f", ~{expected_cpu_s / max(workers, 1):.0f} s on {workers} core{'s' if workers > 1 else ''}" \
            if expected_cpu_s else ""
        log.warning("building the %s look-up table once%s; later runs read it from %s", what, eta, path.parent)
    lut = build()
    path.parent.mkdir(parents=True, exist_ok=True)
    lut.save(path)
    return lut, path


def _dark_lamp_zenith_deg(zenith_nodes_deg, tables, axis: int) -> float:
    """The lamp zenith angle beyond which ``tables`` (each with the lamp's zenith angle along
    ``axis``) are 0: the first node of the all-zero slabs that run to the axis' end, in every
    table, plus 1e-6 deg, so that a point within rounding of that node (which the cell finder
    may place in the cell below) is still looked up; inf when the last slab is not 0.
    Beyond it the interpolation gives exactly 0 and no look-up is needed."""
    nonzero = np.zeros(zenith_nodes_deg.size, bool)
    for table in tables:
        nonzero |= np.any(np.moveaxis(np.asarray(table), axis, 0).reshape(zenith_nodes_deg.size, -1) != 0, axis=1)
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
    (:class:`~straylight.sky.geometry.SceneRuns`)."""
    sat, lamp, los = np.broadcast_arrays(np.asarray(sat_km, float), np.asarray(lamp_km, float),
                                         np.asarray(los, float))
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
    xy = [np.ascontiguousarray(np.broadcast_to(a, shape + (3,)).reshape(-1, 3), dtype=float)
          for a in frame_xy] if with_roll else [np.zeros((0, 3))] * 2
    _los_components_kernel(np.ascontiguousarray(los.reshape(-1, 3)), *xy, np.ascontiguousarray(index, dtype=np.intp),
                           np.ascontiguousarray(up), np.ascontiguousarray(lamp_h),
                           np.ascontiguousarray(np.cross(up, lamp_h)), comp)
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
        out[p] = 1.2 * max(max(table[z0, i - 1], table[z0, i]), max(table[z1, i - 1], table[z1, i])) + door_bound


def _local_scene(R, Z, L, A):
    """Satellite, Sun (km) and line of sight in the local frame: vertical +x, Sun in the x-y plane."""
    sat = np.stack([R, 0 * R, 0 * R], axis=-1)
    sun = AU_KM * np.stack([np.cos(Z), np.sin(Z), 0 * Z], axis=-1)
    los = np.stack([np.cos(L), np.sin(L) * np.cos(A), np.sin(L) * np.sin(A)], axis=-1)
    return sat, sun, los


def sun_coefficients_direct(off, R, Z, L, A, state, earth_radius_km):
    """Direct sums in the local frame (vertical +x, the Sun in the x-y plane): radius R (km),
    Sun zenith Z, line-of-sight zenith L and azimuth A (rad), one door state."""
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
        d, g = off.earthshine_scene_sums(sat[idx[0]], sun[idx[0]], _NO_MOON_KM, frame, earth_radius_km,
                                         np.full((idx.size, 1), state_index), with_moon=False)
        d_out[idx], g_out[idx] = d[:, 0, 0], g[:, 0, 0]
    return d_out, g_out


#: a Moon far away, for sums that leave the Moon out (its position must still be finite)
_NO_MOON_KM = np.array([0.0, 0.0, -1e9])


def _sunlit_scene(off, r_km: float, sun_zenith_rad: float, los_zenith_rad, azimuth_rad, earth_radius_km: float):
    """One (radius, Sun zenith) scene of the sunlit table over every (line-of-sight zenith,
    azimuth) node (flattened, zenith-major): (direct, door) per unit solar irradiance, (nodes,
    door states ascending), and the moonlit Earth's direct bound with the Moon where the Sun is
    (:meth:`OffFieldModel.lamp_bound_one_scene`), (nodes,)."""
    L, A = (v.ravel() for v in np.meshgrid(los_zenith_rad, azimuth_rad, indexing="ij"))
    sat, sun, los = _local_scene(np.full(L.size, r_km), np.full(L.size, sun_zenith_rad), L, A)
    frame = telescope_frame(los, sun - sat)
    n_states = len(off.door_states_deg)
    d, g = off.earthshine_scene_sums(sat[0], sun[0], _NO_MOON_KM, frame, earth_radius_km,
                                     np.broadcast_to(np.arange(n_states), (L.size, n_states)), with_moon=False)
    bound = off.lamp_bound_one_scene(sat[0], unit(sun[0]), los, earth_radius_km)
    return d[:, :, 0], g[:, :, 0], bound


def _run_scenes(fn, tasks: list, workers: int, what: str, log=None) -> list:
    """fn(*task) for every task (a scene each), in ``workers`` threads (the sums are compiled
    and release the GIL), with a progress bar on standard error once it runs for more than a
    few seconds.  Each task's result does not depend on the threads, so the table is the same
    byte for byte whatever ``workers`` is (tests/sources/test_earthshine_lut.py)."""
    from concurrent.futures import ThreadPoolExecutor

    from tqdm import tqdm

    results = [None] * len(tasks)
    import sys

    tty = sys.stderr.isatty()
    with tqdm(total=len(tasks), desc=what, unit="scene", delay=3.0, mininterval=1.0 if tty else 60.0,
              leave=not tty, file=sys.stderr) as bar:
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
    """PST(theta, phi) == PST(theta, -phi) and the door shade likewise (sampled check)."""
    th = np.r_[np.linspace(0.0, 89.0, 90), np.linspace(91.0, 180.0, 90)][:, None]  # 90: grazing, noise
    ph = np.linspace(0.0, 360.0, 73)[None, :]
    if not np.allclose(off.pst(th, ph), off.pst(th, 360.0 - ph), rtol=1e-9):
        return False
    return all(np.allclose(off.door_factor(th, ph, s), off.door_factor(th, 360.0 - ph, s), atol=1e-9)
               for s in off.door_states_deg)


def _observable_points(rr, earth_radius_km, symmetric, n, avoidance_deg):
    """n random (radius, Sun zenith, line-of-sight zenith, azimuth) points (deg) whose line of
    sight meets the dark-limb, bright-limb and Sun avoidance angles (rejection sampling)."""
    from straylight.sky.geometry import angle_between_deg, limb_geometry

    dark_min, bright_min, sun_min = (float(a) for a in avoidance_deg)
    rng = np.random.default_rng(20261122)
    limb = 90.0 + np.degrees(np.arccos(earth_radius_km / rr.min()))
    kept = []
    while sum(len(k[0]) for k in kept) < n:
        m = 4 * n
        p = (rng.uniform(rr.min(), rr.max(), m), rng.uniform(0.0, 180.0, m),
             rng.uniform(0.0, max(limb - dark_min, 1.0), m), rng.uniform(0.0, 180.0 if symmetric else 360.0, m))
        sat, sun, los = _local_scene(p[0], *np.radians(p[1:]))
        lg = limb_geometry(sat, los, sun, earth_radius_km)
        ok = ((lg.dark_limb_angle_deg >= dark_min) & (lg.bright_limb_angle_deg >= bright_min)
              & (angle_between_deg(los, sun - sat) >= sun_min))
        if not ok.any() and not kept:
            raise InputError(f"earthshine table validation: no observable line of sight with avoidance angles "
                             f"{avoidance_deg} deg")
        kept.append(tuple(v[ok] for v in p))
    return tuple(np.concatenate([k[i] for k in kept])[:n] for i in range(4))


@dataclass
class EarthshineLUT:
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
    validation_max_rel_error: float = float("nan")  # see build(): against the direct sum
    build_seconds: float = float("nan")

    # -- construction ---------------------------------------------------------------------------
    @classmethod
    def build(cls, off, earth_radius_km: float, radius_range_km: tuple[float, float],
              settings: LUTSettings = LUTSettings(), floor: float = 0.0,
              n_validation: int = 400, avoidance_deg: tuple = (30.0, 80.0, 50.0),
              workers: int = 1) -> "EarthshineLUT":
        """Tabulate ``off.earthshine_coefficients`` (an :class:`OffFieldModel`), then validate:
        at ``n_validation`` random points where a line of sight is observable (``avoidance_deg``:
        the minimum angles from the dark limb, the bright limb and the Sun, as the campaign's
        constraints) the largest |table - direct| / (direct + floor), with ``floor`` the darkest
        sky background in the same units (so the error is a fraction of the total, and a
        pessimistic one).  ``workers`` threads share the scenes (one per core; the sums are
        compiled, :mod:`straylight.sources.earthshine_kernel`)."""
        import time

        t_start = time.perf_counter()
        s = settings
        symmetric = mirror_symmetric(off)
        off._kernel_tables  # the door's tables once, before the threads share them
        rr = np.linspace(radius_range_km[0], radius_range_km[1], s.n_radius) if s.n_radius > 1 \
            else np.array([0.5 * (radius_range_km[0] + radius_range_km[1])])
        zs, zl, az = s.nodes(float(rr.min()), earth_radius_km, symmetric)
        shape = (rr.size, zs.size, zl.size, az.size)
        # one task per (radius, Sun zenith) scene: its cap grid once, every door state at once
        tasks = [(off, float(r), float(z), np.radians(zl), np.radians(az), earth_radius_km)
                 for r in rr for z in np.radians(zs)]
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
        moon_door = max(off.earthshine.door_reflectance * float(np.sum(w)) * off.pixel_area_m2
                        for _, _, w in off._door_weights.values()) * off.earthshine.albedo
        scale = _asinh_scale(direct, door)
        lut = cls(rr, zs, zl, az, direct, door, bound, moon_door, symmetric, scale)
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

    # -- evaluation -----------------------------------------------------------------------------
    def _interpolators(self):
        if not hasattr(self, "_interp"):
            axes = (self.sun_zenith_deg, self.los_zenith_deg, self.azimuth_deg)
            if self.radius_km.size > 1:
                axes = (self.radius_km,) + axes

            # the axes span every coordinate's whole range; one radius: no radius axis
            self._interp = _asinh_grids(axes, self.direct, self.door, self.scale, drop_first=self.radius_km.size == 1)
        return self._interp

    def coordinates(self, sat_km, sun_km, los, runs=None):
        """(r, z_sun, zeta, A) of samples; arrays of the samples' shape; ``runs``: the samples'
        scene runs when known."""
        return _lamp_coordinates(sat_km, sun_km, los, self.symmetric, runs=runs)

    def sun_coefficients(self, sat_km, sun_km, los, opening_deg, runs=None):
        """(direct_sun, door_sun) per unit solar irradiance, excluding the in-field term;
        ``runs``: the samples' scene runs when known.  Samples whose Sun zenith angle lies
        beyond :attr:`dark_sun_zenith_deg` (no sunlit Earth in view: every table node from there
        on is 0, so the interpolation gives exactly 0) get 0 without a look-up: a low orbit's
        night side, ~40 % of its samples."""
        sat, sun, los = np.broadcast_arrays(np.asarray(sat_km, float), np.asarray(sun_km, float),
                                            np.asarray(los, float))
        shape = los.shape[:-1]
        op = np.broadcast_to(np.asarray(opening_deg, float), shape)
        rows = scene_rows(sat, sun, runs=runs)
        dark_run = self.dark_runs(rows)
        if not np.any(dark_run):
            return self._sun_lookup(sat, sun, los, op, rows)
        lit = np.flatnonzero(~np.take(dark_run, rows.index))
        direct, door = np.zeros(shape), np.zeros(shape)
        if lit.size:
            d, g = self._sun_lookup(*(rows_at(v, shape, lit) for v in (sat, sun, los)), op.reshape(-1)[lit],
                                    rows.at(lit))
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
        """The Sun zenith angle beyond which the table is 0 (:func:`_dark_lamp_zenith_deg`)."""
        return _dark_lamp_zenith_deg(self.sun_zenith_deg, (*self.direct.values(), *self.door.values()), axis=1)

    def dark_runs(self, rows) -> np.ndarray:
        """Per run of ``rows`` (scene runs of (satellite, Sun)): no sunlit Earth in view, the
        table 0 (beyond :attr:`dark_sun_zenith_deg`)."""
        return _beyond_dark_zenith(rows, self.dark_sun_zenith_deg)

    def moon_bound(self, sat_km, moon_km, los, earth_radius_km: float, runs=None):
        """Upper bound of direct_moon + door_moon per unit lunar irradiance at the Earth: the
        larger of the four neighbouring (Moon zenith, line-of-sight zenith) nodes (largest
        radius node), x 1.2 for the azimuth between nodes; infinite for a line of sight less
        than 1 deg above the limb or below it (there a grid block can sit next to the field
        edge, where the PST jumps, and no table bounds it).  ``runs``: the samples' scene runs
        when known."""
        sat, moon, los = np.broadcast_arrays(np.asarray(sat_km, float), np.asarray(moon_km, float),
                                             np.asarray(los, float))
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
        _moon_bound_kernel(np.ascontiguousarray(los.reshape(-1, 3)), np.ascontiguousarray(index, dtype=np.intp),
                           np.ascontiguousarray(up), np.cos(np.radians(limb - 1.0)), zi, self._moon_bound_table,
                           -np.cos(np.radians(self.los_zenith_deg)), float(self.moon_door_bound), out)
        return out.reshape(shape)

    # -- storage --------------------------------------------------------------------------------
    def save(self, path) -> None:
        _save_tables(path, {"radius_km": self.radius_km, "sun_zenith_deg": self.sun_zenith_deg,
                            "los_zenith_deg": self.los_zenith_deg, "azimuth_deg": self.azimuth_deg,
                            "moon_direct_bound": self.moon_direct_bound}, self.direct, self.door,
                     {"moon_door_bound": self.moon_door_bound, "symmetric": self.symmetric, "scale": self.scale,
                      "validation_max_rel_error": self.validation_max_rel_error, "build_seconds": self.build_seconds})

    @classmethod
    def load(cls, path) -> "EarthshineLUT":
        z, meta, direct, door = _load_tables(path, "earthshine")
        return cls(z["radius_km"], z["sun_zenith_deg"], z["los_zenith_deg"], z["azimuth_deg"], direct, door,
                   z["moon_direct_bound"], float(meta["moon_door_bound"]), bool(meta["symmetric"]),
                   float(meta["scale"]), float(meta["validation_max_rel_error"]), float(meta["build_seconds"]))


def load_or_build(off, earth_radius_km, radius_range_km, settings: LUTSettings, floor: float, log=None,
                  avoidance_deg: tuple = (30.0, 80.0, 50.0), workers: int = 1):
    """The table for these inputs from the cache, built (by ``workers`` threads) and stored
    there if missing."""
    key = lut_key(off, earth_radius_km, radius_range_km, settings, floor, avoidance_deg)
    expected = LUT_BUILD_SECONDS_PER_NODE * settings.node_count(radius_range_km[0], earth_radius_km,
                                                                mirror_symmetric(off)) * len(off.door_states_deg)
    return _cached("earthshine_lut", key, "earthshine", EarthshineLUT.load,
                   lambda: EarthshineLUT.build(off, earth_radius_km, radius_range_km, settings, floor,
                                               avoidance_deg=avoidance_deg, workers=workers), log, expected, workers)


def lut_key(off, earth_radius_km, radius_range_km, settings: LUTSettings, floor: float = 0.0,
            avoidance_deg: tuple = (30.0, 80.0, 50.0)) -> str:
    """Digest of everything the table depends on (PST, door, cap grid, albedo, radii, nodes)."""
    return _digest(f"format {LUT_FORMAT}", off,
                   (round(earth_radius_km, 6), tuple(round(r, 3) for r in radius_range_km), settings,
                    f"{floor:.6g}", tuple(float(a) for a in avoidance_deg)))


def _digest(prefix: str, off, items: tuple) -> str:
    """16 hex digits of sha256 over ``prefix``, the PST, the door and Earth settings, and ``items``."""
    h = hashlib.sha256(prefix.encode())
    h.update(np.ascontiguousarray(off.pst.values).tobytes())
    h.update(np.ascontiguousarray(off.pst.theta_deg).tobytes() + np.ascontiguousarray(off.pst.phi_deg).tobytes())
    h.update(repr((off.door, off.door_states_deg, off.pixel_area_m2, off.field_radius_deg, off.earthshine)
                  + items).encode())
    return h.hexdigest()[:16]


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
    within 1.7e-4 of the total at full Moon (:meth:`MoonlitLUT.build`); in the cube of a
    full-Moon day (bench/run.py moonlit_grid, 6 x 12 grid, against 48 x 96) they err by 4.2e-4,
    10/6/15/30 deg by 6.3e-4."""

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
        edge plus one step the Moon lights none of the visible cap (one node at 180)."""
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
    from straylight.sky.geometry import TelescopeFrame

    sat = np.stack([R, 0 * R, 0 * R], axis=-1)
    moon = D[..., None] * np.stack([np.cos(Zm), np.sin(Zm), 0 * Zm], axis=-1)
    los = np.stack([np.cos(L), np.sin(L) * np.cos(A), np.sin(L) * np.sin(A)], axis=-1)
    up_ref = np.stack([np.sin(L), -np.cos(L) * np.cos(A), -np.cos(L) * np.sin(A)], axis=-1)  # upward, in the vertical plane
    x = np.cos(P)[..., None] * up_ref + np.sin(P)[..., None] * np.cross(los, up_ref)
    return sat, moon, TelescopeFrame(x=x, y=np.cross(los, x), z=los)


def _moon_coefficients_direct(off, R, D, Zm, L, A, P, state, earth_radius_km, grid):
    """(direct_moon, door_moon) of the moonlit Earth on the Earth-cap ``grid``, per unit lunar
    irradiance at the Earth, for scenes in the local frame (rad, km), one door state (or,
    ``state`` None, every door state: arrays (samples, door states ascending)); samples sharing
    (R, D, Zm) share one cap grid."""
    n_states = len(off.door_states_deg)
    sel = (np.arange(n_states) if state is None else np.array([sorted(off.door_states_deg).index(state)]))
    d_out, g_out = np.empty((R.size, sel.size)), np.empty((R.size, sel.size))
    groups = {}
    for i, key in enumerate(zip(R.tolist(), D.tolist(), Zm.tolist())):
        groups.setdefault(key, []).append(i)
    es = replace(off.earthshine, n_gamma=int(grid[0]), n_psi=int(grid[1]))
    for idx in groups.values():
        idx = np.asarray(idx)
        sat, moon, frame = _moonlit_scene(R[idx], D[idx], Zm[idx], L[idx], A[idx], P[idx])
        d, g = off.earthshine_scene_sums(sat[0], moon[0], moon[0], frame, earth_radius_km,
                                         np.broadcast_to(sel, (idx.size, sel.size)), with_sun=False, s=es)
        d_out[idx], g_out[idx] = d[:, :, 1], g[:, :, 1]
    return (d_out[:, 0], g_out[:, 0]) if state is not None else (d_out, g_out)


@dataclass
class MoonlitLUT:
    """The moonlit Earth's coefficients (direct and via the door, per unit lunar irradiance at
    the Earth, outside the field) on the coarse Earth-cap ``grid`` the direct path sums
    (models.earthshine.moonlit_grid), tabulated over (Moon zenith, line-of-sight zenith,
    azimuth from the Moon, roll) per door state and interpolated linearly in asinh(c / scale).
    The satellite's radius and the Moon's distance are fixed at the orbit's mean and the
    Moon's mean; the validation draws both over their ranges."""

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

    @classmethod
    def build(cls, off, earth_radius_km: float, radius_range_km: tuple[float, float],
              settings: MoonlitSettings = MoonlitSettings(), grid: tuple[int, int] = (8, 16),
              floor: float = 0.0, moon_max: float = 0.0, dark_limb_min_deg: float = 30.0,
              n_validation: int = 400, workers: int = 1) -> "MoonlitLUT":
        """Tabulate, then validate at ``n_validation`` random points whose line of sight is at
        least ``dark_limb_min_deg`` above the limb (any Moon, roll, radius in the orbit's range
        and Moon distance from perigee to apogee): the largest |table - direct| x moon_max /
        (direct x moon_max + floor), with ``moon_max`` the brightest lunar irradiance (full Moon
        at perigee) and ``floor`` the darkest sky, both per unit solar irradiance at 1 AU: an
        error as a fraction of the total, at full Moon (a pessimistic one)."""
        import time

        t_start = time.perf_counter()
        symmetric = mirror_symmetric(off)
        off._kernel_tables  # the door's tables once, before the threads share them
        r0 = 0.5 * (radius_range_km[0] + radius_range_km[1])
        zm, zl, az, roll = settings.nodes(float(radius_range_km[0]), earth_radius_km, symmetric)
        Zm, L, A, P = (v.ravel() for v in np.meshgrid(*(np.radians(v) for v in (zm, zl, az, roll)), indexing="ij"))
        # built at the Moon's mean distance; the validation draws perigee to apogee, so the
        # parallax this ignores is inside the validated error
        R, D = np.full(Zm.size, r0), np.full(Zm.size, MOON_MEAN_DISTANCE_KM)
        per_zm = zl.size * az.size * roll.size  # nodes of one Moon zenith are contiguous: one scene
        tasks = [(off, R[p], D[p], Zm[p], L[p], A[p], P[p], None, earth_radius_km, tuple(grid))
                 for p in (slice(i * per_zm, (i + 1) * per_zm) for i in range(zm.size))]
        results = _run_scenes(_moon_coefficients_direct, tasks, workers, "moonlit-Earth table")
        shape = (zm.size, zl.size, az.size, roll.size)
        ascending = sorted(off.door_states_deg)
        direct, door = {}, {}
        for state in off.door_states_deg:
            j = ascending.index(state)
            direct[state] = np.concatenate([res[0][:, j] for res in results]).reshape(shape)
            door[state] = np.concatenate([res[1][:, j] for res in results]).reshape(shape)
        scale = _asinh_scale(direct, door)
        lut = cls(zm, zl, az, roll, direct, door, symmetric, scale, tuple(int(g) for g in grid))
        rng = np.random.default_rng(20261122)
        n = n_validation
        limb = 90.0 + np.degrees(np.arccos(earth_radius_km / radius_range_km[0]))
        vr = rng.uniform(radius_range_km[0], radius_range_km[1], n)
        vd = rng.uniform(MOON_PERIGEE_KM, MOON_APOGEE_KM, n)
        vz, vl = np.radians(rng.uniform(0.0, 180.0, n)), np.radians(rng.uniform(0.0, max(limb - dark_limb_min_deg, 1.0), n))
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

    def _interpolators(self):
        if not hasattr(self, "_interp"):
            axes = (self.moon_zenith_deg, self.los_zenith_deg, self.azimuth_deg, self.roll_deg)
            self._interp = _asinh_grids(axes, self.direct, self.door, self.scale)
        return self._interp

    @cached_property
    def dark_moon_zenith_deg(self) -> float:
        """The Moon zenith angle beyond which the table is 0 (:func:`_dark_lamp_zenith_deg`)."""
        return _dark_lamp_zenith_deg(self.moon_zenith_deg, (*self.direct.values(), *self.door.values()), axis=0)

    def dark_runs(self, rows) -> np.ndarray:
        """Per run of ``rows`` (scene runs of (satellite, Moon)): no moonlit Earth in view, the
        table 0 (beyond :attr:`dark_moon_zenith_deg`)."""
        return _beyond_dark_zenith(rows, self.dark_moon_zenith_deg)

    def coordinates(self, sat_km, moon_km, frame, runs=None):
        """(Moon zenith, line-of-sight zenith, azimuth from the Moon, roll) of samples, deg;
        ``runs``: the samples' scene runs when known."""
        return _lamp_coordinates(sat_km, moon_km, frame.z, self.symmetric, (frame.x, frame.y), runs)[1:]

    def coefficients(self, sat_km, moon_km, frame, opening_deg, runs=None):
        """(direct_moon, door_moon) per unit lunar irradiance at the Earth, outside the field;
        ``runs``: the samples' scene runs when known."""
        zm, zeta, a, roll = self.coordinates(sat_km, moon_km, frame, runs)
        shape = zm.shape
        return _per_door_state(self._interpolators(), [v.ravel() for v in (zm, zeta, a, roll)], opening_deg, shape,
                               self.scale)

    def save(self, path) -> None:
        _save_tables(path, {"moon_zenith_deg": self.moon_zenith_deg, "los_zenith_deg": self.los_zenith_deg,
                            "azimuth_deg": self.azimuth_deg, "roll_deg": self.roll_deg}, self.direct, self.door,
                     {"symmetric": self.symmetric, "scale": self.scale, "grid": list(self.grid),
                      "validation_max_rel_error": self.validation_max_rel_error, "build_seconds": self.build_seconds})

    @classmethod
    def load(cls, path) -> "MoonlitLUT":
        z, meta, direct, door = _load_tables(path, "moonlit-Earth")
        return cls(z["moon_zenith_deg"], z["los_zenith_deg"], z["azimuth_deg"], z["roll_deg"], direct, door,
                   bool(meta["symmetric"]), float(meta["scale"]), tuple(meta["grid"]),
                   float(meta["validation_max_rel_error"]), float(meta["build_seconds"]))


def moonlit_key(off, earth_radius_km, radius_range_km, settings: MoonlitSettings, grid, floor: float,
                moon_max: float, dark_limb_min_deg: float) -> str:
    """Digest of everything the moonlit table depends on."""
    return _digest(f"moonlit format {MOONLIT_FORMAT}", off,
                   (round(earth_radius_km, 6), tuple(round(r, 3) for r in radius_range_km), settings,
                    tuple(int(g) for g in grid), f"{floor:.6g}", f"{moon_max:.6g}", float(dark_limb_min_deg)))


def load_or_build_moonlit(off, earth_radius_km, radius_range_km, settings: MoonlitSettings, grid, floor: float,
                          moon_max: float, dark_limb_min_deg: float = 30.0, log=None, workers: int = 1):
    """The moonlit table for these inputs from the cache, built and stored there if missing."""
    key = moonlit_key(off, earth_radius_km, radius_range_km, settings, grid, floor, moon_max, dark_limb_min_deg)
    nodes = int(np.prod([a.size for a in settings.nodes(float(radius_range_km[0]), earth_radius_km,
                                                        mirror_symmetric(off))]))
    expected = MOONLIT_LUT_BUILD_SECONDS_PER_NODE * nodes * len(off.door_states_deg)
    return _cached("moonlit_lut", key, "moonlit-Earth", MoonlitLUT.load,
                   lambda: MoonlitLUT.build(off, earth_radius_km, radius_range_km, settings, grid, floor, moon_max,
                                            dark_limb_min_deg, workers=workers), log, expected, workers)
