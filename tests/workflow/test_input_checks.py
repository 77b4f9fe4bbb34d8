"""Inputs a user trial found unchecked (issue #53): each refused in one line before any long work
(the API: InputError or ConfigError), or accepted with one warning where the value is legal but
surprising.  docs/reliability.md lists them with the bad-input corpus."""

import contextlib
import logging
import os

import astropy.units as u
import numpy as np
import pytest
from astropy.coordinates import SkyCoord
from astropy.time import Time
from conftest import tiny_config

import straylight
from straylight.errors import InputError

T = Time("2026-01-01T00:30:00")
#: a campaign with no table to build (the direct earthshine sum), for the tests that compute
DIRECT = {
    "campaign": {"name": "direct", "end": "2026-01-01T02:00:00"},
    "models": {"earthshine": {"method": "direct"}},
}


@pytest.fixture
def no_model(monkeypatch):
    """Fails the test if a background model (or its tables) is built: the refusal comes first."""
    import straylight.skymodel as skymodel

    def built(*_a, **_k):
        raise AssertionError("a model was built before the bad input was refused")

    monkeypatch.setattr(skymodel, "cached_sky_model", built)
    monkeypatch.setattr(skymodel, "SkyModel", built)


def _main(argv, capsys):
    from straylight.cli import main

    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


# -- the API: one exception naming the argument, before a model --------------------------------
def test_altaz_without_location_is_refused(no_model):
    altaz = SkyCoord(az=10 * u.deg, alt=30 * u.deg, frame="altaz", obstime=T)
    with pytest.raises(InputError, match="coord: its altaz frame has no location"):
        straylight.sky_background(T, altaz, bands=["g"])


def test_a_time_far_outside_de405_is_refused_not_an_erfa_error(no_model):
    with pytest.raises(InputError, match=r"time = JD 1e\+10 \(utc\) is outside the DE405 range"):
        straylight.sky_background(Time(1e10, format="jd"), SkyCoord(10, 20, unit="deg"))
    with pytest.raises(
        InputError, match=r"time: sample 1 = JD 1e\+10 \(utc\) .*; 1 of 2 samples are outside it"
    ):
        straylight.sky_background(Time([2461041.5, 1e10], format="jd"), SkyCoord(10, 20, unit="deg"))


def test_a_band_twice_is_refused(no_model):
    with pytest.raises(InputError, match="band 'g' given twice"):
        straylight.sky_background(T, SkyCoord(10, 20, unit="deg"), bands=["g", "g"])


def test_open_campaign_refuses_a_non_path_and_an_empty_folder(tmp_path):
    with pytest.raises(InputError, match="expected a campaign results folder .*got int"):
        straylight.open_campaign(42)
    with pytest.raises(InputError, match="no campaign product in this folder"):
        straylight.open_campaign(tmp_path)  # at open, not on first access
    (tmp_path / "provenance.json").write_text("{}")  # a folder with a product opens
    assert straylight.open_campaign(tmp_path).provenance == {}


def test_a_coordinate_with_a_distance_is_taken_as_a_direction_said_once(caplog, monkeypatch):
    import straylight.skymodel as skymodel
    from straylight.skymodel import checked_samples

    monkeypatch.setattr(skymodel, "_DISTANCE_WARNED", [])  # a fresh process's
    near = SkyCoord([10.0, 11.0] * u.deg, [20.0, 21.0] * u.deg, distance=[1000.0, 2000.0] * u.km)
    with caplog.at_level(logging.WARNING):
        _, ra, dec = checked_samples(T, near)
        checked_samples(T, near)  # a scheduler's next call: not again
    said = [r.getMessage() for r in caplog.records if "has a distance" in r.getMessage()]
    assert len(said) == 1 and "1000.0 km" in said[0], said
    np.testing.assert_allclose(ra, [10.0, 11.0], atol=1e-9)  # the direction, unchanged
    np.testing.assert_allclose(dec, [20.0, 21.0], atol=1e-9)


# -- files and folders -------------------------------------------------------------------------
def test_a_cache_that_is_a_file_is_refused_before_a_table_build(tmp_path, monkeypatch, capsys):
    import straylight.sources.earthshine.nodes as nodes

    afile = tmp_path / "cache"
    afile.write_text("not a folder")
    monkeypatch.setenv("STRAYLIGHT_CACHE", str(afile))
    monkeypatch.setattr(nodes, "cache_dir", nodes.cache_dir)  # the real one, read at the build
    with pytest.raises(InputError, match=f"STRAYLIGHT_CACHE = {afile}: is a file, not a folder"):
        straylight.SkyModel(config={"campaign": {"name": "cachetest"}})
    monkeypatch.setenv("STRAYLIGHT_CACHE", str(afile / "below"))
    # a campaign no earlier test has built a model of (the process keeps models by config)
    cfg = tmp_path / "cachetest.yaml"
    cfg.write_text("campaign: {name: cachetest_cli}\n")
    argv = ["sky", "--config", cfg, "--time", "2026-01-01T00:30:00", "--ra", 10, "--dec", 20]
    code, _, err = _main(argv, capsys)
    assert code == 2 and err.count("\n") == 1 and f"is under {afile}, a file" in err, err


