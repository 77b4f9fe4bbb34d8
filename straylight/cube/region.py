"""The computation of one region of the background cube: every component in every band, and the
observability, at a time block's times x a pixel block's lines of sight.

:func:`region_values` computes a region as numpy arrays (what a worker writes),
:func:`compute_region` as a Dataset.  The steps of a region are evaluated together, as flat
batches of samples (:func:`_step_batches`, each a
:class:`~straylight.model.samples.SampleBatch`); with ``models.unobservable_samples: skip`` only
the observable samples are evaluated (:func:`~straylight.model.pointing.background_at`).  The
faint stars' map depends on the line of sight only, so the cube computes it once for the whole
footprint (:func:`faint_star_map`) and every region reads its pixels.

The model and the off-field stars are built by the caller, once for many regions
(:class:`straylight.cube.executors.WorkerState` keeps them in a worker).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from straylight.cube import layout as cube_layout
from straylight.cube.layout import OBSERVABILITY_ANGLES
from straylight.model import registry
from straylight.model.pointing import background_at, sample_geometry
from straylight.model.samples import SampleBatch
from straylight.sky.observing import Scene
from straylight.sky.runs import SceneRuns
from straylight.sky.vectors import radec_to_unit

if TYPE_CHECKING:  # xarray where a Dataset is made: a worker computing regions does without it
    import xarray as xr

    from straylight.config import Campaign
    from straylight.cube.footprint import Footprint

__all__ = [
    "SAMPLES_PER_EVALUATION",
    "RegionInputs",
    "compute_region",
    "envelope_end_values",
    "faint_star_map",
    "offfield_stars",
    "region_values",
]

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


@dataclass(frozen=True)
class RegionInputs:
    """What the caller of :func:`region_values` may already hold, computed once for many
    regions: ``stars``, the off-field stars (:func:`offfield_stars`; None: stars = 0);
    ``faint_map``, the faint stars' map at the region's pixels, (pixel, band) e-/s/pix, as
    :func:`faint_star_map` gives it (None: computed here from ``stars``); ``scene``, the
    satellite's and the bodies' positions at exactly the region's times
    (:func:`straylight.sky.observing.scene`, shared by a time block's pixel blocks; None:
    computed here)."""

    stars: object = None
    faint_map: np.ndarray | None = None
    scene: Scene | None = None


def compute_region(
    campaign: Campaign, fp: Footprint, t_slice: slice, p_slice: slice, model=None, stars=None, scene=None
) -> xr.Dataset:
    """Compute the cube values of times t_slice x pixels p_slice (numpy-backed Dataset).

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
        Off-field stars (:func:`offfield_stars`); None: the stars component is 0.
    scene : straylight.sky.observing.Scene, optional
        Satellite and body positions at exactly these times, when already computed for another
        pixel block of the same times; None: computed here.

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
    values = region_values(campaign, fp, t_slice, p_slice, model, RegionInputs(stars, scene=scene))
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
    inputs: RegionInputs | None = None,
    angles: dict | None = None,
) -> dict:
    """:func:`compute_region`'s variables as numpy arrays (name -> (time, pixel[, band]) array),
    without the Dataset: what a worker writes.

    Parameters
    ----------
    campaign, fp, t_slice, p_slice
        As :func:`compute_region`.
    model : BackgroundModel
        The campaign's model.
    inputs : RegionInputs, optional
        The off-field stars, the faint stars' map at these pixels and the times' scene, where
        the caller holds them (None: no stars, the scene computed here).
    angles : dict, optional
        If given, filled with the :data:`~straylight.cube.layout.OBSERVABILITY_ANGLES`
        arrays, float32 deg, shape (n_time, n_pixel).

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
        When ``inputs.scene`` is not at exactly the region's times.
    """
    from straylight.model import unobservable_samples

    inputs = RegionInputs() if inputs is None else inputs
    times = campaign.times[t_slice]
    sc = _region_scene(campaign, inputs.scene, times)
    los = radec_to_unit(fp.ra_deg[p_slice], fp.dec_deg[p_slice])
    nt, npix, nb = len(times), los.shape[0], len(campaign.bands)
    faint = _faint_by_pixel(model, campaign, inputs.stars, inputs.faint_map, los)
    names, n_model, block = _region_block(nt, npix, nb)
    out = dict(zip(names, block))
    grid = _geometry_block(nt, npix, angles is not None)
    # Steps are evaluated together, as one flat batch of samples: numpy's per-call cost is then
    # paid once per batch, not once per step.  The direct earthshine sum grids the Earth per
    # sample, so there one step per call bounds its memory (the star pairs bound their own:
    # OffFieldStars.STAR_PAIRS_PER_PASS).
    max_samples = _samples_per_evaluation(model, npix)
    skip_unobservable = unobservable_samples(campaign) == "skip"  # the campaign's, not the model's
    for steps in _step_batches(nt, npix, max_samples):
        k = steps.stop - steps.start
        samples = _step_samples(sc, steps, los, faint)
        # written straight into the region's float32 block: a view (the steps are consecutive,
        # so step and pixel merge into the batch's step-major samples)
        rows = {name: out[name][steps].reshape(k * npix, nb) for name in names}
        # (the envelope's re-evaluated groups, last, are not the model's: _envelope_ends fills them)
        into = (names[:n_model], block[:n_model, steps].reshape(n_model, k * npix, nb))
        result = background_at(model, samples, campaign.bands, inputs.stars, into, skip_unobservable)
        _envelope_ends(model, campaign, samples, result.geometry, rows)
        for name, values in result.on_grid((k, npix), grid).items():
            grid[name][steps] = values
    _mask_parts(model, campaign, out, grid["observable"])
    if angles is not None:
        angles.update({k: grid.pop(k) for k in OBSERVABILITY_ANGLES})
    return {**out, **grid}


