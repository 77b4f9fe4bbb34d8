"""The campaign's time grid split into time blocks (the grid itself:
:func:`straylight.sky.timeutil.campaign_times`)."""

from __future__ import annotations

__all__ = ["time_blocks"]


def time_blocks(n_times: int, cadence_s: float, block_hours: float) -> list[tuple[int, int]]:
    """Split sample indices [0, n_times) into blocks of about ``block_hours``: (start, stop).

    Parameters
    ----------
    n_times : int
        Samples in the time grid.
    cadence_s : float
        Time between samples, s.
    block_hours : float
        Length of a block asked for, h (rounded to whole samples, at least one).

    Returns
    -------
    list of tuple of int
        ``(start, stop)`` sample indices, covering [0, n_times) in order; the last may be shorter.
    """
    per_block = max(1, int(round(block_hours * 3600.0 / cadence_s)))
    return [(i, min(i + per_block, n_times)) for i in range(0, n_times, per_block)]
