"""``straylight run CONFIG``: a campaign through Snakemake, from a checkout or an install.

The workflow is the checkout's ``workflow/`` when straylight runs from one (where Snakemake's
own command line uses the same files), else the copy an installed package carries as
``straylight/_workflow`` (pyproject.toml maps ``workflow/`` to that package).  The run's folder is
the current directory: the products go to ``./results/<campaign name>/``, Snakemake's state to
``./.snakemake/``, as a ``snakemake`` started there does.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

from straylight.errors import InputError
from straylight.util.daskutil import available_cores

__all__ = [
    "INTERRUPTED_EXIT",
    "workflow_dir",
    "snakemake_command",
    "check_campaign",
    "check_results_folder",
    "warn_if_large",
    "run_campaign",
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
    Snakemake as they are (``-n``, ``--report report.html``, ...)."""
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
    :class:`~straylight.errors.ConfigError` naming the file, key and value."""
    from straylight.config import load_campaign

    return load_campaign(Path(config))


def check_results_folder(campaign, workdir=None) -> Path:
    """``results/<campaign name>/`` under ``workdir`` (default: the current directory), refused in
    one line when it, or ``results``, exists as something other than a folder (Snakemake would
    fail on it after its start-up, with a long traceback)."""
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
    """The campaign's size warning (:func:`straylight.survey.sizes.size_warning`), logged as one
    line before the run starts; returns it."""
    import logging

    from straylight.survey.footprint import footprint_from_config
    from straylight.survey.sizes import size_warning

    fp = footprint_from_config(campaign.settings.footprint, campaign.path.parent)
    msg = size_warning(campaign, int(fp.pixels.size))
    if msg:
        logging.getLogger(__name__).warning("warning: %s", msg)
    return msg


#: The exit status of a run stopped by Ctrl-C (128 + SIGINT, as a shell reports it)
INTERRUPTED_EXIT = 130


def run_campaign(config, cores: int | None = None, extra=(), argv=None) -> int:
    """Check the campaign ``config`` (one line on a mistake: :class:`~straylight.errors.StraylightError`),
    then run Snakemake on it in the current directory; returns Snakemake's exit status, or
    :data:`INTERRUPTED_EXIT` after a Ctrl-C (Snakemake and its jobs stopped with SIGTERM, without
    a traceback, and one line on stderr; a re-run resumes).
    ``argv``: the ``straylight`` command line, recorded in provenance.json."""
    if cores is not None and cores < 1:
        raise InputError(f"--cores must be at least 1, got {cores}")
    campaign = check_campaign(config)
    check_results_folder(campaign)
    warn_if_large(campaign)
    cmd = snakemake_command(config, cores, extra)
    from straylight.survey.provenance import LAUNCHER_ENV

    env = dict(os.environ)
    env[LAUNCHER_ENV] = json.dumps(["straylight", *(argv if argv is not None else sys.argv[1:])])
    # Snakemake and its jobs in a session of their own: a Ctrl-C reaches this process alone, which
    # stops them with SIGTERM (a job ends without a traceback wherever it is, even in Snakemake's
    # preamble or its imports; the cube job stops cleanly), and says so in one line
    proc = subprocess.Popen(cmd, env=env, start_new_session=True)
    previous = _forward_signals(proc)
    try:
        return proc.wait()
    except KeyboardInterrupt:
        _stop(proc)
        print(
            f"straylight run: interrupted; the finished products are kept in results/{campaign.name}/ "
            "and the same command resumes the run",
            file=sys.stderr,
        )
        return INTERRUPTED_EXIT
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _stop(proc) -> None:
    """SIGTERM to Snakemake's process group (Snakemake and its jobs), then wait for it, a further
    Ctrl-C meanwhile taken as the first."""
    try:
        os.killpg(proc.pid, signal.SIGTERM)
    except (ProcessLookupError, PermissionError):  # gone already
        pass
    while True:
        try:
            proc.wait()
            return
        except KeyboardInterrupt:
            continue


def _forward_signals(proc) -> dict:
    """SIGTERM and SIGHUP to this process (a scheduler's stop, the terminal closed) passed on to
    Snakemake's process group as SIGTERM, since it has a session of its own; returns the previous
    handlers (none outside the main thread)."""

    def forward(signum, frame):
        try:
            os.killpg(proc.pid, signal.SIGTERM)
        except (ProcessLookupError, PermissionError):
            pass

    previous = {}
    for sig in (signal.SIGTERM, signal.SIGHUP):
        try:
            previous[sig] = signal.signal(sig, forward)
        except ValueError:  # not the main thread: left as they are
            break
    return previous
