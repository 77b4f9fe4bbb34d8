"""Exposure-time calculator: the time a point source needs to reach a signal-to-noise ratio, and
the ratio a time reaches, at the background of a time and pointing.

The noise model is the 5-sigma limits' own (:mod:`straylight.limits.point_source`): in the EE80
aperture (N_pix pixels), a source of AB magnitude m gives S = 0.8 F(m) electrons per second
(:func:`~straylight.limits.point_source.source_rate_e_per_s`), and over a total time t

    SNR = S t / sqrt(S t + N_b(t)),   N_b(t) = N_pix (B t + D t + n RN^2)

(:func:`~straylight.limits.point_source.aperture_noise_e2`), with B the total background at that time
and pointing (e-/s/pix, :meth:`straylight.SkyModel.background`), D the dark current, RN the read
noise and n the number of exposures t is split into: the band's survey count (2 x 150 s; NUV
and y 4 x 150 s) unless another is given, the read noise counted once per exposure.  Solving
for t gives the exposure time: with N_b(t) = r t + c,

    t = [SNR^2 (S + r) + sqrt(SNR^4 (S + r)^2 + 4 S^2 SNR^2 c)] / (2 S^2),

so that SNR 5 at the limiting magnitude of the survey's exposures gives back their total time.
"""

from __future__ import annotations

import math

import numpy as np

from straylight.errors import InputError

__all__ = [
    "MODES",
    "checked_bands",
    "checked_request",
    "magnitude_warnings",
    "etc_summary",
    "etc_table",
    "snr_for_time",
    "time_for_snr",
    "time_grid",
]

#: the two questions: the time for a given SNR, or the SNR for a given time
MODES = ("exposure_time", "snr")

#: Mean source electrons per pixel of the EE80 aperture in one survey exposure above which the
#: source is warned about: the order of a CCD's full well (~1e5 e- for 10-um pixels; the peak
#: pixel holds more than the mean).  The noise model has no saturation: a warning threshold,
#: not a model parameter.
BRIGHT_E_PER_PIXEL = 1e5
#: Total exposure times above which the time is warned about as out of reach: a day, longer
#: than any visit (the observable windows last less than an orbit).  A warning threshold.
LONG_EXPOSURE_S = 86400.0


def snr_for_time(mag_ab, exposure_s, background_e_per_s_per_pix, x, n_exposures=None) -> np.ndarray:
    """Signal-to-noise ratio of a point source in the EE80 aperture after a total time.

    Parameters
    ----------
    mag_ab : array_like of float
        Source AB magnitude.
    exposure_s : array_like of float
        Total exposure time t, s, split into ``n_exposures`` exposures.
    background_e_per_s_per_pix : array_like of float
        Total background B, e-/s/pix.
    x : straylight.limits.point_source.SurveyExposure
        The band's aperture, detector noise and zero point.
    n_exposures : int, optional
        Exposures t is split into (read noise once each); None: the band's survey count.

    Returns
    -------
    ndarray of float, broadcast shape of the inputs
        SNR (dimensionless).
    """
    from straylight.limits.point_source import aperture_noise_e2, source_rate_e_per_s

    t = np.asarray(exposure_s, dtype=float)
    signal_e = source_rate_e_per_s(mag_ab, x) * t
    return signal_e / np.sqrt(signal_e + aperture_noise_e2(background_e_per_s_per_pix, t, x, n_exposures))


def time_for_snr(mag_ab, snr, background_e_per_s_per_pix, x, n_exposures=None) -> np.ndarray:
    """Total exposure time a point source needs to reach ``snr`` in the EE80 aperture (the
    positive root of the CCD equation, see the module's notes).

    Parameters
    ----------
    mag_ab : array_like of float
        Source AB magnitude.
    snr : array_like of float
        Signal-to-noise ratio to reach (> 0).
    background_e_per_s_per_pix : array_like of float
        Total background B, e-/s/pix.
    x : straylight.limits.point_source.SurveyExposure
        The band's aperture, detector noise and zero point.
    n_exposures : int, optional
        Exposures the time is split into (read noise once each); None: the band's survey count.

    Returns
    -------
    ndarray of float, broadcast shape of the inputs
        Total exposure time t, s (all exposures together).
    """
    from straylight.limits.point_source import aperture_noise_e2, source_rate_e_per_s

    s = source_rate_e_per_s(mag_ab, x)
    q2 = np.asarray(snr, dtype=float) ** 2
    # N_b(t) is linear in t: c its read-noise part, r its rate (background and dark)
    c = aperture_noise_e2(background_e_per_s_per_pix, 0.0, x, n_exposures)
    r = aperture_noise_e2(background_e_per_s_per_pix, 1.0, x, n_exposures) - c
    b = q2 * (s + r)
    return (b + np.sqrt(b**2 + 4.0 * s**2 * q2 * c)) / (2.0 * s**2)


