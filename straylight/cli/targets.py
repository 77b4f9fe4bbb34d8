"""``straylight visibility --targets FILE``: many targets at once, a summary per target and month
and, with ``--out FOLDER``, each target's windows and days."""

from __future__ import annotations

import time

from straylight.cli._common import check_out
from straylight.errors import InputError

__all__ = ["cmd_visibility_targets"]


def cmd_visibility_targets(args) -> int:
    """Run ``straylight visibility --targets``: check everything before any work, evaluate all
    targets together, print the summary and write the tables.

    Parameters
    ----------
    args : argparse.Namespace
        The command's parsed arguments (:func:`straylight.cli.parser.build_parser`).
    """
    from pathlib import Path

    from straylight.config import load_campaign
    from straylight.planning.target_names import read_targets
    from straylight.planning.targets import SampledWindow, format_summary, targets_visibility, write_targets
    from straylight.planning.visibility import time_grid

    if args.ra is not None or args.dec is not None:
        raise InputError("give either --targets FILE or --ra/--dec, not both")
    if args.plot is not None:
        raise InputError(
            f"--plot {args.plot}: draws one target; with --targets, plot a target alone "
            "(straylight visibility --ra RA --dec DEC --plot FILE)"
        )
    if args.out is not None and Path(args.out).suffix.lower() in (".csv", ".ecsv"):
        raise InputError(
            f"--out {args.out}: with --targets, --out names a folder (summary.csv and per-target tables)"
        )
    campaign = load_campaign(args.config)
    c = campaign.settings.campaign
    step_s = args.step_min * 60.0 if args.step_min is not None else float(c.cadence_s)
    start, end = args.start or c.start, args.end or c.end
    time_grid(
        campaign, args.band, start, end, step_s, warn=False
    )  # times, step and band refused before any work

    def catalog():
        from straylight.catalog.campaign_catalog import default_catalog_path

        return default_catalog_path(campaign)

    targets = read_targets(args.targets, catalog)
    from straylight.planning.bright_targets import warn_bright_targets

    warn_bright_targets(targets.ra_deg, targets.dec_deg, start, targets.names)
    if args.out is not None:
        check_out(args, args.out, "--out", folder=True)
    w0 = time.perf_counter()
    window = SampledWindow(start, end, step_s)
    res = targets_visibility(campaign, targets, args.band, window, args.threshold, model=_model(args.config))
    wall, sec, n = time.perf_counter() - w0, res["seconds"], res["observable"].size
    print(
        f"{len(targets)} targets, band {args.band}: {res['observable'].shape[1]} samples each every "
        f"{step_s / 60:.3g} min from {res['time'][0].isot[:19]}; {n:,} samples in {wall:.1f} s "
        f"(background evaluation {sec['evaluation_wall_s']:.1f} s wall, {sec['evaluation_cpu_s']:.1f} CPU-s: "
        f"{n / max(sec['evaluation_cpu_s'], 1e-9):,.0f} samples/s/core)"
    )
    print(format_summary(res["summary"]))
    if args.out is not None:
        paths = write_targets(res, args.out)
        print(
            f"{args.out}: summary.csv, targets.csv and {len(paths) - 2} per-target tables (_windows, _days)"
        )
    return 0


def _model(config):
    """The API's warm model of this config, as ``straylight sky`` evaluates with."""
    from straylight.skymodel import cached_sky_model

    return cached_sky_model(config).model
