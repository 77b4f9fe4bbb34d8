"""A campaign's size before anything is built: its times counted from the config (no time array),
and a warning when the products would be unusually large (``straylight plan`` prints it,
``straylight run`` gives it before Snakemake starts)."""

from __future__ import annotations

import math

__all__ = ["LARGE_PRODUCT_BYTES", "campaign_size", "size_warning"]

#: Products' bytes on disk above which a campaign is warned about before it runs: 20 GB, over
#: five years at the default 300 s cadence on the default nside-16 footprint (3.5 GB a year).  A
#: warning threshold, not a model parameter (`straylight plan` prices the products at
#: PRODUCT_BYTES_PER_SAMPLE).
LARGE_PRODUCT_BYTES = 20e9


def campaign_size(campaign, n_pixels: int) -> dict:
    """The campaign's times (counted as :func:`straylight.sky.timeutil.campaign_times` makes
    them), samples (times x ``n_pixels``) and products' bytes on disk, without building the times.

    Parameters
    ----------
    campaign : straylight.config.Campaign
        Loaded campaign.
    n_pixels : int
        The footprint's pixels.

    Returns
    -------
    dict
        ``times`` and ``samples`` (int), ``product_bytes`` (float, bytes).
    """
    from straylight.planning.plan import PRODUCT_BYTES_PER_SAMPLE
    from straylight.sky.timeutil import parse_utc, quiet_dubious_years

    c = campaign.settings.campaign
    with quiet_dubious_years():
        span_s = float((parse_utc(c.end) - parse_utc(c.start)).to_value("s"))
    nt = int(math.ceil(span_s / float(c.cadence_s) - 1e-9))
    n = nt * int(n_pixels)
    return {"times": nt, "samples": n, "product_bytes": n * PRODUCT_BYTES_PER_SAMPLE}


def size_warning(campaign, n_pixels: int) -> str | None:
    """One line when the campaign's products exceed :data:`LARGE_PRODUCT_BYTES`, naming the
    config, its cadence, the samples and the bytes; None otherwise.

    Parameters
    ----------
    campaign : straylight.config.Campaign
        Loaded campaign.
    n_pixels : int
        The footprint's pixels.

    Returns
    -------
    str or None
        The warning, or None for a campaign of ordinary size.
    """
    size = campaign_size(campaign, n_pixels)
    if size["product_bytes"] <= LARGE_PRODUCT_BYTES:
        return None
    c = campaign.settings.campaign
    return (
        f"{campaign.path}: campaign.cadence_s = {c.cadence_s:g} over {c.start} .. {c.end} gives "
        f"{size['times']:,} times x {int(n_pixels):,} pixels = {size['samples']:.3g} samples and "
        f"~{size['product_bytes'] / 1e9:,.0f} GB of products (over {LARGE_PRODUCT_BYTES / 1e9:.0f} GB): "
        "check the cadence, the dates and footprint.nside"
    )