def checked_bands(bands, campaign, field: str = "bands") -> list[str]:
    """The bands asked for (None: every survey band), each one with survey exposures.

    Parameters
    ----------
    bands : list of str or None
        Band names.
    campaign : straylight.config.Campaign
        Loaded campaign.
    field : str
        The argument's name in error messages (``--bands`` for the CLI).

    Returns
    -------
    list of str
        The bands, in the order given.

    Raises
    ------
    InputError
        An empty list, an unknown band, a band given twice, or ``"V"`` (a diagnostic band, no
        survey exposures).
    """
    valid = list(campaign.bands)
    if bands is None:
        return valid
    bands = [str(b) for b in ([bands] if isinstance(bands, str) else bands)]
    if not bands:
        raise InputError(f"{field}: no band given; valid bands: {', '.join(valid)} (leave it out for all)")
    for b in bands:
        if b == "V":
            raise InputError(
                f"{field}: 'V' is a diagnostic band without survey exposures; valid: {', '.join(valid)}"
            )
        if b not in valid:
            raise InputError(f"{field}: unknown band {b!r}; valid bands: {', '.join(valid)}")
    twice = [b for i, b in enumerate(bands) if b in bands[:i]]
    if twice:
        raise InputError(f"{field}: band {twice[0]!r} given twice ({', '.join(bands)}); give each band once")
    return bands


