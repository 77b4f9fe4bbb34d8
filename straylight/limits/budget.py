"""The depth error budget: every unmeasured input of the 5-sigma depth with its range, carried into
limits.zarr as a central interval of the median depth and the worst hours' change.

The inputs (:func:`depth_budget`): the assumption envelope's parameters
(:mod:`straylight.model.envelope`: the PST's tail, the door's reflectance, the Earth's albedo level
and spectrum, the bands' zero points) and the instrument file's ``depth_budget`` section: the read
noise, the dark current, the EE80 radius per band, the zodiacal light per band, the Moon's and the
off-field stars' light.  Each is either a factor on some parts of the background (per band) or a
change of the noise model's inputs (:class:`~straylight.limits.point_source.SurveyExposure`), or both
(a zero point scales every part and the source).

The interval is a linear propagation, sample by sample: each input alone at each end of its range
gives a change of the sample's limit; the ends are taken as one standard deviation, so the sample's
16th (84th) percentile limit is the nominal one minus (plus) the quadrature sum of the changes
towards shallower (deeper) limits.  limits.zarr's ``limiting_mag_median_p16`` / ``_p84`` are the
per-pixel medians of those over the observable times (the median commutes with a change that keeps
the samples' order, as every input that moves all samples the same way nearly does).
``limiting_mag_shift_p90`` / ``_p99``: the 90th / 99th percentile over observable times of the size
of the pessimistic end's change, pessimistic minus nominal limit (the worst hours)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

__all__ = [
    "BUDGET_LONG_NAMES",
    "BUDGET_VARIABLES",
    "SHIFT_PERCENTILES",
    "BudgetTerm",
    "background_budget_limits",
    "budget_limits",
    "depth_budget",
    "shift_percentiles",
    "term_limits",
    "with_budget",
]

#: limits.zarr's budget variables: per-sample limits (work store) -> their per-pixel medians
BUDGET_VARIABLES = {
    "p16": ("limiting_mag_p16", "limiting_mag_median_p16"),
    "p84": ("limiting_mag_p84", "limiting_mag_median_p84"),
}
BUDGET_LONG_NAMES = {
    "p16": "16th percentile (shallow side) of the depth error budget, linear propagation",
    "p84": "84th percentile (deep side) of the depth error budget, linear propagation",
}
#: percentiles over observable times of the size of the pessimistic end's change -> variable
SHIFT_PERCENTILES = {90: "limiting_mag_shift_p90", 99: "limiting_mag_shift_p99"}


@dataclass(frozen=True)
class BudgetTerm:
    """One input of the depth budget at its two ends.

    Attributes
    ----------
    key : str
        Its name (an envelope parameter's key, or a ``depth_budget`` key).
    leaves : tuple of str
        The background's parts it scales (empty: none).
    factors : tuple of ndarray
        (dark, bright) factors on ``leaves`` per band, dimensionless (ones without leaves).
    zero_point : tuple of ndarray
        (dark, bright) zero-point offsets per band, mag: every part x 10^(0.4 dmag), limit + dmag.
    exposure : tuple of dict
        (dark, bright) changes of the bands' :class:`SurveyExposure` (field -> value per band).
    range : tuple
        Its configured range (dark, bright), or per band.
    unit, source : str
        The range's unit and where it comes from.
    reevaluated : bool
        Whether its ends are the model's re-evaluation (the envelope's calibrated members): then
        ``leaves`` are the parts it changes followed by their re-evaluated groups at each end
        (:data:`~straylight.model.envelope.MEMBER_GROUPS`), and ``factors`` are ones.
    """

    key: str
    leaves: tuple
    factors: tuple
    zero_point: tuple
    exposure: tuple
    range: tuple
    unit: str
    source: str
    reevaluated: bool = False


def _ones(n):
    return np.ones(n), np.ones(n)


def depth_budget(campaign, bands=None, context=None) -> tuple:
    """The campaign's depth budget: the envelope's parameters, then the instrument's
    ``depth_budget`` inputs (cached on the campaign per set of bands).

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign.
    bands : sequence of str, optional
        Bands of the factors; None: the campaign's.
    context : SourceContext, optional
        The sources' context, for the envelope (None: made there).

    Returns
    -------
    tuple of BudgetTerm
        Empty without an envelope or a ``depth_budget`` section.
    """
    from straylight.model.envelope import ENDS, MEMBER_GROUPS, campaign_envelope, end_part_name

    bands = tuple(campaign.bands if bands is None else bands)
    cache = campaign.__dict__.setdefault("_depth_budget", {})
    if bands in cache:
        return cache[bands]
    n = len(bands)
    zeros = (np.zeros(n), np.zeros(n))
    terms = []
    for p in campaign_envelope(campaign, bands, context).parameters:
        if p.zero_point:
            terms.append(
                BudgetTerm(p.key, (), _ones(n), (p.dark, p.bright), ({}, {}), p.range, p.unit, p.source)
            )
        elif p.reevaluated:
            groups = tuple(end_part_name(g, e) for e in ENDS for g in MEMBER_GROUPS)
            term = (p.key, p.leaves + groups, _ones(n), zeros, ({}, {}), p.range, p.unit, p.source)
            terms.append(BudgetTerm(*term, reevaluated=True))
        else:
            terms.append(
                BudgetTerm(p.key, p.leaves, (p.dark, p.bright), zeros, ({}, {}), p.range, p.unit, p.source)
            )
    spec = campaign.instrument_settings.depth_budget
    if spec is not None:
        terms += _instrument_terms(campaign, spec, bands)
    cache[bands] = tuple(terms)
    return cache[bands]


def _instrument_terms(campaign, spec, bands) -> list:
    """The ``depth_budget`` section's inputs as budget terms."""
    inst = campaign.instrument_settings
    n = len(bands)
    zeros = (np.zeros(n), np.zeros(n))
    out = []
    for key, field in (("read_noise_e", "read_noise_e"), ("dark_current_e_per_s", "dark_e_per_s")):
        r = getattr(spec, key)
        if r is None:
            continue
        lo, hi = float(min(r.range)), float(max(r.range))
        out.append(
            BudgetTerm(
                key, (), _ones(n), zeros, ({field: [lo] * n}, {field: [hi] * n}), r.range, r.unit, r.source
            )
        )
    if spec.ee80_radius_arcsec:
        pix = campaign.pixel_scale_arcsec
        lo, hi, sources = [], [], []
        for b in bands:
            r = spec.ee80_radius_arcsec.get(b)
            rr = (inst.detector.ee80_radius_arcsec.value,) * 2 if r is None else (min(r.range), max(r.range))
            lo.append(np.pi * (float(rr[0]) / pix) ** 2)
            hi.append(np.pi * (float(rr[1]) / pix) ** 2)
            if r is not None and f"{r.source}" not in sources:
                sources.append(r.source)
        rng = tuple(
            (float(min(spec.ee80_radius_arcsec[b].range)), float(max(spec.ee80_radius_arcsec[b].range)))
            for b in bands
            if b in spec.ee80_radius_arcsec
        )
        out.append(
            BudgetTerm(
                "ee80_radius_arcsec",
                (),
                _ones(n),
                zeros,
                ({"n_pix": lo}, {"n_pix": hi}),
                rng,
                "arcsec",
                "; ".join(sources),
            )
        )
    for key, leaf, per_band in (
        ("zodiacal_level", "zodiacal", True),
        ("moon_level", "moon", False),
        ("stars_pst_core", "stars", False),
    ):
        r = getattr(spec, key)
        if not r:
            continue
        if per_band:
            ranges = [tuple(r[b].range) if b in r else (1.0, 1.0) for b in bands]
            source = "; ".join(f"{b}: {r[b].source}" for b in bands if b in r)
            unit = next(iter(r.values())).unit
        else:
            ranges, source, unit = [tuple(r.range)] * n, r.source, r.unit
        lo = np.array([float(min(x)) for x in ranges])
        hi = np.array([float(max(x)) for x in ranges])
        out.append(BudgetTerm(key, (leaf,), (lo, hi), zeros, ({}, {}), tuple(ranges), unit, source))
    return out


