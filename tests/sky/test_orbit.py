"""Orbit models: circular with J2, and TLE through SGP4.

Reference values: the sgp4 library for TLEs; the analytic J2 nodal rate (Vallado 2013, eq. 9-41)."""

import numpy as np
import pytest
from astropy.time import Time, TimeDelta
from conftest import ISS_L1, ISS_L2

from straylight.errors import ConfigError, InputError
from straylight.sky.orbit import CircularOrbit, EarthModel, TLEOrbit

EARTH = EarthModel(radius_km=6378.137, gm_km3_s2=398600.4418, j2=1.08262668e-3)


def orbit(**kw):
    args = dict(
        altitude_km=400.0,
        inclination_deg=41.5,
        raan_deg=30.0,
        arg_latitude_deg=10.0,
        epoch="2026-01-01T00:00:00",
        earth=EARTH,
    )
    args.update(kw)
    return CircularOrbit(**args)


def test_radius_is_constant():
    o = orbit()
    t = Time("2026-01-01T00:00:00") + TimeDelta(np.linspace(0, 86400, 500), format="sec")
    r = np.linalg.norm(o.position_gcrs_km(t), axis=-1)
    np.testing.assert_allclose(r, 6378.137 + 400.0, rtol=1e-12)


def test_period_matches_kepler_with_j2():
    """Keplerian period 2 pi sqrt(a^3/GM) = 92.56 min at 400 km; J2 shortens the nodal one."""
    o = orbit()
    a = 6378.137 + 400.0
    kepler = 2 * np.pi * np.sqrt(a**3 / 398600.4418)
    assert abs(kepler / 60 - 92.56) < 0.01
    assert 0.995 < o.period_s / kepler < 1.0
    o0 = orbit(earth=EarthModel(6378.137, 398600.4418, 0.0))
    assert o0.period_s == pytest.approx(kepler, rel=1e-12)
    # after one nodal period the satellite is back at the same argument of latitude
    t0 = Time(o.epoch)
    p0 = o.position_gcrs_km(t0)
    p1 = o.position_gcrs_km(t0 + TimeDelta(o.period_s, format="sec"))
    assert abs(p0[2] - p1[2]) < 1e-6  # z depends on u only


def _ascending_node_deg(o, t_start):
    """RA of the ascending node, measured where z(t) crosses zero upwards (brentq)."""
    from scipy.optimize import brentq

    t0 = Time(t_start)
    dt = np.arange(0.0, o.period_s * 1.1, 10.0)
    z = o.position_gcrs_km(t0 + TimeDelta(dt, format="sec"))[:, 2]
    k = np.flatnonzero((z[:-1] < 0) & (z[1:] >= 0))[0]
    f = lambda s: o.position_gcrs_km(t0 + TimeDelta(s, format="sec"))[2]  # noqa: E731
    s_cross = brentq(f, dt[k], dt[k + 1], xtol=1e-9)
    p = o.position_gcrs_km(t0 + TimeDelta(s_cross, format="sec"))
    return np.degrees(np.arctan2(p[1], p[0])), s_cross


def test_nodal_precession_equals_analytic_j2_rate():
    """Node measured at two ascending-node crossings 10 days apart vs -3/2 n J2 (Re/a)^2 cos i.

    At 400 km and 41.5 deg the analytic rate is -6.03 deg/day (Vallado 2013, eq. 9-41;
    the ISS at 51.6 deg has the familiar -5.0 deg/day).
    """
    o = orbit()
    node0, s0 = _ascending_node_deg(o, "2026-01-01T00:00:00")
    node1, s1 = _ascending_node_deg(o, "2026-01-11T00:00:00")
    elapsed_days = (10 * 86400.0 + s1 - s0) / 86400.0
    measured = ((node1 - node0 + 180) % 360 - 180) / elapsed_days
    n = np.sqrt(398600.4418 / (6778.137**3))
    analytic = (
        np.degrees(-1.5 * n * 1.08262668e-3 * (6378.137 / 6778.137) ** 2 * np.cos(np.radians(41.5))) * 86400
    )
    assert measured == pytest.approx(analytic, rel=1e-6)
    assert analytic == pytest.approx(-6.03, abs=0.01)


