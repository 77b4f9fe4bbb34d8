"""The report's depth figures and first page: the limit maps with the depth table (median and best
5-sigma depth and observable fraction per band), and the first page: that table and the depth
maps first, then a guide to the other figures and their thumbnails.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from straylight.plots.common import DEPTH_PERCENTILES, MIN_COLOUR_SPAN_MAG
from straylight.plots.depth_maps import limit_maps
from straylight.plots.maps import _percentiles

__all__ = [
    "DEPTH_TABLE",
    "DEPTH_THUMBNAILS",
    "FRONT_PAGE_STYLE",
    "OTHER_THUMBNAILS",
    "REPORT_CATEGORIES",
    "THUMBNAILS",
    "depth_summary",
    "limit_figures",
    "read_depth_table",
    "write_depth_table",
    "write_report_front",
]


def depth_summary(limits_ds, observable_fraction: float | None = None) -> dict:
    """Per band: the median over the footprint of each pixel's median 5-sigma limit, the best
    pixel's best limit (AB mag), and the observable fraction of all (time, pixel) samples
    (``observable_fraction`` where the caller has counted it, else counted here from
    ``limits_ds["observable"]``).

    Parameters
    ----------
    limits_ds : xarray.Dataset
        The limits product.
    observable_fraction : float, optional
        The observable fraction of all samples, if counted by the caller.
    """
    obs = observable_fraction
    if obs is None:
        # counted a pixel block at a time (an exact integer, so the same fraction as the mean of
        # the whole array), as stored: never the whole (time, pixel) array at once
        observable = limits_ds["observable"]
        block = int((observable.encoding.get("chunks") or observable.shape)[1])
        count = sum(
            int(np.count_nonzero(observable.isel(pixel=slice(a, a + block)).values))
            for a in range(0, observable.shape[1], block)
        )
        obs = count / observable.size
    rows = {}
    for ib, band in enumerate(limits_ds["band"].values):
        med = np.asarray(limits_ds["limiting_mag_median"].isel(band=ib), float)
        best = np.asarray(limits_ds["limiting_mag_best"].isel(band=ib), float)
        rows[str(band)] = {
            "median_depth_mag": float(np.nanmedian(med)) if np.isfinite(med).any() else float("nan"),
            "best_depth_mag": float(np.nanmax(best)) if np.isfinite(best).any() else float("nan"),
            "observable_fraction": obs,
        }
        # the depth budget's central interval of the median depth, where the product has it
        for key in ("p16", "p84"):
            name = f"limiting_mag_median_{key}"
            if name in limits_ds:
                v = np.asarray(limits_ds[name].isel(band=ib), float)
                rows[str(band)][f"median_depth_{key}_mag"] = (
                    float(np.nanmedian(v)) if np.isfinite(v).any() else float("nan")
                )
    return rows


#: The depth table's file name (written with the limit maps: :func:`limit_figures`)
DEPTH_TABLE = "depth_summary.csv"


def write_depth_table(rows: dict, path) -> Path:
    """The depth table ``rows`` of :func:`depth_summary` as CSV at ``path``: per band, the
    median and best 5-sigma depth (AB mag) and the observable fraction of all samples, then,
    where the rows have them, the depth budget's 16th and 84th percentiles of the median depth
    (AB mag).

    Parameters
    ----------
    rows : dict
        Band -> row (:func:`depth_summary`).
    path : str or pathlib.Path
        The CSV file.
    """
    from straylight.util.io import atomic_path

    path = Path(path)
    interval = all("median_depth_p16_mag" in r for r in rows.values()) and bool(rows)
    extra = ",median_depth_p16_mag,median_depth_p84_mag" if interval else ""
    with atomic_path(path) as tmp:
        lines = ["band,median_depth_mag,best_depth_mag,observable_fraction" + extra]
        lines += [
            f"{b},{r['median_depth_mag']:.2f},{r['best_depth_mag']:.2f},{r['observable_fraction']:.3f}"
            + (f",{r['median_depth_p16_mag']:.2f},{r['median_depth_p84_mag']:.2f}" if interval else "")
            for b, r in rows.items()
        ]
        tmp.write_text("\n".join(lines) + "\n")
    return path


def read_depth_table(path) -> dict:
    """The rows :func:`write_depth_table` wrote (band -> the three numbers, as written).

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file.
    """
    import csv

    with open(path, newline="") as f:
        return {r["band"]: {k: float(v) for k, v in r.items() if k != "band"} for r in csv.DictReader(f)}


def limit_figures(limits_path, campaign, out_dir) -> list:
    """The limits' figures in ``out_dir``: the best and median limit maps (:func:`limit_maps`)
    and the depth table (:data:`DEPTH_TABLE`, :func:`depth_summary`); the paths written.

    Parameters
    ----------
    limits_path : str or pathlib.Path
        The limits product (Zarr).
    campaign : Campaign
        The campaign.
    out_dir : str or pathlib.Path
        The folder the figures are written to.
    """
    import xarray as xr
    import zarr

    from straylight.storage.zarr_io import read_region

    # the per-pixel summaries (pixel x band: small) read once, not once a band and map
    with xr.open_zarr(limits_path, chunks=None) as stored:
        summaries = stored[[v for v in stored.data_vars if "time" not in stored[v].dims]].load()
    # the observable samples counted from the store's chunks, a pixel block at a time (an exact
    # integer: the fraction depth_summary would count, without zarr's pipeline per chunk)
    observable = zarr.open_group(str(limits_path), mode="r", use_consolidated=False)["observable"]
    block = int(observable.chunks[1])
    count = sum(
        int(np.count_nonzero(read_region(observable, (slice(None), slice(a, a + block)))))
        for a in range(0, observable.shape[1], block)
    )
    written = limit_maps(summaries, campaign, out_dir)
    rows = depth_summary(summaries, count / observable.size)
    return written + [write_depth_table(rows, Path(out_dir) / DEPTH_TABLE)]


#: The report's categories (Snakemake sorts them by name: the numbers set their order), as the
#: workflow's report rules name them
REPORT_CATEGORIES = (
    "1. Depth: table and maps",
    "2. Sky background maps",
    "3. Time series",
    "4. Scheduling tables",
    "5. Provenance",
    "6. Speed against accuracy",
)


#: The first page's layout (raw HTML in its RST): Snakemake's report centres the page vertically in
#: a window-high box, so a page taller than the window has its top (the depth table) out of
#: reach above the scroll, and holds it to 32 rem, too narrow for a page of maps.  Aligned to the
#: top and up to 64 rem wide, the table and then the depth maps are the first thing a reader
#: sees.  The style lives in the page's own HTML: it goes with the page when the reader opens
#: another view.
FRONT_PAGE_STYLE = """.. raw:: html

   <style>
   div.items-center.justify-center.h-screen.overflow-auto { align-items: flex-start; }
   div.prose.max-w-lg { max-width: 64rem; }
   </style>