def term_limits(term: BudgetTerm, end: int, total, parts, exposures) -> np.ndarray:
    """The limits (float64, (..., n_band), mag(AB)) with one input at one end, the others nominal.

    Parameters
    ----------
    term : BudgetTerm
        The input.
    end : int
        0: its dark end; 1: its bright end.
    total : ndarray, shape (..., n_band)
        The nominal total, e-/s/pix.
    parts : mapping of str to ndarray, shape (..., n_band)
        The nominal parts it scales, e-/s/pix.
    exposures : sequence of SurveyExposure
        Each band's exposures (nominal).

    Returns
    -------
    ndarray of float64, shape of ``total``
    """
    from straylight.limits.point_source import _limit_mag

    out = np.array(total, dtype=np.float64)
    if term.reevaluated:
        # the end's re-evaluated groups replace the nominal parts they sum
        from straylight.model.envelope import ENDS, MEMBER_GROUPS, end_part_name

        for group, leaves in MEMBER_GROUPS.items():
            out += np.asarray(parts[end_part_name(group, ENDS[end])], np.float64)
            for leaf in leaves:
                out -= np.asarray(parts[leaf], np.float64)
    else:
        f = term.factors[end]
        for leaf in term.leaves:
            out += np.asarray(parts[leaf], np.float64) * (np.asarray(f, np.float64) - 1.0)
    zp = np.asarray(term.zero_point[end], np.float64)
    if np.any(zp != 0):
        out *= 10.0 ** (0.4 * zp)
    changes = term.exposure[end]
    lim = np.empty(out.shape, np.float64)
    for ib, x in enumerate(exposures):
        if changes:
            x = dataclasses.replace(x, **{k: float(v[ib]) for k, v in changes.items()})
        lim[..., ib] = _limit_mag(out[..., ib], x) + zp[ib]
    return lim


