"""Ending a process without the interpreter's teardown (execution.exit_without_teardown): the
job scripts' and the pool workers' last step; and the hygiene of a process tree: workers that die
with their parent (die_with_parent), SIGTERM and SIGINT stopping a pool (stop_on_signals).

Reference: the process's own log file and exit status, read by its parent; the processes' table
(psutil)."""

import subprocess
import sys
import time

import pytest


def test_exit_without_teardown_flushes_the_logs_and_skips_the_rest(tmp_path):
    """The status given, the log line written before it flushed to its file, and nothing of the
    interpreter's teardown run (an atexit handler registered earlier never writes)."""
    log, marker = tmp_path / "job.log", tmp_path / "teardown_ran"
    code = (
        "import atexit, logging, sys\n"
        f"atexit.register(lambda: open({str(marker)!r}, 'w').write('ran'))\n"
        f"logging.basicConfig(level=logging.INFO, handlers=[logging.FileHandler({str(log)!r})])\n"
        "logging.getLogger('job').info('products written')\n"
        "sys.stdout.write('unflushed stdout')\n"
        "from straylight.execution import exit_without_teardown\n"
        "exit_without_teardown(3)\n"
        "raise SystemExit('not reached')\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 3, r.stderr[-2000:]
    assert r.stdout == "unflushed stdout"
    assert log.read_text().strip() == "INFO:job:products written"
    assert not marker.exists()


def _write(path: str, n: int) -> int:
    with open(path, "w") as f:
        f.write("x" * n)
    return n


def test_spawned_pool_workers_end_after_their_tasks_complete(tmp_path):
    """A spawned pool's workers, which end without the teardown at the pool's shutdown, have
    returned every task's result and written every task's file by then."""
    from straylight.execution import spawned_pool

    paths = [tmp_path / f"part_{i}.txt" for i in range(6)]
    with spawned_pool(2) as pool:
        results = [f.result() for f in [pool.submit(_write, str(p), 1000 + i) for i, p in enumerate(paths)]]
        workers = list(pool._processes.values())
    assert results == [1000 + i for i in range(6)]
    assert [p.stat().st_size for p in paths] == results
    assert workers and all(w.exitcode == 0 for w in workers)


def _gone(pid: int) -> bool:
    import psutil

    try:
        return psutil.Process(pid).status() == psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return True


def _wait_gone(pids, seconds: float) -> list:
    import time

    t0 = time.monotonic()
    while not all(_gone(p) for p in pids) and time.monotonic() - t0 < seconds:
        time.sleep(0.05)
    return [p for p in pids if not _gone(p)]


def test_spawned_pool_workers_die_with_the_pools_process():
    """SIGKILL the process that opened a spawned pool while its workers run long tasks: the
    workers die with it (die_with_parent in the workers' start) instead of running on."""
    import os
    import signal

    code = (
        "import os, sys, time\n"
        "from straylight.execution import spawned_pool\n"
        "with spawned_pool(2) as pool:\n"
        "    futures = [pool.submit(time.sleep, 60) for _ in range(4)]\n"
        "    print(*pool._processes, flush=True)\n"
        "    time.sleep(60)\n"
    )
    owner = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    workers = [int(p) for p in owner.stdout.readline().split()]
    try:
        assert len(workers) == 2 and not any(_gone(p) for p in workers)
    finally:
        os.kill(owner.pid, signal.SIGKILL)
        owner.wait()
    left = _wait_gone(workers, 10.0)
    for p in left:
        os.kill(p, signal.SIGKILL)
    assert not left


@pytest.mark.parametrize("mechanism", ["prctl", "poll"])
def test_die_with_parent(mechanism):
    """A process that called die_with_parent gets its signal when its parent is SIGKILLed,
    through the kernel (Linux: prctl) or the polling thread used elsewhere; and at once when
    its parent was gone before the call."""
    import os
    import signal

    fake = "sys.platform = 'darwin'\n" if mechanism == "poll" else ""
    child = (
        "import signal, sys, time\n" + fake + "from straylight.execution import die_with_parent\n"
        "die_with_parent(signal.SIGTERM)\n"
        "time.sleep(60)\n"
    )
    parent = (
        "import subprocess, sys, time\n"
        f"c = subprocess.Popen([sys.executable, '-c', {child!r}])\n"
        "print(c.pid, flush=True)\n"
        "time.sleep(60)\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", parent], stdout=subprocess.PIPE, text=True)
    pid = int(proc.stdout.readline())
    time.sleep(1.0)  # the child's imports and its call
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    left = _wait_gone([pid], 10.0)
    for p in left:
        os.kill(p, signal.SIGKILL)
    assert not left

    code = (
        "import os, signal\n"
        + fake.replace("sys.", "__import__('sys').")
        + "from straylight.execution import die_with_parent\n"
        "die_with_parent(signal.SIGTERM, parent_pid=os.getppid() + 1)\n"  # not its parent: gone
        "import time; time.sleep(30)\n"
    )
    r = subprocess.run([sys.executable, "-c", code], timeout=60)
    assert r.returncode == -signal.SIGTERM


@pytest.mark.parametrize("signame", ["SIGTERM", "SIGINT"])
def test_stop_on_signals_kills_the_pools_workers_and_exits_non_zero(signame):
    """SIGTERM or SIGINT inside stop_on_signals with a spawned pool whose workers run 60 s
    tasks: the workers are killed, no task finishes (the queued ones cancelled, the running ones
    failed), Stopped reaches the caller (which here exits 128 + the signal's number, as the cube
    job does) within seconds, the pool's shutdown not waiting for the tasks."""
    import os
    import signal

    code = (
        "import sys, time\n"
        "from concurrent.futures import wait\n"
        "from straylight.execution import Stopped, exit_without_teardown, spawned_pool, stop_on_signals\n"
        "try:\n"
        "    with stop_on_signals() as stopping, spawned_pool(2) as pool:\n"
        "        stopping.append(pool)\n"
        "        futures = [pool.submit(time.sleep, 60) for _ in range(6)]\n"
        "        print(*pool._processes, flush=True)\n"
        "        wait(futures)\n"
        "except Stopped as stop:\n"
        "    ran = [f for f in futures if not f.cancelled() and f.exception(timeout=0) is None]\n"
        "    print(stop, len(ran), flush=True)\n"
        "    exit_without_teardown(128 + stop.signum)\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    workers = [int(p) for p in proc.stdout.readline().split()]
    time.sleep(1.0)  # the workers started, the first tasks running
    sig = getattr(signal, signame)
    t0 = time.monotonic()
    os.kill(proc.pid, sig)
    out, _ = proc.communicate(timeout=60)
    assert time.monotonic() - t0 < 10.0
    assert proc.returncode == 128 + sig
    said, ran = out.rsplit(" ", 1)
    assert (
        said.strip() == f"stopped by {signame}" and int(ran) == 0
    )  # each cancelled or failed, none finished
    assert len(workers) == 2 and not _wait_gone(workers, 5.0)
