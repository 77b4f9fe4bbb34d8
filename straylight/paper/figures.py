"""The seed paper's in-field figures reproduced (``straylight figure NAME``), each from the
pipeline's own models, with the numbers the paper states about it:

* ``zodiacal-map`` (sect. 4.1): the all-sky zodiacal light in V on 2026-01-01 00:50 UTC, the
  Sun marked; the paper's Table 1 quotes the zodiacal light as ~3e-18 erg s-1 cm-2 A-1 arcsec-2
  (V ~22.7 mag/arcsec2, HST's "average" zodiacal light).
* ``scattering`` (sect. 4.2): the Harvey-Shack mirror scattering against the distance from the
  image, with the PSF core and their blend; TIS ~2 % per mirror, ~1e-4 of the image's peak at
  10 pixels and ~1e-6 at 100 pixels (sect. 4.4).
* ``ghosts`` (sect. 4.3): the NUV ghost example (D1 = 5 mm, D2 = 8 mm, T = 0.825, R = 0.0093,
  Rd = 0.15, 3.9 deg): ghosts at or below ~1e-6 of the star image.
* ``detector`` (sect. 4.4): a part of an NUV detector with the scattering halos and ghosts of
  the catalog's stars.

The CSST-versus-HST earthshine figure of sect. 3.3 is ``straylight scenario``.
Each ``*_data`` function returns the numbers (tested in tests/paper/test_paper_figures.py); each
``plot_*`` draws them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from straylight.config import Campaign, needed

__all__ = [
    "FIGURE_TIME",
    "FIGURES",
    "NUV_GHOST_EXAMPLE",
    "FLAM_ARCSEC2_TABLE1",
    "zodiacal_map_data",
    "plot_zodiacal_map",
    "scattering_data",
    "plot_scattering",
    "ghost_example_data",
    "plot_ghosts",
    "detector_image_data",
    "plot_detector_image",
    "make_figure",
    "DETECTOR_STAR_RADEC_DEG",
    "detector_catalog",
]

FIGURE_TIME = "2026-01-01T00:50:00"  # the paper's scenario time (sects. 3.3, 4.1)
FIGURES = ("zodiacal-map", "scattering", "ghosts", "detector")
# paper sect. 4.3: the NUV example's ghost parameters
NUV_GHOST_EXAMPLE = dict(
    d1_mm=5.0, d2_mm=8.0, t1=0.825, t2=0.825, r1=0.0093, r2=0.0093, rd=0.15, incidence_deg=3.9
)
FLAM_ARCSEC2_TABLE1 = 3e-18  # erg s-1 cm-2 A-1 arcsec-2, the paper's Table 1 zodiacal light


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


# -- sect. 4.1 ----------------------------------------------------------------------------------
def zodiacal_map_data(campaign: Campaign, time: str = FIGURE_TIME, nside: int = 64) -> dict:
    """V-band zodiacal light (AB mag/arcsec2) on a HEALPix grid (ICRS, RING) seen from the
    Earth's centre at ``time``; NaN where the Leinert table has no data (near the Sun).

    Parameters
    ----------
    campaign : Campaign
        The campaign (its models and instrument).
    time : str, optional
        The time, UTC ISO (default :data:`FIGURE_TIME`).
    nside : int, optional
        The HEALPix grid's nside (default 64).
    """
    import healpy as hp

    from straylight.optics.bandpass import load_band
    from straylight.sky.observing import scene
    from straylight.sky.vectors import unit
    from straylight.sources.zodiacal import zodiacal_model_from_instrument

    sun = unit(np.asarray(scene(campaign.orbit, time).bodies_km["sun"][0], float))  # geocentric
    x, y, z = hp.pix2vec(nside, np.arange(hp.nside2npix(nside)))
    los = np.stack([x, y, z], axis=-1)
    zm = zodiacal_model_from_instrument(campaign.instrument_settings)
    res = zm.evaluate(load_band(campaign.instrument_settings, "V"), los, sun[None, :])
    mag = np.where(res["no_data"], np.nan, np.ravel(res["mag_per_arcsec2"]))
    return {
        "nside": nside,
        "v_mag_per_arcsec2": mag,
        "sun_ra_deg": float(np.degrees(np.arctan2(sun[1], sun[0])) % 360),
        "sun_dec_deg": float(np.degrees(np.arcsin(sun[2]))),
        "time": time,
    }


def plot_zodiacal_map(d: dict, out_png) -> None:
    """Draw :func:`zodiacal_map_data`'s all-sky V-band zodiacal light (AB mag/arcsec2, Sun marked)
    as a Mollweide map to the PNG ``out_png``.

    Parameters
    ----------
    d : dict
        :func:`zodiacal_map_data`'s result.
    out_png : str or pathlib.Path
        The PNG written.
    """
    import healpy as hp
    from healpy import visufunc  # by name: a process may have loaded healpy without it (util.healpix)

    plt = _pyplot()
    fig = plt.figure(figsize=(8, 5))
    m = np.where(np.isnan(d["v_mag_per_arcsec2"]), hp.UNSEEN, d["v_mag_per_arcsec2"])
    visufunc.mollview(
        m,
        fig=fig.number,
        title=f"Zodiacal light, V (AB mag/arcsec$^2$), {d['time']} UTC (paper sect. 4.1)",
        unit="V mag / arcsec$^2$",
        cmap="viridis_r",
        min=21.0,
        max=23.6,
        flip="astro",
    )
    visufunc.graticule(dpar=30, dmer=60, alpha=0.4)
    visufunc.projplot(d["sun_ra_deg"], d["sun_dec_deg"], "r*", lonlat=True, markersize=16, label="Sun")
    plt.legend(loc="lower right", fontsize=8)
    fig.savefig(out_png, dpi=90)
    plt.close(fig)


# -- sect. 4.2 ----------------------------------------------------------------------------------
def scattering_data(campaign: Campaign, r_max_px: float = 1000.0) -> dict:
    """Star image against distance (pixels): PSF core, Harvey-Shack halo (paper eq. 8, four
    mirrors), and their blend, each relative to the blend's peak; TIS per mirror.

    Parameters
    ----------
    campaign : Campaign
        The campaign (its instrument).
    r_max_px : float, optional
        The largest distance from the image's centre, pixels (default 1000).
    """
    from straylight.optics.scatter import scatter_model_from_instrument

    sm = scatter_model_from_instrument(campaign.instrument_settings)
    p_m = campaign.instrument_settings.detector.pixel_size_um.value * 1e-6
    r = np.concatenate([[0.0], np.geomspace(0.05, r_max_px, 400)])
    peak = float(sm.profile(0.0))
    return {
        "r_px": r,
        "core": sm.core_profile(r * p_m) / peak,
        "halo": sm.halo_profile_raw(r * p_m) / peak,
        "blend": sm.profile(r * p_m) / peak,
        "tis_per_mirror": sm.brdf.tis(),
        "tis_total": sm.tis_total,
    }


def plot_scattering(d: dict, out_png) -> None:
    """Draw :func:`scattering_data`'s profiles (PSF core, mirror-scattering halo and their blend,
    relative to the image's peak, against the distance in pixels, log-log) to the PNG ``out_png``.

    Parameters
    ----------
    d : dict
        :func:`scattering_data`'s result.
    out_png : str or pathlib.Path
        The PNG written.
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    r = d["r_px"][1:]
    ax.loglog(r, d["core"][1:], "b--", label='PSF core (Gaussian, EE80 in 0.15")')
    ax.loglog(
        r,
        d["halo"][1:],
        "g:",
        lw=2,
        label=f"Harvey-Shack scattering, 4 mirrors (TIS {d['tis_per_mirror']:.1%} each)",
    )
    ax.loglog(r, d["blend"][1:], "k-", label="star image used (blend)")
    ax.plot(
        [10, 100],
        [1e-4, 1e-6],
        "rs",
        ms=8,
        mfc="none",
        label="paper sect. 4.4: ~1e-4 at 10 px, ~1e-6 at 100 px",
    )
    ax.set_ylim(1e-10, 2)
    ax.set_xlabel("distance from the image (pixels of 10 um)")
    ax.set_ylabel("irradiance / image peak")
    ax.set_title("Scattering by the mirrors (paper sect. 4.2)")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out_png, dpi=90)
    plt.close(fig)


