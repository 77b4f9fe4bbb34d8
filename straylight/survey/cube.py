"""Survey-wide background cubes: every footprint pixel at every campaign time, every component
in every band.

Layout of ``background.zarr`` (xarray Dataset):

* dims (time, pixel, band); one float32 variable per component (e- s-1 pixel-1) plus ``total``;
  ``observable`` (bool) and ``violations`` (uint8 bit mask) and ``door_opening_deg`` on
  (time, pixel); coords time (UTC), pixel (HEALPix index), ra_deg/dec_deg, band, and
  ``mag_zero_point`` (band): AB mag/arcsec2 = mag_zero_point - 2.5 log10(e-/s/pixel);
* attrs: HEALPix nside, ordering and frame, campaign, models, provenance pointers.
* chunks: one time block (``campaign.time_block_hours``) x about ``footprint.pixel_block_size``
  pixels (equal blocks: :func:`~straylight.survey.footprint.pixel_block_length`) x all bands.
  A time-series read of one pointing then touches one chunk per time block, and a
  whole-sky read at one time one chunk per pixel block (bench/storage.py times both).

Work split: one Snakemake job computes many time blocks (:func:`run_time_blocks`: all of them,
or ``compute.time_blocks_per_job``) with a pool of worker processes started once per job; each
worker builds the model (PST, door tables, stars, earthshine tables) once and reuses it for every
(time block, pixel block) region it is given, and every region is written to its own part of the
store exactly once, through the store's arrays opened once per worker.  The region's geometry
(observable, violations, the Sun, Moon and limb angles, the door) is observability.zarr's, so
the worker writes that region of the observability store too (:func:`init_observability_store`,
:func:`publish_work_store`) instead of a later step computing the geometry again, and the
region's 5-sigma limits, from the total it has just computed, to the limits store
(:func:`init_limits_store`, :func:`publish_work_store`) instead of a later step reading the total
back.  A time block is marked done by its own sentinel file only after all its
regions are written, so a killed job redoes only the unfinished time blocks and, the computation
being deterministic, gives identical bytes.
"""
from __future__ import annotations

import json
import time as _time
from contextlib import contextmanager
from dataclasses import dataclass

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from straylight.config import Campaign
from straylight.errors import OutputError
from straylight.survey.footprint import Footprint, pixel_block_length
from straylight.survey.limits import ZERO_POINT_NAME, zero_point_coord
from straylight.survey.storage import stored_values
from straylight.sky.frames import TelescopeFrame, telescope_frame
from straylight.sky.geometry import observing_geometry, violation_mask_attrs
from straylight.sky.runs import SceneRuns
from straylight.sky.vectors import radec_to_unit

if TYPE_CHECKING:  # xarray where a Dataset is made: a worker computing regions does without it
    import xarray as xr

CUBE_COMPONENTS = ("zodiacal", "earthshine", "moon", "sun", "planets", "stars")
#: observability.zarr's angles besides the cube's own (time, pixel) variables: the cube's
#: geometry computes them for every sample, so its workers write observability.zarr too
OBSERVABILITY_ANGLES = ("sun_angle_deg", "moon_angle_deg", "earth_limb_angle_deg")
#: observability.zarr's data variables (straylight.survey.products.observability_dataset)
OBSERVABILITY_VARIABLES = ("observable", "violations") + OBSERVABILITY_ANGLES + ("door_opening_deg",)
#: the cube's (time, pixel, band) variables, e-/s/pix: the components and their total
CUBE_BAND_VARIABLES = CUBE_COMPONENTS + ("total",)
#: limits.zarr's variables the cube's workers write, region by region (:func:`region_limits`)
LIMITS_REGION_VARIABLES = ("limiting_mag", "observable")
#: samples per evaluation on the table path (whole time steps of a pixel block): large enough
#: that numpy's per-call cost is paid rarely: a default production region (72 steps x 660
#: pixels) in one call, 53-54 ms against 57-66 ms in three calls of 16,384 (three interleaved
#: rounds; peak memory 854 against 830 MB, the tables most of it).  A region of 72 steps x
#: 1024 pixels (the schema's default pixel block) in one call: 71-74 ms against 75-79 ms in two
#: (three interleaved rounds), 116 against 105 MB traced at the peak (~1.6 kB a sample)
SAMPLES_PER_EVALUATION = 131072
LONG_NAMES = {
    "zodiacal": "in-field zodiacal light (Leinert 1998)",
    "earthshine": "earthshine through the PST, direct + via the aperture door",
    "moon": "moonlight through the PST",
    "sun": "sunlight through the PST (door-shaded)",
    "planets": "planets (Mercury-Pluto) through the PST",
    "stars": "off-field bright stars through the PST",
    "total": "total stray light and sky background",
}


def cube_chunks(campaign: Campaign, n_times: int, n_pixels: int) -> dict:
    from straylight.survey.timegrid import time_blocks

    c = campaign.config["campaign"]
    tb = time_blocks(n_times, float(c["cadence_s"]), float(c.get("time_block_hours", 6)))
    t_chunk = tb[0][1] - tb[0][0]
    p_chunk = pixel_block_length(n_pixels, int(campaign.config["footprint"].get("pixel_block_size", 1024)))
    return {"time": t_chunk, "pixel": p_chunk, "band": len(campaign.bands)}


