"""The Python API (straylight.api): sky_background against `straylight sky`, broadcasting, bad
input, open_campaign and the zero-point conversion, and the module's doctests.

Reference values: `straylight sky` for the same samples (the CLI's own path) and astropy's units."""

import doctest
import json

import numpy as np
import pytest
from conftest import run_cli

T0 = "2026-01-01T00:30:00"


def test_doctests_run():
    import straylight.api

    res = doctest.testmod(straylight.api, optionflags=doctest.ELLIPSIS)
    assert res.attempted >= 8 and res.failed == 0


def test_sky_background_equals_the_sky_command():
    """Same code path as `straylight sky` (pointings.pointing_table vs sky_record): equal numbers."""
    import astropy.units as u
    from astropy.coordinates import SkyCoord
    from astropy.time import Time

    import straylight

    sky = straylight.sky_background(Time(T0), SkyCoord(150.0, 30.0, unit="deg"), bands=["g", "NUV"])
    r = run_cli("sky", "--time", T0, "--ra", "150", "--dec", "30", "--bands", "g,NUV", "--json")
    assert r.returncode == 0, r.stderr
    rec = json.loads(r.stdout)
    assert bool(sky["observable"][0]) == rec["observable"]
    for b in ("g", "NUV"):
        for c in ("zodiacal", "earthshine", "moon", "sun", "planets", "total"):
            e = rec["bands"][b][c]["e_per_s_per_pix"]
            assert sky[f"{c}_{b}"][0].to_value(u.electron / u.s / u.pix) == pytest.approx(
                e, rel=1e-6, abs=1e-12
            )
        # magnitudes: the JSON's (offfield.magnitude_per_arcsec2) and the table's (zero point)
        assert sky[f"total_mag_{b}"][0].to_value(u.mag / u.arcsec**2) == pytest.approx(
            rec["bands"][b]["total"]["mag_per_arcsec2"], abs=1e-6
        )
        assert sky[f"limit_mag_{b}"][0].to_value(u.mag) == pytest.approx(
            rec["bands"][b]["limit_mag"], abs=1e-6
        )
    # g-band dark sky 23.1-23.6 mag/arcsec2 (from the cube); this pointing has Moon light
    assert 21.5 < sky["total_mag_g"][0].value < 23.8


def test_broadcasting_and_reasons():
    import astropy.units as u
    from astropy.coordinates import SkyCoord
    from astropy.time import Time

    import straylight

    t = Time(T0) + np.arange(3) * 20 * u.min
    # the Sun's direction on 2026-01-01 (RA ~281 deg, Dec ~-23 deg): the sun constraint is violated
    c = SkyCoord([150.0, 281.5], [30.0, -23.0], unit="deg")
    sky = straylight.sky_background(t[:, None], c[None, :], bands=["r"])
    assert len(sky) == 6
    assert np.allclose(sky["ra"].to_value(u.deg), [150.0, 281.5] * 3)
    sun_rows = sky[sky["ra"] > 200 * u.deg]
    names = straylight.violation_names(sun_rows["violations"])
    assert all("sun" in v.split(",") for v in names) and not sun_rows["observable"].any()
    assert np.all(sun_rows["violations"] & 1) and sky["violations"].dtype == np.uint8
    assert np.all(sky["violations"][sky["observable"]] == 0)
    assert sky.meta["mag_zero_point"]["r"].unit == u.mag / u.arcsec**2


def test_bad_input_raises_input_error():
    from astropy.coordinates import SkyCoord
    from astropy.time import Time

    import straylight

    c = SkyCoord(150.0, 30.0, unit="deg")
    with pytest.raises(straylight.InputError, match="astropy.time.Time"):
        straylight.sky_background("2026-01-01", c)
    with pytest.raises(straylight.InputError, match="DE405"):
        straylight.sky_background(Time("2300-01-01"), c, bands=["g"])
    with pytest.raises(straylight.InputError, match="unknown band 'w'"):
        straylight.sky_background(Time(T0), c, bands=["w"])
    with pytest.raises(straylight.InputError, match="broadcast"):
        straylight.sky_background(Time([T0] * 3), SkyCoord([1.0, 2.0], [3.0, 4.0], unit="deg"))


