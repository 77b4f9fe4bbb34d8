"""Multilinear interpolation on a rectilinear grid, for the hot loops (PST, door, earthshine table).

It computes exactly what ``scipy.interpolate.RegularGridInterpolator(method="linear")`` computes
(tests/util/test_gridinterp.py checks agreement to 1e-12), faster on the earthshine sum's millions
of points per time step: scipy locates cells with a binary search and validates its input on every
call; here each axis gets, once, a table of bins of uniform width no wider than its narrowest cell,
so a point's cell is one multiplication, one look-up and one comparison (on an evenly spaced axis,
one multiplication).  The look-ups are compiled (numba, :func:`_interpolate`): one pass per point
instead of numpy's pass per operation, the same numbers bit for bit (the cube's totals compared
array to array).  On two to four axes the corners are then combined as nested linear steps written
out, not a loop over corners (fewer operations a point); the values differ from the corner sum's by
rounding (~1e-15 on values of order 1) and the cube's float32 totals not at all (compared array to
array).  The speed-ups are in docs/performance.md.

Points outside the grid are clipped to its edges (callers clip or wrap before: theta 0-180,
phi periodic).  NaN inputs give NaN.
"""

from __future__ import annotations

import numpy as np

from straylight.util.kernel_cache import njit

__all__ = ["cell_of", "AxisCells", "LinearGrid"]


@njit(cache=True, nogil=True, inline="always")
def _bilinear(flat, b, ch, sa, sb, ta, tb):
    """Channel ``ch`` of the cell at flat node ``b`` interpolated over two axes of strides
    ``sa``, ``sb`` at fractions ``ta``, ``tb`` (the second axis first)."""
    return (flat[b, ch] * (1 - tb) + flat[b + sb, ch] * tb) * (1 - ta) + (
        flat[b + sa, ch] * (1 - tb) + flat[b + sa + sb, ch] * tb
    ) * ta


@njit(cache=True, nogil=True, inline="always")
def cell_of(k, x, lo, hi, uniform, inv_width, n_bins, bin_cell, nodes, n_nodes, inv_step):
    """(cell index, fraction within it) of ``x`` on axis ``k`` of the packed axes (see
    :class:`LinearGrid`): clipped to the axis; on an evenly spaced axis one multiplication, else
    the bin's cell or the next (:class:`AxisCells`).

    Parameters
    ----------
    k : int
        The axis.
    x : float
        The coordinate on axis ``k``, in the axis' unit.
    lo, hi : ndarray
        Each axis' first and last node.
    uniform : ndarray of bool
        Whether each axis is evenly spaced.
    inv_width : ndarray
        Each axis' bins per unit of its coordinate.
    n_bins : ndarray of int
        Each axis' number of bins.
    bin_cell : ndarray of int
        Each axis' first cell of each bin, (axes, bins).
    nodes : ndarray
        Each axis' nodes, (axes, nodes), padded.
    n_nodes : ndarray of int
        Each axis' number of nodes.
    inv_step : ndarray
        Each axis' inverse node spacing per cell, (axes, nodes), padded.
    """
    x = min(max(x, lo[k]), hi[k])
    last = n_nodes[k] - 2
    if uniform[k]:
        i = min(int((x - lo[k]) * inv_step[k, 0]), last)
    else:
        i = bin_cell[k, min(int((x - lo[k]) * inv_width[k]), n_bins[k])]
        if x >= nodes[k, min(i + 1, last + 1)]:
            i = min(i + 1, last)
    return i, (x - nodes[k, i]) * inv_step[k, i]


