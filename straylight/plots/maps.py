"""All-sky Mollweide maps: the panel (healpy's projection, drawn once per page layout) with its
graticule labelled in RA and Dec, the ecliptic, the Galactic plane and the Sun; the pages of every
background component and the total per band at chosen times (the limiting-magnitude maps:
:mod:`straylight.plots.depth_maps`).

Maps are in the cube's HEALPix frame (ICRS), centred on RA 0h with RA increasing to the left
(East left, as the sky is seen from inside); pixels outside the footprint are light grey.
Background values are shown as AB mag/arcsec2 (brighter = smaller), the unit planners compare
with sky tables; depths as AB mag.  The maps of one band share one colour scale
(:func:`~straylight.plots.common.band_colour_limits`): a colour means the same number on each.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from straylight.plots.common import (
    OUTSIDE_COLOUR,
    SKY_CMAP,
    SKY_PERCENTILES,
    _full_sky,
    _mag,
    _save,
    _tick_format,
    band_colour_limits,
)
from straylight.plots.overlays import (
    ECLIPTIC_STYLE,
    GALACTIC_STYLE,
    SUN_END_STYLE,
    SUN_START_STYLE,
    SUN_TRACK_STYLE,
    ecliptic_radec_deg,
    galactic_plane_radec_deg,
    sun_radec_deg,
)

__all__ = [
    "GRATICULE_ALPHA",
    "GRATICULE_COLOUR",
    "GRATICULE_LW",
    "MOLLWEIDE_XSIZE",
    "MollweidePanel",
    "ORIENTATION",
    "map_time_indices",
    "overlay_legend",
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


#: The maps' graticule lines: colour, opacity, width (points); spacing of the parallels and the
#: meridians (deg); the labels' font size (points)
GRATICULE_COLOUR, GRATICULE_ALPHA, GRATICULE_LW = "0.3", 0.5, 0.4
GRATICULE_DPAR_DEG, GRATICULE_DMER_DEG = 30.0, 60.0
GRATICULE_LABEL_SIZE = 7


@lru_cache(maxsize=1)
def _graticule_segments(step: int = 8) -> tuple:
    """Healpy's Mollweide graticule (parallels every ``GRATICULE_DPAR_DEG``, meridians every
    ``GRATICULE_DMER_DEG``) and its border, as (line style, line width, colour, alpha, vertices)
    groups in the axes' data coordinates: projected once by ``SphericalProjAxes.graticule`` on
    a scratch axes.  healpy samples the lines every 0.1 deg; every ``step``-th vertex (and the
    last) is kept: vertices ~1 page pixel apart on a 4-panel-wide page, the same curves as drawn."""
    import healpy.projaxes as PA
    from matplotlib.figure import Figure

    ax = PA.HpxMollweideAxes(Figure(), (0.0, 0.0, 1.0, 1.0), flipconv="astro")
    ax.graticule(
        dpar=GRATICULE_DPAR_DEG,
        dmer=GRATICULE_DMER_DEG,
        color=GRATICULE_COLOUR,
        alpha=GRATICULE_ALPHA,
        lw=GRATICULE_LW,
    )
    groups = {}
    for line in ax.lines:
        xy = line.get_xydata()
        keep = np.unique(np.r_[np.arange(0, len(xy), step), len(xy) - 1])
        key = (line.get_linestyle(), line.get_linewidth(), line.get_color(), line.get_alpha())
        groups.setdefault(key, []).append(xy[keep])
    return tuple((*key, tuple(segs)) for key, segs in groups.items())


def _projected(proj, radec_deg) -> list:
    """The line through ``radec_deg`` ((n, 2) RA, Dec in deg) in ``proj``'s plane, as the pieces
    between its crossings of the map's edge (RA 12h): a list of (m, 2) vertex arrays."""
    radec = np.atleast_2d(np.asarray(radec_deg, float))
    x, y = proj.ang2xy(radec[:, 0], radec[:, 1], lonlat=True)
    xy = np.column_stack([np.atleast_1d(x), np.atleast_1d(y)])
    cuts = np.flatnonzero(np.abs(np.diff(xy[:, 0])) > 1.0) + 1
    return np.split(xy, cuts)


