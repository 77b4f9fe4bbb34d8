"""Rebuild straylight/data/pickles1998_template_teff.csv: the Teff of every embedded Pickles
template from its spectral type (straylight.catalog.sed.teff_from_spectral_type: Pecaut & Mamajek 2013
for class V, de Jager & Nieuwenhuijzen 1987 via PyAstronomy for classes IV-I).

Usage::

    pip install PyAstronomy
    python scripts/dev/build_template_teff.py
"""

from __future__ import annotations

import numpy as np
from astropy.io import fits

from straylight.catalog.sed import PICKLES_FILE, PICKLES_TEFF_FILE, teff_from_spectral_type, teff_scale

HEADER = """\
# Teff of the embedded Pickles (1998) templates from their spectral type and luminosity class.
# Class V: Pecaut & Mamajek 2013, ApJS 208, 9, Table 5 (updated table v2024.05.15), linear in
# subtype; classes IV-I: de Jager & Nieuwenhuijzen 1987, A&A 177, 217, 20-coefficient relation
# (PyAstronomy SpecTypeDeJager; class I as Iab).  Empty: giants/supergiants after M4, where the
# DJ87 relation turns over.  Written by scripts/dev/build_template_teff.py; do not edit.
template,teff_k,source
"""


def main() -> None:
    # the template names straight from the library file: load_pickles() needs this table already
    with fits.open(PICKLES_FILE) as h:
        names = [str(n).strip() for n in h["TEMPLATES"].data["TEMPLATE"]]
        lcs = [str(c).strip() for c in h["TEMPLATES"].data["LUMCLASS"]]
    teff = teff_from_spectral_type(names)
    rows = []
    for n, lc, t in zip(names, lcs, teff):
        src = teff_scale(lc) if np.isfinite(t) else ""
        rows.append(f"{n},{'' if not np.isfinite(t) else f'{t:.0f}'},{src}")
    PICKLES_TEFF_FILE.write_text(HEADER + "\n".join(rows) + "\n")
    print(f"{PICKLES_TEFF_FILE}: {len(rows)} templates, {int(np.isnan(teff).sum())} without Teff")


if __name__ == "__main__":
    main()
