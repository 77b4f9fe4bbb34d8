"""The computation of one region of the background cube: every component in every band, and the
observability, at a time block's times x a pixel block's lines of sight.

:func:`region_values` computes a region as numpy arrays (what a worker writes),
:func:`compute_region` as a Dataset.  The steps of a region are evaluated together, as flat
batches of samples (:func:`_step_batches`); with ``models.unobservable_samples: skip`` only the
observable samples are evaluated (:func:`_evaluate_observable`).  The faint stars' map depends on
the line of sight only, so the cube computes it once for the whole footprint
(:func:`faint_star_map`) and every region reads its pixels.

The model and the off-field stars are built by the caller, once for many regions
(:class:`straylight.cube.executors.WorkerState` keeps them in a worker).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from straylight.cube import layout as cube_layout
from straylight.cube.layout import OBSERVABILITY_ANGLES
from straylight.model import registry
from straylight.model.pointing import background_at
from straylight.sky.runs import SceneRuns
from straylight.sky.vectors import radec_to_unit

if TYPE_CHECKING:  # xarray where a Dataset is made: a worker computing regions does without it
    import xarray as xr

    from straylight.config import Campaign
    from straylight.cube.footprint import Footprint

__all__ = ["SAMPLES_PER_EVALUATION", "compute_region", "faint_star_map", "offfield_stars", "region_values"]

#: samples per evaluation on the table path (whole time steps of a pixel block): large enough
#: that numpy's per-call cost is paid rarely, a default production region in one call, small
#: enough to bound the batch's temporaries (figures: docs/performance.md)
SAMPLES_PER_EVALUATION = 131072


def offfield_stars(campaign: Campaign, stars_path):
    """The catalog's off-field stars at ``stars_path`` (brighter than stars.offfield_mag_limit,
    and the fainter ones for the faint map when ``stars.faint_map``), in the campaign's bands;
    None without a catalog.

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign (its ``stars`` settings and bands).
    stars_path : str or path-like or None
        Star table (``ra``, ``dec`` in deg, ``mag_<band>`` in AB mag); None: no catalog.

    Returns
    -------
    straylight.sources.stars_table.StarTable or None
        The off-field stars (bright ones, and the faint ones for the faint map), or None.
    """
    if stars_path is None:
        return None
    from straylight.sources.stars_table import load_offfield_stars

    limit = float(campaign.settings.stars.offfield_mag_limit)
    faint = campaign.settings.stars.faint_map
    return load_offfield_stars(stars_path, campaign.bands, limit, faint)


def compute_region(
    campaign: Campaign,
    fp: Footprint,
    t_slice: slice,
    p_slice: slice,
    model=None,
    stars=None,
    faint_map=None,
    scene=None,
    angles: dict | None = None,
) -> xr.Dataset:
    """Compute the cube values of times t_slice x pixels p_slice (numpy-backed Dataset);
    ``model``: the campaign's BackgroundModel (None: built here); ``stars``: the off-field stars
    (:func:`offfield_stars`; None: stars = 0); ``faint_map``: the faint stars' map at these
    pixels, (pixel, band) e-/s/pix, as :func:`faint_star_map` gives it (None: computed here);
    ``scene``: the satellite's and the bodies' positions at these times
    (:func:`straylight.sky.observing.scene`), when already computed for another pixel block of
    the same times (None: computed here); ``angles``: a dict that receives the samples' other
    observability angles (:data:`~straylight.cube.layout.OBSERVABILITY_ANGLES`, (time,
    pixel) float32 deg, the geometry the cube computes anyway; None: not kept).  ValueError if
    ``scene`` is not at exactly these times.

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign (times, orbit, bands, models).
    fp : Footprint
        The survey footprint.
    t_slice, p_slice : slice
        The region: indices into ``campaign.times`` (n_time of them) and into the footprint's
        pixels (n_pixel).
    model : BackgroundModel, optional
        The campaign's model; None: built here.
    stars : straylight.sources.stars_table.StarTable, optional
        Off-field stars; None: the stars component is 0.
    faint_map : array_like, shape (n_pixel, n_band), optional
        The faint stars' map at these pixels, e-/s/pix; None: computed here (if ``stars``).
    scene : straylight.sky.observing.Scene, optional
        Satellite and body positions at exactly these times; None: computed here.
    angles : dict, optional
        If given, filled with the :data:`~straylight.cube.layout.OBSERVABILITY_ANGLES`
        arrays, float32 deg, shape (n_time, n_pixel).

    Returns
    -------
    xarray.Dataset
        Numpy-backed, no coordinates: each component and ``total`` (time, pixel, band) float32
        e-/s/pix; ``observable`` (time, pixel) bool; ``violations`` (time, pixel) uint8 bit mask
        of the violated constraints; ``door_opening_deg`` (time, pixel) float32 deg.

    Raises
    ------
    ValueError
        When ``scene`` is not at exactly the region's times.
    """
    import xarray as xr

    if model is None:
        from straylight.model import BackgroundModel

        model = BackgroundModel(campaign)
    values = region_values(campaign, fp, t_slice, p_slice, model, stars, faint_map, scene, angles)
    return xr.Dataset(
        {name: (_dims(name), v) for name, v in values.items() if not cube_layout.is_envelope_end_part(name)}
    )


def _dims(name: str) -> tuple:
    """A cube variable's dims: (time, pixel, band) for the components and the total, else
    (time, pixel)."""
    band_vars = registry.component_names(total=True) + cube_layout.CUBE_PART_VARIABLES
    return ("time", "pixel", "band") if name in band_vars else ("time", "pixel")


def region_values(
    campaign: Campaign,
    fp: Footprint,
    t_slice: slice,
    p_slice: slice,
    model,
    stars=None,
    faint_map=None,
    scene=None,
    angles: dict | None = None,
) -> dict:
    """:func:`compute_region`'s variables as numpy arrays (name -> (time, pixel[, band]) array),
    without the Dataset: what a worker writes.  ``model`` is required here.

    Parameters
    ----------
    campaign, fp, t_slice, p_slice, stars, faint_map, scene, angles
        As :func:`compute_region`.
    model : BackgroundModel
        The campaign's model (required).

    Returns
    -------
    dict of str to ndarray
        Each component (:func:`~straylight.model.registry.component_names`), ``total`` and
        each part of :data:`~straylight.cube.layout.CUBE_PART_VARIABLES`
        (NaN where not observable) and of
        :data:`~straylight.cube.layout.ENVELOPE_END_VARIABLES` (the envelope's
        re-evaluated ends, for the region's limits; not stored): float32, shape (n_time,
        n_pixel, n_band), e-/s/pix (views into one block);
        ``observable``: bool, (n_time, n_pixel); ``violations``: uint8 bit mask,
        (n_time, n_pixel); ``door_opening_deg``: float32 deg, (n_time, n_pixel).

    Raises
    ------
    ValueError
        When ``scene`` is not at exactly the region's times.
    """
    from straylight.model import unobservable_samples
    from straylight.sky import observing

    times = campaign.times[t_slice]
    sc = observing.scene(campaign.orbit, times) if scene is None else _checked_scene(scene, times)
    los = radec_to_unit(fp.ra_deg[p_slice], fp.dec_deg[p_slice])
    nt, npix, nb = len(times), los.shape[0], len(campaign.bands)
    faint = _faint_by_pixel(model, campaign, stars, faint_map, los)
    names, n_model, block = _region_block(nt, npix, nb)
    out = dict(zip(names, block))
    obs = np.zeros((nt, npix), bool)
    viol = np.zeros((nt, npix), np.uint8)
    door = np.zeros((nt, npix), np.float32)
    if angles is not None:
        angles.update({k: np.zeros((nt, npix), np.float32) for k in OBSERVABILITY_ANGLES})
    # Steps are evaluated together, as one flat batch of samples: numpy's per-call cost is then
    # paid once per batch, not once per step.  The direct earthshine sum grids the Earth per
    # sample, so there one step per call bounds its memory (the star pairs bound their own:
    # OffFieldStars.STAR_PAIRS_PER_PASS).
    max_samples = SAMPLES_PER_EVALUATION if model.uses_sunlit_table else npix
    skip_unobservable = unobservable_samples(campaign) == "skip"  # the campaign's, not the model's
    for steps in _step_batches(nt, npix, max_samples):
        k = steps.stop - steps.start
        los_k = np.broadcast_to(los[None], (k,) + los.shape).reshape(-1, 3)
        # written straight into the region's float32 block: a view (the steps are consecutive,
        # so step and pixel merge into the batch's step-major samples)
        # (the envelope's re-evaluated groups, last, are not the model's: _envelope_ends fills them)
        into = (names[:n_model], block[:n_model, steps].reshape(n_model, k * npix, nb))
        g = _evaluate_steps(model, sc, steps, los_k, campaign.bands, (stars, faint), into, skip_unobservable)
        obs[steps], viol[steps], door[steps] = (
            _by_step(g[v], k, npix) for v in ("observable", "violations", "door_opening_deg")
        )
        _envelope_ends(model, campaign, sc, steps, los_k, g, out, k, npix)
        if angles is not None:
            for name in OBSERVABILITY_ANGLES:
                angles[name][steps] = _by_step(g[name], k, npix)
    _mask_parts(model, campaign, out, obs)
    return {**out, "observable": obs, "violations": viol, "door_opening_deg": door}


def _evaluate_steps(
    model, sc, steps: slice, los_k: np.ndarray, bands, stars: tuple, into: tuple, skip: bool
) -> dict:
    """The background at the time ``steps`` of scene ``sc`` x the region's pixels (``los_k``:
    their lines of sight repeated per step) in ``bands``, written ``into`` (names, block view);
    ``stars``: (the off-field stars, the faint map per pixel or None); ``skip``: the observable
    samples only.  Returns the samples' observing geometry."""
    k = steps.stop - steps.start
    npix = los_k.shape[0] // k
    stars, faint = stars
    # each step's scene repeated over its pixels: the samples' scene runs are the steps,
    # known here, so no function scans every sample's vectors to find them again
    g, _ = background_at(
        model,
        sc.satellite_km[steps],
        {b: v[steps] for b, v in sc.bodies_km.items()},
        los_k,
        bands,
        scene_index=np.repeat(np.arange(k), npix),
        stars=stars,
        faint_rates=None if faint is None else {b: np.tile(v, k) for b, v in faint.items()},
        runs=SceneRuns.steps(k, npix),
        into=into,
        observable_only=skip,
    )
    return g


