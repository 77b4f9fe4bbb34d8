"""5-sigma limiting magnitudes against the published CSST wide-survey depth (issue #6, check 3).

Published depth: Qu et al. 2023, MNRAS 519, 6499 (arXiv:2212.10804), abstract: "the point-source
depth reaches 26.3 mag in the g band and 25.9 mag in the i band" for the 17,500 deg2 wide survey
(2 x 150 s).  Only g and i are quoted there; the other bands' published values could not be
checked offline, so they are printed but not compared.
"""
import shutil

import numpy as np
import pytest
import yaml

from conftest import REPO, SHARED_DATA

PUBLISHED_DEPTH_MAG = {"g": 26.3, "i": 25.9}  # Qu et al. 2023 abstract
THROUGHPUT = SHARED_DATA / "csst_throughput"


@pytest.fixture(scope="module")
def real_curve_campaign(tmp_path_factory):
    """The default campaign with the real CSST throughput curves (Wen et al. 2024; test-only data
    read from ../shared, never copied into the repository)."""
    from straylight.config import load_campaign

    tmp = tmp_path_factory.mktemp("instrument")
    src = REPO / "config" / "instruments"
    for p in src.iterdir():
        (shutil.copytree if p.is_dir() else shutil.copy)(p, tmp / p.name)
    inst = yaml.safe_load((src / "csst.yaml").read_text())
    for name, band in inst["bands"].items():
        band.pop("peak_throughput", None)
        band.pop("edge_width_nm", None)
        band["throughput_file"] = str(THROUGHPUT / f"csst_phot.{name.lower()}.fits")
    (tmp / "csst.yaml").write_text(yaml.safe_dump(inst))
    return load_campaign(REPO / "config" / "config.yaml", overrides={"instrument": str(tmp / "csst.yaml")})


def _high_latitude_limits(campaign):
    """Limits over observable samples at ecliptic |beta| >= 60 deg (the darkest zodiacal light),
    a 10 x 10 deg grid of pointings every 30 min of the default campaign day, full model."""
    from straylight.components import ComponentModel
    from straylight.geometry import radec_to_unit
    from straylight.limits import point_source_limit
    from straylight.sky import sample_geometry, scene
    from straylight.zodiacal import icrs_to_ecliptic_matrix

    ra, dec = np.meshgrid(np.arange(0.0, 360.0, 10.0), np.arange(-80.0, 81.0, 10.0))
    ra, dec = ra.ravel(), dec.ravel()
    beta = np.degrees(np.arcsin((radec_to_unit(ra, dec) @ icrs_to_ecliptic_matrix().T)[:, 2]))
    ra, dec = ra[np.abs(beta) >= 60], dec[np.abs(beta) >= 60]
    sc = scene(campaign, campaign.times[::6])
    g = sample_geometry(campaign, sc, ra, dec)
    shape = g["observable"].shape + (3,)
    sat = np.broadcast_to(sc.satellite_km[:, None, :], shape)
    bodies = {k: np.broadcast_to(v[:, None, :], shape) for k, v in sc.bodies_km.items()}
    los = np.broadcast_to(radec_to_unit(ra, dec)[None], shape)
    res = ComponentModel(campaign).evaluate(sat, bodies, los, g, campaign.bands)
    obs = g["observable"]
    assert obs.sum() > 100, "too few observable high-latitude samples"
    return {b: point_source_limit(res[b]["total"][obs], b, campaign) for b in campaign.bands}


@pytest.mark.skipif(not THROUGHPUT.exists(), reason="../shared/data/csst_throughput (test-only real CSST curves) not present")
@pytest.mark.xfail(strict=True, raises=AssertionError, reason=(
    "measured: the model is 0.38 (g) and 0.40 (i) mag deeper than Qu et al. 2023 at dark high-latitude "
    "pointings, beyond the issue's 0.3 mag; with these curves and noise terms the published depths need a "
    "sky of 0.37 (g) and 0.41 (i) e-/s/pix against ~0.1 at the darkest pointings, so the published "
    "calculation likely assumes a brighter sky; its inputs could not be checked offline. "
    "strict: the test fails as soon as the check passes, so the mark must then be removed"))
def test_depth_within_0p3_mag_of_published_wide_survey(real_curve_campaign):
    lims = _high_latitude_limits(real_curve_campaign)
    for b, lim in lims.items():
        ref = PUBLISHED_DEPTH_MAG.get(b)
        extra = f"; published {ref:.1f}, difference {np.median(lim) - ref:+.2f} mag" if ref else ""
        print(f"{b:4s} 5-sigma limit at ecliptic |beta| >= 60: median {np.median(lim):.2f}, "
              f"best {lim.max():.2f}, worst {lim.min():.2f}{extra}")
    from scipy.optimize import brentq

    from straylight.limits import point_source_limit

    for b, ref in PUBLISHED_DEPTH_MAG.items():  # what sky the published depth implies here
        sky = brentq(lambda s: float(point_source_limit(s, b, real_curve_campaign)) - ref, 1e-6, 1e3)
        print(f"{b:4s} the published {ref:.1f} needs a sky + stray light of {sky:.3f} e-/s/pix")
    for b, ref in PUBLISHED_DEPTH_MAG.items():
        assert np.median(lims[b]) == pytest.approx(ref, abs=0.3), b


