"""The assumption envelope's figures: a map per band of the spread of the median depth between the
envelope's ends, and the depth's sensitivity to each parameter alone (with its table).

The envelope (:mod:`straylight.model.envelope`): every unmeasured parameter (the PST's tail, the
door's reflectance, the Earth's albedo) at its dark end (optimistic) or bright end (pessimistic).
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from straylight.plots.common import FIGURE_DPI, _full_sky, _save, band_colour_limits

__all__ = ["SENSITIVITY_TABLE", "envelope_figures", "envelope_sensitivity", "spread_maps"]

#: the sensitivity chart's table, written beside it
SENSITIVITY_TABLE = "envelope_sensitivity.csv"
#: time blocks of the cube read for the sensitivity chart at most (evenly spread over the campaign):
#: 4 of 6 h are a day's worth of samples, each parameter's median moves by less than 0.005 mag
#: from 8 (3 days at nside 32)
SENSITIVITY_TIME_BLOCKS = 4
#: the spread maps' colour scale
SPREAD_CMAP = "magma"


def spread_maps(limits_ds, campaign, out_dir) -> list:
    """A page of maps, one per band, of the median depth's spread over the envelope:
    ``limiting_mag_median_optimistic - limiting_mag_median_pessimistic`` (mag, >= 0).

    Parameters
    ----------
    limits_ds : xarray.Dataset
        limits.zarr's per-pixel summaries (with the envelope's medians), ``pixel``, ``band`` and
        the HEALPix attributes.
    campaign : Campaign
        The campaign (its name).
    out_dir : str or path-like
        Folder of the figure.

    Returns
    -------
    list of pathlib.Path
        ``envelope_spread.png``, or nothing without the envelope's medians.
    """
    from matplotlib.figure import Figure

    from straylight.plots.maps import ORIENTATION, MollweidePanel, overlay_legend
    from straylight.plots.overlays import sun_radec_deg, sun_track_times

    names = ("limiting_mag_median_optimistic", "limiting_mag_median_pessimistic")
    if not all(n in limits_ds for n in names):
        return []
    nest = str(limits_ds.attrs.get("healpix_ordering", "RING")).upper() == "NESTED"
    bands = [str(b) for b in limits_ds["band"].values]
    nrow = int(np.ceil(len(bands) / 4))
    sun = sun_radec_deg(sun_track_times(campaign.times))
    fig = Figure(figsize=(16, 3.4 * nrow))
    for ib, band in enumerate(bands):
        spread = np.asarray(limits_ds[names[0]].isel(band=ib), float) - np.asarray(
            limits_ds[names[1]].isel(band=ib), float
        )
        med = float(np.nanmedian(spread)) if np.isfinite(spread).any() else float("nan")
        lo, hi = band_colour_limits([spread], min_span=0.05)
        MollweidePanel(
            fig, (nrow, 4, ib + 1), SPREAD_CMAP, "optimistic - pessimistic median depth, mag"
        ).show(
            _full_sky(limits_ds, spread),
            nest,
            f"{band}: median over the footprint {med:.2f} mag",
            max(lo, 0.0),
            hi,
            sun,
        )
    overlay_legend(fig, "track", "outside the footprint, or never observable")
    fig.suptitle(
        f"{campaign.name}: spread of the median 5-sigma depth over the assumption envelope "
        "(every unmeasured parameter at its dark end minus at its bright end; config envelope)\n"
        f"{ORIENTATION}; colours: each band's 2nd-98th percentile",
        fontsize=10,
    )
    return [_save(fig, Path(out_dir) / "envelope_spread.png")]


def envelope_sensitivity(background_store, campaign, time_blocks: int = SENSITIVITY_TIME_BLOCKS) -> dict:
    """The median depth's change with each input of the depth budget alone at each end (the
    others nominal), with every envelope parameter at once, and the budget's interval: per band,
    the median over the footprint of each pixel's median limit over its observable times, minus
    the nominal one, over ``time_blocks`` of the cube's time blocks evenly spread over the
    campaign.

    Parameters
    ----------
    background_store : str or path-like
        background.zarr (``total``, the parts the envelope scales, ``observable``); the
        envelope members' re-evaluated groups, which it does not store, are evaluated again at
        the time blocks read (the campaign's model at each member's values).
    campaign : Campaign
        The campaign (envelope, exposures).
    time_blocks : int
        Time blocks (chunks) of the cube read at most.

    Returns
    -------
    dict
        ``bands`` (list), ``nominal`` (band -> median depth, mag), ``rows``: list of
        (input key, end, band -> change in median depth, mag; negative: shallower): every input
        of the depth budget (:func:`~straylight.limits.budget.depth_budget`, the
        envelope's parameters among them) alone at each end, then every envelope parameter at
        once ("all": pessimistic, optimistic) and the budget's central interval ("budget": p16,
        p84); ``times`` (how many times were read).
    """
    import zarr

    from straylight.limits.budget import BUDGET_VARIABLES, budget_limits, depth_budget, term_limits
    from straylight.limits.envelope import _part, envelope_limits
    from straylight.limits.point_source import band_limits, campaign_exposures
    from straylight.model.envelope import ENDS, campaign_envelope

    group = zarr.open_group(str(background_store), mode="r", use_consolidated=False)
    bands = [str(b) for b in group["band"][...]]
    env = campaign_envelope(campaign, bands)
    terms = depth_budget(campaign, bands)
    exposures = campaign_exposures(campaign, bands)
    region = _sampled_region(background_store, campaign, group, (env, terms), time_blocks)
    obs = region["observable"]
    median_depth = functools.partial(_median_depth, obs=obs, n_bands=len(bands))
    nominal = median_depth(np.where(obs[..., None], band_limits(region["total"], exposures), np.nan))
    rows = []
    # every input of the depth budget alone at each end (the envelope's parameters among them)
    where = np.nonzero(np.asarray(obs, bool))
    tot = np.asarray(region["total"])[where]
    leaves = list(dict.fromkeys(leaf for t in terms for leaf in t.leaves))
    parts = {leaf: _part(region, leaf, where) for leaf in leaves}
    for term in terms:
        for i, end in enumerate(ENDS):
            lim = np.full(np.shape(region["total"]), np.nan, np.float32)
            lim[where] = term_limits(term, i, tot, parts, exposures)
            change = median_depth(lim) - nominal
            rows.append((term.key, end, dict(zip(bands, change.tolist()))))
    if env.parameters:  # the envelope's ends: every parameter at once
        lims = envelope_limits(env, region, exposures)
        for end in ENDS:
            change = median_depth(lims[f"limiting_mag_{end}"]) - nominal
            rows.append(("all", end, dict(zip(bands, change.tolist()))))
    if terms:  # the budget's central interval
        lims = budget_limits(terms, region, exposures)
        for key, (name, _) in BUDGET_VARIABLES.items():
            change = median_depth(lims[name]) - nominal
            rows.append(("budget", key, dict(zip(bands, change.tolist()))))
    return {
        "bands": bands,
        "nominal": dict(zip(bands, nominal.tolist())),
        "rows": rows,
        "times": int(obs.shape[0]),
    }


def _median_depth(lim, obs, n_bands: int) -> np.ndarray:
    """Per band, the median over the pixels of each pixel's median limit over its observable
    times (``obs``), mag; NaN where no pixel is ever observable."""
    from straylight.limits.cube import limit_summaries

    med = limit_summaries(lim, obs)[1]
    with np.errstate(all="ignore"):
        return np.array(
            [np.nanmedian(med[:, ib]) if np.isfinite(med[:, ib]).any() else np.nan for ib in range(n_bands)]
        )


def _sampled_region(background_store, campaign, group, inputs: tuple, time_blocks: int) -> dict:
    """The background's variables :func:`envelope_sensitivity` reads (e-/s/pix, and
    ``observable``) over at most ``time_blocks`` of its time blocks evenly spread, every
    pixel; the envelope members' re-evaluated groups (``inputs``: envelope, budget terms),
    which the store does not hold, evaluated again."""
    from straylight.cube.footprint import footprint_from_store
    from straylight.cube.layout import ENVELOPE_END_VARIABLES
    from straylight.cube.region import envelope_end_values
    from straylight.model import BackgroundModel
    from straylight.storage.zarr_io import read_region

    env, terms = inputs
    chunk = int(group["total"].chunks[0])
    n_time = int(group["total"].shape[0])
    starts = np.arange(0, n_time, chunk)
    pick = starts[
        np.unique(np.linspace(0, starts.size - 1, min(time_blocks, starts.size)).round().astype(int))
    ]
    budget_leaves = [leaf for t in terms for leaf in t.leaves]
    names = [n for n in ("total", "earthshine", "earthshine_door", *env.leaves, *budget_leaves) if n in group]
    names = list(dict.fromkeys(names))
    parts = {n: [] for n in names + ["observable"]}
    # the members' re-evaluated groups are the cube workers', not stored: evaluated again here
    regroup = [n for n in ENVELOPE_END_VARIABLES if n in env.leaves and n not in group]
    parts.update({n: [] for n in regroup})
    model = BackgroundModel(campaign) if regroup else None
    fp = footprint_from_store(background_store) if regroup else None
    for t0 in pick:
        t_slice = slice(int(t0), int(min(t0 + chunk, n_time)))
        for n in names + ["observable"]:
            parts[n].append(read_region(group[n], (t_slice, slice(None))))
        if regroup:
            again = envelope_end_values(campaign, fp, t_slice, slice(None), model)
            for n in regroup:
                parts[n].append(again[n])
    return {n: np.concatenate(v) for n, v in parts.items()}


def sensitivity_chart(result: dict, campaign, out_dir) -> list:
    """The sensitivity chart (bars per band: the median depth's change with each parameter alone
    at each end, and with all) and its table :data:`SENSITIVITY_TABLE`.

    Parameters
    ----------
    result : dict
        :func:`envelope_sensitivity`'s.
    campaign : Campaign
        The campaign (its name).
    out_dir : str or path-like
        Folder of the figure and table.

    Returns
    -------
    list of pathlib.Path
        ``envelope_sensitivity.png`` and the table.
    """
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    from straylight.util.io import atomic_path

    bands, rows = result["bands"], result["rows"]
    fig = Figure(figsize=(14, 4.6), dpi=FIGURE_DPI)
    ax = fig.add_subplot(111)
    width = 0.8 / max(len(rows), 1)
    colours = {}
    for k, (key, end, d) in enumerate(rows):
        c = colours.setdefault(key, colormaps["tab20"](2 * len(colours) % 20 + (len(colours) >= 10)))
        x = np.arange(len(bands)) + (k - (len(rows) - 1) / 2) * width
        ax.bar(
            x,
            [d[b] for b in bands],
            width,
            color=c,
            alpha=1.0 if end in ("pessimistic", "p16") else 0.45,
            label=f"{key}: {end}",
        )
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xticks(np.arange(len(bands)), bands)
    ax.set_ylabel("change of the median depth, mag (negative: shallower)")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    ax.set_title(
        f"{campaign.name}: median 5-sigma depth over the footprint, each input of the depth budget alone "
        f"at its bright (pessimistic) and dark (optimistic) end, every envelope parameter at once (all) and "
        f"the budget's 16th-84th percentile ({result['times']} times read)",
        fontsize=9,
    )
    out_dir = Path(out_dir)
    written = [_save(fig, out_dir / "envelope_sensitivity.png")]
    path = out_dir / SENSITIVITY_TABLE
    with atomic_path(path) as tmp:
        lines = ["parameter,end," + ",".join(bands)]
        lines.append("nominal median depth,," + ",".join(f"{result['nominal'][b]:.3f}" for b in bands))
        lines += [f"{key},{end}," + ",".join(f"{d[b]:+.3f}" for b in bands) for key, end, d in rows]
        Path(tmp).write_text("\n".join(lines) + "\n")
    return written + [path]


def envelope_figures(limits_ds, background_store, campaign, out_dir) -> list:
    """The envelope's spread maps (:func:`spread_maps`) and, with ``background_store``, its
    sensitivity chart and table (:func:`envelope_sensitivity`).

    Parameters
    ----------
    limits_ds : xarray.Dataset
        limits.zarr's per-pixel summaries.
    background_store : str or path-like or None
        background.zarr; None: no sensitivity chart.
    campaign : Campaign
        The campaign.
    out_dir : str or path-like
        Folder of the figures.

    Returns
    -------
    list of pathlib.Path
        The files written.
    """
    written = spread_maps(limits_ds, campaign, out_dir)
    if background_store is not None and written:
        written += sensitivity_chart(envelope_sensitivity(background_store, campaign), campaign, out_dir)
    return written