def test_results_name_existing_as_a_file_is_refused_before_snakemake(tmp_path, monkeypatch, capsys):
    import straylight.runner as runner

    cfg = tiny_config(tmp_path)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "tiny").write_text("a file where the products' folder goes")

    def started(*_a, **_k):
        raise AssertionError("Snakemake started")

    monkeypatch.setattr(runner.subprocess, "Popen", started)
    code, _, err = _main(["run", cfg], capsys)
    assert code == 2 and err.count("\n") == 1, err
    assert f"{tmp_path / 'results' / 'tiny'}: exists and is not a folder" in err


def test_a_csv_with_a_byte_order_mark_is_read_by_every_csv_reader(tmp_path):
    from straylight.catalog.star_table import read_star_columns
    from straylight.planning.pointings import read_pointings
    from straylight.planning.target_names import read_targets

    bom = b"\xef\xbb\xbf"
    files = {
        "pointings.csv": b"time,ra,dec\n2026-01-01T00:30:00,150.5,30.25\n",
        "targets.csv": b"name,ra,dec\nfield,150.5,30.25\n",
        "stars.csv": b"ra,dec,mag_g\n150.5,30.25,7.5\n",
    }
    for name, text in files.items():
        (tmp_path / name).write_bytes(bom + text)
    p = read_pointings(tmp_path / "pointings.csv")
    assert (p["ra"][0], p["dec"][0]) == (150.5, 30.25)
    tg = read_targets(tmp_path / "targets.csv")
    assert (tg.names, tg.ra_deg[0], tg.dec_deg[0]) == (["field"], 150.5, 30.25)
    ra, dec, mags = read_star_columns(tmp_path / "stars.csv", ["g"])
    assert (ra[0], dec[0], mags["g"][0]) == (150.5, 30.25, 7.5)


# -- warnings: legal but surprising ------------------------------------------------------------
def test_plan_and_run_warn_of_a_huge_campaign_before_any_work(tmp_path, monkeypatch, capsys, caplog):
    """cadence_s 0.001 over an hour: 3.6e6 times x 192 pixels (nside 4) = 6.9e8 samples, 17 GB at
    25 bytes a sample is under the 20 GB threshold; over 2 h it is 35 GB and warned about."""
    import straylight.runner as runner
    from straylight.config import load_campaign
    from straylight.planning.sizes import campaign_size, size_warning

    cfg = tiny_config(tmp_path, campaign={"cadence_s": 0.001})
    c = load_campaign(cfg)
    size = campaign_size(c, 192)
    nt = int(np.ceil(7200.0 / 0.001 - 1e-9))  # as campaign_times counts them
    assert size["times"] == nt and abs(nt - 7.2e6) <= 1
    assert size["product_bytes"] == pytest.approx(nt * 192 * 25.0)
    said = size_warning(c, 192)
    assert "campaign.cadence_s = 0.001" in said and "~35 GB of products (over 20 GB)" in said
    assert size_warning(load_campaign(tiny_config(tmp_path, name="ordinary")), 192) is None

    # run: the footprint's own pixels (nside 4 less the latitude cuts), at a yet finer cadence
    cfg = tiny_config(tmp_path, name="finer", campaign={"cadence_s": 0.0002})
    monkeypatch.chdir(tmp_path)

    class Done:
        def __init__(self, *_a, **_k):
            pass

        def wait(self):
            return 0

    monkeypatch.setattr(runner.subprocess, "Popen", Done)
    with caplog.at_level(logging.WARNING, logger="straylight.runner"):
        code, _, _ = _main(["run", cfg, "-v"], capsys)  # -v: Snakemake's console, the plain Popen
    said = [r.getMessage() for r in caplog.records if r.name == "straylight.runner"]
    assert code == 0 and len(said) == 1 and "(over 20 GB)" in said[0], said


