"""5-sigma point-source limiting magnitudes.

For a band with n exposures of t seconds (total T = n t), a point source of AB magnitude m gives
S = f80 F(m) T electrons inside the 80 % encircled-energy aperture (radius r80, N_pix pixels),
with F(m) = 10^(-0.4 m) ZP pi D^2 / 4 and ZP the band's AB photon zero point.  The noise is
sigma^2 = S + N_pix (B T + D T + n RN^2), B the sky + stray-light rate (e-/s/pix), D the dark
current and RN the read noise.  The 5-sigma limit solves S = 5 sigma:
    S = (25 + sqrt(625 + 100 N_b)) / 2,   N_b = N_pix (B T + D T + n RN^2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from straylight.config import Campaign

__all__ = [
    "EE_FRACTION",
    "SNR",
    "ZERO_POINT_NAME",
    "SurveyExposure",
    "aperture_noise_e2",
    "band_limits",
    "campaign_exposures",
    "point_source_limit",
    "sky_zero_points",
    "source_rate_e_per_s",
    "survey_exposure",
    "zero_point_coord",
]

EE_FRACTION = 0.8
SNR = 5.0


@dataclass(frozen=True)
class SurveyExposure:
    """A band's survey exposures and the detector noise terms (from the instrument config)."""

    n_exposures: int
    exposure_s: float
    read_noise_e: float
    dark_e_per_s: float
    n_pix: float  # pixels in the 80 % encircled-energy aperture
    zero_point_e_per_s: float  # AB mag 0 source, e-/s through the whole aperture

    @property
    def total_s(self) -> float:
        """Total survey exposure of the band, n_exposures x exposure_s, s."""
        return self.n_exposures * self.exposure_s


def _derived(campaign: Campaign, key: tuple, compute):
    """``compute()``, kept on the campaign under ``key``: a value derived from its config alone
    (a campaign is not changed once loaded), computed once however often it is asked for."""
    memo = campaign.__dict__.setdefault("_derived", {})
    if key not in memo:
        memo[key] = compute()
    return memo[key]


def survey_exposure(campaign: Campaign, band_name: str) -> SurveyExposure:
    """The band's survey exposures and the noise model's inputs (:class:`SurveyExposure`),
    computed once per campaign and band.

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign (instrument config, pixel scale).
    band_name : str
        A band of the instrument.

    Returns
    -------
    SurveyExposure
        Exposure count, exposure time (s), read noise (e-), dark current (e-/s), pixels in the
        EE80 aperture, and the AB mag 0 rate through the whole aperture (e-/s).
    """
    return _derived(campaign, ("survey_exposure", band_name), lambda: _survey_exposure(campaign, band_name))


def _survey_exposure(campaign: Campaign, band_name: str) -> SurveyExposure:
    # bandpass (scipy's erf) where it is used: the workflow's parse imports this module
    from straylight.optics.bandpass import load_band

    inst = campaign.instrument_settings
    b = inst.bands[band_name]
    r80 = inst.detector.ee80_radius_arcsec.value / campaign.pixel_scale_arcsec
    band = load_band(inst, band_name, campaign.instrument_path.parent)
    zp_e = band.ab_zero_point_photons_s_m2 * np.pi * inst.telescope.aperture_diameter_m.value**2 / 4
    return SurveyExposure(
        int(b.n_exposures),
        float(b.exposure_s),
        inst.detector.read_noise_e.value,
        inst.detector.dark_current_e_per_s.value,
        np.pi * r80**2,
        zp_e,
    )


#: name of the (band) coordinate of background.zarr and limits.zarr holding each band's zero point
ZERO_POINT_NAME = "mag_zero_point"


def sky_zero_points(campaign: Campaign, bands=None) -> dict:
    """Each band's AB surface-brightness zero point, mag/arcsec2 at 1 e-/s/pixel (see
    :func:`straylight.sources.photometry.sky_zero_point_mag_per_arcsec2`): the instrument's throughput,
    aperture and pixel scale, nothing else.

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign.
    bands : list of str, optional
        Bands; None: every band of the campaign.

    Returns
    -------
    dict of str to float
        Band to zero point, AB mag/arcsec2 (mag/arcsec2 = zp - 2.5 log10(rate in e-/s/pix)).
    """
    from straylight.optics.bandpass import load_band
    from straylight.sources.photometry import sky_zero_point_mag_per_arcsec2

    inst = campaign.instrument_settings
    d = inst.telescope.aperture_diameter_m.value
    pix = campaign.pixel_scale_arcsec

    def zero_point(b):
        return sky_zero_point_mag_per_arcsec2(load_band(inst, b, campaign.instrument_path.parent), d, pix)

    return {
        b: _derived(campaign, ("sky_zero_point", b), lambda b=b: zero_point(b))
        for b in (bands or campaign.bands)
    }


def zero_point_coord(campaign: Campaign, bands) -> tuple:
    """The products' ``mag_zero_point`` (band) coordinate: mag/arcsec2 = zp - 2.5 log10(e-/s/pixel).

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign.
    bands : sequence of str, shape (n_band,)
        The product's bands, in its order.

    Returns
    -------
    tuple
        ``("band", values, attrs)`` for an xarray coordinate: values float64, shape (n_band,),
        AB mag/arcsec2 at 1 e-/s/pixel; attrs its ``units`` and ``long_name``.
    """
    zp = sky_zero_points(campaign, [str(b) for b in bands])
    return (
        "band",
        np.array([zp[str(b)] for b in bands], dtype=np.float64),
        {
            "units": "mag(AB) arcsec-2",
            "long_name": "AB surface brightness of a background of 1 e-/s/pixel; "
            "mag_per_arcsec2 = mag_zero_point - 2.5 log10(rate / (electron / (s pixel)))",
        },
    )


