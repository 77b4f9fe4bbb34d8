"""Saturn's ring terms in its V magnitude (Meeus 1998, "Astronomical Algorithms", 2nd ed.)."""

import numpy as np
import pytest

from straylight.sky.ephemeris import default_ephemeris
from straylight.sources.body_magnitudes import planet_v_magnitude, saturn_ring_angles_deg
from straylight.sources.photometry import AU_KM

# Meeus (1998) Example 45.a: 1992 December 16, 0h TD (JDE 2448972.50068): B = 16.442 deg,
# B' = 14.679 deg, Delta U = 4.198 deg
MEEUS_45A_JDE = 2448972.50068
MEEUS_45A_B_DEG = 16.442
MEEUS_45A_DELTA_U_DEG = 4.198


def _meeus_45a_positions():
    """Geocentric DE405 positions (km) of Saturn and the Sun at Example 45.a's instant.  Geometric:
    the light time (1.46 h) moves Saturn by ~50,000 km across a 1.6e9 km line of sight, 0.002 deg
    of B and Delta U."""
    p = default_ephemeris().positions_tdb(MEEUS_45A_JDE, bodies=("saturn", "sun"))
    return p["saturn"], p["sun"]


def test_ring_angles_match_meeus_example_45a():
    """B and Delta U at 1992 Dec 16 0h TD from DE405 and the IAU pole: Meeus Example 45.a gives
    16.442 and 4.198 deg (his ring plane from ch. 45's i and Omega; the two planes agree to
    ~0.01 deg)."""
    saturn, sun = _meeus_45a_positions()
    b_deg, delta_u_deg = saturn_ring_angles_deg(saturn, sun, np.zeros(3))
    assert abs(float(b_deg)) == pytest.approx(MEEUS_45A_B_DEG, abs=0.02)
    assert float(delta_u_deg) == pytest.approx(MEEUS_45A_DELTA_U_DEG, abs=0.02)


def test_saturn_magnitude_has_both_ring_terms():
    """Meeus (1998) ch. 41: V = -8.88 + 5 log10(r Delta) + 0.044 |Delta U| - 2.60 sin|B| +
    1.25 sin^2 B.  With Example 45.a's B and Delta U and DE405's r and Delta the formula gives
    +0.74; the magnitude without the Delta U term (0.044 x 4.198 = 0.185 mag) is refused."""
    saturn, sun = _meeus_45a_positions()
    r = np.linalg.norm(saturn - sun) / AU_KM
    delta = np.linalg.norm(saturn) / AU_KM
    b = np.radians(MEEUS_45A_B_DEG)
    want = (
        -8.88
        + 5 * np.log10(r * delta)
        + 0.044 * MEEUS_45A_DELTA_U_DEG
        - 2.60 * np.sin(abs(b))
        + 1.25 * np.sin(b) ** 2
    )
    assert want == pytest.approx(0.74, abs=0.01)
    got = float(planet_v_magnitude("saturn", saturn, sun, np.zeros(3)))
    assert got == pytest.approx(want, abs=0.003)


def test_delta_u_reaches_six_to_seven_degrees():
    """Over a Saturn year the phase angle reaches asin(1 AU / r) at quadrature, 5.7 deg at
    aphelion (10.05 AU) to 6.4 deg at perihelion (9.02 AU); |Delta U|, that angle projected on
    the ring plane, reaches up to 6.4 / cos(26.7 deg) = 7.2 deg (B at most the ring's 26.7 deg
    obliquity).  So the Delta U term is worth up to ~0.3 mag (Meeus ch. 41's 0.044 mag/deg).
    DE405 geocentric positions every 5 days, 2020-2049."""
    eph = default_ephemeris()
    jd = 2458849.5 + np.arange(0.0, 30 * 365.25, 5.0)
    pos = eph.positions_tdb(jd, bodies=("saturn", "sun"))
    _, du = saturn_ring_angles_deg(pos["saturn"], pos["sun"], np.zeros(3))
    print(f"max |Delta U| 2020-2049: {float(du.max()):.2f} deg")
    assert 5.7 < float(du.max()) < 7.25
    assert 0.044 * float(du.max()) < 0.32
