"""The published CSST wide-survey depths reconciled in all seven bands, term by term
(docs/assumptions.md, "Depth against the published CSST figures").

Published 5-sigma point-source depths: Gong et al. 2019 (ApJ 883, 203), wide survey: NUV 25.4,
u 25.4, g 26.3, r 26.0, i 25.9, z 25.2, y 24.4; Qu et al. 2023 (MNRAS 519, 6499, abstract): g 26.3,
i 25.9.  The sky behind such figures: the CSST signal-to-noise module's default (``calSN``;
shared/data/DATA.md, "Published CSST figures"), zodiacal light of V = 21.0 mag/arcsec2 with
HST's zodiacal spectrum (``Zodi.fits``) plus half of HST's "high" earthshine
(``earthshine.fits``, test-only data here).  Our noise model is the CCD equation of
``straylight.limits.point_source`` with the instrument file's exposures, read noise, dark current and
EE80 aperture.
"""

import numpy as np
import pytest
from conftest import REPO, SHARED_DATA, THROUGHPUT

PUBLISHED_DEPTH_MAG = {"NUV": 25.4, "u": 25.4, "g": 26.3, "r": 26.0, "i": 25.9, "z": 25.2, "y": 24.4}
CALSN_ZODIACAL_V_MAG = 21.0  # calSN's default zodiacal light, V mag/arcsec2 (DATA.md)
CALSN_EARTHSHINE_FRACTION = 0.5  # calSN's default: half of HST's "high" earthshine (DATA.md)
EARTHSHINE = SHARED_DATA / "hst_sky" / "earthshine.fits"
POLE_B500 = 77e-8  # W m-2 sr-1 um-1: Leinert et al. 1998 Table 17 at the ecliptic pole


def _flam_per_arcsec2(path):
    """An HST sky spectrum (STScI flam per arcsec2) as (wavelength A, W m-2 um-1 per arcsec2)."""
    from astropy.io import fits

    with fits.open(path) as h:
        wl = np.asarray(h[1].data["WAVELENGTH"], dtype=float)
        flam = np.asarray(h[1].data["FLUX"], dtype=float)
    return wl, flam * 1e-7 * 1e4 * 1e4  # erg s-1 cm-2 A-1 -> W m-2 um-1


def _e_per_s_per_pix(campaign, band, wl, flam_arcsec2):
    """e-/s/pixel of a uniform sky (F_lambda per arcsec2) through ``band``, the 2 m aperture and
    the campaign's pixel (arcsec2)."""
    from straylight.optics.bandpass import aperture_area_m2

    area = aperture_area_m2(campaign.instrument_settings)
    return float(band.photon_rate(wl, flam_arcsec2)) * area * campaign.pixel_scale_arcsec**2


def _calsn_sky(campaign, band):
    """calSN's default sky through ``band``: (zodiacal light, earthshine), e-/s/pixel."""
    from straylight.optics.bandpass import load_band

    wl_z, f_z = _flam_per_arcsec2(REPO / "straylight" / "data" / "hst_zodi.fits")
    v = load_band(campaign.instrument_settings, "V")
    f_z = f_z * 10.0 ** (-0.4 * (CALSN_ZODIACAL_V_MAG - float(v.ab_magnitude(wl_z, f_z))))
    wl_e, f_e = _flam_per_arcsec2(EARTHSHINE)
    return (
        _e_per_s_per_pix(campaign, band, wl_z, f_z),
        _e_per_s_per_pix(campaign, band, wl_e, CALSN_EARTHSHINE_FRACTION * f_e),
    )


def _darkest_sky(campaign, band):
    """The default zodiacal light at the ecliptic pole (the darkest pointing), e-/s/pixel."""
    from straylight.sources.zodiacal import icrs_to_ecliptic_matrix

    pole = icrs_to_ecliptic_matrix().T @ np.array([0.0, 0.0, 1.0])
    zm = campaign_zodiacal(campaign)
    return float(np.ravel(zm.evaluate(band, pole, np.array([1.0, 0.0, 0.0]))["e_per_s_per_pix"])[0])


def campaign_zodiacal(campaign):
    from straylight.sources.zodiacal import zodiacal_model_from_instrument

    models = campaign.settings.models
    return zodiacal_model_from_instrument(
        campaign.instrument_settings, models.zodiacal_spectrum, models.zodiacal_reddening.as_tuple()
    )


