"""The Earth's spectral albedo and its average through each band.

The earthshine's coefficients (:mod:`straylight.sources.earthshine.sums`, the tables) are
summed with the grey albedo ``models.earthshine.albedo`` (the Bond albedo, ~0.3); the Earth
reflects sunlight (and moonlight) with an albedo A(lambda) that ozone darkens below 320 nm
(the Hartley-Huggins bands) and Rayleigh scattering brightens near 340 nm.  The earthshine is
linear in the albedo, so a band's earthshine is the grey one times the band's factor
``A_band / A_grey`` (:func:`band_albedo_factors`), applied after the band-independent tables.

A(lambda) is a published reflectance spectrum R(lambda) scaled so that its solar-weighted mean
over the spectrum's range, integral R E dlambda / integral E dlambda with E the ASTM E490 solar
irradiance, equals the grey albedo: the grey value keeps its role as the Earth's Bond albedo
(the fraction of the solar energy reflected), and the spectrum gives its colour.  A band's
albedo is photon-weighted through the band, as its solar photon irradiance is:

    A_band = integral A E T lambda dlambda / integral E T lambda dlambda.

Spectra (``models.earthshine.albedo_spectrum``):

* ``vpl``: the Virtual Planetary Laboratory's 3-D spectral Earth model at quadrature (Robinson et
  al. 2011, Astrobiology 11, 393, validated against EPOXI), ``data/earth_reflectance_vpl.csv``;
* ``hst_earthshine``: STScI's earthshine spectrum (HST exposure-time calculators; Giavalisco,
  Sahu & Bohlin 2002, WFC3 ISR 2002-12: the solar spectrum in the optical, IUE measurements in
  the UV) over the E490 solar spectrum, ``data/hst_earthshine.fits``;
* ``grey``: A(lambda) = the grey albedo (the paper's model).
"""

from __future__ import annotations

from functools import lru_cache
from importlib import resources
from pathlib import Path

import numpy as np

from straylight.errors import ConfigError

__all__ = [
    "ALBEDO_SPECTRA",
    "albedo_spectrum",
    "band_albedo",
    "band_albedo_factors",
    "earth_band_factors",
    "reflectance_spectrum",
]

#: the spectra ``models.earthshine.albedo_spectrum`` may name
ALBEDO_SPECTRA = ("vpl", "hst_earthshine", "grey")


def _data_path(name: str) -> Path:
    return Path(resources.files("straylight") / "data" / name)


@lru_cache(maxsize=4)
def reflectance_spectrum(name: str) -> tuple[np.ndarray, np.ndarray]:
    """A published reflectance spectrum of the whole Earth, in relative units.

    Parameters
    ----------
    name : str
        One of :data:`ALBEDO_SPECTRA` but ``grey``.

    Returns
    -------
    wavelength_angstrom : ndarray, shape (n,)
        Increasing wavelengths, Angstrom.
    reflectance : ndarray, shape (n,)
        Reflectance, relative (only its shape is used).

    Raises
    ------
    ConfigError
        For an unknown name.
    """
    if name == "vpl":
        d = np.loadtxt(_data_path("earth_reflectance_vpl.csv"), delimiter=",", comments="#", skiprows=8)
        return d[:, 0] * 10.0, d[:, 1]
    if name == "hst_earthshine":
        from astropy.io import fits

        from straylight.sources.zodiacal import solar_spectrum

        with fits.open(_data_path("hst_earthshine.fits")) as h:
            wl = np.asarray(h[1].data["WAVELENGTH"], float)
            flam = np.asarray(h[1].data["FLUX"], float)
        sun_wl, sun = solar_spectrum()
        keep = (wl >= 2000.0) & (wl <= 25000.0)  # E490 is reliable there; below 200 nm no band
        wl, flam = wl[keep], flam[keep]
        return wl, flam / np.interp(wl, sun_wl, sun)
    raise ConfigError(
        f"models.earthshine.albedo_spectrum = {name!r}: must be one of {', '.join(ALBEDO_SPECTRA)}"
    )


