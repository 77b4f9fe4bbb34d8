"""limits.zarr's depths at the assumption envelope's two ends (:mod:`straylight.model.envelope`):
the limits of a region's observable samples with every parameter at its bright end
(pessimistic) or dark end (optimistic), from the same evaluation's parts, and their per-pixel
medians."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from straylight.config import Campaign
    from straylight.model.envelope import Envelope

__all__ = [
    "ENVELOPE_LONG_NAMES",
    "ENVELOPE_VARIABLES",
    "add_limit_pair",
    "per_sample_from_background",
    "background_envelope_limits",
    "envelope_limits",
    "with_envelope",
]

#: limits.zarr's variables at the envelope's ends: end -> (per-sample limits (time, pixel, band),
#: their per-pixel median over observable times (pixel, band))
ENVELOPE_VARIABLES = {
    end: (f"limiting_mag_{end}", f"limiting_mag_median_{end}") for end in ("pessimistic", "optimistic")
}
#: what each end is, in their long names
ENVELOPE_LONG_NAMES = {
    "pessimistic": "every assumption of the envelope at its bright end",
    "optimistic": "every assumption of the envelope at its dark end",
}


def envelope_limits(envelope: Envelope, region, exposures) -> dict:
    """The 5-sigma limits at both ends of the envelope, at a region's observable samples.

    Parameters
    ----------
    envelope : Envelope
        The campaign's envelope (its bands those of the region's last axis).
    region : mapping
        ``total`` and the scaled parts (:attr:`Envelope.leaves`), (n_time, n_pixel, n_band)
        e-/s/pix, and ``observable`` (n_time, n_pixel) bool.  A part it lacks is its
        component minus the component's other parts (the cube stores the earthshine and its
        part via the door: the direct part is their difference).
    exposures : sequence of SurveyExposure
        Each band's exposures (:func:`~straylight.limits.point_source.campaign_exposures`).

    Returns
    -------
    dict of str to ndarray
        ``limiting_mag_pessimistic`` and ``limiting_mag_optimistic``: float32, (n_time,
        n_pixel, n_band), mag(AB); NaN where not observable.
    """
    from straylight.limits.point_source import band_limits
    from straylight.model.envelope import ENDS

    total = np.asarray(region["total"])
    where = np.nonzero(np.asarray(region["observable"], bool))
    parts = {leaf: _part(region, leaf, where) for leaf in envelope.leaves}
    out = {}
    for end in ENDS:
        lim = np.full(total.shape, np.nan, np.float32)
        shift = envelope.zero_point_shift(end).astype(np.float32)
        lim[where] = band_limits(envelope.scaled_total(total[where], parts, end), exposures) + shift
        out[f"limiting_mag_{end}"] = lim
    return out


def _part(region, leaf: str, where) -> np.ndarray:
    """A part's values at ``where`` (index arrays into (time, pixel)): the region's, or its
    component's minus the component's other parts."""
    from straylight.model import registry

    if leaf in region:
        return np.asarray(region[leaf])[where]
    comp = next((c for c in registry.COMPONENTS if leaf in dict(c.parts)), None)
    if comp is None or comp.name not in region:
        raise KeyError(f"region has neither {leaf!r} nor the component it is part of")
    out = np.asarray(region[comp.name])[where].astype(np.float64)
    for p, _ in comp.parts:
        if p != leaf:
            out -= np.asarray(region[p])[where]
    return out


def background_envelope_limits(campaign: Campaign, background, bands, exposures) -> dict:
    """The (time, pixel, band) limits at the envelope's ends (end -> limits) from background's
    total and the parts the envelope scales (NaN where not observable); {} when background lacks
    a part.

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign (its envelope).
    background : xarray.Dataset
        background.zarr's dataset (eager or lazy): ``total``, ``observable`` and the parts.
    bands : sequence of str
        The bands of ``background``.
    exposures : sequence of SurveyExposure
        Each band's exposures.

    Returns
    -------
    dict of str to xarray.DataArray
        :data:`~straylight.model.envelope.ENDS` -> float32 (time, pixel, band) mag(AB).
    """
    from straylight.model.envelope import ENDS, campaign_envelope

    env = campaign_envelope(campaign, bands)
    have = set(background.data_vars)
    if not all(n in have or n == "earthshine_direct" for n in env.leaves):
        # the members' re-evaluated ends are computed by the cube's workers, not stored: from a
        # stored background the ends carry the other parameters only
        from straylight.model.envelope import Envelope

        env = Envelope([p for p in env.parameters if not p.reevaluated], env.bands)
    names = ["total"] + [n for n in (*env.leaves, "earthshine", "earthshine_door") if n in have]
    names = list(dict.fromkeys(names))
    if not env.parameters or not all(leaf in have or leaf == "earthshine_direct" for leaf in env.leaves):
        return {}
    return {
        end: per_sample_from_background(
            background,
            names,
            lambda region, end=end: envelope_limits(env, region, exposures)[f"limiting_mag_{end}"],
        )
        for end in ENDS
    }


def per_sample_from_background(background, names, limits_of):
    """Per-sample limits (time, pixel, band) from a stored background, block by block.

    Parameters
    ----------
    background : xarray.Dataset
        background.zarr's dataset (dask-backed or not), with ``observable``.
    names : list of str
        Its variables each block's region holds (e-/s/pixel).
    limits_of : callable
        region (dict: name -> (time, pixel, band) array, ``observable`` -> (time, pixel)) ->
        limits (time, pixel, band), mag(AB).

    Returns
    -------
    xarray.DataArray
        float32 limits, dims (time, pixel, band).
    """
    import xarray as xr

    def one(observable, *arrays):
        # apply_ufunc broadcasts the (time, pixel) flags to the bands' dims: one column
        observable = np.asarray(observable).reshape(np.shape(arrays[0])[:2] + (-1,))[..., 0]
        return limits_of(dict(zip(names, arrays), observable=observable))

    return xr.apply_ufunc(
        one,
        background["observable"],
        *(background[n] for n in names),
        dask="parallelized",
        output_dtypes=[np.float32],
    ).transpose("time", "pixel", "band")


def with_envelope(ds, envelope: dict, per_sample: bool = False):
    """limits.zarr's dataset with the envelope's per-sample limits and per-pixel medians.

    Parameters
    ----------
    ds : xarray.Dataset
        limits.zarr's dataset.
    envelope : dict
        end -> (per-sample limits (time, pixel, band), per-pixel medians (pixel, band)), mag(AB).
    per_sample : bool
        Whether to add the per-sample limits too (the work store's; the product keeps the
        medians only).

    Returns
    -------
    xarray.Dataset
        ``ds`` with the medians of :data:`ENVELOPE_VARIABLES` (and the per-sample limits),
        units and long names.
    """
    for end, (lim, med) in envelope.items():
        add_limit_pair(ds, ENVELOPE_VARIABLES[end], ENVELOPE_LONG_NAMES[end], lim, med, per_sample)
    return ds


def add_limit_pair(ds, names, what: str, lim, med, per_sample: bool, median_note: str = ""):
    """Add to ``ds`` one variant of the limits: its per-pixel median over observable times
    (pixel, band) and, with ``per_sample``, its per-sample limits (time, pixel, band), mag(AB).

    Parameters
    ----------
    ds : xarray.Dataset
        limits.zarr's dataset (changed in place).
    names : tuple of str
        (the per-sample variable's name, the median's).
    what : str
        The variant, as the long names say it.
    lim, med : array-like
        The per-sample limits and the medians (xarray objects or arrays), mag(AB).
    per_sample : bool
        Whether to add the per-sample limits too.
    median_note : str, optional
        Added to the median's long name after ``what`` (how it is computed).
    """
    data = getattr(med, "data", med)
    name, median_name = names
    if per_sample:
        ds[name] = (
            ("time", "pixel", "band"),
            getattr(lim, "data", lim),
            {"units": "mag(AB)", "long_name": f"5-sigma point-source limit, {what} (NaN: not observable)"},
        )
    ds[median_name] = (
        ("pixel", "band"),
        data,
        {
            "units": "mag(AB)",
            "long_name": f"median limit over observable times, {what}{median_note} (NaN: never observable)",
        },
    )
