"""Time series of chosen pointings: every component and the total per band against time, over
the first orbit and over the whole campaign, in AB mag/arcsec2 with unobservable times shaded.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from straylight.plots.common import _mag, _save

__all__ = ["ORBIT_MINUTES", "pointing_series", "series_pixel_indices", "time_series", "time_series_figures"]


ORBIT_MINUTES = 92.6  # ~400 km circular orbit: the first-orbit panel spans this long


def series_pixel_indices(ds, n_pointings: int = 3, pointings=()) -> list[int]:
    """Indices into ``ds.pixel`` of the time series' pointings: the footprint pixels nearest
    ``pointings`` ([ra, dec] deg) if given, else ``n_pointings`` pixels evenly spread."""
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
    chunk by chunk in this thread (:func:`~straylight.survey.storage.read_region`)."""
    import zarr

    from straylight.model import registry
    from straylight.survey.storage import read_region

    group = zarr.open_group(str(background_path), mode="r", use_consolidated=False)
    names = list(registry.component_names(total=True)) + ["observable"]
    return [
        {n: read_region(group[n], (slice(None), slice(ip, ip + 1)))[:, 0] for n in names}
        for ip in pixel_indices
    ]


def time_series(ds, campaign, out_dir, pixel_indices, series: list[dict]) -> list:
    """For the pointings ``pixel_indices`` (into ``ds.pixel``, see :func:`series_pixel_indices`)
    and their ``series`` (:func:`pointing_series`): total and components in each band against
    time, over the first orbit and over the whole campaign; unobservable times shaded."""
    from matplotlib.figure import Figure
    from matplotlib.patches import PathPatch
    from matplotlib.ticker import MaxNLocator

    from straylight.model import registry

    comps = registry.component_names(total=True)
    pix_idx = list(pixel_indices)
    t = ds["time"].values
    minutes = (t - t[0]) / np.timedelta64(1, "m")
    written = []
    for ip, sub in zip(pix_idx, series):
        ra, dec = float(ds["ra_deg"][ip]), float(ds["dec_deg"][ip])
        obs = np.asarray(sub["observable"], bool)
        for span, sel in (("orbit", minutes <= ORBIT_MINUTES), ("campaign", np.ones(minutes.size, bool))):
            bands = list(ds["band"].values)
            fig = Figure(figsize=(10, 2.2 * len(bands)))
            axes = fig.subplots(len(bands), 1, sharex=True)
            shown = {}
            for ax, band in zip(np.atleast_1d(axes), bands):
                ib = bands.index(band)
                zp = float(_mag(ds, np.array([1.0]), str(band), campaign)[0])  # mag/arcsec2 at 1 e-/s/pix
                for k, comp in enumerate(comps):
                    y = np.asarray(sub[comp][:, ib], float)[sel]
                    if not np.any(y > 0):
                        continue  # zero all along: no line (listed in the title)
                    mag = np.where(y > 0, zp - 2.5 * np.log10(np.where(y > 0, y, 1.0)), np.nan)
                    (line,) = ax.plot(
                        minutes[sel],
                        mag,
                        lw=1.8 if comp == "total" else 1.0,
                        color="k" if comp == "total" else f"C{k}",
                        label=comp,
                    )
                    shown[comp] = line
                # each run of unobservable samples, first to last sample, over the axes' height
                # (an artist, not a patch: the data limits come from the lines)
                ax.add_artist(
                    PathPatch(
                        _span_path(minutes[sel], ~obs[sel]),
                        facecolor="0.88",
                        lw=0,
                        transform=ax.get_xaxis_transform(),
                    )
                )
                total = np.asarray(sub["total"][:, ib], float)[sel]
                tmag = zp - 2.5 * np.log10(total[total > 0]) if np.any(total > 0) else np.array([20.0])
                # brighter up; the faint end a few magnitudes below the total's faintest value
                ax.set_ylim(min(float(np.nanmax(tmag)) + 4.0, 32.0), float(np.nanmin(tmag)) - 1.0)
                ax.set_ylabel(f"{band}\nmag/arcsec2", fontsize=9)
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
            missing = [c for c in comps if c not in shown]
            fig.legend(
                handles=list(shown.values()),
                loc="upper center",
                ncol=len(shown),
                fontsize=8,
                bbox_to_anchor=(0.5, 0.965),
                frameon=False,
            )
            np.atleast_1d(axes)[-1].set_xlabel(
                f"minutes after {str(t[0])[:16]} UTC (grey: not observable)"
                + (f"; zero all along, not drawn: {', '.join(missing)}" if missing else "")
            )
            fig.suptitle(
                f"{campaign.name}: pointing RA {ra:.1f}, Dec {dec:.1f} deg, {span} (AB mag/arcsec2, "
                "brighter up; e-/s/pixel = 10^(-0.4 (mag - zero point)))",
                fontsize=10,
            )
            fig.tight_layout(rect=(0, 0, 1, 0.95))
            written.append(_save(fig, Path(out_dir) / f"series_{span}_ra{ra:06.2f}_dec{dec:+06.2f}.png"))
    return written


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


def time_series_figures(background_path, campaign, out_dir) -> list:
    """The time series (:func:`time_series`) of the report's pointings (``report.pointings``,
    else ``report.series_pointings`` spread over the footprint) in ``out_dir``, each pointing's
    whole series read in one pass over its pixel's chunks (:func:`pointing_series`).  Returns
    the paths written."""
    import xarray as xr

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rc = campaign.settings.report
    # chunks=None: no dask, the coordinates read as they are needed; the arrays' own metadata
    # (rule background may be consolidating it meanwhile)
    with xr.open_zarr(background_path, chunks=None, consolidated=False) as ds:
        pixels = series_pixel_indices(ds, int(rc.series_pointings), rc.pointings)
        return time_series(ds, campaign, out, pixels, pointing_series(background_path, pixels))
