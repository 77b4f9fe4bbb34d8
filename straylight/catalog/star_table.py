"""Reading a star table (the catalog's ``stars_csst.parquet`` or any Parquet, FITS, CSV or ECSV
table with ``ra``, ``dec`` (ICRS deg) and ``mag_<band>`` (AB) columns), optionally with the
positions carried to an epoch by the stars' proper motions (``pmra``, ``pmdec``, ``ref_epoch``)."""

from __future__ import annotations

import numpy as np

from straylight.errors import InputError

__all__ = ["propagate_positions", "read_star_columns", "read_star_table"]

#: milliarcseconds per radian
MAS_PER_RAD = 180.0 / np.pi * 3.6e6


def propagate_positions(ra_deg, dec_deg, pmra_mas_yr, pmdec_mas_yr, ref_epoch_yr, epoch_yr):
    """Star positions at ``epoch_yr`` from their positions and proper motions at ``ref_epoch_yr``.

    The star moves uniformly in space with no radial velocity (Hipparcos and most of Gaia DR2
    give none): its direction at t is p0 + (t - t0) (pmra e_ra + pmdec e_dec), normalised (ESA
    1997, The Hipparcos Catalogue, SP-1200 vol. 1, sect. 1.5.5, with v_r = 0; ERFA's pmsafe,
    which astropy's SkyCoord.apply_space_motion calls, reduces to it).  Written out rather than
    through SkyCoord: one numpy pass over the whole catalog, and no distance needed (stars with
    a zero, negative or missing parallax move too).  Annual parallax is not applied: it moves
    the nearest stars by up to 0.38 arcsec (Sirius, 379 mas) and all but a few dozen Hipparcos
    stars by < 0.1 arcsec, against stray-light halos thousands of pixels wide.

    Parameters
    ----------
    ra_deg, dec_deg : array_like, shape (n,)
        ICRS positions at ``ref_epoch_yr``, deg.
    pmra_mas_yr, pmdec_mas_yr : array_like, shape (n,)
        Proper motions, mas/yr (pmra is mu_alpha* = mu_alpha cos dec); NaN: no motion.
    ref_epoch_yr : array_like, shape (n,) or scalar
        The positions' epochs, Julian years (TT), e.g. 1991.25 (Hipparcos), 2015.5 (Gaia DR2);
        NaN: the position is kept.
    epoch_yr : float
        The target epoch, Julian years (TT) (``astropy.time.Time.jyear``).

    Returns
    -------
    ra_deg, dec_deg : ndarray, shape (n,)
        ICRS positions at ``epoch_yr``, deg (RA in [0, 360)).
    """
    ra, dec = np.radians(np.asarray(ra_deg, float)), np.radians(np.asarray(dec_deg, float))
    dt = float(epoch_yr) - np.asarray(ref_epoch_yr, float)
    mu_a = np.nan_to_num(np.asarray(pmra_mas_yr, float)) / MAS_PER_RAD
    mu_d = np.nan_to_num(np.asarray(pmdec_mas_yr, float)) / MAS_PER_RAD
    dt = np.where(np.isfinite(dt), dt, 0.0)
    sa, ca, sd, cd = np.sin(ra), np.cos(ra), np.sin(dec), np.cos(dec)
    x = cd * ca + dt * (-mu_a * sa - mu_d * sd * ca)
    y = cd * sa + dt * (mu_a * ca - mu_d * sd * sa)
    z = sd + dt * mu_d * cd
    return np.degrees(np.arctan2(y, x)) % 360.0, np.degrees(np.arctan2(z, np.hypot(x, y)))


def read_star_columns(path, bands, epoch=None) -> tuple[np.ndarray, np.ndarray, dict]:
    """Read ra, dec and mag_<band> for every band in one pass (Parquet, FITS, CSV, ECSV).

    Parameters
    ----------
    path : str or path-like
        The star table.
    bands : sequence of str
        The bands whose ``mag_<band>`` columns are read.
    epoch : astropy.time.Time, optional
        Carry the positions to this time by the stars' proper motions
        (:func:`propagate_positions`) when the table has ``pmra``, ``pmdec`` (mas/yr) and
        ``ref_epoch`` (Julian year); a table without them keeps its positions.  None: the
        positions as stored.  The images take the observation's time; the off-field sources
        (:mod:`straylight.sources.stars_table`) keep the catalog's epoch: decades of proper
        motion move a star by at most ~1 arcmin (Barnard's star, 10 arcsec/yr; Sirius 46 arcsec
        from J1991.25 to 2026), against a PST that changes over degrees.

    Returns
    -------
    ra_deg, dec_deg : ndarray, shape (n,)
        ICRS, deg (RA in [0, 360)).
    mags : dict
        band -> ndarray, shape (n,), AB mag.

    Raises
    ------
    InputError
        A missing file or column, or a position out of range.
    """
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

            from straylight.util.io import without_bom

            text_format = {".csv": "ascii.csv", ".ecsv": "ascii.ecsv"}.get(p.suffix.lower())
            t = Table.read(without_bom(p), format=text_format) if text_format else Table.read(p)
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
    mags = {b: get(f"mag_{b.lower()}") for b in bands}
    if epoch is not None and all(c in cols for c in ("pmra", "pmdec", "ref_epoch")):
        from astropy.time import Time

        ra, dec = propagate_positions(
            ra, dec, get("pmra"), get("pmdec"), get("ref_epoch"), float(Time(epoch).tt.jyear)
        )
        return ra, dec, mags
    return ra % 360.0, dec, mags


def read_star_table(path, band: str, epoch=None):
    """Read ra, dec (deg, ICRS) and mag_<band> (AB) columns (Parquet, FITS, CSV, ECSV), the
    positions carried to ``epoch`` (astropy Time) by proper motion when given
    (:func:`read_star_columns`); clear errors otherwise.

    Parameters
    ----------
    path : str or pathlib.Path
        The star table (Parquet, FITS, CSV, ECSV).
    band : str
        The band whose ``mag_<band>`` column is read (AB mag).
    epoch : astropy.time.Time, optional
        The epoch the positions are carried to by proper motion.
    """
    ra, dec, mags = read_star_columns(path, [band], epoch=epoch)
    return ra, dec, mags[band]
