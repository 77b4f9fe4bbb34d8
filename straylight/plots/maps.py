"""All-sky Mollweide maps: the panel (healpy's projection, drawn once per page layout), the
pages of every background component and the total per band at chosen times, and the best and
median limiting-magnitude maps.

Maps are in the cube's HEALPix frame (ICRS); pixels outside the footprint are grey.  Values are
shown as AB mag/arcsec2 (brighter = smaller), the unit planners compare with sky tables.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from straylight.plots.common import _colour_range, _full_sky, _mag, _save, _tick_format

__all__ = [
    "GRATICULE_ALPHA",
    "GRATICULE_COLOUR",
    "GRATICULE_LW",
    "MOLLWEIDE_XSIZE",
    "MollweidePanel",
    "limit_maps",
    "map_time_indices",
    "sky_map_figures",
    "sky_maps",
]


#: Width in image pixels of a Mollweide panel's projected map (0.9 deg per image pixel at the
#: equator): about the map's width on a 4-panel-wide page at 90 dpi (~345 pixels), so that the
#: image is not projected finer than it is shown (healpy mollview's default is 800).
MOLLWEIDE_XSIZE = 400


@lru_cache(maxsize=8)
def _mollweide_pixel_index(nside: int, nest: bool, xsize: int = MOLLWEIDE_XSIZE) -> np.ndarray:
    """The HEALPix pixel seen at each pixel of healpy's Mollweide image (``xsize`` x ``xsize``/2,
    origin lower left, east to the left as in ``mollview``), -1 outside the ellipse: the
    projection healpy's ``projmap`` makes for every map, made once per nside and ordering."""
    import healpy as hp
    from healpy.projector import MollweideProj

    proj = MollweideProj(xsize=xsize, flipconv="astro")
    x, y = proj.ij2xy()
    inside = ~np.ma.getmaskarray(x)
    index = np.full(x.shape, -1, dtype=np.int64)
    vec = proj.xy2vec(np.asarray(x[inside]), np.asarray(y[inside]))
    index[inside] = hp.vec2pix(nside, vec[0], vec[1], vec[2], nest=nest)
    index.setflags(write=False)
    return index


#: The maps' graticule lines: colour, opacity, width (points)
GRATICULE_COLOUR, GRATICULE_ALPHA, GRATICULE_LW = "0.3", 0.5, 0.4


@lru_cache(maxsize=1)
def _graticule_segments(dpar_deg: float = 30.0, dmer_deg: float = 60.0, step: int = 8) -> tuple:
    """Healpy's Mollweide graticule (parallels every ``dpar_deg``, meridians every ``dmer_deg``) and
    its border, as (line style, line width, colour, alpha, vertices) groups in the axes' data
    coordinates: projected once by ``SphericalProjAxes.graticule`` on a scratch axes.  healpy
    samples the lines every 0.1 deg; every ``step``-th vertex (and the last) is kept: vertices
    ~1 page pixel apart on a 4-panel-wide page, the same curves as drawn."""
    import healpy.projaxes as PA
    from matplotlib.figure import Figure

    ax = PA.HpxMollweideAxes(Figure(), (0.0, 0.0, 1.0, 1.0), flipconv="astro")
    ax.graticule(dpar=dpar_deg, dmer=dmer_deg, color=GRATICULE_COLOUR, alpha=GRATICULE_ALPHA, lw=GRATICULE_LW)
    groups = {}
    for line in ax.lines:
        xy = line.get_xydata()
        keep = np.unique(np.r_[np.arange(0, len(xy), step), len(xy) - 1])
        key = (line.get_linestyle(), line.get_linewidth(), line.get_color(), line.get_alpha())
        groups.setdefault(key, []).append(xy[keep])
    return tuple((*key, tuple(segs)) for key, segs in groups.items())