def _depths(campaign):
    """Per band: (darkest-sky depth, depth with calSN's zodiacal light only, depth with calSN's
    whole sky), AB mag."""
    from straylight.limits.point_source import point_source_limit
    from straylight.optics.bandpass import load_band

    out = {}
    for b in campaign.bands:
        band = load_band(campaign.instrument_settings, b, campaign.instrument_path.parent)
        zodi, earth = _calsn_sky(campaign, band)
        out[b] = tuple(
            float(point_source_limit(sky, b, campaign))
            for sky in (_darkest_sky(campaign, band), zodi, zodi + earth)
        )
        print(
            f"{b:4s} darkest {out[b][0]:.3f}; calSN zodiacal {zodi:.4f} e-/s/pix -> {out[b][1]:.3f}; "
            f"+ earthshine {earth:.4f} -> {out[b][2]:.3f}; published {PUBLISHED_DEPTH_MAG[b]}"
        )
    return out


@pytest.mark.skipif(
    not EARTHSHINE.exists(), reason="../shared/data/hst_sky/earthshine.fits (HST) not present"
)
def test_the_darkest_and_calsn_skies_bracket_the_published_depths(campaign):
    """g r i z: the published depth lies between ours at the darkest sky (the ecliptic pole's
    zodiacal light, nothing else) and ours under calSN's sky (measured g 26.616 > 26.3 > 26.075,
    r 26.381 > 26.0 > 25.744, i 26.195 > 25.9 > 25.546, z 25.673 > 25.2 > 25.140): the sky
    assumed, not the noise model, separates our depths from the published ones."""
    depths = _depths(campaign)
    for b in "griz":
        dark, _, calsn = depths[b]
        assert dark > PUBLISHED_DEPTH_MAG[b] > calsn, b
    assert depths["g"][2] == pytest.approx(26.075, abs=0.01)
    assert depths["i"][2] == pytest.approx(25.546, abs=0.01)


# The published calculations' aperture and sky conventions are not given: at calSN's i-band sky
# an aperture of twice the EE80 pixels moves the depth by 0.36 mag, and 2 instead of 4 exposures
# NUV's by 0.40 (docs/assumptions.md), so 0.4 mag is what "reconciled" can mean here.
CALSN_TOLERANCE_MAG = 0.4


@pytest.mark.skipif(
    not EARTHSHINE.exists(), reason="../shared/data/hst_sky/earthshine.fits (HST) not present"
)
def test_depth_with_calsn_sky_against_qu_2023_and_gong_2019(campaign):
    """With calSN's sky (zodiacal V = 21.0 plus half of HST's high earthshine) our g and i depths
    are within CALSN_TOLERANCE_MAG of Qu et al. 2023 / Gong et al. 2019 (26.3, 25.9): measured
    26.075 (-0.225) and 25.546 (-0.354); with calSN's zodiacal light alone 26.108 and 25.576."""
    depths = _depths(campaign)
    for b in "gi":
        assert depths[b][2] == pytest.approx(PUBLISHED_DEPTH_MAG[b], abs=CALSN_TOLERANCE_MAG), b
        assert depths[b][1] == pytest.approx(PUBLISHED_DEPTH_MAG[b], abs=CALSN_TOLERANCE_MAG), b
    assert depths["g"][1] == pytest.approx(26.108, abs=0.01)
    assert depths["i"][1] == pytest.approx(25.576, abs=0.01)


@pytest.mark.skipif(
    not THROUGHPUT.exists(), reason="../shared/data/csst_throughput (test-only real CSST curves) not present"
)
def test_nuv_and_u_zero_points_are_wen_2024s_and_the_offset_range_is_gri_zs_spread(
    campaign, zero_point_less_real_curves_mag
):
    """NUV and u have no published zero point: the instrument file gives those of Wen et al.
    2024's curves (24.87, 25.30; the flat top at the peak gave 25.136 and 25.493).  The published
    g r i z zero points sit below the same curves by -0.088, -0.144, -0.108, +0.003 mag: their
    offset ranges reach +0.14 (Wen's curves' side), and NUV's, u's and y's reach at least -0.14
    (lower still where the published depth's residual needs it:
    test_the_single_input_that_closes_each_residual)."""
    d = zero_point_less_real_curves_mag
    print("AB zero point, default - Wen et al. 2024:", {b: round(v, 3) for b, v in d.items()})
    spread = -min(d[x] for x in "griz")
    assert spread == pytest.approx(0.14, abs=0.01)
    for b in ("NUV", "u", "y"):
        assert abs(d[b]) < 0.005, b
        low, high = campaign.instrument_settings.bands[b].zero_point_offset_mag.range
        assert high == 0.0 and low <= -spread + 0.01, b
    for b in "griz":
        low, high = campaign.instrument_settings.bands[b].zero_point_offset_mag.range
        assert low == 0.0 and high == pytest.approx(spread, abs=0.01), b
    assert max(d[x] for x in "griz") == pytest.approx(0.0, abs=0.01)