@njit(cache=True, nogil=True)
def _interpolate(
    points,
    lo,
    hi,
    uniform,
    inv_width,
    n_bins,
    bin_cell,
    nodes,
    n_nodes,
    inv_step,
    strides,
    flat,
    channel,
    group_rows,
    out,
):
    """:meth:`LinearGrid.__call__` on ``points`` (ndim, N) into ``out`` (N, channels out), from
    the axes packed by :class:`LinearGrid`.  Each point is clipped to the grid and its cell found
    per axis (:class:`AxisCells`); on an evenly spaced axis the cell can be one off the exact one
    only where the point lies within rounding of a node, and t is then ~1 in the cell below
    (or ~0 just below the node): the same value to rounding (1e-15; tests/util/test_gridinterp.py).
    Then the cell's corners: on two, three and four axes written out as nested linear steps,
    the last axis first (the cube's PST, door, zodiacal and earthshine tables: faster than the
    general loop over corners, which stays for other dimensions).
    ``channel``: per point, the group of ``out.shape[1]`` consecutive channels it takes, or
    empty for all channels; ``group_rows``: 0 when a node's row holds every group's channels
    (the group is a column offset), else the rows per group (``flat`` stored group-major: the
    group is a row offset, and a point's corners hold only its own group's channels)."""
    n_dim, n_points = points.shape
    frac = np.empty(max(n_dim, 4))
    n_out = out.shape[1]
    for p in range(n_points):
        base = 0
        missing = False
        for k in range(n_dim):
            x = points[k, p]
            if x != x:  # NaN in, NaN out
                missing = True
                break
            i, frac[k] = cell_of(k, x, lo, hi, uniform, inv_width, n_bins, bin_cell, nodes, n_nodes, inv_step)
            base += i * strides[k]
        if missing:
            out[p, :] = np.nan
            continue
        first = 0
        if channel.size:
            if group_rows:
                base += channel[p] * group_rows
            else:
                first = channel[p] * n_out
        # two to four axes: the last two bilinearly, then the others a linear step each
        if n_dim == 2:
            for j in range(n_out):
                out[p, j] = _bilinear(flat, base, first + j, strides[0], strides[1], frac[0], frac[1])
        elif n_dim == 3:
            s0, s1, s2, t0, t1, t2 = strides[0], strides[1], strides[2], frac[0], frac[1], frac[2]
            for j in range(n_out):
                ch = first + j
                out[p, j] = (
                    _bilinear(flat, base, ch, s1, s2, t1, t2) * (1 - t0)
                    + _bilinear(flat, base + s0, ch, s1, s2, t1, t2) * t0
                )
        elif n_dim == 4:
            s0, s1, s2, s3 = strides[0], strides[1], strides[2], strides[3]
            t0, t1, t2, t3 = frac[0], frac[1], frac[2], frac[3]
            for j in range(n_out):
                ch = first + j
                lower = (
                    _bilinear(flat, base, ch, s2, s3, t2, t3) * (1 - t1)
                    + _bilinear(flat, base + s1, ch, s2, s3, t2, t3) * t1
                )
                upper = (
                    _bilinear(flat, base + s0, ch, s2, s3, t2, t3) * (1 - t1)
                    + _bilinear(flat, base + s0 + s1, ch, s2, s3, t2, t3) * t1
                )
                out[p, j] = lower * (1 - t0) + upper * t0
        else:
            for j in range(n_out):
                out[p, j] = 0.0
            for corner in range(1 << n_dim):  # bit k: the upper node of axis k
                wc = 1.0
                offset = 0
                for k in range(n_dim):
                    if (corner >> k) & 1:
                        wc *= frac[k]
                        offset += strides[k]
                    else:
                        wc *= 1 - frac[k]
                for j in range(n_out):
                    out[p, j] += wc * flat[base + offset, first + j]


class AxisCells:
    """Cell finder for one strictly increasing axis."""

    def __init__(self, nodes: np.ndarray):
        nodes = np.asarray(nodes, float)
        if nodes.ndim != 1 or nodes.size < 2 or np.any(np.diff(nodes) <= 0):
            raise ValueError("grid axis must be strictly increasing with >= 2 nodes")
        self.nodes = nodes
        self.lo, self.hi = float(nodes[0]), float(nodes[-1])
        width = float(np.min(np.diff(nodes)))
        n_bins = int(np.ceil((self.hi - self.lo) / width)) + 1
        self.inv_width = n_bins / (self.hi - self.lo)
        edges = self.lo + np.arange(n_bins + 1) / self.inv_width
        # cell holding each bin's left edge; a bin spans at most two cells (it is no wider than one)
        self.bin_cell = np.clip(np.searchsorted(nodes, edges, side="right") - 1, 0, nodes.size - 2)
        self.n_bins = n_bins
        steps = np.diff(nodes)
        self.inv_step = 1.0 / steps
        # evenly spaced nodes (the PST's phi, the door's and most tables' axes): a point's cell is
        # one multiplication, with no look-up
        self.uniform = bool(np.all(np.abs(steps - steps[0]) <= 1e-12 * steps[0]))


