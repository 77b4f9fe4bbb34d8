"""Many targets over a time range (``straylight visibility --targets``), evaluated together.

Every target is sampled at the same times (:func:`~straylight.planning.visibility.time_grid`).
The samples of all targets go through the one evaluation path,
:func:`~straylight.planning.pointings.pointing_table` (and so
:func:`~straylight.model.pointing.background_at`): the satellite, the Sun, the Moon and the
planets are computed once per time and every target's line of sight is a sample indexed into
those scenes, so a sample's background and limit are those ``straylight visibility`` gives the
same target alone.  Per target come its observable windows and UTC days
(:func:`~straylight.planning.visibility.observable_windows`,
:func:`~straylight.planning.visibility.daily_tables`, computed for all targets at once), and one
summary table gives per target and UTC month the observable hours, the deepest 5-sigma limit
and its time, the hours deeper than a threshold and the background's 10th, 50th and 90th
percentiles over the observable samples.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = [
    "PERCENTILES",
    "BATCH_SAMPLES",
    "SampledWindow",
    "targets_visibility",
    "monthly_summary",
    "format_summary",
    "write_targets",
]

#: the background's percentiles in the summary (over a month's observable samples)
PERCENTILES = (10, 50, 90)
#: samples evaluated per vectorised call: bounds the evaluation's working memory (larger batches are
#: no faster; the peak is mostly the model and the columns kept for every sample)
BATCH_SAMPLES = 16384


@dataclass(frozen=True)
class SampledWindow:
    """A UTC window and its sampling step (:func:`~straylight.planning.visibility.time_grid`).

    Attributes
    ----------
    start, end : str or astropy.time.Time
        UTC times (ISO 8601 text or a scalar Time); ``end`` exclusive.
    step_s : float
        Sampling step, s.
    """

    start: object
    end: object
    step_s: float


def targets_visibility(
    campaign,
    targets,
    band: str,
    window: SampledWindow,
    threshold_mag: float | None = None,
    model=None,
    batch: int = BATCH_SAMPLES,
) -> dict:
    """Windows, days and the monthly summary of several targets sampled at the same times.

    Parameters
    ----------
    campaign : straylight.config.Campaign
        Loaded campaign (orbit, instrument, models).
    targets : straylight.planning.target_names.Targets
        The targets (names, file names, ICRS RA/Dec in deg).
    band : str
        One of the campaign's bands.
    window : SampledWindow
        The UTC start and end (exclusive) and the sampling step, s.
    threshold_mag : float, optional
        Limit, AB mag: days and months get the observable hours with a limit at least this deep.
    model : BackgroundModel, optional
        The campaign's warm model; None: one is built.
    batch : int, optional
        Samples per vectorised evaluation.

    Returns
    -------
    dict
        ``targets`` (as given); ``time`` (astropy Time, shape (n,)); ``observable`` (bool),
        ``total_e_per_s_per_pix`` (e-/s/pix) and ``limit_mag`` (5-sigma, AB mag), each an
        ndarray of shape (m, n); ``windows`` and ``days``: lists of m QTables as
        :func:`~straylight.planning.visibility.visibility` gives them for one target;
        ``summary``: the :func:`monthly_summary` QTable; ``band``, ``step_s`` (s),
        ``threshold_mag``; ``models``: the record of the models that ran; ``seconds``: the
        background evaluation's ``evaluation_wall_s`` and ``evaluation_cpu_s`` (this process's
        CPU seconds, every thread), s.

    Raises
    ------
    InputError
        As :func:`~straylight.planning.visibility.time_grid`.
    """
    from straylight.model import BackgroundModel
    from straylight.planning.visibility import daily_tables, observable_windows, time_grid

    t0, t, offset_s = time_grid(campaign, band, window.start, window.end, window.step_s)
    # the model built (or its tables read) outside the evaluation's timing
    model = BackgroundModel(campaign) if model is None else model
    obs, total, lim, models, seconds = _evaluate_targets(campaign, targets, band, t, model, batch)
    return {
        "targets": targets,
        "time": t,
        "observable": obs,
        "total_e_per_s_per_pix": total,
        "limit_mag": lim,
        "windows": observable_windows(obs, t, t0, offset_s),
        "days": daily_tables(obs, lim, t, offset_s, threshold_mag),
        "summary": monthly_summary(targets, band, obs, lim, total, t, offset_s, threshold_mag),
        "band": band,
        "step_s": float(window.step_s),
        "threshold_mag": threshold_mag,
        "models": models,
        "seconds": seconds,
    }


def _evaluate_targets(campaign, targets, band: str, t, model, batch: int):
    """Every target at every time ``t`` through the one evaluation path, timed: observable
    (bool), the band's total background (e-/s/pix) and 5-sigma limit (AB mag), each (m, n);
    the record of the models that ran; the evaluation's wall and CPU seconds."""
    from astropy.time import Time

    from straylight.planning.pointings import pointing_table

    m, n = len(targets), len(t)
    w0, c0 = time.perf_counter(), time.process_time()
    # target-major flat samples: target k's time i is sample k * n + i
    times = Time(np.tile(t.jd1, m), np.tile(t.jd2, m), format="jd", scale="utc")
    models: dict = {}
    cols = pointing_table(
        campaign,
        {
            "time": times,
            "ra": np.repeat(np.asarray(targets.ra_deg, float) % 360.0, n),
            "dec": np.repeat(np.asarray(targets.dec_deg, float), n),
        },
        [band],
        None,
        batch=batch,
        source="--targets",
        models=models,
        model=model,
    )
    seconds = {"evaluation_wall_s": time.perf_counter() - w0, "evaluation_cpu_s": time.process_time() - c0}
    obs = np.asarray(cols["observable"], bool).reshape(m, n)
    total = np.asarray(cols[f"total_{band}"], float).reshape(m, n)
    lim = np.asarray(cols[f"limit_mag_{band}"], float).reshape(m, n)
    return obs, total, lim, models, seconds


