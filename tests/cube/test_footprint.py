"""Footprint: latitude cuts give the CSST wide-survey area; a user mask replaces them.

Reference numbers: the CSST wide survey's ~17,500 deg2 (Gong et al. 2019); healpy and astropy
for pixels and frames."""

import healpy as hp
import numpy as np
import pytest

from straylight.cube.footprint import footprint_from_config, latitude_cut_mask
from straylight.errors import InputError


def test_default_cuts_give_about_17500_deg2(campaign):
    """CSST wide survey ~17,500 deg2 (Gong et al. 2019); the default cuts give 17,700 at nside 16."""
    fp = footprint_from_config(campaign.settings.footprint)
    assert fp.area_deg2 == pytest.approx(17500, rel=0.03)
    # converged with resolution: nside 64 gives the same area within 1%
    m64 = latitude_cut_mask(64, False, 20.0, 18.0)
    assert m64.sum() * hp.nside2pixarea(64, degrees=True) == pytest.approx(fp.area_deg2, rel=0.01)


def test_pixels_satisfy_the_cuts(campaign):
    import astropy.units as u
    from astropy.coordinates import SkyCoord

    fp = footprint_from_config(campaign.settings.footprint)
    b = SkyCoord(fp.ra_deg * u.deg, fp.dec_deg * u.deg).galactic.b.deg
    assert np.all(np.abs(b) >= 20.0)


def test_user_mask_file_replaces_the_cuts(tmp_path):
    m = np.zeros(hp.nside2npix(32))
    ipix = hp.query_disc(32, hp.ang2vec(150.0, 2.0, lonlat=True), np.radians(10))
    m[ipix] = 1
    path = tmp_path / "mask.fits"
    hp.write_map(str(path), m, dtype=np.float32)
    fp = footprint_from_config({"nside": 16, "ordering": "nested", "mask_file": str(path)})
    cap_deg2 = 2 * np.pi * (1 - np.cos(np.radians(10))) * (180 / np.pi) ** 2  # 314.6 deg2
    assert fp.area_deg2 == pytest.approx(cap_deg2, rel=0.15)  # nside 16 pixels are 13 deg2
    assert np.all(np.abs(fp.ra_deg - 150) < 15) and np.all(np.abs(fp.dec_deg - 2) < 15)


def test_bad_mask_file(tmp_path):
    p = tmp_path / "mask.fits"
    p.write_text("not fits")
    with pytest.raises(InputError, match="mask.fits is not a HEALPix FITS map"):
        footprint_from_config({"nside": 16, "mask_file": str(p)})
    with pytest.raises(InputError, match="does not exist"):
        footprint_from_config({"nside": 16, "mask_file": str(tmp_path / "none.fits")})


def test_pixel_blocks_are_equal_and_never_a_sliver():
    """round(n / size) blocks of equal length (cube.footprint.pixel_block_length): 5286 pixels
    (nside 32's footprint) at 660 are 8 blocks of 661, not 8 of 660 and a chunk of 6 pixels that
    costs nearly a whole chunk to encode; an exact multiple keeps the size asked."""
    from straylight.cube.footprint import pixel_block_length

    assert pixel_block_length(5286, 660) == 661
    assert pixel_block_length(1320, 660) == 660
    assert pixel_block_length(100, 660) == 100
    for n, size in ((5286, 660), (21100, 1024), (86, 40), (7, 3)):
        step = pixel_block_length(n, size)
        lengths = np.diff(list(range(0, n, step)) + [n])
        assert lengths.sum() == n and lengths.max() == step
        assert lengths.min() >= step - len(
            lengths
        )  # the last block short by fewer pixels than there are blocks


def test_healpy_without_its_plotting_functions_gives_the_same_pixels():
    """straylight.util.healpix: a pipeline process that asks (load_without_plotting) gets healpy
    without matplotlib: the same pix2ang as healpy whole, matplotlib not loaded, astropy.time
    still noting matplotlib as installed, and the plotting module importable by name afterwards.
    A process that does not ask (the Python API) gets healpy whole."""
    import subprocess
    import sys

    code = (
        "import sys, numpy as np\n"
        "from straylight.util.healpix import healpy, load_without_plotting\n"
        "load_without_plotting()\n"
        "hp = healpy()\n"
        "assert 'matplotlib' not in sys.modules and not hasattr(hp, 'mollview')\n"
        "import astropy.time.formats as f\n"
        "assert f.HAS_MATPLOTLIB\n"
        "ra, dec = hp.pix2ang(32, np.arange(12 * 32**2), lonlat=True)\n"
        "from healpy import visufunc\n"
        "assert callable(visufunc.mollview) and 'matplotlib' in sys.modules\n"
        "print(repr(ra.tobytes().hex()[:64]), float(ra.sum()), float(dec.sum()))\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    ra, dec = hp.pix2ang(32, np.arange(12 * 32**2), lonlat=True)  # healpy whole (matplotlib loaded here)
    assert r.stdout.split() == [repr(ra.tobytes().hex()[:64]), repr(float(ra.sum())), repr(float(dec.sum()))]
    whole = "from straylight.util.healpix import healpy\nassert callable(healpy().mollview)\n"
    r = subprocess.run([sys.executable, "-c", whole], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
