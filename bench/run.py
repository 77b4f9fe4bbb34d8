"""The benchmark suite in one command (issue #7):  python bench/run.py [--samples N] [--quick]

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
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import write_results  # noqa: E402
from _samples import random_samples  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
COMPONENTS = ("zodiacal", "sun", "moon", "planets", "stars", "earthshine")


#: runs of each fast cube timing (tens of ms each), the best kept
FAST_REPEATS = 7
#: issue #7's goal figures: samples/s/core (all bands), the largest error as a fraction of the
#: total background, and the speed-up over the direct path measured side by side
GOAL_SAMPLES_PER_S_PER_CORE, GOAL_MAX_REL_ERROR, GOAL_SPEEDUP_OVER_DIRECT = 1e6, 0.01, 10.0


def timed(fn, repeats=3):
    fn()  # warm-up: tables, caches
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return out, best


def max_rel_error(res, ref, bands):
    return max(float(np.max(np.abs(res[b]["total"] - ref[b]["total"]) / ref[b]["total"])) for b in bands)


class Bench:
    def __init__(self, n_samples: int, seed: int = 5):
        from straylight.catalog.build import make_catalog
        from straylight.model import BackgroundModel
        from straylight.config import load_campaign

        self.campaign = load_campaign()
        self.bands = list(self.campaign.bands)
        base = BackgroundModel(self.campaign)
        self.catalog, _ = make_catalog({b: base.context.band(b).response for b in self.bands})
        sc, los, g = random_samples(self.campaign, 12 * n_samples, seed=seed)
        obs = np.flatnonzero(g["observable"])[:n_samples]
        self.sat, self.los = sc.satellite_km[obs], los[obs]
        self.bodies = {k: v[obs] for k, v in sc.bodies_km.items()}
        self.geometry = {k: v[obs] for k, v in g.items()}
        self.n = len(obs)

    def stars(self, limit: float, faint: bool):
        from straylight.sources.stars import split_stars

        return split_stars(self.catalog["ra"], self.catalog["dec"],
                           {b: self.catalog[f"mag_{b}"] for b in self.bands}, limit, faint)

    def model(self, n_gamma=24, n_psi=48, door_blocks=(24, 24), n_aperture_door=128, pst_step=(0.5, 5.0),
              lut_steps=None, tolerance=None):
        """A component model with these knobs; ``lut_steps`` (deg): the earthshine look-up table
        with these node steps instead of the direct sum (built on first use, cached);
        ``tolerance``: models.tolerance (with the direct sum it sizes only the bright stars'
        skipping on their bound; 1e-12 skips nothing)."""
        import copy

        from straylight.model import BackgroundModel
        from straylight.config import campaign_from_dict
        from straylight.optics.pst import PST, default_pst_grid

        raw = copy.deepcopy(self.campaign.config)
        if tolerance is not None:
            raw["models"]["tolerance"] = tolerance
        es = raw["models"]["earthshine"]
        if lut_steps is None:
            es["method"] = "direct"
        else:
            es["method"] = "lut"
            es["lut"] = dict(zip(("sun_zenith_step_deg", "los_zenith_step_deg", "azimuth_step_deg"), lut_steps))
        cm = BackgroundModel(campaign_from_dict(raw, self.campaign.path), expected_samples=10**6)
        off = cm.context.offfield
        es = replace(off.earthshine, n_gamma=n_gamma, n_psi=n_psi, door_blocks=tuple(door_blocks),
                     n_aperture_door=n_aperture_door)
        pst = off.pst if tuple(pst_step) == (0.5, 5.0) else PST(*default_pst_grid(*pst_step), source="bench")
        cm.__dict__["offfield"] = replace(off, earthshine=es, pst=pst)
        return cm

    def evaluate(self, cm, stars, sl=slice(None)):
        bodies = {k: v[sl] for k, v in self.bodies.items()}
        g = {k: v[sl] for k, v in self.geometry.items()}
        return cm.evaluate(self.sat[sl], bodies, self.los[sl], g, self.bands, stars)


DEFAULT = dict(n_gamma=24, n_psi=48, door_blocks=(24, 24), n_aperture_door=128, pst_step=(0.5, 5.0))
REFERENCE = dict(n_gamma=96, n_psi=192, door_blocks=(48, 48), n_aperture_door=512, pst_step=(0.1, 1.0),
                 tolerance=1e-12)
DEFAULT_STARS = (2.0, True)
REFERENCE_STARS = (99.0, False)  # every catalog star summed with the exact transfer


def sweep(bench, ref, name, settings):
    rows = []
    for label, kwargs, stars in settings:
        cm = bench.model(**kwargs)
        info = cm.sunlit_earth.model  # builds the look-up table if one is asked for (or loads it)
        res, dt = timed(lambda: bench.evaluate(cm, stars))
        err = max_rel_error(res, ref, bench.bands)
        row = {"setting": label, "max_rel_error": err, "seconds_per_sample": dt / bench.n}
        extra = ""
        if info["method"] == "lut":
            # the tables' own recorded build times: a cached table loads in milliseconds
            mlut = cm.moonlit_earth.model["lut"]
            row["lut_build_seconds"] = info["lut"].build_seconds + (mlut.build_seconds if mlut is not None else 0.0)
            row["lut_validation_max_rel_error"] = info["lut_validation_max_rel_error"]
            extra = f"  (table built in {row['lut_build_seconds']:.0f} s)"
        rows.append(row)
        print(f"  {name:14s} {label:24s} error {err:9.2e}   {dt / bench.n * 1e3:8.3f} ms/sample{extra}")
    return rows


#: the adaptive cadence accepts an interval when its computed midpoint is within this fraction
#: of itself from the straight line between the ends (assumption: a quarter of the 1 % default
#: tolerance, as the interior points between checks are not computed)
ADAPTIVE_CHECK_FRACTION = 0.0025


def adaptive_in_time(full, obs, door, step, check_fraction):
    """Error-checked adaptive time sampling of each pointing's series ``full`` (T, B, P),
    replayed on values already computed: samples every ``step`` (and the last) are computed;
    an interval between computed samples is split at its midpoint, which is computed; the two
    halves are filled by linear interpolation when the midpoint lies within ``check_fraction``
    of itself (every band) from the line between the ends and neither the observability nor
    the door state changes inside, else each half is split again.  Returns the (T, P) mask of
    computed samples and the series it gives."""
    n_t = full.shape[0]
    state = obs.astype(int) * 1000 + np.round(door).astype(int)  # a break where either changes
    knots = sorted(set(range(0, n_t, step)) | {n_t - 1})
    computed = np.zeros(obs.shape, bool)
    computed[knots] = True
    out = np.array(full)
    for p in range(full.shape[2]):
        y, s = full[:, :, p], state[:, p]
        todo = list(zip(knots[:-1], knots[1:]))
        while todo:
            a, b = todo.pop()
            if b - a <= 1:
                continue
            m = (a + b) // 2
            computed[m, p] = True
            line = y[a] + (y[b] - y[a]) * (m - a) / (b - a)
            if np.all(s[a:b + 1] == s[a]) and np.all(np.abs(line - y[m]) <= check_fraction * y[m]):
                for lo, hi in ((a, m), (m, b)):
                    inner = np.arange(lo + 1, hi)
                    out[inner, :, p] = y[lo] + (y[hi] - y[lo]) * ((inner - lo) / (hi - lo))[:, None]
            else:
                todo += [(a, m), (m, b)]
    return computed, out


def time_cadence_rows(bench):
    """Background over 6 h at 60 s for 40 random pointings; coarser cadences linearly
    interpolated in time, and the error-checked adaptive sampling (:func:`adaptive_in_time`)
    from each coarse cadence; error over samples observable at the fine cadence."""
    from straylight.model import BackgroundModel
    from straylight.sky.geometry import observing_geometry, radec_to_unit
    from straylight.sky.observing import scene
    from astropy.time import Time, TimeDelta

    c = bench.campaign
    cm = BackgroundModel(c)
    stars = bench.stars(*DEFAULT_STARS)
    t0 = Time("2026-01-01T00:00:00", scale="utc")
    fine_s = 60.0
    times = t0 + TimeDelta(np.arange(0, 6 * 3600 + 1, fine_s), format="sec")
    rng = np.random.default_rng(2)
    ra, dec = rng.uniform(0, 360, 40), np.degrees(np.arcsin(rng.uniform(-1, 1, 40)))
    los = radec_to_unit(ra, dec)
    sc = scene(c, times)

    def at(idx):
        out, obs, door = [], [], []
        for i in idx:
            sat = np.broadcast_to(sc.satellite_km[i], los.shape)
            bodies = {k: np.broadcast_to(v[i], los.shape) for k, v in sc.bodies_km.items()}
            g = observing_geometry(sat, bodies, los, c.earth.radius_km, c.constraints)
            r = cm.evaluate(sat, bodies, los, g, bench.bands, stars)
            out.append([r[b]["total"] for b in bench.bands])
            obs.append(g["observable"])
            door.append(g["door_opening_deg"])
        return np.array(out), np.array(obs), np.array(door)  # (T, B, P), (T, P), (T, P)

    t_start = time.perf_counter()
    full, obs, door = at(range(len(times)))
    per_sample = (time.perf_counter() - t_start) / (len(times) * los.shape[0])
    rows = []
    x = np.arange(len(times))
    for step in (1, 5, 10, 30, 60):
        idx = np.arange(0, len(times), step)
        coarse = full[idx]  # the same numbers a coarse run computes
        interp = np.empty_like(full)
        for b in range(full.shape[1]):
            for p in range(full.shape[2]):
                interp[:, b, p] = np.interp(x, idx, coarse[:, b, p])
        rel = np.abs(interp - full) / full
        err = float(np.max(np.where(obs[:, None, :], rel, 0.0)))
        p99 = float(np.percentile(rel.transpose(0, 2, 1)[obs], 99))
        cost = per_sample * len(idx) / len(times)
        rows.append({"setting": f"{step * fine_s:.0f} s", "max_rel_error": err, "p99_rel_error": p99,
                     "seconds_per_sample": cost})
        print(f"  {'cadence':14s} {step * fine_s:6.0f} s{'':17s} error {err:9.2e} (p99 {p99:.1e}) "
              f"{cost * 1e3:8.3f} ms/sample")
        if step == 1:
            continue
        # adaptive, as issue #7 describes it: drop the samples interpolation reproduces
        computed, adaptive = adaptive_in_time(full, obs, door, step, ADAPTIVE_CHECK_FRACTION)
        rel_a = np.abs(adaptive - full) / full
        err_a = float(np.max(np.where(obs[:, None, :], rel_a, 0.0)))
        fraction = float(computed.mean())
        rows.append({"setting": f"adaptive {step * fine_s:.0f} s", "max_rel_error": err_a,
                     "seconds_per_sample": per_sample * fraction, "fraction_computed": fraction})
        print(f"  {'cadence':14s} adaptive {step * fine_s:6.0f} s{'':8s} error {err_a:9.2e}   "
              f"{per_sample * fraction * 1e3:8.3f} ms/sample ({fraction:.0%} computed)")
    return rows


def nside_rows(bench):
    """A pixel's value standing for every direction inside it: random directions against the
    value at their pixel's centre, at one time."""
    import healpy as hp

    from straylight.model import BackgroundModel
    from straylight.sky.geometry import observing_geometry, radec_to_unit
    from straylight.sky.observing import scene

    c = bench.campaign
    cm = BackgroundModel(c)
    stars = bench.stars(*DEFAULT_STARS)
    sc = scene(c, ["2026-01-01T03:00:00"])
    rng = np.random.default_rng(4)
    n = 400
    ra, dec = rng.uniform(0, 360, n), np.degrees(np.arcsin(rng.uniform(-1, 1, n)))

    def total(ra_, dec_):
        los = radec_to_unit(ra_, dec_)
        sat = np.broadcast_to(sc.satellite_km[0], los.shape)
        bodies = {k: np.broadcast_to(v[0], los.shape) for k, v in sc.bodies_km.items()}
        g = observing_geometry(sat, bodies, los, c.earth.radius_km, c.constraints)
        r = cm.evaluate(sat, bodies, los, g, bench.bands, stars)
        return np.array([r[b]["total"] for b in bench.bands]), g["observable"]

    exact, obs = total(ra, dec)
    rows = []
    for nside in (8, 16, 32, 64, 128):
        pix = hp.ang2pix(nside, ra, dec, lonlat=True)
        cra, cdec = hp.pix2ang(nside, pix, lonlat=True)
        centre, obs_c = total(cra, cdec)
        both = obs & obs_c
        err = float(np.max(np.abs(centre - exact)[:, both] / exact[:, both]))
        cost_rel = hp.nside2npix(nside) / hp.nside2npix(16)
        rows.append({"setting": f"nside {nside}", "max_rel_error": err, "cost_relative_to_nside16": cost_rel,
                     "seconds_per_sample": cost_rel})
        print(f"  {'nside':14s} {nside:<24d} error {err:9.2e}   cost x{cost_rel:g} of nside 16")
    return rows


