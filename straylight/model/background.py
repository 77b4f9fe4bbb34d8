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
from numba import njit

from straylight.config import Campaign
from straylight.model.fidelity import ERROR_BUDGET_SHARES, FidelityPolicy
from straylight.sky.ephemeris import PLANETS
from straylight.sky.geometry import telescope_frame, unit
from straylight.sources.bodies import InFieldBodies, Moon, Planets, SolarBodySkip, Sun
from straylight.sources.context import Samples, SourceContext
from straylight.sources.moonlit_earth import MoonlitEarth
from straylight.sources.photometry import magnitude_per_arcsec2
from straylight.sources.stars import OffFieldStars, StarTable
from straylight.sources.sunlit_earth import SunlitEarth


class BackgroundModel:
    """The background of one campaign: its sources and its fidelity policy.  ``build_workers``:
    threads that build an earthshine table that is not cached (None: every CPU this process may
    run on; the result does not depend on it); ``moonlit_skip_share``: see
    :class:`~straylight.model.fidelity.FidelityPolicy`."""

    def __init__(self, campaign: Campaign, build_workers: int | None = None,
                 moonlit_skip_share: float = ERROR_BUDGET_SHARES["moonlit_earthshine_skip"]):
        self.campaign = campaign
        if build_workers is None:
            from straylight.util.daskutil import available_cores

            build_workers = available_cores()
        self.policy = FidelityPolicy(campaign, moonlit_skip_share)
        self.context = SourceContext(campaign)
        self.sun = Sun(self.context)
        self.body_skip = SolarBodySkip(self.context, self.policy)
        self.moon = Moon(self.context, self.body_skip)
        self.planets = Planets(self.context, self.body_skip)
        self.stars = OffFieldStars(self.context, self.policy)
        self.moonlit_earth = MoonlitEarth(self.context, self.policy, build_workers)
        self.sunlit_earth = SunlitEarth(self.context, self.policy, self.moonlit_earth, build_workers)
        self.in_field = InFieldBodies(self.context)

    def evaluate(self, satellite_km, bodies_km, los, geometry, bands, stars: StarTable | None = None,
                 faint_rates: dict | None = None, frame=None, into: tuple | None = None, runs=None) -> dict:
        """Components for broadcastable samples, band -> {component: e-/s/pix, float64 arrays
        of the samples' shape (:data:`BAND_COMPONENTS`), and ``_band``, ``_zodiacal_no_data``,
        ``_mag``}; ``geometry`` from :func:`~straylight.sky.observing.observing_geometry` (the
        Sun's and the Moon's entries and the limb's are read; each planet in ``bodies_km`` gets
        its angles where it can count: :class:`~straylight.sources.bodies.Planets`);
        ``stars``: the off-field stars (None: stars = 0); ``faint_rates``: the faint stars' map
        at these lines of sight, band -> e-/s/pix (as
        :meth:`~straylight.sources.stars.OffFieldStars.faint_star_rates` gives it), when already
        computed; ``frame``: the samples' ``telescope_frame(los, sun - satellite)``, when
        already computed; ``into``: (component names, array (names, samples flattened, bands)),
        e.g. a cube region's float32 block, that receives those components (the result's arrays
        are then views of it, and the other components are not computed); ``runs``: the
        samples' scene runs when the caller knows them (:class:`~straylight.sky.geometry.SceneRuns`,
        e.g. a cube's time steps: runs of samples that share the satellite and every body in
        ``bodies_km``), else found where needed.  ValueError for an unknown name or an array of
        another shape."""
        c = self.context
        sat = np.asarray(satellite_km, float)
        sun = bodies_km["sun"]
        frame = telescope_frame(los, sun - sat) if frame is None else frame
        shape = geometry["sun_angle_deg"].shape
        if into is not None:  # checked before any work
            _check_into(into, int(np.prod(shape)), len(bands))
        samples = Samples(sat, bodies_km, frame, geometry, runs)
        moon_lamp = self.moon.lamp(samples)
        zodi_e, zodi_no_data = c.zodiacal.rates([c.band(name) for name in bands], frame.z, unit(sun - sat), shape,
                                                runs)  # (bands, samples)
        # the solar-spectrum sources' rates are band-independent until multiplied by each band's
        # photon irradiance of the Sun at 1 AU
        sun_at_1au = {name: c.photometry(name).sun_at_1au_photons_s_m2 for name in bands}
        moon_at_earth_unit = {name: sun_at_1au[name] * moon_lamp["at_earth"] for name in bands}
        t_sun, inverse_square = self.sun.rates(samples)
        es_coeff = self.sunlit_earth.rates(samples)
        # the terms never skipped make each sample's floor (the band-independent sums once), and
        # the floor in units of the darkest zodiacal light, worst band: what the skip radii scale with
        per_sun = t_sun + es_coeff["direct_sun"] + es_coeff["door_sun"]
        per_moon = es_coeff["direct_moon"] + es_coeff["door_moon"]
        floor, floor_ratio = self._floor(zodi_e, per_sun, inverse_square, per_moon, moon_lamp["at_earth"],
                                         [sun_at_1au[name] for name in bands], bands, shape)
        if self.sunlit_earth.lut is not None:
            self.moonlit_earth.add(es_coeff, samples, self.sunlit_earth.lut, moon_at_earth_unit, floor)
        moon_fraction = self.moon.rates(samples, moon_lamp, bands, floor_ratio)
        planets_fraction = self.planets.rates(samples, bands, floor_ratio)
        stars_e = self.stars.rates(samples, stars, bands, floor_ratio, faint_rates)  # (bands, samples)
        # every band's components in one compiled pass over the samples (reads the
        # band-independent arrays once, not once a band)
        n = int(np.prod(shape))
        names, values = into if into is not None else (BAND_COMPONENTS, np.empty((len(BAND_COMPONENTS), len(bands), n))
                                                         .transpose(0, 2, 1))  # band-major: each band's row contiguous
        slot = np.array([list(names).index(comp) if comp in names else -1 for comp in BAND_COMPONENTS], np.intp)
        flat = [np.ascontiguousarray(np.broadcast_to(np.asarray(v, float), shape).ravel()) for v in
                (t_sun, inverse_square, moon_fraction, planets_fraction, es_coeff["direct_sun"],
                 es_coeff["door_sun"], es_coeff["direct_moon"], es_coeff["door_moon"], moon_lamp["at_earth"])]
        _band_components_kernel(zodi_e, *flat, stars_e, np.array([sun_at_1au[name] for name in bands]), slot, values)
        aperture_d = self.campaign.instrument_value("telescope", "aperture_diameter_m")
        pix_arcsec = self.campaign.pixel_scale_arcsec
        out = {}
        for ib, name in enumerate(bands):
            band = c.band(name)
            res = {comp: values[k, :, ib].reshape(shape) for k, comp in enumerate(names)}
            res["_band"] = band
            res["_zodiacal_no_data"] = zodi_no_data
            res["_mag"] = lambda e, b=band: magnitude_per_arcsec2(e, b, aperture_d, pix_arcsec)
            out[name] = res
        return out

    def _floor(self, zodi_e, per_sun, inverse_square, per_moon, moon_at_earth_fraction, sun_at_1au: list, bands,
               shape) -> tuple[dict, np.ndarray]:
        """A lower bound of the samples' total per band (band -> e-/s/pix, arrays of ``shape``):
        the terms computed before the skippable ones, zodi_e[band] + per_sun * (sun_at_1au[band]
        * inverse_square) + per_moon * (sun_at_1au[band] * moon_at_earth_fraction), never below
        the band's darkest zodiacal light (nor NaN); and its smallest ratio to that darkest light
        over the bands, per sample.  One compiled pass (:func:`_floor_kernel`)."""
        n = int(np.prod(shape))
        flat = [np.ascontiguousarray(np.broadcast_to(np.asarray(v, float), shape).ravel()) for v in
                (per_sun, inverse_square, per_moon, moon_at_earth_fraction)]
        darkest = np.array([self.context.darkest_zodiacal_e_per_s(name) for name in bands], float)
        floor, ratio = np.empty((len(bands), n)), np.empty(n)
        _floor_kernel(np.asarray(zodi_e, float).reshape(len(bands), n), *flat, np.asarray(sun_at_1au, float), darkest,
                      floor, ratio)
        return {name: floor[ib].reshape(shape) for ib, name in enumerate(bands)}, ratio.reshape(shape)

    def models_record(self) -> dict:
        """Which models ran and their error budget, for a product's attributes (JSON-able)."""
        sc = self.campaign.config["stars"]
        policy, tolerance = self.policy, self.policy.tolerance
        es = self.sunlit_earth.record()
        shares, lut_runs = ERROR_BUDGET_SHARES, es["method"] == "lut"
        moonlit = self.moonlit_earth
        return {"tolerance": tolerance, "earthshine": es, "pst": self.context.offfield.pst.source,
                "unobservable_samples": ("skipped: NaN in every component"
                                         if policy.unobservable_samples == "skip" else "evaluated"),
                "skip_floor": ("each sample's zodiacal light + Sun + sunlit Earth + moonlit Earth in the field "
                               "(a lower bound of its total; never below the darkest zodiacal light)"),
                "moonlit_earthshine": moonlit.record(lut_runs),
                "earthshine_near_limb": ("indicative only within the dark-limb angle of the limb and below it "
                                         "(never observable; no Earth grid converges there)"),
                "stars": {"direct_mag_limit": float(sc.get("offfield_mag_limit", 2.0)),
                          "faint_map": bool(sc.get("faint_map", True)),
                          "direct_skipped": (f"per sky cell and floor level, the stars of smallest bound, "
                                             f"together < {shares['stars_skip']:g} x tolerance x the "
                                             f"sample's floor")},
                "moon_and_planets_skipped": (f"where the bound of each is < {shares['moon_and_planets_skip']:g} / "
                                             f"{1 + len(PLANETS)} x tolerance x the sample's floor"),
                "error_budget": {"earthshine_lut_validated": es.get("lut_validation_max_rel_error")
                                 if lut_runs else 0.0,
                                 "moonlit_earthshine_skip_max": policy.moonlit_skip_share * tolerance
                                 if lut_runs else 0.0,
                                 "moonlit_earthshine_grid_share": shares["moonlit_earthshine_grid"] * tolerance
                                 if lut_runs else 0.0,
                                 "moonlit_earthshine_lut_validated": moonlit.model["lut_validation_max_rel_error"]
                                 if lut_runs and moonlit.model["method"] == "lut" else 0.0,
                                 "stars_skip_max": shares["stars_skip"] * tolerance,
                                 "moon_and_planets_skip_max": shares["moon_and_planets_skip"] * tolerance,
                                 "see": "bench/results/summary.json for the whole model against the converged "
                                        "reference, knobs.json moonlit_grid for the moonlit grid's measured error"}}


