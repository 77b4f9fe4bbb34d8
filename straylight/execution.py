"""Execution policy, one layer above ``straylight.util``: worker processes' environment (threads,
malloc settings), a pool of spawned ones, ending a process without the interpreter's teardown,
and the hygiene of a process tree (a process that dies with its parent; SIGINT and SIGTERM
stopping a pool's workers).  The cube's region pool built on them (or on an existing Dask
cluster, ``compute.dask_scheduler``) is :func:`straylight.cube.executors.region_pool`."""

from __future__ import annotations

import os
import signal
import sys
from contextlib import contextmanager

__all__ = [
    "WORKER_MALLOC_MMAP_THRESHOLD",
    "WORKER_MALLOC_TRIM_THRESHOLD",
    "available_cores",
    "worker_environment",
    "temporary_environment",
    "spawned_pool",
    "PARENT_POLL_SECONDS",
    "die_with_parent",
    "Stopped",
    "kill_pool_workers",
    "REPEATED_SIGNAL_SECONDS",
    "stop_on_signals",
    "exit_without_teardown",
    "dask_rechunk_by_tasks",
]

#: glibc malloc settings for worker processes (bytes), see worker_environment
WORKER_MALLOC_MMAP_THRESHOLD = 32 * 2**20
WORKER_MALLOC_TRIM_THRESHOLD = 256 * 2**20


def available_cores() -> int:
    """The CPUs this process may run on (its affinity: a cluster job's or taskset's share)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # no affinity on this platform
        return os.cpu_count() or 1


def worker_environment() -> dict:
    """Environment variables of a worker process (read by glibc and the BLAS libraries at the
    process's start).  One thread per worker for OpenMP, MKL and OpenBLAS, as Dask's nanny sets
    them: the workers are the parallelism.  Dask starts workers with MALLOC_TRIM_THRESHOLD_=65536,
    which also freezes glibc's mmap threshold at 128 KiB: every array temporary of the earthshine
    sum (~10 MB) is then mmapped and page-faulted afresh, making the cube several times slower in
    a worker than in a plain process (docs/performance.md).
    Temporaries up to 32 MiB come from the heap instead, and only more than 256 MiB of free
    heap is handed back."""
    return {
        "OMP_NUM_THREADS": "1",
        "MKL_NUM_THREADS": "1",
        "OPENBLAS_NUM_THREADS": "1",
        "MALLOC_MMAP_THRESHOLD_": str(WORKER_MALLOC_MMAP_THRESHOLD),
        "MALLOC_TRIM_THRESHOLD_": str(WORKER_MALLOC_TRIM_THRESHOLD),
    }


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
    interpreter's teardown (:func:`exit_without_teardown`), which the pool's shutdown waits for.

    The workers die with this process (:func:`die_with_parent`, SIGKILL: whatever they were
    writing is redone by a re-run, the stores being written through temporary files) and ignore
    SIGINT (a Ctrl-C reaches the terminal's whole process group: this process decides).  All of
    them are started here, from the thread that opens the pool, which outlives it (Linux sends
    the parent-death signal when the creating *thread* ends).  Left by :class:`Stopped` or
    KeyboardInterrupt, the pool kills its workers instead of waiting for their running tasks."""
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    n = int(max_workers)
    with (
        temporary_environment(worker_environment()),
        ProcessPoolExecutor(
            max_workers=n,
            mp_context=get_context("spawn"),
            initializer=_pool_worker_start,
            initargs=(initializer, initargs, os.getpid()),
        ) as pool,
    ):
        try:
            for _ in range(n):
                pool.submit(os.getpid)  # a spawned process starts at a submission that finds none idle
            yield pool
        except (Stopped, KeyboardInterrupt):
            kill_pool_workers(pool)
            raise


def _pool_worker_start(initializer, initargs: tuple, parent_pid: int | None = None) -> None:
    """A :func:`spawned_pool` process's start: SIGKILL when its parent (``parent_pid``) dies,
    SIGINT ignored, its exit made immediate, then ``initializer``.  The pool's tasks have
    returned their results, and closed the files they wrote, before the process exits."""
    import atexit

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent(signal.SIGKILL, parent_pid)
    atexit.register(exit_without_teardown)  # the last registered runs first: nothing after it
    if initializer is not None:
        initializer(*initargs)


#: prctl(2)'s option setting the signal a process gets when its parent dies (linux/prctl.h)
_PR_SET_PDEATHSIG = 1
#: seconds between two looks at the parent where prctl is not available
PARENT_POLL_SECONDS = 1.0


def die_with_parent(sig: int = signal.SIGTERM, parent_pid: int | None = None) -> None:
    """Have this process receive ``sig`` when its parent process dies, so that a killed
    Snakemake, job or pool leaves no orphan still computing and writing to the stores.
    ``parent_pid``: the parent it was started by (None: the present one); a parent already gone
    sends ``sig`` at once.

    On Linux the kernel sends it (prctl PR_SET_PDEATHSIG), at the moment the parent's thread
    that started this process ends, which for a process started from the main thread, or from a
    thread waiting for it (Snakemake's job threads), is the parent's death.  Elsewhere, or if
    prctl fails, a daemon thread looks at the parent every :data:`PARENT_POLL_SECONDS`."""
    parent = os.getppid() if parent_pid is None else int(parent_pid)
    watched = False
    if sys.platform.startswith("linux"):
        import ctypes

        try:
            watched = ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0) == 0
        except (OSError, AttributeError):  # no prctl in this libc
            watched = False
    if not watched:
        import threading

        threading.Thread(
            target=_watch_parent, args=(parent, int(sig)), daemon=True, name="die-with-parent"
        ).start()
    if os.getppid() != parent:  # died before the signal was armed: reparented already
        os.kill(os.getpid(), sig)