def _cube_model(base, campaign: dict | None = None, earthshine: dict | None = None, models: dict | None = None,
                **model_kw):
    """A campaign from ``base`` with ``campaign``, ``models.earthshine`` and ``models``
    overrides, and its BackgroundModel for cube-sized runs, the earthshine table built or loaded
    before timing."""
    import copy

    from straylight.model import BackgroundModel
    from straylight.config import campaign_from_dict

    raw = copy.deepcopy(base.config)
    raw["campaign"].update(campaign or {})
    raw["models"].update(models or {})
    raw["models"].setdefault("earthshine", {}).update(earthshine or {})
    c = campaign_from_dict(raw, base.path)
    model = BackgroundModel(c, expected_samples=10**9, **model_kw)
    model.sunlit_earth.model
    return c, model


def moonlit_grid_rows(bench, day: str = "2026-01-03", time_step: int = 24, n_times: int = 12):
    """The moonlit Earth on the table path: its grid (models.earthshine.moonlit_grid) summed
    directly, and its own table of that sum (moonlit_method lut, with moonlit_lut steps).  The
    cube's access pattern (every footprint pixel at ``n_times`` times of a full-Moon day, when
    the moonlit Earth is brightest), against a 48 x 96 grid summed directly with nothing
    skipped; error over observable samples, as a fraction of the total, of the product's
    treatment (skip on the bound plus the grid or table); seconds per sample of the whole cube
    (best of three; the table's build, once and cached, not included)."""
    from dataclasses import astuple

    from straylight.survey.cube import compute_region
    from straylight.sources.earthshine_lut import MoonlitSettings
    from straylight.survey.footprint import footprint_from_config

    base = bench.campaign
    fp = footprint_from_config(base.config["footprint"])
    t_slice = slice(0, time_step * n_times, time_step)

    def run(grid, method, steps=None, **kw):
        es = {"method": "lut", "moonlit_grid": list(grid), "moonlit_method": method}
        if steps:
            es["moonlit_lut"] = vars(MoonlitSettings(*steps))
        c, model = _cube_model(base, {"start": f"{day}T00:00:00", "end": f"{day}T23:59:59"}, es, **kw)
        model.moonlit_earth.model  # built (or loaded) before timing
        return timed(lambda: compute_region(c, fp, t_slice, slice(None), model=model), repeats=1 if kw else 3)

    ref, _ = run((48, 96), "direct", moonlit_skip_share=0.0)
    total, obs = ref["total"].values.astype(float), ref["observable"].values
    rows = []
    cases = [(g, "direct", None) for g in ((3, 6), (4, 8), (6, 12), (8, 16), (12, 24), (24, 48))]
    cases += [((4, 8), "lut", None), ((6, 12), "lut", (10, 6, 15, 30)), ((6, 12), "lut", None), ((8, 16), "lut", None)]
    for grid, method, steps in cases:
        ds, dt = run(grid, method, steps)
        rel = np.abs(ds["total"].values - total) / total
        err = float(rel[obs].max())
        cost = dt / (n_times * fp.pixels.size)
        label = f"{grid[0]} x {grid[1]} " + ("direct" if method == "direct" else
                                             "table " + "/".join(f"{v:g}" for v in (steps or astuple(MoonlitSettings()))) + " deg")
        rows.append({"setting": label, "max_rel_error": err, "seconds_per_sample": cost,
                     "samples_per_s_per_core": 1.0 / cost, "observable_samples": int(obs.sum()), "day": day})
        print(f"  {'moonlit':14s} {label:24s} error {err:9.2e}   {cost * 1e6:8.1f} us/sample (cube)")
    return rows


