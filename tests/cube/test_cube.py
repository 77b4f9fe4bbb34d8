"""Survey cubes through the real Snakemake workflow: values, resume, Dask scheduler, limits.

Reference values: `straylight sky` at the same time and pixel, an uninterrupted run (resume, Dask)."""

import json
import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from conftest import REPO, run_cli

SNAKEMAKE = str(Path(sys.executable).with_name("snakemake"))
BIN = Path(sys.executable).parent


def _config(tmp, name="cube", **compute):
    from conftest import tiny_config

    return tiny_config(
        tmp,
        name=name,
        campaign={"end": "2026-01-01T01:00:00", "time_block_hours": 0.5},
        footprint={"pixel_block_size": 40},
        compute=compute or {"dask_scheduler": None},
    )


def _run(tmp, cfg, *extra):
    r = subprocess.run(
        [
            SNAKEMAKE,
            "-s",
            str(REPO / "workflow" / "Snakefile"),
            "-d",
            str(tmp),
            "--configfile",
            str(cfg),
            "--cores",
            "2",
            *extra,
        ],
        capture_output=True,
        text=True,
        timeout=900,
        env={**os.environ, "PATH": f"{BIN}:{os.environ['PATH']}"},
    )
    return r


@pytest.fixture(scope="module")
def cube_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("cube")
    cfg = _config(tmp)
    r = _run(tmp, cfg)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    return tmp, cfg, tmp / "results" / "cube"


def test_cube_layout_units_and_attrs(cube_run):
    _, _, out = cube_run
    ds = xr.open_zarr(out / "background.zarr")
    assert dict(ds.sizes) == {"time": 6, "pixel": 86, "band": 7}
    for v in ("zodiacal", "earthshine", "moon", "sun", "planets", "stars", "total"):
        assert ds[v].dims == ("time", "pixel", "band")
        assert ds[v].attrs["units"] == "electron / (s pixel)" and ds[v].attrs["long_name"]
        assert np.all(np.isfinite(ds[v].values)) and np.all(ds[v].values >= 0)
    assert ds.attrs["healpix_nside"] == 4 and ds.attrs["healpix_ordering"] == "RING"
    assert ds["total"].encoding["chunks"] == (3, 43, 7)  # 86 pixels: 2 equal blocks (pixel_block_length)
    parts = sum(
        ds[v].values.astype(float) for v in ("zodiacal", "earthshine", "moon", "sun", "planets", "stars")
    )
    # each stored within its bound of the computed value (straylight/storage/zarr_io.py), the total and the
    # (nonnegative) parts each: the sum of the stored parts within twice the bound of the total
    bound = ds["total"].attrs["max_relative_error"]
    assert 0 < bound <= 1e-3 and ds.attrs["float_max_relative_error"] == bound
    np.testing.assert_allclose(ds["total"].values, parts, rtol=2 * bound + 1e-5)
    # the faint stars' map, computed once at init: part of every time step's star term
    faint = ds["faint_star_map"]
    assert faint.dims == ("pixel", "band") and faint.attrs["units"] == "electron / (s pixel)"
    assert np.all(faint.values > 0)
    assert faint.attrs["max_relative_error"] == 0.0  # stored exactly: the time blocks read it
    assert np.all(ds["stars"].values >= faint.values[None].astype(np.float32) * (1 - bound - 1e-6))


def test_observability_from_the_cube_equals_its_own_geometry(cube_run, tmp_path):
    """The cube's workers write observability.zarr beside the background (their geometry is the
    observability's, sample by sample): identical, values and attributes, to the product computed
    on its own from the ephemeris (straylight.cube.products.observability_dataset) and stored
    through the same codecs; chunked as the cube."""
    from straylight.config import load_campaign
    from straylight.cube.products import footprint_products, observability_dataset
    from straylight.storage.zarr_io import write_zarr_atomic

    _, cfg, out = cube_run
    c = load_campaign(cfg)
    fp, _ = footprint_products(c)
    with xr.open_zarr(out / "ephemeris.zarr") as ephem:
        write_zarr_atomic(
            observability_dataset(c, ephem.load(), fp), tmp_path / "obs.zarr", storage=c.settings.storage
        )
    with xr.open_zarr(out / "observability.zarr") as got, xr.open_zarr(tmp_path / "obs.zarr") as want:
        assert got["sun_angle_deg"].encoding["chunks"] == (
            3,
            43,
        )  # 86 pixels: 2 equal blocks (pixel_block_length)
        xr.testing.assert_identical(got.load(), want.load())