def _check_into(into, n_samples: int, n_bands: int) -> None:
    """ValueError unless ``into`` is (distinct names of :data:`BAND_COMPONENTS`, an array of
    shape (names, samples, bands))."""
    names, values = into
    unknown = sorted(set(names) - set(BAND_COMPONENTS))
    expected = (len(names), n_samples, n_bands)
    if unknown or len(set(names)) != len(names) or np.shape(values) != expected:
        raise ValueError(f"into: components {tuple(names)} (unknown: {unknown}; each at most once) in an array of "
                         f"shape {np.shape(values)}, not (components, samples, bands) = {expected}")


#: the per-band components :meth:`BackgroundModel.evaluate` returns, in e-/s/pix
BAND_COMPONENTS = ("zodiacal", "sun", "moon", "planets", "stars", "earthshine_direct", "earthshine_door",
                   "earthshine", "total")


@njit(cache=True, nogil=True)
def _floor_kernel(zodi_e, per_sun, inverse_square, per_moon, moon_at_earth_fraction, sun_at_1au, darkest, floor,
                  ratio):
    """:meth:`BackgroundModel._floor` per sample: ``floor[band, sample]`` and ``ratio[sample]``,
    the numpy expression's operations in its order (the same bits), np.fmax's rule for NaN."""
    for i in range(per_sun.shape[0]):
        smallest = np.inf
        for ib in range(sun_at_1au.shape[0]):
            s1 = sun_at_1au[ib]
            partial = (zodi_e[ib, i] + per_sun[i] * (s1 * inverse_square[i])
                       + per_moon[i] * (s1 * moon_at_earth_fraction[i]))
            f = partial if partial >= darkest[ib] else darkest[ib]  # np.fmax: NaN gives the darkest
            floor[ib, i] = f
            q = f / darkest[ib]
            if q < smallest:
                smallest = q
        ratio[i] = smallest


