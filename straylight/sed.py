"""Stellar SED template libraries and their synthetic photometry (issue #3).

A :class:`TemplateLibrary` holds spectra on one wavelength grid.  Two sources:

- :func:`load_pickles` - the embedded Pickles (1998, PASP 110, 863) UVKLIB library, 106
  solar-abundance spectra O5-M10 of luminosity classes V-I, resampled to 10 A over
  1500-12000 A (``data/pickles1998_uvk_sed.fits``, rebuilt by ``scripts/dev/build_sed_library.py``);
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

from .errors import InputError

DATA = Path(__file__).parent / "data"
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

# Colour-Teff relations, theta = 5040 / Teff = b0 + b1 X + b2 X^2 + b3 X [Fe/H] + b4 [Fe/H] + b5 [Fe/H]^2.
# Dwarfs and subgiants: Casagrande et al. 2010, A&A 512, A54, Table 4, X = (V - Ic), valid 0.46-1.47,
# sigma 59 K.  Giants: Gonzalez Hernandez & Bonifacio 2009, A&A 497, 497, Table 5, X = (B - V),
# valid 0.3-1.4, sigma 57 K.
TEFF_RELATIONS = {
    "dwarf": ("V-I", (0.4033, 0.8171, -0.1987, -0.0409, 0.0319, 0.0012), (0.46, 1.47)),
    "giant": ("B-V", (0.4967, 0.7260, -0.1563, 0.0255, -0.0585, -0.0061), (0.3, 1.4)),
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
        mask = np.asarray(mask)
        return TemplateLibrary(self.name, self.wavelength_angstrom, self.flam[mask], self.template[mask],
                               self.luminosity_class[mask], self.teff_k[mask], self.logg_cgs[mask],
                               self.feh_dex[mask])


def bin_average(wavelength_angstrom, flam, centres_angstrom, step_angstrom) -> np.ndarray:
    """Mean of the piecewise-linear spectrum over bins of width ``step`` centred on ``centres``
    (flux-conserving resampling)."""
    wl, fl = np.asarray(wavelength_angstrom, float), np.asarray(flam, float)
    edges = np.concatenate([centres_angstrom - step_angstrom / 2, [centres_angstrom[-1] + step_angstrom / 2]])
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (fl[1:] + fl[:-1]) * np.diff(wl))])
    return np.diff(np.interp(edges, wl, cum)) / step_angstrom


def magnitudes(wavelength_angstrom, flam, responses: dict) -> dict[str, np.ndarray]:
    """AB magnitudes of spectra (last axis = wavelength) through speclite responses (name -> response).

    ``flam`` in any F_lambda unit; magnitudes are relative (offset by one constant for all bands)
    unless ``flam`` is in erg s-1 cm-2 A-1.  A response reaching outside the grid raises.
    """
    import astropy.units as u

    wl = np.asarray(wavelength_angstrom, float)
    fl = np.atleast_2d(np.asarray(flam, float)) * u.erg / (u.s * u.cm**2 * u.Angstrom)
    out = {}
    for name, f in responses.items():
        lo, hi = float(f.wavelength.min()), float(f.wavelength.max())
        if lo < wl[0] or hi > wl[-1]:
            raise InputError(f"band {name} ({lo:.0f}-{hi:.0f} A) reaches outside the spectra "
                             f"({wl[0]:.0f}-{wl[-1]:.0f} A)")
        out[name] = np.asarray(f.get_ab_magnitude(fl, wl * u.Angstrom), float)
    return out


def ab_magnitudes(wavelength_angstrom, flam, filter_names) -> dict[str, np.ndarray]:
    """AB magnitudes through speclite's named filters (e.g. ``sdss2010-g``); see :func:`magnitudes`."""
    return magnitudes(wavelength_angstrom, flam, {n: _filter(n) for n in filter_names})


@lru_cache(maxsize=64)
def _filter(name: str):
    import speclite.filters as sf

    return sf.load_filter(name)


def template_magnitudes(library: TemplateLibrary, responses: dict) -> dict[str, np.ndarray]:
    """AB magnitude of every template through each response (name -> speclite FilterResponse)."""
    return magnitudes(library.wavelength_angstrom, library.flam, responses)


def vega_magnitudes(library: TemplateLibrary, filter_names) -> dict[str, np.ndarray]:
    """Template magnitudes in the Vega system for filters with a known AB - Vega offset."""
    ab = ab_magnitudes(library.wavelength_angstrom, library.flam, filter_names)
    return {n: ab[n] - AB_MINUS_VEGA[n] for n in filter_names}


def teff_from_colours(luminosity_class, v_minus_i, b_minus_v, feh_dex=0.0) -> np.ndarray:
    """Teff (K) from Johnson-Cousins colours with the relations of ``TEFF_RELATIONS``; NaN outside."""
    lc = np.asarray(luminosity_class).astype(str)
    vi, bv = np.asarray(v_minus_i, float), np.asarray(b_minus_v, float)
    feh = np.broadcast_to(np.asarray(feh_dex, float), vi.shape)
    teff = np.full(vi.shape, np.nan)
    giant = np.isin(lc, ["III", "II", "I"])
    for kind, sel in (("dwarf", ~giant), ("giant", giant)):
        _, b, (lo, hi) = TEFF_RELATIONS[kind]
        x = vi if kind == "dwarf" else bv
        ok = sel & (x >= lo) & (x <= hi)
        theta = b[0] + b[1] * x + b[2] * x**2 + b[3] * x * feh + b[4] * feh + b[5] * feh**2
        teff[ok] = 5040.0 / theta[ok]
    return teff


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
    lib = TemplateLibrary("pickles1998", wl, flam, names, lc, np.full(len(names), np.nan),
                          np.array([NOMINAL_LOGG[c] for c in lc]), np.zeros(len(names)))
    vega = vega_magnitudes(lib, ["bessell-B", "bessell-V", "bessell-I"])
    teff = teff_from_colours(lc, vega["bessell-V"] - vega["bessell-I"], vega["bessell-B"] - vega["bessell-V"])
    return TemplateLibrary(lib.name, wl, flam, names, lc, teff, lib.logg_cgs, lib.feh_dex)


_BTSETTL_NAME = re.compile(r"lte(?P<teff>\d+(?:\.\d+)?)-?(?P<logg>[+-]?\d+\.\d+)(?P<feh>[+-]\d+\.\d+)")


def load_btsettl(paths, wavelength_min_angstrom=1500.0, wavelength_max_angstrom=12000.0,
                 step_angstrom=10.0) -> TemplateLibrary:
    """BT-Settl spectra (text: Angstrom and F_lambda columns; or FITS WAVELENGTH/FLUX) -> library.

    Parameters come from the file name, e.g. ``lte058-4.5-0.0a+0.0.BT-Settl.7.dat.txt``
    (Teff 5800 K, log g 4.5, [M/H] 0.0).  Spectra are bin-averaged to a common grid.
    """
    from astropy.io import fits

    grid = np.arange(wavelength_min_angstrom, wavelength_max_angstrom + step_angstrom / 2, step_angstrom)
    rows, names, teff, logg, feh = [], [], [], [], []
    for p in map(Path, paths):
        m = _BTSETTL_NAME.search(p.name)
        if not m:
            raise InputError(f"{p}: file name does not follow the BT-Settl pattern lte<Teff/100>-<logg><[M/H]>")
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
    return TemplateLibrary("bt-settl", grid, np.asarray(rows), np.array(names), lc, np.array(teff),
                           np.array(logg), np.array(feh))
