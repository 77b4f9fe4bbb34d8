"""Band throughputs and synthetic photometry (via speclite).

A :class:`Band` is the total system throughput (mirrors x filter x detector QE) of one band, as
a speclite ``FilterResponse``.  Its source is, in order of preference:

1. a measured curve named by ``throughput_file`` in the instrument config (CSV, ECSV or FITS
   table with a wavelength and a throughput column; wavelength unit from
   ``throughput_wavelength_unit``);
2. the documented parametric default: flat at ``peak_throughput`` between the paper's band edges
   with error-function edges of 10-90 % width ``edge_width_nm``.

Where the band gives ``zero_point_ab_mag`` (the AB magnitude giving 1 e-/s through the whole
aperture: published for CSST g r i z; for NUV and u that of Wen et al. 2024's curves), either
curve is scaled so that its zero point is that one plus ``zero_point_offset_mag``'s value (0 by
default; its range is the assumption envelope's) (:func:`zero_point_ab_mag`); the curve then
gives the shape only.  A flat top at the peak
throughput overstates a real band's mean (filter ripple, the CCD's QE slope), so unscaled it is
0.1-0.6 mag too bright.

The Bessell V curve (speclite ``bessell-V``) is available as the diagnostic band ``V`` for
comparison with published V-band sky tables; it has no QE, so its e-/s are nominal.

Units: wavelengths in Angstrom inside speclite; spectra passed as F_lambda in W m-2 um-1
(per steradian for surface brightness).  Photon rates in photons s-1 m-2.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache
from pathlib import Path

import numpy as np
from scipy.special import erf

from straylight.config import InstrumentSettings, instrument_settings
from straylight.errors import ConfigError, InputError
from straylight.util.io import without_bom

__all__ = [
    "H_PLANCK",
    "C_LIGHT",
    "DIAGNOSTIC_BANDS",
    "Band",
    "parametric_curve",
    "read_throughput_file",
    "aperture_area_m2",
    "zero_point_ab_mag",
    "load_band",
]

H_PLANCK = 6.62607015e-34  # J s (exact, SI 2019)
C_LIGHT = 299792458.0  # m / s (exact)
DIAGNOSTIC_BANDS = ("V",)
_UNIT_TO_ANGSTROM = {"angstrom": 1.0, "nm": 10.0, "um": 1.0e4}


@dataclass(frozen=True)
class Band:
    """One band: speclite response plus provenance."""

    name: str
    wavelength_angstrom: np.ndarray
    throughput: np.ndarray
    origin: str  # "parametric", "file:<path>", or "speclite:<name>"

    @cached_property
    def response(self):
        """The band's speclite ``FilterResponse`` (wavelengths in Angstrom)."""
        return _speclite_response(
            self.name, self.origin, tuple(self.wavelength_angstrom), tuple(self.throughput)
        )

    @cached_property  # an astropy unit conversion: too slow for every evaluation
    def ab_zero_point_photons_s_m2(self) -> float:
        """Photon rate of a 0 mag (AB) point source through this band, photons s-1 m-2."""
        return float(self.response.ab_zeropoint.to_value("1 / (s m2)"))

    def photon_rate(self, wavelength_angstrom: np.ndarray, flam_w_m2_um: np.ndarray) -> np.ndarray:
        """Integral of F_lambda T(lambda) lambda / (h c) d lambda, photons s-1 m-2 (per sr if F is).

        ``flam_w_m2_um`` may have leading axes; the last axis matches ``wavelength_angstrom``.

        Parameters
        ----------
        wavelength_angstrom : ndarray
            Wavelength grid, Angstrom.
        flam_w_m2_um : ndarray
            Spectral irradiance F_lambda, W m-2 um-1 (per sr for a radiance), last axis over
            ``wavelength_angstrom``.
        """
        wl = np.asarray(wavelength_angstrom, dtype=float)
        t = np.interp(wl, self.wavelength_angstrom, self.throughput, left=0.0, right=0.0)
        integrand = np.asarray(flam_w_m2_um) * t * (wl * 1e-10) / (H_PLANCK * C_LIGHT)  # per um
        return np.trapezoid(integrand, wl * 1e-4, axis=-1)

    def ab_magnitude(self, wavelength_angstrom: np.ndarray, flam_w_m2_um: np.ndarray) -> np.ndarray:
        """AB magnitude of a spectrum (photon-weighted, as speclite and the SDSS/Gaia systems).

        Parameters
        ----------
        wavelength_angstrom : ndarray
            Wavelength grid, Angstrom.
        flam_w_m2_um : ndarray
            Spectral irradiance F_lambda, W m-2 um-1, last axis over ``wavelength_angstrom``.
        """
        rate = self.photon_rate(wavelength_angstrom, flam_w_m2_um)
        with np.errstate(divide="ignore"):
            return -2.5 * np.log10(rate / self.ab_zero_point_photons_s_m2)

    @property
    def pivot_wavelength_nm(self) -> float:
        """Pivot wavelength sqrt(int T lambda dlambda / int T / lambda dlambda), nm."""
        wl, t = self.wavelength_angstrom, self.throughput
        return float(np.sqrt(np.trapezoid(t * wl, wl) / np.trapezoid(t / wl, wl)) / 10.0)


