"""Bright-star catalog in the CSST bands: template matching and synthetic photometry.

Pipeline (seed paper sect. 2.2 item 4, with the substitutions documented in docs/physics.md):

1. Stars: Gaia DR2 rows from :mod:`straylight.catalog.gaia`, and/or the Hipparcos default of
   :mod:`straylight.catalog.hipparcos`.  With both, Hipparcos only fills the stars that have no Gaia
   counterpart within ``match_radius_arcsec`` (the stars too bright for Gaia DR2).
2. SDSS g, r, i from G and BP - RP with the DR2 relations (:func:`straylight.catalog.gaia.sdss_from_gaia`),
   flagged outside their validity ranges.
3. Each star gets a template: the nearest template in Gaia BP - RP (a KD-tree over the templates'
   synthetic colours).  Hipparcos stars whose V - Ic lies outside the Johnson-Cousins -> Gaia
   relations are matched on V - Ic instead and take G, BP, RP from the template ("the SED route
   decides").  Hipparcos stars with a measured parallax take the luminosity class whose
   template's M_V is nearest their own (:mod:`straylight.catalog.luminosity`: hip2.dat has no
   spectral types); the others are matched among the dwarf-to-giant classes.  With a
   user-supplied mock population (Teff, log g, [Fe/H], SDSS g r i, e.g. a
   Galaxia output) stars first take the parameters of the nearest mock star in (g - r, r - i),
   as the paper does, and then the template nearest in (Teff, log g, [Fe/H]) when the library
   has parameters (BT-Settl), else the colour match.
4. Magnitudes: m_band = G_star + (m_band - G)_template, with template magnitudes computed once
   per template through the instrument's filter curves (speclite).

Flags (bit mask): 1/2/4 SDSS g/r/i relation outside validity; 8 star colour beyond the template
range by more than 0.05 mag; 16 Hipparcos Hp -> V outside the verified range; 32 Hipparcos V - Ic
outside the Gaia relations (G, BP, RP from the template); 64 Teff unknown for the template;
128 luminosity class from the parallax (M_V).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from straylight.catalog.gaia import sdss_from_gaia
from straylight.catalog.hipparcos import FLAG_VI_RELATION_EXTRAPOLATED
from straylight.catalog.luminosity import absolute_v_mag, choose_templates, template_abs_v_mag
from straylight.catalog.sed import (
    AB_MINUS_VEGA,
    TemplateLibrary,
    ab_magnitudes,
    load_pickles,
    template_magnitudes,
)
from straylight.errors import InputError

__all__ = [
    "FLAG_SDSS",
    "FLAG_COLOUR_BEYOND_TEMPLATES",
    "FLAG_TEFF_UNKNOWN",
    "FLAG_CLASS_FROM_PARALLAX",
    "CATALOG_BUILD_VERSION",
    "ALL_CLASSES",
    "GAIA_FILTERS",
    "SDSS_FILTERS",
    "JC_FILTERS",
    "STAR_COLUMNS",
    "TemplatePhotometry",
    "select_templates",
    "cross_match_fill",
    "read_population",
    "build_catalog",
    "round_trip",
    "CatalogOptions",
    "make_catalog",
]

FLAG_SDSS = {"g": 1, "r": 2, "i": 4}
FLAG_COLOUR_BEYOND_TEMPLATES = 8
FLAG_TEFF_UNKNOWN = 64
FLAG_CLASS_FROM_PARALLAX = 128
#: the default catalog's build: part of its cache key, raised whenever the columns or the way
#: they are derived change (so a cached catalog of an older build is never reused)
CATALOG_BUILD_VERSION = 2
ALL_CLASSES = ("V", "IV", "III", "II", "I")
GAIA_FILTERS = ("gaiadr2-G", "gaiadr2-BP", "gaiadr2-RP")
SDSS_FILTERS = ("sdss2010-u", "sdss2010-g", "sdss2010-r", "sdss2010-i", "sdss2010-z")
JC_FILTERS = ("bessell-B", "bessell-V", "bessell-I")
STAR_COLUMNS = (
    "source_id",
    "ra",
    "dec",
    "pmra",
    "pmdec",
    "ref_epoch",
    "phot_g_mean_mag",
    "phot_bp_mean_mag",
    "phot_rp_mean_mag",
)


class TemplatePhotometry:
    """Per-template colours, computed once: Gaia (Vega), SDSS (AB), Johnson-Cousins (Vega), bands (AB)."""

    def __init__(self, library: TemplateLibrary, band_responses: dict):
        self.library = library
        ab = ab_magnitudes(
            library.wavelength_angstrom, library.flam, GAIA_FILTERS + SDSS_FILTERS + JC_FILTERS
        )
        vega = {n: ab[n] - AB_MINUS_VEGA[n] for n in GAIA_FILTERS + JC_FILTERS}
        self.g_vega = vega["gaiadr2-G"]
        self.bp_rp = vega["gaiadr2-BP"] - vega["gaiadr2-RP"]
        self.bp_minus_g = vega["gaiadr2-BP"] - self.g_vega
        self.rp_minus_g = vega["gaiadr2-RP"] - self.g_vega
        self.v_minus_g = vega["bessell-V"] - self.g_vega
        self.v_i = vega["bessell-V"] - vega["bessell-I"]
        self.sdss_minus_g = {n.split("-")[1]: ab[n] - self.g_vega for n in SDSS_FILTERS}
        bands = template_magnitudes(library, band_responses)
        self.band_minus_g = {name: m - self.g_vega for name, m in bands.items()}
        self.tree_bp_rp = cKDTree(self.bp_rp[:, None])
        self.tree_v_i = cKDTree(self.v_i[:, None])
        self.abs_v = template_abs_v_mag(library.template)  # NaN outside the Pickles library


def select_templates(library: TemplateLibrary, classes) -> TemplateLibrary:
    """The library's templates of the luminosity classes ``classes`` (stars.template_classes;
    empty or None: the whole library).  InputError when no template is of those classes.

    Parameters
    ----------
    library : TemplateLibrary
        The template library.
    classes : sequence of str or None
        Luminosity classes to keep (``"V"``, ``"IV"``, ``"III"``, ``"II"``, ``"I"``); empty or None
        keeps the whole library.
    """
    if not classes:
        return library
    keep = np.isin(library.luminosity_class, list(classes))
    if not keep.any():
        raise InputError(
            f"stars.template_classes {list(classes)}: no template of those luminosity classes "
            f"(library has {sorted(set(library.luminosity_class))})"
        )
    return library.subset(keep)


def cross_match_fill(gaia: dict, hip: dict, match_radius_arcsec: float) -> np.ndarray:
    """Mask of Hipparcos stars without a Gaia counterpart within the radius (positions at J2015.5).

    Parameters
    ----------
    gaia : dict of str to ndarray
        Gaia catalog columns (``ra``, ``dec`` in deg at J2015.5).
    hip : dict of str to ndarray
        Hipparcos star columns (ingest layout, positions at J2015.5, deg).
    match_radius_arcsec : float
        Match radius, arcsec.
    """
    if len(gaia["ra"]) == 0:
        return np.ones(len(hip["ra"]), bool)
    dt = 2015.5 - np.asarray(hip["ref_epoch"], float)
    cosd = np.cos(np.radians(hip["dec"]))
    ra = hip["ra"] + hip["pmra"] * dt / 3.6e6 / np.maximum(cosd, 1e-6)
    dec = hip["dec"] + hip["pmdec"] * dt / 3.6e6

    def unit(r, d):
        r, d = np.radians(r), np.radians(d)
        return np.column_stack([np.cos(d) * np.cos(r), np.cos(d) * np.sin(r), np.sin(d)])

    tree = cKDTree(unit(gaia["ra"], gaia["dec"]))
    chord = 2 * np.sin(np.radians(match_radius_arcsec / 3600.0) / 2)
    dist, _ = tree.query(unit(ra, dec), k=1, distance_upper_bound=chord)
    return ~np.isfinite(dist)


def read_population(path) -> dict:
    """A mock population table (Teff, log g, [Fe/H], SDSS g r i), any format astropy reads.

    Parameters
    ----------
    path : str or pathlib.Path
        The population table's file.
    """
    from astropy.table import Table

    try:
        t = Table.read(str(path), format=_format(path))
    except Exception as exc:
        raise InputError(f"{path}: cannot read the mock population ({type(exc).__name__}: {exc})") from exc
    cols = {c.lower(): c for c in t.colnames}
    need = {
        "teff": ("teff",),
        "logg": ("logg",),
        "feh": ("feh", "[fe/h]", "m_h"),
        "sdss_g": ("sdss_g", "g"),
        "sdss_r": ("sdss_r", "r"),
        "sdss_i": ("sdss_i", "i"),
    }
    out = {}
    for key, names in need.items():
        found = next((cols[n] for n in names if n in cols), None)
        if found is None:
            raise InputError(
                f"{path}: mock population lacks a {key} column (accepted names: {', '.join(names)})"
            )
        out[key] = np.asarray(t[found], float)
    good = np.all([np.isfinite(v) for v in out.values()], axis=0)
    if not good.any():
        raise InputError(
            f"{path}: mock population has no row with all of teff, logg, feh, sdss_g, sdss_r, sdss_i"
        )
    return {k: v[good] for k, v in out.items()}


def _format(path) -> str | None:
    s = str(path).lower()
    for ext, fmt in (
        (".parquet", "parquet"),
        (".fits", "fits"),
        (".ecsv", "ascii.ecsv"),
        (".csv", "ascii.csv"),
    ):
        if s.endswith(ext):
            return fmt
    return None


def build_catalog(
    stars: dict,
    photometry: TemplatePhotometry,
    population: dict | None = None,
    parallax_snr_min: float | None = 5.0,
) -> dict:
    """CSST-band catalog columns for ``stars`` (the ingest's column layout, plus ``source`` and
    optionally ``flags``, ``hip_v_mag``, ``hip_v_i_mag``, ``parallax`` and ``parallax_error``
    (mas) for Hipparcos rows).

    ``parallax_snr_min``: stars whose parallax is at least this many times its error take their
    luminosity class from M_V (:func:`straylight.catalog.luminosity.choose_templates`); None:
    colour alone.  Returns a dict of columns.

    Parameters
    ----------
    stars : dict of str to ndarray
        The stars' columns in the ingest's layout (positions in deg, magnitudes in Vega mag).
    photometry : TemplatePhotometry
        The templates' colours and band magnitudes (the library and the instrument's bands).
    population : dict of str to ndarray, optional
        A mock population (Teff in K, log g in dex cgs, [Fe/H] in dex, SDSS g r i in AB mag) whose
        nearest colours give the templates' stellar parameters.
    parallax_snr_min : float or None, optional
        Parallax over its error above which a star's luminosity class comes from M_V; None: colour
        alone.
    """
    tp, lib = photometry, photometry.library
    n = len(stars["ra"])
    idx, by_lum, (g, bp, rp), flags = _template_choice(stars, tp, parallax_snr_min)
    bp_rp = bp - rp
    lo, hi = tp.bp_rp.min(), tp.bp_rp.max()
    flags[(bp_rp < lo - 0.05) | (bp_rp > hi + 0.05)] |= FLAG_COLOUR_BEYOND_TEMPLATES
    sdss = sdss_from_gaia(g, bp_rp)
    for b, bit in FLAG_SDSS.items():
        flags[~sdss[f"sdss_{b}_valid"]] |= bit
    teff, logg, feh = lib.teff_k[idx], lib.logg_cgs[idx], lib.feh_dex[idx]
    if population is not None and n:
        teff, logg, feh, idx = _population_match(population, lib, sdss, idx, by_lum)
    flags[~np.isfinite(teff)] |= FLAG_TEFF_UNKNOWN
    flags[by_lum] |= FLAG_CLASS_FROM_PARALLAX

    out = {c: np.asarray(stars[c]) for c in ("source_id", "ra", "dec", "pmra", "pmdec", "ref_epoch")}
    out.update(
        {
            "phot_g_mean_mag": g,
            "phot_bp_mean_mag": bp,
            "phot_rp_mean_mag": rp,
            "sdss_g": sdss["sdss_g"],
            "sdss_r": sdss["sdss_r"],
            "sdss_i": sdss["sdss_i"],
            "teff": teff,
            "logg": logg,
            "feh": feh,
            "template": lib.template[idx].astype(object),
            "template_bp_rp_residual": tp.bp_rp[idx] - bp_rp,
        }
    )
    for name, m in tp.band_minus_g.items():
        out[f"mag_{name}"] = g + m[idx]
    out["flags"] = flags
    out["source"] = np.asarray(stars.get("source", np.full(n, "gaia_dr2", dtype=object)), dtype=object)
    return out


def _template_choice(stars: dict, tp: TemplatePhotometry, parallax_snr_min: float | None):
    """Each star's template index, whether its luminosity class came from M_V (bool), its G,
    BP, RP (Vega mag) and its flags: the template nearest in BP - RP; Hipparcos stars outside
    the V - I relations by nearest V - Ic, their G, BP, RP then from the template's colours;
    the class from M_V where the parallax is measured."""
    lib = tp.library
    n = len(stars["ra"])
    g = np.asarray(stars["phot_g_mean_mag"], float).copy()
    bp = np.asarray(stars["phot_bp_mean_mag"], float).copy()
    rp = np.asarray(stars["phot_rp_mean_mag"], float).copy()
    flags = np.asarray(stars.get("flags", np.zeros(n, np.int32)), np.int32).copy()
    nan = np.full(n, np.nan)
    abs_v = (
        absolute_v_mag(
            stars.get("hip_v_mag", nan),
            stars.get("parallax", nan),
            stars.get("parallax_error", nan),
            parallax_snr_min,
        )
        if parallax_snr_min is not None
        else nan
    )
    redo = (flags & FLAG_VI_RELATION_EXTRAPOLATED).astype(bool) & np.isfinite(stars.get("hip_v_i_mag", nan))
    idx, by_lum = choose_templates(tp.bp_rp, lib.luminosity_class, tp.abs_v, bp - rp, abs_v)
    if redo.any():
        j, by_lum[redo] = choose_templates(
            tp.v_i, lib.luminosity_class, tp.abs_v, np.asarray(stars["hip_v_i_mag"], float)[redo], abs_v[redo]
        )
        idx[redo] = j
        g[redo] = np.asarray(stars["hip_v_mag"], float)[redo] - tp.v_minus_g[j]
        bp[redo] = g[redo] + tp.bp_minus_g[j]
        rp[redo] = g[redo] + tp.rp_minus_g[j]
    return idx, by_lum, (g, bp, rp), flags


def _population_match(population: dict, lib: TemplateLibrary, sdss: dict, idx, by_lum):
    """Each star's (Teff K, log g dex, [Fe/H] dex, template index) from a mock population: the
    parameters of the mock star nearest in (g - r, r - i), and when the library has parameters
    the template nearest them (whose class then does not come from M_V: ``by_lum`` cleared in
    place); else the templates ``idx`` stay."""
    pop_tree = cKDTree(
        np.column_stack(
            [population["sdss_g"] - population["sdss_r"], population["sdss_r"] - population["sdss_i"]]
        )
    )
    _, k = pop_tree.query(
        np.column_stack([sdss["sdss_g"] - sdss["sdss_r"], sdss["sdss_r"] - sdss["sdss_i"]]), k=1
    )
    teff, logg, feh = population["teff"][k], population["logg"][k], population["feh"][k]
    has_params = np.isfinite(lib.teff_k)
    if has_params.all() and not np.all(np.isnan(lib.logg_cgs)):
        p_tree = cKDTree(np.column_stack([lib.teff_k / 100.0, lib.logg_cgs, lib.feh_dex]))
        _, idx = p_tree.query(np.column_stack([teff / 100.0, logg, feh]), k=1)
        idx = np.asarray(idx, int)
        by_lum[:] = False  # the mock population's parameters chose the template
    return teff, logg, feh, idx


def round_trip(catalog: dict, photometry: TemplatePhotometry) -> dict:
    """Template synthetic BP - RP against the input (mag): per-star differences and summary.

    (G needs no check: every template is scaled to the star's G, so it holds by construction.)

    Parameters
    ----------
    catalog : dict of str to ndarray
        Catalog columns (:func:`build_catalog`).
    photometry : TemplatePhotometry
        The templates' colours the catalog was built with.
    """
    idx = _template_index(catalog["template"], photometry.library.template)
    d_bp_rp = photometry.bp_rp[idx] - (catalog["phot_bp_mean_mag"] - catalog["phot_rp_mean_mag"])
    a = np.abs(d_bp_rp)
    return {
        "d_bp_rp": d_bp_rp,
        "median_abs_bp_rp_mag": float(np.median(a)) if a.size else float("nan"),
        "p90_abs_bp_rp_mag": float(np.percentile(a, 90)) if a.size else float("nan"),
        "p99_abs_bp_rp_mag": float(np.percentile(a, 99)) if a.size else float("nan"),
    }


def _template_index(names, library_names) -> np.ndarray:
    lookup = {n: i for i, n in enumerate(library_names)}
    return np.array([lookup[n] for n in names], int)


def _concat(parts: list[dict], keys) -> dict:
    out = {}
    for k in keys:
        vals = [np.asarray(p[k]) if k in p else np.full(len(p["ra"]), np.nan) for p in parts]
        out[k] = np.concatenate(vals) if vals else np.zeros(0)
    return out


@dataclass(frozen=True)
class CatalogOptions:
    """How :func:`make_catalog` assembles the catalog (the campaign's ``stars`` settings).

    Attributes
    ----------
    g_limit_mag : float
        Faintest G of the Hipparcos stars kept, Vega mag (Gaia's are cut when ingested).
    hipparcos : {"fill", "all", "none"}
        Hipparcos stars where Gaia has none within ``match_radius_arcsec`` (``"fill"``),
        Hipparcos alone (``"all"``) or none.
    match_radius_arcsec : float
        Gaia-Hipparcos match radius, arcsec.
    template_classes : sequence of str or None
        Luminosity classes of the templates used (empty or None: the whole library).
    parallax_snr_min : float or None
        Parallax over its error above which a star's luminosity class comes from M_V
        (:func:`build_catalog`); None: colour alone.
    """

    g_limit_mag: float = 12.0
    hipparcos: str = "fill"
    match_radius_arcsec: float = 2.0
    template_classes: tuple | None = ALL_CLASSES
    parallax_snr_min: float | None = 5.0


def make_catalog(
    band_responses: dict,
    gaia_stars: dict | None = None,
    options: CatalogOptions | None = None,
    population: dict | None = None,
    library: TemplateLibrary | None = None,
    hip2_path=None,
) -> tuple[dict, dict]:
    """The full catalog from Gaia stars (ingested columns) and/or Hipparcos; returns (columns, summary).

    Parameters
    ----------
    band_responses : dict of str to speclite.filters.FilterResponse
        Band name -> its response.
    gaia_stars : dict of str to ndarray, optional
        Ingested Gaia columns (:func:`ingest_many`); None: Hipparcos alone.
    options : CatalogOptions, optional
        The G limit, the Hipparcos rule, the match radius, the templates' classes and the
        parallax threshold (default: :class:`CatalogOptions`'s defaults).
    population : dict of str to ndarray, optional
        A mock population (:func:`read_population`).
    library : TemplateLibrary, optional
        The SED templates (default: the Pickles library).
    hip2_path : str or pathlib.Path, optional
        The Hipparcos ``hip2.dat`` (default: the packaged one).
    """
    options = options if options is not None else CatalogOptions()
    library = select_templates(library if library is not None else load_pickles(), options.template_classes)
    tp = TemplatePhotometry(library, band_responses)
    parts, counts = _catalog_parts(tp, gaia_stars, options, population, hip2_path)
    if not parts:
        raise InputError("stars.hipparcos is 'none' and no Gaia file is given: the catalog would be empty")
    columns = _concat(parts, list(parts[0]))
    order = np.argsort(columns["phot_g_mean_mag"], kind="stable")
    columns = {k: v[order] for k, v in columns.items()}
    return columns, _catalog_summary(columns, counts, tp, band_responses)


def _catalog_parts(tp: TemplatePhotometry, gaia_stars, options: CatalogOptions, population, hip2_path):
    """The Gaia stars' catalog columns, then the Hipparcos stars' (those without a Gaia
    counterpart with ``"fill"``, down to the G limit), as the options say; and each part's
    number of stars by source."""
    from straylight.catalog.hipparcos import hipparcos_stars

    parts, counts = [], {}
    if gaia_stars is not None and options.hipparcos != "all":
        g = dict(gaia_stars)
        g.setdefault("source", np.full(len(g["ra"]), "gaia_dr2", dtype=object))
        parts.append(build_catalog(g, tp, population=population))
        counts["gaia_dr2"] = len(g["ra"])
    if options.hipparcos in ("fill", "all") or gaia_stars is None:
        hip = hipparcos_stars(hip2_path)
        if parts:
            fill = cross_match_fill(parts[0], hip, options.match_radius_arcsec)
            hip = {k: v[fill] for k, v in hip.items()}
        cat = build_catalog(hip, tp, population=population, parallax_snr_min=options.parallax_snr_min)
        keep = np.isfinite(cat["phot_g_mean_mag"]) & (cat["phot_g_mean_mag"] <= options.g_limit_mag)
        parts.append({k: v[keep] for k, v in cat.items()})
        counts["hipparcos"] = int(keep.sum())
    return parts, counts


def _catalog_summary(columns: dict, counts: dict, tp: TemplatePhotometry, band_responses: dict) -> dict:
    """The catalog's summary: stars (by source), the template library, the BP - RP round trip
    (mag), each flag's count and the bands."""
    rt = round_trip(columns, tp)
    flags = columns["flags"]
    return {
        "stars": int(len(columns["ra"])),
        "by_source": counts,
        "template_library": tp.library.name,
        "templates": int(len(tp.library)),
        "round_trip_bp_rp_mag": {
            k: rt[k] for k in ("median_abs_bp_rp_mag", "p90_abs_bp_rp_mag", "p99_abs_bp_rp_mag")
        },
        "flag_counts": {str(b): int(((flags & b) != 0).sum()) for b in (1, 2, 4, 8, 16, 32, 64, 128)},
        "bands": sorted(band_responses),
    }
