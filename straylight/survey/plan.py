"""Before a campaign runs: what it will cost (``straylight plan``).

How many samples the cube evaluates (:func:`evaluated_samples`), the cube's compute at this
code's measured per-sample figures (:func:`cube_compute_seconds`, scaled to a machine by
:func:`machine_speed`), the whole run wall to wall at the pipeline's measured figure
(:func:`pipeline_rate`: bench/pipeline.py), and the products' bytes
(:data:`PRODUCT_BYTES_PER_SAMPLE`); :func:`estimated_cost` puts them together.
"""
from __future__ import annotations

import json
import time as _time
from pathlib import Path

import numpy as np

from straylight.config import Campaign
from straylight.sky.geometry import observing_geometry, radec_to_unit
from straylight.survey.footprint import Footprint


def evaluated_samples(campaign: Campaign, fp: Footprint, max_times: int = 144, max_pixels: int = 660) -> int:
    """How many samples the campaign's cube evaluates: every (time, pixel) one, or with
    models.unobservable_samples: skip the observable ones, their fraction estimated from an
    even subsample of at most ``max_times`` x ``max_pixels`` (deterministic: the same config
    gives the same count, and so the same earthshine model, on every machine; exact when the
    campaign is no bigger).  On the default day (16.5 % observable) 144 x 660 of its 288 x 1320
    samples give the fraction to 0.1 % of the samples in 0.15 s; 48 x 256 erred by 2.4 % (every
    sixth step, 30 minutes apart, meets the 92-minute orbit in a pattern)."""
    from straylight.model import unobservable_samples
    from straylight.sky.observing import scene

    n = len(campaign.times) * int(fp.pixels.size)
    if unobservable_samples(campaign) != "skip" or n == 0:
        return n
    t_idx = np.unique(np.linspace(0, len(campaign.times) - 1, min(max_times, len(campaign.times))).round().astype(int))
    p_idx = np.unique(np.linspace(0, fp.pixels.size - 1, min(max_pixels, fp.pixels.size)).round().astype(int))
    sc = scene(campaign, campaign.times[t_idx])
    los = radec_to_unit(fp.ra_deg[p_idx], fp.dec_deg[p_idx])
    g = observing_geometry(sc.satellite_km[:, None], {b: sc.bodies_km[b][:, None] for b in ("sun", "moon")},
                           los[None], campaign.earth.radius_km, campaign.constraints)
    return int(round(n * float(np.mean(g["observable"]))))


#: The cube's cost on one core, all bands, per sample, as ``straylight plan`` predicts it: the
#: table path evaluating every sample, and with models.unobservable_samples: skip the screen
#: (the Sun's and the Moon's geometry, every sample) and each observable sample evaluated (they
#: cost ~1.7x the average sample: more moonlit-Earth sums and star pairs); the direct earthshine
#: sum adds straylight.model.fidelity.LUT_SAVED_SECONDS_PER_SAMPLE per evaluated sample.  Seconds, in the units
#: of the reference machine those figures are given for (:func:`machine_speed` scales them to
#: another), from ``bench/run.py --only cube`` on the default day (12 steps x 1320 pixels, best
#: of seven), which prints them again as cube.plan_cost_model with its runs' predicted seconds
#: against the measured ones, so a drift shows.
CUBE_TABLE_SECONDS_PER_SAMPLE = 4.8e-6
CUBE_SCREEN_SECONDS_PER_SAMPLE = 1.05e-6
CUBE_TABLE_SECONDS_PER_OBSERVABLE_SAMPLE = 10.3e-6


#: Bytes on disk per (time, pixel) sample of the whole product set (background.zarr, limits.zarr,
#: observability.zarr), all bands: the compressed stores' budget (at most 25 bytes per sample;
#: docs/performance.md gives the measured figure).  The one figure `straylight plan` sizes a campaign's products with.
PRODUCT_BYTES_PER_SAMPLE = 25.0
#: The pipeline's speed wall to wall (samples / wall seconds / cores: `snakemake` to the last
#: product, every rule included, the earthshine tables cached), when neither
#: compute.pipeline_samples_per_s_per_core nor bench/results/pipeline.json gives one:
#: bench/pipeline.py on one month of config/cycle.yaml (nside 64, 5-minute cadence, 183,081,600
#: samples; the run that computes the footprint's faint-star map) on the 2-core development
#: machine.  Per-run costs (job start-up, the faint-star map, figures) weigh more in smaller
#: campaigns (docs/performance.md gives both figures).
PIPELINE_SAMPLES_PER_S_PER_CORE = 617_175.0
#: where bench/pipeline.py writes its figures
PIPELINE_BENCH_RESULTS = Path(__file__).resolve().parents[2] / "bench" / "results" / "pipeline.json"