def test_etc_warns_outside_its_noise_model_and_prints_no_60_digits(caplog):
    from straylight.cli.etc import _fmt_s

    sky = straylight.SkyModel(config=DIRECT)
    c = SkyCoord(150.0, 30.0, unit="deg")
    for mag, said in ((-30.0, "the source saturates"), (99.0, "over a day"), (22.0, None)):
        caplog.clear()
        with caplog.at_level(logging.WARNING):
            etc = sky.exposure_time(T, c, mag, bands=["g"])
        lines = [r.getMessage() for r in caplog.records if f"AB {mag:g} in g" in r.getMessage()]
        assert lines == [] if said is None else (len(lines) == 1 and said in lines[0]), lines
        t = float(etc["exposure_time"][0].value)
        assert len(_fmt_s(t)) <= 12, _fmt_s(t)  # 3 significant digits at the extremes
    assert _fmt_s(1.1e60) == "1.1e+60 s" and _fmt_s(5.67e-21) == "5.67e-21 s" and _fmt_s(150.04) == "150.0 s"


def test_visibility_warns_of_a_target_on_a_bright_star(caplog):
    from straylight.planning.bright_targets import bright_stars_at, warn_bright_targets

    # Sirius at its J2000 position (SIMBAD: 101.2871553, -16.7161159): 35 arcsec from where its
    # proper motion (-546, -1223 mas/yr) carries it by 2026.0
    hits = bright_stars_at([101.2871553, 150.0], [-16.7161159, 30.0], 2026.0)
    assert len(hits) == 1 and hits[0]["index"] == 0 and hits[0]["hip"] == 32349
    assert hits[0]["separation_arcsec"] == pytest.approx(34.8, abs=0.5)
    with caplog.at_level(logging.WARNING):
        lines = warn_bright_targets([101.2871553], [-16.7161159], 2026.0, names=["Sirius"])
    assert len(lines) == 1 and lines[0].startswith("Sirius: on the star HIP 32349")


@pytest.mark.slow
def test_ctrl_c_during_run_is_one_line_and_exit_130(tmp_path):
    """A Ctrl-C (SIGINT to the terminal's whole process group: `straylight run`, Snakemake and
    its jobs) once a job runs: exit 130, our one line last on stderr, no traceback from any job
    (the job's log says it stopped)."""
    import signal
    import subprocess
    import sys
    import time

    psutil = pytest.importorskip("psutil")
    cfg = tiny_config(tmp_path)

    def as_a_terminals_foreground_job():
        # Ctrl-C's and SIGTERM's default actions, none blocked, as a shell gives its foreground
        # job (a suite started in the background, `make test &`, passes SIGINT down ignored; a
        # harness may pass signals down blocked)
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
            signal.signal(sig, signal.SIG_DFL)
        signal.pthread_sigmask(signal.SIG_SETMASK, set())

    proc = subprocess.Popen(
        [sys.executable, "-m", "straylight.cli", "run", str(cfg), "--cores", "2"],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group, as a terminal's foreground job
        preexec_fn=as_a_terminals_foreground_job,
    )
    deadline, job = time.monotonic() + 300, None
    while job is None and time.monotonic() < deadline and proc.poll() is None:
        for child in psutil.Process(proc.pid).children(recursive=True):
            try:
                if ".snakemake/scripts/" in " ".join(child.cmdline()):
                    job = child
            except psutil.NoSuchProcess:
                pass
        time.sleep(0.2)
    assert job is not None, "no job started"
    time.sleep(3.0)  # the job's imports done: it computes

    def signal_masks(pid):  # blocked, ignored, caught
        try:
            with open(f"/proc/{pid}/status") as status:
                return [line.split()[1] for line in status if line.startswith(("SigBlk", "SigIgn", "SigCgt"))]
        except OSError:
            return "gone"

    def tree():  # the run's processes: pid, name, state and signal masks
        out = []
        for c in psutil.Process(proc.pid).children(recursive=True):
            try:
                out.append((c.pid, c.name(), c.status(), signal_masks(c.pid)))
            except psutil.NoSuchProcess:
                pass
        return out

    # the processes when the Ctrl-C comes, for a failure's message
    at_ctrl_c, masks = tree(), signal_masks(proc.pid)
    os.killpg(proc.pid, signal.SIGINT)
    try:
        # the run's SIGTERM to Snakemake's group, then SIGKILL after runner.STOP_GRACE_SECONDS (30)
        out, err = proc.communicate(timeout=150)
    except subprocess.TimeoutExpired:
        left = tree()
        for pid in [proc.pid] + [c[0] for c in left]:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        out, err = proc.communicate()
        pytest.fail(f"no end 150 s after the Ctrl-C; run {masks}, at the Ctrl-C {at_ctrl_c}, left {left}")
    assert proc.returncode == 130, f"{masks}; running at the Ctrl-C: {at_ctrl_c}\n{err[-3000:]}"
    assert "Traceback" not in out + err and "KeyboardInterrupt" not in out + err, err[-3000:]
    assert err.strip().splitlines()[-1].startswith("straylight run: interrupted"), err[-3000:]
    for log in (tmp_path / "results" / "tiny" / "work" / "logs").glob("*.log"):
        assert "Traceback" not in log.read_text(), log
