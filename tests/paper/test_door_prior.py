"""The angles at which the Earth's light reaches the door's inner face
(straylight.paper.door_prior), on which the door's reflectance prior rests
(config/instruments/csst.yaml door_geometry.reflectance; docs/pst.md "The door's priors").

Coarse phase grid (raan 90 x u 30 deg: 24 sunlit phases), nside 8 pointings at least 80 deg
from the bright limb; the instrument file quotes the finer raan 60 x u 20 deg grid (p16-p84 of
the 135-deg door: 52-76 deg, median 62)."""

import pytest


def test_earth_light_reaches_the_door_at_large_incidence_away_from_the_specular(campaign):
    """The 135-deg door: incidence 52-76 deg (p16-p84, weighted by the light delivered), median
    62.5 (+/-3); the 105-deg door: median 48 (+/-4).  The aperture lies >= 75 deg from the
    specular reflection for 84 % of the light: the coating's diffuse part, not its forward
    specular lobe, sends the light to the aperture."""
    from straylight.paper.door_prior import door_incidence
    from straylight.paper.tail_calibration import orbit_phases

    d = door_incidence(campaign, orbit_phases(campaign, 90.0, 30.0), 8)
    wide, narrow = d[135.0], d[105.0]
    assert wide["incidence_deg"]["p50"] == pytest.approx(62.5, abs=3.0)
    assert wide["incidence_deg"]["p16"] == pytest.approx(52.0, abs=3.0)
    assert wide["incidence_deg"]["p84"] == pytest.approx(76.0, abs=3.0)
    assert narrow["incidence_deg"]["p50"] == pytest.approx(48.0, abs=4.0)
    assert wide["specular_to_aperture_deg"]["p16"] > 100.0
    assert narrow["specular_to_aperture_deg"]["p16"] > 75.0
