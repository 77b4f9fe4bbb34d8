"""The DE405 ephemeris's span as calendar dates, from the package's own bounds."""

import datetime

import pytest
from astropy.time import Time

from straylight.errors import EphemerisRangeError
from straylight.sky.ephemeris import check_in_ephemeris, default_ephemeris


def test_span_labels_are_the_package_bounds():
    """The de405 package's constants jalpha = 2305424.5 and jomega = 2525008.5 (TDB Julian dates;
    Standish 1998, JPL IOM 312.F-98-048) are 1599-12-09 and 2201-02-20 at 0h, the dates of the
    DE405 header: counted here in days from JD 2451544.5 = 2000-01-01 0h in Python's proleptic
    Gregorian calendar, and through astropy's Time.  The labels were 1600-12-21 and 2200-02-02
    before (both wrong)."""
    eph = default_ephemeris()
    assert (eph.jd_start, eph.jd_end) == (2305424.5, 2525008.5)
    j2000_day = datetime.date(2000, 1, 1)
    start = j2000_day + datetime.timedelta(days=eph.jd_start - 2451544.5)
    end = j2000_day + datetime.timedelta(days=eph.jd_end - 2451544.5)
    assert (start.isoformat(), end.isoformat()) == ("1599-12-09", "2201-02-20")
    assert Time(2525008.5, format="jd", scale="tdb").iso == "2201-02-20 00:00:00.000"
    assert Time(2305424.5, format="jd", scale="tdb").iso == "1599-12-09 00:00:00.000"
    assert eph.span == "1599-12-09 to 2201-02-20"
    from straylight.sky.ephemeris import DE405_SPAN

    assert DE405_SPAN == eph.span


def test_range_check_accepts_2201_and_names_the_true_end():
    """A time in January 2201 is inside DE405 (it was refused by no check, but labelled outside);
    a time after 2201-02-20 is refused with the true end in the message."""
    check_in_ephemeris(Time("2201-01-15T00:00:00", scale="utc"), "--time")
    with pytest.raises(EphemerisRangeError, match=r"\(1599-12-09 to 2201-02-20\)"):
        check_in_ephemeris(Time("2201-03-01T00:00:00", scale="utc"), "--time")
