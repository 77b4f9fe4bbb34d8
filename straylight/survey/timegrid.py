"""The campaign's time grid and its split into time blocks."""
from __future__ import annotations

import numpy as np
from astropy.time import Time, TimeDelta

from straylight.errors import ConfigError
from straylight.sky.timeutil import parse_utc


def campaign_times(start, end, cadence_s: float) -> Time:
    """UTC times start, start + cadence, ... strictly before end."""
    t0 = parse_utc(start, "campaign.start")
    t1 = parse_utc(end, "campaign.end")
    span_s = float((t1 - t0).to_value("s"))
    if span_s <= 0:
        raise ConfigError(f"campaign.end {t1.isot} must be after campaign.start {t0.isot}")
    n = int(np.ceil(span_s / cadence_s - 1e-9))
    return t0 + TimeDelta(np.arange(n) * cadence_s, format="sec")


def time_blocks(n_times: int, cadence_s: float, block_hours: float) -> list[tuple[int, int]]:
    """Split sample indices [0, n_times) into blocks of about ``block_hours``: (start, stop)."""
    per_block = max(1, int(round(block_hours * 3600.0 / cadence_s)))
    return [(i, min(i + per_block, n_times)) for i in range(0, n_times, per_block)]
