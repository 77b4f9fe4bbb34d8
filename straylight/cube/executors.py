"""Where the cube's regions run: a pool of local worker processes, an existing Dask cluster, or
this process.

A worker keeps what it needs from one region to the next in a :class:`WorkerState`: the job's
campaign, footprint, star catalog and stores, the background model and the off-field stars
built once, and the stores' arrays opened once.  A pool's workers are started by
:func:`start_worker` (the job's campaign and footprint sent to each) or, for a pool started
before the job has loaded its campaign (:func:`start_region_workers`), by
:func:`start_worker_from_config`; each then builds the model once, at its start, for every
region it computes.  A Dask worker keeps the state of its last job between tasks and jobs
(:func:`_dask_region`).  :func:`region_pool` hands the regions to one of these.

This module imports nothing beyond the standard library at its top: a cube job starts its
workers from here first, and they load the campaign and build the model while the job imports
and loads its own.
"""

from __future__ import annotations

import time as _time
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from straylight.cube.layout import CubeStores

if TYPE_CHECKING:
    from straylight.config import Campaign
    from straylight.cube.footprint import Footprint
    from straylight.cube.store import StoreArrays

__all__ = [
    "Execution",
    "WorkerState",
    "region_pool",
    "start_region_workers",
    "start_worker",
    "start_worker_from_config",
    "write_region",
]


@dataclass
class Execution:
    """How the cube's regions run (:func:`region_pool`): on the Dask cluster at
    ``scheduler_address`` when given; else on ``pool``, worker processes already started for
    the job's stores (:func:`start_region_workers`); else on ``workers`` processes started for
    the job (each building the model once), in this process when ``workers`` is 1.
    ``workers`` also bounds the regions in flight.

    Attributes
    ----------
    workers : int
        Worker processes (1: this process); the regions in flight are at most 2 x workers + 1.
    scheduler_address : str or None
        Address of a running Dask scheduler (e.g. ``"tcp://host:8786"``); None: no cluster.
    pool : concurrent.futures.Executor or None
        Workers already started by :func:`start_region_workers`; None: none.
    """

    workers: int = 1
    scheduler_address: str | None = None
    pool: Any = None


