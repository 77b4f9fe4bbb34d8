"""The Earth-cap sum of one scene, compiled: the inner loop of the direct earthshine
(:meth:`~straylight.sources.earthshine.engine.EarthGrid.earthshine_coefficients` for lines of sight
sharing a satellite and lamps) and of the earthshine tables' builds
(:mod:`straylight.sources.earthshine.sunlit_build`, :mod:`straylight.sources.earthshine.moonlit_build`).

For each line of sight m (its telescope frame x, y, z) and each lit cap block k (unit direction
d_k from the satellite, spans across the block, luminance-times-solid-angle L_kc per lamp c):

* direct (EA1): sum_k L_kc PST(theta, phi) Sp_s(min(theta, 90), phi) front_k [theta > field]
  x pixel area, with theta, phi the block's direction in the telescope frame, front_k the part
  of the block in front of the aperture plane (:meth:`EarthGrid.front_fraction`); a block
  the plane cuts is summed over its children, the blocks of the finer grid nested in it
  (:meth:`EarthGrid.cut_children`), each with its own angles, front part and luminance:
  there Sp steps to 0 and the luminance changes fastest across a block (near the limb);
* door (EA2): k_s sum_k L_kc max(d_k . n_s, 0) f_s(theta, phi), with n_s the door's inner normal,
  f_s the share of the door the telescope body leaves lit and k_s = reflectance x sum of the
  door's weights x pixel area, per door state s.

The look-ups are those of :class:`~straylight.util.gridinterp.LinearGrid` (clipped, bilinear),
written for two axes; the PST is interpolated in its natural log, as :class:`~straylight.optics.pst.PST`.
Each line of sight asks for one or more door states (``state_sel``, -1: none, which gives 0 for
both terms, as :meth:`EarthGrid.door_factor` does for an opening that is no state): the
table builds ask for every state at once, so the geometry and the PST are computed once per
block and line of sight for all of them.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from straylight.util.gridinterp import cell_of
from straylight.util.kernel_cache import njit

__all__ = [
    "CapBlocks",
    "DoorArrays",
    "GridArrays",
    "GridPack",
    "OpticsArrays",
    "Sightlines",
    "cap_sums",
    "lamp_bound_sums",
]

_DEG = 180.0 / math.pi


class GridArrays(NamedTuple):
    """A two-axis grid's cell finders (:func:`~straylight.util.gridinterp.cell_of`'s arrays, in
    the axes' units: deg) and ``values`` (grids, nodes), for :func:`cap_sums`."""

    lo: np.ndarray
    hi: np.ndarray
    uniform: np.ndarray
    inv_width: np.ndarray
    n_bins: np.ndarray
    bin_cell: np.ndarray
    nodes: np.ndarray
    n_nodes: np.ndarray
    inv_step: np.ndarray
    stride0: int
    values: np.ndarray


class Sightlines(NamedTuple):
    """The lines of sight :func:`cap_sums` sums for."""

    x: np.ndarray
    """Telescope frame x axes, (M, 3) unit vectors, ICRS."""
    y: np.ndarray
    """Telescope frame y axes, (M, 3)."""
    z: np.ndarray
    """Telescope frame z axes (the boresights), (M, 3)."""
    state_sel: np.ndarray
    """Door state indices (M, J) of int, ascending states (-1: none, which gives 0)."""


class CapBlocks(NamedTuple):
    """The lit cap blocks (:meth:`EarthGrid.lit_cap_blocks`) and their children
    (:meth:`EarthGrid.cut_children`): a block the aperture plane cuts is summed over them."""

    dirs: np.ndarray
    """Unit directions from the satellite, (K, 3)."""
    span_g: np.ndarray
    """Spans in nadir angle, (K, 3) vectors."""
    span_p: np.ndarray
    """Spans in azimuth, (K, 3) vectors."""
    lum: np.ndarray
    """albedo / pi x cos(lamp zenith) x solid angle per lamp, (K, C), dimensionless (sr-1 x sr)."""
    child_dirs: np.ndarray
    """The children's directions, (K, S, 3) (S = 0: the block whole)."""
    child_g: np.ndarray
    """The children's nadir-angle spans, (K, S, 3)."""
    child_p: np.ndarray
    """The children's azimuth spans, (K, S, 3)."""
    child_lum: np.ndarray
    """The children's luminance times solid angle per lamp, (K, S, C), as ``lum``."""


