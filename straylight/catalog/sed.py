"""Stellar SED template libraries and their synthetic photometry.

A :class:`TemplateLibrary` holds spectra on one wavelength grid.  Two sources:

- :func:`load_pickles` - the embedded Pickles (1998, PASP 110, 863) UVKLIB library, 106
  solar-abundance spectra O5-M10 of luminosity classes V-I, resampled to 10 A over
  1500-12000 A (``data/pickles1998_uvk_sed.fits``, rebuilt by ``scripts/dev/build_sed_library.py``),
  each with the Teff of its spectral type (:func:`teff_from_spectral_type`, frozen in
  ``data/pickles1998_template_teff.csv``);
- :func:`load_btsettl` - BT-Settl model spectra (Allard et al. 2012) for a team that has them:
  two-column text (Angstrom, F_lambda) or FITS tables (WAVELENGTH, FLUX), with Teff, log g and
  [M/H] read from the standard file name ``lte{Teff/100}-{logg}{[M/H]}...``.

:func:`template_magnitudes` computes AB magnitudes of every template through any speclite
filter once; stars then take their template's colours (never integrate per star).

Photometric systems.  speclite gives AB magnitudes.  Gaia DR2 catalogue magnitudes are Vega
magnitudes: AB - Vega offsets are the differences of the DR2 passband zero points (Evans et al.
2018, A&A 616, A4, revised passbands: G 25.7934 - 25.6884, BP 25.3806 - 25.3514,
RP 25.1161 - 24.7619).  SDSS is taken as AB.  Johnson-Cousins B, V, Ic (speclite ``bessell-*``,
Bessell 1990 passbands) use the AB - Vega offsets of Blanton & Roweis (2007, AJ 133, 734,
Table 1: B -0.09, V 0.02, I 0.45).
"""

from __future__ import annotations

import io
import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from straylight.errors import InputError

__all__ = [
    "DATA",
    "PICKLES_FILE",
    "AB_MINUS_VEGA",
    "TemplateLibrary",
    "bin_average",
    "magnitudes",
    "ab_magnitudes",
    "template_magnitudes",
    "vega_magnitudes",
    "DWARF_TEFF_FILE",
    "SPECTRAL_CLASSES",
    "DEJAGER_LATEST_M_SUBTYPE",
    "parse_spectral_type",
    "teff_scale",
    "teff_from_spectral_type",
    "NOMINAL_LOGG",
    "load_pickles",
    "PICKLES_TEFF_FILE",
    "pickles_teff",
    "load_btsettl",
]

DATA = Path(__file__).resolve().parents[1] / "data"
PICKLES_FILE = DATA / "pickles1998_uvk_sed.fits"

# m_AB - m_Vega per speclite filter (sources in the module docstring)
AB_MINUS_VEGA = {
    "gaiadr2-G": 25.7934 - 25.6884,
    "gaiadr2-BP": 25.3806 - 25.3514,
    "gaiadr2-RP": 25.1161 - 24.7619,
    "bessell-B": -0.09,
    "bessell-V": 0.02,
    "bessell-I": 0.45,
}


@dataclass(frozen=True)
class TemplateLibrary:
    """Spectra on a common wavelength grid.

    ``flam``: (n_template, n_wavelength) F_lambda in arbitrary units per template (only colours
    matter; stars are scaled to their own magnitude).  ``teff_k``, ``logg_cgs``, ``feh_dex`` may be
    NaN where the source gives none.
    """

    name: str
    wavelength_angstrom: np.ndarray
    flam: np.ndarray
    template: np.ndarray
    luminosity_class: np.ndarray
    teff_k: np.ndarray
    logg_cgs: np.ndarray
    feh_dex: np.ndarray

    def __len__(self) -> int:
        return len(self.template)

    def subset(self, mask) -> TemplateLibrary:
        """The templates where ``mask`` (boolean or index array over the templates) selects, same grid.

        Parameters
        ----------
        mask : ndarray of bool or int
            Boolean mask or indices over the templates.
        """
        mask = np.asarray(mask)
        return TemplateLibrary(
            self.name,
            self.wavelength_angstrom,
            self.flam[mask],
            self.template[mask],
            self.luminosity_class[mask],
            self.teff_k[mask],
            self.logg_cgs[mask],
            self.feh_dex[mask],
        )


