"""provenance.json: what produced a campaign's products and checksums of all of them.

An archive keeps the record with the products, on another machine: it names the code (version,
and the git commit with its uncommitted changes when run from a checkout), the Snakemake command
line and cores of the run, the config, and no absolute path.  Paths are written relative to the
folder stated in the record's ``paths`` note, and files shipped with straylight (its default
config, instrument, schemas and workflow) as ``straylight:config/...`` and
``straylight:workflow/...``, which the recorded version identifies.
"""

from __future__ import annotations

import copy
import hashlib
import json
import os
import platform
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from straylight._version import __version__, build_commit
from straylight.config import CONFIG_DIR, PATH_KEYS
from straylight.util.io import sha256_path

__all__ = [
    "PACKAGES",
    "SOURCE_ROOT",
    "RUN_ENV",
    "LAUNCHER_ENV",
    "PATHS_NOTE",
    "versions",
    "source_revision",
    "RunInfo",
    "snakemake_run",
    "portable_path",
    "provenance_record",
]

PACKAGES = (
    "straylight",
    "numpy",
    "scipy",
    "astropy",
    "healpy",
    "xarray",
    "zarr",
    "dask",
    "distributed",
    "snakemake",
    "de405",
    "sgp4",
    "speclite",
    "erfa",
    "pyerfa",
)

#: the folder holding the straylight package: a git checkout when it holds .git
SOURCE_ROOT = Path(__file__).resolve().parents[2]

#: environment variable carrying the run (JSON of :class:`RunInfo`) from Snakemake's main process
#: to the jobs a cluster executor starts, whose own Snakemake has another command line
RUN_ENV = "STRAYLIGHT_RUN"
#: environment variable in which ``straylight run`` hands its own command line to Snakemake
LAUNCHER_ENV = "STRAYLIGHT_RUN_COMMAND"

PATHS_NOTE = (
    "config_file, and the paths given absolute in run's command lines: relative to this file's folder "
    "(the campaign's results folder; the command lines' other paths are as typed, relative to the folder "
    "the run started in); instrument_file and the config's files: relative to the config file's folder; "
    "straylight:config/... and straylight:workflow/...: files shipped with straylight (source.version)"
)


def versions() -> dict:
    """The versions of Python, the platform and the packages in :data:`PACKAGES` that are installed.

    Returns
    -------
    dict of str to str
        ``python``, ``platform`` and each installed package's version (missing ones left out);
        ``straylight`` is the imported code's version.
    """
    from importlib import metadata

    out = {"python": sys.version.split()[0], "platform": platform.platform()}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            pass
    out["straylight"] = __version__  # the imported code's (an editable install's metadata is its install's)
    return out