def test_zero_point_matches_the_library_conversion(campaign):
    """The stored zero point converts e-/s/pixel to the same mag/arcsec2 as offfield's function."""
    from straylight.limits.point_source import sky_zero_points
    from straylight.optics.bandpass import load_band
    from straylight.sources.photometry import magnitude_per_arcsec2

    zp = sky_zero_points(campaign)
    d = campaign.instrument_value("telescope", "aperture_diameter_m")
    pix = campaign.pixel_scale_arcsec
    for b in campaign.bands:
        band = load_band(campaign.instrument_settings, b, campaign.instrument_path.parent)
        # by definition: 1 e-/s/pixel is zp; 0.1 e-/s/pixel is 2.5 mag fainter
        assert magnitude_per_arcsec2(1.0, band, d, pix) == pytest.approx(zp[b], abs=1e-12)
        assert magnitude_per_arcsec2(0.1, band, d, pix) == pytest.approx(zp[b] + 2.5, abs=1e-12)
        # AB: 3631 Jy over the band's photon zero point, pi (D/2)^2 and a pixel of pix^2 arcsec2
        ref = band.ab_zero_point_photons_s_m2 * np.pi * d**2 / 4 * pix**2
        assert zp[b] == pytest.approx(2.5 * np.log10(ref), abs=1e-12)


def test_open_campaign_and_mag_conversion(tmp_path, campaign):
    import xarray as xr

    import straylight
    from straylight.limits.point_source import ZERO_POINT_NAME, zero_point_coord

    bands = campaign.bands
    rate = np.array([[[0.1, 1.0, 0.0, 10.0, 0.2, 0.3, 0.4]]], dtype=np.float32)[:, :, : len(bands)]
    ds = xr.Dataset(
        {"total": (("time", "pixel", "band"), rate, {"units": "electron / (s pixel)", "long_name": "total"})},
        coords={
            "band": ("band", np.array(bands, dtype=object)),
            ZERO_POINT_NAME: zero_point_coord(campaign, bands),
        },
    )
    ds.to_zarr(tmp_path / "background.zarr")
    prod = straylight.open_campaign(tmp_path)
    mag = prod.to_mag_per_arcsec2(prod.background["total"]).compute()
    zp = prod.background[ZERO_POINT_NAME].values
    assert mag.attrs["units"] == "mag(AB) arcsec-2"
    assert float(mag[0, 0, 1]) == pytest.approx(zp[1], abs=1e-5)  # 1 e-/s/pixel -> the zero point
    assert float(mag[0, 0, 0]) == pytest.approx(zp[0] + 2.5, abs=1e-5)
    assert np.isinf(float(mag[0, 0, 2]))
    sub = prod.background["total"].sel(band=["g"])  # a band subset keeps its zero point
    assert float(prod.to_mag_per_arcsec2(sub)[0, 0, 0]) == pytest.approx(
        float(mag.sel(band="g")[0, 0]), abs=1e-6
    )
    with pytest.raises(straylight.InputError, match="limits.zarr: product missing"):
        prod.limits
    with pytest.raises(straylight.InputError, match="not a campaign results folder"):
        straylight.open_campaign(tmp_path / "nope")


def test_catalog_stars_enter_as_in_the_sky_command(tmp_path):
    """With a catalog the star term is the cube's (stars.offfield_mag_limit split and faint map),
    equal to `straylight sky --catalog`; a -1.5 mag star 5 deg off axis makes it non-zero."""
    import astropy.units as u
    from astropy.coordinates import SkyCoord
    from astropy.time import Time

    import straylight

    cat = tmp_path / "stars.csv"
    cat.write_text("ra,dec,mag_g,mag_r\n155.0,30.0,-1.5,-1.4\n20.0,-40.0,5.0,5.0\n")
    sky = straylight.sky_background(
        Time(T0), SkyCoord(150.0, 30.0, unit="deg"), bands=["g", "r"], catalog=cat
    )
    r = run_cli(
        "sky", "--time", T0, "--ra", "150", "--dec", "30", "--bands", "g,r", "--catalog", cat, "--json"
    )
    assert r.returncode == 0, r.stderr
    rec = json.loads(r.stdout)
    for b in ("g", "r"):
        stars = sky[f"stars_{b}"][0].to_value(u.electron / u.s / u.pix)
        assert stars > 0
        assert stars == pytest.approx(rec["bands"][b]["stars"]["e_per_s_per_pix"], rel=1e-6)


