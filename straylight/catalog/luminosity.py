"""Luminosity classes of catalog stars from their Hipparcos parallaxes, for the template choice.

The Hipparcos new reduction (``hip2.dat``, van Leeuwen 2007) carries no spectral types, so a
star's luminosity class is read from its absolute magnitude instead:
M_V = V + 5 log10(parallax / 100 mas), for stars whose parallax is measured to better than
1 / ``snr_min`` of itself (``stars.luminosity_parallax_snr_min``).

Each Pickles template's M_V follows from its spectral type and luminosity class: log L and
log Teff of de Jager & Nieuwenhuijzen (1987, A&A 177, 217; through PyAstronomy's
``SpecTypeDeJager``, class I as Iab), frozen in ``data/pickles1998_template_luminosity.csv``,
and the bolometric correction BC_V(Teff) of Flower (1996, ApJ 469, 355) with the coefficients
as corrected by Torres (2010, AJ 140, 1158, Table 1):
M_V = M_bol,sun - 2.5 log10(L / Lsun) - BC_V, with M_bol,sun = 4.73 on Flower's BC scale
(Torres 2010 sect. 3: V_sun = -26.76, BC_V,sun = -0.080).

The choice (:func:`choose_templates`): each class offers the template nearest the star in
colour, and the offer of least (d_colour / ``COLOUR_SCALE_MAG``)^2 + (d_M_V /
``ABS_MAG_SCALE_MAG``)^2 wins: a class must match the star's luminosity without straying far
from its colour (Antares, M_V = -5.3 and BP - RP = 2.9, takes the library's only M supergiant,
M2I, 0.6 mag bluer, rather than an M4 dwarf of its colour 18 mag fainter).  Stars without a
measured luminosity keep the colour match among the dwarf-to-giant classes
(``NO_LUMINOSITY_CLASSES``): supergiants and bright giants are rare among field stars, and a
colour alone cannot tell them apart.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.spatial import cKDTree

from straylight.catalog.sed import DATA
from straylight.errors import InputError

__all__ = [
    "PICKLES_LUMINOSITY_FILE",
    "M_BOL_SUN",
    "COLOUR_SCALE_MAG",
    "ABS_MAG_SCALE_MAG",
    "NO_LUMINOSITY_CLASSES",
    "bc_v_flower",
    "absolute_v_mag",
    "template_abs_v_mag",
    "choose_templates",
]

PICKLES_LUMINOSITY_FILE = DATA / "pickles1998_template_luminosity.csv"
#: the Sun's bolometric absolute magnitude on Flower's (1996) BC scale (Torres 2010 sect. 3)
M_BOL_SUN = 4.73
#: assumption: the colour mismatch (mag, BP - RP or V - Ic) that costs as much as
#: ABS_MAG_SCALE_MAG of M_V: twice the ~0.05 mag spacing of neighbouring Pickles templates of
#: one class in BP - RP
COLOUR_SCALE_MAG = 0.1
#: assumption: the spread of M_V within one luminosity class at one spectral type, ~1 mag (the
#: de Jager & Nieuwenhuijzen class III K giants have M_V ~ +0.9; Arcturus, K1.5 III, -0.3)
ABS_MAG_SCALE_MAG = 1.0
#: the classes a star without a measured luminosity is matched among (those the library has)
NO_LUMINOSITY_CLASSES = ("V", "IV", "III")

# Torres (2010) Table 1: BC_V = sum_k c_k (log Teff)^k, in three ranges of log Teff
_BC_RANGES = (
    (3.70, (-0.190537291496456e05, 0.155144866764412e05, -0.421278819301717e04, 0.381476328422343e03)),
    (
        3.90,
        (
            -0.370510203809015e05,
            0.385672629965804e05,
            -0.150651486316025e05,
            0.261724637119416e04,
            -0.170623810323864e03,
        ),
    ),
    (
        np.inf,
        (
            -0.118115450538963e06,
            0.137145973583929e06,
            -0.636233812100225e05,
            0.147412923562646e05,
            -0.170587278406872e04,
            0.788731721804990e02,
        ),
    ),
)


def bc_v_flower(teff_k) -> np.ndarray:
    """Bolometric correction BC_V (mag) at effective temperature ``teff_k`` (K, any shape):
    Flower (1996) as corrected by Torres (2010, Table 1); NaN where Teff is NaN.

    Parameters
    ----------
    teff_k : array_like
        Effective temperature, K.
    """
    log_t = np.log10(np.asarray(teff_k, float))
    out = np.full(log_t.shape, np.nan)
    lower = -np.inf
    for upper, coeffs in _BC_RANGES:
        sel = (log_t >= lower) & (log_t < upper)
        out[sel] = np.polynomial.polynomial.polyval(log_t[sel], coeffs)
        lower = upper
    return out


def absolute_v_mag(v_mag, parallax_mas, parallax_error_mas, snr_min: float) -> np.ndarray:
    """M_V = V + 5 log10(parallax / 100 mas) (mag) where the parallax is at least ``snr_min``
    times its error, else NaN.

    Parameters
    ----------
    v_mag : array_like, shape (n,)
        Johnson V, mag.
    parallax_mas, parallax_error_mas : array_like, shape (n,)
        Parallax and its standard error, mas.
    snr_min : float
        The least parallax / error that counts as a measured distance.

    Returns
    -------
    ndarray, shape (n,)
        Absolute V magnitude, mag; NaN without a measured distance.
    """
    v, plx, err = (np.asarray(x, float) for x in (v_mag, parallax_mas, parallax_error_mas))
    good = np.isfinite(v) & (plx > 0) & (err > 0) & (plx >= snr_min * err)
    out = np.full(v.shape, np.nan)
    out[good] = v[good] + 5.0 * np.log10(plx[good] / 100.0)
    return out


@lru_cache(maxsize=1)
def _luminosity_table() -> dict[str, tuple[float, float]]:
    from astropy.table import Table

    t = Table.read(PICKLES_LUMINOSITY_FILE, format="ascii.csv", comment="#")
    log_l = np.ma.filled(np.ma.asarray(t["log_l_lsun"], float), np.nan)
    log_t = np.ma.filled(np.ma.asarray(t["log_teff_k"], float), np.nan)
    return {str(n): (a, b) for n, a, b in zip(t["template"], log_l, log_t)}


def template_abs_v_mag(names) -> np.ndarray:
    """M_V (mag) of Pickles templates from their frozen de Jager & Nieuwenhuijzen (1987) log L
    and log Teff (``data/pickles1998_template_luminosity.csv``) and :func:`bc_v_flower`; NaN
    where the relation gives none (giants and supergiants after M4).  Names the table lacks
    (another library): NaN.

    Parameters
    ----------
    names : sequence of str
        Pickles template names (e.g. ``"G2V"``).
    """
    table = _luminosity_table()
    log_l = np.array([table.get(str(n), (np.nan, np.nan))[0] for n in names], float)
    log_t = np.array([table.get(str(n), (np.nan, np.nan))[1] for n in names], float)
    return M_BOL_SUN - 2.5 * log_l - bc_v_flower(10.0**log_t)


def choose_templates(
    template_colour,
    template_class,
    template_abs_v,
    star_colour,
    star_abs_v,
    colour_scale_mag: float = COLOUR_SCALE_MAG,
    abs_mag_scale_mag: float = ABS_MAG_SCALE_MAG,
    no_luminosity_classes=NO_LUMINOSITY_CLASSES,
) -> tuple[np.ndarray, np.ndarray]:
    """Each star's template: by luminosity class where its M_V is known, else by colour.

    Parameters
    ----------
    template_colour : array_like, shape (t,)
        The templates' colour (BP - RP or V - Ic, mag).
    template_class : array_like of str, shape (t,)
        Their luminosity classes (V, IV, III, II, I).
    template_abs_v : array_like, shape (t,)
        Their M_V, mag (:func:`template_abs_v_mag`); NaN: unknown.
    star_colour : array_like, shape (n,)
        The stars' colour in the same system, mag.
    star_abs_v : array_like, shape (n,)
        The stars' M_V, mag (:func:`absolute_v_mag`); NaN: not measured.
    colour_scale_mag, abs_mag_scale_mag : float
        See :data:`COLOUR_SCALE_MAG` and :data:`ABS_MAG_SCALE_MAG`, mag.
    no_luminosity_classes : sequence of str
        See :data:`NO_LUMINOSITY_CLASSES`.

    Returns
    -------
    index : ndarray of int, shape (n,)
        The template of each star (an index into the templates).
    by_luminosity : ndarray of bool, shape (n,)
        True where the class came from the star's M_V.
    """
    t_colour = np.asarray(template_colour, float)
    t_class = np.asarray(template_class).astype(str)
    t_abs_v = np.asarray(template_abs_v, float)
    colour = np.asarray(star_colour, float)
    abs_v = np.asarray(star_abs_v, float)
    n = colour.size
    if not t_colour.size:
        raise InputError("no templates to choose from")
    classes = list(dict.fromkeys(t_class))
    offer = np.zeros((len(classes), n), int)
    distance = np.full((len(classes), n), np.inf)
    query = np.nan_to_num(colour, nan=0.0)[:, None]
    for k, c in enumerate(classes):
        members = np.flatnonzero(t_class == c)
        d, j = cKDTree(t_colour[members][:, None]).query(query, k=1)
        offer[k], distance[k] = members[np.asarray(j, int)], d
    cols = np.arange(n)
    # without a luminosity: the colour match among the dwarf-to-giant classes the library has
    plain = [k for k, c in enumerate(classes) if c in no_luminosity_classes] or list(range(len(classes)))
    index = offer[plain][np.argmin(distance[plain], axis=0), cols] if n else np.zeros(0, int)
    by_luminosity = np.isfinite(abs_v) & bool(np.isfinite(t_abs_v).any())  # none: another library
    if by_luminosity.any():
        mismatch = (t_abs_v[offer] - abs_v[None, :]) / abs_mag_scale_mag
        score = (distance / colour_scale_mag) ** 2 + mismatch**2
        # a template without an M_V (giants after M4) competes last: it wins only alone
        score = np.where(np.isfinite(score), score, 1e12 + distance)
        best = offer[np.argmin(score, axis=0), cols]
        index = np.where(by_luminosity, best, index)
    return np.asarray(index, int), by_luminosity
