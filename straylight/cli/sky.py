"""The sky at one pointing: ``ephem`` (the bodies' positions), ``sky`` (one pointing, or a table of
them) and ``visibility`` (a target over time)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from straylight.cli._common import check_out, checked_pointing, print_json
from straylight.errors import InputError

__all__ = ["cmd_ephem", "cmd_sky", "cmd_visibility", "sky_record"]


def cmd_ephem(args) -> int:
    """``straylight ephem``: the bodies' geocentric positions at one time.

    Parameters
    ----------
    args : argparse.Namespace
        The command's parsed arguments (:func:`straylight.cli.parser.build_parser`).
    """
    from straylight.sky.ephemeris import BODIES, default_ephemeris, radec_distance
    from straylight.sky.timeutil import parse_utc

    bodies = [b.strip().lower() for b in args.bodies.split(",") if b.strip()] if args.bodies else list(BODIES)
    unknown = [b for b in bodies if b not in BODIES]
    if unknown:
        raise InputError(f"--bodies: unknown body {unknown[0]!r}; known: {', '.join(BODIES)}")
    t = parse_utc(args.time, "--time")
    pos = default_ephemeris().positions(t, bodies)
    out = {"time": t.isot, "frame": "ICRS", "origin": "geocentre", "kind": "geometric", "bodies": {}}
    for b in bodies:
        p = pos[b]
        ra, dec, dist = radec_distance(p)
        out["bodies"][b] = {
            "x_km": float(p[0]),
            "y_km": float(p[1]),
            "z_km": float(p[2]),
            "ra_deg": float(ra),
            "dec_deg": float(dec),
            "distance_km": float(dist),
        }
    if args.json:
        print_json(out)
    else:
        print(f"{out['time']} UTC, geocentric geometric ICRS")
        for b, v in out["bodies"].items():
            print(f"{b:8s} RA {v['ra_deg']:10.5f}  Dec {v['dec_deg']:+9.5f}  d {v['distance_km']:.6e} km")
    return 0


def sky_record(campaign, time, ra_deg: float, dec_deg: float, bands=None, stars=None, model=None) -> dict:
    """The ``straylight sky`` JSON record for one time and pointing (grows with the physics);
    ``model``: a function giving the campaign's :class:`~straylight.model.BackgroundModel` (the
    SkyModel's, as the API evaluates with), called once the scene is computed (an orbit that
    cannot be propagated is refused before any table is read or built), else one built for this
    sample.

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign.
    time : str or astropy.time.Time
        One UTC time.
    ra_deg : float
        ICRS right ascension, deg.
    dec_deg : float
        ICRS declination, deg.
    bands : list of str, optional
        Bands (None: the campaign's).
    stars : StarTable, optional
        The off-field stars (None: stars = 0).
    model : callable, optional
        ``model() -> BackgroundModel``; None: one is built.

    Returns
    -------
    dict
        JSON-ready: the sample, the satellite (GCRS km), the model's record and
        :meth:`~straylight.model.result.BackgroundResult.to_record`'s entries.
    """
    from straylight.model import BackgroundModel
    from straylight.model.pointing import background_result
    from straylight.model.samples import SampleBatch
    from straylight.planning.pointings import with_limits
    from straylight.sky.observing import scene
    from straylight.sky.vectors import radec_to_unit

    sc = scene(campaign.orbit, time)
    model = model() if model is not None else BackgroundModel(campaign)
    samples = SampleBatch(sc, np.atleast_2d(radec_to_unit(np.array([ra_deg]), np.array([dec_deg]))))
    bands = bands or campaign.bands
    result = background_result(
        model, samples, bands, stars=stars, in_field_bands=bands, geometry_bodies=tuple(sc.bodies_km)
    )
    one = with_limits(result, campaign).to_record(0)
    record = {
        "time": sc.times[0].isot,
        "ra_deg": ra_deg,
        "dec_deg": dec_deg,
        "satellite_gcrs_km": [float(x) for x in sc.satellite_km[0]],
        **{k: one[k] for k in ("geometry", "observable", "violations", "bands")},
        "models": model.models_record(),
    }
    record.update({k: one[k] for k in ("in_field_point_sources", "zodiacal_no_data_near_sun")})
    record["stars_included"] = stars is not None
    return record


def cmd_sky(args) -> int:
    """``straylight sky``: the geometry and background of one pointing, or of a table of them.

    Parameters
    ----------
    args : argparse.Namespace
        The command's parsed arguments (:func:`straylight.cli.parser.build_parser`).
    """
    from straylight.config import load_campaign

    if args.input:
        if not args.out or not str(args.out).endswith(".parquet"):
            raise InputError("--input needs --out FILE.parquet")
        check_out(args, args.out)
    elif args.time is None or args.ra is None or args.dec is None:
        raise InputError("give --time, --ra and --dec, or --input TABLE --out FILE")
    else:
        from straylight.sky.ephemeris import check_in_ephemeris
        from straylight.sky.timeutil import parse_utc

        pointing = checked_pointing(args)
        given, args.time = args.time, parse_utc(args.time, "--time")  # ISO 8601, with or without a UTC offset
        check_in_ephemeris(args.time, "--time", given)
    campaign = load_campaign(args.config)
    bands = _sky_bands(args.bands, campaign)
    stars = None
    if args.catalog:  # the cube's star model: stars brighter than stars.offfield_mag_limit
        from straylight.sources.stars_table import load_offfield_stars

        stars = load_offfield_stars(
            args.catalog,
            bands or campaign.bands,
            float(campaign.settings.stars.offfield_mag_limit),
            campaign.settings.stars.faint_map,
        )
    if args.input:
        return _sky_table(args, campaign, bands, stars)
    rec = sky_record(
        campaign, args.time, pointing[0], pointing[1], bands, stars, lambda: _sky_model(args.config)
    )
    if args.json:
        print_json(rec)
    else:
        g = rec["geometry"]
        print(f"{rec['time']}  RA {rec['ra_deg']:.4f}  Dec {rec['dec_deg']:+.4f}")
        for k, val in g.items():
            if k != "planet_angles_deg":  # angles (deg) and the Moon's lit fraction to 3 decimals
                print(f"  {k:28s} {val:.3f}" if isinstance(val, float) else f"  {k:28s} {val}")
        print(f"  observable: {rec['observable']}  violations: {', '.join(rec['violations']) or 'none'}")
        for src in rec["in_field_point_sources"]:
            mags = "  ".join(f"{b} {m:.2f}" for b, m in src["mag_ab"].items())
            print(
                f"  in the field (a point source, not in the background): {src['body']} "
                f"{src['angle_deg']:.3f} deg off axis, V {src['v_mag']:.2f}; AB {mags}"
            )
        print(_sky_band_table(rec["bands"]))
    return 0


def _sky_bands(text, campaign) -> list[str] | None:
    """--bands as a list (None when not given: the instrument's); an empty list or an unknown
    band is refused before any work."""
    from straylight.optics.bandpass import DIAGNOSTIC_BANDS

    if text is None:
        return None
    bands = [b.strip() for b in text.split(",") if b.strip()]
    known = [*campaign.bands, *DIAGNOSTIC_BANDS]
    if not bands:
        raise InputError(
            f"--bands {text!r}: no band given; valid bands: {', '.join(known)} "
            "(leave --bands out for all the instrument's)"
        )
    unknown = [b for b in bands if b not in known]
    if unknown:
        raise InputError(f"--bands: unknown band {unknown[0]!r}; valid bands: {', '.join(known)}")
    twice = [b for i, b in enumerate(bands) if b in bands[:i]]
    if twice:
        raise InputError(f"--bands {text!r}: band {twice[0]!r} given twice; give each band once")
    return bands


def _sky_band_table(bands: dict) -> str:
    """The per-band lines of `straylight sky`: each component in e-/s/pixel (3 significant
    digits) and in AB mag/arcsec2 (2 decimals), then the 5-sigma limit (AB mag); the
    components are the registry's, then the total."""
    from straylight.model import registry

    columns = registry.component_names(total=True)
    head = f"  {'band':4s} {'unit':14s}" + "".join(f"{c:>11s}" for c in columns) + f"{'5-sigma lim':>13s}"
    lines = [head]
    for name, comp in bands.items():
        rate = "".join(f"{comp[c]['e_per_s_per_pix']:>11.3g}" for c in columns)
        mags = "".join(
            f"{comp[c]['mag_per_arcsec2']:>11.2f}"
            if comp[c]["mag_per_arcsec2"] is not None
            else f"{'-':>11s}"
            for c in columns
        )
        lim = f"{comp['limit_mag']:>9.2f} mag" if comp.get("limit_mag") is not None else f"{'-':>13s}"
        lines.append(f"  {name:4s} {'e-/s/pixel':14s}{rate}")
        lines.append(f"  {'':4s} {'mag/arcsec2':14s}{mags}{lim}")
    return "\n".join(lines)


def _sky_model(config):
    """The API's model of this config (the earthshine tables under auto), so that the command and
    sky_background agree; built after the command's input is checked."""
    from straylight.skymodel import cached_sky_model

    return cached_sky_model(config).model


def _sky_table(args, campaign, bands, stars) -> int:
    """``sky --input``: every row of a pointing table evaluated, written as Parquet."""
    from straylight.catalog.gaia import write_parquet
    from straylight.planning.pointings import CHUNK_ROWS, column_units, pointing_chunks, read_pointings
    from straylight.sky.timeutil import quiet_dubious_years

    p = read_pointings(args.input)
    # a masked time (ECSV, Parquet, FITS Time columns) has no value to compute at: refused by row
    masked = [i for i, v in enumerate(p["time"]) if np.any(getattr(v, "mask", False))]
    if masked:
        raise InputError(
            f"{args.input}: row {masked[0] + 1}: time is masked (no value); {len(masked)} of "
            f"{len(p['time'])} rows are masked: fill or drop them"
        )
    models: dict = {}
    counts = {"rows": 0, "observable": 0}

    def chunks():  # one chunk of rows evaluated, written and let go at a time (bounded memory)
        with quiet_dubious_years():  # a time outside DE405 is refused in one line of ours, without ERFA's
            for _, cols in pointing_chunks(
                campaign,
                p,
                bands,
                stars,
                CHUNK_ROWS,
                source=str(args.input),
                models=models,
                model=lambda: _sky_model(args.config),
            ):
                counts["rows"] += len(cols["time"])
                counts["observable"] += int(np.sum(cols["observable"]))
                yield cols

    from straylight import __version__

    write_parquet(
        chunks(),
        args.out,
        {
            "straylight_version": __version__,
            "input": str(args.input),
            "config": str(campaign.path),
            "stars_included": stars is not None,
            "models": models,
            "units": "components e-/s/pixel; total_mag_per_arcsec2 AB mag/arcsec2; "
            "limit_mag 5-sigma AB for the band's survey exposures",
        },
        units=column_units,
    )
    print(
        f"{args.out}: {counts['rows']} pointings ({counts['observable']} observable), "
        f"bands {', '.join(bands or campaign.bands)}"
    )
    return 0


def cmd_visibility(args) -> int:
    """``straylight visibility``: a target's background, limit and observable windows over time
    (``--targets FILE``: many targets, :func:`straylight.cli.targets.cmd_visibility_targets`).

    Parameters
    ----------
    args : argparse.Namespace
        The command's parsed arguments (:func:`straylight.cli.parser.build_parser`).
    """
    from straylight.config import load_campaign
    from straylight.planning.visibility import plot_visibility, visibility

    if getattr(args, "targets", None) is not None:
        from straylight.cli.targets import cmd_visibility_targets

        return cmd_visibility_targets(args)
    if args.ra is None or args.dec is None:
        raise InputError("give --ra and --dec, or --targets FILE (a CSV of name, ra, dec)")
    ra_deg, dec_deg = checked_pointing(args)
    _check_visibility_outputs(args)
    campaign = load_campaign(args.config)
    c = campaign.settings.campaign
    step_s = args.step_min * 60.0 if args.step_min is not None else float(c.cadence_s)
    res = visibility(
        campaign,
        ra_deg,
        dec_deg,
        args.band,
        args.start or c.start,
        args.end or c.end,
        step_s,
        args.threshold,
    )
    from straylight.planning.bright_targets import warn_bright_targets

    warn_bright_targets(ra_deg, dec_deg, args.start or c.start)  # the times checked by now
    _print_visibility(res, ra_deg, dec_deg, args, step_s)
    if args.out:
        _write_visibility(res, Path(args.out))
    else:
        w = res["windows"]
        print(w if len(w) else "  no observable window")
    if args.plot:
        plot_visibility(res, args.plot, args.threshold)
        print(args.plot)
    return 0


def _check_visibility_outputs(args) -> None:
    """--out (.csv or .ecsv, with its _windows and _days files) and --plot (.png, .pdf or
    .svg) refused before any work when misnamed or already there."""
    for path, flag, suffixes in (
        (args.out, "--out", (".csv", ".ecsv")),
        (args.plot, "--plot", (".png", ".pdf", ".svg")),
    ):
        if path is not None:
            if Path(path).suffix.lower() not in suffixes:
                raise InputError(f"{flag} {path}: must end in {' or '.join(suffixes)}")
            check_out(args, path, flag)
    if args.out:
        stem, suffix = Path(args.out).with_suffix(""), Path(args.out).suffix
        for extra in (f"{stem}_windows{suffix}", f"{stem}_days{suffix}"):
            check_out(args, extra, "--out")


def _print_visibility(res: dict, ra_deg: float, dec_deg: float, args, step_s: float) -> None:
    """The visibility's summary lines: samples and windows, the observable samples' median
    background (AB mag/arcsec2) and limits (AB mag), the days deeper than the threshold."""
    s, w, d = res["samples"], res["windows"], res["days"]
    n_obs = int(np.sum(s["observable"]))
    print(
        f"RA {ra_deg:.4f} Dec {dec_deg:+.4f} band {args.band}: {len(s)} samples every "
        f"{step_s / 60:.3g} min from {s['time'][0].isot[:19]}; {n_obs} observable "
        f"({100.0 * n_obs / len(s):.1f} %); {len(w)} observable windows"
    )
    if n_obs:
        ok = np.asarray(s["observable"], bool)
        print(
            f"  observable: background {np.median(s['total_mag_per_arcsec2'][ok].value):.2f} mag/arcsec2 "
            f"(median), "
            f"5-sigma limit median {np.median(s['limit_mag'][ok].value):.2f}, deepest "
            f"{np.max(s['limit_mag'][ok].value):.2f} mag (AB)"
        )
    if args.threshold is not None:
        deep = d[d["hours_deeper_than_threshold"].value > 0]
        print(
            f"  days with the limit deeper than {args.threshold:.2f} mag: {len(deep)} of {len(d)}"
            + (f" ({', '.join(deep['date'][:10])}{', ...' if len(deep) > 10 else ''})" if len(deep) else "")
        )


def _write_visibility(res: dict, out: Path) -> None:
    """The samples, windows and days as ``out`` and its ``_windows`` and ``_days`` files (ECSV
    or CSV by the suffix), each path printed."""
    from straylight.util.io import atomic_path

    fmt = "ascii.ecsv" if out.suffix.lower() == ".ecsv" else "ascii.csv"
    stem = out.with_suffix("")
    for table, path in (
        (res["samples"], out),
        (res["windows"], Path(f"{stem}_windows{out.suffix}")),
        (res["days"], Path(f"{stem}_days{out.suffix}")),
    ):
        with atomic_path(path) as tmp:
            table.write(tmp, format=fmt, overwrite=True)
        print(path)
