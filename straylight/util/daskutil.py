"""Workers for the cube's regions inside a pipeline job: a process pool started once per job,
or an existing Dask cluster (``compute.dask_scheduler``)."""
from __future__ import annotations

import os
from contextlib import contextmanager

#: glibc malloc settings for worker processes (bytes), see worker_environment
WORKER_MALLOC_MMAP_THRESHOLD = 32 * 2**20
WORKER_MALLOC_TRIM_THRESHOLD = 256 * 2**20


def worker_environment() -> dict:
    """Environment variables of a worker process (read by glibc and the BLAS libraries at the
    process's start).  One thread per worker for OpenMP, MKL and OpenBLAS, as Dask's nanny sets
    them: the workers are the parallelism.  Dask starts workers with MALLOC_TRIM_THRESHOLD_=65536,
    which also freezes glibc's mmap threshold at 128 KiB: every array temporary of the earthshine
    sum (~10 MB) is then mmapped and page-faulted afresh, making the cube 3x slower in a worker
    than in a plain process (measured: 8.3 s against 2.6 s per 330-pixel x 24-time chunk).
    Temporaries up to 32 MiB come from the heap instead, and only more than 256 MiB of free
    heap is handed back."""
    return {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
            "MALLOC_MMAP_THRESHOLD_": str(WORKER_MALLOC_MMAP_THRESHOLD),
            "MALLOC_TRIM_THRESHOLD_": str(WORKER_MALLOC_TRIM_THRESHOLD)}


@contextmanager
def _environment(values: dict):
    """``os.environ`` with ``values`` set, restored afterwards (children started inside inherit it)."""
    saved = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


@contextmanager
def region_pool(campaign, fp, store: str, stars_path, workers: int, scheduler_address: str | None = None,
                obs_store: str | None = None):
    """Yield ``(submit, wait)`` for the cube's regions: ``submit(t_slice, p_slice, scene,
    faint_map)`` returns a future of the region's seconds (:func:`straylight.survey.cube.write_region`),
    ``wait`` is the matching ``wait(futures, return_when=...)``; ``obs_store``: where each
    region's observability goes too (None: not written).

    * ``scheduler_address``: the regions run on that Dask cluster (campaign and footprint sent
      to every worker once); its workers keep the model between regions, time blocks and jobs.
    * else ``workers`` > 1: a pool of that many spawned processes (:func:`worker_environment`),
      each building the model once, at its start, for all the regions it computes.
    * else: in this process, one region after the other.
    """
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures import wait as wait_local
    from multiprocessing import get_context

    from straylight.survey import cube

    if scheduler_address:
        from distributed import Client
        from distributed import wait as wait_dask

        with Client(scheduler_address, timeout="30s") as client:
            c_fut, fp_fut = client.scatter([campaign, fp], broadcast=True)

            def submit(t_slice, p_slice, scene, faint_map):
                return client.submit(cube.write_region, c_fut, fp_fut, store, t_slice, p_slice, stars_path, scene,
                                     faint_map, None, obs_store, pure=False)

            yield submit, wait_dask
        return
    if int(workers) <= 1:
        yield cube._InProcess(campaign, fp, store, stars_path, obs_store).submit_region, wait_local
        return
    with _environment(worker_environment()), \
            ProcessPoolExecutor(max_workers=int(workers), mp_context=get_context("spawn"),
                                initializer=cube._pool_init, initargs=(campaign, fp, store, stars_path, obs_store)) as pool:
        def submit(t_slice, p_slice, scene, faint_map):
            return pool.submit(cube._pool_region, t_slice, p_slice, scene, faint_map)

        try:
            yield submit, wait_local
        except BaseException:
            pool.shutdown(wait=True, cancel_futures=True)
            raise


@contextmanager
def dask_client(scheduler_address: str | None, threads: int, mem_mb: int | None = None):
    """Yield a ``distributed.Client``: connected to ``scheduler_address`` when given, else to a
    LocalCluster of ``threads`` single-threaded worker processes sharing ``mem_mb`` (with
    :func:`worker_environment`)."""
    from distributed import Client, LocalCluster

    if scheduler_address:
        client = Client(scheduler_address, timeout="30s")
        try:
            yield client
        finally:
            client.close()
        return
    import dask

    n = max(1, int(threads))
    mem = f"{int(mem_mb / n)}MiB" if mem_mb else "auto"
    env = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}) or {})
    env.update(worker_environment())
    with dask.config.set({"distributed.nanny.pre-spawn-environ": env}), \
            LocalCluster(n_workers=n, threads_per_worker=1, processes=True, memory_limit=mem,
                         dashboard_address=None) as cluster, Client(cluster) as client:
        yield client