def _watch_parent(parent: int, sig: int) -> None:
    import time

    while os.getppid() == parent:
        time.sleep(PARENT_POLL_SECONDS)
    os.kill(os.getpid(), sig)


class Stopped(BaseException):
    """Raised in the main thread by :func:`stop_on_signals`' handler: the process was asked to
    stop (SIGINT, SIGTERM; ``signum``).  A BaseException, as KeyboardInterrupt, so that no
    ``except Exception`` takes it for a task's failure."""

    def __init__(self, signum: int):
        super().__init__(f"stopped by {signal.Signals(signum).name}")
        self.signum = int(signum)


def kill_pool_workers(pool) -> None:
    """SIGKILL every worker process of the ``ProcessPoolExecutor`` ``pool`` now, without waiting
    for them (safe in a signal handler: no lock taken).  Their running tasks end unfinished, and
    the pool's manager thread, finding them gone, fails their futures (BrokenProcessPool), so a
    shutdown of the pool returns at once instead of after the running tasks."""
    for pid in list(getattr(pool, "_processes", None) or {}):
        try:
            os.kill(pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):  # gone already
            pass


#: seconds within which stop_on_signals takes a further signal for a repeat of the first
REPEATED_SIGNAL_SECONDS = 2.0


@contextmanager
def stop_on_signals(signals=(signal.SIGINT, signal.SIGTERM)):
    """SIGINT and SIGTERM stop this process cleanly: at the first one the workers of every pool
    put in the yielded list are killed (:func:`kill_pool_workers`) and :class:`Stopped` is raised
    in the main thread, so that the ``with`` blocks unwind (the queued tasks cancelled, nothing
    marked done that was not) and the caller exits non-zero (128 + the signal's number, as a
    shell reports a process killed by it).  A further signal within :data:`REPEATED_SIGNAL_SECONDS`
    is ignored: the kernel sends the parent-death signal (:func:`die_with_parent`) again as each
    thread of a dying parent exits, which must not cut the unwinding short; a later one (a second
    Ctrl-C) ends the process at once.  Only in the main thread (Python runs signal handlers
    there)."""
    import time

    pools: list = []
    first: list = []

    def handler(signum, frame):
        for pool in pools:
            kill_pool_workers(pool)
        if first:
            if time.monotonic() - first[0] > REPEATED_SIGNAL_SECONDS:
                exit_without_teardown(128 + signum)
            return
        first.append(time.monotonic())
        raise Stopped(signum)

    previous = {s: signal.signal(s, handler) for s in signals}
    try:
        yield pools
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


def exit_without_teardown(code: int = 0) -> None:
    """End this process now with status ``code``: logging's handlers and the standard streams
    flushed, then ``os._exit``, skipping the interpreter's teardown of its modules and objects,
    which is slow in a process that has loaded the model, xarray or matplotlib and which a
    Snakemake job's or a pool's caller would wait for (docs/performance.md).  Only once
    the process's work is done: every file it wrote closed (and renamed into place), every
    child process joined."""
    import logging

    logging.shutdown()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # closed or gone: nothing left to flush
            pass
    os._exit(code)


def dask_rechunk_by_tasks():
    """A context in which dask rechunks by tasks, its choice outside a distributed cluster, without
    importing distributed (a slow import) to find that out."""
    import dask

    return dask.config.set({"array.rechunk.method": "tasks"})
