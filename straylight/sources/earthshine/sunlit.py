"""The sunlit Earth (paper sect. 3.2): earthshine reaching the aperture directly (EA1) and by
the door's reflection (EA2), as coefficients in e-/s/pix per photon s-1 m-2 of the lamp's
irradiance (the Sun's at the satellite, the Moon's at the Earth), summed with the grey albedo
and scaled in each band by the Earth's band albedo over it
(:mod:`straylight.sources.earthshine.albedo`).

Two ways side by side, chosen by models.earthshine.method and the fidelity policy: the direct
sum over the Earth grid (:meth:`~straylight.sources.earthshine.engine.EarthGrid.earthshine_coefficients`,
which lights each block by the Sun and the Moon in one pass, so the moonlit Earth comes with it),
or the look-up table of that sum (:class:`~straylight.sources.earthshine.sunlit_table.EarthshineLUT`,
the Sun only; the moonlit Earth then adds its own, :mod:`straylight.sources.earthshine.moonlit`).
``auto`` takes the table whenever it validates within the earthshine_lut share of the
tolerance."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from straylight.sources.context import Samples, SourceContext
from straylight.sources.earthshine.engine import EARTH_PARTS, Earthshine
from straylight.sources.earthshine.sums import Bodies
from straylight.sources.rates import BandRates

__all__ = ["COEFFICIENTS", "SunlitEarth"]

#: the keys of the earthshine coefficients (e-/s/pix per photon s-1 m-2 of the lamp): direct
#: (EA1) and via the door (EA2), lit by the Sun and by the Moon
COEFFICIENTS = ("direct_sun", "door_sun", "direct_moon", "door_moon")


class SunlitEarth:
    """The sunlit Earth's coefficients for a batch of samples (:meth:`rates`), by the model the
    engine picks (:attr:`Earthshine.sunlit_model
    <straylight.sources.earthshine.engine.Earthshine.sunlit_model>`).

    Parameters
    ----------
    engine : Earthshine
        The earthshine engine (Earth grid, tables) the moonlit Earth shares.
    """

    def __init__(self, engine: Earthshine):
        self.engine = engine

    @property
    def context(self) -> SourceContext:
        """The campaign's instrument as the sources see it."""
        return self.engine.context

    def node_states(self, settings) -> int:
        """:meth:`Earthshine.sunlit_node_states
        <straylight.sources.earthshine.engine.Earthshine.sunlit_node_states>`.

        Parameters
        ----------
        settings : LUTSettings
            The table's node steps.

        Returns
        -------
        int
        """
        return self.engine.sunlit_node_states(settings)

    @property
    def choice(self) -> dict:
        """Which model runs, decided without building anything
        (:attr:`~straylight.sources.earthshine.engine.Earthshine.sunlit_choice`)."""
        return self.engine.sunlit_choice

    def lut_path(self) -> Path:
        """Where the table is cached
        (:meth:`~straylight.sources.earthshine.engine.Earthshine.sunlit_lut_path`).

        Returns
        -------
        Path
        """
        return self.engine.sunlit_lut_path()

    @property
    def model(self) -> dict:
        """The model that runs, the table built or loaded
        (:attr:`~straylight.sources.earthshine.engine.Earthshine.sunlit_model`)."""
        return self.engine.sunlit_model

    @property
    def lut(self):
        """The sunlit table when it runs, else None (the direct sum runs)."""
        return self.engine.sunlit_lut

    def rates(self, samples: Samples, bands) -> BandRates:
        """The earthshine's coefficients on the ``sun`` and ``moon_at_earth`` lamps, direct
        (``earthshine_direct``) and via the door (``earthshine_door``), arrays of the samples'
        shape (:meth:`coefficients`).

        Parameters
        ----------
        samples : Samples
            The batch of (time, pointing) samples (reads the satellite, the Sun, the Moon,
            ``frame``, the door and ``runs``).
        bands : sequence of str
            Band names of the instrument (the coefficients are band-independent; the Earth's
            band albedos give their factors).

        Returns
        -------
        BandRates
            ``per_lamp["earthshine_direct"]`` and ``per_lamp["earthshine_door"]``, each with
            ``"sun"`` (e-/s/pix per photon s-1 m-2 of the Sun at the satellite) and
            ``"moon_at_earth"`` (e-/s/pix per photon s-1 m-2 of the Moon's lamp): ndarrays of
            the samples' shape, summed with the grey albedo; ``band_factors`` of both parts: the
            band albedo over the grey one per band
            (:func:`~straylight.sources.earthshine.albedo.earth_band_factors`; none for ``grey``).
        """
        c = self.coefficients(samples)
        factors = self.engine.band_factors(bands)
        return BandRates(
            per_lamp={
                "earthshine_direct": {"sun": c["direct_sun"], "moon_at_earth": c["direct_moon"]},
                "earthshine_door": {"sun": c["door_sun"], "moon_at_earth": c["door_moon"]},
            },
            band_factors={} if factors is None else {p: factors for p in EARTH_PARTS},
        )

    def coefficients(self, samples: Samples) -> dict:
        """The earthshine coefficients (:data:`COEFFICIENTS`, arrays of the samples' shape).  The
        direct sum gives every term; the table gives the sunlit Earth, and of the moonlit Earth
        only the part inside the field (the rest: :meth:`MoonlitEarth.rates
        <straylight.sources.earthshine.moonlit.MoonlitEarth.rates>`).

        Parameters
        ----------
        samples : Samples
            The batch of samples (reads the satellite, the Sun, the Moon, ``frame``, the door
            and ``runs``).

        Returns
        -------
        dict of str to ndarray
            :data:`COEFFICIENTS` -> array of the samples' shape: ``*_sun`` in e-/s/pix per
            photon s-1 m-2 of the Sun at the satellite, ``*_moon`` per photon s-1 m-2 of the
            Moon at the Earth.
        """
        off, re_km = self.engine.grid, self.context.campaign.earth.radius_km
        sat, sun, moon, frame, door = (
            samples.satellite_km,
            samples.sun_km,
            samples.moon_km,
            samples.frame,
            samples.door_deg,
        )
        shape, lut = samples.shape, self.lut
        if lut is None:
            return off.earthshine_coefficients(Bodies(sat, sun, moon), frame, door, re_km)
        full = shape + (3,)
        sat_b, sun_b, moon_b = (np.broadcast_to(np.asarray(v, float), full) for v in (sat, sun, moon))
        d_sun, g_sun = lut.sun_coefficients(
            sat_b,
            sun_b,
            np.broadcast_to(frame.z, full),
            np.broadcast_to(np.asarray(door, float), shape),
            samples.runs,
        )
        in_field_sun, in_field_moon = off.earth_in_field(sat_b, sun_b, moon_b, frame, re_km)
        return {
            "direct_sun": d_sun + in_field_sun,
            "door_sun": g_sun,
            "direct_moon": in_field_moon,
            "door_moon": np.zeros(shape),
        }

    def record(self) -> dict:
        """The model that ran and its Earth grid, for a product's attributes (JSON-able; the
        build time left out: products' bytes must not vary run to run).

        Returns
        -------
        dict
            :attr:`model`'s keys less the table object, build time and node states, with
            ``earth_grid`` [n_gamma, n_psi], ``door_blocks`` and ``aperture_points_door``.
        """
        es = {k: v for k, v in self.model.items() if k not in ("lut", "lut_build_seconds", "lut_node_states")}
        s = self.engine.grid.earthshine
        es["earth_grid"] = [s.n_gamma, s.n_psi]
        es["door_blocks"], es["aperture_points_door"] = list(s.door_blocks), s.n_aperture_door
        return es