def _faint_by_pixel(model, campaign: Campaign, stars, faint_map, los: np.ndarray) -> dict | None:
    """The faint stars' map at the region's pixels, band -> e-/s/pix (n_pixel,): ``faint_map``'s
    columns, else summed here (once per pixel, not per sample of a many-step batch: it depends on
    the line of sight only); None without faint stars."""
    if faint_map is not None:
        return {b: np.asarray(faint_map)[:, i] for i, b in enumerate(campaign.bands)}
    if stars is not None and len(stars.faint_ra_deg):
        return model.source("stars").faint_star_rates(stars, los, campaign.bands)
    return None


def _region_block(nt: int, npix: int, nb: int) -> tuple:
    """(the names of the region's float32 variables, how many the model writes, one zeroed block
    (names, time, pixel, band) for all): the components, the total, the parts the envelope
    scales apart (CUBE_PART_VARIABLES) and its re-evaluated ends, last.  One allocation: numpy
    asks the kernel for huge pages on arrays of 4 MiB or more (a default region's block is),
    fewer page faults than one array per component."""
    names = (
        registry.component_names(total=True)
        + cube_layout.CUBE_PART_VARIABLES
        + cube_layout.ENVELOPE_END_VARIABLES
    )
    n_model = len(names) - sum(cube_layout.is_envelope_end_part(n) for n in names)
    return names, n_model, np.zeros((len(names), nt, npix, nb), np.float32)


