"""The ``straylight`` argument parser: one small function per command adds its sub-parser and
names the function that runs it (``cmd_<command>`` in the command group's module).

A new command: its ``cmd_`` function in the module of its group (or a new one), an ``_add_``
function here and a line in :data:`COMMANDS`.
"""

from __future__ import annotations

import argparse

from straylight.cli import campaign, etc, image, paper, sky
from straylight.cli._common import CONFIG_HELP, add_output_flags, finite_float

__all__ = ["COMMANDS", "OneLineParser", "build_parser"]


def _add_ephem(sub) -> None:
    e = sub.add_parser("ephem", help="geocentric DE405 positions of the Sun, Moon and planets")
    e.add_argument("--time", required=True, help="UTC time, ISO 8601 (e.g. 2026-01-01T00:50:00)")
    e.add_argument("--bodies", default=None, help="comma-separated bodies (default: all)")
    e.add_argument("--json", action="store_true", help="print JSON")
    e.set_defaults(func=sky.cmd_ephem)


def _add_sky(sub) -> None:
    s = sub.add_parser(
        "sky",
        help="the sky background of one pointing at one time: every component and the total "
        "(e-/s/pixel, AB mag/arcsec2), the 5-sigma limit, geometry and observability; --input: "
        "a table of pointings",
    )
    s.add_argument("--time", default=None, help="UTC time, ISO 8601")
    s.add_argument("--ra", default=None, help="ICRS right ascension, deg, within [-360, 360]")
    s.add_argument("--dec", default=None, help="ICRS declination, deg, within [-90, 90]")
    s.add_argument(
        "--input",
        default=None,
        help="table of pointings (time, ra, dec; CSV/ECSV/Parquet/FITS) -> --out table.parquet",
    )
    s.add_argument("--out", default=None, help="with --input: output Parquet table")
    add_output_flags(s)
    s.add_argument("--config", default=None, help=CONFIG_HELP)
    s.add_argument(
        "--bands",
        default=None,
        help="comma-separated bands (default: the instrument's); 'V' = Bessell V diagnostic",
    )
    s.add_argument(
        "--catalog",
        default=None,
        help="star table (ra, dec, mag_<band>) for the off-field star term (stars brighter than "
        "stars.offfield_mag_limit, as in the cube); without it stars = 0",
    )
    s.add_argument("--json", action="store_true", help="print JSON")
    s.set_defaults(func=sky.cmd_sky)


def _add_image(sub) -> None:
    im = sub.add_parser(
        "image",
        help="in-field stray light of one detector (stars, planets, mirror scattering, ghosts) as "
        "FITS, e-/s/pixel",
    )
    im.add_argument(
        "--time", required=True, help="UTC time, ISO 8601, or with an offset (+08:00); sets the roll"
    )
    im.add_argument("--ra", default=None, help="target RA, deg (ICRS)")
    im.add_argument("--dec", default=None, help="target Dec, deg (ICRS)")
    im.add_argument(
        "--star",
        default=None,
        help="target star instead of --ra/--dec: a HIP number (e.g. 32349 or HIP32349) or an IAU "
        "name of a bright star (e.g. Sirius), looked up in the catalog",
    )
    im.add_argument(
        "--center",
        choices=("detector", "boresight"),
        default="detector",
        help="detector (default): the target lands on the centre of --detector; boresight: the "
        "target is the telescope axis (which falls in a gap between chips)",
    )
    im.add_argument("--band", required=True, help="band (NUV u g r i z y)")
    im.add_argument("--detector", type=int, default=12, help="detector index 0..29 (row-major; default 12)")
    im.add_argument(
        "--catalog",
        default=None,
        help="star table with ra, dec, mag_<band> (Parquet/FITS/CSV/ECSV); default: the "
        "campaign's Hipparcos catalog (as `straylight catalog` without --input), built once "
        "and cached",
    )
    im.add_argument("--out", required=True, help="output FITS file")
    im.add_argument(
        "--bin",
        type=int,
        default=1,
        help="average N x N pixels (e-/s per chip pixel kept; 8 makes a 5 MB preview)",
    )
    im.add_argument(
        "--cutout",
        default=None,
        help="WIDTH[,HEIGHT] pixels around the target instead of the whole 9216 x 9232 chip",
    )
    im.add_argument(
        "--compress",
        choices=("gzip", "rice", "none"),
        default="gzip",
        help="FITS tile compression: gzip (lossless, default), rice (values quantised to "
        "--quantize-step), none",
    )
    im.add_argument(
        "--quantize-step",
        type=float,
        default=None,
        help="with --compress rice: quantisation step, e-/s/pixel (default 1e-4)",
    )
    im.add_argument(
        "--background",
        action="store_true",
        help="add the diffuse background (zodiacal, earthshine, Moon, Sun, planets, off-field "
        "stars) at that time and boresight, as `straylight sky` gives it",
    )
    im.add_argument(
        "--allow-empty",
        action="store_true",
        help="write the image even when no star reaches the chip (otherwise: warning, exit 1)",
    )
    im.add_argument(
        "--far-bin", type=int, default=8, help="binning of the far-field halo convolution (1 = exact)"
    )
    im.add_argument(
        "--margin-arcsec", type=float, default=600.0, help="stars this far off the chip still count"
    )
    im.add_argument("--no-ghosts", action="store_true", help="list ghost discs but do not paint them")
    im.add_argument("--config", default=None, help=CONFIG_HELP)
    add_output_flags(im)
    im.set_defaults(func=image.cmd_image)