@njit(cache=True, nogil=True)
def _band_components_kernel(zodi_e, t_sun, inverse_square, moon_fraction, planets_fraction, direct_sun, door_sun,
                            direct_moon, door_moon, moon_at_earth_fraction, stars_e, sun_at_1au, slot, out):
    """Every band's :data:`BAND_COMPONENTS` (e-/s/pix) per sample, component ``c`` into
    ``out[slot[c], sample, band]`` (any float dtype and strides; not written where slot[c] is
    -1), from the band-independent per-sample terms and each band's solar photon irradiance
    at 1 AU; ``zodi_e`` and ``stars_e``: each band's zodiacal light and stars, (bands,
    samples).  The arithmetic is the plain per-band expression in a fixed order, so the float64
    values do not depend on batch size (the cube's totals compare bit for bit), in one pass
    over the samples instead of ~25 numpy passes a band."""
    # the components in scalars, not a scratch array: the compiler keeps them in registers
    # (stores into ``out`` could alias an array): 1.6-2x faster on a region's 47,520 x 7 samples
    s0, s1, s2, s3, s4, s5, s6, s7, s8 = (slot[0], slot[1], slot[2], slot[3], slot[4], slot[5], slot[6], slot[7],
                                          slot[8])
    for i in range(t_sun.shape[0]):
        t_s, inv_sq, m_f, p_f = t_sun[i], inverse_square[i], moon_fraction[i], planets_fraction[i]
        d_s, g_s, d_m, g_m = direct_sun[i], door_sun[i], direct_moon[i], door_moon[i]
        m_e = moon_at_earth_fraction[i]
        for ib in range(sun_at_1au.shape[0]):
            sun_1au = sun_at_1au[ib]
            sun_irr = sun_1au * inv_sq
            moon_irr_earth = sun_1au * m_e
            zodiacal = zodi_e[ib, i]
            sun = t_s * sun_irr
            moon = m_f * sun_1au
            planets = p_f * sun_1au
            stars = stars_e[ib, i]
            direct = d_s * sun_irr + d_m * moon_irr_earth
            door = g_s * sun_irr + g_m * moon_irr_earth
            earthshine = direct + door
            total = zodiacal + sun + moon + planets + stars + earthshine
            # BAND_COMPONENTS' order
            if s0 >= 0:
                out[s0, i, ib] = zodiacal
            if s1 >= 0:
                out[s1, i, ib] = sun
            if s2 >= 0:
                out[s2, i, ib] = moon
            if s3 >= 0:
                out[s3, i, ib] = planets
            if s4 >= 0:
                out[s4, i, ib] = stars
            if s5 >= 0:
                out[s5, i, ib] = direct
            if s6 >= 0:
                out[s6, i, ib] = door
            if s7 >= 0:
                out[s7, i, ib] = earthshine
            if s8 >= 0:
                out[s8, i, ib] = total
