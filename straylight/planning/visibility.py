"""A target's visibility over a time range (``straylight visibility``), for planners.

For one ICRS pointing and one band: the background (e-/s/pixel and AB mag/arcsec2) and the
5-sigma point-source limit sampled every ``step`` over ``[start, end)``, through the same
vectorised per-pointing path as ``straylight sky --input`` and :func:`straylight.sky_background`;
the observable windows (runs of observable samples; times resolved to ``step``, cut at ``end``);
and per UTC day the observable time, the deepest limit, and the time the limit is deeper than a
threshold.  Observability changes within an orbit (the Earth occults the target and its limbs
pass by every ~92 min), so a step longer than :data:`MAX_STEP_ORBIT_FRACTION` of the orbital
period is warned about: windows can fall between its samples, and near a multiple of the period
every sample sees the same orbital phase (aliasing).
"""

from __future__ import annotations

import logging

import numpy as np

from straylight.errors import InputError

__all__ = [
    "MAX_SAMPLES",
    "MAX_STEP_ORBIT_FRACTION",
    "ALIAS_TOLERANCE",
    "visibility",
    "time_grid",
    "sampled_window",
    "observable_windows",
    "period_starts",
    "period_sums",
    "daily_tables",
    "warn_if_step_aliases",
    "plot_visibility",
]

#: more samples than this are refused (a year at 1 min is 525,960): ask for a coarser --step
MAX_SAMPLES = 600_000
#: steps longer than this fraction of the orbital period are warned about: an observable window
#: lasts a fraction of an orbit (between Earth occultations; ~35 min of the 92-min orbit for a
#: target away from the orbit's pole, less near the constraints), so a quarter-orbit step gives
#: such a window at least one sample
MAX_STEP_ORBIT_FRACTION = 0.25
#: a step within this fraction of a whole number of orbital periods is named as aliasing
ALIAS_TOLERANCE = 0.03


def visibility(
    campaign,
    ra_deg: float,
    dec_deg: float,
    band: str,
    start,
    end,
    step_s: float,
    threshold_mag: float | None = None,
) -> dict:
    """Samples, observable windows and daily summary of one pointing.

    Parameters
    ----------
    campaign : straylight.config.Campaign
        Loaded campaign (orbit, instrument, models).
    ra_deg, dec_deg : float
        ICRS pointing, deg (Dec within [-90, 90]), already checked.
    band : str
        One of the campaign's bands (not ``"V"``: it has no limit).
    start, end : str or astropy.time.Time
        UTC times (ISO 8601 text or a scalar Time); ``end`` exclusive; both within DE405.
    step_s : float
        Sampling step, s (> 0, at most ``end - start``); window edges are known to this
        resolution.  A step over :data:`MAX_STEP_ORBIT_FRACTION` of the orbit is warned about.
    threshold_mag : float, optional
        Limit, AB mag; if given, days list the observable hours with a limit at least this deep.
        None: no such column.

    Returns
    -------
    dict of str to astropy.table.QTable
        ``samples``: n rows (n = ceil((end - start) / step)) with ``time`` (UTC),
        ``observable`` (bool), ``violations`` (str), ``total_e_per_s_per_pix`` (e-/s/pix),
        ``total_mag_per_arcsec2`` (AB mag/arcsec2) and ``limit_mag`` (5-sigma, AB mag); its
        ``meta`` holds the pointing, band, step (s) and zero point.  ``windows``: one row per
        run of observable samples, ``start``, ``end`` (UTC) and ``duration_h`` (h).  ``days``:
        one row per UTC date, ``date`` (YYYY-MM-DD), ``observable_hours`` (h),
        ``limit_mag_best`` (AB mag, NaN on a day never observable) and, with a threshold,
        ``hours_deeper_than_threshold`` (h).

    Raises
    ------
    InputError
        Unparsable, out-of-ephemeris or reversed times, a non-positive step or one longer than
        the window, more than :data:`MAX_SAMPLES` samples, an unknown band.
    """
    from astropy.table import QTable

    from straylight.model.result import violation_text
    from straylight.planning.pointings import background_table

    t0, t, offset_s = time_grid(campaign, band, start, end, step_s)
    n = len(t)
    sky = background_table(campaign, t, np.full(n, ra_deg), np.full(n, dec_deg), [band])
    samples = QTable(
        {
            "time": sky["time"],
            "observable": sky["observable"],
            "violations": violation_text(sky["violations"]),
            "total_e_per_s_per_pix": sky[f"total_{band}"],
            "total_mag_per_arcsec2": sky[f"total_mag_{band}"],
            "limit_mag": sky[f"limit_mag_{band}"],
        },
        meta={
            "ra_deg": float(ra_deg),
            "dec_deg": float(dec_deg),
            "band": band,
            "step_s": float(step_s),
            "mag_zero_point": sky.meta["mag_zero_point"][band],
        },
    )
    obs = np.asarray(samples["observable"], bool)[None, :]
    lim = np.asarray(samples["limit_mag"].value, float)[None, :]
    windows = observable_windows(obs, t, t0, offset_s)[0]
    days = daily_tables(obs, lim, t, offset_s, threshold_mag)[0]
    return {"samples": samples, "windows": windows, "days": days}


