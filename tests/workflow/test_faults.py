"""Faults while writing: a disk that fills during a Zarr write.  The failure is one
clear error naming the store and region, finished time blocks keep their bytes, and re-running
the failed block gives a store bit-identical to an uninterrupted run.  And kills: Snakemake
killed in the middle of the cube leaves no process behind, and the resumed run's products are
bit-identical; the cube job stopped by SIGTERM or SIGINT stops its workers and exits non-zero."""

import errno

import pytest
from conftest import tiny_config

from straylight.config import load_campaign
from straylight.cube.footprint import footprint_from_config
from straylight.cube.provenance import sha256_path
from straylight.cube.run import run_time_blocks
from straylight.cube.store import init_store
from straylight.errors import OutputError


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("faults")
    path = tiny_config(
        tmp,
        name="faults",
        campaign={"end": "2026-01-01T01:00:00", "time_block_hours": 0.5},
        footprint={"pixel_block_size": 40},
    )
    # the faults are the store's: a coarser Earth grid (a quarter of the default's direct sum)
    # computes the same variables and chunks
    c = load_campaign(_with_earth_grid(path, 12, 24))
    fp = footprint_from_config(c.settings.footprint, c.path.parent)
    ref = tmp / "reference.zarr"
    init_store(c, fp, ref)
    run_time_blocks(c, fp, ref, [0, 1], tmp / "reference_done")
    return tmp, c, fp, sha256_path(ref)


def _files(store):
    return {str(p.relative_to(store)): p.read_bytes() for p in sorted(store.rglob("*")) if p.is_file()}


