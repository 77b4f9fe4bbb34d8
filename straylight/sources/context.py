"""The base every source of light builds on, importing no source: :class:`Samples`, the batch of
(time, pointing) samples every source is asked about; :class:`Source`, the one question it
answers; and :class:`SourceContext`, what every source shares: the campaign, the off-field
transfer (PST, door, Earth blocking: :class:`~straylight.sources.offfield.OffFieldModel`), each
band's throughput and solar photometry, and the darkest sky every skip bound is measured against
(the zodiacal floor, passed in by the model)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Callable, Protocol, Sequence

import numpy as np

from straylight.config import Campaign, needed
from straylight.optics.bandpass import Band, load_band
from straylight.optics.door import door_from_instrument
from straylight.optics.pst import load_pst
from straylight.sky.frames import TelescopeFrame
from straylight.sky.vectors import norm
from straylight.sources.offfield import OffFieldModel
from straylight.sources.photometry import AU_KM, BandPhotometry, pixel_etendue_m2_sr
from straylight.sources.rates import BandRates

__all__ = ["Samples", "Source", "SourceContext"]


@dataclass
class Samples:
    """A batch of (time, pointing) samples, broadcastable arrays: ``satellite_km`` (..., 3) and
    ``bodies_km`` (body -> (..., 3), geocentric ICRS km; at least the Sun and the Moon),
    ``frame`` (the samples' ``telescope_frame(los, sun - satellite)``), ``geometry``
    (:func:`~straylight.sky.observing.observing_geometry`'s: the Sun's and the Moon's angles,
    the door's state), ``runs``: the samples' scene runs when the caller knows them
    (:class:`~straylight.sky.runs.SceneRuns`, e.g. a cube's time steps), else None;
    ``stars``: the off-field stars (a :class:`~straylight.sources.stars_table.StarTable`, or None:
    no stars); ``faint_rates``: the faint stars' map at these lines of sight, band -> e-/s/pix,
    when already computed.

    The background model sets the rest before it asks the sources: ``moon_lamp`` (the Moon's
    irradiance, :meth:`~straylight.sources.bodies.Moon.lamp`), then, once the sources that are
    never skipped are summed, ``floor`` (band -> e-/s/pix, a lower bound of each sample's total)
    and ``floor_ratio`` (its smallest ratio over the bands to the darkest zodiacal light, >= 1),
    which the skippable sources measure their skips against."""

    satellite_km: np.ndarray
    bodies_km: dict
    frame: TelescopeFrame
    geometry: dict
    runs: object = None
    stars: object = None
    faint_rates: dict | None = None
    moon_lamp: dict | None = None
    floor: dict | None = None
    floor_ratio: np.ndarray | None = None

    @property
    def shape(self) -> tuple:
        """The samples' shape."""
        return self.geometry["sun_angle_deg"].shape

    @property
    def door_deg(self) -> np.ndarray:
        """Each sample's door opening, deg."""
        return self.geometry["door_opening_deg"]

    @property
    def sun_km(self) -> np.ndarray:
        """The Sun's geocentric ICRS position, km, (..., 3)."""
        return self.bodies_km["sun"]

    @property
    def moon_km(self) -> np.ndarray:
        """The Moon's geocentric ICRS position, km, (..., 3)."""
        return self.bodies_km["moon"]

    @cached_property
    def sun_inverse_square(self) -> np.ndarray:
        """(1 AU / Sun-satellite distance)^2 per sample, dimensionless: the Sun's irradiance at
        the satellite relative to 1 AU (the ``sun`` lamp's scale,
        :data:`~straylight.sources.rates.LAMPS`)."""
        return (AU_KM / norm(self.sun_km - self.satellite_km)) ** 2


class Source(Protocol):
    """What the background model asks a source of light."""

    def rates(self, samples: Samples, bands: Sequence[str]) -> BandRates:
        """The source's e-/s/pix in each band at the samples.

        Parameters
        ----------
        samples : Samples
            The batch of (time, pointing) samples; a skippable source also reads its
            ``floor`` and ``floor_ratio``, which the model sets before asking it.
        bands : sequence of str
            Band names of the instrument.

        Returns
        -------
        BandRates
            Per-band arrays (bands, samples) and/or per-lamp coefficients of the samples'
            shape, keyed by the component (or part) the source adds to.
        """


@dataclass
class SourceContext:
    """One campaign's instrument as the sources see it: the off-field transfer, the bands and
    their solar photometry, and the darkest sky.  Built once per model; everything is cached.

    Attributes
    ----------
    campaign : Campaign
        The campaign (instrument, settings, bands, Earth and orbit).
    zodiacal_floor : callable, optional
        ``zodiacal_floor(band) -> float``: e-/s/pix of the darkest zodiacal light in a
        :class:`~straylight.optics.bandpass.Band`
        (:meth:`~straylight.sources.zodiacal.ZodiacalModel.darkest_e_per_s_per_pix`); None: a
        context without floors (its bands and transfer only).
    """

    campaign: Campaign
    zodiacal_floor: Callable[[Band], float] | None = None

    @cached_property
    def offfield(self) -> OffFieldModel:
        """The off-field transfer from the instrument (PST, door, pixel, field radius) and the
        models' Moon phase law and eclipse factor."""
        inst = self.campaign.instrument_settings
        pst_file = inst.pst.file
        if pst_file and not Path(pst_file).is_absolute():
            pst_file = self.campaign.instrument_path.parent / pst_file
        models = self.campaign.settings.models
        fov_deg2 = needed(inst.detector.field_of_view_deg2, "detector.field_of_view_deg2").value
        field_radius_deg = float(np.sqrt(fov_deg2 / np.pi))
        return OffFieldModel(
            pst=load_pst(pst_file, field_radius_deg, inst.pst.tail_log10_at_90deg.value),
            door=door_from_instrument(inst),
            door_states_deg=tuple(s.opening_deg for s in inst.door.states),
            pixel_area_m2=(inst.detector.pixel_size_um.value * 1e-6) ** 2,
            pixel_etendue_m2_sr=pixel_etendue_m2_sr(
                inst.telescope.aperture_diameter_m.value,
                inst.telescope.focal_length_m.value,
                inst.detector.pixel_size_um.value * 1e-6,
            ),
            field_radius_deg=field_radius_deg,
            moon_law=models.moon_phase_law,
            moon_eclipse_factor=float(models.moon_eclipse_factor),
        )

    @cached_property
    def _bands(self) -> dict:
        return {}

    def band(self, name) -> Band:
        """The instrument's band ``name`` (throughput, zero points), loaded once.

        Parameters
        ----------
        name : str
            The band's name in the instrument settings.

        Returns
        -------
        Band
        """
        if name not in self._bands:
            b = load_band(self.campaign.instrument_settings, name, self.campaign.instrument_path.parent)
            self._bands[name] = (b, BandPhotometry(b))
        return self._bands[name][0]

    def photometry(self, name) -> BandPhotometry:
        """Band ``name``'s photometry: the Sun's photon irradiance at 1 AU through it, AB and
        solar-like magnitudes to photons s-1 m-2.

        Parameters
        ----------
        name : str
            The band's name in the instrument settings.

        Returns
        -------
        BandPhotometry
        """
        self.band(name)
        return self._bands[name][1]

    def darkest_zodiacal_e_per_s(self, band: str) -> float:
        """e-/s/pix of the zodiacal light at the darkest point of the Leinert (1998) table, in a
        band: the floor of any total background (scheduling tables, error budgets).  Cached per
        band (every evaluation's skips read it).

        Parameters
        ----------
        band : str
            The band's name.

        Returns
        -------
        float
            e-/s/pix.
        """
        cache = self.__dict__.setdefault("_darkest_zodiacal", {})
        if band not in cache:
            if self.zodiacal_floor is None:
                raise ValueError("this source context was built without the zodiacal floor")
            cache[band] = float(self.zodiacal_floor(self.band(band)))
        return cache[band]

    def solar_floor(self, bands: tuple) -> float:
        """The darkest sky background over ``bands`` in units of the Sun's light (cached per set
        of bands).

        Parameters
        ----------
        bands : tuple of str
            Band names.

        Returns
        -------
        float
            The smallest over ``bands`` of the darkest zodiacal light over the band's solar
            photon irradiance at 1 AU: e-/s/pix per photon s-1 m-2 of the Sun at 1 AU.
        """
        cache = self.__dict__.setdefault("_solar_floor", {})
        if bands not in cache:
            cache[bands] = min(
                self.darkest_zodiacal_e_per_s(b) / self.photometry(b).sun_at_1au_photons_s_m2 for b in bands
            )
        return cache[bands]
