"""Knob of the PST: the grid step at which the default matrix is interpolated."""

from __future__ import annotations

from .common import DEFAULT, sweep


def pst_grid_rows(bench, ref, stars, quick: bool):
    """The PST grid step (deg, two ranges)."""
    p = (
        [(0.5, 5.0), (0.25, 2.5), (0.1, 1.0)]
        if quick
        else [(2.0, 20.0), (1.0, 10.0), (0.5, 5.0), (0.25, 2.5), (0.1, 1.0)]
    )
    return sweep(
        bench, ref, "PST grid", [(f"{a} x {b} deg", {**DEFAULT, "pst_step": (a, b)}, stars) for a, b in p]
    )
