"""Knobs of the off-field stars: the split between stars summed directly and the smoothed
faint-star map, and the tolerance that sizes the direct stars' skip per sky cell."""

from __future__ import annotations

from .common import DEFAULT, sweep


def star_split_rows(bench, ref, quick: bool):
    """The direct magnitude limit, with and without the faint-star map."""
    s = (
        [(-99.0, True), (2.0, True), (4.0, True), (4.0, False)]
        if quick
        else [
            (-99.0, True),
            (0.0, True),
            (2.0, True),
            (4.0, True),
            (6.0, True),
            (2.0, False),
            (4.0, False),
            (6.0, False),
            (8.0, False),
        ]
    )
    return sweep(
        bench,
        ref,
        "stars",
        [(f"direct <= {lim:g}{' + map' if f else ''}", DEFAULT, bench.stars(lim, f)) for lim, f in s],
    )


def star_skip_rows(bench, ref, stars, quick: bool):
    """The tolerance (models.tolerance) that sizes the direct stars' skip on their bound."""
    tols = [1e-12, 1e-2, 1e-1] if quick else [1e-12, 1e-3, 1e-2, 3e-2, 1e-1]
    return sweep(
        bench, ref, "star skip", [(f"tolerance {t:g}", {**DEFAULT, "tolerance": t}, stars) for t in tols]
    )
