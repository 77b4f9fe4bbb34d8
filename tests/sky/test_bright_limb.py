"""The bright limb as the nearest sunlit point of the Earth's disc, and the limb seen at the top
of the atmosphere (straylight.sky.limb).

Reference values: closed forms of constructed geometries (spherical trigonometry, worked in each
test), and a brute-force search over sampled points of the visible disc."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from straylight.config import load_campaign
from straylight.errors import InputError
from straylight.sky.geometry import Constraints, DoorState, observing_geometry
from straylight.sky.limb import limb_geometry
from straylight.sky.vectors import radec_to_unit

RE = 6378.137  # WGS84 equatorial radius, km (config/config.yaml)
ALT = 400.0  # km, CSST (seed paper sect. 3.3)
FAR = 1.0e12  # km: a Sun this far lights exactly a hemisphere (the terminator offset Re^2/D is 4e-5 km)


def _los(gamma_deg, beta_deg):
    """Unit LOS from a satellite at (Re + ALT) x: gamma from nadir (-x), in the plane through
    nadir turned by beta from the -y side towards +z."""
    g, b = np.radians(gamma_deg), np.radians(beta_deg)
    return np.array([-np.cos(g), -np.sin(g) * np.cos(b), np.sin(g) * np.sin(b)])


@pytest.mark.parametrize("height_km", [0.0, 100.0])
def test_nearest_sunlit_disc_point_on_the_terminator_not_on_the_limb(height_km):
    """Satellite at r = (Re + 400 km) x, Sun along +y: the terminator's plane y = 0 holds the
    satellite, so seen from it the terminator is the great circle of directions with d_y = 0
    through nadir, the sunlit disc the directions with d_y > 0.  A LOS above the dark limb at
    gamma = 75 deg from nadir, turned beta = 10 deg from -y towards +z, has its nearest point of
    that great circle at arcsin(|l_y|) = arcsin(sin gamma cos beta) = 72.04 deg, at
    atan2(sin gamma sin beta, cos gamma) = 32.9 deg from nadir, inside the disc: the bright-limb
    angle.  The nearest sunlit limb point (the lit arc's end, (-cos rho, 0, sin rho)) lies at
    arccos(cos gamma cos rho + sin gamma sin beta sin rho) = 75.8 deg (h = 0), which the
    nearest-sunlit-limb-point definition returned."""
    sat = np.array([RE + ALT, 0.0, 0.0])
    sun = np.array([0.0, FAR, 0.0])
    gamma, beta = 75.0, 10.0
    los = _los(gamma, beta)
    g, b = np.radians(gamma), np.radians(beta)
    foot_deg = np.degrees(np.arctan2(np.sin(g) * np.sin(b), np.cos(g)))
    rho_deg = np.degrees(np.arcsin((RE + height_km) / (RE + ALT)))
    assert foot_deg < rho_deg  # the nearest terminator point is on the disc
    expected = np.degrees(np.arcsin(np.sin(g) * np.cos(b)))
    rho = np.radians(rho_deg)
    limb_end = np.degrees(np.arccos(np.cos(g) * np.cos(rho) + np.sin(g) * np.sin(b) * np.sin(rho)))
    lg = limb_geometry(sat, los, sun, RE, limb_height_km=height_km)
    assert not bool(lg.limb_is_bright)
    assert float(lg.bright_limb_angle_deg) == pytest.approx(expected, abs=1e-4)
    assert limb_end - expected > 3.0  # the two definitions differ here by 3.8 deg (h = 0)
    # the dark limb stays the nearest limb point: gamma - rho
    assert float(lg.dark_limb_angle_deg) == pytest.approx(gamma - rho_deg, abs=1e-9)


def test_los_on_a_sunlit_point_of_the_disc_is_zero_from_the_bright_limb():
    """A LOS at nadir with the Sun overhead meets the sunlit disc: the angle is 0, where the
    nearest-limb-point definition gave the limb's 70.2 deg."""
    sat = np.array([RE + ALT, 0.0, 0.0])
    lg = limb_geometry(sat, np.array([-1.0, 0.0, 0.0]), np.array([FAR, 0.0, 0.0]), RE)
    assert float(lg.bright_limb_angle_deg) == 0.0
    assert float(lg.earth_limb_angle_deg) == pytest.approx(-np.degrees(np.arcsin(RE / (RE + ALT))), abs=1e-9)


@pytest.mark.parametrize("height_km", [50.0, 100.0])
def test_the_atmosphere_moves_the_limb_by_the_angle_of_its_height(height_km):
    """The limb of a sphere of radius Ra seen from |r| lies arcsin(Ra / |r|) from nadir, so an
    atmosphere of height h moves it away from nadir by arcsin((Re + h) / |r|) - arcsin(Re / |r|):
    1.29 deg for 50 km and 2.67 deg for 100 km at 400 km altitude (limb 70.21, 71.50 and
    72.88 deg from nadir for h = 0, 50, 100 km).  A LOS 85 deg from nadir,
    Sun overhead (the visible disc all lit): the bright-limb angle shrinks by that much; Sun
    behind the Earth (the disc all dark, even the layer's tangent points, which lie within one
    Earth radius of the shadow's axis): the dark-limb angle does.  The solid Earth's limb angle
    does not move."""
    d = RE + ALT
    shift = np.degrees(np.arcsin((RE + height_km) / d) - np.arcsin(RE / d))
    assert shift == pytest.approx({50.0: 1.2892, 100.0: 2.6718}[height_km], abs=1e-3)
    sat = np.array([d, 0.0, 0.0])
    los = _los(85.0, 0.0)
    for sun, name in (([FAR, 0.0, 0.0], "bright_limb_angle_deg"), ([-FAR, 0.0, 0.0], "dark_limb_angle_deg")):
        base = limb_geometry(sat, los, np.array(sun), RE)
        high = limb_geometry(sat, los, np.array(sun), RE, limb_height_km=height_km)
        assert float(getattr(base, name)) - float(getattr(high, name)) == pytest.approx(shift, abs=1e-9)
        assert float(high.earth_limb_angle_deg) == pytest.approx(float(base.earth_limb_angle_deg), abs=1e-12)


def test_the_limb_height_comes_from_the_instrument_file_and_reaches_the_constraints():
    """config/instruments/csst.yaml's avoidance.limb_height_km (100 km, the Karman line) is the
    campaign's constraints', and observing_geometry measures the limbs there: a LOS 85 deg from
    nadir with the disc all lit is 85 - arcsin(6478.137 / 6778.137) = 12.11 deg from it."""
    campaign = load_campaign()
    k = campaign.constraints
    assert k.limb_height_km == pytest.approx(100.0, abs=0.0)
    d = RE + ALT
    sat = np.array([d, 0.0, 0.0])
    bodies = {"sun": np.array([FAR, 0.0, 0.0]), "moon": np.array([0.0, 0.0, 384400.0])}
    g = observing_geometry(sat, bodies, _los(85.0, 0.0), RE, k)
    assert float(g["bright_limb_angle_deg"]) == pytest.approx(
        85.0 - np.degrees(np.arcsin((RE + 100.0) / d)), abs=1e-9
    )


def test_a_limb_above_the_satellite_is_refused():
    with pytest.raises(InputError, match="limb height"):
        limb_geometry(
            np.array([RE + ALT, 0.0, 0.0]),
            np.array([0.0, 1.0, 0.0]),
            np.array([FAR, 0, 0]),
            RE,
            limb_height_km=500.0,
        )


ang_st = st.floats(-720.0, 720.0, allow_nan=False)
dec_st = st.floats(-90.0, 90.0, allow_nan=False)


@settings(max_examples=25, deadline=None)
@given(ang_st, dec_st, st.floats(300.0, 800.0), ang_st, dec_st, ang_st, dec_st, st.sampled_from([0.0, 100.0]))
def test_bright_limb_angle_is_the_nearest_sunlit_point_of_the_sampled_disc(
    sra, sdec, alt, ura, udec, lra, ldec, height_km
):
    """Against a brute-force search: 400 x 2400 directions across the visible disc (radius Ra =
    Re + h), each one's first point on the sphere Ra lit when P . S > Re Ra (the surface point
    below it lit), the smallest angle from the LOS to a lit one.  The sampled minimum is never
    below the exact one, and exceeds it by at most one cell's diagonal (rho / 399 radially,
    2 pi / 2400 sin(rho) around: ~0.24 deg), within which a lit sample lies next to the exact
    nearest point."""
    sat = radec_to_unit(np.array(sra), np.array(sdec)) * (RE + alt)
    sun = radec_to_unit(np.array(ura), np.array(udec)) * 1.495978707e8
    los = radec_to_unit(np.array(lra), np.array(ldec))
    ra_km = RE + height_km
    lg = limb_geometry(sat, los, sun, RE, limb_height_km=height_km)
    r = np.linalg.norm(sat)
    nadir = -sat / r
    rho = np.arcsin(ra_km / r)
    e1 = np.cross(nadir, [0.3, 0.5, 0.8])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(nadir, e1)
    a = np.linspace(0.0, rho, 400)[:, None, None]
    psi = np.linspace(0.0, 2 * np.pi, 2400, endpoint=False)[None, :, None]
    d = (np.cos(a) * nadir + np.sin(a) * (np.cos(psi) * e1 + np.sin(psi) * e2)).reshape(-1, 3)
    b = d @ sat
    t = -b - np.sqrt(np.maximum(b * b - (r * r - ra_km * ra_km), 0.0))
    p = sat + t[:, None] * d
    lit = p @ sun > RE * ra_km
    if not lit.any():
        assert float(lg.bright_limb_angle_deg) == 180.0
        return
    brute = np.degrees(np.arccos(np.clip(d[lit] @ los, -1.0, 1.0))).min()
    got = float(lg.bright_limb_angle_deg)
    assert got <= brute + 1e-6
    assert brute - got <= np.degrees(np.hypot(rho / 399, 2 * np.pi / 2400 * np.sin(rho)))


def test_an_instrument_file_without_a_limb_height_reads_zero():
    """The schema's default (0 km, the solid Earth's limb) fills an instrument file without
    avoidance.limb_height_km; Constraints' own default is the same."""
    from pathlib import Path

    from straylight.config import load_instrument
    from straylight.config.instrument import instrument_settings

    raw = load_instrument(Path(__file__).resolve().parents[2] / "config" / "instruments" / "csst.yaml")
    del raw["avoidance"]["limb_height_km"]
    assert instrument_settings(raw).avoidance.limb_height_km.value == 0.0
    assert Constraints(50.0, 40.0, 80.0, 30.0, (DoorState(135.0, 65.0, False),)).limb_height_km == 0.0