@lru_cache(maxsize=64)
def _speclite_response(name, origin, wavelength, throughput):
    import astropy.units as u
    import speclite.filters as sf

    if origin.startswith("speclite:"):
        return sf.load_filter(origin.split(":", 1)[1])
    return sf.FilterResponse(
        wavelength=np.asarray(wavelength) * u.Angstrom,
        response=np.asarray(throughput),
        meta=dict(group_name="straylight", band_name=name.replace("-", "_")),
    )


def parametric_curve(wavelength_min_nm, wavelength_max_nm, peak, edge_width_nm, step_nm=0.5):
    """Flat-topped throughput with erf edges; zero at both ends of the returned grid.

    Parameters
    ----------
    wavelength_min_nm : float
        The band's blue edge (half maximum), nm.
    wavelength_max_nm : float
        The band's red edge (half maximum), nm.
    peak : float
        The throughput on the flat top, dimensionless.
    edge_width_nm : float
        The 10-90 % rise of each erf edge, nm.
    step_nm : float, optional
        The grid's step, nm (default 0.5).
    """
    if not (0 < peak <= 1):
        raise ConfigError(f"peak_throughput = {peak}: must be in (0, 1]")
    w = edge_width_nm / (2 * 0.9061938)  # erf: 10-90 % rise over 2 * 0.906 w * sqrt(2)/sqrt(2)
    lo = wavelength_min_nm - 6 * edge_width_nm
    hi = wavelength_max_nm + 6 * edge_width_nm
    wl_nm = np.arange(lo, hi + step_nm, step_nm)
    t = 0.5 * peak * (erf((wl_nm - wavelength_min_nm) / w) - erf((wl_nm - wavelength_max_nm) / w))
    t[0] = t[-1] = 0.0
    return wl_nm * 10.0, np.clip(t, 0.0, 1.0)


def read_throughput_file(
    path: str | Path, wavelength_unit: str = "angstrom"
) -> tuple[np.ndarray, np.ndarray]:
    """Read a measured throughput curve; validate it; return (wavelength_angstrom, throughput).

    Accepts CSV (first two numeric columns, or columns named like wavelength/throughput),
    ECSV and FITS tables (columns WAVELENGTH and SENSITIVITY/THROUGHPUT, case-insensitive).

    Parameters
    ----------
    path : str or pathlib.Path
        The throughput file (CSV, ECSV, FITS).
    wavelength_unit : str, optional
        The file's wavelength unit, an astropy unit name (default ``"angstrom"``).
    """
    from astropy.table import Table

    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: throughput file does not exist")
    try:
        if path.suffix.lower() in (".fits", ".fit", ".fz"):
            tab = Table.read(path, hdu=1)
        elif path.suffix.lower() == ".ecsv":
            tab = Table.read(without_bom(path), format="ascii.ecsv")
        else:
            tab = Table.read(without_bom(path), format="ascii.csv", comment="#")
    except Exception as exc:
        raise InputError(f"{path}: cannot read throughput table ({exc})") from exc
    names = {n.lower(): n for n in tab.colnames}
    wl_col = next((names[k] for k in names if k.startswith("wave") or k.startswith("lam")), None)
    t_col = next(
        (names[k] for k in names if any(s in k for s in ("sens", "through", "trans", "response"))), None
    )
    if wl_col is None or t_col is None:
        if len(tab.colnames) < 2:
            raise InputError(f"{path}: needs a wavelength and a throughput column, found {tab.colnames}")
        wl_col, t_col = tab.colnames[:2]
    wl = np.asarray(tab[wl_col], dtype=float) * _UNIT_TO_ANGSTROM[wavelength_unit]
    t = np.asarray(tab[t_col], dtype=float)
    if wl.size < 3:
        raise InputError(f"{path}: only {wl.size} rows; a throughput curve needs at least 3")
    bad = ~np.isfinite(wl) | ~np.isfinite(t)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(
            f"{path}: row {i}: non-finite value ({tab[wl_col][i]}, {tab[t_col][i]}) in {wl_col}/{t_col}"
        )
    if np.any(t < 0) or np.any(t > 1):
        i = int(np.flatnonzero((t < 0) | (t > 1))[0])
        raise InputError(f"{path}: {t_col} = {t[i]} at row {i}: throughput must be within [0, 1]")
    if np.any(np.diff(wl) <= 0):
        i = int(np.flatnonzero(np.diff(wl) <= 0)[0])
        raise InputError(
            f"{path}: {wl_col} not strictly increasing at row {i + 1} ({wl[i]} then {wl[i + 1]})"
        )
    if not (1000.0 <= wl[0] and wl[-1] <= 30000.0):
        raise InputError(
            f"{path}: wavelengths {wl[0]:.4g}-{wl[-1]:.4g} A are outside 1000-30000 A; "
            f"is throughput_wavelength_unit ({wavelength_unit}) right?"
        )
    # speclite requires zero response at both ends
    wl = np.concatenate([[wl[0] - 1.0], wl, [wl[-1] + 1.0]])
    t = np.concatenate([[0.0], t, [0.0]])
    return wl, t