def _add_scenario(sub) -> None:
    sc = sub.add_parser(
        "scenario",
        help="the paper's CSST-versus-HST earthshine scenario (sect. 3.3) as a figure and a table",
    )
    sc.add_argument(
        "--out",
        default=None,
        help="output PNG, a CSV goes beside it (default: results/scenarios/earthshine.png, its "
        "folders created)",
    )
    sc.add_argument("--band", default="V", help="band (default V, as the HST comparison)")
    add_output_flags(sc)
    sc.add_argument(
        "--hst-curve",
        default=None,
        metavar="PATH",
        help="HST earthshine curve (CSV: limb_angle_deg, v_mag_per_arcsec2) to overlay; prints "
        "and writes (JSON beside the CSV) the limb angle where CSST's median falls to HST's "
        "at 20 deg",
    )
    sc.add_argument("--config", default=None, help=CONFIG_HELP)
    sc.set_defaults(func=paper.cmd_scenario)


def _add_plan(sub) -> None:
    pl = sub.add_parser("plan", help="samples, output size and core-hours of a campaign before running it")
    pl.add_argument("config", nargs="?", default=None, help=CONFIG_HELP)
    how = pl.add_mutually_exclusive_group()
    how.add_argument(
        "--seconds-per-sample",
        type=float,
        default=None,
        help="cost of one evaluated (time, pointing) sample, all bands, one core, on the "
        "machine that will run (default: straylight.planning.plan's cost figures for the "
        "earthshine model auto picks)",
    )
    how.add_argument(
        "--calibrate",
        action="store_true",
        help="time a few cube steps on this machine (seconds) and scale the figures by it",
    )
    pl.add_argument(
        "--cores",
        type=int,
        default=None,
        help="cores the campaign will run on (default: the CPUs this process may use)",
    )
    pl.set_defaults(func=campaign.cmd_plan)


def _add_catalog(sub) -> None:
    ca = sub.add_parser(
        "catalog", help="bright-star catalog in the CSST bands (Gaia DR2 files, or Hipparcos)"
    )
    ca.add_argument(
        "--input",
        nargs="*",
        default=[],
        help="Gaia DR2 files (CSV, CSV.gz, ECSV, VOTable, FITS); none: the default Hipparcos catalog",
    )
    ca.add_argument("--out", required=True, help="output catalog (.parquet or .fits)")
    ca.add_argument("--fits", default=None, help="also write a FITS copy for image-simulation tools")
    ca.add_argument("--config", default=None, help=CONFIG_HELP)
    ca.add_argument("--json", action="store_true", help="print the summary as JSON")
    add_output_flags(ca)
    ca.set_defaults(func=campaign.cmd_catalog)


def _add_pst(sub) -> None:
    ps = sub.add_parser("pst", help="export the embedded default PST matrix (CSV) to inspect or replace")
    ps.add_argument("--write-default", required=True, help="output CSV (theta_deg, phi_deg, pst)")
    add_output_flags(ps)
    ps.set_defaults(func=campaign.cmd_pst)


def _add_schedule(sub) -> None:
    sh = sub.add_parser(
        "schedule",
        help="scheduling tables (CSV and PNG): Moon angle per lunar phase, bright-limb elevation per Sun "
        "zenith angle, exposure-time factor",
    )
    sh.add_argument("--out", required=True, help="output folder (CSV and PNG per table)")
    sh.add_argument(
        "--fraction",
        type=float,
        default=None,
        help="stray light allowed, as a fraction of the darkest zodiacal light (default: config "
        "scheduling.fraction_of_zodiacal)",
    )
    sh.add_argument("--config", default=None, help=CONFIG_HELP)
    add_output_flags(sh)
    sh.set_defaults(func=campaign.cmd_schedule)