def time_grid(campaign, band: str, start, end, step_s: float, warn: bool = True):
    """The sampling times of :func:`visibility` over ``[start, end)``, every ``step_s``, with its
    checks (each refusal one line naming the option).

    Parameters
    ----------
    campaign : straylight.config.Campaign
        Loaded campaign (its bands and orbital period).
    band : str
        One of the campaign's bands.
    start, end : str or astropy.time.Time
        UTC times (ISO 8601 text or a scalar Time); ``end`` exclusive; both within DE405.
    step_s : float
        Sampling step, s.
    warn : bool, optional
        Log :func:`warn_if_step_aliases`' warning (False: a check made again later).

    Returns
    -------
    t0 : astropy.time.Time
        The start, UTC (scalar).
    t : astropy.time.Time, shape (n,)
        The samples' times, ``t0 + i * step``.
    offset_s : ndarray, shape (n + 1,)
        Each sample's start and the last one's end after ``t0``, s: sample i stands for
        ``[offset_s[i], offset_s[i + 1])``, the last one cut at ``end``.

    Raises
    ------
    InputError
        Unparsable, out-of-ephemeris or reversed times, a non-positive step or one longer than
        the window, more than :data:`MAX_SAMPLES` samples, an unknown band.
    """
    if band not in campaign.bands:
        raise InputError(f"--band: {band!r} is not one of {', '.join(campaign.bands)}")
    period_s = float(campaign.orbit.period_s) if warn else None
    return sampled_window(start, end, step_s, period_s)


def sampled_window(start, end, step_s: float, period_s: float | None, start_field: str = "--start"):
    """Times every ``step_s`` from ``start`` to ``end`` (exclusive), checked as a user's window.

    Parameters
    ----------
    start, end : str or astropy.time.Time
        UTC times (ISO 8601 text or a scalar Time); ``end`` exclusive; both within DE405.
    step_s : float
        Sampling step, s (> 0, at most ``end - start``).
    period_s : float or None
        The orbit's period, s: a step over a quarter of it is warned about
        (:func:`warn_if_step_aliases`); None: no warning.
    start_field : str, optional
        The option that gave ``start``, for the messages.

    Returns
    -------
    t0 : astropy.time.Time
        The start, UTC (scalar).
    t : astropy.time.Time, shape (n,)
        ``t0 + i * step``, n = ceil((end - start) / step).
    offset_s : ndarray, shape (n + 1,)
        Each sample's start and the last one's end after ``t0``, s (the last one cut at ``end``).

    Raises
    ------
    InputError
        Unparsable, out-of-ephemeris or reversed times, a non-positive step or one longer than
        the window, more than :data:`MAX_SAMPLES` samples.
    """
    import astropy.units as u

    from straylight.sky.ephemeris import check_in_ephemeris
    from straylight.sky.timeutil import parse_utc

    t0, t1 = parse_utc(start, start_field), parse_utc(end, "--end")
    check_in_ephemeris(t0, start_field, start if isinstance(start, str) else None)
    check_in_ephemeris(t1, "--end", end if isinstance(end, str) else None)
    if not t1 > t0:
        raise InputError(f"--end {t1.isot} must be after {start_field} {t0.isot}")
    if not (np.isfinite(step_s) and step_s > 0):
        raise InputError(f"--step-min: must be > 0, got {step_s / 60.0:g}")
    span_s = float((t1 - t0).to_value(u.s))
    if step_s > span_s:
        raise InputError(
            f"--step-min {step_s / 60.0:g}: longer than the window {start_field} {t0.isot[:19]} to --end "
            f"{t1.isot[:19]} ({span_s / 60.0:g} min); use a step of at most that"
        )
    if period_s is not None:
        warn_if_step_aliases(step_s, period_s)
    n = int(np.ceil(span_s / step_s - 1e-9))
    if n > MAX_SAMPLES:
        raise InputError(
            f"{start_field}/--end/--step-min: {n:,} samples, more than {MAX_SAMPLES:,}; "
            "use a larger --step-min"
        )
    t = t0 + np.arange(n) * step_s * u.s
    return t0, t, np.minimum(np.arange(n + 1) * step_s, span_s)


