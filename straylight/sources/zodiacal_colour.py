"""The zodiacal light's spectrum relative to its 500 nm brightness (seed paper sect. 4.1).

The zodiacal light is sunlight scattered by interplanetary dust, slightly reddened with respect
to the Sun.  Three spectra S(lambda), each normalised to its mean over 495-505 nm (Leinert's
reference wavelength), are offered (``models.zodiacal_spectrum``):

* ``leinert_fit`` (default): the ASTM E490 solar spectrum times Leinert et al. (1998)'s fit of
  the zodiacal light's colour with respect to the Sun (sect. 8, eq. 22, as reproduced by Noll et
  al. 2012, A&A 543, A92, sect. 3.3):

      f_co(lambda) = 1 + a log10(lambda / 0.5 um),

  with a = ``blue_per_dex`` below 0.5 um and ``red_per_dex`` above (0.9 and 0.6 at elongation
  90 deg, 1.2 and 0.8 at 30 deg; ``models.zodiacal_reddening``).  Smooth and monotonic: the
  solar lines are the Sun's own, nothing is divided by a line-affected mean.
* ``solar_leinert``: the E490 Sun times Leinert's Table 19 points over the Sun's mean within
  +/-25 nm of each point, interpolated in log(lambda).  Kept to compare: the Ca II H and K lines
  (393/397 nm) in the 375-425 nm window make it non-monotonic (0.79 at 0.3 um, 1.16 at 0.4 um).
* ``hst``: the HST/STScI zodiacal spectrum (``Zodi.fits``), the seed paper's own ratios.
"""

from __future__ import annotations

from functools import lru_cache
from importlib import resources
from pathlib import Path

import numpy as np

from straylight.errors import ConfigError
from straylight.sources.photometry import solar_spectrum

__all__ = [
    "SPECTRA",
    "REFERENCE_WAVELENGTH_UM",
    "LEINERT_REDDENING_EPS90",
    "solar_spectrum",
    "reddening_factor",
    "leinert_colour_correction",
    "zodiacal_spectrum_shape",
]

SPECTRA = ("leinert_fit", "solar_leinert", "hst")
REFERENCE_WAVELENGTH_UM = 0.5
#: Leinert et al. 1998 eq. 22 at elongation 90 deg: (blue_per_dex, red_per_dex)
LEINERT_REDDENING_EPS90 = (0.9, 0.6)


def _data_path(name: str) -> Path:
    return Path(resources.files("straylight") / "data" / name)


def reddening_factor(wavelength_um, blue_per_dex: float, red_per_dex: float) -> np.ndarray:
    """Leinert et al. (1998) eq. 22: the zodiacal light's colour relative to the Sun,
    f_co = 1 + a log10(lambda / 0.5 um), a = ``blue_per_dex`` at lambda <= 0.5 um and
    ``red_per_dex`` above; 1 at 0.5 um.

    Parameters
    ----------
    wavelength_um : array_like
        Wavelengths, um (positive).
    blue_per_dex : float
        Change of f_co per decade of wavelength below 0.5 um (0.9 at elongation 90 deg).
    red_per_dex : float
        Change of f_co per decade of wavelength above 0.5 um (0.6 at elongation 90 deg).

    Returns
    -------
    ndarray
        f_co, dimensionless, of ``wavelength_um``'s shape.
    """
    wl = np.asarray(wavelength_um, dtype=float)
    dex = np.log10(wl / REFERENCE_WAVELENGTH_UM)
    return 1.0 + np.where(dex <= 0.0, blue_per_dex, red_per_dex) * dex


@lru_cache(maxsize=1)
def leinert_colour_correction() -> tuple[np.ndarray, np.ndarray]:
    """Leinert Table 19 over the Sun's mean within +/-25 nm, normalised to 1 at 500 nm (the
    ``solar_leinert`` spectrum's correction; it carries the solar lines inside each window).

    Returns
    -------
    wavelength_um : ndarray, shape (n,)
        The Table 19 wavelengths, um.
    factor : ndarray, shape (n,)
        The colour correction, dimensionless, 1 at 500 nm.
    """
    lines = _data_path("leinert1998_table19.csv").read_text().splitlines()
    t19 = np.array(
        [
            [float(x) for x in ln.split(",")]
            for ln in lines
            if ln and not ln.startswith("#") and not ln.startswith("wavelength")
        ]
    )
    wl_a, sun = solar_spectrum()
    sun_smooth = np.array(
        [np.mean(sun[(wl_a >= w * 1e4 - 250.0) & (wl_a <= w * 1e4 + 250.0)]) for w in t19[:, 0]]
    )
    ratio = t19[:, 1] / sun_smooth
    i500 = int(np.argmin(np.abs(t19[:, 0] - REFERENCE_WAVELENGTH_UM)))
    return t19[:, 0], ratio / ratio[i500]


@lru_cache(maxsize=8)
def zodiacal_spectrum_shape(
    kind: str, reddening: tuple = LEINERT_REDDENING_EPS90
) -> tuple[np.ndarray, np.ndarray]:
    """Relative zodiacal spectrum S(lambda)/S(500 nm): (wavelength A, dimensionless).

    Parameters
    ----------
    kind : str
        One of :data:`SPECTRA`.
    reddening : tuple of float
        ``(blue_per_dex, red_per_dex)`` of :func:`reddening_factor`; read by ``leinert_fit``
        only.

    Returns
    -------
    wavelength_angstrom : ndarray, shape (n,)
        Wavelengths, Angstrom.
    shape : ndarray, shape (n,)
        The spectrum over its mean at 495-505 nm, dimensionless.

    Raises
    ------
    ConfigError
        When ``kind`` is not one of :data:`SPECTRA`.
    """
    if kind == "leinert_fit":
        wl_a, sun = solar_spectrum()
        s = sun * reddening_factor(wl_a / 1e4, *reddening)
    elif kind == "solar_leinert":
        wl_a, sun = solar_spectrum()
        wl_cc, cc = leinert_colour_correction()
        s = sun * np.interp(np.log(wl_a / 1e4), np.log(wl_cc), cc)
    elif kind == "hst":
        from astropy.io import fits

        with fits.open(_data_path("hst_zodi.fits")) as h:
            wl_a = np.asarray(h[1].data["WAVELENGTH"], dtype=float)
            s = np.asarray(h[1].data["FLUX"], dtype=float)
    else:
        raise ConfigError(f"zodiacal spectrum {kind!r} is not one of {SPECTRA}")
    # normalise by the mean over 495-505 nm (the Leinert reference wavelength)
    sel = (wl_a >= 4950.0) & (wl_a <= 5050.0)
    return wl_a, s / np.mean(s[sel])
