"""Knobs of the sunlit and moonlit Earth: the Earth-cap grid summed directly, the look-up table's
node steps, the door path's discretisation, and the moonlit Earth's grid or table in the cube."""

from __future__ import annotations

import numpy as np

from .common import DEFAULT, cube_model, sweep, timed


def earth_grid_rows(bench, ref, stars, quick: bool):
    """The Earth-cap grid (n_gamma x n_psi) of the direct sum."""
    g = (
        [(16, 32), (24, 48), (32, 64), (48, 96)]
        if quick
        else [(8, 16), (12, 24), (16, 32), (24, 48), (32, 64), (48, 96), (96, 192)]
    )
    return sweep(
        bench, ref, "earth grid", [(f"{a} x {b}", {**DEFAULT, "n_gamma": a, "n_psi": b}, stars) for a, b in g]
    )


def earthshine_lut_rows(bench, ref, stars, quick: bool):
    """The direct sum, then the look-up table at node steps from coarse to the default (last)."""
    lut = (
        [(5.0, 5.0, 20.0), (0.5, 2.0, 2.5)]
        if quick
        else [(5.0, 5.0, 20.0), (2.5, 4.0, 10.0), (1.0, 2.0, 10.0), (0.5, 2.0, 5.0), (0.5, 2.0, 2.5)]
    )
    return sweep(
        bench,
        ref,
        "earthshine",
        [("direct 24 x 48", DEFAULT, stars)]
        + [(f"table {a:g}/{b:g}/{c:g} deg", {**DEFAULT, "lut_steps": (a, b, c)}, stars) for a, b, c in lut],
    )


def door_rows(bench, ref, stars, quick: bool):
    """The door path's blocks and aperture points."""
    d = (
        [(8, 32), (24, 128), (24, 256)]
        if quick
        else [(2, 8), (4, 16), (8, 32), (16, 64), (24, 128), (24, 256), (32, 512)]
    )
    return sweep(
        bench,
        ref,
        "door",
        [
            (f"{a}x{a} blocks, {b} ap.", {**DEFAULT, "door_blocks": (a, a), "n_aperture_door": b}, stars)
            for a, b in d
        ],
    )


def table_summary(rows):
    """The default earthshine table (the last, finest row) against the direct sum (first row):
    speed, error, build time and the campaign size above which the table pays off."""
    direct, table = rows[0], rows[-1]
    saved = direct["seconds_per_sample"] - table["seconds_per_sample"]
    return {
        "setting": table["setting"],
        "samples_per_s_per_core": 1.0 / table["seconds_per_sample"],
        "max_rel_error": table["max_rel_error"],
        "build_seconds": table.get("lut_build_seconds"),
        "validation_max_rel_error": table.get("lut_validation_max_rel_error"),
        "direct_samples_per_s_per_core": 1.0 / direct["seconds_per_sample"],
        "pays_off_above_samples": table.get("lut_build_seconds", 0.0) / saved if saved > 0 else None,
    }


def moonlit_grid_rows(bench, day: str = "2026-01-03", time_step: int = 24, n_times: int = 12):
    """The moonlit Earth on the table path: its grid (models.earthshine.moonlit_grid) summed
    directly, and its own table of that sum (moonlit_method lut, with moonlit_lut steps).  The
    cube's access pattern (every footprint pixel at ``n_times`` times of a full-Moon day, when
    the moonlit Earth is brightest), against a 48 x 96 grid summed directly with nothing
    skipped; error over observable samples, as a fraction of the total, of the product's
    treatment (skip on the bound plus the grid or table); seconds per sample of the whole cube
    (best of three; the table's build, once and cached, not included)."""
    from dataclasses import astuple

    from straylight.cube.footprint import footprint_from_config
    from straylight.cube.region import compute_region
    from straylight.sources.earthshine.nodes import MoonlitSettings

    base = bench.campaign
    fp = footprint_from_config(base.settings.footprint)
    t_slice = slice(0, time_step * n_times, time_step)

    def run(grid, method, steps=None, **kw):
        es = {"method": "lut", "moonlit_grid": list(grid), "moonlit_method": method}
        if steps:
            es["moonlit_lut"] = vars(MoonlitSettings(*steps))
        c, model = cube_model(base, {"start": f"{day}T00:00:00", "end": f"{day}T23:59:59"}, es, **kw)
        model.source("moonlit_earth").model  # built (or loaded) before timing
        return timed(lambda: compute_region(c, fp, t_slice, slice(None), model=model), repeats=1 if kw else 3)

    ref, _ = run((48, 96), "direct", moonlit_skip_share=0.0)
    total, obs = ref["total"].values.astype(float), ref["observable"].values
    rows = []
    cases = [(g, "direct", None) for g in ((3, 6), (4, 8), (6, 12), (8, 16), (12, 24), (24, 48))]
    cases += [
        ((4, 8), "lut", None),
        ((6, 12), "lut", (10, 6, 15, 30)),
        ((6, 12), "lut", None),
        ((8, 16), "lut", None),
    ]
    for grid, method, steps in cases:
        ds, dt = run(grid, method, steps)
        rel = np.abs(ds["total"].values - total) / total
        err = float(rel[obs].max())
        cost = dt / (n_times * fp.pixels.size)
        label = f"{grid[0]} x {grid[1]} " + (
            "direct"
            if method == "direct"
            else "table " + "/".join(f"{v:g}" for v in (steps or astuple(MoonlitSettings()))) + " deg"
        )
        rows.append(
            {
                "setting": label,
                "max_rel_error": err,
                "seconds_per_sample": cost,
                "samples_per_s_per_core": 1.0 / cost,
                "observable_samples": int(obs.sum()),
                "day": day,
            }
        )
        print(f"  {'moonlit':14s} {label:24s} error {err:9.2e}   {cost * 1e6:8.1f} us/sample (cube)")
    return rows