def test_the_zero_point_offset_moves_the_band(campaign):
    """bands.<b>.zero_point_offset_mag's value is added to the band's zero point (the envelope
    evaluates its range's ends this way): NUV at -0.14 has the zero point 24.73, and its darkest-
    sky depth (read-noise limited: the source and the sky scale alike) moves by -0.140 mag."""
    import dataclasses

    from straylight.limits.point_source import _limit_mag, survey_exposure
    from straylight.optics.bandpass import aperture_area_m2, load_band, zero_point_ab_mag

    inst = campaign.instrument_mapping()
    inst["bands"]["NUV"]["zero_point_offset_mag"]["value"] = -0.14
    area = aperture_area_m2(inst)
    assert zero_point_ab_mag(load_band(inst, "NUV"), area) == pytest.approx(24.73, abs=1e-6)
    band0 = load_band(campaign.instrument_settings, "NUV")
    band1 = load_band(inst, "NUV")
    x0 = survey_exposure(campaign, "NUV")
    x1 = dataclasses.replace(x0, zero_point_e_per_s=x0.zero_point_e_per_s * 10 ** (-0.4 * 0.14))
    d0 = float(_limit_mag(_darkest_sky(campaign, band0), x0))
    d1 = float(_limit_mag(_darkest_sky(campaign, band1), x1))
    print(f"NUV darkest-sky depth {d0:.3f} -> {d1:.3f} at a zero point 0.14 mag lower")
    assert d1 - d0 == pytest.approx(-0.14, abs=0.005)


@pytest.mark.skipif(
    not EARTHSHINE.exists(), reason="../shared/data/hst_sky/earthshine.fits (HST) not present"
)
def test_the_single_input_that_closes_each_residual(campaign):
    """Under calSN's sky, each of our inputs alone set to close the residual to Gong et al. 2019
    (docs/assumptions.md, "Reconciliation with Gong et al. 2019"): g r i z need a sky 0.38-0.85
    times calSN's (between it and the darkest sky: the sky explains them); NUV, u and y are
    shallower than ours even under calSN's sky and need a noise floor no sourced range reaches:
    read noise 7.1-7.5 e- (5 +/- 1), or the zero point 0.26-0.37 mag fainter, which is then
    their zero-point range's low end in the instrument file."""
    import dataclasses

    from scipy.optimize import brentq

    from straylight.limits.point_source import _limit_mag, survey_exposure
    from straylight.optics.bandpass import load_band

    found = {}
    for b in campaign.bands:
        band = load_band(campaign.instrument_settings, b, campaign.instrument_path.parent)
        sky = sum(_calsn_sky(campaign, band))
        x = survey_exposure(campaign, b)
        pub = PUBLISHED_DEPTH_MAG[b]

        def closes(f, lo, hi):
            return brentq(lambda v: float(f(v)) - pub, lo, hi)

        if b in "griz":  # ours shallower than published under calSN's sky: a darker sky
            found[b] = ("sky", closes(lambda f: _limit_mag(sky * f, x), 0.01, 1.0))
            continue

        def at_zp(d):
            return _limit_mag(
                sky * 10 ** (0.4 * d),
                dataclasses.replace(x, zero_point_e_per_s=x.zero_point_e_per_s * 10 ** (0.4 * d)),
            )

        zp = closes(at_zp, -2.0, 0.0)
        rn = closes(lambda r: _limit_mag(sky, dataclasses.replace(x, read_noise_e=r)), 5.0, 30.0)
        found[b] = ("zero point", zp, rn)
    print(found)
    for b in "griz":
        kind, f = found[b]
        dark = _darkest_sky(
            campaign, load_band(campaign.instrument_settings, b, campaign.instrument_path.parent)
        )
        band = load_band(campaign.instrument_settings, b, campaign.instrument_path.parent)
        calsn = sum(_calsn_sky(campaign, band))
        assert kind == "sky" and dark / calsn < f < 1.0, b
    for b in ("NUV", "u", "y"):
        _, zp, rn = found[b]
        assert 7.0 < rn < 7.6, b  # beyond the read noise's range, 4-6 e-
        low = campaign.instrument_settings.bands[b].zero_point_offset_mag.range[0]
        assert low == pytest.approx(zp, abs=0.01), b
