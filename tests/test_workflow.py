"""The Snakemake spine: dry run, lint, schema validation and a small end-to-end run."""
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from conftest import REPO

SNAKEMAKE = str(Path(sys.executable).with_name("snakemake"))


def snakemake(*args, cwd=REPO, timeout=600):
    return subprocess.run([SNAKEMAKE, *args], cwd=cwd, capture_output=True, text=True, timeout=timeout)


def test_dry_run_is_clean():
    r = snakemake("-n", "--quiet")
    assert r.returncode == 0, r.stderr


def test_lint_is_clean():
    r = snakemake("--lint")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "Congratulations" in r.stdout + r.stderr


def tiny_config(tmp_path, **campaign):
    from conftest import tiny_config as make

    return make(tmp_path, campaign=campaign)


def test_snakemake_validate_refuses_bad_config(tmp_path):
    p = tiny_config(tmp_path, cadence_s=-5)
    r = snakemake("-s", str(REPO / "Snakefile"), "-d", str(tmp_path), "--configfile", str(p), "-n")
    assert r.returncode != 0
    assert "cadence_s" in r.stdout + r.stderr


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("wf")
    p = tiny_config(tmp)
    r = snakemake("-s", str(REPO / "Snakefile"), "-d", str(tmp), "--configfile", str(p), "--cores", "2")
    assert r.returncode == 0, r.stdout + r.stderr
    return tmp / "results" / "tiny", p


def test_end_to_end_products(tiny_run):
    import healpy as hp

    out, _ = tiny_run
    eph = xr.open_zarr(out / "ephemeris.zarr")
    assert eph.sizes["time"] == 12 and eph.sizes["body"] == 10
    for name, var in eph.data_vars.items():
        assert "units" in var.attrs and "long_name" in var.attrs, name
    m = hp.read_map(out / "footprint.fits")
    assert hp.get_nside(m) == 4 and 0 < m.sum() < m.size
    obs = xr.open_zarr(out / "observability.zarr")
    assert obs.sizes["pixel"] == int(m.sum())
    assert obs.attrs["healpix_nside"] == 4
    assert not np.any(np.isnan(obs["sun_angle_deg"].values))


def test_cube_value_equals_sky_command(tiny_run):
    """An observability value equals `straylight sky` for the same time and pointing (to the
    stored values' bound, straylight/storage.py)."""
    from conftest import sky_at

    out, cfg = tiny_run
    obs = xr.open_zarr(out / "observability.zarr")
    it, ip = 7, 5
    rec = sky_at(obs, it, ip, cfg)
    for k in ("sun_angle_deg", "moon_angle_deg", "earth_limb_angle_deg"):
        assert float(obs[k][it, ip]) == pytest.approx(rec["geometry"][k], rel=obs[k].attrs["max_relative_error"] + 1e-6,
                                                     abs=1e-4)
    assert bool(obs["observable"][it, ip]) == rec["observable"]


def test_rerun_does_nothing(tiny_run):
    out, cfg = tiny_run
    r = snakemake("-s", str(REPO / "Snakefile"), "-d", str(out.parent.parent), "--configfile", str(cfg), "-n")
    assert r.returncode == 0
    assert "Nothing to be done" in r.stdout + r.stderr
