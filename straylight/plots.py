"""Figures of a campaign's products for the report (issue #8 item 1): all-sky Mollweide maps of
every component and the total per band at chosen times, time series of chosen pointings over
the first orbit and the whole campaign, and the limiting-magnitude maps.

Maps are in the cube's HEALPix frame (ICRS); pixels outside the footprint are grey.  Values are
shown as AB mag/arcsec2 (brighter = smaller), the unit planners compare with sky tables.
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

ORBIT_MINUTES = 92.6  # ~400 km circular orbit: the first-orbit panel spans this long


def _mag(ds, e_per_s, band: str, campaign):
    """AB mag/arcsec2 of ``e_per_s`` (e-/s/pix) in ``band``: through the product's own
    ``mag_zero_point`` coordinate where ``ds`` has it (the number a reader of the store uses,
    computed from the instrument as below), else from the campaign's instrument."""
    from straylight.survey.limits import ZERO_POINT_NAME

    if ZERO_POINT_NAME in ds.coords:  # photometry.magnitude_per_arcsec2 at the stored zero point
        zp = float(ds[ZERO_POINT_NAME].sel(band=band))
        with np.errstate(divide="ignore"):
            return zp - 2.5 * np.log10(np.asarray(e_per_s, dtype=float))
    from straylight.optics.bandpass import load_band
    from straylight.sources.photometry import magnitude_per_arcsec2

    b = load_band(campaign.instrument, band, campaign.instrument_path.parent)
    return magnitude_per_arcsec2(e_per_s, b, campaign.instrument_value("telescope", "aperture_diameter_m"),
                                 campaign.pixel_scale_arcsec)


def _full_sky(ds, values):
    import healpy as hp

    m = np.full(hp.nside2npix(int(ds.attrs["healpix_nside"])), hp.UNSEEN)
    v = np.asarray(values, float)
    m[np.asarray(ds["pixel"])] = np.where(np.isfinite(v), v, hp.UNSEEN)
    return m


def _tick_format(lo: float, hi: float, n: int = 4):
    """Rounded colour-bar ticks for [lo, hi]: a matplotlib locator and formatter with as few
    decimals as the tick step needs."""
    from matplotlib.ticker import FormatStrFormatter, MaxNLocator

    loc = MaxNLocator(n, steps=[1, 2, 2.5, 5, 10])
    ticks = loc.tick_values(lo, hi)
    step = float(np.min(np.diff(ticks))) if ticks.size > 1 else max(hi - lo, 1.0)
    decimals = int(max(0, -np.floor(np.log10(step) + 1e-9)))
    return loc, FormatStrFormatter(f"%.{decimals}f")


def _colour_range(values, percentiles=(2.0, 98.0), min_span: float = 0.01) -> tuple[float, float]:
    """The range of the colour scale: the given percentiles of the finite values, widened
    symmetrically to ``min_span`` where the values are nearly uniform."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return 20.0, 30.0
    lo, hi = (float(x) for x in np.percentile(v, percentiles))
    if hi - lo < min_span:
        mid = 0.5 * (lo + hi)
        lo, hi = mid - min_span / 2, mid + min_span / 2
    return lo, hi


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
    """healpy's Mollweide graticule (parallels every ``dpar_deg``, meridians every ``dmer_deg``) and
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
        extent = (c / ncols + margins[0], 1.0 - (r + 1) / nrows + margins[1],
                  1.0 / ncols - margins[2] - margins[0], 1.0 / nrows - margins[3] - margins[1])
        self.fig, self.cmap, self.unit = fig, cmap, unit
        self.ax = PA.HpxMollweideAxes(fig, extent, flipconv="astro")
        # the axes are off (healpy): hidden x and y axes also spare the tick layout that placing
        # the title would otherwise make at every draw
        self.ax.xaxis.set_visible(False)
        self.ax.yaxis.set_visible(False)
        fig.add_axes(self.ax)
        for style, lw, colour, alpha, segments in _graticule_segments():
            self.ax.add_collection(LineCollection(segments, linestyles=style, linewidths=lw, colors=colour,
                                                  alpha=alpha), autolim=False)
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
            self.image = self.ax.imshow(data, extent=self.ax.proj.get_extent(), cmap=cm, norm=norm,
                                        interpolation="nearest", origin="lower")
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
        """mollview's colour bar: ``n_colours`` solid steps between the limits, under the map."""
        from matplotlib.cm import ScalarMappable
        from matplotlib.colors import Normalize

        bounds = norm.inverse(np.linspace(0, 1, n_colours + 1))
        values = np.linspace(norm.vmin, norm.vmax, n_colours)
        bar_norm = Normalize(vmin=norm.vmin, vmax=norm.vmax)
        if self.colour_bar is None:
            self.colour_bar = self.fig.colorbar(ScalarMappable(norm=bar_norm, cmap=self.cmap), ax=self.ax,
                                                orientation="horizontal", shrink=0.5, aspect=25, pad=0.05,
                                                fraction=0.1, boundaries=bounds, values=values)
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


