"""``straylight run CONFIG``: a campaign through Snakemake, from a checkout or an install.

The workflow is the checkout's ``workflow/`` when straylight runs from one (where Snakemake's
own command line uses the same files), else the copy an installed package carries as
``straylight/_workflow`` (pyproject.toml maps ``workflow/`` to that package).  The run's folder is
the current directory: the products go to ``./results/<campaign name>/``, Snakemake's state to
``./.snakemake/``, as a ``snakemake`` started there does.

A run is quiet: a progress bar (Snakemake's steps and the cube's time blocks, with an ETA) and a
closing line; Snakemake's own log goes to ``results/<campaign name>/work/logs/snakemake.log``
(``verbose``, or Snakemake arguments that print rather than run, such as ``-n``: on the console).
"""

from __future__ import annotations

import json
import math
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections import deque
from pathlib import Path

from straylight.errors import InputError
from straylight.execution import available_cores

__all__ = [
    "INTERRUPTED_EXIT",
    "workflow_dir",
    "snakemake_command",
    "check_campaign",
    "check_results_folder",
    "warn_if_large",
    "run_campaign",
    "RunProgress",
    "SnakemakeGroup",
]

_CHECKOUT_WORKFLOW = Path(__file__).resolve().parents[1] / "workflow"
_PACKAGED_WORKFLOW = Path(__file__).resolve().parent / "_workflow"


def workflow_dir() -> Path:
    """The folder of the Snakefile: the checkout's ``workflow/``, else the packaged copy."""
    if (_CHECKOUT_WORKFLOW / "Snakefile").is_file():
        return _CHECKOUT_WORKFLOW
    return _PACKAGED_WORKFLOW


def snakemake_command(config, cores: int | None = None, extra=(), workdir=None) -> list[str]:
    """The Snakemake command that runs the campaign ``config`` in ``workdir`` (default: the
    current directory), resuming what a killed run left unfinished; ``extra`` arguments go to
    Snakemake as they are (``-n``, ``--report report.html``, ...).

    Parameters
    ----------
    config : str or os.PathLike
        The campaign's config file.
    cores : int, optional
        Snakemake's ``--cores`` (default: the cores this process may use).
    extra : sequence of str, optional
        Arguments passed to Snakemake as they are.
    workdir : str or os.PathLike, optional
        The folder Snakemake runs in (default: the current directory).
    """
    workdir = Path(workdir) if workdir is not None else Path.cwd()
    cores = available_cores() if cores is None else cores
    # -P: not the current directory on sys.path, which Snakemake hands on to the jobs: a folder
    # named straylight where the campaign runs (a checkout) would shadow the installed package
    return [
        sys.executable,
        "-P",
        "-m",
        "snakemake",
        "-s",
        str(workflow_dir() / "Snakefile"),
        "-d",
        str(workdir.resolve()),
        "--configfile",
        str(Path(config).resolve()),
        "--cores",
        str(cores),
        "--rerun-incomplete",
        *extra,
    ]


def check_campaign(config):
    """The campaign Snakemake will run from ``config``: the file merged over the default config
    (the Snakefile's configfile; a campaign file may hold only the keys it changes), each file's
    relative paths against its own folder, validated.  A mistake raises
    :class:`~straylight.errors.ConfigError` naming the file, key and value.

    Parameters
    ----------
    config : str or os.PathLike
        The campaign's config file.
    """
    from straylight.config import load_campaign

    return load_campaign(Path(config))


def check_results_folder(campaign, workdir=None) -> Path:
    """``results/<campaign name>/`` under ``workdir`` (default: the current directory), refused in
    one line when it, or ``results``, exists as something other than a folder (Snakemake would
    fail on it after its start-up, with a long traceback).

    Parameters
    ----------
    campaign : Campaign
        The campaign (its name).
    workdir : str or os.PathLike, optional
        The folder the run writes ``results/`` in (default: the current directory).
    """
    workdir = Path(workdir) if workdir is not None else Path.cwd()
    out = workdir / "results" / campaign.name
    for p in (workdir / "results", out):
        if p.exists() and not p.is_dir():
            raise InputError(
                f"{p}: exists and is not a folder; the campaign's products go to the folder "
                f"results/{campaign.name}/: move or remove it (or give campaign.name another name)"
            )
    return out


def warn_if_large(campaign) -> str | None:
    """The campaign's size warning (:func:`straylight.planning.sizes.size_warning`), logged as one
    line before the run starts; returns it."""
    import logging

    from straylight.cube.footprint import footprint_from_config
    from straylight.planning.sizes import size_warning

    fp = footprint_from_config(campaign.settings.footprint, campaign.path.parent)
    msg = size_warning(campaign, int(fp.pixels.size))
    if msg:
        logging.getLogger(__name__).warning("warning: %s", msg)
    return msg