def _git(*args) -> str | None:
    try:
        r = subprocess.run(["git", "-C", str(SOURCE_ROOT), *args], capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return None
    return r.stdout if r.returncode == 0 else None


def source_revision() -> dict:
    """The code that runs: its version; from a git checkout its commit, whether tracked files
    differ from it (``dirty``) and which (``modified``, relative to the checkout); from an install
    the commit it was built from when known (setuptools-scm's short id).

    Returns
    -------
    dict
        ``version`` (str), ``from`` (``"checkout"`` or ``"install"``), ``commit`` (str or None:
        unknown), ``dirty`` (bool, or None: unknown); from a checkout also ``modified`` (list
        of str).
    """
    if (SOURCE_ROOT / ".git").exists():
        commit = _git("rev-parse", "HEAD")
        status = _git("status", "--porcelain", "--untracked-files=no") if commit is not None else None
        modified = sorted(line[3:] for line in (status or "").splitlines() if line.strip())
        # no git here (or it refuses the folder): a checkout all the same, its commit unknown
        return {
            "version": __version__,
            "from": "checkout",
            "commit": commit.strip() if commit else None,
            "dirty": bool(modified) if status is not None else None,
            "modified": modified,
        }
    commit = build_commit[1:] if build_commit and build_commit.startswith("g") else build_commit
    return {"version": __version__, "from": "install", "commit": commit, "dirty": None}


@dataclass(frozen=True)
class RunInfo:
    """The run that writes the record: Snakemake's command line, its ``--cores`` (None: not
    given) and the ``straylight run`` command that started Snakemake, if one did.

    Handed to the provenance rule as a param: Snakemake compares only builtin values (str, int,
    list, ...) of params with the last run's, so another command line or core count (a resumed
    run, a dry run, ``--report``) does not make the record out of date.

    Attributes
    ----------
    command : tuple of str
        Snakemake's command line.
    cores : int or None
        Snakemake's ``--cores``; None: not given.
    started_by : tuple of str or None
        The ``straylight run`` command line that started Snakemake; None: none did.
    """

    command: tuple
    cores: int | None
    started_by: tuple | None = None

    def as_dict(self) -> dict:
        """The run as JSON-ready builtins.

        Returns
        -------
        dict
            ``command`` (list of str), ``cores`` (int or None), ``started_by`` (list of str or
            None).
        """
        return {
            "command": list(self.command),
            "cores": self.cores,
            "started_by": list(self.started_by) if self.started_by else None,
        }


def snakemake_run(argv, cores, main_process: bool = True) -> RunInfo:
    """The run as the Snakefile sees it: ``argv`` (sys.argv) and ``cores`` (workflow.cores) in
    Snakemake's main process, which also puts them in the environment (:data:`RUN_ENV`) for the
    jobs; a job's own Snakemake (a cluster executor's) takes them from there.

    Parameters
    ----------
    argv : sequence of str
        Snakemake's ``sys.argv`` (its first element, the program, is replaced by
        ``"snakemake"``).
    cores : int or None
        ``workflow.cores``; None: not given.
    main_process : bool, optional
        True in Snakemake's main process (sets :data:`RUN_ENV`); False in a job, which reads it
        when set.

    Returns
    -------
    RunInfo
        The run.
    """
    if not main_process and os.environ.get(RUN_ENV):
        d = json.loads(os.environ[RUN_ENV])
        return RunInfo(tuple(d["command"]), d["cores"], tuple(d["started_by"]) if d["started_by"] else None)
    launcher = os.environ.get(LAUNCHER_ENV)
    run = RunInfo(
        ("snakemake", *map(str, argv[1:])),
        int(cores) if cores is not None else None,
        tuple(json.loads(launcher)) if launcher else None,
    )
    if main_process:
        os.environ[RUN_ENV] = json.dumps(run.as_dict())
    return run


def portable_path(path, base, roots: dict) -> str:
    """``path`` without the machine's folders: ``label/rest`` under one of ``roots`` ({label:
    folder}), else relative to the folder ``base`` (``..`` where it lies outside).

    Parameters
    ----------
    path : str or path-like
        The path (relative ones are taken from the working directory).
    base : str or path-like
        Folder the path is written relative to when under no root.
    roots : dict of str to path-like
        Label to folder (e.g. ``{"straylight:config": CONFIG_DIR}``).

    Returns
    -------
    str
        The portable path, with ``/`` separators.
    """
    p = Path(os.path.abspath(path))
    for label, root in roots.items():
        root = Path(os.path.abspath(root))
        if p == root or root in p.parents:
            return f"{label}/{p.relative_to(root).as_posix()}".rstrip("/")
    return Path(os.path.relpath(p, os.path.abspath(base))).as_posix()


def _portable_command(argv, base, roots) -> list:
    """A command line with every absolute path (also ``--option=/path``) made portable."""
    out = []
    for arg in argv:
        opt, eq, value = arg.partition("=") if arg.startswith("-") else ("", "", arg)
        if os.path.isabs(value):
            out.append(f"{opt}{eq}{portable_path(value, base, roots)}")
        else:
            out.append(arg)
    return out


def _portable_config(config: dict, config_dir, roots) -> dict:
    """The config with its file paths (config.PATH_KEYS) relative to the config file's folder."""
    out = copy.deepcopy(config)
    for keys in PATH_KEYS:
        node = out
        for k in keys[:-1]:
            node = node.get(k) if isinstance(node, dict) else None
        if not isinstance(node, dict) or not node.get(keys[-1]):
            continue

        def portable(v):
            return portable_path(v, config_dir, roots) if isinstance(v, str) and os.path.isabs(v) else v

        v = node[keys[-1]]
        node[keys[-1]] = [portable(x) for x in v] if isinstance(v, list) else portable(v)
    return out


def provenance_record(
    campaign, inputs: dict, outputs: dict, results=None, run: RunInfo | None = None, workflow_dir=None
) -> dict:
    """The record of a campaign's run: ``inputs`` and ``outputs`` ({name: path}) checksummed;
    ``results`` the campaign's results folder (default: the folder of the first output), to
    which the paths are written relative; ``run`` the Snakemake run; ``workflow_dir`` the
    workflow that ran (its files written as ``straylight:workflow/...``).

    Parameters
    ----------
    campaign : straylight.config.Campaign
        Loaded campaign (its config, config file and instrument file).
    inputs : dict of str to path-like
        Input name to file, checksummed.
    outputs : dict of str to path-like
        Output name to file, checksummed (at least one when ``results`` is None).
    results : str or path-like, optional
        The campaign's results folder; None: the first output's folder.
    run : RunInfo, optional
        The Snakemake run; None: recorded as null.
    workflow_dir : str or path-like, optional
        The workflow folder that ran; None: its files are not given the ``straylight:workflow``
        label.

    Returns
    -------
    dict
        The JSON-ready record: ``campaign``, ``config``, ``config_file``, ``instrument_file``,
        ``paths``, ``source``, ``run``, ``versions``, ``inputs_sha256``, ``outputs_sha256``
        (hex SHA-256 per file) and ``outputs_digest_sha256`` (one digest of them all).
    """
    data_dir = Path(__file__).resolve().parents[1] / "data"
    results = Path(results if results is not None else Path(next(iter(outputs.values()))).parent)
    roots = {"straylight:config": CONFIG_DIR}
    if workflow_dir is not None:
        roots["straylight:workflow"] = workflow_dir
    config_dir = Path(campaign.path).parent
    rec = {
        "campaign": campaign.name,
        "config": _portable_config(campaign.config_mapping(), config_dir, roots),
        "config_file": portable_path(campaign.path, results, roots),
        "instrument_file": portable_path(campaign.instrument_path, config_dir, roots),
        "paths": PATHS_NOTE,
        "source": source_revision(),
        "run": run.as_dict() if run is not None else None,
        "versions": versions(),
        "inputs_sha256": {
            "config": sha256_path(campaign.path),
            "instrument": sha256_path(campaign.instrument_path),
            **{f"data/{f.name}": sha256_path(f) for f in sorted(data_dir.iterdir()) if f.is_file()},
            **{k: sha256_path(v) for k, v in inputs.items()},
        },
    }
    if run is not None:
        rec["run"]["command"] = _portable_command(run.command, results, roots)
        if run.started_by:
            rec["run"]["started_by"] = _portable_command(run.started_by, results, roots)
    rec["outputs_sha256"] = {k: sha256_path(v) for k, v in outputs.items()}
    # one digest for the whole campaign: two runs from the same config and inputs must agree
    # (tests/cube/test_cube.py compares it after ten kill -9 and resumes)
    rec["outputs_digest_sha256"] = hashlib.sha256(
        "".join(f"{k}:{v}\n" for k, v in sorted(rec["outputs_sha256"].items())).encode()
    ).hexdigest()
    return rec