#: the figures' resolution (dots per inch)
FIGURE_DPI = 90


def _save(fig, path: Path) -> Path:
    """``fig`` to ``path`` as PNG, cropped to its artists' tight box (the colour bars' labels
    overhang the axes) with matplotlib's padding.  The box is measured here, at the saving
    resolution, and handed to ``savefig``: ``bbox_inches="tight"`` would first run a whole draw
    (every panel's image resampled) only to measure it."""
    import matplotlib as mpl
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from straylight.util.io import atomic_path

    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)  # savefig's PNG one
    dpi = fig.dpi
    fig.dpi = FIGURE_DPI
    try:
        bbox = fig.get_tightbbox(canvas.get_renderer()).padded(mpl.rcParams["savefig.pad_inches"])
    finally:
        fig.dpi = dpi
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=FIGURE_DPI, format="png", bbox_inches=bbox)
    return path


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
    from straylight.survey.cube import CUBE_BAND_VARIABLES

    nest = str(ds.attrs["healpix_ordering"]).upper() == "NESTED"
    written = []
    pages = {}  # number of component panels -> (figure, their panels, the observability panel)
    for it in time_indices:
        t = str(ds["time"].values[it])[:16]
        # every component at this time, all bands, in one read (each chunk decompressed once)
        snap = ds[list(CUBE_BAND_VARIABLES) + ["observable"]].isel(time=it).compute()
        for ib, band in enumerate(ds["band"].values):
            if bands is not None and str(band) not in bands:
                continue
            maps, zero = [], []
            for comp in CUBE_BAND_VARIABLES:
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
            grey = "outside the footprint, or a component's 0" + (", or not evaluated (not observable)"
                                                                  if np.isnan(maps[-1][1]).any() else "")
            note = f"; zero everywhere, not shown: {', '.join(zero)}" if zero else ""
            fig.suptitle(f"{campaign.name}: band {band} at {t} UTC (ICRS Mollweide, graticule every 30 deg in Dec "
                         f"and 60 deg in RA; colours: 2nd-98th percentile per panel; grey: {grey}{note})",
                         fontsize=10)
            written.append(_save(fig, Path(out_dir) / f"sky_{band}_{t.replace(':', '').replace('-', '')}.png"))
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
    panels = [MollweidePanel(fig, (nrow, ncol, k + 1), "viridis_r", "AB mag/arcsec2 (brighter: yellow)")
              for k in range(n_maps)]
    obs_panel = MollweidePanel(fig, (nrow, ncol, n_maps + 1), "RdYlGn", None)
    obs_panel.ax.legend(handles=[Patch(color=colormaps["RdYlGn"](1.0), label="observable"),
                                 Patch(color=colormaps["RdYlGn"](0.0), label="not observable"),
                                 Patch(color="0.5", label="outside the footprint")],
                        loc="upper center", bbox_to_anchor=(0.5, -0.02), ncol=3, fontsize=8, frameon=False)
    return fig, panels, obs_panel