#: The exit status of a run stopped by Ctrl-C (128 + SIGINT, as a shell reports it)
INTERRUPTED_EXIT = 130


#: Snakemake arguments that print something rather than run the campaign: their output is the
#: point, so it goes to the console as Snakemake writes it
_PRINTING_ARGS = {
    "-n",
    "--dry-run",
    "--dryrun",
    "--report",
    "--lint",
    "-l",
    "--list",
    "--list-rules",
    "--lt",
    "--list-target-rules",
    "-S",
    "--summary",
    "-D",
    "--detailed-summary",
    "--dag",
    "--rulegraph",
    "--filegraph",
    "--d3dag",
    "-h",
    "--help",
    "--version",
    "--lc",
    "--list-changes",
    "--list-code-changes",
    "--list-input-changes",
    "--list-params-changes",
    "--print-compilation",
    "--containerize",
    "--unlock",
    "--cleanup-metadata",
    "--archive",
    "-t",
    "--touch",
    "--delete-all-output",
    "--delete-temp-output",
    "--generate-unit-tests",
}
#: "3 of 17 steps (18%) done": a job finished
_STEP_LINE = re.compile(r"^(\d+) of (\d+) steps \(\d+%\) done")
#: the cube's rule in the "Job stats" table Snakemake prints first: its time blocks are in the run
_CUBE_JOBS_LINE = re.compile(r"^background_blocks\s+\d+\s*$")


def _prints_rather_than_runs(extra) -> bool:
    return any(str(a).split("=", 1)[0] in _PRINTING_ARGS for a in extra)


class RunProgress:
    """What a quiet run shows: Snakemake's finished steps (from its log lines) plus the cube's
    finished time blocks (their sentinels, ``work/background_blocks/block_<i>.json``), which
    hold most of a long campaign's time."""

    def __init__(self, results: Path, n_time_blocks: int):
        self.sentinels = Path(results) / "work" / "background_blocks"
        self.n_time_blocks = int(n_time_blocks)
        self.steps_done = 0
        self.steps_total = None  # known from Snakemake's first finished step
        self.nothing_to_do = False
        self.cube_in_run = False  # the cube's jobs listed in Snakemake's job stats

    def read_line(self, line: str) -> None:
        """Take one line of Snakemake's log.

        Parameters
        ----------
        line : str
            One line of Snakemake's log.
        """
        m = _STEP_LINE.match(line.strip())
        if _CUBE_JOBS_LINE.match(line):
            self.cube_in_run = True
        elif m:
            self.steps_done, self.steps_total = int(m.group(1)), int(m.group(2))
        elif line.startswith("Nothing to be done"):
            self.nothing_to_do = True

    def blocks_done(self) -> int:
        """The cube's time blocks done: their sentinels (0 while the folder is not there)."""
        try:
            return min(self.n_time_blocks, sum(1 for _ in self.sentinels.glob("block_*.json")))
        except OSError:
            return 0

    def counts(self) -> tuple[int, int | None]:
        """(units done, units in all or None while unknown): a step, or a time block of a run
        that computes the cube, each."""
        blocks = self.n_time_blocks if self.cube_in_run else 0
        total = None if self.steps_total is None else self.steps_total + blocks
        return self.steps_done + (self.blocks_done() if self.cube_in_run else 0), total


def _size(path: Path) -> int:
    if path.is_file():
        return path.stat().st_size
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())


def _products_line(results: Path) -> str:
    """'14 products, 52.3 MB': the results folder's entries but its work/ folder."""
    products = [p for p in results.iterdir() if p.name != "work" and not p.name.startswith(".")]
    size = sum(_size(p) for p in products)
    return f"{len(products)} products, {size / 1e6:.1f} MB"


