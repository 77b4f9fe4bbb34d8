"""How the products store their variables on disk (Zarr v3 codecs).

Floating-point data variables are bit-rounded, byte-shuffled and zstd-compressed:
``numcodecs.bitround`` keeps ``storage.float_keepbits`` mantissa bits (``storage.magnitude_keepbits`` in variables whose
units are magnitudes, e.g. 16 bits: within 2.4e-4 mag of a 30-mag value), rounding to nearest, so a
stored float differs from the computed one by at most half a unit in the last kept place,
2^-(keepbits + 1) of its magnitude (exactly 0, NaN and inf are kept as they are); the byte
shuffle then groups the exponent bytes and the zeroed mantissa bytes, which zstd packs.
Booleans and integers (``observable``, ``violations``) are zstd-compressed losslessly.
Coordinates keep xarray's default (lossless) encoding, and ephemeris.zarr is stored losslessly:
observability.zarr is computed from its positions.

A bound holds against the values the writing step computed.  limits.zarr's ``limiting_mag`` is
computed by the cube's workers from the total they computed, before it is bit-rounded, so it is
within its own bound of the limit of the computed total; its per-pixel summaries are computed
from the stored ``limiting_mag``.  A limit computed from the stored background instead
(``straylight.survey.limits.limits_dataset`` on a re-read background.zarr) carries the
background's propagated bound too: the limit's signal grows at most as the square root of the
background, so a relative error e of the total moves the limit by at most
2.5 / ln 10 * e / 2 mag (2.7e-4 mag at 10 bits; 1.8e-5 of a 15-mag limit).

The codec and the bound are recorded in each variable's attributes (``compression``,
``max_relative_error``) and the bound in the dataset's (``float_max_relative_error``).
Zarr-python reads the stores with no extra setting; ``numcodecs.bitround`` and
``numcodecs.shuffle`` are numcodecs codecs, outside the Zarr v3 specification, so another Zarr
implementation needs numcodecs' codecs to read them.
"""
from __future__ import annotations

import os

import numpy as np

from straylight.util.io import atomic_path

#: attribute names recording the codec and its bound
COMPRESSION_ATTR = "compression"
MAX_RELATIVE_ERROR_ATTR = "max_relative_error"


def max_relative_error(keepbits: int, dtype=np.float32) -> float:
    """The largest |stored - computed| / |computed| of a float of ``dtype`` bit-rounded to
    ``keepbits`` mantissa bits (round to nearest: half a unit in the last kept place); 0 when
    ``keepbits`` is all of the type's mantissa (float32: 23, float64: 52)."""
    if int(keepbits) >= np.finfo(dtype).nmant:
        return 0.0
    return 2.0 ** -(int(keepbits) + 1)


def encoded(dataset, settings: dict, lossless: tuple = ()):
    """``dataset`` with the codecs recorded in its attributes, and the ``encoding`` dict that
    stores its data variables so (``Dataset.to_zarr(..., encoding=...)``).

    ``settings``: the campaign's ``storage`` section (``float_keepbits``: mantissa bits kept in
    every float data variable, ``zstd_level``); ``lossless``: float data variables stored
    exactly all the same (inputs a later step computes from).  Returns (a shallow copy of
    ``dataset``, encoding).
    """
    keepbits = int(settings["float_keepbits"])
    mag_keepbits = int(settings.get("magnitude_keepbits", keepbits))
    level = int(settings["zstd_level"])
    out = dataset.copy(deep=False)
    encoding = {}
    for name, var in out.data_vars.items():
        # magnitudes are read to a fixed number of decimals, not to a fraction of themselves
        bits = mag_keepbits if str(var.attrs.get("units", "")).startswith("mag") else keepbits
        encoding[name], described, error = _codecs(var.dtype, name in lossless, bits, level)
        # a new attrs dict: the caller's dataset is left as it was
        out[name] = var.copy(deep=False)
        out[name].attrs = {**var.attrs, COMPRESSION_ATTR: described, MAX_RELATIVE_ERROR_ATTR: error}
    out.attrs = {**dataset.attrs, "float_max_relative_error": max(
                     (out[n].attrs[MAX_RELATIVE_ERROR_ATTR] for n in out.data_vars), default=0.0),
                 "compression": f"float data variables bit-rounded to {keepbits} mantissa bits (numcodecs BitRound)"
                                + (f" but {', '.join(lossless)}" if lossless else "")
                                + f", byte-shuffled and zstd level {level}; the others zstd level {level}, lossless"
                                " (each variable's compression and max_relative_error attributes)"}
    return out, encoding


def _codecs(dtype, lossless: bool, keepbits: int, level: int) -> tuple[dict, str, float]:
    """One variable's encoding, its description and its bound (relative, 0: lossless)."""
    import warnings

    from zarr.codecs import ZstdCodec
    from zarr.codecs.numcodecs import BitRound, Shuffle

    dtype = np.dtype(dtype)
    zstd = ZstdCodec(level=level)
    if dtype.kind != "f":  # bool, integers
        return {"compressors": [zstd]}, f"zstd(level={level}), lossless", 0.0
    error = 0.0 if lossless else max_relative_error(keepbits, dtype)
    with warnings.catch_warnings():  # zarr: numcodecs codecs are outside the v3 spec (module docstring)
        warnings.filterwarnings("ignore", message="Numcodecs codecs are not in the Zarr version 3")
        shuffle = Shuffle(elementsize=dtype.itemsize)
        if error == 0.0:
            return ({"compressors": [shuffle, zstd]},
                    f"numcodecs.shuffle(elementsize={dtype.itemsize}) + zstd(level={level}), lossless", 0.0)
        return ({"filters": [BitRound(keepbits=keepbits)], "compressors": [shuffle, zstd]},
                f"numcodecs.bitround(keepbits={keepbits}) + numcodecs.shuffle(elementsize={dtype.itemsize})"
                f" + zstd(level={level})", error)


def write_zarr_atomic(dataset, path: str | os.PathLike, storage: dict | None = None) -> None:
    """Write an xarray Dataset to a Zarr store at ``path`` atomically (consolidated metadata);
    with ``storage`` (a campaign's storage section) through the products' codecs
    (:func:`encoded`), else xarray's default (lossless) ones."""
    encoding = None
    if storage is not None:
        dataset, encoding = encoded(dataset, storage)
    with atomic_path(path) as tmp:
        dataset.to_zarr(tmp, mode="w", consolidated=True, encoding=encoding)


def write_skeleton(dataset, store: str | os.PathLike, settings: dict, chunks: dict, lossless: tuple = ()) -> None:
    """Lay down a Zarr store for ``dataset`` through the products' codecs (:func:`encoded`):
    metadata, coordinates and the in-memory data variables written; the lazy (dask) data
    variables chunked by ``chunks`` ({dimension: size}) and left empty, for writers to fill
    region by region.  The lazy variables are replaced by one-chunk lazy arrays first, so no
    graph of the store's chunks is built (seconds for a month's thousands of chunks)."""
    import dask.array as da

    template = dataset.copy(deep=False)
    lazy = [name for name, var in dataset.data_vars.items() if isinstance(var.data, da.Array)]
    for name in lazy:
        var = dataset[name].variable
        template[name] = var.copy(deep=False, data=da.zeros(var.shape, dtype=var.dtype, chunks=-1))
    template, encoding = encoded(template, settings, lossless)
    for name in lazy:
        var = template[name]
        encoding[name]["chunks"] = tuple(int(min(chunks.get(d, n), n)) for d, n in zip(var.dims, var.shape))
    template.to_zarr(store, mode="w", compute=False, consolidated=False, encoding=encoding)