@pytest.mark.parametrize("fail_after_writes", [0, 2, 5, 11])
def test_disk_full_during_a_zarr_write_then_rerun(small, tmp_path, monkeypatch, fail_after_writes):
    import straylight.storage.zarr_io as storage

    _, c, fp, ref_digest = small
    store, done = tmp_path / "background.zarr", tmp_path / "done"
    init_store(c, fp, store)
    run_time_blocks(c, fp, store, [0], done)
    block0 = _files(store)

    # the workers' chunk files go through storage._write_file (storage.ChunkWriter)
    real_write = storage._write_file
    calls = {"n": 0}

    def full_disk_write(path, data):
        # worst case for a non-atomic file system: half the chunk reaches the disk, then ENOSPC
        calls["n"] += 1
        if calls["n"] > fail_after_writes:
            data = bytes(memoryview(data).cast("B"))
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data[: len(data) // 2])
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        return real_write(path, data)

    monkeypatch.setattr(storage, "_write_file", full_disk_write)
    with pytest.raises(OutputError) as err:
        run_time_blocks(c, fp, store, [0, 1], done)
    msg = str(err.value)
    assert str(store) in msg and "No space left on device" in msg and "re-run" in msg
    assert "times 3:6" in msg  # the failed block's region is named
    after = _files(store)
    # the finished block 0 is untouched: every file it wrote still has its bytes
    assert all(after.get(k) == v for k, v in block0.items() if "/c/0/" in k or k.endswith("zarr.json"))
    assert not (done / "block_1.json").exists()  # the failed block is not marked done
    monkeypatch.setattr(storage, "_write_file", real_write)  # space freed
    # and a chunk file a killed writer left half written (never renamed into place) in block 1
    partial = store / "total" / "c" / "1" / "0" / f"0.0123abcd{storage.PARTIAL_SUFFIX}"
    partial.parent.mkdir(parents=True, exist_ok=True)
    partial.write_bytes(b"half a chunk")
    run_time_blocks(c, fp, store, [0, 1], done)  # block 0 skipped (its sentinel), block 1 redone
    assert not partial.exists()
    assert sha256_path(store) == ref_digest


def test_job_script_reports_a_full_disk_in_one_line(tmp_path):
    """A job script's uncaught StraylightError, or OSError refusing a named file (here ENOSPC):
    one line "error: ..." on stderr and in the rule's log, exit status 2, no traceback
    (workflow/scripts/_common.setup_logging's hook); any other exception (a bug, a wrong path) keeps its
    traceback."""
    import subprocess
    import sys

    from conftest import REPO

    def job(raise_line):
        log = tmp_path / "rule.log"
        code = (
            "import errno, sys, types\n"
            f"sys.path.insert(0, {str(REPO / 'workflow' / 'scripts')!r})\n"
            "from _common import setup_logging\n"
            f"log = setup_logging(types.SimpleNamespace(log=[{str(log)!r}], rule='report_front'))\n"
            "log.info('started')\n"
            f"{raise_line}\n"
        )
        r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
        return r, log.read_text()

    r, log = job("raise OSError(errno.ENOSPC, 'No space left on device', '/results/x/summary.rst.tmp')")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    errors = [ln for ln in r.stderr.splitlines() if "error:" in ln]
    assert len(errors) == 1 and "/results/x/summary.rst.tmp: No space left on device" in errors[0]
    assert errors[0].split("straylight.report_front ", 1)[1] in log
    r, _ = job("from straylight.errors import InputError; raise InputError('gaia_0.csv.gz: row 3: ra = nan')")
    assert (
        r.returncode == 2
        and "Traceback" not in r.stderr
        and "error: gaia_0.csv.gz: row 3: ra = nan" in r.stderr
    )
    r, _ = job("raise ValueError('a bug')")
    assert r.returncode == 1 and "Traceback" in r.stderr and "ValueError: a bug" in r.stderr
    r, _ = job("open('/nonexistent/folder/file.png')")  # a wrong path is a bug, not the disk's refusal
    assert r.returncode == 1 and "Traceback" in r.stderr and "FileNotFoundError" in r.stderr


def _snakemake_cmd(workdir, cfg, name):
    """The workflow on ``cfg`` in ``workdir`` up to the cube's products the workers write: the
    background (with observability.zarr) and the limits (the figures and report left out)."""
    import sys
    from pathlib import Path

    from conftest import REPO

    snakemake = str(Path(sys.executable).with_name("snakemake"))
    base = [
        snakemake,
        "-s",
        str(REPO / "workflow" / "Snakefile"),
        "-d",
        str(workdir),
        "--configfile",
        str(cfg),
    ]
    # the targets after a fixed-arity option: --configfile would swallow them
    return base, base + [
        "--cores",
        "2",
        f"results/{name}/work/background_summary.json",
        f"results/{name}/limits.zarr",
        "--rerun-incomplete",
        "-q",
    ]


def _env():
    import os
    import sys
    from pathlib import Path

    return {**os.environ, "PATH": f"{Path(sys.executable).parent}:{os.environ['PATH']}"}


def _kill_campaign(folder):
    """The kill tests' campaign in ``folder``: 6 hours at 10 min in one-hour time blocks, 6
    time blocks x 3 pixel blocks, on the converged Earth grid (96 x 192, 16 times the default's
    cost per sample): the cube lasts well over 10 s after its first block (five blocks more), so
    that processes a killed run left behind would still be running when the test looks."""
    from conftest import tiny_config

    folder.mkdir()
    path = tiny_config(
        folder,
        name="killed",
        campaign={"end": "2026-01-01T06:00:00", "time_block_hours": 1},
        footprint={"pixel_block_size": 30},
    )
    return _with_earth_grid(path, 96, 192)


def _with_earth_grid(path, n_gamma: int, n_psi: int):
    """The campaign config at ``path`` with its earthshine summed directly on an Earth grid of
    n_gamma x n_psi (rewritten in place); returns ``path``."""
    import yaml

    cfg = yaml.safe_load(path.read_text())
    cfg["models"]["earthshine"].update(n_gamma=n_gamma, n_psi=n_psi, method="direct")
    path.write_text(yaml.safe_dump(cfg))
    return path


#: the kill tests' campaign's time blocks
N_KILL_BLOCKS = 6
#: the products the cube's workers write, compared with an uninterrupted run's
KILL_PRODUCTS = ("background.zarr", "observability.zarr", "limits.zarr", "maps")


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    """An uninterrupted run of the kill tests' campaign: its folder, config, and its products'
    SHA-256, taken at once (test_cube_job_stops_cleanly_on_a_signal reruns the cube in the
    folder afterwards)."""
    import subprocess

    folder = tmp_path_factory.mktemp("uninterrupted") / "run"
    cfg = _kill_campaign(folder)
    _, cmd = _snakemake_cmd(folder, cfg, "killed")
    r = subprocess.run(cmd, capture_output=True, text=True, env=_env(), timeout=900)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    return folder, cfg, {p: sha256_path(folder / "results" / "killed" / p) for p in KILL_PRODUCTS}


def _run_until_a_block_is_done(cmd, out, output):
    """Start Snakemake (``cmd``, its output to the file ``output``: a pipe would be held open
    by any process the run leaves behind) and return (its Popen, every process of the run seen
    so far as psutil knows it) once the cube job has marked a time block done (its sentinel),
    its workers then on the next block."""
    import subprocess
    import time

    import psutil

    with open(output, "w") as f:
        proc = subprocess.Popen(cmd, stdout=f, stderr=subprocess.STDOUT, env=_env())
    seen: dict = {}  # pid -> psutil.Process, which knows a reused pid is not its process
    snake = psutil.Process(proc.pid)
    deadline = time.monotonic() + 600
    try:
        while not list((out / "work" / "background_blocks").glob("block_*.json")):
            assert proc.poll() is None, "the run ended before the cube finished a time block"
            assert time.monotonic() < deadline, "no time block done in 600 s"
            for p in snake.children(recursive=True):
                seen.setdefault(p.pid, p)
            time.sleep(0.05)
        for p in snake.children(recursive=True):
            seen.setdefault(p.pid, p)
    except BaseException:
        proc.kill()
        proc.wait()
        raise
    return proc, seen


def _alive(processes, folder=None) -> dict:
    """pid -> process of ``processes`` still running (a zombie waiting for its reaper is not),
    and of any other process whose command line names ``folder``."""
    import os

    import psutil

    def running(p):
        try:
            return p.is_running() and p.status() != psutil.STATUS_ZOMBIE
        except psutil.NoSuchProcess:
            return False

    alive = {p.pid: p for p in processes if running(p)}
    if folder is not None:
        for p in psutil.process_iter(["pid", "cmdline"]):
            if p.pid != os.getpid() and str(folder) in " ".join(p.info["cmdline"] or ()) and running(p):
                alive[p.pid] = p
    return alive


def _wait_gone(processes, folder=None, seconds=10.0) -> dict:
    """Wait up to ``seconds`` for ``processes`` (and any process naming ``folder``) to end; the
    ones left, killed so that a failing test does not leave them running."""
    import time

    import psutil

    t0 = time.monotonic()
    while _alive(processes, folder) and time.monotonic() - t0 < seconds:
        time.sleep(0.1)
    left = _alive(processes, folder)
    described = {}
    for pid, p in left.items():
        try:
            described[pid] = " ".join(p.cmdline())[:150]
            p.kill()
        except psutil.NoSuchProcess:
            pass
    return described


def _cmdline(p) -> str:
    import psutil

    try:
        return " ".join(p.cmdline())
    except psutil.NoSuchProcess:
        return ""


@pytest.mark.slow
@pytest.mark.parametrize("signame", ["SIGTERM", "SIGINT"])
def test_cube_job_stops_cleanly_on_a_signal(uninterrupted, signame):
    """SIGTERM or SIGINT to the cube job (Snakemake stopping it, a Ctrl-C) in the middle of the
    cube: the job kills its workers, runs no queued region, marks no time block done that has a
    region missing, logs one line and exits with 128 + the signal's number, which Snakemake
    reports; its workers are gone at once."""
    import re
    import signal

    folder, cfg, _ = uninterrupted
    out = folder / "results" / "killed"
    # the cube redone in the uninterrupted run's folder (its products' digests already taken)
    for p in [
        out / "work" / "background_blocks" / "part_0.json",
        *(out / "work" / "background_blocks").glob("block_*.json"),
    ]:
        p.unlink(missing_ok=True)
    _, cmd = _snakemake_cmd(folder, cfg, "killed")
    cmd += ["--forcerun", "background_blocks"]  # its products downstream are there
    proc, seen = _run_until_a_block_is_done(cmd, out, folder / f"snakemake_{signame}.out")
    job = [p for p in seen.values() if "background_blocks.py" in _cmdline(p)]
    workers = [p for p in seen.values() if "--multiprocessing-fork" in _cmdline(p)]
    assert len(job) == 1 and len(workers) == 2, [_cmdline(p) for p in seen.values()]
    sig = getattr(signal, signame)
    job[0].send_signal(sig)
    left = _wait_gone([job[0], *workers], seconds=10.0)
    assert proc.wait(timeout=300) != 0
    assert not left, left
    said = (folder / f"snakemake_{signame}.out").read_text()
    assert f"returned non-zero exit status {128 + sig}" in said, said[-3000:]
    log = (out / "work" / "logs" / "background_blocks_0.log").read_text()
    assert f"stopped by {signame}: workers stopped" in log
    assert "chunk time" not in log.split(f"stopped by {signame}")[1]  # no region after the stop
    assert not (out / "work" / "background_blocks" / "part_0.json").exists()
    # every time block marked done has all its regions written (3 pixel blocks of 6 times each)
    regions = re.findall(r"chunk time (\d+):\d+ pixels", log)
    done = sorted((out / "work" / "background_blocks").glob("block_*.json"))
    assert 1 <= len(done) < N_KILL_BLOCKS
    for sentinel in done:
        b = int(sentinel.stem.split("_")[1])
        assert regions.count(str(6 * b)) == 3, (sentinel.name, log)


@pytest.mark.slow
def test_snakemake_killed_mid_cube_leaves_no_process_and_resumes_bit_identical(uninterrupted, tmp_path):
    """SIGKILL Snakemake alone (not its process group: its jobs get no signal from the killer)
    while the cube's workers compute regions: within 10 s no process of the killed run is left
    (the cube job dies with Snakemake, its pool workers with the job:
    execution.die_with_parent), none still writing to the stores a resumed run writes; the
    run resumed with the same command (after --unlock, as `make run` does) skips the finished
    time blocks and gives products bit-identical to an uninterrupted run's."""
    import signal
    import subprocess
    import time

    _, _, reference = uninterrupted
    work = tmp_path / "killed"
    cfg = _kill_campaign(work)
    base, cmd = _snakemake_cmd(work, cfg, "killed")
    out = work / "results" / "killed"
    proc, seen = _run_until_a_block_is_done(cmd, out, tmp_path / "snakemake.out")
    workers = [p for p in seen.values() if "--multiprocessing-fork" in _cmdline(p)]
    proc.send_signal(signal.SIGKILL)  # Snakemake alone
    proc.wait()
    assert len(workers) == 2, [_cmdline(p) for p in seen.values()]
    time.sleep(1.0)  # the job's and its workers' stop
    done_at_kill = sorted(p.name for p in (out / "work" / "background_blocks").glob("block_*.json"))
    orphans = _wait_gone(seen.values(), folder=tmp_path, seconds=9.0)
    assert not orphans, f"alive 10 s after Snakemake was killed: {orphans}"
    # and none went on writing meanwhile: no time block marked done since
    assert sorted(p.name for p in (out / "work" / "background_blocks").glob("block_*.json")) == done_at_kill
    assert (
        len(done_at_kill) < N_KILL_BLOCKS and not (out / "work" / "background_summary.json").exists()
    )  # killed in the middle

    subprocess.run(base + ["--unlock", "-q"], capture_output=True, env=_env(), timeout=120)
    r = subprocess.run(cmd, capture_output=True, text=True, env=_env(), timeout=900)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert "time blocks already done" in (out / "work" / "logs" / "background_blocks_0.log").read_text()
    for product in KILL_PRODUCTS:
        assert sha256_path(out / product) == reference[product], product
