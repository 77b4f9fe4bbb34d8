import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def _session_cache() -> str:
    """The folder of the session's earthshine look-up tables: STRAYLIGHT_TEST_CACHE where a
    developer names one that already holds them; else a fresh one, shared by the pytest-xdist
    workers of one run (``make test`` runs two)."""
    if os.environ.get("STRAYLIGHT_TEST_CACHE"):
        return os.environ["STRAYLIGHT_TEST_CACHE"]
    run = os.environ.get("PYTEST_XDIST_TESTRUNUID")
    if run:
        path = Path(tempfile.gettempdir()) / f"straylight-test-cache-{run}"
        path.mkdir(exist_ok=True)
        return str(path)
    return tempfile.mkdtemp(prefix="straylight-test-cache-")


# tests keep their earthshine look-up tables to themselves (subprocesses inherit this)
os.environ["STRAYLIGHT_CACHE"] = _session_cache()
SHARED_DATA = REPO.parent / "shared" / "data"
# ISS TLE (public NORAD element set, 2008 example from the CelesTrak documentation)
ISS_L1 = "1 25544U 98067A   08264.51782528 -.00002182  00000-0 -11606-4 0  2927"
ISS_L2 = "2 25544  51.6416 247.4627 0006703 130.5360 325.0288 15.72125391563537"


@pytest.fixture(scope="session")
def campaign():
    from straylight.config import load_campaign

    return load_campaign(REPO / "config" / "config.yaml")


#: the real CSST throughput curves (Wen et al. 2024; test-only data, shared/data/DATA.md)
THROUGHPUT = SHARED_DATA / "csst_throughput"


@pytest.fixture(scope="session")
def zero_point_less_real_curves_mag(campaign):
    """Per band, the default instrument's AB zero point less that of the real CSST curve
    (:data:`THROUGHPUT`), mag, both through the campaign's aperture; skips when the curves are
    absent."""
    from straylight.optics.bandpass import (
        Band,
        aperture_area_m2,
        load_band,
        read_throughput_file,
        zero_point_ab_mag,
    )

    if not THROUGHPUT.exists():
        pytest.skip("../shared/data/csst_throughput (test-only real CSST curves) not present")
    area = aperture_area_m2(campaign.instrument_settings)
    d = {}
    for b in campaign.bands:
        wl, t = read_throughput_file(THROUGHPUT / f"csst_phot.{b.lower()}.fits")
        d[b] = zero_point_ab_mag(load_band(campaign.instrument_settings, b), area) - zero_point_ab_mag(
            Band(b, wl, t, "file"), area
        )
    return d


@pytest.fixture(scope="session")
def default_tables():
    """The default campaign's earthshine tables in the session's cache (built once if missing), for
    tests that read a command's whole output (a build prints its notice and progress)."""
    subprocess.run([sys.executable, "-c", _BUILD_DEFAULT_TABLES], cwd=REPO, check=True)


# -- the default campaign's earthshine tables: built while the tests that never read them run ---
#: test modules (under tests/) that never read the default campaign's earthshine tables: their
#: campaigns sum the earthshine directly (:func:`tiny_config`) or evaluate none, and they run
#: while the tables are built.  The slow ones among them (campaigns run and killed, a SLURM
#: cluster's polls) leave a core idle at times, which the background build, at low priority,
#: takes.  test_earthshine_lut.py builds its own coarse sunlit tables but reads the default
#: moonlit one: listed all the same, it builds that table itself or waits for it (one build of a
#: table at a time), beside the background build.  A module wrongly listed here costs time only.
TABLE_FREE_MODULES = frozenset(
    {
        "test_api_reference.py",
        "test_architecture.py",
        "test_config.py",
        "test_execution.py",
        "test_function_limits.py",
        "test_instrument_settings.py",
        "test_plots.py",
        "test_runner.py",
        "test_settings.py",
        "catalog/test_catalog.py",
        "catalog/test_gaia.py",
        "catalog/test_luminosity_class.py",
        "catalog/test_proper_motion.py",
        "cube/test_compact.py",
        "cube/test_cube.py",
        "cube/test_footprint.py",
        "cube/test_provenance.py",
        "image/test_detector_fits.py",
        "limits/test_published_depths.py",
        "model/test_envelope.py",
        "model/test_envelope_members.py",
        "optics/test_pst_out_of_field.py",
        "optics/test_pst_tail.py",
        "optics/test_scatter_ghosts.py",
        "paper/test_door_prior.py",
        "paper/test_earthshine_checks.py",
        "paper/test_paper_figures.py",
        "sky/test_bright_limb.py",
        "sky/test_ephemeris.py",
        "sky/test_ephemeris_span.py",
        "sky/test_geometry.py",
        "sky/test_orbit.py",
        "sky/test_timeutil.py",
        "sources/test_earth_grid_cut.py",
        "sources/test_earthshine_lut.py",
        "sources/test_saturn_rings.py",
        "sources/test_table_cache_lock.py",
        "sources/test_zodiacal.py",
        "sources/test_zodiacal_colour.py",
        "util/test_gridinterp.py",
        "util/test_kernel_cache.py",
        "workflow/test_bench.py",
        "workflow/test_faults.py",
        "workflow/test_slurm.py",
        "workflow/test_workflow.py",
    }
)
#: the background build: the default campaign's model reading (so building) both its tables, at
#: low priority, so that the tests running beside it keep their core (one build of a table at a
#: time: the other xdist worker's waits for it, then reads it).  The assumption envelope's
#: members' tables are built by the first test that reads them: the tests' small campaigns sum
#: their earthshine directly (:func:`tiny_config`)
_BUILD_DEFAULT_TABLES = (
    "import os; os.nice(10); from straylight.config import load_campaign; "
    "from straylight.model import BackgroundModel; BackgroundModel(load_campaign()).models_record()"
)
_table_build = None  # its Popen, until the first test that may read the tables has waited for it


