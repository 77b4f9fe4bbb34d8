"""Geometry: ranges and finiteness (hypothesis), exact thresholds, limb graze, cross-checks.

Reference values: exact angles built by construction, and the paper's Earth-blockage test and
door states."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from straylight.sky.frames import telescope_frame
from straylight.sky.geometry import VIOLATION_BITS, Constraints, DoorState, observing_geometry
from straylight.sky.limb import earth_blocks, limb_geometry
from straylight.sky.vectors import angle_between_deg, radec_to_unit, wrap_360_deg

RE = 6378.137
AU = 1.495978707e8
CONSTRAINTS = Constraints(
    sun_min_deg=50.0,
    moon_min_deg=40.0,
    bright_limb_min_deg=80.0,
    dark_limb_min_deg=30.0,
    door_states=(DoorState(135.0, 65.0, False), DoorState(105.0, 50.0, True)),
)

ra_st = st.floats(-720.0, 720.0, allow_nan=False)
dec_st = st.floats(-90.0, 90.0, allow_nan=False)
alt_st = st.floats(200.0, 2000.0, allow_nan=False)


def _unit(ra, dec):
    return radec_to_unit(np.array(ra), np.array(dec))


def _scene(sat_ra, sat_dec, alt, sun_ra, sun_dec, moon_ra, moon_dec):
    sat = _unit(sat_ra, sat_dec) * (RE + alt)
    sun = _unit(sun_ra, sun_dec) * AU
    moon = _unit(moon_ra, moon_dec) * 384400.0
    return sat, {"sun": sun, "moon": moon}


@settings(max_examples=300, deadline=None)
@given(ra_st, dec_st, alt_st, ra_st, dec_st, ra_st, dec_st, ra_st, dec_st)
def test_all_outputs_finite_and_in_range(sra, sdec, alt, ura, udec, mra, mdec, lra, ldec):
    sat, bodies = _scene(sra, sdec, alt, ura, udec, mra, mdec)
    g = observing_geometry(sat, bodies, _unit(lra, ldec), RE, CONSTRAINTS)
    for k, v in g.items():
        assert np.all(np.isfinite(np.asarray(v, dtype=float))), k
    for k in (
        "sun_angle_deg",
        "moon_angle_deg",
        "zenith_angle_deg",
        "moon_phase_angle_deg",
        "bright_limb_angle_deg",
        "dark_limb_angle_deg",
    ):
        assert 0.0 <= float(g[k]) <= 180.0, k
    assert 0.0 <= float(g["sun_phi_deg"]) < 360.0 and 0.0 <= float(g["moon_phi_deg"]) < 360.0
    assert 0.0 <= float(g["moon_illuminated_fraction"]) <= 1.0
    rho = np.degrees(np.arcsin(RE / (RE + alt)))
    assert -rho - 1e-9 <= float(g["earth_limb_angle_deg"]) <= 180.0 - rho + 1e-9
    # the limb angle is negative exactly when the paper's Earth-blockage test hides the LOS
    blocked = bool(earth_blocks(sat, _unit(lra, ldec), RE))
    if abs(float(g["earth_limb_angle_deg"])) > 1e-9:
        assert blocked == (float(g["earth_limb_angle_deg"]) < 0)
    # the nearest limb point is bright or dark: the dark-limb angle is |limb angle| when it is
    # dark; the bright-limb angle (the nearest sunlit point of the disc) is when it is lit and
    # the LOS is off the disc (the nearest point of the disc is then that limb point)
    nearest = abs(float(g["earth_limb_angle_deg"]))
    off_disc = float(g["earth_limb_angle_deg"]) > 0.0
    if not bool(g["limb_is_bright"]):
        assert float(g["dark_limb_angle_deg"]) == pytest.approx(nearest, abs=1e-9)
    elif off_disc:
        assert float(g["bright_limb_angle_deg"]) == pytest.approx(nearest, abs=1e-9)
    if off_disc:
        assert float(g["bright_limb_angle_deg"]) >= nearest - 1e-9
    assert float(g["dark_limb_angle_deg"]) >= nearest - 1e-9


@settings(max_examples=60, deadline=None)
@given(ra_st, dec_st, alt_st, ra_st, dec_st, ra_st, dec_st)
def test_bright_and_dark_limb_angles_match_brute_force(sra, sdec, alt, ura, udec, lra, ldec):
    """Closed-form limb arcs against 20000 sampled limb points (sunlit test P.(S-P) > 0): the
    dark-limb angle is the nearest dark one; the bright-limb angle, the nearest sunlit point of
    the whole disc (tests/sky/test_bright_limb.py), is at most the nearest sunlit limb point."""
    sat = _unit(sra, sdec) * (RE + alt)
    sun = _unit(ura, udec) * AU
    los = _unit(lra, ldec)
    lg = limb_geometry(sat, los, sun, RE)
    r = np.linalg.norm(sat)
    nadir = -sat / r
    rho = np.arcsin(RE / r)
    a = np.cross(nadir, [0.3, 0.5, 0.8])
    a /= np.linalg.norm(a)
    b = np.cross(nadir, a)
    psi = np.linspace(0, 2 * np.pi, 20000, endpoint=False)[:, None]
    d = np.cos(rho) * nadir + np.sin(rho) * (np.cos(psi) * a + np.sin(psi) * b)
    p = sat + d * np.sqrt(r**2 - RE**2)
    lit = np.einsum("ij,ij->i", p, sun - p) > 0
    ang = angle_between_deg(d, los)
    bright = ang[lit].min() if lit.any() else 180.0
    dark = ang[~lit].min() if (~lit).any() else 180.0
    # sampling step 0.018 deg along the limb -> allow 0.05 deg
    if 0 < lit.sum() < lit.size:
        assert float(lg.bright_limb_angle_deg) <= bright + 0.05
        assert float(lg.dark_limb_angle_deg) == pytest.approx(dark, abs=0.05)


def test_limb_angle_changes_sign_exactly_at_graze():
    sat = np.array([RE + 400.0, 0.0, 0.0])
    rho = np.arcsin(RE / (RE + 400.0))
    sun = np.array([0.0, 0.0, AU])  # Sun at the pole: the x-y limb is on the terminator side
    for delta in (-1e-7, 0.0, 1e-7):
        ang = rho + np.radians(delta)  # angle from nadir
        los = np.array([-np.cos(ang), np.sin(ang), 0.0])
        lg = limb_geometry(sat, los, sun, RE)
        assert float(lg.earth_limb_angle_deg) == pytest.approx(delta, abs=1e-9)
        if delta != 0.0:
            assert bool(earth_blocks(sat, los, RE)) == (delta < 0)


def test_pointing_at_zenith_nadir_poles_and_ra_wrap_are_finite():
    sat = np.array([0.0, 0.0, RE + 400.0])  # over the north pole
    sun = np.array([AU, 0.0, 0.0])
    bodies = {"sun": sun, "moon": np.array([0.0, 384400.0, 0.0])}
    for ra, dec in [(0, 90), (0, -90), (359.9999999, 10), (0.0, 10), (360.0, 10), (-1e-12, 0)]:
        g = observing_geometry(sat, bodies, _unit(ra, dec), RE, CONSTRAINTS)
        assert all(np.all(np.isfinite(np.asarray(v, float))) for v in g.values())
    g_up = observing_geometry(sat, bodies, _unit(0, 90), RE, CONSTRAINTS)
    assert float(g_up["zenith_angle_deg"]) == pytest.approx(0.0, abs=1e-9)
    g_down = observing_geometry(sat, bodies, _unit(0, -90), RE, CONSTRAINTS)
    assert float(g_down["earth_limb_angle_deg"]) == pytest.approx(
        -np.degrees(np.arcsin(RE / (RE + 400))), abs=1e-9
    )
    # RA wrap: 359.9999999 and -1e-7 are the same direction within 1e-7 deg
    a = observing_geometry(sat, bodies, _unit(359.9999999, 10), RE, CONSTRAINTS)
    b = observing_geometry(sat, bodies, _unit(-1e-7, 10), RE, CONSTRAINTS)
    for k in ("sun_angle_deg", "earth_limb_angle_deg", "bright_limb_angle_deg"):
        assert float(a[k]) == pytest.approx(float(b[k]), abs=1e-6)


def test_sun_exactly_on_and_behind_the_pointing():
    sat = np.array([RE + 400.0, 0.0, 0.0])
    sun = np.array([0.0, AU, 0.0])
    to_sun = (sun - sat) / np.linalg.norm(sun - sat)  # the Sun as seen from the satellite
    for los in (to_sun, -to_sun):
        f = telescope_frame(los, sun - sat)
        m = np.stack([f.x, f.y, f.z])
        np.testing.assert_allclose(m @ m.T, np.eye(3), atol=1e-12)
        g = observing_geometry(sat, {"sun": sun, "moon": -sun / 400}, los, RE, CONSTRAINTS)
        assert all(np.all(np.isfinite(np.asarray(v, float))) for v in g.values())
    g = observing_geometry(sat, {"sun": sun, "moon": -sun / 400}, -to_sun, RE, CONSTRAINTS)
    assert float(g["sun_angle_deg"]) == pytest.approx(180.0, abs=1e-9)
    g = observing_geometry(sat, {"sun": sun, "moon": -sun / 400}, to_sun, RE, CONSTRAINTS)
    assert float(g["sun_angle_deg"]) == pytest.approx(0.0, abs=1e-9)
    assert not bool(g["observable"]) and float(g["door_opening_deg"]) == 0.0


def test_telescope_frame_puts_sun_at_phi_zero_and_is_right_handed():
    rng = np.random.default_rng(3)
    los = rng.normal(size=(200, 3))
    los /= np.linalg.norm(los, axis=1, keepdims=True)
    sun = rng.normal(size=(200, 3))
    f = telescope_frame(los, sun)
    theta, phi = f.theta_phi_deg(sun)
    assert np.all((phi < 1e-9) | (phi > 360 - 1e-9) | (phi == 0.0))
    np.testing.assert_allclose(theta, angle_between_deg(los, sun), atol=1e-9)
    np.testing.assert_allclose(np.cross(f.x, f.y), f.z, atol=1e-12)


def test_earth_blockage_two_conditions():
    sat = np.array([RE + 400.0, 0.0, 0.0])
    assert bool(earth_blocks(sat, np.array([-1.0, 0.0, 0.0]), RE))  # nadir
    assert not bool(earth_blocks(sat, np.array([1.0, 0.0, 0.0]), RE))  # zenith
    assert not bool(earth_blocks(sat, np.array([0.0, 1.0, 0.0]), RE))  # horizontal: angle = 90, not > 90
    # behind (angle > 90) but missing the Earth: condition 2 fails
    assert not bool(earth_blocks(sat, np.array([-0.1, 1.0, 0.0]), RE))


@pytest.mark.parametrize(
    "name,arg,threshold",
    [
        ("sun", 0, 50.0),
        ("moon", 1, 40.0),
        ("bright_limb", 2, 80.0),
        ("dark_limb", 3, 30.0),
    ],
)
def test_each_constraint_switches_exactly_at_threshold(name, arg, threshold):
    base = [120.0, 120.0, 120.0, 120.0, 60.0]
    for value, violated in (
        (threshold, False),
        (np.nextafter(threshold, 0), True),
        (np.nextafter(threshold, 180), False),
    ):
        vals = list(base)
        vals[arg] = value
        flags = int(CONSTRAINTS.violations(*vals))
        assert bool(flags & VIOLATION_BITS[name]) == violated, (name, value)
        assert (flags & ~VIOLATION_BITS[name]) == 0
    occ = [int(CONSTRAINTS.violations(120, 120, 120, 120, v)) for v in (0.0, 1e-12, -1e-12)]
    assert [bool(f & VIOLATION_BITS["earth_occultation"]) for f in occ] == [True, False, True]


def test_door_states_follow_the_paper():
    s = np.array([180.0, 65.0 + 1e-12, 65.0, 57.0, 50.0, 50.0 - 1e-12, 10.0])
    np.testing.assert_array_equal(CONSTRAINTS.door_opening_deg(s), [135, 135, 105, 105, 105, 0, 0])


def test_moon_phase_full_and_new():
    from straylight.sky.geometry import moon_phase

    sun = np.array([AU, 0, 0])
    obs = np.zeros(3)
    full = np.array([-384400.0, 0, 1.0])
    new = np.array([384400.0, 0, 1.0])
    a, k, e = moon_phase(sun, full, obs)
    assert a < 1e-3 and k == pytest.approx(1.0) and e == pytest.approx(180.0, abs=1e-3)
    a, k, e = moon_phase(sun, new, obs)
    assert a > 179.9 and k == pytest.approx(0.0, abs=1e-9)


def test_nan_and_out_of_range_pointings_are_refused():
    from straylight.errors import InputError

    with pytest.raises(InputError, match="RA"):
        radec_to_unit(np.nan, 0.0)
    with pytest.raises(InputError, match="Dec"):
        radec_to_unit(0.0, 91.0)


def test_grid_shapes(campaign):
    from straylight.sky.observing import sample_geometry, scene

    sc = scene(campaign.orbit, campaign.times[:5])
    g = sample_geometry(
        sc,
        np.array([0.0, 90.0, 180.0]),
        np.array([0.0, 45.0, -89.0]),
        campaign.earth.radius_km,
        campaign.constraints,
    )
    assert g["observable"].shape == (5, 3)
    assert g["moon_phase_angle_deg"].shape == (5, 3)


def test_wrap_360_equals_numpys_modulo():
    """wrap_360_deg skips the floating-point modulo where it can: its values equal np.mod's
    (numpy is the reference; -0.0 stays -0.0, equal to np.mod's 0.0), for arctan2's range,
    angles already wrapped, -1e-15 (which np.mod rounds to 360.0), beyond +-360 deg, huge
    values and NaN."""
    rng = np.random.default_rng(5)
    cases = [
        np.degrees(np.arctan2(rng.normal(size=10_000), rng.normal(size=10_000))),
        rng.uniform(0.0, 360.0, 1000),
        rng.uniform(-1e4, 1e4, 1000),
        np.array([-1e-15, -0.0, 0.0, 360.0 - 2**-44, -359.9, 359.9, 720.5, -1e300, np.nan]),
        np.zeros(0),
    ]
    for x in cases:
        assert np.array_equal(wrap_360_deg(x), np.mod(x, 360.0), equal_nan=True)


def test_tiled_period_finds_repeated_lines_of_sight_exactly():
    """A cube batch repeats its pixels' lines of sight at every time step: tiled_period finds
    the period only when every step's rows equal the first step's bit for bit (one ulp off, a
    step of another length, or a single run: None), so work done on the first step's rows and
    tiled is the same as per sample (here the zodiacal light's coordinates, compared exactly)."""
    from straylight.sky.runs import scene_runs, tiled_period
    from straylight.sources.zodiacal import _ecliptic_lon_lat_deg, helioecliptic_coordinates

    rng = np.random.default_rng(3)
    steps, pixels = 5, 7
    los = rng.normal(size=(pixels, 3))
    los /= np.linalg.norm(los, axis=1)[:, None]
    tiled = np.tile(los, (steps, 1))
    sun = np.repeat(rng.normal(size=(steps, 3)), pixels, axis=0)
    runs = scene_runs(sun)
    assert tiled_period(tiled, runs) == pixels
    assert tiled_period(tiled.reshape(steps, pixels, 3), runs) == pixels
    off = tiled.copy()
    off[3 * pixels + 2, 1] = np.nextafter(off[3 * pixels + 2, 1], 2.0)
    assert tiled_period(off, runs) is None
    assert tiled_period(tiled[:-1], scene_runs(sun[:-1])) is None
    assert tiled_period(tiled, None) is None and tiled_period(los, scene_runs(sun[:pixels])) is None
    dlon, beta = helioecliptic_coordinates(tiled, sun)
    lon, lat = _ecliptic_lon_lat_deg(tiled)
    lon_sun, _ = _ecliptic_lon_lat_deg(sun)
    d = np.abs(lon - lon_sun)
    assert np.array_equal(dlon, np.where(d > 180.0, 360.0 - d, d)) and np.array_equal(beta, np.abs(lat))