def _colour_map(name: str):
    """Colour scale ``name`` with the values beyond its range in its end colours (clipped, never
    the background's) and pixels without a value in :data:`OUTSIDE_COLOUR`."""
    from matplotlib import colormaps

    cmap = colormaps[name]
    return cmap.with_extremes(under=cmap(0.0), over=cmap(1.0), bad=OUTSIDE_COLOUR)


class MollweidePanel:
    """One Mollweide panel at subplot ``sub`` (rows, columns, index from 1) of ``fig``, laid out
    as healpy's ``mollview(..., notext=True)`` (ICRS, centred on RA 0h, RA increasing to the
    left) with a 30/60-deg graticule labelled in RA (hours) and Dec (deg), East and West marked,
    and with ``overlays`` the ecliptic and the Galactic plane; with ``unit`` a colour bar of a few
    rounded ticks, ``unit`` below.  :meth:`show` draws a map in it, and may be called again for
    the next map (pages of the same layout share their panels: making the axes and colour bars
    costs more than drawing a map)."""

    def __init__(self, fig, sub: tuple, cmap: str, unit: str | None, overlays: bool = True):
        import healpy.projaxes as PA
        from matplotlib.collections import LineCollection
        from matplotlib.lines import Line2D

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
        self.fig, self.cmap, self.unit = fig, _colour_map(cmap), unit
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
        self._label_graticule()
        self.image = self.colour_bar = None
        self.sun = ()
        if overlays:
            for radec, style in (
                (ecliptic_radec_deg(), ECLIPTIC_STYLE),
                (galactic_plane_radec_deg(), GALACTIC_STYLE),
            ):
                self.ax.add_collection(
                    LineCollection(
                        _projected(self.ax.proj, radec),
                        colors=style["color"],
                        linestyles=[style["linestyle"]],
                        linewidths=style["linewidth"],
                    ),
                    autolim=False,
                )
            # the Sun's track, its start and its position (at the map's time, or the end)
            self.sun = tuple(
                self.ax.add_line(Line2D([], [], **style))
                for style in (
                    SUN_TRACK_STYLE,
                    {**SUN_START_STYLE, "linestyle": "none"},
                    {**SUN_END_STYLE, "linestyle": "none"},
                )
            )

    def _label_graticule(self) -> None:
        """RA in hours on the equator at each meridian (the map's edge, 12h, left out), Dec in deg
        left of the border at each parallel, E at the equator's left end (RA increases to the left,
        towards East, as on the sky seen from inside)."""
        import matplotlib.patheffects as pe

        proj = self.ax.proj
        kw = {"fontsize": GRATICULE_LABEL_SIZE, "color": "0.1", "clip_on": False}
        halo = [pe.withStroke(linewidth=1.6, foreground="white")]
        for ra in np.arange(0.0, 360.0, GRATICULE_DMER_DEG):
            if ra == 180.0:
                continue
            x, y = proj.ang2xy(ra, 0.0, lonlat=True)
            label = self.ax.text(
                x, y - 0.03, f"{ra / 15:.0f}h", ha="center", va="top", path_effects=halo, **kw
            )
            label.set_in_layout(False)  # inside the ellipse: not measured for the page's tight box
        for dec in np.arange(-90.0 + GRATICULE_DPAR_DEG, 90.0, GRATICULE_DPAR_DEG):
            if dec == 0.0:
                continue
            x, y = proj.ang2xy(179.999, dec, lonlat=True)  # the parallel's left end
            self.ax.text(x - 0.04, y, f"{dec:+.0f}°", ha="right", va="center", **kw)
        self.ax.text(-2.04, 0.0, "E", ha="right", va="center", fontweight="bold", **kw)

    def show(
        self, full_sky, nest: bool, title: str, vmin: float, vmax: float, sun_radec_deg=None
    ) -> "MollweidePanel":
        """Draw ``full_sky`` (a full HEALPix map; ``UNSEEN`` and non-finite pixels light grey)
        between ``vmin`` and ``vmax`` (values beyond in the end colours), and the Sun at
        ``sun_radec_deg`` ((n, 2) RA, Dec in deg: one position, or a track from the first to
        the last; None: no Sun): the image is the cached pixel index of
        :func:`_mollweide_pixel_index` applied to the map, drawn with imshow inside the ellipse.

        Parameters
        ----------
        full_sky : ndarray
            A full HEALPix map (mag/arcsec2 or AB mag as the page shows).
        nest : bool
            Whether the map is in NESTED order.
        title : str
            The panel's title.
        vmin : float
            The value at the colour scale's bright end, in the map's unit.
        vmax : float
            The value at the colour scale's faint end, in the map's unit.
        sun_radec_deg : ndarray, optional
            The Sun's RA, Dec, deg, shape (n, 2): one position, or a track; None: no Sun.
        """
        import healpy as hp
        from matplotlib.colors import Normalize
        from matplotlib.patches import Ellipse

        m = np.asarray(full_sky, float)
        index = _mollweide_pixel_index(hp.npix2nside(m.size), bool(nest))
        img = np.full(index.shape, hp.UNSEEN)  # outside the ellipse: clipped away below
        img[index >= 0] = m[index[index >= 0]]
        data = np.ma.masked_array(img, mask=~np.isfinite(img) | hp.mask_bad(img))
        norm = Normalize(vmin=vmin, vmax=vmax)
        if self.image is None:
            self.image = self.ax.imshow(
                data,
                extent=self.ax.proj.get_extent(),
                cmap=self.cmap,
                norm=norm,
                interpolation="nearest",
                origin="lower",
            )
            # only the ellipse: the image's corners are no pixel of the sky
            self.image.set_clip_path(Ellipse((0.0, 0.0), 4.0, 2.0, transform=self.ax.transData))
            # the limits after imshow, which sets them to the image's extent
            self.ax.set_xlim(-2.01, 2.01)
            self.ax.set_ylim(-1.01, 1.01)
        else:
            self.image.set_data(data)
            self.image.set_norm(norm)
        self._show_sun(sun_radec_deg)
        self.ax.set_title(title)
        if self.unit is not None:
            self._colour_bar(norm, vmin, vmax)
        return self

    def _show_sun(self, sun_radec_deg) -> None:
        if not self.sun:
            return
        track, start, end = self.sun
        if sun_radec_deg is None:
            for line in self.sun:
                line.set_data([], [])
            return
        pieces = _projected(self.ax.proj, sun_radec_deg)
        xy = np.concatenate([p for piece in pieces for p in (piece, [[np.nan, np.nan]])])[:-1]
        end.set_data(xy[-1:, 0], xy[-1:, 1])
        several = len(xy) > 1
        start.set_data(xy[:1, 0] if several else [], xy[:1, 1] if several else [])
        track.set_data(xy[:, 0] if several else [], xy[:, 1] if several else [])

    def _colour_bar(self, norm, vmin: float, vmax: float) -> None:
        """A colour bar under the map, with triangles for the values beyond its ends."""
        from matplotlib.cm import ScalarMappable

        if self.colour_bar is None:
            self.colour_bar = self.fig.colorbar(
                ScalarMappable(norm=norm, cmap=self.cmap),
                ax=self.ax,
                orientation="horizontal",
                shrink=0.5,
                aspect=25,
                pad=0.05,
                fraction=0.1,
                extend="both",
                extendfrac=0.06,
            )
            self.colour_bar.ax.tick_params(labelsize=8)
            self.colour_bar.ax.set_xlabel(self.unit, fontsize=8, labelpad=2)
        else:
            # the norm's change redraws the bar (and resets its ticks)
            self.colour_bar.mappable.set_norm(norm)
        self.colour_bar.solids.set_rasterized(True)
        loc, fmt = _tick_format(vmin, vmax)
        self.colour_bar.ax.xaxis.set_major_locator(loc)
        self.colour_bar.ax.xaxis.set_major_formatter(fmt)


