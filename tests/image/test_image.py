"""Detector stray-light images: accuracy of the fast renderer, energy, WCS, CLI.

Reference numbers: the paper's ghost ratios (sect. 4.3 eq. 10), energy conservation, astropy's WCS."""

import numpy as np
import pytest
from conftest import run_cli

from straylight.errors import InputError
from straylight.image.detector import Aim, DetectorOptics, RenderSettings, Stars, render_detector
from straylight.image.focal_plane import FocalPlane, focal_plane_from_instrument, pointing_wcs
from straylight.optics.ghosts import ghost_model_from_instrument
from straylight.optics.scatter import scatter_model_from_instrument

SUN = np.array([1.0, 0.0, 0.0])
N = 768
AIM = Aim(150.0, 30.0, SUN, 12)


@pytest.fixture(scope="module")
def parts(campaign):
    fp = focal_plane_from_instrument(campaign.instrument_settings)
    small = FocalPlane(N, N, fp.pixel_scale_arcsec, fp.pixel_size_mm, fp.columns, fp.rows, fp.gap_px)
    return (
        fp,
        small,
        scatter_model_from_instrument(campaign.instrument_settings),
        ghost_model_from_instrument(campaign.instrument_settings, "g"),
    )


def _render(parts, xy, flux, **kw):
    fp, small, sc, gh = parts
    w = pointing_wcs(150.0, 30.0, SUN, small, 12)
    ra, dec = w.pixel_to_world_values(np.asarray(xy)[:, 0], np.asarray(xy)[:, 1])
    ghosts = kw.pop("ghosts", None)
    return render_detector(
        Aim(150.0, 30.0, SUN, 12),
        Stars(ra, dec, flux),
        DetectorOptics(fp, sc, ghosts, 3.9),
        RenderSettings(**kw),
        size_override=(N, N),
    )


def test_one_star_matches_direct_evaluation(parts):
    """FFT image of one star against the profile evaluated directly at every pixel centre."""
    sc = parts[2]
    res = _render(parts, [[400.0, 300.0]], [1e6], margin_arcsec=10.0)
    y, x = np.mgrid[0:N, 0:N]
    d = np.hypot(x - 400.0, y - 300.0) * 10e-6
    direct = sc.profile(d) * 1e-10 * 1e6
    im = res.image_e_per_s_per_pix.astype(float)
    assert im.sum() == pytest.approx(direct.sum(), rel=1e-4)
    far = d > 150 * 10e-6
    rel = np.abs(im[far] - direct[far]) / direct[far]
    print(f"far-field (>150 px) max rel error at far_bin 8: {rel.max():.3e}")
    assert rel.max() < 0.02


def test_energy_of_scatter_and_ghosts(parts):
    """Star at the centre of the image: painted ghosts hold exactly sum Phi_k, and core+halo
    inside the image equals 1 - halo power outside it (analytic) within 1 %.

    The star's flux is its detected rate, which already holds the filter's T1 T2 (band
    throughput); its ghosts are Phi_k / (Phi T1 T2) of it (paper sect. 4.3 eq. 10):
    R1 R2 + Rd R2 + T2^2 R1 Rd = 8.65e-5 + 1.395e-3 + 9.49e-4 = 2.431e-3 for the NUV example's
    values (R = 0.0093, Rd = 0.15, T = 0.825), not the 1.655e-3 of Phi_k / Phi."""
    sc, gh = parts[2], parts[3]
    flux = 1e6
    res = _render(parts, [[N / 2, N / 2]], [flux], ghosts=gh, margin_arcsec=10.0)
    ghost_energy = res.ghosts["energy_e_per_s"].sum()
    assert (gh.r1, gh.r2, gh.rd, gh.t2) == (0.0093, 0.0093, 0.15, 0.825)
    assert ghost_energy == pytest.approx(
        flux * (0.0093**2 + 0.15 * 0.0093 + 0.825**2 * 0.0093 * 0.15), rel=1e-12
    )
    assert ghost_energy / flux == pytest.approx(2.431e-3, rel=1e-3)
    no_ghost = _render(parts, [[N / 2, N / 2]], [flux], margin_arcsec=10.0).image_e_per_s_per_pix.astype(
        float
    )
    assert res.image_e_per_s_per_pix.astype(float).sum() - no_ghost.sum() == pytest.approx(
        ghost_energy, rel=1e-3
    )
    # halo inside the inscribed circle (radius N/2) vs analytic; image square holds a bit more
    y, x = np.mgrid[0:N, 0:N]
    inside = np.hypot(x - N / 2, y - N / 2) <= N / 2 - 1
    captured = no_ghost[inside].sum() / flux
    expected = (1 - sc.halo_power) + sc.halo_energy_within((N / 2 - 1) * 10e-6)
    assert captured == pytest.approx(expected, rel=0.01)


