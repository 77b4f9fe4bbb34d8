"""Report figures: colour scales that show the footprint's spread, rounded ticks, the maps' lines
and Sun, the depth table and the report's first page.

Reference values: synthetic fields whose ranges and ticks are known; astropy's frames and
published positions (the Galactic pole and centre, the J2000 obliquity) for the lines; astropy's
own Sun for the ephemeris' Sun."""

import numpy as np
import pytest
import xarray as xr

from straylight.plots.common import _tick_format, band_colour_limits
from straylight.plots.report import depth_summary


def test_ticks_are_few_and_rounded():
    """A 0.01-mag span gets 3-5 ticks at round values with no more decimals than the step needs."""
    loc, fmt = _tick_format(26.0581, 26.0689)
    ticks = [t for t in loc.tick_values(26.0581, 26.0689) if 26.0581 <= t <= 26.0689]
    assert 2 <= len(ticks) <= 5
    labels = [fmt(t) for t in ticks]
    assert all(len(s.split(".")[1]) <= 3 for s in labels), labels
    assert all(abs(float(s) - t) < 1e-9 for s, t in zip(labels, ticks))
    loc, fmt = _tick_format(4.03659, 19.3616)
    assert [fmt(t) for t in loc.tick_values(4.03659, 19.3616)][:2] == ["0", "5"]


def test_band_colour_limits_pool_the_maps_and_keep_a_minimum_span():
    """One scale for a band's depth maps: the 5th-99.5th percentile of all their in-footprint
    values together (healpy's UNSEEN and NaN, outside the footprint, left out); a band whose
    values span 0.008 mag (NUV's median depth in the default day) gets the 0.1-mag minimum,
    centred; the sky maps' 2nd-98th percentile when asked."""
    import healpy as hp

    median = np.r_[np.linspace(26.0, 26.25, 500), hp.UNSEEN, np.nan]
    best = np.r_[np.linspace(26.25, 26.5, 500), hp.UNSEEN]
    lo, hi = band_colour_limits([median, best])
    # 1000 values evenly from 26.0 to 26.5: the 5th and 99.5th percentiles are 26.025 and 26.4975
    assert lo == pytest.approx(26.025, abs=1e-3) and hi == pytest.approx(26.4975, abs=1e-3)
    lo, hi = band_colour_limits([median, best], (2.0, 98.0))
    assert lo == pytest.approx(26.01, abs=1e-3) and hi == pytest.approx(26.49, abs=1e-3)
    lo, hi = band_colour_limits([np.linspace(26.055, 26.063, 300), [hp.UNSEEN]])
    assert hi - lo == pytest.approx(0.1) and 0.5 * (lo + hi) == pytest.approx(26.059, abs=5e-4)


def _recorded_scales(monkeypatch):
    """MollweidePanel.show patched to record each panel's (title, vmin, vmax) as well as draw."""
    from straylight.plots.maps import MollweidePanel

    shown, show = [], MollweidePanel.show

    def record(self, full_sky, nest, title, vmin, vmax, *args, **kwargs):
        shown.append((title, vmin, vmax))
        return show(self, full_sky, nest, title, vmin, vmax, *args, **kwargs)

    monkeypatch.setattr(MollweidePanel, "show", record)
    return shown


def test_depth_maps_of_one_band_share_one_colour_scale(campaign, tmp_path, monkeypatch):
    """The median and best depth pages (plots.depth_maps.limit_maps) draw each band on one scale, that
    of both maps' values together: the best map 0.3 mag deeper than the median one still reads
    0.3 mag brighter on the same colour bar."""
    import healpy as hp

    from straylight.plots.common import DEPTH_PERCENTILES
    from straylight.plots.depth_maps import limit_maps

    nside, bands = 4, ["NUV", "g"]
    pix = np.arange(hp.nside2npix(nside))[::2]
    rng = np.random.default_rng(5)
    med = np.column_stack([26.06 + 0.008 * rng.random(pix.size), 26.3 + 0.2 * rng.random(pix.size)])
    ds = xr.Dataset(
        {
            "limiting_mag_median": (("pixel", "band"), med),
            "limiting_mag_best": (("pixel", "band"), med + 0.3),
        },
        coords={"pixel": pix, "band": bands},
        attrs={"healpix_nside": nside, "healpix_ordering": "RING"},
    )
    shown = _recorded_scales(monkeypatch)
    written = limit_maps(ds, campaign, tmp_path)
    assert [p.name for p in written] == ["limits_median.png", "limits_best.png"]
    for ib, band in enumerate(bands):
        scales = {(lo, hi) for title, lo, hi in shown if title.startswith(f"{band}:")}
        assert len(scales) == 1, (band, scales)
        lo, hi = scales.pop()
        both = np.r_[med[:, ib], med[:, ib] + 0.3]
        assert (lo, hi) == pytest.approx(tuple(np.percentile(both, DEPTH_PERCENTILES)))
        assert hi - lo > 0.29  # NUV: 0.3 between the maps, not the 0.008 of one map


