"""The paper's results: ``scenario`` (the earthshine scenario of sect. 3.3) and ``figure`` (the
in-field figures of sects. 4.1-4.4)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from straylight.cli._common import check_out

__all__ = ["cmd_figure", "cmd_scenario"]


def cmd_scenario(args) -> int:
    """``straylight scenario``: the paper's earthshine scenario as a figure and a table.

    Parameters
    ----------
    args : argparse.Namespace
        The command's parsed arguments (:func:`straylight.cli.parser.build_parser`).
    """
    from astropy.table import Table

    from straylight.config import load_campaign
    from straylight.paper.scenarios import (
        earthshine_scenario,
        hst_comparison,
        plot_earthshine_scenario,
        read_hst_curve,
        sunlit_limb,
    )

    if args.out is None:
        args.out, args.parents = "results/scenarios/earthshine.png", True
    out = Path(args.out)
    check_out(args, out)
    check_out(args, out.with_suffix(".csv"))
    campaign = load_campaign(args.config)
    if args.hst_curve:
        check_out(args, out.with_suffix(".json"))
        read_hst_curve(args.hst_curve)  # a bad curve is refused before the work
    res = earthshine_scenario(campaign, band=args.band)
    cols = {k: v for k, v in res.items() if isinstance(v, np.ndarray)}
    Table(cols).write(out.with_suffix(".csv"), overwrite=True)
    comparison = hst_comparison(res, args.hst_curve) if args.hst_curve else None
    plot_earthshine_scenario(res, out, args.hst_curve, comparison)
    sel = sunlit_limb(res)
    print(f"{out}: {int(sel.sum())} sunlit-limb pointings of {sel.size}; table {out.with_suffix('.csv')}")
    if comparison:
        out.with_suffix(".json").write_text(json.dumps(comparison, indent=1) + "\n")
        print(
            f"HST at {comparison['hst_limb_angle_deg']:g} deg from the bright limb: "
            f"{comparison['hst_v_mag_per_arcsec2']:.2f} V mag/arcsec2; CSST's median earthshine "
            f"({res['band']}) "
            f"falls to it {comparison['csst_crossing_limb_angle_deg']:.1f} deg from the bright limb "
            f"(paper sect. 3.3: 70); {out.with_suffix('.json')}"
        )
    return 0


def cmd_figure(args) -> int:
    """``straylight figure``: one of the paper's in-field figures.

    Parameters
    ----------
    args : argparse.Namespace
        The command's parsed arguments (:func:`straylight.cli.parser.build_parser`).
    """
    from straylight.config import load_campaign
    from straylight.paper.figures import make_figure

    campaign = load_campaign(args.config)
    out = args.out or f"docs/img/paper_{args.name.replace('-', '_')}.png"
    d = make_figure(args.name, campaign, out, args.catalog)
    if args.name == "zodiacal-map":
        v = d["v_mag_per_arcsec2"]
        print(
            f"zodiacal V: darkest {np.nanmax(v):.2f}, median {np.nanmedian(v):.2f} mag/arcsec2; "
            f"Sun at RA {d['sun_ra_deg']:.2f} Dec {d['sun_dec_deg']:+.2f} deg"
        )
    elif args.name == "scattering":
        r = d["r_px"]
        print(
            f"TIS {d['tis_per_mirror']:.4f} per mirror; halo / peak "
            f"{np.interp(10, r, d['halo']):.2e} at 10 px, "
            f"{np.interp(100, r, d['halo']):.2e} at 100 px"
        )
    elif args.name == "ghosts":
        print("ghost / star peak pixel: " + ", ".join(f"{v:.2e}" for v in d["ghost_relative_to_peak"]))
    print(out)
    return 0