#: test modules that take minutes (campaigns run, killed and resumed, a wheel installed), the
#: longest first: each kind's run first in this order, so that the two workers of `make test`
#: end together
SLOW_MODULES = (
    "cube/test_cube.py",
    "workflow/test_faults.py",
    "sources/test_earthshine_lut.py",
    "workflow/test_slurm.py",
    "workflow/test_readme.py",
    "workflow/test_packaging.py",
    "workflow/test_workflow.py",
    "workflow/test_bench.py",
    "image/test_image.py",
    "cube/test_compact.py",
)


def _module(item) -> str:
    """The test module's path under tests/ ("" outside it)."""
    try:
        return Path(item.path).resolve().relative_to(REPO / "tests").as_posix()
    except ValueError:
        return ""


def _may_read_default_tables(item) -> bool:
    return _module(item) not in TABLE_FREE_MODULES


def pytest_collection_modifyitems(config, items):
    """In a session with tests of both kinds, the table-free modules run first (the order within
    each kind kept, but for :data:`SLOW_MODULES` first) while the default tables (once per
    session) are built in a background process; the first test of another module waits for
    that build.  pytest-xdist hands the modules out in this order with --no-loadscope-reorder
    (``make test``); without it, by their number of tests."""
    global _table_build
    # the slow modules first within each kind, in their order (a stable sort keeps the others')
    rank = {m: i for i, m in enumerate(SLOW_MODULES)}
    items.sort(key=lambda item: rank.get(_module(item), len(SLOW_MODULES)))
    free = [item for item in items if not _may_read_default_tables(item)]
    if not free or len(free) == len(items) or config.option.collectonly:
        return
    items[:] = free + [item for item in items if _may_read_default_tables(item)]
    _table_build = subprocess.Popen(
        [sys.executable, "-c", _BUILD_DEFAULT_TABLES],
        cwd=REPO,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )


def pytest_runtest_setup(item):
    global _table_build
    if _table_build is not None and _may_read_default_tables(item):
        _table_build.wait()  # a failed build is the test's to redo and report
        _table_build = None


def pytest_sessionfinish(session):
    if _table_build is not None and _table_build.poll() is None:  # stopped early (-x, Ctrl-C)
        _table_build.kill()
        _table_build.wait()


def run_cli(*args, cwd=REPO, timeout=120):
    """Run the CLI in a subprocess, as a user would; returns CompletedProcess."""
    env = dict(os.environ)
    return subprocess.run(
        [sys.executable, "-m", "straylight.cli", *map(str, args)],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=timeout,
        env=env,
    )


def run_clis(*commands, cwd=REPO, timeout=120):
    """Independent CLI commands (each a tuple of :func:`run_cli`'s arguments) run side by side,
    each in its own subprocess as :func:`run_cli` runs one, so that they share the machine's
    cores; returns their CompletedProcess in the order given.  A test using it asks for
    ``default_tables`` (or its campaign's tables are cached): each command would build them."""
    env = dict(os.environ)
    procs = [
        subprocess.Popen(
            [sys.executable, "-m", "straylight.cli", *map(str, args)],
            cwd=cwd,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
        )
        for args in commands
    ]
    done = []
    try:
        for p in procs:
            out, err = p.communicate(timeout=timeout)
            done.append(subprocess.CompletedProcess(p.args, p.returncode, out, err))
    finally:
        for p in procs:
            if p.poll() is None:  # a timeout: none is left running
                p.kill()
                p.communicate()
    return done


def tiny_config(tmp, name="tiny", campaign=None, footprint=None, compute=None, earthshine_method="direct"):
    """A small campaign config (2 h at 10 min, nside 4) written to tmp; returns its path.  Its
    earthshine is summed directly by default: a few thousand samples cost seconds so, where the
    look-up tables (the nominal model's and the envelope's two members') would cost minutes to
    build; ``earthshine_method`` "auto" reads the default tables."""
    import yaml

    cfg = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    cfg["models"]["earthshine"]["method"] = earthshine_method
    cfg["campaign"].update(name=name, end="2026-01-01T02:00:00", cadence_s=600, time_block_hours=1)
    cfg["campaign"].update(campaign or {})
    cfg["instrument"] = str(REPO / "config" / "instruments" / "csst.yaml")
    cfg["footprint"]["nside"] = 4
    # figures cost time: one map page at a chosen time, one chosen pointing
    cfg["report"] = {"sky_map_bands": ["g"], "times": ["2026-01-01T00:30:00"], "pointings": [[150.0, 30.0]]}
    cfg["footprint"].update(footprint or {})
    if compute is not None:
        cfg["compute"] = compute
    p = Path(tmp) / f"{name}.yaml"
    p.write_text(yaml.safe_dump(cfg))
    return p


def sky_at(ds, it, ip, cfg, catalog=None):
    """`straylight sky --json` at the time and pixel (indices it, ip) of a products Dataset."""
    import json

    t = str(ds["time"].values[it])[:23]
    ra, dec = float(ds["ra_deg"][ip]), float(ds["dec_deg"][ip])
    extra = ("--catalog", catalog) if catalog else ()
    r = run_cli("sky", "--time", t, "--ra", repr(ra), "--dec", repr(dec), "--config", cfg, "--json", *extra)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)
