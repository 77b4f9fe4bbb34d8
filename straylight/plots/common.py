"""What the report's figures share: AB magnitudes of the cube's rates, full-sky maps of its
pixels, colour ranges and ticks, and saving a figure as PNG.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = [
    "DEPTH_CMAP",
    "DEPTH_PERCENTILES",
    "FIGURE_DPI",
    "MIN_COLOUR_SPAN_MAG",
    "OUTSIDE_COLOUR",
    "SKY_CMAP",
    "SKY_PERCENTILES",
    "band_colour_limits",
]


def _mag(ds, e_per_s, band: str, campaign):
    """AB mag/arcsec2 of ``e_per_s`` (e-/s/pix) in ``band``: through the product's own
    ``mag_zero_point`` coordinate where ``ds`` has it (the number a reader of the store uses,
    computed from the instrument as below), else from the campaign's instrument."""
    from straylight.limits.point_source import ZERO_POINT_NAME

    if ZERO_POINT_NAME in ds.coords:  # photometry.magnitude_per_arcsec2 at the stored zero point
        zp = float(ds[ZERO_POINT_NAME].sel(band=band))
        with np.errstate(divide="ignore"):
            return zp - 2.5 * np.log10(np.asarray(e_per_s, dtype=float))
    from straylight.optics.bandpass import load_band
    from straylight.sources.photometry import magnitude_per_arcsec2

    b = load_band(campaign.instrument_settings, band, campaign.instrument_path.parent)
    return magnitude_per_arcsec2(
        e_per_s, b, campaign.instrument_value("telescope", "aperture_diameter_m"), campaign.pixel_scale_arcsec
    )


def _full_sky(ds, values):
    import healpy as hp

    m = np.full(hp.nside2npix(int(ds.attrs["healpix_nside"])), hp.UNSEEN)
    v = np.asarray(values, float)
    m[np.asarray(ds["pixel"])] = np.where(np.isfinite(v), v, hp.UNSEEN)
    return m


def _tick_format(lo: float, hi: float, n: int = 4):
    """Rounded colour-bar ticks for [lo, hi]: a matplotlib locator and formatter with as few
    decimals as the tick step needs."""
    from matplotlib.ticker import FormatStrFormatter, MaxNLocator

    loc = MaxNLocator(n, steps=[1, 2, 2.5, 5, 10])
    ticks = loc.tick_values(lo, hi)
    step = float(np.min(np.diff(ticks))) if ticks.size > 1 else max(hi - lo, 1.0)
    decimals = int(max(0, -np.floor(np.log10(step) + 1e-9)))
    return loc, FormatStrFormatter(f"%.{decimals}f")


#: The colour of the maps' pixels outside the footprint (or without a value: never observable, a
#: component's 0), light grey: distinct from every colour of the colour scales below
OUTSIDE_COLOUR = "0.82"
#: The colour scales: the limiting-magnitude maps (deeper: brighter) and the background maps
#: (brighter sky: yellow).  Neither has black at either end, so that a pixel clipped to the end of
#: its scale never reads as a hole in the footprint.
DEPTH_CMAP, SKY_CMAP = "plasma", "viridis_r"
#: Percentiles of the in-footprint values that set a colour scale's ends; pixels beyond are drawn
#: in the end colours (the colour bar's triangles).  Depth maps pile up within a few 0.01 mag of
#: the dark-sky limit with a tail of a few per cent up to 1 mag shallower next to the Sun and the
#: Moon: the 5th percentile keeps that tail from taking the whole scale (the default day's g band:
#: 2nd percentile 25.65, 5th 26.33, median 26.54 mag).  Background maps span many magnitudes and
#: are not piled up: their 2nd-98th percentile.
DEPTH_PERCENTILES = (5.0, 99.5)
SKY_PERCENTILES = (2.0, 98.0)
#: The smallest span of a colour scale, mag: depths or sky brightnesses that differ by less are
#: shown as (nearly) one colour rather than stretched over the whole scale.  0.1 mag of depth is
#: 20 % of exposure time for a background-limited source, about the least a planner acts on.
MIN_COLOUR_SPAN_MAG = 0.1


def band_colour_limits(
    maps, percentiles=DEPTH_PERCENTILES, min_span: float = MIN_COLOUR_SPAN_MAG
) -> tuple[float, float]:
    """One colour scale for every map of one band (a depth map's median and best, or the maps of
    several times): the ``percentiles`` of all their in-footprint values together, widened
    symmetrically to ``min_span`` where they are nearly uniform.

    Parameters
    ----------
    maps : iterable of array_like
        The band's maps (pixel values, or full HEALPix maps): non-finite values and healpy's
        ``UNSEEN`` (outside the footprint) are left out.
    percentiles : (float, float)
        Lower and upper percentile (0-100) of the values pooled over ``maps``.
    min_span : float
        The smallest ``vmax - vmin``, in the maps' unit (mag).

    Returns
    -------
    (float, float)
        ``(vmin, vmax)`` in the maps' unit; (20, 30) if no map has a value.
    """
    from healpy import UNSEEN

    pooled = [np.asarray(m, float).ravel() for m in maps]
    v = np.concatenate(pooled) if pooled else np.empty(0)
    v = v[np.isfinite(v) & (v != UNSEEN)]
    if v.size == 0:
        return 20.0, 30.0
    lo, hi = (float(x) for x in np.percentile(v, percentiles))
    if hi - lo < min_span:
        mid = 0.5 * (lo + hi)
        lo, hi = mid - min_span / 2, mid + min_span / 2
    return lo, hi


#: the figures' resolution (dots per inch)
FIGURE_DPI = 90


def _save(fig, path: Path) -> Path:
    """``fig`` to ``path`` as PNG, cropped to its artists' tight box (the colour bars' labels
    overhang the axes) with matplotlib's padding.  The box is measured here, at the saving
    resolution, and handed to ``savefig``: ``bbox_inches="tight"`` would first run a whole draw
    (every panel's image resampled) only to measure it."""
    import matplotlib as mpl
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from straylight.util.io import atomic_path

    canvas = (
        fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    )  # savefig's PNG one
    dpi = fig.dpi
    fig.dpi = FIGURE_DPI
    try:
        bbox = fig.get_tightbbox(canvas.get_renderer()).padded(mpl.rcParams["savefig.pad_inches"])
    finally:
        fig.dpi = dpi
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=FIGURE_DPI, format="png", bbox_inches=bbox)
    return path