def test_sky_maps_of_one_band_share_one_colour_scale_over_the_times(campaign, tmp_path, monkeypatch):
    """A component's panels at the map times (plots.maps.sky_maps) use one scale per band, that of
    its values at all those times: a total 1 mag brighter at the second time shows brighter."""
    import healpy as hp

    from straylight.limits.point_source import ZERO_POINT_NAME, zero_point_coord
    from straylight.model.registry import component_names
    from straylight.plots.maps import sky_maps

    nside, pix = 4, np.arange(hp.nside2npix(4))
    rng = np.random.default_rng(7)
    first = 1.0 + rng.random(pix.size)
    rates = np.stack([first, first * 10**0.4])[:, :, None]  # (time, pixel, band g)
    ds = xr.Dataset(
        {c: (("time", "pixel", "band"), rates) for c in component_names(total=True)}
        | {"observable": (("time", "pixel"), np.ones(rates.shape[:2], bool))},
        coords={
            "time": np.array(["2026-01-01T00:00", "2026-01-01T12:00"], "datetime64[ns]"),
            "pixel": pix,
            "band": ["g"],
            ZERO_POINT_NAME: zero_point_coord(campaign, ["g"]),
        },
        attrs={"healpix_nside": nside, "healpix_ordering": "RING"},
    )
    shown = _recorded_scales(monkeypatch)
    assert len(sky_maps(ds, campaign, tmp_path, [0, 1], ["g"])) == 2
    totals = [(lo, hi) for title, lo, hi in shown if title == "total"]
    assert len(totals) == 2 and totals[0] == totals[1]
    assert totals[0][1] - totals[0][0] > 1.0  # spans both times' values, 1 mag apart


def test_sky_map_colour_scale_comes_from_the_observable_pixels(campaign, tmp_path, monkeypatch):
    """A quarter of the pixels unobservable and 10 mag brighter (near the Earth's limb, as the
    earthshine there): each component's scale is the 2nd-98th percentile of the observable
    pixels (22.3-23.3 mag here), not one whose bright end sits among the unobservable ones
    (before: the scale ran from their ~12.6 mag, the observable sky one colour)."""
    import healpy as hp

    from straylight.limits.point_source import ZERO_POINT_NAME, zero_point_coord
    from straylight.model.registry import component_names
    from straylight.plots.common import SKY_PERCENTILES
    from straylight.plots.maps import sky_maps

    nside, pix = 4, np.arange(hp.nside2npix(4))
    zp = float(zero_point_coord(campaign, ["g"])[1][0])
    rng = np.random.default_rng(11)
    mags = 22.3 + rng.random(pix.size)  # the observable sky, AB mag/arcsec2
    observable = np.arange(pix.size) % 4 != 0
    mags[~observable] -= 10.0
    rates = 10 ** (-0.4 * (mags - zp))[None, :, None]  # (time, pixel, band g), e-/s/pixel
    ds = xr.Dataset(
        {c: (("time", "pixel", "band"), rates) for c in component_names(total=True)}
        | {"observable": (("time", "pixel"), observable[None, :])},
        coords={
            "time": np.array(["2026-01-01T00:00"], "datetime64[ns]"),
            "pixel": pix,
            "band": ["g"],
            ZERO_POINT_NAME: zero_point_coord(campaign, ["g"]),
        },
        attrs={"healpix_nside": nside, "healpix_ordering": "RING"},
    )
    shown = _recorded_scales(monkeypatch)
    sky_maps(ds, campaign, tmp_path, [0], ["g"])
    expected = np.percentile(mags[observable], SKY_PERCENTILES)
    for title in ("total", "earthshine"):
        ((lo, hi),) = [(lo, hi) for t, lo, hi in shown if t == title]
        assert (lo, hi) == pytest.approx(tuple(expected), abs=1e-9)
        assert lo > 22.3 and hi < 23.3