def test_never_observable_pixels_are_nan_in_zarr_and_unseen_in_fits(tmp_path):
    """A pixel never observable has no best or median limit: NaN in limits.zarr (a float
    sentinel there passed as a magnitude: the report's limit maps took -1.6e30 mag as their
    colour range's low end), healpy's UNSEEN in the FITS maps.  The observable pixel's best and
    median are the largest and the median of its observable times' limits, from
    point_source_limit itself (the masked times, brighter or fainter, are ignored)."""
    import healpy as hp
    import xarray as xr

    from straylight.config import load_campaign
    from straylight.limits import limits_dataset, point_source_limit, write_limit_maps

    c = load_campaign()
    bands = list(c.bands)
    total = np.array([[1.0, 5.0], [0.2, 5.0], [0.5, 5.0], [1e-3, 5.0]])  # (time, pixel) e-/s/pix
    observable = np.array([[True, False], [True, False], [True, False], [False, False]])
    background = xr.Dataset(
        {"total": (("time", "pixel", "band"), np.repeat(total[:, :, None], len(bands), axis=2)),
         "observable": (("time", "pixel"), observable)},
        coords={"time": np.arange(4), "pixel": [0, 1], "ra_deg": ("pixel", [0.0, 10.0]),
                "dec_deg": ("pixel", [0.0, 10.0]), "band": bands},
        attrs={"healpix_nside": 1, "healpix_ordering": "RING", "healpix_frame": "ICRS", "campaign": "test"})
    ds = limits_dataset(c, background)
    g = bands.index("g")
    expected = point_source_limit(total[:3, 0], "g", c)
    assert ds["limiting_mag_best"].values[0, g] == pytest.approx(expected.max(), abs=1e-5)
    assert ds["limiting_mag_median"].values[0, g] == pytest.approx(np.median(expected), abs=1e-5)
    assert np.all(np.isnan(ds["limiting_mag_best"].values[1])) and np.all(np.isnan(ds["limiting_mag_median"].values[1]))
    ds.to_zarr(tmp_path / "limits.zarr")
    back = xr.open_zarr(tmp_path / "limits.zarr")
    assert np.isnan(back["limiting_mag_best"].values[1]).all() and np.isfinite(back["limiting_mag_best"].values[0]).all()
    write_limit_maps(ds, tmp_path / "maps")
    m = hp.read_map(tmp_path / "maps" / "limit_best_g.fits")
    assert m[0] == pytest.approx(expected.max(), abs=1e-5)
    assert m[1] == hp.UNSEEN and np.all(m[2:] == hp.UNSEEN)


def test_limits_stream_over_chunks_with_the_eager_values(tmp_path):
    """limits_dataset on a lazy cube (dask chunks, as the limits rule opens background.zarr)
    gives the same bytes as on the cube in memory: the limits chunk by chunk, the per-pixel
    summaries a few pixels at a time over all times."""
    import xarray as xr

    from straylight.config import load_campaign
    from straylight.limits import limits_dataset

    c = load_campaign()
    bands = list(c.bands)
    rng = np.random.default_rng(3)
    nt, npix = 30, 600
    total = rng.lognormal(0.0, 1.0, (nt, npix, len(bands))).astype(np.float32)
    observable = rng.random((nt, npix)) < 0.3
    observable[:, :5] = False  # never observable: NaN summaries
    background = xr.Dataset(
        {"total": (("time", "pixel", "band"), total), "observable": (("time", "pixel"), observable)},
        coords={"time": np.arange(nt), "pixel": np.arange(npix), "ra_deg": ("pixel", np.zeros(npix)),
                "dec_deg": ("pixel", np.zeros(npix)), "band": bands},
        attrs={"healpix_nside": 8, "healpix_ordering": "RING", "healpix_frame": "ICRS", "campaign": "test"})
    eager = limits_dataset(c, background)
    lazy = limits_dataset(c, background.chunk({"time": 7, "pixel": 100}))
    assert lazy["limiting_mag"].chunks is not None  # nothing computed yet
    lazy.to_zarr(tmp_path / "lazy.zarr")
    back = xr.open_zarr(tmp_path / "lazy.zarr").load()
    for name in ("limiting_mag", "limiting_mag_best", "limiting_mag_median", "observable_fraction", "observable"):
        np.testing.assert_array_equal(back[name].values, eager[name].values, err_msg=name)
        assert back[name].dtype == eager[name].dtype
    assert np.isnan(back["limiting_mag_best"].values[:5]).all()