"""


def write_report_front(rows: dict, config: dict, path, figure_dirs=()) -> Path:
    """``path`` (the report's first page, RST rendered by Snakemake's Jinja): the campaign of
    ``config`` (a validated campaign config: ``Campaign.config_mapping()``, or the workflow's), then the
    depth table ``rows`` (:func:`read_depth_table`) and the depth maps, then a guide to the other
    figures, with thumbnails of those found in ``figure_dirs`` (depth/, sky/ and series/ of the
    campaign's results).

    Parameters
    ----------
    rows : dict
        The depth table (:func:`read_depth_table`).
    config : dict
        A validated campaign config.
    path : str or pathlib.Path
        The page written (RST).
    figure_dirs : sequence of str or pathlib.Path, optional
        Folders whose figures get thumbnails.
    """
    from straylight.util.io import atomic_path

    c = config["campaign"]
    table = [
        "   * - band",
        "     - median depth (AB mag)",
        "     - best depth (AB mag)",
        "     - observable fraction",
    ]
    for b, r in rows.items():
        interval = (
            f" ({r['median_depth_p16_mag']:.2f} - {r['median_depth_p84_mag']:.2f})"
            if "median_depth_p16_mag" in r
            else ""
        )
        table += [
            f"   * - {b}",
            f"     - {r['median_depth_mag']:.2f}{interval}",
            f"     - {r['best_depth_mag']:.2f}",
            f"     - {100 * r['observable_fraction']:.1f} %",
        ]
    dirs = [Path(d) for d in figure_dirs]
    depth_cat, sky_cat, series_cat, sched_cat = REPORT_CATEGORIES[:4]
    text = f"""{FRONT_PAGE_STYLE}
Campaign **{c["name"]}**, {c["start"]} to {c["end"]} UTC, every {float(c["cadence_s"]):g} s:
stray light and sky background for the CSST survey camera (straylight; method of Xian et al.).

.. list-table:: 5-sigma point-source depth for the band's survey exposures (median over the footprint of each
   pixel's median over time, in brackets its 16th - 84th percentile from the depth error budget; best: the
   deepest pixel at its best time), and the fraction of (time, pointing) samples that are observable
   :header-rows: 1

{chr(10).join(table)}
{_thumbnails(dirs, DEPTH_THUMBNAILS, 1500)}

**Reading the maps**: all-sky Mollweide in ICRS, centred on RA 0h, RA (hours) increasing to the left
(East, marked E), Dec in degrees. Dashed: the ecliptic; dotted: the Galactic plane; yellow disc: the
Sun (on the depth maps, a ring at the campaign's start and a disc at its end). Light grey: outside the
footprint or never observable. One colour scale per band for all its depth maps (its
{_percentiles(DEPTH_PERCENTILES)}, at least {MIN_COLOUR_SPAN_MAG:g} mag wide); pixels beyond it take the
end colours. ``{DEPTH_TABLE}`` holds the table above (*{depth_cat}*).

**Other figures**: *{sky_cat}*: ``sky_<band>_<time>``, each background component at one time in AB
mag/arcsec2 (components zero everywhere are listed in the title instead of drawn); *{series_cat}*:
``series_orbit_*`` and ``series_campaign_*`` follow three pointings in mag/arcsec2 (grey: not
observable); *{sched_cat}* (CSV and PNG): the Moon angle and bright-limb elevation that keep stray
light below a fraction of the darkest zodiacal light, and the exposure-time factor. Provenance
(config, software versions, checksums) is in provenance.json.
"""
    text += _thumbnails(dirs, OTHER_THUMBNAILS, 560)
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return path


#: The figures shown on the report's first page as thumbnails (file-name prefix, caption): the
#: depth maps under the depth table, full width; the others after the guide
DEPTH_THUMBNAILS = (
    ("limits_median", "Median 5-sigma depth per band over the campaign (AB mag)."),
    ("limits_best", "Best 5-sigma depth per band (AB mag)."),
)
OTHER_THUMBNAILS = (
    ("sky_g_", "Every background component in g at the first map time (AB mag/arcsec2)."),
    (
        "series_orbit_",
        "One pointing over the first orbit, every band (AB mag/arcsec2; grey: not observable).",
    ),
)
THUMBNAILS = DEPTH_THUMBNAILS + OTHER_THUMBNAILS


def _thumbnails(dirs: list, which=THUMBNAILS, width_px: int = 560) -> str:
    """RST figures of ``which`` (of :data:`THUMBNAILS`) found in ``dirs``, at most ``width_px``
    wide, as embedded PNG (data URIs: the report is one self-contained file)."""
    import base64
    import io

    from PIL import Image

    parts = []
    for prefix, caption in which:
        found = sorted(p for d in dirs for p in d.glob(f"{prefix}*.png"))
        if not found:
            continue
        img = Image.open(found[0])
        img.thumbnail((width_px, width_px))
        buf = io.BytesIO()
        img.save(buf, format="PNG", optimize=True)
        # raw HTML with the base64 split over lines (docutils limits a line to 10,000 characters;
        # browsers drop the whitespace inside a base64 data URI)
        b64 = base64.b64encode(buf.getvalue()).decode()
        lines = "\n".join("   " + b64[i : i + 76] for i in range(0, len(b64), 76))
        parts.append(
            f'.. raw:: html\n\n   <figure style="display:inline-block;margin:6px;vertical-align:top">\n'
            f'   <img style="width:{img.width}px;max-width:100%" alt="{found[0].stem}" '
            f'src="data:image/png;base64,\n{lines}\n   ">\n'
            f'   <figcaption style="font-size:90%"><b>{found[0].stem}</b>: {caption} Full size in '
            f"<i>{_category(prefix)}</i>.</figcaption></figure>\n"
        )
    return "\n" + "\n".join(parts) if parts else ""


def _category(prefix: str) -> str:
    """The report category holding the figures named ``prefix``*."""
    if prefix.startswith("limits_"):
        return REPORT_CATEGORIES[0]
    return REPORT_CATEGORIES[1] if prefix.startswith("sky_") else REPORT_CATEGORIES[2]