def series_pixel_indices(ds, n_pointings: int = 3, pointings=()) -> list[int]:
    """Indices into ``ds.pixel`` of the time series' pointings: the footprint pixels nearest
    ``pointings`` ([ra, dec] deg) if given, else ``n_pointings`` pixels evenly spread."""
    if pointings:
        from straylight.sky.geometry import radec_to_unit

        centres = radec_to_unit(np.asarray(ds["ra_deg"]), np.asarray(ds["dec_deg"]))
        wanted = np.atleast_2d(radec_to_unit(*np.asarray(pointings, float).T, "report.pointings"))
        pix_idx = np.unique(np.argmax(wanted @ centres.T, axis=1))
    else:
        pix_idx = np.unique(np.linspace(0, ds.sizes["pixel"] - 1, n_pointings).round().astype(int))
    return [int(i) for i in pix_idx]


def pointing_series(background_path, pixel_indices) -> list[dict]:
    """Per pointing of ``pixel_indices`` (into the cube's ``pixel``), its whole series in the
    background cube at ``background_path``: name -> (time[, band]) array of every component,
    the total (:data:`~straylight.survey.cube.CUBE_BAND_VARIABLES`) and ``observable``.  Read
    chunk by chunk in this thread (:func:`~straylight.survey.storage.read_region`)."""
    import zarr

    from straylight.survey.cube import CUBE_BAND_VARIABLES
    from straylight.survey.storage import read_region

    group = zarr.open_group(str(background_path), mode="r", use_consolidated=False)
    names = list(CUBE_BAND_VARIABLES) + ["observable"]
    return [{n: read_region(group[n], (slice(None), slice(ip, ip + 1)))[:, 0] for n in names}
            for ip in pixel_indices]


def time_series(ds, campaign, out_dir, pixel_indices, series: list[dict]) -> list:
    """For the pointings ``pixel_indices`` (into ``ds.pixel``, see :func:`series_pixel_indices`)
    and their ``series`` (:func:`pointing_series`): total and components in each band against
    time, over the first orbit and over the whole campaign; unobservable times shaded."""
    from matplotlib.figure import Figure
    from matplotlib.patches import PathPatch
    from matplotlib.ticker import MaxNLocator

    from straylight.survey.cube import CUBE_BAND_VARIABLES

    pix_idx = list(pixel_indices)
    t = ds["time"].values
    minutes = (t - t[0]) / np.timedelta64(1, "m")
    written = []
    for ip, sub in zip(pix_idx, series):
        ra, dec = float(ds["ra_deg"][ip]), float(ds["dec_deg"][ip])
        obs = np.asarray(sub["observable"], bool)
        for span, sel in (("orbit", minutes <= ORBIT_MINUTES), ("campaign", np.ones(minutes.size, bool))):
            bands = list(ds["band"].values)
            fig = Figure(figsize=(10, 2.2 * len(bands)))
            axes = fig.subplots(len(bands), 1, sharex=True)
            shown = {}
            for ax, band in zip(np.atleast_1d(axes), bands):
                ib = bands.index(band)
                zp = float(_mag(ds, np.array([1.0]), str(band), campaign)[0])  # mag/arcsec2 at 1 e-/s/pix
                for k, comp in enumerate(CUBE_BAND_VARIABLES):
                    y = np.asarray(sub[comp][:, ib], float)[sel]
                    if not np.any(y > 0):
                        continue  # zero all along: no line (listed in the title)
                    mag = np.where(y > 0, zp - 2.5 * np.log10(np.where(y > 0, y, 1.0)), np.nan)
                    line, = ax.plot(minutes[sel], mag, lw=1.8 if comp == "total" else 1.0,
                                    color="k" if comp == "total" else f"C{k}", label=comp)
                    shown[comp] = line
                # each run of unobservable samples, first to last sample, over the axes' height
                # (an artist, not a patch: the data limits come from the lines)
                ax.add_artist(PathPatch(_span_path(minutes[sel], ~obs[sel]), facecolor="0.88", lw=0,
                                        transform=ax.get_xaxis_transform()))
                total = np.asarray(sub["total"][:, ib], float)[sel]
                tmag = zp - 2.5 * np.log10(total[total > 0]) if np.any(total > 0) else np.array([20.0])
                # brighter up; the faint end a few magnitudes below the total's faintest value
                ax.set_ylim(min(float(np.nanmax(tmag)) + 4.0, 32.0), float(np.nanmin(tmag)) - 1.0)
                ax.set_ylabel(f"{band}\nmag/arcsec2", fontsize=9)
                ax.yaxis.set_major_locator(MaxNLocator(4, integer=True))
                ax.grid(alpha=0.3, lw=0.5)
                # the band's zero point: e-/s/pixel = 10^(-0.4 (mag - zp))
                ax.text(1.005, 0.5, f"zero point\n{zp:.2f}\n(1 e-/s/pix)", transform=ax.transAxes, fontsize=7,
                        va="center", ha="left")
            missing = [c for c in CUBE_BAND_VARIABLES if c not in shown]
            fig.legend(handles=list(shown.values()), loc="upper center", ncol=len(shown), fontsize=8,
                       bbox_to_anchor=(0.5, 0.965), frameon=False)
            np.atleast_1d(axes)[-1].set_xlabel(f"minutes after {str(t[0])[:16]} UTC (grey: not observable)"
                                               + (f"; zero all along, not drawn: {', '.join(missing)}" if missing else ""))
            fig.suptitle(f"{campaign.name}: pointing RA {ra:.1f}, Dec {dec:.1f} deg, {span} (AB mag/arcsec2, "
                         "brighter up; e-/s/pixel = 10^(-0.4 (mag - zero point)))", fontsize=10)
            fig.tight_layout(rect=(0, 0, 1, 0.95))
            written.append(_save(fig, Path(out_dir) / f"series_{span}_ra{ra:06.2f}_dec{dec:+06.2f}.png"))
    return written


