"""Rebuild straylight/data/pickles1998_template_luminosity.csv: log L and log Teff of every
embedded Pickles template from its spectral type and luminosity class, by de Jager &
Nieuwenhuijzen (1987, A&A 177, 217) through PyAstronomy's SpecTypeDeJager (class I as Iab),
for the luminosity-class choice of straylight.catalog.luminosity.

Usage::

    pip install PyAstronomy
    python scripts/dev/build_template_luminosity.py
"""

from __future__ import annotations

from astropy.io import fits

from straylight.catalog.luminosity import PICKLES_LUMINOSITY_FILE
from straylight.catalog.sed import DEJAGER_LATEST_M_SUBTYPE, PICKLES_FILE, parse_spectral_type

HEADER = """\
# log L (Lsun) and log Teff (K) of the embedded Pickles (1998) templates from their spectral type
# and luminosity class: de Jager & Nieuwenhuijzen 1987, A&A 177, 217, 20-coefficient relation
# (PyAstronomy SpecTypeDeJager; class I as Iab).  Empty: classes IV-I after M4, where the
# relation turns over.  Written by scripts/dev/build_template_luminosity.py; do not edit.
template,log_l_lsun,log_teff_k
"""


def main() -> None:
    from PyAstronomy.pyasl import SpecTypeDeJager

    dj = SpecTypeDeJager()
    with fits.open(PICKLES_FILE) as h:
        names = [str(n).strip() for n in h["TEMPLATES"].data["TEMPLATE"]]
    rows = []
    for name in names:
        cls, sub, lc = parse_spectral_type(name)
        if lc != "V" and cls == "M" and sub > DEJAGER_LATEST_M_SUBTYPE:
            rows.append(f"{name},,")
            continue
        log_l, log_t = dj.lumAndTeff(f"{cls}{sub:g}", "Iab" if lc == "I" else lc)
        rows.append(f"{name},{float(log_l):.3f},{float(log_t):.4f}")
    PICKLES_LUMINOSITY_FILE.write_text(HEADER + "\n".join(rows) + "\n")
    print(f"{PICKLES_LUMINOSITY_FILE}: {len(rows)} templates")


if __name__ == "__main__":
    main()