def overlay_legend(fig, sun: str, outside: str, y: float = -0.01):
    """The page's legend of what the panels draw over the maps, centred under the panels (at
    figure fraction ``y``): the ecliptic, the Galactic plane, the Sun (``sun``: ``"at"`` one
    time, or ``"track"``: a ring at the start, a disc at the end, the line between) and the colour
    of pixels without a value, ``outside`` saying which.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The page.
    sun : {"at", "track"}
        The Sun drawn at one time, or as a track.
    outside : str
        What the light grey pixels are (e.g. ``"outside the footprint"``).
    y : float, optional
        The legend's height, figure fraction (default -0.01).
    """
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles = [Line2D([], [], **ECLIPTIC_STYLE), Line2D([], [], **GALACTIC_STYLE)]
    if sun == "track":
        handles += [
            Line2D([], [], linestyle="none", label="Sun at the start (ring)", **SUN_START_STYLE),
            Line2D([], [], linestyle="none", label="Sun at the end (line: its track)", **SUN_END_STYLE),
        ]
    else:
        handles.append(Line2D([], [], linestyle="none", label="Sun at the map's time", **SUN_END_STYLE))
    handles.append(Patch(facecolor=OUTSIDE_COLOUR, edgecolor="0.5", linewidth=0.5, label=outside))
    return fig.legend(
        handles=handles,
        loc="upper center",
        bbox_to_anchor=(0.5, y),
        ncol=len(handles),
        fontsize=9,
        frameon=False,
    )


