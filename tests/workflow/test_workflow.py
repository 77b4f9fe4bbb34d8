"""The Snakemake spine: dry run, lint, schema validation and a small end-to-end run.

Reference values: `straylight sky` at the products' samples."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from conftest import REPO

SNAKEMAKE = str(Path(sys.executable).with_name("snakemake"))


def snakemake(*args, cwd=REPO, timeout=600, env=None):
    return subprocess.run(
        [SNAKEMAKE, *args], cwd=cwd, capture_output=True, text=True, timeout=timeout, env=env
    )


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
    # zarr-python's warning for a data type outside the Zarr v3 specification (its
    # UnstableSpecificationWarning, a FutureWarning whose message starts so) is an error in every
    # process of the run: a product written with one fails the run
    env = {**os.environ, "PYTHONWARNINGS": "error:The data type:FutureWarning"}
    r = snakemake(
        "-s",
        str(REPO / "workflow" / "Snakefile"),
        "-d",
        str(tmp),
        "--configfile",
        str(p),
        "--cores",
        "2",
        env=env,
    )
    assert r.returncode == 0, r.stdout + r.stderr
    assert "UnstableSpecificationWarning" not in r.stdout + r.stderr
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


#: Zarr v3's core data types (the specification's "Data types") and `string`, the variable-length
#: UTF-8 type of the zarr-extensions registry that the products' labels use
V3_CORE_TYPES = {
    "bool",
    *(f"{k}{n}" for k in ("int", "uint") for n in (8, 16, 32, 64)),
    "float16",
    "float32",
    "float64",
    "complex64",
    "complex128",
}


def test_products_open_in_a_second_zarr_implementation(tiny_run):
    """Every array of every Zarr product has a data type of the v3 specification (or `string`),
    and tensorstore (Google's independent C++ Zarr v3 implementation) reads each numeric array
    to the same values as zarr-python; tensorstore 0.1 has no `string` type, so those (the
    band, body and xyz labels) are read here from their metadata and chunks by the zarr-extensions
    specification of `string` and `vlen-utf8` (:func:`_string_array_by_the_spec`) and compared."""
    import json

    import zarr

    ts = pytest.importorskip("tensorstore")
    out, _ = tiny_run
    stores = sorted(p for p in out.rglob("*.zarr") if (p / "zarr.json").exists())
    names = {p.relative_to(out).as_posix() for p in stores}
    assert {"ephemeris.zarr", "observability.zarr", "background.zarr", "limits.zarr"} <= names, names
    n_numeric = n_string = 0
    for store in stores:
        group = zarr.open_group(store, mode="r")
        for name, arr in group.arrays():
            meta = json.loads((store / name / "zarr.json").read_text())
            dtype = meta["data_type"]
            where = f"{store.relative_to(out)}/{name}"
            assert isinstance(dtype, str) and (dtype in V3_CORE_TYPES or dtype == "string"), (where, dtype)
            if dtype == "string":
                theirs = _string_array_by_the_spec(store / name, meta)
                np.testing.assert_array_equal(theirs, np.array([str(v) for v in arr[...]]), err_msg=where)
                n_string += 1
                continue
            other = ts.open(
                {"driver": "zarr3", "kvstore": {"driver": "file", "path": str(store / name)}}, read=True
            ).result()
            mine = arr[...]
            theirs = other.read().result()
            assert theirs.shape == mine.shape and theirs.dtype == mine.dtype, where
            np.testing.assert_array_equal(theirs, mine, err_msg=where)
            n_numeric += 1
    assert n_numeric >= 20  # the cube's components, limits, angles, positions and coordinates
    assert n_string >= 4  # the bands of background and limits, the ephemeris' bodies and axes


def _string_array_by_the_spec(path, meta) -> np.ndarray:
    """A 1-d `string` array read without zarr-python: its chunks at the default chunk keys
    (``c/<i>``), their bytes-to-bytes codecs undone (zstd, gzip), then `vlen-utf8`
    (zarr-extensions: a little-endian uint32 item count, then per item a uint32 length and its
    UTF-8 bytes); a missing chunk is the fill value."""
    import gzip
    import struct

    from numcodecs import Zstd

    assert meta["chunk_key_encoding"]["name"] == "default" and len(meta["shape"]) == 1
    sep = meta["chunk_key_encoding"].get("configuration", {}).get("separator", "/")
    (n,), (size,) = meta["shape"], meta["chunk_grid"]["configuration"]["chunk_shape"]
    codecs = [c["name"] for c in meta["codecs"]]
    assert codecs[0] == "vlen-utf8", codecs
    out = []
    for i in range(-(-n // size)):
        chunk = path / f"c{sep}{i}"
        if not chunk.exists():
            out += [meta["fill_value"]] * min(size, n - i * size)
            continue
        raw = chunk.read_bytes()
        for name in reversed(codecs[1:]):
            raw = {"zstd": lambda b: bytes(Zstd().decode(b)), "gzip": gzip.decompress}[name](raw)
        (count,), at = struct.unpack_from("<I", raw, 0), 4
        for _ in range(count):
            (length,) = struct.unpack_from("<I", raw, at)
            out.append(raw[at + 4 : at + 4 + length].decode("utf-8"))
            at += 4 + length
    return np.array(out[:n], dtype=str)


def test_cube_value_equals_sky_command(tiny_run):
    """An observability value equals `straylight sky` for the same time and pointing (to the
    stored values' bound, straylight/storage/zarr_io.py)."""
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
    limit; storage/zarr_io.py: 2^-11 relative of ~26 mag); background.zarr records which parts each
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
    # every input of the depth budget has its rows, the members' too (re-evaluated by the chart)
    rows = (out / "depth" / "envelope_sensitivity.csv").read_text().splitlines()
    keys = {tuple(r.split(",")[:2]) for r in rows}
    for key in ("calibrated_members", "earth_albedo", "zero_point", "read_noise_e", "all", "budget"):
        assert any(k == key for k, _ in keys), (key, rows[:3])
    assert ("calibrated_members", "pessimistic") in keys and ("calibrated_members", "optimistic") in keys


@pytest.mark.slow
def test_orbit_series_model_equals_the_cube_at_its_samples(tiny_run):
    """The time series' first orbit is the model every minute (plots.series.model_series): at the
    cube's own sample times (every 10 min) it gives the cube's values, every component in every
    band, to models.tolerance (1 % of the total: the cube's fast paths against the pointwise
    path) plus the stored values' 2^-11; and the same observability.  The module's campaign (its
    earthshine summed directly: no table to build)."""
    from straylight.config import load_campaign
    from straylight.model import registry
    from straylight.plots.series import model_series, pointing_series, series_pixel_indices

    out, cfg = tiny_run
    campaign = load_campaign(cfg)
    assert campaign.settings.models.earthshine.method == "direct"
    store = out / "background.zarr"
    with xr.open_zarr(store, chunks=None, consolidated=False) as ds:
        pixels = series_pixel_indices(ds, 1, [[150.0, 30.0]])
        minutes = (ds["time"].values - ds["time"].values[0]) / np.timedelta64(1, "m")
        (model,) = model_series(campaign, ds, pixels, minutes, out / "stars_csst.parquet")
    (cube,) = pointing_series(store, pixels)
    assert minutes.tolist() == [10.0 * i for i in range(12)]
    np.testing.assert_array_equal(model["observable"], cube["observable"])
    tol = float(campaign.settings.models.tolerance) + 2.0**-11
    for name in registry.component_names(total=True):
        error = np.abs(model[name] - cube[name])
        assert np.all(error <= tol * cube["total"] + 2.0**-11 * np.abs(cube[name])), name


def test_a_campaign_in_2200_parses_and_runs_without_erfas_dubious_year_warnings(tmp_path):
    """2200 is inside DE405 and beyond ERFA's leap-second table: Snakemake's parse and the
    ephemeris job print none of ERFA's "dubious year" warnings (before: some here; 152 for a whole
    campaign), and a warning of another kind would still show."""
    import yaml
    from conftest import tiny_config

    p = tiny_config(
        tmp_path, name="y2200", campaign={"start": "2200-06-01T00:00:00", "end": "2200-06-01T01:00:00"}
    )
    cfg = yaml.safe_load(p.read_text())
    cfg["orbit"]["circular"]["epoch"] = "2200-06-01T00:00:00"
    p.write_text(yaml.safe_dump(cfg))
    r = snakemake(
        "-s", str(REPO / "workflow" / "Snakefile"), "-d", str(tmp_path), "--configfile", str(p),
        "--cores", "1", "results/y2200/ephemeris.zarr",
    )  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    assert "dubious year" not in r.stdout + r.stderr
