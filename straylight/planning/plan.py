"""Before a campaign runs: what it will cost (``straylight plan``).

How many samples the cube evaluates (:func:`evaluated_samples`), the cube's compute at this
code's measured per-sample figures (:func:`cube_compute_seconds`), the whole run wall to wall
(a fixed part plus the samples at the pipeline's rate, :func:`pipeline_rate`, plus the
earthshine tables' build when they are not cached), and the products' bytes
(:data:`PRODUCT_BYTES_PER_SAMPLE`); :func:`estimated_cost` puts them together.  The figures
are one reference machine's (docs/performance.md says how each is measured); :func:`machine_speed`
scales them to this one.
"""

from __future__ import annotations

import time as _time

import numpy as np

from straylight.config import Campaign
from straylight.cube.footprint import Footprint
from straylight.sky.geometry import observing_geometry
from straylight.sky.vectors import radec_to_unit

__all__ = [
    "evaluated_samples",
    "CUBE_TABLE_SECONDS_PER_SAMPLE",
    "CUBE_SCREEN_SECONDS_PER_SAMPLE",
    "CUBE_TABLE_SECONDS_PER_OBSERVABLE_SAMPLE",
    "PRODUCT_BYTES_PER_SAMPLE",
    "COMPACT_BYTES_PER_SAMPLE",
    "PIPELINE_FIXED_SECONDS",
    "PIPELINE_SAMPLES_PER_S_PER_CORE",
    "FAINT_MAP_SECONDS_PER_PIXEL",
    "pipeline_rate",
    "cube_compute_seconds",
    "machine_speed",
    "probed_speed_factor",
    "needed_tables",
    "estimated_cost",
]


def evaluated_samples(campaign: Campaign, fp: Footprint, max_times: int = 144, max_pixels: int = 660) -> int:
    """How many samples the campaign's cube evaluates: every (time, pixel) one, or with
    models.unobservable_samples: skip the observable ones, their fraction estimated from an
    even subsample of at most ``max_times`` x ``max_pixels`` (deterministic: the same config
    gives the same count on every machine; exact when the campaign is no bigger).  On the
    default day (16.5 % observable) 144 x 660 of its 288 x 1320 samples give the fraction to
    0.1 % of the samples; 48 x 256 erred by 2.4 % (every sixth step, 30 minutes apart, meets the
    92-minute orbit in a pattern).

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign (times, orbit, constraints, models).
    fp : Footprint
        The survey footprint.
    max_times, max_pixels : int, optional
        Most time steps and pixels of the subsample that estimates the observable fraction.

    Returns
    -------
    int
        Samples evaluated (time steps x pixels, or its estimated observable part).
    """
    from straylight.model import unobservable_samples
    from straylight.sky.observing import scene

    n = len(campaign.times) * int(fp.pixels.size)
    if unobservable_samples(campaign) != "skip" or n == 0:
        return n
    t_idx = np.unique(
        np.linspace(0, len(campaign.times) - 1, min(max_times, len(campaign.times))).round().astype(int)
    )
    p_idx = np.unique(np.linspace(0, fp.pixels.size - 1, min(max_pixels, fp.pixels.size)).round().astype(int))
    sc = scene(campaign.orbit, campaign.times[t_idx])
    los = radec_to_unit(fp.ra_deg[p_idx], fp.dec_deg[p_idx])
    g = observing_geometry(
        sc.satellite_km[:, None],
        {b: sc.bodies_km[b][:, None] for b in ("sun", "moon")},
        los[None],
        campaign.earth.radius_km,
        campaign.constraints,
    )
    return int(round(n * float(np.mean(g["observable"]))))


#: The cube's compute on one reference core, all bands, per sample: the table path evaluating
#: every sample, and with models.unobservable_samples: skip the screen (the Sun's and the Moon's
#: geometry, every sample) and each observable sample evaluated (they cost more than the average
#: sample: more moonlit-Earth sums and star pairs); the direct earthshine sum
#: adds straylight.model.fidelity.LUT_SAVED_SECONDS_PER_SAMPLE per evaluated sample.  From
#: ``bench/run.py --only cube`` on the default day, which prints them again as
#: cube.plan_cost_model with its runs' predicted seconds against the measured ones.
CUBE_TABLE_SECONDS_PER_SAMPLE = 1.2e-6
CUBE_SCREEN_SECONDS_PER_SAMPLE = 0.26e-6
CUBE_TABLE_SECONDS_PER_OBSERVABLE_SAMPLE = 2.6e-6


