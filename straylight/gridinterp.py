"""Multilinear interpolation on a rectilinear grid, for the hot loops (PST, door, earthshine table).

It computes exactly what ``scipy.interpolate.RegularGridInterpolator(method="linear")`` computes
(tests/test_gridinterp.py checks agreement to 1e-12), faster on the earthshine sum's millions
of points per time step (measured in the cube: 0.7 s instead of 1.0 s for the PST and door
look-ups of 2 x 1320 lines of sight x 1152 Earth blocks): scipy locates cells with a binary
search and validates its input on every call; here each axis gets, once, a table of bins of
uniform width no wider than its narrowest cell, so a point's cell is one multiplication, one
look-up and one comparison (on an evenly spaced axis, one multiplication).

Points outside the grid are clipped to its edges (callers clip or wrap before: theta 0-180,
phi periodic).  NaN inputs give NaN.
"""
from __future__ import annotations

import numpy as np


class _Axis:
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

    def locate(self, x: np.ndarray):
        """(cell index, fractional position in the cell) of clipped points."""
        x = np.clip(x, self.lo, self.hi)
        if self.uniform:
            # the cell can be one off the exact one only where x lies within rounding of a node:
            # t is then ~1 in the cell below (or ~0 just below the node), the same value to
            # rounding (1e-15; tests/test_gridinterp.py)
            with np.errstate(invalid="ignore"):  # NaN -> cell 0, then t = NaN
                i = np.clip(((x - self.lo) * self.inv_step[0]).astype(np.intp), 0, self.nodes.size - 2)
            return i, (x - self.nodes[i]) * self.inv_step[i]
        with np.errstate(invalid="ignore"):  # NaN -> bin 0, then t = NaN
            b = np.clip(((x - self.lo) * self.inv_width).astype(np.intp), 0, self.n_bins)
        i = self.bin_cell[b]
        i = np.minimum(i + (x >= self.nodes[np.minimum(i + 1, self.nodes.size - 1)]), self.nodes.size - 2)
        return i, (x - self.nodes[i]) * self.inv_step[i]


class LinearGrid:
    """f(x1, ..., xn) linear in each axis between the nodes of ``axes``; ``values`` of shape
    (len(axes[0]), ..., len(axes[-1])) or with trailing dimensions (several functions on one
    grid, e.g. a table's direct and door terms: located once, interpolated together; the result
    then ends in those dimensions).  Call with n broadcastable arrays."""

    def __init__(self, axes, values):
        self.axes = [_Axis(a) for a in axes]
        self.values = np.ascontiguousarray(values, dtype=float)
        n = len(self.axes)
        if self.values.shape[:n] != tuple(a.nodes.size for a in self.axes):
            raise ValueError(f"values shape {self.values.shape} does not match the axes")
        self._trailing = self.values.shape[n:]
        # one row per node: a channel-less grid is a flat array, else (nodes, channels)
        self._flat = self.values.reshape(int(np.prod(self.values.shape[:n])), -1) if self._trailing \
            else self.values.ravel()
        self._strides = [int(np.prod(self.values.shape[k + 1:n])) for k in range(n)]

    def __call__(self, *coords, channel=None) -> np.ndarray:
        """The interpolant at the points ``coords``; with ``channel`` (integer array, broadcast
        with them; a two-axis grid with one trailing dimension only), that channel's value at each point
        instead of all channels: e.g. each sample's own door state from one stacked table,
        located once (the same arithmetic as a separate grid per channel, so the same numbers)."""
        if channel is not None and (len(self._trailing) != 1 or len(self.axes) != 2):
            raise ValueError("channel needs a two-axis grid with exactly one trailing dimension")
        coords = np.broadcast_arrays(*(np.asarray(c, float) for c in coords))
        shape = coords[0].shape
        base = np.zeros(shape, np.intp)
        fracs = []
        for ax, x, stride in zip(self.axes, coords, self._strides):
            i, t = ax.locate(x)
            base += i * stride
            fracs.append(t)
        if channel is not None:
            n_channels = self._trailing[0]
            ch = np.broadcast_to(np.asarray(channel, np.intp), shape)
            if ch.size and (ch.min() < 0 or ch.max() >= n_channels):
                raise ValueError(f"channel outside 0..{n_channels - 1}")
            base = base * n_channels + ch
            strides = [st * n_channels for st in self._strides]
            f = self._flat.ravel()
        else:
            strides, f = self._strides, self._flat
        if len(self.axes) == 2 and (channel is not None or not self._trailing):  # PST, door: unrolled
            s, c = strides[0], strides[1]
            tx, ty = fracs
            return ((f[base] * (1 - ty) + f[base + c] * ty) * (1 - tx)
                    + (f[base + s] * (1 - ty) + f[base + s + c] * ty) * tx)
        # corner weights and offsets built axis by axis (corner bit k = the upper node of axis k)
        weights, offsets = [1.0], [0]
        for t, stride in zip(fracs, self._strides):
            weights = [w * (1 - t) for w in weights] + [w * t for w in weights]
            offsets = offsets + [o + stride for o in offsets]
        if self._trailing:
            out = np.zeros(shape + (self._flat.shape[1],))
            for w, off in zip(weights, offsets):
                out += w[..., None] * self._flat[base + off]
            return out.reshape(shape + self._trailing)
        out = np.zeros(shape)
        for w, off in zip(weights, offsets):
            out += w * self._flat[base + off]
        return out
