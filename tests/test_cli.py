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
