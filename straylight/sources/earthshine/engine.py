"""The one earthshine engine the sunlit and the moonlit Earth wrap (seed paper sect. 3.2).

:class:`EarthGrid` is the Earth-cap grid over the off-field transfer: the transfer
(:class:`~straylight.sources.offfield.OffFieldModel`: PST, door, pixel) with models.earthshine's
grid, albedo and door reflection, and the grid's methods
(:class:`~straylight.sources.earthshine.grid.EarthCapGrid`) and sums
(:class:`~straylight.sources.earthshine.sums.EarthshineSums`).

:class:`Earthshine` holds what both sources read: the grid, the darkest sky in its units, the
Earth's band albedos and the two look-up tables (which model runs, their cache paths, their
builds).  The sources (:class:`~straylight.sources.earthshine.sunlit.SunlitEarth`,
:class:`~straylight.sources.earthshine.moonlit.MoonlitEarth`) each take the one engine; neither
reaches the other."""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

from straylight.optics.door import Door, DoorTable
from straylight.optics.pst import PST
from straylight.sources.body_magnitudes import MOON_PERIGEE_KM, moon_v_magnitude
from straylight.sources.context import SourceContext
from straylight.sources.earthshine.albedo import earth_band_factors
from straylight.sources.earthshine.grid import EarthCapGrid, EarthshineSettings
from straylight.sources.earthshine.sums import EarthshineSums
from straylight.sources.offfield import OffFieldModel
from straylight.sources.photometry import solar_like_fraction

__all__ = ["EARTH_PARTS", "EarthGrid", "Earthshine"]

#: the parts the Earth's light adds to (each scaled by the Earth's band albedo)
EARTH_PARTS = ("earthshine_direct", "earthshine_door")


@dataclass
class EarthGrid(EarthCapGrid, EarthshineSums):
    """The Earth-cap grid of the earthshine sum over one instrument's off-field transfer:
    e-/s/pix per photon s-1 m-2 of the lamp, band-independent.  The transfer's fields are read
    through (the tables' cache keys digest them, :mod:`straylight.sources.earthshine.nodes`).

    Attributes
    ----------
    transfer : OffFieldModel
        The off-field transfer (PST, door, pixel, field radius).
    earthshine : EarthshineSettings
        The Earth grid, albedo and door reflection.
    """

    transfer: OffFieldModel
    earthshine: EarthshineSettings = field(default_factory=EarthshineSettings)

    @property
    def pst(self) -> PST:
        """The transfer's PST."""
        return self.transfer.pst

    @property
    def door(self) -> Door:
        """The transfer's door."""
        return self.transfer.door

    @property
    def door_states_deg(self) -> tuple:
        """The door's allowed openings, deg."""
        return self.transfer.door_states_deg

    @property
    def door_tables(self) -> dict[float, DoorTable]:
        """Door state (opening, deg) -> its Sp table."""
        return self.transfer.door_tables

    @property
    def pixel_area_m2(self) -> float:
        """Detector pixel area, m2."""
        return self.transfer.pixel_area_m2

    @property
    def pixel_etendue_m2_sr(self) -> float:
        """Aperture area times pixel solid angle, m2 sr."""
        return self.transfer.pixel_etendue_m2_sr

    @property
    def field_radius_deg(self) -> float:
        """Radius of the field of view, deg."""
        return self.transfer.field_radius_deg

    def door_factor(self, theta_deg, phi_deg, opening_deg):
        """The transfer's :meth:`~straylight.sources.offfield.OffFieldModel.door_factor`.

        Parameters
        ----------
        theta_deg, phi_deg : array_like
            Directions in the telescope frame, deg.
        opening_deg : array_like
            Each sample's door opening, deg.

        Returns
        -------
        ndarray
            Sp in [0, 1], of the broadcast shape.
        """
        return self.transfer.door_factor(theta_deg, phi_deg, opening_deg)


def _earth_grid(context: SourceContext) -> EarthGrid:
    """The campaign's Earth grid: models.earthshine's grid and albedo, the instrument's door
    reflectance, over the context's transfer."""
    es = context.campaign.settings.models.earthshine
    inst = context.campaign.instrument_settings
    return EarthGrid(
        context.offfield,
        EarthshineSettings(
            n_gamma=es.n_gamma,
            n_psi=es.n_psi,
            albedo=float(es.albedo),
            door_blocks=es.door_blocks,
            door_reflectance=inst.door_geometry.reflectance.value,
            n_aperture_door=es.n_aperture_door,
            cut_block_split=es.cut_block_split,
        ),
    )