def cube_summary(catalog, time_step: int = 24, n_times: int = 12) -> dict:
    """The survey cube's access pattern: every footprint pixel of the default campaign at
    ``n_times`` times spread over its day, as compute_region runs it (the direct path one time
    step per evaluation, the Earth cap gridded once per step; the table path whole steps as one
    batch, cube.SAMPLES_PER_EVALUATION), stars included.  Seconds per sample on one
    core (best of three for the direct earthshine sum, of :data:`FAST_REPEATS` for the look-up table, built once
    and cached), and the
    table path's largest difference from the direct path at observable samples, as a fraction
    of the total (the direct path's own error is the random-sample figure above).  Then the
    table path with models.unobservable_samples: skip, its rate counted over every sample
    (the unobservable ones are NaN), its observable values checked identical to the table
    path's."""
    import tempfile

    from straylight.catalog.build import write_catalog
    from straylight.config import load_campaign
    from straylight.survey.cube import compute_region
    from straylight.survey.footprint import footprint_from_config

    base = load_campaign()
    fp = footprint_from_config(base.config["footprint"])
    t_slice = slice(0, time_step * n_times, time_step)
    out = {"pixels": int(fp.pixels.size), "times": n_times, "time_step_s": time_step * float(base.config["campaign"]["cadence_s"])}
    res, lut_model = {}, None
    with tempfile.TemporaryDirectory() as tmp:
        stars_path = Path(tmp) / "stars.parquet"
        write_catalog(catalog, stars_path, {})
        for key, method, unobservable in (("direct", "direct", "evaluate"), ("lut", "lut", "evaluate"),
                                          ("lut_observable_only", "lut", "skip"),
                                          ("direct_observable_only", "direct", "skip")):
            c, model = _cube_model(base, earthshine={"method": method}, models={"unobservable_samples": unobservable})
            lut_model = model if key == "lut" else lut_model
            # the best of several after a warm-up: single runs varied by up to 30 % (this machine's
            # speed wanders within seconds); the table path's runs are short, so seven of them
            res[key], dt = timed(lambda: compute_region(c, fp, t_slice, slice(None), model=model,
                                                        stars_path=stars_path),
                                 repeats=3 if method == "direct" else FAST_REPEATS)
            out[key] = {"samples_per_s_per_core": n_times * fp.pixels.size / dt}
            print(f"cube, earthshine {method}, unobservable samples {unobservable}: "
                  f"{out[key]['samples_per_s_per_core']:.0f} samples/s/core")
        out["production_region"] = production_region_rates(base, fp, stars_path)
    obs = res["direct"]["observable"].values
    skipped = res["lut_observable_only"]["total"].values
    out["lut_observable_only"]["identical_at_observable"] = bool(
        np.array_equal(skipped[obs], res["lut"]["total"].values[obs]) and np.all(np.isnan(skipped[~obs])))
    direct_skipped = res["direct_observable_only"]["total"].values
    out["direct_observable_only"]["identical_at_observable"] = bool(
        np.array_equal(direct_skipped[obs], res["direct"]["total"].values[obs]) and np.all(np.isnan(direct_skipped[~obs])))
    out["lut_observable_only"]["speedup_over_lut"] = (out["lut_observable_only"]["samples_per_s_per_core"]
                                                      / out["lut"]["samples_per_s_per_core"])
    diff = np.abs(res["lut"]["total"].values - res["direct"]["total"].values) / res["direct"]["total"].values
    out["lut_vs_direct_max_rel_error_observable"] = float(diff[obs].max()) if obs.any() else None
    out["lut_vs_direct_max_rel_error_all"] = float(diff.max())
    out["observable_samples"] = int(obs.sum())
    out["speedup_lut_over_direct"] = out["lut"]["samples_per_s_per_core"] / out["direct"]["samples_per_s_per_core"]
    out["auto_cost_model"] = auto_cost_model(lut_model, out)
    out["plan_cost_model"] = plan_cost_model(base, fp, t_slice, out)
    print(f"cube: table path differs from the direct path by <= {out['lut_vs_direct_max_rel_error_observable']:.2e} "
          f"of the total at {out['observable_samples']} observable samples ({out['lut_vs_direct_max_rel_error_all']:.2e} at all)")
    return out


