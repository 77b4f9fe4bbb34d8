"""The figure of the PST tail's calibration over orbital phases
(:func:`~straylight.paper.tail_calibration.calibrate_tail`): the crossing angle against the
argument of latitude (one line per node) and against the Sun's zenith angle at the satellite,
and the earthshine against the limb angle at every sunlit phase with HST's curve."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["plot_tail_calibration"]

#: where a phase that never crosses is drawn on the crossing axes, deg
_NEVER_DEG = 115.0


def plot_tail_calibration(
    summary: dict, out_png: str | Path, hst_curve: str | Path | None = None, default: dict | None = None
) -> None:
    """Write the calibration's figure.

    Parameters
    ----------
    summary : dict
        :func:`~straylight.paper.tail_calibration.calibrate_tail`'s (with its ``_crossings``).
    out_png : str or Path
        The PNG to write.
    hst_curve : str, Path or None
        HST's earthshine curve (CSV, :func:`~straylight.paper.scenarios.read_hst_curve`), drawn
        when given.
    default : dict or None
        :func:`~straylight.paper.tail_calibration.default_phase_crossing`'s, marked when given.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2, a3) = plt.subplots(1, 3, figsize=(16, 4.8))
    _crossing_panels(a1, a2, summary, default)
    _earthshine_panel(a3, summary, hst_curve)
    fig.suptitle(
        f"PST tail over orbital phases, {summary['time']} UTC (seed paper sect. 3.3): median crossing "
        f"{summary['median_crossing_deg']:.1f} deg",
        fontsize=10,
    )
    fig.tight_layout()
    fig.savefig(out_png, dpi=110)
    plt.close(fig)


def _crossing_panels(a1, a2, summary: dict, default: dict | None) -> None:
    """The crossing angle (deg) against the argument of latitude (``a1``, a line per node) and
    against the Sun's zenith angle at the satellite (``a2``)."""
    import matplotlib.pyplot as plt

    cross = np.asarray(summary["crossing_deg"], float)
    shown = np.where(np.isnan(cross), _NEVER_DEG, cross)
    raan, u, zen = (np.asarray(summary[k]) for k in ("raan_deg", "arg_latitude_deg", "sun_zenith_deg"))
    target = summary["target_deg"]
    cmap = plt.get_cmap("twilight")
    step = summary.get("u_step_deg", 10.0)
    for o in np.unique(raan):
        sel = raan == o
        order = np.argsort(u[sel])
        x, y = u[sel][order], shown[sel][order]
        gap = np.flatnonzero(np.diff(x) > 1.5 * step) + 1  # the line breaks where phases are dark
        x, y = np.insert(x, gap, np.nan), np.insert(y, gap, np.nan)
        a1.plot(x, y, "o-", ms=3, lw=0.8, color=cmap(o / 360.0), label=f"{o:g}")
    never = np.isnan(cross)
    a2.scatter(zen[~never], cross[~never], s=10, c=raan[~never], cmap="twilight", vmin=0, vmax=360)
    a2.scatter(zen[never], np.full(never.sum(), _NEVER_DEG), s=14, marker="^", c="k", label="never crosses")
    for ax in (a1, a2):
        ax.axhline(target, color="r", ls=":", lw=1, label=f"paper: {target:g} deg")
        ax.axhline(
            summary["median_crossing_deg"], color="b", ls="--", lw=1, label="median over sunlit phases"
        )
        ax.axhline(110.0, color="grey", lw=0.5)
        ax.set_ylabel("crossing angle above the bright limb (deg)")
        ax.set_ylim(0, _NEVER_DEG + 5)
    if default:
        for ax, x in ((a1, default["arg_latitude_deg"]), (a2, default["sun_zenith_deg"])):
            if np.isfinite(default["crossing_deg"]):
                ax.plot(x, default["crossing_deg"], "r*", ms=12, label="default orbit's phase")
    a1.set_xlabel("argument of latitude at the scenario's time (deg)")
    a1.set_title(f"crossing per phase (raan in legend, deg); {_NEVER_DEG:g} = never", fontsize=9)
    a1.legend(fontsize=6, ncol=3)
    a2.set_xlabel("Sun's zenith angle at the satellite (deg)")
    a2.set_title(f"sunlit phases: {cross.size}, never crossing: {int(never.sum())}", fontsize=9)
    a2.legend(fontsize=7)


def _earthshine_panel(a3, summary: dict, hst_curve) -> None:
    """The earthshine (V mag/arcsec2) against the limb angle at every sunlit phase, its
    percentiles over the phases and HST's curve when given."""
    from straylight.paper.scenarios import read_hst_curve

    tail, target, level = (
        summary["tail_log10_at_90deg"],
        summary["target_deg"],
        summary["level_v_mag_per_arcsec2"],
    )
    bins = summary["_crossings"]["bins"]
    for c, m, _ in bins:
        a3.plot(c, m, "-", color="0.6", lw=0.4, alpha=0.5)
    centres = np.unique(np.concatenate([c for c, _, _ in bins]))
    grid = np.full((len(bins), centres.size), np.nan)
    for i, (c, m, _) in enumerate(bins):
        grid[i, np.searchsorted(centres, c)] = m
    with np.errstate(all="ignore"):
        for q, ls in ((16, ":"), (50, "-"), (84, ":")):
            a3.plot(centres, np.nanpercentile(grid, q, axis=0), "b" + ls, lw=1.5, label=f"p{q} over phases")
    if hst_curve:
        angle, mag = read_hst_curve(hst_curve)
        a3.plot(angle, mag, "r-", label="HST (WFC3 IHB fig. 9.2, V)")
    a3.axhline(level, color="r", ls=":", lw=1, label=f"HST at 20 deg: {level:.2f}")
    a3.axvline(target, color="k", ls=":", lw=0.8)
    a3.set_ylim(30, 8)
    a3.set_xlim(0, 115)
    a3.set_xlabel("angle above the bright Earth limb (deg)")
    a3.set_ylabel("earthshine, median in 10-deg bins (V mag/arcsec$^2$)")
    a3.set_title(f"CSST earthshine per sunlit phase, tail 10^{tail:.2f} at 90 deg", fontsize=9)
    a3.legend(fontsize=7)
