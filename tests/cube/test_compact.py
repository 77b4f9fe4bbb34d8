"""The compact sky product (sky_compact.zarr) of a small campaign run by the workflow, against the
cube it is made from (background.zarr's total in AB mag/arcsec2), and its reader SkyMaps.

The bounds are the product's requirement (issue #55): over the observable samples, per band, an
rms error of at most 0.02 mag and a 99.9th percentile of at most 0.1 mag; the observability is
exact."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from conftest import REPO

SNAKEMAKE = str(Path(sys.executable).with_name("snakemake"))
BIN = Path(sys.executable).parent
RMS_BOUND_MAG = 0.02
P999_BOUND_MAG = 0.1


@pytest.fixture(scope="module")
def compact_run(tmp_path_factory):
    """Six hours at 5 minutes, nside 8 (72 times x the footprint's pixels), the direct Earth sum
    (no tables to build); only the compact product and what it needs."""
    from conftest import tiny_config

    tmp = tmp_path_factory.mktemp("compact")
    cfg = tiny_config(
        tmp,
        name="compact",
        campaign={"end": "2026-01-01T06:00:00", "cadence_s": 300, "time_block_hours": 3},
        footprint={"nside": 8, "pixel_block_size": 200},
    )
    import yaml

    conf = yaml.safe_load(cfg.read_text())
    conf["models"]["earthshine"]["method"] = "direct"
    cfg.write_text(yaml.safe_dump(conf))
    run = tmp / "results" / "compact"
    r = subprocess.run(
        [SNAKEMAKE, "-s", str(REPO / "workflow" / "Snakefile"), "-d", str(tmp), "--configfile", str(cfg)]
        + ["--cores", "2", "results/compact/sky_compact.zarr"],
        capture_output=True,
        text=True,
        timeout=900,
        env={**os.environ, "PATH": f"{BIN}:{os.environ['PATH']}"},
    )
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    bg = xr.open_zarr(run / "background.zarr")
    cube = (bg["mag_zero_point"] - 2.5 * np.log10(bg["total"].astype(np.float64))).transpose(
        "time", "pixel", "band"
    )
    return run, cube.values, bg["observable"].values, bg


def test_compact_holds_the_bounds_and_the_exact_observability(compact_run):
    """Decoded through xarray's CF decoding (scale_factor, add_offset, _FillValue): NaN exactly
    where the cube is not observable, and per band rms <= 0.02 mag and p99.9 <= 0.1 mag over the
    observable samples; the attributes' errors equal the ones measured here (to the histogram's
    1e-4 mag for the percentiles)."""
    run, cube, observable, _ = compact_run
    ds = xr.open_zarr(run / "sky_compact.zarr")
    mag = ds["mag"].values  # decoded: AB mag/arcsec2, NaN where not observable
    assert ds["mag"].attrs["units"] == "mag(AB)/arcsec2" and ds["mag"].attrs["long_name"]
    assert observable.mean() > 0.05 and observable.sum() > 1000  # enough samples to test
    np.testing.assert_array_equal(ds["observable"].values, observable)
    np.testing.assert_array_equal(np.isfinite(mag).all(axis=2), observable)
    assert np.isnan(mag[~observable]).all()
    err = mag[observable] - cube[observable]  # (samples, band)
    rms = np.sqrt(np.mean(err**2, axis=0))
    p999 = np.percentile(np.abs(err), 99.9, axis=0)
    step = ds.attrs["mag_step"]
    assert (rms <= RMS_BOUND_MAG).all(), f"rms {rms} mag over the bound {RMS_BOUND_MAG}"
    assert (p999 <= P999_BOUND_MAG).all(), f"p99.9 {p999} mag over the bound {P999_BOUND_MAG}"
    # rounding to the step: within half a step (float32 arithmetic: 1e-5 mag) ...
    assert np.abs(err).max() <= step / 2 + 1e-5
    bands = list(ds.attrs["bands"])
    for i, b in enumerate(bands):
        assert ds.attrs["error_rms_mag"][b] == pytest.approx(rms[i], rel=1e-3, abs=1e-6)
        assert ds.attrs["error_max_mag"][b] == pytest.approx(np.abs(err[:, i]).max(), abs=2e-6)
        assert abs(ds.attrs["error_p999_mag"][b] - p999[i]) <= 2e-4
    # ... and an rms of step / sqrt(12) (uniform rounding error) to 10 %
    np.testing.assert_allclose(rms, step / np.sqrt(12), rtol=0.1)


def test_skymaps_values_and_maps_on_and_between_grid_times(compact_run):
    """SkyMaps: on grid times the stored magnitudes (within the step's half of the cube) and the
    cube's observability; halfway between two times the mean of the two, observable only where
    both are; a full-sky map equal to the batch at its pixels; bad input one InputError line."""
    import straylight

    run, cube, observable, bg = compact_run
    sky = straylight.open_campaign(run).compact
    assert isinstance(sky, straylight.SkyMaps)
    times = bg["time"].values
    pixels = bg["pixel"].values
    nt, npix = observable.shape
    rng = np.random.default_rng(5)
    it = rng.integers(0, nt, 2000)
    ip = rng.integers(0, npix, 2000)
    mag, obs = sky.values(times[it], pixels[ip])
    np.testing.assert_array_equal(obs, observable[it, ip])
    assert np.abs(mag[obs] - cube[it, ip][obs]).max() <= sky.mag_step / 2 + 1e-5
    assert np.isnan(mag[~obs]).all()
    # halfway between grid times it and it + 1
    it = np.minimum(it, nt - 2)
    half = times[it] + (times[1] - times[0]) / 2
    m_half, o_half = sky.values(half, pixels[ip], bands=["g", "i"])
    both = observable[it, ip] & observable[it + 1, ip]
    np.testing.assert_array_equal(o_half, both)
    g, i = list(bg["band"].values).index("g"), list(bg["band"].values).index("i")
    expect = 0.5 * (cube[it, ip][:, [g, i]] + cube[it + 1, ip][:, [g, i]])
    assert np.abs(m_half[both] - expect[both]).max() <= sky.mag_step / 2 + 1e-5
    # a full-sky map at one time: (bands, 12 nside^2), equal to values() at the footprint's pixels
    m_map, o_map = sky.map(half[0])
    assert m_map.shape == (7, 12 * 8**2) and o_map.shape == (12 * 8**2,)
    m_all, o_all = sky.values(np.repeat(half[0], npix), pixels)
    np.testing.assert_array_equal(o_map[pixels], o_all)
    np.testing.assert_array_equal(m_map[:, pixels].T, m_all)
    outside = np.setdiff1d(np.arange(12 * 8**2), pixels)
    assert np.isnan(m_map[:, outside]).all() and not o_map[outside].any()
    with pytest.raises(straylight.InputError, match="outside the product's grid"):
        sky.values(np.datetime64("2026-01-02T00:00"), pixels[:1])
    with pytest.raises(straylight.InputError, match="not in the product's footprint"):
        sky.values(times[:1], outside[:1])
    with pytest.raises(straylight.InputError, match="bands"):
        sky.map(times[0], bands=["V"])


def test_plan_prices_the_compact_product():
    """`straylight plan` on the default day (380,160 samples) prints the compact product's size:
    the samples x plan.COMPACT_BYTES_PER_SAMPLE, the figure measured by bench/compact.py."""
    from conftest import run_cli

    from straylight.planning.plan import COMPACT_BYTES_PER_SAMPLE

    r = run_cli("plan", "--cores", "2")
    assert r.returncode == 0, r.stderr
    expect = f"compact sky (sky_compact.zarr, besides): {380_160 * COMPACT_BYTES_PER_SAMPLE / 1e9:.3g} GB"
    assert expect in r.stdout, r.stdout
    assert 0.05 <= COMPACT_BYTES_PER_SAMPLE <= 0.5  # the product's budget (issue #55): <= 0.5


def test_skymaps_within_its_memory_budget_equals_the_whole_product(compact_run, tmp_path):
    """SkyMaps with a memory budget of two time chunks: a random batch over every chunk is
    answered a group of chunks at a time and equals the fully decoded product's answer exactly;
    afterwards at most two chunks stay decoded (the others' pages given back)."""
    import shutil

    import zarr

    import straylight

    run, cube, observable, bg = compact_run
    copy = tmp_path / "sky_compact.zarr"
    shutil.copytree(
        run / "sky_compact.zarr",
        copy,
        ignore=lambda d, names: ["mag"] if Path(d) == run / "sky_compact.zarr" else [],
    )
    mag = zarr.open_array(str(run / "sky_compact.zarr" / "mag"), mode="r")
    data, attrs, dims = mag[:], dict(mag.attrs), mag.metadata.dimension_names
    # the same codes in chunks of 6 time steps: 12 chunks over the 72 times
    zarr.create_array(
        store=str(copy),
        name="mag",
        data=data,
        chunks=(6, *data.shape[1:]),
        attributes=attrs,
        dimension_names=dims,
        fill_value=mag.fill_value,
    )
    zarr.consolidate_metadata(str(copy))  # the group's consolidated metadata names the new chunks
    whole = straylight.SkyMaps(copy).load()
    chunk_gb = 6 * whole.pixels.size * 8 * 2 / 1e9
    bounded = straylight.SkyMaps(copy, max_memory_gb=2.5 * chunk_gb)
    times, pixels = bg["time"].values, bg["pixel"].values
    rng = np.random.default_rng(11)
    t = times[0] + (rng.random(3000) * (times[-1] - times[0]).astype(np.int64)).astype("timedelta64[ns]")
    p = pixels[rng.integers(0, pixels.size, 3000)]
    m0, o0 = whole.values(t, p)
    m1, o1 = bounded.values(t, p)
    np.testing.assert_array_equal(o1, o0)
    np.testing.assert_array_equal(m1, m0)
    assert bounded._decoded.sum() <= 2 and len(bounded._recent) <= 2
    for k in range(0, 72, 7):  # maps chunk after chunk: the same, within the budget
        np.testing.assert_array_equal(bounded.map(times[k])[0], whole.map(times[k])[0])
        assert bounded._decoded.sum() <= 2
    with pytest.raises(straylight.InputError, match="max_memory_gb"):
        straylight.SkyMaps(copy, max_memory_gb=0)