class WorkerState:
    """What a process computing the cube's regions keeps from one region to the next: the
    job's ``campaign``, footprint ``fp``, ``stores`` (:class:`CubeStores`) and star catalog at
    ``stars_path``, and, built on first use, the campaign's background model (with
    ``build_workers`` for an earthshine table it may build), the catalog's off-field stars and
    the stores' arrays opened for writing.

    Parameters
    ----------
    campaign : Campaign
        The job's loaded campaign.
    fp : Footprint
        The job's footprint.
    stores : CubeStores
        Where the regions are written (their skeletons laid down).
    stars_path : str or path-like, optional
        The star catalog; None: stars = 0.
    build_workers : int, optional
        Threads for an earthshine table the model may build.
    """

    def __init__(
        self, campaign: Campaign, fp: Footprint, stores: CubeStores, stars_path=None, build_workers: int = 1
    ):
        self.campaign, self.fp, self.stores, self.stars_path = campaign, fp, stores, stars_path
        self.build_workers = build_workers
        self._model = None
        self._stars = None
        self._stars_loaded = False
        self._arrays: StoreArrays | None = None

    @property
    def model(self):
        """The campaign's BackgroundModel: its door tables, bands and earthshine table built
        once for every region."""
        if self._model is None:
            from straylight.model import BackgroundModel

            self._model = BackgroundModel(self.campaign, build_workers=self.build_workers)
        return self._model

    @property
    def stars(self):
        """The catalog's off-field stars (:func:`~straylight.cube.region.offfield_stars`;
        None without a catalog), loaded once."""
        if not self._stars_loaded:
            from straylight.cube.region import offfield_stars

            self._stars, self._stars_loaded = offfield_stars(self.campaign, self.stars_path), True
        return self._stars

    def same_job(self, campaign: Campaign, fp: Footprint, stores: CubeStores, stars_path) -> bool:
        """Whether this state is for that job: the same campaign (compared by content: a
        campaign sent to a worker arrives pickled), footprint size, stores and catalog.

        Parameters
        ----------
        campaign : Campaign
            The job's campaign.
        fp : Footprint
            The job's footprint.
        stores : CubeStores
            The job's stores.
        stars_path : str or None
            The job's star catalog.

        Returns
        -------
        bool
            True when this state can compute that job's regions.
        """
        return (
            self.stores == stores
            and self.stars_path == stars_path
            and self.fp.pixels.size == fp.pixels.size
            and _campaign_key(self.campaign) == _campaign_key(campaign)
        )

    def prepare(self) -> WorkerState:
        """Build the model and load the stars now (a worker's start), not at the first region;
        returns this state.

        Returns
        -------
        WorkerState
            This state.
        """
        _ = self.model, self.stars  # each made at its first reading
        return self

    def warm_up(self) -> None:
        """Build every part of the model now (the tables read, the star cells listed, the compiled
        kernels loaded) by computing one sample, so that the first region does not wait for it."""
        import numpy as np

        from straylight.cube.region import RegionInputs, region_values

        # (the faint stars' map comes with each region: zeros here)
        faint = np.zeros((1, len(self.campaign.bands)))
        region_values(
            self.campaign, self.fp, slice(0, 1), slice(0, 1), self.model, RegionInputs(self.stars, faint)
        )

    def write_region(
        self, t_slice: slice, p_slice: slice, scene=None, faint_map=None, keep_arrays: bool = True
    ) -> float:
        """Compute one (time block, pixel block) region and write it to its part of the stores;
        seconds.  ``scene``: the time block's positions, shared by its pixel blocks (None:
        computed here); ``faint_map``: the cube's faint-star map at these pixels, (pixel, band)
        e-/s/pix, when the caller has read it (None: read from the store here when there is a
        star catalog).  The region's observability goes to the observability store and its
        limits, computed from its total, to the limits store, where those are given.  The
        stores' arrays are opened at the first region and kept for the next ones
        (``keep_arrays`` False: opened for this region alone, in this thread).  OutputError when
        the file system refuses.

        Parameters
        ----------
        t_slice, p_slice : slice
            The region: time indices into ``campaign.times`` and indices into the footprint's
            pixels (one chunk of the cube).
        scene : straylight.sky.observing.Scene, optional
            Satellite and body positions at exactly these times; None: computed here.
        faint_map : array_like, shape (n_pixel, n_band), optional
            The faint-star map at these pixels, e-/s/pix; None: read from the store if there
            is a catalog.
        keep_arrays : bool, optional
            Keep the stores' arrays open for the next regions (False: for this one alone).

        Returns
        -------
        float
            Wall-clock time to compute and write the region, s.

        Raises
        ------
        OutputError
            When the file system refuses to open or write the stores.
        ValueError
            When ``scene`` is not at exactly the region's times.
        """
        from straylight.cube.region import RegionInputs, region_values
        from straylight.cube.store import (
            open_stores,
            region_limits,
            region_write_error,
            stored_faint_map,
        )

        t0 = _time.perf_counter()
        stores = self.stores
        faint = faint_map
        if faint is None and self.stars_path is not None:
            faint = stored_faint_map(stores.cube)
            faint = None if faint is None else faint[p_slice]
        angles = None if stores.observability is None else {}
        inputs = RegionInputs(self.stars, faint, scene)
        region = region_values(self.campaign, self.fp, t_slice, p_slice, self.model, inputs, angles)
        lim = None if stores.limits is None else region_limits(self.campaign, region)
        try:
            arrays = self._arrays or open_stores(stores)
        except OSError as exc:  # ENOSPC, EDQUOT, EACCES...: the block's sentinel is not written
            raise region_write_error(stores, t_slice, p_slice, exc) from exc
        if keep_arrays:
            self._arrays = arrays
        arrays.write_region(t_slice, p_slice, region, angles, lim)
        return _time.perf_counter() - t0


def _campaign_key(campaign: Campaign) -> tuple:
    """What a campaign's model depends on: its configuration's content and its instrument file."""
    import json

    return json.dumps(campaign.config_mapping(), sort_keys=True, default=str), str(campaign.instrument_path)


def write_region(
    campaign: Campaign,
    fp: Footprint,
    stores,
    t_slice: slice,
    p_slice: slice,
    stars_path=None,
    scene=None,
    faint_map=None,
) -> float:
    """Compute one region and write it (:meth:`WorkerState.write_region`), the model built for
    it alone; seconds.  ``stores``: a :class:`CubeStores`, or the cube's store's path alone.

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign.
    fp : Footprint
        The footprint.
    stores : CubeStores or str or path-like
        The stores, or background.zarr's path alone.
    t_slice, p_slice, scene, faint_map
        As :meth:`WorkerState.write_region`.
    stars_path : str or path-like, optional
        The star catalog; None: stars = 0.

    Returns
    -------
    float
        Wall-clock time to compute and write the region, s.

    Raises
    ------
    OutputError
        When the file system refuses.
    """
    state = WorkerState(campaign, fp, CubeStores.of(stores), stars_path)
    return state.write_region(t_slice, p_slice, scene, faint_map)


