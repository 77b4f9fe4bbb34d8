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
from straylight.model.fidelity import ERROR_BUDGET_SHARES, FidelityPolicy
from straylight.sky.ephemeris import PLANETS
from straylight.sky.frames import telescope_frame
from straylight.sources.bodies import InFieldBodies, SolarBodySkip
from straylight.sources.context import Samples, SourceContext
from straylight.sources.photometry import magnitude_per_arcsec2
from straylight.sources.rates import LAMPS
from straylight.sources.stars_table import StarTable
from straylight.sources.zodiacal import campaign_zodiacal_model
from straylight.util.kernel_cache import njit

__all__ = ["BackgroundModel", "KERNEL_BLOCK_SAMPLES"]


class BackgroundModel:
    """The background of one campaign: its sources of light (built from
    :data:`~straylight.model.registry.SOURCES`, ``sources[name]``, each also an attribute:
    ``model.stars``) and its fidelity policy.

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

    def __getattr__(self, name):
        sources = self.__dict__.get("sources")
        if sources is not None and name in sources:
            return sources[name]
        raise AttributeError(f"{type(self).__name__!r} has no attribute or source {name!r}")

    def evaluate(
        self,
        satellite_km,
        bodies_km,
        los,
        geometry,
        bands,
        stars: StarTable | None = None,
        faint_rates: dict | None = None,
        frame=None,
        into: tuple | None = None,
        runs=None,
    ) -> dict:
        """Every source's e-/s/pix in each band, added into the components and their total.

        Parameters
        ----------
        satellite_km : array_like, shape (..., 3)
            Geocentric ICRS satellite positions, km (broadcastable to the samples).
        bodies_km : dict of str to array_like
            Body -> geocentric ICRS position (..., 3), km: at least the Sun and the Moon; each
            planet in it is a source where it can count
            (:class:`~straylight.sources.planets.Planets`).
        los : array_like, shape (..., 3)
            Unit lines of sight, ICRS.
        geometry : dict
            :func:`~straylight.sky.observing.observing_geometry`'s (the Sun's, the Moon's and
            the limb's entries are read); its ``sun_angle_deg`` gives the samples' shape.
        bands : sequence of str
            Band names.
        stars : StarTable or None
            The off-field stars (None: stars = 0).
        faint_rates : dict or None
            The faint stars' map at these lines of sight, band -> e-/s/pix (as
            :meth:`~straylight.sources.stars.OffFieldStars.faint_star_rates` gives it), when
            already computed.
        frame : TelescopeFrame or None
            The samples' ``telescope_frame(los, sun - satellite)``, when already computed.
        into : (sequence of str, ndarray) or None
            (component names, array (names, samples flattened, bands)), e.g. a cube region's
            float32 block, that receives those components (the result's arrays are then views
            of it, and the other components are not computed).
        runs : SceneRuns or None
            The samples' scene runs when the caller knows them (e.g. a cube's time steps: runs
            of samples that share the satellite and every body in ``bodies_km``), else found
            where needed.

        Returns
        -------
        dict
            Band -> {component: e-/s/pix, float64 array of the samples' shape, for every name
            of :func:`~straylight.model.registry.band_components` (or those of ``into``); and
            ``_band`` (the Band), ``_mag`` (e-/s/pix -> AB mag/arcsec2) and ``_<flag>`` for each
            flag a source reports (``_zodiacal_no_data``)}.

        Raises
        ------
        ValueError
            For an unknown name in ``into`` or an array of another shape.
        """
        c = self.context
        sat = np.asarray(satellite_km, float)
        sun = bodies_km["sun"]
        frame = telescope_frame(los, sun - sat) if frame is None else frame
        shape = geometry["sun_angle_deg"].shape
        n = int(np.prod(shape))
        outputs = self.outputs
        if into is not None:  # checked before any work
            _check_into(into, n, len(bands), outputs)
        samples = Samples(sat, bodies_km, frame, geometry, runs, stars=stars, faint_rates=faint_rates)
        samples.moon_lamp = self.source("moon").lamp(samples)
        scales = {
            "sun": samples.sun_inverse_square,
            "sun_at_1au": 1.0,
            "moon_at_earth": samples.moon_lamp["at_earth"],
        }
        sun_at_1au = np.array([c.photometry(name).sun_at_1au_photons_s_m2 for name in bands])
        rates = {}
        # the sources never skipped make each sample's floor, which the skippable ones measure
        # their skips against
        for entry in self.entries:
            if not entry.skippable:
                rates[entry.name] = self.sources[entry.name].rates(samples, bands)
        samples.floor, samples.floor_ratio = self._floor(
            [rates[e.name] for e in self.entries if not e.skippable], scales, sun_at_1au, bands, shape
        )
        for entry in self.entries:
            if entry.skippable:
                rates[entry.name] = self.sources[entry.name].rates(samples, bands)
        terms = _Terms(self.entries, self.leaves, rates, scales, shape)
        names, values = (
            into
            if into is not None
            else (outputs, np.empty((len(outputs), len(bands), n)).transpose(0, 2, 1))
        )  # band-major: each band's row contiguous
        sums, writes, n_rows = _sum_program(self.components, self.leaves, names)
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
        extras = {f"_{k}": v for r in rates.values() for k, v in r.extras.items()}
        aperture_d = self.campaign.instrument_settings.telescope.aperture_diameter_m.value
        pix_arcsec = self.campaign.pixel_scale_arcsec
        out = {}
        for ib, name in enumerate(bands):
            band = c.band(name)
            res = {comp: values[k, :, ib].reshape(shape) for k, comp in enumerate(names)}
            res["_band"] = band
            res.update(extras)
            res["_mag"] = lambda e, b=band: magnitude_per_arcsec2(e, b, aperture_d, pix_arcsec)
            out[name] = res
        return out

    def _floor(
        self, never_skipped: list, scales: dict, sun_at_1au: np.ndarray, bands, shape
    ) -> tuple[dict, np.ndarray]:
        """A lower bound of the samples' total per band (band -> e-/s/pix, arrays of ``shape``):
        the sources never skipped, their per-band terms added, then for each lamp the sum of
        their coefficients times the lamp's irradiance, never below the band's darkest zodiacal
        light (nor NaN); and its smallest ratio to that darkest light over the bands, per
        sample.  One compiled pass (:func:`_floor_kernel`)."""
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
        es = self.sunlit_earth.record()
        shares, lut_runs = ERROR_BUDGET_SHARES, es["method"] == "lut"
        moonlit = self.moonlit_earth
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


def _sum_program(components: tuple, leaves: tuple, names) -> tuple:
    """The band kernel's rows after the leaves (rows 0..len(leaves)-1): each component with
    parts gets a row, the total one; a component without parts is its leaf's row.  Returns
    (sums (k, 3): src row, dst row, whether it sets dst; writes (k, 2): row, index in
    ``names``, for the names asked; the number of rows)."""
    rows, sums, n_rows = {leaf: i for i, leaf in enumerate(leaves)}, [], len(leaves)
    for c in components:
        if c.parts:
            rows[c.name] = n_rows
            sums += [(rows[p], n_rows, k == 0) for k, (p, _) in enumerate(c.parts)]
            n_rows += 1
    rows[registry.TOTAL] = n_rows
    sums += [(rows[c.name], n_rows, k == 0) for k, c in enumerate(components)]
    writes = [(rows[name], k) for k, name in enumerate(names)]
    return (np.array(sums, np.intp).reshape(-1, 3), np.array(writes, np.intp).reshape(-1, 2), n_rows + 1)


def _rows(arrays: list, shape: tuple) -> tuple:
    """The arrays as a tuple for a compiled kernel: each float64, C-contiguous, writable, of
    ``shape`` (broadcast, and copied only where it is not so already); an empty list gives one
    zero array (the kernels take the count apart)."""
    out = []
    for a in arrays:
        a = np.asarray(a, float)
        if not (a.shape == tuple(shape) and a.flags.c_contiguous and a.flags.writeable):
            a = np.ascontiguousarray(np.broadcast_to(a, shape))
            a = a if a.flags.writeable else a.copy()
        out.append(a)
    return tuple(out) if out else (np.zeros(shape),)


def _flat(a, shape: tuple) -> np.ndarray:
    """``a`` broadcast to the samples' ``shape`` and flattened (a view where it can be)."""
    a = np.asarray(a, float)
    return a.reshape(-1) if a.shape == tuple(shape) else np.broadcast_to(a, shape).reshape(-1)


