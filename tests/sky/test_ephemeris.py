"""DE405 evaluator against jplephem (same data) and skyfield + DE421 (independent ephemeris)."""

import numpy as np
import pytest

from straylight.errors import EphemerisRangeError
from straylight.sky.ephemeris import BODIES, DE405, radec_distance

JD_1950 = 2433282.5
JD_2100 = 2488069.5


@pytest.fixture(scope="module")
def eph():
    return DE405()


def test_matches_jplephem_same_data_under_1m(eph):
    """Same coefficients, independent evaluator (jplephem.ephem.Ephemeris): agree < 1 m."""
    import de405
    from jplephem.ephem import Ephemeris

    ref = Ephemeris(de405)
    jd = np.random.default_rng(405).uniform(JD_1950, JD_2100, 500)
    ours = eph.positions_tdb(jd)
    earth = ref.position("earthmoon", jd) - ref.position("moon", jd) * ref.earth_share
    worst = {}
    for body in BODIES:
        if body == "moon":
            expected = ref.position("moon", jd).T
        else:
            expected = (ref.position(body, jd) - earth).T
        worst[body] = np.abs(ours[body] - expected).max()
    print("max |ours - jplephem| km:", {k: f"{v:.1e}" for k, v in worst.items()})
    assert max(worst.values()) < 1e-3  # km


def _angle_arcsec(a, b):
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    return np.degrees(np.arctan2(cross, np.sum(a * b, axis=-1))) * 3600.0


def test_matches_skyfield_de421(eph):
    """Independent ephemeris DE421 (skyfield-data): < 1 arcsec Sun/planets, < 2 arcsec Moon.

    DE421 covers 1900-2053, so the random times are drawn from 1950-2050 (the issue asks
    1950-2100; DE405 past 2053 is checked against jplephem above).  Pluto, a dwarf planet,
    gets 2 arcsec: its DE405 orbit differs from DE421's by up to 1.4 arcsec as seen from the
    Earth (measured here; Pluto's orbit was refitted for DE421, Folkner et al. 2009, IPN PR
    42-178), which is the ephemerides' difference, not an evaluation error.
    """
    from skyfield.api import Loader
    from skyfield_data import get_skyfield_data_path

    load = Loader(get_skyfield_data_path(), verbose=False)
    planets = load("de421.bsp")
    ts = load.timescale(builtin=True)
    jd = np.random.default_rng(421).uniform(JD_1950, 2469807.5, 300)
    t = ts.tdb_jd(jd)
    earth = planets["earth"]
    names = {
        "sun": "sun",
        "moon": "moon",
        "mercury": "mercury",
        "venus": "venus",
        "mars": "mars barycenter",
        "jupiter": "jupiter barycenter",
        "saturn": "saturn barycenter",
        "uranus": "uranus barycenter",
        "neptune": "neptune barycenter",
        "pluto": "pluto barycenter",
    }
    ours = eph.positions_tdb(jd)
    worst = {}
    for body, sf_name in names.items():
        ref = (planets[sf_name] - earth).at(t).position.km.T
        worst[body] = _angle_arcsec(ours[body], ref).max()
    print("max angular difference DE405 vs DE421, arcsec:", {k: f"{v:.3f}" for k, v in worst.items()})
    assert worst["moon"] < 2.0
    assert worst["pluto"] < 2.0
    assert max(v for k, v in worst.items() if k not in ("moon", "pluto")) < 1.0


def test_out_of_range_times_raise_clear_error(eph):
    with pytest.raises(EphemerisRangeError, match="outside the DE405 range"):
        eph.positions_tdb(np.array([2451545.0, 2600000.0]))
    with pytest.raises(EphemerisRangeError):
        eph.positions("1500-01-01T00:00:00")


def test_range_ends_are_valid(eph):
    p = eph.positions_tdb(np.array([eph.jd_start, eph.jd_end]))
    assert all(np.all(np.isfinite(v)) for v in p.values())


def test_continuous_across_record_boundaries(eph):
    """Records join continuously: each side, extrapolated linearly to the boundary, agrees < 1 m.

    Times are given as two-part JDs (boundary + offset) so no precision is lost in the sum.
    """
    b = eph.block_boundaries_jd[1000:1005]
    eps = 1e-3 / 86400.0  # 1 ms

    def at(offset):
        return eph.positions_tdb(b, np.full_like(b, offset))

    left_m1, left_m3, right_p1, right_p3 = at(-eps), at(-3 * eps), at(eps), at(3 * eps)
    for body in ("moon", "sun", "mercury", "mars"):
        left = 1.5 * left_m1[body] - 0.5 * left_m3[body]
        right = 1.5 * right_p1[body] - 0.5 * right_p3[body]
        assert np.abs(left - right).max() < 1e-3, body


def test_shapes_broadcast(eph):
    jd = np.full((4, 3), 2461041.5)
    p = eph.positions_tdb(jd, bodies=["sun"])
    assert p["sun"].shape == (4, 3, 3)


def test_radec_distance_of_sun_on_known_date(eph):
    """Sun near RA 281 deg, Dec -23 deg at 2026-01-01 (close to the December solstice)."""
    ra, dec, dist = radec_distance(eph.positions("2026-01-01T00:50:00", ["sun"])["sun"])
    # Astronomical Almanac 2026: Sun apparent RA 18h44m, Dec -23.0 deg at 0h TT on Jan 1;
    # geometric ICRS differs from apparent by < 0.4 deg (aberration + precession).
    assert abs(ra - 281.0) < 0.5 and abs(dec + 23.0) < 0.3
    assert abs(dist / 1.495978707e8 - 0.9833) < 0.001  # perihelion season