class OpticsArrays(NamedTuple):
    """The telescope's part of :func:`cap_sums`."""

    field_radius_deg: float
    """The field's radius, deg (blocks within it add no direct term)."""
    pixel_area_m2: float
    """Detector pixel area, m2."""
    pst: GridArrays
    """The PST's grid: one row, the natural log of the PST over (theta, phi) in deg."""


class DoorArrays(NamedTuple):
    """The door's part of :func:`cap_sums`, per door state (S states, ascending)."""

    normal: np.ndarray
    """The door's inner normal per state, (S, 3), telescope frame."""
    k: np.ndarray
    """Reflectance x sum of the door's weights x pixel area per state, (S,), m2."""
    sp: GridArrays
    """The door's Sp grids, one row per state."""
    lit: GridArrays
    """The lit-fraction grids, one row per state."""
    has_body: bool
    """False: the lit fraction is 1 everywhere (``lit`` is not read)."""
    lit_at_plane: np.ndarray
    """(S,) the lit fraction at theta <= 90 deg (where the grid is clipped to its first row)
    when that row is constant in phi, else -1: a direction in front of the aperture plane then
    needs no angles for the door's term."""


class GridPack:
    """A two-axis :class:`~straylight.util.gridinterp.LinearGrid`'s cell finders as flat arrays
    for :func:`cap_sums`, with the values of one or more grids sharing those axes as rows of
    ``values`` (grids, nodes).

    Parameters
    ----------
    grids : sequence of LinearGrid
        Two-axis grids sharing their nodes.

    Raises
    ------
    ValueError
        When a grid has not two axes or the grids' nodes differ.
    """

    def __init__(self, grids):
        g0 = grids[0]
        if len(g0.axes) != 2:
            raise ValueError("GridPack needs two-axis grids")
        for g in grids[1:]:
            if not all(np.array_equal(a.nodes, b.nodes) for a, b in zip(g.axes, g0.axes)):
                raise ValueError("the grids of a GridPack must share their nodes")
        self.lo, self.hi = g0._lo, g0._hi
        self.uniform = np.array([a.uniform for a in g0.axes])
        self.inv_width, self.n_bins, self.bin_cell = g0._inv_width, g0._n_bins, g0._bin_cell
        self.nodes, self.n_nodes, self.inv_step = g0._nodes, g0._n_nodes, g0._inv_step
        self.stride0 = int(g0._strides[0])
        self.values = np.ascontiguousarray(np.stack([np.asarray(g._flat, float).ravel() for g in grids]))

    def arrays(self) -> GridArrays:
        """The arrays :func:`cap_sums` takes for this grid.

        Returns
        -------
        GridArrays
            The cell finders (in the axes' units) and ``values`` (grids, nodes).
        """
        return GridArrays(
            self.lo,
            self.hi,
            self.uniform,
            self.inv_width,
            self.n_bins,
            self.bin_cell,
            self.nodes,
            self.n_nodes,
            self.inv_step,
            self.stride0,
            self.values,
        )


@njit(cache=True, nogil=True, inline="always")
def _bilinear_at(values, row, base, s0, ta, tb):
    """Row ``row`` of ``values`` interpolated in the cell at flat node ``base``."""
    return (values[row, base] * (1 - tb) + values[row, base + 1] * tb) * (1 - ta) + (
        values[row, base + s0] * (1 - tb) + values[row, base + s0 + 1] * tb
    ) * ta


