"""Dask inside a pipeline job: an existing scheduler, or a LocalCluster sized from the job."""
from __future__ import annotations

from contextlib import contextmanager

#: glibc malloc settings for worker processes (bytes), see dask_client
WORKER_MALLOC_MMAP_THRESHOLD = 32 * 2**20
WORKER_MALLOC_TRIM_THRESHOLD = 256 * 2**20


@contextmanager
def dask_client(scheduler_address: str | None, threads: int, mem_mb: int | None = None):
    """Yield a ``distributed.Client``: connected to ``scheduler_address`` when given, else to a
    LocalCluster of ``threads`` single-threaded worker processes sharing ``mem_mb``."""
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
    # Dask starts workers with MALLOC_TRIM_THRESHOLD_=65536, which also freezes glibc's mmap
    # threshold at 128 KiB: every array temporary of the earthshine sum (~10 MB) is then mmapped
    # and page-faulted afresh, making the cube 3x slower in a worker than in a plain process
    # (measured: 8.3 s against 2.6 s per 330-pixel x 24-time chunk).  Temporaries up to 32 MiB
    # come from the heap instead, and only more than 256 MiB of free heap is handed back.
    env = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}) or {})
    env.update(MALLOC_MMAP_THRESHOLD_=WORKER_MALLOC_MMAP_THRESHOLD, MALLOC_TRIM_THRESHOLD_=WORKER_MALLOC_TRIM_THRESHOLD)
    with dask.config.set({"distributed.nanny.pre-spawn-environ": env}), \
            LocalCluster(n_workers=n, threads_per_worker=1, processes=True, memory_limit=mem,
                         dashboard_address=None) as cluster, Client(cluster) as client:
        yield client
