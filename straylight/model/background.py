"""The background model: asks each source of light for its e-/s/pixel in every band for a batch
of (time, pointing) samples and adds them (:meth:`BackgroundModel.evaluate`, the Python API
behind ``straylight sky`` and the survey cubes).  The sources are in :mod:`straylight.sources`;
the error each fast path may spend is :class:`~straylight.model.fidelity.FidelityPolicy`'s.

The only thing the model itself computes is each sample's floor: the terms never skipped (the
zodiacal light, the Sun, the sunlit Earth and, on the direct sum's path, the moonlit Earth),
never below the darkest zodiacal light, a lower bound of the total that the skippable sources
(the moonlit Earth on the table's path, the Moon, the planets, the stars) measure their budgets
against, so a term that matters only against the darkest sky is still summed there and skipped
where the scene's brighter light swamps it.  Every component is reported whether or not the
pointing is observable."""

from __future__ import annotations

import numpy as np

from straylight.config import Campaign
from straylight.model import registry
from straylight.model._kernels import KERNEL_BLOCK_SAMPLES
from straylight.model._kernels import Terms as _Terms
from straylight.model._kernels import band_components_kernel as _band_components_kernel
from straylight.model._kernels import check_into as _check_into
from straylight.model._kernels import flat as _flat
from straylight.model._kernels import floor_kernel as _floor_kernel
from straylight.model._kernels import irradiance as _irradiance
from straylight.model._kernels import rows as _rows
from straylight.model._kernels import sum_program as _sum_program
from straylight.model.fidelity import ERROR_BUDGET_SHARES, FidelityPolicy
from straylight.sky.ephemeris import PLANETS
from straylight.sky.frames import telescope_frame
from straylight.sources.bodies import InFieldBodies, SolarBodySkip
from straylight.sources.context import Samples, SourceContext
from straylight.sources.photometry import magnitude_per_arcsec2, sky_zero_point_mag_per_arcsec2
from straylight.sources.rates import LAMPS
from straylight.sources.stars_table import StarTable
from straylight.sources.zodiacal import campaign_zodiacal_model

__all__ = ["BackgroundModel", "KERNEL_BLOCK_SAMPLES"]


