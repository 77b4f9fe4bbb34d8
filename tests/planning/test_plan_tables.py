"""`straylight plan`: the look-up tables a config needs, whether each is cached, a changed orbit
altitude named, and the cost figures scaled by the machine probe.

Reference values: the default campaign's tables (built by the session's ``default_tables``) and
the orbit altitudes of the configs (config/config.yaml: 400 km)."""

import json

import yaml
from conftest import REPO, run_cli


def _config_at(tmp_path, altitude_km):
    cfg = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    cfg["orbit"]["circular"]["altitude_km"] = altitude_km
    cfg["instrument"] = str(REPO / "config" / "instruments" / "csst.yaml")
    p = tmp_path / f"orbit{altitude_km:.0f}.yaml"
    p.write_text(yaml.safe_dump(cfg))
    return p


def test_plan_lists_the_tables_and_another_orbit_altitude(tmp_path, default_tables):
    """The default campaign: its sunlit and moonlit tables listed as cached, and the envelope
    members', each cached or with its build time.  The same at 450 km: the sunlit table not
    cached, with its build time, and the cached one's altitude (400 km) named beside this
    orbit's; the probe's factor printed and kept in the cache."""
    from straylight.util.io import cache_dir

    r = run_cli("plan", "--cores", "2", timeout=300)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    listed = [
        x for x in lines if x.startswith("  sunlit-Earth table") or x.startswith("  moonlit-Earth table")
    ]
    # the nominal model's two and each envelope member's two (config/instruments/csst.yaml): the
    # session builds the nominal ones (default_tables), the members' where a test needs them
    assert len(listed) == 6, r.stdout
    nominal = [x for x in listed if "member)" not in x]
    assert len(nominal) == 2 and all(x.endswith(": cached") for x in nominal), r.stdout
    assert all(x.endswith(": cached") or ": not cached: ~" in x for x in listed), r.stdout
    assert sum("(the envelope's pessimistic member)" in x for x in listed) == 2, r.stdout
    every = all(x.endswith(": cached") for x in listed)
    assert ("its tables are cached" in r.stdout) == every, r.stdout
    line = next(x for x in lines if x.startswith("this machine now"))
    factor = float(line.split(" x", 1)[1].split(" ", 1)[0])
    assert 0.0 < factor < 100.0
    kept = json.loads((cache_dir() / "speed_probe.json").read_text())["2"]
    assert abs(kept["factor"] - factor) < 0.005 + 1e-3 * factor  # printed to 2 decimals

    r = run_cli("plan", _config_at(tmp_path, 450.0), "--cores", "2", timeout=300)
    assert r.returncode == 0, r.stderr
    sunlit = next(x for x in r.stdout.splitlines() if x.startswith("  sunlit-Earth table"))
    assert ": not cached: ~" in sunlit and "s to build on 2 core(s)" in sunlit
    assert "orbit altitudes 400 km" in r.stdout and "this orbit, 450 km, needs its own" in r.stdout