class MollweidePanel:
    """One Mollweide panel at subplot ``sub`` (rows, columns, index from 1) of ``fig``, laid out,
    coloured and annotated as healpy's ``mollview(..., notext=True)`` with a 30/60-deg graticule,
    and with ``unit`` a colour bar of a few rounded ticks with the unit below; :meth:`show` draws
    a map in it, and may be called again for the next map (pages of the same layout share their
    panels: making the axes and colour bars costs more than drawing a map)."""

    def __init__(self, fig, sub: tuple, cmap: str, unit: str | None):
        import healpy.projaxes as PA
        from matplotlib.collections import LineCollection

        # mollview's subplot extent and margins (left, bottom, right, top), in figure fractions
        nrows, ncols, idx = sub
        c, r = (idx - 1) % ncols, (idx - 1) // ncols
        margins = (0.01, 0.0, 0.0, 0.02)
        extent = (
            c / ncols + margins[0],
            1.0 - (r + 1) / nrows + margins[1],
            1.0 / ncols - margins[2] - margins[0],
            1.0 / nrows - margins[3] - margins[1],
        )
        self.fig, self.cmap, self.unit = fig, cmap, unit
        self.ax = PA.HpxMollweideAxes(fig, extent, flipconv="astro")
        # the axes are off (healpy): hidden x and y axes also spare the tick layout that placing
        # the title would otherwise make at every draw
        self.ax.xaxis.set_visible(False)
        self.ax.yaxis.set_visible(False)
        fig.add_axes(self.ax)
        for style, lw, colour, alpha, segments in _graticule_segments():
            self.ax.add_collection(
                LineCollection(segments, linestyles=style, linewidths=lw, colors=colour, alpha=alpha),
                autolim=False,
            )
        self.image = self.colour_bar = None

    def show(self, full_sky, nest: bool, title: str, vmin: float, vmax: float) -> "MollweidePanel":
        """Draw ``full_sky`` (a full HEALPix map; ``UNSEEN`` grey) between ``vmin`` and ``vmax``:
        the image is the cached pixel index of :func:`_mollweide_pixel_index` applied to it,
        drawn with imshow."""
        import healpy as hp
        import healpy.projaxes as PA

        m = np.asarray(full_sky, float)
        index = _mollweide_pixel_index(hp.npix2nside(m.size), bool(nest))
        img = np.full(index.shape, -np.inf)  # outside the ellipse: healpy's background colour
        img[index >= 0] = m[index[index >= 0]]
        seen = np.isfinite(img) & ~hp.mask_bad(img)
        cm, norm = PA.get_color_table(vmin, vmax, img[seen], cmap=self.cmap, badcolor="gray", bgcolor="white")
        data = np.ma.masked_values(img, hp.UNSEEN)
        if self.image is None:
            self.image = self.ax.imshow(
                data,
                extent=self.ax.proj.get_extent(),
                cmap=cm,
                norm=norm,
                interpolation="nearest",
                origin="lower",
            )
            # the limits after imshow, which sets them to the image's extent
            self.ax.set_xlim(-2.01, 2.01)
            self.ax.set_ylim(-1.01, 1.01)
        else:
            self.image.set_data(data)
            self.image.set_cmap(cm)
            self.image.set_norm(norm)
        self.ax.set_title(title)
        if self.unit is not None:
            self._colour_bar(norm, vmin, vmax, cm.N)
        return self

    def _colour_bar(self, norm, vmin: float, vmax: float, n_colours: int) -> None:
        """Mollview's colour bar: ``n_colours`` solid steps between the limits, under the map."""
        from matplotlib.cm import ScalarMappable
        from matplotlib.colors import Normalize

        bounds = norm.inverse(np.linspace(0, 1, n_colours + 1))
        values = np.linspace(norm.vmin, norm.vmax, n_colours)
        bar_norm = Normalize(vmin=norm.vmin, vmax=norm.vmax)
        if self.colour_bar is None:
            self.colour_bar = self.fig.colorbar(
                ScalarMappable(norm=bar_norm, cmap=self.cmap),
                ax=self.ax,
                orientation="horizontal",
                shrink=0.5,
                aspect=25,
                pad=0.05,
                fraction=0.1,
                boundaries=bounds,
                values=values,
            )
            self.colour_bar.ax.tick_params(labelsize=8)
            self.colour_bar.ax.set_xlabel(self.unit, fontsize=9, labelpad=2)
        else:
            # the new steps, then the norm: its change redraws the bar (and resets its ticks)
            self.colour_bar.boundaries, self.colour_bar.values = bounds, values
            self.colour_bar.mappable.set_norm(bar_norm)
        self.colour_bar.solids.set_rasterized(True)
        loc, fmt = _tick_format(vmin, vmax)
        self.colour_bar.ax.xaxis.set_major_locator(loc)
        self.colour_bar.ax.xaxis.set_major_formatter(fmt)


