"""The sunlit Earth (paper sect. 3.2): earthshine reaching the aperture directly (EA1) and by
the door's reflection (EA2), as coefficients in e-/s/pix per photon s-1 m-2 of the lamp's
irradiance (the Sun's at the satellite, the Moon's at the Earth), summed with the grey albedo
and scaled in each band by the Earth's band albedo over it
(:mod:`straylight.sources.earthshine.albedo`).

Two ways side by side, chosen by models.earthshine.method and the fidelity policy: the direct
sum over the Earth grid (:meth:`~straylight.sources.offfield.OffFieldModel.earthshine_coefficients`,
which lights each block by the Sun and the Moon in one pass, so the moonlit Earth comes with it),
or the look-up table of that sum (:class:`~straylight.sources.earthshine.sunlit_table.EarthshineLUT`,
the Sun only; the moonlit Earth then adds its own, :mod:`straylight.sources.earthshine.moonlit`).
``auto`` takes the table whenever it validates within the earthshine_lut share of the
tolerance."""

from __future__ import annotations

import logging
from functools import cached_property
from pathlib import Path

import numpy as np

from straylight.sources.context import Samples, SourceContext
from straylight.sources.earthshine.albedo import earth_band_factors
from straylight.sources.rates import BandRates

__all__ = ["COEFFICIENTS", "EARTH_PARTS", "SunlitEarth"]

#: the parts the Earth's light adds to (each scaled by the Earth's band albedo)
EARTH_PARTS = ("earthshine_direct", "earthshine_door")

#: the keys of the earthshine coefficients (e-/s/pix per photon s-1 m-2 of the lamp): direct
#: (EA1) and via the door (EA2), lit by the Sun and by the Moon
COEFFICIENTS = ("direct_sun", "door_sun", "direct_moon", "door_moon")


