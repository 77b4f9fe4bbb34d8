"""The background model's compiled sums: the sources' rates as the band kernel's arrays
(:class:`Terms`), each sample's floor (:func:`floor_kernel`) and every band's components
(:func:`band_components_kernel`), with the small helpers that lay their arrays out."""

from __future__ import annotations

import numpy as np

from straylight.model import registry
from straylight.sources.rates import LAMPS
from straylight.util.kernel_cache import njit

__all__ = [
    "KERNEL_BLOCK_SAMPLES",
    "Terms",
    "band_components_kernel",
    "check_into",
    "flat",
    "floor_kernel",
    "irradiance",
    "rows",
    "sum_program",
]


def sum_program(components: tuple, leaves: tuple, names) -> tuple:
    """The band kernel's rows after the leaves (rows 0..len(leaves)-1): each component with
    parts gets a row, the total one; a component without parts is its leaf's row.  Returns
    (sums (k, 3): src row, dst row, whether it sets dst; writes (k, 2): row, index in
    ``names``, for the names asked; the number of rows)."""
    rows, sums, n_rows = {leaf: i for i, leaf in enumerate(leaves)}, [], len(leaves)
    for c in components:
        if c.parts:
            rows[c.name] = n_rows
            sums += [(rows[p], n_rows, k == 0) for k, (p, _) in enumerate(c.parts)]
            n_rows += 1
    rows[registry.TOTAL] = n_rows
    sums += [(rows[c.name], n_rows, k == 0) for k, c in enumerate(components)]
    writes = [(rows[name], k) for k, name in enumerate(names)]
    return (np.array(sums, np.intp).reshape(-1, 3), np.array(writes, np.intp).reshape(-1, 2), n_rows + 1)


def rows(arrays: list, shape: tuple) -> tuple:
    """The arrays as a tuple for a compiled kernel: each float64, C-contiguous, writable, of
    ``shape`` (broadcast, and copied only where it is not so already); an empty list gives one
    zero array (the kernels take the count apart)."""
    out = []
    for a in arrays:
        a = np.asarray(a, float)
        if not (a.shape == tuple(shape) and a.flags.c_contiguous and a.flags.writeable):
            a = np.ascontiguousarray(np.broadcast_to(a, shape))
            a = a if a.flags.writeable else a.copy()
        out.append(a)
    return tuple(out) if out else (np.zeros(shape),)


def flat(a, shape: tuple) -> np.ndarray:
    """``a`` broadcast to the samples' ``shape`` and flattened (a view where it can be)."""
    a = np.asarray(a, float)
    return a.reshape(-1) if a.shape == tuple(shape) else np.broadcast_to(a, shape).reshape(-1)


class Terms:
    """The sources' rates as the band kernel's arrays: the per-band terms, a tuple of (bands,
    samples) arrays, and the per-lamp coefficients, a tuple of (samples,) arrays (views of the
    sources' arrays where they can be), each with the leaf (component or
    part) it adds to and whether it is that leaf's first term (which sets it; the others add,
    per-band terms before per-lamp ones, lamps in :data:`LAMPS` order).  Coefficients of several
    sources for one leaf and lamp are added first, in registry order."""

    def __init__(self, entries, leaves: tuple, rates: dict, scales: dict, shape):
        n = int(np.prod(shape))
        dense, dense_leaf = [], []
        lamp_coeff = {}  # (leaf, lamp) -> coefficient
        factors = {}  # leaf -> its per-band factor on its lamp terms
        for entry in entries:
            r = rates[entry.name]
            for part, values in r.per_band.items():
                dense.append(values)
                dense_leaf.append(leaves.index(part))
            for part, f in r.band_factors.items():
                f = np.asarray(f, float)
                if part in factors and not np.array_equal(factors[part], f):
                    raise ValueError(f"sources give {part!r} different band factors: {factors[part]}, {f}")
                factors[part] = f
            for part, by_lamp in r.per_lamp.items():
                for lamp, coeff in by_lamp.items():
                    key = (part, lamp)
                    lamp_coeff[key] = coeff if key not in lamp_coeff else lamp_coeff[key] + coeff
        keys = sorted(lamp_coeff, key=lambda k: (leaves.index(k[0]), LAMPS.index(k[1])))
        lamps = [lamp for lamp in LAMPS if any(k[1] == lamp for k in keys)]
        nb = dense[0].shape[0] if dense else 0
        self.dense = rows([np.asarray(d, float).reshape(nb, n) for d in dense], (nb, n))
        self.n_dense = len(dense)
        self.dense_leaf = np.array(dense_leaf, np.intp)
        seen = set()
        self.dense_first = np.array([not (leaf in seen or seen.add(leaf)) for leaf in dense_leaf], np.bool_)
        self.coeff = rows([flat(lamp_coeff[k], shape) for k in keys], (n,))
        self.n_coeff = len(keys)
        self.term_leaf = np.array([leaves.index(k[0]) for k in keys], np.intp)
        self.term_lamp = np.array([lamps.index(k[1]) for k in keys], np.intp)
        self.term_first = np.array(
            [not (leaf in seen or seen.add(leaf)) for leaf in self.term_leaf.tolist()], np.bool_
        )
        self.scales = rows([flat(scales[lamp], shape) for lamp in lamps], (n,))
        self.factors = [factors.get(k[0]) for k in keys]


def irradiance(sun_at_1au, factors: list) -> np.ndarray:
    """(terms, bands) photon irradiance per unit lamp scale of each lamp term: the band's solar
    irradiance at 1 AU times the term's per-band factor (None: 1; the product is then the
    irradiance itself, bit for bit); one row of the irradiance when there is no term."""
    s1 = np.asarray(sun_at_1au, float)
    rows = [s1 if f is None else s1 * np.asarray(f, float) for f in factors] or [s1]
    return np.ascontiguousarray(np.stack(rows))