def pipeline_rate(campaign: Campaign, bench_results=PIPELINE_BENCH_RESULTS) -> tuple[float, str]:
    """The pipeline's wall-to-wall samples/s/core and where it comes from: the config's
    compute.pipeline_samples_per_s_per_core, else the last bench/pipeline.py run's figure
    (``bench_results``), else PIPELINE_SAMPLES_PER_S_PER_CORE."""
    configured = (campaign.config.get("compute") or {}).get("pipeline_samples_per_s_per_core")
    if configured:
        return float(configured), "compute.pipeline_samples_per_s_per_core"
    path = Path(bench_results)
    if path.exists():
        try:
            rec = json.loads(path.read_text())
            c = rec["campaign"]
            return float(rec["samples_per_s_per_core"]), (
                f"{path.name}: {c['days']:g} days at nside {c['nside']}, {c['cadence_s']:g} s, {rec['cores']} cores")
        except (ValueError, KeyError, TypeError):
            pass  # an unreadable or partial file: the stated default below
    return PIPELINE_SAMPLES_PER_S_PER_CORE, "straylight.survey.plan.PIPELINE_SAMPLES_PER_S_PER_CORE"


def cube_compute_seconds(samples: int, evaluated: int, earthshine_method: str, skip: bool,
                         seconds_per_evaluated_sample: float | None = None, speed_factor: float = 1.0) -> float:
    """Seconds on one core to compute a cube of ``samples`` (time, pixel) samples of which
    ``evaluated`` are evaluated (all, or with ``skip`` the observable ones), with the sunlit
    earthshine ``earthshine_method`` ('lut' or 'direct'), at the CUBE_* and
    straylight.model.fidelity.LUT_SAVED_SECONDS_PER_SAMPLE figures above times ``speed_factor`` (this machine
    against the one they were measured on, :func:`machine_speed`); or at
    ``seconds_per_evaluated_sample`` per evaluated sample when given (another machine)."""
    from straylight.model import LUT_SAVED_SECONDS_PER_SAMPLE

    if seconds_per_evaluated_sample is not None:
        return evaluated * seconds_per_evaluated_sample
    per_eval = CUBE_TABLE_SECONDS_PER_OBSERVABLE_SAMPLE if skip else CUBE_TABLE_SECONDS_PER_SAMPLE
    if earthshine_method == "direct":
        per_eval += LUT_SAVED_SECONDS_PER_SAMPLE
    return speed_factor * (evaluated * per_eval + (samples * CUBE_SCREEN_SECONDS_PER_SAMPLE if skip else 0.0))


