"""The compiled gather of :meth:`straylight.cube.skymaps.SkyMaps.values` (imported on its first
call, so that opening a product does not import numba)."""

from __future__ import annotations

import numpy as np

from straylight.util.kernel_cache import njit

__all__ = ["gather_interpolate"]


@njit(cache=True, nogil=True)
def gather_interpolate(codes, r0, r1, w, bands, fill, step, offset, mag, obs):  # pragma: no cover
    """For each sample i: the codes of rows r0[i] and r1[i] of ``codes`` (rows, width) uint16
    at columns ``bands``, interpolated with weight w[i] of the later one, as magnitudes
    ``offset + step * code`` into mag[i] (NaN unless observable), and the observability into
    obs[i]: row r0[i] observable, and row r1[i] too unless w[i] is 0."""
    nb = bands.size
    for i in range(r0.size):
        a = codes[r0[i]]
        c = codes[r1[i]]
        ok = a[0] != fill and (w[i] == 0.0 or c[0] != fill)
        obs[i] = ok
        if not ok:
            for k in range(nb):
                mag[i, k] = np.nan
            continue
        for k in range(nb):
            x = np.float32(a[bands[k]])
            y = np.float32(c[bands[k]])
            mag[i, k] = offset + step * (x + (y - x) * w[i])