#: Bytes on disk per (time, pixel) sample of the whole product set (background.zarr, limits.zarr,
#: observability.zarr), all bands: the compressed stores' budget (at most 25 bytes per sample;
#: docs/performance.md gives the measured figure).  The one figure `straylight plan` sizes a
#: campaign's products with.
PRODUCT_BYTES_PER_SAMPLE = 25.0
#: Bytes on disk per (time, pixel) sample of the compact sky product (sky_compact.zarr: seven
#: bands' magnitudes and the observability, straylight.cube.compact) at the default
#: storage.compact_mag_step: a month at nside 32 measured 0.171 (bench/compact.py, docs/performance.md).
COMPACT_BYTES_PER_SAMPLE = 0.18
#: The pipeline's wall time, `snakemake` to the last product, on N cores with the earthshine
#: tables cached: PIPELINE_FIXED_SECONDS + samples / (PIPELINE_SAMPLES_PER_S_PER_CORE x N).  The
#: fixed part is the jobs' start-up, the model's set-up, the figures and the report; the rest
#: grows with the samples.  Both at the speed probe's reference (factor 1): the fixed part from
#: the bench/pipeline.py runs on 2 cores (1 day at nside 16, 3 days at nside 32), the rate from a
#: month at nside 32 with the envelope's members, 234.6 s on the idle 2 cores at a probed factor
#: of 2.01 (docs/performance.md); the config's compute.pipeline_samples_per_s_per_core replaces
#: the rate for another machine.
PIPELINE_FIXED_SECONDS = 26.0
PIPELINE_SAMPLES_PER_S_PER_CORE = 252_000.0
#: A footprint's first campaign also sums its faint-star map (kept for later ones), seconds on one
#: core per footprint pixel (bench/pipeline.py, the same runs).
FAINT_MAP_SECONDS_PER_PIXEL = 3.0e-3
#: The largest relative error of the wall-time estimates measured by bench/estimates.py
#: (|estimate / measured - 1| of a default day, 3 days and a month at nside 32, at load 0 and 2 on
#: 2 cores, and a default day with an empty table cache; bench/results/estimates.json): a measured
#: bound on those runs, not a guarantee, since a shared machine's speed drifts as much.
ESTIMATE_MEASURED_ERROR = 0.30


def pipeline_rate(campaign: Campaign) -> tuple[float, str]:
    """The pipeline's samples/s/core beyond its fixed part and where it comes from: the config's
    compute.pipeline_samples_per_s_per_core, else PIPELINE_SAMPLES_PER_S_PER_CORE.

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign.

    Returns
    -------
    rate : float
        Samples per second per core.
    source : str
        The config key or the module constant the rate comes from.
    """
    configured = campaign.settings.compute.pipeline_samples_per_s_per_core
    if configured:
        return float(configured), "compute.pipeline_samples_per_s_per_core"
    return PIPELINE_SAMPLES_PER_S_PER_CORE, "straylight.planning.plan.PIPELINE_SAMPLES_PER_S_PER_CORE"


def cube_compute_seconds(
    samples: int,
    evaluated: int,
    earthshine_method: str,
    skip: bool,
    seconds_per_evaluated_sample: float | None = None,
    speed_factor: float = 1.0,
) -> float:
    """Seconds on one core to compute a cube of ``samples`` (time, pixel) samples of which
    ``evaluated`` are evaluated (all, or with ``skip`` the observable ones), with the sunlit
    earthshine ``earthshine_method`` ('lut' or 'direct'), at the CUBE_* and
    straylight.model.fidelity.LUT_SAVED_SECONDS_PER_SAMPLE figures above times ``speed_factor`` (this machine
    against the one they were measured on, :func:`machine_speed`); or at
    ``seconds_per_evaluated_sample`` per evaluated sample when given (another machine).

    Parameters
    ----------
    samples : int
        (time, pixel) samples of the cube.
    evaluated : int
        Samples evaluated (:func:`evaluated_samples`).
    earthshine_method : str
        ``"lut"`` or ``"direct"``.
    skip : bool
        Whether unobservable samples are skipped (adds the screen's cost per sample).
    seconds_per_evaluated_sample : float, optional
        s per evaluated sample replacing the figures; None: the figures.
    speed_factor : float, optional
        This machine's time against the reference machine's (> 1: slower).

    Returns
    -------
    float
        Compute time on one core, s.
    """
    from straylight.model import LUT_SAVED_SECONDS_PER_SAMPLE

    if seconds_per_evaluated_sample is not None:
        return evaluated * seconds_per_evaluated_sample
    per_eval = CUBE_TABLE_SECONDS_PER_OBSERVABLE_SAMPLE if skip else CUBE_TABLE_SECONDS_PER_SAMPLE
    if earthshine_method == "direct":
        per_eval += LUT_SAVED_SECONDS_PER_SAMPLE
    return speed_factor * (evaluated * per_eval + (samples * CUBE_SCREEN_SECONDS_PER_SAMPLE if skip else 0.0))