class Earthshine:
    """What the sunlit and the moonlit Earth share: the Earth grid (:attr:`grid`), the darkest
    sky in its units (:attr:`floor`), the Earth's band albedos and the two tables: which model
    runs (:attr:`sunlit_choice`, :attr:`sunlit_model`, :attr:`moonlit_model`), where each is
    cached, and their builds (``build_workers`` threads; the result does not depend on them).

    Parameters
    ----------
    context : SourceContext
        The campaign's instrument as the sources see it.
    policy : FidelityPolicy
        The fidelity policy (tolerance, table shares, build-cost figures).
    build_workers : int
        Threads that build a missing table.
    """

    def __init__(self, context: SourceContext, policy, build_workers: int = 1):
        self.context, self.policy, self.build_workers = context, policy, build_workers

    @cached_property
    def grid(self) -> EarthGrid:
        """The Earth-cap grid over the off-field transfer (models.earthshine)."""
        return _earth_grid(self.context)

    @cached_property
    def floor(self) -> float:
        """The darkest sky background in earthshine-coefficient units (e-/s/pix per photon
        s-1 m-2 of the Sun at 1 AU), over the instrument's bands, each band's solar irradiance
        times the Earth's band albedo over the grey one: errors relative to it bound errors
        relative to the total."""
        c = self.context
        bands = tuple(c.campaign.bands)
        factors = earth_band_factors(c, bands)
        if factors is None:
            return c.solar_floor(bands)
        return min(
            c.darkest_zodiacal_e_per_s(b) / (c.photometry(b).sun_at_1au_photons_s_m2 * float(f))
            for b, f in zip(bands, factors)
        )

    def band_factors(self, bands):
        """The Earth's band albedo over the grey one in ``bands``
        (:func:`~straylight.sources.earthshine.albedo.earth_band_factors`).

        Parameters
        ----------
        bands : sequence of str
            Band names.

        Returns
        -------
        ndarray or None
            One factor per band, dimensionless; None for the grey spectrum.
        """
        return earth_band_factors(self.context, bands)

    # -- the sunlit table -------------------------------------------------------------------
    def sunlit_node_states(self, settings) -> int:
        """How many (node, door state) pairs the sunlit table with these
        :class:`~straylight.sources.earthshine.nodes.LUTSettings` sums, each an Earth-grid sum.

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
        return settings.node_count(r[0], c.earth.radius_km, mirror_symmetric(self.grid)) * len(
            self.grid.door_states_deg
        )

    @cached_property
    def sunlit_choice(self) -> dict:
        """Which model :attr:`sunlit_model` will run, decided without building anything
        (``straylight plan`` reads it).  Keys: method ('lut' or 'direct'), requested
        (models.earthshine.method), reason, settings
        (:class:`~straylight.sources.earthshine.nodes.LUTSettings`), node_states and
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
        node_states = self.sunlit_node_states(settings)
        build_s, moonlit_s = self.policy.tables_build_seconds(node_states, self.moonlit_node_states())
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
        """The avoidance angles the sunlit table depends on (dark limb, bright limb, Sun), deg."""
        k = self.context.campaign.constraints
        return (k.dark_limb_min_deg, k.bright_limb_min_deg, k.sun_min_deg)

    def sunlit_lut_path(self) -> Path:
        """Where the sunlit table of :attr:`sunlit_choice`'s settings is cached (it may not
        exist yet): the path :func:`~straylight.sources.earthshine.sunlit_build.load_or_build`
        reads or writes.

        Returns
        -------
        Path
        """
        from straylight.sources.earthshine.nodes import cache_path, lut_key

        c = self.context.campaign
        key = lut_key(
            self.grid,
            c.earth.radius_km,
            c.orbit_radius_range_km,
            self.sunlit_choice["settings"],
            self.floor,
            self.avoidance_deg,
        )
        return cache_path("earthshine_lut", key)

    @cached_property
    def sunlit_model(self) -> dict:
        """The sunlit model that runs (:attr:`sunlit_choice`, the table built or loaded): keys
        method, lut (the :class:`~straylight.sources.earthshine.sunlit_table.EarthshineLUT` or
        None), reason, and for the table its file, validated error, build time, node states and
        steps."""
        from straylight.sources.earthshine.sunlit_build import load_or_build

        choice = self.sunlit_choice
        if choice["method"] == "direct":
            return {"method": "direct", "lut": None, "reason": choice["reason"]}
        settings, c = choice["settings"], self.context.campaign
        log = logging.getLogger("straylight")
        lut, path = load_or_build(
            self.grid,
            c.earth.radius_km,
            c.orbit_radius_range_km,
            settings,
            self.floor,
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
        return self._accept_sunlit(choice, lut, info, log)

    def _accept_sunlit(self, choice: dict, lut, info: dict, log) -> dict:
        """:attr:`sunlit_model` once the table is read: the table, or with 'auto' the direct
        sum when its validated error exceeds its share of the tolerance."""
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
    def sunlit_lut(self):
        """The sunlit table when it runs, else None (the direct sum runs)."""
        return self.sunlit_model["lut"]

    # -- the moonlit table ------------------------------------------------------------------
    @cached_property
    def moonlit_grid(self) -> tuple[int, int]:
        """models.earthshine.moonlit_grid: (n_gamma, n_psi) of the moonlit Earth's coarse grid."""
        return tuple(int(n) for n in self.context.campaign.settings.models.earthshine.moonlit_grid)

    def moonlit_settings(self):
        """The moonlit table's :class:`~straylight.sources.earthshine.nodes.MoonlitSettings`
        from the config, or None when the moonlit Earth is summed directly (moonlit_method =
        direct).

        Returns
        -------
        MoonlitSettings or None
        """
        from straylight.sources.earthshine.nodes import MoonlitSettings

        es = self.context.campaign.settings.models.earthshine
        if es.moonlit_method == "direct":
            return None
        steps = es.moonlit_lut
        return MoonlitSettings(
            float(steps.moon_zenith_step_deg),
            float(steps.los_zenith_step_deg),
            float(steps.azimuth_step_deg),
            float(steps.roll_step_deg),
        )

    def moonlit_node_states(self) -> int:
        """How many (node, door state) pairs the moonlit table sums, each a coarse Earth-grid
        sum; 0 with models.earthshine.moonlit_method = direct.

        Returns
        -------
        int
        """
        from straylight.sources.earthshine.nodes import mirror_symmetric

        settings = self.moonlit_settings()
        if settings is None:
            return 0
        c = self.context.campaign
        r = c.orbit_radius_range_km
        nodes = settings.node_count(float(r[0]), c.earth.radius_km, mirror_symmetric(self.grid))
        return nodes * len(self.grid.door_states_deg)

    def _moonlit_table_inputs(self, settings):
        """The arguments of :func:`~straylight.sources.earthshine.moonlit_build.load_or_build_moonlit`
        (and of its cache key) before the logger: the grid, the Earth, the orbit, the settings,
        the coarse grid, the darkest sky and the brightest Moon (full, at perigee) per unit
        solar irradiance at 1 AU, and the dark-limb angle."""
        c = self.context.campaign
        moon_max = float(
            solar_like_fraction(moon_v_magnitude(0.0, MOON_PERIGEE_KM, self.context.offfield.moon_law, 180.0))
        )
        from straylight.sources.earthshine.nodes import MoonlitInputs

        return MoonlitInputs(
            self.grid,
            c.earth.radius_km,
            c.orbit_radius_range_km,
            settings,
            self.moonlit_grid,
            self.floor,
            moon_max,
            c.constraints.dark_limb_min_deg,
        )

    def moonlit_lut_path(self) -> Path | None:
        """Where the moonlit table of the configured settings is cached (it may not exist
        yet); None when the moonlit Earth is summed directly.

        Returns
        -------
        Path or None
        """
        from straylight.sources.earthshine.nodes import cache_path, moonlit_key

        settings = self.moonlit_settings()
        return (
            None
            if settings is None
            else cache_path("moonlit_lut", moonlit_key(*self._moonlit_table_inputs(settings)))
        )

    @cached_property
    def moonlit_model(self) -> dict:
        """How the moonlit Earth is summed where its bound does not let it be skipped: 'lut', its
        own table over (Moon zenith, line-of-sight zenith, azimuth from the Moon, roll) of the
        coarse grid's sum, when its validated error (full Moon at perigee, a fraction of the
        total) is within the moonlit grid's share of the tolerance, else (or with 'direct') the
        coarse grid's direct sum.  Keys: method, lut, and for the table its file, validated error
        and steps."""
        from straylight.sources.earthshine.moonlit_build import load_or_build_moonlit

        settings = self.moonlit_settings()
        if settings is None:
            return {"method": "direct", "lut": None, "reason": "models.earthshine.moonlit_method = direct"}
        lut, path = load_or_build_moonlit(
            self._moonlit_table_inputs(settings), logging.getLogger("straylight"), self.build_workers
        )
        info = {
            "lut_file": path.name,
            "lut_validation_max_rel_error": lut.validation_max_rel_error,
            "lut_steps_deg": [
                settings.moon_zenith_step_deg,
                settings.los_zenith_step_deg,
                settings.azimuth_step_deg,
                settings.roll_step_deg,
            ],
        }
        if not self.policy.accepts_table("moonlit_earthshine_grid", lut.validation_max_rel_error):
            return {
                "method": "direct",
                "lut": None,
                **info,
                "reason": f"table error {lut.validation_max_rel_error:.2g} > "
                f"{self.policy.share('moonlit_earthshine_grid'):g} x the tolerance",
            }
        return {"method": "lut", "lut": lut, **info}