def bin_average(wavelength_angstrom, flam, centres_angstrom, step_angstrom) -> np.ndarray:
    """Mean of the piecewise-linear spectrum over bins of width ``step`` centred on ``centres``
    (flux-conserving resampling).

    Parameters
    ----------
    wavelength_angstrom : ndarray
        The spectrum's wavelengths, Angstrom, increasing.
    flam : ndarray
        F_lambda on ``wavelength_angstrom`` (last axis), any unit.
    centres_angstrom : ndarray
        Bin centres, Angstrom.
    step_angstrom : float
        Bin width, Angstrom.
    """
    wl, fl = np.asarray(wavelength_angstrom, float), np.asarray(flam, float)
    edges = np.concatenate([centres_angstrom - step_angstrom / 2, [centres_angstrom[-1] + step_angstrom / 2]])
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (fl[1:] + fl[:-1]) * np.diff(wl))])
    return np.diff(np.interp(edges, wl, cum)) / step_angstrom


def magnitudes(wavelength_angstrom, flam, responses: dict) -> dict[str, np.ndarray]:
    """AB magnitudes of spectra (last axis = wavelength) through speclite responses (name -> response).

    ``flam`` in any F_lambda unit; magnitudes are relative (offset by one constant for all bands)
    unless ``flam`` is in erg s-1 cm-2 A-1.  A response reaching outside the grid raises.

    Parameters
    ----------
    wavelength_angstrom : ndarray
        Wavelength grid, Angstrom.
    flam : ndarray
        Spectra, F_lambda (last axis over ``wavelength_angstrom``).
    responses : dict of str to speclite.filters.FilterResponse
        Name -> response.
    """
    import astropy.units as u

    wl = np.asarray(wavelength_angstrom, float)
    fl = np.atleast_2d(np.asarray(flam, float)) * u.erg / (u.s * u.cm**2 * u.Angstrom)
    out = {}
    for name, f in responses.items():
        lo, hi = float(f.wavelength.min()), float(f.wavelength.max())
        if lo < wl[0] or hi > wl[-1]:
            raise InputError(
                f"band {name} ({lo:.0f}-{hi:.0f} A) reaches outside the spectra ({wl[0]:.0f}-{wl[-1]:.0f} A)"
            )
        out[name] = np.asarray(f.get_ab_magnitude(fl, wl * u.Angstrom), float)
    return out


def ab_magnitudes(wavelength_angstrom, flam, filter_names) -> dict[str, np.ndarray]:
    """AB magnitudes through speclite's named filters (e.g. ``sdss2010-g``); see :func:`magnitudes`.

    Parameters
    ----------
    wavelength_angstrom : ndarray
        Wavelength grid, Angstrom.
    flam : ndarray
        Spectra, F_lambda (last axis over ``wavelength_angstrom``).
    filter_names : sequence of str
        speclite filter names.
    """
    return magnitudes(wavelength_angstrom, flam, {n: _filter(n) for n in filter_names})


@lru_cache(maxsize=64)
def _filter(name: str):
    import speclite.filters as sf

    return sf.load_filter(name)


def template_magnitudes(library: TemplateLibrary, responses: dict) -> dict[str, np.ndarray]:
    """AB magnitude of every template through each response (name -> speclite FilterResponse).

    Parameters
    ----------
    library : TemplateLibrary
        The templates.
    responses : dict of str to speclite.filters.FilterResponse
        Name -> response.
    """
    return magnitudes(library.wavelength_angstrom, library.flam, responses)


def vega_magnitudes(library: TemplateLibrary, filter_names) -> dict[str, np.ndarray]:
    """Template magnitudes in the Vega system for filters with a known AB - Vega offset.

    Parameters
    ----------
    library : TemplateLibrary
        The templates.
    filter_names : sequence of str
        speclite filter names with a known AB - Vega offset.
    """
    ab = ab_magnitudes(library.wavelength_angstrom, library.flam, filter_names)
    return {n: ab[n] - AB_MINUS_VEGA[n] for n in filter_names}


DWARF_TEFF_FILE = DATA / "pecaut_mamajek_dwarf_teff.csv"
SPECTRAL_CLASSES = "OBAFGKM"
# de Jager & Nieuwenhuijzen's polynomial turns over for luminosity classes IV-I after M4 (it
# makes M9 III 480 K hotter than M4 III): no Teff from it for later M types.
DEJAGER_LATEST_M_SUBTYPE = 4.0
_PICKLES_TYPE = re.compile(r"^[rw]?(?P<cls>[OBAFGKM])(?P<sub>\d+(?:\.\d+)?)(?P<lc>I{1,3}|IV|V)$")