class _Terms:
    """The sources' rates as the band kernel's arrays: the per-band terms, a tuple of (bands,
    samples) arrays, and the per-lamp coefficients, a tuple of (samples,) arrays (views of the
    sources' arrays where they can be), each with the leaf (component or
    part) it adds to and whether it is that leaf's first term (which sets it; the others add,
    per-band terms before per-lamp ones, lamps in :data:`LAMPS` order).  Coefficients of several
    sources for one leaf and lamp are added first, in registry order."""

    def __init__(self, entries, leaves: tuple, rates: dict, scales: dict, shape):
        n = int(np.prod(shape))
        dense, dense_leaf = [], []
        lamp_coeff = {}  # (leaf, lamp) -> coefficient
        factors = {}  # leaf -> its per-band factor on its lamp terms
        for entry in entries:
            r = rates[entry.name]
            for part, values in r.per_band.items():
                dense.append(values)
                dense_leaf.append(leaves.index(part))
            for part, f in r.band_factors.items():
                f = np.asarray(f, float)
                if part in factors and not np.array_equal(factors[part], f):
                    raise ValueError(f"sources give {part!r} different band factors: {factors[part]}, {f}")
                factors[part] = f
            for part, by_lamp in r.per_lamp.items():
                for lamp, coeff in by_lamp.items():
                    key = (part, lamp)
                    lamp_coeff[key] = coeff if key not in lamp_coeff else lamp_coeff[key] + coeff
        keys = sorted(lamp_coeff, key=lambda k: (leaves.index(k[0]), LAMPS.index(k[1])))
        lamps = [lamp for lamp in LAMPS if any(k[1] == lamp for k in keys)]
        nb = dense[0].shape[0] if dense else 0
        self.dense = _rows([np.asarray(d, float).reshape(nb, n) for d in dense], (nb, n))
        self.n_dense = len(dense)
        self.dense_leaf = np.array(dense_leaf, np.intp)
        seen = set()
        self.dense_first = np.array([not (leaf in seen or seen.add(leaf)) for leaf in dense_leaf], np.bool_)
        self.coeff = _rows([_flat(lamp_coeff[k], shape) for k in keys], (n,))
        self.n_coeff = len(keys)
        self.term_leaf = np.array([leaves.index(k[0]) for k in keys], np.intp)
        self.term_lamp = np.array([lamps.index(k[1]) for k in keys], np.intp)
        self.term_first = np.array(
            [not (leaf in seen or seen.add(leaf)) for leaf in self.term_leaf.tolist()], np.bool_
        )
        self.scales = _rows([_flat(scales[lamp], shape) for lamp in lamps], (n,))
        self.factors = [factors.get(k[0]) for k in keys]