def _mask_parts(model, campaign: Campaign, out: dict, obs: np.ndarray) -> None:
    """The parts the envelope scales apart, needed where observable only: NaN elsewhere, which
    the store compresses to almost nothing (the components stay everywhere); NaN everywhere for
    the re-evaluated ends without the instrument's ``envelope.members``."""
    ends = bool(_end_models(model, campaign))
    for name in cube_layout.CUBE_PART_VARIABLES + cube_layout.ENVELOPE_END_VARIABLES:
        if cube_layout.is_envelope_end_part(name) and not ends:  # nothing re-evaluated
            out[name][...] = np.nan
        else:
            out[name][~obs] = np.nan


def _end_models(model, campaign) -> dict:
    """The models at the assumption envelope's re-evaluated ends (end -> BackgroundModel;
    {} without the instrument's ``envelope.members``), built once per model."""
    cache = model.__dict__.get("_envelope_end_models")
    if cache is None:
        from straylight.model import BackgroundModel
        from straylight.model.envelope import ENDS, end_campaign

        env = campaign.instrument_settings.envelope
        cache = {}
        if env is not None and env.members is not None:
            cache = {
                e: BackgroundModel(end_campaign(campaign, e), build_workers=model.build_workers) for e in ENDS
            }
        model.__dict__["_envelope_end_models"] = cache
    return cache