def machine_speed(campaign: Campaign, fp: Footprint, n_times: int = 4, n_pixels: int = 1320, repeats: int = 2) -> dict:
    """This machine's speed against the one the cost figures (CUBE_*, fidelity.LUT_*) were
    measured on: ``n_times`` cube time steps spread over the campaign at ~``n_pixels`` footprint
    pixels spread over it (one step, or a few hundred pixels, weigh the per-step costs too
    much), on the direct earthshine sum, every sample evaluated, without stars (~1 % of that
    path's cost), best of ``repeats`` after a full-size warm-up, against
    :func:`cube_compute_seconds` for it.  Returns the samples, ``measured_seconds``,
    ``assumed_seconds`` and ``factor`` (measured / assumed: below 1 on a faster machine).  One
    factor for every figure: on the development machine it reads about x0.24 where the cube
    bench's four paths read x0.21-0.33 against the same figures, so it errs by -12 % to +40 %
    per path."""
    from straylight.config import campaign_from_dict, deep_merge
    from straylight.model import BackgroundModel
    from straylight.survey.cube import compute_region

    direct = campaign_from_dict(deep_merge(campaign.config, {"models": {"earthshine": {"method": "direct"},
                                                                        "unobservable_samples": "evaluate"}}),
                                campaign.path)
    model = BackgroundModel(direct, expected_samples=1)
    nt = len(direct.times)
    t_slice = slice(0, nt, max(1, nt // max(1, n_times)))
    p_slice = slice(0, None, max(1, int(fp.pixels.size) // max(1, n_pixels)))
    n = len(range(*t_slice.indices(nt))) * len(range(*p_slice.indices(int(fp.pixels.size))))
    if n == 0:  # no time or no pixel: nothing to time, the figures stand
        return {"samples": 0, "measured_seconds": 0.0, "assumed_seconds": 0.0, "factor": 1.0}
    # warm-up at full size: door tables, bands, and glibc's mmap threshold, which rises only after
    # the first large arrays are freed (the first call ran 1.4x slower)
    compute_region(direct, fp, t_slice, p_slice, model=model)
    best = np.inf
    for _ in range(max(1, repeats)):
        t0 = _time.perf_counter()
        compute_region(direct, fp, t_slice, p_slice, model=model)
        best = min(best, _time.perf_counter() - t0)
    assumed = cube_compute_seconds(n, n, "direct", False)
    return {"samples": n, "measured_seconds": best, "assumed_seconds": assumed, "factor": best / assumed}


def estimated_cost(campaign: Campaign, fp: Footprint, seconds_per_evaluated_sample: float | None = None,
                   speed_factor: float = 1.0) -> dict:
    """What the campaign's cube will cost before it runs: its samples, the samples it
    evaluates (:func:`evaluated_samples`), the sunlit earthshine model ``auto`` picks
    (SunlitEarth.choice, nothing built), the table's build when it is not cached
    yet, and the compute (:func:`cube_compute_seconds`).  Seconds on one core.  Also the
    whole run, wall to wall, at the measured pipeline figure (:func:`pipeline_rate`, measured
    on the table path; on the direct sum the kernel's compute where that is slower; the table's build added
    when it is not cached), and the products' bytes
    (PRODUCT_BYTES_PER_SAMPLE).  The compute and build seconds are in the units of the machine
    the CUBE_* and fidelity.LUT_* figures are given for (single runs wander by 20-40 %), times
    ``speed_factor`` (:func:`machine_speed`) for this one."""
    from straylight.model import BackgroundModel, unobservable_samples

    n = len(campaign.times) * int(fp.pixels.size)
    n_eval = evaluated_samples(campaign, fp)
    model = BackgroundModel(campaign, expected_samples=n_eval)
    choice = model.sunlit_earth.choice
    skip = unobservable_samples(campaign) == "skip"
    compute_s = cube_compute_seconds(n, n_eval, choice["method"], skip, seconds_per_evaluated_sample, speed_factor)
    build_s, table_cached = 0.0, False
    if choice["method"] == "lut":  # the sunlit table and the moonlit one, each unless cached
        moonlit_s = choice["moonlit_build_seconds_estimate"]
        sunlit_cached = model.sunlit_earth.lut_path().exists()
        moonlit_path = model.moonlit_earth.lut_path()
        moonlit_cached = moonlit_path is None or moonlit_path.exists()
        table_cached = sunlit_cached and moonlit_cached
        build_s = speed_factor * ((0.0 if sunlit_cached else choice["build_seconds_estimate"] - moonlit_s)
                                  + (0.0 if moonlit_cached else moonlit_s))
    rate, rate_source = pipeline_rate(campaign)
    return {"samples": n, "evaluated_samples": n_eval, "unobservable_samples": "skip" if skip else "evaluate",
            "earthshine_method": choice["method"], "earthshine_reason": choice["reason"],
            "table_cached": table_cached, "table_build_seconds": build_s, "compute_seconds": compute_s,
            "core_hours": (compute_s + build_s) / 3600.0, "speed_factor": speed_factor,
            "pipeline_samples_per_s_per_core": rate, "pipeline_rate_source": rate_source,
            # the figure is measured on the table path; the direct sum's kernel alone is slower
            "pipeline_core_hours": ((n / rate if choice["method"] == "lut" else max(n / rate, compute_s))
                                    + build_s) / 3600.0,
            "product_bytes": n * PRODUCT_BYTES_PER_SAMPLE}