def parse_spectral_type(name: str) -> tuple[str, float, str]:
    """Spectral class, subtype and luminosity class of a Pickles template name: 'G2V' ->
    ('G', 2.0, 'V'); two digits are Pickles' subtype ranges ('B57V' is B5-7 V -> 6.0, 'K01II'
    -> 0.5), except M10.

    Parameters
    ----------
    name : str
        A Pickles template name (e.g. ``"G2V"``).
    """
    m = _PICKLES_TYPE.match(str(name).strip())
    if not m:
        raise InputError(f"template {name!r}: not a spectral type like G2V, B57V or M10III")
    sub = m["sub"]
    if len(sub) == 2 and sub != "10":
        value = (int(sub[0]) + int(sub[1])) / 2.0
    else:
        value = float(sub)
    return m["cls"], value, m["lc"]


def _read_teff_csv(path: Path, name_column: str) -> dict[str, float]:
    """Name -> Teff (K) from one of the embedded CSV tables (``#`` comments; empty: NaN)."""
    from astropy.table import Table

    t = Table.read(path, format="ascii.csv", comment="#")
    teff = np.ma.filled(np.ma.asarray(t["teff_k"], float), np.nan)
    return dict(zip((str(n) for n in t[name_column]), teff))


@lru_cache(maxsize=1)
def _dwarf_teff_table() -> tuple[np.ndarray, np.ndarray]:
    table = _read_teff_csv(DWARF_TEFF_FILE, "spt")
    codes = np.array([_type_code(*parse_spectral_type(n)[:2]) for n in table])
    return codes, np.array(list(table.values()))


def _type_code(spectral_class: str, subtype: float) -> float:
    return 10.0 * SPECTRAL_CLASSES.index(spectral_class) + subtype


def teff_scale(luminosity_class: str) -> str:
    """Which published scale gives a luminosity class its Teff: "PM13" (class V) or "DJ87".

    Parameters
    ----------
    luminosity_class : str
        Luminosity class (``"V"``, ``"IV"``, ``"III"``, ``"II"``, ``"I"``).
    """
    return "PM13" if luminosity_class == "V" else "DJ87"


def teff_from_spectral_type(names) -> np.ndarray:
    """Teff (K) of templates from their spectral type and luminosity class.

    Class V: Pecaut & Mamajek (2013, ApJS 208, 9) Table 5 (updated table v2024.05.15,
    ``data/pecaut_mamajek_dwarf_teff.csv``), linear between tabulated subtypes.  Classes IV-I:
    de Jager & Nieuwenhuijzen (1987, A&A 177, 217) 20-coefficient relation through PyAstronomy's
    ``SpecTypeDeJager`` (class I taken as Iab); it reproduces their tables to a few per cent.
    NaN for giants and supergiants later than M4 (see ``DEJAGER_LATEST_M_SUBTYPE``).  Needs
    PyAstronomy (a test dependency; the product reads the frozen table, :func:`pickles_teff`).

    Parameters
    ----------
    names : sequence of str
        Pickles template names.
    """
    from PyAstronomy.pyasl import SpecTypeDeJager

    codes, teffs = _dwarf_teff_table()
    dj = SpecTypeDeJager()
    out = np.full(len(names), np.nan)
    for i, name in enumerate(names):
        cls, sub, lc = parse_spectral_type(name)
        code = _type_code(cls, sub)
        if teff_scale(lc) == "PM13":
            if codes[0] <= code <= codes[-1]:
                out[i] = np.interp(code, codes, teffs)
        elif not (cls == "M" and sub > DEJAGER_LATEST_M_SUBTYPE):
            out[i] = 10.0 ** float(dj.lumAndTeff(f"{cls}{sub:g}", "Iab" if lc == "I" else lc)[1])
    return out


# assumption: Pickles (1998) gives no log g; typical values of each luminosity class
# (dwarfs 4.5, subgiants 3.8, giants 2.5, bright giants 1.8, supergiants 1.0)
NOMINAL_LOGG = {"V": 4.5, "IV": 3.8, "III": 2.5, "II": 1.8, "I": 1.0}


@lru_cache(maxsize=1)
def load_pickles() -> TemplateLibrary:
    """The embedded Pickles (1998) UVKLIB library (106 solar-abundance templates)."""
    from astropy.io import fits

    with fits.open(PICKLES_FILE) as h:
        flam = np.asarray(h["SED"].data, float)
        wl = np.asarray(h["WAVELENGTH"].data, float)
        t = h["TEMPLATES"].data
        names = np.char.strip(np.asarray(t["TEMPLATE"]).astype(str))
        lc = np.char.strip(np.asarray(t["LUMCLASS"]).astype(str))
    return TemplateLibrary(
        "pickles1998",
        wl,
        flam,
        names,
        lc,
        pickles_teff(names),
        np.array([NOMINAL_LOGG[c] for c in lc]),
        np.zeros(len(names)),
    )


