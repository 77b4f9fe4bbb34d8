"""Time handling: UTC input, TDB for the ephemeris, never a network access.

astropy normally fetches fresh IERS tables when its bundled ones look stale.  The pipeline must
run on machines without internet, so :func:`configure_offline` turns downloads off and lets
astropy use its bundled tables (``astropy-iers-data``), warning instead of failing where they
do not reach.  The UTC->TT step only needs the leap-second table; TT->TDB is the analytic
series of ERFA (geocentric), so no Earth-orientation data enter the ephemeris path.

Parsing and the UTC->TDB step run without ERFA's "dubious year" warnings
(:func:`quiet_dubious_years`): a time outside the ephemeris is refused by our own one line
(:func:`straylight.sky.ephemeris.check_in_ephemeris`), which the warnings would otherwise
precede.
"""

from __future__ import annotations

import re
import warnings
from contextlib import contextmanager

import numpy as np
from astropy.time import Time, TimeDelta
from astropy.utils import iers

from straylight.errors import ConfigError, InputError

__all__ = [
    "configure_offline",
    "quiet_dubious_years",
    "ignore_dubious_years",
    "parse_utc",
    "DTDB_DIRECT_MAX",
    "DTDB_GRID_STEP_D",
    "tdb_minus_tt_s",
    "utc_to_tdb_jd",
    "campaign_times",
]

_CONFIGURED = False


def configure_offline() -> None:
    """Make astropy work from its bundled IERS and leap-second tables, with no download."""
    global _CONFIGURED
    if _CONFIGURED:
        return
    iers.conf.auto_download = False
    iers.conf.auto_max_age = None
    iers.conf.iers_degraded_accuracy = "warn"
    warnings.filterwarnings("ignore", category=iers.IERSStaleWarning)
    _CONFIGURED = True


# the package's modules that compute with astropy times import this one (the public API calls
# configure_offline before its first conversion)
configure_offline()


#: ERFA's "dubious year" warning: the UTC of a year before 1960 or beyond its leap-second table
#: (ERFA's Notes 3-5 of utctai, taiutc, d2dtf, dat), as erfa.core words it
DUBIOUS_YEAR_MESSAGE = r'ERFA function "\w+" yielded \d+ of "dubious year \(Note \d+\)"'


def ignore_dubious_years() -> None:
    """Silence ERFA's "dubious year" warnings for the rest of the process: for a process whose
    times are a validated campaign's (inside DE405; see :func:`quiet_dubious_years` for why they
    are harmless there), such as the workflow's jobs and their worker processes.  Only that
    category and message: every other warning still shows."""
    import erfa

    warnings.filterwarnings("ignore", message=DUBIOUS_YEAR_MESSAGE, category=erfa.ErfaWarning)


@contextmanager
def quiet_dubious_years():
    """Silence ERFA's "dubious year" warnings inside the block.

    ERFA flags UTC before 1960 (there was no UTC: it takes TAI - UTC = 0) and beyond its
    leap-second table's horizon (it holds the last offset).  Outside DE405 we refuse the time in
    one line of our own; for the survey's years the error is the leap seconds not yet announced
    (seconds: a few km along the orbit), which the background does not resolve.  Not
    thread-safe (warnings.catch_warnings).
    """
    import erfa

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=DUBIOUS_YEAR_MESSAGE, category=erfa.ErfaWarning)
        yield


def parse_utc(times, field: str = "time") -> Time:
    """Parse ISO strings, a :class:`~astropy.time.Time`, or UTC Julian dates into a UTC Time.

    Parameters
    ----------
    times : str, sequence of str, Time, or float array (taken as UTC Julian dates)
    field : name used in error messages (e.g. ``"--time"`` or ``"campaign.start"``).

    Raises
    ------
    InputError
        When the value cannot be parsed as a time or is not finite.
    """
    configure_offline()
    with quiet_dubious_years():
        if isinstance(times, Time):
            return times.utc
        try:
            arr = np.asarray(times)
            if arr.dtype.kind in "fi":
                if not np.all(np.isfinite(arr)):
                    raise InputError(f"{field}: times must be finite, got {times!r}")
                return Time(arr, format="jd", scale="utc")
            return _parse_iso_with_offsets(times)
        except InputError:
            raise
        except Exception as exc:  # astropy raises ValueError with a long message
            raise InputError(
                f"{field}: cannot parse {times!r} as a UTC time "
                "(expected ISO 8601, e.g. 2026-01-01T00:50:00 or 2026-01-01T08:50:00+08:00)"
            ) from exc


_UTC_OFFSET = re.compile(r"(Z|[+-](\d\d):?(\d\d))$", re.IGNORECASE)


