"""Per-pointing background table for a list of planned pointings and times.

``straylight sky --input pointings.csv --out table.parquet``: each row of the input (columns
``time`` (UTC ISO 8601), ``ra`` and ``dec`` (ICRS deg); ``ra_deg``/``dec_deg``/``utc`` accepted) gets
its geometry, observability, every background component per band in e-/s/pixel, the total in
AB mag/arcsec2 and the 5-sigma point-source limit for the band's survey exposures;
``planet_in_field`` names the brightest Sun, Moon or planet inside the field ("" if none) and
``planet_in_field_v_mag`` its V magnitude: such a body is a point source (imaged like a star),
not part of the background components.  Samples are
evaluated vectorised in batches (same code path as the cube), so thousands of rows take seconds.
A bad row stops the run with the file, row, field and value; nothing is written.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from straylight.errors import InputError
from straylight.model.result import (
    TABLE_VIOLATION_BITS,
    VIOLATIONS_DESCRIPTION,
    violation_mask,
    violation_text,
)

__all__ = [
    "ALIASES",
    "read_pointings",
    "check_radec",
    "pointing_table",
    "pointing_chunks",
    "CHUNK_ROWS",
    "UNITS",
    "column_units",
    "background_table",
    "TableLayout",
    "with_limits",
    "TABLE_VIOLATION_BITS",
    "VIOLATIONS_DESCRIPTION",
    "violation_mask",
    "violation_text",
]


ALIASES = {"time": ("time", "utc", "time_utc"), "ra": ("ra", "ra_deg"), "dec": ("dec", "dec_deg")}


def read_pointings(path) -> dict:
    """Read and check a pointing table (the input of ``straylight sky``).

    Column names are matched case-insensitively, with the aliases in ``ALIASES``; masked RA/Dec
    entries become NaN and are then refused by :func:`check_radec`.

    Parameters
    ----------
    path : str or path-like
        ``.csv``, ``.ecsv``, ``.parquet`` or ``.fits`` table with a UTC time column (``time``,
        ``utc`` or ``time_utc``; ISO 8601 text) and ICRS ``ra``/``ra_deg`` and ``dec``/``dec_deg``
        in deg.

    Returns
    -------
    dict
        ``"time"``: ndarray, shape (n,), the time column's values as read (not yet parsed);
        ``"ra"``: ndarray of float, shape (n,), RA wrapped to [0, 360) deg; ``"dec"``: ndarray of
        float, shape (n,), Dec in deg.

    Raises
    ------
    InputError
        When the file is missing, has an unknown suffix, cannot be read, has no rows or lacks a
        column, or a row's RA/Dec breaks :func:`check_radec`'s rule (the message names the row).
    """
    from astropy.table import Table

    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: pointing table does not exist")
    fmt = {".csv": "ascii.csv", ".ecsv": "ascii.ecsv", ".parquet": "parquet", ".fits": "fits"}.get(
        path.suffix.lower()
    )
    if fmt is None:
        raise InputError(f"{path}: unknown format; expected .csv, .ecsv, .parquet or .fits")
    try:
        from straylight.util.io import without_bom

        t = Table.read(without_bom(path) if fmt.startswith("ascii") else path, format=fmt)
    except Exception as exc:
        raise InputError(f"{path}: cannot read ({type(exc).__name__}: {exc})") from exc
    if len(t) == 0:
        raise InputError(f"{path}: no rows")
    cols = {c.lower(): c for c in t.colnames}
    out = {}
    for key, names in ALIASES.items():
        found = next((cols[n] for n in names if n in cols), None)
        if found is None:
            raise InputError(
                f"{path}: missing column {key!r} (accepted: {', '.join(names)}); "
                f"found {', '.join(t.colnames)}"
            )
        out[key] = np.asarray(np.ma.filled(t[found], np.nan) if key != "time" else t[found])
    out["ra"], out["dec"] = check_radec(out["ra"], out["dec"], lambda i: f"{path}: row {i + 1}: ")
    return out


def check_radec(ra, dec, where=lambda i: "", names=("ra", "dec")) -> tuple[np.ndarray, np.ndarray]:
    """The rule every pointing obeys (table rows and the command line alike): RA and Dec are
    numbers, finite, Dec within [-90, 90] deg, RA within [-360, 360] deg (a wrap is fine, 1e308
    is a mistake).  Returns (RA wrapped to [0, 360), Dec) in deg as float arrays.

    Parameters
    ----------
    ra, dec : array_like, shape (n,) or scalar
        RA and Dec, deg (numbers or text convertible to float).
    where : callable, optional
        ``where(i)`` gives the prefix of the message for element ``i`` (e.g. the file and row);
        default: no prefix.
    names : tuple of str, optional
        The field names used in messages (e.g. ``("--ra", "--dec")``).

    Returns
    -------
    ra : ndarray of float, shape (n,)
        RA wrapped to [0, 360), deg (a scalar input gives shape (1,)).
    dec : ndarray of float, shape (n,)
        Dec, deg.

    Raises
    ------
    InputError
        When a value is not a number, not finite, or out of range; the first bad element is named.
    """
    vals = {}
    for key, name, v in (("ra", names[0], ra), ("dec", names[1], dec)):
        v = np.atleast_1d(np.asarray(v, dtype=object) if not isinstance(v, np.ndarray) else v)
        try:
            arr = v.astype(float)
        except (TypeError, ValueError):
            bad = next(i for i, x in enumerate(v) if not _is_number(x))
            raise InputError(f"{where(bad)}{name} = {str(v[bad])!r} is not a number") from None
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            raise InputError(f"{where(bad[0])}{name} = {arr[bad[0]]} is not finite")
        vals[key] = arr
    bad = np.flatnonzero(np.abs(vals["dec"]) > 90.0)
    if bad.size:
        raise InputError(f"{where(bad[0])}{names[1]} = {vals['dec'][bad[0]]} outside [-90, 90] deg")
    bad = np.flatnonzero(np.abs(vals["ra"]) > 360.0)
    if bad.size:
        raise InputError(f"{where(bad[0])}{names[0]} = {vals['ra'][bad[0]]} outside [-360, 360] deg")
    return vals["ra"] % 360.0, vals["dec"]


def _is_number(v) -> bool:
    try:
        float(v)
        return True
    except (TypeError, ValueError):
        return False


def pointing_table(
    campaign,
    pointings: dict,
    bands=None,
    stars=None,
    batch: int = 8192,
    source="",
    models: dict | None = None,
    model=None,
) -> dict:
    """Columns of the per-pointing background table (see the module docstring); ``models``, if
    given, receives the record of which models ran and their error budget; ``model``: the
    campaign's :class:`~straylight.model.BackgroundModel` when the caller keeps one warm, or a
    function giving it, called once the scene is computed (else one is built for this table).
    The satellite and the bodies are computed once per distinct time, for all of them at once;
    the samples are evaluated ``batch`` at a time (:func:`~straylight.model.pointing.background_at`).

    Parameters
    ----------
    campaign : straylight.config.campaign.Campaign
        Loaded campaign (orbit, instrument, models, survey exposures).
    pointings : dict
        ``"time"``: UTC times, shape (n,), as ISO 8601 text (each parsed and checked against the
        DE405 range here) or an :class:`astropy.time.Time` (already checked); ``"ra"``, ``"dec"``:
        ndarray of float, shape (n,), ICRS deg, already checked (:func:`read_pointings`).
    bands : list of str, optional
        Bands to evaluate; None: every band of the campaign.
    stars : straylight.sources.stars_table.StarTable, optional
        Off-field stars (:func:`straylight.sources.stars_table.load_offfield_stars`); None: stars = 0.
    batch : int, optional
        Samples evaluated per vectorised call (bounds the memory).
    source : str, optional
        Name of the input (e.g. the file) used to prefix error messages.
    models : dict, optional
        If given, updated in place with the record of which models ran and their error budget.
    model : BackgroundModel or callable, optional
        The campaign's warm model, or a function returning it; None: one is built.

    Returns
    -------
    dict of str to ndarray, each shape (n,)
        ``time`` (UTC ISO text, or the given Time), ``ra_deg``, ``dec_deg`` (deg); geometry
        (``observable``, ``violations`` bit mask, ``sun_angle_deg``, ``moon_angle_deg``,
        ``moon_illuminated_fraction``, ``earth_limb_angle_deg``, ``limb_is_bright``,
        ``door_opening_deg``); ``planet_in_field`` (name, "" if none) and
        ``planet_in_field_v_mag`` (Vega V mag, NaN if none); per band ``b``:
        ``<component>_<b>`` for the registry's components and the total
        (:func:`~straylight.model.registry.component_names`) in e-/s/pix,
        ``total_mag_per_arcsec2_<b>`` in AB mag/arcsec2, and (except V) ``limit_mag_<b>``,
        the 5-sigma point-source limit in AB mag.

    Raises
    ------
    InputError
        When a time cannot be parsed (the first bad row is named) or lies outside the DE405
        range.
    """
    t_all, iso = _checked_times(pointings, source)
    tables = _Tables(campaign, list(bands or campaign.bands), stars, model, models)
    return _columns(tables.result(t_all, pointings["ra"], pointings["dec"], batch), iso)


def _checked_times(pointings: dict, source: str):
    """(the pointings' times as a UTC Time, whether they were given as text): text parsed and
    checked against DE405 here, the first bad row named (an astropy Time is taken as checked)."""
    from astropy.time import Time

    from straylight.sky.ephemeris import default_ephemeris
    from straylight.sky.timeutil import parse_utc, utc_to_tdb_jd

    if isinstance(pointings["time"], Time):  # the Python API's times: already parsed (and checked)
        return parse_utc(pointings["time"], f"{source}: time").reshape(-1), False
    iso = [str(v) for v in pointings["time"]]
    try:
        t_all = parse_utc(iso, f"{source}: time")
    except InputError:  # find the first bad row to name it (one parse per row only on failure)
        for i, v in enumerate(iso):
            parse_utc(v, f"{source} row {i + 1}: time")
        raise
    eph = default_ephemeris()
    jd1, jd2 = utc_to_tdb_jd(t_all)
    jd = jd1 + jd2
    out_of_range = np.flatnonzero((jd < eph.jd_start) | (jd > eph.jd_end))
    if out_of_range.size:
        i = int(out_of_range[0])
        raise InputError(
            f"{source} row {i + 1}: time = {iso[i]} is outside the DE405 range ({eph.span}); "
            f"{out_of_range.size} of {len(iso)} rows are out of range"
        )
    return t_all, True


def pointing_chunks(
    campaign, pointings: dict, bands=None, stars=None, chunk_rows: int = 0, source="", models=None, model=None
):
    """:func:`pointing_table`'s columns ``chunk_rows`` rows at a time (0: all at once): a
    generator of (row slice, columns of those rows), so that a caller writing or copying each
    chunk holds one chunk's work at a time.  The times are parsed and checked first, for all
    rows; the model is built (or ``model()`` called) once.  Each chunk's columns equal those
    rows of one :func:`pointing_table` (every step is per sample or per distinct time).

    Parameters
    ----------
    campaign, pointings, bands, stars, source, models, model
        As :func:`pointing_table`.
    chunk_rows : int, optional
        Rows per chunk (0: all at once).

    Yields
    ------
    slice, dict
        The chunk's rows and its columns (:func:`pointing_table`'s).
    """
    t_all, iso = _checked_times(pointings, source)
    tables = _Tables(campaign, list(bands or campaign.bands), stars, model, models)
    for sl, result in tables.chunks(t_all, pointings["ra"], pointings["dec"], chunk_rows):
        yield sl, _columns(result, iso)


def _columns(result, iso: bool) -> dict:
    """:func:`pointing_table`'s columns of a result (``iso``: its times as UTC ISO text; else the
    Time as given)."""
    cols = {"time": np.asarray(result.time.isot, dtype=object) if iso else result.time}
    cols.update(result.columns())
    return cols


def with_limits(result, campaign):
    """The result with each band's 5-sigma point-source limit at its total (every band but V).

    Parameters
    ----------
    result : BackgroundResult
        The background at the samples.
    campaign : straylight.config.campaign.Campaign
        Loaded campaign (the survey exposures, the instrument).

    Returns
    -------
    BackgroundResult
        With ``limits``: band -> AB mag (n,).
    """
    from dataclasses import replace

    from straylight.limits.point_source import point_source_limit

    limits = {b: point_source_limit(result.rates[b]["total"], b, campaign) for b in result.bands if b != "V"}
    return replace(result, limits=limits)


@dataclass
class _Tables:
    """What every chunk of one pointing table shares: the campaign, the bands, the off-field
    stars (None: stars = 0), the model (a :class:`~straylight.model.BackgroundModel`, a function
    giving it, or None: built here; made once, at the first chunk, after its scene) and the dict
    that receives its record (None: not kept)."""

    campaign: object
    bands: list
    stars: object = None
    model: object = None
    models: dict | None = None

    def warm_model(self):
        """The model, made (and its record kept) on the first call."""
        from straylight.model import BackgroundModel

        if self.model is None or callable(self.model):
            self.model = BackgroundModel(self.campaign) if self.model is None else self.model()
            if self.models is not None:
                self.models.update(self.model.models_record())
        return self.model

    def result(self, t, ra_deg, dec_deg, batch: int = 8192):
        """The :class:`~straylight.model.result.BackgroundResult` at UTC times ``t`` (parsed and
        checked, (n,)) and ICRS pointings (deg, (n,)), with their times, pointing and limits:
        one batch of samples (:meth:`~straylight.model.samples.SampleBatch.at_times`, the scene
        once per distinct time) evaluated ``batch`` samples at a time."""
        from straylight.model.pointing import background_result
        from straylight.model.result import BackgroundResult
        from straylight.model.samples import SampleBatch

        # the scene before the model: an orbit that cannot be propagated is refused before any
        # table is read or built
        samples = SampleBatch.at_times(self.campaign.orbit, t, ra_deg, dec_deg)
        model = self.warm_model()
        # the brightest Sun, Moon or planet inside the field: a point source, not in the background
        parts = [
            background_result(model, samples[a : a + batch], self.bands, self.stars, in_field_bands=[])
            for a in range(0, samples.n, batch)
        ]
        return with_limits(BackgroundResult.concatenate(parts), self.campaign).at(t, ra_deg, dec_deg)

    def chunks(self, t, ra_deg, dec_deg, chunk_rows: int):
        """(row slice, :meth:`result` of those rows), ``chunk_rows`` rows at a time (0: all at
        once)."""
        n = len(t)
        step = n if chunk_rows <= 0 else int(chunk_rows)
        for a in range(0, n, max(step, 1)):
            sl = slice(a, min(a + step, n))
            yield sl, self.result(t[sl], ra_deg[sl], dec_deg[sl])


UNITS = {
    "ra_deg": "deg",
    "dec_deg": "deg",
    "sun_angle_deg": "deg",
    "moon_angle_deg": "deg",
    "earth_limb_angle_deg": "deg",
    "door_opening_deg": "deg",
    "planet_in_field_v_mag": "mag(Vega V)",
}


def column_units(cols) -> dict:
    """Units of the pointing table's columns (Parquet field metadata ``unit``).

    Parameters
    ----------
    cols : iterable of str
        Column names of a :func:`pointing_table`.

    Returns
    -------
    dict of str to str
        Column name to unit string (e.g. ``"deg"``, ``"electron / (s pixel)"``,
        ``"mag(AB) arcsec-2"``); unitless columns are absent.
    """
    from straylight.model import registry

    out, components = dict(UNITS), registry.component_names(total=True)
    for k in cols:
        if k.startswith("total_mag_per_arcsec2_"):
            out[k] = "mag(AB) arcsec-2"
        elif k.startswith("limit_mag_"):
            out[k] = "mag(AB)"
        elif k.rsplit("_", 1)[0] in components:
            out[k] = "electron / (s pixel)"
    out["moon_illuminated_fraction"] = "1"
    return out


#: rows of the pointing table evaluated at a time by :func:`background_table` and ``straylight sky
#: --input``: one chunk's work (the scene, the model's scratch, its table) is then a fixed
#: amount beside the result, whatever the number of rows
CHUNK_ROWS = 2**16


@dataclass(frozen=True)
class TableLayout:
    """How :func:`background_table` lays its table out: ``columns``, the columns kept (names of
    the full table's, already checked; None: all, in its order); ``dtype``, of the float
    columns (float64, or float32 for half the memory); ``chunk_rows``, the rows evaluated at a
    time (None: :data:`CHUNK_ROWS`; 0: all at once)."""

    columns: tuple | None = None
    dtype: object = np.float64
    chunk_rows: int | None = None


def background_table(campaign, t, ra_deg, dec_deg, bands, stars=None, model=None, layout=None):
    """:func:`straylight.sky_background`'s table for a loaded campaign and 1-D UTC times ``t`` with ICRS
    ``ra_deg``, ``dec_deg`` (deg) of the same length, already checked; ``stars`` as
    :func:`straylight.sources.stars_table.load_offfield_stars` gives them (None: stars = 0); ``model``:
    the campaign's warm :class:`~straylight.model.BackgroundModel`, if any.  Evaluated
    ``layout.chunk_rows`` rows at a time, each chunk copied into the result, which is allocated
    once.

    Parameters
    ----------
    campaign : straylight.config.campaign.Campaign
        Loaded campaign.
    t : astropy.time.Time, shape (n,)
        UTC times, already parsed and checked (read as they are).
    ra_deg, dec_deg : array_like of float, shape (n,)
        ICRS pointing, deg (RA is wrapped to [0, 360)).
    bands : list of str
        Bands to evaluate (``"V"`` gets no limit column).
    stars : straylight.sources.stars_table.StarTable, optional
        Off-field stars; None: the stars component is 0.
    model : BackgroundModel or callable, optional
        The campaign's warm model, or a function returning it; None: one is built.
    layout : TableLayout, optional
        The columns kept, the float dtype, the rows evaluated at a time (None: every column,
        float64, :data:`CHUNK_ROWS`).

    Returns
    -------
    astropy.table.QTable
        ``n`` rows with the columns and ``meta`` that :func:`straylight.sky_background`
        documents (rates in electron / (s pix), magnitudes in AB mag/arcsec2, angles in deg).
    """
    layout = TableLayout() if layout is None else layout
    models: dict = {}
    ra = np.asarray(ra_deg, float)
    if ra.size and not (np.min(ra) >= 0.0 and np.max(ra) < 360.0):  # else no copy: x % 360 == x there
        ra = ra % 360.0
    chunk_rows = CHUNK_ROWS if layout.chunk_rows is None else layout.chunk_rows
    out, n = None, len(t)
    tables = _Tables(campaign, list(bands), stars, model, models)
    for sl, result in tables.chunks(t, ra, np.asarray(dec_deg, float), chunk_rows):
        part = result.to_table(models)
        del result
        if layout.columns is not None:
            part = part[list(layout.columns)]  # in the order asked for
        if out is None:
            whole = sl.stop == n and np.dtype(layout.dtype) == np.float64
            out = part if whole else _allocated_like(part, t, layout.dtype)
        if out is not part:
            _copy_rows(out, part, sl)
    return out


def _allocated_like(part, t, dtype):
    """A table of ``len(t)`` rows with ``part``'s columns, units, formats, descriptions and meta,
    its float columns of ``dtype``, the others as they are (its ``time`` is ``t``'s already)."""
    import astropy.units as u
    from astropy.table import QTable
    from astropy.time import Time

    n, columns = len(t), {}
    for name in part.colnames:
        col = part[name]
        if isinstance(col, Time):
            columns[name] = Time(t, format="isot", precision=3)
        elif isinstance(col, u.Quantity):
            columns[name] = u.Quantity(np.empty(n, dtype), col.unit, copy=False)
        else:
            columns[name] = np.empty(n, np.asarray(col).dtype)
    out = QTable(columns, copy=False, meta=part.meta)
    for name in part.colnames:
        out[name].info.format = part[name].info.format
        out[name].info.description = part[name].info.description
    return out


def _copy_rows(out, part, sl: slice) -> None:
    """``part``'s rows into ``out[sl]``; a text column widened first when ``part``'s is wider."""
    from astropy.time import Time

    for name in part.colnames:
        col = part[name]
        if isinstance(col, Time):
            continue  # the result's times were set whole
        dest = out[name]
        if dest.dtype.kind == "U" and col.dtype.itemsize > dest.dtype.itemsize:
            out.replace_column(name, np.asarray(dest).astype(col.dtype))
            dest = out[name]
        dest[sl] = col
