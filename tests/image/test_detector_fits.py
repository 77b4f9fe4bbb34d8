"""The detector image's FITS file (straylight/image/detector_fits.py): RICE_1 with subtractive
dithering (the FITS tiled-image convention, Pence et al. 2010 PASP 122, 1065) quantises to
QSTEP with an error of at most QSTEP/2 per pixel, and the same image gives the same pixels."""

import numpy as np
from astropy.io import fits
from astropy.wcs import WCS

from straylight.image.detector import DetectorImage
from straylight.image.detector_fits import write_fits


def _image() -> DetectorImage:
    rng = np.random.default_rng(7)
    data = (0.3 + 0.05 * rng.standard_normal((64, 96))).astype(np.float32)
    wcs = WCS(naxis=2)
    wcs.wcs.ctype = ["RA---TAN", "DEC--TAN"]
    wcs.wcs.crval = [150.0, 2.0]
    wcs.wcs.crpix = [48.5, 32.5]
    wcs.wcs.cdelt = [-0.074 / 3600, 0.074 / 3600]
    empty = {"x_pix": np.zeros(0), "y_pix": np.zeros(0)}
    return DetectorImage(data, dict(empty), dict(empty), wcs, {"bin": 1})


def test_rice_is_reproducible_and_within_half_a_step(tmp_path):
    """Two writes of one image hold the same quantised pixels (the dither's seed comes from the
    first tile's checksum, DITHER_SEED_CHECKSUM, not the clock); each pixel is within QSTEP/2
    of the computed value (the quantisation's bound, astropy.io.fits CompImageHDU)."""
    img = _image()
    step = 1e-3
    pixels = []
    for name in ("a.fits", "b.fits"):
        write_fits(img, tmp_path / name, {"origin": "test"}, compress="rice", quantize_step=step)
        with fits.open(tmp_path / name) as hdul:
            pixels.append(np.array(hdul["SCI"].data))
    np.testing.assert_array_equal(pixels[0], pixels[1])
    assert np.max(np.abs(pixels[0] - img.image_e_per_s_per_pix)) <= step / 2 * (1 + 1e-6)