def _parse_iso_with_offsets(times) -> Time:
    """ISO 8601 strings, with an optional UTC offset (``Z``, ``+08:00``, ``-0530``), as UTC.

    A time with an offset is local time: UTC = local - offset (ISO 8601-1:2019 sect. 4.3.8).
    Strings without an offset are UTC.
    """
    arr = np.asarray(times)
    flat = [str(v).strip() for v in arr.ravel()] if arr.dtype.kind in "USO" else None
    if flat is None:
        return Time(times, scale="utc")
    base, offset_s = [], np.zeros(len(flat))
    for i, s in enumerate(flat):
        m = _UTC_OFFSET.search(s) if "T" in s or " " in s else None
        if m and not s[: m.start()].endswith(("T", " ")):
            if m.group(1).upper() != "Z":
                hours, minutes = int(m.group(2)), int(m.group(3))
                if hours > 23 or minutes > 59:
                    raise ValueError(f"bad UTC offset in {s!r}")
                sign = -1.0 if m.group(1)[0] == "-" else 1.0
                offset_s[i] = sign * (hours * 3600.0 + minutes * 60.0)
            s = s[: m.start()]
        base.append(s)
    t = Time(base if arr.ndim else base[0], scale="utc")
    if np.any(offset_s):
        import astropy.units as u

        t = Time(
            t - (offset_s.reshape(arr.shape) if arr.ndim else offset_s[0]) * u.s, scale="utc", format="isot"
        )
    return t


#: Above this many times, TDB-TT is interpolated from a grid instead of the full series.
DTDB_DIRECT_MAX = 4096
#: Grid step of the interpolated TDB-TT, days (its shortest geocentric terms have periods of
#: days; the spline error is measured in tests/sky/test_timeutil.py).
DTDB_GRID_STEP_D = 0.25


def tdb_minus_tt_s(tt_jd1: np.ndarray, tt_jd2: np.ndarray) -> np.ndarray:
    """Geocentric TDB - TT in seconds (ERFA dtdb, Fairhead & Bretagnon 1990 series).

    The full series is summed term by term for every time; for more than
    :data:`DTDB_DIRECT_MAX` times it is evaluated on a :data:`DTDB_GRID_STEP_D` grid and
    interpolated with a cubic spline (error < 1 ns, against ~1.7 ms amplitude).

    Parameters
    ----------
    tt_jd1 : ndarray
        TT Julian date, days (first part).
    tt_jd2 : ndarray
        TT Julian date, days (second part).
    """
    import erfa

    jd1 = np.asarray(tt_jd1, dtype=float)
    jd2 = np.asarray(tt_jd2, dtype=float)
    if jd1.size <= DTDB_DIRECT_MAX:
        return erfa.dtdb(jd1, jd2, 0.0, 0.0, 0.0, 0.0)
    from scipy.interpolate import CubicSpline

    ref = float(np.min(jd1))
    x = (jd1 - ref) + jd2
    lo, hi = float(x.min()) - DTDB_GRID_STEP_D, float(x.max()) + DTDB_GRID_STEP_D
    grid = np.arange(lo, hi + DTDB_GRID_STEP_D, DTDB_GRID_STEP_D)
    values = erfa.dtdb(np.full_like(grid, ref), grid, 0.0, 0.0, 0.0, 0.0)
    return CubicSpline(grid, values)(x)


def utc_to_tdb_jd(times, field: str = "time") -> tuple[np.ndarray, np.ndarray]:
    """Return the TDB Julian date as a two-part (jd1, jd2) pair of float64 arrays.

    UTC -> TT by astropy (leap seconds); TT -> TDB by :func:`tdb_minus_tt_s`.  Two parts keep
    sub-microsecond precision over the whole DE405 range.

    Parameters
    ----------
    times : str, sequence of str or astropy.time.Time
        UTC times, any shape.
    field : str, optional
        The input's name in an error message (default ``"time"``).
    """
    with quiet_dubious_years():
        tt = parse_utc(times, field).tt
    jd1 = np.asarray(tt.jd1, dtype=float)
    jd2 = np.asarray(tt.jd2, dtype=float)
    return jd1, jd2 + tdb_minus_tt_s(jd1, jd2) / 86400.0


def campaign_times(start, end, cadence_s: float) -> Time:
    """UTC times start, start + cadence, ... strictly before end.

    Parameters
    ----------
    start : str or astropy.time.Time
        The first time (UTC).
    end : str or astropy.time.Time
        The end (UTC), excluded.
    cadence_s : float
        The step between times, s.
    """
    t0 = parse_utc(start, "campaign.start")
    t1 = parse_utc(end, "campaign.end")
    span_s = float((t1 - t0).to_value("s"))
    if span_s <= 0:
        raise ConfigError(f"campaign.end {t1.isot} must be after campaign.start {t0.isot}")
    n = int(np.ceil(span_s / cadence_s - 1e-9))
    with quiet_dubious_years():
        return t0 + TimeDelta(np.arange(n) * cadence_s, format="sec")