def test_time_series_legend_lists_only_the_curves_on_the_axes(campaign, tmp_path, monkeypatch):
    """The y axis reaches 4 mag below the total's faintest value (plots.series): a component
    6 mag below it is drawn off the axes all along and is not in the legend (the x label names
    it), one 1 mag below it is; a zero one is neither.  Before: every non-zero component was in
    the legend."""
    from matplotlib.figure import Figure

    from straylight.limits.point_source import ZERO_POINT_NAME, zero_point_coord
    from straylight.plots.series import time_series

    n = 10
    ds = xr.Dataset(
        coords={
            "time": np.datetime64("2026-01-01T00:00", "ns") + np.arange(n) * np.timedelta64(10, "m"),
            "pixel": [0],
            "band": ["g"],
            "ra_deg": ("pixel", [150.0]),
            "dec_deg": ("pixel", [30.0]),
            ZERO_POINT_NAME: zero_point_coord(campaign, ["g"]),
        },
    )
    ones = np.ones((n, 1))
    series = {
        "zodiacal": 0.5 * ones,
        "sun": 0 * ones,
        "moon": 10**-2.4 * ones,  # 6 mag below the total
        "planets": 0 * ones,
        "stars": 10**-0.4 * ones,  # 1 mag below it
        "earthshine": 0.1 * ones,
        "total": ones,
        "observable": np.ones(n, bool),
    }
    labels, legend = [], Figure.legend

    def record(self, *args, handles=(), **kwargs):
        labels.append([h.get_label() for h in handles])
        return legend(self, *args, handles=handles, **kwargs)

    monkeypatch.setattr(Figure, "legend", record)
    assert len(time_series(ds, campaign, tmp_path, [0], [series])) == 2
    assert labels == [["zodiacal", "stars", "earthshine", "total"]] * 2


def test_no_footprint_pixel_reads_as_a_hole(monkeypatch):
    """On a drawn depth panel, a footprint pixel shallower than the scale has the scale's first
    colour and a deeper one its last (clipped, as the colour bar's triangles say), never the
    light grey of pixels outside the footprint nor black; the depth scale has no black end and
    its ends differ clearly from that grey."""
    import healpy as hp
    from healpy.projector import MollweideProj
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import to_rgba
    from matplotlib.figure import Figure

    from straylight.plots.common import DEPTH_CMAP, OUTSIDE_COLOUR
    from straylight.plots.maps import MOLLWEIDE_XSIZE, MollweidePanel

    nside = 8
    m = np.full(hp.nside2npix(nside), 26.0)
    shallow = hp.ang2pix(nside, 45.0, 15.0, lonlat=True)
    deep = hp.ang2pix(nside, 315.0, -15.0, lonlat=True)
    outside = hp.ang2pix(nside, 200.0, -40.0, lonlat=True)
    m[shallow], m[deep], m[outside] = 20.0, 30.0, hp.UNSEEN
    fig = Figure(figsize=(16, 3.3))
    FigureCanvasAgg(fig)
    ax = MollweidePanel(fig, (1, 4, 2), DEPTH_CMAP, None, overlays=False).show(m, False, "t", 25.5, 26.5).ax
    fig.canvas.draw()
    rgba = np.asarray(fig.canvas.buffer_rgba()) / 255.0
    reference = MollweideProj(xsize=MOLLWEIDE_XSIZE, flipconv="astro")
    cmap, grey = colormaps[DEPTH_CMAP], np.array(to_rgba(OUTSIDE_COLOUR))
    for pix, colour in ((shallow, cmap(0.0)), (deep, cmap(1.0)), (outside, tuple(grey))):
        xy = reference.ang2xy(*hp.pix2ang(nside, pix, lonlat=True), lonlat=True)
        col, row = ax.transData.transform(np.array(xy, float).reshape(1, 2))[0]
        assert rgba[int(rgba.shape[0] - row), int(col)] == pytest.approx(colour, abs=2 / 255), pix
    for end in (cmap(0.0), cmap(1.0)):
        assert max(end[:3]) > 0.4  # not black (magma's first colour is 0.0, 0.0, 0.016)
        assert np.abs(np.array(end[:3]) - grey[:3]).max() > 0.3  # not the outside grey


