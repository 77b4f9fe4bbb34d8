"""Zodiacal light in the field of view (seed paper sect. 4.1).

Brightness at 500 nm: Leinert et al. (1998) Table 17, interpolated bilinearly in log10 of the
brightness over |helioecliptic longitude| (0-180 deg) and |ecliptic latitude| (0-90 deg), so it
is exact at the table's nodes, continuous, and symmetric in both angles.  Near the Sun the table
has no data (marked 1e6); those nodes are filled with the nearest valid value at higher latitude
in the same longitude row (a lower bound, never an extrapolation) and every sample touching one
is flagged ``no_data``.  The Sun-avoidance angle (50 deg) keeps survey pointings out of it.

Spectrum: V(lambda) = B_500 * S(lambda) / S(500 nm), S one of
:data:`~straylight.sources.zodiacal_colour.SPECTRA` (``models.zodiacal_spectrum``; default the
E490 Sun times Leinert et al. 1998's colour fit, :mod:`straylight.sources.zodiacal_colour`).

Band integration and focal plane (paper eqs. 2-3): L = integral V(lambda) T(lambda) d lambda,
E = L pi D^2 / (4 f^2); per pixel, photons s-1 = N_photon * pi D^2 / 4 * (p / f)^2, which is
the same thing counted in photons, with T the total throughput including QE, so the result is
in e- s-1 pixel-1.

Ecliptic coordinates: the mean ecliptic and equinox of J2000 (IAU 2006 obliquity).  Leinert's
table is a function of the longitude difference to the Sun, which precession leaves unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache
from importlib import resources
from pathlib import Path

import numpy as np

from straylight.config import InstrumentSettings, instrument_settings
from straylight.errors import ConfigError
from straylight.optics.bandpass import Band
from straylight.sky.runs import scene_rows, tiled_period
from straylight.sky.vectors import unit
from straylight.sources.photometry import pixel_etendue_m2_sr
from straylight.sources.rates import BandRates
from straylight.sources.zodiacal_colour import (
    LEINERT_REDDENING_EPS90,
    SPECTRA,
    leinert_colour_correction,
    solar_spectrum,
    zodiacal_spectrum_shape,
)
from straylight.util.gridinterp import LinearGrid

__all__ = [
    "NO_DATA",
    "LEINERT_UNIT_W_M2_SR_UM",
    "OBLIQUITY_J2000_RAD",
    "ARCSEC2_PER_SR",
    "SPECTRA",
    "icrs_to_ecliptic_matrix",
    "ecliptic_lon_lat_deg",
    "helioecliptic_coordinates",
    "LeinertTable",
    "leinert_table",
    "solar_spectrum",
    "leinert_colour_correction",
    "zodiacal_spectrum_shape",
    "ZodiacalModel",
    "ZodiacalLight",
    "zodiacal_model_from_instrument",
    "campaign_zodiacal_model",
]

NO_DATA = 1.0e6
LEINERT_UNIT_W_M2_SR_UM = 1.0e-8
OBLIQUITY_J2000_RAD = np.radians(84381.406 / 3600.0)  # IAU 2006 (Hilton et al. 2006)
ARCSEC2_PER_SR = (180.0 / np.pi * 3600.0) ** 2


def _data_path(name: str) -> Path:
    return Path(resources.files("straylight") / "data" / name)


def icrs_to_ecliptic_matrix() -> np.ndarray:
    """Rotation from ICRS (equatorial J2000) to the J2000 mean ecliptic.

    Returns
    -------
    ndarray, shape (3, 3)
        The rotation matrix: ``ecliptic = M @ icrs``.
    """
    ce, se = np.cos(OBLIQUITY_J2000_RAD), np.sin(OBLIQUITY_J2000_RAD)
    return np.array([[1.0, 0.0, 0.0], [0.0, ce, se], [0.0, -se, ce]])


def _ecliptic_lon_lat_deg(vectors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ecliptic longitude in (-180, 180] and latitude (deg) of ICRS vectors (..., 3)."""
    e = np.asarray(vectors, dtype=float) @ icrs_to_ecliptic_matrix().T
    return (
        np.degrees(np.arctan2(e[..., 1], e[..., 0])),
        np.degrees(np.arctan2(e[..., 2], np.hypot(e[..., 0], e[..., 1]))),
    )