def envelope_end_values(campaign: Campaign, fp: Footprint, t_slice: slice, p_slice: slice, model) -> dict:
    """The envelope's re-evaluated ends of a region alone, as :func:`region_values` gives them
    (bit for bit: the same batches, geometry and member models), without the nominal model's
    evaluation: for a reader of the cube, which stores the nominal parts but not these.

    Parameters
    ----------
    campaign, fp, t_slice, p_slice
        As :func:`compute_region`.
    model : BackgroundModel
        The campaign's model (its envelope members' models are built once on it).

    Returns
    -------
    dict of str to ndarray
        Each of :data:`~straylight.cube.layout.ENVELOPE_END_VARIABLES`: float32, shape (n_time,
        n_pixel, n_band), e-/s/pix, NaN where not observable (everywhere without the
        instrument's ``envelope.members``).
    """
    times = campaign.times[t_slice]
    sc = _region_scene(campaign, None, times)
    los = radec_to_unit(fp.ra_deg[p_slice], fp.dec_deg[p_slice])
    nt, npix, nb = len(times), los.shape[0], len(campaign.bands)
    out = {n: np.full((nt, npix, nb), np.nan, np.float32) for n in cube_layout.ENVELOPE_END_VARIABLES}
    if not _end_models(model, campaign):
        return out
    for steps in _step_batches(nt, npix, _samples_per_evaluation(model, npix)):
        k = steps.stop - steps.start
        samples = _step_samples(sc, steps, los, None)
        rows = {n: v[steps].reshape(k * npix, nb) for n, v in out.items()}
        _envelope_ends(model, campaign, samples, sample_geometry(model, samples), rows)
    return out


def _samples_per_evaluation(model, npix: int) -> int:
    """Samples per evaluation of a region: :data:`SAMPLES_PER_EVALUATION` on the table path; one
    time step where the direct earthshine sum grids the Earth per sample (it bounds the memory)."""
    return SAMPLES_PER_EVALUATION if model.uses_sunlit_table else npix


def _geometry_block(nt: int, npix: int, with_angles: bool) -> dict:
    """The region's (time, pixel) geometry, zeroed: ``observable`` (bool), ``violations``
    (uint8), ``door_opening_deg`` (float32 deg) and with ``with_angles`` the
    :data:`~straylight.cube.layout.OBSERVABILITY_ANGLES` (float32 deg)."""
    grid = {
        "observable": np.zeros((nt, npix), bool),
        "violations": np.zeros((nt, npix), np.uint8),
        "door_opening_deg": np.zeros((nt, npix), np.float32),
    }
    if with_angles:
        grid.update({k: np.zeros((nt, npix), np.float32) for k in OBSERVABILITY_ANGLES})
    return grid


def _step_samples(sc: Scene, steps: slice, los: np.ndarray, faint: dict | None) -> SampleBatch:
    """The region's samples at the time ``steps`` of scene ``sc``: each step's scene over every
    pixel (``los``, (n_pixel, 3)), step-major, with the faint stars' map per pixel (band ->
    e-/s/pix) where known.  The samples' scene runs are the steps, known here, so no function
    scans every sample's vectors to find them again."""
    k, npix = steps.stop - steps.start, los.shape[0]
    return SampleBatch(
        sc.rows(steps),
        np.broadcast_to(los[None], (k,) + los.shape).reshape(-1, 3),
        np.repeat(np.arange(k), npix),
        SceneRuns.steps(k, npix),
        None if faint is None else {b: np.tile(v, k) for b, v in faint.items()},
    )


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


def _envelope_ends(model, campaign, samples: SampleBatch, g: dict, rows: dict) -> None:
    """The parts the envelope's members change, re-evaluated at each end at a batch's observable
    samples (``g``: the batch's geometry), into the ``<part>_<end>`` variables' ``rows``
    (name -> (samples, band) view; NaN elsewhere)."""
    from straylight.model.envelope import end_part_name, end_parts

    models = _end_models(model, campaign)
    sel = np.flatnonzero(np.asarray(g["observable"], bool))
    if not models or not sel.size:
        return
    sat = np.take(samples.satellite_km, sel, axis=0)
    # the Sun and the Moon only: the planets and the stars are not among the members' parts
    bodies = {b: np.take(samples.body_km(b), sel, axis=0) for b in ("sun", "moon")}
    geom = {name: np.asarray(v)[sel] for name, v in g.items() if np.shape(v)[:1] == (samples.n,)}
    los = np.take(samples.los, sel, axis=0)
    for end, end_model in models.items():
        for group, v in end_parts(end_model, sat, bodies, los, geom, campaign.bands).items():
            name = end_part_name(group, end)
            if name in rows:
                rows[name][sel] = v


def _region_scene(campaign, sc, times):
    """``sc`` if it is at exactly ``times`` (the same UTC Julian dates), else ValueError: a
    scene from other times would put every body in the wrong place without a sign; None: the
    scene computed here."""
    if sc is None:
        from straylight.sky import observing

        return observing.scene(campaign.orbit, times)
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