def test_ecliptic_and_galactic_plane_against_published_positions():
    """The maps' lines (astropy's BarycentricMeanEcliptic and Galactic frames, to ICRS): the
    ecliptic reaches Dec +23.4393 deg (the J2000 obliquity, IAU 2006: 84381.406 arcsec) at RA 90 and
    lies 90 deg from its north pole (RA 270, Dec 90 - 23.4393); the Galactic plane passes through
    the Galactic centre (l = b = 0: RA 266.40500, Dec -28.93617, Hipparcos vol. 1 sect. 1.5.3) and
    lies 90 deg from the north Galactic pole (RA 192.85948, Dec +27.12825, same source).  A drawn
    panel carries the line through the centre's projected position."""
    import astropy.units as u
    from astropy.coordinates import SkyCoord
    from matplotlib.collections import LineCollection
    from matplotlib.figure import Figure

    from straylight.plots.maps import MollweidePanel
    from straylight.plots.overlays import ecliptic_radec_deg, galactic_plane_radec_deg

    obliquity = 84381.406 / 3600.0
    ecl, gal = ecliptic_radec_deg(), galactic_plane_radec_deg()
    solstice = ecl[np.argmin(np.abs(ecl[:, 0] - 90.0))]
    assert solstice == pytest.approx([90.0, obliquity], abs=1e-3)
    assert np.max(ecl[:, 1]) == pytest.approx(obliquity, abs=1e-3)
    assert gal[0] == pytest.approx([266.40500, -28.93617], abs=2e-4)
    for line, pole in ((ecl, (270.0, 90.0 - obliquity)), (gal, (192.85948, 27.12825))):
        sep = SkyCoord(*pole, unit="deg").separation(SkyCoord(line[:, 0] * u.deg, line[:, 1] * u.deg))
        assert np.allclose(sep.deg, 90.0, atol=2e-3)

    panel = MollweidePanel(Figure(), (1, 1, 1), "viridis", None)
    centre = np.array(panel.ax.proj.ang2xy(266.40500, -28.93617, lonlat=True), float)
    drawn = [c for c in panel.ax.collections if isinstance(c, LineCollection)]
    nearest = min(np.min(np.hypot(*(seg - centre).T)) for c in drawn for seg in c.get_segments())
    assert nearest < 1e-6


def test_sun_marker_at_the_june_solstice():
    """The Sun a map marks (the DE405 ephemeris, geometric and geocentric) at the June solstice of
    2026 (21 June, 08:24 UTC, IMCCE/USNO): on the ecliptic at its northernmost, Dec 23.44 deg, RA
    89.6 deg (the solstice of date is 90 deg of apparent longitude; 26.5 years of precession
    since J2000 take 0.37 deg off in ICRS), the position astropy's get_sun gives within its 20
    arcsec of aberration; the panel's marker sits at that position's projection."""
    from astropy.coordinates import get_sun
    from astropy.time import Time
    from matplotlib.figure import Figure

    from straylight.plots.maps import MollweidePanel
    from straylight.plots.overlays import sun_radec_deg

    t = Time("2026-06-21T08:24:00", scale="utc")
    sun = sun_radec_deg(t)
    assert sun.shape == (1, 2)
    assert sun[0, 1] == pytest.approx(23.44, abs=0.01) and sun[0, 0] == pytest.approx(89.6, abs=0.05)
    ref = get_sun(t)
    assert sun[0] == pytest.approx([ref.ra.deg, ref.dec.deg], abs=0.01)

    panel = MollweidePanel(Figure(), (1, 1, 1), "viridis", None)
    panel.show(np.zeros(12 * 4**2), False, "t", 0.0, 1.0, sun)
    track, start, end = panel.sun
    assert end.get_xydata()[0] == pytest.approx(panel.ax.proj.ang2xy(*sun[0], lonlat=True), abs=1e-9)
    assert start.get_xydata().size == 0 and track.get_xydata().size == 0  # one time: no track


def test_depth_summary_numbers():
    """The report's first-page table: median of the per-pixel medians, best of the per-pixel
    bests (NaN pixels ignored), observable fraction of all samples."""
    med = np.array([[25.0, 24.0], [26.0, 24.5], [np.nan, np.nan], [27.0, 25.0]])
    best = med + 0.5
    obs = np.zeros((4, 4), bool)
    obs[0, :3] = True
    ds = xr.Dataset(
        {
            "limiting_mag_median": (("pixel", "band"), med),
            "limiting_mag_best": (("pixel", "band"), best),
            "observable": (("time", "pixel"), obs),
        },
        coords={"band": ["g", "r"]},
    )
    rows = depth_summary(ds)
    assert rows["g"]["median_depth_mag"] == 26.0 and rows["g"]["best_depth_mag"] == 27.5
    assert rows["r"]["median_depth_mag"] == 24.5 and rows["r"]["best_depth_mag"] == 25.5
    assert rows["g"]["observable_fraction"] == pytest.approx(3 / 16)