def _run_quietly(cmd, env, campaign) -> int:
    """Run ``cmd`` (Snakemake) with its output in the results folder's work/logs/snakemake.log,
    a progress bar on stderr and one closing line; on failure the log's error lines."""
    from tqdm import tqdm

    from straylight.cube.timegrid import time_blocks

    c = campaign.settings.campaign
    results = Path("results") / campaign.name
    log_path = results / "work" / "logs" / "snakemake.log"
    log = _open_log(log_path)
    from straylight.sky.timeutil import quiet_dubious_years

    with quiet_dubious_years():  # the campaign checked: inside DE405
        n_times = len(campaign.times)
    n_blocks = len(time_blocks(n_times, float(c.cadence_s), float(c.time_block_hours)))
    progress = RunProgress(results, n_blocks)
    tail: deque[str] = deque(maxlen=400)
    print(f"straylight run: campaign {campaign.name}, log in {log_path}", file=sys.stderr, flush=True)
    start = time.monotonic()
    snakemake = SnakemakeGroup()
    previous = snakemake.forward_signals()

    def read(proc):
        for line in proc.stdout:
            log.write(line)
            log.flush()
            tail.append(line.rstrip("\n"))
            progress.read_line(line)

    bar, reader, interrupted = None, None, False
    try:
        snakemake.start(
            cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, errors="replace"
        )
        reader = threading.Thread(target=read, args=(snakemake.proc,), daemon=True)
        reader.start()
        # disable=None: no bar where stderr is not a terminal (a pipe, a batch job's file)
        bar = tqdm(total=None, unit="step", desc=campaign.name, file=sys.stderr, disable=None, leave=False)
        interrupted = _follow(snakemake, progress, bar)
        snakemake.join_output(reader)
    except KeyboardInterrupt:  # a Ctrl-C before the run is followed: stopped all the same
        interrupted = True
        snakemake.stop()
        if reader is not None:
            snakemake.join_output(reader)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if bar is not None:
            bar.close()
        log.close()
    wall = time.monotonic() - start
    code = None if snakemake.proc is None else snakemake.proc.returncode
    if code == 0:
        what = "already complete" if progress.nothing_to_do else f"done in {wall:.0f} s wall"
        print(f"straylight run: {what}: {_products_line(results)} in {results}/", file=sys.stderr)
    elif interrupted:
        print(
            f"straylight run: interrupted after {wall:.0f} s; the finished products are kept in "
            f"{results}/ and the same command resumes the run",
            file=sys.stderr,
        )
        return INTERRUPTED_EXIT
    else:
        _print_failure(list(tail), code, wall, log_path)
    return code


def _open_log(log_path: Path):
    """The run's log, opened for writing (its folder made); InputError when it cannot be."""
    try:
        log_path.parent.mkdir(parents=True, exist_ok=True)
        return open(log_path, "w", encoding="utf-8")  # noqa: SIM115 - the caller closes it, after the reader
    except OSError as exc:
        raise InputError(f"{log_path}: cannot write the run's log ({exc.strerror or exc})") from None


def _follow(snakemake: SnakemakeGroup, progress: RunProgress, bar) -> bool:
    """Move ``bar`` with the run's progress every 0.5 s until Snakemake ends; True when a Ctrl-C
    stopped it (:meth:`SnakemakeGroup.stop`)."""
    interrupted = False
    while True:
        try:
            if snakemake.proc.poll() is not None:
                return interrupted
            done, total = progress.counts()
            if total is not None and bar.total != total:
                bar.total = total
            if done != bar.n:
                bar.update(done - bar.n)
            else:
                bar.refresh()
            time.sleep(0.5)
        except KeyboardInterrupt:
            interrupted = True
            snakemake.stop()


def _print_failure(lines: list, code: int, wall: float, log_path: Path) -> None:
    """A failed run's log lines from its first error (else its last 20), and the closing line
    (``wall``: its wall seconds)."""
    first = next((i for i, ln in enumerate(lines) if re.match(r"\s*(Error|Exception|\w+Error\b)", ln)), None)
    shown = lines[first:][:40] if first is not None else lines[-20:]
    print("\n".join(shown), file=sys.stderr)
    print(
        f"straylight run: failed (Snakemake exit status {code}) after {wall:.0f} s; "
        f"the whole log: {log_path}",
        file=sys.stderr,
    )


def run_campaign(config, cores: int | None = None, extra=(), argv=None, verbose: bool = False) -> int:
    """Check the campaign ``config`` (one line on a mistake: :class:`~straylight.errors.StraylightError`),
    then run Snakemake on it in the current directory; returns Snakemake's exit status, or
    :data:`INTERRUPTED_EXIT` after a Ctrl-C (Snakemake and its jobs stopped with SIGTERM, without
    a traceback, and one line on stderr; a re-run resumes).
    ``argv``: the ``straylight`` command line, recorded in provenance.json.  Quiet unless
    ``verbose`` or ``extra`` asks Snakemake to print rather than run (``-n``, ``--report``):
    a progress bar and a closing line, Snakemake's log in the results folder's work/logs/.

    Parameters
    ----------
    config : str or os.PathLike
        The campaign's config file.
    cores : int, optional
        Snakemake's ``--cores`` (default: the cores this process may use).
    extra : sequence of str, optional
        Arguments passed to Snakemake as they are.
    argv : sequence of str, optional
        The ``straylight`` command line, recorded in provenance.json.
    verbose : bool, optional
        Print Snakemake's log rather than a progress bar (default False).
    """
    if cores is not None and cores < 1:
        raise InputError(f"--cores must be at least 1, got {cores}")
    campaign = check_campaign(config)
    check_results_folder(campaign)
    warn_if_large(campaign)
    cmd = snakemake_command(config, cores, extra)
    from straylight.cube.provenance import LAUNCHER_ENV

    env = dict(os.environ)
    env[LAUNCHER_ENV] = json.dumps(["straylight", *(argv if argv is not None else sys.argv[1:])])
    if not verbose and not _prints_rather_than_runs(extra):
        return _run_quietly(cmd, env, campaign)
    # Snakemake and its jobs in a session of their own: a Ctrl-C reaches this process alone, which
    # stops them with SIGTERM (a job ends without a traceback wherever it is, even in Snakemake's
    # preamble or its imports; the cube job stops cleanly), and says so in one line
    snakemake = SnakemakeGroup()
    previous = snakemake.forward_signals()
    try:
        snakemake.start(cmd, env=env)
        return snakemake.proc.wait()
    except KeyboardInterrupt:
        snakemake.stop()
        print(
            f"straylight run: interrupted; the finished products are kept in results/{campaign.name}/ "
            "and the same command resumes the run",
            file=sys.stderr,
        )
        return INTERRUPTED_EXIT
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