def budget_limits(terms, region, exposures) -> dict:
    """The budget's per-sample 16th and 84th percentile limits at a region's observable samples.

    Parameters
    ----------
    terms : sequence of BudgetTerm
        The budget (:func:`depth_budget`).
    region : mapping
        ``total`` and the parts the terms scale, (n_time, n_pixel, n_band) e-/s/pix, and
        ``observable`` (n_time, n_pixel) bool (a missing part: its component minus the others,
        as :func:`~straylight.limits.envelope.envelope_limits`).
    exposures : sequence of SurveyExposure
        Each band's exposures.

    Returns
    -------
    dict of str to ndarray
        ``limiting_mag_p16`` and ``limiting_mag_p84``: float32 (n_time, n_pixel, n_band),
        mag(AB); NaN where not observable.
    """
    from straylight.limits.envelope import _part
    from straylight.limits.point_source import _limit_mag

    total = np.asarray(region["total"])
    where = np.nonzero(np.asarray(region["observable"], bool))
    leaves = list(dict.fromkeys(leaf for t in terms for leaf in t.leaves))
    parts = {leaf: _part(region, leaf, where) for leaf in leaves}
    tot = np.asarray(total[where], np.float64)
    nominal = np.empty(tot.shape, np.float64)
    for ib, x in enumerate(exposures):
        nominal[..., ib] = _limit_mag(tot[..., ib], x)
    shallow = np.zeros(tot.shape, np.float64)
    deep = np.zeros(tot.shape, np.float64)
    for term in terms:
        for end in (0, 1):
            d = term_limits(term, end, tot, parts, exposures) - nominal
            shallow += np.minimum(d, 0.0) ** 2
            deep += np.maximum(d, 0.0) ** 2
    out = {}
    for key, values in (("p16", nominal - np.sqrt(shallow)), ("p84", nominal + np.sqrt(deep))):
        lim = np.full(total.shape, np.nan, np.float32)
        lim[where] = values
        out[BUDGET_VARIABLES[key][0]] = lim
    return out