def empty_cube(campaign: Campaign, fp: Footprint, times, stars_path=None, build_workers: int = 1) -> xr.Dataset:
    """The cube's skeleton backed by lazy dask zeros (for writing metadata only); the models
    record it carries builds the earthshine table if one runs and is not cached
    (``build_workers`` threads)."""
    import dask.array as da
    import xarray as xr

    nt, npix, nb = len(times), fp.pixels.size, len(campaign.bands)
    ch = cube_chunks(campaign, nt, npix)
    chunks3 = (ch["time"], ch["pixel"], ch["band"])
    chunks2 = (ch["time"], ch["pixel"])
    data = {}
    for comp in CUBE_BAND_VARIABLES:
        data[comp] = xr.Variable(("time", "pixel", "band"), da.zeros((nt, npix, nb), chunks=chunks3, dtype=np.float32),
                                 {"units": "electron / (s pixel)", "long_name": LONG_NAMES[comp]})
    data["observable"] = xr.Variable(("time", "pixel"), da.zeros((nt, npix), chunks=chunks2, dtype=bool),
                                     {"units": "1", "long_name": "pointing satisfies every constraint"})
    data["violations"] = xr.Variable(("time", "pixel"), da.zeros((nt, npix), chunks=chunks2, dtype=np.uint8),
                                     violation_mask_attrs())
    data["door_opening_deg"] = xr.Variable(("time", "pixel"), da.zeros((nt, npix), chunks=chunks2, dtype=np.float32),
                                           {"units": "deg", "long_name": "aperture door opening (0 = no allowed state)"})
    ds = xr.Dataset(
        data,
        coords={
            "time": ("time", times.datetime64, {"long_name": "UTC sample time"}),
            "pixel": ("pixel", fp.pixels, {"long_name": "HEALPix pixel index"}),
            "ra_deg": ("pixel", fp.ra_deg, {"units": "deg", "long_name": "ICRS RA of pixel centre"}),
            "dec_deg": ("pixel", fp.dec_deg, {"units": "deg", "long_name": "ICRS Dec of pixel centre"}),
            "band": ("band", np.array(campaign.bands, dtype=object), {"long_name": "CSST band"}),
            ZERO_POINT_NAME: zero_point_coord(campaign, campaign.bands),
        },
        attrs={
            "campaign": campaign.name,
            "healpix_nside": fp.nside,
            "healpix_ordering": fp.ordering.upper(),
            "healpix_frame": "ICRS",
            "zodiacal_spectrum": campaign.config["models"].get("zodiacal_spectrum"),
            "moon_phase_law": campaign.config["models"].get("moon_phase_law"),
            "pst_source": str(campaign.instrument.get("pst", {}).get("source", "")),
            "stars_included": int(len(_offfield_stars(campaign, stars_path).ra_deg)) if stars_path else 0,
            "stars_in_faint_map": int(len(_offfield_stars(campaign, stars_path).faint_ra_deg)) if stars_path else 0,
            "stars_catalog": Path(stars_path).name if stars_path else "none",
            "stars_offfield_mag_limit": float(campaign.config["stars"].get("offfield_mag_limit", 2.0)),
            "stars_faint_map": int(bool(campaign.config["stars"].get("faint_map", True))),
            "chunking": "time block x pixel block x all bands",
            # which models ran and their error budget (the earthshine table is built here, once,
            # before the time-block jobs start)
            "models": json.dumps(background_model_for(campaign, fp, build_workers).models_record(),
                                 sort_keys=True),
        },
    )
    return ds


def _faint_rows(campaign: Campaign, fp: Footprint, stars_path, rows: slice) -> np.ndarray:
    """The faint-star map at footprint pixels ``rows``, (pixel, band) e-/s/pix (0 in a band
    the catalog has no faint magnitudes in)."""
    stars = _offfield_stars(campaign, stars_path)
    los = radec_to_unit(fp.ra_deg[rows], fp.dec_deg[rows])
    rates = background_model_for(campaign, fp).stars.faint_star_rates(stars, los, campaign.bands, saved=True)
    values = np.zeros((los.shape[0], len(campaign.bands)))
    for i, band in enumerate(campaign.bands):
        if band in rates:
            values[:, i] = rates[band]
    return values


def _faint_rows_saved(campaign: Campaign, fp: Footprint, stars, rows: slice, build_workers: int) -> bool:
    """Whether the faint-star map at footprint pixels ``rows`` is kept on disk (:func:`_faint_rows`
    reads it instead of summing); the process's model is made here with ``build_workers`` for
    an earthshine table it may build later."""
    los = radec_to_unit(fp.ra_deg[rows], fp.dec_deg[rows])
    return background_model_for(campaign, fp, build_workers).stars.faint_star_map_saved(stars, los, campaign.bands)


