"""Reading a star table (the catalog's ``stars_csst.parquet`` or any Parquet, FITS, CSV or ECSV
table with ``ra``, ``dec`` (ICRS deg) and ``mag_<band>`` (AB) columns)."""

from __future__ import annotations

import numpy as np

from straylight.errors import InputError

__all__ = ["read_star_columns", "read_star_table"]


def read_star_columns(path, bands) -> tuple[np.ndarray, np.ndarray, dict]:
    """Read ra, dec and mag_<band> for every band in one pass (Parquet, FITS, CSV, ECSV);
    returns (ra_deg, dec_deg, {band: mag}); clear errors otherwise."""
    from pathlib import Path

    p = Path(path)
    if not p.exists():
        raise InputError(f"{p}: star catalog does not exist")
    try:
        if p.suffix.lower() == ".parquet":
            import pyarrow.parquet as pq

            t = pq.ParquetFile(p).read()  # one file: without read_table's dataset layer (and pandas)
            names = t.column_names
        else:
            from astropy.table import Table

            t = Table.read(p)
            names = t.colnames
    except Exception as exc:
        raise InputError(f"{p}: cannot read star catalog ({exc})") from exc
    cols = {c.lower(): c for c in names}
    need = ["ra", "dec"] + [f"mag_{b.lower()}" for b in bands]
    missing = [c for c in need if c not in cols]
    if missing:
        raise InputError(f"{p}: missing column(s) {', '.join(missing)}; have {', '.join(cols.values())}")

    def get(c):
        col = t[cols[c]]
        return np.asarray(col.to_numpy() if hasattr(col, "to_numpy") else col, dtype=float)

    ra, dec = get("ra"), get("dec")
    for name, v, lo, hi in (("ra", ra, -360.0, 360.0), ("dec", dec, -90.0, 90.0)):
        bad = np.flatnonzero(~np.isfinite(v) | (v < lo) | (v > hi))
        if bad.size:
            raise InputError(
                f"{p}: row {bad[0]}: {cols[name]} = {v[bad[0]]} must be finite and within "
                f"[{lo:g}, {hi:g}] deg"
            )
    return ra % 360.0, dec, {b: get(f"mag_{b.lower()}") for b in bands}


def read_star_table(path, band: str):
    """Read ra, dec and mag_<band> columns (Parquet, FITS, CSV, ECSV); clear errors otherwise."""
    ra, dec, mags = read_star_columns(path, [band])
    return ra, dec, mags[band]