def test_tle_path_equals_sgp4_directly():
    from sgp4.api import Satrec

    orb = TLEOrbit(ISS_L1, ISS_L2)
    t = Time("2008-09-20T12:25:40") + TimeDelta(np.arange(0, 5400, 600.0), format="sec")
    ours = orb.position_teme_km(t)
    sat = Satrec.twoline2rv(ISS_L1, ISS_L2)
    for i, ti in enumerate(t):
        jd, fr = ti.jd1, ti.jd2
        e, r, _ = sat.sgp4(jd, fr)
        assert e == 0
        np.testing.assert_allclose(ours[i], r, atol=1e-9)
    g = orb.position_gcrs_km(t)
    # TEME -> GCRS is a rotation: lengths preserved, directions within ~0.5 deg (precession since 2000)
    np.testing.assert_allclose(np.linalg.norm(g, axis=-1), np.linalg.norm(ours, axis=-1), rtol=1e-9)
    cosang = np.sum(g * ours, axis=-1) / np.linalg.norm(g, axis=-1) / np.linalg.norm(ours, axis=-1)
    assert np.all(np.degrees(np.arccos(np.clip(cosang, -1, 1))) < 0.5)


def test_bad_tle_checksum_is_clear():
    bad = ISS_L1[:-1] + str((int(ISS_L1[-1]) + 1) % 10)
    with pytest.raises(InputError, match="checksum"):
        TLEOrbit(bad, ISS_L2)


def test_decayed_tle_reports_sgp4_error():
    """Propagating far past epoch with strong drag makes SGP4 report decay (error 6) or similar."""
    # same ISS elements with a huge B* drag term (columns 54-61) -> decays within weeks
    l1 = ISS_L1[:53] + " 50000-0" + ISS_L1[61:68]
    digits = sum(int(c) for c in l1 if c.isdigit()) + l1.count("-")
    l1 = l1 + str(digits % 10)
    orb = TLEOrbit(l1, ISS_L2)
    with pytest.raises(InputError, match="SGP4 error"):
        orb.position_teme_km(Time("2008-09-20T12:25:40") + TimeDelta([0.0, 60 * 86400.0], format="sec"))


@pytest.mark.parametrize(
    "kw,match",
    [
        ({"altitude_km": 50.0}, "altitude_km"),
        ({"inclination_deg": 200.0}, "inclination_deg"),
        ({"epoch": "not a time"}, "epoch"),
    ],
)
def test_bad_circular_elements(kw, match):
    with pytest.raises((ConfigError, InputError), match=match):
        orbit(**kw)


def test_tle_epoch_and_period():
    """The TLE's epoch (2008 day 264.51782528) and its period from the mean motion
    (15.72125391 rev/day: 91.60 min)."""
    orb = TLEOrbit(ISS_L1, ISS_L2)
    expected = Time("2008-01-01T00:00:00", scale="utc") + TimeDelta(263.51782528, format="jd")
    assert abs((orb.epoch_time - expected).to_value("s")) < 1e-3
    assert orb.period_s == pytest.approx(86400.0 / 15.72125391, rel=1e-6)


def test_epoch_gap_warning_text():
    """One line: the epoch, campaign.start, the gap to it and the largest over the campaign; no
    warning within the threshold."""
    from straylight.sky.orbit import TLE_EPOCH_WARN_DAYS, epoch_gap_warning

    epoch = Time("2026-01-01T00:00:00")
    assert (
        epoch_gap_warning(
            "orbit.tle epoch",
            epoch,
            Time("2026-01-10T00:00:00"),
            Time("2026-01-20T00:00:00"),
            TLE_EPOCH_WARN_DAYS,
            "reason",
        )
        is None
    )
    msg = epoch_gap_warning(
        "orbit.tle epoch",
        epoch,
        Time("2026-01-10T00:00:00"),
        Time("2026-03-01T00:00:00"),
        TLE_EPOCH_WARN_DAYS,
        "reason",
    )
    assert msg == (
        "orbit.tle epoch 2026-01-01T00:00:00 is 9 days before campaign.start 2026-01-10T00:00:00 "
        "(up to 59 days over the campaign): reason"
    )
    msg = epoch_gap_warning(
        "orbit.tle epoch",
        Time("2026-06-01T00:00:00"),
        Time("2026-01-01T00:00:00"),
        Time("2026-01-02T00:00:00"),
        TLE_EPOCH_WARN_DAYS,
        "reason",
    )
    assert "151 days after campaign.start 2026-01-01T00:00:00 (up to 151 days" in msg