def observable_windows(obs, t, t0, offset_s) -> list:
    """The observable windows of several pointings sampled at the same times: the runs of
    observable samples, each sample standing for ``[offset_s[i], offset_s[i + 1])``.

    Parameters
    ----------
    obs : ndarray of bool, shape (m, n)
        Each pointing's observability at the n samples.
    t : astropy.time.Time, shape (n,)
        The samples' times (:func:`time_grid`).
    t0 : astropy.time.Time
        The start (scalar).
    offset_s : ndarray, shape (n + 1,)
        The samples' edges after ``t0``, s (:func:`time_grid`).

    Returns
    -------
    list of astropy.table.QTable
        Per pointing, one row per window: ``start``, ``end`` (UTC, to the second) and
        ``duration_h`` (h).
    """
    import astropy.units as u
    from astropy.table import QTable
    from astropy.time import Time

    obs = np.asarray(obs, bool)
    pad = np.zeros((obs.shape[0], 1), np.int8)
    edges = np.diff(np.concatenate([pad, obs.astype(np.int8), pad], axis=1), axis=1)
    # row-major: by pointing, then in time; every run has one rise and one fall
    k_rise, first = np.nonzero(edges == 1)
    last = np.nonzero(edges == -1)[1]
    empty = Time([], format="isot", scale="utc")
    starts = Time(t[first], format="isot", precision=0) if first.size else empty
    ends = Time(t0 + offset_s[last] * u.s, format="isot", precision=0) if last.size else empty
    hours = (offset_s[last] - offset_s[first]) / 3600.0
    bounds = np.searchsorted(k_rise, np.arange(obs.shape[0] + 1))
    out = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        w = QTable({"start": starts[a:b], "end": ends[a:b], "duration_h": hours[a:b] * u.h})
        w["duration_h"].info.format = ".2f"
        out.append(w)
    return out


def period_starts(labels) -> tuple[np.ndarray, np.ndarray]:
    """(the distinct labels in order, the index where each begins) of time-ordered labels, such
    as each sample's UTC date: a period's samples are contiguous.

    Parameters
    ----------
    labels : array_like of str, shape (n,)
        One label per sample, equal labels adjacent.

    Returns
    -------
    names : ndarray of str, shape (p,)
        The periods' labels.
    starts : ndarray of int, shape (p,)
        The index of each period's first sample.
    """
    labels = np.asarray(labels)
    new = np.ones(labels.size, bool)
    new[1:] = labels[1:] != labels[:-1]
    starts = np.flatnonzero(new)
    return labels[starts], starts


def period_sums(obs, lim, sample_h, starts, threshold_mag: float | None = None) -> dict:
    """Per pointing and period: observable hours, the deepest limit and, with a threshold, the
    observable hours with a limit at least that deep.

    Parameters
    ----------
    obs : ndarray of bool, shape (m, n)
        Observability of m pointings at n samples.
    lim : ndarray of float, shape (m, n)
        5-sigma limits, AB mag.
    sample_h : ndarray, shape (n,)
        Each sample's duration, h.
    starts : ndarray of int, shape (p,)
        Each period's first sample (:func:`period_starts`).
    threshold_mag : float, optional
        Limit, AB mag.

    Returns
    -------
    dict of str to ndarray, each shape (m, p)
        ``observable_hours`` (h), ``limit_mag_best`` (AB mag; NaN for a period never
        observable) and, with a threshold, ``hours_deeper_than_threshold`` (h).
    """
    obs = np.asarray(obs, bool)
    out = {"observable_hours": np.add.reduceat(obs * sample_h, starts, axis=1)}
    best = np.maximum.reduceat(np.where(obs, lim, -np.inf), starts, axis=1)
    out["limit_mag_best"] = np.where(best == -np.inf, np.nan, best)
    if threshold_mag is not None:
        deep = obs & (lim >= threshold_mag)
        out["hours_deeper_than_threshold"] = np.add.reduceat(deep * sample_h, starts, axis=1)
    return out


def daily_tables(obs, lim, t, offset_s, threshold_mag: float | None = None) -> list:
    """Per pointing, the UTC days of :func:`visibility`: observable hours, the deepest limit and,
    with a threshold, the hours deeper than it.

    Parameters
    ----------
    obs : ndarray of bool, shape (m, n)
        Observability of m pointings at the n samples.
    lim : ndarray of float, shape (m, n)
        5-sigma limits, AB mag.
    t : astropy.time.Time, shape (n,)
        The samples' times (:func:`time_grid`).
    offset_s : ndarray, shape (n + 1,)
        The samples' edges, s (:func:`time_grid`).
    threshold_mag : float, optional
        Limit, AB mag; None: no such column.

    Returns
    -------
    list of astropy.table.QTable
        Per pointing, one row per UTC date: ``date`` (YYYY-MM-DD), ``observable_hours`` (h),
        ``limit_mag_best`` (AB mag, NaN on a day never observable) and, with a threshold,
        ``hours_deeper_than_threshold`` (h; the threshold in ``meta``).
    """
    import astropy.units as u
    from astropy.table import QTable

    dates, starts = period_starts(np.array([s[:10] for s in t.isot]))
    sums = period_sums(obs, lim, np.diff(offset_s) / 3600.0, starts, threshold_mag)
    out = []
    for k in range(np.shape(obs)[0]):
        days = QTable(
            {
                "date": dates,
                "observable_hours": sums["observable_hours"][k] * u.h,
                "limit_mag_best": sums["limit_mag_best"][k] * u.mag,
            }
        )
        days["observable_hours"].info.format = ".2f"
        days["limit_mag_best"].info.format = ".3f"
        if threshold_mag is not None:
            days["hours_deeper_than_threshold"] = sums["hours_deeper_than_threshold"][k] * u.h
            days["hours_deeper_than_threshold"].info.format = ".2f"
            days.meta["threshold_mag"] = float(threshold_mag)
        out.append(days)
    return out


