"""Scheduling tables for the survey planners (seed paper sects. 3.1-3.3 ask for
avoidance angles set by the stray light rather than fixed ones).

All three are computed against the darkest zodiacal background of each band (the Leinert 1998
table's minimum, at 500 nm scaled through the band), so they are conservative: on a brighter
zodiacal sky a smaller angle or exposure factor suffices.

* :func:`moon_avoidance_table`: the smallest Moon angle at which the Moon's stray light is below
  ``fraction`` of that background, per lunar phase angle and band.  Worst case over the PST's
  azimuth, door fully open (Sp = 1), Moon at its mean distance.
* :func:`bright_limb_table`: the smallest elevation above the Earth's limb at which the
  earthshine (direct + door) is below ``fraction`` of that background, per Sun zenith angle at
  the sub-satellite point and band, worst case over the line of sight's azimuth from the Sun;
  lines of sight closer than the Sun avoidance angle are left out.
* :func:`exposure_time_factor`: the exposure time needed to reach the nominal 5-sigma depth under
  a stray-light level, relative to the nominal time, from the limit equation of
  :mod:`straylight.limits.point_source` solved for the time: T = 25 (s + N_pix c) / s^2 with s the limiting
  source's signal rate and c = B + D + RN^2 / t per pixel.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from straylight.config import Campaign
from straylight.limits.point_source import SNR, survey_exposure
from straylight.model import BackgroundModel
from straylight.sources.body_magnitudes import MOON_MEAN_DISTANCE_KM, moon_v_magnitude

__all__ = [
    "moon_avoidance_table",
    "bright_limb_table",
    "exposure_time_factor",
    "exposure_factor_table",
    "write_tables",
]


def _pst_max_over_phi(model: BackgroundModel, theta_deg: np.ndarray) -> np.ndarray:
    phi = np.linspace(0.0, 360.0, 145)
    return model.offfield.pst(np.asarray(theta_deg)[:, None], phi[None, :]).max(axis=1)


def moon_avoidance_table(
    model: BackgroundModel, fraction: float = 0.1, phase_step_deg: float = 10.0, theta_step_deg: float = 0.25
) -> dict:
    """Columns phase_angle_deg, illuminated_fraction and min_moon_angle_deg_<band> (deg).

    Parameters
    ----------
    model : BackgroundModel
        The campaign's model (PST, photometry, darkest zodiacal background per band).
    fraction : float, optional
        The Moon's stray light must stay below this fraction of the darkest zodiacal rate.
    phase_step_deg : float, optional
        Step of the lunar phase angle over [0, 180] deg (0 = full Moon), deg.
    theta_step_deg : float, optional
        Step of the Moon angle searched over [0, 180] deg, deg.

    Returns
    -------
    dict of str to ndarray, each shape (n_phase,)
        ``phase_angle_deg`` (deg), ``illuminated_fraction`` (0 to 1) and, per band,
        ``min_moon_angle_deg_<band>``: the smallest Moon angle from which the Moon stays below
        the limit, deg (0 where it never exceeds it).
    """
    phases = np.arange(0.0, 180.0 + phase_step_deg / 2, phase_step_deg)
    theta = np.arange(0.0, 180.0 + theta_step_deg / 2, theta_step_deg)
    transfer = (
        _pst_max_over_phi(model, theta)
        * model.offfield.pixel_area_m2
        * (theta > model.offfield.field_radius_deg)
    )
    out = {"phase_angle_deg": phases, "illuminated_fraction": (1 + np.cos(np.radians(phases))) / 2}
    v = moon_v_magnitude(
        phases, np.full(phases.size, MOON_MEAN_DISTANCE_KM), model.offfield.moon_law, 180.0 - phases
    )
    for b in model.campaign.bands:
        limit = fraction * model.darkest_zodiacal_e_per_s(b)
        irr = model.photometry(b).solar_like_from_v(v)  # photons s-1 m-2
        rate = irr[:, None] * transfer[None, :]  # (phase, theta)
        # the smallest angle beyond which the Moon stays below the limit at every larger angle
        above = rate > limit
        last = np.where(above.any(axis=1), theta.size - 1 - np.argmax(above[:, ::-1], axis=1), -1)
        out[f"min_moon_angle_deg_{b}"] = np.where(last >= 0, theta[np.minimum(last + 1, theta.size - 1)], 0.0)
    return out


def bright_limb_table(
    model: BackgroundModel,
    fraction: float = 0.1,
    sun_zenith_step_deg: float = 10.0,
    azimuth_step_deg: float = 30.0,
    elevation_step_deg: float = 1.0,
    terminator_step_deg: float = 1.0,
) -> dict:
    """Columns sun_zenith_deg and min_limb_elevation_deg_<band> (deg above the limb): the lowest
    elevation, itself clear of the Sun avoidance angle, from which every line of sight that
    clears it stays below the limit, worst case over azimuth; inf where no such elevation exists
    within 90 deg of the limb, NaN where no line of sight clears the Sun avoidance angle.  Sun
    zenith angles every ``sun_zenith_step_deg`` up to 90 deg, then every ``terminator_step_deg``
    until the visible cap is dark (the limb's zenith angle, ~110 deg at 400 km), where the
    answer changes fastest.

    Parameters
    ----------
    model : BackgroundModel
        The campaign's model (orbit radius, Earth, constraints, door states, photometry).
    fraction : float, optional
        The earthshine must stay below this fraction of the darkest zodiacal rate.
    sun_zenith_step_deg : float, optional
        Step of the Sun zenith angle below 90 deg, deg.
    azimuth_step_deg : float, optional
        Step of the line of sight's azimuth from the Sun over [0, 180] deg, deg.
    elevation_step_deg : float, optional
        Step of the elevation above the limb over [0, 90] deg, deg.
    terminator_step_deg : float, optional
        Step of the Sun zenith angle from 90 deg to the limb's zenith angle, deg.

    Returns
    -------
    dict of str to ndarray, each shape (n_zenith,)
        ``sun_zenith_deg`` (deg) and, per band, ``min_limb_elevation_deg_<band>`` (deg above
        the limb; inf and NaN as above).
    """
    c: Campaign = model.campaign
    r = 0.5 * sum(c.orbit_radius_range_km)
    limb_zeta = 90.0 + np.degrees(np.arccos(c.earth.radius_km / r))
    zs = np.concatenate(
        [
            np.arange(0.0, 90.0 - 1e-9, sun_zenith_step_deg),
            np.arange(90.0, np.ceil(limb_zeta) + terminator_step_deg / 2, terminator_step_deg),
        ]
    )
    az = np.arange(0.0, 180.0 + azimuth_step_deg / 2, azimuth_step_deg)
    h = np.arange(0.0, 90.0 + elevation_step_deg / 2, elevation_step_deg)
    Z, A, H = np.meshgrid(zs, az, h, indexing="ij")
    L = limb_zeta - H
    door = _door_opening_deg(_sun_angle_deg(Z, L, A), c.constraints)
    coeff = model.sunlit_earth_coefficients(r, Z, L, A, door)  # NaN: no door state allowed
    out = {"sun_zenith_deg": zs}
    albedo = model.earth_band_factors(c.bands)  # the Earth's band albedo / grey
    for ib, b in enumerate(c.bands):
        limit = fraction * model.darkest_zodiacal_e_per_s(b)
        rate = coeff * model.photometry(b).sun_at_1au_photons_s_m2  # e-/s/pix, Sun at 1 AU
        rate = rate if albedo is None else rate * float(albedo[ib])
        out[f"min_limb_elevation_deg_{b}"] = _lowest_clear_elevation(rate, limit, ~np.isnan(coeff), h)
    return out


def _sun_angle_deg(Z, L, A):
    """The angle between the line of sight and the Sun, deg, from their zenith angles ``Z``
    (Sun), ``L`` (line of sight) and the azimuth ``A`` between them (deg)."""
    cos_sun = np.cos(np.radians(Z)) * np.cos(np.radians(L)) + np.sin(np.radians(Z)) * np.sin(
        np.radians(L)
    ) * np.cos(np.radians(A))
    return np.degrees(np.arccos(np.clip(cos_sun, -1, 1)))


def _door_opening_deg(sun_angle, constraints):
    """The door's opening (deg; 0: no state allowed) at each Sun angle (deg)."""
    door = np.zeros(sun_angle.shape)
    for st in sorted(constraints.door_states, key=lambda s: s.sun_angle_min_deg):
        ok = (sun_angle >= st.sun_angle_min_deg) if st.min_inclusive else (sun_angle > st.sun_angle_min_deg)
        door = np.where(ok, st.opening_deg, door)
    return door


def _lowest_clear_elevation(rate, limit, allowed, h):
    """Per Sun zenith (first axis of ``rate`` (zenith, azimuth, elevation), e-/s/pix): the
    lowest allowed elevation (``h``, deg) from which every allowed, higher line of sight stays
    below ``limit``, worst case over azimuth; inf where none within 90 deg of the limb, NaN
    where no line of sight is allowed."""
    bad = ~(rate <= limit)  # too bright, or not allowed (NaN)
    need = np.full(rate.shape[0], np.nan)
    for i in range(rate.shape[0]):
        worst = 0.0
        for j in range(rate.shape[1]):
            if not allowed[i, j].any():
                continue
            # the lowest allowed elevation from which every allowed, higher line of sight stays
            # below the limit (inf: none within 90 deg of the limb).  The node above the last
            # bright one can lie inside the Sun's avoidance cone: that is no answer (with the
            # Sun overhead the cone starts 50 deg from the zenith, and every allowed line of
            # sight below it is too bright).
            k = np.flatnonzero(bad[i, j] & allowed[i, j])
            if k.size:
                above = k[-1] + 1 + np.flatnonzero(allowed[i, j, k[-1] + 1 :])
                worst = max(worst, h[above[0]] if above.size else np.inf)
        need[i] = worst if allowed[i].any() else np.nan
    return need


def exposure_time_factor(
    stray_e_per_s, nominal_background_e_per_s, band: str, campaign: Campaign
) -> np.ndarray:
    """Exposure time to reach the nominal 5-sigma depth with ``stray_e_per_s`` added to the
    nominal background, over the nominal time (1 when there is no stray light).  The number of
    exposures grows with the time (read noise per exposure of the band's length).

    Parameters
    ----------
    stray_e_per_s : array_like of float, any shape
        Stray light added to the background, e-/s/pix.
    nominal_background_e_per_s : float or array_like broadcasting with it
        Nominal background, e-/s/pix.
    band : str
        A band of the instrument (with survey exposures).
    campaign : Campaign
        Loaded campaign.

    Returns
    -------
    ndarray of float, the broadcast shape
        Exposure time needed over the nominal time (>= 1).
    """
    x = survey_exposure(campaign, band)
    c0 = nominal_background_e_per_s + x.dark_e_per_s + x.read_noise_e**2 / x.exposure_s
    n_b = x.n_pix * c0 * x.total_s
    s = (
        (SNR**2 + np.sqrt(SNR**4 + 4 * SNR**2 * n_b)) / 2.0 / x.total_s
    )  # limiting source, e-/s in the aperture
    c = (
        nominal_background_e_per_s
        + np.asarray(stray_e_per_s, float)
        + x.dark_e_per_s
        + x.read_noise_e**2 / x.exposure_s
    )
    t_needed = SNR**2 * (s + x.n_pix * c) / s**2  # the encircled-energy fraction cancels in the ratio
    return t_needed / x.total_s


def exposure_factor_table(model: BackgroundModel, ratios=(0.0, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0)) -> dict:
    """Columns stray_to_zodiacal_ratio and exposure_time_factor_<band> at the darkest zodiacal sky.

    Parameters
    ----------
    model : BackgroundModel
        The campaign's model.
    ratios : sequence of float, optional
        Stray light over the darkest zodiacal rate (dimensionless).

    Returns
    -------
    dict of str to ndarray, each shape (n_ratio,)
        ``stray_to_zodiacal_ratio`` and, per band, ``exposure_time_factor_<band>``
        (:func:`exposure_time_factor`).
    """
    r = np.asarray(ratios, float)
    out = {"stray_to_zodiacal_ratio": r}
    for b in model.campaign.bands:
        z = model.darkest_zodiacal_e_per_s(b)
        out[f"exposure_time_factor_{b}"] = exposure_time_factor(r * z, z, b, model.campaign)
    return out


class _TableSpec(NamedTuple):
    """A scheduling table and how it is drawn: its columns, the x column's name, the y columns'
    prefix (followed by the band) and the axes' labels (with their units)."""

    columns: dict
    x: str
    prefix: str
    xlabel: str
    ylabel: str


def write_tables(model: BackgroundModel, out_dir, fraction: float = 0.1) -> list:
    """The three tables as CSV and PNG in ``out_dir``; returns the written paths.

    Parameters
    ----------
    model : BackgroundModel
        The campaign's model.
    out_dir : str or path-like
        Folder for the files (created if missing).
    fraction : float, optional
        Fraction of the darkest zodiacal rate for the Moon and limb tables.

    Returns
    -------
    list of pathlib.Path
        ``moon_avoidance``, ``bright_limb`` and ``exposure_factor``, each ``.csv`` then ``.png``.
    """
    from pathlib import Path

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    tables = {
        "moon_avoidance": _TableSpec(
            moon_avoidance_table(model, fraction),
            "phase_angle_deg",
            "min_moon_angle_deg_",
            "lunar phase angle (deg; 0 = full)",
            "Moon angle needed (deg)",
        ),
        "bright_limb": _TableSpec(
            bright_limb_table(model, fraction),
            "sun_zenith_deg",
            "min_limb_elevation_deg_",
            "Sun zenith angle at the sub-satellite point (deg)",
            "elevation above the limb needed (deg)",
        ),
        "exposure_factor": _TableSpec(
            exposure_factor_table(model),
            "stray_to_zodiacal_ratio",
            "exposure_time_factor_",
            "stray light / darkest zodiacal light",
            "exposure time / nominal",
        ),
    }
    written = []
    for name, spec in tables.items():
        csv, png = out_dir / f"{name}.csv", out_dir / f"{name}.png"
        _write_table_csv(csv, name, spec.columns, fraction)
        _plot_table(png, name, spec, model.campaign.bands, fraction)
        written += [csv, png]
    return written


def _write_table_csv(path, name: str, columns: dict, fraction: float) -> None:
    """One table as CSV, its name and the fraction of the darkest zodiacal light in a comment."""
    from astropy.table import Table

    from straylight.util.io import atomic_path

    t = Table(columns)
    t.meta["comments"] = [
        f"straylight scheduling table {name}; fraction of the darkest zodiacal light: {fraction}"
    ]
    with atomic_path(path) as tmp:
        t.write(tmp, format="ascii.csv", overwrite=True)


def _plot_table(path, name: str, spec: _TableSpec, bands, fraction: float) -> None:
    """One table drawn as PNG: a line per band against its x column."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from straylight.util.io import atomic_path

    cols, x, prefix = spec.columns, spec.x, spec.prefix
    fig, ax = plt.subplots(figsize=(6, 4))
    for b in bands:
        ax.plot(cols[x], cols[prefix + b], marker="o", ms=3, label=b)
    if name == "exposure_factor":
        ax.set_xscale("symlog", linthresh=0.01)
    if name == "bright_limb":  # inf draws nothing: shade where no elevation works in some band
        _shade_never(ax, spec, bands)
    ax.set_xlabel(spec.xlabel)
    ax.set_ylabel(spec.ylabel)
    ax.set_title(
        f"{name.replace('_', ' ')} (stray light <= {fraction:g} x darkest zodiacal)"
        if name != "exposure_factor"
        else "exposure time to reach the nominal depth"
    )
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def _shade_never(ax, spec: _TableSpec, bands) -> None:
    """Grey spans over the x nodes where some band's value is inf (no elevation works), each
    node's span reaching halfway to its neighbours."""
    cols, x, prefix = spec.columns, spec.x, spec.prefix
    never = np.any([np.isinf(cols[prefix + b]) for b in bands], axis=0)
    xs = np.asarray(cols[x], float)
    mid = (xs[1:] + xs[:-1]) / 2  # each node's span reaches halfway to its neighbours
    edges = np.concatenate(
        [
            [xs[0] - (mid[0] - xs[0] if mid.size else 0.5)],
            mid,
            [xs[-1] + (xs[-1] - mid[-1] if mid.size else 0.5)],
        ]
    )
    for k, i in enumerate(np.flatnonzero(never)):
        ax.axvspan(
            edges[i],
            edges[i + 1],
            color="0.88",
            lw=0,
            label=None if k else "no elevation works (inf)",
        )