def test_faint_star_map_shared_among_processes_is_bit_identical(cube_run, campaign):
    """background_init sums the faint-star map on its processes, each a share of the pixels;
    each pixel's sum runs over the stars on its own (stars_faint._faint_star_kernel), so the same bits
    as one process."""
    from straylight.cube.footprint import footprint_from_config
    from straylight.cube.region import faint_star_map

    _, _, out = cube_run
    fp = footprint_from_config(campaign.settings.footprint, campaign.path.parent)
    one = faint_star_map(campaign, fp, out / "stars_csst.parquet", workers=1)
    two = faint_star_map(campaign, fp, out / "stars_csst.parquet", workers=2)
    assert one.dims == two.dims == ("pixel", "band") and np.all(one.values > 0)
    np.testing.assert_array_equal(one.values, two.values)


def test_cube_value_equals_sky_command(cube_run):
    """A cube value equals `straylight sky --catalog` (the run's star catalog) for the same time and
    pointing (to the stored values' bound, straylight/storage/zarr_io.py); the star term is the same
    model (stars.offfield_mag_limit)."""
    _, cfg, out = cube_run
    from conftest import sky_at

    ds = xr.open_zarr(out / "background.zarr")
    assert ds.attrs["stars_included"] > 150 and ds.attrs["stars_offfield_mag_limit"] == 2.0
    assert ds.attrs["stars_in_faint_map"] > 100_000 and ds.attrs["stars_faint_map"] == 1
    it, ip = 4, 17
    rec = sky_at(ds, it, ip, cfg, catalog=out / "stars_csst.parquet")
    for ib, b in enumerate(ds["band"].values):
        for comp in ("zodiacal", "earthshine", "moon", "stars", "total"):
            assert float(ds[comp][it, ip, ib]) == pytest.approx(
                rec["bands"][b][comp]["e_per_s_per_pix"],
                rel=ds[comp].attrs["max_relative_error"] + 1e-6,
                abs=1e-30,
            )
    assert bool(ds["observable"][it, ip]) == rec["observable"]


def test_limits_and_maps(cube_run):
    import healpy as hp

    _, _, out = cube_run
    lim = xr.open_zarr(out / "limits.zarr")
    assert (
        lim["limiting_mag"].dims == ("time", "pixel", "band")
        and lim["limiting_mag"].attrs["units"] == "mag(AB)"
    )
    assert np.all(np.isfinite(lim["limiting_mag"].values))
    g = lim["limiting_mag"].sel(band="g").values
    assert 24.0 < np.median(g) < 28.0
    m = hp.read_map(out / "maps" / "limit_best_g.fits")
    assert hp.get_nside(m) == 4
    seen = m[m != hp.UNSEEN]
    assert seen.size > 0 and np.all((seen > 20) & (seen < 30))
    frac = hp.read_map(out / "maps" / "observable_fraction.fits")
    assert np.all((frac[frac != hp.UNSEEN] >= 0) & (frac[frac != hp.UNSEEN] <= 1))


