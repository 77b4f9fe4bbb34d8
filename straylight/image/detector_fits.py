"""A detector image (:class:`~straylight.image.detector.DetectorImage`) as FITS: the image
(e-/s per chip pixel) with its WCS and provenance, and the GHOSTS and STARS tables with their
units; the image's compression (:data:`COMPRESSIONS`) and quantization."""

from __future__ import annotations

import numpy as np

from straylight.errors import InputError
from straylight.image.detector import DetectorImage

__all__ = ["COMPRESSIONS", "GHOST_UNITS", "STAR_UNITS", "write_fits"]


COMPRESSIONS = ("gzip", "rice", "none")

GHOST_UNITS = {
    "star_index": ("", "row of the input star catalog"),
    "path": ("", "ghost path 1-3 (seed paper sect. 4.2)"),
    "x_pix": ("pix", "disc centre, 0-based chip column"),
    "y_pix": ("pix", "disc centre, 0-based chip row"),
    "radius_pix": ("pix", "disc radius"),
    "e_per_s_per_pix": ("electron/s", "irradiance per chip pixel"),
    "energy_e_per_s": ("electron/s", "energy in the disc"),
}
STAR_UNITS = {
    "catalog_index": ("", "row of the input star catalog"),
    "x_pix": ("pix", "0-based chip column"),
    "y_pix": ("pix", "0-based chip row"),
    "flux_e_per_s": ("electron/s", "star flux through the full aperture"),
}


def _table_hdu(columns: dict, units: dict, name: str):
    """A FITS table with TUNITn (unit strings as written, e.g. ``electron/s``, which FITS readers
    pass through) and each column's meaning as the TTYPEn comment."""
    from astropy.io import fits
    from astropy.table import Table

    hdu = fits.BinTableHDU(Table(columns), name=name)
    for i, c in enumerate(hdu.columns.names, start=1):
        unit, desc = units.get(c, ("", ""))
        if unit:
            hdu.header[f"TUNIT{i}"] = unit
        if desc:
            hdu.header[f"TTYPE{i}"] = (c, desc[: 80 - 14 - len(c)])
    return hdu


def write_fits(
    result: DetectorImage, path, provenance: dict, compress: str = "gzip", quantize_step: float | None = None
) -> None:
    """FITS: the image (e-/s per chip pixel) with WCS and provenance; GHOSTS and STARS tables
    with a unit on every column.

    ``compress``: ``gzip`` (GZIP_2 tile compression, lossless: no quantisation), ``rice``
    (RICE_1 on values quantised to ``quantize_step`` e-/s/pixel; the error is at most half a
    step) or ``none`` (plain primary image).  A compressed image sits in extension 1
    (``SCI``); astropy and ``fitsio`` read it transparently.

    Parameters
    ----------
    result : DetectorImage
        The rendered image.
    path : str or pathlib.Path
        The FITS file written.
    provenance : dict
        Header keywords recording how the image was made.
    compress : {"gzip", "rice", "none"}, optional
        The image's compression (default ``"gzip"``).
    quantize_step : float, optional
        With ``"rice"``: the quantisation step, e-/s/pixel.
    """
    from astropy.io import fits

    from straylight.util.io import atomic_path

    hdr = result.wcs.to_header()
    hdr["BUNIT"] = ("electron/s", "per chip pixel; binned: mean of BIN x BIN")
    for k, v in provenance.items():
        key = k.upper()[:8]
        hdr[key] = v if not isinstance(v, float) else float(v)
    for k, v in result.meta.items():
        hdr[k.upper()[:8]] = v
    data = result.image_e_per_s_per_pix
    if compress == "none":
        hdus = [fits.PrimaryHDU(data, header=hdr)]
    elif compress == "gzip":
        hdr["COMPNOTE"] = "GZIP_2 lossless, no quantisation"
        hdus = [
            fits.PrimaryHDU(),
            fits.CompImageHDU(data, header=hdr, name="SCI", compression_type="GZIP_2", quantize_level=0),
        ]
    elif compress == "rice":
        step = float(quantize_step if quantize_step is not None else 1e-4)
        if not (np.isfinite(step) and step > 0):
            raise InputError(f"--quantize-step {quantize_step}: must be a positive number of e-/s/pixel")
        hdr["QSTEP"] = (step, "e-/s/pixel quantisation step (error <= QSTEP/2)")
        hdr["COMPNOTE"] = "RICE_1 on values quantised to QSTEP, lossy"
        hdus = [
            fits.PrimaryHDU(),
            fits.CompImageHDU(
                data,
                header=hdr,
                name="SCI",
                compression_type="RICE_1",
                quantize_level=-step,
                quantize_method=1,
                # the dither's seed from the first tile's checksum, not the clock: the same image
                # gives the same file
                dither_seed=fits.hdu.compressed.DITHER_SEED_CHECKSUM,
            ),
        ]
    else:
        raise InputError(f"--compress {compress!r}: one of {', '.join(COMPRESSIONS)}")
    hdus += [_table_hdu(result.ghosts, GHOST_UNITS, "GHOSTS"), _table_hdu(result.stars, STAR_UNITS, "STARS")]
    with atomic_path(path) as tmp:
        fits.HDUList(hdus).writeto(tmp)