@pytest.mark.parametrize("nest", [False, True])
def test_mollweide_panel_puts_each_pixel_where_healpy_projects_it(nest):
    """A panel's image is healpy's own Mollweide projection of the map (the image
    ``healpy.projector.MollweideProj.projmap`` makes, which ``mollview`` draws), and on the
    rendered page the point at a chosen RA/Dec has the colour of the map's pixel there: one
    bright pixel at (RA 45, Dec 15) is drawn at healpy's projected position of that point, the
    mirror point (RA 315) keeps the background value (east to the left, as in mollview), an
    UNSEEN pixel is the outside-the-footprint grey."""
    import healpy as hp
    from healpy.projector import MollweideProj
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import to_rgba
    from matplotlib.figure import Figure

    from straylight.plots.common import OUTSIDE_COLOUR
    from straylight.plots.maps import MOLLWEIDE_XSIZE, MollweidePanel

    nside = 8
    m = np.zeros(hp.nside2npix(nside))
    lit = hp.ang2pix(nside, 45.0, 15.0, nest=nest, lonlat=True)
    mirror = hp.ang2pix(nside, 315.0, 15.0, nest=nest, lonlat=True)
    unseen = hp.ang2pix(nside, 200.0, -40.0, nest=nest, lonlat=True)
    m[lit], m[unseen] = 1.0, hp.UNSEEN
    fig = Figure(figsize=(16, 3.3))
    FigureCanvasAgg(fig)
    ax = MollweidePanel(fig, (1, 4, 2), "viridis", None, overlays=False).show(m, nest, "t", 0.0, 1.0).ax

    reference = MollweideProj(xsize=MOLLWEIDE_XSIZE, flipconv="astro")
    expected = reference.projmap(m, lambda x, y, z: hp.vec2pix(nside, x, y, z, nest=nest))
    image = ax.get_images()[0].get_array()
    # masked: UNSEEN (grey) and the -inf outside the ellipse (clipped away)
    masked = (expected == hp.UNSEEN) | np.isinf(expected)
    assert np.array_equal(np.ma.getmaskarray(image), masked)
    assert np.array_equal(np.ma.getdata(image)[~masked], expected[~masked])

    fig.canvas.draw()
    rgba = np.asarray(fig.canvas.buffer_rgba())
    height = rgba.shape[0]
    for pix, colour in (
        (lit, colormaps["viridis"](1.0)),
        (mirror, colormaps["viridis"](0.0)),
        (unseen, to_rgba(OUTSIDE_COLOUR)),
    ):
        ra, dec = hp.pix2ang(nside, pix, nest=nest, lonlat=True)  # the pixel's centre
        xy = reference.ang2xy(ra, dec, lonlat=True)
        col, row = ax.transData.transform(np.array(xy, float).reshape(1, 2))[0]
        drawn = rgba[int(height - row), int(col)] / 255.0
        assert drawn == pytest.approx(colour, abs=2 / 255), (ra, dec)
    # outside the ellipse (the image's corner): the page's white, not a colour of the map
    corner = ax.transData.transform([[-1.95, 0.95]])[0]
    assert rgba[int(height - corner[1]), int(corner[0])] / 255.0 == pytest.approx((1, 1, 1, 1), abs=2 / 255)


