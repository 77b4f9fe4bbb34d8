"""Dask inside a pipeline job: an existing scheduler, or a LocalCluster sized from the job."""
from __future__ import annotations

from contextlib import contextmanager


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
    n = max(1, int(threads))
    mem = f"{int(mem_mb / n)}MiB" if mem_mb else "auto"
    with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, memory_limit=mem,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        yield client
