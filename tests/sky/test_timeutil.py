"""Time scales: UTC -> TDB against astropy's full conversion, and no network access."""

import numpy as np
import pytest
from astropy.time import Time

from straylight.errors import InputError
from straylight.sky.timeutil import DTDB_DIRECT_MAX, parse_utc, utc_to_tdb_jd


@pytest.mark.parametrize("n", [10, DTDB_DIRECT_MAX + 1, 50_000])
def test_tdb_matches_astropy_full_series(n):
    """Direct series (small arrays) and spline (large arrays) equal astropy's .tdb within 1 ns,
    over 1950-2100 at random times."""
    jd = 2433282.5 + np.sort(np.random.default_rng(n).uniform(0, 150 * 365.25, n))
    jd1, jd2 = utc_to_tdb_jd(Time(jd, format="jd", scale="utc"))
    pick = np.linspace(0, n - 1, min(n, 2000)).astype(int)  # astropy's reference is slow
    ref = Time(jd[pick], format="jd", scale="utc").tdb
    diff_s = ((jd1[pick] - ref.jd1) + (jd2[pick] - ref.jd2)) * 86400.0
    assert np.abs(diff_s).max() < 1e-9


def test_interpolated_path_on_a_dense_grid():
    """A one-year, 1e5-sample grid takes the spline path; check 500 samples against astropy."""
    jd = 2461041.5 + np.linspace(0, 365.25, 100_000)
    jd1, jd2 = utc_to_tdb_jd(Time(jd, format="jd", scale="utc"))
    pick = np.arange(0, jd.size, 200)
    ref = Time(jd[pick], format="jd", scale="utc").tdb
    diff_s = ((jd1[pick] - ref.jd1) + (jd2[pick] - ref.jd2)) * 86400.0
    assert np.abs(diff_s).max() < 1e-9


def test_parse_errors_are_clear():
    with pytest.raises(InputError, match="cannot parse"):
        parse_utc("2026-13-45T00:00:00", "--time")
    with pytest.raises(InputError, match="finite"):
        parse_utc(np.array([np.nan]), "--time")


def test_no_network_access(monkeypatch):
    """Converting far-future times must not try to download IERS tables."""
    import socket

    def refuse(*a, **k):
        raise AssertionError("network access attempted")

    monkeypatch.setattr(socket.socket, "connect", refuse)
    jd1, jd2 = utc_to_tdb_jd(["2026-06-01T00:00:00", "2150-01-01T00:00:00"])
    assert np.all(np.isfinite(jd1 + jd2))


def test_ignore_dubious_years_silences_that_warning_only():
    """ERFA's "dubious year" (UTC of 2200, beyond the leap-second table) is silenced; another
    ERFA warning and a non-ERFA warning with the same words are not."""
    import warnings

    import erfa

    from straylight.sky.timeutil import ignore_dubious_years

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ignore_dubious_years()
        _ = Time("2200-06-01T00:00:00", scale="utc").tai  # ERFA utctai: "dubious year (Note 3)"
        warnings.warn('ERFA function "utctai" yielded 1 of "dubious year (Note 3)"', UserWarning)
        warnings.warn('ERFA function "x" yielded 1 of "something else"', erfa.ErfaWarning)
    assert [(w.category.__name__, str(w.message)) for w in caught] == [
        ("UserWarning", 'ERFA function "utctai" yielded 1 of "dubious year (Note 3)"'),
        ("ErfaWarning", 'ERFA function "x" yielded 1 of "something else"'),
    ]
    with warnings.catch_warnings(record=True) as caught:  # the reference: ERFA does warn there
        warnings.simplefilter("always")
        _ = Time("2200-06-01T00:00:00", scale="utc").tai
    assert 'ERFA function "utctai" yielded 1 of "dubious year (Note 3)"' in [str(w.message) for w in caught]
