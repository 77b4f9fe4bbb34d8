"""The benchmark suite in one command:  python bench/run.py [--samples N] [--quick]

For every approximation knob, the error of the whole background (all components, all seven
bands) against a converged reference, against its cost, at random observable (time, pointing)
samples of the default campaign; one Pareto chart per knob; and the default and reference
settings side by side.  Writes bench/results/summary.json, bench/results/knobs.json and
bench/results/pareto_<knob>.png.

Error: max over samples and bands of |B - B_ref| / B_ref,total (the same "fraction of the total
background" as the tolerance in the config).  Cost: seconds per sample on one core
(OMP_NUM_THREADS=1), best of three after a warm-up (the cube's table path: of seven, FAST_REPEATS).

Knobs: earthshine Earth-cap grid (n_gamma x n_psi); door and aperture discretisation of the
door path; star split (direct magnitude limit, smoothed faint-star map on/off); star skip (the
tolerance that sizes the direct stars' skip per sky cell); PST grid step
(interpolation of the default matrix); the moonlit Earth's grid on the table path (in the cube,
on a full-Moon day); time cadence with linear interpolation in time, plain and
error-checked adaptive; HEALPix nside (a pixel's
value standing for every direction inside it).

This module is the driver; what each part measures is in bench/knobs/ (one module per knob
family, the cube's speed, the goal check).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import write_results  # noqa: E402
from knobs.common import (
    DEFAULT,
    DEFAULT_STARS,
    REFERENCE,
    REFERENCE_STARS,
    RESULTS,
    Bench,  # noqa: E402
    max_rel_error,
    pareto_chart,
    timed,
)
from knobs.cube import cube_summary  # noqa: E402
from knobs.earthshine import (
    door_rows,
    earth_grid_rows,
    earthshine_lut_rows,
    moonlit_grid_rows,  # noqa: E402
    table_summary,
)
from knobs.goal import GOAL_MAX_REL_ERROR, GOAL_SAMPLES_PER_S_PER_CORE, goal_check, print_goal_check  # noqa: E402
from knobs.pst import pst_grid_rows  # noqa: E402
from knobs.sampling import nside_rows, time_cadence_rows  # noqa: E402
from knobs.stars import star_skip_rows, star_split_rows  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=150, help="random observable samples (default 150)")
    ap.add_argument("--quick", action="store_true", help="fewer settings (a smoke run)")
    ap.add_argument(
        "--only",
        choices=("time_cadence", "healpix_nside", "moonlit_grid", "cube"),
        default=None,
        help="re-run one model-independent sweep and update knobs.json and its chart "
        "(cube: the cube section of summary.json)",
    )
    args = ap.parse_args(argv)
    if args.only == "cube":
        import json

        bench = Bench(args.samples)
        path = RESULTS / "summary.json"
        summary = json.loads(path.read_text()) if path.exists() else {}
        summary["cube"] = cube_summary(bench.catalog)
        summary["goal_check"] = goal_check(summary)
        print_goal_check(summary["goal_check"])
        write_results("summary", summary)
        return
    if args.only:
        import json

        bench = Bench(args.samples)
        rows = {
            "time_cadence": time_cadence_rows,
            "healpix_nside": nside_rows,
            "moonlit_grid": moonlit_grid_rows,
        }[args.only](bench)
        path = RESULTS / "knobs.json"
        knobs = json.loads(path.read_text()) if path.exists() else {}
        knobs[args.only] = rows
        write_results("knobs", knobs)
        pareto_chart(
            args.only,
            rows,
            RESULTS / f"pareto_{args.only}.png",
            "cost relative to nside 16"
            if args.only == "healpix_nside"
            else "seconds per sample (one core, all bands)",
        )
        return
    t_start = time.perf_counter()
    bench = Bench(args.samples)
    print(f"{bench.n} observable samples, {len(bench.bands)} bands")
    ref_model = bench.model(**REFERENCE)
    ref_stars = bench.stars(*REFERENCE_STARS)
    ref, t_ref = timed(lambda: bench.evaluate(ref_model, ref_stars), repeats=1)
    # the reference itself against a still finer one, on a few samples: is it converged?
    finer = bench.model(
        n_gamma=192,
        n_psi=384,
        door_blocks=(64, 64),
        n_aperture_door=1024,
        pst_step=(0.05, 0.5),
        tolerance=1e-12,
    )
    few = slice(0, min(20, bench.n))
    res_finer = bench.evaluate(finer, ref_stars, few)
    ref_few = bench.evaluate(ref_model, ref_stars, few)
    ref_err = max_rel_error(ref_few, res_finer, bench.bands)
    def_model = bench.model(**DEFAULT)
    def_stars = bench.stars(*DEFAULT_STARS)
    res_def, t_def = timed(lambda: bench.evaluate(def_model, def_stars))
    def_err = max_rel_error(res_def, ref, bench.bands)
    from straylight.model import registry

    per_component = {
        c: max(float(np.max(np.abs(res_def[b][c] - ref[b][c]) / ref[b]["total"])) for b in bench.bands)
        for c in registry.component_names()
    }
    print(f"default:   {bench.n / t_def:9.0f} samples/s/core, max error {def_err:.2e} of the total")
    print(f"reference: {bench.n / t_ref:9.1f} samples/s/core, max error {ref_err:.2e} against a finer model")
    print("default error by component:", {k: f"{v:.1e}" for k, v in per_component.items()})

    knobs = {}
    print("knob sweeps (others at their default):")
    knobs["earth_grid"] = earth_grid_rows(bench, ref, def_stars, args.quick)
    knobs["earthshine_lut"] = earthshine_lut_rows(bench, ref, def_stars, args.quick)
    knobs["door_discretisation"] = door_rows(bench, ref, def_stars, args.quick)
    knobs["pst_grid"] = pst_grid_rows(bench, ref, def_stars, args.quick)
    knobs["star_split"] = star_split_rows(bench, ref, args.quick)
    knobs["star_skip"] = star_skip_rows(bench, ref, def_stars, args.quick)
    knobs["moonlit_grid"] = moonlit_grid_rows(bench)
    knobs["time_cadence"] = time_cadence_rows(bench)
    knobs["healpix_nside"] = nside_rows(bench)
    RESULTS.mkdir(parents=True, exist_ok=True)
    for name, rows in knobs.items():
        xlabel = (
            "cost relative to nside 16"
            if name == "healpix_nside"
            else "seconds per sample (one core, all bands)"
        )
        pareto_chart(name, rows, RESULTS / f"pareto_{name}.png", xlabel)
    summary = {
        "samples": bench.n,
        "bands": bench.bands,
        "background_samples_per_s_per_core": bench.n / t_def,
        "background_max_rel_error": def_err,
        "background_max_rel_error_by_component": per_component,
        "default_settings": {
            **DEFAULT,
            "stars_direct_mag_limit": DEFAULT_STARS[0],
            "stars_faint_map": DEFAULT_STARS[1],
        },
        "reference": {
            "background_samples_per_s_per_core": bench.n / t_ref,
            "background_max_rel_error": ref_err,
            "background_max_rel_error_against": "a finer model (Earth grid 192 x 384, door 64 x 64 blocks, "
            "1024 aperture points, PST 0.05 x 0.5 deg), 20 samples",
            "settings": {**REFERENCE, "stars_direct_mag_limit": REFERENCE_STARS[0], "stars_faint_map": False},
        },
        "speedup_default_over_reference": t_ref / t_def,
        "earthshine_table": table_summary(knobs["earthshine_lut"]),
        "cube": cube_summary(bench.catalog),
        "goal_samples_per_s_per_core": GOAL_SAMPLES_PER_S_PER_CORE,
        "goal_max_rel_error": GOAL_MAX_REL_ERROR,
        "bench_seconds": time.perf_counter() - t_start,
        "charts": sorted(str(p.name) for p in RESULTS.glob("pareto_*.png")),
    }
    summary["goal_check"] = goal_check(summary)
    print_goal_check(summary["goal_check"])
    write_results("knobs", knobs)
    write_results("summary", summary)
    print(
        f"default {summary['background_samples_per_s_per_core']:.0f} samples/s/core at max error "
        f"{def_err:.2e}; reference {summary['reference']['background_samples_per_s_per_core']:.1f}; "
        f"speed-up {summary['speedup_default_over_reference']:.0f}x; {summary['bench_seconds']:.0f} s"
    )


if __name__ == "__main__":
    main()
