"""Independent checks of the modelled earthshine's angular shape (docs/pst.md, "Independent
checks"): none of them sets a parameter.

* **The limb profile**: per sunlit orbital phase, the binned median earthshine against the
  bright-limb angle (:func:`~straylight.paper.tail_calibration.phase_crossings`'s bins), then the
  median over the phases of each bin (:func:`limb_profile`).
* **HST's shape**: the profile's fall per degree against HST's WFC3 curve over the same angles,
  and the ratios at 24, 38 and 50 deg against the HST ETC's (about 2 : 1 : 0.5)
  (:func:`shape_against_hst`).
* **The paper's sect. 1**: its preliminary 80-deg bright-limb avoidance, and the 50-80 deg
  range where a longer exposure improves the signal-to-noise ratio (:func:`sect1_figures`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["HST_ETC_RATIOS", "limb_profile", "profile_mag_at", "shape_against_hst", "sect1_figures"]

#: the HST ETC's earthshine at 24, 38 and 50 deg from the bright limb relative to 38 deg (about
#: 2 : 1 : 0.5; the ETC's "high", "average" and "low" earthshine levels' limb angles)
HST_ETC_RATIOS = {24.0: 2.0, 38.0: 1.0, 50.0: 0.5}


def limb_profile(bins, lo_deg: float = 0.0, hi_deg: float = 180.0) -> dict:
    """The median over phases of each phase's binned median earthshine.

    Parameters
    ----------
    bins : sequence of (centres, medians, counts)
        Per phase: bin centres (deg), median earthshine (mag/arcsec2; inf where 0), pointings
        (:func:`~straylight.paper.tail_calibration.phase_crossings`'s ``bins``).
    lo_deg, hi_deg : float
        Keep bin centres within [lo_deg, hi_deg], deg.

    Returns
    -------
    dict
        ``centre_deg`` (deg), ``median_mag`` (mag/arcsec2, the median over the phases with
        pointings in the bin), ``phases`` (how many).
    """
    table: dict = {}
    for c, m, _ in bins:
        for x, y in zip(np.asarray(c, float), np.asarray(m, float)):
            if lo_deg <= x <= hi_deg:
                table.setdefault(round(float(x), 6), []).append(y)
    centres = np.array(sorted(table))
    return {
        "centre_deg": centres,
        "median_mag": np.array([np.median(table[c]) for c in centres]),
        "phases": np.array([len(table[c]) for c in centres]),
    }


def profile_mag_at(profile: dict, angles_deg) -> np.ndarray:
    """The profile at ``angles_deg`` (deg), linear in magnitude between bin centres,
    mag/arcsec2.

    Parameters
    ----------
    profile : dict
        ``centre_deg`` (bin centres, deg) and ``median_mag`` (mag/arcsec2).
    angles_deg : array_like
        Bright-limb angles, deg.

    Returns
    -------
    ndarray
        mag/arcsec2.
    """
    return np.interp(np.asarray(angles_deg, float), profile["centre_deg"], profile["median_mag"])


def shape_against_hst(
    profile: dict, hst_angle_deg, hst_mag, lo_deg: float = 20.0, hi_deg: float = 90.0
) -> dict:
    """The profile's shape against HST's curve.

    Parameters
    ----------
    profile : dict
        :func:`limb_profile`'s.
    hst_angle_deg, hst_mag : array_like
        HST's curve: limb angle (deg) and V mag/arcsec2.
    lo_deg, hi_deg : float
        The angles compared, deg.

    Returns
    -------
    dict
        ``slope_mag_per_deg`` and ``hst_slope_mag_per_deg`` (least-squares fall per degree over
        the bin centres within [lo, hi] and HST's curve at the same angles; positive: fainter
        outwards), ``slope_ratio`` (model / HST), ``ratios`` (model's earthshine at 24, 38, 50 deg
        relative to 38 deg), ``hst_curve_ratios`` (HST's curve's), ``hst_etc_ratios``
        (:data:`HST_ETC_RATIOS`), ``ratio_24_38`` and ``ratio_38_50`` for both.
    """
    c = profile["centre_deg"]
    sel = (c >= lo_deg) & (c <= hi_deg) & np.isfinite(profile["median_mag"])
    x, y = c[sel], profile["median_mag"][sel]
    h = np.interp(x, np.asarray(hst_angle_deg, float), np.asarray(hst_mag, float))
    slope = float(np.polyfit(x, y, 1)[0])
    hst_slope = float(np.polyfit(x, h, 1)[0])
    angles = np.array(sorted(HST_ETC_RATIOS))
    m = profile_mag_at(profile, angles)
    hm = np.interp(angles, np.asarray(hst_angle_deg, float), np.asarray(hst_mag, float))
    ratio = 10.0 ** (-0.4 * (m - m[1]))
    hratio = 10.0 ** (-0.4 * (hm - hm[1]))
    return {
        "angles_deg": [lo_deg, hi_deg],
        "slope_mag_per_deg": slope,
        "hst_slope_mag_per_deg": hst_slope,
        "slope_ratio": slope / hst_slope,
        "ratios": {f"{a:g}": float(r) for a, r in zip(angles, ratio)},
        "hst_curve_ratios": {f"{a:g}": float(r) for a, r in zip(angles, hratio)},
        "hst_etc_ratios": {f"{a:g}": v for a, v in HST_ETC_RATIOS.items()},
        "ratio_24_38": float(ratio[0] / ratio[1]),
        "ratio_38_50": float(ratio[1] / ratio[2]),
        "hst_curve_ratio_24_38": float(hratio[0] / hratio[1]),
        "hst_curve_ratio_38_50": float(hratio[1] / hratio[2]),
    }


def sect1_figures(profile: dict, crossing_deg, level_mag: float, zodiacal_v_mag=(22.5, 23.3)) -> dict:
    """The figures for the paper's sect. 1 statements.

    Parameters
    ----------
    profile : dict
        :func:`limb_profile`'s.
    crossing_deg : array_like
        Each sunlit phase's crossing (deg; NaN: never).
    level_mag : float
        HST's earthshine at its 20-deg limit, V mag/arcsec2.
    zodiacal_v_mag : tuple of float
        The zodiacal light's V surface brightness at the survey's dark pointings, brightest and
        faintest, mag/arcsec2.

    Returns
    -------
    dict
        ``share_crossing_by_80_deg`` (the share of sunlit phases whose crossing is at most 80
        deg: the preliminary 80-deg avoidance is conservative where it is large),
        ``profile_mag_at`` (the profile at 50, 70, 80 deg), ``earthshine_over_zodi`` (the
        profile over the zodiacal light at 50 and 80 deg, [vs the brightest, vs the faintest]),
        ``exposure_factor_at_50_deg`` (the exposure that restores the dark sky's depth when
        background-limited: 1 + earthshine / zodi, vs the brightest and faintest zodi).
    """
    cr = np.where(np.isnan(np.asarray(crossing_deg, float)), np.inf, np.asarray(crossing_deg, float))
    m = profile_mag_at(profile, [50.0, 70.0, 80.0])
    over = {
        f"{a:g}": [float(10.0 ** (-0.4 * (mm - z))) for z in zodiacal_v_mag]
        for a, mm in zip((50, 80), m[[0, 2]])
    }
    return {
        "share_crossing_by_80_deg": float(np.mean(cr <= 80.0)),
        "level_v_mag_per_arcsec2": float(level_mag),
        "profile_mag_at": {"50": float(m[0]), "70": float(m[1]), "80": float(m[2])},
        "earthshine_over_zodi": over,
        "exposure_factor_at_50_deg": [1.0 + r for r in over["50"]],
        "zodiacal_v_mag_per_arcsec2": list(zodiacal_v_mag),
    }
