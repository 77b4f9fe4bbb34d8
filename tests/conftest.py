import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
# tests keep their earthshine look-up tables to themselves (subprocesses inherit this)
os.environ["STRAYLIGHT_CACHE"] = tempfile.mkdtemp(prefix="straylight-test-cache-")
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
    area = aperture_area_m2(campaign.instrument)
    d = {}
    for b in campaign.bands:
        wl, t = read_throughput_file(THROUGHPUT / f"csst_phot.{b.lower()}.fits")
        d[b] = zero_point_ab_mag(load_band(campaign.instrument, b), area) - zero_point_ab_mag(
            Band(b, wl, t, "file"), area
        )
    return d


@pytest.fixture(scope="session")
def default_tables():
    """The default campaign's earthshine tables in the session's cache (built once if missing), for
    tests that read a command's whole output (a build prints its notice and progress)."""
    import straylight

    straylight.SkyModel()


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


def tiny_config(tmp, name="tiny", campaign=None, footprint=None, compute=None):
    """A small campaign config (2 h at 10 min, nside 4) written to tmp; returns its path."""
    import yaml

    cfg = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
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