PICKLES_TEFF_FILE = DATA / "pickles1998_template_teff.csv"


def pickles_teff(names) -> np.ndarray:
    """The templates' Teff (K) frozen in ``data/pickles1998_template_teff.csv`` (written by
    ``scripts/dev/build_template_teff.py`` with :func:`teff_from_spectral_type`, so a run needs
    no PyAstronomy; tests re-derive it).  NaN where the file has none.

    Parameters
    ----------
    names : sequence of str
        Pickles template names.
    """
    table = _read_teff_csv(PICKLES_TEFF_FILE, "template")
    missing = [n for n in names if n not in table]
    if missing:
        raise InputError(
            f"{PICKLES_TEFF_FILE}: no row for templates {missing}; rebuild it "
            "with scripts/dev/build_template_teff.py"
        )
    return np.array([table[n] for n in names])


_BTSETTL_NAME = re.compile(r"lte(?P<teff>\d+(?:\.\d+)?)-?(?P<logg>[+-]?\d+\.\d+)(?P<feh>[+-]\d+\.\d+)")


def load_btsettl(
    paths, wavelength_min_angstrom=1500.0, wavelength_max_angstrom=12000.0, step_angstrom=10.0
) -> TemplateLibrary:
    """BT-Settl spectra (text: Angstrom and F_lambda columns; or FITS WAVELENGTH/FLUX) -> library.

    Parameters come from the file name, e.g. ``lte058-4.5-0.0a+0.0.BT-Settl.7.dat.txt``
    (Teff 5800 K, log g 4.5, [M/H] 0.0).  Spectra are bin-averaged to a common grid.

    Parameters
    ----------
    paths : sequence of str or pathlib.Path
        BT-Settl spectra files.
    wavelength_min_angstrom : float, optional
        Start of the common grid, Angstrom (default 1500).
    wavelength_max_angstrom : float, optional
        End of the common grid, Angstrom (default 12000).
    step_angstrom : float, optional
        Step of the common grid, Angstrom (default 10).
    """
    from astropy.io import fits

    grid = np.arange(wavelength_min_angstrom, wavelength_max_angstrom + step_angstrom / 2, step_angstrom)
    rows, names, teff, logg, feh = [], [], [], [], []
    for p in map(Path, paths):
        m = _BTSETTL_NAME.search(p.name)
        if not m:
            raise InputError(
                f"{p}: file name does not follow the BT-Settl pattern lte<Teff/100>-<logg><[M/H]>"
            )
        try:
            if p.suffix.lower() in (".fits", ".fit"):
                with fits.open(p) as h:
                    d = h[1].data
                    wl, fl = np.asarray(d["WAVELENGTH"], float), np.asarray(d["FLUX"], float)
            else:  # BT-Settl text files write Fortran exponents (1.0D+05)
                a = np.loadtxt(io.StringIO(p.read_text().replace("D", "E")), comments="#", usecols=(0, 1))
                wl, fl = a[:, 0], a[:, 1]
        except (OSError, ValueError, KeyError, IndexError) as exc:
            raise InputError(f"{p}: cannot read a BT-Settl spectrum: {exc}") from exc
        order = np.argsort(wl)
        wl, fl = wl[order], fl[order]
        if wl[0] > grid[0] or wl[-1] < grid[-1]:
            raise InputError(f"{p}: covers {wl[0]:.0f}-{wl[-1]:.0f} A, need {grid[0]:.0f}-{grid[-1]:.0f} A")
        if not np.all(np.isfinite(fl)) or np.any(fl < 0):
            raise InputError(f"{p}: FLUX has negative or non-finite values")
        rows.append(bin_average(wl, fl, grid, step_angstrom))
        t = float(m["teff"]) * 100.0
        names.append(f"BT-Settl {t:.0f}/{float(m['logg']):.1f}/{float(m['feh']):+.1f}")
        teff.append(t)
        logg.append(float(m["logg"]))
        feh.append(float(m["feh"]))
    if not rows:
        raise InputError("no BT-Settl files given")
    lc = np.array(["V" if g >= 4.0 else "III" for g in logg])
    return TemplateLibrary(
        "bt-settl", grid, np.asarray(rows), np.array(names), lc, np.array(teff), np.array(logg), np.array(feh)
    )
