"""The compact sky product's reader for schedulers: :class:`SkyMaps`.

Opening reads only the metadata and the coordinates; each time chunk is decoded (blosc, about a
day of every pixel and band) the first time a look-up needs it and is kept in memory as its
uint16 codes, up to 8 bands padded to 8 (16 bytes per sample: 0.73 GB for a month at nside 32),
so later look-ups are a compiled gather (:mod:`straylight.cube.skymaps_kernel`).

Between two grid times the magnitude is interpolated linearly in time, and a sample is
observable only if it is at both neighbouring grid times (a constraint that starts or ends
between them is not crossed); on a grid time both are the grid's.
"""

from __future__ import annotations

from collections import OrderedDict
from pathlib import Path
from typing import NamedTuple

import numpy as np

from straylight.errors import InputError

__all__ = ["SkyMaps", "SkyValues"]


class SkyValues(NamedTuple):
    """Magnitudes and observability of :meth:`SkyMaps.map` and :meth:`SkyMaps.values`."""

    #: total background, AB mag/arcsec2 (float32); NaN where not observable
    mag: np.ndarray
    #: whether the sample is observable (bool)
    observable: np.ndarray


def _datetime64_ns(times) -> np.ndarray:
    """``times`` (astropy Time, numpy datetime64, datetime or ISO text; scalar or array) as
    int64 ns since 1970 (UTC)."""
    if hasattr(times, "utc") and hasattr(times, "datetime64"):  # astropy Time
        values = times.utc.datetime64
    else:
        try:
            values = np.asarray(times, dtype="datetime64[ns]")
        except (TypeError, ValueError) as exc:
            raise InputError(f"times {times!r}: not a time (astropy Time, datetime64 or ISO text)") from exc
    return np.asarray(values, dtype="datetime64[ns]").astype(np.int64)


def _lazy_zeros(shape):
    """(a uint16 array whose memory is taken only where it is written, its mapping or None): an
    anonymous mapping without a swap reservation (a year at nside 64 would be 34 GiB, which
    malloc refuses), whose pages :func:`_release` gives back."""
    import mmap
    import sys

    nbytes = int(np.prod(shape)) * 2
    if nbytes == 0:
        return np.zeros(shape, dtype=np.uint16), None
    try:
        # MAP_NORESERVE is Linux's 0x4000 (Python names it from 3.13 only)
        noreserve = getattr(mmap, "MAP_NORESERVE", 0x4000 if sys.platform.startswith("linux") else 0)
        buf = mmap.mmap(-1, nbytes, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS | noreserve)
    except (OSError, ValueError, AttributeError):  # no such mapping here: an ordinary array
        return np.empty(shape, dtype=np.uint16), None
    return np.frombuffer(buf, dtype=np.uint16).reshape(shape), buf


