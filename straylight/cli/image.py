"""``straylight image``: the in-field stray light of one detector as a FITS image; the parsing
of its target (--ra/--dec or --star) and cutout, and its printed summary."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from straylight.cli._common import check_out, checked_pointing
from straylight.errors import InputError

__all__ = ["cmd_image"]


def _resolve_star(catalog: dict, source_id: np.ndarray, text: str) -> int:
    """Row of the catalog star named ``text``: a HIP number (or a catalog source_id) or an IAU
    proper name of :data:`straylight.catalog.hipparcos.BRIGHT_STAR_HIP`."""
    from straylight.catalog.hipparcos import BRIGHT_STAR_HIP

    key = text.strip()
    if key.lower().startswith("hip"):
        key = key.lower().replace("hip", "").strip()
    if key.isdigit():
        number = int(key)
    elif key.lower() in BRIGHT_STAR_HIP:
        number = BRIGHT_STAR_HIP[key.lower()]
    else:
        raise InputError(
            f"--star {text!r}: not a HIP number or a known name "
            f"({', '.join(sorted(n.capitalize() for n in BRIGHT_STAR_HIP))})"
        )
    rows = np.flatnonzero(source_id == number)
    if rows.size == 0:
        raise InputError(f"--star {text!r}: HIP/source_id {number} is not in the catalog {catalog['path']}")
    return int(rows[0])


def _read_source_ids(path) -> np.ndarray:
    """The source_id column of a star table (Parquet read alone, else through astropy)."""
    from astropy.table import Table

    p = Path(path)
    try:
        if p.suffix.lower() == ".parquet":
            import pyarrow.parquet as pq

            t = pq.read_table(p, columns=["source_id"])
            return np.asarray(t.column("source_id").to_numpy())
        return np.asarray(Table.read(p)["source_id"])
    except Exception as exc:
        raise InputError(
            f"--star needs a catalog with a source_id column (HIP numbers for Hipparcos stars); "
            f"{p}: {type(exc).__name__}: {exc}"
        ) from None


def _checked_image_args(args) -> tuple[tuple[float, float] | None, list[int] | None]:
    """The target (None with --star: looked up in the catalog) and the cutout's (width, height)
    (None without --cutout), with the flags checked before any work."""
    if args.star is None and (args.ra is None or args.dec is None):
        raise InputError("give --ra and --dec, or --star HIP|NAME")
    if args.star is not None and (args.ra is not None or args.dec is not None):
        raise InputError("give either --ra/--dec or --star, not both")
    target = checked_pointing(args) if args.star is None else None
    if args.bin < 1:
        raise InputError(f"--bin {args.bin}: must be a positive integer")
    if args.quantize_step is not None:  # checked here, not after the rendering
        if args.compress != "rice":
            raise InputError(
                f"--quantize-step {args.quantize_step:g}: applies only with --compress rice "
                f"(this image is written with --compress {args.compress}, which does not "
                "quantise)"
            )
        if not (math.isfinite(args.quantize_step) and args.quantize_step > 0):
            raise InputError(
                f"--quantize-step {args.quantize_step:g}: must be a positive number of e-/s/pixel"
            )
    cutout = None
    if args.cutout:
        try:
            parts = [int(v) for v in args.cutout.split(",")]
            if len(parts) == 1:
                parts = parts * 2
            if len(parts) != 2 or min(parts) < 1:
                raise ValueError
        except ValueError:
            raise InputError(
                f"--cutout {args.cutout!r}: expected WIDTH or WIDTH,HEIGHT in pixels, positive"
            ) from None
        cutout = parts
    return target, cutout


def cmd_image(args) -> int:
    """``straylight image``: render one detector around a target and write it as FITS.

    Parameters
    ----------
    args : argparse.Namespace
        The command's parsed arguments (:func:`straylight.cli.parser.build_parser`).
    """
    out = check_out(args, args.out)
    from straylight.catalog.star_table import read_star_table
    from straylight.config import load_campaign
    from straylight.image.detector import RenderSettings
    from straylight.image.detector_fits import write_fits
    from straylight.image.focal_plane import focal_plane_from_instrument
    from straylight.image.frame import StarCatalog, cutout_window, frame_for_target, render_frame
    from straylight.optics.bandpass import load_band
    from straylight.sky.ephemeris import check_in_ephemeris
    from straylight.sky.timeutil import parse_utc

    target, cutout = _checked_image_args(args)
    campaign = load_campaign(args.config)
    inst = campaign.instrument_settings
    if args.band not in campaign.bands:
        raise InputError(f"--band: {args.band!r} is not one of {', '.join(campaign.bands)}")
    t = parse_utc(args.time, "--time")
    check_in_ephemeris(t, "--time", args.time)
    fp = focal_plane_from_instrument(inst)
    fp.detector_offset_px(args.detector)  # checks the index
    catalog = args.catalog
    if catalog is None:
        from straylight.catalog.campaign_catalog import default_catalog_path

        catalog = default_catalog_path(campaign)
    band = load_band(inst, args.band, campaign.instrument_path.parent)
    ra, dec, mag = read_star_table(catalog, args.band, epoch=t)  # at DATE-OBS: proper motions applied
    star_label = ""
    if args.star is not None:
        row = _resolve_star({"path": catalog}, _read_source_ids(catalog), args.star)
        target = (float(ra[row]), float(dec[row]))
        star_label = f"{args.star} (mag_{args.band} {mag[row]:.2f})"
    settings = RenderSettings(
        far_bin=args.far_bin, margin_arcsec=args.margin_arcsec, paint_ghosts=not args.no_ghosts
    )
    frame = frame_for_target(
        campaign, t, target, band, StarCatalog(ra, dec, mag), args.detector, args.center, settings
    )
    if frame.body_names:
        print(
            "in the field, imaged as stars: "
            + ", ".join(f"{n} ({m:.2f} AB)" for n, m in zip(frame.body_names, frame.body_mag_ab))
        )
    if frame.selection.index.size == 0 and not _empty_field_allowed(args, catalog, target):
        return 1
    window = None
    if cutout is not None:
        xt, yt = frame.pixel_of(target[0], target[1])
        window = cutout_window(fp, xt, yt, cutout[0], cutout[1])
        if window is None:
            raise InputError(
                f"--cutout {args.cutout}: the target (pixel {xt:.0f}, {yt:.0f}) is off "
                f"detector {args.detector}; use --center detector"
            )
    bore_ra, bore_dec = frame.boresight_ra_deg, frame.boresight_dec_deg
    background = None
    if args.background:
        background = _image_background(campaign, t, bore_ra, bore_dec, args.band, catalog)
    result = render_frame(
        frame, inst, args.band, window, args.bin, background["total"] if background is not None else None
    )
    prov = _provenance(args, t, (bore_ra, bore_dec), target, (catalog, campaign, band), background)
    write_fits(result, out, prov, compress=args.compress, quantize_step=args.quantize_step)
    _print_summary(out, result, args, frame, star_label, background)
    return 0


def _empty_field_allowed(args, catalog, target) -> bool:
    """No star reaches the detector: warn; True with ``--allow-empty`` (the zero image is
    written), else False (nothing is written)."""
    where = "the chip's centre" if args.center == "detector" else "the boresight (in a gap between chips)"
    msg = (
        f"no star of {catalog} reaches detector {args.detector} (target RA {target[0]:.4f}, Dec "
        f"{target[1]:+.4f} at {where}): the stray-light image is zero everywhere"
    )
    if not args.allow_empty:
        print(
            f"straylight: warning: {msg}; nothing written (pass --allow-empty to write it)",
            file=sys.stderr,
        )
        return False
    print(f"straylight: warning: {msg}", file=sys.stderr)
    return True


def _provenance(args, t, boresight, target, inputs, background) -> dict:
    """The FITS header's provenance cards of ``straylight image``: ``boresight`` and ``target``
    (RA, Dec) deg, ``inputs`` (catalog path, campaign, band), ``background`` (or None)."""
    from straylight import __version__

    bore_ra, bore_dec = boresight
    catalog, campaign, band = inputs
    prov = {
        "DATE-OBS": t.isot,
        "RA_PNT": bore_ra,
        "DEC_PNT": bore_dec,
        "RA_TARG": target[0],
        "DEC_TARG": target[1],
        "CENTER": args.center,
        "BAND": args.band,
        "DETECTOR": args.detector,
        "CATALOG": str(catalog)[-60:],
        "SLVERS": __version__,
        "CONFIG": str(campaign.path)[-60:],
        "TPUTSRC": band.origin[:60],
    }
    if args.star is not None:
        prov["STAR"] = args.star[:60]
    if background is not None:
        prov.update(
            {
                "BKG_TOT": background["total"],
                "BKG_ZODI": background["zodiacal"],
                "BKG_OBS": bool(background["observable"]),
                "BKG_NOTE": "diffuse bkg at RA/DEC_PNT, e-/s/pix",
            }
        )
    return prov


def _print_summary(out, result, args, frame, star_label: str, background) -> None:
    """``straylight image``'s closing line: the file, the image and what reached it."""
    bore_ra, bore_dec = frame.boresight_ra_deg, frame.boresight_dec_deg
    img = result.image_e_per_s_per_pix
    centred = f", centred: {star_label}" if star_label else ""
    added = ""
    if background is not None:
        added = f"; background {background['total']:.4g} e-/s/pix added"
        if not background["observable"]:
            added += f" (pointing NOT observable: {background['violations']})"
    print(
        f"{out}: {img.shape[1]} x {img.shape[0]} px (bin {args.bin}), {out.stat().st_size / 1e6:.1f} MB "
        f"({args.compress}); boresight RA {bore_ra:.5f} Dec {bore_dec:+.5f}; "
        f"{len(result.stars['x_pix'])} stars reach the chip ({frame.selection.n_on_chip} on it){centred}; "
        f"{len(result.ghosts['x_pix'])} ghost discs; max {img.max():.4g}, median {np.median(img):.4g} "
        f"e-/s/pix{added}"
    )


def _image_background(campaign, t, ra_deg: float, dec_deg: float, band: str, catalog) -> dict:
    """Diffuse background (zodiacal, earthshine, Moon, Sun, planets, off-field stars) at the
    boresight and time, e-/s/pixel, through the pointing-table evaluation."""
    from straylight.planning.pointings import pointing_table
    from straylight.sky.geometry import violation_names
    from straylight.sources.stars_table import load_offfield_stars

    stars = load_offfield_stars(
        catalog,
        [band],
        float(campaign.settings.stars.offfield_mag_limit),
        campaign.settings.stars.faint_map,
    )
    cols = pointing_table(
        campaign,
        {"time": np.array([t.isot]), "ra": np.array([ra_deg]), "dec": np.array([dec_deg])},
        [band],
        stars,
        source="--time/--ra/--dec",
    )
    return {
        "total": float(cols[f"total_{band}"][0]),
        "zodiacal": float(cols[f"zodiacal_{band}"][0]),
        "observable": bool(cols["observable"][0]),
        "violations": ", ".join(violation_names(int(cols["violations"][0]))) or "door",
    }