# -- sect. 4.3 ----------------------------------------------------------------------------------
def ghost_example_data(campaign: Campaign, x_range_px=(-60, 260), half_height_px: int = 110) -> dict:
    """The NUV example's three ghost discs around a star (incidence 3.9 deg along +x), each
    pixel's ghost irradiance relative to the star image's peak pixel.

    Parameters
    ----------
    campaign : Campaign
        The campaign (its instrument's NUV ghosts).
    x_range_px : tuple of int, optional
        The image's columns from the star, pixels (default -60 to 260).
    half_height_px : int, optional
        The image's rows above and below the star, pixels (default 110).
    """
    from straylight.optics.ghosts import GhostModel
    from straylight.optics.scatter import scatter_model_from_instrument

    e = NUV_GHOST_EXAMPLE
    inst = campaign.instrument_settings
    g = needed(inst.ghosts, "ghosts")
    model = GhostModel(
        d1_mm=e["d1_mm"],
        d2_mm=e["d2_mm"],
        n=g.filter_refractive_index.value,
        u_rad=g.marginal_ray_angle_rad.value,
        r1=e["r1"],
        r2=e["r2"],
        t1=e["t1"],
        t2=e["t2"],
        rd=e["rd"],
    )
    p_mm = inst.detector.pixel_size_um.value / 1000.0
    sm = scatter_model_from_instrument(inst)
    peak_pixel = float(sm.profile(0.0)) * (p_mm * 1e-3) ** 2  # fraction of the star in its peak pixel
    th = np.radians(e["incidence_deg"])
    centres = model.centre_offsets_mm(th, 0.0)[:, :, ...] / p_mm  # (3, 2) px
    radii = model.radii_mm() / p_mm
    per_pixel = model.irradiance_relative_to_image_per_mm2() * p_mm**2  # fraction of the star per pixel
    y, x = np.mgrid[-half_height_px : half_height_px + 1, x_range_px[0] : x_range_px[1] + 1].astype(float)
    image = np.zeros_like(x)
    for k in range(3):
        image += np.where(np.hypot(x - centres[k, 0], y - centres[k, 1]) <= radii[k], per_pixel[k], 0.0)
    return {
        "relative_to_peak": image / peak_pixel,
        "ghost_relative_to_peak": per_pixel / peak_pixel,
        "centres_px": centres,
        "radii_px": radii,
        "energy_relative_to_image": model.energy_relative_to_image(),
        "extent": (x_range_px[0] - 0.5, x_range_px[1] + 0.5, -half_height_px - 0.5, half_height_px + 0.5),
    }