class LinearGrid:
    """f(x1, ..., xn) linear in each axis between the nodes of ``axes``; ``values`` of shape
    (len(axes[0]), ..., len(axes[-1])) or with trailing dimensions (several functions on one
    grid, e.g. a table's direct and door terms: located once, interpolated together; the result
    then ends in those dimensions).  Call with n broadcastable arrays.  ``channel_group`` g:
    the grid is only ever read g channels at a time (``channel=..., group=g``: each sample its
    own door state's pair), so it is stored group-major (a point's corners then read only its
    group's channels, fewer bytes from a table of tens of MB), the same values bit for bit."""

    def __init__(self, axes, values, channel_group: int | None = None):
        self.axes = [AxisCells(a) for a in axes]
        self.values = np.ascontiguousarray(values, dtype=float)
        n = len(self.axes)
        if self.values.shape[:n] != tuple(a.nodes.size for a in self.axes):
            raise ValueError(f"values shape {self.values.shape} does not match the axes")
        self._trailing = self.values.shape[n:]
        self._n_nodes_total = int(np.prod(self.values.shape[:n]))
        self._strides = [int(np.prod(self.values.shape[k + 1 : n])) for k in range(n)]
        # one row per node: a channel-less grid is a flat array, else (nodes, channels)
        self._flat = self.values.reshape(self._n_nodes_total, -1) if self._trailing else self.values.ravel()
        # channel_group g: always read in groups of g channels (each sample its own door state):
        # stored group-major, so a point's cell corners hold only its group's channels (fewer
        # cache lines a point on tables of tens of MB)
        self._group = channel_group
        if channel_group is not None:
            if len(self._trailing) != 1 or self._trailing[0] % channel_group:
                raise ValueError(
                    f"channel_group {channel_group} needs one trailing dimension in groups of it"
                )
            n_groups = self._trailing[0] // channel_group
            self._flat = np.ascontiguousarray(
                self._flat.reshape(self._n_nodes_total, n_groups, channel_group)
                .transpose(1, 0, 2)
                .reshape(-1, channel_group)
            )
            self.values = None  # the group-major copy is the table (tens of MB: not kept twice)
        # the axes packed for the compiled kernel (rows padded to the longest axis)
        longest = max(a.nodes.size for a in self.axes)
        widest = max(a.n_bins for a in self.axes) + 1
        self._lo = np.array([a.lo for a in self.axes])
        self._hi = np.array([a.hi for a in self.axes])
        self._inv_width = np.array([a.inv_width for a in self.axes])
        self._n_bins = np.array([a.n_bins for a in self.axes], np.intp)
        self._n_nodes = np.array([a.nodes.size for a in self.axes], np.intp)
        self._nodes = np.zeros((n, longest))
        self._inv_step = np.zeros((n, longest))
        self._bin_cell = np.zeros((n, widest), np.intp)
        for k, a in enumerate(self.axes):
            self._nodes[k, : a.nodes.size] = a.nodes
            self._inv_step[k, : a.nodes.size - 1] = a.inv_step
            self._bin_cell[k, : a.n_bins + 1] = a.bin_cell
        self._strides_arr = np.array(self._strides, np.intp)

    def __call__(self, *coords, channel=None, group: int = 1) -> np.ndarray:
        """The interpolant at the points ``coords``; with ``channel`` (integer array, broadcast
        with them; a grid with one trailing dimension only), each point's own group of ``group``
        consecutive channels (channels channel * group .. channel * group + group - 1; the
        result then ends in a dimension of ``group`` unless it is 1) instead of all channels:
        e.g. each sample's own door state from one stacked table, located once (the same
        arithmetic as a separate grid per group, so the same numbers)."""
        if channel is not None and (len(self._trailing) != 1 or self._trailing[0] % group):
            raise ValueError(
                f"channel needs a grid with exactly one trailing dimension, in groups of {group}"
            )
        if self._group is not None and (channel is None or group != self._group):
            raise ValueError(
                f"this grid is stored in channel groups of {self._group}: call it with channel= and "
                f"group={self._group}"
            )
        coords = np.broadcast_arrays(*(np.asarray(c, float) for c in coords))
        shape = coords[0].shape
        points = np.empty((len(coords), int(np.prod(shape))))
        for k, x in enumerate(coords):
            points[k] = x.ravel()
        flat = self._flat if self._trailing else self._flat[:, None]
        if channel is not None:
            n_groups = self._trailing[0] // group
            ch = np.ascontiguousarray(np.broadcast_to(np.asarray(channel, np.intp), shape).ravel())
            if ch.size and (ch.min() < 0 or ch.max() >= n_groups):
                raise ValueError(f"channel outside 0..{n_groups - 1}")
            out = np.empty((points.shape[1], group))
        else:
            ch = np.zeros(0, np.intp)
            out = np.empty((points.shape[1], flat.shape[1]))
        uniform = np.array([ax.uniform for ax in self.axes])
        _interpolate(
            points,
            self._lo,
            self._hi,
            uniform,
            self._inv_width,
            self._n_bins,
            self._bin_cell,
            self._nodes,
            self._n_nodes,
            self._inv_step,
            self._strides_arr,
            flat,
            ch,
            0 if self._group is None else self._n_nodes_total,
            out,
        )
        if self._trailing and channel is None:
            return out.reshape(shape + self._trailing)
        return out.reshape(shape + ((group,) if group > 1 else ()))
