"""The limits cube and its summaries: limits.zarr's dataset from the background cube (the
(time, pixel, band) 5-sigma limits of :mod:`straylight.limits.point_source`), the per-pixel campaign
summaries over the observable times (best, median, observable fraction; from a limits store in
parallel processes) and the HEALPix FITS maps of them."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from straylight.config import Campaign
from straylight.execution import dask_rechunk_by_tasks
from straylight.limits.budget import (
    BUDGET_VARIABLES,
    SHIFT_PERCENTILES,
    background_budget_limits,
    shift_percentiles,
    with_budget,
)
from straylight.limits.envelope import (
    ENVELOPE_VARIABLES,
    background_envelope_limits,
    with_envelope,
)
from straylight.limits.maps import write_limit_maps
from straylight.limits.point_source import (
    ZERO_POINT_NAME,
    band_limits,
    campaign_exposures,
    zero_point_coord,
)

if TYPE_CHECKING:
    import xarray as xr

__all__ = [
    "SUMMARY_BYTES_PER_PROCESS",
    "SUMMARY_PIXELS_PER_TASK",
    "SUMMARY_TASK_BYTES",
    "SUMMARY_VARIABLES",
    "ENVELOPE_VARIABLES",
    "limit_summaries",
    "limits_dataset",
    "observable_fraction",
    "store_limit_summaries",
    "summary_processes",
    "write_limit_maps",
]


def limit_summaries(limiting_mag, observable) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel campaign summaries of (time, pixel, band) limits (mag(AB)) over the observable
    times (``observable``: (time, pixel) bool): the deepest (NaN-ignoring maximum) and the median
    (``np.nanmedian``: NaN-ignoring, the mean of the two middle values in float32 for an even
    count), each (pixel, band) float32, NaN where a pixel is never observable.  The one way the
    products compute them.  Pixel by pixel on its observable times only, with ``np.median``'s
    partition (the same values as ``np.nanmedian`` over the times with the others masked as NaN,
    which goes row by row through ``apply_along_axis`` for 600 or more times, several times
    slower; docs/performance.md).

    Parameters
    ----------
    limiting_mag : array_like, shape (n_time, n_pixel, n_band)
        Limiting magnitudes, mag(AB).
    observable : array_like of bool, shape (n_time, n_pixel)
        Whether each pointing satisfies every constraint.

    Returns
    -------
    best : ndarray of float32, shape (n_pixel, n_band)
        Deepest limit over the observable times, mag(AB); NaN where never observable.
    median : ndarray of float32, shape (n_pixel, n_band)
        Median limit over the observable times, mag(AB); NaN where never observable.
    """
    import warnings

    limiting_mag = np.asarray(limiting_mag)
    observable = np.asarray(observable, dtype=bool)
    n_pix, n_band = limiting_mag.shape[1:]
    best = np.full((n_pix, n_band), np.nan, np.float32)
    median = np.full((n_pix, n_band), np.nan, np.float32)
    for p in range(n_pix):
        times = np.flatnonzero(observable[:, p])
        if times.size == 0:
            continue  # never observable: NaN
        v = np.ascontiguousarray(limiting_mag[times, p, :].T)  # (band, observable times)
        if np.isnan(v).any():
            with np.errstate(all="ignore"), warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # a band with no finite limit: NaN
                best[p], median[p] = np.nanmax(v, axis=-1), np.nanmedian(v, axis=-1)
        else:
            best[p], median[p] = v.max(axis=-1), np.median(v, axis=-1)
    return best, median


def observable_fraction(observable) -> np.ndarray:
    """(time, pixel) bool -> the fraction of times observable per pixel, float32.

    Parameters
    ----------
    observable : array_like of bool, shape (n_time, n_pixel)
        Whether each pointing satisfies every constraint.

    Returns
    -------
    ndarray of float32, shape (n_pixel,)
        Fraction of the times observable, in [0, 1].
    """
    return np.asarray(observable, dtype=bool).mean(axis=0).astype(np.float32)


#: pixels per task of the per-pixel summaries, which need every time of a pixel at once: a
#: month at 5-minute cadence, 7 bands, float32 is 62 MB per task
SUMMARY_PIXELS_PER_TASK = 256
#: limits.zarr's per-pixel summaries (pixel, band), and its (pixel) observable fraction
SUMMARY_VARIABLES = ("limiting_mag_best", "limiting_mag_median", "observable_fraction")