def test_star_just_off_the_chip_still_scatters(parts):
    res = _render(parts, [[N + 200.0, N / 2]], [1e9], margin_arcsec=100.0)
    assert len(res.stars["x_pix"]) == 1
    assert res.image_e_per_s_per_pix.max() > 0
    assert res.image_e_per_s_per_pix[:, -1].mean() > res.image_e_per_s_per_pix[:, 0].mean()


def test_faint_star_far_off_the_chip_is_skipped(parts):
    res = _render(parts, [[N + 5000.0, N / 2]], [10.0], margin_arcsec=1000.0)
    assert len(res.stars["x_pix"]) == 0


def test_empty_catalog_gives_zero_image(parts):
    res = _render(parts, np.zeros((0, 2)), np.zeros(0))
    assert res.image_e_per_s_per_pix.shape == (N, N) and not res.image_e_per_s_per_pix.any()


def test_nan_flux_is_refused(parts):
    with pytest.raises(InputError, match="finite"):
        _render(parts, [[10.0, 10.0]], [np.nan])


def test_detector_layout_and_bad_index(parts):
    fp = parts[0]
    assert fp.n_detectors == 30
    with pytest.raises(InputError, match="--detector 30"):
        fp.detector_offset_px(30)


def test_wcs_roll_follows_the_sun(parts):
    """+x of the image points towards the Sun's projection (the door side)."""
    from astropy.wcs.utils import proj_plane_pixel_scales

    small = parts[1]
    w = pointing_wcs(150.0, 30.0, SUN, small, 12)
    assert proj_plane_pixel_scales(w)[0] * 3600 == pytest.approx(
        10e-6 / 28.0 * 206264.806247, rel=1e-9
    )  # p / f
    from straylight.sky.vectors import radec_to_unit

    c0 = radec_to_unit(*w.pixel_to_world_values(100.0, 100.0))
    c1 = radec_to_unit(*w.pixel_to_world_values(200.0, 100.0))
    step = c1 - c0
    z = radec_to_unit(150.0, 30.0)
    sun_proj = SUN - (SUN @ z) * z
    cosang = step @ sun_proj / np.linalg.norm(step) / np.linalg.norm(sun_proj)
    assert cosang == pytest.approx(1.0, abs=1e-6)


@pytest.mark.slow
def test_image_cli_end_to_end(tmp_path, campaign):
    """Full 9216 x 9232 detector through the CLI with a small catalog: FITS, WCS, ghosts."""
    from astropy.io import fits
    from astropy.table import Table
    from astropy.wcs import WCS

    from straylight.image.focal_plane import sun_direction_at

    fp = parts_fp = focal_plane_from_instrument(campaign.instrument_settings)
    w = pointing_wcs(150.0, 30.0, sun_direction_at(campaign, "2026-01-01T00:50:00"), parts_fp, 12)
    ra, dec = w.pixel_to_world_values(np.array([1000.0, 5000.0, 9000.0]), np.array([2000.0, 4000.0, 100.0]))
    cat = tmp_path / "stars.ecsv"
    Table({"ra": ra, "dec": dec, "mag_g": [8.0, 10.0, 12.0]}).write(cat)
    out = tmp_path / "img.fits"
    r = run_cli(
        "image",
        "--time",
        "2026-01-01T00:50:00",
        "--ra",
        150,
        "--dec",
        30,
        "--band",
        "g",
        "--catalog",
        cat,
        "--out",
        out,
        "--center",
        "boresight",
        timeout=600,
    )
    assert r.returncode == 0, r.stderr
    with fits.open(out) as h:
        assert h["SCI"].data.shape == (fp.ny, fp.nx) and h["SCI"].header["BUNIT"] == "electron/s"
        assert h["SCI"].header["BAND"] == "g" and "DATE-OBS" in h["SCI"].header
        ww = WCS(h["SCI"].header)
        x, y = ww.world_to_pixel_values(ra[0], dec[0])
        assert (x, y) == pytest.approx((1000.0, 2000.0), abs=1e-6)
        assert len(h["GHOSTS"].data) == 9
        assert h["GHOSTS"].columns["energy_e_per_s"].unit == "electron/s"
        assert h["STARS"].columns["x_pix"].unit == "pix"
        img = h["SCI"].data
        assert np.unravel_index(np.argmax(img), img.shape) == (2000, 1000)