def machine_speed(
    campaign: Campaign, fp: Footprint, n_times: int = 4, n_pixels: int = 1320, repeats: int = 2
) -> dict:
    """The speed of this machine against the reference machine of the cost figures (CUBE_*,
    fidelity.LUT_*, PIPELINE_*): ``n_times`` cube time steps spread over the
    campaign at ~``n_pixels`` footprint pixels spread over it (one step, or a few hundred
    pixels, weigh the per-step costs too much), on the direct earthshine sum, every sample
    evaluated, without stars (a small part of that path's cost), best of ``repeats`` after a full-size
    warm-up, against :func:`cube_compute_seconds` for it.  Returns the samples,
    ``measured_seconds``, ``assumed_seconds`` and ``factor`` (measured / assumed: below 1 on a
    faster machine).  One factor for every figure.

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign (its config is copied with the direct earthshine sum).
    fp : Footprint
        The survey footprint.
    n_times : int, optional
        Time steps timed, spread over the campaign.
    n_pixels : int, optional
        About this many footprint pixels timed, spread over the footprint.
    repeats : int, optional
        Timed repeats after the warm-up; the best is kept.

    Returns
    -------
    dict
        ``samples`` (int), ``measured_seconds`` and ``assumed_seconds`` (s), ``factor``
        (measured / assumed; 1.0 with no samples).
    """
    from straylight.config import campaign_from_dict, deep_merge
    from straylight.cube.region import compute_region
    from straylight.model import BackgroundModel

    direct = campaign_from_dict(
        deep_merge(
            campaign.config_mapping(),
            {"models": {"earthshine": {"method": "direct"}, "unobservable_samples": "evaluate"}},
        ),
        campaign.path,
    )
    model = BackgroundModel(direct)
    nt = len(direct.times)
    t_slice = slice(0, nt, max(1, nt // max(1, n_times)))
    p_slice = slice(0, None, max(1, int(fp.pixels.size) // max(1, n_pixels)))
    n = len(range(*t_slice.indices(nt))) * len(range(*p_slice.indices(int(fp.pixels.size))))
    if n == 0:  # no time or no pixel: nothing to time, the figures stand
        return {"samples": 0, "measured_seconds": 0.0, "assumed_seconds": 0.0, "factor": 1.0}
    # warm-up at full size: door tables, bands, and glibc's mmap threshold, which rises only after
    # the first large arrays are freed
    compute_region(direct, fp, t_slice, p_slice, model=model)
    best = np.inf
    for _ in range(max(1, repeats)):
        t0 = _time.perf_counter()
        compute_region(direct, fp, t_slice, p_slice, model=model)
        best = min(best, _time.perf_counter() - t0)
    assumed = cube_compute_seconds(n, n, "direct", False)
    return {"samples": n, "measured_seconds": best, "assumed_seconds": assumed, "factor": best / assumed}


def probed_speed_factor(campaign: Campaign, cores: int) -> float:
    """The time of this machine against the cost figures' now, on ``cores`` cores: the table build's
    probe (:func:`~straylight.sources.earthshine.sunlit_build.build_speed_factor`, a few of the
    sunlit table's scenes in ``cores`` threads, a few seconds, cached), which sees both the
    cores' speed and how much of them other processes leave free.

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign (its off-field model, Earth and orbit).
    cores : int
        Cores the run will use.

    Returns
    -------
    float
        Measured time over the figures' (> 1: slower).
    """
    from straylight.model import BackgroundModel
    from straylight.sources.earthshine.sunlit_build import build_speed_factor

    model = BackgroundModel(campaign)
    return build_speed_factor(
        model.earth_grid,
        campaign.earth.radius_km,
        campaign.orbit_radius_range_km,
        model.earthshine_choice["settings"],
        max(int(cores), 1),
    )


def needed_tables(model) -> list[dict]:
    """The look-up tables a campaign's model reads, each with ``name``, ``path`` and ``cached``
    (the assumption envelope's members' too: the cube re-evaluates the model at each); the
    sunlit table also with ``other_radii_km``: the orbit radii (km) of the sunlit tables cached
    for other settings or orbits (a changed orbit altitude needs its own table).

    Parameters
    ----------
    model : BackgroundModel
        The campaign's model (nothing is built).

    Returns
    -------
    list of dict
    """
    if model.earthshine_choice["method"] != "lut":
        return []
    from straylight.model import BackgroundModel
    from straylight.model.envelope import ENDS, end_campaign

    radii = _cached_sunlit_radii_km(model.table_paths()["sunlit"].parent)
    out = _model_tables(model, "", radii)
    env = model.campaign.instrument_settings.envelope
    if env is not None and env.members is not None:
        for end in ENDS:
            end_model = BackgroundModel(end_campaign(model.campaign, end))
            out += _model_tables(end_model, f" (the envelope's {end} member)", radii)
    return out


def _cached_sunlit_radii_km(folder) -> dict:
    """Each sunlit table cached in ``folder`` -> its mean orbit radius, km (read once: each file is
    tens of MB); unreadable files are left out."""
    radii = {}
    for p in sorted(folder.glob("earthshine_lut_*.npz")) if folder.is_dir() else []:
        try:
            with np.load(p) as z:
                radii[p] = float(np.mean(z["radius_km"]))
        except (OSError, EOFError, KeyError, ValueError):  # an unreadable cached table: not an altitude
            continue
    return radii


def _model_tables(model, label: str, radii_km: dict) -> list[dict]:
    """One model's sunlit and moonlit tables (:func:`needed_tables`), names ending in ``label``;
    ``radii_km``: the cached sunlit tables' orbit radii (:func:`_cached_sunlit_radii_km`)."""
    paths = model.table_paths()
    sunlit = paths["sunlit"]
    others = [r for p, r in radii_km.items() if p != sunlit]
    out = [
        {
            "name": "sunlit-Earth table" + label,
            "path": sunlit,
            "cached": sunlit.exists(),
            "other_radii_km": others,
        }
    ]
    moonlit = paths["moonlit"]
    if moonlit is not None:
        out.append({"name": "moonlit-Earth table" + label, "path": moonlit, "cached": moonlit.exists()})
    return out


def _table_builds(tables: list, choice: dict, speed_factor: float) -> tuple:
    """(seconds on one core to build the tables not cached, whether all are cached); each
    table's ``build_seconds`` set (s on one core) when the sunlit Earth takes the tables."""
    if choice["method"] != "lut":
        return 0.0, True
    # each model's sunlit table and moonlit one, each unless cached
    moonlit_s = choice["moonlit_build_seconds_estimate"]
    for t in tables:
        one = moonlit_s if t["name"].startswith("moonlit") else choice["build_seconds_estimate"] - moonlit_s
        t["build_seconds"] = speed_factor * one
    return sum(t["build_seconds"] for t in tables if not t["cached"]), all(t["cached"] for t in tables)


def _samples_seconds(
    counts: tuple, method: str, rate: tuple, seconds_per_evaluated_sample, speed_factor, cores
) -> float:
    """The samples' wall seconds on ``cores``: ``counts`` (samples, evaluated samples) at the
    pipeline's ``rate`` (samples/s/core, its source), plus on the direct sum (``method``) its
    extra per evaluated sample; ``seconds_per_evaluated_sample`` (s on one core) replaces both."""
    from straylight.model import LUT_SAVED_SECONDS_PER_SAMPLE

    n, n_eval = counts
    rate, rate_source = rate
    if seconds_per_evaluated_sample is not None:
        return n_eval * seconds_per_evaluated_sample / cores
    # a configured rate is already that machine's: not scaled again
    samples_s = (1.0 if rate_source.startswith("compute.") else speed_factor) * n / (rate * cores)
    if method == "direct":
        samples_s += speed_factor * n_eval * LUT_SAVED_SECONDS_PER_SAMPLE / cores
    return samples_s


def _pipeline_times(
    campaign: Campaign, fp: Footprint, counts: tuple, method: str, build_s: float, options
) -> dict:
    """:func:`estimated_cost`'s wall times on the cores (s) and core-hours: the fixed part, the
    samples (``counts``: samples, evaluated samples; ``method``: the sunlit Earth's), the
    tables' build (``build_s``, s on one core) and the faint-star map; ``options``: (s per
    evaluated sample or None, speed factor, cores)."""
    seconds_per_evaluated_sample, speed_factor, cores = options
    rate, rate_source = pipeline_rate(campaign)
    samples_s = _samples_seconds(
        counts, method, (rate, rate_source), seconds_per_evaluated_sample, speed_factor, cores
    )
    fixed_s = speed_factor * PIPELINE_FIXED_SECONDS
    faint = campaign.settings.stars.faint_map
    faint_s = speed_factor * FAINT_MAP_SECONDS_PER_PIXEL * int(fp.pixels.size) / cores if faint else 0.0
    wall_s = fixed_s + samples_s + build_s / cores
    return {
        "cores": cores,
        "pipeline_samples_per_s_per_core": rate,
        "pipeline_rate_source": rate_source,
        "fixed_seconds": fixed_s,
        "samples_seconds": samples_s,
        "wall_seconds": wall_s,
        "faint_map_first_seconds": faint_s,
        "pipeline_core_hours": wall_s * cores / 3600.0,
    }


def estimated_cost(
    campaign: Campaign,
    fp: Footprint,
    seconds_per_evaluated_sample: float | None = None,
    speed_factor: float = 1.0,
    cores: int = 2,
) -> dict:
    """What the campaign will cost before it runs, nothing built: its samples, the samples it
    evaluates (:func:`evaluated_samples`), the sunlit earthshine model that will run
    (SunlitEarth.choice), the tables' build when they are not cached yet (seconds on one core),
    the cube's compute alone (:func:`cube_compute_seconds`, seconds on one core), and the whole
    run wall to wall on ``cores`` cores: PIPELINE_FIXED_SECONDS, the samples at the pipeline's
    rate (:func:`pipeline_rate`; on the direct sum its extra per evaluated sample added;
    ``seconds_per_evaluated_sample`` replaces both), the build spread over the cores.  Every
    figure but the products' bytes is times ``speed_factor`` (this machine against the cost
    figures' reference machine, :func:`machine_speed`).

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign.
    fp : Footprint
        The survey footprint.
    seconds_per_evaluated_sample : float, optional
        s per evaluated sample on one core replacing the figures; None: the figures.
    speed_factor : float, optional
        This machine's time against the reference machine's (> 1: slower).
    cores : int, optional
        Cores the pipeline runs on (at least 1).

    Returns
    -------
    dict
        ``samples``, ``evaluated_samples`` (int); ``unobservable_samples`` (``"skip"`` or
        ``"evaluate"``); ``earthshine_method``, ``earthshine_reason`` (str); ``table_cached``
        (bool); ``tables`` (:func:`needed_tables`, each with its ``build_seconds`` on one
        core); ``table_build_seconds``, ``compute_seconds`` (s on one core); ``core_hours``
        (h); ``speed_factor``; ``cores``; ``pipeline_samples_per_s_per_core`` and
        ``pipeline_rate_source``; ``fixed_seconds``, ``samples_seconds``, ``wall_seconds``,
        ``faint_map_first_seconds`` (s, wall on ``cores``); ``pipeline_core_hours`` (h);
        ``product_bytes``, ``compact_bytes`` (bytes on disk: the products, the compact sky).
    """
    from straylight.model import BackgroundModel, unobservable_samples

    n = len(campaign.times) * int(fp.pixels.size)
    n_eval = evaluated_samples(campaign, fp)
    model = BackgroundModel(campaign)
    choice = model.earthshine_choice
    skip = unobservable_samples(campaign) == "skip"
    compute_s = cube_compute_seconds(
        n, n_eval, choice["method"], skip, seconds_per_evaluated_sample, speed_factor
    )
    tables = needed_tables(model)
    build_s, table_cached = _table_builds(tables, choice, speed_factor)
    options = (seconds_per_evaluated_sample, speed_factor, max(int(cores), 1))
    return {
        "samples": n,
        "evaluated_samples": n_eval,
        "unobservable_samples": "skip" if skip else "evaluate",
        "earthshine_method": choice["method"],
        "earthshine_reason": choice["reason"],
        "table_cached": table_cached,
        "tables": tables,
        "table_build_seconds": build_s,
        "compute_seconds": compute_s,
        "core_hours": (compute_s + build_s) / 3600.0,
        "speed_factor": speed_factor,
        **_pipeline_times(campaign, fp, (n, n_eval), choice["method"], build_s, options),
        "product_bytes": n * PRODUCT_BYTES_PER_SAMPLE,
        "compact_bytes": n * COMPACT_BYTES_PER_SAMPLE,
    }
