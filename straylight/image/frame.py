"""One detector frame aimed at a target: the catalog's stars and the bodies in the field as
sources, the boresight that puts the target where asked, the stars that reach the chip, a cutout
around the target, and the rendering with an optional uniform background.

:func:`frame_for_target` sets the frame up without making an image, so that a caller can refuse
an empty field or a cutout off the chip before :func:`render_frame` does the work.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from straylight.image import detector
from straylight.image.detector import RenderSettings, StarSelection
from straylight.image.focal_plane import FocalPlane, boresight_for_target, sun_direction_at

__all__ = ["StarCatalog", "TargetFrame", "cutout_window", "frame_for_target", "render_frame"]


class StarCatalog(NamedTuple):
    """A star catalog read for a band: positions (ICRS, deg) and AB magnitudes in the band."""

    ra_deg: np.ndarray
    dec_deg: np.ndarray
    mag_ab: np.ndarray


@dataclass
class TargetFrame:
    """A detector frame set up for a target, before rendering.

    Attributes
    ----------
    boresight_ra_deg, boresight_dec_deg : float
        The telescope axis, deg (ICRS).
    star_ra_deg, star_dec_deg, star_flux_e_per_s : numpy.ndarray, shape (n,)
        The sources: the catalog's stars, then the bodies in the field; flux in e-/s through the
        full aperture.
    body_names : list of str
        The Sun, Moon and planets inside the field, imaged as stars.
    body_mag_ab : numpy.ndarray, shape (len(body_names),)
        Their AB magnitudes in the band.
    sun_direction : numpy.ndarray, shape (3,)
        Unit vector from the satellite to the Sun (it sets the roll).
    focal_plane : FocalPlane
    detector : int
        The detector's index.
    scatter : straylight.optics.scatter.ScatterModel
    settings : RenderSettings
    selection : StarSelection
        The sources that reach the chip, with the chip's WCS.
    """

    boresight_ra_deg: float
    boresight_dec_deg: float
    star_ra_deg: np.ndarray
    star_dec_deg: np.ndarray
    star_flux_e_per_s: np.ndarray
    body_names: list
    body_mag_ab: np.ndarray
    sun_direction: np.ndarray
    focal_plane: FocalPlane
    detector: int
    scatter: object
    settings: RenderSettings
    selection: StarSelection

    @property
    def aim(self) -> detector.Aim:
        """The boresight, the Sun's direction and the detector."""
        return detector.Aim(self.boresight_ra_deg, self.boresight_dec_deg, self.sun_direction, self.detector)

    @property
    def stars(self) -> detector.Stars:
        """The sources: the catalog's stars, then the bodies in the field."""
        return detector.Stars(self.star_ra_deg, self.star_dec_deg, self.star_flux_e_per_s)

    def pixel_of(self, ra_deg: float, dec_deg: float) -> tuple[float, float]:
        """The 0-based chip pixel (x, y) of a sky position (deg, ICRS), on the chip or off it.

        Parameters
        ----------
        ra_deg : float
            Right ascension, ICRS, deg.
        dec_deg : float
            Declination, ICRS, deg.
        """
        x, y = self.selection.wcs.world_to_pixel_values(ra_deg, dec_deg)
        return float(x), float(y)