def test_image_cli_bad_catalog(tmp_path):
    from astropy.table import Table

    cat = tmp_path / "stars.ecsv"
    Table({"ra": [1.0], "dec": [2.0]}).write(cat)
    r = run_cli(
        "image",
        "--time",
        "2026-01-01T00:50:00",
        "--ra",
        1,
        "--dec",
        2,
        "--band",
        "g",
        "--catalog",
        cat,
        "--out",
        tmp_path / "x.fits",
    )
    assert r.returncode == 2 and "missing column(s) mag_g" in r.stderr and "Traceback" not in r.stderr


def test_strips_equal_whole_image(parts, monkeypatch):
    """Rendering in row strips (memory bound) gives the whole-image result to FFT round-off."""
    import straylight.image.detector as image

    xy, flux = [[100.0, 120.0], [400.0, 700.0], [700.0, 30.0], [N + 150.0, 300.0]], [1e8, 1e6, 1e7, 1e9]
    gh = parts[3]
    whole = _render(parts, xy, flux, ghosts=gh, margin_arcsec=60.0).image_e_per_s_per_pix.astype(float)
    monkeypatch.setattr(image, "STRIP_ROWS", 100)
    strips = _render(parts, xy, flux, ghosts=gh, margin_arcsec=60.0).image_e_per_s_per_pix.astype(float)
    assert np.abs(strips - whole).max() <= 1e-6 * whole.max()