def _add_figure(sub) -> None:
    fg = sub.add_parser(
        "figure",
        help="one of the paper's in-field figures as a PNG: zodiacal V map (4.1), mirror "
        "scattering (4.2), NUV ghosts (4.3), a partial NUV detector image (4.4)",
    )
    fg.add_argument(
        "name",
        choices=["zodiacal-map", "scattering", "ghosts", "detector"],
        help="zodiacal-map (4.1), scattering (4.2), ghosts (4.3), detector (4.4); "
        "the earthshine figure (3.3) is 'straylight scenario'",
    )
    fg.add_argument("--out", default=None, help="output PNG (default docs/img/paper_<name>.png)")
    fg.add_argument(
        "--catalog",
        default=None,
        help="detector: star table (ra, dec, mag_NUV); default the Hipparcos catalog in the CSST bands",
    )
    fg.add_argument("--config", default=None, help=CONFIG_HELP)
    fg.set_defaults(func=paper.cmd_figure)


def _add_time_window(p, start_flag: str, one_time: bool = False) -> None:
    """The options of a window of sampled times, as
    :func:`straylight.planning.visibility.sampled_window` checks them: its start ``start_flag``,
    ``--end`` (exclusive) and ``--step-min``.  ``one_time`` (etc): the start is required, one time
    without ``--end``; else (visibility) the window is the campaign's by default."""
    if one_time:
        p.add_argument(start_flag, required=True, help="UTC time, ISO 8601 (with --end: the window's start)")
        end_help, step_help = "UTC end of a window of times, exclusive", "with --end: sampling step"
    else:
        p.add_argument(start_flag, default=None, help="UTC start, ISO 8601 (default: the campaign's start)")
        end_help, step_help = "UTC end, exclusive (default: the campaign's end)", "sampling step"
    p.add_argument("--end", default=None, help=end_help)
    p.add_argument(
        "--step-min",
        type=finite_float("--step-min"),
        default=None,
        help=f"{step_help}, minutes (default: the campaign's cadence)",
    )


def _add_visibility(sub) -> None:
    v = sub.add_parser(
        "visibility",
        help="a target's (or, with --targets, many targets') background, 5-sigma limit and "
        "observable windows over time, and the days deeper than a threshold (tables, a plot)",
    )
    v.add_argument("--ra", default=None, help="ICRS right ascension, deg")
    v.add_argument("--dec", default=None, help="ICRS declination, deg")
    v.add_argument(
        "--targets",
        default=None,
        metavar="FILE",
        help="CSV of targets (name, ra, dec in deg; ra and dec empty: the name is looked up among "
        "the packaged fields and galaxies and the catalog's stars) instead of --ra/--dec: a summary "
        "per target and month; --out FOLDER gets it and each target's windows and days",
    )
    v.add_argument("--band", required=True, help="band (NUV u g r i z y)")
    _add_time_window(v, "--start")
    v.add_argument(
        "--threshold",
        type=finite_float("--threshold"),
        default=None,
        help="AB mag: list the days when the 5-sigma limit is at least this deep",
    )
    v.add_argument(
        "--out",
        default=None,
        help="table of the samples (.csv or .ecsv); _windows and _days tables are written beside it "
        "(with --targets: a folder)",
    )
    v.add_argument(
        "--plot", default=None, help="figure of background and limit against time (.png, .pdf, .svg)"
    )
    v.add_argument("--config", default=None, help=CONFIG_HELP)
    add_output_flags(v)
    v.set_defaults(func=sky.cmd_visibility)