#: this process's worker state: set by a pool worker's start, or kept by a Dask worker between
#: its tasks (None in a process that computes no region for a pool or a cluster)
_state: WorkerState | None = None


def start_worker(campaign: Campaign, fp: Footprint, stores: CubeStores, stars_path=None) -> WorkerState:
    """A pool worker's start: keep the job's inputs in this process's :class:`WorkerState` and
    build the model and load the stars now, once per process (every region this process
    computes reuses them).

    Parameters
    ----------
    campaign : Campaign
        The job's loaded campaign.
    fp : Footprint
        The job's footprint.
    stores : CubeStores
        The job's stores (absolute paths).
    stars_path : str, optional
        The star catalog (absolute path); None: stars = 0.

    Returns
    -------
    WorkerState
        This process's state, prepared.
    """
    global _state
    from straylight.sky.timeutil import ignore_dubious_years

    ignore_dubious_years()  # a spawned process starts without the job's filters; the campaign is checked
    _state = WorkerState(campaign, fp, stores, stars_path).prepare()
    return _state


def start_worker_from_config(config: dict, config_path: str, stores: CubeStores, stars_path) -> None:
    """A pool worker's start for workers started before the job has loaded its campaign
    (:func:`start_region_workers`): the campaign from the job's config, the footprint from the
    store's skeleton (:func:`~straylight.cube.footprint.footprint_from_store`), then
    :func:`start_worker`, then the model warmed up (:meth:`WorkerState.warm_up`) before the
    first region arrives.

    Parameters
    ----------
    config : dict
        The job's campaign config.
    config_path : str
        The config file's path (relative paths in the config are resolved against its folder).
    stores : CubeStores
        The job's stores (absolute paths; background.zarr's skeleton laid down).
    stars_path : str or None
        The star catalog (absolute path); None: stars = 0.
    """
    from straylight.config import campaign_from_dict
    from straylight.cube.footprint import footprint_from_store
    from straylight.sky.timeutil import ignore_dubious_years
    from straylight.util.healpix import load_without_plotting

    load_without_plotting()  # the star cells' healpy: a worker draws nothing
    ignore_dubious_years()  # the job's campaign, checked inside DE405 when the workflow was parsed
    campaign = campaign_from_dict(dict(config), config_path)
    fp = footprint_from_store(stores.cube)  # the skeleton's coordinates: no astropy frames, no cuts again
    start_worker(campaign, fp, stores, stars_path).warm_up()


def _worker_region(t_slice: slice, p_slice: slice, scene, faint_map) -> float:
    """One region in a pool worker, with the state its start kept; seconds."""
    return _state.write_region(t_slice, p_slice, scene, faint_map)


def _dask_region(
    campaign: Campaign,
    fp: Footprint,
    stores: CubeStores,
    stars_path,
    t_slice: slice,
    p_slice: slice,
    scene,
    faint_map,
) -> float:
    """One region on a Dask worker; seconds.  The worker's state is kept between tasks and jobs
    with the same inputs, so the model is built once per worker; the stores' arrays are opened
    for each region, in the thread that writes it (a Dask worker runs tasks in several threads)."""
    global _state
    if _state is None or not _state.same_job(campaign, fp, stores, stars_path):
        _state = WorkerState(campaign, fp, stores, stars_path)
    return _state.write_region(t_slice, p_slice, scene, faint_map, keep_arrays=False)


class InProcess:
    """An executor running each region at once in this process (one worker, no pool), with its
    own :class:`WorkerState`.

    Parameters
    ----------
    campaign, fp, stores, stars_path
        As :class:`WorkerState`.
    """

    def __init__(self, campaign: Campaign, fp: Footprint, stores: CubeStores, stars_path=None):
        self.state = WorkerState(campaign, fp, stores, stars_path).prepare()

    def submit_region(self, t_slice: slice, p_slice: slice, scene, faint_map):
        """The region's seconds as a finished future (its exception, if it failed).

        Parameters
        ----------
        t_slice, p_slice, scene, faint_map
            As :meth:`WorkerState.write_region`.

        Returns
        -------
        concurrent.futures.Future
            Done: its result the region's wall-clock time, s, or the exception raised.
        """
        from concurrent.futures import Future

        fut = Future()
        try:
            fut.set_result(self.state.write_region(t_slice, p_slice, scene, faint_map))
        except BaseException as exc:  # noqa: BLE001 - handed to the caller by fut.result()
            fut.set_exception(exc)
        return fut


