"""The survey cube's speed on its own access pattern (direct and table paths, every sample and
observable samples only), one production region, time block and the whole campaign, and the
cost figures ``straylight plan`` and ``models.earthshine.method = auto`` assume, against this run."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import FAST_REPEATS, cube_model, timed


def cube_summary(catalog, time_step: int = 24, n_times: int = 12) -> dict:
    """The survey cube's access pattern: every footprint pixel of the default campaign at
    ``n_times`` times spread over its day, as compute_region runs it (the direct path one time
    step per evaluation, the Earth cap gridded once per step; the table path whole steps as one
    batch, cube.region.SAMPLES_PER_EVALUATION), stars included.  Seconds per sample on one
    core (best of three for the direct earthshine sum, of :data:`FAST_REPEATS` for the look-up
    table, built once and cached), and the table path's largest difference from the direct path
    at observable samples, as a fraction of the total (the direct path's own error is the
    random-sample figure above).  Then the table path with models.unobservable_samples: skip,
    its rate counted over every sample (the unobservable ones are NaN), its observable values
    checked identical to the table path's."""
    import tempfile

    from straylight.catalog.campaign_catalog import write_catalog
    from straylight.config import load_campaign
    from straylight.cube.footprint import footprint_from_config
    from straylight.cube.region import compute_region, offfield_stars

    base = load_campaign()
    fp = footprint_from_config(base.config["footprint"])
    t_slice = slice(0, time_step * n_times, time_step)
    out = {
        "pixels": int(fp.pixels.size),
        "times": n_times,
        "time_step_s": time_step * float(base.config["campaign"]["cadence_s"]),
    }
    res, lut_model = {}, None
    with tempfile.TemporaryDirectory() as tmp:
        stars_path = Path(tmp) / "stars.parquet"
        write_catalog(catalog, stars_path, {})
        stars = offfield_stars(base, stars_path)
        for key, method, unobservable in (
            ("direct", "direct", "evaluate"),
            ("lut", "lut", "evaluate"),
            ("lut_observable_only", "lut", "skip"),
            ("direct_observable_only", "direct", "skip"),
        ):
            c, model = cube_model(
                base, earthshine={"method": method}, models={"unobservable_samples": unobservable}
            )
            lut_model = model if key == "lut" else lut_model
            # the best of several after a warm-up: single runs varied by up to 30 % (this machine's
            # speed wanders within seconds); the table path's runs are short, so seven of them
            res[key], dt = timed(
                lambda: compute_region(c, fp, t_slice, slice(None), model=model, stars=stars),
                repeats=3 if method == "direct" else FAST_REPEATS,
            )
            out[key] = {"samples_per_s_per_core": n_times * fp.pixels.size / dt}
            print(
                f"cube, earthshine {method}, unobservable samples {unobservable}: "
                f"{out[key]['samples_per_s_per_core']:.0f} samples/s/core"
            )
        out["production_region"] = production_region_rates(base, fp, stars_path)
    obs = res["direct"]["observable"].values
    skipped = res["lut_observable_only"]["total"].values
    out["lut_observable_only"]["identical_at_observable"] = bool(
        np.array_equal(skipped[obs], res["lut"]["total"].values[obs]) and np.all(np.isnan(skipped[~obs]))
    )
    direct_skipped = res["direct_observable_only"]["total"].values
    out["direct_observable_only"]["identical_at_observable"] = bool(
        np.array_equal(direct_skipped[obs], res["direct"]["total"].values[obs])
        and np.all(np.isnan(direct_skipped[~obs]))
    )
    out["lut_observable_only"]["speedup_over_lut"] = (
        out["lut_observable_only"]["samples_per_s_per_core"] / out["lut"]["samples_per_s_per_core"]
    )
    diff = np.abs(res["lut"]["total"].values - res["direct"]["total"].values) / res["direct"]["total"].values
    out["lut_vs_direct_max_rel_error_observable"] = float(diff[obs].max()) if obs.any() else None
    out["lut_vs_direct_max_rel_error_all"] = float(diff.max())
    out["observable_samples"] = int(obs.sum())
    out["speedup_lut_over_direct"] = (
        out["lut"]["samples_per_s_per_core"] / out["direct"]["samples_per_s_per_core"]
    )
    out["auto_cost_model"] = auto_cost_model(lut_model, out)
    out["plan_cost_model"] = plan_cost_model(base, fp, t_slice, out)
    print(
        "cube: table path differs from the direct path by <= "
        f"{out['lut_vs_direct_max_rel_error_observable']:.2e} of the total at "
        f"{out['observable_samples']} observable samples "
        f"({out['lut_vs_direct_max_rel_error_all']:.2e} at all)"
    )
    return out