def production_region_rates(base, fp, stars_path) -> dict:
    """The table path (every sample, and observable samples only) on what one task of a
    production run computes (cube.run_time_block): one time block of consecutive steps
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
    from straylight.survey.cube import compute_region, cube_chunks
    from straylight.sky.observing import scene

    n_times = len(base.times)
    ch = cube_chunks(base, n_times, int(fp.pixels.size))
    t_slice, p_slice = slice(0, ch["time"]), slice(0, ch["pixel"])
    p_blocks = [slice(a, b) for a, b in fp.blocks(ch["pixel"])]
    t_blocks = [slice(t, min(t + ch["time"], n_times)) for t in range(0, n_times, ch["time"])]
    n, n_block = ch["time"] * ch["pixel"], ch["time"] * int(fp.pixels.size)
    out = {"times": int(ch["time"]), "pixels": int(ch["pixel"]), "time_block": {"pixel_blocks": len(p_blocks)},
           "campaign": {"time_blocks": len(t_blocks), "samples": n_times * int(fp.pixels.size)}}
    for key, unobservable in (("lut", "evaluate"), ("lut_observable_only", "skip")):
        c, model = _cube_model(base, earthshine={"method": "lut"}, models={"unobservable_samples": unobservable})
        _, dt = timed(lambda: compute_region(c, fp, t_slice, p_slice, model=model, stars_path=stars_path),
                      repeats=FAST_REPEATS)
        out[key] = {"samples_per_s_per_core": n / dt}
        print(f"cube, one production region ({out['times']} steps x {out['pixels']} pixels), unobservable samples "
              f"{unobservable}: {n / dt:.0f} samples/s/core")

        def time_block(ts=t_slice):
            sc = scene(c, c.times[ts])
            for ps in p_blocks:
                compute_region(c, fp, ts, ps, model=model, stars_path=stars_path, scene=sc)

        _, dt = timed(time_block, repeats=FAST_REPEATS)
        out["time_block"][key] = {"samples_per_s_per_core": n_block / dt}
        print(f"cube, one production time block ({out['times']} steps x {fp.pixels.size} pixels in {len(p_blocks)} "
              f"blocks, the scene once), unobservable samples {unobservable}: {n_block / dt:.0f} samples/s/core")
        block_s = [timed(lambda ts=ts: time_block(ts), repeats=FAST_REPEATS)[1] for ts in t_blocks]
        samples = [(ts.stop - ts.start) * int(fp.pixels.size) for ts in t_blocks]
        out["campaign"][key] = {"samples_per_s_per_core": sum(samples) / sum(block_s),
                                "per_time_block": [k / s for k, s in zip(samples, block_s)]}
        print(f"cube, the whole campaign ({len(t_blocks)} time blocks, {sum(samples)} samples), unobservable samples "
              f"{unobservable}: {sum(samples) / sum(block_s):.0f} samples/s/core (blocks: "
              + ", ".join(f"{k / s:.0f}" for k, s in zip(samples, block_s)) + ")")
    return out


def plan_cost_model(base, fp, t_slice, cube: dict) -> dict:
    """``straylight plan``'s figures (straylight.survey.cube.CUBE_*) against this run: the table path
    per sample; the skip mode's screen per sample (the Sun's and the Moon's geometry of every
    sample, timed here through cube.evaluated_samples on the same steps and pixels) and per
    observable sample (the rest of the skip run); then each of the four runs' seconds as the
    plan's formula gives them from the assumed figures, against the measured ones."""
    from astropy.time import TimeDelta

    from straylight.survey import cube as cu
    from straylight.config import campaign_from_dict, deep_merge

    steps = range(*t_slice.indices(len(base.times)))
    over = {"models": {"unobservable_samples": "skip"},
            "campaign": {"start": base.times[steps[0]].isot,
                         "end": (base.times[steps[-1]] + TimeDelta(1, format="sec")).isot,
                         "cadence_s": steps.step * float(base.config["campaign"]["cadence_s"])}}
    sub = campaign_from_dict(deep_merge(base.config, over), base.path)  # the same steps as a campaign of their own
    assert len(sub.times) == len(steps)
    _, screen = timed(lambda: cu.evaluated_samples(sub, fp, max_times=len(sub.times), max_pixels=fp.pixels.size))
    n = len(steps) * fp.pixels.size
    n_obs = cube["observable_samples"]
    measured = {"table_seconds_per_sample": 1.0 / cube["lut"]["samples_per_s_per_core"],
                "screen_seconds_per_sample": screen / n}
    measured["table_seconds_per_observable_sample"] = (
        (n / cube["lut_observable_only"]["samples_per_s_per_core"] - n * measured["screen_seconds_per_sample"]) / n_obs)
    assumed = {"table_seconds_per_sample": cu.CUBE_TABLE_SECONDS_PER_SAMPLE,
               "screen_seconds_per_sample": cu.CUBE_SCREEN_SECONDS_PER_SAMPLE,
               "table_seconds_per_observable_sample": cu.CUBE_TABLE_SECONDS_PER_OBSERVABLE_SAMPLE}
    predicted = {"lut": cu.cube_compute_seconds(n, n, "lut", False),
                 "direct": cu.cube_compute_seconds(n, n, "direct", False),
                 "lut_observable_only": cu.cube_compute_seconds(n, n_obs, "lut", True),
                 "direct_observable_only": cu.cube_compute_seconds(n, n_obs, "direct", True)}
    runs = {k: {"predicted_seconds": v, "measured_seconds": n / cube[k]["samples_per_s_per_core"]}
            for k, v in predicted.items()}
    for k, v in measured.items():
        print(f"plan: {k} {v * 1e6:.2f} us (assumed {assumed[k] * 1e6:.2f})")
    for k, v in runs.items():
        print(f"plan: {k:22s} predicted {v['predicted_seconds']:.2f} s, measured {v['measured_seconds']:.2f} s")
    return {"measured": measured, "assumed": assumed, "runs": runs}


