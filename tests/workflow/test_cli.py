"""The CLI as a user runs it: JSON content, and clear errors without tracebacks.

Reference values: the library's API for the same inputs (ephemeris, zero points, limits) and,
for the scenario, the paper's sect. 3.3."""

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO, run_cli, run_clis


def test_ephem_json_matches_library():
    from straylight.sky.ephemeris import default_ephemeris

    r = run_cli("ephem", "--time", "2026-01-01T00:50:00", "--bodies", "sun,moon,jupiter", "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert set(out["bodies"]) == {"sun", "moon", "jupiter"}
    ref = default_ephemeris().positions("2026-01-01T00:50:00", ["moon"])["moon"]
    m = out["bodies"]["moon"]
    np.testing.assert_allclose([m["x_km"], m["y_km"], m["z_km"]], ref, rtol=1e-12)
    assert m["distance_km"] == pytest.approx(np.linalg.norm(ref))
    assert 356000 < m["distance_km"] < 407000  # lunar perigee-apogee range


def test_sky_json_has_the_documented_fields():
    r = run_cli("sky", "--time", "2026-01-01T00:50:00", "--ra", "150", "--dec", "60", "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    for key in ("time", "ra_deg", "dec_deg", "satellite_gcrs_km", "geometry", "observable", "violations"):
        assert key in out
    g = out["geometry"]
    for key in (
        "sun_angle_deg",
        "moon_angle_deg",
        "moon_phase_angle_deg",
        "moon_illuminated_fraction",
        "earth_limb_angle_deg",
        "limb_is_bright",
        "zenith_angle_deg",
        "door_opening_deg",
        "planet_angles_deg",
    ):
        assert key in g
    assert set(g["planet_angles_deg"]) == {
        "mercury",
        "venus",
        "mars",
        "jupiter",
        "saturn",
        "uranus",
        "neptune",
        "pluto",
    }
    assert np.linalg.norm(out["satellite_gcrs_km"]) == pytest.approx(6778.137, rel=1e-9)
    assert out["observable"] == (out["violations"] == [])


def test_sky_gives_magnitudes_and_the_limit_in_text_and_json(campaign, default_tables):
    """mag/arcsec2 = zero point - 2.5 log10(e-/s/pixel), the limit = limits.point_source_limit."""
    from straylight.limits.point_source import point_source_limit, sky_zero_points

    args = ("sky", "--time", "2026-01-01T00:30:00", "--ra", "150", "--dec", "30", "--bands", "g,y")
    r, text = run_clis((*args, "--json"), args)  # side by side
    assert r.returncode == 0, r.stderr
    bands = json.loads(r.stdout)["bands"]
    zp = sky_zero_points(campaign, ["g", "y"])
    for b in ("g", "y"):
        tot = bands[b]["total"]
        assert bands[b]["mag_zero_point"] == pytest.approx(zp[b], abs=1e-9)
        assert tot["mag_per_arcsec2"] == pytest.approx(
            zp[b] - 2.5 * np.log10(tot["e_per_s_per_pix"]), abs=1e-9
        )
        assert bands[b]["limit_mag"] == pytest.approx(
            point_source_limit(tot["e_per_s_per_pix"], b, campaign), abs=1e-9
        )
    # g dark sky 23.1-23.6 mag/arcsec2 and depth ~26.8 (from the cube); the Moon adds a little here
    assert 22.0 < bands["g"]["total"]["mag_per_arcsec2"] < 23.8 and 26.0 < bands["g"]["limit_mag"] < 27.2
    assert text.returncode == 0, text.stderr
    mag_line = next(
        line for line in text.stdout.splitlines() if "mag/arcsec2" in line and "mag" in line.split()[-1]
    )
    assert f"{bands['g']['total']['mag_per_arcsec2']:.2f}" in mag_line
    assert f"{bands['g']['limit_mag']:.2f} mag" in mag_line


@pytest.mark.parametrize(
    "args,fragment",
    [
        (("sky", "--time", "2026-01-01T00:00:00", "--ra", "nan", "--dec", "0"), "--ra = nan is not finite"),
        (
            ("sky", "--time", "2026-01-01T00:00:00", "--ra", "10", "--dec", "95"),
            "--dec = 95.0 outside [-90, 90] deg",
        ),
        (
            ("sky", "--time", "2026-01-01T00:00:00", "--ra", "400", "--dec", "5"),
            "--ra = 400.0 outside [-360, 360] deg",
        ),
        (("sky", "--time", "2026-01-01T00:00:00", "--ra", "1e308", "--dec", "5"), "--ra = 1e+308 outside"),
        (("sky", "--time", "2301-01-01T00:00:00", "--ra", "10", "--dec", "5"), "outside the DE405 range"),
        (("sky", "--time", "tomorrow", "--ra", "10", "--dec", "5"), "cannot parse 'tomorrow'"),
        (("ephem", "--time", "2026-01-01T00:00:00", "--bodies", "vulcan"), "unknown body 'vulcan'"),
        (("ephem", "--time", "1200-01-01T00:00:00"), "outside the DE405 range"),
    ],
)
def test_user_mistakes_give_one_clear_line(args, fragment):
    r = run_cli(*args)
    assert r.returncode == 2
    assert fragment in r.stderr
    assert "Traceback" not in r.stderr


def test_bad_config_key_via_cli(tmp_path):
    cfg = (REPO / "config" / "config.yaml").read_text().replace("cadence_s: 300", "cadense_s: 300")
    cfg = cfg.replace("instrument: instruments/csst.yaml", f"instrument: {REPO}/config/instruments/csst.yaml")
    p = tmp_path / "bad.yaml"
    p.write_text(cfg)
    r = run_cli("sky", "--time", "2026-01-01T00:00:00", "--ra", "1", "--dec", "1", "--config", p)
    assert r.returncode == 2
    assert "unknown key campaign.cadense_s" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.parametrize("cmd", ["ephem", "sky", "footprint"])
def test_every_command_has_help(cmd):
    r = run_cli(cmd, "--help")
    assert r.returncode == 0 and "usage" in r.stdout


# -- output paths checked before any work ------------------------------------------------------
OUTPUT_COMMANDS = [
    ("pst", "--write-default", "pst.csv"),
    ("catalog", "--out", "cat.parquet"),
    ("image", "--out", "img.fits"),
    ("sky", "--out", "table.parquet"),
    ("scenario", "--out", "scenario.png"),
]


def _argv(cmd, flag, path, tmp_path):
    if cmd == "image":
        return (
            "image",
            "--time",
            "2026-01-01T00:50:00",
            "--ra",
            "150",
            "--dec",
            "30",
            "--band",
            "g",
            flag,
            path,
        )
    if cmd == "sky":
        table = tmp_path / "p.csv"
        table.write_text("time,ra,dec\n2026-01-01T00:50:00,10,30\n")
        return ("sky", "--input", table, flag, path)
    return (cmd, flag, path)


@pytest.mark.parametrize("cmd,flag,name", OUTPUT_COMMANDS, ids=[c[0] for c in OUTPUT_COMMANDS])
def test_existing_output_is_refused_untouched(cmd, flag, name, tmp_path):
    out = tmp_path / name
    out.write_bytes(b"an earlier product")
    r = run_cli(*_argv(cmd, flag, out, tmp_path))
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert f"{flag} {out}: file exists; pass --overwrite" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert out.read_bytes() == b"an earlier product"


@pytest.mark.parametrize("cmd,flag,name", OUTPUT_COMMANDS, ids=[c[0] for c in OUTPUT_COMMANDS])
def test_missing_folder_is_refused_not_created(cmd, flag, name, tmp_path):
    out = tmp_path / "no" / "such" / name
    r = run_cli(*_argv(cmd, flag, out, tmp_path))
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert f"folder {out.parent} does not exist; create it or pass --parents" in r.stderr
    assert not (tmp_path / "no").exists()


def test_unwritable_folder_is_one_line_before_work(tmp_path):
    """A folder the user cannot write (read-only for non-root; /proc refuses even root): one line
    naming the path, exit 2, before the catalog is built."""
    import os

    if os.geteuid() == 0:
        out = Path("/proc/straylight-test.parquet")
    else:
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o555)
        out = ro / "cat.parquet"
    r = run_cli("catalog", "--out", out, timeout=60)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert f"--out {out}: cannot write in {out.parent}" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_parents_and_overwrite_allow_writing(tmp_path):
    out = tmp_path / "new" / "dir" / "pst.csv"
    r = run_cli("pst", "--write-default", out, "--parents")
    assert r.returncode == 0, r.stderr
    first = out.read_bytes()
    r = run_cli("pst", "--write-default", out, "--overwrite")
    assert r.returncode == 0, r.stderr and out.read_bytes() == first


def test_schedule_folder_not_empty_is_refused(tmp_path):
    (tmp_path / "sched").mkdir()
    (tmp_path / "sched" / "moon_angle.csv").write_text("earlier")
    r = run_cli("schedule", "--out", tmp_path / "sched")
    assert r.returncode == 2 and "folder exists and is not empty; pass --overwrite" in r.stderr
    assert (tmp_path / "sched" / "moon_angle.csv").read_text() == "earlier"


def test_check_output_path_unit(tmp_path):
    from straylight.errors import InputError
    from straylight.util.io import check_output_path

    assert check_output_path(tmp_path / "a.fits") == tmp_path / "a.fits"
    with pytest.raises(InputError, match="is a folder"):
        check_output_path(tmp_path)
    assert not list(tmp_path.iterdir())  # the write probe leaves nothing behind


# -- times with a UTC offset (ISO 8601) ------------------------------------------------------------
def test_utc_offset_is_converted():
    """2026-01-01T08:50:00+08:00 (Beijing time) is 2026-01-01T00:50:00 UTC: same sky record."""
    a = run_cli("sky", "--time", "2026-01-01T08:50:00+08:00", "--ra", "10", "--dec", "30", "--json")
    b = run_cli("sky", "--time", "2026-01-01T00:50:00", "--ra", "10", "--dec", "30", "--json")
    assert a.returncode == 0 and b.returncode == 0, a.stderr + b.stderr
    ja, jb = json.loads(a.stdout), json.loads(b.stdout)
    assert ja["time"] == "2026-01-01T00:50:00.000"
    assert ja["geometry"] == jb["geometry"]


def test_utc_offsets_in_a_pointing_table(tmp_path, campaign):
    from straylight.planning.pointings import pointing_table, read_pointings

    p = tmp_path / "p.csv"
    p.write_text(
        "time,ra,dec\n2026-01-01T08:50:00+08:00,10,30\n2026-01-01T00:50:00Z,10,30\n"
        "2025-12-31T19:20:00-05:30,10,30\n"
    )
    cols = pointing_table(campaign, read_pointings(p), ["g"])
    assert list(cols["time"]) == ["2026-01-01T00:50:00.000"] * 3
    assert cols["total_g"][0] == cols["total_g"][1] == cols["total_g"][2]


def test_scenario_overlays_hst_and_writes_the_crossing_angle(tmp_path):
    """`straylight scenario --hst-curve PATH` (paper sect. 3.3): prints, and writes to a JSON beside
    its CSV, the limb angle at which CSST's median earthshine falls to HST's at 20 deg (the WFC3
    IHB fig. 9.2 curve: 20.6 V mag/arcsec2); the paper: 70 deg over the sunlit orbital phases'
    median; the default orbit's phase (a dim Earth, the Sun 3.7 deg above the satellite's
    horizon): 55.1 deg at the calibrated tail (docs/pst.md, "The tail over orbital phases")."""
    from conftest import SHARED_DATA

    curve = SHARED_DATA / "hst_sky" / "wfc3_earthshine_v_vs_limb_angle.csv"
    if not curve.exists():
        pytest.skip(
            f"{curve} is absent: the HST WFC3 earthshine curve is test and validation only "
            "(shared/data/DATA.md)"
        )
    out = tmp_path / "es.png"
    r = run_cli("scenario", "--hst-curve", curve, "--out", out, timeout=900)
    assert r.returncode == 0, r.stderr
    res = json.loads(out.with_suffix(".json").read_text())
    assert res["hst_v_mag_per_arcsec2"] == pytest.approx(20.6, abs=0.05)
    assert res["csst_crossing_limb_angle_deg"] == pytest.approx(55.1, abs=2.0)
    assert f"{res['csst_crossing_limb_angle_deg']:.1f} deg from the bright limb" in r.stdout
    assert out.with_suffix(".csv").exists() and out.stat().st_size > 10000


def test_scenario_refuses_a_bad_hst_curve_before_the_work(tmp_path):
    bad = tmp_path / "hst.csv"
    bad.write_text("angle,mag\n10,15\n30,21\n")
    r = run_cli("scenario", "--hst-curve", bad, "--out", tmp_path / "es.png")
    assert r.returncode == 2
    assert f"{bad}: missing column(s) limb_angle_deg, v_mag_per_arcsec2" in r.stderr
    assert "Traceback" not in r.stderr and not (tmp_path / "es.csv").exists()