def production_region_rates(base, fp, stars_path) -> dict:
    """The table path (every sample, and observable samples only) on what one task of a
    production run computes (cube.run.run_time_blocks): one time block of consecutive steps
    (campaign.time_block_hours, 72 at the default 5-minute cadence) x one pixel block
    (footprint.pixel_block_size, 660 by default), the day's first, with the star catalog at
    ``stars_path``; samples per second on one core, the best of :data:`FAST_REPEATS` after a
    warm-up.  The
    per-region costs (the faint-star map's tile) are then shared by 72 steps instead of the 12
    spread over the day in :func:`cube_summary`.  Also the whole time block as its job computes
    it, writes aside: the bodies' positions once (sky.scene), then every pixel block; and every
    time block of the campaign so, each the best of its own repeats: the whole default campaign's
    samples over the sum of its blocks' times (``campaign``; the first block alone could be a
    cheaper scene than the others)."""
    from straylight.cube.layout import cube_chunks
    from straylight.cube.region import compute_region, offfield_stars
    from straylight.sky.observing import scene

    stars = offfield_stars(base, stars_path)
    n_times = len(base.times)
    ch = cube_chunks(base, n_times, int(fp.pixels.size))
    t_slice, p_slice = slice(0, ch["time"]), slice(0, ch["pixel"])
    p_blocks = [slice(a, b) for a, b in fp.blocks(ch["pixel"])]
    t_blocks = [slice(t, min(t + ch["time"], n_times)) for t in range(0, n_times, ch["time"])]
    n, n_block = ch["time"] * ch["pixel"], ch["time"] * int(fp.pixels.size)
    out = {
        "times": int(ch["time"]),
        "pixels": int(ch["pixel"]),
        "time_block": {"pixel_blocks": len(p_blocks)},
        "campaign": {"time_blocks": len(t_blocks), "samples": n_times * int(fp.pixels.size)},
    }
    for key, unobservable in (("lut", "evaluate"), ("lut_observable_only", "skip")):
        c, model = cube_model(
            base, earthshine={"method": "lut"}, models={"unobservable_samples": unobservable}
        )
        _, dt = timed(
            lambda: compute_region(c, fp, t_slice, p_slice, model=model, stars=stars), repeats=FAST_REPEATS
        )
        out[key] = {"samples_per_s_per_core": n / dt}
        print(
            f"cube, one production region ({out['times']} steps x {out['pixels']} pixels), "
            f"unobservable samples {unobservable}: {n / dt:.0f} samples/s/core"
        )

        def time_block(ts=t_slice):
            sc = scene(c.orbit, c.times[ts])
            for ps in p_blocks:
                compute_region(c, fp, ts, ps, model=model, stars=stars, scene=sc)

        _, dt = timed(time_block, repeats=FAST_REPEATS)
        out["time_block"][key] = {"samples_per_s_per_core": n_block / dt}
        print(
            f"cube, one production time block ({out['times']} steps x {fp.pixels.size} pixels in "
            f"{len(p_blocks)} blocks, the scene once), unobservable samples {unobservable}: "
            f"{n_block / dt:.0f} samples/s/core"
        )
        block_s = [timed(lambda ts=ts: time_block(ts), repeats=FAST_REPEATS)[1] for ts in t_blocks]
        samples = [(ts.stop - ts.start) * int(fp.pixels.size) for ts in t_blocks]
        out["campaign"][key] = {
            "samples_per_s_per_core": sum(samples) / sum(block_s),
            "per_time_block": [k / s for k, s in zip(samples, block_s)],
        }
        print(
            f"cube, the whole campaign ({len(t_blocks)} time blocks, {sum(samples)} samples), "
            f"unobservable samples {unobservable}: {sum(samples) / sum(block_s):.0f} samples/s/core (blocks: "
            + ", ".join(f"{k / s:.0f}" for k, s in zip(samples, block_s))
            + ")"
        )
    return out


