"""How the products store their variables on disk (Zarr v3 codecs).

Floating-point data variables are bit-rounded before they are written, then byte-shuffled and
zstd-compressed (Zarr v3's blosc codec): :func:`~straylight.storage.bitround.bitround` keeps
``storage.float_keepbits`` mantissa bits (``storage.magnitude_keepbits`` in variables whose
units are magnitudes, e.g. 16 bits: within 2.4e-4 mag of a 30-mag value), rounding to nearest
(ties to even kept bits, as ``numcodecs.BitRound`` does, bit for bit), so a stored float differs
from the computed one by at most half a unit in the last kept place, 2^-(keepbits + 1) of its
magnitude (exactly 0, NaN and inf are kept as they are); the byte shuffle then groups the
exponent bytes and the zeroed mantissa bytes, which zstd packs.  The rounding is done by the
writer, in one compiled pass (:func:`encoded` for a whole dataset,
:func:`~straylight.storage.bitround.stored_values` for a region written into an existing store),
so the stores' codec pipelines are lossless (blosc: shuffle + zstd) and a reader needs no
rounding codec.  Booleans and integers (``observable``, ``violations``) are zstd-compressed
losslessly (blosc without the shuffle).  Coordinates keep xarray's default (lossless) encoding,
and ephemeris.zarr is stored losslessly: observability.zarr is computed from its positions.

A bound holds against the values the writing step computed.  limits.zarr's ``limiting_mag`` is
computed by the cube's workers from the total they computed, before it is bit-rounded, so it is
within its own bound of the limit of the computed total; its per-pixel summaries are computed
from the stored ``limiting_mag``.  A limit computed from the stored background instead
(``straylight.limits.cube.limits_dataset`` on a re-read background.zarr) carries the
background's propagated bound too: the limit's signal grows at most as the square root of the
background, so a relative error e of the total moves the limit by at most
2.5 / ln 10 * e / 2 mag (2.7e-4 mag at 10 bits; 1.8e-5 of a 15-mag limit).

The rounding and its bound are recorded in each variable's attributes (``compression``,
``max_relative_error``) and the bound in the dataset's (``float_max_relative_error``); a region
writer reads the bits to keep back from ``max_relative_error``
(:func:`~straylight.storage.bitround.recorded_keepbits`).
The data variables' codecs (bytes, blosc) are in the Zarr v3 specification; the coordinates keep
zarr-python's defaults (zstd, and vlen-utf8 for the band names).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from straylight.storage.bitround import (
    COMPRESSION_ATTR,
    MAX_RELATIVE_ERROR_ATTR,
    bitround,
    max_relative_error,
)
from straylight.util.io import atomic_path

if TYPE_CHECKING:
    from straylight.config.settings import StorageSection

__all__ = [
    "BLOSC_BLOCK_BYTES",
    "ChunkWriter",
    "PARTIAL_SUFFIX",
    "encoded",
    "read_region",
    "remove_partial_chunks",
    "write_skeleton",
    "write_zarr_atomic",
]


def encoded(dataset, settings: StorageSection | Mapping, lossless: tuple = ()):
    """``dataset`` with its float data variables bit-rounded (:func:`bitround`; lazily for dask
    arrays) and the rounding recorded in their attributes, and the ``encoding`` dict that
    stores its data variables (``Dataset.to_zarr(..., encoding=...)``: blosc, lossless).

    ``settings``: the campaign's typed ``storage`` section (``float_keepbits``: mantissa bits
    kept in every float data variable, ``magnitude_keepbits``, ``blosc_clevel``), or its mapping
    (typed with the schema's defaults: :func:`~straylight.config.settings.section_settings`);
    ``lossless``: float data variables stored
    exactly all the same (inputs a later step computes from).  Returns (a shallow copy of
    ``dataset``, encoding).

    Parameters
    ----------
    dataset : xarray.Dataset
        The product (numpy- or dask-backed); left as it was.
    settings : StorageSection or mapping
        The campaign's ``storage`` section (``campaign.settings.storage``), or its mapping with
        the schema's defaults for the keys it lacks: ``float_keepbits`` (int),
        ``magnitude_keepbits`` (int, for variables whose units start with ``mag``),
        ``blosc_clevel`` (int).
    lossless : tuple of str, optional
        Float data variables stored exactly.

    Returns
    -------
    dataset : xarray.Dataset
        Shallow copy with the rounded data, each data variable's ``compression`` and
        ``max_relative_error`` attributes and the dataset's ``float_max_relative_error`` and
        ``compression``.
    encoding : dict of str to dict
        Variable name to its zarr encoding (``compressors``).
    """
    if isinstance(settings, Mapping):
        from straylight.config.settings import section_settings

        settings = section_settings("storage", settings)
    keepbits = int(settings.float_keepbits)
    mag_keepbits = int(settings.magnitude_keepbits)
    level = int(settings.blosc_clevel)
    out = dataset.copy(deep=False)
    encoding = {}
    for name, var in out.data_vars.items():
        # magnitudes are read to a fixed number of decimals, not to a fraction of themselves
        bits = mag_keepbits if str(var.attrs.get("units", "")).startswith("mag") else keepbits
        encoding[name], described, error = _codecs(var.dtype, name in lossless, bits, level)
        # new data and a new attrs dict: the caller's dataset is left as it was
        out[name] = var.copy(deep=False, data=_rounded_copy(var.data, None if error == 0.0 else bits))
        out[name].attrs = {**var.attrs, COMPRESSION_ATTR: described, MAX_RELATIVE_ERROR_ATTR: error}
    out.attrs = {
        **dataset.attrs,
        "float_max_relative_error": max(
            (out[n].attrs[MAX_RELATIVE_ERROR_ATTR] for n in out.data_vars), default=0.0
        ),
        "compression": f"float data variables bit-rounded to {keepbits} mantissa bits (as numcodecs BitRound)"
        + (f" but {', '.join(lossless)}" if lossless else "")
        + f", byte-shuffled and zstd level {level}; the others zstd level {level}, lossless"
        " (each variable's compression and max_relative_error attributes)",
    }
    return out, encoding


def _rounded_copy(data, keepbits: int | None):
    """``data`` (numpy or dask) bit-rounded to ``keepbits`` on a copy; ``data`` itself when it
    keeps every bit."""
    if keepbits is None:
        return data
    if hasattr(data, "map_blocks"):  # dask: rounded chunk by chunk when computed
        return data.map_blocks(_rounded_block, keepbits, dtype=data.dtype)
    return _rounded_block(data, keepbits)


def _rounded_block(block, keepbits: int) -> np.ndarray:
    """A C-ordered copy of ``block`` bit-rounded to ``keepbits`` (a module function: dask
    pickles it to its workers)."""
    return bitround(np.array(block, order="C"), keepbits)


#: blosc's block: at least a cube chunk (72 times x 661 pixels x 7 bands of float32 is 1.3 MB),
#: so a chunk up to 16 MiB is shuffled and compressed whole, as one zstd frame; blosc's own
#: choice (blocks of a few hundred kB compressed apart) stores the cube's floats in far more
#: bytes (docs/performance.md).  Larger chunks are split in blocks of this size, in order: zarr
#: and the chunk writer run blosc in one thread (zarr turns numcodecs' blosc threads off), so the
#: bytes are the same.
BLOSC_BLOCK_BYTES = 16 * 2**20


def _codecs(dtype, lossless: bool, keepbits: int, level: int) -> tuple[dict, str, float]:
    """One variable's encoding, its description and its bound (relative, 0: lossless)."""
    from zarr.codecs import BloscCodec

    dtype = np.dtype(dtype)
    floats = dtype.kind == "f"
    # byte-shuffled floats (the exponent bytes together, then the rounded mantissas'); bool and
    # integers (one byte) as they are
    blosc = BloscCodec(
        typesize=dtype.itemsize,
        cname="zstd",
        clevel=level,
        shuffle="shuffle" if floats else "noshuffle",
        blocksize=BLOSC_BLOCK_BYTES,
    )
    pipeline = f"blosc(zstd, clevel={level}{', byte shuffle' if floats else ''})"
    error = max_relative_error(keepbits, dtype) if floats and not lossless else 0.0
    if error == 0.0:
        return {"compressors": [blosc]}, f"{pipeline}, lossless", 0.0
    # rounded by the writer (encoded, stored_values), the bits numcodecs.bitround would give
    return {"compressors": [blosc]}, f"bitround(keepbits={keepbits}) before writing + {pipeline}", error


def write_zarr_atomic(
    dataset, path: str | os.PathLike, storage: StorageSection | Mapping | None = None
) -> None:
    """Write an xarray Dataset to a Zarr store at ``path`` atomically (consolidated metadata);
    with ``storage`` (a campaign's storage section) through the products' codecs
    (:func:`encoded`), else xarray's default (lossless) ones.

    Parameters
    ----------
    dataset : xarray.Dataset
        The dataset to write.
    path : str or path-like
        The store's path (replaced atomically).
    storage : StorageSection or mapping, optional
        A campaign's ``storage`` section (:func:`encoded`); None: xarray's default encoding.
    """
    encoding = None
    if storage is not None:
        dataset, encoding = encoded(dataset, storage)
    with atomic_path(path) as tmp:
        dataset.to_zarr(tmp, mode="w", consolidated=True, encoding=encoding)


def write_skeleton(
    dataset, store: str | os.PathLike, settings: StorageSection | Mapping, lossless: tuple = ()
) -> None:
    """Lay down a Zarr store for ``dataset`` through the products' codecs (:func:`encoded`):
    metadata, coordinates and the in-memory data variables written; the lazy (dask) data
    variables chunked as their dask arrays are and left empty, for writers to fill region by
    region.  The lazy variables are replaced by one-chunk lazy arrays first, so no graph of the
    store's chunks is built (seconds for a month's thousands of chunks).

    Parameters
    ----------
    dataset : xarray.Dataset
        The product's skeleton: lazy (dask) data variables are left unwritten.
    store : str or path-like
        The store's path (overwritten).
    settings : StorageSection or mapping
        The campaign's ``storage`` section (:func:`encoded`).
    lossless : tuple of str, optional
        Float data variables stored exactly.
    """
    import dask.array as da

    template = dataset.copy(deep=False)
    chunks = {}
    for name, var in dataset.data_vars.items():
        if isinstance(var.data, da.Array):
            chunks[name] = tuple(int(c) for c in var.data.chunksize)
            template[name] = var.variable.copy(
                deep=False, data=da.zeros(var.shape, dtype=var.dtype, chunks=-1)
            )
    template, encoding = encoded(template, settings, lossless)
    for name, shape in chunks.items():
        encoding[name]["chunks"] = shape
    template.to_zarr(store, mode="w", compute=False, consolidated=False, encoding=encoding)


class ChunkWriter:
    """One Zarr v3 array of a local store, written a whole chunk at a time in this thread: the
    cube's workers write every region through it (a region is one chunk).

    A region that is exactly one chunk (the in-bounds part of an edge chunk included) is encoded
    here by the array's own codecs, mapped to numcodecs (the bytes codec's endianness, then each
    bytes-to-bytes codec: blosc, the products' only one), and written to a temporary file renamed
    onto the chunk's key, as zarr writes it; a chunk holding only the fill value is removed
    instead when the array does not write empty chunks, as zarr does.  The files are the ones
    zarr writes, byte for byte (tests/storage/test_storage.py), with less CPU than zarr's
    asynchronous pipeline, which hands every chunk to its event loop and threads (a cube
    region's chunks: docs/performance.md, bench/storage.py --regions).  Any other region, values
    of another shape, codec, store or zarr format is written by zarr itself.

    It reads zarr below its public API (the metadata's chunk key encoding, the codecs' settings,
    the array's runtime config, the local store's root folder, zarr's fill-value comparison),
    so pyproject.toml pins zarr to the releases tests/storage/test_storage.py passed on
    (``test_fast_paths_hold_on_the_installed_zarr`` fails on a release where they changed).

    ``attrs`` are the array's; ``writer[region] = values`` writes (``region`` a tuple of slices,
    trailing dimensions whole).  Raises OSError as the file system does (no space, no access).

    Parameters
    ----------
    array : zarr.Array
        The array, opened for writing.
    """

    def __init__(self, array):
        self.array = array
        self.attrs = array.attrs
        self._codecs = _numcodecs_chain(array)

    def __setitem__(self, region, values) -> None:
        coords, shape = (None, None) if self._codecs is None else self._chunk_coords(region)
        values = np.asarray(values)
        if coords is None or values.shape != shape:  # zarr broadcasts or refuses
            self.array[region] = values
            return
        meta = self.array.metadata
        chunk_shape = meta.chunk_grid.chunk_shape
        values = np.asarray(values, dtype=meta.data_type.to_native_dtype())
        if values.shape != chunk_shape:  # an edge chunk: zarr pads it with the fill value
            chunk = np.full(chunk_shape, meta.fill_value, dtype=values.dtype)
            chunk[tuple(slice(0, n) for n in values.shape)] = values
            values = chunk
        path = Path(self.array.store.root) / self.array.path / meta.encode_chunk_key(coords)
        if not self.array.config.write_empty_chunks and _all_fill(values, meta.fill_value):
            path.unlink(missing_ok=True)
            return
        byteorder, chain = self._codecs
        data = np.ascontiguousarray(values, dtype=values.dtype.newbyteorder(byteorder))
        for codec in chain:
            data = codec.encode(data)
        _write_file(path, data)

    def _chunk_coords(self, region) -> tuple:
        """The coordinates of the chunk ``region`` is exactly (its in-bounds part) and that part's
        shape, or (None, None)."""
        shape, chunks = self.array.shape, self.array.metadata.chunk_grid.chunk_shape
        region = tuple(region) + (slice(None),) * (len(shape) - len(tuple(region)))
        if len(region) != len(shape) or not all(isinstance(s, slice) for s in region):
            return None, None
        coords, part = [], []
        for s, n, c in zip(region, shape, chunks):
            start, stop, step = s.indices(n)
            if step != 1 or start % c or stop != min(start + c, n):
                return None, None
            coords.append(start // c)
            part.append(stop - start)
        return tuple(coords), tuple(part)


def read_region(array, region) -> np.ndarray:
    """``array[region]`` (a Zarr v3 array; ``region`` a tuple of step-1 slices, trailing
    dimensions whole) read in this thread: each chunk it meets decoded by the array's own codecs
    mapped to numcodecs (:class:`ChunkWriter`'s, in reverse), a chunk without a file the fill
    value.  The values zarr reads, without its asynchronous pipeline, which hands every chunk to
    its event loop and threads (the time series' and the limits' summaries' reads cost less CPU
    this way: docs/performance.md, bench/storage.py --regions).  Any other region, codec, store or
    zarr format is read by zarr itself.  Below zarr's public API as :class:`ChunkWriter` is, and
    tested with it.

    Parameters
    ----------
    array : zarr.Array
        The array to read.
    region : tuple of slice
        The region, one slice per leading dimension (missing trailing ones whole).

    Returns
    -------
    ndarray
        The region's values, in the array's native dtype.
    """
    chain = _numcodecs_chain(array)
    shape = array.shape
    region = tuple(region) + (slice(None),) * (len(shape) - len(tuple(region)))
    if chain is None or len(region) != len(shape) or not all(isinstance(s, slice) for s in region):
        return np.asarray(array[region])
    bounds = [s.indices(n) for s, n in zip(region, shape)]
    if any(step != 1 for _, _, step in bounds):
        return np.asarray(array[region])
    meta = array.metadata
    chunk_shape = meta.chunk_grid.chunk_shape
    byteorder, codecs = chain
    dtype = meta.data_type.to_native_dtype()
    out = np.full([max(0, stop - start) for start, stop, _ in bounds], meta.fill_value, dtype=dtype)
    root = Path(array.store.root) / array.path
    ranges = [range(start // c, -(-stop // c)) for (start, stop, _), c in zip(bounds, chunk_shape)]
    for coords in np.ndindex(*[len(r) for r in ranges]):
        coords = tuple(r[i] for r, i in zip(ranges, coords))
        try:
            data = (root / meta.encode_chunk_key(coords)).read_bytes()
        except FileNotFoundError:  # never written, or only the fill value: out holds it
            continue
        # this chunk's part of the region, in the chunk's and in the output's indices
        inner, outer = [], []
        for k, (start, stop, _), c in zip(coords, bounds, chunk_shape):
            a, b = max(start, k * c), min(stop, (k + 1) * c)
            inner.append(slice(a - k * c, b - k * c))
            outer.append(slice(a - start, b - start))
        for codec in reversed(codecs):
            data = codec.decode(data)
        chunk = np.frombuffer(data, dtype=dtype.newbyteorder(byteorder)).reshape(chunk_shape)
        out[tuple(outer)] = chunk[tuple(inner)]
    return out


def _numcodecs_chain(array) -> tuple[str, list] | None:
    """The byte order ('<', '>' or '|') and the numcodecs codecs that encode a chunk of ``array``
    as its Zarr v3 codecs do, or None where :class:`ChunkWriter` leaves the array to zarr (another
    format, store, order or codec)."""
    import numcodecs
    from zarr.codecs import BloscCodec, BytesCodec
    from zarr.storage import LocalStore

    meta = array.metadata
    if (
        meta.zarr_format != 3
        or not isinstance(array.store, LocalStore)
        or array.config.order != "C"
        or type(meta.chunk_grid).__name__ != "RegularChunkGrid"
    ):
        return None
    first, *rest = meta.codecs
    if not isinstance(first, BytesCodec):
        return None
    byteorder = {"little": "<", "big": ">", None: "|"}[getattr(first.endian, "value", first.endian)]
    chain = []
    for codec in rest:
        if isinstance(codec, BloscCodec):
            shuffle = {
                "noshuffle": numcodecs.Blosc.NOSHUFFLE,
                "shuffle": numcodecs.Blosc.SHUFFLE,
                "bitshuffle": numcodecs.Blosc.BITSHUFFLE,
            }[codec.shuffle.value]
            chain.append(
                numcodecs.Blosc(
                    cname=codec.cname.value,
                    clevel=codec.clevel,
                    shuffle=shuffle,
                    blocksize=codec.blocksize,
                    typesize=codec.typesize,
                )
            )
        else:
            return None
    return byteorder, chain


def _all_fill(values: np.ndarray, fill_value) -> bool:
    """Whether ``values`` hold only ``fill_value``, as zarr decides it (NaN equal to NaN, and
    0.0 and -0.0 told apart)."""
    from zarr.core.buffer import default_buffer_prototype

    def all_equal(a):
        return bool(default_buffer_prototype().nd_buffer.from_numpy_array(a).all_equal(fill_value))

    if values.size == 0:
        return True
    # the first value decides most chunks at once, compared here as zarr compares (a whole
    # chunk's comparison costs more than one value's through zarr's buffer)
    first = values.reshape(-1)[0]
    fill = np.asarray(fill_value, dtype=values.dtype)
    if values.dtype.kind in "fc" and np.isnan(first) and np.isnan(fill):
        pass  # NaN equal to NaN
    elif first.tobytes() != fill.tobytes():  # bit for bit: 0.0 and -0.0 told apart
        return False
    return all_equal(values)


#: the suffix of a chunk file being written (:func:`_write_file`, as zarr's own writes name it)
PARTIAL_SUFFIX = ".partial"


def remove_partial_chunks(store, time_chunks) -> int:
    """Remove the chunk files a killed writer left half written (``*.partial``, never renamed into
    place) in ``store``'s chunks at time-chunk indices ``time_chunks`` (the first chunk
    coordinate), of every array; how many were removed.  Only those chunks': another job may be
    writing other time chunks of the same store.

    Parameters
    ----------
    store : str or path-like
        A local Zarr v3 store.
    time_chunks : iterable of int
        Chunk indices along the first dimension (time blocks).

    Returns
    -------
    int
        Number of files removed.
    """
    removed = 0
    for array_dir in (p for p in Path(store).iterdir() if (p / "c").is_dir()):
        for t in time_chunks:
            for partial in (array_dir / "c" / str(int(t))).rglob(f"*{PARTIAL_SUFFIX}"):
                partial.unlink(missing_ok=True)
                removed += 1
    return removed


def _write_file(path: Path, data) -> None:
    """``data`` (bytes-like) to ``path`` through a temporary sibling renamed into place, so a
    reader never meets half a chunk."""
    import uuid

    tmp = path.with_suffix(f".{uuid.uuid4().hex}{PARTIAL_SUFFIX}")
    try:
        try:
            f = tmp.open("wb")
        except FileNotFoundError:  # the chunk's first file in its folder
            path.parent.mkdir(parents=True, exist_ok=True)
            f = tmp.open("wb")
        with f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