@njit(cache=True, nogil=True, error_model="numpy")
def cap_sums(los, cap, optics, door_arrays, direct, door):
    """The module's sums into ``direct`` and ``door`` (M, J, C), zeroed here.

    Parameters
    ----------
    los : Sightlines
        The lines of sight's telescope frames and door states.
    cap : CapBlocks
        The lit blocks and their children.
    optics : OpticsArrays
        The field's radius, the pixel area and the PST's grid.
    door_arrays : DoorArrays
        The door's normals, factors and grids per state.
    direct, door : ndarray, shape (M, J, C)
        Output: e-/s/pix per photon s-1 m-2 of each lamp, outside the field (EA1 and EA2).
    """
    fx, fy, fz, state_sel = los
    blocks, span_g, span_p, lum, child_dirs, child_g, child_p, child_lum = cap
    field_radius_deg, pixel_area_m2, pst = optics
    door_normal, door_k, sp, lit, has_body, lit_at_plane = door_arrays
    p_lo, p_hi, p_uni, p_iw, p_nb, p_bc, p_nodes, p_nn, p_is, p_s0, p_val = pst
    d_lo, d_hi, d_uni, d_iw, d_nb, d_bc, d_nodes, d_nn, d_is, d_s0, d_val = sp
    f_lo, f_hi, f_uni, f_iw, f_nb, f_bc, f_nodes, f_nn, f_is, f_s0, f_val = lit
    n_los, n_sel = state_sel.shape
    n_blocks, n_lamps = lum.shape
    n_child = child_dirs.shape[1]
    acc = np.zeros((n_sel, n_lamps))
    direct[:] = 0.0
    door[:] = 0.0
    for m in range(n_los):
        x0, x1, x2 = fx[m, 0], fx[m, 1], fx[m, 2]
        y0, y1, y2 = fy[m, 0], fy[m, 1], fy[m, 2]
        z0, z1, z2 = fz[m, 0], fz[m, 1], fz[m, 2]
        for k in range(n_blocks):
            bx, by, bz = blocks[k, 0], blocks[k, 1], blocks[k, 2]
            dx = x0 * bx + x1 * by + x2 * bz
            dy = y0 * bx + y1 * by + y2 * bz
            dz = z0 * bx + z1 * by + z2 * bz
            # the part of the block in front of the aperture plane
            gz = abs(z0 * span_g[k, 0] + z1 * span_g[k, 1] + z2 * span_g[k, 2])
            pz = abs(z0 * span_p[k, 0] + z1 * span_p[k, 1] + z2 * span_p[k, 2])
            half = 0.5 * (gz + pz)
            if half > 0.0:
                front = min(max(0.5 + 0.5 * dz / half, 0.0), 1.0)
            else:
                front = 1.0 if dz > 0.0 else 0.0
            # the door's inner faces it lights; the angles only where a term needs them
            lights_door = False
            door_angles = False  # the door's term needs the angles (the lit fraction's look-up)
            for j in range(n_sel):
                s = state_sel[m, j]
                if s >= 0 and dx * door_normal[s, 0] + dy * door_normal[s, 1] + dz * door_normal[s, 2] > 0.0:
                    lights_door = True
                    if has_body and not (dz >= 0.0 and lit_at_plane[s] >= 0.0):
                        door_angles = True
            if not (front > 0.0 or lights_door):
                continue
            theta = math.atan2(math.sqrt(dx * dx + dy * dy), dz) * _DEG
            w = 0.0
            in_view = front > 0.0 and theta > field_radius_deg
            if not (in_view or door_angles):
                phi = 0.0  # not needed: the door's terms without a body take no angle
            else:
                phi = math.atan2(dy, dx) * _DEG
                if phi < 0.0:
                    phi += 360.0
            if n_child > 1 and 0.0 < front < 1.0:
                # the aperture plane cuts the block: its children's own angles, front parts and
                # luminances give the direct term (the door's term below takes the block whole)
                acc[:, :] = 0.0
                for q in range(n_child):
                    ux, uy, uz = child_dirs[k, q, 0], child_dirs[k, q, 1], child_dirs[k, q, 2]
                    ex = x0 * ux + x1 * uy + x2 * uz
                    ey = y0 * ux + y1 * uy + y2 * uz
                    ez = z0 * ux + z1 * uy + z2 * uz
                    cgz = abs(z0 * child_g[k, q, 0] + z1 * child_g[k, q, 1] + z2 * child_g[k, q, 2])
                    cpz = abs(z0 * child_p[k, q, 0] + z1 * child_p[k, q, 1] + z2 * child_p[k, q, 2])
                    ch = 0.5 * (cgz + cpz)
                    if ch > 0.0:
                        f_sub = min(max(0.5 + 0.5 * ez / ch, 0.0), 1.0)
                    else:
                        f_sub = 1.0 if ez > 0.0 else 0.0
                    if not f_sub > 0.0:
                        continue
                    th = math.atan2(math.sqrt(ex * ex + ey * ey), ez) * _DEG
                    if not th > field_radius_deg:
                        continue
                    ph = math.atan2(ey, ex) * _DEG
                    if ph < 0.0:
                        ph += 360.0
                    i0, t0 = cell_of(0, th, p_lo, p_hi, p_uni, p_iw, p_nb, p_bc, p_nodes, p_nn, p_is)
                    i1, t1 = cell_of(1, ph, p_lo, p_hi, p_uni, p_iw, p_nb, p_bc, p_nodes, p_nn, p_is)
                    ws = (
                        math.exp(_bilinear_at(p_val, 0, i0 * p_s0 + i1, p_s0, t0, t1)) * f_sub * pixel_area_m2
                    )
                    si0, st0 = cell_of(
                        0, min(th, 90.0), d_lo, d_hi, d_uni, d_iw, d_nb, d_bc, d_nodes, d_nn, d_is
                    )
                    si1, st1 = cell_of(1, ph, d_lo, d_hi, d_uni, d_iw, d_nb, d_bc, d_nodes, d_nn, d_is)
                    for j in range(n_sel):
                        s = state_sel[m, j]
                        if s >= 0:
                            wj = ws * _bilinear_at(d_val, s, si0 * d_s0 + si1, d_s0, st0, st1)
                            for c in range(n_lamps):
                                acc[j, c] += child_lum[k, q, c] * wj
                for j in range(n_sel):
                    for c in range(n_lamps):
                        direct[m, j, c] += acc[j, c]
                in_view = False  # the direct term is done
            if in_view:
                i0, t0 = cell_of(0, theta, p_lo, p_hi, p_uni, p_iw, p_nb, p_bc, p_nodes, p_nn, p_is)
                i1, t1 = cell_of(1, phi, p_lo, p_hi, p_uni, p_iw, p_nb, p_bc, p_nodes, p_nn, p_is)
                w = math.exp(_bilinear_at(p_val, 0, i0 * p_s0 + i1, p_s0, t0, t1)) * front * pixel_area_m2
            sp_ready = False
            lit_ready = False
            di0, dt0, di1, dt1, fi0, ft0, fi1, ft1 = 0, 0.0, 0, 0.0, 0, 0.0, 0, 0.0
            for j in range(n_sel):
                s = state_sel[m, j]
                if s < 0:
                    continue
                if w > 0.0:
                    if not sp_ready:
                        di0, dt0 = cell_of(
                            0, min(theta, 90.0), d_lo, d_hi, d_uni, d_iw, d_nb, d_bc, d_nodes, d_nn, d_is
                        )
                        di1, dt1 = cell_of(1, phi, d_lo, d_hi, d_uni, d_iw, d_nb, d_bc, d_nodes, d_nn, d_is)
                        sp_ready = True
                    ws = w * _bilinear_at(d_val, s, di0 * d_s0 + di1, d_s0, dt0, dt1)
                    for c in range(n_lamps):
                        direct[m, j, c] += lum[k, c] * ws
                if not lights_door:
                    continue
                cos_inc = dx * door_normal[s, 0] + dy * door_normal[s, 1] + dz * door_normal[s, 2]
                if cos_inc > 0.0:
                    if has_body and dz >= 0.0 and lit_at_plane[s] >= 0.0:
                        cos_inc *= lit_at_plane[s]  # theta <= 90: the grid's first row, constant in phi
                    elif has_body:
                        if not lit_ready:
                            fi0, ft0 = cell_of(
                                0,
                                min(max(theta, 90.0), 180.0),
                                f_lo,
                                f_hi,
                                f_uni,
                                f_iw,
                                f_nb,
                                f_bc,
                                f_nodes,
                                f_nn,
                                f_is,
                            )
                            fi1, ft1 = cell_of(
                                1, phi, f_lo, f_hi, f_uni, f_iw, f_nb, f_bc, f_nodes, f_nn, f_is
                            )
                            lit_ready = True
                        cos_inc *= _bilinear_at(f_val, s, fi0 * f_s0 + fi1, f_s0, ft0, ft1)
                    for c in range(n_lamps):
                        door[m, j, c] += lum[k, c] * cos_inc
        for j in range(n_sel):
            s = state_sel[m, j]
            if s >= 0:
                for c in range(n_lamps):
                    door[m, j, c] *= door_k[s]


