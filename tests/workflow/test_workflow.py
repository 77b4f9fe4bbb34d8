"""The Snakemake spine: dry run, lint, schema validation and a small end-to-end run.

Reference values: `straylight sky` at the products' samples."""

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
    r = snakemake(
        "-s", str(REPO / "workflow" / "Snakefile"), "-d", str(tmp_path), "--configfile", str(p), "-n"
    )
    assert r.returncode != 0
    assert "cadence_s" in r.stdout + r.stderr


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("wf")
    p = tiny_config(tmp)
    r = snakemake(
        "-s", str(REPO / "workflow" / "Snakefile"), "-d", str(tmp), "--configfile", str(p), "--cores", "2"
    )
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
    stored values' bound, straylight/survey/storage.py)."""
    from conftest import sky_at

    out, cfg = tiny_run
    obs = xr.open_zarr(out / "observability.zarr")
    it, ip = 7, 5
    rec = sky_at(obs, it, ip, cfg)
    for k in ("sun_angle_deg", "moon_angle_deg", "earth_limb_angle_deg"):
        assert float(obs[k][it, ip]) == pytest.approx(
            rec["geometry"][k], rel=obs[k].attrs["max_relative_error"] + 1e-6, abs=1e-4
        )
    assert bool(obs["observable"][it, ip]) == rec["observable"]


def test_rerun_does_nothing(tiny_run):
    out, cfg = tiny_run
    r = snakemake(
        "-s",
        str(REPO / "workflow" / "Snakefile"),
        "-d",
        str(out.parent.parent),
        "--configfile",
        str(cfg),
        "-n",
    )
    assert r.returncode == 0
    assert "Nothing to be done" in r.stdout + r.stderr


def _campaign_in_another_folder(tmp_path, **campaign):
    """my.yaml in its own folder with relative paths: the instrument (copied into inst/) and a
    HEALPix mask beside it, neither of which exists relative to config/."""
    import shutil

    import healpy as hp
    import yaml

    folder = tmp_path / "elsewhere"
    shutil.copytree(REPO / "config" / "instruments", folder / "inst")
    cfg = yaml.safe_load(tiny_config(tmp_path, **campaign).read_text())
    cfg["instrument"] = "inst/csst.yaml"
    mask = np.zeros(hp.nside2npix(4))
    mask[: mask.size // 3] = 1
    hp.write_map(str(folder / "mask.fits"), mask, dtype=np.float64)
    cfg["footprint"]["mask_file"] = "mask.fits"
    p = folder / "my.yaml"
    p.write_text(yaml.safe_dump(cfg))
    return p


def test_configfile_paths_resolve_against_that_file(tmp_path):
    """snakemake --configfile my.yaml from the repository (config/config.yaml loaded first):
    instrument and mask are found beside my.yaml; the resolved config the rules see is absolute."""
    from straylight.config import resolve_config_files

    p = _campaign_in_another_folder(tmp_path)
    r = snakemake("--configfile", str(p), "-n", "--quiet")
    assert r.returncode == 0, r.stdout + r.stderr
    import yaml

    base = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    merged = {**base, **yaml.safe_load(p.read_text())}
    cfg, sources, last = resolve_config_files(merged, [REPO / "config" / "config.yaml", p])
    assert last == p.resolve()
    assert cfg["instrument"] == str(p.parent.resolve() / "inst" / "csst.yaml")
    assert cfg["footprint"]["mask_file"] == str(p.parent.resolve() / "mask.fits")
    assert sources["campaign.end"] == p.resolve()


def test_configfile_error_names_that_file(tmp_path):
    p = _campaign_in_another_folder(tmp_path, end="2025-01-01T00:00:00")
    r = snakemake("--configfile", str(p), "-n", "--quiet")
    assert r.returncode != 0
    text = r.stdout + r.stderr
    assert f"{p.resolve()}: campaign.end = '2025-01-01T00:00:00' must be after" in text, text
    assert "config/config.yaml: campaign.end" not in text


def test_configfile_in_another_folder_runs(tmp_path):
    """One real tiny run from the repository's folder with my.yaml elsewhere: the footprint is
    the mask beside my.yaml (its first third of the pixels at nside 4)."""
    import healpy as hp

    p = _campaign_in_another_folder(tmp_path)
    r = snakemake(
        "-s",
        str(REPO / "workflow" / "Snakefile"),
        "-d",
        str(tmp_path),
        "--configfile",
        str(p),
        "--cores",
        "2",
        "results/tiny/footprint.fits",
    )
    assert r.returncode == 0, r.stdout + r.stderr
    m = hp.read_map(tmp_path / "results" / "tiny" / "footprint.fits")
    assert m.sum() == hp.nside2npix(4) // 3


def test_depth_bounds_present_ordered_and_finite(tiny_run):
    """limits.zarr's envelope medians (straylight.model.envelope): present with units and
    long_name, finite wherever a pixel is observable (NaN elsewhere), and ordered pessimistic <=
    median <= optimistic within the storage rounding (a brighter background gives a shallower
    limit; storage.py: 2^-11 relative of ~26 mag); background.zarr records which parts each
    envelope parameter scales; the spread map and sensitivity chart are in depth/."""
    import json

    out, _ = tiny_run
    lim = xr.open_zarr(out / "limits.zarr")
    med = lim["limiting_mag_median"].values
    pess, opt = lim["limiting_mag_median_pessimistic"].values, lim["limiting_mag_median_optimistic"].values
    for name in ("limiting_mag_median_pessimistic", "limiting_mag_median_optimistic"):
        assert lim[name].attrs["units"] == "mag(AB)" and lim[name].attrs["long_name"], name
    seen = lim["observable_fraction"].values > 0
    assert seen.any()
    for v in (pess, opt):
        assert np.all(np.isfinite(v[seen])) and np.all(np.isnan(v[~seen]))
    tol = 2.0**-11 * 30.0
    assert np.all(pess[seen] <= med[seen] + tol) and np.all(med[seen] <= opt[seen] + tol)
    assert np.nanmax(opt - pess) > 0.01  # the envelope has a width
    env = json.loads(xr.open_zarr(out / "background.zarr").attrs["envelope"])
    assert env["calibrated_members"]["scales"] == ["sun", "moon", "earthshine_direct", "earthshine_door"]
    assert (out / "depth" / "envelope_spread.png").exists()
    assert (out / "depth" / "envelope_sensitivity.csv").exists()