def map_time_indices(ds, n_times: int = 2, times=()) -> list[int]:
    """Indices into ``ds.time`` of the sky maps' times: the samples nearest ``times`` (UTC ISO)
    if given, else ``n_times`` evenly spread over the campaign."""
    if times:
        from straylight.sky.timeutil import parse_utc

        wanted = np.asarray(parse_utc(list(times), "report.times").datetime64, dtype="datetime64[ns]")
        t_all = ds["time"].values
        idx = np.unique([int(np.argmin(np.abs(t_all - w))) for w in wanted])
    else:
        idx = np.unique(np.linspace(0, ds.sizes["time"] - 1, n_times).round().astype(int))
    return [int(i) for i in idx]


def sky_maps(ds, campaign, out_dir, time_indices, bands=None) -> list:
    """Per time (``time_indices`` into ``ds.time``, see :func:`map_time_indices`) and band (all,
    or ``bands``): a 2 x 4 page of Mollweide maps, one per component, the total and the
    observability."""
    from straylight.survey import cube_layout

    nest = str(ds.attrs["healpix_ordering"]).upper() == "NESTED"
    written = []
    pages = {}  # number of component panels -> (figure, their panels, the observability panel)
    for it in time_indices:
        t = str(ds["time"].values[it])[:16]
        # every component at this time, all bands, in one read (each chunk decompressed once)
        snap = ds[list(cube_layout.CUBE_BAND_VARIABLES) + ["observable"]].isel(time=it).compute()
        for ib, band in enumerate(ds["band"].values):
            if bands is not None and str(band) not in bands:
                continue
            maps, zero = [], []
            for comp in cube_layout.CUBE_BAND_VARIABLES:
                e = np.asarray(snap[comp].isel(band=ib), float)
                if not np.any(np.isfinite(e) & (e > 0)):
                    zero.append(comp)  # no panel: say so in the title instead
                    continue
                maps.append((comp, e, _mag(ds, e, str(band), campaign)))
            # the pages with as many panels share one figure, redrawn for each
            if len(maps) not in pages:
                pages[len(maps)] = _sky_page(len(maps))
            fig, panels, obs_panel = pages[len(maps)]
            for panel, (comp, e, mag) in zip(panels, maps):
                lo, hi = _colour_range(mag)
                panel.show(_full_sky(ds, mag), nest, comp, lo, hi)
            obs_panel.show(_full_sky(ds, np.asarray(snap["observable"], float)), nest, "observable", 0, 1)
            # models.unobservable_samples: skip leaves NaN where not observable (e: the total here)
            # a component's 0 (blocked, or skipped below its share of the tolerance) has no magnitude
            grey = "outside the footprint, or a component's 0" + (
                ", or not evaluated (not observable)" if np.isnan(maps[-1][1]).any() else ""
            )
            note = f"; zero everywhere, not shown: {', '.join(zero)}" if zero else ""
            fig.suptitle(
                f"{campaign.name}: band {band} at {t} UTC (ICRS Mollweide, graticule every 30 deg in Dec "
                f"and 60 deg in RA; colours: 2nd-98th percentile per panel; grey: {grey}{note})",
                fontsize=10,
            )
            written.append(
                _save(fig, Path(out_dir) / f"sky_{band}_{t.replace(':', '').replace('-', '')}.png")
            )
    return written