class BackgroundModel:
    """The background of one campaign: its sources of light (built from
    :data:`~straylight.model.registry.SOURCES`: :meth:`source`) and its fidelity policy; what
    callers need of the instrument and the earthshine tables through its own methods
    (:meth:`band`, :meth:`photometry`, :meth:`darkest_zodiacal_e_per_s`, :attr:`offfield`,
    :attr:`earth_grid`, :meth:`earth_band_factors`, :attr:`earthshine_choice`,
    :meth:`table_paths`, :attr:`uses_sunlit_table`).

    Parameters
    ----------
    campaign : Campaign
        The campaign (its instrument, models and orbit).
    build_workers : int or None
        Threads that build an earthshine table that is not cached (None: every CPU this
        process may run on; the result does not depend on it).
    moonlit_skip_share : float
        See :class:`~straylight.model.fidelity.FidelityPolicy`.
    """

    def __init__(
        self,
        campaign: Campaign,
        build_workers: int | None = None,
        moonlit_skip_share: float = ERROR_BUDGET_SHARES["moonlit_earthshine_skip"],
    ):
        self.campaign = campaign
        if build_workers is None:
            from straylight.execution import available_cores

            build_workers = available_cores()
        self.build_workers = build_workers
        self.policy = FidelityPolicy(campaign, moonlit_skip_share)
        self.context = SourceContext(
            campaign, zodiacal_floor=campaign_zodiacal_model(campaign).darkest_e_per_s_per_pix
        )
        self.body_skip = SolarBodySkip(self.context, self.policy)
        self.in_field = InFieldBodies(self.context)
        # the registry as it is now: a source registered later is not this model's
        self.entries = tuple(registry.SOURCES)
        registry.check_config_paths(self.entries)
        self.components = tuple(registry.COMPONENTS)
        self.leaves = registry.leaves()
        self.outputs = registry.band_components()
        self._built = {}
        self._shared = {}
        self._zero_points = {}
        self.sources = {e.name: self.source(e.name) for e in self.entries}

    def shared(self, name: str, make):
        """A part several sources share (the earthshine engine), ``make()`` on first use.

        Parameters
        ----------
        name : str
            The part's name.
        make : callable
            ``make() -> object``, called once per model.

        Returns
        -------
        object
            The part.
        """
        if name not in self._shared:
            self._shared[name] = make()
        return self._shared[name]

    def source(self, name: str):
        """The source ``name`` of the registry, built on first use.

        Parameters
        ----------
        name : str
            A source's name in :data:`~straylight.model.registry.SOURCES`.

        Returns
        -------
        Source
            The built source (its ``rates(samples, bands)`` gives e-/s/pix per band).

        Raises
        ------
        KeyError
            For a name that is not registered.
        """
        if name not in self._built:
            entry = next((e for e in self.entries if e.name == name), None)
            if entry is None:
                raise KeyError(f"no source named {name!r}: {[e.name for e in self.entries]}")
            self._built[name] = entry.factory(self)
        return self._built[name]

    # -- what callers need of the instrument, through the sources' shared context --------------
    def band(self, name: str):
        """The instrument's band ``name`` (throughput, zero points), loaded once.

        Parameters
        ----------
        name : str
            The band's name in the instrument settings.

        Returns
        -------
        Band
        """
        return self.context.band(name)

    def photometry(self, name: str):
        """Band ``name``'s photometry: the Sun's photon irradiance at 1 AU through it (photons
        s-1 m-2), AB and solar-like magnitudes to photons s-1 m-2.

        Parameters
        ----------
        name : str
            The band's name.

        Returns
        -------
        BandPhotometry
        """
        return self.context.photometry(name)

    def darkest_zodiacal_e_per_s(self, band: str) -> float:
        """The zodiacal light at the darkest point of the Leinert (1998) table in ``band``: the
        floor of any total background.

        Parameters
        ----------
        band : str
            The band's name.

        Returns
        -------
        float
            e-/s/pix.
        """
        return self.context.darkest_zodiacal_e_per_s(band)

    def sky_zero_point(self, band: str) -> float:
        """The band's AB surface-brightness zero point: the instrument's throughput, aperture and
        pixel scale.

        Parameters
        ----------
        band : str
            The band's name.

        Returns
        -------
        float
            AB mag/arcsec2 at 1 e-/s/pix (mag/arcsec2 = zero point - 2.5 log10(e-/s/pix)).
        """
        aperture_d = self.campaign.instrument_settings.telescope.aperture_diameter_m.value
        return sky_zero_point_mag_per_arcsec2(self.band(band), aperture_d, self.campaign.pixel_scale_arcsec)

    def sky_zero_points(self, bands) -> dict:
        """:meth:`sky_zero_point` of each band, computed once per band and kept.

        Parameters
        ----------
        bands : sequence of str
            Band names.

        Returns
        -------
        dict of str to float
            Band -> AB mag/arcsec2 at 1 e-/s/pix.
        """
        for b in bands:
            if b not in self._zero_points:
                self._zero_points[b] = self.sky_zero_point(b)
        return {b: self._zero_points[b] for b in bands}

    def mag_per_arcsec2(self, e_per_s_per_pix, band: str):
        """AB surface brightness of a uniform background (inf where zero).

        Parameters
        ----------
        e_per_s_per_pix : array_like
            Background rate, e-/s/pix.
        band : str
            The band's name.

        Returns
        -------
        ndarray
            AB mag/arcsec2, of ``e_per_s_per_pix``'s shape.
        """
        aperture_d = self.campaign.instrument_settings.telescope.aperture_diameter_m.value
        return magnitude_per_arcsec2(
            e_per_s_per_pix, self.band(band), aperture_d, self.campaign.pixel_scale_arcsec
        )

    @property
    def offfield(self):
        """The off-field transfer (:class:`~straylight.sources.offfield.OffFieldModel`): the PST,
        the door, the pixel's area (m2), the field's radius (deg) and the Moon's phase law."""
        return self.context.offfield

    # -- the earthshine engine both Earths share -------------------------------------------------
    @property
    def _earthshine(self):
        return self.source("sunlit_earth").engine

    @property
    def earth_grid(self):
        """The Earth-cap grid over the off-field transfer that the earthshine sums over
        (:class:`~straylight.sources.earthshine.grid.EarthGrid`; nothing built)."""
        return self._earthshine.grid

    def earth_band_factors(self, bands):
        """The Earth's band albedo over the grey one in ``bands``.

        Parameters
        ----------
        bands : sequence of str
            Band names.

        Returns
        -------
        ndarray or None
            One factor per band, dimensionless; None for the grey spectrum.
        """
        return self._earthshine.band_factors(tuple(bands))

    def sunlit_earth_coefficients(
        self, radius_km: float, sun_zenith_deg, los_zenith_deg, azimuth_deg, door_deg
    ):
        """The sunlit Earth's light outside the field (direct + via the door) per unit of the
        Sun's irradiance at 1 AU, summed over the Earth grid, at a satellite ``radius_km`` from
        the Earth's centre, in its local frame (the Sun and the line of sight by their zenith
        angles and the azimuth between them); the Earth grey (see :meth:`earth_band_factors`).

        Parameters
        ----------
        radius_km : float
            The satellite's geocentric radius, km.
        sun_zenith_deg, los_zenith_deg, azimuth_deg : ndarray
            The Sun's and the line of sight's zenith angles and the azimuth of the line of
            sight from the Sun's, deg, one shape.
        door_deg : ndarray
            The door's opening, deg (one of the instrument's states; another: NaN), same shape.

        Returns
        -------
        ndarray
            e-/s/pix per photon s-1 m-2 of the Sun at 1 AU, the inputs' shape.
        """
        from straylight.sources.earthshine.sunlit_build import sun_coefficients_direct

        grid, re_km = self.earth_grid, self.campaign.earth.radius_km
        coeff = np.full(np.shape(door_deg), np.nan)
        for state in grid.door_states_deg:
            sel = door_deg == state
            if sel.any():
                d, g = sun_coefficients_direct(
                    grid,
                    np.full(sel.sum(), radius_km),
                    np.radians(sun_zenith_deg[sel]),
                    np.radians(los_zenith_deg[sel]),
                    np.radians(azimuth_deg[sel]),
                    state,
                    re_km,
                )
                coeff[sel] = d + g
        return coeff

    @property
    def earthshine_choice(self) -> dict:
        """Which sunlit-earthshine model runs, decided without building anything: ``method``
        (``"lut"`` or ``"direct"``), ``reason``, and for the table its ``settings``
        (:class:`~straylight.sources.earthshine.nodes.LUTSettings`), node states and build-time
        estimates (s on one core)."""
        return self._earthshine.sunlit_choice

    def table_paths(self) -> dict:
        """Where the earthshine tables this model reads are cached (nothing built).

        Returns
        -------
        dict
            ``sunlit``: Path of the sunlit table; ``moonlit``: Path of the moonlit table, or
            None where the moonlit Earth runs without one.
        """
        return {"sunlit": self._earthshine.sunlit_lut_path(), "moonlit": self._earthshine.moonlit_lut_path()}

    @property
    def uses_sunlit_table(self) -> bool:
        """Whether the sunlit earthshine runs on its table (read, or built, now) rather than the
        direct sum over the Earth grid per sample."""
        return self._earthshine.sunlit_lut is not None

    def evaluate(
        self,
        satellite_km,
        bodies_km,
        los,
        geometry,
        bands,
        stars: StarTable | None = None,
        into: tuple | None = None,
        runs=None,
    ) -> dict:
        """Every source's e-/s/pix in each band, added into the components and their total.

        Parameters
        ----------
        satellite_km : array_like, shape (..., 3)
            Geocentric ICRS satellite positions, km (broadcastable to the samples).
        bodies_km : dict of str to array_like
            Body -> geocentric ICRS position (..., 3), km: the Sun, the Moon and each planet
            that is a source where it can count (:class:`~straylight.sources.planets.Planets`).
        los : array_like, shape (..., 3)
            Unit lines of sight, ICRS.
        geometry : dict
            :func:`~straylight.sky.observing.observing_geometry`'s (the Sun's, the Moon's and
            the limb's entries are read); its ``sun_angle_deg`` gives the samples' shape.
        bands : sequence of str
            Band names.
        stars : StarTable or None
            The off-field stars (None: stars = 0).
        into : (sequence of str, ndarray) or None
            (component names, array (names, samples flattened, bands)), e.g. a cube region's
            float32 block, receiving those components (the result's arrays are its views; no
            other component is computed).
        runs : SceneRuns or None
            The samples' scene runs (sharing the satellite and every body) when the caller
            knows them (a cube's time steps), else found where needed.

        Returns
        -------
        dict
            Band -> {component: e-/s/pix, float64 array of the samples' shape, for every name
            of :func:`~straylight.model.registry.band_components` (or those of ``into``); and
            ``_<flag>`` for each flag a source reports (``_zodiacal_no_data``)}.

        Raises
        ------
        ValueError
            For an unknown name in ``into`` or an array of another shape.
        """
        sat = np.asarray(satellite_km, float)
        frame = telescope_frame(los, bodies_km["sun"] - sat)
        return self.evaluate_samples(Samples(sat, bodies_km, frame, geometry, runs, stars=stars), bands, into)

    def evaluate_samples(self, samples: Samples, bands, into: tuple | None = None) -> dict:
        """:meth:`evaluate` at samples as the sources read them (positions, telescope frame,
        geometry, stars, the faint stars' map where known; e.g.
        :meth:`~straylight.model.samples.SampleBatch.source_samples`).

        Parameters
        ----------
        samples : Samples
            The samples (their ``moon_lamp``, ``floor`` and ``floor_ratio`` are set here).
        bands : sequence of str
            Band names.
        into : (sequence of str, ndarray) or None
            As :meth:`evaluate`.

        Returns
        -------
        dict
            As :meth:`evaluate`.

        Raises
        ------
        ValueError
            For an unknown name in ``into`` or an array of another shape.
        """
        shape = samples.shape
        n, outputs = int(np.prod(shape)), self.outputs
        if into is not None:  # checked before any work
            _check_into(into, n, len(bands), outputs)
        scales = self._lamp_scales(samples)
        sun_at_1au = np.array([self.context.photometry(name).sun_at_1au_photons_s_m2 for name in bands])
        rates = self._source_rates(samples, bands, scales, sun_at_1au)
        terms = _Terms(self.entries, self.leaves, rates, scales, shape)
        names, values = (
            into
            if into is not None
            else (outputs, np.empty((len(outputs), len(bands), n)).transpose(0, 2, 1))
        )  # band-major: each band's row contiguous
        _sum_terms(terms, sun_at_1au, _sum_program(self.components, self.leaves, names), values)
        extras = {f"_{k}": v for r in rates.values() for k, v in r.extras.items()}
        out = {}
        for ib, name in enumerate(bands):
            res = {comp: values[k, :, ib].reshape(shape) for k, comp in enumerate(names)}
            res.update(extras)
            out[name] = res
        return out

    def _lamp_scales(self, samples: Samples) -> dict:
        """Each lamp's scale at the samples (``samples.moon_lamp`` set): the Sun's inverse square
        at the satellite, 1 at 1 AU, the Moon's at the Earth."""
        samples.moon_lamp = self.source("moon").lamp(samples)
        return {
            "sun": samples.sun_inverse_square,
            "sun_at_1au": 1.0,
            "moon_at_earth": samples.moon_lamp["at_earth"],
        }

    def _source_rates(self, samples: Samples, bands, scales: dict, sun_at_1au: np.ndarray) -> dict:
        """Each source's :class:`~straylight.sources.rates.BandRates` at the samples (source name
        -> rates): the sources never skipped first, whose sum makes each sample's floor
        (``samples.floor``, ``samples.floor_ratio``), which the skippable ones then measure their
        skips against."""
        rates = {}
        for entry in self.entries:
            if not entry.skippable:
                rates[entry.name] = self.sources[entry.name].rates(samples, bands)
        samples.floor, samples.floor_ratio = self._floor(
            [rates[e.name] for e in self.entries if not e.skippable],
            scales,
            sun_at_1au,
            bands,
            samples.geometry["sun_angle_deg"].shape,
        )
        for entry in self.entries:
            if entry.skippable:
                rates[entry.name] = self.sources[entry.name].rates(samples, bands)
        return rates

    def _floor(
        self, never_skipped: list, scales: dict, sun_at_1au: np.ndarray, bands, shape
    ) -> tuple[dict, np.ndarray]:
        """A lower bound of the samples' total per band (band -> e-/s/pix, arrays of ``shape``):
        the sources never skipped, their per-band terms added, then for each lamp the sum of
        their coefficients times the lamp's irradiance, never below the band's darkest zodiacal
        light (nor NaN); and its smallest ratio to that darkest light over the bands, per
        sample.  One compiled pass (:func:`floor_kernel`)."""
        n = int(np.prod(shape))
        dense = [r.per_band[p] for r in never_skipped for p in r.per_band]
        # coefficients summed per lamp and per-band factor (a part's band_factors, e.g. the
        # Earth's albedo): (lamp, factors or None) -> coefficient
        lamp_sums = {}
        for r in never_skipped:
            for part, by_lamp in r.per_lamp.items():
                f = r.band_factors.get(part)
                fkey = None if f is None else tuple(np.asarray(f, float).tolist())
                for lamp, coeff in by_lamp.items():
                    key = (lamp, fkey)
                    lamp_sums[key] = coeff if key not in lamp_sums else lamp_sums[key] + coeff
        keys = sorted(lamp_sums, key=lambda k: (LAMPS.index(k[0]), k[1] is not None, k[1] or ()))
        coeff = _rows([_flat(lamp_sums[k], shape) for k in keys], (n,))
        scale = _rows([_flat(scales[k[0]], shape) for k in keys], (n,))
        irradiance = _irradiance(sun_at_1au, [k[1] for k in keys])
        dense_arr = _rows([np.asarray(d, float).reshape(len(bands), n) for d in dense], (len(bands), n))
        darkest = np.array([self.context.darkest_zodiacal_e_per_s(name) for name in bands], float)
        floor, ratio = np.empty((len(bands), n)), np.empty(n)
        _floor_kernel(
            dense_arr,
            len(dense),
            coeff,
            len(keys),
            scale,
            irradiance,
            darkest,
            floor,
            ratio,
        )
        return {name: floor[ib].reshape(shape) for ib, name in enumerate(bands)}, ratio.reshape(shape)

    def models_record(self) -> dict:
        """Which models ran and their error budget, for a product's attributes (JSON-able).

        Returns
        -------
        dict
            The tolerance (a fraction of the total), the earthshine and moonlit-Earth records,
            the PST's source, how unobservable samples and skips are handled, the stars'
            selection, and ``error_budget``: each fast path's largest error, a fraction of the
            total (0.0 where the path does not run).
        """
        sc = self.campaign.settings.stars
        policy, tolerance = self.policy, self.policy.tolerance
        es = self.source("sunlit_earth").record()
        shares, lut_runs = ERROR_BUDGET_SHARES, es["method"] == "lut"
        moonlit = self.source("moonlit_earth")
        return {
            "tolerance": tolerance,
            "earthshine": es,
            "pst": self.context.offfield.pst.source,
            "unobservable_samples": (
                "skipped: NaN in every component" if policy.unobservable_samples == "skip" else "evaluated"
            ),
            "skip_floor": (
                "each sample's zodiacal light + Sun + sunlit Earth + moonlit Earth in the field "
                "(a lower bound of its total; never below the darkest zodiacal light)"
            ),
            "moonlit_earthshine": moonlit.record(lut_runs),
            "earthshine_near_limb": (
                "indicative only within the dark-limb angle of the limb and below it "
                "(never observable; no Earth grid converges there)"
            ),
            "stars": {
                "direct_mag_limit": float(sc.offfield_mag_limit),
                "faint_map": sc.faint_map,
                "direct_skipped": (
                    f"per sky cell and floor level, the stars of smallest bound, "
                    f"together < {shares['stars_skip']:g} x tolerance x the "
                    f"sample's floor"
                ),
            },
            "moon_and_planets_skipped": (
                f"where the bound of each is < {shares['moon_and_planets_skip']:g} / "
                f"{1 + len(PLANETS)} x tolerance x the sample's floor"
            ),
            "error_budget": {
                "earthshine_lut_validated": es.get("lut_validation_max_rel_error") if lut_runs else 0.0,
                "moonlit_earthshine_skip_max": policy.moonlit_skip_share * tolerance if lut_runs else 0.0,
                "moonlit_earthshine_grid_share": shares["moonlit_earthshine_grid"] * tolerance
                if lut_runs
                else 0.0,
                "moonlit_earthshine_lut_validated": moonlit.model["lut_validation_max_rel_error"]
                if lut_runs and moonlit.model["method"] == "lut"
                else 0.0,
                "stars_skip_max": shares["stars_skip"] * tolerance,
                "moon_and_planets_skip_max": shares["moon_and_planets_skip"] * tolerance,
                "see": "bench/results/summary.json for the whole model against the converged "
                "reference, knobs.json moonlit_grid for the moonlit grid's measured error",
            },
        }


def _sum_terms(terms: _Terms, sun_at_1au: np.ndarray, program: tuple, values: np.ndarray) -> None:
    """The band kernel over the sources' ``terms``: ``program`` (:func:`sum_program`'s sums,
    writes and row count) into ``values`` (names, samples, bands), e-/s/pix."""
    sums, writes, n_rows = program
    _band_components_kernel(
        terms.dense,
        terms.n_dense,
        terms.dense_leaf,
        terms.dense_first,
        terms.coeff,
        terms.n_coeff,
        terms.term_leaf,
        terms.term_lamp,
        terms.term_first,
        terms.scales,
        _irradiance(sun_at_1au, terms.factors),
        sums,
        writes,
        n_rows,
        values,
    )