def monthly_summary(targets, band, obs, lim, total, t, offset_s, threshold_mag=None):
    """Per target and UTC month: observable hours, the deepest limit and its time, the hours
    deeper than the threshold, and the background's :data:`PERCENTILES` over the observable
    samples.

    Parameters
    ----------
    targets : straylight.planning.target_names.Targets
        The m targets.
    band : str
        The band evaluated.
    obs : ndarray of bool, shape (m, n)
        Observability.
    lim : ndarray of float, shape (m, n)
        5-sigma limits, AB mag.
    total : ndarray of float, shape (m, n)
        The band's total background, e-/s/pix.
    t : astropy.time.Time, shape (n,)
        The samples' times.
    offset_s : ndarray, shape (n + 1,)
        The samples' edges, s (:func:`~straylight.planning.visibility.time_grid`).
    threshold_mag : float, optional
        Limit, AB mag; None: no threshold columns.

    Returns
    -------
    astropy.table.QTable
        One row per target and month (targets in order, then months): ``target``, ``ra_deg``,
        ``dec_deg`` (deg), ``band``, ``month_utc`` (YYYY-MM), ``samples`` and
        ``observable_samples`` (counts), ``observable_hours_h`` (h), ``limit_best_mag_ab``
        (AB mag) and ``limit_best_time_utc`` (ISO, "" and NaN in a month never observable),
        with a threshold ``threshold_mag_ab`` and ``hours_deeper_than_threshold_h`` (h), and
        ``background_p<q>_e_per_s_per_pix`` (e-/s/pix, the band's total; NaN in a month never
        observable).
    """
    import astropy.units as u
    from astropy.table import QTable

    from straylight.planning.visibility import period_starts, period_sums

    iso = np.array(t.isot)
    months, starts = period_starts(np.array([s[:7] for s in iso]))
    ends = np.append(starts[1:], iso.size)
    m, p = obs.shape[0], months.size
    sums = period_sums(obs, lim, np.diff(offset_s) / 3600.0, starts, threshold_mag)
    n_obs, best_time, pct = _monthly_samples(obs, lim, total, iso, starts, ends)
    columns = {
        "target": np.repeat(np.asarray(targets.names, dtype=str), p),
        "ra_deg": np.repeat(np.asarray(targets.ra_deg, float), p) * u.deg,
        "dec_deg": np.repeat(np.asarray(targets.dec_deg, float), p) * u.deg,
        "band": np.full(m * p, band),
        "month_utc": np.tile(months, m),
        "samples": np.tile(ends - starts, m),
        "observable_samples": n_obs.ravel(),
        "observable_hours_h": sums["observable_hours"].ravel() * u.h,
        "limit_best_mag_ab": sums["limit_mag_best"].ravel() * u.mag,
        "limit_best_time_utc": best_time.ravel().astype(str),
    }
    if threshold_mag is not None:
        columns["threshold_mag_ab"] = np.full(m * p, float(threshold_mag)) * u.mag
        columns["hours_deeper_than_threshold_h"] = sums["hours_deeper_than_threshold"].ravel() * u.h
    rate = u.electron / (u.s * u.pix)
    for q, v in zip(PERCENTILES, pct):
        columns[f"background_p{q}_e_per_s_per_pix"] = v.ravel() * rate
    out = QTable(columns)
    _set_summary_formats(out)
    out.meta = {"band": band, "threshold_mag": threshold_mag, "percentiles": list(PERCENTILES)}
    return out