@contextmanager
def region_pool(campaign: Campaign, fp: Footprint, stores: CubeStores, stars_path, execution: Execution):
    """Yield ``(submit, wait)`` for the cube's regions: ``submit(t_slice, p_slice, scene,
    faint_map)`` returns a future of the region's seconds (:meth:`WorkerState.write_region`),
    ``wait`` is the matching ``wait(futures, return_when=...)``; ``stores``: where each
    region goes (:class:`CubeStores`, absolute paths).  Where the regions run:

    * ``execution.scheduler_address``: on that Dask cluster (campaign and footprint sent to
      every worker once); its workers keep the model between regions, time blocks and jobs.
    * else ``execution.pool``: that pool of processes (:func:`start_region_workers`), left
      running.
    * else ``execution.workers`` > 1: a pool of that many spawned processes
      (:func:`~straylight.execution.spawned_pool`), each building the model once, at its
      start (:func:`start_worker`), for all the regions it computes.
    * else: in this process, one region after the other (:class:`InProcess`).

    Parameters
    ----------
    campaign : Campaign
        The job's loaded campaign.
    fp : Footprint
        The job's footprint.
    stores : CubeStores
        The job's stores, absolute paths.
    stars_path : str or None
        The star catalog, absolute path; None: stars = 0.
    execution : Execution
        Where the regions run.

    Yields
    ------
    submit : callable
        ``submit(t_slice, p_slice, scene, faint_map)`` -> future of the region's seconds.
    wait : callable
        ``wait(futures, return_when=...)`` for those futures (``concurrent.futures.wait`` or
        ``distributed.wait``).
    """
    from concurrent.futures import wait as wait_local

    if execution.scheduler_address:
        from distributed import Client
        from distributed import wait as wait_dask

        with Client(execution.scheduler_address, timeout="30s") as client:
            c_fut, fp_fut = client.scatter([campaign, fp], broadcast=True)

            def submit(t_slice, p_slice, scene, faint_map):
                return client.submit(
                    _dask_region,
                    c_fut,
                    fp_fut,
                    stores,
                    stars_path,
                    t_slice,
                    p_slice,
                    scene,
                    faint_map,
                    pure=False,
                )

            yield submit, wait_dask
        return
    if execution.pool is None and int(execution.workers) <= 1:
        yield InProcess(campaign, fp, stores, stars_path).submit_region, wait_local
        return
    with _own_pool(execution, campaign, fp, stores, stars_path) as pool:

        def submit(t_slice, p_slice, scene, faint_map):
            return pool.submit(_worker_region, t_slice, p_slice, scene, faint_map)

        try:
            yield submit, wait_local
        except BaseException:
            pool.shutdown(wait=True, cancel_futures=True)  # the queued regions are not run
            raise


@contextmanager
def _own_pool(execution: Execution, campaign, fp, stores, stars_path):
    """``execution.pool`` (left running), else a pool of ``execution.workers`` spawned processes
    started by :func:`start_worker` (shut down on leaving)."""
    if execution.pool is not None:
        yield execution.pool
        return
    from straylight.execution import spawned_pool

    with spawned_pool(execution.workers, start_worker, (campaign, fp, stores, stars_path)) as pool:
        yield pool


def start_region_workers(workers: int, config: dict, config_path, stores: CubeStores, stars_path=None):
    """A pool of ``workers`` spawned processes for
    :func:`~straylight.cube.run.run_time_blocks` (``Execution(pool=...)``), each loading
    the campaign of ``config`` (read from ``config_path``) and building the model as it starts
    (:func:`start_worker_from_config`), for ``stores`` and the catalog at ``stars_path``
    (resolved as run_time_blocks resolves them).  Returns the pool's context manager; its
    processes start at the first tasks submitted to it.

    Parameters
    ----------
    workers : int
        Processes in the pool.
    config : dict
        The job's campaign config.
    config_path : str or path-like
        The config file's path.
    stores : CubeStores
        The job's stores (resolved to absolute paths here).
    stars_path : str or path-like, optional
        The star catalog (resolved here); None: stars = 0.

    Returns
    -------
    contextlib.AbstractContextManager
        Enters to the pool (a :class:`concurrent.futures.Executor`) and shuts it down on leaving.
    """
    from pathlib import Path

    from straylight.execution import spawned_pool

    stars = str(Path(stars_path).resolve()) if stars_path else None
    init_args = (dict(config), str(config_path), stores.resolved(), stars)
    return spawned_pool(workers, start_worker_from_config, init_args)