def faint_star_map(campaign: Campaign, fp: Footprint, stars_path, workers: int = 1,
                   before=None) -> xr.Variable | None:
    """The faint stars' smoothed map at every footprint pixel, (pixel, band), e-/s/pix: it
    depends on the line of sight only, so the cube computes it once (in :func:`init_store`)
    and every time block reads it.  None without a catalog or with no faint stars.

    ``workers`` processes share the pixels (this one and ``workers`` - 1 spawned ones, each
    loading the catalog and the model once): the same values as one process (each pixel's sum
    is computed on its own).  ``before``: a callable run in this process while the spawned ones
    start (the skeleton's other work); its result is returned with the map as a pair then."""
    import xarray as xr

    stars = _offfield_stars(campaign, stars_path)
    if stars is None or not len(stars.faint_ra_deg):
        return None if before is None else (None, before())
    edges = np.linspace(0, fp.pixels.size, max(1, min(int(workers), fp.pixels.size)) + 1).round().astype(int)
    parts = [slice(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]
    if len(parts) == 1 or all(_faint_rows_saved(campaign, fp, stars, rows, workers) for rows in parts):
        # one process, or every part's sums kept on disk (read here: no process to start)
        other = None if before is None else before()
        values = np.concatenate([_faint_rows(campaign, fp, stars_path, rows) for rows in parts])
    else:
        from straylight.util.daskutil import spawned_pool

        with spawned_pool(len(parts) - 1) as pool:
            futures = [pool.submit(_faint_rows, campaign, fp, str(stars_path), rows) for rows in parts[1:]]
            other = None if before is None else before()
            values = np.concatenate([_faint_rows(campaign, fp, stars_path, parts[0])]
                                    + [f.result() for f in futures])
    var = xr.Variable(("pixel", "band"), values,
                      {"units": "electron / (s pixel)",
                       "long_name": "faint off-field stars: smoothed map (azimuth-averaged PST), part of stars"})
    return var if before is None else (var, other)


def init_store(campaign: Campaign, fp: Footprint, store, stars_path=None, build_workers: int = 1,
               limits_store=None) -> None:
    """Write the skeleton (metadata and coordinates, no data chunks) to ``store``, and the
    faint-star map (computed here once for the whole campaign, on ``build_workers``
    processes); an earthshine table the campaign needs is built here too, before the time
    blocks start (``build_workers`` threads).  ``limits_store``: where the limits' skeleton
    goes too (:func:`init_limits_store`; None: not laid down)."""
    from straylight.survey.storage import write_skeleton

    # the faint map's other processes start first and sum while this one lays down the skeleton
    faint, ds = faint_star_map(campaign, fp, stars_path, build_workers,
                               before=lambda: empty_cube(campaign, fp, campaign.times, stars_path, build_workers))
    if limits_store is not None:
        init_limits_store(campaign, ds, limits_store)
    if faint is not None:
        ds["faint_star_map"] = faint
    # the products' codecs (bit-rounded floats); the faint map exactly, the time blocks read it
    write_skeleton(ds, store, campaign.config["storage"], lossless=("faint_star_map",))


_MODELS: dict = {}


def background_model_for(campaign: Campaign, fp: Footprint, build_workers: int = 1):
    """One BackgroundModel per process and campaign: its door tables, bands and earthshine table
    are built once, not once per Dask task (the campaign arrives pickled, so key on its content).
    It expects the samples the cube evaluates (:func:`evaluated_samples`)."""
    from straylight.model import BackgroundModel
    from straylight.survey.plan import evaluated_samples

    key = (json.dumps(campaign.config, sort_keys=True, default=str), str(campaign.instrument_path), fp.pixels.size)
    if key not in _MODELS:
        _MODELS[key] = BackgroundModel(campaign,
                                      build_workers=build_workers)
    return _MODELS[key]


_STARS: dict = {}


def _offfield_stars(campaign: Campaign, stars_path):
    """The catalog's off-field stars (brighter than stars.offfield_mag_limit), once per process."""
    if stars_path is None:
        return None
    from straylight.sources.stars import load_offfield_stars

    limit = float(campaign.config["stars"].get("offfield_mag_limit", 2.0))
    faint = bool(campaign.config["stars"].get("faint_map", True))
    key = (str(stars_path), tuple(campaign.bands), limit, faint)
    if key not in _STARS:
        _STARS[key] = load_offfield_stars(stars_path, campaign.bands, limit, faint)
    return _STARS[key]


def compute_region(campaign: Campaign, fp: Footprint, t_slice: slice, p_slice: slice, model=None,
                   stars_path=None, faint_map=None, scene=None, angles: dict | None = None) -> xr.Dataset:
    """Compute the cube values of times t_slice x pixels p_slice (numpy-backed Dataset);
    ``stars_path``: the star catalog for the off-field star term (None: stars = 0);
    ``faint_map``: the faint stars' map at these pixels, (pixel, band) e-/s/pix, as
    :func:`faint_star_map` gives it (None: computed here); ``scene``: the satellite's and the
    bodies' positions at these times (:func:`straylight.sky.observing.scene`), when already computed for
    another pixel block of the same times (None: computed here); ``angles``: a dict that receives
    the samples' other observability angles (:data:`OBSERVABILITY_ANGLES`, (time, pixel) float32
    deg, the geometry the cube computes anyway; None: not kept).  ValueError if ``scene`` is
    not at exactly these times."""
    import xarray as xr

    values = region_values(campaign, fp, t_slice, p_slice, model, stars_path, faint_map, scene, angles)
    return xr.Dataset({name: (("time", "pixel", "band") if name in CUBE_BAND_VARIABLES else ("time", "pixel"), v)
                       for name, v in values.items()})


def region_values(campaign: Campaign, fp: Footprint, t_slice: slice, p_slice: slice, model=None,
                  stars_path=None, faint_map=None, scene=None, angles: dict | None = None) -> dict:
    """:func:`compute_region`'s variables as numpy arrays (name -> (time, pixel[, band]) array),
    without the Dataset: what a worker writes."""
    from straylight.sky import observing
    from straylight.model import unobservable_samples

    model = model or background_model_for(campaign, fp)
    stars = _offfield_stars(campaign, stars_path)
    times = campaign.times[t_slice]
    sc = observing.scene(campaign.orbit, times) if scene is None else _checked_scene(scene, times)
    los = radec_to_unit(fp.ra_deg[p_slice], fp.dec_deg[p_slice])
    nt, npix, nb = len(times), los.shape[0], len(campaign.bands)
    faint = None if faint_map is None else {b: np.asarray(faint_map)[:, i] for i, b in enumerate(campaign.bands)}
    if faint is None and stars is not None and len(stars.faint_ra_deg):
        # once per pixel, not per sample of a many-step batch (it depends on the line of sight only)
        faint = model.stars.faint_star_rates(stars, los, campaign.bands)
    # one allocation for every component: numpy asks the kernel for huge pages on arrays of 4 MiB
    # or more (a default region's 9.3 MB).  Seven fresh 1.3 MB arrays took 3.6 ms of page faults
    # in a micro-benchmark; in a run of regions, where freed memory is reused, it gained ~0.6 %
    names = CUBE_BAND_VARIABLES
    block = np.zeros((len(names), nt, npix, nb), np.float32)
    out = dict(zip(names, block))
    obs = np.zeros((nt, npix), bool)
    viol = np.zeros((nt, npix), np.uint8)
    door = np.zeros((nt, npix), np.float32)
    if angles is not None:
        angles.update({k: np.zeros((nt, npix), np.float32) for k in OBSERVABILITY_ANGLES})
    # Steps are evaluated together, as one flat batch of samples: numpy's per-call cost is then
    # paid once per batch, not once per step (1.5-1.7x on the table path).  The direct earthshine
    # sum grids the Earth per sample, so there one step per call bounds its memory (the star
    # pairs bound their own: OffFieldStars.STAR_PAIRS_PER_PASS).
    max_samples = npix if model.sunlit_earth.model["lut"] is None else SAMPLES_PER_EVALUATION
    skip_unobservable = unobservable_samples(campaign) == "skip"  # the campaign's, not the model's
    for steps in _step_batches(nt, npix, max_samples):
        k = steps.stop - steps.start
        # each step's scene repeated over its pixels: the samples' scene runs are the steps,
        # known here, so no function reads every sample's vectors to find them again (twelve
        # scans of 0.1-0.2 ms each on a region's 47,520 samples)
        runs = SceneRuns.steps(k, npix)
        sat = np.repeat(sc.satellite_km[steps], npix, axis=0)
        los_k = np.broadcast_to(los[None], (k,) + los.shape).reshape(-1, 3)
        # the constraints need the Sun's and the Moon's angles only; the background finds the
        # planets' where they can matter (sources.bodies.Planets)
        bodies = {b: np.repeat(sc.bodies_km[b][steps], npix, axis=0)
                  for b in (("sun", "moon") if skip_unobservable else sc.bodies_km)}
        frame = telescope_frame(los_k, bodies["sun"] - sat)  # once for the geometry and the background
        g = observing_geometry(sat, {b: bodies[b] for b in ("sun", "moon")}, los_k, campaign.earth.radius_km,
                               campaign.constraints, frame=frame, runs=runs)
        if skip_unobservable:
            _evaluate_observable(model, campaign, sc, los, faint, g, frame, stars, out, steps, runs)
        else:
            faint_k = None if faint is None else {b: np.tile(v, k) for b, v in faint.items()}
            # written straight into the region's float32 block: a view (the steps are consecutive,
            # so step and pixel merge into the batch's step-major samples)
            into = (names, block[:, steps].reshape(len(names), k * npix, nb))
            model.evaluate(sat, bodies, los_k, g, campaign.bands, stars, faint_rates=faint_k, frame=frame, into=into,
                           runs=runs)
        obs[steps], viol[steps], door[steps] = (_by_step(g[v], k, npix)
                                                for v in ("observable", "violations", "door_opening_deg"))
        if angles is not None:
            for name in OBSERVABILITY_ANGLES:
                angles[name][steps] = _by_step(g[name], k, npix)
    return {**out, "observable": obs, "violations": viol, "door_opening_deg": door}


def _checked_scene(sc, times):
    """``sc`` if it is at exactly ``times`` (the same UTC Julian dates), else ValueError: a
    scene from other times would put every body in the wrong place without a sign."""
    t = sc.times
    same = (len(t) == len(times) and np.array_equal(t.utc.jd1, times.utc.jd1)
            and np.array_equal(t.utc.jd2, times.utc.jd2))
    if not same:
        raise ValueError(f"scene at {len(t)} times ({t[0].isot if len(t) else '-'} ...) is not at the region's "
                         f"{len(times)} times ({times[0].isot if len(times) else '-'} ...)")
    return sc


def _evaluate_observable(model, campaign: Campaign, sc, los, faint, screen: dict, frame, stars, out, steps, runs):
    """Evaluate the observable samples (flat, step-major) of the time steps ``steps`` of the
    scene ``sc`` at the lines of sight ``los`` (pixel, 3) only, and write them into ``out`` at
    ``steps``; the other samples get NaN.  ``screen``: the batch's geometry with the Sun and
    the Moon (:func:`observing_geometry`), ``frame`` its telescope frame: the observable samples
    take their values (the background finds the planets' angles itself).  Each sample's values
    depend on that sample alone, so the observable ones come out as they do in a whole batch
    (tests/sources/test_earthshine_lut.py).  ``faint``: band -> per-pixel faint-star rates; ``runs``:
    the batch's scene runs (its steps)."""
    npix = los.shape[0]
    sel = np.flatnonzero(screen["observable"])
    for comp in CUBE_BAND_VARIABLES:
        out[comp][steps] = np.nan
    if sel.size == 0:
        return
    t_idx, p_idx = np.divmod(sel, npix)
    # rows by index with np.take (3-4x numpy's fancy indexing of (N, 3) rows)
    sat = np.take(sc.satellite_km[steps], t_idx, axis=0)
    bodies = {b: np.take(v[steps], t_idx, axis=0) for b, v in sc.bodies_km.items()}
    sub = TelescopeFrame(*(np.take(a, sel, axis=0) for a in (frame.x, frame.y, frame.z)))
    g = {name: np.asarray(v)[sel] for name, v in screen.items()}
    names = CUBE_BAND_VARIABLES
    values = np.empty((len(names), sel.size, len(campaign.bands)), np.float32)
    model.evaluate(sat, bodies, np.take(los, p_idx, axis=0), g, campaign.bands, stars,
                   faint_rates=None if faint is None else {b: v[p_idx] for b, v in faint.items()}, frame=sub,
                   into=(names, values), runs=runs.at(sel))
    for comp, v in zip(names, values):  # every band of a sample at once
        out[comp][steps.start + t_idx, p_idx] = v


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


def store_arrays(store, names=None) -> dict:
    """The cube's data variables in ``store`` opened for writing whole chunks (name ->
    :class:`~straylight.survey.storage.ChunkWriter`): a worker opens them once and writes every
    region through them (xarray's region write opens the store and reads its metadata again
    each time, ~15 ms a region).  The same codecs encode the same values, so the chunks' bytes
    are those xarray writes."""
    import zarr

    from straylight.survey.storage import ChunkWriter

    group = zarr.open_group(str(store), mode="r+", use_consolidated=False)
    names = names or CUBE_BAND_VARIABLES + ("observable", "violations", "door_opening_deg")
    return {name: ChunkWriter(group[name]) for name in names}


def init_observability_store(campaign: Campaign, fp: Footprint, ephem: xr.Dataset, store) -> None:
    """Lay down observability.zarr's skeleton at ``store`` (metadata, coordinates, the products'
    codecs; no data chunks), chunked as the cube: the cube's workers write each region's
    observability beside its background (:func:`write_region`), and
    :func:`publish_work_store` makes it the product once every time block is done.  The
    variables and attributes are those of
    :func:`straylight.survey.products.observability_dataset` (``ephem``: the ephemeris product),
    whose geometry the cube's is, sample by sample, bit for bit."""
    from straylight.survey.products import observability_dataset
    from straylight.survey.storage import write_skeleton

    chunks = cube_chunks(campaign, ephem.sizes["time"], fp.pixels.size)
    write_skeleton(observability_dataset(campaign, ephem, fp, chunks=chunks), store, campaign.config["storage"])


def init_limits_store(campaign: Campaign, cube, store) -> None:
    """Lay down limits.zarr's skeleton at ``store`` (metadata, coordinates, the products' codecs;
    no data chunks) from the cube's skeleton ``cube`` (:func:`empty_cube`): the variables,
    attributes and chunks of :func:`straylight.survey.limits.limits_dataset` on the cube.  The
    cube's workers write each region's ``limiting_mag`` and ``observable`` (:func:`write_region`);
    the limits rule adds the per-pixel summaries in :func:`publish_work_store`."""
    from straylight.survey.limits import limits_dataset
    from straylight.survey.storage import write_skeleton

    write_skeleton(limits_dataset(campaign, cube), store, campaign.config["storage"])


def region_limits(campaign: Campaign, region) -> dict:
    """A computed region's limits.zarr variables (name -> (time, pixel[, band]) array): the
    5-sigma limits of its computed ``total`` (:func:`straylight.survey.limits.band_limits`),
    and its ``observable``; ``region``: :func:`compute_region`'s Dataset or
    :func:`region_values`' arrays."""
    from straylight.survey.limits import band_limits, campaign_exposures

    return {"limiting_mag": band_limits(np.asarray(region["total"]), campaign_exposures(campaign)),
            "observable": np.asarray(region["observable"])}


def publish_work_store(work_store, product, summaries: dict | None = None) -> None:
    """A store the cube's workers filled (``work_store``: the observability or the limits one),
    its metadata consolidated, appears at ``product`` complete or not at all: its files
    hard-linked (copied where links fail), and ``summaries`` (name -> the whole array of a
    variable the work store lays down but has no chunk of: the limits' per-pixel summaries)
    written there only.  The work store stays as it was, for a re-run of the publishing step;
    its writers (:class:`~straylight.survey.storage.ChunkWriter`, zarr) replace a chunk file by
    renaming a new one into place, so a later write to the work store leaves the product's files
    as they are."""
    import os
    import shutil

    import zarr

    from straylight.survey.storage import PARTIAL_SUFFIX
    from straylight.util.io import atomic_path

    zarr.consolidate_metadata(str(work_store))

    def link(src, dst):
        try:
            os.link(src, dst)
        except OSError:
            shutil.copy2(src, dst)

    with atomic_path(product) as tmp:
        # every time block is done, so no chunk is being written: a *.partial file is a killed
        # writer's, never part of the store
        shutil.copytree(work_store, tmp, copy_function=link, ignore=shutil.ignore_patterns(f"*{PARTIAL_SUFFIX}"))
        if summaries:
            group = zarr.open_group(str(tmp), mode="r+", use_consolidated=False)
            for name, values in summaries.items():
                # rounded as the variable's attributes record (the codecs are lossless); new chunk
                # files only: no linked file is written
                group[name][...] = stored_values(np.array(values), group[name].attrs)


def write_region(campaign: Campaign, fp: Footprint, store, t_slice: slice, p_slice: slice,
                 stars_path=None, scene=None, faint_map=None, arrays=None, obs_store=None,
                 obs_arrays=None, lim_store=None, lim_arrays=None) -> float:
    """Compute one (time block, pixel block) region and write it to its Zarr region; seconds.
    ``scene``: the time block's positions, shared by its pixel blocks (None: computed here);
    ``faint_map``: the store's faint-star map at these pixels, (pixel, band) e-/s/pix, when the
    caller has read it (None: read from the store here when there is a star catalog);
    ``arrays``: the store's arrays (:func:`store_arrays`) when the caller keeps them open (None:
    opened here); ``obs_store``: the observability store the region's observability
    goes to as well (:func:`init_observability_store`; None: not written), ``obs_arrays`` its
    arrays kept open; ``lim_store``: the limits store the region's limits, computed from its
    computed total (:func:`region_limits`), go to (:func:`init_limits_store`; None: not
    computed), ``lim_arrays`` its arrays kept open."""
    t0 = _time.perf_counter()
    faint = faint_map
    if faint is None and stars_path is not None:
        faint = _stored_faint_map(store)
        faint = None if faint is None else faint[p_slice]
    angles = None if obs_store is None else {}
    region = region_values(campaign, fp, t_slice, p_slice, stars_path=stars_path, faint_map=faint, scene=scene,
                           angles=angles)
    lim = None if lim_store is None else region_limits(campaign, region)
    try:
        # written through the stores' arrays, each rounded as its attributes record (storage.stored_values)
        arrays = arrays or store_arrays(store, tuple(region))
        for name, values in region.items():
            arrays[name][t_slice, p_slice] = stored_values(values, arrays[name].attrs)
        if obs_store is not None:
            obs_arrays = obs_arrays or store_arrays(obs_store, OBSERVABILITY_VARIABLES)
            for name in OBSERVABILITY_VARIABLES:
                values = angles[name] if name in angles else region[name]
                obs_arrays[name][t_slice, p_slice] = stored_values(values, obs_arrays[name].attrs)
        if lim is not None:
            lim_arrays = lim_arrays or store_arrays(lim_store, tuple(lim))
            for name, values in lim.items():
                lim_arrays[name][t_slice, p_slice] = stored_values(values, lim_arrays[name].attrs)
    except OSError as exc:  # ENOSPC, EDQUOT, EACCES...: the block's sentinel is not written
        raise OutputError(f"{store}: writing times {t_slice.start}:{t_slice.stop} x pixels {p_slice.start}:"
                          f"{p_slice.stop} failed ({exc.strerror or exc}); finished time blocks are kept, "
                          "free space and re-run to redo this block") from exc
    return _time.perf_counter() - t0


@dataclass
class BlockReport:
    time_block: int
    pixel_blocks: int
    samples: int
    seconds: float


def _stored_faint_map(store) -> np.ndarray | None:
    """The store's faint_star_map, (pixel, band) e-/s/pix, or None when it has none."""
    import zarr

    group = zarr.open_group(str(store), mode="r", use_consolidated=False)
    return group["faint_star_map"][...] if "faint_star_map" in group else None


def block_sentinel(done_dir, block_index: int) -> Path:
    """The file marking time block ``block_index`` done (its BlockReport as JSON)."""
    return Path(done_dir) / f"block_{block_index}.json"


def clear_block_sentinels(done_dir) -> int:
    """Remove every time block's sentinel from ``done_dir`` (a fresh store has no block done);
    returns how many were removed."""
    removed = 0
    for p in Path(done_dir).glob("block_*.json"):
        p.unlink()
        removed += 1
    return removed


#: the worker process's campaign, footprint, store and catalog (set once by _pool_init)
_WORKER: dict = {}


def _pool_init(campaign: Campaign, fp: Footprint, store: str, stars_path, obs_store=None, lim_store=None) -> None:
    """Pool worker start-up: keep the job's inputs and build the model now, once per process
    (every region this process computes reuses it)."""
    _WORKER.clear()
    _WORKER.update(campaign=campaign, fp=fp, store=store, stars_path=stars_path, obs_store=obs_store,
                   lim_store=lim_store)
    background_model_for(campaign, fp)
    _offfield_stars(campaign, stars_path)


def _pool_init_from_config(config: dict, config_path: str, store: str, stars_path, obs_store=None,
                           lim_store=None) -> None:
    """Pool worker start-up for workers started before the job has loaded its campaign
    (:func:`straylight.survey.workers.start_region_workers`): the campaign from the job's
    config, the footprint from the store's skeleton
    (:func:`~straylight.survey.footprint.footprint_from_store`), then :func:`_pool_init`, then
    one sample computed so that every part of the model is built (the tables read, the star
    cells listed, the compiled kernels loaded) before the first region arrives."""
    from straylight.config import campaign_from_dict
    from straylight.survey.footprint import footprint_from_store
    from straylight.util.healpix import load_without_plotting

    load_without_plotting()  # the star cells' healpy: a worker draws nothing
    campaign = campaign_from_dict(dict(config), config_path)
    fp = footprint_from_store(store)  # the skeleton's coordinates: no astropy frames, no cuts again
    _pool_init(campaign, fp, store, stars_path, obs_store, lim_store)
    # (the faint stars' map comes with each region: zeros here)
    region_values(campaign, fp, slice(0, 1), slice(0, 1), stars_path=stars_path,
                  faint_map=np.zeros((1, len(campaign.bands))))


def _pool_region(t_slice: slice, p_slice: slice, scene, faint_map) -> float:
    """One region in a pool worker, with the inputs _pool_init kept and the store's arrays
    opened once; seconds."""
    w = _WORKER
    if "arrays" not in w:
        w["arrays"] = store_arrays(w["store"])
        w["obs_arrays"] = None if w["obs_store"] is None else store_arrays(w["obs_store"], OBSERVABILITY_VARIABLES)
        w["lim_arrays"] = None if w["lim_store"] is None else store_arrays(w["lim_store"], LIMITS_REGION_VARIABLES)
    return write_region(w["campaign"], w["fp"], w["store"], t_slice, p_slice, w["stars_path"], scene, faint_map,
                        w["arrays"], w["obs_store"], w["obs_arrays"], w["lim_store"], w["lim_arrays"])


class _InProcess:
    """An executor running each region at once in this process (one worker, no pool)."""

    def __init__(self, campaign, fp, store, stars_path, obs_store=None, lim_store=None):
        _pool_init(campaign, fp, store, stars_path, obs_store, lim_store)

    def submit_region(self, t_slice: slice, p_slice: slice, scene, faint_map):
        from concurrent.futures import Future

        fut = Future()
        try:
            fut.set_result(_pool_region(t_slice, p_slice, scene, faint_map))
        except BaseException as exc:  # noqa: BLE001 - handed to the caller by fut.result()
            fut.set_exception(exc)
        return fut


@contextmanager
def region_pool(campaign, fp, store: str, stars_path, workers: int, scheduler_address: str | None = None,
                obs_store: str | None = None, lim_store: str | None = None, pool=None):
    """Yield ``(submit, wait)`` for the cube's regions: ``submit(t_slice, p_slice, scene,
    faint_map)`` returns a future of the region's seconds (:func:`write_region`),
    ``wait`` is the matching ``wait(futures, return_when=...)``; ``obs_store``, ``lim_store``:
    where each region's observability and limits go too (None: not written).

    * ``scheduler_address``: the regions run on that Dask cluster (campaign and footprint sent
      to every worker once); its workers keep the model between regions, time blocks and jobs.
    * else ``pool``: that pool of processes
      (:func:`~straylight.survey.workers.start_region_workers`), left running.
    * else ``workers`` > 1: a pool of that many spawned processes (:func:`worker_environment`),
      each building the model once, at its start, for all the regions it computes.
    * else: in this process, one region after the other.
    """
    from concurrent.futures import wait as wait_local

    from straylight.util.daskutil import spawned_pool

    if scheduler_address:
        from distributed import Client
        from distributed import wait as wait_dask

        with Client(scheduler_address, timeout="30s") as client:
            c_fut, fp_fut = client.scatter([campaign, fp], broadcast=True)

            def submit(t_slice, p_slice, scene, faint_map):
                return client.submit(write_region, c_fut, fp_fut, store, t_slice, p_slice, stars_path, scene,
                                     faint_map, None, obs_store, None, lim_store, pure=False)

            yield submit, wait_dask
        return
    if pool is not None:
        def submit(t_slice, p_slice, scene, faint_map):
            return pool.submit(_pool_region, t_slice, p_slice, scene, faint_map)

        try:
            yield submit, wait_local
        except BaseException:
            pool.shutdown(wait=True, cancel_futures=True)  # the queued regions are not run
            raise
        return
    if int(workers) <= 1:
        yield _InProcess(campaign, fp, store, stars_path, obs_store, lim_store).submit_region, wait_local
        return
    with spawned_pool(workers, _pool_init, (campaign, fp, store, stars_path, obs_store, lim_store)) as pool:
        def submit(t_slice, p_slice, scene, faint_map):
            return pool.submit(_pool_region, t_slice, p_slice, scene, faint_map)

        try:
            yield submit, wait_local
        except BaseException:
            pool.shutdown(wait=True, cancel_futures=True)
            raise


def run_time_blocks(campaign: Campaign, fp: Footprint, store, blocks, done_dir, workers: int = 1,
                    scheduler_address: str | None = None, log=None, stars_path=None,
                    obs_store=None, lim_store=None, pool=None) -> list[BlockReport]:
    """Compute the time blocks ``blocks`` (indices) of the cube into ``store``, each marked done
    by its sentinel in ``done_dir`` (:func:`block_sentinel`) once all its pixel blocks are
    written; blocks already marked done are skipped (resume).  Regions run on ``workers``
    processes started once for all the blocks (:func:`region_pool`: each builds
    the model once), in this process when ``workers`` is 1, or on the Dask cluster at
    ``scheduler_address`` when given (its workers keep the model between tasks and jobs).
    ``log`` (a logging.Logger) gets one line per finished region.  ``obs_store``: each region's
    observability is written there too (:func:`init_observability_store`), and to ``lim_store``
    its limits (:func:`init_limits_store`), before its time block's sentinel.  ``pool``: workers
    already started for these stores (:func:`~straylight.survey.workers.start_region_workers`),
    used instead of new ones.
    Returns every requested block's report (a skipped one's from its sentinel)."""
    from concurrent.futures import FIRST_COMPLETED

    from straylight.util.io import write_json_atomic
    from straylight.sky.observing import scene
    from straylight.survey.storage import remove_partial_chunks
    from straylight.survey.timegrid import time_blocks

    c = campaign.config["campaign"]
    tb = time_blocks(len(campaign.times), float(c["cadence_s"]), float(c.get("time_block_hours", 6)))
    blocks = [int(b) for b in blocks]
    bad = [b for b in blocks if not 0 <= b < len(tb)]
    if bad:
        raise IndexError(f"time block {bad[0]} outside 0..{len(tb) - 1}")
    store = str(Path(store).resolve())  # workers (other hosts, other cwd) need an absolute path
    stars_path = str(Path(stars_path).resolve()) if stars_path else None
    obs_store = str(Path(obs_store).resolve()) if obs_store else None
    lim_store = str(Path(lim_store).resolve()) if lim_store else None
    todo = [b for b in blocks if not block_sentinel(done_dir, b).exists()]
    if log is not None and len(todo) < len(blocks):
        log.info("%d of %d time blocks already done (sentinels in %s): skipped", len(blocks) - len(todo),
                 len(blocks), done_dir)
    p_blocks = [slice(a, b) for a, b in fp.blocks(int(campaign.config["footprint"].get("pixel_block_size", 1024)))]
    faint = _stored_faint_map(store) if (stars_path is not None and todo) else None
    # a time block is a time chunk: its half-written chunk files of a killed run go before it is redone
    removed = sum(remove_partial_chunks(s, todo) for s in (store, obs_store, lim_store) if s is not None)
    if log is not None and removed:
        log.info("removed %d half-written chunk files of an earlier run", removed)
    if todo:
        with region_pool(campaign, fp, store, stars_path, workers, scheduler_address, obs_store,
                         lim_store, pool) as (submit, wait):
            # a bounded window of regions in flight: the next time block's scene is computed
            # while the workers are busy, and memory does not grow with the campaign
            window = 2 * max(1, int(workers)) + 1
            pending: dict = {}
            left = {b: len(p_blocks) for b in todo}
            started: dict = {}

            def finish(done):
                for fut in done:
                    b, ps, t_slice = pending.pop(fut)
                    seconds = fut.result()
                    if log is not None:
                        log.info("chunk time %d:%d pixels %d:%d done in %.2f s", t_slice.start, t_slice.stop,
                                 ps.start, ps.stop, seconds)
                    left[b] -= 1
                    if left[b] == 0:
                        n = (t_slice.stop - t_slice.start) * fp.pixels.size
                        rep = BlockReport(b, len(p_blocks), n, _time.perf_counter() - started[b])
                        write_json_atomic(rep.__dict__, block_sentinel(done_dir, b))

            for b in todo:
                t_slice = slice(*tb[b])
                # the satellite's and the bodies' positions once per time block, shared by its
                # pixel blocks (~20 kB for 72 steps, sent with each region)
                sc = scene(campaign.orbit, campaign.times[t_slice])
                started[b] = _time.perf_counter()
                for ps in p_blocks:
                    while len(pending) >= window:
                        finish(wait(list(pending), return_when=FIRST_COMPLETED)[0])
                    fut = submit(t_slice, ps, sc, None if faint is None else faint[ps])
                    pending[fut] = (b, ps, t_slice)
            while pending:
                finish(wait(list(pending), return_when=FIRST_COMPLETED)[0])
    return [BlockReport(**json.loads(block_sentinel(done_dir, b).read_text())) for b in blocks]