def auto_cost_model(lut_model, cube: dict) -> dict:
    """models.earthshine.method = auto's two constants against this run: the seconds a cube
    sample saves on the table path (measured just now) and the table's build seconds per node
    and door state (as recorded when the cached table was built, on whatever cores it had).
    A measured figure far from the assumed one means the constants in straylight/model/fidelity.py
    want updating."""
    from straylight.model import fidelity as comp

    es = lut_model.sunlit_earth.model
    saved = 1.0 / cube["direct"]["samples_per_s_per_core"] - 1.0 / cube["lut"]["samples_per_s_per_core"]
    build = es["lut_build_seconds"] / es["lut_node_states"]
    out = {"saved_seconds_per_sample": {"measured": saved, "assumed": comp.LUT_SAVED_SECONDS_PER_SAMPLE},
           "build_seconds_per_node": {"recorded": build, "assumed": comp.LUT_BUILD_SECONDS_PER_NODE},
           "pays_off_above_samples": {"measured": es["lut_build_seconds"] / saved,
                                      "assumed": comp.LUT_BUILD_SECONDS_PER_NODE * es["lut_node_states"]
                                      / comp.LUT_SAVED_SECONDS_PER_SAMPLE}}
    print(f"auto: the table saves {saved * 1e3:.3f} ms per cube sample (assumed "
          f"{comp.LUT_SAVED_SECONDS_PER_SAMPLE * 1e3:.3f}), was built at {build * 1e3:.3f} ms per node and "
          f"state (assumed {comp.LUT_BUILD_SECONDS_PER_NODE * 1e3:.3f}): pays off above "
          f"{out['pays_off_above_samples']['measured']:.3g} samples (assumed {out['pays_off_above_samples']['assumed']:.3g})")
    return out