def test_depth_table_round_trip_and_report_front(campaign, tmp_path):
    """The depth table the limits rule writes (depth/depth_summary.csv) is read back as written
    (mags to 0.01, the fraction to 0.001), and the report's first page built from it shows each
    row and a thumbnail of each figure found in the folders it is given (depth/, sky/, series/),
    the limit map first."""
    from PIL import Image

    from straylight.plots.report import DEPTH_TABLE, read_depth_table, write_depth_table, write_report_front

    rows = {
        "g": {"median_depth_mag": 26.5349, "best_depth_mag": 26.6151, "observable_fraction": 0.16549},
        "y": {"median_depth_mag": 24.8461, "best_depth_mag": float("nan"), "observable_fraction": 0.16549},
    }
    depth, sky = tmp_path / "depth", tmp_path / "sky"
    for d in (depth, sky):
        d.mkdir()
    back = read_depth_table(write_depth_table(rows, depth / DEPTH_TABLE))
    assert back["g"] == {"median_depth_mag": 26.53, "best_depth_mag": 26.62, "observable_fraction": 0.165}
    assert back["y"]["median_depth_mag"] == 24.85 and np.isnan(back["y"]["best_depth_mag"])
    Image.new("RGB", (80, 40), "red").save(depth / "limits_median.png")
    Image.new("RGB", (80, 40), "blue").save(sky / "sky_g_20260101T0000.png")
    text = write_report_front(
        back, campaign.config_mapping(), tmp_path / "summary.rst", [depth, sky]
    ).read_text()
    assert "     - 26.53" in text and "     - 16.5 %" in text and "     - nan" in text
    shown = [line for line in text.splitlines() if "<b>" in line]
    assert [s.split("<b>")[1].split("</b>")[0] for s in shown] == ["limits_median", "sky_g_20260101T0000"]
    assert text.count("data:image/png;base64") == 2
    # the page opens on the table, then the depth map, then the guide and the other figures
    order = ["median depth (AB mag)", "<b>limits_median</b>", "**Reading the maps**", "**Other figures**"]
    positions = [text.index(s) for s in order + ["<b>sky_g_20260101T0000</b>"]]
    assert positions == sorted(positions)


def test_report_categories_put_depth_first():
    """Snakemake's report lists its categories sorted by name (localeCompare in its menu): the
    workflow's report rules use the numbered categories of plots.report, the depth table and
    maps first."""
    import re
    from pathlib import Path

    from straylight.plots.report import REPORT_CATEGORIES

    rules = Path(__file__).resolve().parents[1] / "workflow" / "rules"
    used = {m for p in rules.glob("*.smk") for m in re.findall(r'category="([^"]+)"', p.read_text())}
    assert used == set(REPORT_CATEGORIES)
    assert sorted(used, key=str.casefold)[0] == "1. Depth: table and maps"
    assert sorted(used, key=str.casefold) == list(REPORT_CATEGORIES)


def test_mollweide_panel_redrawn_is_the_panel_drawn_afresh():
    """Sky-map pages share their figure (plots.maps.sky_maps): a panel that showed one map and then
    another renders, pixel for pixel, as a new panel showing only the second (image, colour
    range, colour bar's steps and ticks, title)."""
    import healpy as hp
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from straylight.plots.maps import MollweidePanel

    rng = np.random.default_rng(3)
    first, second = (rng.normal(20.0, 1.0, hp.nside2npix(8)) for _ in range(2))
    second[:50] = hp.UNSEEN
    pages = []
    for maps in ((first, second), (second,)):
        fig = Figure(figsize=(8, 3.3))
        FigureCanvasAgg(fig)
        panel = MollweidePanel(fig, (1, 2, 1), "viridis_r", "mag")
        for m, (lo, hi) in zip(maps, ((17.0, 23.0), (19.5, 20.25))[-len(maps) :]):
            panel.show(m, False, f"map {lo}", lo, hi)
        fig.canvas.draw()
        pages.append(np.asarray(fig.canvas.buffer_rgba()).copy())
    assert np.array_equal(pages[0], pages[1])


def test_magnitudes_through_the_products_zero_point_equal_the_instruments(campaign):
    """The figures turn e-/s/pix into AB mag/arcsec2 through the store's mag_zero_point
    coordinate (limits.zero_point_coord) where it has one: the numbers the instrument's
    throughput gives (sources.photometry.magnitude_per_arcsec2), bit for bit."""
    from straylight.limits.point_source import ZERO_POINT_NAME, zero_point_coord
    from straylight.plots.common import _mag

    bands = list(campaign.bands)
    rates = np.array([0.0, 1e-3, 0.37, 1.0, 25.0])
    with_zp = xr.Dataset(coords={"band": bands, ZERO_POINT_NAME: zero_point_coord(campaign, bands)})
    without = xr.Dataset(coords={"band": bands})
    for band in bands:
        a, b = _mag(with_zp, rates, band, campaign), _mag(without, rates, band, campaign)
        assert np.array_equal(a, b) and np.isinf(a[0]) and 15 < a[3] < 30
