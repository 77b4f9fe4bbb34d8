"""The report's depth figures and first page: the limit maps with the depth table (median and best
5-sigma depth and observable fraction per band), and the first page with that table, a guide to
the figures and their thumbnails.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from straylight.plots.maps import limit_maps

__all__ = [
    "DEPTH_TABLE",
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
    ``limits_ds["observable"]``)."""
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
    return rows


#: The depth table's file name (written with the limit maps: :func:`limit_figures`)
DEPTH_TABLE = "depth_summary.csv"


def write_depth_table(rows: dict, path) -> Path:
    """The depth table ``rows`` of :func:`depth_summary` as CSV at ``path``: per band, the
    median and best 5-sigma depth (AB mag) and the observable fraction of all samples."""
    from straylight.util.io import atomic_path

    path = Path(path)
    with atomic_path(path) as tmp:
        lines = ["band,median_depth_mag,best_depth_mag,observable_fraction"]
        lines += [
            f"{b},{r['median_depth_mag']:.2f},{r['best_depth_mag']:.2f},{r['observable_fraction']:.3f}"
            for b, r in rows.items()
        ]
        tmp.write_text("\n".join(lines) + "\n")
    return path


def read_depth_table(path) -> dict:
    """The rows :func:`write_depth_table` wrote (band -> the three numbers, as written)."""
    import csv

    with open(path, newline="") as f:
        return {r["band"]: {k: float(v) for k, v in r.items() if k != "band"} for r in csv.DictReader(f)}


def limit_figures(limits_path, campaign, out_dir) -> list:
    """The limits' figures in ``out_dir``: the best and median limit maps (:func:`limit_maps`)
    and the depth table (:data:`DEPTH_TABLE`, :func:`depth_summary`); the paths written."""
    import xarray as xr
    import zarr

    from straylight.survey.storage import read_region

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


def write_report_front(rows: dict, config: dict, path, figure_dirs=()) -> Path:
    """``path`` (the report's first page, RST rendered by Snakemake's Jinja): the campaign of
    ``config`` (a validated campaign config: ``Campaign.config``, or the workflow's), the depth
    table ``rows`` (:func:`read_depth_table`) and a guide to the figures, with thumbnails of
    those found in ``figure_dirs`` (depth/, sky/ and series/ of the campaign's results)."""
    from straylight.util.io import atomic_path

    c = config["campaign"]
    table = [
        "   * - band",
        "     - median depth (AB mag)",
        "     - best depth (AB mag)",
        "     - observable fraction",
    ]
    for b, r in rows.items():
        table += [
            f"   * - {b}",
            f"     - {r['median_depth_mag']:.2f}",
            f"     - {r['best_depth_mag']:.2f}",
            f"     - {100 * r['observable_fraction']:.1f} %",
        ]
    text = f"""Stray-light and sky-background products of the campaign **{c["name"]}**
({c["start"]} to {c["end"]} UTC, every {float(c["cadence_s"]):g} s) for the CSST survey camera
(straylight; method of Xian et al., the seed paper).

.. list-table:: 5-sigma point-source depth for the band's survey exposures (median over the footprint of each
   pixel's median over time; best: the deepest pixel at its best time), and the fraction of (time, pointing)
   samples that are observable
   :header-rows: 1

{chr(10).join(table)}

**Figures** (in *Maps and time series*): ``limits_median`` and ``limits_best`` map the depth
(``{DEPTH_TABLE}`` holds this table); ``sky_<band>_<time>`` show each background component at one
time in AB mag/arcsec2 (components zero everywhere are listed in the title instead of drawn);
``series_orbit_*`` and ``series_campaign_*`` follow three pointings in mag/arcsec2 (grey: not
observable). **Scheduling tables** (CSV and PNG): the Moon angle and bright-limb elevation that
keep stray light below a fraction of the darkest zodiacal light, and the exposure-time factor.
Provenance (config, software versions, checksums) is in provenance.json.
"""
    text += _thumbnails([Path(d) for d in figure_dirs])
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return path


#: The figures shown on the report's first page as thumbnails (file-name prefix, caption).
THUMBNAILS = (
    ("limits_median", "Median 5-sigma depth per band over the campaign (AB mag)."),
    ("limits_best", "Best 5-sigma depth per band (AB mag)."),
    ("sky_g_", "Every background component in g at the first map time (AB mag/arcsec2)."),
    (
        "series_orbit_",
        "One pointing over the first orbit, every band (AB mag/arcsec2; grey: not observable).",
    ),
)


def _thumbnails(dirs: list, width_px: int = 560) -> str:
    """RST figures of :data:`THUMBNAILS` found in ``dirs`` as embedded PNG thumbnails (data URIs:
    the report is one self-contained file)."""
    import base64
    import io

    from PIL import Image

    parts = []
    for prefix, caption in THUMBNAILS:
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
            f'   <img style="width:{img.width}px" alt="{found[0].stem}" '
            f'src="data:image/png;base64,\n{lines}\n   ">\n'
            f'   <figcaption style="font-size:90%"><b>{found[0].stem}</b>: {caption} Full size in '
            f"<i>Maps and time series</i>.</figcaption></figure>\n"
        )
    return "\n" + "\n".join(parts) if parts else ""