def test_fused_limits_equal_limits_dataset_within_the_propagated_bound(cube_run, tmp_path):
    """The cube's workers compute limits.zarr's limiting_mag from the total they computed, before
    it is bit-rounded (straylight/storage/zarr_io.py); limits_dataset on the stored background
    differs from it by at most: the stored total's relative error e (its max_relative_error,
    2^-11 at 10 kept bits) propagated to the limit, 2.5 / ln 10 * e / 2 mag (the limit's signal
    grows at most as the square root of the background: 2.65e-4 mag), plus the stored limit's own
    rounding (its max_relative_error of the magnitude, 2^-17 at 16 bits: 2.0e-4 of a 26-mag
    limit) and float32's (< 4e-6 mag).  The per-pixel summaries are limits_dataset's of the stored
    limiting_mag, through the same codecs: identical, values and attributes."""
    from straylight.config import load_campaign
    from straylight.limits.cube import limits_dataset
    from straylight.storage.zarr_io import write_zarr_atomic

    _, cfg, out = cube_run
    c = load_campaign(cfg)
    with xr.open_zarr(out / "background.zarr") as bg, xr.open_zarr(out / "limits.zarr") as got:
        background = bg.drop_vars("faint_star_map").load()
        got = got.load()
    ref = limits_dataset(c, background)
    e_total = background["total"].attrs["max_relative_error"]
    e_mag = got["limiting_mag"].attrs["max_relative_error"]
    assert e_total == 2.0**-11 and e_mag == 2.0**-17
    diff = np.abs(got["limiting_mag"].values.astype(float) - ref["limiting_mag"].values)
    bound = 2.5 / np.log(10) * e_total / 2 + e_mag * np.abs(ref["limiting_mag"].values) + 4e-6
    assert np.all(np.isfinite(diff)) and np.all(diff <= bound), float((diff - bound).max())
    assert diff.max() > 0  # computed from different totals: not the same bits everywhere
    # the envelope's and the budget's per-sample limits as the workers stored them in the limits
    # work store (from the region's unrounded parts, like limiting_mag:
    # straylight/limits/envelope.py, budget.py); the
    # product keeps their medians only
    with xr.open_zarr(out / "work" / "background_blocks" / "limits.zarr", consolidated=False) as work:
        ends = {e: work[f"limiting_mag_{e}"].load() for e in ("pessimistic", "optimistic")}
        budget = {k: work[f"limiting_mag_{k}"].load() for k in ("p16", "p84")}
    write_zarr_atomic(
        limits_dataset(
            c, background, limiting_mag=got["limiting_mag"], envelope_limits=ends, budget_limits=budget
        ),
        tmp_path / "ref.zarr",
        storage=c.settings.storage,
    )
    with xr.open_zarr(tmp_path / "ref.zarr") as want, xr.open_zarr(out / "limits.zarr") as stored:
        xr.testing.assert_identical(stored.load(), want.load())
        # chunked as the cube (time block x pixel block); the summaries as limits_dataset chunks them
        assert stored["limiting_mag"].encoding["chunks"] == (3, 43, 7)
        assert stored["observable"].encoding["chunks"] == (3, 43)
        assert stored["limiting_mag_best"].encoding["chunks"] == (86, 7)
        assert stored["observable_fraction"].encoding["chunks"] == (43,)


def test_limit_summaries_on_processes_equal_the_published_ones(cube_run, monkeypatch):
    """store_limit_summaries split among spawned processes (one more per
    SUMMARY_BYTES_PER_PROCESS, here lowered so the tiny store takes two) and in one process
    gives the published summaries' bits (limits.zarr decoded: the summaries are stored
    bit-rounded, so compared after the same rounding)."""
    from numcodecs import BitRound

    from straylight.limits import cube as lm

    _, _, out = cube_run
    work = out / "work" / "background_blocks" / "limits.zarr"
    one = lm.store_limit_summaries(work, workers=1)
    monkeypatch.setattr(lm, "SUMMARY_BYTES_PER_PROCESS", 1024)
    two = lm.store_limit_summaries(work, workers=2)
    with xr.open_zarr(out / "limits.zarr") as published:
        for name in lm.SUMMARY_VARIABLES:
            np.testing.assert_array_equal(two[name], one[name], err_msg=name)
            keepbits = int(published[name].attrs["compression"].split("keepbits=")[1].split(")")[0])
            rounded = BitRound(keepbits=keepbits).decode(BitRound(keepbits=keepbits).encode(one[name]))
            np.testing.assert_array_equal(
                np.asarray(rounded).reshape(one[name].shape), published[name].values, err_msg=name
            )