def frame_for_target(
    campaign,
    time,
    target_radec_deg: tuple[float, float],
    band,
    catalog: StarCatalog,
    detector_index: int,
    center: str = "detector",
    settings: RenderSettings | None = None,
) -> TargetFrame:
    """Set up the frame of one detector of the campaign's focal plane aimed at a target; no
    image is made.

    Parameters
    ----------
    campaign : straylight.config.Campaign
        Its instrument (focal plane, aperture, scattering) and orbit.
    time : astropy.time.Time
        The time, scalar: the satellite's position, the bodies and the roll.
    target_radec_deg : tuple of float
        The target (RA, Dec), deg (ICRS).
    band : straylight.optics.bandpass.Band
        The band the stars' fluxes are integrated over.
    catalog : StarCatalog
        The catalog's stars: deg (ICRS) and AB magnitudes in ``band``.
    detector_index : int
    center : {"detector", "boresight"}
        ``detector``: the target lands on the centre of the detector; ``boresight``: the target
        is the telescope axis.
    settings : RenderSettings, optional
        The renderer's settings (default: :class:`RenderSettings`).

    Returns
    -------
    TargetFrame
    """
    from straylight.image.focal_plane import focal_plane_from_instrument
    from straylight.optics.scatter import scatter_model_from_instrument

    settings = settings or RenderSettings()
    focal_plane = focal_plane_from_instrument(campaign.instrument_settings)
    target_ra_deg, target_dec_deg = target_radec_deg
    aperture_m = campaign.instrument_settings.telescope.aperture_diameter_m.value
    ra, dec = catalog.ra_deg, catalog.dec_deg
    flux = detector.star_fluxes_e_per_s(catalog.mag_ab, band, aperture_m)
    sun = sun_direction_at(campaign, time)
    if center == "detector":
        bore_ra, bore_dec = boresight_for_target(
            target_ra_deg, target_dec_deg, sun, focal_plane, detector_index
        )
    else:
        bore_ra, bore_dec = target_ra_deg, target_dec_deg
    # the Sun, Moon and planets inside the field are imaged like stars
    b_ra, b_dec, b_mag, b_names = detector.bodies_as_stars(campaign, time, bore_ra, bore_dec, band.name)
    if b_names:
        b_flux = detector.star_fluxes_e_per_s(b_mag, band, aperture_m)
        ra, dec = np.concatenate([ra, b_ra]), np.concatenate([dec, b_dec])
        flux = np.concatenate([flux, b_flux])
    scatter = scatter_model_from_instrument(campaign.instrument_settings)
    aim = detector.Aim(bore_ra, bore_dec, sun, detector_index)
    sel = detector.select_stars(aim, detector.Stars(ra, dec, flux), focal_plane, scatter, settings)
    return TargetFrame(
        bore_ra,
        bore_dec,
        ra,
        dec,
        flux,
        b_names,
        b_mag,
        sun,
        focal_plane,
        detector_index,
        scatter,
        settings,
        sel,
    )


def cutout_window(
    focal_plane: FocalPlane, x_pix: float, y_pix: float, width: int, height: int
) -> tuple[int, int, int, int] | None:
    """The window (x0, y0, width, height), 0-based chip pixels, of a ``width`` x ``height`` cutout
    centred on the pixel (``x_pix``, ``y_pix``) and clipped to the chip; None when the cutout
    misses the chip.

    Parameters
    ----------
    focal_plane : FocalPlane
        The focal plane (the chip's size).
    x_pix : float
        The cutout's centre, 0-based chip column.
    y_pix : float
        The cutout's centre, 0-based chip row.
    width : int
        The cutout's width, pixels.
    height : int
        The cutout's height, pixels.
    """
    window = (int(round(float(x_pix) - width / 2)), int(round(float(y_pix) - height / 2)), width, height)
    x0, y0 = max(window[0], 0), max(window[1], 0)
    if window[0] + width <= 0 or window[1] + height <= 0 or x0 >= focal_plane.nx or y0 >= focal_plane.ny:
        return None
    return (x0, y0, window[0] + width - x0, window[1] + height - y0)


def render_frame(
    frame: TargetFrame,
    instrument,
    band_name: str,
    window=None,
    bin_factor: int = 1,
    background_e_per_s_per_pix: float | None = None,
) -> detector.DetectorImage:
    """Render the frame's in-field stray light (:func:`~straylight.image.detector.render_detector`).

    Parameters
    ----------
    frame : TargetFrame
    instrument : straylight.config.InstrumentSettings or dict
        The instrument (its ghosts): its typed settings, or its mapping
        (:func:`straylight.config.instrument_settings`).
    band_name : str
        The band (its ghosts).
    window : tuple of int, optional
        (x0, y0, width, height), 0-based chip pixels (:func:`cutout_window`); default the chip.
    bin_factor : int
        Average N x N pixels (still e-/s per chip pixel).
    background_e_per_s_per_pix : float, optional
        A uniform background added to every pixel, e-/s/pixel.

    Returns
    -------
    straylight.image.detector.DetectorImage
        The image in e-/s/pixel, float32, shape (height // bin_factor, width // bin_factor) of
        the window (the chip's when no window).
    """
    from straylight.config import instrument_settings, needed
    from straylight.optics.ghosts import ghost_model_from_instrument

    inst = instrument_settings(instrument)
    result = detector.render_detector(
        frame.aim,
        frame.stars,
        detector.DetectorOptics(
            frame.focal_plane,
            frame.scatter,
            ghost_model_from_instrument(inst, band_name),
            needed(inst.ghosts, "ghosts").chief_ray_angle_deg.value,
        ),
        frame.settings,
        window=window,
        bin_factor=bin_factor,
    )
    if background_e_per_s_per_pix is not None:
        result.image_e_per_s_per_pix += np.float32(background_e_per_s_per_pix)
    return result
