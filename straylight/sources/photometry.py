"""Photometry of the sources through a band: the Sun's photon irradiance at 1 AU (ASTM E490-00a
spectrum), a solar-spectrum source's from its V magnitude (V_sun = -26.76, Willmer 2018, ApJS
236, 47), a star's from its AB magnitude, and a uniform background's surface brightness in AB
mag/arcsec2.  A solar-spectrum source's irradiance is the same fraction of the Sun's in every
band (:func:`solar_like_fraction`), which is why the Sun, Moon, planets and both Earths give
band-independent rates."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache
from importlib import resources
from pathlib import Path

import numpy as np

from straylight.optics.bandpass import Band

__all__ = [
    "AU_KM",
    "V_SUN_VEGA",
    "solar_like_fraction",
    "BandPhotometry",
    "sky_zero_point_mag_per_arcsec2",
    "magnitude_per_arcsec2",
    "pixel_etendue_m2_sr",
    "solar_spectrum",
]

AU_KM = 1.495978707e8
V_SUN_VEGA = -26.76


@lru_cache(maxsize=1)
def solar_spectrum() -> tuple[np.ndarray, np.ndarray]:
    """ASTM E490-00a solar spectral irradiance at 1 AU: (wavelength A, W m-2 um-1).

    Returns
    -------
    wavelength_angstrom : ndarray, shape (n,)
        Wavelengths, Angstrom.
    irradiance : ndarray, shape (n,)
        Spectral irradiance at 1 AU, W m-2 um-1.
    """
    data = np.loadtxt(Path(resources.files("straylight") / "data" / "e490_00a.dat"), comments="#")
    return data[:, 0] * 1.0e4, data[:, 1]


def pixel_etendue_m2_sr(aperture_diameter_m: float, focal_length_m: float, pixel_size_m: float) -> float:
    """Aperture area times pixel solid angle, pi D^2 / 4 * (p / f)^2: the etendue through which a
    pixel sees an extended source (the zodiacal light, the Earth inside the field).

    Parameters
    ----------
    aperture_diameter_m : float
        The aperture's diameter D, m.
    focal_length_m : float
        The focal length f, m.
    pixel_size_m : float
        The pixel's side p, m.

    Returns
    -------
    float
        m2 sr.
    """
    return np.pi * aperture_diameter_m**2 / 4.0 * (pixel_size_m / focal_length_m) ** 2


def solar_like_fraction(v_mag) -> np.ndarray:
    """Irradiance of a source with the Sun's spectrum and V magnitude ``v_mag`` as a fraction of
    the Sun's at 1 AU, in any band (the same spectrum, so the same fraction in every band).

    Parameters
    ----------
    v_mag : array_like
        V magnitude (Vega).

    Returns
    -------
    ndarray
        Irradiance over the Sun's at 1 AU, dimensionless, of ``v_mag``'s shape.
    """
    return 10.0 ** (-0.4 * (np.asarray(v_mag, dtype=float) - V_SUN_VEGA))


@dataclass
class BandPhotometry:
    """Photon irradiances through one band for the solar-spectrum sources.

    Attributes
    ----------
    band : Band
        The band (throughput including QE, AB zero point).
    """

    band: Band

    @cached_property
    def sun_at_1au_photons_s_m2(self) -> float:
        """The Sun's photon irradiance at 1 AU through the band (ASTM E490-00a), photons s-1 m-2."""
        wl, flux = solar_spectrum()
        return float(self.band.photon_rate(wl, flux))

    def solar_like_from_v(self, v_mag) -> np.ndarray:
        """Photon irradiance of a source with the Sun's spectrum and V magnitude ``v_mag``.

        Parameters
        ----------
        v_mag : array_like
            V magnitude (Vega).

        Returns
        -------
        ndarray
            Photons s-1 m-2 through the band, of ``v_mag``'s shape.
        """
        return self.sun_at_1au_photons_s_m2 * solar_like_fraction(v_mag)

    def from_ab(self, mag_ab) -> np.ndarray:
        """Photon irradiance of a source of AB magnitude ``mag_ab`` in the band.

        Parameters
        ----------
        mag_ab : array_like
            AB magnitude in the band (+inf gives 0).

        Returns
        -------
        ndarray
            Photons s-1 m-2 through the band, of ``mag_ab``'s shape.
        """
        return self.band.ab_zero_point_photons_s_m2 * 10.0 ** (-0.4 * np.asarray(mag_ab, dtype=float))


def sky_zero_point_mag_per_arcsec2(
    band: Band, aperture_diameter_m: float, pixel_scale_arcsec: float
) -> float:
    """AB surface brightness (mag/arcsec2) of a uniform background giving 1 e-/s/pixel, so that
    ``mag_per_arcsec2 = zero_point - 2.5 log10(rate_e_per_s_per_pix)``: the band's AB photon
    zero point times the aperture area, spread over one pixel's solid angle (arcsec2).

    Parameters
    ----------
    band : Band
        The band (its AB zero point, photons s-1 m-2).
    aperture_diameter_m : float
        Telescope aperture diameter, m.
    pixel_scale_arcsec : float
        Pixel scale, arcsec per pixel.

    Returns
    -------
    float
        The zero point, AB mag/arcsec2.
    """
    ref = band.ab_zero_point_photons_s_m2 * np.pi * aperture_diameter_m**2 / 4.0
    return float(2.5 * np.log10(ref * pixel_scale_arcsec**2))


def magnitude_per_arcsec2(e_per_s_per_pix, band: Band, aperture_diameter_m: float, pixel_scale_arcsec: float):
    """AB mag/arcsec2 of a uniform background giving ``e_per_s_per_pix`` (inf where zero).

    Parameters
    ----------
    e_per_s_per_pix : array_like
        Background rate, e-/s/pix.
    band : Band
        The band.
    aperture_diameter_m : float
        Telescope aperture diameter, m.
    pixel_scale_arcsec : float
        Pixel scale, arcsec per pixel.

    Returns
    -------
    ndarray
        Surface brightness, AB mag/arcsec2, of ``e_per_s_per_pix``'s shape.
    """
    zp = sky_zero_point_mag_per_arcsec2(band, aperture_diameter_m, pixel_scale_arcsec)
    with np.errstate(divide="ignore"):
        return zp - 2.5 * np.log10(np.asarray(e_per_s_per_pix, dtype=float))
