"""Independent checks of the modelled earthshine's angular shape (straylight.paper.earthshine_checks;
docs/pst.md "Independent checks").  None of them sets a parameter: they report how the model,
calibrated on the paper's 70-deg median crossing alone, compares with HST's curve, the HST ETC's
levels and the paper's sect. 1 statements.  The figures are those of a coarse phase grid (raan
90 x u 30 deg: 24 sunlit phases; HEALPix nside 8 pointings) at the configured tail and door; the
fine grid's (108 phases) are in docs/img/pst_tail_calibration.json's ``checks``."""

import ast
from pathlib import Path

import numpy as np
import pytest
from conftest import SHARED_DATA

HST_CURVE = SHARED_DATA / "hst_sky" / "wfc3_earthshine_v_vs_limb_angle.csv"
REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def profile(campaign):
    from straylight.paper.earthshine_checks import limb_profile
    from straylight.paper.tail_calibration import orbit_phases, phase_crossings, phase_earthshine

    pst = campaign.instrument_settings.pst
    tail = pst.tail_log10_at_90deg.value
    level = pst.tail_calibration.hst_earthshine_v_mag_per_arcsec2.value
    res = phase_earthshine(campaign, orbit_phases(campaign, 90.0, 30.0), [tail], nside=8)
    cr = phase_crossings(res, level, tail)
    return limb_profile(cr["bins"], 0.0, 120.0), cr, level


def test_the_checks_set_nothing():
    """The calibration and the envelope's members never import the checks: no parameter can
    depend on them."""
    for mod in ("tail_calibration", "envelope_members", "door_prior"):
        tree = ast.parse((REPO / "straylight" / "paper" / f"{mod}.py").read_text())
        names = {
            a.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom | ast.Import) for a in n.names
        }
        mods = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
        assert "straylight.paper.earthshine_checks" not in mods | names, mod


def test_shape_against_hsts_curve_and_the_etc(profile):
    """Over 20-90 deg the model's median falls 0.150 mag/deg, HST's WFC3 curve 0.128: 1.17x
    (within 0.15).  Near the limb it falls about twice as fast in log: the model's 24/38-deg
    ratio is 5.7 and 38/50-deg 4.6 (+/-1), against HST's curve's 2.5 and 2.3 and the HST ETC's
    ~2 and ~2 (docs/pst.md: a different baffle, and the limb defined at 100 km, not at the
    surface).  Skips without the test-only HST curve."""
    from straylight.paper.earthshine_checks import HST_ETC_RATIOS, shape_against_hst
    from straylight.paper.scenarios import read_hst_curve

    if not HST_CURVE.exists():
        pytest.skip(
            f"{HST_CURVE} is absent: the HST WFC3 curve is test and validation only (shared/data/DATA.md)"
        )
    prof, _, _ = profile
    s = shape_against_hst(prof, *read_hst_curve(HST_CURVE))
    assert s["hst_slope_mag_per_deg"] == pytest.approx(0.128, abs=0.005)
    assert s["slope_mag_per_deg"] == pytest.approx(0.150, abs=0.015)
    assert s["slope_ratio"] == pytest.approx(1.17, abs=0.15)
    assert s["hst_curve_ratio_24_38"] == pytest.approx(2.5, abs=0.2)
    assert s["hst_curve_ratio_38_50"] == pytest.approx(2.3, abs=0.2)
    assert s["ratio_24_38"] == pytest.approx(5.7, abs=1.0)
    assert s["ratio_38_50"] == pytest.approx(4.6, abs=1.0)
    etc_24_38 = HST_ETC_RATIOS[24.0] / HST_ETC_RATIOS[38.0]
    assert (
        s["ratio_24_38"] / etc_24_38 > 2.0
        and s["ratio_38_50"] / (HST_ETC_RATIOS[38.0] / HST_ETC_RATIOS[50.0]) > 2.0
    )


def test_the_papers_sect1_statements(profile):
    """Sect. 1's preliminary 80-deg bright-limb avoidance is conservative for about two thirds
    of the sunlit phases (0.71 of them cross HST's level by 80 deg; the median at 70 by
    construction).  Its 50-80 deg range "where a longer exposure helps": at 80 deg the median
    earthshine is 1.2-2.4x the zodiacal light (V 22.5-23.3), so a 2.2-3.4x exposure restores the
    dark sky's depth; at 50 deg it is 90-188x, beyond what an exposure can make up: the model
    puts that range at ~70-85 deg (docs/pst.md)."""
    from straylight.paper.earthshine_checks import sect1_figures

    prof, cr, level = profile
    f = sect1_figures(prof, cr["crossing_deg"], level)
    assert f["share_crossing_by_80_deg"] == pytest.approx(0.71, abs=0.1)
    assert f["profile_mag_at"]["70"] == pytest.approx(level, abs=0.3)
    lo80, hi80 = f["earthshine_over_zodi"]["80"]
    assert lo80 == pytest.approx(1.16, rel=0.3) and hi80 == pytest.approx(2.43, rel=0.3)
    lo50, hi50 = f["earthshine_over_zodi"]["50"]
    assert lo50 == pytest.approx(90.0, rel=0.3) and hi50 == pytest.approx(188.0, rel=0.3)
    assert np.all(np.diff(prof["median_mag"][prof["centre_deg"] <= 85.0]) > 0)  # fainter outwards to 85 deg
