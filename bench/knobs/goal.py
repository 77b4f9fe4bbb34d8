"""The speed and accuracy goal's figures against a run's summary."""

from __future__ import annotations

#: the goal's figures: samples/s/core (all bands), the largest error as a fraction of the
#: total background, and the speed-up over the direct path measured side by side
GOAL_SAMPLES_PER_S_PER_CORE, GOAL_MAX_REL_ERROR, GOAL_SPEEDUP_OVER_DIRECT = 1e6, 0.01, 10.0


def goal_check(summary: dict) -> dict:
    """The goal's figures against this run's (the default path: the cube on the table
    path, every sample evaluated, as production computes it): samples/s/core for all bands on
    the whole default campaign, time block by time block as its jobs compute it (the figure
    production runs at), its first time block, a single region and the day-spread batch; the
    default's error against the converged reference (the earthshine
    table's row of the random-sample sweep, the largest term's error; None in a ``--only
    cube`` run without an earlier full run) and the cube's table path against its direct
    path; the speed-up over the direct path, side by side in one run."""
    cube = summary.get("cube", {})
    region = cube.get("production_region", {})
    rates = {
        "production_campaign": region.get("campaign", {}).get("lut", {}).get("samples_per_s_per_core"),
        "production_time_block": region.get("time_block", {}).get("lut", {}).get("samples_per_s_per_core"),
        "production_region": region.get("lut", {}).get("samples_per_s_per_core"),
        "day_spread_batch": cube.get("lut", {}).get("samples_per_s_per_core"),
    }
    error = (summary.get("earthshine_table") or {}).get("max_rel_error")
    speedup = cube.get("speedup_lut_over_direct")
    goal_rate, goal_error, goal_speedup = (
        GOAL_SAMPLES_PER_S_PER_CORE,
        GOAL_MAX_REL_ERROR,
        GOAL_SPEEDUP_OVER_DIRECT,
    )
    return {
        "samples_per_s_per_core": rates,
        "goal_samples_per_s_per_core": goal_rate,
        "max_rel_error_vs_reference": error,
        "max_rel_error_table_vs_direct_observable": cube.get("lut_vs_direct_max_rel_error_observable"),
        "goal_max_rel_error": goal_error,
        "speedup_over_direct": speedup,
        "goal_speedup_over_direct": goal_speedup,
        "met": {
            **{
                f"rate_{k}": _met(rates[k], goal_rate)
                for k in ("production_campaign", "production_time_block", "day_spread_batch")
            },
            "error": _met(error, goal_error, at_most=True),
            "speedup": _met(speedup, goal_speedup),
        },
    }


def _met(value, goal, at_most: bool = False):
    """Whether a measured figure meets its goal (at least it; at most it for an error); None
    when the run did not measure it (not a pass)."""
    if value is None:
        return None
    return bool(value <= goal if at_most else value >= goal)


def print_goal_check(check: dict) -> None:
    r = check["samples_per_s_per_core"]
    fmt = lambda v: "-" if v is None else f"{v:,.0f}"  # noqa: E731
    err = check["max_rel_error_vs_reference"]
    err = "-" if err is None else f"{err:.2e}"
    print(
        f"goal: {fmt(r['production_campaign'])} samples/s/core on the whole default campaign "
        f"({fmt(r['production_time_block'])} its first time block, {fmt(r['production_region'])} one region, "
        f"{fmt(r['day_spread_batch'])} the day-spread batch) against "
        f"{check['goal_samples_per_s_per_core']:,.0f}; error {err} against "
        f"{check['goal_max_rel_error']:g}; {fmt(check['speedup_over_direct'])}x the direct path; "
        f"met: {check['met']}"
    )
