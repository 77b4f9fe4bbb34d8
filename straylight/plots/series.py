"""Time series of chosen pointings: every component and the total per band against time, over
the first orbit (the model evaluated every minute) and over the whole campaign (the cube's
samples), in AB mag/arcsec2 with unobservable times shaded.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from straylight.plots.common import _mag, _save

__all__ = [
    "ORBIT_MINUTES",
    "ORBIT_STEP_MINUTES",
    "model_series",
    "pointing_series",
    "series_pixel_indices",
    "time_series",
    "time_series_figures",
]


ORBIT_MINUTES = 92.6  # ~400 km circular orbit: the first-orbit panel spans this long
#: the first-orbit panel's step: the model evaluated this often (a campaign's cadence, 5-10 min,
#: draws an orbit's Earth-limb passes with a handful of points)
ORBIT_STEP_MINUTES = 1.0
#: the time series' faint end: this far below the total's faintest value (mag), at most 32
SERIES_DEPTH_MAG = 4.0


def series_pixel_indices(ds, n_pointings: int = 3, pointings=()) -> list[int]:
    """Indices into ``ds.pixel`` of the time series' pointings: the footprint pixels nearest
    ``pointings`` ([ra, dec] deg) if given, else ``n_pointings`` pixels evenly spread.

    Parameters
    ----------
    ds : xarray.Dataset
        The background cube (its ``pixel``, ``ra``, ``dec``).
    n_pointings : int, optional
        Number of evenly spread pixels when ``pointings`` is empty (default 3).
    pointings : sequence of (float, float), optional
        Pointings as [RA, Dec], deg.
    """
    if pointings:
        from straylight.sky.vectors import radec_to_unit

        centres = radec_to_unit(np.asarray(ds["ra_deg"]), np.asarray(ds["dec_deg"]))
        wanted = np.atleast_2d(radec_to_unit(*np.asarray(pointings, float).T, "report.pointings"))
        pix_idx = np.unique(np.argmax(wanted @ centres.T, axis=1))
    else:
        pix_idx = np.unique(np.linspace(0, ds.sizes["pixel"] - 1, n_pointings).round().astype(int))
    return [int(i) for i in pix_idx]


def pointing_series(background_path, pixel_indices) -> list[dict]:
    """Per pointing of ``pixel_indices`` (into the cube's ``pixel``), its whole series in the
    background cube at ``background_path``: name -> (time[, band]) array of every component,
    the total (:func:`~straylight.model.registry.component_names`) and ``observable``.  Read
    chunk by chunk in this thread (:func:`~straylight.storage.zarr_io.read_region`)."""
    import zarr

    from straylight.model import registry
    from straylight.storage.zarr_io import read_region

    group = zarr.open_group(str(background_path), mode="r", use_consolidated=False)
    names = list(registry.component_names(total=True)) + ["observable"]
    return [
        {n: read_region(group[n], (slice(None), slice(ip, ip + 1)))[:, 0] for n in names}
        for ip in pixel_indices
    ]


def model_series(campaign, ds, pixel_indices, minutes, stars_path=None, model=None) -> list[dict]:
    """Per pointing of ``pixel_indices`` (into ``ds.pixel``: its centre), the background model
    at ``minutes`` after the cube's first time, in the cube's bands: name -> (time, band) array
    of every component and the total (e-/s/pixel), ``observable`` (time,) and ``minutes``.
    ``stars_path``: the campaign's star catalog (None: stars = 0); ``model``: a warm
    :class:`~straylight.model.BackgroundModel` of ``campaign`` (None: one is built).

    Parameters
    ----------
    campaign : Campaign
        The campaign.
    ds : xarray.Dataset
        The background cube.
    pixel_indices : sequence of int
        Indices into ``ds.pixel``.
    minutes : array_like
        Times after the cube's first time, min.
    stars_path : str or pathlib.Path, optional
        The campaign's star catalog (None: stars = 0).
    model : BackgroundModel, optional
        A warm model of ``campaign`` (None: one is built).
    """
    import astropy.units as u
    from astropy.time import Time

    from straylight.cube.region import offfield_stars
    from straylight.model import registry
    from straylight.planning.pointings import background_table

    bands = [str(b) for b in ds["band"].values]
    minutes = np.asarray(minutes, float)
    t = Time(np.datetime64(ds["time"].values[0], "ns"), scale="utc") + minutes * u.min
    stars = offfield_stars(campaign, stars_path)
    out = []
    for ip in pixel_indices:
        ra, dec = (np.full(minutes.size, float(ds[k].values[ip])) for k in ("ra_deg", "dec_deg"))
        table = background_table(campaign, t, ra, dec, bands, stars, model=model)
        sub = {
            c: np.stack([np.asarray(table[f"{c}_{b}"].value, float) for b in bands], axis=1)
            for c in registry.component_names(total=True)
        }
        sub["observable"] = np.asarray(table["observable"], bool)
        sub["minutes"] = minutes
        out.append(sub)
    return out


def time_series(ds, campaign, out_dir, pixel_indices, series: list[dict], orbit_series=None) -> list:
    """For the pointings ``pixel_indices`` (into ``ds.pixel``, see :func:`series_pixel_indices`)
    and their ``series`` (:func:`pointing_series`): total and components in each band against
    time, over the first orbit (``orbit_series``, :func:`model_series`, if given; else the
    cube's samples) and over the whole campaign; unobservable times shaded.  The legend lists
    the curves that enter the axes; the x label names those that do not.

    Parameters
    ----------
    ds : xarray.Dataset
        The background cube.
    campaign : Campaign
        The campaign.
    out_dir : str or pathlib.Path
        The folder the figures are written to.
    pixel_indices : sequence of int
        Indices into ``ds.pixel``.
    series : list of dict
        Each pointing's series (:func:`pointing_series`).
    orbit_series : list of dict, optional
        Each pointing's series over the first orbit (:func:`model_series`).
    """
    from matplotlib.figure import Figure

    from straylight.model import registry

    comps = registry.component_names(total=True)
    pix_idx = list(pixel_indices)
    t = ds["time"].values
    minutes = (t - t[0]) / np.timedelta64(1, "m")
    written = []
    orbit_series = orbit_series if orbit_series is not None else [None] * len(series)
    for ip, sub, orbit in zip(pix_idx, series, orbit_series):
        ra, dec = float(ds["ra_deg"][ip]), float(ds["dec_deg"][ip])
        spans = [
            ("orbit", orbit, orbit["minutes"]) if orbit is not None else ("orbit", sub, minutes),
            ("campaign", sub, minutes),
        ]
        for span, values, x_all in spans:
            sel = x_all <= ORBIT_MINUTES if span == "orbit" else np.ones(x_all.size, bool)
            x = x_all[sel]
            obs = np.asarray(values["observable"], bool)[sel]
            bands = list(ds["band"].values)
            fig = Figure(figsize=(10, 2.2 * len(bands)))
            axes = fig.subplots(len(bands), 1, sharex=True)
            shown, nonzero = {}, set()
            for ax, band in zip(np.atleast_1d(axes), bands):
                ib = bands.index(band)
                zp = float(_mag(ds, np.array([1.0]), str(band), campaign)[0])  # mag/arcsec2 at 1 e-/s/pix
                curves = {c: np.asarray(values[c][:, ib], float)[sel] for c in comps}
                _draw_band(ax, x, curves, obs, (zp, band), (shown, nonzero))
            shown = {c: shown[c] for c in comps if c in shown}  # the registry's order
            zero = [c for c in comps if c not in nonzero]
            below = [c for c in comps if c in nonzero and c not in shown]
            fig.legend(
                handles=list(shown.values()),
                loc="upper center",
                ncol=max(1, len(shown)),
                fontsize=8,
                bbox_to_anchor=(0.5, 0.965),
                frameon=False,
            )
            step = (
                f"the model every {ORBIT_STEP_MINUTES:g} min"
                if span == "orbit" and orbit is not None
                else f"the cube's {float(campaign.settings.campaign.cadence_s) / 60:g}-min samples"
            )
            np.atleast_1d(axes)[-1].set_xlabel(
                f"minutes after {str(t[0])[:16]} UTC, {step} (grey: not observable)"
                + (f"; below the axes all along: {', '.join(below)}" if below else "")
                + (f"; zero all along: {', '.join(zero)}" if zero else "")
            )
            fig.suptitle(
                f"{campaign.name}: pointing RA {ra:.1f}, Dec {dec:.1f} deg, {span} (AB mag/arcsec2, "
                "brighter up; e-/s/pixel = 10^(-0.4 (mag - zero point)))",
                fontsize=10,
            )
            fig.tight_layout(rect=(0, 0, 1, 0.95))
            written.append(_save(fig, Path(out_dir) / f"series_{span}_ra{ra:06.2f}_dec{dec:+06.2f}.png"))
    return written


def _draw_band(ax, x, curves: dict, obs, band: tuple, found: tuple) -> None:
    """One band's axes of :func:`time_series`: each component's curve (``curves``: component ->
    e-/s/pix at minutes ``x``) in AB mag/arcsec2 through the band's zero point (``band``: zero
    point, name), the unobservable runs (``obs`` False) shaded; ``found`` (shown, nonzero)
    collects the lines that enter the axes and the components not zero all along."""
    from matplotlib.patches import PathPatch
    from matplotlib.ticker import MaxNLocator

    zp, name = band
    shown, nonzero = found
    total = curves["total"]
    tmag = zp - 2.5 * np.log10(total[total > 0]) if np.any(total > 0) else np.array([20.0])
    # brighter up; the faint end a few magnitudes below the total's faintest value
    faint, bright = (
        min(float(np.nanmax(tmag)) + SERIES_DEPTH_MAG, 32.0),
        float(np.nanmin(tmag)) - 1.0,
    )
    for k, (comp, y) in enumerate(curves.items()):
        if not np.any(y > 0):
            continue  # zero all along: no line (listed in the x label)
        nonzero.add(comp)
        mag = np.where(y > 0, zp - 2.5 * np.log10(np.where(y > 0, y, 1.0)), np.nan)
        (line,) = ax.plot(
            x,
            mag,
            lw=1.8 if comp == "total" else 1.0,
            color="k" if comp == "total" else f"C{k}",
            label=comp,
        )
        if np.any(mag <= faint):  # enters the axes somewhere: in the legend
            shown.setdefault(comp, line)
    # each run of unobservable samples, first to last sample, over the axes' height
    # (an artist, not a patch: the data limits come from the lines)
    ax.add_artist(PathPatch(_span_path(x, ~obs), facecolor="0.88", lw=0, transform=ax.get_xaxis_transform()))
    ax.set_ylim(faint, bright)
    ax.set_ylabel(f"{name}\nmag/arcsec2", fontsize=9)
    ax.yaxis.set_major_locator(MaxNLocator(4, integer=True))
    ax.grid(alpha=0.3, lw=0.5)
    # the band's zero point: e-/s/pixel = 10^(-0.4 (mag - zp))
    ax.text(
        1.005,
        0.5,
        f"zero point\n{zp:.2f}\n(1 e-/s/pix)",
        transform=ax.transAxes,
        fontsize=7,
        va="center",
        ha="left",
    )


def _span_path(x, mask):
    """One compound path of rectangles from ``x`` at the first to ``x`` at the last sample of
    each run of True in ``mask``, from y 0 to 1 (the axes' height under an x-axis transform)."""
    from matplotlib.path import Path as MplPath

    edges = np.flatnonzero(np.diff(np.r_[0, np.asarray(mask, np.int8), 0]))
    x0, x1 = np.asarray(x, float)[edges[::2]], np.asarray(x, float)[edges[1::2] - 1]
    zero, one = np.zeros_like(x0), np.ones_like(x0)
    verts = np.stack(
        [np.c_[x0, zero], np.c_[x0, one], np.c_[x1, one], np.c_[x1, zero], np.c_[x0, zero]], axis=1
    )
    codes = np.tile(
        [MplPath.MOVETO, MplPath.LINETO, MplPath.LINETO, MplPath.LINETO, MplPath.CLOSEPOLY], x0.size
    )
    return MplPath(verts.reshape(-1, 2), codes.astype(MplPath.code_type))


def time_series_figures(background_path, campaign, out_dir, stars_path=None) -> list:
    """The time series (:func:`time_series`) of the report's pointings (``report.pointings``,
    else ``report.series_pointings`` spread over the footprint) in ``out_dir``: over the first
    orbit the model every :data:`ORBIT_STEP_MINUTES` (:func:`model_series`, with the star
    catalog at ``stars_path``), over the campaign each pointing's whole series in the cube, read
    in one pass over its pixel's chunks (:func:`pointing_series`).  Returns the paths written.

    Parameters
    ----------
    background_path : str or pathlib.Path
        The background cube (Zarr).
    campaign : Campaign
        The campaign (its ``report`` settings).
    out_dir : str or pathlib.Path
        The folder the figures are written to.
    stars_path : str or pathlib.Path, optional
        The campaign's star catalog (None: stars = 0 over the first orbit).
    """
    import xarray as xr

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rc = campaign.settings.report
    # chunks=None: no dask, the coordinates read as they are needed; the arrays' own metadata
    # (rule background may be consolidating it meanwhile)
    with xr.open_zarr(background_path, chunks=None, consolidated=False) as ds:
        pixels = series_pixel_indices(ds, int(rc.series_pointings), rc.pointings)
        t = ds["time"].values
        span = min(ORBIT_MINUTES, float((t[-1] - t[0]) / np.timedelta64(1, "m")))
        minutes = np.arange(0.0, span + 1e-9, ORBIT_STEP_MINUTES)
        orbit = model_series(campaign, ds, pixels, minutes, stars_path)
        return time_series(ds, campaign, out, pixels, pointing_series(background_path, pixels), orbit)