def _add_etc(sub) -> None:
    et = sub.add_parser(
        "etc",
        help="exposure time for a point source to reach an SNR (or the SNR of a time), per band",
        description="Exposure time a point source of AB magnitude --mag needs to reach --snr in the "
        "EE80 aperture, or with --exptime the SNR it reaches, at the background of that time and "
        "pointing (as `straylight sky` gives it) and the survey's noise model (read noise, dark "
        "current, zero points; the CCD equation of the 5-sigma limits).  The time is the total of "
        "all exposures: it is split into the band's survey number of exposures (2; NUV and y 4, "
        "as 2 x 150 s and 4 x 150 s) or --n-exp, the read noise counted once per exposure.  A "
        "sample that is not observable gets no time or SNR.  With --end: every --step-min from "
        "--time, and per band the shortest (or best), median and longest over the observable samples.",
    )
    et.add_argument("--ra", required=True, help="ICRS right ascension, deg")
    et.add_argument("--dec", required=True, help="ICRS declination, deg")
    _add_time_window(et, "--time", one_time=True)
    et.add_argument("--mag", required=True, type=finite_float("--mag"), help="source AB magnitude")
    what = et.add_mutually_exclusive_group()
    what.add_argument(
        "--snr",
        type=finite_float("--snr"),
        default=None,
        help="SNR to reach (default 5): gives the exposure time",
    )
    what.add_argument(
        "--exptime",
        type=finite_float("--exptime"),
        default=None,
        help="total exposure time, s (all exposures): gives the SNR instead",
    )
    et.add_argument(
        "--bands",
        "--band",
        dest="bands",
        default=None,
        help="comma-separated survey bands (default: all of NUV u g r i z y)",
    )
    et.add_argument(
        "--n-exp",
        type=int,
        default=None,
        help="exposures the time is split into (default: the band's survey count)",
    )
    et.add_argument(
        "--catalog",
        default=None,
        help="star table (ra, dec, mag_<band>) for the off-field star term, as `straylight sky`; "
        "without it stars = 0",
    )
    et.add_argument(
        "--ignore-constraints",
        action="store_true",
        help="compute where a constraint is violated too (still flagged), e.g. 50-80 deg from the "
        "bright limb, where the paper (sect. 1) suggests longer exposures; the window's summary "
        "keeps to observable samples",
    )
    et.add_argument("--out", default=None, help="also write the per-sample table (.csv or .ecsv)")
    add_output_flags(et)
    et.add_argument("--config", default=None, help=CONFIG_HELP)
    et.add_argument(
        "--json", action="store_true", help="print JSON (samples, units and, with --end, the summary)"
    )
    et.set_defaults(func=etc.cmd_etc)


def _add_config_doc(sub) -> None:
    cd = sub.add_parser("config-doc", help="print the campaign-config reference (Markdown) from the schema")
    cd.set_defaults(func=campaign.cmd_config_doc)


def _add_footprint(sub) -> None:
    f = sub.add_parser("footprint", help="the survey footprint of a campaign: pixels, nside and area")
    f.add_argument("--config", default=None, help=CONFIG_HELP)
    f.set_defaults(func=campaign.cmd_footprint)


def _add_run(sub) -> None:
    # arguments it does not know go to Snakemake (straylight.cli.main: parse_known_args)
    ru = sub.add_parser(
        "run",
        help="run a campaign through Snakemake in the current directory: products in "
        "./results/<campaign name>/, a progress bar, Snakemake's log in their work/logs/ "
        "(-v: on the console)",
        usage="straylight run CONFIG [--cores N] [-v] [Snakemake arguments: -n, --report report.html ...]",
    )
    ru.add_argument(
        "config", metavar="CONFIG", help="campaign config; products go to ./results/<campaign name>/"
    )
    ru.add_argument(
        "--cores",
        type=int,
        default=None,
        help="cores Snakemake may use (default: every CPU this process may run on)",
    )
    ru.add_argument(
        "-v",
        "--verbose",
        action="store_true",
        help="Snakemake's log on the console instead of the progress bar (it goes to "
        "results/<campaign name>/work/logs/snakemake.log otherwise)",
    )
    ru.set_defaults(func=campaign.cmd_run, snakemake_args=[])


#: The commands in the order ``straylight --help`` lists them: each adds its sub-parser.
COMMANDS = (
    _add_ephem,
    _add_sky,
    _add_image,
    _add_scenario,
    _add_plan,
    _add_catalog,
    _add_pst,
    _add_schedule,
    _add_figure,
    _add_visibility,
    _add_etc,
    _add_config_doc,
    _add_footprint,
    _add_run,
)


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr and exit status 2, as the
    commands' own (no usage block): ``straylight sky: error: argument --dec: ...``."""

    def error(self, message):
        """Print ``message`` as one line and exit with status 2.

        Parameters
        ----------
        message : str
            The error's text.
        """
        text = " ".join(str(message).split())
        self.exit(2, f"{self.prog}: error: {text} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """The ``straylight`` parser: ``--version`` and one sub-parser per command of :data:`COMMANDS`
    (each a :class:`OneLineParser`)."""
    from straylight import __version__

    p = OneLineParser(prog="straylight", description="CSST stray-light and sky-background pipeline")
    p.add_argument("--version", action="version", version=f"straylight {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    for add in COMMANDS:
        add(sub)
    return p