@lru_cache(maxsize=8)
def albedo_spectrum(name: str, bond_albedo: float) -> tuple[np.ndarray, np.ndarray]:
    """The Earth's spectral albedo A(lambda) on the E490 solar spectrum's wavelengths inside the
    reflectance spectrum's range: R(lambda) scaled so that its E490-weighted mean over that range
    is ``bond_albedo`` (see the module's docstring).

    Parameters
    ----------
    name : str
        One of :data:`ALBEDO_SPECTRA`.
    bond_albedo : float
        The grey (Bond) albedo, in [0, 1].

    Returns
    -------
    wavelength_angstrom : ndarray, shape (n,)
        E490's wavelengths, Angstrom.
    albedo : ndarray, shape (n,)
        A(lambda), dimensionless.
    """
    from straylight.sources.zodiacal import solar_spectrum

    sun_wl, sun = solar_spectrum()
    if name == "grey":
        return sun_wl, np.full(sun_wl.shape, float(bond_albedo))
    wl, refl = reflectance_spectrum(name)
    inside = (sun_wl >= wl[0]) & (sun_wl <= wl[-1])
    grid, e = sun_wl[inside], sun[inside]
    r = np.interp(grid, wl, refl)
    mean = np.trapezoid(r * e, grid) / np.trapezoid(e, grid)
    return grid, float(bond_albedo) * r / mean


def band_albedo(band, name: str, bond_albedo: float) -> float:
    """The Earth's albedo through a band, photon-weighted with the E490 solar spectrum.

    Parameters
    ----------
    band : Band
        The band (its throughput).
    name : str
        One of :data:`ALBEDO_SPECTRA`.
    bond_albedo : float
        The grey (Bond) albedo.

    Returns
    -------
    float
        integral A E T lambda dlambda / integral E T lambda dlambda, dimensionless.
    """
    from straylight.sources.zodiacal import solar_spectrum

    if name == "grey":
        return float(bond_albedo)
    wl, albedo = albedo_spectrum(name, float(bond_albedo))
    sun_wl, sun = solar_spectrum()
    e = np.interp(wl, sun_wl, sun)
    return float(band.photon_rate(wl, albedo * e) / band.photon_rate(wl, e))


def band_albedo_factors(bands, name: str, bond_albedo: float) -> np.ndarray:
    """Each band's albedo over the grey one: the factor on the grey earthshine in that band.

    Parameters
    ----------
    bands : sequence of Band
        The bands.
    name : str
        One of :data:`ALBEDO_SPECTRA`.
    bond_albedo : float
        The grey (Bond) albedo the earthshine's coefficients are summed with (> 0).

    Returns
    -------
    ndarray, shape (n_bands,)
        ``band_albedo(band) / bond_albedo``; ones for ``grey``.
    """
    if name == "grey" or bond_albedo == 0:
        return np.ones(len(bands))
    return np.array([band_albedo(b, name, bond_albedo) / bond_albedo for b in bands])


def earth_band_factors(context, bands) -> np.ndarray | None:
    """The campaign's factors on the grey earthshine in ``bands`` (models.earthshine's
    ``albedo_spectrum`` and ``albedo``), cached on ``context``; None for the grey spectrum (no
    factor: the earthshine's terms are then those of the grey albedo, bit for bit).

    Parameters
    ----------
    context : SourceContext
        The campaign's sources' context (its bands and settings).
    bands : sequence of str
        Band names.

    Returns
    -------
    ndarray, shape (n_bands,), or None
        ``A_band / A_grey`` per band, dimensionless.
    """
    es = context.campaign.settings.models.earthshine
    name = getattr(es, "albedo_spectrum", "grey")
    if name == "grey":
        return None
    cache = context.__dict__.setdefault("_earth_band_factors", {})
    key = tuple(bands)
    if key not in cache:
        cache[key] = band_albedo_factors([context.band(b) for b in bands], name, float(es.albedo))
    return cache[key]
