"""The wheel as a user installs it: built from the source tree, installed into a fresh virtual
environment (no editable install of this checkout; the dependencies lent by this environment,
each declared by the wheel: checked from its imports), and used from an empty folder: the CLI,
the Python API, and a campaign through the packaged workflow with its report."""

import json
import os
import shutil
import subprocess
import sys
import sysconfig
import textwrap
import zipfile
from pathlib import Path

import pytest
from conftest import REPO

#: a campaign file holding only what differs from the packaged default (Snakemake merges it over
#: the Snakefile's configfile): one hour at 20 minutes over nside 4, the earthshine summed directly
TINY = """\
campaign: {name: tiny, end: "2026-01-01T01:00:00", cadence_s: 1200, time_block_hours: 1}
footprint: {nside: 4}
models: {earthshine: {method: direct}}
report: {sky_map_bands: [g], times: ["2026-01-01T00:30:00"], pointings: [[150.0, 30.0]]}
"""


def test_version_flag():
    from conftest import run_cli

    import straylight

    r = run_cli("--version")
    assert r.returncode == 0 and r.stdout.strip() == f"straylight {straylight.__version__}"


def test_run_refuses_a_bad_campaign_in_one_line(tmp_path):
    from conftest import run_cli

    r = run_cli("run", tmp_path / "missing.yaml", cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert "missing.yaml: cannot read campaign config" in r.stderr
    bad = tmp_path / "bad.yaml"
    bad.write_text("campaign: {cadence_s: -5}\n")
    r = run_cli("run", bad, "--cores", "2", "-n", cwd=tmp_path)
    assert (
        r.returncode == 2
        and r.stderr.strip() == f"straylight: error: {bad}: campaign.cadence_s = -5: must be > 0"
    )
    assert not (tmp_path / ".snakemake").exists()  # refused before Snakemake started
    r = run_cli("sky", "--no-such-flag", cwd=tmp_path)  # other commands still refuse unknown arguments
    assert r.returncode == 2 and "unrecognized arguments: --no-such-flag" in r.stderr


def test_run_command_is_snakemake_on_the_workflow_in_the_current_directory(tmp_path):
    from straylight.runner import available_cores, snakemake_command, workflow_dir

    assert workflow_dir() == REPO / "workflow"  # a checkout runs its own workflow/
    cmd = snakemake_command("tiny.yaml", extra=["-n", "--report", "r.html"], workdir=tmp_path)
    assert cmd[:4] == [sys.executable, "-P", "-m", "snakemake"]
    assert cmd[4:] == [
        "-s",
        str(REPO / "workflow" / "Snakefile"),
        "-d",
        str(tmp_path),
        "--configfile",
        str(Path("tiny.yaml").resolve()),
        "--cores",
        str(available_cores()),
        "--rerun-incomplete",
        "-n",
        "--report",
        "r.html",
    ]
    assert available_cores() == len(os.sched_getaffinity(0))


def _copy_source(dst: Path) -> None:
    """The files a build may use, as the working tree has them (git metadata of their own)."""
    dst.mkdir()
    for name in ("pyproject.toml", "setup.py", "README.md", ".gitignore"):
        if (REPO / name).exists():
            shutil.copy(REPO / name, dst / name)
    for name in ("straylight", "config", "workflow"):
        shutil.copytree(
            REPO / name,
            dst / name,
            ignore=shutil.ignore_patterns("__pycache__", "_scm_version.py", "*.egg-info"),
        )


def _git(cwd, *args) -> str:
    return subprocess.run(
        ["git", "-c", "user.name=test", "-c", "user.email=test@example.org", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
    ).stdout


def _tracked(folder: str) -> list[str]:
    return _git(REPO, "ls-files", folder).split()


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(wheel, version, commit, venv's bin folder, environment, an empty folder)."""
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    _copy_source(src)
    # a user's campaign beside the shipped ones, committed: the wheel must still leave it out
    (src / "config" / "my_campaign.yaml").write_text("campaign: {name: mine}\n")
    _git(src, "init", "-q")
    _git(src, "add", "-A")
    _git(src, "commit", "-q", "-m", "source")
    commit = _git(src, "rev-parse", "HEAD").strip()
    wheels = tmp / "wheels"
    # pip's isolated build: the backend pyproject.toml names, from PyPI or pip's cache
    r = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(wheels), str(src)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stderr
    (wheel,) = wheels.glob("straylight-*.whl")
    version = wheel.name.split("-")[1]
    venv = tmp / "venv"
    r = subprocess.run([sys.executable, "-m", "venv", str(venv)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    # The dependencies are this environment's installed distributions, reached through a plain
    # path line: Python does not run the .pth files of a folder added that way, so this checkout's
    # editable install (its import finder) stays out, and straylight comes from the wheel alone.
    # That the wheel declares every distribution its code imports is checked on its own
    # (test_wheel_declares_every_distribution_it_imports).
    site = next((venv / "lib").glob("python3*/site-packages"))
    (site / "dependencies_of_the_test.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    r = subprocess.run(
        [str(venv / "bin" / "python"), "-m", "pip", "install", "-q", "--no-deps", str(wheel)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")}
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    empty = tmp / "elsewhere"
    empty.mkdir()
    return wheel, version, commit, venv / "bin", env, empty


@pytest.mark.slow
def test_wheel_holds_the_package_workflow_and_shipped_configs_only(installed):
    wheel, version, commit, *_ = installed
    names = set(zipfile.ZipFile(wheel).namelist())
    py = {f for f in _tracked("straylight") if f.endswith(".py")}
    assert "straylight/model/__init__.py" in py and not py - names, sorted(py - names)
    data = {f for f in _tracked("straylight/data")}
    assert data and not data - names
    # the whole workflow, as straylight/_workflow
    workflow = {"straylight/_workflow/" + f.removeprefix("workflow/") for f in _tracked("workflow")}
    assert {
        "straylight/_workflow/Snakefile",
        "straylight/_workflow/rules/limits.smk",
        "straylight/_workflow/scripts/_common.py",
        "straylight/_workflow/profiles/default/config.yaml",
    } <= workflow
    assert not workflow - names, sorted(workflow - names)
    # exactly the configs git tracks, as straylight/_config: not the user's campaign beside them
    config = {n for n in names if n.startswith("straylight/_config/")}
    assert config == {"straylight/_config/" + f.removeprefix("config/") for f in _tracked("config")}
    assert not [n for n in names if "my_campaign" in n]
    # the version from git (setuptools-scm), not a number written by hand
    assert commit[:7] in version and version != "0.1.0"
    assert (
        f"__version__ = version = '{version}'"
        in zipfile.ZipFile(wheel).read("straylight/_scm_version.py").decode()
    )


def _top_level_imports(source: str) -> set[str]:
    """The top-level module names a Python source imports (absolute imports only)."""
    import ast

    names = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names.update(a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


def _norm(name: str) -> str:
    import re

    return re.sub(r"[-_.]+", "-", name).lower()


def _active(requirements, extras=frozenset()) -> list:
    """The requirements (packaging Requirement objects) that apply with these extras on this
    platform (no extra: only the unconditional ones)."""
    from packaging.requirements import Requirement

    out = []
    for text in requirements or ():
        req = Requirement(text)
        if req.marker is None or any(req.marker.evaluate({"extra": e}) for e in {"", *extras}):
            out.append(req)
    return out


#: imported by the package but not needed to run it: module -> why
NOT_RUNTIME = {
    "PyAstronomy": "catalog.sed.teff_from_spectral_type re-derives a frozen table; a test dependency"
}


@pytest.mark.slow
def test_wheel_declares_every_distribution_it_imports(installed):
    """Every module the wheel's code imports is the standard library's, straylight's, or comes
    from a distribution its metadata requires (directly, with their extras, or through them):
    the test's environment lends the dependencies, so a missing requirement is caught here."""
    import importlib.metadata as md
    import re

    wheel = installed[0]
    z = zipfile.ZipFile(wheel)
    meta = next(n for n in z.namelist() if n.endswith(".dist-info/METADATA"))
    todo = [
        (_norm(r.name), frozenset(r.extras))
        for r in _active(re.findall(r"^Requires-Dist: (.+)$", z.read(meta).decode(), re.M))
    ]
    assert {"numpy", "astropy", "tqdm", "pygments", "numba"} <= {n for n, _ in todo}
    # the requirements' own requirements (with the extras asked for), as this environment has them
    closure, seen = set(), set()
    while todo:
        name, extras = todo.pop()
        if (name, extras) in seen:
            continue
        seen.add((name, extras))
        closure.add(name)
        try:
            todo.extend((_norm(r.name), frozenset(r.extras)) for r in _active(md.requires(name), extras))
        except md.PackageNotFoundError:
            pass
    providers = {mod: {_norm(d) for d in dists} for mod, dists in md.packages_distributions().items()}
    missing = {}
    for name in z.namelist():
        if not name.endswith(".py"):
            continue
        for mod in _top_level_imports(z.read(name).decode()):
            if (
                mod in sys.stdlib_module_names
                or mod in ("straylight", "_common", "__future__")
                or mod in NOT_RUNTIME
            ):
                continue
            if not providers.get(mod, set()) & closure:
                missing.setdefault(mod, []).append(name)
    assert not missing, f"imported but not required by the wheel: {missing}"


@pytest.mark.slow
def test_installed_cli_and_api_work_from_an_empty_folder(installed):
    wheel, version, commit, bin_, env, empty = installed

    def python(code):
        return subprocess.run(
            [str(bin_ / "python"), "-c", textwrap.dedent(code)],
            cwd=empty,
            env=env,
            capture_output=True,
            text=True,
            timeout=600,
        )

    r = python("""
        import straylight, straylight.config as c, straylight.runner as rn
        print(straylight.__file__); print(c.DEFAULT_CONFIG)
        print(c.CAMPAIGN_SCHEMA); print(rn.workflow_dir())
        """)
    assert r.returncode == 0, r.stderr
    site = bin_.parent / "lib"
    for line in r.stdout.split():
        assert line.startswith(str(site)), line
    assert r.stdout.split()[-1].endswith("straylight/_workflow")
    r = subprocess.run(
        ["straylight", "--version"], cwd=empty, env=env, capture_output=True, text=True, timeout=300
    )
    assert r.returncode == 0 and r.stdout.strip() == f"straylight {version}", r.stdout + r.stderr
    r = subprocess.run(
        ["straylight", "sky", "--time", "2026-01-01T00:30:00", "--ra", "150", "--dec", "30", "--bands", "g"],
        cwd=empty,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stderr
    assert "mag/arcsec2" in r.stdout and "5-sigma" in r.stdout
    # the Python API: 3 times x 4 pointings, the packaged default config
    r = python("""
        import numpy as np, astropy.units as u
        from astropy.time import Time
        from astropy.coordinates import SkyCoord
        import straylight
        t = Time("2026-01-01T00:00:00") + np.arange(3)[:, None] * 30 * u.min
        coord = SkyCoord([150, 10, 200, 300], [30, -60, 0, 45], unit="deg")[None, :]
        sky = straylight.sky_background(t, coord, bands=["g", "i"])
        assert len(sky) == 12 and sky["total_i"].unit == u.electron / u.s / u.pix, sky
        ok = sky["observable"]
        print(int(ok.sum()), float(np.median(sky["total_mag_g"][ok].value)))
        """)
    assert r.returncode == 0, r.stderr
    n_obs, median_g = r.stdout.split()
    assert int(n_obs) > 0
    assert 21.0 < float(median_g) < 23.8  # g sky 23.1-23.6 mag/arcsec2 when dark; Moon up here
    assert sorted(p.name for p in empty.iterdir()) == []  # nothing written where it ran


@pytest.mark.slow
def test_installed_run_makes_the_products_and_the_report(installed):
    """`straylight run tiny.yaml --cores 2` from an empty folder with only the campaign file: the
    packaged workflow (its job scripts import their _common module from the install), products
    in ./results/tiny/, provenance naming the build's commit; then the HTML report."""
    wheel, version, commit, bin_, env, empty = installed
    run = empty.parent / "run"
    run.mkdir()
    (run / "tiny.yaml").write_text(TINY)
    r = subprocess.run(
        ["straylight", "run", "tiny.yaml", "--cores", "2"],
        cwd=run,
        env=env,
        capture_output=True,
        text=True,
        timeout=1200,
    )
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-5000:]
    out = run / "results" / "tiny"
    # quiet: where the log is and the closing line (no bar: stderr is not a terminal)
    assert r.stderr.splitlines()[-1].startswith("straylight run: done in ") and r.stderr.count("\n") == 2
    assert "steps (100%) done" in (out / "work" / "logs" / "snakemake.log").read_text()
    for p in (
        "background.zarr",
        "limits.zarr",
        "observability.zarr",
        "sky_compact.zarr",
        "ephemeris.zarr",
        "footprint.fits",
        "stars_csst.parquet",
        "maps/limit_best_g.fits",
        "depth/depth_summary.csv",
        "summary.rst",
        "provenance.json",
    ):
        assert (out / p).exists(), p
    assert list((out / "sky").glob("sky_g_*.png"))
    prov = json.loads((out / "provenance.json").read_text())
    assert prov["source"]["from"] == "install" and prov["source"]["version"] == version
    assert commit.startswith(prov["source"]["commit"]) and len(prov["source"]["commit"]) >= 7
    assert prov["run"]["command"][:3] == ["snakemake", "-s", "straylight:workflow/Snakefile"]
    assert prov["run"]["cores"] == 2 and prov["run"]["started_by"] == [
        "straylight",
        "run",
        "tiny.yaml",
        "--cores",
        "2",
    ]
    assert prov["config_file"] == "../../tiny.yaml"
    assert (
        prov["instrument_file"] == prov["config"]["instrument"] == "straylight:config/instruments/csst.yaml"
    )
    assert str(run) not in (out / "provenance.json").read_text() and str(bin_.parent) not in json.dumps(prov)
    # the report, as the README gives it for an install (Snakemake's report needs pygments)
    r = subprocess.run(
        ["straylight", "run", "tiny.yaml", "--report", "report.html"],
        cwd=run,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    text = (run / "report.html").read_text(errors="replace")
    assert (run / "report.html").stat().st_size > 100_000
    for needle in ("1. Depth: table and maps", "5. Provenance", "median depth (AB mag)"):
        assert needle in text, needle