def _table_summary(rows):
    """The default earthshine table (the last, finest row) against the direct sum (first row):
    speed, error, build time and the campaign size above which the table pays off."""
    direct, table = rows[0], rows[-1]
    saved = direct["seconds_per_sample"] - table["seconds_per_sample"]
    return {"setting": table["setting"], "samples_per_s_per_core": 1.0 / table["seconds_per_sample"],
            "max_rel_error": table["max_rel_error"], "build_seconds": table.get("lut_build_seconds"),
            "validation_max_rel_error": table.get("lut_validation_max_rel_error"),
            "direct_samples_per_s_per_core": 1.0 / direct["seconds_per_sample"],
            "pays_off_above_samples": table.get("lut_build_seconds", 0.0) / saved if saved > 0 else None}


def pareto_chart(name, rows, path, xlabel="seconds per sample (one core, all bands)"):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    x = np.array([r["seconds_per_sample"] for r in rows])
    y = np.array([max(r["max_rel_error"], 1e-9) for r in rows])
    fig, ax = plt.subplots(figsize=(6, 4.2))
    ax.loglog(x, y, "o", color="C0")
    order = np.argsort(x)
    front, best = [], np.inf
    for i in order:  # Pareto front: nothing cheaper is as accurate
        if y[i] < best:
            front.append(i)
            best = y[i]
    ax.loglog(x[front], y[front], "-", color="C1", label="Pareto front")
    for xi, yi, r in zip(x, y, rows):
        ax.annotate(r["setting"], (xi, yi), textcoords="offset points", xytext=(4, 4), fontsize=7)
    ax.axhline(0.01, color="grey", ls="--", lw=0.8, label="default tolerance 1 %")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("max |error| / total background")
    ax.set_title(f"straylight: {name}")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def goal_check(summary: dict) -> dict:
    """Issue #7's goal figures against this run's (the default path: the cube on the table
    path, every sample evaluated, as production computes it): samples/s/core for all bands on
    the whole default campaign, time block by time block as its jobs compute it (the figure
    production runs at), its first time block, a single region and the day-spread batch; the
    default's error against the converged reference (the earthshine
    table's row of the random-sample sweep, the largest term's error; None in a ``--only
    cube`` run without an earlier full run) and the cube's table path against its direct
    path; the speed-up over the direct path, side by side in one run."""
    cube = summary.get("cube", {})
    region = cube.get("production_region", {})
    rates = {"production_campaign": region.get("campaign", {}).get("lut", {}).get("samples_per_s_per_core"),
             "production_time_block": region.get("time_block", {}).get("lut", {}).get("samples_per_s_per_core"),
             "production_region": region.get("lut", {}).get("samples_per_s_per_core"),
             "day_spread_batch": cube.get("lut", {}).get("samples_per_s_per_core")}
    error = (summary.get("earthshine_table") or {}).get("max_rel_error")
    speedup = cube.get("speedup_lut_over_direct")
    goal_rate, goal_error, goal_speedup = GOAL_SAMPLES_PER_S_PER_CORE, GOAL_MAX_REL_ERROR, GOAL_SPEEDUP_OVER_DIRECT
    return {
        "samples_per_s_per_core": rates,
        "goal_samples_per_s_per_core": goal_rate,
        "max_rel_error_vs_reference": error,
        "max_rel_error_table_vs_direct_observable": cube.get("lut_vs_direct_max_rel_error_observable"),
        "goal_max_rel_error": goal_error,
        "speedup_over_direct": speedup,
        "goal_speedup_over_direct": goal_speedup,
        "met": {**{f"rate_{k}": _met(rates[k], goal_rate)
                   for k in ("production_campaign", "production_time_block", "day_spread_batch")},
                "error": _met(error, goal_error, at_most=True),
                "speedup": _met(speedup, goal_speedup)},
    }