@njit(cache=True, nogil=True)
def lamp_bound_sums(los, blocks, lum, cos_field, neg_cos_nodes, pst_row_max, out):
    """:meth:`EarthGrid.lamp_bound_one_scene`'s sum for lines of sight ``los`` (M, 3, unit)
    over blocks (K, 3) with ``lum`` (K,) = albedo / pi x cos(lamp zenith) x solid angle x pixel
    area: sum_k lum_k max(PST row maxima at the theta nodes either side of theta_k) over the
    blocks outside the field (cos theta < ``cos_field``), into ``out`` (M,).  In cosines: the
    node is found in ``neg_cos_nodes`` (minus the cosines of the PST's theta nodes, increasing).

    Parameters
    ----------
    los : ndarray, shape (M, 3)
        Lines of sight, unit vectors.
    blocks : ndarray, shape (K, 3)
        The lit blocks' unit directions from the satellite.
    lum : ndarray, shape (K,)
        albedo / pi x cos(lamp zenith) x solid angle x pixel area, m2.
    cos_field : float
        Cosine of the field's radius.
    neg_cos_nodes : ndarray, shape (T,)
        Minus the cosines of the PST's theta nodes, increasing.
    pst_row_max : ndarray, shape (T,)
        The PST's maximum over phi at each theta node, dimensionless.
    out : ndarray, shape (M,)
        Output: the bound, e-/s/pix per photon s-1 m-2 of the lamp.
    """
    n_th = neg_cos_nodes.size
    for m in range(los.shape[0]):
        lx, ly, lz = los[m, 0], los[m, 1], los[m, 2]
        total = 0.0
        i = 0
        for k in range(blocks.shape[0]):
            c = min(max(lx * blocks[k, 0] + ly * blocks[k, 1] + lz * blocks[k, 2], -1.0), 1.0)
            if not c < cos_field:
                continue
            # np.searchsorted(neg_cos_nodes, -c), walked from the previous block's node: the
            # blocks run around rings of the cap, so their angles change little from one to the next
            x = -c
            while i < n_th and neg_cos_nodes[i] < x:
                i += 1
            while i > 0 and neg_cos_nodes[i - 1] >= x:
                i -= 1
            j = min(max(i, 1), n_th - 1)
            total += lum[k] * max(pst_row_max[j - 1], pst_row_max[j])
        out[m] = total