#: What the maps' titles say of the projection and its orientation
ORIENTATION = (
    "ICRS Mollweide centred on RA 0h; RA in hours, increasing to the left (East, E), Dec in deg; "
    "graticule every 30 deg in Dec and 4 h in RA"
)


def map_time_indices(ds, n_times: int = 2, times=()) -> list[int]:
    """Indices into ``ds.time`` of the sky maps' times: the samples nearest ``times`` (UTC ISO)
    if given, else ``n_times`` evenly spread over the campaign.

    Parameters
    ----------
    ds : xarray.Dataset
        The background cube (its ``time``).
    n_times : int, optional
        Number of evenly spread times when ``times`` is empty (default 2).
    times : sequence of str, optional
        UTC ISO times.
    """
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
    observability, with the Sun at that time.  Each component of a band has one colour scale
    over all the map times (:func:`~straylight.plots.common.band_colour_limits`), from its
    observable pixels (all, where none is observable); the others take the end colours.

    Parameters
    ----------
    ds : xarray.Dataset
        The background cube.
    campaign : Campaign
        The campaign.
    out_dir : str or pathlib.Path
        The folder the pages are written to.
    time_indices : sequence of int
        Indices into ``ds.time``.
    bands : sequence of str, optional
        The bands drawn (default: all).
    """
    from astropy.time import Time

    from straylight.model import registry

    nest = str(ds.attrs["healpix_ordering"]).upper() == "NESTED"
    comps = list(registry.component_names(total=True))
    band_idx = {str(b): ib for ib, b in enumerate(ds["band"].values) if bands is None or str(b) in bands}
    # every component at each map time, all bands, one read a time (each chunk decompressed once)
    snaps = [ds[comps + ["observable"]].isel(time=it).compute() for it in time_indices]
    times = Time(ds["time"].values[list(time_indices)].astype("datetime64[ns]"), scale="utc")
    suns = sun_radec_deg(times)
    # (band, component) -> e-/s/pix and AB mag/arcsec2 per map time; the colour scale over them
    rates = {
        (b, c): [np.asarray(s[c].isel(band=ib), float) for s in snaps]
        for b, ib in band_idx.items()
        for c in comps
    }
    mags = {(b, c): [_mag(ds, e, b, campaign) for e in rates[b, c]] for b, c in rates}
    # the scale from the observable pixels (the unobservable ones near the Sun or the Earth are
    # magnitudes brighter and would leave the observable sky one colour); none observable: all
    seen = [np.asarray(s["observable"], bool) for s in snaps]
    if not any(o.any() for o in seen):
        seen = [np.ones_like(o) for o in seen]
    limits = {
        key: band_colour_limits([v[o] for v, o in zip(m, seen)], SKY_PERCENTILES) for key, m in mags.items()
    }
    written = []
    pages = {}  # number of component panels -> (figure, their panels, the observability panel)
    for k, (it, snap) in enumerate(zip(time_indices, snaps)):
        t = str(ds["time"].values[it])[:16]
        for band in band_idx:
            # a component zero everywhere has no panel: the title says so instead
            shown = [c for c in comps if np.any(np.isfinite(rates[band, c][k]) & (rates[band, c][k] > 0))]
            zero = [c for c in comps if c not in shown]
            # the pages with as many panels share one figure, redrawn for each
            if len(shown) not in pages:
                pages[len(shown)] = _sky_page(len(shown))
            fig, panels, obs_panel = pages[len(shown)]
            for panel, comp in zip(panels, shown):
                panel.show(
                    _full_sky(ds, mags[band, comp][k]), nest, comp, *limits[band, comp], suns[k : k + 1]
                )
            obs = np.asarray(snap["observable"], float)
            obs_panel.show(_full_sky(ds, obs), nest, "observable", 0, 1, suns[k : k + 1])
            note = f"; zero everywhere, not shown: {', '.join(zero)}" if zero else ""
            fig.suptitle(
                f"{campaign.name}: background in band {band} at {t} UTC (AB mag/arcsec2){note}\n"
                f"{ORIENTATION}\ncolours: each component's {_percentiles(SKY_PERCENTILES)} in this band "
                "over the observable pixels of all the map times (beyond: the end colours, the bar's "
                "triangles)",
                fontsize=10,
            )
            written.append(
                _save(fig, Path(out_dir) / f"sky_{band}_{t.replace(':', '').replace('-', '')}.png")
            )
    return written


def _sky_page(n_maps: int) -> tuple:
    """A sky-map page's figure (4 panels a row) with ``n_maps`` component panels and the
    observability panel after them, with the legends: (figure, panels, observability panel)."""
    from matplotlib import colormaps
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    ncol = 4
    nrow = int(np.ceil((n_maps + 1) / ncol))
    fig = Figure(figsize=(16, 3.4 * nrow))
    panels = [
        MollweidePanel(fig, (nrow, ncol, k + 1), SKY_CMAP, "background, AB mag/arcsec2 (brighter: yellow)")
        for k in range(n_maps)
    ]
    obs_panel = MollweidePanel(fig, (nrow, ncol, n_maps + 1), "RdYlGn", None)
    obs_panel.ax.legend(
        handles=[
            Patch(color=colormaps["RdYlGn"](1.0), label="observable"),
            Patch(color=colormaps["RdYlGn"](0.0), label="not observable"),
        ],
        loc="upper center",
        bbox_to_anchor=(0.5, -0.02),
        ncol=2,
        fontsize=8,
        frameon=False,
    )
    overlay_legend(fig, "at", "outside the footprint, or no value (a component's 0; not evaluated)")
    return fig, panels, obs_panel


def sky_map_figures(background_path, campaign, out_dir) -> list:
    """The sky-map pages (:func:`sky_maps`) of the background cube at ``background_path`` in
    ``out_dir``, at the report's map times (``report.times``, else ``report.sky_map_times``
    spread over the campaign) in its bands (``report.sky_map_bands``, else all): each time read
    once for all its bands.  Returns the paths written; ConfigError naming the config file for a
    band the cube does not have.

    Parameters
    ----------
    background_path : str or pathlib.Path
        The background cube (Zarr).
    campaign : Campaign
        The campaign (its ``report`` settings).
    out_dir : str or pathlib.Path
        The folder the pages are written to.
    """
    import xarray as xr

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rc = campaign.settings.report
    # chunks=None: no dask (the figure rules run side by side; its threads only add overhead);
    # the arrays' own metadata (rule background may be consolidating it meanwhile)
    with xr.open_zarr(background_path, chunks=None, consolidated=False) as ds:
        cube_bands = [str(b) for b in ds["band"].values]
        unknown = sorted(set(rc.sky_map_bands or ()) - set(cube_bands))
        if unknown:
            from straylight.errors import ConfigError

            raise ConfigError(
                f"{campaign.path}: report.sky_map_bands: {', '.join(unknown)} not among the cube's "
                f"bands {', '.join(cube_bands)}"
            )
        bands = [b for b in cube_bands if b in set(rc.sky_map_bands or cube_bands)]
        times = map_time_indices(ds, int(rc.sky_map_times), rc.times)
        return sky_maps(ds, campaign, out, times, bands)


def _percentiles(p) -> str:
    """``(5.0, 99.5)`` as ``5th-99.5th percentile``."""

    def ordinal(x: float) -> str:
        n = f"{x:g}"
        last = "" if n.endswith(("11", "12", "13")) else n[-1]
        return n + {"1": "st", "2": "nd", "3": "rd"}.get(last, "th")

    return f"{ordinal(p[0])}-{ordinal(p[1])} percentile"