def _positive(name: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a number, got {value!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise InputError(f"{name}: must be finite and > 0, got {v:g}")
    return v


def checked_request(
    mag_ab, snr=None, exposure_time=None, n_exposures=None, observable_only=True, names=None
) -> dict:
    """The ETC's request checked before any background is computed.

    Parameters
    ----------
    mag_ab : float or astropy.units.Quantity
        Source AB magnitude, scalar (a Quantity in ``mag`` or ``ABmag``).
    snr : float, optional
        SNR to reach (> 0): the exposure-time question.
    exposure_time : astropy.units.Quantity, optional
        Total exposure time (a time unit, > 0): the SNR question.  Exactly one of ``snr`` and
        ``exposure_time`` is given.
    n_exposures : int, optional
        Exposures the time is split into (>= 1); None: each band's survey count.
    observable_only : bool
        True: no time or SNR (NaN) where a constraint is violated; False: computed at every
        sample (``observable`` and ``violations`` still flag them), e.g. for the longer
        exposures the paper (sect. 1) suggests 50-80 deg from the bright limb.
    names : dict of str to str, optional
        The arguments' names in error messages (e.g. ``{"mag_ab": "--mag"}`` for the CLI).

    Returns
    -------
    dict
        ``mode`` (one of :data:`MODES`), ``mag_ab`` (float, AB mag), ``snr`` (float or None),
        ``exposure_s`` (float, s, or None), ``n_exposures`` (int or None), ``observable_only``.

    Raises
    ------
    InputError
        A non-scalar or non-finite magnitude, a magnitude in another unit, both or neither of
        ``snr`` and ``exposure_time``, an exposure time without a time unit, a value <= 0.
    """
    names = {k: (names or {}).get(k, k) for k in ("mag_ab", "snr", "exposure_time", "n_exposures")}
    mag = _checked_mag(mag_ab, names["mag_ab"])
    if (snr is None) == (exposure_time is None):
        raise InputError(
            f"give exactly one of {names['snr']} (for the exposure time) and {names['exposure_time']} "
            "(for the SNR)"
        )
    exposure_s = None
    if exposure_time is not None:
        exposure_s = _checked_exposure_s(exposure_time, names["exposure_time"])
    else:
        snr = _positive(names["snr"], snr)
    if n_exposures is not None:
        whole = isinstance(n_exposures, (int, np.integer)) and not isinstance(n_exposures, bool)
        if not whole or n_exposures < 1:
            raise InputError(f"{names['n_exposures']}: expected a whole number >= 1, got {n_exposures!r}")
        n_exposures = int(n_exposures)
    return {
        "mode": MODES[0] if exposure_s is None else MODES[1],
        "mag_ab": mag,
        "snr": snr,
        "exposure_s": exposure_s,
        "n_exposures": n_exposures,
        "observable_only": bool(observable_only),
    }


def _checked_mag(mag_ab, name: str) -> float:
    """One finite AB magnitude (a number, or a Quantity in mag or ABmag), as a float."""
    import astropy.units as u

    if isinstance(mag_ab, u.Quantity):
        if mag_ab.unit not in (u.mag, u.ABmag, u.dimensionless_unscaled):
            raise InputError(f"{name}: expected an AB magnitude (mag or ABmag), got unit {mag_ab.unit}")
        mag_ab = mag_ab.value
    if np.ndim(mag_ab) != 0:
        raise InputError(f"{name}: expected one magnitude, got shape {np.shape(mag_ab)}")
    try:
        mag = float(mag_ab)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a number, got {mag_ab!r}") from None
    if not math.isfinite(mag):
        raise InputError(f"{name}: must be finite, got {mag_ab!r}")
    return mag


def _checked_exposure_s(exposure_time, name: str) -> float:
    """One positive time (a Quantity with a time unit), in s."""
    import astropy.units as u

    if not isinstance(exposure_time, u.Quantity) or exposure_time.unit.physical_type != "time":
        raise InputError(
            f"{name}: expected a Quantity with a time unit (e.g. 300 * u.s), got {exposure_time!r}"
        )
    if np.ndim(exposure_time) != 0:
        raise InputError(f"{name}: expected one time, got shape {np.shape(exposure_time)}")
    return _positive(name, exposure_time.to_value(u.s))


def etc_table(background, bands, campaign, request: dict):
    """Exposure times (or SNRs) at the samples of a background table.

    Parameters
    ----------
    background : astropy.table.QTable
        :meth:`straylight.SkyModel.background`'s table for ``bands`` (n samples).
    bands : list of str
        Survey bands (:func:`checked_bands`).
    campaign : straylight.config.Campaign
        The campaign the background was computed with.
    request : dict
        :func:`checked_request`'s result.

    Returns
    -------
    astropy.table.QTable
        n x len(bands) rows, sample by sample and the bands in order, each column with its unit
        and description: ``time``, ``ra``, ``dec``, ``band``, ``observable``, ``violations``,
        ``mag_ab`` (mag), ``snr``, ``exposure_time`` (s, all exposures), ``n_exposures``,
        ``single_exposure`` (s), ``background_total`` (e-/s/pix), ``background_mag`` (AB
        mag/arcsec2), ``dominant`` (the largest component by name) and ``dominant_fraction``,
        ``background_<component>`` (e-/s/pix, each of the registry's components),
        ``source_rate`` (e-/s in the aperture) and ``limit_mag`` (5-sigma limit of the survey's
        exposures at this background, AB mag).  Where a sample is not observable
        ``violations`` names the constraints and, unless the request's ``observable_only`` is
        False, the computed quantity (``exposure_time``, or ``snr`` for a given time) is NaN.
        ``meta``: the request, each band's survey exposures and aperture pixels.
    """
    from straylight.limits.point_source import campaign_exposures
    from straylight.model.registry import component_names

    comps = component_names()
    obs = np.asarray(background["observable"], bool)
    computed = obs if request["observable_only"] else np.ones_like(obs)
    exposures = campaign_exposures(campaign, bands)
    per_band = [_band_values(background, b, x, request, comps, computed) for b, x in zip(bands, exposures)]
    columns = _etc_columns(background, bands, request, per_band, comps)
    return _etc_qtable(columns, bands, exposures, request)


def _band_values(background, band: str, x, request: dict, comps, computed) -> dict:
    """One band's values at every sample: ``snr``, ``exposure_s`` (s; NaN where not
    ``computed``), ``n_exp``, ``total`` (e-/s/pix), ``mag`` (AB mag/arcsec2), ``dom`` and
    ``frac`` (the largest component and its share), ``src`` (source e-/s in the aperture),
    ``lim`` (AB mag) and ``stack`` (each component, e-/s/pix, (component, sample))."""
    import astropy.units as u

    from straylight.limits.point_source import source_rate_e_per_s

    n = len(background)
    rate_unit = u.electron / (u.s * u.pix)
    total = np.asarray(background[f"total_{band}"].to_value(rate_unit), float)
    stack = np.stack([np.asarray(background[f"{c}_{band}"].to_value(rate_unit), float) for c in comps])
    n_exp = x.n_exposures if request["n_exposures"] is None else request["n_exposures"]
    if request["mode"] == "snr":
        exposure_s = np.full(n, request["exposure_s"])
        snr = np.where(computed, snr_for_time(request["mag_ab"], exposure_s, total, x, n_exp), np.nan)
    else:
        snr = np.full(n, request["snr"])
        exposure_s = np.where(computed, time_for_snr(request["mag_ab"], snr, total, x, n_exp), np.nan)
    big = np.argmax(stack, axis=0) if n else np.zeros(0, int)
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = np.take_along_axis(stack, big[None], 0)[0] / total
    out = {"frac": frac, "dom": np.asarray(comps)[big], "stack": stack}
    for key, v in (
        ("snr", snr),
        ("exposure_s", exposure_s),
        ("n_exp", np.full(n, n_exp)),
        ("total", total),
        ("mag", background[f"total_mag_{band}"].value),
        ("src", np.full(n, float(source_rate_e_per_s(request["mag_ab"], x)))),
        ("lim", background[f"limit_mag_{band}"].value),
    ):
        out[key] = np.asarray(v)
    return out


def _etc_columns(background, bands, request: dict, per_band: list, comps) -> dict:
    """The table's columns, sample by sample and the bands in order: name -> (values, unit or
    None, description)."""
    import astropy.units as u
    from astropy.time import Time

    from straylight.model.registry import long_names
    from straylight.model.result import violation_text

    n, nb = len(background), len(bands)
    rate_unit = u.electron / (u.s * u.pix)

    def interleave(key, i=None):  # (band, sample) -> sample by sample, bands in order
        parts = [v[key] if i is None else v[key][i] for v in per_band]
        return np.stack(parts, axis=1).reshape(n * nb) if n else np.zeros(0)

    idx = np.repeat(np.arange(n), nb)
    t = Time(background["time"][idx] if n else background["time"][:0], format="isot", precision=3)
    exp = interleave("exposure_s")
    n_exp = interleave("n_exp").astype(np.int64)
    lname = long_names()
    obs, violated = np.asarray(background["observable"], bool), violation_text(background["violations"])
    given = request["mode"] == "snr"
    snr_text = "signal-to-noise ratio in the EE80 aperture" + (
        " reached in exposure_time" if given else " asked for"
    )
    time_text = "total exposure time, all exposures" + (" (given)" if given else " to reach snr")
    dominant_text = f"largest background component ({', '.join(comps)})"
    columns = {
        "time": (t, None, "UTC time of the sample"),
        "ra": (background["ra"][idx], None, "ICRS right ascension"),
        "dec": (background["dec"][idx], None, "ICRS declination"),
        "band": (np.tile(np.asarray(bands, dtype=str), n), None, "band"),
        "observable": (obs[idx], None, "the pointing meets every constraint at this time"),
        "violations": (violated[idx], None, "violated constraints, comma-separated (empty when observable)"),
        "mag_ab": (np.full(n * nb, request["mag_ab"]), u.mag, "source AB magnitude"),
        "snr": (interleave("snr"), None, snr_text),
        "exposure_time": (exp, u.s, time_text),
        "n_exposures": (n_exp, None, "exposures the time is split into (read noise once each)"),
        "single_exposure": (
            exp / n_exp if n else exp,
            u.s,
            "time of one exposure, exposure_time / n_exposures",
        ),
        "background_total": (interleave("total"), rate_unit, lname["total"]),
        "background_mag": (interleave("mag"), u.mag / u.arcsec**2, "total background, AB surface brightness"),
        "dominant": (interleave("dom").astype(str), None, dominant_text),
        "dominant_fraction": (interleave("frac"), None, "the dominant component's share of the total"),
    }
    for i, c in enumerate(comps):
        columns[f"background_{c}"] = (interleave("stack", i), rate_unit, lname[c])
    columns["source_rate"] = (
        interleave("src"),
        u.electron / u.s,
        "source electrons per second in the EE80 aperture",
    )
    columns["limit_mag"] = (
        interleave("lim"),
        u.mag,
        "5-sigma point-source limit of the survey's exposures at this background, AB",
    )
    return columns


def _etc_qtable(columns: dict, bands, exposures, request: dict):
    """The QTable of the columns (values with their units, descriptions, display formats),
    with the request and each band's survey exposures and aperture pixels in its ``meta``."""
    import astropy.units as u
    from astropy.table import QTable

    meta = {k: request[k] for k in ("mode", "observable_only", "mag_ab", "snr", "exposure_s")}
    meta["survey_exposures"] = {b: f"{x.n_exposures} x {x.exposure_s:g} s" for b, x in zip(bands, exposures)}
    meta["aperture_pixels"] = {b: x.n_pix for b, x in zip(bands, exposures)}
    out = QTable(
        {
            k: (v if unit is None or isinstance(v, u.Quantity) else u.Quantity(v, unit))
            for k, (v, unit, _) in columns.items()
        },
        meta=meta,
    )
    for k, (_, _, desc) in columns.items():
        out[k].info.description = desc
    for k, f in (
        ("exposure_time", ".1f"),
        ("single_exposure", ".1f"),
        ("snr", ".2f"),
        ("background_total", ".3g"),
    ):
        out[k].info.format = f
    return out


def magnitude_warnings(table, campaign) -> list[str]:
    """Lines for a magnitude the noise model does not cover, per band of an :func:`etc_table`:
    a source bright enough to fill a pixel in one survey exposure (mean electrons per pixel of
    the EE80 aperture over :data:`BRIGHT_E_PER_PIXEL`; the model has no saturation), or an
    exposure time over :data:`LONG_EXPOSURE_S` (a source far below the background, where the
    CCD equation's perfect background subtraction does not hold).

    Parameters
    ----------
    table : astropy.table.QTable
        :func:`etc_table`'s result.
    campaign : straylight.config.Campaign
        The campaign it was computed with.

    Returns
    -------
    list of str
        One line per band and case, empty for an ordinary magnitude.
    """
    from straylight.limits.point_source import campaign_exposures

    if not len(table):
        return []
    bands = list(dict.fromkeys(str(b) for b in table["band"]))
    mag, lines = table.meta["mag_ab"], []
    for b, x in zip(bands, campaign_exposures(campaign, bands)):
        rows = np.asarray(table["band"]) == b
        per_pix = float(table["source_rate"][rows][0].value) * x.exposure_s / x.n_pix
        if per_pix > BRIGHT_E_PER_PIXEL:
            lines.append(
                f"AB {mag:g} in {b}: {per_pix:.3g} e- per pixel (mean over the EE80 aperture) in one "
                f"{x.exposure_s:g} s survey exposure, beyond a CCD's full well "
                f"(~{BRIGHT_E_PER_PIXEL:.0e} e-): "
                "the source saturates; the noise model has no saturation, so its figures do not hold"
            )
        t = np.asarray(table["exposure_time"][rows].value, float)
        t = t[np.isfinite(t)]
        if table.meta["mode"] == MODES[0] and t.size and t.min() > LONG_EXPOSURE_S:
            limit = np.asarray(table["limit_mag"][rows].value, float)
            below = mag - np.nanmax(limit) if np.isfinite(limit).any() else float("nan")
            lines.append(
                f"AB {mag:g} in {b}: {t.min():.3g} s at best, over a day: the source is "
                f"{below:.1f} mag fainter than the survey's 5-sigma limit; the CCD equation assumes a "
                "perfectly subtracted background (no flat-field or confusion floor), so no real "
                "exposure reaches it"
            )
    return lines


def etc_summary(table):
    """Per band, the best, median and worst of an :func:`etc_table` over its observable samples
    (a window of times): the shortest exposure time, or the highest SNR, and when.

    Parameters
    ----------
    table : astropy.table.QTable
        :func:`etc_table`'s result.

    Returns
    -------
    astropy.table.QTable
        One row per band: ``band``, ``n_samples``, ``n_observable``, then for the exposure-time
        question ``exposure_time_min`` (s), ``time_of_min`` (UTC ISO text, empty when never
        observable), ``exposure_time_median``, ``exposure_time_max`` (s); for the SNR question
        ``snr_max``, ``time_of_max``, ``snr_median``, ``snr_min``; and at the best sample
        ``background_total`` (e-/s/pix) and ``dominant``.  NaN where a band is never observable.
    """
    import astropy.units as u
    from astropy.table import QTable

    by_time = table.meta["mode"] == "exposure_time"
    key = "exposure_time" if by_time else "snr"
    bands = list(dict.fromkeys(np.asarray(table["band"], dtype=str)))
    rows = [_summary_row(table, b, key, by_time) for b in bands]
    best_name, worst_name, when = (
        ("exposure_time_min", "exposure_time_max", "time_of_min")
        if by_time
        else ("snr_max", "snr_min", "time_of_max")
    )
    unit = u.s if by_time else u.dimensionless_unscaled
    cols = list(zip(*rows)) if rows else [[]] * 9
    out = QTable(
        {
            "band": np.asarray(cols[0], dtype=str),
            "n_samples": np.asarray(cols[1], dtype=np.int64),
            "n_observable": np.asarray(cols[2], dtype=np.int64),
            best_name: u.Quantity(np.asarray(cols[3], float), unit),
            when: np.asarray(cols[4], dtype=str),
            f"{key}_median": u.Quantity(np.asarray(cols[5], float), unit),
            worst_name: u.Quantity(np.asarray(cols[6], float), unit),
            "background_total": u.Quantity(np.asarray(cols[7], float), u.electron / (u.s * u.pix)),
            "dominant": np.asarray(cols[8], dtype=str),
        },
        meta=dict(table.meta),
    )
    what = "exposure time" if by_time else "SNR"
    for name, desc in (
        ("band", "band"),
        ("n_samples", "samples in the window"),
        ("n_observable", "observable samples"),
        (best_name, f"best {what} over the observable samples"),
        (when, "UTC time of the best sample (ISO 8601; empty when never observable)"),
        (f"{key}_median", f"median {what} over the observable samples"),
        (worst_name, f"worst {what} over the observable samples"),
        ("background_total", "total background at the best sample"),
        ("dominant", "largest background component at the best sample"),
    ):
        out[name].info.description = desc
    return out


def _summary_row(table, band: str, key: str, by_time: bool) -> tuple:
    """One band's summary row: band, samples, observable samples, the best value of ``key``
    (the shortest time, s, or the highest SNR), its UTC time, the median, the worst, and the
    total background (e-/s/pix) and dominant component at the best sample; NaN and "" when
    the band is never observable."""
    import astropy.units as u

    in_band = np.asarray(table["band"], dtype=str) == band
    sel = np.flatnonzero(in_band & np.asarray(table["observable"], bool))
    n_all = int(np.sum(in_band))
    vals = np.asarray(u.Quantity(table[key]).value, float)[sel]
    if not sel.size:
        return (band, n_all, 0, np.nan, "", np.nan, np.nan, np.nan, "")
    best = sel[np.argmin(vals) if by_time else np.argmax(vals)]
    return (
        band,
        n_all,
        sel.size,
        float(np.min(vals) if by_time else np.max(vals)),
        table["time"][best].isot,
        float(np.median(vals)),
        float(np.max(vals) if by_time else np.min(vals)),
        float(table["background_total"][best].value),
        str(table["dominant"][best]),
    )


def time_grid(start, end, step_s: float, period_s: float):
    """UTC times every ``step_s`` from ``start`` to ``end`` (exclusive), checked as
    ``straylight visibility`` checks its window.

    Parameters
    ----------
    start, end : str or astropy.time.Time
        UTC start and end (ISO 8601 text or scalar Time), within DE405.
    step_s : float
        Step, s (> 0, at most ``end - start``).
    period_s : float
        The orbit's period, s: a step over a quarter of it is warned about (observable windows
        fall between samples).

    Returns
    -------
    astropy.time.Time, shape (n,)
        n = ceil((end - start) / step) times, UTC.

    Raises
    ------
    InputError
        Unparsable, out-of-ephemeris or reversed times, a bad step, too many samples.
    """
    from straylight.planning.visibility import sampled_window

    return sampled_window(start, end, step_s, period_s, start_field="--time")[1]
