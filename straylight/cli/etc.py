"""``straylight etc``: the exposure time a point source needs for a signal-to-noise ratio (or the
ratio a time gives) at one pointing, at one time or over a window of times."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from straylight.cli._common import check_out, checked_pointing, print_json
from straylight.errors import InputError

__all__ = ["cmd_etc", "etc_text", "table_records"]


def cmd_etc(args) -> int:
    """``straylight etc``: exposure time for an SNR, or SNR for a time, per band.

    Parameters
    ----------
    args : argparse.Namespace
        The command's parsed arguments (:func:`straylight.cli.parser.build_parser`).
    """
    import astropy.units as u
    from astropy.coordinates import SkyCoord

    from straylight.config import load_campaign
    from straylight.planning.exposure_time import (
        checked_bands,
        checked_request,
        etc_summary,
        etc_table,
        time_grid,
    )
    from straylight.sky.ephemeris import check_in_ephemeris
    from straylight.sky.timeutil import parse_utc

    ra_deg, dec_deg = checked_pointing(args)
    exptime = None if args.exptime is None else args.exptime * u.s
    snr = None if exptime is not None else (5.0 if args.snr is None else args.snr)
    names = {"mag_ab": "--mag", "snr": "--snr", "exposure_time": "--exptime", "n_exposures": "--n-exp"}
    request = checked_request(
        args.mag,
        snr=snr,
        exposure_time=exptime,
        n_exposures=args.n_exp,
        observable_only=not args.ignore_constraints,
        names=names,
    )
    if args.out is not None:
        if Path(args.out).suffix.lower() not in (".csv", ".ecsv"):
            raise InputError(f"--out {args.out}: must end in .csv or .ecsv")
        check_out(args, args.out)
    campaign = load_campaign(args.config)
    bands = checked_bands(_band_list(args.bands), campaign, "--bands")
    step_s = None
    if args.end is None:
        if args.step_min is not None:
            raise InputError("--step-min needs --end (a window from --time to --end)")
        times = parse_utc(args.time, "--time")
        check_in_ephemeris(times, "--time", args.time)
    else:
        c = campaign.settings.campaign
        step_s = args.step_min * 60.0 if args.step_min is not None else float(c.cadence_s)
        times = time_grid(args.time, args.end, step_s, float(campaign.orbit.period_s))
    from straylight.skymodel import cached_sky_model

    sky = cached_sky_model(args.config, args.catalog)
    background = sky.background(times, SkyCoord(ra_deg, dec_deg, unit="deg"), bands)
    table = etc_table(background, bands, sky.campaign, request)
    from straylight.skymodel import _warn_magnitude

    _warn_magnitude(table, sky.campaign)
    window = args.end is not None
    summary = etc_summary(table) if window else None
    if args.out:
        from straylight.util.io import atomic_path

        with atomic_path(args.out) as tmp:
            table.write(
                tmp,
                format="ascii.ecsv" if args.out.lower().endswith(".ecsv") else "ascii.csv",
                overwrite=True,
            )
    if args.json:
        rows, units = table_records(table)
        out = {"request": _request_record(request, ra_deg, dec_deg, table), "samples": rows, "units": units}
        if summary is not None:
            out["summary"], out["summary_units"] = table_records(summary)
        print_json(out)
    else:
        print(etc_text(table, summary, ra_deg, dec_deg, None if step_s is None else step_s / 60.0))
    if args.out:
        print(args.out)
    return 0


def _band_list(text):
    """--bands as a list of names (None when not given)."""
    if text is None:
        return None
    bands = [b.strip() for b in text.split(",") if b.strip()]
    if not bands:
        raise InputError(f"--bands {text!r}: no band given (leave --bands out for every survey band)")
    return bands


def _request_record(request: dict, ra_deg: float, dec_deg: float, table) -> dict:
    """The question asked, for the JSON output."""
    return {
        "ra_deg": ra_deg,
        "dec_deg": dec_deg,
        "mode": request["mode"],
        "mag_ab": request["mag_ab"],
        "snr": request["snr"],
        "exposure_time_s": request["exposure_s"],
        "n_exposures": request["n_exposures"],
        "survey_exposures": table.meta["survey_exposures"],
        "aperture": "EE80 (80 % of the source's light)",
    }


def table_records(table) -> tuple[list, dict]:
    """The rows of an astropy table as JSON-ready dicts, and the columns' units.

    Parameters
    ----------
    table : astropy.table.Table or QTable
        Any table of scalars, Times and Quantities.

    Returns
    -------
    rows : list of dict
        One dict per row: Time as ISO 8601 text (UTC), a Quantity as its value, NaN as None.
    units : dict of str to str
        Column name to unit, for the columns that have one.
    """
    from astropy.time import Time

    cols = {}
    for name in table.colnames:
        col = table[name]
        if isinstance(col, Time):
            cols[name] = list(col.isot)
        else:
            v = np.asarray(getattr(col, "value", col))
            cols[name] = (
                [float(x) if np.isfinite(x) else None for x in v] if v.dtype.kind == "f" else v.tolist()
            )
    units = {n: str(table[n].unit) for n in table.colnames if getattr(table[n], "unit", None) is not None}
    return [{k: cols[k][i] for k in table.colnames} for i in range(len(table))], units


def etc_text(table, summary, ra_deg: float, dec_deg: float, step_min: float | None = None) -> str:
    """The command's text output: for one time, a line per band (background, dominant component,
    exposure time or SNR, exposures, the survey's 5-sigma limit); for a window, the summary per band.

    Parameters
    ----------
    table : astropy.table.QTable
        :func:`straylight.planning.exposure_time.etc_table`'s result.
    summary : astropy.table.QTable or None
        :func:`straylight.planning.exposure_time.etc_summary`'s result for a window, else None.
    ra_deg, dec_deg : float
        The pointing, deg (ICRS).
    step_min : float, optional
        The window's step, min.

    Returns
    -------
    str
        Lines to print.
    """
    m = table.meta
    by_time = m["mode"] == "exposure_time"
    ask = f"SNR {m['snr']:g}" if by_time else f"{m['exposure_s']:g} s"
    n_pix = next(iter(m["aperture_pixels"].values()))
    lines = [
        f"RA {ra_deg:.4f}  Dec {dec_deg:+.4f}: AB {m['mag_ab']:.2f} point source, {ask} in the EE80 aperture "
        f"({n_pix:.1f} pixels); the time is split into the exposures, read noise once each"
    ]
    if summary is None:
        return "\n".join(lines + _sample_lines(table, by_time))
    n = int(np.max(summary["n_samples"])) if len(summary) else 0
    lines.append(f"{n} samples every {step_min:.3g} min from {table['time'][0].isot[:19]} UTC")
    if by_time:
        best, when, med, worst = (
            "exposure_time_min",
            "time_of_min",
            "exposure_time_median",
            "exposure_time_max",
        )
        heads = ("shortest", "median", "longest")
    else:
        best, when, med, worst = "snr_max", "time_of_max", "snr_median", "snr_min"
        heads = ("best SNR", "median", "worst")
    lines.append(
        f"  {'band':<4s}  {'observable':>10s}  {heads[0]:>10s}  {'at (UTC)':<19s}  {heads[1]:>10s}  "
        f"{heads[2]:>10s}  {'exposures':>9s}  {'bkg e-/s/pix':>12s}  dominant (at the best)"
    )
    n_exp = {str(b): int(k) for b, k in zip(table["band"], table["n_exposures"])}

    def fmt(q):
        v = float(getattr(q, "value", q))
        return "-" if not np.isfinite(v) else _fmt_s(v) if by_time else _fmt_snr(v)

    for r in summary:
        lines.append(
            f"  {r['band']:<4s}  {r['n_observable']:>4d} / {r['n_samples']:<3d}  {fmt(r[best]):>10s}  "
            f"{(r[when][:19] or '-'):<19s}  {fmt(r[med]):>10s}  {fmt(r[worst]):>10s}  "
            f"{n_exp[r['band']]:>9d}  {_fmt_g(r['background_total'].value):>12s}  {r['dominant'] or '-'}"
        )
    return "\n".join(lines)


def _fmt_s(v: float) -> str:
    """A time in seconds, 0.1 s resolution between 0.1 s and 1e6 s, else 3 significant digits
    (no "0.0 s" for a bright source, no 60 digits for a faint one)."""
    return f"{v:.1f} s" if 0.1 <= v < 1e6 else f"{v:.3g} s"


def _fmt_snr(v: float) -> str:
    """An SNR to 0.01 between 0.01 and 1e6, else 3 significant digits."""
    return f"{v:.2f}" if 0.01 <= v < 1e6 else f"{v:.3g}"


def _fmt_g(v: float) -> str:
    """A rate to 4 significant digits, '-' when not finite."""
    return f"{v:.4g}" if np.isfinite(v) else "-"


def _sample_lines(table, by_time: bool) -> list:
    """One time: its observability, then a line per band."""
    first = table[0]
    state = "observable" if first["observable"] else f"NOT observable (violated: {first['violations']})"
    what = "exposure time" if by_time else "SNR"
    lines = [
        f"{first['time'].isot[:19]} UTC: {state}",
        f"  {'band':<4s}  {'bkg e-/s/pix':>12s}  {'mag/arcsec2':>11s}  {'dominant (share)':<20s}  "
        f"{what:>13s}  {'exposures':>13s}  {'5-sigma limit':>13s}",
    ]
    for r in table:
        dom = f"{r['dominant']} ({100 * r['dominant_fraction']:.0f} %)"
        val = float(r["exposure_time"].value if by_time else r["snr"])
        shown = "-" if not np.isfinite(val) else _fmt_s(val) if by_time else _fmt_snr(val)
        one = r["single_exposure"].value
        split = f"{r['n_exposures']} x " + (_fmt_s(one) if np.isfinite(one) else "-")
        lines.append(
            f"  {r['band']:<4s}  {_fmt_g(r['background_total'].value):>12s}  "
            f"{r['background_mag'].value:>11.2f}  "
            f"{dom:<20s}  {shown:>13s}  {split:>13s}  {r['limit_mag'].value:>9.2f} mag"
        )
    if not first["observable"]:
        lines.append(
            "  not observable: computed anyway (--ignore-constraints)"
            if not table.meta["observable_only"]
            else "  not observable: no exposure time or SNR (--ignore-constraints computes them)"
        )
    return lines
