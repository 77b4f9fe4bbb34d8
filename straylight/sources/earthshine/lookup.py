"""What the two earthshine look-up tables share: their coordinates and interpolation.

A sample's coordinates in a table (:func:`_lamp_coordinates`: the satellite's radius, the lamp's
zenith angle, the line of sight's zenith angle and azimuth from the lamp, and for the moonlit
Earth's table the roll; the vectors' components in one compiled pass), the interpolation in
asinh(c / scale) with each sample read from its own door state's channels
(:func:`_asinh_grids`, :func:`_per_door_state`), the lamp zenith angle beyond which a table is 0
(:func:`_dark_lamp_zenith_deg`).  The tables are
:class:`~straylight.sources.earthshine.sunlit_table.EarthshineLUT` (the sunlit Earth) and
:class:`~straylight.sources.earthshine.moonlit_table.MoonlitLUT` (the moonlit Earth); their files are
:class:`~straylight.sources.earthshine.table.LampTable`'s.  This module has no public names.
"""

from __future__ import annotations

import numpy as np

from straylight.optics.door import door_state_index
from straylight.sky.runs import scene_rows
from straylight.sky.vectors import any_perpendicular_xyz, dot, norm, unit, unit_xyz
from straylight.util.gridinterp import LinearGrid
from straylight.util.kernel_cache import njit

#: the tables' private helpers, for sunlit_table, moonlit_table and table only
__all__: list[str] = []


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