def _span_path(x, mask):
    """One compound path of rectangles from ``x`` at the first to ``x`` at the last sample of
    each run of True in ``mask``, from y 0 to 1 (the axes' height under an x-axis transform)."""
    from matplotlib.path import Path as MplPath

    edges = np.flatnonzero(np.diff(np.r_[0, np.asarray(mask, np.int8), 0]))
    x0, x1 = np.asarray(x, float)[edges[::2]], np.asarray(x, float)[edges[1::2] - 1]
    zero, one = np.zeros_like(x0), np.ones_like(x0)
    verts = np.stack([np.c_[x0, zero], np.c_[x0, one], np.c_[x1, one], np.c_[x1, zero], np.c_[x0, zero]], axis=1)
    codes = np.tile([MplPath.MOVETO, MplPath.LINETO, MplPath.LINETO, MplPath.LINETO, MplPath.CLOSEPOLY], x0.size)
    return MplPath(verts.reshape(-1, 2), codes.astype(MplPath.code_type))


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
                _full_sky(limits_ds, v), nest, f"{band} (median {med:.2f})", lo, hi)
        fig.suptitle(f"{campaign.name}: {stat} 5-sigma point-source limit over the campaign (survey exposures; "
                     "colours: 10th-99.9th percentile per band, shallower pixels black; graticule 30/60 deg; "
                     "grey: outside the footprint or never observable)", fontsize=10)
        written.append(_save(fig, Path(out_dir) / f"limits_{stat}.png"))
    return written


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
        count = sum(int(np.count_nonzero(observable.isel(pixel=slice(a, a + block)).values))
                    for a in range(0, observable.shape[1], block))
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
        lines += [f"{b},{r['median_depth_mag']:.2f},{r['best_depth_mag']:.2f},{r['observable_fraction']:.3f}"
                  for b, r in rows.items()]
        tmp.write_text("\n".join(lines) + "\n")
    return path


