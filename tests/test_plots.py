"""Report figures: colour ranges that show structure, rounded ticks, the depth table.

Reference values: synthetic fields whose ranges and ticks are known."""

import numpy as np
import pytest
import xarray as xr

from straylight.plots.common import _colour_range, _tick_format
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


def test_colour_range_follows_each_band_not_the_tail():
    """Limit maps: 95 % of the sky within 0.02 mag and a 2-mag shallow tail near the Sun: the
    10th-99.9th percentile range spans the bulk, so its structure shows."""
    rng = np.random.default_rng(1)
    bulk = 26.06 + 0.02 * rng.random(950)
    tail = 24.0 + 2.0 * rng.random(50)
    lo, hi = _colour_range(np.r_[bulk, tail, np.nan], (10.0, 99.9))
    assert 26.05 < lo < 26.07 and hi == pytest.approx(bulk.max(), abs=1e-3)
    lo, hi = _colour_range(np.full(10, 25.0))
    assert hi - lo == pytest.approx(0.01)


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
    UNSEEN pixel is grey."""
    import healpy as hp
    from healpy.projector import MollweideProj
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from straylight.plots.maps import MOLLWEIDE_XSIZE, MollweidePanel

    nside = 8
    m = np.zeros(hp.nside2npix(nside))
    lit = hp.ang2pix(nside, 45.0, 15.0, nest=nest, lonlat=True)
    mirror = hp.ang2pix(nside, 315.0, 15.0, nest=nest, lonlat=True)
    unseen = hp.ang2pix(nside, 200.0, -40.0, nest=nest, lonlat=True)
    m[lit], m[unseen] = 1.0, hp.UNSEEN
    fig = Figure(figsize=(16, 3.3))
    FigureCanvasAgg(fig)
    ax = MollweidePanel(fig, (1, 4, 2), "viridis", None).show(m, nest, "t", 0.0, 1.0).ax

    reference = MollweideProj(xsize=MOLLWEIDE_XSIZE, flipconv="astro")
    expected = reference.projmap(m, lambda x, y, z: hp.vec2pix(nside, x, y, z, nest=nest))
    image = ax.get_images()[0].get_array()
    assert np.array_equal(np.ma.getdata(image), expected)
    # masked: UNSEEN (grey) and, as in mollview, the -inf outside the ellipse (background)
    assert np.array_equal(np.ma.getmaskarray(image), (expected == hp.UNSEEN) | np.isinf(expected))

    fig.canvas.draw()
    rgba = np.asarray(fig.canvas.buffer_rgba())
    height = rgba.shape[0]
    for pix, colour in (
        (lit, colormaps["viridis"](1.0)),
        (mirror, colormaps["viridis"](0.0)),
        (unseen, (0.5, 0.5, 0.5, 1.0)),
    ):
        ra, dec = hp.pix2ang(nside, pix, nest=nest, lonlat=True)  # the pixel's centre
        xy = reference.ang2xy(ra, dec, lonlat=True)
        col, row = ax.transData.transform(np.array(xy, float).reshape(1, 2))[0]
        drawn = rgba[int(height - row), int(col)] / 255.0
        assert drawn == pytest.approx(colour, abs=2 / 255), (ra, dec)


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
    text = write_report_front(back, campaign.config, tmp_path / "summary.rst", [depth, sky]).read_text()
    assert "     - 26.53" in text and "     - 16.5 %" in text and "     - nan" in text
    shown = [line for line in text.splitlines() if "<b>" in line]
    assert [s.split("<b>")[1].split("</b>")[0] for s in shown] == ["limits_median", "sky_g_20260101T0000"]
    assert text.count("data:image/png;base64") == 2


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
    from straylight.plots.common import _mag
    from straylight.survey.limits import ZERO_POINT_NAME, zero_point_coord

    bands = list(campaign.bands)
    rates = np.array([0.0, 1e-3, 0.37, 1.0, 25.0])
    with_zp = xr.Dataset(coords={"band": bands, ZERO_POINT_NAME: zero_point_coord(campaign, bands)})
    without = xr.Dataset(coords={"band": bands})
    for band in bands:
        a, b = _mag(with_zp, rates, band, campaign), _mag(without, rates, band, campaign)
        assert np.array_equal(a, b) and np.isinf(a[0]) and 15 < a[3] < 30