def _irradiance(sun_at_1au, factors: list) -> np.ndarray:
    """(terms, bands) photon irradiance per unit lamp scale of each lamp term: the band's solar
    irradiance at 1 AU times the term's per-band factor (None: 1; the product is then the
    irradiance itself, bit for bit); one row of the irradiance when there is no term."""
    s1 = np.asarray(sun_at_1au, float)
    rows = [s1 if f is None else s1 * np.asarray(f, float) for f in factors] or [s1]
    return np.ascontiguousarray(np.stack(rows))


def _check_into(into, n_samples: int, n_bands: int, outputs: tuple) -> None:
    """ValueError unless ``into`` is (distinct names of ``outputs``, an array of shape (names,
    samples, bands))."""
    names, values = into
    unknown = sorted(set(names) - set(outputs))
    expected = (len(names), n_samples, n_bands)
    if unknown or len(set(names)) != len(names) or np.shape(values) != expected:
        raise ValueError(
            f"into: components {tuple(names)} (unknown: {unknown}; each at most once) in an array of "
            f"shape {np.shape(values)}, not (components, samples, bands) = {expected}"
        )


@njit(cache=True, nogil=True)
def _floor_kernel(dense, n_dense, coeff, n_coeff, scale, irradiance, darkest, floor, ratio):
    """:meth:`BackgroundModel._floor` per sample: ``floor[band, sample]`` and ``ratio[sample]``:
    the per-band terms added in order, then each lamp term's summed coefficient times its
    irradiance in the band (``irradiance[term, band]``: the solar irradiance at 1 AU times the
    term's band factor) times the lamp's scale, np.fmax's rule for NaN against ``darkest``.
    Each band's row is built a term at a time (1-D loops the compiler vectorizes)."""
    n, nb = floor.shape[1], floor.shape[0]
    for ib in range(nb):
        row = floor[ib]
        for k in range(n_dense):
            src = dense[k][ib]
            if k == 0:
                for i in range(n):
                    row[i] = src[i]
            else:
                for i in range(n):
                    row[i] += src[i]
        for k in range(n_coeff):
            c, sc, s1 = coeff[k], scale[k], irradiance[k, ib]
            if k == 0 and n_dense == 0:
                for i in range(n):
                    row[i] = c[i] * (s1 * sc[i])
            else:
                for i in range(n):
                    row[i] += c[i] * (s1 * sc[i])
        if n_dense == 0 and n_coeff == 0:
            row[:] = 0.0
        d = darkest[ib]
        for i in range(n):
            f = row[i] if row[i] >= d else d  # np.fmax: NaN gives the darkest
            row[i] = f
    for i in range(n):
        smallest = np.inf
        for ib in range(nb):
            q = floor[ib, i] / darkest[ib]
            if q < smallest:
                smallest = q
        ratio[i] = smallest