def _monthly_samples(obs, lim, total, iso, starts, ends):
    """Per target and month (samples ``starts[j]`` to ``ends[j]``): the observable samples
    (count), the deepest limit's UTC time (ISO to the second, "" when none) and the total
    background's :data:`PERCENTILES` over the observable samples (e-/s/pix, NaN when none)."""
    m, p = obs.shape[0], len(starts)
    best_time = np.full((m, p), "", dtype=object)
    pct = np.full((len(PERCENTILES), m, p), np.nan)
    n_obs = np.zeros((m, p), np.int64)
    for j, (a, b) in enumerate(zip(starts, ends)):
        o = obs[:, a:b]
        n_obs[:, j] = o.sum(axis=1)
        k = np.argmax(np.where(o, lim[:, a:b], -np.inf), axis=1)
        seen = n_obs[:, j] > 0
        best_time[seen, j] = [s[:19] for s in iso[a + k[seen]]]
        with warnings.catch_warnings():  # a target never observable in the month: NaN, no warning
            warnings.simplefilter("ignore", RuntimeWarning)
            pct[:, :, j] = np.nanpercentile(np.where(o, total[:, a:b], np.nan), PERCENTILES, axis=1)
    return n_obs, best_time, pct


def _set_summary_formats(out) -> None:
    """The summary's display formats: positions to 1e-5 deg, hours to 0.01 h, limits to 1e-3
    mag, backgrounds to 4 significant digits."""
    for name, f in (
        ("ra_deg", ".5f"),
        ("dec_deg", ".5f"),
        ("observable_hours_h", ".2f"),
        ("limit_best_mag_ab", ".3f"),
        ("hours_deeper_than_threshold_h", ".2f"),
        *((f"background_p{q}_e_per_s_per_pix", ".4g") for q in PERCENTILES),
    ):
        if name in out.colnames:
            out[name].info.format = f