def _envelope_ends(model, campaign, sc, steps, los_k, g, out, k, npix) -> None:
    """The parts the envelope's members change, re-evaluated at each end at a batch's observable
    samples, into ``out``'s ``<part>_<end>`` variables (NaN elsewhere)."""
    from straylight.model.envelope import end_part_name, end_parts

    models = _end_models(model, campaign)
    sel = np.flatnonzero(np.asarray(g["observable"], bool))
    if not models or not sel.size:
        return
    scene_of = np.repeat(np.arange(k), npix)[sel]
    sat = np.take(sc.satellite_km[steps], scene_of, axis=0)
    # the Sun and the Moon only: the planets and the stars are not among the members' parts
    bodies = {b: np.take(sc.bodies_km[b][steps], scene_of, axis=0) for b in ("sun", "moon")}
    geom = {name: np.asarray(v)[sel] for name, v in g.items() if np.shape(v)[:1] == (k * npix,)}
    los = np.take(los_k, sel, axis=0)
    for end, end_model in models.items():
        for group, v in end_parts(end_model, sat, bodies, los, geom, campaign.bands).items():
            name = end_part_name(group, end)
            if name in out:
                out[name][steps].reshape(k * npix, -1)[sel] = v


def _checked_scene(sc, times):
    """``sc`` if it is at exactly ``times`` (the same UTC Julian dates), else ValueError: a
    scene from other times would put every body in the wrong place without a sign."""
    t = sc.times
    same = (
        len(t) == len(times)
        and np.array_equal(t.utc.jd1, times.utc.jd1)
        and np.array_equal(t.utc.jd2, times.utc.jd2)
    )
    if not same:
        raise ValueError(
            f"scene at {len(t)} times ({t[0].isot if len(t) else '-'} ...) is not at the "
            f"region's {len(times)} times ({times[0].isot if len(times) else '-'} ...)"
        )
    return sc