def warn_if_step_aliases(step_s: float, period_s: float) -> str | None:
    """Warn (one logged line) when the step is longer than :data:`MAX_STEP_ORBIT_FRACTION` of the
    orbital period, naming aliasing when it is within :data:`ALIAS_TOLERANCE` of a whole number of
    periods; returns the warning.  A warning, not a refusal: a coarse look over months is a fair
    request, as long as the user knows windows are missed.

    Parameters
    ----------
    step_s : float
        Sampling step, s.
    period_s : float
        Orbital period, s.

    Returns
    -------
    str or None
        The warning logged, or None when the step is short enough.
    """
    quarter_min = MAX_STEP_ORBIT_FRACTION * period_s / 60.0
    if step_s <= MAX_STEP_ORBIT_FRACTION * period_s:
        return None
    k = max(1, int(round(step_s / period_s)))
    off = abs(step_s / (k * period_s) - 1.0)
    head = f"--step-min {step_s / 60.0:g}: "
    if off <= ALIAS_TOLERANCE:
        msg = (
            f"{head}within {100 * off:.1f} % of {k} x the orbital period ({period_s / 60.0:.1f} min): "
            "every sample sees nearly the same orbital phase (aliasing), so observability looks constant "
            f"and windows are missed; use --step-min {quarter_min:.1f} or less"
        )
    else:
        msg = (
            f"{head}longer than a quarter of the orbital period ({period_s / 60.0:.1f} min): observability "
            f"changes within an orbit and windows can fall between samples; use --step-min {quarter_min:.1f} "
            "or less"
        )
    logging.getLogger(__name__).warning("warning: %s", msg)
    return msg


def plot_visibility(result: dict, path, threshold_mag: float | None = None) -> None:
    """Background (AB mag/arcsec2) and 5-sigma limit (AB mag) against time, observable samples
    in colour, the others grey, the windows shaded, the threshold dashed.

    Parameters
    ----------
    result : dict
        A :func:`visibility` result (its ``samples`` and ``windows``).
    path : str or path-like
        Image to write; the suffix (e.g. ``.png``, ``.pdf``) picks the format.
    threshold_mag : float, optional
        Limit drawn as a dashed line, AB mag; None: none drawn.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from straylight.util.io import atomic_path

    s = result["samples"]
    t = s["time"].datetime64
    obs = np.asarray(s["observable"], bool)
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(9, 5.5), constrained_layout=True)
    for ax, col, label in (
        (ax1, "total_mag_per_arcsec2", "sky + stray light (AB mag/arcsec$^2$)"),
        (ax2, "limit_mag", "5-sigma limit (AB mag)"),
    ):
        y = np.asarray(s[col].value, float)
        ax.plot(t[~obs], y[~obs], ".", ms=2, color="0.7", label="not observable")
        ax.plot(t[obs], y[obs], ".", ms=2, color="C0", label="observable")
        for w in result["windows"]:
            ax.axvspan(w["start"].datetime64, w["end"].datetime64, color="C2", alpha=0.12, lw=0)
        if obs.any():  # the observable samples set the range; Earth-occulted ones are far off it
            lo, hi = np.nanmin(y[obs]), np.nanmax(y[obs])
            pad = max(0.25, 0.15 * (hi - lo))
            ax.set_ylim(lo - pad, hi + pad)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    if threshold_mag is not None:
        ax2.axhline(threshold_mag, ls="--", color="C3", label=f"threshold {threshold_mag:.2f} mag")
    ax2.legend(loc="lower right", fontsize=8, markerscale=4)
    ax2.set_xlabel("time (UTC)")
    m = s.meta
    ax1.set_title(
        f"RA {m['ra_deg']:.3f} deg, Dec {m['dec_deg']:+.3f} deg, band {m['band']} "
        f"(step {m['step_s'] / 60:.3g} min; shaded: observable windows)",
        fontsize=10,
    )
    fig.autofmt_xdate()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format=str(path).rsplit(".", 1)[-1])
    plt.close(fig)
