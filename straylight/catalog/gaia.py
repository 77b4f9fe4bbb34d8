"""Gaia DR2 bright-star ingest and the DR2 photometric relations.

:func:`ingest_file` reads one Gaia archive file - the bulk ``gaia_source`` CSV or CSV.gz, or an
archive query result as CSV, ECSV, VOTable (.vot, .xml, .vot.gz) or FITS - by column name
(case-insensitive), keeps the stars brighter than a G limit, and splits the rows into clean
stars and a quarantine with one reason per row.  Nothing is dropped silently and nothing is
written half-way (atomic Parquet writes).

:func:`sdss_from_gaia` applies the Gaia DR2 documentation's relations (sect. 5.3.7, Table 5.8;
Evans et al. 2018, A&A 616, A4, Tables A.1-A.2), G - x = c0 + c1 C + c2 C^2 (+ c3 C^3) with
C = BP - RP, and flags stars outside each relation's validity range.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from straylight.errors import InputError
from straylight.util.io import without_bom

__all__ = [
    "REQUIRED",
    "OPTIONAL",
    "G_RANGE",
    "SDSS_RELATIONS",
    "sdss_from_gaia",
    "IngestResult",
    "ingest_file",
    "GAIA_UNITS",
    "parquet_units",
    "write_parquet",
]

REQUIRED = ("source_id", "ra", "dec", "phot_g_mean_mag", "phot_bp_mean_mag", "phot_rp_mean_mag")
OPTIONAL = ("pmra", "pmdec", "ref_epoch", "parallax")
G_RANGE = (-2.0, 23.0)  # brightest star G ~ -1.6 (Sirius in Hipparcos-based G); DR2 limit ~21

# Gaia DR2 documentation sect. 5.3.7, Table 5.8: G - {g, r, i}_SDSS vs (BP - RP), sigma, validity
SDSS_RELATIONS = {
    "g": ((0.13518, -0.46245, -0.25171, 0.021349), 0.16497, (-0.5, 2.0)),
    "r": ((-0.12879, 0.24662, -0.027464, -0.049465), 0.066739, (0.2, 2.7)),
    "i": ((-0.29676, 0.64728, -0.10141), 0.098957, (0.0, 4.5)),
}


def sdss_from_gaia(g_mag, bp_rp) -> dict:
    """SDSS g, r, i (and per-band validity flags and scatter) from G and BP - RP.

    Parameters
    ----------
    g_mag : array_like
        Gaia G, Vega mag.
    bp_rp : array_like
        Gaia BP - RP, mag.
    """
    g_mag, c = np.asarray(g_mag, float), np.asarray(bp_rp, float)
    out = {}
    for band, (coef, sigma, (lo, hi)) in SDSS_RELATIONS.items():
        g_minus = sum(k * c**n for n, k in enumerate(coef))
        out[f"sdss_{band}"] = g_mag - g_minus
        out[f"sdss_{band}_valid"] = (c > lo) & (c < hi)
        out[f"sdss_{band}_sigma"] = sigma
    return out


def _check_gzip(path: Path) -> None:
    """A ``.gz`` file must be a complete gzip stream: a partial download or a renamed plain file
    is refused here rather than read as garbage or as a different file than the name says."""
    import gzip
    import zlib

    with open(path, "rb") as fh:
        magic = fh.read(2)
    if magic != b"\x1f\x8b":
        raise InputError(
            f"{path}: not gzip data (starts with {magic!r}, gzip starts with b'\\x1f\\x8b'); "
            "re-download it or drop the .gz suffix"
        )
    try:
        with gzip.open(path, "rb") as fh:
            while fh.read(1 << 24):
                pass
    except (EOFError, OSError, zlib.error) as exc:
        raise InputError(f"{path}: truncated or corrupt gzip stream ({exc}); re-download it") from exc


def _read_table(path: Path):
    from astropy.table import Table

    name = path.name.lower()
    if name.endswith(".gz"):
        _check_gzip(path)
    try:
        if name.endswith((".vot", ".xml", ".vot.gz", ".xml.gz")):
            return Table.read(path, format="votable")
        if name.endswith((".fits", ".fits.gz", ".fit")):
            return Table.read(path, format="fits")
        if name.endswith((".ecsv", ".ecsv.gz")):
            return Table.read(without_bom(path), format="ascii.ecsv")
        if name.endswith((".csv", ".csv.gz")):
            return Table.read(without_bom(path), format="ascii.csv", fill_values=[("", "0"), ("null", "0")])
    except (EOFError, OSError) as exc:  # gzip: truncated stream or not gzip at all
        raise InputError(f"{path}: cannot read ({exc}); is the file truncated or not really gzip?") from exc
    except Exception as exc:
        raise InputError(f"{path}: cannot read as a Gaia table ({type(exc).__name__}: {exc})") from exc
    raise InputError(f"{path}: unknown format; expected .csv, .csv.gz, .ecsv, .vot(.gz), .xml or .fits")


@dataclass
class IngestResult:
    """One Gaia file read: the clean stars (column -> array, G <= the limit), the quarantined rows
    (column -> array, with a ``reason`` column) and a summary of the counts."""

    stars: dict  # column -> array (clean rows brighter than the limit)
    quarantine: dict  # column -> array, with a 'reason' column
    summary: dict = field(default_factory=dict)


def ingest_file(path: str | Path, g_limit: float) -> IngestResult:
    """Read one Gaia file; keep G <= g_limit; quarantine bad rows with reasons.

    Parameters
    ----------
    path : str or pathlib.Path
        The Gaia file (CSV, ECSV, FITS, Parquet).
    g_limit : float
        Faintest G kept, Vega mag.
    """
    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: Gaia input file does not exist")
    if path.stat().st_size == 0:
        raise InputError(f"{path}: file is empty")
    t = _read_table(path)
    cols = {c.lower(): c for c in t.colnames}
    missing = [c for c in REQUIRED if c not in cols]
    if missing:
        raise InputError(
            f"{path}: missing column(s) {', '.join(missing)}; found {', '.join(t.colnames[:12])}..."
        )
    n = len(t)

    def col(name, dtype=float):
        c = t[cols[name]]
        mask = np.ma.getmaskarray(c) if hasattr(c, "mask") else np.zeros(n, bool)
        try:
            vals = np.asarray(np.ma.filled(c, np.nan if dtype is float else 0), dtype=dtype)
        except (TypeError, ValueError) as exc:
            raise InputError(f"{path}: column {cols[name]} is not numeric ({exc})") from exc
        if dtype is float:
            vals = np.where(mask, np.nan, vals)
        return vals, mask

    data, masks = {}, {}
    for c in REQUIRED + tuple(o for o in OPTIONAL if o in cols):
        data[c], masks[c] = col(c, np.int64 if c == "source_id" else float)
    reason = np.full(n, "", dtype=object)

    def flag(cond, text):
        sel = cond & (reason == "")
        reason[sel] = text

    flag(masks["source_id"], "missing source_id")
    for c in ("ra", "dec", "phot_g_mean_mag", "phot_bp_mean_mag", "phot_rp_mean_mag"):
        flag(~np.isfinite(data[c]), f"missing or NaN {c}")
    flag((data["ra"] < 0) | (data["ra"] >= 360), "ra outside [0, 360)")
    flag(np.abs(data["dec"]) > 90, "dec outside [-90, 90]")
    for c in ("phot_g_mean_mag", "phot_bp_mean_mag", "phot_rp_mean_mag"):
        flag((data[c] < G_RANGE[0]) | (data[c] > G_RANGE[1]), f"{c} outside {G_RANGE}")
    _, first = np.unique(data["source_id"], return_index=True)
    dup = np.ones(n, bool)
    dup[first] = False
    flag(dup, "duplicate source_id")

    ok = reason == ""
    bright = ok & (data["phot_g_mean_mag"] <= g_limit)
    stars = {k: v[bright] for k, v in data.items()}
    for o in ("pmra", "pmdec"):
        if o not in stars:
            stars[o] = np.zeros(bright.sum())
    if "ref_epoch" not in stars:
        stars["ref_epoch"] = np.full(bright.sum(), 2015.5)  # DR2 reference epoch J2015.5
    stars["pmra"] = np.nan_to_num(stars["pmra"])
    stars["pmdec"] = np.nan_to_num(stars["pmdec"])
    quarantine = {k: v[~ok] for k, v in data.items()}
    quarantine["reason"] = reason[~ok].astype(str)
    quarantine["file"] = np.full((~ok).sum(), str(path))
    reasons, counts = np.unique(reason[~ok].astype(str), return_counts=True)
    summary = {
        "file": str(path),
        "rows": int(n),
        "kept": int(bright.sum()),
        "fainter_than_limit": int((ok & ~bright).sum()),
        "quarantined": int((~ok).sum()),
        "quarantine_reasons": dict(zip(reasons.tolist(), counts.tolist())),
    }
    return IngestResult(stars, quarantine, summary)


#: units of the Gaia archive's columns (Gaia DR2 data model), written as Parquet field metadata
GAIA_UNITS = {
    "ra": "deg",
    "dec": "deg",
    "pmra": "mas/yr",
    "pmdec": "mas/yr",
    "parallax": "mas",
    "ref_epoch": "yr",
    "phot_g_mean_mag": "mag",
    "phot_bp_mean_mag": "mag",
    "phot_rp_mean_mag": "mag",
}


def parquet_units(names, units: dict | None = None) -> dict:
    """Each column's unit: ``units`` first, then the Gaia names, then a ``_deg`` suffix (deg) and
    a ``mag_`` prefix (AB mag); columns without one (flags, ids, strings) get none.

    Parameters
    ----------
    names : iterable of str
        Column names.
    units : dict of str to str, optional
        Units given by the caller, column -> unit string; they win.
    """
    out = {}
    for k in names:
        u = (units or {}).get(k) or GAIA_UNITS.get(k)
        if u is None and k.endswith("_deg"):
            u = "deg"
        if u is None and k.startswith("mag_"):
            u = "mag(AB)"
        if u:
            out[k] = u
    return out


def write_parquet(columns, path, metadata: dict | None = None, units=None) -> None:
    """Atomic Parquet write with optional key/value metadata; each column's unit (see
    :func:`parquet_units`) goes in its field metadata under ``unit``.  ``columns``: a dict of
    columns, or an iterable of such dicts (chunks of rows, each written as it comes, so only one
    is held); ``metadata`` and ``units`` (a dict, or a function of the column names giving one)
    are read when the first chunk has come.

    Parameters
    ----------
    columns : dict of str to ndarray or iterable of dict
        The columns, or chunks of rows each a dict of columns.
    path : str or pathlib.Path
        The Parquet file.
    metadata : dict, optional
        Key/value metadata of the file (values JSON-encoded).
    units : dict of str to str or callable, optional
        Column units (see :func:`parquet_units`), or a function of the column names giving them.
    """
    import json

    import pyarrow as pa
    import pyarrow.parquet as pq

    from straylight.util.io import atomic_path

    chunks = [columns] if isinstance(columns, dict) else columns
    with atomic_path(path) as tmp:
        writer = schema = None
        try:
            for cols in chunks:
                table = pa.table({k: np.asarray(v) for k, v in cols.items()})
                if schema is None:
                    col_units = parquet_units(cols, units(list(cols)) if callable(units) else units)
                    schema = pa.schema(
                        [
                            f.with_metadata({"unit": col_units[f.name]}) if f.name in col_units else f
                            for f in table.schema
                        ]
                    )
                    if metadata:
                        schema = schema.with_metadata({k: json.dumps(v) for k, v in metadata.items()})
                    writer = pq.ParquetWriter(tmp, schema)
                writer.write_table(table.cast(schema))
        finally:
            if writer is not None:
                writer.close()
