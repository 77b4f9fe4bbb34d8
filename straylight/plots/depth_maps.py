"""The 5-sigma limiting-magnitude maps over a campaign: a page per depth statistic, one Mollweide
panel per band (:class:`~straylight.plots.maps.MollweidePanel`), each band on one colour scale over
all its depth maps, with the Sun's track over the campaign."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from straylight.plots.common import (
    DEPTH_CMAP,
    DEPTH_PERCENTILES,
    MIN_COLOUR_SPAN_MAG,
    _full_sky,
    _save,
    band_colour_limits,
)
from straylight.plots.maps import ORIENTATION, MollweidePanel, _percentiles, overlay_legend
from straylight.plots.overlays import sun_radec_deg, sun_track_times

__all__ = ["DEPTH_MAP_STATS", "depth_colour_limits", "limit_maps"]


#: The per-pixel depth maps drawn, when the limits store has them (``limiting_mag_<stat>``,
#: (pixel, band), AB mag): the median and best over the campaign, and the median at the
#: assumption envelope's pessimistic and optimistic ends where the store carries them
DEPTH_MAP_STATS = ("median", "best", "median_pessimistic", "median_optimistic")


def depth_colour_limits(limits_ds) -> dict:
    """One colour scale per band for all its depth maps (the ``limiting_mag_<stat>`` of
    :data:`DEPTH_MAP_STATS` that ``limits_ds`` has): band -> (vmin, vmax), AB mag, from
    :func:`~straylight.plots.common.band_colour_limits` over the maps' values together.

    Parameters
    ----------
    limits_ds : xarray.Dataset
        The limits product.
    """
    names = [f"limiting_mag_{s}" for s in DEPTH_MAP_STATS if f"limiting_mag_{s}" in limits_ds]
    return {
        str(band): band_colour_limits(
            [np.asarray(limits_ds[n].isel(band=ib), float) for n in names], DEPTH_PERCENTILES
        )
        for ib, band in enumerate(limits_ds["band"].values)
    }


def limit_maps(limits_ds, campaign, out_dir) -> list:
    """Per depth statistic of :data:`DEPTH_MAP_STATS` that ``limits_ds`` has, a page of its
    5-sigma limiting-magnitude maps over the campaign, one panel per band, each band on one
    colour scale over all its depth maps (:func:`depth_colour_limits`), with the Sun's track over
    the campaign.  Returns the paths written.

    Parameters
    ----------
    limits_ds : xarray.Dataset
        The limits product.
    campaign : Campaign
        The campaign.
    out_dir : str or pathlib.Path
        The folder the pages are written to.
    """
    from matplotlib.figure import Figure

    nest = str(limits_ds.attrs.get("healpix_ordering", "RING")).upper() == "NESTED"
    limits = depth_colour_limits(limits_ds)
    times = campaign.times
    sun = sun_radec_deg(sun_track_times(times))
    span = f"{times[0].isot[:16]} to {times[-1].isot[:16]} UTC"
    written = []
    for stat in DEPTH_MAP_STATS:
        var = f"limiting_mag_{stat}"
        if var not in limits_ds:
            continue
        bands = [str(b) for b in limits_ds["band"].values]
        nrow = int(np.ceil(len(bands) / 4))
        fig = Figure(figsize=(16, 3.4 * nrow))
        for ib, band in enumerate(bands):
            v = np.asarray(limits_ds[var].isel(band=ib), float)
            med = float(np.nanmedian(v)) if np.isfinite(v).any() else float("nan")
            MollweidePanel(fig, (nrow, 4, ib + 1), DEPTH_CMAP, _depth_unit(limits_ds, stat, ib)).show(
                _full_sky(limits_ds, v),
                nest,
                f"{band}: median over the footprint {med:.2f}",
                *limits[band],
                sun,
            )
        overlay_legend(fig, "track", "outside the footprint, or never observable")
        fig.suptitle(
            f"{campaign.name}: {stat.replace('_', ' ')} 5-sigma point-source limit over the campaign, "
            f"{span} (AB mag; deeper: brighter)\n{ORIENTATION}\n"
            f"colours: each band's {_percentiles(DEPTH_PERCENTILES)} over all its depth maps, at least "
            f"{MIN_COLOUR_SPAN_MAG:g} mag (one scale for the band's maps; beyond: the end colours, the "
            "bar's triangles)",
            fontsize=10,
        )
        written.append(_save(fig, Path(out_dir) / f"limits_{stat}.png"))
    return written


def _depth_unit(limits_ds, stat: str, ib: int) -> str:
    """A depth map's colour-bar label: what is shown, its unit and the band's survey exposures."""
    exposures = ""
    if "n_exposures" in limits_ds.coords and "exposure_s" in limits_ds.coords:
        n, t = int(limits_ds["n_exposures"][ib]), float(limits_ds["exposure_s"][ib])
        exposures = f", {n} x {t:g} s"
    return f"{stat.replace('_', ' ')} 5σ point-source limit, AB mag{exposures}"
