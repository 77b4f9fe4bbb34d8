"""Bit rounding of the products' float variables and its recorded bound.

:func:`bitround` keeps a number of mantissa bits, rounding to nearest (ties to even kept bits,
as ``numcodecs.BitRound`` does, bit for bit), in one compiled pass; a stored float then differs
from the computed one by at most 2^-(keepbits + 1) of its magnitude (:func:`max_relative_error`).
The bound is recorded in each variable's attributes (:data:`COMPRESSION_ATTR`,
:data:`MAX_RELATIVE_ERROR_ATTR`), from which a region writer reads the bits back
(:func:`recorded_keepbits`, :func:`stored_values`).  How the stores use it:
:mod:`straylight.storage.zarr_io`.
"""

from __future__ import annotations

import math

import numpy as np

from straylight.util.kernel_cache import njit

__all__ = [
    "COMPRESSION_ATTR",
    "MAX_RELATIVE_ERROR_ATTR",
    "bitround",
    "max_relative_error",
    "recorded_keepbits",
    "stored_values",
]

#: attribute names recording the codec and its bound
COMPRESSION_ATTR = "compression"
MAX_RELATIVE_ERROR_ATTR = "max_relative_error"


def max_relative_error(keepbits: int, dtype=np.float32) -> float:
    """The largest |stored - computed| / |computed| of a float of ``dtype`` bit-rounded to
    ``keepbits`` mantissa bits (round to nearest: half a unit in the last kept place); 0 when
    ``keepbits`` is all of the type's mantissa (float32: 23, float64: 52).

    Parameters
    ----------
    keepbits : int
        Mantissa bits kept (>= 0).
    dtype : numpy dtype, optional
        float32 or float64.

    Returns
    -------
    float
        The relative bound, 2^-(keepbits + 1), or 0.0.
    """
    if int(keepbits) >= np.finfo(dtype).nmant:
        return 0.0
    return 2.0 ** -(int(keepbits) + 1)


#: unsigned integer of each float's width, and its mantissa bits
_BITS = {np.dtype(np.float32): (np.uint32, 23), np.dtype(np.float64): (np.uint64, 52)}


@njit(cache=True, nogil=True)
def _bitround_bits(bits, maskbits, one, half_quantum1, mask):
    """Round the floats whose bit patterns ``bits`` (flat, unsigned) holds to ``maskbits`` fewer
    mantissa bits, in place: numcodecs.BitRound.encode's integer steps (modulo 2^width, as its
    signed integers wrap), one pass; the scalars are of ``bits``' type."""
    for i in range(bits.size):
        b = bits[i]
        bits[i] = (b + ((b >> maskbits) & one) + half_quantum1) & mask


def bitround(values: np.ndarray, keepbits: int | None) -> np.ndarray:
    """``values`` (float32 or float64) rounded to ``keepbits`` mantissa bits, the bits
    ``numcodecs.BitRound(keepbits).encode`` gives (round to nearest, ties to an even last kept
    bit; a carry can reach the exponent, so the largest finite floats round to inf and a NaN with
    a payload only in the dropped bits to inf, as there).  In place when ``values`` is a writeable
    C-contiguous float array, else on a copy; returned either way.  ``keepbits`` None or at least
    the type's mantissa bits (float32: 23, float64: 52): ``values`` as they are.

    Parameters
    ----------
    values : array_like, any shape
        Values to round; non-float values are returned as they are.
    keepbits : int or None
        Mantissa bits kept (>= 0); None: no rounding.

    Returns
    -------
    ndarray, same shape and dtype
        The rounded values (``values`` itself when rounded in place or not rounded).

    Raises
    ------
    TypeError
        When the floats are neither float32 nor float64.
    ValueError
        When ``keepbits`` is negative.
    """
    values = np.asarray(values)
    if keepbits is None or values.dtype.kind != "f":
        return values
    if values.dtype not in _BITS:
        raise TypeError(f"bit-rounding needs float32 or float64 values, not {values.dtype}")
    uint, nmant = _BITS[values.dtype]
    if int(keepbits) < 0:
        raise ValueError(f"keepbits must be zero or positive, not {keepbits}")
    if int(keepbits) >= nmant:
        return values
    if not (values.flags.c_contiguous and values.flags.writeable):
        values = np.array(values, order="C")
    maskbits = nmant - int(keepbits)
    all_set = np.iinfo(uint).max
    _bitround_bits(
        values.reshape(-1).view(uint),
        uint(maskbits),
        uint(1),
        uint((1 << (maskbits - 1)) - 1),
        uint((all_set >> maskbits) << maskbits),
    )
    return values


def recorded_keepbits(attrs) -> int | None:
    """The mantissa bits a stored variable keeps, from the bound :func:`encoded` recorded in its
    attributes (``max_relative_error`` = 2^-(keepbits + 1)); None when it is stored exactly
    (bound 0, or no bound recorded: a store written without the products' codecs).

    Parameters
    ----------
    attrs : mapping
        The variable's attributes.

    Returns
    -------
    int or None
        Mantissa bits kept, or None when stored exactly.

    Raises
    ------
    ValueError
        When the recorded bound is not a power of two 2^-(keepbits + 1).
    """
    error = float(attrs.get(MAX_RELATIVE_ERROR_ATTR, 0.0))
    if error == 0.0:
        return None
    mantissa, exponent = math.frexp(error)  # error = 0.5 * 2^exponent
    if mantissa != 0.5 or exponent > 0:
        raise ValueError(f"{MAX_RELATIVE_ERROR_ATTR} = {error} is not a bit-rounding bound 2^-(keepbits + 1)")
    return -exponent


def stored_values(values: np.ndarray, attrs) -> np.ndarray:
    """``values`` as a variable whose stored attributes are ``attrs`` keeps them on disk
    (:func:`bitround` to :func:`recorded_keepbits`; in place where it can): what a region writer
    puts into an existing store's array (its codecs are lossless).

    Parameters
    ----------
    values : ndarray, any shape
        Computed values of a region.
    attrs : mapping
        The stored variable's attributes.

    Returns
    -------
    ndarray, same shape and dtype
        The values as they will be stored.

    Raises
    ------
    ValueError
        As :func:`recorded_keepbits`.
    """
    return bitround(values, recorded_keepbits(attrs))
