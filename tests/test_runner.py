"""`straylight run`'s quiet console: a progress bar, one closing line, Snakemake's log in the
results folder's work/logs/ (-v: on the console).  Real Snakemake runs on one cheap target of a
tiny campaign (its footprint), so that each takes seconds."""

import pytest
from conftest import run_cli, tiny_config

from straylight.runner import RunProgress


def test_progress_counts_snakemake_steps_and_the_cubes_time_blocks(tmp_path):
    blocks = tmp_path / "work" / "background_blocks"
    blocks.mkdir(parents=True)
    for i in (0, 1):
        (blocks / f"block_{i}.json").write_text("{}")
    (blocks / "init.json").write_text("{}")  # not a time block
    # a run without the cube (other targets): its steps only
    progress = RunProgress(tmp_path, n_time_blocks=4)
    progress.read_line("2 of 3 steps (67%) done\n")
    assert progress.counts() == (2, 3)
    # Snakemake's job stats list the cube's job: its 4 time blocks count, 2 of them done
    progress = RunProgress(tmp_path, n_time_blocks=4)
    for line in ("Job stats:\n", "job                  count\n", "background_blocks        1\n"):
        progress.read_line(line)
    progress.read_line("Select jobs to execute...\n")
    assert progress.counts() == (2, None)  # the steps' total comes with the first finished one
    progress.read_line("3 of 9 steps (33%) done\n")
    assert progress.counts() == (3 + 2, 9 + 4)
    assert not progress.nothing_to_do
    progress.read_line("Nothing to be done (all requested files are present and up to date).\n")
    assert progress.nothing_to_do


def test_quiet_run_prints_two_lines_and_logs_snakemake(tmp_path):
    """The footprint of a tiny campaign through Snakemake: on stderr (not a terminal: no bar) the
    log's place and the closing line only; Snakemake's lines in the log.  Before: Snakemake's
    49 lines for this one job on the console, no log file."""
    cfg = tiny_config(tmp_path)
    r = run_cli("run", cfg, "--cores", "1", "results/tiny/footprint.fits", cwd=tmp_path, timeout=600)
    assert r.returncode == 0, r.stderr
    lines = r.stderr.splitlines()
    assert len(lines) == 2, r.stderr
    assert lines[0] == "straylight run: campaign tiny, log in results/tiny/work/logs/snakemake.log"
    # footprint.fits and plan.json: 2 products, a few kB
    assert (
        lines[1].startswith("straylight run: done in ") and "2 products, 0.0 MB in results/tiny/" in lines[1]
    )
    log = (tmp_path / "results" / "tiny" / "work" / "logs" / "snakemake.log").read_text()
    assert "1 of 1 steps (100%) done" in log and "rule footprint" in log
    # the same again: nothing to do, said in one line
    r = run_cli("run", cfg, "--cores", "1", "results/tiny/footprint.fits", cwd=tmp_path, timeout=600)
    assert r.returncode == 0 and r.stderr.splitlines()[1].startswith("straylight run: already complete")


def test_quiet_run_shows_snakemakes_error_on_failure(tmp_path):
    cfg = tiny_config(tmp_path)
    r = run_cli("run", cfg, "--cores", "1", "results/tiny/no_such_product", cwd=tmp_path, timeout=600)
    assert r.returncode == 1
    assert "No rule to produce results/tiny/no_such_product" in r.stderr
    last = r.stderr.splitlines()[-1]
    assert last.startswith("straylight run: failed (Snakemake exit status 1) after ")
    assert last.endswith("the whole log: results/tiny/work/logs/snakemake.log")


@pytest.mark.parametrize("flag", ["-v", "-n"])
def test_verbose_and_dry_runs_print_snakemakes_log(tmp_path, flag):
    cfg = tiny_config(tmp_path)
    r = run_cli("run", cfg, "--cores", "1", flag, "results/tiny/footprint.fits", cwd=tmp_path, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "rule footprint" in r.stdout + r.stderr and "straylight run:" not in r.stderr


@pytest.mark.parametrize("snakemake_ignores_sigterm", [True, False])
def test_a_group_that_ignores_sigterm_is_killed_after_the_grace_time(snakemake_ignores_sigterm):
    """A Snakemake that ignores the stop's SIGTERM, or a process of its group that does and keeps
    the pipe of Snakemake's log open once Snakemake has ended, gets SIGKILL after the grace time:
    `straylight run` never waits forever."""
    import signal
    import subprocess
    import sys
    import threading
    import time

    from straylight.runner import SnakemakeGroup

    ignoring = "import signal, time; signal.signal(signal.SIGTERM, signal.SIG_IGN); "
    child = ignoring + "print('child', flush=True); time.sleep(600)"
    fake = (
        ignoring if snakemake_ignores_sigterm else "import time; "
    ) + f"import subprocess, sys; subprocess.Popen([sys.executable, '-c', {child!r}]); time.sleep(600)"
    group = SnakemakeGroup(grace_s=1.0)
    group.start([sys.executable, "-c", fake], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = []
    reader = threading.Thread(target=lambda: lines.extend(group.proc.stdout), daemon=True)
    reader.start()
    deadline = time.monotonic() + 60
    while not lines and time.monotonic() < deadline:  # both started, SIGTERM ignored
        time.sleep(0.1)
    assert lines == ["child\n"]
    start = time.monotonic()
    group.stop()
    group.join_output(reader)
    expected = signal.SIGKILL if snakemake_ignores_sigterm else signal.SIGTERM
    assert group.proc.returncode == -expected and not reader.is_alive()
    assert time.monotonic() - start < 10.0  # two grace times of 1 s and the kills