class SunlitEarth:
    """The sunlit Earth's coefficients for a batch of samples (:meth:`rates`), by the model
    :attr:`model` picks.  ``moonlit``: the moonlit Earth, whose table the table path builds
    too (its build is counted in the estimate); ``build_workers``: threads that build a table
    that is not cached (the result does not depend on it).

    Parameters
    ----------
    context : SourceContext
        The campaign's instrument as the sources see it.
    policy : FidelityPolicy
        The fidelity policy (tolerance, table shares, build-cost figures).
    moonlit : MoonlitEarth
        The moonlit Earth.
    build_workers : int
        Threads that build a missing table.
    """

    def __init__(self, context: SourceContext, policy, moonlit, build_workers: int = 1):
        self.context, self.policy, self.moonlit, self.build_workers = context, policy, moonlit, build_workers

    def node_states(self, settings) -> int:
        """How many (node, door state) pairs the sunlit table with these
        :class:`~straylight.sources.earthshine.nodes.LUTSettings` sums, each an Earth-grid
        sum.

        Parameters
        ----------
        settings : LUTSettings
            The table's node steps.

        Returns
        -------
        int
        """
        from straylight.sources.earthshine.nodes import mirror_symmetric

        c = self.context.campaign
        r = c.orbit_radius_range_km
        return settings.node_count(r[0], c.earth.radius_km, mirror_symmetric(self.context.offfield)) * len(
            self.context.offfield.door_states_deg
        )

    @cached_property
    def choice(self) -> dict:
        """Which model :attr:`model` will run, decided without building anything (``straylight
        plan`` reads it).  Keys: method ('lut' or 'direct'), requested (models.earthshine.method),
        reason, settings (:class:`~straylight.sources.earthshine.nodes.LUTSettings`), node_states and
        build_seconds_estimate (the sunlit table's build plus the moonlit one's,
        moonlit_build_seconds_estimate, at the policy's cost figures; 0 for 'direct' by config).
        With 'auto' the table still falls back to the direct sum when its validated error,
        known once it is built, exceeds its share of the tolerance."""
        from straylight.sources.earthshine.nodes import LUTSettings

        es = self.context.campaign.settings.models.earthshine
        method = es.method
        if method == "direct":
            return {
                "method": "direct",
                "requested": method,
                "reason": "models.earthshine.method = direct",
                "settings": None,
                "node_states": 0,
                "build_seconds_estimate": 0.0,
                "moonlit_build_seconds_estimate": 0.0,
            }
        steps = es.lut
        settings = LUTSettings(
            float(steps.sun_zenith_step_deg),
            float(steps.los_zenith_step_deg),
            float(steps.azimuth_step_deg),
            int(steps.n_radius),
        )
        node_states = self.node_states(settings)
        build_s, moonlit_s = self.policy.tables_build_seconds(node_states, self.moonlit.node_states())
        chosen, reason = self.policy.earthshine_method(method)
        return {
            "method": chosen,
            "requested": method,
            "reason": reason,
            "settings": settings,
            "node_states": node_states,
            "build_seconds_estimate": build_s,
            "moonlit_build_seconds_estimate": moonlit_s,
        }

    @property
    def avoidance_deg(self) -> tuple:
        """The avoidance angles the table depends on (dark limb, bright limb, Sun), deg."""
        k = self.context.campaign.constraints
        return (k.dark_limb_min_deg, k.bright_limb_min_deg, k.sun_min_deg)

    def lut_path(self) -> Path:
        """Where the table of :attr:`choice`'s settings is cached (it may not exist yet): the
        path :func:`~straylight.sources.earthshine.sunlit_build.load_or_build` reads or writes.

        Returns
        -------
        Path
        """
        from straylight.sources.earthshine.nodes import cache_path, lut_key

        c = self.context
        key = lut_key(
            c.offfield,
            c.campaign.earth.radius_km,
            c.campaign.orbit_radius_range_km,
            self.choice["settings"],
            c.earthshine_floor,
            self.avoidance_deg,
        )
        return cache_path("earthshine_lut", key)

    @cached_property
    def model(self) -> dict:
        """The model that runs (:attr:`choice`, the table built or loaded): keys method, lut
        (the :class:`~straylight.sources.earthshine.sunlit_table.EarthshineLUT` or None), reason, and for
        the table its file, validated error, build time, node states and steps."""
        from straylight.sources.earthshine.sunlit_build import load_or_build

        choice = self.choice
        if choice["method"] == "direct":
            return {"method": "direct", "lut": None, "reason": choice["reason"]}
        settings, c = choice["settings"], self.context
        log = logging.getLogger("straylight")
        lut, path = load_or_build(
            c.offfield,
            c.campaign.earth.radius_km,
            c.campaign.orbit_radius_range_km,
            settings,
            c.earthshine_floor,
            log,
            avoidance_deg=self.avoidance_deg,
            workers=self.build_workers,
        )
        info = {
            "lut_file": str(path.name),
            "lut_validation_max_rel_error": lut.validation_max_rel_error,
            "lut_build_seconds": lut.build_seconds,
            "lut_node_states": choice["node_states"],
            "lut_steps_deg": [
                settings.sun_zenith_step_deg,
                settings.los_zenith_step_deg,
                settings.azimuth_step_deg,
            ],
        }
        share = self.policy.share("earthshine_lut")
        if choice["requested"] == "auto" and not self.policy.accepts_table(
            "earthshine_lut", lut.validation_max_rel_error
        ):
            reason = (
                f"auto: table error {lut.validation_max_rel_error:.2g} > {share:g} x the tolerance "
                f"{self.policy.tolerance:g}"
            )
            log.info("earthshine: %s: direct sum", reason)
            return {"method": "direct", "lut": None, "reason": reason, **info}
        return {"method": "lut", "lut": lut, "reason": choice["reason"], **info}

    @property
    def lut(self):
        """The sunlit table when it runs, else None (the direct sum runs)."""
        return self.model["lut"]

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
        factors = earth_band_factors(self.context, bands)
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
        off, re_km = self.context.offfield, self.context.campaign.earth.radius_km
        sat, sun, moon, frame, door = (
            samples.satellite_km,
            samples.sun_km,
            samples.moon_km,
            samples.frame,
            samples.door_deg,
        )
        shape, lut = samples.shape, self.lut
        if lut is None:
            return off.earthshine_coefficients(sat, sun, moon, frame, door, re_km)
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
        s = self.context.offfield.earthshine
        es["earth_grid"] = [s.n_gamma, s.n_psi]
        es["door_blocks"], es["aperture_points_door"] = list(s.door_blocks), s.n_aperture_door
        return es
