"""Ending a process without the interpreter's teardown (util.daskutil.exit_without_teardown): the
job scripts' and the pool workers' last step.

Reference: the process's own log file and exit status, read by its parent."""
import subprocess
import sys


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
        "from straylight.util.daskutil import exit_without_teardown\n"
        "exit_without_teardown(3)\n"
        "raise SystemExit('not reached')\n")
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
    from straylight.util.daskutil import spawned_pool

    paths = [tmp_path / f"part_{i}.txt" for i in range(6)]
    with spawned_pool(2) as pool:
        results = [f.result() for f in [pool.submit(_write, str(p), 1000 + i) for i, p in enumerate(paths)]]
        workers = list(pool._processes.values())
    assert results == [1000 + i for i in range(6)]
    assert [p.stat().st_size for p in paths] == results
    assert workers and all(w.exitcode == 0 for w in workers)
