"""What the report's figures share: AB magnitudes of the cube's rates, full-sky maps of its
pixels, colour ranges and ticks, and saving a figure as PNG.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["FIGURE_DPI"]


def _mag(ds, e_per_s, band: str, campaign):
    """AB mag/arcsec2 of ``e_per_s`` (e-/s/pix) in ``band``: through the product's own
    ``mag_zero_point`` coordinate where ``ds`` has it (the number a reader of the store uses,
    computed from the instrument as below), else from the campaign's instrument."""
    from straylight.survey.limits import ZERO_POINT_NAME

    if ZERO_POINT_NAME in ds.coords:  # photometry.magnitude_per_arcsec2 at the stored zero point
        zp = float(ds[ZERO_POINT_NAME].sel(band=band))
        with np.errstate(divide="ignore"):
            return zp - 2.5 * np.log10(np.asarray(e_per_s, dtype=float))
    from straylight.optics.bandpass import load_band
    from straylight.sources.photometry import magnitude_per_arcsec2

    b = load_band(campaign.instrument, band, campaign.instrument_path.parent)
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


def _colour_range(values, percentiles=(2.0, 98.0), min_span: float = 0.01) -> tuple[float, float]:
    """The range of the colour scale: the given percentiles of the finite values, widened
    symmetrically to ``min_span`` where the values are nearly uniform."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
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
