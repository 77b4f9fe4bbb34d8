"""The benchmark's error-checked adaptive time sampling (bench/knobs/sampling.py): what it
computes and what it fills in, on series whose answer is known in closed form."""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
from knobs.sampling import adaptive_in_time  # noqa: E402


def _series(values):
    """(T,) values as a one-band, one-pointing series, observable, door open at 135 deg."""
    full = np.asarray(values, float)[:, None, None]
    return full, np.ones(full.shape[::2], bool), np.full(full.shape[::2], 135.0)


def test_a_straight_line_is_filled_after_one_check_per_interval():
    # a line passes every check: knots every 8 of 33 samples (0, 8, 16, 24, 32) and one
    # midpoint per interval are computed, 9 of 33, and the rest is exact to rounding
    full, obs, door = _series(1.0 + 0.01 * np.arange(33))
    computed, out = adaptive_in_time(full, obs, door, 8, 0.0025)
    assert np.flatnonzero(computed[:, 0]).tolist() == [0, 4, 8, 12, 16, 20, 24, 28, 32]
    np.testing.assert_allclose(out, full, rtol=1e-14)


def test_a_door_change_is_bracketed_down_to_single_steps():
    # the door narrows at sample 11 (inside 8..16): 8..12 is split down to single steps around
    # the change (9, 10, 11 computed), 12..16 lies in one state and is checked once (14)
    full, obs, door = _series(np.ones(33))
    door[11:, 0] = 105.0
    computed, out = adaptive_in_time(full, obs, door, 8, 0.0025)
    assert np.flatnonzero(computed[:, 0]).tolist() == [0, 4, 8, 9, 10, 11, 12, 14, 16, 20, 24, 28, 32]
    np.testing.assert_array_equal(out, full)


def test_a_curve_is_refined_until_the_midpoint_check_holds():
    # y = 1 + t^2 / 2000: the line between a and b misses the midpoint by (b - a)^2 / 8000, so
    # intervals of 8 fail the check (0.008 > 0.0025 y for t <= 32) and intervals of 4 pass it
    # (0.002): every second sample is computed, and the others are off by 1/2000 / y at most
    t = np.arange(33)
    full, obs, door = _series(1.0 + t**2 / 2000.0)
    computed, out = adaptive_in_time(full, obs, door, 8, 0.0025)
    assert np.flatnonzero(computed[:, 0]).tolist() == list(range(0, 33, 2))
    rel = np.abs(out - full) / full
    assert 0.0004 < rel.max() <= 0.0005


def test_a_spike_between_the_checks_is_missed():
    # the method's failure mode: a feature narrower than the check spacing, here one sample
    # (a star crossing the field's edge, say) between an interval's ends and its midpoint
    full, obs, door = _series(np.ones(33))
    full[2, 0, 0] = 2.0
    computed, out = adaptive_in_time(full, obs, door, 8, 0.0025)
    assert not computed[2, 0]
    assert out[2, 0, 0] == 1.0  # the spike is interpolated away: a 50 % error


def test_goal_check_reads_the_production_figures_and_flags_each_goal():
    """bench/run.py's goal_check: the whole campaign's rate is the production figure, each goal
    (the goal: 1e6 samples/s/core, 1 % error, 10x the direct path) flagged on its own, and a
    figure the run did not measure is None, not a pass."""
    from knobs.goal import goal_check

    summary = {
        "cube": {
            "lut": {"samples_per_s_per_core": 8.0e5},
            "production_region": {
                "lut": {"samples_per_s_per_core": 1.08e6},
                "time_block": {"lut": {"samples_per_s_per_core": 1.02e6}},
                "campaign": {"lut": {"samples_per_s_per_core": 0.99e6}},
            },
            "speedup_lut_over_direct": 9.5,
            "lut_vs_direct_max_rel_error_observable": 1.1e-3,
        },
        "earthshine_table": {"max_rel_error": 0.012},
    }
    check = goal_check(summary)
    assert check["samples_per_s_per_core"] == {
        "production_campaign": 0.99e6,
        "production_time_block": 1.02e6,
        "production_region": 1.08e6,
        "day_spread_batch": 8.0e5,
    }
    assert check["met"] == {
        "rate_production_campaign": False,
        "rate_production_time_block": True,
        "rate_day_spread_batch": False,
        "error": False,
        "speedup": False,
    }
    partial = goal_check({"cube": {"lut": {"samples_per_s_per_core": 1.2e6}}})
    assert partial["met"] == {
        "rate_production_campaign": None,
        "rate_production_time_block": None,
        "rate_day_spread_batch": True,
        "error": None,
        "speedup": None,
    }