def test_provenance_records_checksums(cube_run):
    _, _, out = cube_run
    prov = json.loads((out / "provenance.json").read_text())
    assert prov["config"]["campaign"]["name"] == "cube"
    for k in (
        "background.zarr",
        "limits.zarr",
        "maps",
        "ephemeris.zarr",
        "footprint.fits",
        "sky_compact.zarr",
    ):
        assert len(prov["outputs_sha256"][k]) == 64
    assert len(prov["outputs_digest_sha256"]) == 64
    assert "numpy" in prov["versions"] and "config" in prov["inputs_sha256"]
    # the code (this checkout's commit), the run's command line and cores, portable paths
    head = subprocess.run(
        ["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True
    ).stdout.strip()
    assert prov["source"]["from"] == "checkout" and isinstance(prov["source"]["dirty"], bool)
    import straylight

    assert prov["source"]["commit"] == head and prov["source"]["version"] == straylight.__version__
    assert prov["run"]["cores"] == 2 and prov["run"]["started_by"] is None
    assert prov["run"]["command"] == [
        "snakemake",
        "-s",
        "straylight:workflow/Snakefile",
        "-d",
        "../..",
        "--configfile",
        "../../cube.yaml",
        "--cores",
        "2",
    ]
    assert prov["config_file"] == "../../cube.yaml"
    assert prov["config"]["instrument"] == "straylight:config/instruments/csst.yaml"
    text = (out / "provenance.json").read_text()
    assert str(out.parents[1]) not in text and str(REPO) not in text and '"/' not in text


def test_rerun_recomputes_only_what_is_missing(cube_run):
    tmp, cfg, out = cube_run
    r = _run(tmp, cfg, "-n")
    assert "Nothing to be done" in r.stdout + r.stderr
    before = out / "background.zarr"
    from straylight.cube.provenance import sha256_path

    digest = sha256_path(before)
    limits_work = out / "work" / "background_blocks" / "limits.zarr"
    limits_digests = (sha256_path(limits_work), sha256_path(out / "limits.zarr"))
    # as after a crash inside time block 1: its sentinel, the cube job's record and everything
    # downstream are missing
    blocks = out / "work" / "background_blocks"
    (blocks / "block_1.json").unlink()
    for p in ("work/background_summary.json", "provenance.json", "work/background_blocks/part_0.json"):
        (out / p).unlink()
    for d in ("limits.zarr", "maps"):
        shutil.rmtree(out / d)
    finished = {p.name: p.stat().st_mtime_ns for p in blocks.glob("block_*.json")}
    assert finished  # block 0 (of the two half-hour blocks) stays done
    r = _run(tmp, cfg, "-n")
    text = r.stdout + r.stderr
    assert "background_blocks" in text and "background_init" not in text
    import re

    counts = {m.group(1): int(m.group(2)) for m in re.finditer(r"^(\w+)\s+(\d+)$", text, re.M)}
    assert counts.get("background_blocks") == 1
    r = _run(tmp, cfg, "results/cube/provenance.json")
    assert r.returncode == 0
    # only the block that was not finished is recomputed: the others' sentinels are untouched
    assert {p: (blocks / p).stat().st_mtime_ns for p in finished} == finished
    assert (blocks / "block_1.json").exists()
    log = (out / "work" / "logs" / "background_blocks_0.log").read_text()
    assert f"{len(finished)} of {len(finished) + 1} time blocks already done" in log
    assert sha256_path(out / "background.zarr") == digest  # recomputed block is bit-identical
    # and so are its limits (written before the block's sentinel) and the published limits.zarr
    assert (sha256_path(limits_work), sha256_path(out / "limits.zarr")) == limits_digests


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_dask_scheduler_address_gives_the_same_products(tmp_path, cube_run):
    """A real `dask scheduler` and `dask worker` on loopback, started here; same cube bytes."""
    port = _free_port()
    addr = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, "PATH": f"{BIN}:{os.environ['PATH']}"}
    sched = subprocess.Popen(
        [
            str(BIN / "dask"),
            "scheduler",
            "--host",
            "127.0.0.1",
            "--port",
            str(port),
            "--dashboard-address",
            ":0",
            "--no-show",
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=env,
    )
    worker = None
    try:
        deadline = time.time() + 60
        while time.time() < deadline:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                time.sleep(0.5)
        worker = subprocess.Popen(
            [str(BIN / "dask"), "worker", addr, "--nworkers", "2", "--nthreads", "1", "--no-dashboard"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env=env,
        )
        cfg = _config(tmp_path, name="cube", dask_scheduler=addr)
        r = _run(tmp_path, cfg, "results/cube/work/background_summary.json")  # the cube only (relative to -d)
        assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    finally:
        for p in (worker, sched):
            if p is not None:
                p.terminate()
                p.wait(timeout=30)
    from straylight.cube.provenance import sha256_path

    _, _, ref = cube_run
    assert sha256_path(tmp_path / "results" / "cube" / "background.zarr") == sha256_path(
        ref / "background.zarr"
    )


def _campaign_with(campaign, over: dict):
    """``campaign`` with the config keys of ``over`` replaced (config.deep_merge), validated again."""
    from straylight.config import campaign_from_dict, deep_merge

    return campaign_from_dict(deep_merge(campaign.config_mapping(), over), campaign.path)


#: three weeks of the default campaign (8.0 million samples)
WEEKS = {"campaign": {"end": "2026-01-22T00:00:00"}}
N_DAYS = 21


def test_evaluated_samples_skipping_counts_the_observable_ones(campaign):
    """The samples the cube evaluates (plan prices them): with unobservable_samples: skip, the
    observable ones, estimated from 144 times x 660 pixels; on
    the default day (288 times x 1320 pixels, 16.5 % observable) against the exact count from
    the geometry of every sample, and every sample without skipping."""
    from straylight.cube.footprint import footprint_from_config
    from straylight.planning.plan import evaluated_samples
    from straylight.sky.geometry import observing_geometry
    from straylight.sky.observing import scene
    from straylight.sky.vectors import radec_to_unit

    fp = footprint_from_config(campaign.settings.footprint)
    n = len(campaign.times) * fp.pixels.size
    assert evaluated_samples(campaign, fp) == n == 380_160
    skipping = _campaign_with(campaign, {"models": {"unobservable_samples": "skip"}})
    sc = scene(skipping.orbit, skipping.times)
    los = radec_to_unit(fp.ra_deg, fp.dec_deg)
    g = observing_geometry(
        sc.satellite_km[:, None],
        {b: sc.bodies_km[b][:, None] for b in ("sun", "moon")},
        los[None],
        campaign.earth.radius_km,
        campaign.constraints,
    )
    exact = int(g["observable"].sum())
    assert 0.12 * n < exact < 0.2 * n
    estimate = evaluated_samples(skipping, fp)
    assert abs(estimate - exact) < 0.005 * n  # measured: 0.09 % of the samples
    # no bigger than the subsample: the count is exact
    assert evaluated_samples(skipping, fp, max_times=len(campaign.times), max_pixels=fp.pixels.size) == exact


def test_plan_prints_samples_size_and_cost(tmp_path):
    """plan on an empty table cache: the samples, the earthshine path it assumes and that its
    tables must be built (once), the wall time on the cores given, the products' size."""
    import os

    env_cache = os.environ["STRAYLIGHT_CACHE"]
    # the session's compiled kernels (plan's speed probe runs them), not its tables
    kernels = Path(env_cache) / "numba"
    kernels.mkdir(exist_ok=True)
    (tmp_path / "numba").symlink_to(kernels, target_is_directory=True)
    try:
        os.environ["STRAYLIGHT_CACHE"] = str(tmp_path)  # inherited by the subprocess: no table cached
        r = run_cli("plan", "--cores", "2")
    finally:
        os.environ["STRAYLIGHT_CACHE"] = env_cache
    assert r.returncode == 0, r.stderr
    assert "samples (time, pointing): 380,160; evaluated: 380,160" in r.stdout
    assert (
        "earthshine: look-up tables (models.earthshine.method = auto); its tables are not cached yet"
        in r.stdout
    )
    assert "estimated wall time on 2 cores: " in r.stdout and "the tables' build" in r.stdout
    assert "core-hours" in r.stdout and "GB" in r.stdout


def test_pipeline_rate_from_config_else_the_packaged_figure(campaign):
    """plan.pipeline_rate: compute.pipeline_samples_per_s_per_core when set, else the figure the
    package ships (no file outside it is read); estimated_cost's wall time is the fixed part plus
    samples / (rate x cores), the table's build spread over the cores, and it sizes the products
    at PRODUCT_BYTES_PER_SAMPLE."""
    from straylight.cube.footprint import footprint_from_config
    from straylight.planning import plan

    assert plan.pipeline_rate(campaign) == (
        plan.PIPELINE_SAMPLES_PER_S_PER_CORE,
        "straylight.planning.plan.PIPELINE_SAMPLES_PER_S_PER_CORE",
    )
    configured = _campaign_with(campaign, {"compute": {"pipeline_samples_per_s_per_core": 2.5e5}})
    assert plan.pipeline_rate(configured) == (2.5e5, "compute.pipeline_samples_per_s_per_core")
    month = _campaign_with(
        campaign,
        {"campaign": {"end": "2026-01-31T00:00:00"}, "compute": {"pipeline_samples_per_s_per_core": 2.5e5}},
    )
    fp = footprint_from_config(month.settings.footprint)
    for cores in (1, 2, 8):
        cost = plan.estimated_cost(month, fp, cores=cores)
        assert cost["earthshine_method"] == "lut"
        assert cost["wall_seconds"] == pytest.approx(
            plan.PIPELINE_FIXED_SECONDS
            + cost["samples"] / (2.5e5 * cores)
            + cost["table_build_seconds"] / cores,
            rel=1e-12,
        )
        assert cost["pipeline_core_hours"] == pytest.approx(cost["wall_seconds"] * cores / 3600, rel=1e-12)
    assert cost["product_bytes"] == cost["samples"] * plan.PRODUCT_BYTES_PER_SAMPLE


def test_cycle_config_is_valid_and_planned_from_the_pipeline_figure():
    """config/cycle.yaml (half a year at nside 64, 5-minute cadence) passes the schema, and
    `straylight plan` costs it wall to wall at the pipeline's figure: 182.5 days x 288 steps x
    its footprint's pixels."""
    from straylight.config import load_campaign

    c = load_campaign(REPO / "config" / "cycle.yaml")
    assert len(c.times) == 52_560 and c.settings.footprint.nside == 64
    r = run_cli("plan", REPO / "config" / "cycle.yaml", timeout=300)
    assert r.returncode == 0, r.stderr
    assert "estimated wall time on " in r.stdout and "samples/s/core" in r.stdout
    assert "products on disk: " in r.stdout


def test_plan_calibrate_scales_the_figures_by_this_machines_speed():
    """plan --calibrate times a few cube steps on this machine and prints the factor it scales
    the cost figures by; it and --seconds-per-sample exclude each other."""
    r = run_cli("plan", "--calibrate")
    assert r.returncode == 0, r.stderr
    line = next(x for x in r.stdout.splitlines() if x.startswith("this machine: "))
    factor = float(line.rsplit("(x", 1)[1].split(")")[0])
    assert 0.0 < factor < 100.0
    assert "every figure above is scaled by it" in r.stdout
    assert run_cli("plan", "--calibrate", "--seconds-per-sample", "1e-5").returncode == 2


def test_machine_speed_and_its_factor(campaign, tmp_path, monkeypatch):
    """plan.machine_speed: the measured seconds of a small direct-path cube against the
    figures' seconds for it (cube_compute_seconds, the direct sum evaluating every sample);
    estimated_cost scales the compute, the table's build and the wall time by the factor."""
    from straylight.cube.footprint import footprint_from_config
    from straylight.planning import plan

    fp = footprint_from_config(campaign.settings.footprint)
    speed = plan.machine_speed(campaign, fp, n_times=1, n_pixels=66, repeats=1)
    assert speed["samples"] == 66  # every 20th of the 1320 pixels at the first step
    assert speed["assumed_seconds"] == pytest.approx(
        plan.cube_compute_seconds(66, 66, "direct", False), rel=1e-12
    )
    assert speed["measured_seconds"] > 0.0
    assert speed["factor"] == pytest.approx(speed["measured_seconds"] / speed["assumed_seconds"], rel=1e-12)
    monkeypatch.setenv("STRAYLIGHT_CACHE", str(tmp_path))  # an empty cache: the build is counted
    week = _campaign_with(campaign, WEEKS)
    base, fast = plan.estimated_cost(week, fp), plan.estimated_cost(week, fp, speed_factor=0.25)
    assert fast["compute_seconds"] == pytest.approx(0.25 * base["compute_seconds"], rel=1e-12)
    assert base["table_build_seconds"] > 0.0
    assert fast["table_build_seconds"] == pytest.approx(0.25 * base["table_build_seconds"], rel=1e-12)
    assert fast["wall_seconds"] == pytest.approx(0.25 * base["wall_seconds"], rel=1e-12)
    assert (fast["earthshine_method"], fast["evaluated_samples"]) == (
        base["earthshine_method"],
        base["evaluated_samples"],
    )


def test_plan_costs_the_model_that_runs(campaign, tmp_path, monkeypatch):
    """straylight plan (plan.estimated_cost) costs the earthshine model the cube will run,
    without building anything: auto takes the tables for the default day as for three weeks;
    their build (1,840,841 nodes x 2 door states at LUT_BUILD_SECONDS_PER_NODE, the default
    table's node count, and the moonlit table's 534,375 x 2 at MOONLIT_LUT_BUILD_SECONDS_PER_NODE)
    is counted while it is not cached, each table on its own, for the nominal model and each of
    the assumption envelope's two members (the same grids, so the same node counts); method:
    direct prices the direct sum's extra per evaluated sample instead."""
    from straylight import model as comp
    from straylight.cube.footprint import footprint_from_config
    from straylight.planning import plan

    monkeypatch.setenv("STRAYLIGHT_CACHE", str(tmp_path))  # an empty cache: the table is not built
    fp = footprint_from_config(campaign.settings.footprint)
    day = plan.estimated_cost(campaign, fp)
    assert (day["samples"], day["evaluated_samples"], day["earthshine_method"]) == (380_160, 380_160, "lut")
    sunlit_s = 1_840_841 * 2 * comp.LUT_BUILD_SECONDS_PER_NODE
    moonlit_s = (
        534_375 * 2 * comp.MOONLIT_LUT_BUILD_SECONDS_PER_NODE
    )  # (Moon zenith, zenith, azimuth, roll) nodes
    sets = 3  # the nominal model's tables and each envelope member's (config envelope.members)
    assert day["table_build_seconds"] == pytest.approx(sets * (sunlit_s + moonlit_s), rel=1e-12)
    assert day["compute_seconds"] == pytest.approx(380_160 * plan.CUBE_TABLE_SECONDS_PER_SAMPLE, rel=1e-12)

    def week(unobservable, method="auto"):
        return plan.estimated_cost(
            _campaign_with(
                campaign,
                {**WEEKS, "models": {"unobservable_samples": unobservable, "earthshine": {"method": method}}},
            ),
            fp,
        )

    evaluating = week("evaluate")
    assert (evaluating["samples"], evaluating["earthshine_method"]) == (N_DAYS * 380_160, "lut")
    assert not evaluating["table_cached"]
    assert evaluating["table_build_seconds"] == pytest.approx(sets * (sunlit_s + moonlit_s), rel=1e-12)
    assert evaluating["core_hours"] * 3600 == pytest.approx(
        N_DAYS * 380_160 * plan.CUBE_TABLE_SECONDS_PER_SAMPLE + evaluating["table_build_seconds"], rel=1e-12
    )
    # each table counted only while it is not cached: with the sunlit one in the cache, the moonlit
    week_model = comp.BackgroundModel(
        _campaign_with(campaign, {**WEEKS, "models": {"unobservable_samples": "evaluate"}})
    )
    week_model.source("sunlit_earth").lut_path().write_bytes(b"")  # only its existence is checked
    one_left = week("evaluate")
    assert not one_left["table_cached"]
    assert one_left["table_build_seconds"] == pytest.approx(
        moonlit_s + (sets - 1) * (sunlit_s + moonlit_s), rel=1e-12
    )
    week_model.source("moonlit_earth").lut_path().write_bytes(b"")
    for t in week("evaluate")["tables"]:  # the members' too
        t["path"].write_bytes(b"")
    assert week("evaluate")["table_cached"] and week("evaluate")["table_build_seconds"] == 0.0
    direct = week("skip", method="direct")
    assert 0.12 < direct["evaluated_samples"] / direct["samples"] < 0.2  # the default day: 16.5 %
    assert direct["earthshine_method"] == "direct" and direct["table_build_seconds"] == 0.0
    assert direct["compute_seconds"] == pytest.approx(
        N_DAYS * 380_160 * plan.CUBE_SCREEN_SECONDS_PER_SAMPLE
        + direct["evaluated_samples"]
        * (plan.CUBE_TABLE_SECONDS_PER_OBSERVABLE_SAMPLE + comp.LUT_SAVED_SECONDS_PER_SAMPLE),
        rel=1e-12,
    )
    assert direct["samples_seconds"] == pytest.approx(
        (
            direct["samples"] / plan.PIPELINE_SAMPLES_PER_S_PER_CORE
            + direct["evaluated_samples"] * comp.LUT_SAVED_SECONDS_PER_SAMPLE
        )
        / 2,
        rel=1e-12,
    )


def test_kill_9_at_random_moments_then_resume_is_bit_identical(tmp_path, cube_run):
    """SIGKILL the whole run (Snakemake and its Dask workers) at random moments until it has been
    killed six times, resuming after each kill; whenever a run gets to finish, its products must be
    complete and bit-identical to an uninterrupted run (then they are wiped and the campaign starts
    over, so the kills keep landing in real work)."""
    import signal

    from straylight.cube.provenance import sha256_path

    cfg = _config(tmp_path, name="cube")
    env = {**os.environ, "PATH": f"{BIN}:{os.environ['PATH']}"}
    base = [
        SNAKEMAKE,
        "-s",
        str(REPO / "workflow" / "Snakefile"),
        "-d",
        str(tmp_path),
        "--configfile",
        str(cfg),
    ]
    # the products compared below (the sky maps, time series and scheduling tables are left out to save time)
    # the target after a fixed-arity option: --configfile and -q would swallow it
    cmd = base + ["--cores", "2", "results/cube/provenance.json", "--rerun-incomplete", "-q"]
    _, _, ref = cube_run
    out = tmp_path / "results" / "cube"
    products = (
        "background.zarr",
        "limits.zarr",
        "maps",
        "ephemeris.zarr",
        "footprint.fits",
        "provenance.json",
    )
    reference = {p: sha256_path(ref / p) for p in products[:-1]}

    def check_complete():
        for product in products[:-1]:
            assert sha256_path(out / product) == reference[product], product
        prov = json.loads((out / "provenance.json").read_text())
        ref_prov = json.loads((ref / "provenance.json").read_text())
        assert prov["outputs_sha256"] == ref_prov["outputs_sha256"]
        assert prov["outputs_digest_sha256"] == ref_prov["outputs_digest_sha256"]
        assert not list(out.glob(".*.*"))  # no temporaries left behind

    def unlock():
        # what `snakemake --unlock` does (Persistence.unlock: the killed run's lock files deleted),
        # without starting Snakemake for it
        shutil.rmtree(tmp_path / ".snakemake" / "locks", ignore_errors=True)

    rng = np.random.default_rng(9)
    n_kills = 6  # the moments spread over the run's start-up, its jobs and the cube's time blocks
    kills, finished = 0, 0
    for _ in range(40):
        if kills >= n_kills:
            break
        unlock()
        proc = subprocess.Popen(
            cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env, start_new_session=True
        )
        try:
            code = proc.wait(timeout=float(rng.uniform(2.0, 14.0)))
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            kills += 1
            continue
        assert code == 0
        check_complete()
        finished += 1
        shutil.rmtree(out)
    unlock()
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=900)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert kills >= n_kills
    check_complete()


def test_html_report_holds_maps_series_tables_and_provenance(cube_run):
    """`snakemake --report` after a run: one self-contained HTML file with the figures."""
    tmp, cfg, out = cube_run
    plots = sorted(p.name for d in ("sky", "series") for p in (out / d).glob("*.png"))
    # the test config chooses one time (00:30), one band (g) and one pointing (near RA 150, Dec 30)
    assert [p for p in plots if p.startswith("sky_")] == ["sky_g_20260101T0030.png"]
    series = [p for p in plots if p.startswith("series_")]
    assert len(series) == 2 and all("_ra1" in p for p in series)
    # the limit maps' figures and the depth table (rule limits)
    assert {"limits_best.png", "limits_median.png", "depth_summary.csv"} <= {
        p.name for p in (out / "depth").iterdir()
    }
    assert (out / "scheduling" / "moon_avoidance.png").exists()
    report = tmp / "report.html"
    r = _run(tmp, cfg, "--report", str(report))
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    text = report.read_text(errors="replace")
    assert report.stat().st_size > 100_000
    for needle in (
        "1. Depth: table and maps",
        "2. Sky background maps",
        "4. Scheduling tables",
        "5. Provenance",
        "sky_g_",
        "moon_avoidance",
    ):
        assert needle in text, needle
    # the first page: the depth table (from summary.rst, rule report_front) and thumbnails of the
    # limit maps, a sky page and a series; the CSVs attached
    assert (out / "summary.rst").exists()
    for needle in (
        "median depth (AB mag)",
        "observable fraction",
        "limits_median</b>",
        "sky_g_20260101T0030</b>",
        "series_orbit_ra1",
        "moon_avoidance.csv",
        "per band, the median and best 5-sigma depth",
    ):
        assert needle in text, needle


def test_cube_jobs_footprint_is_the_configs_bit_for_bit(cube_run):
    """The cube job and its workers take the footprint from the skeleton's coordinates
    (footprint_from_store) and background_init from the footprint rule's mask: the pixels and
    centres footprint_from_config computes from the latitude cuts, bit for bit (the cube's
    values depend on them)."""
    from straylight.config import load_campaign
    from straylight.cube.footprint import footprint_from_config, footprint_from_store

    _, cfg, out = cube_run
    c = load_campaign(cfg)
    ref = footprint_from_config(c.settings.footprint, c.path.parent)
    for fp in (
        footprint_from_store(out / "background.zarr"),
        footprint_from_config({**c.config_mapping()["footprint"], "mask_file": str(out / "footprint.fits")}),
    ):
        assert (fp.nside, fp.ordering) == (ref.nside, ref.ordering)
        for name in ("pixels", "ra_deg", "dec_deg"):
            a, b = getattr(fp, name), getattr(ref, name)
            assert a.dtype == b.dtype and np.array_equal(a, b), name