def plot_ghosts(d: dict, out_png) -> None:
    """Draw :func:`ghost_example_data`'s ghost image (log10 of the irradiance relative to the star
    image's peak pixel) to the PNG ``out_png``.

    Parameters
    ----------
    d : dict
        :func:`ghost_example_data`'s result.
    out_png : str or pathlib.Path
        The PNG written.
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 4.6))
    img = np.where(d["relative_to_peak"] > 0, d["relative_to_peak"], np.nan)
    im = ax.imshow(np.log10(img), origin="lower", extent=d["extent"], cmap="cividis")
    ax.plot(0, 0, "r*", ms=12, label="star image (1 at its peak pixel)")
    for k in range(3):
        cx, cy = d["centres_px"][k]
        ax.plot(cx, cy, "k+", ms=6)
        ax.annotate(
            f"ghost {k + 1}: {d['ghost_relative_to_peak'][k]:.2g}",
            (cx, -d["radii_px"][k] - 10 - 8 * k),
            ha="center",
            fontsize=8,
            color="k",
            bbox=dict(fc="white", alpha=0.8, lw=0),
        )
    fig.colorbar(im, ax=ax, label="log10 (ghost irradiance / star peak)")
    ax.set_xlabel("x (pixels)")
    ax.set_ylabel("y (pixels)")
    ax.set_title("NUV ghosts, D1 = 5 mm, D2 = 8 mm, 3.9 deg (paper sect. 4.3)", fontsize=10)
    ax.legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    fig.savefig(out_png, dpi=90)
    plt.close(fig)


# -- sect. 4.4 ----------------------------------------------------------------------------------
def detector_image_data(
    campaign: Campaign,
    catalog: dict,
    star_ra_deg: float,
    star_dec_deg: float,
    time: str = FIGURE_TIME,
    size_px: int = 1024,
    detector: int = 14,
    band: str = "NUV",
) -> dict:
    """A ``size_px`` square part of an NUV detector (``detector``) centred on the star at
    (``star_ra_deg``, ``star_dec_deg``), rendered by :func:`straylight.image.detector.render_detector`
    with every catalog star (``catalog``: ra, dec, mag_<band>) within reach: cores, halos and
    ghosts.  Returns the image and the profile of the centred star.

    Parameters
    ----------
    campaign : Campaign
        The campaign (its orbit and instrument).
    catalog : dict of str to ndarray
        Star columns ``ra``, ``dec`` (ICRS, deg) and ``mag_<band>`` (AB mag).
    star_ra_deg : float
        The centred star's right ascension, ICRS, deg.
    star_dec_deg : float
        The centred star's declination, ICRS, deg.
    time : str, optional
        The time, UTC ISO (default :data:`FIGURE_TIME`), which sets the roll.
    size_px : int, optional
        The image's side, pixels (default 1024).
    detector : int, optional
        The detector's index (default 14).
    band : str, optional
        The band (default ``"NUV"``).
    """
    from straylight.image.detector import Aim, RenderSettings, Stars, render_detector, star_fluxes_e_per_s
    from straylight.image.focal_plane import (
        FocalPlane,
        focal_plane_from_instrument,
        pointing_wcs,
        sun_direction_at,
    )
    from straylight.optics.bandpass import load_band
    from straylight.sky.timeutil import parse_utc

    inst = campaign.instrument_settings
    fp = focal_plane_from_instrument(inst)
    small = FocalPlane(
        size_px, size_px, fp.pixel_scale_arcsec, fp.pixel_size_mm, fp.columns, fp.rows, fp.gap_px
    )
    t = parse_utc(time, "figure time")
    sun = sun_direction_at(campaign, t)
    ox, oy = small.detector_offset_px(detector)
    # the boresight that puts the star at the image's centre (TAN about the star first)
    w = pointing_wcs(star_ra_deg, star_dec_deg, sun, small, detector)
    c = (size_px - 1) / 2.0
    ra0, dec0 = (float(v) for v in w.pixel_to_world_values(c - ox - ox, c - oy - oy))
    band_ = load_band(inst, band, campaign.instrument_path.parent)
    flux = star_fluxes_e_per_s(catalog[f"mag_{band}"], band_, inst.telescope.aperture_diameter_m.value)
    res = render_detector(
        Aim(ra0, dec0, sun, detector),
        Stars(catalog["ra"], catalog["dec"], flux),
        _detector_optics(inst, fp, band),
        RenderSettings(far_bin=4, margin_arcsec=600.0),
        size_override=(size_px, size_px),
    )
    sx, sy = (float(v) for v in res.wcs.world_to_pixel_values(star_ra_deg, star_dec_deg))
    return {
        "image": res.image_e_per_s_per_pix,
        "ghosts": res.ghosts,
        "stars": res.stars,
        "star_xy": (sx, sy),
        "pointing": (ra0, dec0),
        "band": band,
        "detector": detector,
        "time": time,
    }


def _detector_optics(inst, fp, band: str):
    """The instrument's focal plane ``fp``, star image and ``band``'s ghosts for the renderer."""
    from straylight.image.detector import DetectorOptics
    from straylight.optics.ghosts import ghost_model_from_instrument
    from straylight.optics.scatter import scatter_model_from_instrument

    return DetectorOptics(
        fp,
        scatter_model_from_instrument(inst),
        ghost_model_from_instrument(inst, band),
        needed(inst.ghosts, "ghosts").chief_ray_angle_deg.value,
    )


def plot_detector_image(d: dict, out_png) -> None:
    """Left: the image (stars, halos, ghosts); right: its ghosts alone (the painted discs).

    Parameters
    ----------
    d : dict
        :func:`detector_image_data`'s result.
    out_png : str or pathlib.Path
        The PNG written.
    """
    from straylight.image.detector import paint_discs

    plt = _pyplot()
    img = np.asarray(d["image"], float)
    ghosts = paint_discs(img.shape[0], img.shape[1], d["ghosts"], 0.0)
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.4))
    floor = max(float(np.percentile(img[img > 0], 1)), 1e-8) if np.any(img > 0) else 1e-8
    im = axes[0].imshow(np.log10(np.maximum(img, floor)), origin="lower", cmap="magma")
    fig.colorbar(im, ax=axes[0], label="log10 stray light (e-/s/pixel)")
    g = d["ghosts"]
    for xc, yc, r in zip(g["x_pix"], g["y_pix"], g["radius_pix"]):
        axes[0].add_patch(plt.Circle((xc, yc), r, fill=False, color="cyan", lw=0.6))
    axes[0].set_title("stars, scattering halos and ghosts (cyan)", fontsize=9)
    gi = np.where(ghosts > 0, ghosts, np.nan)
    im2 = axes[1].imshow(np.log10(gi), origin="lower", cmap="GnBu")
    fig.colorbar(im2, ax=axes[1], label="log10 ghost irradiance (e-/s/pixel)")
    sx, sy = d["star_xy"]
    axes[1].plot(sx, sy, "r*", ms=10)
    axes[1].set_title("ghosts alone (red star: the bright star's image)", fontsize=9)
    for ax in axes:
        ax.set_xlim(-0.5, img.shape[1] - 0.5)
        ax.set_ylim(-0.5, img.shape[0] - 0.5)
        ax.set_xlabel("x (pixels)")
        ax.set_ylabel("y (pixels)")
    fig.suptitle(
        f"{d['band']} detector {d['detector']} (part), {d['time']} UTC (paper sect. 4.4)", fontsize=10
    )
    fig.tight_layout()
    fig.savefig(out_png, dpi=80)
    plt.close(fig)


def make_figure(name: str, campaign: Campaign, out_png: str | Path, catalog_path=None) -> dict:
    """Compute and draw one figure; returns its data (for the printed summary).

    Parameters
    ----------
    name : str
        The figure, one of :data:`FIGURES`.
    campaign : Campaign
        The campaign.
    out_png : str or pathlib.Path
        The PNG written.
    catalog_path : str or pathlib.Path, optional
        A star table for the ``detector`` figure (default: the Hipparcos catalog).
    """
    from straylight.errors import InputError

    out_png = Path(out_png)
    out_png.parent.mkdir(parents=True, exist_ok=True)
    if name == "zodiacal-map":
        d = zodiacal_map_data(campaign)
        plot_zodiacal_map(d, out_png)
    elif name == "scattering":
        d = scattering_data(campaign)
        plot_scattering(d, out_png)
    elif name == "ghosts":
        d = ghost_example_data(campaign)
        plot_ghosts(d, out_png)
    elif name == "detector":
        cat, ra, dec = detector_catalog(campaign, catalog_path)
        d = detector_image_data(campaign, cat, ra, dec)
        plot_detector_image(d, out_png)
    else:
        raise InputError(f"figure {name!r}: must be one of {', '.join(FIGURES)}")
    return d


# the detector figure's star: a bright (V ~ 2.6) star away from the Galactic plane, in the footprint
DETECTOR_STAR_RADEC_DEG = (168.527, 20.524)  # delta Leo (Zosma, HIP 54872), ICRS J2000


def detector_catalog(campaign: Campaign, catalog_path=None) -> tuple[dict, float, float]:
    """(catalog columns ra, dec, mag_NUV; the centred star's ra, dec): the user's catalog if
    given (its brightest NUV star is centred), else the Hipparcos catalog in the CSST bands
    (:func:`straylight.catalog.build.catalog_for_campaign`) centred on delta Leo.

    Parameters
    ----------
    campaign : Campaign
        The campaign (its instrument and star settings).
    catalog_path : str or pathlib.Path, optional
        A star table with ``ra``, ``dec`` (deg) and ``mag_NUV`` (AB mag).
    """
    if catalog_path is not None:
        from straylight.catalog.star_table import read_star_table

        ra, dec, mag = read_star_table(catalog_path, "NUV")
        k = int(np.argmin(mag))
        return {"ra": ra, "dec": dec, "mag_NUV": mag}, float(ra[k]), float(dec[k])
    from straylight.catalog.campaign_catalog import catalog_for_campaign

    cols, _, _ = catalog_for_campaign(campaign, None)
    ra, dec = np.asarray(cols["ra"], float), np.asarray(cols["dec"], float)
    from straylight.sky.vectors import radec_to_unit

    k = int(np.argmax(radec_to_unit(ra, dec) @ radec_to_unit(*DETECTOR_STAR_RADEC_DEG)))
    return {"ra": ra, "dec": dec, "mag_NUV": np.asarray(cols["mag_NUV"], float)}, float(ra[k]), float(dec[k])