def point_source_limit(background_e_per_s_per_pix, band_name: str, campaign: Campaign) -> np.ndarray:
    """5-sigma AB limiting magnitude for the band's survey exposures at the given background.

    Parameters
    ----------
    background_e_per_s_per_pix : array_like of float, any shape
        Sky + stray-light rate, e-/s/pix.
    band_name : str
        A band of the instrument (not ``"V"``, which has no survey exposures).
    campaign : Campaign
        Loaded campaign.

    Returns
    -------
    ndarray of float, same shape as the background
        Limiting magnitude, mag(AB), in the EE80 aperture.
    """
    return _limit_mag(background_e_per_s_per_pix, survey_exposure(campaign, band_name))


def aperture_noise_e2(background_e_per_s_per_pix, total_s, x: SurveyExposure, n_exposures=None):
    """The CCD equation's variance in the EE80 aperture apart from the source's own shot noise,
    N_b = N_pix (B T + D T + n RN^2), e-^2: sky + stray light, dark current, and the read noise
    once per exposure.  The one noise model of the limits and of the exposure-time calculator
    (:mod:`straylight.planning.exposure_time`).

    Parameters
    ----------
    background_e_per_s_per_pix : array_like of float, any shape
        Sky + stray-light rate B, e-/s/pix.
    total_s : float or array_like, broadcast against the background
        Total exposure time T of all exposures, s.
    x : SurveyExposure
        The band's aperture (N_pix), dark current D (e-/s/pix) and read noise RN (e-).
    n_exposures : int or array_like, optional
        Exposures n the time is split into (read noise counted once each); None: the band's
        survey count, ``x.n_exposures``.

    Returns
    -------
    ndarray of float, broadcast shape
        N_b, e-^2.
    """
    n = x.n_exposures if n_exposures is None else n_exposures
    bkg = np.asarray(background_e_per_s_per_pix, dtype=float)
    return x.n_pix * (bkg * total_s + x.dark_e_per_s * total_s + n * x.read_noise_e**2)


def source_rate_e_per_s(mag_ab, x: SurveyExposure):
    """Electrons per second a point source of AB magnitude ``mag_ab`` puts in the EE80 aperture:
    EE_FRACTION x 10^(-0.4 m) x the band's AB mag-0 rate through the telescope.

    Parameters
    ----------
    mag_ab : array_like of float
        Source AB magnitude.
    x : SurveyExposure
        The band's zero point (``zero_point_e_per_s``).

    Returns
    -------
    ndarray of float, shape of ``mag_ab``
        Source rate in the aperture, e-/s.
    """
    return EE_FRACTION * x.zero_point_e_per_s * 10.0 ** (-0.4 * np.asarray(mag_ab, dtype=float))


def _limit_mag(background_e_per_s_per_pix, x: SurveyExposure) -> np.ndarray:
    """5-sigma AB limiting magnitude for the exposures ``x`` at the background (e-/s/pix)."""
    t_tot = x.total_s
    n_b = aperture_noise_e2(background_e_per_s_per_pix, t_tot, x)
    s = (SNR**2 + np.sqrt(SNR**4 + 4 * SNR**2 * n_b)) / 2.0
    return -2.5 * np.log10(s / (EE_FRACTION * t_tot * x.zero_point_e_per_s))


def band_limits(total_e_per_s_per_pix, exposures) -> np.ndarray:
    """5-sigma AB limiting magnitudes, float32, of a (..., band) background (e-/s/pix) whose
    last axis is the bands of ``exposures`` (:func:`survey_exposure` each, in that order): the
    one way the products compute a limit (the cube's workers for limits.zarr, and
    :func:`straylight.limits.cube.limits_dataset`).

    Parameters
    ----------
    total_e_per_s_per_pix : ndarray, shape (..., n_band)
        Total background, e-/s/pix.
    exposures : sequence of SurveyExposure, length n_band
        Each band's exposures, in the order of the last axis.

    Returns
    -------
    ndarray of float32, shape (..., n_band)
        Limiting magnitudes, mag(AB).
    """
    out = np.empty(np.shape(total_e_per_s_per_pix), np.float32)
    for ib, x in enumerate(exposures):
        out[..., ib] = _limit_mag(total_e_per_s_per_pix[..., ib], x)
    return out


_EXPOSURES: dict = {}


def campaign_exposures(campaign: Campaign, bands=None) -> list:
    """Each band's :func:`survey_exposure` (the campaign's bands by default), kept per campaign
    object: loading the throughput curves reads and integrates files, and the cube's workers
    need them for every region.

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign.
    bands : sequence of str, optional
        Bands; None: every band of the campaign.

    Returns
    -------
    list of SurveyExposure
        One per band, in the order of ``bands``.
    """
    bands = tuple(str(b) for b in (campaign.bands if bands is None else bands))
    kept = _EXPOSURES.get((id(campaign), bands))
    if kept is None or kept[0] is not campaign:
        kept = (campaign, [survey_exposure(campaign, b) for b in bands])
        _EXPOSURES.clear()
        _EXPOSURES[(id(campaign), bands)] = kept
    return kept[1]
