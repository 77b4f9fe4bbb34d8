"""All stray-light components of samples (time, pointing) per band: the Python API behind
``straylight sky`` and the survey cubes.

:meth:`ComponentModel.evaluate` returns, for each band, e-/s/pixel arrays of the in-field zodiacal light and
the off-field terms (Sun, Moon, planets, stars, earthshine direct and via the door), reported
whether or not the pointing is observable.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np
from numba import njit
from threadpoolctl import threadpool_limits

from straylight.optics.bandpass import load_band
from straylight.config import Campaign
from straylight.optics.door import door_from_instrument
from straylight.sky.ephemeris import PLANETS
from straylight.sky.geometry import (TelescopeFrame, body_geometry, earth_blocks, norm, rows_at, scene_rows, scene_runs,
                       telescope_frame, tiled_period, unit)
from straylight.sources.offfield import (AU_KM, BandPhotometry, EarthshineSettings, OffFieldModel, magnitude_per_arcsec2,
                       V_SUN_VEGA, moon_v_magnitude, planet_v_magnitudes, solar_like_fraction)
from straylight.optics.pst import load_pst
from straylight.sources.zodiacal import zodiacal_model_from_instrument

# Shares of models.tolerance (a fraction of the total) held by each fast path; they add up to 1.
# The earthshine table must validate within its share; the moonlit Earth has two: the samples
# skipped on its bound, and the coarse grid of the others (measured, bench/run.py moonlit_grid);
# the skipped star pairs and the skipped Moon and planets are held to theirs by bounds.
ERROR_BUDGET_SHARES = {"earthshine_lut": 0.5, "moonlit_earthshine_skip": 0.125, "moonlit_earthshine_grid": 0.125,
                       "stars_skip": 0.125, "moon_and_planets_skip": 0.125}

# models.earthshine.method = auto weighs the sunlit table's build against what it saves, both
# measured on one core: the default table (782,633 nodes x 2 door states) was built in 608 s,
# 0.39 ms per node and state; in the cube the table path saves 0.27 ms per sample (what
# matters is the ratio of the two, which does not move with the machine: bench/run.py --only
# cube, the saving over the build per node, in units of this 0.39 ms: 0.29-0.36 in three runs
# two cycles ago, 0.293 / 0.284 last cycle, 0.281 / 0.255 this cycle after the direct path got
# faster; 0.32 until this cycle; the bench prints both again as cube.auto_cost_model).
LUT_BUILD_SECONDS_PER_NODE = 0.39e-3
LUT_SAVED_SECONDS_PER_SAMPLE = 0.27e-3
# The moonlit Earth's table (the table path builds it too) per node and door state, in the same
# units: its coarse grid (8 x 16 blocks) makes a node cheap.  Both default tables built in one
# session on one machine: 4.55 s for 878,750 moonlit node-states against 129 s for 1,565,266
# sunlit ones, 0.063 of the sunlit cost per node.
MOONLIT_LUT_BUILD_SECONDS_PER_NODE = 0.063 * LUT_BUILD_SECONDS_PER_NODE


@dataclass
class StarTable:
    """Off-field stars: ``ra_deg, dec_deg, mag_ab`` are summed one by one through the exact
    transfer (Earth, door, PST(theta, phi)); the optional ``faint_*`` stars (fainter than the
    direct limit) enter as a smoothed map, the spherical convolution of their fluxes with the
    azimuth-averaged PST, evaluated at each line of sight (no Earth or door blocking)."""

    ra_deg: np.ndarray
    dec_deg: np.ndarray
    mag_ab: dict  # band -> array (AB mag; +inf where the star is not in this part in that band)
    faint_ra_deg: np.ndarray = field(default_factory=lambda: np.zeros(0))
    faint_dec_deg: np.ndarray = field(default_factory=lambda: np.zeros(0))
    faint_mag_ab: dict = field(default_factory=dict)

    @cached_property
    def unit(self) -> np.ndarray:
        """ICRS unit vectors (S, 3), computed once (the cube reuses the table for every time step)."""
        from straylight.sky.geometry import radec_to_unit

        return np.atleast_2d(radec_to_unit(self.ra_deg, self.dec_deg, "star catalog"))

    @cached_property
    def faint_unit(self) -> np.ndarray:
        from straylight.sky.geometry import radec_to_unit

        if not len(self.faint_ra_deg):
            return np.zeros((0, 3))
        return np.atleast_2d(radec_to_unit(self.faint_ra_deg, self.faint_dec_deg, "star catalog"))


@dataclass
class ComponentModel:
    """All components for one campaign.  ``expected_samples``: how many (time, pointing) samples
    this model will evaluate (the cube: the whole campaign; a pointing table: its rows; one
    pointing: 1); with models.earthshine.method = auto it decides whether building the
    earthshine look-up table pays off.  ``build_workers``: processes that build the table when it
    is not cached (the result does not depend on it)."""

    campaign: Campaign
    expected_samples: int = 1
    build_workers: int = 1
    #: fraction of the tolerance the moonlit Earth's skipped samples may take (0: none skipped,
    #: as the benchmark's reference runs)
    moonlit_skip_share: float = ERROR_BUDGET_SHARES["moonlit_earthshine_skip"]

    @cached_property
    def offfield(self) -> OffFieldModel:
        inst = self.campaign.instrument
        pst_file = inst.get("pst", {}).get("file")
        if pst_file and not Path(pst_file).is_absolute():
            pst_file = self.campaign.instrument_path.parent / pst_file
        es = self.campaign.config["models"].get("earthshine", {})
        dg = inst.get("door_geometry", {})
        field_radius_deg = float(np.sqrt(self.campaign.instrument_value("detector", "field_of_view_deg2") / np.pi))
        return OffFieldModel(
            pst=load_pst(pst_file, field_radius_deg),
            door=door_from_instrument(inst),
            door_states_deg=tuple(float(s["opening_deg"]) for s in inst["door"]["states"]),
            pixel_area_m2=(self.campaign.instrument_value("detector", "pixel_size_um") * 1e-6) ** 2,
            pixel_etendue_m2_sr=self.zodiacal.pixel_etendue_m2_sr,
            field_radius_deg=field_radius_deg,
            earthshine=EarthshineSettings(
                n_gamma=int(es.get("n_gamma", 24)), n_psi=int(es.get("n_psi", 48)),
                albedo=float(es.get("albedo", 0.3)), door_blocks=tuple(es.get("door_blocks", (24, 24))),
                door_reflectance=float(dg["reflectance"]["value"]) if "reflectance" in dg else 0.05,
                n_aperture_door=int(es.get("n_aperture_door", 128)),
            ),
            moon_law=self.campaign.config["models"].get("moon_phase_law", "krisciunas_schaefer"),
            moon_eclipse_factor=float(self.campaign.config["models"].get("moon_eclipse_factor", 1e-4)),
        )

    @cached_property
    def zodiacal(self):
        return zodiacal_model_from_instrument(self.campaign.instrument,
                                              self.campaign.config["models"].get("zodiacal_spectrum", "solar_leinert"))

    @cached_property
    def _bands(self) -> dict:
        return {}

    def band(self, name):
        if name not in self._bands:
            b = load_band(self.campaign.instrument, name, self.campaign.instrument_path.parent)
            self._bands[name] = (b, BandPhotometry(b))
        return self._bands[name][0]

    def photometry(self, name) -> BandPhotometry:
        self.band(name)
        return self._bands[name][1]

    def in_field_point_sources(self, satellite_km, bodies_km, los, geometry, bands) -> dict:
        """The Sun, Moon and planets inside the field (within ``field_radius_deg`` of the line of
        sight), which the background leaves out (:meth:`OffFieldModel.point_source`): a body in
        the field is a point source, imaged with its halo and ghosts like a star.  Returns
        body -> {"in_field": bool, "angle_deg": deg from the line of sight, "v_mag": V (Vega),
        "mag_ab": {band: AB magnitude through the band (solar spectrum)}}, arrays over the
        samples; ``geometry``: :func:`~straylight.sky.observing.sample_geometry`'s (the Moon's phase)."""
        sat = np.asarray(satellite_km, float)
        z = unit(np.asarray(los, float))
        out = {}
        for body in ("sun", "moon", *PLANETS):
            if body not in bodies_km:
                continue
            pos = np.asarray(bodies_km[body], float)
            d = unit(pos - sat)
            angle = np.degrees(np.arccos(np.clip(np.sum(d * z, axis=-1), -1.0, 1.0)))
            dist = norm(pos - sat)
            if body == "sun":
                fraction = (AU_KM / dist) ** 2
                v = V_SUN_VEGA - 2.5 * np.log10(fraction)
            elif body == "moon":
                v = moon_v_magnitude(geometry["moon_phase_angle_deg"], dist, self.offfield.moon_law,
                                     geometry["moon_elongation_deg"])
                fraction = solar_like_fraction(v)
            else:
                v = planet_v_magnitudes([body], pos[None], np.asarray(bodies_km["sun"], float), sat)[0]
                fraction = solar_like_fraction(v)
            mags = {b: -2.5 * np.log10(fraction * self.photometry(b).sun_at_1au_photons_s_m2
                                       / self.band(b).ab_zero_point_photons_s_m2) for b in bands}
            out[body] = {"in_field": angle <= self.offfield.field_radius_deg, "angle_deg": angle,
                         "v_mag": np.asarray(v, float), "mag_ab": mags}
        return out

    def evaluate(self, satellite_km, bodies_km, los, geometry, bands, stars: StarTable | None = None,
                 faint_rates: dict | None = None, frame=None, into: tuple | None = None, runs=None) -> dict:
        """Components for broadcastable samples, band -> {component: e-/s/pix, float64 arrays
        of the samples' shape (:data:`BAND_COMPONENTS`), and ``_band``, ``_zodiacal_no_data``,
        ``_mag``}; ``geometry`` from :func:`observing_geometry` (the Sun's and the Moon's
        entries and the limb's are read; each planet in ``bodies_km`` gets its angles here,
        only where it can count: :meth:`_planets_fraction`); ``faint_rates``: the faint stars'
        map at these lines of sight, band -> e-/s/pix (as :meth:`faint_star_rates` gives it),
        when already computed; ``frame``: the samples' ``telescope_frame(los, sun -
        satellite)``, when already computed; ``into``: (component names, array (names,
        samples flattened, bands)), e.g. a cube region's float32 block, that receives those
        components (the result's arrays are then views of it, and the other components are
        not computed); ``runs``: the samples' scene runs when the caller knows them
        (:class:`~straylight.sky.geometry.SceneRuns`, e.g. a cube's time steps: runs of samples
        that share the satellite and every body in ``bodies_km``), else found where needed.
        ValueError for an unknown name or an array of another shape."""
        off = self.offfield
        re_km = self.campaign.earth.radius_km
        sat = np.asarray(satellite_km, float)
        sun, moon = bodies_km["sun"], bodies_km["moon"]
        frame = telescope_frame(los, sun - sat) if frame is None else frame
        door = geometry["door_opening_deg"]
        shape = geometry["sun_angle_deg"].shape
        if into is not None:  # checked before any work
            _check_into(into, int(np.prod(shape)), len(bands))
        d_sun = norm(sun - sat)
        d_moon = norm(moon - sat)
        rows = scene_rows(sun, moon, runs=runs)  # the Moon's eclipse once per run sharing them (a cube's time step)
        moon_eclipsed = rows.expand(earth_blocks(rows.vectors[1], rows.vectors[0] - rows.vectors[1], re_km))
        v_moon = moon_v_magnitude(geometry["moon_phase_angle_deg"], d_moon, off.moon_law, geometry["moon_elongation_deg"])
        v_moon_at_earth = moon_v_magnitude(geometry["moon_phase_angle_deg"], norm(moon), off.moon_law,
                                           geometry["moon_elongation_deg"])
        eclipse = np.where(moon_eclipsed, off.moon_eclipse_factor, 1.0)
        b500, zodi_no_data = self.zodiacal.brightness_500nm(frame.z, unit(sun - sat), runs)  # once for all bands
        sun_at_1au = {name: self.photometry(name).sun_at_1au_photons_s_m2 for name in bands}
        # the Moon and planets have the Sun's spectrum: one band-independent fraction of the
        # Sun's irradiance at 1 AU, times each band's solar irradiance
        moon_at_earth_fraction = solar_like_fraction(v_moon_at_earth) * eclipse
        moon_at_earth_unit = {name: sun_at_1au[name] * moon_at_earth_fraction for name in bands}
        zodi_e = np.empty((len(bands), int(np.prod(shape))))  # (bands, samples): read by the per-band pass
        for ib, name in enumerate(bands):
            zodi_e[ib] = np.broadcast_to(self.zodiacal.e_per_s_per_pix(self.band(name), b500), shape).ravel()
        zodi = {name: zodi_e[ib].reshape(shape) for ib, name in enumerate(bands)}
        inverse_square = (AU_KM / d_sun) ** 2  # once for all bands
        sun_irr = {name: sun_at_1au[name] * inverse_square for name in bands}
        aperture_d = self.campaign.instrument_value("telescope", "aperture_diameter_m")
        pix_arcsec = self.campaign.pixel_scale_arcsec
        out = {}
        # band-independent transfer (e-/s/pix per photons s-1 m-2): Se * Sp * PST * pixel area
        t_sun = off.point_source(1.0, geometry["sun_angle_deg"], geometry["sun_phi_deg"],
                                 geometry["sun_earth_blocked"], door)  # never skipped on a bound
        es_coeff = self._earthshine_coefficients(sat, sun, moon, frame, door, shape, runs)
        # The terms computed so far (never skipped) are a lower bound of each sample's total: the
        # skippable terms below are held to their shares of the tolerance times it, so a term
        # that matters only against the darkest sky is still summed there, and skipped where the
        # Sun or the sunlit Earth already outshines it (the scene does not need it).
        per_sun = t_sun + es_coeff["direct_sun"] + es_coeff["door_sun"]  # the band-independent sums once
        per_moon = es_coeff["direct_moon"] + es_coeff["door_moon"]
        floor = {name: self._floor(zodi[name] + per_sun * sun_irr[name] + per_moon * moon_at_earth_unit[name], name, shape)
                 for name in bands}
        if self.earthshine_model["lut"] is not None:
            self._add_moonlit_earthshine(es_coeff, sat, sun, moon, frame, door, shape, moon_at_earth_unit, floor, runs)
        # the floor in units of the darkest zodiacal light, worst band: what the skip radii scale with
        floor_ratio = np.min([floor[name] / self.darkest_zodiacal_e_per_s(name) for name in bands], axis=0)
        moon_sun_fraction = solar_like_fraction(v_moon)
        t_moon = self._skippable_transfer(moon_sun_fraction, geometry["moon_angle_deg"], geometry["moon_phi_deg"],
                                          geometry["moon_earth_blocked"], door, bands, floor_ratio)
        planets_fraction = self._planets_fraction(sat, bodies_km, frame, door, bands, floor_ratio, shape, runs)
        moon_fraction = t_moon * moon_sun_fraction * eclipse
        star_pairs = (self._star_pairs(stars, frame, sat, door, floor_ratio, runs)
                      if stars is not None and len(stars.ra_deg) else None)  # once for all bands
        faint = faint_rates
        if faint is None and stars is not None and len(stars.faint_ra_deg):
            faint = self.faint_star_rates(stars, frame.z, bands)
        # each band's stars (bright pairs, then the faint map), then every band's components in
        # one compiled pass over the samples (reads the band-independent arrays once, not once a band)
        n = int(np.prod(shape))
        stars_e = np.zeros((len(bands), n))
        for ib, name in enumerate(bands):
            if star_pairs is not None and name in stars.mag_ab:
                pairs_shape, (pair_sample, pair_star, pair_transfer) = star_pairs
                flux = self.photometry(name).from_ab(stars.mag_ab[name])
                stars_e[ib] = np.bincount(pair_sample, weights=pair_transfer * flux[pair_star], minlength=n)
            if faint is not None and name in faint:
                stars_e[ib] += np.broadcast_to(faint[name], shape).ravel()
        names, values = into if into is not None else (BAND_COMPONENTS, np.empty((len(BAND_COMPONENTS), len(bands), n))
                                                         .transpose(0, 2, 1))  # band-major: each band's row contiguous
        slot = np.array([list(names).index(c) if c in names else -1 for c in BAND_COMPONENTS], np.intp)
        flat = [np.ascontiguousarray(np.broadcast_to(np.asarray(v, float), shape).ravel()) for v in
                (t_sun, inverse_square, moon_fraction, planets_fraction, es_coeff["direct_sun"],
                 es_coeff["door_sun"], es_coeff["direct_moon"], es_coeff["door_moon"], moon_at_earth_fraction)]
        _band_components_kernel(zodi_e, *flat, stars_e, np.array([sun_at_1au[name] for name in bands]), slot, values)
        for ib, name in enumerate(bands):
            band = self.band(name)
            res = {comp: values[k, :, ib].reshape(shape) for k, comp in enumerate(names)}
            res["_band"] = band
            res["_zodiacal_no_data"] = np.broadcast_to(zodi_no_data, shape)
            res["_mag"] = lambda e, b=band: magnitude_per_arcsec2(e, b, aperture_d, pix_arcsec)
            out[name] = res
        return out

    # -- earthshine: direct sum or look-up table ----------------------------------------------
    @cached_property
    def tolerance(self) -> float:
        """models.tolerance: the error allowed to a fast path, as a fraction of the total."""
        return float(self.campaign.config["models"].get("tolerance", 0.01))

    def darkest_zodiacal_e_per_s(self, band: str) -> float:
        """e-/s/pix of the zodiacal light at the darkest point of the Leinert (1998) table, in a
        band: the floor of any total background (scheduling tables, error budgets).  Cached per
        band (every evaluation's skips read it)."""
        from straylight.sources.zodiacal import LEINERT_UNIT_W_M2_SR_UM, leinert_table

        cache = self.__dict__.setdefault("_darkest_zodiacal", {})
        if band not in cache:
            b_min = float(np.min(leinert_table().filled)) * LEINERT_UNIT_W_M2_SR_UM
            cache[band] = float(self.zodiacal.e_per_s_per_pix(self.band(band), b_min))
        return cache[band]

    @cached_property
    def earthshine_floor(self) -> float:
        """The darkest sky background in earthshine-coefficient units (e-/s/pix per photon
        s-1 m-2 of the Sun at 1 AU), over the instrument's bands: errors relative to it bound
        errors relative to the total."""
        return self.solar_floor(tuple(self.campaign.bands))

    def solar_floor(self, bands: tuple) -> float:
        """:attr:`earthshine_floor` over ``bands`` (cached per set of bands)."""
        cache = self.__dict__.setdefault("_solar_floor", {})
        if bands not in cache:
            cache[bands] = min(self.darkest_zodiacal_e_per_s(b) / self.photometry(b).sun_at_1au_photons_s_m2
                               for b in bands)
        return cache[bands]

    def _floor(self, partial_total, band: str, shape) -> np.ndarray:
        """A lower bound of the samples' total in ``band`` (e-/s/pix): the terms computed before
        the skippable ones, never below the darkest zodiacal light (nor NaN)."""
        return np.fmax(np.broadcast_to(np.asarray(partial_total, float), shape),
                       self.darkest_zodiacal_e_per_s(band))

    def _skippable_transfer(self, sun_fraction, angle_deg, phi_deg, earth_blocked, door, bands, floor_ratio=1.0):
        """The band-independent transfer (as OffFieldModel.point_source with E = 1) of the Moon or
        a planet, a solar-spectrum source whose irradiance is ``sun_fraction`` of the Sun's at
        1 AU (:func:`~straylight.sources.offfield.solar_like_fraction` of its V magnitude), skipped (0) where its upper
        bound (the PST at its maximum over phi from the source's angle out, Se = Sp = 1) stays
        below 1/9 of the moon_and_planets_skip share (tolerance / 72) of the sample's floor in
        every band, so the Moon and the eight planets together stay within it.  The floor is
        ``floor_ratio`` (>= 1, per sample) times the darkest zodiacal light: a lower bound of the
        total (:meth:`evaluate`).  A new Moon far from the line of sight is skipped, a bright one
        only where the Sun or the sunlit Earth outshines it by ~10^4."""
        off = self.offfield
        rel, budget = self._skip_scale(sun_fraction, bands)
        if np.size(angle_deg):
            # a source outside the widest radius everywhere (the Moon, often) is skipped with no
            # radius per sample
            widest = self._widest_skip_radius_deg(rel, budget, floor_ratio)
            if widest < 180.0 and np.min(angle_deg) >= widest:
                return np.zeros(np.broadcast_shapes(np.shape(angle_deg), np.shape(phi_deg), np.shape(earth_blocked),
                                                    np.shape(door)))
        # beyond each sample's radius (a radius of 180: nowhere skippable)
        far = off.pst.beyond_influence_radius(angle_deg, budget * np.asarray(floor_ratio, float) / rel)
        # a skipped source is treated as hidden: point_source then looks nothing up for it
        return off.point_source(1.0, angle_deg, phi_deg, np.asarray(earth_blocked, bool) | far, door)

    def _skip_scale(self, sun_fraction, bands) -> tuple:
        """(rel, budget) of :meth:`_skippable_transfer`: the source's e-/s/pix at PST = 1 relative
        to the darkest zodiacal light, worst band (solar spectrum), and its share of the
        tolerance (the Moon and each planet: 1/9 of moon_and_planets_skip)."""
        rel = self.offfield.pixel_area_m2 * np.asarray(sun_fraction, float) / self.solar_floor(tuple(bands))
        per_source = ERROR_BUDGET_SHARES["moon_and_planets_skip"] / (1 + len(PLANETS))
        return rel, per_source * self.tolerance

    def _widest_skip_radius_deg(self, rel, budget, floor_ratio) -> float:
        """The largest of the samples' skip radii (:meth:`_skippable_transfer`): the radius
        shrinks as its limit rises, so the smallest limit (the darkest floor over the brightest
        source; a hair smaller against rounding) gives a radius that bounds every sample's."""
        with np.errstate(divide="ignore"):
            smallest = budget * float(np.min(floor_ratio)) / float(np.max(rel)) * (1 - 1e-12)
        return float(self.offfield.pst.influence_radius_deg(smallest))

    def _planets_fraction(self, sat, bodies_km, frame, door, bands, floor_ratio, shape, runs=None) -> np.ndarray:
        """The planets in ``bodies_km`` together, per sample: the sum of each one's
        :meth:`_planet_transfer` times its fraction of the Sun's irradiance at 1 AU.  Each
        planet's magnitude and direction are computed once per run of samples that share a
        scene (a cube's time step; else once per sample), and one compiled pass finds every
        planet's samples within its widest skip radius (:func:`_near_runs_kernel`): the only
        ones whose angles are computed (most planets, most of the time, reach no sample; the
        angles' two arctangents are most of the geometry's cost)."""
        out = np.zeros(shape)
        planets = [p for p in PLANETS if p in bodies_km]
        if not planets or not out.size:
            return out
        rows = scene_rows(*(np.broadcast_to(np.asarray(v, float), shape + (3,))
                            for v in (sat, bodies_km["sun"], *(bodies_km[p] for p in planets))), runs=runs)
        vectors, index = rows.vectors, rows.index
        fractions = solar_like_fraction(planet_v_magnitudes(planets, np.stack(vectors[2:]), vectors[1],
                                                            vectors[0]))  # (planets, runs)
        min_floor = float(np.min(floor_ratio))
        widest = np.array([self._widest_skip_radius_deg(*self._skip_scale(f, bands), min_floor) for f in fractions])
        # a margin of 1e-6 deg: the samples left out lie beyond the widest radius whatever the
        # rounding, and the others get the per-sample rule; a radius of 180 deg: every sample
        cos_limit = np.where(widest < 180.0, np.cos(np.radians(widest + 1e-6)), -np.inf)
        directions = np.ascontiguousarray(unit(np.stack(vectors[2:]) - vectors[0]))  # (planets, runs, 3)
        fz = np.ascontiguousarray(np.broadcast_to(frame.z, shape + (3,)).reshape(-1, 3), dtype=float)
        near = _near_runs_kernel(fz, directions, np.ascontiguousarray(index, dtype=np.intp), cos_limit)
        flat_out = out.reshape(-1)  # a view: the sums land in out
        for i, p in enumerate(planets):
            near_i = np.flatnonzero(near[i])
            if near_i.size:  # added at the near samples only (elsewhere the planet adds 0)
                fraction_near = np.take(fractions[i], np.take(index, near_i))
                flat_out[near_i] += self._planet_transfer(fraction_near, sat, bodies_km[p], frame, door, bands,
                                                          floor_ratio, shape, near_i,
                                                          None if runs is None else runs.at(near_i)) * fraction_near
        return out

    def _planet_transfer(self, fraction_near, satellite_km, planet_km, frame, door, bands, floor_ratio, shape,
                         near, runs_near=None) -> np.ndarray:
        """:meth:`_skippable_transfer` of a planet at the samples ``near`` (flat indices: those
        :meth:`_planets_fraction` finds within its widest skip radius), there only, (len(near),);
        ``fraction_near``: its fraction of the Sun's irradiance there; its angles
        (:func:`body_geometry`) computed there only; ``runs_near``: the scene runs of the
        samples ``near``, when known."""
        sat, planet, fx, fy, fz = (rows_at(v, shape, near) for v in (satellite_km, planet_km, frame.x, frame.y, frame.z))
        g = body_geometry(sat, {"planet": planet}, TelescopeFrame(fx, fy, fz), self.campaign.earth.radius_km,
                          runs=runs_near)
        door_near, floor_near = (np.broadcast_to(np.asarray(v, float), shape).ravel()[near] for v in (door, floor_ratio))
        return self._skippable_transfer(fraction_near, g["planet_angle_deg"], g["planet_phi_deg"],
                                        g["planet_earth_blocked"], door_near, bands, floor_near)

    def lut_node_states(self, settings) -> int:
        """How many (node, door state) pairs the sunlit earthshine table with these
        :class:`~straylight.sources.earthshine_lut.LUTSettings` sums, each an Earth-grid sum."""
        r = self.campaign.orbit_radius_range_km
        return settings.node_count(r[0], self.campaign.earth.radius_km) * len(self.offfield.door_states_deg)

    def moonlit_node_states(self) -> int:
        """How many (node, door state) pairs the moonlit Earth's table (:attr:`moonlit_model`)
        sums, each a coarse Earth-grid sum; 0 with models.earthshine.moonlit_method = direct."""
        from straylight.sources.earthshine_lut import _mirror_symmetric

        settings = self._moonlit_settings()
        if settings is None:
            return 0
        r = self.campaign.orbit_radius_range_km
        nodes = settings.nodes(float(r[0]), self.campaign.earth.radius_km, _mirror_symmetric(self.offfield))
        return int(np.prod([a.size for a in nodes])) * len(self.offfield.door_states_deg)

    def _moonlit_settings(self):
        """The moonlit table's :class:`~straylight.sources.earthshine_lut.MoonlitSettings` from the
        config, or None when the moonlit Earth is summed directly (moonlit_method = direct)."""
        from straylight.sources.earthshine_lut import MoonlitSettings

        es = self.campaign.config["models"].get("earthshine", {})
        if es.get("moonlit_method", "lut") == "direct":
            return None
        return MoonlitSettings(**{k: float(v) for k, v in es.get("moonlit_lut", {}).items()})  # keys checked by the schema

    @cached_property
    def earthshine_choice(self) -> dict:
        """Which sunlit earthshine model :attr:`earthshine_model` will run, decided without
        building anything (``straylight plan`` reads it).  Keys: method ('lut' or 'direct'),
        requested (models.earthshine.method), reason, settings (:class:`~straylight.sources.earthshine_lut.LUTSettings`), node_states and
        build_seconds_estimate (the sunlit table's build at LUT_BUILD_SECONDS_PER_NODE, plus the
        moonlit one's at MOONLIT_LUT_BUILD_SECONDS_PER_NODE, which the table path builds too:
        moonlit_build_seconds_estimate; 0 for 'direct' by config).  With 'auto' the table still
        falls back to the direct sum when its validated error, known once it is built, exceeds
        its share of the tolerance."""
        from straylight.sources.earthshine_lut import LUTSettings

        es = self.campaign.config["models"].get("earthshine", {})
        method = es.get("method", "auto")
        if method == "direct":
            return {"method": "direct", "requested": method, "reason": "models.earthshine.method = direct",
                    "settings": None, "node_states": 0, "build_seconds_estimate": 0.0,
                    "moonlit_build_seconds_estimate": 0.0}
        lut_cfg = es.get("lut", {})
        settings = LUTSettings(float(lut_cfg.get("sun_zenith_step_deg", 0.5)),
                               float(lut_cfg.get("los_zenith_step_deg", 1.0)),
                               float(lut_cfg.get("azimuth_step_deg", 2.5)),
                               int(lut_cfg.get("n_radius", 1)))
        node_states = self.lut_node_states(settings)
        moonlit_s = MOONLIT_LUT_BUILD_SECONDS_PER_NODE * self.moonlit_node_states()
        build_s = LUT_BUILD_SECONDS_PER_NODE * node_states + moonlit_s
        choice = {"method": "lut", "requested": method, "reason": f"{method}: {self.expected_samples} samples",
                  "settings": settings, "node_states": node_states, "build_seconds_estimate": build_s,
                  "moonlit_build_seconds_estimate": moonlit_s}
        if method == "auto":
            # deliberately blind to the cache: the same config must give the same products on
            # every machine, whether or not a table was built there before.
            # build cost against what the table saves (LUT_BUILD_SECONDS_PER_NODE, above)
            saved_s = LUT_SAVED_SECONDS_PER_SAMPLE * self.expected_samples
            if saved_s < build_s:
                choice.update(method="direct", reason=f"auto: {self.expected_samples} samples save ~{saved_s:.0f} s, "
                                                      f"the table costs ~{build_s:.0f} s")
        return choice

    @property
    def _lut_avoidance_deg(self) -> tuple:
        """The avoidance angles the sunlit table depends on (dark limb, bright limb, Sun), deg."""
        k = self.campaign.constraints
        return (k.dark_limb_min_deg, k.bright_limb_min_deg, k.sun_min_deg)

    def earthshine_lut_path(self) -> Path:
        """Where the sunlit table of :attr:`earthshine_choice`'s settings is cached (it may not
        exist yet): the path :func:`~straylight.sources.earthshine_lut.load_or_build` reads or writes."""
        from straylight.sources.earthshine_lut import cache_path, lut_key

        key = lut_key(self.offfield, self.campaign.earth.radius_km, self.campaign.orbit_radius_range_km,
                      self.earthshine_choice["settings"], self.earthshine_floor, self._lut_avoidance_deg)
        return cache_path("earthshine_lut", key)

    @cached_property
    def earthshine_model(self) -> dict:
        """Which earthshine model runs, from models.earthshine.method (auto | lut | direct) and
        the tolerance (:attr:`earthshine_choice`): 'auto' takes the look-up table when the
        campaign's samples repay its build and its validated error is within half the
        tolerance, else the direct sum.  Keys: method, and for the table its file, validated
        error, build time and node steps."""
        import logging

        from straylight.sources.earthshine_lut import load_or_build

        choice = self.earthshine_choice
        if choice["method"] == "direct":
            return {"method": "direct", "lut": None, "reason": choice["reason"]}
        settings = choice["settings"]
        log = logging.getLogger("straylight")
        lut, path = load_or_build(self.offfield, self.campaign.earth.radius_km, self.campaign.orbit_radius_range_km,
                                  settings, self.earthshine_floor, log, avoidance_deg=self._lut_avoidance_deg,
                                  workers=self.build_workers)
        info = {"lut_file": str(path.name), "lut_validation_max_rel_error": lut.validation_max_rel_error,
                "lut_build_seconds": lut.build_seconds, "lut_node_states": choice["node_states"],
                "lut_steps_deg": [settings.sun_zenith_step_deg, settings.los_zenith_step_deg, settings.azimuth_step_deg]}
        share = ERROR_BUDGET_SHARES["earthshine_lut"]
        if choice["requested"] == "auto" and not lut.validation_max_rel_error <= share * self.tolerance:
            reason = (f"auto: table error {lut.validation_max_rel_error:.2g} > {share:g} x the tolerance "
                      f"{self.tolerance:g}")
            log.info("earthshine: %s: direct sum", reason)
            return {"method": "direct", "lut": None, "reason": reason, **info}
        return {"method": "lut", "lut": lut, "reason": choice["reason"], **info}

    @cached_property
    def moonlit_model(self) -> dict:
        """How the moonlit Earth is summed where its bound does not let it be skipped, on the
        table's path (models.earthshine.moonlit_method): 'lut', its own look-up table over (Moon
        zenith, line-of-sight zenith, azimuth from the Moon, roll) of the coarse grid's sum,
        when its validated error (full Moon at perigee, a fraction of the total) is within the
        moonlit grid's share of the tolerance, else (or with 'direct') the coarse grid's direct
        sum.  Keys: method, lut, and for the table its file, validated error and steps."""
        import logging

        from straylight.sources.earthshine_lut import load_or_build_moonlit

        settings = self._moonlit_settings()
        if settings is None:
            return {"method": "direct", "lut": None, "reason": "models.earthshine.moonlit_method = direct"}
        lut, path = load_or_build_moonlit(*self._moonlit_table_inputs(settings), logging.getLogger("straylight"),
                                          self.build_workers)
        info = {"lut_file": path.name, "lut_validation_max_rel_error": lut.validation_max_rel_error,
                "lut_steps_deg": [settings.moon_zenith_step_deg, settings.los_zenith_step_deg,
                                  settings.azimuth_step_deg, settings.roll_step_deg]}
        share = ERROR_BUDGET_SHARES["moonlit_earthshine_grid"]
        if not lut.validation_max_rel_error <= share * self.tolerance:
            return {"method": "direct", "lut": None, **info,
                    "reason": f"table error {lut.validation_max_rel_error:.2g} > {share:g} x the tolerance"}
        return {"method": "lut", "lut": lut, **info}

    def _moonlit_table_inputs(self, settings) -> tuple:
        """The arguments of :func:`~straylight.sources.earthshine_lut.load_or_build_moonlit` (and of its
        cache key) before the logger: the model, the Earth, the orbit, the settings, the grid, the
        darkest sky and the brightest Moon (full, at perigee) per unit solar irradiance at 1 AU,
        and the dark-limb angle."""
        from straylight.sources.offfield import MOON_PERIGEE_KM

        moon_max = float(solar_like_fraction(moon_v_magnitude(0.0, MOON_PERIGEE_KM, self.offfield.moon_law, 180.0)))
        return (self.offfield, self.campaign.earth.radius_km, self.campaign.orbit_radius_range_km, settings,
                self.moonlit_grid, self.earthshine_floor, moon_max, self.campaign.constraints.dark_limb_min_deg)

    def moonlit_lut_path(self) -> Path | None:
        """Where the moonlit table of the configured settings is cached (it may not exist yet);
        None when the moonlit Earth is summed directly."""
        from straylight.sources.earthshine_lut import cache_path, moonlit_key

        settings = self._moonlit_settings()
        return None if settings is None else cache_path("moonlit_lut", moonlit_key(*self._moonlit_table_inputs(settings)))

    @cached_property
    def moonlit_grid(self) -> tuple[int, int]:
        """models.earthshine.moonlit_grid: (n_gamma, n_psi) of the moonlit Earth's direct sum on
        the table's path, away from the limb."""
        return tuple(int(n) for n in self.campaign.config["models"].get("earthshine", {}).get("moonlit_grid", (8, 16)))

    def models_record(self) -> dict:
        """Which models ran and their error budget, for a product's attributes (JSON-able)."""
        sc = self.campaign.config["stars"]
        # build time left out: the record goes into products, whose bytes must not vary run to run
        es = {k: v for k, v in self.earthshine_model.items() if k not in ("lut", "lut_build_seconds", "lut_node_states")}
        s = self.offfield.earthshine
        es["earth_grid"] = [s.n_gamma, s.n_psi]
        es["door_blocks"], es["aperture_points_door"] = list(s.door_blocks), s.n_aperture_door
        shares, lut_runs = ERROR_BUDGET_SHARES, es["method"] == "lut"
        return {"tolerance": self.tolerance, "earthshine": es, "pst": self.offfield.pst.source,
                "unobservable_samples": ("skipped: NaN in every component"
                                         if unobservable_samples(self.campaign) == "skip" else "evaluated"),
                "skip_floor": ("each sample's zodiacal light + Sun + sunlit Earth + moonlit Earth in the field "
                               "(a lower bound of its total; never below the darkest zodiacal light)"),
                "moonlit_earthshine": (f"skipped where its bound < {self.moonlit_skip_share:g} x tolerance x the "
                                       f"sample's floor, else "
                                       + (f"from its table of the grid {list(self.moonlit_grid)} sum (steps "
                                          f"{self.moonlit_model['lut_steps_deg']} deg, validated "
                                          f"{self.moonlit_model['lut_validation_max_rel_error']:.2g} of the total "
                                          f"at full Moon)" if self.moonlit_model["method"] == "lut" else
                                          f"summed directly on grid {list(self.moonlit_grid)}"))
                                      if lut_runs else "summed directly",
                "earthshine_near_limb": ("indicative only within the dark-limb angle of the limb and below it "
                                         "(never observable; no Earth grid converges there)"),
                "stars": {"direct_mag_limit": float(sc.get("offfield_mag_limit", 2.0)),
                          "faint_map": bool(sc.get("faint_map", True)),
                          "direct_skipped": (f"per sky cell and floor level, the stars of smallest bound, "
                                             f"together < {shares['stars_skip']:g} x tolerance x the "
                                             f"sample's floor")},
                "moon_and_planets_skipped": (f"where the bound of each is < {shares['moon_and_planets_skip']:g} / "
                                             f"{1 + len(PLANETS)} x tolerance x the sample's floor"),
                "error_budget": {"earthshine_lut_validated": es.get("lut_validation_max_rel_error") if lut_runs else 0.0,
                                 "moonlit_earthshine_skip_max": self.moonlit_skip_share * self.tolerance if lut_runs else 0.0,
                                 "moonlit_earthshine_grid_share": shares["moonlit_earthshine_grid"] * self.tolerance
                                 if lut_runs else 0.0,
                                 "moonlit_earthshine_lut_validated": self.moonlit_model["lut_validation_max_rel_error"]
                                 if lut_runs and self.moonlit_model["method"] == "lut" else 0.0,
                                 "stars_skip_max": shares["stars_skip"] * self.tolerance,
                                 "moon_and_planets_skip_max": shares["moon_and_planets_skip"] * self.tolerance,
                                 "see": "bench/results/summary.json for the whole model against the converged "
                                        "reference, knobs.json moonlit_grid for the moonlit grid's measured error"}}

    def _earthshine_coefficients(self, sat, sun, moon, frame, door, shape, runs=None) -> dict:
        """Earthshine coefficients (see OffFieldModel.earthshine_coefficients) by the model that
        runs.  The direct sum gives every term; the table gives the sunlit Earth, and of the
        moonlit Earth only the part inside the field (the rest: :meth:`_add_moonlit_earthshine`)."""
        off, re_km = self.offfield, self.campaign.earth.radius_km
        lut = self.earthshine_model["lut"]
        if lut is None:
            return off.earthshine_coefficients(sat, sun, moon, frame, door, re_km)
        full = shape + (3,)
        sat_b, sun_b, moon_b = (np.broadcast_to(np.asarray(v, float), full) for v in (sat, sun, moon))
        d_sun, g_sun = lut.sun_coefficients(sat_b, sun_b, np.broadcast_to(frame.z, full),
                                            np.broadcast_to(np.asarray(door, float), shape), runs)
        in_field_sun, in_field_moon = off.earth_in_field(sat_b, sun_b, moon_b, frame, re_km)
        return {"direct_sun": d_sun + in_field_sun, "door_sun": g_sun, "direct_moon": in_field_moon,
                "door_moon": np.zeros(shape)}

    def _add_moonlit_earthshine(self, es_coeff: dict, sat, sun, moon, frame, door, shape, moon_at_earth_unit: dict,
                                floor: dict, runs=None) -> None:
        """On the table's path, add the moonlit Earth outside the field to ``es_coeff`` (in place):
        skipped where its bound, times the Moon's irradiance, is below ``moonlit_skip_share`` x
        the tolerance x the sample's floor (a lower bound of its total, :meth:`evaluate`) in every
        band, and elsewhere the coarse ``moonlit_grid`` sum, from its table (:attr:`moonlit_model`)
        or summed directly.  With the table, samples whose Moon zenith angle lies beyond its
        ``dark_moon_zenith_deg`` (no moonlit Earth in view: the table is 0 there) are left out
        from the start, bound and all: they would add exactly 0."""
        off, re_km = self.offfield, self.campaign.earth.radius_km
        lut, mlut = self.earthshine_model["lut"], self.moonlit_model["lut"]
        sat_b, sun_b, moon_b, los_b = (np.broadcast_to(np.asarray(v, float), shape + (3,)).reshape(-1, 3)
                                       for v in (sat, sun, moon, frame.z))
        door_b = np.broadcast_to(np.asarray(door, float), shape).reshape(-1)
        floor_b = {b: np.broadcast_to(floor[b], shape).reshape(-1) for b in moon_at_earth_unit}
        cand = None  # the samples considered (flat indices; None: all)
        if mlut is not None:
            runs = scene_rows(sat_b, moon_b, runs=runs)  # found once here if not known
            dark = mlut.dark_runs(runs)
            if np.all(dark):
                return
            if np.any(dark):
                cand = np.flatnonzero(~np.take(dark, runs.index))
                # (the Sun's rows serve the direct moonlit sum only, which has no dark test)
                sat_b, moon_b, los_b = (np.take(v, cand, axis=0) for v in (sat_b, moon_b, los_b))
                door_b = np.take(door_b, cand)
                floor_b = {b: np.take(v, cand) for b, v in floor_b.items()}
                runs = runs.at(cand)
        bound = lut.moon_bound(sat_b, moon_b, los_b, re_km, runs)
        # within 1 deg of the limb and below it the table has no bound: there the whole cap, fully
        # lit, at the PST's largest value outside the field
        no_bound = ~np.isfinite(bound)
        if np.any(no_bound):  # the cap's bound only where needed (it grids each sample's cap)
            unbounded = np.flatnonzero(no_bound)
            bound[no_bound] = (off.earthshine_cap_bound(np.take(sat_b, unbounded, axis=0), re_km, self.moonlit_grid,
                                                        None if runs is None else runs.at(unbounded))
                               + lut.moon_door_bound)
        need = np.zeros(bound.shape, bool)
        for b, e_moon in moon_at_earth_unit.items():
            e_moon = np.broadcast_to(e_moon, shape).reshape(-1)
            need |= bound * (e_moon if cand is None else np.take(e_moon, cand)) > (
                self.moonlit_skip_share * self.tolerance * floor_b[b])
        if not np.any(need):
            return
        # the moonlit Earth is ~1e-5 of the sunlit: a coarse grid (models.earthshine.moonlit_grid)
        # is enough where a line of sight can be observable (>= the dark-limb angle above the
        # limb).  Nearer the limb and below it no Earth grid converges (blocks next to the field
        # edge meet the PST's jump), so the configured grid would cost 5x for numbers no better
        # than indicative: the coarse grid runs there too.
        at = np.flatnonzero(need)  # among the samples considered
        sub = TelescopeFrame(*(rows_at(a, shape, at if cand is None else np.take(cand, at))
                               for a in (frame.x, frame.y, frame.z)))
        door_need = np.take(door_b, at)
        if mlut is not None:  # the coarse grid's sum, tabulated
            direct_moon, door_moon = mlut.coefficients(np.take(sat_b, at, axis=0), np.take(moon_b, at, axis=0), sub,
                                                       door_need, None if runs is None else runs.at(at))
        else:
            c = off.earthshine_coefficients(*(np.take(v, at, axis=0) for v in (sat_b, sun_b, moon_b)), sub, door_need,
                                            re_km, in_field=False, sun=False, grid=self.moonlit_grid)
            direct_moon, door_moon = c["direct_moon"], c["door_moon"]
        samples = np.unravel_index(at if cand is None else np.take(cand, at), shape)
        es_coeff["direct_moon"][samples] += direct_moon
        es_coeff["door_moon"][samples] = door_moon

    @cached_property
    def _pst_azimuthal_table(self):
        """Natural log of the azimuth-averaged PST on a uniform 0.01 deg theta grid (for the
        faint-star map): nodes, values, and the per-cell slopes for direct-index interpolation."""
        theta = np.linspace(0.0, 180.0, 18001)
        ln_pst = np.log(self.offfield.pst.azimuthal_mean(theta))
        return theta, ln_pst, np.diff(ln_pst)

    def faint_star_rates(self, stars: StarTable, los, bands, batch: int = 4096, los_batch: int = 1024) -> dict:
        """e-/s/pix per band from the faint stars: sum_s E_s PSTavg(theta_s) * pixel area over the
        stars outside the field and in front of the aperture plane (theta <= 90 deg, where the
        door's Sp is not 0: :func:`~straylight.optics.door.behind_aperture_plane`), for lines of sight ``los`` (..., 3).  Depends on the line of sight
        only, so it is computed once per distinct set of lines of sight (cached).  ``los_batch``
        lines of sight x ``batch`` stars at a time bound the temporaries (~34 MB each)."""
        import hashlib

        los = np.asarray(los, float)
        # cached on the star table (whose lifetime bounds the entries) per model and lines of sight
        key = (hashlib.sha1(np.ascontiguousarray(los).tobytes()).hexdigest(), id(self), tuple(bands))
        cache = stars.__dict__.setdefault("_faint_cache", {})
        if key in cache:
            return cache[key]
        flat = los.reshape(-1, 3)
        bands = [b for b in bands if b in stars.faint_mag_ab]
        flux = np.array([self.photometry(b).from_ab(stars.faint_mag_ab[b]) for b in bands]).T  # (S, B)
        theta_grid, ln_pst, slope = self._pst_azimuthal_table
        per_deg = (theta_grid.size - 1) / theta_grid[-1]
        out = np.zeros((flat.shape[0], len(bands)))
        s_all = stars.faint_unit
        # one BLAS thread: the products' summation order, and so the map's last bits, must not
        # depend on how many cores the job was given (Snakemake sets OPENBLAS_NUM_THREADS per job)
        with threadpool_limits(limits=1, user_api="blas"):
            self._faint_star_sums(flat, s_all, flux, ln_pst, slope, per_deg, out, batch, los_batch)
        out *= self.offfield.pixel_area_m2
        res = {b: out[:, j].reshape(los.shape[:-1]) for j, b in enumerate(bands)}
        if len(cache) > 64:
            cache.clear()
        cache[key] = res
        return res

    def _faint_star_sums(self, flat, s_all, flux, ln_pst, slope, per_deg, out, batch, los_batch) -> None:
        """Adds sum_s flux_s PSTavg(theta_s) over the faint stars to ``out`` (lines of sight x bands)."""
        r_field = self.offfield.field_radius_deg
        for a in range(0, flat.shape[0], los_batch):
            for i in range(0, len(s_all), batch):
                cosang = np.clip(flat[a:a + los_batch] @ s_all[i:i + batch].T, -1.0, 1.0)
                x = np.degrees(np.arccos(cosang)) * per_deg  # position on the uniform grid
                k = np.minimum(x.astype(np.intp), slope.size - 1)  # linear in ln PST, as np.interp on the grid
                t = np.exp(ln_pst[k] + (x - k) * slope[k]) * ((x > r_field * per_deg) & (x <= 90.0 * per_deg))
                out[a:a + los_batch] += t @ flux[i:i + batch]

    #: the star skip's floor levels, in units of the darkest zodiacal light: a sample's floor
    #: is rounded down to one of them, so each sky cell's candidates are chosen once per level
    STAR_FLOOR_LEVELS = 4.0 ** np.arange(12)

    def star_bound_scale(self, stars: StarTable) -> np.ndarray:
        """Per direct star, (S,), its e-/s/pix at PST = 1 (Se = Sp = 1) as a fraction of the
        darkest zodiacal light, in the band where that fraction is largest: times the PST's
        bound at a line of sight (:meth:`~straylight.optics.pst.PST.tail_max`), an upper bound of the
        star's share of any total in every band."""
        rel = np.zeros(len(stars.ra_deg))
        for b in self.campaign.bands:
            if b in stars.mag_ab:
                e = self.photometry(b).from_ab(stars.mag_ab[b]) * self.offfield.pixel_area_m2
                rel = np.maximum(rel, e / self.darkest_zodiacal_e_per_s(b))
        return rel

    #: HEALPix nside of the sky cells whose lines of sight share a list of candidate direct
    #: stars (:meth:`star_cells`): a cell's radius (1.9 deg at 32) loosens every star's bound
    #: over the cell, so finer cells sum fewer pairs but cost more to build.  Measured on a
    #: cube batch (15,840 samples, 212 direct stars), with each cell's bounds sorted: 0.68,
    #: 0.47, 0.38 candidates per sample at nside 16, 32, 64 (a per-sample choice would need
    #: 0.23), built in 0.04, 0.2, 1.8 s (once per star table), the batch's time within noise
    #: across the three; 32 the balance
    STAR_CELL_NSIDE = 32
    #: the cells' lists hold this many entries at most (int32: 64 MB; while they are built, 16
    #: bytes an entry): beyond, the stars listed in most cells are summed at every line of
    #: sight at every level instead (a deep catalog at a tiny tolerance: the benchmark's
    #: reference, 117,598 stars at 1e-12, lists 9.0 million entries and sums 116,861-117,238
    #: stars everywhere, built in ~55 s)
    STAR_CELL_ENTRIES = 16_000_000
    #: candidate (sample, star) pairs tested at once: bounds the memory of a deep catalog
    STAR_PAIRS_PER_PASS = 1 << 20

    def star_cells(self, stars: StarTable) -> "StarCells":
        """Per sky cell (HEALPix ring order, :attr:`STAR_CELL_NSIDE`) and floor level
        (:attr:`STAR_FLOOR_LEVELS`), the direct stars summed at the cell's lines of sight; the
        others are skipped.  Each star's bound over the cell is its :meth:`star_bound_scale`
        times the PST's :meth:`~straylight.optics.pst.PST.tail_max` from its angle to the cell's
        nearest point (the angle to the centre less the cell's radius; :meth:`_cell_bound_table`):
        the stars of smallest bound are skipped for as long as their bounds add up to no more
        than the stars_skip share of the tolerance (1/8) times the level, and the rest are the
        candidates.  So at every line of sight of the cell the skipped stars together stay below
        that share of the sample's floor (a lower bound of its total, :meth:`evaluate`) in every
        band, the Earth and the door only lowering them further.  One budget shared by all the
        stars rather than split evenly among them: a line of sight sees few stars close, so a
        cube batch sums 0.42 pairs per sample instead of 5.4 (a radius per star, each held to
        1/212 of the budget, tested 8 candidates per sample).  The smallest bounds are found
        without sorting: they are binned by :attr:`STAR_BOUND_BINS_PER_DEX` and whole bins are
        skipped, from the smallest, while their sum stays within the budget.

        Each cell's candidates are sorted by the number of levels that need them, so a level's
        candidates are a prefix of the cell's list.  A star that every cell needs at a level (a
        bright star against the darkest floors, or every star at a tiny tolerance) is listed
        once for the whole sky there instead of in every cell.  Cached on the star table."""
        import healpy as hp

        key = (id(self), tuple(self.campaign.bands), self.tolerance, self.STAR_CELL_NSIDE)
        cache = stars.__dict__.setdefault("_cells_cache", {})
        if key in cache:
            return cache[key]
        n_stars, n_levels = len(stars.ra_deg), self.STAR_FLOOR_LEVELS.size
        rel = self.star_bound_scale(stars)
        # a hair under the share, against the rounding of the sums
        budget = ERROR_BUDGET_SHARES["stars_skip"] * self.tolerance * self.STAR_FLOOR_LEVELS * (1.0 - 1e-9)
        nside = self.STAR_CELL_NSIDE
        n_cells = hp.nside2npix(nside)
        centres = np.array(hp.pix2vec(nside, np.arange(n_cells))).T
        # max_pixrad: the largest centre-to-corner distance; 1 % and 1e-9 rad over it for the
        # curved edges and rounding (sampled: no point of a cell lies beyond 0.999 of it)
        tail = self._cell_bound_table(1.01 * hp.max_pixrad(nside) + 1e-9)
        per_cos = (tail.size - 1) / 2.0
        # bins from STAR_BOUND_DEPTH_DEX below the smallest budget (the first bin gathers every
        # smaller bound) to a dex over the largest (the last holds bounds no level skips)
        per_dex = self.STAR_BOUND_BINS_PER_DEX
        lo_dex = int(np.floor(np.log10(budget[0]))) - self.STAR_BOUND_DEPTH_DEX
        n_bins = (int(np.ceil(np.log10(budget[-1]))) + 1 - lo_dex) * per_dex + 1
        with np.errstate(divide="ignore"):
            log_rel, log_tail = np.log10(rel), np.log10(tail)
        # a star whose bound exceeds a level's budget even at the far side of the sky is summed
        # at every line of sight there: its entries below that level are never listed
        sure = np.count_nonzero(rel[:, None] * tail[0] > budget[None, :], axis=1)
        s_unit = stars.unit if n_stars else np.zeros((0, 3))
        everywhere = np.full(n_stars, n_levels, np.intp)  # levels at which every cell needs the star
        promoted = np.zeros(n_stars, bool)  # summed everywhere at every level: the lists outgrew the cap
        parts, n_entries = [], 0
        block = max(1, (1 << 21) // max(n_stars, n_bins))  # cells at a time: arrays of ~2 million
        for a in range(0, n_cells, block):
            node = np.clip(np.ceil((centres[a:a + block] @ s_unit.T + 1.0) * per_cos), 0, tail.size - 1).astype(np.intp)
            bound = rel * tail[node]  # (c, S)
            bins = np.clip(np.floor((log_rel + log_tail[node]) * per_dex) - lo_dex * per_dex, 0, n_bins - 1
                           ).astype(np.intp)
            rows = bins.shape[0]
            sums = np.bincount((np.arange(rows)[:, None] * n_bins + bins).ravel(), weights=bound.ravel(),
                               minlength=rows * n_bins).reshape(rows, n_bins)
            cum = np.cumsum(sums, axis=1)
            # per level, the leading bins skipped; per bin, the levels that skip it not: a star's
            # reach (the levels that need it, nested: 0 .. reach - 1) is its bin's
            cut = np.stack([np.count_nonzero(cum <= lim, axis=1) for lim in budget], axis=1)  # (c, L)
            reach_of_bin = np.cumsum(np.bincount((np.arange(rows)[:, None] * (n_bins + 1) + cut).ravel(),
                                                 minlength=rows * (n_bins + 1)).reshape(rows, -1), axis=1)
            reach = np.take_along_axis(reach_of_bin, bins, axis=1)
            if n_stars:
                everywhere = np.minimum(everywhere, reach.min(axis=0))
            r, k = np.nonzero((reach > sure) & ~promoted)
            parts.append((r + a, k, reach[r, k]))
            n_entries += r.size
            if n_entries > self.STAR_CELL_ENTRIES:
                parts = self._promote_to_whole_sky(parts, promoted, self.STAR_CELL_ENTRIES // 2)
                n_entries = sum(p[0].size for p in parts)
        cell, star, reach = (np.concatenate(x) for x in zip(*parts))
        everywhere[promoted] = n_levels
        kept = reach > everywhere[star]  # entries the whole sky's list does not already hold
        cell, star, reach = cell[kept], star[kept], reach[kept]
        order = np.lexsort((-reach, cell))  # cell after cell, each by decreasing reach
        cell, star, reach = cell[order], star[order], reach[order]
        hist = np.bincount(cell * (n_levels + 1) + reach, minlength=n_cells * (n_levels + 1)).reshape(n_cells, -1)
        counts = np.cumsum(hist[:, ::-1], axis=1)[:, ::-1][:, 1:]  # (cells, levels): reach > level
        start = np.concatenate([[0], np.cumsum(counts[:, 0])[:-1]]).astype(np.intp)
        sky_order = np.argsort(-everywhere, kind="stable")
        sky_count = np.array([np.count_nonzero(everywhere > lv) for lv in range(n_levels)], np.intp)
        cells = StarCells(nside, star.astype(np.int32), start, counts, sky_order, sky_count, everywhere)
        cache[key] = cells
        return cells

    #: :meth:`star_cells`' bounds: the cosine nodes of its PST table, and the bins (per dex,
    #: from this many dex below the smallest budget) whose sums decide which stars are skipped.
    #: Coarser bins skip fewer stars (whole bins only): at 25 per dex (10 % wide) the default
    #: catalog's cells list 19,835 entries where sorting every bound gave 19,309, and a cube
    #: batch sums 6580 pairs instead of 6378; the 212 stars' lists build in 0.2 s
    STAR_BOUND_COS_NODES = 2_000_001
    STAR_BOUND_BINS_PER_DEX = 25
    STAR_BOUND_DEPTH_DEX = 8

    def _cell_bound_table(self, margin_rad: float) -> np.ndarray:
        """The PST's :meth:`~straylight.optics.pst.PST.tail_max` from ``margin_rad`` short of the angle
        whose cosine is each of :attr:`STAR_BOUND_COS_NODES` evenly spaced nodes from -1 to 1: at
        a cosine, the node at or above it (a smaller angle) bounds the tail maximum there.
        Cached per margin."""
        cache = self.__dict__.setdefault("_cell_bound_tables", {})
        if margin_rad not in cache:
            cos_nodes = np.linspace(-1.0, 1.0, self.STAR_BOUND_COS_NODES)
            angle_deg = np.degrees(np.maximum(np.arccos(cos_nodes) - margin_rad, 0.0))
            cache[margin_rad] = self.offfield.pst.tail_max(angle_deg)
        return cache[margin_rad]

    @staticmethod
    def _promote_to_whole_sky(parts, promoted, entries_max) -> list:
        """:meth:`star_cells`' lists so far, ``parts`` [(cell, star, reach)], less the entries
        of the stars listed in most cells, marked in ``promoted`` (in place), until at most
        ``entries_max`` entries are left: a promoted star is summed at every line of sight at
        every level (summing a star never breaks the budget; it only costs).  A deep catalog at
        a tiny tolerance (the benchmark's reference: every star needed nearly everywhere)."""
        star = np.concatenate([p[1] for p in parts])
        entries = np.bincount(star, minlength=promoted.size)
        entries[promoted] = 0
        by_entries = np.argsort(-entries, kind="stable")
        excess = entries.sum() - entries_max
        if excess > 0:
            promoted[by_entries[:int(np.searchsorted(np.cumsum(entries[by_entries]), excess)) + 1]] = True
        return [(c[~promoted[k]], k[~promoted[k]], r[~promoted[k]]) for c, k, r in parts]

    def _star_pairs(self, stars: StarTable, frame, sat, door, floor_ratio=1.0, runs=None):
        """The off-field catalog stars' band-independent transfer, E = 1 photon s-1 m-2:
        Se * Sp * PST * pixel factor, for the (sample, star) pairs that count: the star is a
        candidate of the sample's sky cell at its floor level (``floor_ratio`` >= 1 times the
        darkest zodiacal light, per sample; :meth:`star_cells`), is not behind the Earth, and is
        outside the field (stars inside scatter and make ghosts instead).  Returns the shape of
        the samples and ``(sample, star, transfer)``: flat sample index, star index, transfer.

        Where samples come in runs that share a satellite position (cube time steps) the Earth
        test runs once per star and step (``runs``: the samples' scene runs when known)."""
        s_all = np.ascontiguousarray(stars.unit, dtype=float)  # (S, 3)
        cells = self.star_cells(stars)
        shape = np.broadcast_shapes(np.shape(frame.z)[:-1], np.shape(door), np.shape(sat)[:-1])
        fz, fx, fy = (np.ascontiguousarray(np.broadcast_to(a, shape + (3,)).reshape(-1, 3), dtype=float)
                      for a in (frame.z, frame.x, frame.y))
        op = np.broadcast_to(np.asarray(door, float), shape).ravel()
        # each sample's floor level: rounded down, so its budget is never too large
        level = np.searchsorted(self.STAR_FLOOR_LEVELS, np.broadcast_to(np.asarray(floor_ratio, float), shape).ravel(),
                                side="right") - 1
        level = np.clip(level, 0, self.STAR_FLOOR_LEVELS.size - 1)
        re_km = self.campaign.earth.radius_km
        sat_b = np.broadcast_to(np.asarray(sat, float), shape + (3,))
        runs = scene_runs(sat_b, runs=runs)
        period = tiled_period(fz, runs)  # a cube batch: the same lines of sight at every time step
        if runs is not None and runs.count * len(s_all) > self.STAR_PAIRS_PER_PASS:
            runs = None  # many short runs of a deep catalog: the test per pair costs less memory
        if runs is not None:  # the Earth test once per star and time step
            star_blocked = earth_blocks(runs.vectors[0][:, None, :], s_all[None], re_km)  # (R, S)
            run_index, sat_flat = runs.index, np.zeros((0, 3))
        else:
            star_blocked, run_index = np.zeros((0, 0), bool), np.zeros(0, np.intp)
            sat_flat = np.ascontiguousarray(sat_b.reshape(-1, 3))
        cell = cells.cell_of(fz) if period is None else np.tile(cells.cell_of(fz[:period]), len(fz) // period)
        n_cand = cells.count[cell, level] + cells.sky_count[level]  # the cell's and the whole sky's candidates
        ends = np.cumsum(n_cand)
        parts = []
        a = 0
        while a < fz.shape[0]:  # passes of at most STAR_PAIRS_PER_PASS candidates (one sample at least)
            base = ends[a - 1] if a else 0
            b = max(int(np.searchsorted(ends, base + self.STAR_PAIRS_PER_PASS, side="right")), a + 1)
            r, k, theta, phi = (np.empty(int(ends[b - 1] - base), t) for t in (np.intp, np.intp, float, float))
            n = _star_pairs_kernel(a, b, fz, fx, fy, s_all, level, cell, cells.start, cells.count,
                                   cells.stars, cells.sky_order, cells.sky_count, cells.everywhere, star_blocked,
                                   run_index, sat_flat, float(re_km), float(self.offfield.field_radius_deg),
                                   r, k, theta, phi)
            r, k, theta, phi = r[:n], k[:n], theta[:n], phi[:n]
            parts.append((r, k, self.offfield.point_source(1.0, theta, phi, False, op[r])))
            a = b
        if not parts:
            return shape, (np.zeros(0, np.intp), np.zeros(0, np.intp), np.zeros(0))
        return shape, tuple(np.concatenate(x) for x in zip(*parts))


def _check_into(into, n_samples: int, n_bands: int) -> None:
    """ValueError unless ``into`` is (distinct names of :data:`BAND_COMPONENTS`, an array of
    shape (names, samples, bands))."""
    names, values = into
    unknown = sorted(set(names) - set(BAND_COMPONENTS))
    expected = (len(names), n_samples, n_bands)
    if unknown or len(set(names)) != len(names) or np.shape(values) != expected:
        raise ValueError(f"into: components {tuple(names)} (unknown: {unknown}; each at most once) in an array of "
                         f"shape {np.shape(values)}, not (components, samples, bands) = {expected}")


#: the per-band components :meth:`ComponentModel.evaluate` returns, in e-/s/pix
BAND_COMPONENTS = ("zodiacal", "sun", "moon", "planets", "stars", "earthshine_direct", "earthshine_door",
                   "earthshine", "total")


@njit(cache=True, nogil=True)
def _band_components_kernel(zodi_e, t_sun, inverse_square, moon_fraction, planets_fraction, direct_sun, door_sun,
                            direct_moon, door_moon, moon_at_earth_fraction, stars_e, sun_at_1au, slot, out):
    """Every band's :data:`BAND_COMPONENTS` (e-/s/pix) per sample, component ``c`` into
    ``out[slot[c], sample, band]`` (any float dtype and strides; not written where slot[c] is
    -1), from the band-independent per-sample terms and each band's solar photon irradiance
    at 1 AU; ``zodi_e`` and ``stars_e``: each band's zodiacal light and stars, (bands,
    samples).  The arithmetic is the per-band numpy expressions it replaced, in the same
    order, so the same float64 values (the cube's totals compared bit for bit), in one pass
    over the samples instead of ~25 numpy passes a band."""
    v = np.empty(len(BAND_COMPONENTS))
    for i in range(t_sun.shape[0]):
        for ib in range(sun_at_1au.shape[0]):
            s1 = sun_at_1au[ib]
            sun_irr = s1 * inverse_square[i]
            moon_irr_earth = s1 * moon_at_earth_fraction[i]
            v[0] = zodi_e[ib, i]
            v[1] = t_sun[i] * sun_irr
            v[2] = moon_fraction[i] * s1
            v[3] = planets_fraction[i] * s1
            v[4] = stars_e[ib, i]
            v[5] = direct_sun[i] * sun_irr + direct_moon[i] * moon_irr_earth
            v[6] = door_sun[i] * sun_irr + door_moon[i] * moon_irr_earth
            v[7] = v[5] + v[6]
            v[8] = v[0] + v[1] + v[2] + v[3] + v[4] + v[7]
            for c in range(len(BAND_COMPONENTS)):
                if slot[c] >= 0:
                    out[slot[c], i, ib] = v[c]


@njit(cache=True, nogil=True)
def _star_pairs_kernel(first, stop, fz, fx, fy, s, level, cell, start, count, cell_stars, sky_order,
                       sky_count, everywhere, blocked_by_run, run_index, sat, re_km, field_radius_deg,
                       out_sample, out_star, out_theta, out_phi):
    """:meth:`ComponentModel._star_pairs` for samples ``first`` .. ``stop`` - 1: each sample's
    candidates (its sky cell's at its level, then the whole sky's), kept where the star is
    not behind the Earth (per run from ``blocked_by_run``, else tested
    here against ``sat``) and lies outside the field; writes (sample, star, theta, phi) of the
    pairs kept and returns their number.  One pass per candidate instead of numpy's pass per
    operation over every candidate."""
    n = 0
    for i in range(first, stop):
        lv = level[i]
        c = cell[i]
        n_cell = count[c, lv]
        for j in range(n_cell + sky_count[lv]):
            if j < n_cell:
                k = cell_stars[start[c] + j]
                if everywhere[k] > lv:  # a whole-sky star at this level: the sky's list has it
                    continue
            else:
                k = sky_order[j - n_cell]
            if blocked_by_run.size:
                if blocked_by_run[run_index[i], k]:
                    continue
            else:  # geometry.earth_blocks: behind the satellite's horizon plane and within the Earth
                sk = np.sqrt(s[k, 0] ** 2 + s[k, 1] ** 2 + s[k, 2] ** 2)
                u0, u1, u2 = s[k, 0] / sk, s[k, 1] / sk, s[k, 2] / sk
                x0, x1, x2 = sat[i, 0], sat[i, 1], sat[i, 2]
                if u0 * x0 + u1 * x1 + u2 * x2 < 0.0:
                    m0, m1, m2 = x1 * u2 - x2 * u1, x2 * u0 - x0 * u2, x0 * u1 - x1 * u0
                    if np.sqrt(m0 * m0 + m1 * m1 + m2 * m2) < re_km:
                        continue
            dz = fz[i, 0] * s[k, 0] + fz[i, 1] * s[k, 1] + fz[i, 2] * s[k, 2]
            dx = fx[i, 0] * s[k, 0] + fx[i, 1] * s[k, 1] + fx[i, 2] * s[k, 2]
            dy = fy[i, 0] * s[k, 0] + fy[i, 1] * s[k, 1] + fy[i, 2] * s[k, 2]
            theta = np.degrees(np.arctan2(np.hypot(dx, dy), dz))
            if not theta > field_radius_deg:
                continue
            phi = np.degrees(np.arctan2(dy, dx))
            out_sample[n] = i
            out_star[n] = k
            out_theta[n] = theta
            out_phi[n] = phi + 360.0 if phi < 0.0 else phi
            n += 1
    return n


@njit(cache=True, nogil=True)
def _near_runs_kernel(fz, directions, run_index, cos_limit):
    """(bodies, samples) bool: sample n's line of sight ``fz[n]`` has a cosine over
    ``cos_limit[b]`` with body b's direction in the sample's run, ``directions[b, run_index[n]]``
    (the products summed in :func:`~straylight.sky.geometry.dot`'s order, so the same cosines)."""
    n_bodies, n = directions.shape[0], fz.shape[0]
    out = np.zeros((n_bodies, n), np.bool_)
    for b in range(n_bodies):
        limit = cos_limit[b]
        for i in range(n):
            r = run_index[i]
            c = fz[i, 0] * directions[b, r, 0] + fz[i, 1] * directions[b, r, 1] + fz[i, 2] * directions[b, r, 2]
            out[b, i] = c > limit
    return out


def unobservable_samples(campaign) -> str:
    """models.unobservable_samples of a campaign: 'evaluate' (every cube sample gets its
    background) or 'skip' (samples that break a constraint get NaN in every component)."""
    return str(campaign.config["models"].get("unobservable_samples", "evaluate"))


@dataclass(frozen=True)
class StarCells:
    """Candidate direct stars per HEALPix sky cell (ring order) and floor level
    (:meth:`ComponentModel.star_cells`): cell c's candidates at level l are
    ``stars[start[c] : start[c] + count[c, l]]`` (less those that count everywhere at l) and
    ``sky_order[:sky_count[l]]``."""

    nside: int
    stars: np.ndarray  # star indices, cell after cell
    start: np.ndarray  # (cells,) each cell's first entry
    count: np.ndarray  # (cells, levels) candidates
    sky_order: np.ndarray  # star indices, by the number of levels at which they count everywhere
    sky_count: np.ndarray  # (levels,) whole-sky candidates: a prefix of sky_order
    everywhere: np.ndarray  # (stars,) levels 0 .. everywhere - 1 count for the whole sky

    def cell_of(self, unit_vectors) -> np.ndarray:
        """The sky cell of each unit vector (N, 3)."""
        import healpy as hp

        v = np.asarray(unit_vectors, float)
        return hp.vec2pix(self.nside, v[:, 0], v[:, 1], v[:, 2])


def load_offfield_stars(path, bands, mag_limit: float, faint_map: bool = False) -> StarTable:
    """Catalog stars (``stars_csst.parquet`` or any table with ra, dec, mag_<band>), split by
    :func:`split_stars`.  Positions are taken at the catalog epoch: proper motions move bright
    stars by < 1 arcmin in a century, far below the PST's angular structure."""
    from straylight.catalog.star_table import read_star_columns

    bands = [b for b in bands if b != "V"]
    if not bands:
        return StarTable(np.zeros(0), np.zeros(0), {})
    ra, dec, by_band = read_star_columns(path, bands)
    return split_stars(ra, dec, by_band, mag_limit, faint_map)


def split_stars(ra_deg, dec_deg, mag_by_band: dict, mag_limit: float, faint_map: bool) -> StarTable:
    """Stars brighter than ``mag_limit`` (AB) in at least one band are summed directly (in each
    band only those brighter than the limit count; the others get +inf mag there).  With
    ``faint_map`` every other star enters the smoothed faint-star map
    (:meth:`ComponentModel.faint_star_rates`), so each star counts exactly once in each band;
    without it they are left out."""
    bands = list(mag_by_band)
    mags = np.array([mag_by_band[b] for b in bands])  # (B, S)
    bright = mags <= mag_limit
    keep = np.any(bright, axis=0)
    direct = np.where(bright, mags, np.inf)[:, keep]
    if not faint_map:
        return StarTable(ra_deg[keep], dec_deg[keep], {b: direct[i] for i, b in enumerate(bands)})
    rest = np.any(~bright & np.isfinite(mags), axis=0)
    faint = np.where(~bright, mags, np.inf)[:, rest]
    return StarTable(ra_deg[keep], dec_deg[keep], {b: direct[i] for i, b in enumerate(bands)},
                     ra_deg[rest], dec_deg[rest], {b: faint[i] for i, b in enumerate(bands)})