def ecliptic_lon_lat_deg(vectors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ecliptic longitude [0, 360) and latitude (deg) of ICRS vectors (..., 3).

    Parameters
    ----------
    vectors : ndarray, shape (..., 3)
        ICRS vectors (any length, any unit).

    Returns
    -------
    lon_deg, lat_deg : ndarray, shape (...)
        J2000 mean-ecliptic longitude in [0, 360) and latitude in [-90, 90], deg.
    """
    lon, lat = _ecliptic_lon_lat_deg(vectors)
    return lon % 360.0, lat


def helioecliptic_coordinates(
    los: np.ndarray, sun_direction: np.ndarray, runs=None
) -> tuple[np.ndarray, np.ndarray]:
    """(|lambda - lambda_sun| in [0, 180], |beta| in [0, 90]) for lines of sight, deg (their
    longitudes' difference folded without a modulo); ``runs``: the samples' scene runs when
    known (:class:`~straylight.sky.runs.SceneRuns`).

    Parameters
    ----------
    los : ndarray, shape (..., 3)
        Lines of sight, ICRS unit vectors.
    sun_direction : ndarray, shape (..., 3)
        Directions to the Sun from the satellite, ICRS unit vectors, broadcastable with ``los``.
    runs : SceneRuns, optional
        The samples' scene runs; None: found here.

    Returns
    -------
    dlon_deg, beta_deg : ndarray, shape (...)
        |helioecliptic longitude| in [0, 180] and |ecliptic latitude| in [0, 90], deg.
    """
    rows = scene_rows(
        sun_direction, runs=runs
    )  # a cube's time step shares the Sun: its longitude once per step
    # and a cube batch repeats its lines of sight at every step: theirs once per pixel
    period = tiled_period(los, rows) if np.shape(los) == np.shape(sun_direction) else None
    if period is None:
        lon, lat = _ecliptic_lon_lat_deg(los)
    else:
        lon, lat = (
            np.tile(v, rows.count).reshape(np.shape(los)[:-1])
            for v in _ecliptic_lon_lat_deg(np.asarray(los, float).reshape(-1, 3)[:period])
        )
    lon_sun = rows.expand(_ecliptic_lon_lat_deg(rows.vectors[0])[0])
    d = np.abs(lon - lon_sun)
    return np.where(d > 180.0, 360.0 - d, d), np.abs(lat)  # d in [0, 360]: the angle between them


@dataclass(frozen=True)
class LeinertTable:
    """Leinert et al. (1998) Table 17: the zodiacal light's brightness at 500 nm over
    helioecliptic longitude and ecliptic latitude.

    Attributes
    ----------
    lon_deg : ndarray, shape (n_lon,)
        |Helioecliptic longitude| nodes, deg (0-180).
    lat_deg : ndarray, shape (n_lat,)
        |Ecliptic latitude| nodes, deg (0-90).
    values : ndarray, shape (n_lon, n_lat)
        Brightness at 500 nm, 1e-8 W m-2 sr-1 um-1 (:data:`LEINERT_UNIT_W_M2_SR_UM`);
        :data:`NO_DATA` where the table has none.
    """

    lon_deg: np.ndarray  # helioecliptic longitude nodes
    lat_deg: np.ndarray  # ecliptic latitude nodes
    values: np.ndarray  # 1e-8 W m-2 sr-1 um-1, NO_DATA where missing

    @classmethod
    def load(cls, path: Path | None = None) -> "LeinertTable":
        """Read the table from its CSV file.

        Parameters
        ----------
        path : Path, optional
            The CSV file (header ``lon_minus_sun_deg,beta_<deg>,...``; ``#`` comments); None: the packaged
            ``leinert1998_table17.csv``.

        Returns
        -------
        LeinertTable
        """
        path = path or _data_path("leinert1998_table17.csv")
        rows = [ln for ln in Path(path).read_text().splitlines() if ln and not ln.startswith("#")]
        header = rows[0].split(",")
        lat = np.array([float(h.split("_")[1]) for h in header[1:]])
        data = np.array([[float(x) for x in r.split(",")] for r in rows[1:]])
        return cls(lon_deg=data[:, 0], lat_deg=lat, values=data[:, 1:])

    @cached_property
    def no_data(self) -> np.ndarray:
        """Bool (n_lon, n_lat): the nodes where the table has no data."""
        return self.values >= NO_DATA

    @cached_property
    def filled(self) -> np.ndarray:
        """(n_lon, n_lat), 1e-8 W m-2 sr-1 um-1: :attr:`values` with no-data nodes replaced by
        the first valid value at higher latitude in their row."""
        v = self.values.copy()
        for i in range(v.shape[0]):
            for j in range(v.shape[1] - 1, -1, -1):
                if v[i, j] >= NO_DATA:
                    v[i, j] = v[i, j + 1]
        return v

    @cached_property
    def _interp(self):
        """The log of the filled table and the no-data nodes (as 0/1) on one grid, two channels
        (the natural log: bilinear in it is bilinear in log10, and exp is cheaper than 10**)."""
        return LinearGrid(
            (self.lon_deg, self.lat_deg), np.stack([np.log(self.filled), self.no_data], axis=-1)
        )

    def brightness_500nm(self, dlon_deg, beta_deg) -> tuple[np.ndarray, np.ndarray]:
        """Brightness at 500 nm, W m-2 sr-1 um-1, and the no-data flag (any no-data node among
        the sample's cell corners that carry weight), for |dlon|, |beta| in deg.

        Parameters
        ----------
        dlon_deg : array_like
            Helioecliptic longitude, deg (its absolute value, clipped to [0, 180]).
        beta_deg : array_like
            Ecliptic latitude, deg (its absolute value, clipped to [0, 90]), broadcastable with
            ``dlon_deg``.

        Returns
        -------
        brightness : ndarray
            Brightness at 500 nm, W m-2 sr-1 um-1, of the broadcast shape.
        no_data : ndarray of bool
            True where a weighted corner has no data (the value is then a lower bound).
        """
        dlon = np.clip(np.abs(np.asarray(dlon_deg, dtype=float)), 0.0, 180.0)
        beta = np.clip(np.abs(np.asarray(beta_deg, dtype=float)), 0.0, 90.0)
        both = self._interp(dlon, beta)
        return np.exp(both[..., 0]) * LEINERT_UNIT_W_M2_SR_UM, both[..., 1] > 0.0


@lru_cache(maxsize=1)
def leinert_table() -> LeinertTable:
    """The packaged Leinert (1998) Table 17, read once.

    Returns
    -------
    LeinertTable
    """
    return LeinertTable.load()


_BAND_FACTOR_CACHE: dict = {}


@dataclass(frozen=True)
class ZodiacalModel:
    """Zodiacal light per band for one instrument.

    Attributes
    ----------
    aperture_diameter_m : float
        Telescope aperture diameter, m.
    focal_length_m : float
        Focal length, m.
    pixel_size_m : float
        Detector pixel pitch, m.
    spectrum : str
        The zodiacal spectrum, one of :data:`SPECTRA`.
    reddening : tuple of float
        ``(blue_per_dex, red_per_dex)``: Leinert et al. 1998 eq. 22's colour law, read by the
        ``leinert_fit`` spectrum (:func:`~straylight.sources.zodiacal_colour.reddening_factor`).
    """

    aperture_diameter_m: float
    focal_length_m: float
    pixel_size_m: float
    spectrum: str = "leinert_fit"
    reddening: tuple = LEINERT_REDDENING_EPS90

    def band_factors(self, band: Band) -> tuple[float, float]:
        """For B_500 = 1 W m-2 sr-1 um-1: (photons s-1 m-2 sr-1 in band, AB mag/arcsec2).

        Parameters
        ----------
        band : Band
            The band (throughput including QE); cached per band, spectrum and reddening.

        Returns
        -------
        rate_sr : float
            Photons s-1 m-2 sr-1 (electrons, the throughput including QE) per unit B_500.
        mag : float
            AB mag/arcsec2 of B_500 = 1 W m-2 sr-1 um-1.

        Raises
        ------
        ConfigError
            When the band reaches outside the spectrum's wavelength range.
        """
        key = (
            band.name,
            band.origin,
            hash(np.asarray(band.throughput).tobytes()),
            self.spectrum,
            tuple(self.reddening),
        )
        if key not in _BAND_FACTOR_CACHE:
            _BAND_FACTOR_CACHE[key] = self._band_factors(band)
        return _BAND_FACTOR_CACHE[key]

    def _band_factors(self, band: Band) -> tuple[float, float]:
        wl, shape = zodiacal_spectrum_shape(self.spectrum, tuple(self.reddening))
        lo, hi = band.wavelength_angstrom[0], band.wavelength_angstrom[-1]
        if wl[0] > lo or wl[-1] < hi:
            raise ConfigError(
                f"band {band.name}: {lo:.0f}-{hi:.0f} A is outside the zodiacal spectrum's range"
            )
        rate_sr = float(band.photon_rate(wl, shape))
        rate_arcsec2 = rate_sr / ARCSEC2_PER_SR
        mag = -2.5 * np.log10(rate_arcsec2 / band.ab_zero_point_photons_s_m2)
        return rate_sr, float(mag)

    @property
    def pixel_etendue_m2_sr(self) -> float:
        """Aperture area times pixel solid angle: pi D^2 / 4 * (p / f)^2, m2 sr."""
        return pixel_etendue_m2_sr(self.aperture_diameter_m, self.focal_length_m, self.pixel_size_m)

    @staticmethod
    def brightness_500nm(los: np.ndarray, sun_direction: np.ndarray, runs=None):
        """Band-independent part: (B_500 in W m-2 sr-1 um-1, no-data flag) for the samples.

        Parameters
        ----------
        los : ndarray, shape (..., 3)
            Lines of sight, ICRS unit vectors.
        sun_direction : ndarray, shape (..., 3)
            Directions to the Sun from the satellite, ICRS unit vectors, broadcastable with
            ``los``.
        runs : SceneRuns, optional
            The samples' scene runs; None: found here.

        Returns
        -------
        brightness : ndarray, shape (...)
            B_500, W m-2 sr-1 um-1.
        no_data : ndarray of bool, shape (...)
            True where the table has no data near the Sun.
        """
        dlon, beta = helioecliptic_coordinates(los, sun_direction, runs)
        return leinert_table().brightness_500nm(dlon, beta)

    def e_per_s_per_pix(self, band: Band, brightness_500nm) -> np.ndarray:
        """e-/s/pixel in ``band`` for a 500 nm brightness B_500 (W m-2 sr-1 um-1).

        Parameters
        ----------
        band : Band
            The band.
        brightness_500nm : array_like
            B_500, W m-2 sr-1 um-1.

        Returns
        -------
        ndarray
            e-/s/pix, of ``brightness_500nm``'s shape.
        """
        return np.asarray(brightness_500nm) * self.band_factors(band)[0] * self.pixel_etendue_m2_sr

    def darkest_e_per_s_per_pix(self, band: Band) -> float:
        """e-/s/pixel in ``band`` at the darkest point of the Leinert (1998) table: the floor of
        any total background (:class:`~straylight.sources.context.SourceContext`'s
        ``zodiacal_floor``).

        Parameters
        ----------
        band : Band
            The band.

        Returns
        -------
        float
            e-/s/pix.
        """
        b_min = float(np.min(leinert_table().filled)) * LEINERT_UNIT_W_M2_SR_UM
        return float(self.e_per_s_per_pix(band, b_min))

    def rates(
        self, bands: list, los: np.ndarray, sun_direction: np.ndarray, shape: tuple, runs=None
    ) -> tuple:
        """(e-/s/pixel per band, (bands, samples flattened); the no-data flag, the samples' shape)
        for a batch of samples of ``shape``: the 500 nm brightness once, then each
        :class:`~straylight.optics.bandpass.Band` of ``bands``.  Never skipped: it is the floor
        every skip bound is measured against.

        Parameters
        ----------
        bands : list of Band
            The bands.
        los : ndarray, shape (..., 3)
            Lines of sight, ICRS unit vectors.
        sun_direction : ndarray, shape (..., 3)
            Directions to the Sun from the satellite, ICRS unit vectors.
        shape : tuple
            The samples' shape (``los`` and ``sun_direction`` broadcast to it).
        runs : SceneRuns, optional
            The samples' scene runs; None: found here.

        Returns
        -------
        e_per_s : ndarray, shape (len(bands), prod(shape))
            e-/s/pix per band.
        no_data : ndarray of bool, shape ``shape``
            True where the table has no data near the Sun.
        """
        b500, no_data = self.brightness_500nm(los, sun_direction, runs)
        e = np.empty((len(bands), int(np.prod(shape))))
        for ib, band in enumerate(bands):
            e[ib] = np.broadcast_to(self.e_per_s_per_pix(band, b500), shape).ravel()
        return e, np.broadcast_to(no_data, shape)

    def evaluate(self, band: Band, los: np.ndarray, sun_direction: np.ndarray) -> dict:
        """Zodiacal light for lines of sight and Sun directions (ICRS vectors, broadcast).

        Parameters
        ----------
        band : Band
            The band.
        los : ndarray, shape (..., 3)
            Lines of sight, ICRS unit vectors.
        sun_direction : ndarray, shape (..., 3)
            Directions to the Sun from the satellite, ICRS unit vectors.

        Returns
        -------
        dict of str to ndarray
            Arrays of the broadcast shape: ``e_per_s_per_pix`` (e-/s/pix),
            ``mag_per_arcsec2`` (AB mag/arcsec2), ``brightness_500nm_w_m2_sr_um`` (B_500,
            W m-2 sr-1 um-1) and ``no_data`` (bool, True where the table has no data near the
            Sun).
        """
        b500, flag = self.brightness_500nm(los, sun_direction)
        rate_sr, mag_unit = self.band_factors(band)
        return {
            "e_per_s_per_pix": self.e_per_s_per_pix(band, b500),
            "mag_per_arcsec2": mag_unit - 2.5 * np.log10(b500),
            "brightness_500nm_w_m2_sr_um": b500,
            "no_data": flag,
        }


class ZodiacalLight:
    """The zodiacal light in the field as a source of the background: the campaign's
    :class:`ZodiacalModel` (:attr:`model`) at the samples' lines of sight.  Never skipped: it is
    the floor every skip bound is measured against.

    Parameters
    ----------
    context : SourceContext
        The campaign's instrument as the sources see it (its bands).
    """

    def __init__(self, context):
        self.context = context
        self.model = campaign_zodiacal_model(context.campaign)

    def rates(self, samples, bands) -> BandRates:
        """e-/s/pix per band, (bands, samples flattened), and the ``zodiacal_no_data`` flag (True
        where the Leinert table has no data near the Sun), of the samples' shape.

        Parameters
        ----------
        samples : Samples
            The batch of (time, pointing) samples (reads ``frame.z``, the Sun and the satellite, ``runs``).
        bands : sequence of str
            Band names of the instrument.

        Returns
        -------
        BandRates
            ``per_band["zodiacal"]``: ndarray, shape (bands, samples flattened), e-/s/pix;
            ``extras["zodiacal_no_data"]``: bool ndarray of the samples' shape.

        Raises
        ------
        ConfigError
            When a band reaches outside the zodiacal spectrum's wavelength range.
        """
        c = self.context
        e, no_data = self.model.rates(
            [c.band(name) for name in bands],
            samples.frame.z,
            unit(samples.sun_km - samples.satellite_km),
            samples.shape,
            samples.runs,
        )
        return BandRates(per_band={"zodiacal": e}, extras={"zodiacal_no_data": no_data})


def zodiacal_model_from_instrument(
    instrument: InstrumentSettings | dict,
    spectrum: str = "leinert_fit",
    reddening: tuple = LEINERT_REDDENING_EPS90,
) -> ZodiacalModel:
    """The zodiacal model of the instrument's aperture, focal length and pixel, with the solar
    ``spectrum`` (models.zodiacal_spectrum).  ``instrument``: its typed settings, or its
    mapping (:func:`~straylight.config.instrument.instrument_settings`).

    Parameters
    ----------
    instrument : InstrumentSettings or dict
        The instrument (aperture diameter and focal length in m, pixel size in um).
    spectrum : str
        The zodiacal spectrum, one of :data:`SPECTRA`.
    reddening : tuple of float
        ``(blue_per_dex, red_per_dex)`` of Leinert et al. 1998 eq. 22 (models.zodiacal_reddening),
        read by ``leinert_fit``.

    Returns
    -------
    ZodiacalModel
    """
    inst = instrument_settings(instrument)
    return ZodiacalModel(
        aperture_diameter_m=inst.telescope.aperture_diameter_m.value,
        focal_length_m=inst.telescope.focal_length_m.value,
        pixel_size_m=inst.detector.pixel_size_um.value * 1e-6,
        spectrum=spectrum,
        reddening=tuple(float(x) for x in reddening),
    )


def campaign_zodiacal_model(campaign) -> ZodiacalModel:
    """The campaign's zodiacal model: its instrument with models.zodiacal_spectrum and
    zodiacal_reddening.

    Parameters
    ----------
    campaign : Campaign
        The campaign.

    Returns
    -------
    ZodiacalModel
    """
    models = campaign.settings.models
    return zodiacal_model_from_instrument(
        campaign.instrument_settings, models.zodiacal_spectrum, models.zodiacal_reddening.as_tuple()
    )