def _release(buf, start: int, stop: int) -> None:
    """Give the whole pages of bytes [start, stop) of the mapping ``buf`` back to the system
    (they read as zeros after); nothing where the mapping or madvise is missing."""
    import mmap

    if buf is None or not hasattr(mmap, "MADV_DONTNEED"):
        return
    page = mmap.PAGESIZE
    first = -(-start // page) * page
    last = (stop // page) * page
    if last > first:
        buf.madvise(mmap.MADV_DONTNEED, first, last - first)


class SkyMaps:
    """The total sky background per band, AB mag/arcsec2, and the observability of a finished
    campaign, read from its compact product (``results/<campaign>/sky_compact.zarr``).

    Parameters
    ----------
    path : str or path-like
        ``sky_compact.zarr``, or a campaign's results folder holding it.
    max_memory_gb : float, optional
        The most memory the decoded codes may hold, GB (default 2). Look-ups decode the
        product's time chunks (a day each) as they need them and keep them for later calls; past
        this size the least recently used chunks are released, and a batch spanning more chunks
        than fit is answered a group of chunks at a time. ``load()`` decodes everything whatever
        this says.

    Attributes
    ----------
    bands : list of str
        The bands, in the product's order.
    nside : int
        HEALPix nside; ``ordering`` ("ring" or "nested").
    pixels : numpy.ndarray
        The footprint's HEALPix indices (int64).
    times : numpy.ndarray
        The campaign's time grid (datetime64[ns], UTC).
    mag_step : float
        The quantisation step, mag.
    errors : dict
        The product's measured error against the cube per statistic (``rms``, ``p99``,
        ``p999``, ``max``) and band, mag.

    Examples
    --------
    >>> sky = SkyMaps("results/default")  # doctest: +SKIP
    >>> mag, observable = sky.map("2026-01-01T06:02:30", bands=["g"])  # doctest: +SKIP
    >>> mag.shape  # (bands, 12 nside^2)  # doctest: +SKIP
    (1, 3072)
    """

    def __init__(self, path, max_memory_gb: float = 2.0):
        import zarr

        from straylight.cube.compact import COMPACT_FORMAT, COMPACT_NAME, FILL

        path = Path(path)
        if (path / COMPACT_NAME).exists():
            path = path / COMPACT_NAME
        try:
            root = zarr.open_group(str(path), mode="r")
        except Exception as exc:  # noqa: BLE001 - zarr raises several types for a missing store
            raise InputError(f"{path}: not a compact sky product ({exc})") from exc
        attrs = dict(root.attrs)
        if attrs.get("format") != COMPACT_FORMAT:
            raise InputError(f"{path}: format {attrs.get('format')!r}, expected {COMPACT_FORMAT!r}")
        self.path = path
        self.bands = list(attrs["bands"])
        self.nside = int(attrs["healpix_nside"])
        self.ordering = str(attrs["healpix_ordering"])
        self.mag_step = float(attrs["mag_step"])
        self.errors = {
            k: dict(attrs[f"error_{k}_mag"])
            for k in ("rms", "p99", "p999", "max")
            if f"error_{k}_mag" in attrs
        }
        self._array = root["mag"]
        self._fill = FILL
        self._offset = np.float32(self._array.attrs.get("add_offset", 0.0))
        self.pixels = np.asarray(root["pixel"][:], dtype=np.int64)
        n_times = int(attrs["n_times"])
        self._start_ns = int(np.datetime64(attrs["time_start"], "ns").astype(np.int64))
        self._cadence_ns = int(round(float(attrs["cadence_s"]) * 1e9))
        self.times = (self._start_ns + self._cadence_ns * np.arange(n_times, dtype=np.int64)).astype(
            "datetime64[ns]"
        )
        self._column = np.full(12 * self.nside**2, -1, dtype=np.int64)
        self._column[self.pixels] = np.arange(self.pixels.size)
        self._tc = int(self._array.chunks[0])
        # (time, pixel, band) uint16, filled chunk by chunk; up to 8 bands padded to 8 (a
        # sample's codes in one 16-byte row)
        self._codes = None
        self._width = 8 if len(self.bands) <= 8 else len(self.bands)
        self._decoded = np.zeros(-(-n_times // self._tc), dtype=bool)
        self._mapping = None
        self._recent: OrderedDict[int, None] = OrderedDict()  # decoded chunks, least recent first
        try:
            budget = float(max_memory_gb) * 1e9
        except (TypeError, ValueError):
            budget = float("nan")
        if not budget > 0:
            raise InputError(f"max_memory_gb: {max_memory_gb!r}; expected a positive number of GB")
        chunk_bytes = self._tc * self.pixels.size * self._width * 2
        self._max_chunks = max(2, int(budget // max(chunk_bytes, 1)))

    def __repr__(self) -> str:
        return (
            f"SkyMaps({str(self.path)!r}: {self.times.size} times x {self.pixels.size} pixels (nside "
            f"{self.nside}) x {len(self.bands)} bands, step {self.mag_step:g} mag)"
        )

    def _band_index(self, bands) -> np.ndarray:
        if bands is None:
            return np.arange(len(self.bands))
        if isinstance(bands, str):
            bands = [bands]
        if not len(bands):
            raise InputError("bands: empty (give at least one, or None for all)")
        unknown = [b for b in bands if b not in self.bands]
        if unknown:
            raise InputError(f"bands {unknown}: not in the product (bands: {', '.join(self.bands)})")
        return np.array([self.bands.index(b) for b in bands], dtype=np.int64)

    def load(self) -> SkyMaps:
        """Decode every chunk now (later look-ups decode nothing), whatever ``max_memory_gb``
        says: 16 bytes a sample."""
        self._max_chunks = max(self._max_chunks, int(self._decoded.size))
        self._decode(np.arange(self._decoded.size))
        return self

    def _decode(self, chunks) -> None:
        """Decode ``chunks`` (time-chunk indices) not decoded yet, then release the least recently
        used others while more than the memory budget's chunks are held."""
        if self._codes is None:
            self._codes, self._mapping = _lazy_zeros(self._array.shape[:2] + (self._width,))
        wanted = [int(c) for c in np.unique(chunks)]
        for c in wanted:
            if not self._decoded[c]:
                t0 = c * self._tc
                t1 = min(self._codes.shape[0], t0 + self._tc)
                self._codes[t0:t1, :, : len(self.bands)] = self._array[t0:t1]
                self._decoded[c] = True
            self._recent[c] = None
            self._recent.move_to_end(c)
        keep = set(wanted)
        for c in list(self._recent):
            if len(self._recent) <= self._max_chunks:
                break
            if c not in keep:
                self._forget(c)

    def _forget(self, c: int) -> None:
        """Release time chunk ``c``'s decoded codes."""
        row = self.pixels.size * self._width * 2  # bytes a time step
        t0 = c * self._tc
        t1 = min(self._codes.shape[0], t0 + self._tc)
        _release(self._mapping, t0 * row, t1 * row)
        self._decoded[c] = False
        del self._recent[c]

    def _gather(self, i0, i1, w, col, b, mag, obs) -> None:
        """The compiled gather into ``mag``, ``obs`` of samples whose chunks are decoded."""
        from straylight.cube.skymaps_kernel import gather_interpolate

        npix = self.pixels.size
        gather_interpolate(
            self._codes.reshape(-1, self._width),
            i0 * npix + col,
            i1 * npix + col,
            np.ascontiguousarray(w, dtype=np.float32),
            b,
            self._fill,
            np.float32(self.mag_step),
            self._offset,
            mag,
            obs,
        )

    def _grid_position(self, times) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For each time: the grid index before it, after it, and the weight of the later one."""
        ns = _datetime64_ns(times)
        n = self.times.size
        rel = ns - self._start_ns
        last = (n - 1) * self._cadence_ns
        outside = (rel < 0) | (rel > last)
        if np.any(outside):
            bad = np.asarray(times).ravel()[np.flatnonzero(np.ravel(outside))[0]] if np.ndim(ns) else times
            raise InputError(
                f"time {bad}: outside the product's grid {self.times[0]} to {self.times[-1]} (UTC)"
            )
        i0 = np.minimum(rel // self._cadence_ns, n - 1)
        w = (rel - i0 * self._cadence_ns).astype(np.float32) / np.float32(self._cadence_ns)
        i1 = np.minimum(i0 + 1, n - 1)
        return i0, i1, w

    def _magnitudes(self, c0, c1, w) -> SkyValues:
        """Magnitudes (samples, bands) from the codes at the two grid times, and the samples'
        observability (the fill is in every band or none); ``w`` (samples, 1) or scalar."""
        # on a grid time (w = 0) the later neighbour does not count
        obs = (c0[:, 0] != self._fill) & ((c1[:, 0] != self._fill) | (np.ravel(w) == 0))
        step = np.float32(self.mag_step)
        mag = c0.astype(np.float32)
        mag += (c1.astype(np.float32) - mag) * w
        mag *= step
        mag += self._offset
        mag[~obs] = np.nan
        return mag, obs

    def map(self, time, bands=None) -> SkyValues:
        """Full-sky HEALPix maps at one time, interpolated in time between grid times.

        Parameters
        ----------
        time : astropy.time.Time, numpy.datetime64, datetime or str
            One time (UTC) within the campaign's grid.
        bands : list of str, optional
            Bands (default: all, the product's order).

        Returns
        -------
        SkyValues
            ``mag`` (bands, 12 nside^2) float32 AB mag/arcsec2, NaN where not observable or
            outside the footprint; ``observable`` (12 nside^2,) bool.
        """
        if np.ndim(_datetime64_ns(time)):
            raise InputError(f"time {time!r}: map takes one time (values takes many)")
        b = self._band_index(bands)
        i0, i1, w = self._grid_position(time)
        i0, i1 = int(i0), int(i1)
        self._decode([i0 // self._tc, i1 // self._tc])
        c0, c1 = self._codes[i0][:, b], self._codes[i1][:, b]
        mag, obs = self._magnitudes(c0, c1, w if i1 != i0 else np.float32(0.0))
        npix = self._column.size
        out = np.full((b.size, npix), np.nan, dtype=np.float32)
        out[:, self.pixels] = mag.T
        seen = np.zeros(npix, dtype=bool)
        seen[self.pixels] = obs
        return SkyValues(out, seen)

    def values(self, times, pixels, bands=None) -> SkyValues:
        """Magnitudes and observability of (time, pixel) samples (broadcast), interpolated in time.

        Parameters
        ----------
        times : astropy.time.Time, numpy.datetime64 array, datetimes or ISO text
            Times (UTC) within the campaign's grid.
        pixels : array of int
            HEALPix indices (the product's nside and ordering) in the footprint.
        bands : list of str, optional
            Bands (default: all).

        Returns
        -------
        SkyValues
            ``mag`` (samples, bands) float32 AB mag/arcsec2, NaN where not observable;
            ``observable`` (samples,) bool; samples in the broadcast shape of times and pixels,
            flattened.
        """
        b = self._band_index(bands)
        i0, i1, w = self._grid_position(times)
        pix = np.asarray(pixels, dtype=np.int64)
        if pix.size and (pix.min() < 0 or pix.max() >= self._column.size):
            raise InputError(
                f"pixels: HEALPix indices must be in 0..{self._column.size - 1} (nside {self.nside})"
            )
        col = self._column[pix]
        if np.any(col < 0):
            bad = np.ravel(pix)[np.flatnonzero(np.ravel(col) < 0)[0]]
            raise InputError(f"pixel {bad}: not in the product's footprint")
        i0, i1, w, col = (np.ravel(a) for a in np.broadcast_arrays(i0, i1, w, col))
        mag = np.empty((i0.size, b.size), dtype=np.float32)
        obs = np.empty(i0.size, dtype=bool)
        chunk = i0 // self._tc
        need = np.unique(np.concatenate([chunk, i1 // self._tc]))
        if need.size <= self._max_chunks:
            self._decode(need)
            self._gather(i0, i1, w, col, b, mag, obs)
            return SkyValues(mag, obs)
        # more chunks than the memory holds: a group of them at a time (a sample's later grid
        # time may lie in the chunk after its own)
        order = np.argsort(chunk, kind="stable")
        starts = np.unique(chunk)
        per_group = max(1, self._max_chunks // 2)
        sorted_chunk = chunk[order]
        for g in range(0, starts.size, per_group):
            lo, hi = starts[g], starts[min(g + per_group, starts.size) - 1]
            a, z = np.searchsorted(sorted_chunk, [lo, hi + 1])
            idx = order[a:z]
            self._decode(np.unique(np.concatenate([chunk[idx], i1[idx] // self._tc])))
            part_mag = np.empty((idx.size, b.size), dtype=np.float32)
            part_obs = np.empty(idx.size, dtype=bool)
            self._gather(i0[idx], i1[idx], w[idx], col[idx], b, part_mag, part_obs)
            mag[idx], obs[idx] = part_mag, part_obs
        return SkyValues(mag, obs)