def plan_cost_model(base, fp, t_slice, cube: dict) -> dict:
    """``straylight plan``'s figures (straylight.planning.plan.CUBE_*) against this run: the table path
    per sample; the skip mode's screen per sample (the Sun's and the Moon's geometry of every
    sample, timed here through plan.evaluated_samples on the same steps and pixels) and per
    observable sample (the rest of the skip run); then each of the four runs' seconds as the
    plan's formula gives them from the assumed figures, against the measured ones."""
    from astropy.time import TimeDelta

    from straylight.config import campaign_from_dict, deep_merge
    from straylight.planning import plan

    steps = range(*t_slice.indices(len(base.times)))
    over = {
        "models": {"unobservable_samples": "skip"},
        "campaign": {
            "start": base.times[steps[0]].isot,
            "end": (base.times[steps[-1]] + TimeDelta(1, format="sec")).isot,
            "cadence_s": steps.step * float(base.settings.campaign.cadence_s),
        },
    }
    sub = campaign_from_dict(
        deep_merge(base.config_mapping(), over), base.path
    )  # the same steps as a campaign of their own
    assert len(sub.times) == len(steps)
    _, screen = timed(
        lambda: plan.evaluated_samples(sub, fp, max_times=len(sub.times), max_pixels=fp.pixels.size)
    )
    n = len(steps) * fp.pixels.size
    n_obs = cube["observable_samples"]
    measured = {
        "table_seconds_per_sample": 1.0 / cube["lut"]["samples_per_s_per_core"],
        "screen_seconds_per_sample": screen / n,
    }
    measured["table_seconds_per_observable_sample"] = (
        n / cube["lut_observable_only"]["samples_per_s_per_core"] - n * measured["screen_seconds_per_sample"]
    ) / n_obs
    assumed = {
        "table_seconds_per_sample": plan.CUBE_TABLE_SECONDS_PER_SAMPLE,
        "screen_seconds_per_sample": plan.CUBE_SCREEN_SECONDS_PER_SAMPLE,
        "table_seconds_per_observable_sample": plan.CUBE_TABLE_SECONDS_PER_OBSERVABLE_SAMPLE,
    }
    predicted = {
        "lut": plan.cube_compute_seconds(n, n, "lut", False),
        "direct": plan.cube_compute_seconds(n, n, "direct", False),
        "lut_observable_only": plan.cube_compute_seconds(n, n_obs, "lut", True),
        "direct_observable_only": plan.cube_compute_seconds(n, n_obs, "direct", True),
    }
    runs = {
        k: {"predicted_seconds": v, "measured_seconds": n / cube[k]["samples_per_s_per_core"]}
        for k, v in predicted.items()
    }
    for k, v in measured.items():
        print(f"plan: {k} {v * 1e6:.2f} us (assumed {assumed[k] * 1e6:.2f})")
    for k, v in runs.items():
        print(
            f"plan: {k:22s} predicted {v['predicted_seconds']:.2f} s, measured {v['measured_seconds']:.2f} s"
        )
    return {"measured": measured, "assumed": assumed, "runs": runs}


def auto_cost_model(lut_model, cube: dict) -> dict:
    """``straylight plan``'s two earthshine constants against this run: the seconds a cube sample
    saves on the table path (measured just now; fidelity.LUT_SAVED_SECONDS_PER_SAMPLE) and the
    table's build seconds per node and door state (as recorded when the cached table was built,
    on whatever cores it had; earthshine.nodes.LUT_BUILD_SECONDS_PER_NODE), and after how many
    samples a build is repaid.  A measured figure far from the assumed one means the constants
    want updating."""
    from straylight.model import fidelity as comp

    es = lut_model.source("sunlit_earth").model
    saved = 1.0 / cube["direct"]["samples_per_s_per_core"] - 1.0 / cube["lut"]["samples_per_s_per_core"]
    build = es["lut_build_seconds"] / es["lut_node_states"]
    out = {
        "saved_seconds_per_sample": {"measured": saved, "assumed": comp.LUT_SAVED_SECONDS_PER_SAMPLE},
        "build_seconds_per_node": {"recorded": build, "assumed": comp.LUT_BUILD_SECONDS_PER_NODE},
        "pays_off_above_samples": {
            "measured": es["lut_build_seconds"] / saved,
            "assumed": comp.LUT_BUILD_SECONDS_PER_NODE
            * es["lut_node_states"]
            / comp.LUT_SAVED_SECONDS_PER_SAMPLE,
        },
    }
    print(
        f"auto: the table saves {saved * 1e3:.3f} ms per cube sample (assumed "
        f"{comp.LUT_SAVED_SECONDS_PER_SAMPLE * 1e3:.3f}), was built at {build * 1e3:.3f} ms per node and "
        f"state (assumed {comp.LUT_BUILD_SECONDS_PER_NODE * 1e3:.3f}): a build is repaid after "
        f"{out['pays_off_above_samples']['measured']:.3g} samples "
        f"(assumed {out['pays_off_above_samples']['assumed']:.3g})"
    )
    return out
