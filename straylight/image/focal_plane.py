"""The focal plane and its geometry: the detectors' layout (:class:`FocalPlane`, from the
instrument's ``detector`` section), each detector's TAN WCS whose roll follows the telescope frame
(+x towards the Sun's projection, the door side; see :mod:`straylight.sky.frames`), the Sun's
direction for the roll, and the boresight that puts a target on a detector's centre."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from straylight.config import InstrumentSettings, instrument_settings, needed, pixel_scale_arcsec
from straylight.errors import InputError
from straylight.sky.frames import telescope_frame
from straylight.sky.vectors import radec_to_unit, unit

__all__ = [
    "FocalPlane",
    "boresight_for_target",
    "focal_plane_from_instrument",
    "pointing_wcs",
    "sun_direction_at",
]


@dataclass(frozen=True)
class FocalPlane:
    """The focal plane's layout: each detector ``nx`` x ``ny`` pixels of ``pixel_scale_arcsec``
    (arcsec) and ``pixel_size_mm`` (mm), ``columns`` x ``rows`` detectors separated by ``gap_px``
    pixels."""

    nx: int
    ny: int
    pixel_scale_arcsec: float
    pixel_size_mm: float
    columns: int
    rows: int
    gap_px: float

    @property
    def n_detectors(self) -> int:
        """Number of detectors, columns x rows."""
        return self.columns * self.rows

    def detector_offset_px(self, detector: int) -> tuple[float, float]:
        """Centre of detector ``detector`` (0-based, row-major) from the optical axis, pixels.

        Parameters
        ----------
        detector : int
            The detector's index (0-based, row-major).
        """
        if not 0 <= detector < self.n_detectors:
            raise InputError(f"--detector {detector}: must be within 0..{self.n_detectors - 1}")
        row, col = divmod(detector, self.columns)
        pitch_x, pitch_y = self.nx + self.gap_px, self.ny + self.gap_px
        return ((col - (self.columns - 1) / 2) * pitch_x, (row - (self.rows - 1) / 2) * pitch_y)


def focal_plane_from_instrument(instrument: InstrumentSettings | dict) -> FocalPlane:
    """The focal plane of the instrument's ``detector`` section (CCD format, pixel, layout).
    ``instrument``: its typed settings, or its mapping
    (:func:`~straylight.config.instrument.instrument_settings`).

    Parameters
    ----------
    instrument : InstrumentSettings or dict
        The instrument's typed settings, or its mapping.
    """
    inst = instrument_settings(instrument)
    d = inst.detector
    nx = int(needed(d.nx_pixels, "detector.nx_pixels").value)
    ny = int(needed(d.ny_pixels, "detector.ny_pixels").value)
    if nx <= 0 or ny <= 0:
        raise InputError(f"detector size {nx} x {ny}: must be positive")
    return FocalPlane(
        nx=nx,
        ny=ny,
        pixel_scale_arcsec=pixel_scale_arcsec(inst),
        pixel_size_mm=d.pixel_size_um.value / 1000.0,
        columns=int(needed(d.layout_columns, "detector.layout_columns").value),
        rows=int(needed(d.layout_rows, "detector.layout_rows").value),
        gap_px=needed(d.layout_gap_pixels, "detector.layout_gap_pixels").value,
    )


def pointing_wcs(ra_deg: float, dec_deg: float, sun_direction: np.ndarray, fp: FocalPlane, detector: int):
    """Astropy WCS of one detector: TAN about the boresight, axes along the telescope frame.

    Parameters
    ----------
    ra_deg : float
        The boresight's right ascension, ICRS, deg.
    dec_deg : float
        The boresight's declination, ICRS, deg.
    sun_direction : ndarray
        Unit vector from the telescope to the Sun (ICRS axes), which sets the roll.
    fp : FocalPlane
        The focal plane.
    detector : int
        The detector's index (0-based, row-major).
    """
    from astropy.wcs import WCS

    z = radec_to_unit(ra_deg, dec_deg)
    frame = telescope_frame(z, np.asarray(sun_direction, dtype=float))
    a, d = np.radians(ra_deg), np.radians(dec_deg)
    east = np.array([-np.sin(a), np.cos(a), 0.0])
    north = np.array([-np.sin(d) * np.cos(a), -np.sin(d) * np.sin(a), np.cos(d)])
    scale_deg = fp.pixel_scale_arcsec / 3600.0
    cd = scale_deg * np.array([[frame.x @ east, frame.y @ east], [frame.x @ north, frame.y @ north]])
    ox, oy = fp.detector_offset_px(detector)
    w = WCS(naxis=2)
    w.wcs.ctype = ["RA---TAN", "DEC--TAN"]
    w.wcs.crval = [ra_deg % 360.0, dec_deg]
    # boresight falls at pixel (centre - offset); FITS pixels are 1-based
    w.wcs.crpix = [(fp.nx + 1) / 2.0 - ox, (fp.ny + 1) / 2.0 - oy]
    w.wcs.cd = cd
    w.wcs.cunit = ["deg", "deg"]
    return w


def sun_direction_at(campaign, time) -> np.ndarray:
    """Unit vector from the satellite to the Sun at ``time`` (for the roll).

    Parameters
    ----------
    campaign : Campaign
        The campaign (its orbit).
    time : str or astropy.time.Time
        The time (UTC).
    """
    from straylight.sky.observing import scene

    sc = scene(campaign.orbit, time)
    return unit(sc.bodies_km["sun"][0] - sc.satellite_km[0])


def boresight_for_target(
    target_ra_deg: float,
    target_dec_deg: float,
    sun_direction,
    fp: FocalPlane,
    detector: int,
    tol_arcsec: float = 1e-4,
) -> tuple[float, float]:
    """The boresight (RA, Dec, deg) that puts ``target`` on the centre of ``detector``.

    The roll follows the Sun (:func:`pointing_wcs`), so the boresight is found by iteration:
    move it by the offset still left between the chip centre and the target, until that offset
    is below ``tol_arcsec``.  Converges in a few steps (the detector offsets are < 1 deg).

    Parameters
    ----------
    target_ra_deg : float
        The target's right ascension, ICRS, deg.
    target_dec_deg : float
        The target's declination, ICRS, deg.
    sun_direction : ndarray
        Unit vector from the telescope to the Sun (ICRS axes), which sets the roll.
    fp : FocalPlane
        The focal plane.
    detector : int
        The detector's index (0-based, row-major).
    tol_arcsec : float, optional
        The largest offset left between the chip's centre and the target, arcsec (default 1e-4).
    """
    import astropy.units as u
    from astropy.coordinates import SkyCoord

    target = SkyCoord(target_ra_deg * u.deg, target_dec_deg * u.deg)
    ra, dec = float(target_ra_deg), float(target_dec_deg)
    for _ in range(20):
        w = pointing_wcs(ra, dec, sun_direction, fp, detector)
        c = w.pixel_to_world_values((fp.nx - 1) / 2.0, (fp.ny - 1) / 2.0)
        centre = SkyCoord(float(c[0]) * u.deg, float(c[1]) * u.deg)
        sep = centre.separation(target)
        if sep.to_value(u.arcsec) < tol_arcsec:
            break
        bore = SkyCoord(ra * u.deg, dec * u.deg).directional_offset_by(centre.position_angle(target), sep)
        ra, dec = float(bore.ra.deg), float(bore.dec.deg)
    else:  # pragma: no cover - the map is a near-rigid rotation
        raise InputError(f"cannot put RA {target_ra_deg}, Dec {target_dec_deg} on detector {detector}")
    return ra, dec