def _sky_page(n_maps: int) -> tuple:
    """A sky-map page's figure (4 panels a row) with ``n_maps`` component panels and the
    observability panel after them, with its legend: (figure, panels, observability panel)."""
    from matplotlib import colormaps
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    ncol = 4
    nrow = int(np.ceil((n_maps + 1) / ncol))
    fig = Figure(figsize=(16, 3.3 * nrow))
    panels = [
        MollweidePanel(fig, (nrow, ncol, k + 1), "viridis_r", "AB mag/arcsec2 (brighter: yellow)")
        for k in range(n_maps)
    ]
    obs_panel = MollweidePanel(fig, (nrow, ncol, n_maps + 1), "RdYlGn", None)
    obs_panel.ax.legend(
        handles=[
            Patch(color=colormaps["RdYlGn"](1.0), label="observable"),
            Patch(color=colormaps["RdYlGn"](0.0), label="not observable"),
            Patch(color="0.5", label="outside the footprint"),
        ],
        loc="upper center",
        bbox_to_anchor=(0.5, -0.02),
        ncol=3,
        fontsize=8,
        frameon=False,
    )
    return fig, panels, obs_panel


def sky_map_figures(background_path, campaign, out_dir) -> list:
    """The sky-map pages (:func:`sky_maps`) of the background cube at ``background_path`` in
    ``out_dir``, at the report's map times (``report.times``, else ``report.sky_map_times``
    spread over the campaign) in its bands (``report.sky_map_bands``, else all): each time read
    once for all its bands.  Returns the paths written; ConfigError naming the config file for a
    band the cube does not have."""
    import xarray as xr

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rc = campaign.config["report"]
    # chunks=None: no dask (the figure rules run side by side; its threads only add overhead);
    # the arrays' own metadata (rule background may be consolidating it meanwhile)
    with xr.open_zarr(background_path, chunks=None, consolidated=False) as ds:
        cube_bands = [str(b) for b in ds["band"].values]
        unknown = sorted(set(rc.get("sky_map_bands") or ()) - set(cube_bands))
        if unknown:
            from straylight.errors import ConfigError

            raise ConfigError(
                f"{campaign.path}: report.sky_map_bands: {', '.join(unknown)} not among the cube's "
                f"bands {', '.join(cube_bands)}"
            )
        bands = [b for b in cube_bands if b in set(rc.get("sky_map_bands") or cube_bands)]
        times = map_time_indices(ds, int(rc["sky_map_times"]), rc.get("times") or ())
        return sky_maps(ds, campaign, out, times, bands)


def limit_maps(limits_ds, campaign, out_dir) -> list:
    """Best and median 5-sigma limiting magnitude over the campaign, per band (Mollweide)."""
    from matplotlib.figure import Figure

    nest = str(limits_ds.attrs.get("healpix_ordering", "RING")).upper() == "NESTED"
    written = []
    for stat in ("best", "median"):
        var = f"limiting_mag_{stat}"
        if var not in limits_ds:
            continue
        fig = Figure(figsize=(16, 6.5))
        for ib, band in enumerate(limits_ds["band"].values):
            v = np.asarray(limits_ds[var].isel(band=ib), float)
            # the bulk of the sky sits within a few 0.01 mag of the best; the shallow tail near the Sun
            # and Moon would take the whole scale: the range is the 10th-99.9th percentile per band
            lo, hi = _colour_range(v, (10.0, 99.9))
            med = float(np.nanmedian(v)) if np.isfinite(v).any() else float("nan")
            MollweidePanel(fig, (2, 4, ib + 1), "magma", "AB mag (5 sigma), deeper: brighter").show(
                _full_sky(limits_ds, v), nest, f"{band} (median {med:.2f})", lo, hi
            )
        fig.suptitle(
            f"{campaign.name}: {stat} 5-sigma point-source limit over the campaign (survey exposures; "
            "colours: 10th-99.9th percentile per band, shallower pixels black; graticule 30/60 deg; "
            "grey: outside the footprint or never observable)",
            fontsize=10,
        )
        written.append(_save(fig, Path(out_dir) / f"limits_{stat}.png"))
    return written