def background_budget_limits(campaign, background, bands, exposures) -> dict:
    """The (time, pixel, band) budget limits (``p16``/``p84`` -> limits; NaN where not
    observable) from background.zarr's total and the parts the budget scales; {} without a
    budget or when background lacks a part.

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign.
    background : xarray.Dataset
        background.zarr's dataset (eager or lazy).
    bands : sequence of str
        Its bands.
    exposures : sequence of SurveyExposure
        Each band's exposures.

    Returns
    -------
    dict of str to xarray.DataArray
        float32 (time, pixel, band) mag(AB).
    """
    have = set(background.data_vars)
    # the members' re-evaluated groups are the cube workers', not stored: their term is left out
    terms = [
        t
        for t in depth_budget(campaign, bands)
        if not t.reevaluated or all(leaf in have or leaf == "earthshine_direct" for leaf in t.leaves)
    ]
    leaves = list(dict.fromkeys(leaf for t in terms for leaf in t.leaves))
    if not terms or not all(leaf in have or leaf == "earthshine_direct" for leaf in leaves):
        return {}
    names = list(
        dict.fromkeys(["total"] + [n for n in (*leaves, "earthshine", "earthshine_door") if n in have])
    )
    from straylight.limits.envelope import per_sample_from_background

    return {
        key: per_sample_from_background(
            background, names, lambda region, name=name: budget_limits(terms, region, exposures)[name]
        )
        for key, (name, _) in BUDGET_VARIABLES.items()
    }


def shift_percentiles(pessimistic, nominal, observable) -> dict:
    """Per pixel, the 90th and 99th percentile over the observable times of the size of the
    pessimistic end's change (pessimistic minus nominal limit; negative: shallower).

    Parameters
    ----------
    pessimistic, nominal : array_like, shape (n_time, n_pixel, n_band)
        Limits, mag(AB).
    observable : array_like of bool, shape (n_time, n_pixel)

    Returns
    -------
    dict of str to ndarray
        :data:`SHIFT_PERCENTILES`' names -> float32 (n_pixel, n_band), mag; NaN where never
        observable.  The value is the change at that percentile of its size, with its sign: p90
        is the change whose size only 10 % of the observable times exceed.
    """
    pessimistic = np.asarray(pessimistic)
    nominal = np.asarray(nominal)
    observable = np.asarray(observable, bool)
    n_pix, n_band = pessimistic.shape[1:]
    qs = sorted(SHIFT_PERCENTILES)
    out = {SHIFT_PERCENTILES[q]: np.full((n_pix, n_band), np.nan, np.float32) for q in qs}
    for p in range(n_pix):
        times = np.flatnonzero(observable[:, p])
        if times.size == 0:
            continue
        d = pessimistic[times, p, :].astype(np.float64) - nominal[times, p, :]
        # the changes are shallower (negative) where the envelope brightens the sky: the size's
        # q-th percentile is the change's (100 - q)-th
        pct = np.nanpercentile if np.isnan(d).any() else np.percentile
        v = pct(d, [100 - q for q in qs], axis=0)
        for q, row in zip(qs, v):
            out[SHIFT_PERCENTILES[q]][p] = row
    return out


def with_budget(ds, budget: dict, shifts=None, per_sample: bool = False):
    """limits.zarr's dataset with the budget's per-pixel medians (and per-sample limits) and the
    pessimistic end's worst-hour percentiles.

    Parameters
    ----------
    ds : xarray.Dataset
        limits.zarr's dataset.
    budget : dict
        ``p16``/``p84`` -> (per-sample limits (time, pixel, band), per-pixel medians (pixel,
        band)), mag(AB).
    shifts : dict, optional
        :data:`SHIFT_PERCENTILES`' names -> (pixel, band) arrays, mag.
    per_sample : bool
        Whether to add the per-sample limits too (the work store's).

    Returns
    -------
    xarray.Dataset
        ``ds`` with the variables, their units and long names.
    """
    data = lambda v: getattr(v, "data", v)  # noqa: E731 - an xarray object's array, or the array
    from straylight.limits.envelope import add_limit_pair

    note = "; each input's range end one standard deviation, the changes added in quadrature"
    for key, (lim, med) in budget.items():
        add_limit_pair(ds, BUDGET_VARIABLES[key], BUDGET_LONG_NAMES[key], lim, med, per_sample, note)
    for q, name in SHIFT_PERCENTILES.items():
        if shifts is None or name not in shifts:
            continue
        ds[name] = (
            ("pixel", "band"),
            data(shifts[name]),
            {
                "units": "mag",
                "long_name": f"pessimistic minus nominal limit at the {q}th percentile over observable "
                f"times of its size: {100 - q} % of the times change more (negative: shallower; "
                "NaN: never observable)",
            },
        )
    return ds
