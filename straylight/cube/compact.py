"""The compact sky product, ``sky_compact.zarr``: every (time, pixel) sample's total background
in AB mag/arcsec2 per band, quantised, with the observability, for schedulers and distribution.

Its layout (Zarr v3; only codecs and data types of the Zarr v3 specification):

* ``mag`` (time, pixel, band) uint16: round((m - ``add_offset``) / ``scale_factor``), m the
  total background in AB mag/arcsec2 (``mag_zero_point - 2.5 log10(total)`` of background.zarr),
  and ``_FillValue`` (65535) where the sample is not observable: the sky's value is kept only
  where it can be observed, and the observability is exact (``mag != _FillValue``).  The CF
  attributes ``scale_factor``, ``add_offset`` and ``_FillValue`` make xarray decode it to
  magnitudes with NaN where not observable.  Stored in (time, pixel, band) order, byte-shuffled
  and zstd-compressed by blosc in blocks of 16 MiB: within a block, the next time's row of codes
  mostly repeats the last one's (91 % of an observable sample's codes are unchanged 5 minutes
  later at 0.02 mag, a month at nside 32), which zstd finds as long matches.  One chunk holds
  about a day of times, every pixel and band (64 MiB decoded at most).
* ``observable`` (time, pixel) bool: the same mask, for readers of the product through xarray.
* ``time`` (int64 seconds since the campaign's first time, CF ``units``), ``pixel`` (HEALPix
  index), the band names in the attribute ``bands``.
* The error of the quantised magnitude against background.zarr's total over the observable
  samples, measured while writing, per band in the attributes ``error_rms_mag``,
  ``error_p99_mag``, ``error_p999_mag``, ``error_max_mag`` (percentiles of the absolute error,
  to the histogram's 1e-4 mag).

The reader is :class:`straylight.cube.skymaps.SkyMaps`.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from straylight.errors import InputError
from straylight.util.io import atomic_path
from straylight.util.kernel_cache import njit

__all__ = [
    "COMPACT_NAME",
    "COMPACT_FORMAT",
    "FILL",
    "ADD_OFFSET_MAG",
    "ERROR_BIN_MAG",
    "compact_time_chunk",
    "write_compact",
    "store_bytes",
]

#: the product's folder name in results/<campaign>/
COMPACT_NAME = "sky_compact.zarr"
#: the layout's name and version, in the group's ``format`` attribute (the reader checks it)
COMPACT_FORMAT = "straylight.sky_compact/1"
#: the code of a sample that is not observable (uint16's largest)
FILL = 65535
#: magnitude of code 0: codes 0-65534 cover 0 to 655 mag at a 0.01 mag step (sky: 15-32 mag)
ADD_OFFSET_MAG = 0.0
#: width of the absolute-error histogram the percentiles are read from, mag
ERROR_BIN_MAG = 1e-4
_ERROR_BINS = 20_000  # up to 2 mag; larger errors fall in the last bin (and in error_max_mag)
#: decoded bytes of one chunk at most (the reader decodes a chunk at a time)
_CHUNK_BYTES = 64 * 2**20
#: blosc's block: zstd finds repeats only within one (blosc's automatic blocks, ~256 KiB at level
#: 5, stored the first 3 days of a month at nside 32 in 0.34 bytes per sample, 0.20 in 16 MiB blocks)
_BLOCK_BYTES = 16 * 2**20


def compact_time_chunk(n_times: int, n_pixels: int, n_bands: int, cadence_s: float) -> int:
    """Times per chunk: a day's, fewer if a chunk would decode to more than 64 MiB."""
    day = max(1, round(86400.0 / float(cadence_s)))
    fit = max(1, _CHUNK_BYTES // max(1, 2 * n_pixels * n_bands))
    return int(max(1, min(day, fit, n_times)))


@njit(cache=True, nogil=True)
def _encode_block(total, zero_point, observable, step, codes, n, sq, mx, hist):  # pragma: no cover
    """Codes of a block of rates (time, pixel, band) e-/s/pix, and the tally of their error
    against the magnitude (float64) over the observable samples: count, sum of squares, largest,
    histogram of |error| in ERROR_BIN_MAG bins.  Returns the observable samples whose magnitude
    is not finite."""
    nt, npix, nb = total.shape
    nbins = hist.shape[1]
    bad = 0
    for t in range(nt):
        for p in range(npix):
            if not observable[t, p]:
                for b in range(nb):
                    codes[t, p, b] = FILL
                continue
            for b in range(nb):
                rate = np.float64(total[t, p, b])
                if not rate > 0.0 or not np.isfinite(rate):
                    bad += 1
                    codes[t, p, b] = FILL - 1
                    continue
                mag = zero_point[b] - 2.5 * np.log10(rate)
                q = np.rint((mag - ADD_OFFSET_MAG) / step)
                q = min(max(q, 0.0), FILL - 1.0)
                codes[t, p, b] = np.uint16(q)
                e = abs(q * step + ADD_OFFSET_MAG - mag)
                n[b] += 1
                sq[b] += e * e
                mx[b] = max(mx[b], e)
                hist[b, min(int(e / ERROR_BIN_MAG), nbins - 1)] += 1
    return bad


class _ErrorTally:
    """Per band: count, sum of squared errors, largest error and a histogram of |error|."""

    def __init__(self, n_bands: int):
        self.n = np.zeros(n_bands, np.int64)
        self.sq = np.zeros(n_bands)
        self.max = np.zeros(n_bands)
        self.hist = np.zeros((n_bands, _ERROR_BINS), np.int64)

    def encode(self, total, zero_point, observable, step: float) -> np.ndarray:
        """uint16 codes of a block of rates (time, pixel, band) e-/s/pix, tallied here."""
        codes = np.empty(total.shape, np.uint16)
        bad = _encode_block(
            np.ascontiguousarray(total, dtype=np.float32),
            np.asarray(zero_point, np.float64),
            np.ascontiguousarray(observable, dtype=np.bool_),
            float(step),
            codes,
            self.n,
            self.sq,
            self.max,
            self.hist,
        )
        if bad:
            raise InputError(f"background.zarr total: {bad} observable samples have no finite magnitude")
        return codes

    def merge(self, other: _ErrorTally) -> None:
        self.n += other.n
        self.sq += other.sq
        self.max = np.maximum(self.max, other.max)
        self.hist += other.hist

    def percentile(self, q: float) -> np.ndarray:
        """Upper edge of the bin holding the q-th percentile of |error|, per band (mag)."""
        out = np.full(self.n.size, np.nan)
        for b in range(self.n.size):
            if self.n[b]:
                k = int(np.searchsorted(np.cumsum(self.hist[b]), math.ceil(q / 100.0 * self.n[b])))
                out[b] = (k + 1) * ERROR_BIN_MAG
        return out


def store_bytes(path) -> int:
    """Bytes of every file under ``path``."""
    return sum(f.stat().st_size for f in Path(path).rglob("*") if f.is_file())


def write_compact(background, out, mag_step: float, clevel: int = 5, threads: int = 1) -> dict:
    """Write ``sky_compact.zarr`` from a finished background.zarr, atomically.

    Parameters
    ----------
    background : path
        background.zarr (its ``total`` e-/s/pix, ``observable``, ``mag_zero_point``, ``time``,
        ``pixel``, ``band`` and HEALPix attributes).
    out : path
        The compact store to write (replaced).
    mag_step : float
        Quantisation step, mag: every code is within ``mag_step / 2`` of the magnitude.
    clevel : int, optional
        blosc's compression level (zstd).
    threads : int, optional
        Threads encoding chunks side by side (numpy and blosc release the GIL).

    Returns
    -------
    dict
        ``samples`` (time x pixel), ``observable_samples``, ``bytes`` (on disk),
        ``bytes_per_sample``, and per band (lists in ``bands`` order) ``error_rms_mag``,
        ``error_p99_mag``, ``error_p999_mag``, ``error_max_mag``.
    """
    import xarray as xr
    import zarr

    if not 0.0 < float(mag_step) <= 1.0:
        raise InputError(f"compact magnitude step {mag_step!r}: must be in (0, 1] mag")
    step = float(mag_step)
    bg = xr.open_zarr(background, chunks=None)
    times = bg["time"].values.astype("datetime64[ns]")
    pixels = bg["pixel"].values.astype(np.int64)
    bands = [str(b) for b in bg["band"].values]
    zp = bg["mag_zero_point"].values.astype(np.float64)
    nt, npix, nb = times.size, pixels.size, len(bands)
    dt = np.diff(times).astype(np.int64)
    if nt > 1 and not np.all(dt == dt[0]):
        raise InputError(f"{background}: the time grid is not uniform; the compact product needs one cadence")
    cadence_ns = int(dt[0]) if nt > 1 else 1
    tc = compact_time_chunk(nt, npix, nb, cadence_ns / 1e9)
    start = np.datetime_as_string(times[0], unit="s")
    tally = _ErrorTally(nb)
    with atomic_path(out) as tmp:
        root = zarr.open_group(str(tmp), mode="w", zarr_format=3)
        mag, obs = _create_arrays(root, (nt, npix, nb), tc, int(clevel))
        _encode(bg, (mag, obs), zp, (step, tc), tally, threads)
        _write_coordinates(root, times, pixels, start)
        stats = _error_stats(tally)
        _annotate_arrays(mag, obs, step)
        root.attrs.update(
            format=COMPACT_FORMAT,
            title="straylight compact sky: total background per band, AB mag/arcsec2, where observable",
            source=f"{Path(background).name}: mag_zero_point - 2.5 log10(total)",
            bands=bands,
            time_start=start,
            cadence_s=cadence_ns / 1e9,
            n_times=nt,
            healpix_nside=int(bg.attrs.get("healpix_nside", 0)),
            healpix_ordering=str(bg.attrs.get("healpix_ordering", "ring")),
            mag_step=step,
            error_reference="background.zarr total in AB mag/arcsec2, over the observable samples",
            error_units="mag",
            error_percentile_resolution_mag=ERROR_BIN_MAG,
            error_samples=int(tally.n[0]) if nb else 0,
            **{k: dict(zip(bands, v, strict=True)) for k, v in stats.items()},
        )
        zarr.consolidate_metadata(str(tmp))
        nbytes = store_bytes(tmp)
    n = nt * npix
    return {
        "bands": bands,
        "samples": n,
        "observable_samples": int(tally.n[0]) if nb else 0,
        "bytes": nbytes,
        "bytes_per_sample": nbytes / max(n, 1),
        "time_chunk": tc,
        **stats,
    }


def _encode(bg, arrays: tuple, zp, quantum: tuple, tally: _ErrorTally, threads: int) -> None:
    """Encode ``bg``'s ``total`` (e-/s/pix) and ``observable`` into the compact ``arrays`` (mag,
    observable), ``quantum`` = (mag step, chunk times) at a time in ``threads`` threads, the
    quantisation errors merged into ``tally``; ``zp`` the bands' zero points, mag."""
    mag, obs = arrays
    step, tc = quantum
    total_arr, obs_arr = bg["total"].variable, bg["observable"].variable
    nt, nb = total_arr.shape[0], bg["band"].size

    def one(t0: int) -> _ErrorTally:
        t1 = min(nt, t0 + tc)
        ob = np.asarray(obs_arr[t0:t1].values, bool)
        part = _ErrorTally(nb)
        mag[t0:t1] = part.encode(np.asarray(total_arr[t0:t1].values), zp, ob, step)
        obs[t0:t1] = ob
        return part

    with ThreadPoolExecutor(max(1, int(threads))) as pool:
        for part in pool.map(one, range(0, nt, tc)):
            tally.merge(part)


def _annotate_arrays(mag, obs, step: float) -> None:
    """The compact arrays' CF attributes (``step``: the magnitude quantum, mag)."""
    mag.attrs.update(
        units="mag(AB)/arcsec2",
        long_name="total sky background, quantised; _FillValue where not observable",
        scale_factor=step,
        add_offset=ADD_OFFSET_MAG,
        _FillValue=FILL,
        coordinates="time pixel",
    )
    obs.attrs.update(units="1", long_name="observable (every constraint met)")


def _create_arrays(root, shape: tuple, tc: int, clevel: int) -> tuple:
    """The compact store's ``mag`` (time, pixel, band) uint16 and ``observable`` (time, pixel)
    bool arrays of ``shape`` (nt, npix, nb), chunked by ``tc`` times, blosc zstd at ``clevel``."""
    from zarr.codecs import BloscCodec

    nt, npix, nb = shape
    blosc = BloscCodec(cname="zstd", clevel=clevel, shuffle="shuffle", typesize=2, blocksize=_BLOCK_BYTES)
    mag = root.create_array(
        "mag",
        shape=(nt, npix, nb),
        chunks=(tc, npix, nb),
        dtype="uint16",
        fill_value=FILL,
        compressors=[blosc],
        dimension_names=("time", "pixel", "band"),
    )
    obs = root.create_array(
        "observable",
        shape=(nt, npix),
        chunks=(tc, npix),
        dtype="bool",
        fill_value=False,
        compressors=[
            BloscCodec(cname="zstd", clevel=clevel, shuffle="bitshuffle", typesize=1, blocksize=_BLOCK_BYTES)
        ],
        dimension_names=("time", "pixel"),
    )
    return mag, obs


def _write_coordinates(root, times, pixels, start: str) -> None:
    """The compact store's ``time`` (seconds since ``start``) and ``pixel`` coordinates."""
    nt, npix = times.size, pixels.size
    t = root.create_array("time", shape=(nt,), dtype="int64", dimension_names=("time",))
    t[:] = (times - times[0]).astype("timedelta64[s]").astype(np.int64)
    t.attrs.update(units=f"seconds since {start}", calendar="proleptic_gregorian", long_name="time (UTC)")
    p = root.create_array("pixel", shape=(npix,), dtype="int64", dimension_names=("pixel",))
    p[:] = pixels
    p.attrs.update(units="1", long_name="HEALPix pixel index")


def _error_stats(tally) -> dict:
    """Per band (lists), the quantisation's RMS, 99th and 99.9th percentile and largest error, mag."""
    rms = np.sqrt(tally.sq / np.maximum(tally.n, 1))
    return {
        "error_rms_mag": rms.tolist(),
        "error_p99_mag": tally.percentile(99.0).tolist(),
        "error_p999_mag": tally.percentile(99.9).tolist(),
        "error_max_mag": tally.max.tolist(),
    }