def _met(value, goal, at_most: bool = False):
    """Whether a measured figure meets its goal (at least it; at most it for an error); None
    when the run did not measure it (not a pass)."""
    if value is None:
        return None
    return bool(value <= goal if at_most else value >= goal)


def _print_goal_check(check: dict) -> None:
    r = check["samples_per_s_per_core"]
    fmt = lambda v: "-" if v is None else f"{v:,.0f}"  # noqa: E731
    err = check["max_rel_error_vs_reference"]
    err = "-" if err is None else f"{err:.2e}"
    print(f"goal: {fmt(r['production_campaign'])} samples/s/core on the whole default campaign "
          f"({fmt(r['production_time_block'])} its first time block, {fmt(r['production_region'])} one region, "
          f"{fmt(r['day_spread_batch'])} the day-spread batch) against "
          f"{check['goal_samples_per_s_per_core']:,.0f}; error {err} against "
          f"{check['goal_max_rel_error']:g}; {fmt(check['speedup_over_direct'])}x the direct path; met: {check['met']}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=150, help="random observable samples (default 150)")
    ap.add_argument("--quick", action="store_true", help="fewer settings (a smoke run)")
    ap.add_argument("--only", choices=("time_cadence", "healpix_nside", "moonlit_grid", "cube"), default=None,
                    help="re-run one model-independent sweep and update knobs.json and its chart "
                         "(cube: the cube section of summary.json)")
    args = ap.parse_args(argv)
    if args.only == "cube":
        import json

        bench = Bench(args.samples)
        path = RESULTS / "summary.json"
        summary = json.loads(path.read_text()) if path.exists() else {}
        summary["cube"] = cube_summary(bench.catalog)
        summary["goal_check"] = goal_check(summary)
        _print_goal_check(summary["goal_check"])
        write_results("summary", summary)
        return
    if args.only:
        import json

        bench = Bench(args.samples)
        rows = {"time_cadence": time_cadence_rows, "healpix_nside": nside_rows,
                "moonlit_grid": moonlit_grid_rows}[args.only](bench)
        path = RESULTS / "knobs.json"
        knobs = json.loads(path.read_text()) if path.exists() else {}
        knobs[args.only] = rows
        write_results("knobs", knobs)
        pareto_chart(args.only, rows, RESULTS / f"pareto_{args.only}.png",
                     "cost relative to nside 16" if args.only == "healpix_nside" else
                     "seconds per sample (one core, all bands)")
        return
    t_start = time.perf_counter()
    bench = Bench(args.samples)
    print(f"{bench.n} observable samples, {len(bench.bands)} bands")
    ref_model = bench.model(**REFERENCE)
    ref_stars = bench.stars(*REFERENCE_STARS)
    ref, t_ref = timed(lambda: bench.evaluate(ref_model, ref_stars), repeats=1)
    # the reference itself against a still finer one, on a few samples: is it converged?
    finer = bench.model(n_gamma=192, n_psi=384, door_blocks=(64, 64), n_aperture_door=1024, pst_step=(0.05, 0.5),
                        tolerance=1e-12)
    few = slice(0, min(20, bench.n))
    res_finer = bench.evaluate(finer, ref_stars, few)
    ref_few = bench.evaluate(ref_model, ref_stars, few)
    ref_err = max_rel_error(ref_few, res_finer, bench.bands)
    def_model = bench.model(**DEFAULT)
    def_stars = bench.stars(*DEFAULT_STARS)
    res_def, t_def = timed(lambda: bench.evaluate(def_model, def_stars))
    def_err = max_rel_error(res_def, ref, bench.bands)
    per_component = {c: max(float(np.max(np.abs(res_def[b][c] - ref[b][c]) / ref[b]["total"])) for b in bench.bands)
                     for c in COMPONENTS}
    print(f"default:   {bench.n / t_def:9.0f} samples/s/core, max error {def_err:.2e} of the total")
    print(f"reference: {bench.n / t_ref:9.1f} samples/s/core, max error {ref_err:.2e} against a finer model")
    print("default error by component:", {k: f"{v:.1e}" for k, v in per_component.items()})

    knobs = {}
    print("knob sweeps (others at their default):")
    g = [(16, 32), (24, 48), (32, 64), (48, 96)] if args.quick else [(8, 16), (12, 24), (16, 32), (24, 48), (32, 64), (48, 96), (96, 192)]
    knobs["earth_grid"] = sweep(bench, ref, "earth grid", [(f"{a} x {b}", {**DEFAULT, "n_gamma": a, "n_psi": b}, def_stars)
                                                          for a, b in g])
    lut = [(5.0, 5.0, 20.0), (0.5, 2.0, 2.5)] if args.quick else \
        [(5.0, 5.0, 20.0), (2.5, 4.0, 10.0), (1.0, 2.0, 10.0), (0.5, 2.0, 5.0), (0.5, 2.0, 2.5)]
    knobs["earthshine_lut"] = sweep(bench, ref, "earthshine", [("direct 24 x 48", DEFAULT, def_stars)] + [
        (f"table {a:g}/{b:g}/{c:g} deg", {**DEFAULT, "lut_steps": (a, b, c)}, def_stars) for a, b, c in lut])
    d = [(8, 32), (24, 128)] if args.quick else [(2, 8), (4, 16), (8, 32), (16, 64), (24, 128), (32, 256)]
    knobs["door_discretisation"] = sweep(bench, ref, "door", [(f"{a}x{a} blocks, {b} ap.", {**DEFAULT, "door_blocks": (a, a), "n_aperture_door": b}, def_stars)
                                                             for a, b in d])
    p = [(0.5, 5.0), (0.25, 2.5), (0.1, 1.0)] if args.quick else [(2.0, 20.0), (1.0, 10.0), (0.5, 5.0), (0.25, 2.5), (0.1, 1.0)]
    knobs["pst_grid"] = sweep(bench, ref, "PST grid", [(f"{a} x {b} deg", {**DEFAULT, "pst_step": (a, b)}, def_stars) for a, b in p])
    s = [(-99.0, True), (2.0, True), (4.0, True), (4.0, False)] if args.quick else \
        [(-99.0, True), (0.0, True), (2.0, True), (4.0, True), (6.0, True), (2.0, False), (4.0, False), (6.0, False), (8.0, False)]
    knobs["star_split"] = sweep(bench, ref, "stars", [(f"direct <= {lim:g}{' + map' if f else ''}", DEFAULT, bench.stars(lim, f))
                                                      for lim, f in s])
    tols = [1e-12, 1e-2, 1e-1] if args.quick else [1e-12, 1e-3, 1e-2, 3e-2, 1e-1]
    knobs["star_skip"] = sweep(bench, ref, "star skip", [(f"tolerance {t:g}", {**DEFAULT, "tolerance": t}, def_stars)
                                                         for t in tols])
    knobs["moonlit_grid"] = moonlit_grid_rows(bench)
    knobs["time_cadence"] = time_cadence_rows(bench)
    knobs["healpix_nside"] = nside_rows(bench)
    RESULTS.mkdir(parents=True, exist_ok=True)
    for name, rows in knobs.items():
        xlabel = "cost relative to nside 16" if name == "healpix_nside" else "seconds per sample (one core, all bands)"
        pareto_chart(name, rows, RESULTS / f"pareto_{name}.png", xlabel)
    summary = {
        "samples": bench.n,
        "bands": bench.bands,
        "background_samples_per_s_per_core": bench.n / t_def,
        "background_max_rel_error": def_err,
        "background_max_rel_error_by_component": per_component,
        "default_settings": {**DEFAULT, "stars_direct_mag_limit": DEFAULT_STARS[0], "stars_faint_map": DEFAULT_STARS[1]},
        "reference": {"background_samples_per_s_per_core": bench.n / t_ref,
                      "background_max_rel_error": ref_err,
                      "background_max_rel_error_against": "a finer model (Earth grid 192 x 384, door 64 x 64 blocks, "
                                                          "1024 aperture points, PST 0.05 x 0.5 deg), 20 samples",
                      "settings": {**REFERENCE, "stars_direct_mag_limit": REFERENCE_STARS[0], "stars_faint_map": False}},
        "speedup_default_over_reference": t_ref / t_def,
        "earthshine_table": _table_summary(knobs["earthshine_lut"]),
        "cube": cube_summary(bench.catalog),
        "goal_samples_per_s_per_core": GOAL_SAMPLES_PER_S_PER_CORE,
        "goal_max_rel_error": GOAL_MAX_REL_ERROR,
        "bench_seconds": time.perf_counter() - t_start,
        "charts": sorted(str(p.name) for p in RESULTS.glob("pareto_*.png")),
    }
    summary["goal_check"] = goal_check(summary)
    _print_goal_check(summary["goal_check"])
    write_results("knobs", knobs)
    write_results("summary", summary)
    print(f"default {summary['background_samples_per_s_per_core']:.0f} samples/s/core at max error "
          f"{def_err:.2e}; reference {summary['reference']['background_samples_per_s_per_core']:.1f}; "
          f"speed-up {summary['speedup_default_over_reference']:.0f}x; {summary['bench_seconds']:.0f} s")


if __name__ == "__main__":
    main()
