"""Worker processes: their environment (threads, malloc settings), a pool of spawned ones, and
ending a process without the interpreter's teardown.
The cube's region pool built on them (or on an existing Dask cluster, ``compute.dask_scheduler``) is
:func:`straylight.survey.cube.region_pool`."""
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
def temporary_environment(values: dict):
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
def spawned_pool(max_workers: int, initializer=None, initargs: tuple = ()):
    """A ``ProcessPoolExecutor`` of ``max_workers`` spawned processes (not forked: none inherits
    this process's threads or open stores) started with :func:`worker_environment`.  Each runs
    ``initializer(*initargs)`` first and, once the pool shuts down, ends without the
    interpreter's teardown (:func:`exit_without_teardown`), which the pool's shutdown waits for."""
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    with temporary_environment(worker_environment()), \
            ProcessPoolExecutor(max_workers=int(max_workers), mp_context=get_context("spawn"),
                                initializer=_pool_worker_start, initargs=(initializer, initargs)) as pool:
        yield pool


def _pool_worker_start(initializer, initargs: tuple) -> None:
    """A :func:`spawned_pool` process's start: its exit made immediate, then ``initializer``.
    The pool's tasks have returned their results, and closed the files they wrote, before the
    process exits."""
    import atexit

    atexit.register(exit_without_teardown)  # the last registered runs first: nothing after it
    if initializer is not None:
        initializer(*initargs)


def exit_without_teardown(code: int = 0) -> None:
    """End this process now with status ``code``: logging's handlers and the standard streams
    flushed, then ``os._exit``, skipping the interpreter's teardown of its modules and objects,
    0.2-0.8 s in a process that has loaded the model, xarray or matplotlib (measured on the
    development machine) that a Snakemake job's or a pool's caller would wait for.  Only once
    the process's work is done: every file it wrote closed (and renamed into place), every
    child process joined."""
    import logging
    import sys

    logging.shutdown()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # closed or gone: nothing left to flush
            pass
    os._exit(code)


def call_by_name(target: str, *args):
    """Call ``target`` ("package.module:function") with ``args``, importing its module here: a
    pool's initializer named by a process that has not imported that module (spawned workers
    unpickle a function by importing its module; this one is light)."""
    from importlib import import_module

    module, name = target.split(":")
    return getattr(import_module(module), name)(*args)


def dask_rechunk_by_tasks():
    """A context in which dask rechunks by tasks, its choice outside a distributed cluster, without
    importing distributed to find that out (~0.3 s)."""
    import dask

    return dask.config.set({"array.rechunk.method": "tasks"})