def _step_batches(n_steps: int, n_pixels: int, max_samples: int) -> list[slice]:
    """The time steps of one evaluation each: as few as keep each within ``max_samples``
    samples (at least one step), sized within one step of each other, so no call is a small
    remainder paying the per-call cost for a few steps (72 steps of 1024 pixels within 65,536:
    two calls of 36, not 64 and 8)."""
    steps_max = max(1, max_samples // max(n_pixels, 1))
    n_calls = -(-n_steps // steps_max)
    bounds = [n_steps * i // n_calls for i in range(n_calls + 1)] if n_calls else [0]
    return [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:])]


def _by_step(values, k: int, npix: int) -> np.ndarray:
    """A batch's k * npix samples (step-major) as (k, npix)."""
    return np.broadcast_to(values, (k * npix,)).reshape(k, npix)


def _faint_rows(campaign: Campaign, fp: Footprint, model, stars, rows: slice) -> np.ndarray:
    """The faint-star map at footprint pixels ``rows``, (pixel, band) e-/s/pix (0 in a band
    the catalog has no faint magnitudes in)."""
    los = radec_to_unit(fp.ra_deg[rows], fp.dec_deg[rows])
    rates = model.source("stars").faint_star_rates(stars, los, campaign.bands, saved=True)
    values = np.zeros((los.shape[0], len(campaign.bands)))
    for i, band in enumerate(campaign.bands):
        if band in rates:
            values[:, i] = rates[band]
    return values


def _faint_rows_in_process(campaign: Campaign, fp: Footprint, stars_path: str, rows: slice) -> np.ndarray:
    """:func:`_faint_rows` in a spawned process of :func:`faint_star_map`, which builds its own
    model and loads the catalog."""
    from straylight.model import BackgroundModel

    return _faint_rows(campaign, fp, BackgroundModel(campaign), offfield_stars(campaign, stars_path), rows)


def faint_star_map(
    campaign: Campaign, fp: Footprint, stars_path, workers: int = 1, before=None, model=None, stars=None
) -> xr.Variable | None:
    """The faint stars' smoothed map at every footprint pixel, (pixel, band), e-/s/pix: it
    depends on the line of sight only, so the cube computes it once (in
    :func:`~straylight.cube.store.init_store`) and every time block reads it.  None
    without a catalog or with no faint stars.

    ``workers`` processes share the pixels (this one and ``workers`` - 1 spawned ones, each
    loading the catalog and the model once): the same values as one process (each pixel's sum
    is computed on its own).  ``before``: a callable run in this process while the spawned ones
    start (the skeleton's other work); its result is returned with the map as a pair then.
    ``model``, ``stars``: this process's BackgroundModel (built with ``workers`` for an
    earthshine table it may build later) and the catalog's off-field stars, when the caller has
    them (None: made here).

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign.
    fp : Footprint
        The survey footprint (n_pixel pixels).
    stars_path : str or path-like or None
        Star table; None: no catalog (the map is None).  Spawned processes load it again.
    workers : int, optional
        Processes sharing the pixels (this one included).
    before : callable, optional
        Run with no arguments in this process while the spawned ones start; None: nothing.
    model : BackgroundModel, optional
        This process's model; None: built here.
    stars : straylight.sources.stars_table.StarTable, optional
        The catalog's off-field stars; None: loaded from ``stars_path``.

    Returns
    -------
    xarray.Variable or None, or tuple
        The map, dims (pixel, band), shape (n_pixel, n_band), float64, e-/s/pix, with its
        ``units`` and ``long_name``; None without a catalog or faint stars.  With ``before``:
        the pair (map or None, ``before()``'s result).
    """
    import xarray as xr

    stars = offfield_stars(campaign, stars_path) if stars is None else stars
    if stars is None or not len(stars.faint_ra_deg):
        return None if before is None else (None, before())
    if model is None:
        from straylight.model import BackgroundModel

        model = BackgroundModel(campaign, build_workers=workers)
    edges = np.linspace(0, fp.pixels.size, max(1, min(int(workers), fp.pixels.size)) + 1).round().astype(int)
    parts = [slice(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]

    def saved(rows):  # this part's sums kept on disk (read instead of summed)
        return model.source("stars").faint_star_map_saved(
            stars, radec_to_unit(fp.ra_deg[rows], fp.dec_deg[rows]), campaign.bands
        )

    if len(parts) == 1 or all(saved(rows) for rows in parts):
        # one process, or every part's sums kept on disk (read here: no process to start)
        other = None if before is None else before()
        values = np.concatenate([_faint_rows(campaign, fp, model, stars, rows) for rows in parts])
    else:
        from straylight.execution import spawned_pool

        with spawned_pool(len(parts) - 1) as pool:
            futures = [
                pool.submit(_faint_rows_in_process, campaign, fp, str(stars_path), rows) for rows in parts[1:]
            ]
            other = None if before is None else before()
            values = np.concatenate(
                [_faint_rows(campaign, fp, model, stars, parts[0])] + [f.result() for f in futures]
            )
    long_name = "faint off-field stars: smoothed map (azimuth-averaged PST), part of stars"
    var = xr.Variable(("pixel", "band"), values, {"units": "electron / (s pixel)", "long_name": long_name})
    return var if before is None else (var, other)