def test_empty_time_and_coord_give_an_empty_table_with_the_columns():
    """Zero samples (a scheduler's empty batch) give an empty QTable with the columns and units
    of a non-empty call, without running the model; the bands and config are still checked."""
    import astropy.units as u
    from astropy.coordinates import SkyCoord
    from astropy.time import Time

    import straylight

    one = straylight.sky_background(Time(T0), SkyCoord(150.0, 30.0, unit="deg"), bands=["g", "V"])
    empty_t = Time(np.array([], float), format="jd", scale="utc")
    empty_c = SkyCoord(np.array([]), np.array([]), unit="deg")
    for t, c in (
        (empty_t, empty_c),
        (empty_t, SkyCoord(150.0, 30.0, unit="deg")),
        (Time([T0] * 3)[:, None], empty_c[None, :]),
    ):
        sky = straylight.sky_background(t, c, bands=["g", "V"])
        assert len(sky) == 0
        assert sky.colnames == one.colnames
        for name in one.colnames:
            assert getattr(sky[name], "unit", None) == getattr(one[name], "unit", None), name
        assert sky.meta["mag_zero_point"]["g"] == one.meta["mag_zero_point"]["g"]
    with pytest.raises(straylight.InputError, match="unknown band 'w'"):
        straylight.sky_background(empty_t, empty_c, bands=["w"])
    assert u.Quantity(sky["total_g"]).size == 0


def test_an_empty_band_list_is_refused():
    from astropy.coordinates import SkyCoord
    from astropy.time import Time

    import straylight

    with pytest.raises(straylight.InputError, match=r"bands: no band given.*NUV, u, g, r, i, z, y"):
        straylight.sky_background(Time(T0), SkyCoord(150.0, 30.0, unit="deg"), bands=[])


def test_a_masked_time_is_refused_naming_the_sample():
    """A masked entry has no time to compute at: refused (as a non-finite coordinate is), naming
    the sample in the broadcast, rather than computed at the value hidden under the mask."""
    from astropy.coordinates import SkyCoord
    from astropy.time import Time

    import straylight

    t = Time([T0, "2026-01-01T00:40:00", "2026-01-01T00:50:00"])
    t[1] = np.ma.masked
    with pytest.raises(straylight.InputError, match=r"time: sample 1 is masked \(1 of 3 samples\)"):
        straylight.sky_background(t, SkyCoord(150.0, 30.0, unit="deg"), bands=["g"])
    c = SkyCoord([150.0, 160.0], [30.0, 30.0], unit="deg")
    with pytest.raises(straylight.InputError, match=r"time: sample 2 is masked \(2 of 6 samples\)"):
        straylight.sky_background(t[:, None], c[None, :], bands=["g"])


def test_a_time_outside_de405_is_one_error_without_erfa_warnings():
    """ERFA's "dubious year" warnings would precede the refusal of a time outside DE405."""
    import warnings

    from astropy.coordinates import SkyCoord
    from astropy.time import Time

    import straylight

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the test's own Time in 2300
        t = Time(["2026-01-01T00:30:00", "2300-01-01T00:00:00"])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(
            straylight.InputError,
            match=r"time: sample 1 = 2300-01-01T00:00:00.000 is outside the "
            r"DE405 range \(1599-12-09 to 2201-02-20\); 1 of 2 samples are outside it",
        ):
            straylight.sky_background(t, SkyCoord(150.0, 30.0, unit="deg"), bands=["g"])
    assert not [w for w in caught if "dubious year" in str(w.message)]