def test_bin_and_cutout_keep_units_and_wcs(parts):
    """--bin N: the mean of N x N pixels (e-/s per chip pixel, so the sum scales by 1/N^2) with a
    WCS that maps the star to its binned pixel; a cutout is the same pixels as the full image."""
    fp, small, sc, _ = parts
    w = pointing_wcs(150.0, 30.0, SUN, small, 12)
    ra, dec = w.pixel_to_world_values(np.array([300.0]), np.array([500.0]))
    kw = dict(settings=RenderSettings(margin_arcsec=10.0), size_override=(N, N))
    full = render_detector(AIM, Stars(ra, dec, [1e6]), DetectorOptics(fp, sc, None, 3.9), **kw)
    binned = render_detector(
        AIM, Stars(ra, dec, [1e6]), DetectorOptics(fp, sc, None, 3.9), bin_factor=8, **kw
    )
    assert binned.image_e_per_s_per_pix.shape == (N // 8, N // 8)
    assert binned.image_e_per_s_per_pix.astype(float).sum() * 64 == pytest.approx(
        full.image_e_per_s_per_pix.astype(float).sum(), rel=1e-5
    )
    x, y = binned.wcs.world_to_pixel_values(ra[0], dec[0])
    assert (float(x), float(y)) == pytest.approx(((300.0 + 0.5) / 8 - 0.5, (500.0 + 0.5) / 8 - 0.5), abs=1e-6)
    cut = render_detector(
        AIM, Stars(ra, dec, [1e6]), DetectorOptics(fp, sc, None, 3.9), window=(200, 450, 128, 96), **kw
    )
    assert cut.image_e_per_s_per_pix.shape == (96, 128)
    ref = full.image_e_per_s_per_pix[450:546, 200:328].astype(float)
    assert np.abs(cut.image_e_per_s_per_pix - ref).max() <= 1e-6 * ref.max()
    x, y = cut.wcs.world_to_pixel_values(ra[0], dec[0])
    assert (float(x), float(y)) == pytest.approx((100.0, 50.0), abs=1e-6)


def test_boresight_puts_target_on_the_chip_centre(parts):
    """--center detector: the solved boresight's WCS maps the target to the chip's centre pixel."""
    from straylight.image.focal_plane import boresight_for_target

    fp = parts[0]
    for det in (0, 12, 29):
        ra, dec = boresight_for_target(101.2885, -16.7131, SUN, fp, det)
        w = pointing_wcs(ra, dec, SUN, fp, det)
        x, y = w.world_to_pixel_values(101.2885, -16.7131)
        assert (float(x), float(y)) == pytest.approx(((fp.nx - 1) / 2, (fp.ny - 1) / 2), abs=1e-3)


def test_named_stars_are_bright_in_the_default_catalog(campaign):
    """Every IAU name of --star resolves to a Hipparcos star brighter than Hp = 2.6 (the list is of
    first- and second-magnitude stars; Hipparcos Hp of Polaris, Algol and Alphard ~2.1-2.2)."""
    from straylight.catalog.hipparcos import BRIGHT_STAR_HIP, read_hip2

    hip = read_hip2()
    vmag = dict(zip(hip["hip"], hip["hp_mag"]))
    for name, number in BRIGHT_STAR_HIP.items():
        assert number in vmag, name
        assert vmag[number] < 2.6, (name, vmag[number])


def test_image_cli_star_bin_and_empty_field(tmp_path, campaign):
    """--star NAME with the default catalog, --bin 16, gzip, --background: a small file whose
    background is the pointing table's total at the boresight; a field with no star gives a
    warning and exit 1, and nothing is written unless --allow-empty."""
    from astropy.io import fits
    from astropy.table import Table

    from straylight.catalog.campaign_catalog import default_catalog_path
    from straylight.planning.pointings import pointing_table
    from straylight.sources.stars_table import load_offfield_stars

    out = tmp_path / "sirius.fits"
    r = run_cli(
        "image",
        "--time",
        "2026-01-01T00:50:00",
        "--star",
        "Sirius",
        "--band",
        "g",
        "--bin",
        "16",
        "--background",
        "--out",
        out,
        timeout=900,
    )
    assert r.returncode == 0, r.stderr
    assert out.stat().st_size < 5e6
    with fits.open(out) as h:
        img = h["SCI"].data
        assert img.shape == (9232 // 16, 9216 // 16)
        assert np.unravel_index(np.argmax(img), img.shape) == pytest.approx((9232 // 32, 9216 // 32), abs=2)
        hdr = h["SCI"].header
        assert hdr["STAR"] == "Sirius"
        sc = campaign.config_mapping()["stars"]
        stars = load_offfield_stars(
            default_catalog_path(campaign),
            ["g"],
            float(sc["offfield_mag_limit"]),
            bool(sc.get("faint_map", True)),
        )
        cols = pointing_table(
            campaign,
            {
                "time": np.array(["2026-01-01T00:50:00"]),
                "ra": np.array([hdr["RA_PNT"]]),
                "dec": np.array([hdr["DEC_PNT"]]),
            },
            ["g"],
            stars,
        )
        assert hdr["BKG_TOT"] == pytest.approx(float(cols["total_g"][0]), rel=1e-9)
        assert img.min() >= hdr["BKG_TOT"] * (1 - 1e-6)
    cat = tmp_path / "one.ecsv"
    Table({"ra": [10.0], "dec": [-60.0], "mag_g": [5.0]}).write(cat)
    empty = tmp_path / "empty.fits"
    args = (
        "image",
        "--time",
        "2026-01-01T00:50:00",
        "--ra",
        150,
        "--dec",
        30,
        "--band",
        "g",
        "--catalog",
        cat,
        "--out",
        empty,
        "--bin",
        "32",
    )
    r = run_cli(*args, timeout=600)
    assert r.returncode == 1 and "no star" in r.stderr and "--allow-empty" in r.stderr and not empty.exists()
    r = run_cli(*args, "--allow-empty", timeout=600)
    assert r.returncode == 0 and empty.exists()