def read_depth_table(path) -> dict:
    """The rows :func:`write_depth_table` wrote (band -> the three numbers, as written)."""
    import csv

    with open(path, newline="") as f:
        return {r["band"]: {k: float(v) for k, v in r.items() if k != "band"} for r in csv.DictReader(f)}


def write_report_front(rows: dict, config: dict, path, figure_dirs=()) -> Path:
    """``path`` (the report's first page, RST rendered by Snakemake's Jinja): the campaign of
    ``config`` (a validated campaign config: ``Campaign.config``, or the workflow's), the depth
    table ``rows`` (:func:`read_depth_table`) and a guide to the figures, with thumbnails of
    those found in ``figure_dirs`` (depth/, sky/ and series/ of the campaign's results)."""
    from straylight.util.io import atomic_path

    c = config["campaign"]
    table = ["   * - band", "     - median depth (AB mag)", "     - best depth (AB mag)",
             "     - observable fraction"]
    for b, r in rows.items():
        table += [f"   * - {b}", f"     - {r['median_depth_mag']:.2f}", f"     - {r['best_depth_mag']:.2f}",
                  f"     - {100 * r['observable_fraction']:.1f} %"]
    text = f"""Stray-light and sky-background products of the campaign **{c['name']}**
({c['start']} to {c['end']} UTC, every {float(c['cadence_s']):g} s) for the CSST survey camera
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
THUMBNAILS = (("limits_median", "Median 5-sigma depth per band over the campaign (AB mag)."),
              ("limits_best", "Best 5-sigma depth per band (AB mag)."),
              ("sky_g_", "Every background component in g at the first map time (AB mag/arcsec2)."),
              ("series_orbit_", "One pointing over the first orbit, every band (AB mag/arcsec2; grey: not observable)."))


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
        lines = "\n".join("   " + b64[i:i + 76] for i in range(0, len(b64), 76))
        parts.append(f".. raw:: html\n\n   <figure style=\"display:inline-block;margin:6px;vertical-align:top\">\n"
                     f"   <img style=\"width:{img.width}px\" alt=\"{found[0].stem}\" src=\"data:image/png;base64,\n{lines}\n   \">\n"
                     f"   <figcaption style=\"font-size:90%\"><b>{found[0].stem}</b>: {caption} Full size in "
                     f"<i>Maps and time series</i>.</figcaption></figure>\n")
    return "\n" + "\n".join(parts) if parts else ""


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

            raise ConfigError(f"{campaign.path}: report.sky_map_bands: {', '.join(unknown)} not among the cube's "
                              f"bands {', '.join(cube_bands)}")
        bands = [b for b in cube_bands if b in set(rc.get("sky_map_bands") or cube_bands)]
        times = map_time_indices(ds, int(rc["sky_map_times"]), rc.get("times") or ())
        return sky_maps(ds, campaign, out, times, bands)


def time_series_figures(background_path, campaign, out_dir) -> list:
    """The time series (:func:`time_series`) of the report's pointings (``report.pointings``,
    else ``report.series_pointings`` spread over the footprint) in ``out_dir``, each pointing's
    whole series read in one pass over its pixel's chunks (:func:`pointing_series`).  Returns
    the paths written."""
    import xarray as xr

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rc = campaign.config["report"]
    # chunks=None: no dask, the coordinates read as they are needed; the arrays' own metadata
    # (rule background may be consolidating it meanwhile)
    with xr.open_zarr(background_path, chunks=None, consolidated=False) as ds:
        pixels = series_pixel_indices(ds, int(rc["series_pointings"]), rc.get("pointings") or ())
        return time_series(ds, campaign, out, pixels, pointing_series(background_path, pixels))


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
    count = sum(int(np.count_nonzero(read_region(observable, (slice(None), slice(a, a + block)))))
                for a in range(0, observable.shape[1], block))
    written = limit_maps(summaries, campaign, out_dir)
    rows = depth_summary(summaries, count / observable.size)
    return written + [write_depth_table(rows, Path(out_dir) / DEPTH_TABLE)]
