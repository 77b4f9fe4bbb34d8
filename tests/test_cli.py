"""The CLI as a user runs it: JSON content, and clear errors without tracebacks."""
import json

import numpy as np
import pytest

from conftest import REPO, run_cli


def test_ephem_json_matches_library():
    from straylight.ephemeris import default_ephemeris

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
    for key in ("sun_angle_deg", "moon_angle_deg", "moon_phase_angle_deg", "moon_illuminated_fraction",
                "earth_limb_angle_deg", "limb_is_bright", "zenith_angle_deg", "door_opening_deg",
                "planet_angles_deg"):
        assert key in g
    assert set(g["planet_angles_deg"]) == {"mercury", "venus", "mars", "jupiter", "saturn", "uranus",
                                           "neptune", "pluto"}
    assert np.linalg.norm(out["satellite_gcrs_km"]) == pytest.approx(6778.137, rel=1e-9)
    assert out["observable"] == (out["violations"] == [])


@pytest.mark.parametrize("args,fragment", [
    (("sky", "--time", "2026-01-01T00:00:00", "--ra", "nan", "--dec", "0"), "--ra must be finite"),
    (("sky", "--time", "2026-01-01T00:00:00", "--ra", "10", "--dec", "95"), "--dec: must be within"),
    (("sky", "--time", "2301-01-01T00:00:00", "--ra", "10", "--dec", "5"), "outside the DE405 range"),
    (("sky", "--time", "tomorrow", "--ra", "10", "--dec", "5"), "cannot parse 'tomorrow'"),
    (("ephem", "--time", "2026-01-01T00:00:00", "--bodies", "vulcan"), "unknown body 'vulcan'"),
    (("ephem", "--time", "1200-01-01T00:00:00"), "outside the DE405 range"),
])
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


def test_scenario_overlays_hst_and_writes_the_crossing_angle(tmp_path):
    """`straylight scenario --hst-curve PATH` (paper sect. 3.3): prints, and writes to a JSON beside
    its CSV, the limb angle at which CSST's median earthshine falls to HST's at 20 deg (the WFC3
    IHB fig. 9.2 curve: 20.6 V mag/arcsec2); the paper: 70 deg; the default instrument: 69.4."""
    from conftest import SHARED_DATA

    curve = SHARED_DATA / "hst_sky" / "wfc3_earthshine_v_vs_limb_angle.csv"
    if not curve.exists():
        pytest.skip(f"{curve} is absent: the HST WFC3 earthshine curve is test and validation only "
                    "(shared/data/DATA.md)")
    out = tmp_path / "es.png"
    r = run_cli("scenario", "--hst-curve", curve, "--out", out, timeout=900)
    assert r.returncode == 0, r.stderr
    res = json.loads(out.with_suffix(".json").read_text())
    assert res["hst_v_mag_per_arcsec2"] == pytest.approx(20.6, abs=0.05)
    assert res["csst_crossing_limb_angle_deg"] == pytest.approx(70.0, abs=5.0)
    assert f"{res['csst_crossing_limb_angle_deg']:.1f} deg from the bright limb" in r.stdout
    assert out.with_suffix(".csv").exists() and out.stat().st_size > 10000


def test_scenario_refuses_a_bad_hst_curve_before_the_work(tmp_path):
    bad = tmp_path / "hst.csv"
    bad.write_text("angle,mag\n10,15\n30,21\n")
    r = run_cli("scenario", "--hst-curve", bad, "--out", tmp_path / "es.png")
    assert r.returncode == 2
    assert f"{bad}: missing column(s) limb_angle_deg, v_mag_per_arcsec2" in r.stderr
    assert "Traceback" not in r.stderr and not (tmp_path / "es.csv").exists()