def test_pipeline_bench_writes_its_figures(tmp_path):
    """bench/pipeline.py end to end on a tiny campaign (2 hours at 10 minutes, nside 4, two
    cores, no kernel figure): the results file holds the wall-to-wall rate, each rule's time,
    peak memory and bytes per sample, consistent with each other (no timed assertion).  Its
    earthshine summed directly (``--base``): the envelope's members' tables would cost minutes
    to build for these 12 steps."""
    import json
    import subprocess

    import yaml

    repo = Path(__file__).resolve().parents[2]
    cfg = yaml.safe_load((repo / "config" / "config.yaml").read_text())
    cfg["models"]["earthshine"]["method"] = "direct"
    cfg["instrument"] = str(repo / "config" / cfg["instrument"])
    base = tmp_path / "base.yaml"
    base.write_text(yaml.safe_dump(cfg))
    out = tmp_path / "pipeline.json"
    bench = repo / "bench" / "pipeline.py"
    r = subprocess.run(
        [
            sys.executable,
            str(bench),
            "--days",
            str(2 / 24),
            "--nside",
            "4",
            "--cadence-s",
            "600",
            "--cores",
            "2",
            "--no-kernel",
            "--base",
            str(base),
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    rec = json.loads(out.read_text())
    c = rec["campaign"]
    assert (c["times"], c["nside"], c["bands"]) == (12, 4, 7)
    assert c["samples"] == 12 * c["pixels"] and 0 < c["pixels"] < 192  # nside 4: 192 pixels on the sky
    assert rec["samples_per_s_per_core"] == c["samples"] / rec["wall_seconds"] / rec["cores"]
    assert rec["cpu_seconds"] > 0 and rec["samples_per_cpu_second"] == c["samples"] / rec["cpu_seconds"]
    assert {"background_blocks", "background_init", "background", "limits", "sky_maps", "time_series"} <= set(
        rec["rules"]
    )
    for name, rule in rec["rules"].items():
        assert rule["jobs"] >= 1 and 0.0 <= rule["seconds"] <= rec["wall_seconds"] + 1.0, name
        assert rule["share_of_wall"] == rule["seconds"] / rec["wall_seconds"]
    assert rec["peak_memory_bytes"] > 50 * 2**20  # at least one Python process with numpy loaded
    assert all(rec["products_bytes"][p] > 0 for p in ("background.zarr", "limits.zarr", "observability.zarr"))
    assert rec["bytes_per_sample"] == sum(rec["products_bytes"].values()) / c["samples"]
    assert rec["kernel"] is None and rec["table_build_seconds_before_run"] >= 0.0
    assert "samples/s/core" in r.stdout


def test_the_bench_knobs_reach_the_model(campaign):
    """bench/knobs/common.Bench.model's Earth grid and door settings are the ones the model
    computes with (its SourceContext's off-field transfer), so a coarser grid gives another
    earthshine: the sweeps and the converged reference in bench/run.py depend on it."""
    from _samples import random_samples
    from knobs.common import Bench

    bench = object.__new__(Bench)  # the knobs only: no catalog
    bench.campaign, bench.bands = campaign, ["g"]
    sc, los, g = random_samples(campaign, 400, seed=5)
    obs = np.flatnonzero(g["observable"])[:20]
    bench.sat, bench.los = sc.satellite_km[obs], los[obs]
    bench.bodies = {k: v[obs] for k, v in sc.bodies_km.items()}
    bench.geometry = {k: v[obs] for k, v in g.items()}
    coarse = bench.model(n_gamma=8, n_psi=16, door_blocks=(4, 4), n_aperture_door=16)
    fine = bench.model(n_gamma=48, n_psi=96)
    s = coarse.earth_grid.earthshine
    assert (s.n_gamma, s.n_psi, tuple(s.door_blocks), s.n_aperture_door) == (8, 16, (4, 4), 16)
    es = [bench.evaluate(m, None)["g"]["earthshine_direct"] for m in (coarse, fine)]
    assert np.any(es[1] > 0)
    assert np.max(np.abs(es[0] - es[1]) / np.maximum(es[1], 1e-30)) > 1e-3