def aperture_area_m2(instrument: InstrumentSettings | dict) -> float:
    """Unobstructed collecting area pi D^2 / 4 of the instrument's telescope, m2.
    ``instrument``: its typed settings, or its mapping
    (:func:`~straylight.config.instrument.instrument_settings`).

    Parameters
    ----------
    instrument : InstrumentSettings or dict
        The instrument's typed settings, or its mapping.
    """
    return float(np.pi * instrument_settings(instrument).telescope.aperture_diameter_m.value ** 2 / 4.0)


def zero_point_ab_mag(band: Band, aperture_area_m2_: float) -> float:
    """AB magnitude of a point source giving 1 e-/s through ``band`` and the aperture.

    Parameters
    ----------
    band : Band
        The band.
    aperture_area_m2_ : float
        The collecting area, m2.
    """
    return float(2.5 * np.log10(band.ab_zero_point_photons_s_m2 * aperture_area_m2_))


def load_band(instrument: InstrumentSettings | dict, name: str, instrument_dir: Path | None = None) -> Band:
    """The band ``name`` of an instrument, or a diagnostic band (``V``).  ``instrument``: its
    typed settings, or its mapping (:func:`~straylight.config.instrument.instrument_settings`);
    ``instrument_dir``: the folder a relative ``throughput_file`` is in.

    Parameters
    ----------
    instrument : InstrumentSettings or dict
        The instrument's typed settings, or its mapping.
    name : str
        The band's name (one of the instrument's, or ``"V"``).
    instrument_dir : pathlib.Path, optional
        The folder a relative ``throughput_file`` is in.
    """
    if name == "V":
        import speclite.filters as sf

        f = sf.load_filter("bessell-V")
        return Band("V", np.asarray(f.wavelength), np.asarray(f.response), "speclite:bessell-V")
    inst = instrument_settings(instrument)
    bands = inst.bands
    if name not in bands:
        raise InputError(f"unknown band {name!r}; known: {', '.join(list(bands) + list(DIAGNOSTIC_BANDS))}")
    b = bands[name]
    if b.throughput_file:
        p = Path(b.throughput_file)
        if not p.is_absolute() and instrument_dir is not None:
            p = instrument_dir / p
        wl, t = read_throughput_file(p, b.throughput_wavelength_unit)
        origin = f"file:{p}"
    else:
        if b.peak_throughput is None:
            raise ConfigError(f"bands.{name}: give peak_throughput (parametric model) or throughput_file")
        wl, t = parametric_curve(b.wavelength_min_nm, b.wavelength_max_nm, b.peak_throughput, b.edge_width_nm)
        origin = "parametric"
    offset = b.zero_point_offset_mag.value if b.zero_point_offset_mag is not None else 0.0
    if b.zero_point_ab_mag is None and offset == 0.0:
        return Band(name, wl, t, origin)
    # the curve's shape, scaled so that its AB zero point is the given one plus the offset
    own_zp = zero_point_ab_mag(Band(name, wl, t, origin), aperture_area_m2(inst))
    target = (own_zp if b.zero_point_ab_mag is None else b.zero_point_ab_mag) + offset
    scale = 10.0 ** (0.4 * (target - own_zp))
    if not 0 < scale * t.max() <= 1:
        raise ConfigError(
            f"bands.{name}: an AB zero point of {target:.3f} (zero_point_ab_mag plus "
            f"zero_point_offset_mag) needs a peak throughput of {scale * t.max():.3g} (the curve's "
            f"own zero point is {own_zp:.3f}); it must be within (0, 1]"
        )
    return Band(name, wl, t * scale, f"{origin} scaled to AB zero point {target:.3f}")