#: samples per block of :func:`_band_components_kernel`: its scratch (values x bands x block
#: float64) stays in the processor's cache while each term runs over the block in a simple loop
KERNEL_BLOCK_SAMPLES = 256


@njit(cache=True, nogil=True)
def _band_components_kernel(
    dense,
    n_dense,
    dense_row,
    dense_first,
    coeff,
    n_coeff,
    term_row,
    term_lamp,
    term_first,
    scales,
    irradiance,
    sums,
    writes,
    n_rows,
    out,
):
    """Every band's components (e-/s/pix) per sample.

    Rows of values per band and sample: a row (a leaf: a component's part, or a component
    without parts) is its per-band terms (the first ``n_dense`` of the tuple ``dense`` of (bands,
    samples) arrays, to row ``dense_row``) then its lamp terms (``coeff[k][sample] *
    (irradiance[k, band] * scales[term_lamp[k]][sample])``, the first ``n_coeff``, to
    ``term_row``; ``irradiance``: the band's solar irradiance at 1 AU times the term's band
    factor),
    the first setting it; then ``sums``
    (src, dst, first) add rows into others in order (parts into their component, components
    into the total), and ``writes`` (row, slot) copy row into ``out[slot, sample, band]`` (any
    float dtype and strides).  Each sample's arithmetic is fixed, so the float64 values do not
    depend on batch size; the samples run in blocks of :data:`KERNEL_BLOCK_SAMPLES`, each term
    over a whole block at a time (1-D views in the inner loops: the compiler vectorizes them)."""
    n, nb = out.shape[1], out.shape[2]
    blk = KERNEL_BLOCK_SAMPLES
    buf = np.zeros((n_rows, nb, blk))  # a row no term reaches stays 0
    for i0 in range(0, n, blk):
        m = min(blk, n - i0)
        for k in range(n_dense):
            for ib in range(nb):
                src, row = dense[k][ib, i0 : i0 + m], buf[dense_row[k], ib]
                if dense_first[k]:
                    for j in range(m):
                        row[j] = src[j]
                else:
                    for j in range(m):
                        row[j] += src[j]
        for k in range(n_coeff):
            c, scale = coeff[k][i0 : i0 + m], scales[term_lamp[k]][i0 : i0 + m]
            for ib in range(nb):
                s1, row = irradiance[k, ib], buf[term_row[k], ib]
                if term_first[k]:
                    for j in range(m):
                        row[j] = c[j] * (s1 * scale[j])
                else:
                    for j in range(m):
                        row[j] += c[j] * (s1 * scale[j])
        for k in range(sums.shape[0]):
            for ib in range(nb):
                src, row = buf[sums[k, 0], ib], buf[sums[k, 1], ib]
                if sums[k, 2]:
                    for j in range(m):
                        row[j] = src[j]
                else:
                    for j in range(m):
                        row[j] += src[j]
        for k in range(writes.shape[0]):
            dst = out[writes[k, 1], i0 : i0 + m]
            for ib in range(nb):
                src = buf[writes[k, 0], ib]
                for j in range(m):
                    dst[j, ib] = src[j]