#: seconds Snakemake's process group has to end after the SIGTERM that stops it, and to release
#: the pipe of its log once Snakemake has ended, before what is left of it gets SIGKILL: three
#: times the 10 s within which the cube job and its workers are gone after a SIGTERM
#: (tests/workflow/test_faults.py::test_cube_job_stops_cleanly_on_a_signal); what SIGKILL cuts
#: short is redone by a re-run (the stores are written through temporary files)
STOP_GRACE_SECONDS = 30.0


class SnakemakeGroup:
    """Snakemake and its jobs, in a session (and process group) of their own: a Ctrl-C at the
    terminal reaches ``straylight run`` alone, which stops the group with SIGTERM (:meth:`stop`),
    then SIGKILL for whatever outlives :data:`STOP_GRACE_SECONDS`.  SIGTERM and SIGHUP to
    ``straylight run`` (a scheduler's stop, the terminal closed) are passed on as SIGTERM
    (:meth:`forward_signals`, set before :meth:`start` so that Snakemake starts with their
    default actions even where this process was started with them ignored)."""

    def __init__(self, grace_s: float = STOP_GRACE_SECONDS):
        self.proc = None
        self.grace_s = float(grace_s)

    def start(self, cmd, **popen_kwargs) -> None:
        """Start ``cmd`` (Snakemake) in a new session.

        Parameters
        ----------
        cmd : sequence of str
            The command line.
        **popen_kwargs
            Passed to :class:`subprocess.Popen` (its output's pipes, its environment).
        """
        self.proc = subprocess.Popen(cmd, start_new_session=True, **popen_kwargs)

    def send(self, sig: int) -> None:
        """Send a signal to every process of the group (none once they have all ended).

        Parameters
        ----------
        sig : int
            The signal (``signal.SIGTERM``, ``signal.SIGKILL``).
        """
        if self.proc is None:
            return
        try:
            os.killpg(self.proc.pid, sig)
        except (ProcessLookupError, PermissionError):  # gone already
            pass

    def stop(self) -> None:
        """SIGTERM to the group, then wait for Snakemake (a further Ctrl-C meanwhile taken as
        the first); SIGKILL to the group if Snakemake has not ended within the grace time.
        Nothing before Snakemake has started."""
        if self.proc is None:
            return
        self.send(signal.SIGTERM)
        deadline = time.monotonic() + self.grace_s
        while True:
            try:
                self.proc.wait(timeout=max(0.0, deadline - time.monotonic()))
                return
            except subprocess.TimeoutExpired:
                self.send(signal.SIGKILL)
                deadline = math.inf
            except KeyboardInterrupt:
                continue

    def join_output(self, reader: threading.Thread) -> None:
        """Wait for the thread reading Snakemake's output, once Snakemake has ended: the pipe
        closes when every process that holds it has ended, so a process of the group still
        holding it after the grace time gets SIGKILL.

        Parameters
        ----------
        reader : threading.Thread
            The thread reading Snakemake's output until its end.
        """
        reader.join(self.grace_s)
        if reader.is_alive():
            self.send(signal.SIGKILL)
            reader.join(self.grace_s)

    def forward_signals(self) -> dict:
        """Pass SIGTERM and SIGHUP to this process on to the group as SIGTERM; returns the previous
        handlers (none outside the main thread, where they are left as they are)."""

        def forward(signum, frame):
            if self.proc is None:  # before Snakemake starts: this process stops
                raise SystemExit(128 + signum)
            self.send(signal.SIGTERM)

        previous = {}
        for sig in (signal.SIGTERM, signal.SIGHUP):
            try:
                previous[sig] = signal.signal(sig, forward)
            except ValueError:  # not the main thread
                break
        return previous