#: decoded bytes of limits per task of :func:`store_limit_summaries` at most (a month at
#: 5-minute cadence x 660 pixels x 7 bands, float32, is 160 MB: one cube pixel block a task)
SUMMARY_TASK_BYTES = 256 * 2**20
#: decoded bytes of limits that justify one more process for the summaries: a spawned process's
#: start (importing straylight) costs as much CPU as decoding and summarising several hundred MB
#: of limits, so a month at nside 32 (1.3 GB) is summarised in the job's own process (the
#: figures: docs/performance.md)
SUMMARY_BYTES_PER_PROCESS = 2 * 2**30


def summary_processes(n_limits: int, workers: int) -> int:
    """How many processes :func:`store_limit_summaries` uses for ``n_limits`` float32 limits
    (times x pixels x bands): one per SUMMARY_BYTES_PER_PROCESS decoded, ``workers`` at most
    (rule limits asks that many cores).

    Parameters
    ----------
    n_limits : int
        Number of float32 limits in the store (times x pixels x bands).
    workers : int
        Most processes allowed.

    Returns
    -------
    int
        Processes to use, in [1, max(1, workers)].
    """
    return max(1, min(int(workers), -(-int(n_limits) * 4 // SUMMARY_BYTES_PER_PROCESS)))


def _store_summary_task(store: str, pixels: slice) -> tuple:
    """The per-pixel summaries of ``pixels`` of a limits store: every time, decoded at once."""
    import zarr

    from straylight.storage.zarr_io import read_region

    group = zarr.open_group(str(store), mode="r", use_consolidated=False)
    observable = read_region(group["observable"], (slice(None), pixels))
    best, median = limit_summaries(read_region(group["limiting_mag"], (slice(None), pixels)), observable)
    envelope = {
        median_name: limit_summaries(read_region(group[name], (slice(None), pixels)), observable)[1]
        for name, median_name in (*ENVELOPE_VARIABLES.values(), *BUDGET_VARIABLES.values())
        if name in group
    }
    pess = ENVELOPE_VARIABLES["pessimistic"][0]
    if pess in group and SHIFT_PERCENTILES[90] in group:
        nominal = read_region(group["limiting_mag"], (slice(None), pixels))
        envelope.update(
            shift_percentiles(read_region(group[pess], (slice(None), pixels)), nominal, observable)
        )
    return pixels, best, median, observable_fraction(observable), envelope


def store_limit_summaries(store, workers: int = 1) -> dict:
    """The per-pixel summaries (SUMMARY_VARIABLES -> array) of the limits in ``store`` (a limits
    store the cube's workers filled: ``limiting_mag`` and ``observable``), streamed over its
    pixel blocks (each split so a task decodes at most SUMMARY_TASK_BYTES) in this process and,
    for every SUMMARY_BYTES_PER_PROCESS of limits beyond the first, one more spawned process,
    ``workers`` processes at most.

    Parameters
    ----------
    store : str or path-like
        Zarr limits store with ``limiting_mag`` (time, pixel, band), mag(AB), and ``observable``
        (time, pixel), bool.
    workers : int, optional
        Most processes to use.

    Returns
    -------
    dict of str to ndarray
        ``limiting_mag_best`` and ``limiting_mag_median``: float32, shape (n_pixel, n_band),
        mag(AB), NaN where never observable; ``observable_fraction``: float32, shape (n_pixel,);
        and where the store has the envelope's per-sample limits,
        ``limiting_mag_median_pessimistic`` and ``limiting_mag_median_optimistic`` (pixel,
        band), as the median; where it has the budget's, ``limiting_mag_median_p16`` and
        ``_p84``; and the pessimistic end's ``limiting_mag_shift_p90`` and ``_p99`` (mag).
    """
    import zarr

    from straylight.execution import spawned_pool

    store = str(store)
    lim = zarr.open_group(store, mode="r", use_consolidated=False)["limiting_mag"]
    n_time, n_pix, n_band = lim.shape
    block = int(lim.chunks[1])
    per_pixel = max(1, n_time * n_band * lim.dtype.itemsize)
    parts = max(1, -(-block * per_pixel // SUMMARY_TASK_BYTES))
    step = max(1, -(-block // parts))
    tasks = [
        slice(a, min(a + step, b0 + block, n_pix))
        for b0 in range(0, n_pix, block)
        for a in range(b0, min(b0 + block, n_pix), step)
    ]
    out = {
        "limiting_mag_best": np.full((n_pix, n_band), np.nan, np.float32),
        "limiting_mag_median": np.full((n_pix, n_band), np.nan, np.float32),
        "observable_fraction": np.zeros(n_pix, np.float32),
    }
    group = zarr.open_group(store, mode="r", use_consolidated=False)
    for name, median_name in (*ENVELOPE_VARIABLES.values(), *BUDGET_VARIABLES.values()):
        if name in group:
            out[median_name] = np.full((n_pix, n_band), np.nan, np.float32)
    if ENVELOPE_VARIABLES["pessimistic"][0] in group and SHIFT_PERCENTILES[90] in group:
        for name in SHIFT_PERCENTILES.values():
            out[name] = np.full((n_pix, n_band), np.nan, np.float32)

    def keep(result):
        pixels, best, median, frac, envelope = result
        out["limiting_mag_best"][pixels], out["limiting_mag_median"][pixels] = best, median
        out["observable_fraction"][pixels] = frac
        for name, values in envelope.items():
            out[name][pixels] = values

    processes = min(summary_processes(n_time * n_pix * n_band, workers), len(tasks))
    if processes == 1:
        for pixels in tasks:
            keep(_store_summary_task(store, pixels))
        return out
    # this process takes its share from the front while the spawned ones start
    own = len(tasks) // processes
    with spawned_pool(processes - 1) as pool:
        futures = [pool.submit(_store_summary_task, store, pixels) for pixels in tasks[own:]]
        for pixels in tasks[:own]:
            keep(_store_summary_task(store, pixels))
        for fut in futures:
            keep(fut.result())
    return out


#: the summaries' chunks: every time of SUMMARY_PIXELS_PER_TASK pixels at a time
_WHOLE_TIMES = {"time": -1, "pixel": SUMMARY_PIXELS_PER_TASK}


def _best_and_median(lim, observable):  # (pixel, band, time), (pixel, 1, time) -> (pixel, band, 2)
    best, median = limit_summaries(np.moveaxis(lim, -1, 0), np.moveaxis(observable[:, 0, :], -1, 0))
    return np.stack([best, median], axis=-1)


def _fraction(observable):  # (pixel, time) -> (pixel,)
    return observable_fraction(np.moveaxis(observable, -1, 0))


def _summarise(limits, obs_t):
    """(time, pixel, band) limits, mag(AB) -> (pixel, band, stat): best and median over the
    observable times (``obs_t``, chunked as ``limits``)."""
    import xarray as xr

    return xr.apply_ufunc(
        _best_and_median,
        limits,
        obs_t,
        input_core_dims=[["time"], ["time"]],
        output_core_dims=[["stat"]],
        dask="parallelized",
        output_dtypes=[np.float32],
        dask_gufunc_kwargs={"output_sizes": {"stat": 2}},
    )


def _envelope_and_budget(campaign: Campaign, background, exposures, given: tuple, chunked: tuple, lazy: bool):
    """:func:`limits_dataset`'s envelope and budget: each end's and each budget percentile's
    (limits, median) (:func:`_with_medians`) and the pessimistic end's shift percentiles (None
    without it); ``given`` (envelope, budget limits) already computed or None, ``chunked`` the
    nominal limits and the observable chunked for the summaries."""
    bands = [str(b) for b in background["band"].values]
    envelope_limits, budget_limits = given
    lim_t, obs_t = chunked
    envelope_lim = (
        background_envelope_limits(campaign, background, bands, exposures)
        if envelope_limits is None
        else dict(envelope_limits)
    )
    envelope = _with_medians(envelope_lim, obs_t, lazy)
    budget_lim = (
        background_budget_limits(campaign, background, bands, exposures)
        if budget_limits is None
        else dict(budget_limits)
    )
    budget = _with_medians(budget_lim, obs_t, lazy)
    shifts = None
    if "pessimistic" in envelope_lim:
        shifts = _shifts(envelope_lim["pessimistic"], lim_t, obs_t, lazy)
    return envelope, budget, shifts


def _nominal_limits(background, exposures):
    """(time, pixel, band) limits, mag(AB), from background.zarr's ``total`` (e-/s/pix)."""
    import xarray as xr

    return xr.apply_ufunc(
        lambda t: band_limits(t, exposures),
        background["total"],
        dask="parallelized",
        output_dtypes=[np.float32],
    )


def _fraction_of_times(obs_t, chunks):
    """(pixel,) the observable fraction of the times, float32; chunked as the cube's pixel
    blocks (the observable's ``chunks``) when lazy."""
    import xarray as xr

    frac = xr.apply_ufunc(
        _fraction, obs_t, input_core_dims=[["time"]], dask="parallelized", output_dtypes=[np.float32]
    )
    if chunks is not None:
        with dask_rechunk_by_tasks():
            frac = frac.chunk({"pixel": chunks[1]})
    return frac


def _with_medians(limits_by_key: dict, obs_t, lazy: bool) -> dict:
    """Each key's (time, pixel, band) limits with their median over observable times (pixel, band)."""
    out = {}
    for key, key_lim in limits_by_key.items():
        with dask_rechunk_by_tasks():
            key_t = key_lim.chunk(_WHOLE_TIMES) if lazy else key_lim
        out[key] = (key_lim, _summarise(key_t, obs_t).isel(stat=1).transpose("pixel", "band"))
    return out


def _shifts(pessimistic, lim_t, obs_t, lazy: bool) -> dict:
    """The pessimistic end's shift percentiles (:data:`SHIFT_PERCENTILES`) -> (pixel, band), mag."""
    import xarray as xr

    with dask_rechunk_by_tasks():
        pess_t = pessimistic.chunk(_WHOLE_TIMES) if lazy else pessimistic

    def percentiles(pess, nominal, observable):  # (pixel, band, time) x2, (pixel, 1, time)
        out = shift_percentiles(
            np.moveaxis(pess, -1, 0), np.moveaxis(nominal, -1, 0), np.moveaxis(observable[:, 0, :], -1, 0)
        )
        return np.stack([out[SHIFT_PERCENTILES[q]] for q in sorted(SHIFT_PERCENTILES)], axis=-1)

    stacked = xr.apply_ufunc(
        percentiles,
        pess_t,
        lim_t,
        obs_t,
        input_core_dims=[["time"], ["time"], ["time"]],
        output_core_dims=[["q"]],
        dask="parallelized",
        output_dtypes=[np.float32],
        dask_gufunc_kwargs={"output_sizes": {"q": len(SHIFT_PERCENTILES)}},
    )
    return {
        SHIFT_PERCENTILES[q]: stacked.isel(q=i).transpose("pixel", "band")
        for i, q in enumerate(sorted(SHIFT_PERCENTILES))
    }


def limits_dataset(
    campaign: Campaign,
    background,
    limiting_mag=None,
    envelope_limits=None,
    per_sample_envelope=False,
    budget_limits=None,
) -> "xr.Dataset":
    """(time, pixel, band) 5-sigma limits from background.zarr's ``total``, plus per-pixel
    campaign summaries over observable times (best, median) and the observable fraction.
    Pixels never observable get NaN in the summaries (the HEALPix FITS maps turn it into
    healpy's UNSEEN: :func:`write_limit_maps`).  A float sentinel here would pass as a
    magnitude: a plot's colour range or a mean over pixels would take -1.6e30 mag.

    ``background`` may be lazy (``xr.open_zarr``): the result is then lazy too, and writing it
    streams over the cube's chunks (the limits chunk by chunk, the summaries
    SUMMARY_PIXELS_PER_TASK pixels at a time over all times) instead of holding the campaign.
    ``limiting_mag``: the (time, pixel, band) limits already computed (e.g. decoded from a
    limits store), summarised instead of computing them from ``total``.

    The pipeline's limits rule writes the same dataset from the limits the cube's workers
    computed (:func:`straylight.cube.store.init_limits_store`,
    :func:`straylight.cube.store.publish_work_store`).

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign (survey exposures, zero points).
    background : xarray.Dataset
        background.zarr's dataset (eager or lazy): ``total`` (time, pixel, band) in e-/s/pix,
        ``observable`` (time, pixel) bool, the ``time``, ``pixel``, ``ra_deg``, ``dec_deg`` and
        ``band`` coordinates and the HEALPix and campaign attributes.
    limiting_mag : xarray.DataArray, optional
        (time, pixel, band) limits already computed, mag(AB); None: computed from ``total``.
    envelope_limits : dict, optional
        The envelope's ends -> their (time, pixel, band) limits already computed (as a limits
        work store holds them), mag(AB); None: computed from ``total`` and the parts.
    per_sample_envelope : bool, optional
        Whether the result holds the envelope's and the budget's per-sample limits too (the
        limits work store's skeleton: the cube's workers write them, the product keeps their
        medians only).
    budget_limits : dict, optional
        The depth budget's ``p16``/``p84`` -> their (time, pixel, band) limits already computed,
        mag(AB); None: computed from ``total`` and the parts
        (:func:`~straylight.limits.budget.background_budget_limits`).

    Returns
    -------
    xarray.Dataset
        limits.zarr's dataset: ``limiting_mag`` (time, pixel, band), ``limiting_mag_best`` and
        ``limiting_mag_median`` (pixel, band), all float32 mag(AB); ``observable_fraction``
        (pixel,) float32; ``observable`` (time, pixel); band coordinates ``mag_zero_point``
        (AB mag/arcsec2), ``n_exposures`` and ``exposure_s`` (s).
    """
    bands = [str(b) for b in background["band"].values]
    exposures = campaign_exposures(campaign, bands)

    lim = _nominal_limits(background, exposures) if limiting_mag is None else limiting_mag
    observable = background["observable"]
    lazy = lim.chunks is not None or observable.chunks is not None
    # dask's task rechunk, named: left to choose, dask imports distributed to look for a
    # cluster (a slow import in every process that lays down a skeleton)
    with dask_rechunk_by_tasks():
        lim_t, obs_t = (
            (lim.chunk(_WHOLE_TIMES), observable.chunk(_WHOLE_TIMES)) if lazy else (lim, observable)
        )
    summary = _summarise(lim_t, obs_t)
    frac = _fraction_of_times(obs_t, observable.chunks)
    given = (envelope_limits, budget_limits)
    envelope, budget, shifts = _envelope_and_budget(
        campaign, background, exposures, given, (lim_t, obs_t), lazy
    )
    ds = _limits_product(campaign, background, lim, summary, frac, observable, exposures)
    ds = with_envelope(ds, envelope, per_sample_envelope)
    return with_budget(ds, budget, shifts, per_sample_envelope)


def _limits_product(
    campaign: Campaign, background, lim, summary, frac, observable, exposures
) -> "xr.Dataset":
    """limits.zarr's dataset (variables, coordinates and attributes) from its variables' data
    (``summary``: (pixel, band, stat), the best and the median limit)."""
    import xarray as xr

    best = summary.isel(stat=0).transpose("pixel", "band")
    median = summary.isel(stat=1).transpose("pixel", "band")
    bands = [str(b) for b in background["band"].values]
    inst = campaign.instrument_settings.bands
    desc = ", ".join(f"{b}: {inst[b].n_exposures} x {inst[b].exposure_s} s" for b in bands)
    data = lambda v: getattr(v, "data", v)  # noqa: E731 - an xarray object's array, or the array
    return xr.Dataset(
        {
            "limiting_mag": (
                ("time", "pixel", "band"),
                data(lim),
                {
                    "units": "mag(AB)",
                    "long_name": f"5-sigma point-source limit in the EE80 aperture ({desc})",
                },
            ),
            "limiting_mag_best": (
                ("pixel", "band"),
                data(best),
                {
                    "units": "mag(AB)",
                    "long_name": "deepest limit over observable times (NaN: never observable)",
                },
            ),
            "limiting_mag_median": (
                ("pixel", "band"),
                data(median),
                {
                    "units": "mag(AB)",
                    "long_name": "median limit over observable times (NaN: never observable)",
                },
            ),
            "observable_fraction": (
                ("pixel",),
                data(frac),
                {"units": "1", "long_name": "fraction of campaign times observable"},
            ),
            "observable": (
                ("time", "pixel"),
                data(observable),
                {"units": "1", "long_name": "pointing satisfies every constraint"},
            ),
        },
        coords={
            **{k: background[k] for k in ("time", "pixel", "ra_deg", "dec_deg", "band")},
            ZERO_POINT_NAME: zero_point_coord(campaign, bands),
            "n_exposures": (
                "band",
                np.array([x.n_exposures for x in exposures], np.int32),
                {"units": "1", "long_name": "survey exposures per field"},
            ),
            "exposure_s": (
                "band",
                np.array([x.exposure_s for x in exposures], np.float64),
                {"units": "s", "long_name": "duration of one survey exposure"},
            ),
        },
        attrs={
            k: background.attrs[k] for k in ("healpix_nside", "healpix_ordering", "healpix_frame", "campaign")
        },
    )