def format_summary(summary) -> str:
    """The summary as fixed-width text, one line per target and month, units in the header.

    Parameters
    ----------
    summary : astropy.table.QTable
        A :func:`monthly_summary` table.

    Returns
    -------
    str
        The lines, without a final newline.
    """
    thr = "hours_deeper_than_threshold_h" in summary.colnames
    width = max(6, *(len(str(s)) for s in summary["target"]))
    band = summary.meta.get("band", "")
    head = (
        f"{'target':{width}s} {'month':7s} {'obs h':>7s} {'best lim':>8s} {'best lim at (UTC)':19s}"
        + (f" {'h >=' + format(summary.meta['threshold_mag'], '.2f'):>9s}" if thr else "")
        + "".join(f" {'bkg p' + str(q):>9s}" for q in PERCENTILES)
    )
    unit = (
        f"{'':{width}s} {'(UTC)':7s} {'(h)':>7s} {'(AB mag)':>8s} {'':19s}"
        + (f" {'(h, lim)':>9s}" if thr else "")
        + f"  (total background, band {band}, e-/s/pix)"
    )
    lines = [head, unit]
    for r in summary:
        best = r["limit_best_mag_ab"].value
        line = (
            f"{r['target']:{width}s} {r['month_utc']:7s} {r['observable_hours_h'].value:7.2f} "
            + (f"{best:8.3f}" if np.isfinite(best) else f"{'-':>8s}")
            + f" {r['limit_best_time_utc'] or '-':19s}"
            + (f" {r['hours_deeper_than_threshold_h'].value:9.2f}" if thr else "")
            + "".join(
                f" {v:9.4g}"
                if np.isfinite(v := r[f"background_p{q}_e_per_s_per_pix"].value)
                else f" {'-':>9s}"
                for q in PERCENTILES
            )
        )
        lines.append(line)
    return "\n".join(lines)


def write_targets(result: dict, out_dir) -> list[Path]:
    """Write the summary, the resolved target list and each target's windows and days as CSV.

    Parameters
    ----------
    result : dict
        A :func:`targets_visibility` result.
    out_dir : str or path-like
        The output folder (existing).

    Returns
    -------
    list of Path
        ``summary.csv`` (:func:`monthly_summary`), ``targets.csv`` (name, file stem, RA and
        Dec in deg, where the position comes from) and per target ``<name>_windows.csv`` and
        ``<name>_days.csv`` (the name sanitized), the same text ``straylight visibility --out``
        writes for one target.
    """
    from astropy.table import Table

    from straylight.util.io import atomic_path

    out = Path(out_dir)
    tg = result["targets"]
    written = []

    def put(table, name):
        path = out / name
        with atomic_path(path) as tmp:
            if isinstance(table, Table):
                table.write(tmp, format="ascii.csv", overwrite=True)
            else:
                tmp.write_text(table, encoding="utf-8")
        written.append(path)

    put(result["summary"], "summary.csv")
    put(
        Table(
            {
                "name": tg.names,
                "file": tg.files,
                "ra_deg": np.round(tg.ra_deg, 7),
                "dec_deg": np.round(tg.dec_deg, 7),
                "position_source": tg.source,
            }
        ),
        "targets.csv",
    )
    for f, w, d in zip(tg.files, result["windows"], result["days"]):
        put(_csv_text(w), f"{f}_windows.csv")
        put(_csv_text(d), f"{f}_days.csv")
    return written


def _csv_text(table) -> str:
    """A windows or days table as the CSV astropy writes for it (its Time columns as ISO text,
    its numbers in their display formats), each column formatted in one vectorised pass: astropy
    formats a Time value at a time, slow for the thousands of windows of a year."""
    from astropy.time import Time

    cols = []
    for name in table.colnames:
        c = table[name]
        if isinstance(c, Time):
            cols.append(np.asarray(c.isot, dtype=str))
        elif getattr(c.info, "format", None):
            v = np.asarray(getattr(c, "value", c), float)
            cols.append(np.char.mod(f"%{c.info.format}", v))
        else:
            cols.append(np.asarray(c, dtype=str))
    lines = [",".join(table.colnames)]
    lines += [",".join(row) for row in zip(*cols)]
    return "\n".join(lines) + "\n"