def check_into(into, n_samples: int, n_bands: int, outputs: tuple) -> None:
    """ValueError unless ``into`` is (distinct names of ``outputs``, an array of shape (names,
    samples, bands))."""
    names, values = into
    unknown = sorted(set(names) - set(outputs))
    expected = (len(names), n_samples, n_bands)
    if unknown or len(set(names)) != len(names) or np.shape(values) != expected:
        raise ValueError(
            f"into: components {tuple(names)} (unknown: {unknown}; each at most once) in an array of "
            f"shape {np.shape(values)}, not (components, samples, bands) = {expected}"
        )


@njit(cache=True, nogil=True)
def floor_kernel(dense, n_dense, coeff, n_coeff, scale, irradiance, darkest, floor, ratio):
    """:meth:`BackgroundModel._floor` per sample: ``floor[band, sample]`` and ``ratio[sample]``:
    the per-band terms added in order, then each lamp term's summed coefficient times its
    irradiance in the band (``irradiance[term, band]``: the solar irradiance at 1 AU times the
    term's band factor) times the lamp's scale, np.fmax's rule for NaN against ``darkest``.
    Each band's row is built a term at a time (1-D loops the compiler vectorizes)."""
    n, nb = floor.shape[1], floor.shape[0]
    for ib in range(nb):
        row = floor[ib]
        for k in range(n_dense):
            src = dense[k][ib]
            if k == 0:
                for i in range(n):
                    row[i] = src[i]
            else:
                for i in range(n):
                    row[i] += src[i]
        for k in range(n_coeff):
            c, sc, s1 = coeff[k], scale[k], irradiance[k, ib]
            if k == 0 and n_dense == 0:
                for i in range(n):
                    row[i] = c[i] * (s1 * sc[i])
            else:
                for i in range(n):
                    row[i] += c[i] * (s1 * sc[i])
        if n_dense == 0 and n_coeff == 0:
            row[:] = 0.0
        d = darkest[ib]
        for i in range(n):
            f = row[i] if row[i] >= d else d  # np.fmax: NaN gives the darkest
            row[i] = f
    for i in range(n):
        smallest = np.inf
        for ib in range(nb):
            q = floor[ib, i] / darkest[ib]
            if q < smallest:
                smallest = q
        ratio[i] = smallest


#: samples per block of :func:`band_components_kernel`: its scratch (values x bands x block
#: float64) stays in the processor's cache while each term runs over the block in a simple loop
KERNEL_BLOCK_SAMPLES = 256


@njit(cache=True, nogil=True)
def band_components_kernel(
    dense,
    n_dense,
    dense_row,
    dense_first,
    coeff,
    n_coeff,
    term_row,
    term_lamp,
    term_first,
    scales,
    irradiance,
    sums,
    writes,
    n_rows,
    out,
):
    """Every band's components (e-/s/pix) per sample.

    Rows of values per band and sample: a row (a leaf: a component's part, or a component
    without parts) is its per-band terms (the first ``n_dense`` of the tuple ``dense`` of (bands,
    samples) arrays, to row ``dense_row``) then its lamp terms (``coeff[k][sample] *
    (irradiance[k, band] * scales[term_lamp[k]][sample])``, the first ``n_coeff``, to
    ``term_row``; ``irradiance``: the band's solar irradiance at 1 AU times the term's band
    factor),
    the first setting it; then ``sums``
    (src, dst, first) add rows into others in order (parts into their component, components
    into the total), and ``writes`` (row, slot) copy row into ``out[slot, sample, band]`` (any
    float dtype and strides).  Each sample's arithmetic is fixed, so the float64 values do not
    depend on batch size; the samples run in blocks of :data:`KERNEL_BLOCK_SAMPLES`, each term
    over a whole block at a time (1-D views in the inner loops: the compiler vectorizes them)."""
    n, nb = out.shape[1], out.shape[2]
    blk = KERNEL_BLOCK_SAMPLES
    buf = np.zeros((n_rows, nb, blk))  # a row no term reaches stays 0
    for i0 in range(0, n, blk):
        m = min(blk, n - i0)
        for k in range(n_dense):
            for ib in range(nb):
                src, row = dense[k][ib, i0 : i0 + m], buf[dense_row[k], ib]
                if dense_first[k]:
                    for j in range(m):
                        row[j] = src[j]
                else:
                    for j in range(m):
                        row[j] += src[j]
        for k in range(n_coeff):
            c, scale = coeff[k][i0 : i0 + m], scales[term_lamp[k]][i0 : i0 + m]
            for ib in range(nb):
                s1, row = irradiance[k, ib], buf[term_row[k], ib]
                if term_first[k]:
                    for j in range(m):
                        row[j] = c[j] * (s1 * scale[j])
                else:
                    for j in range(m):
                        row[j] += c[j] * (s1 * scale[j])
        for k in range(sums.shape[0]):
            for ib in range(nb):
                src, row = buf[sums[k, 0], ib], buf[sums[k, 1], ib]
                if sums[k, 2]:
                    for j in range(m):
                        row[j] = src[j]
                else:
                    for j in range(m):
                        row[j] += src[j]
        for k in range(writes.shape[0]):
            dst = out[writes[k, 1], i0 : i0 + m]
            for ib in range(nb):
                src = buf[writes[k, 0], ib]
                for j in range(m):
                    dst[j, ib] = src[j]
