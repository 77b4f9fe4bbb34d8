"""In-field scattering of bright stars by the mirrors (seed paper sect. 4.2) and the PSF core.

Harvey-Shack BRDF at normal incidence:  BRDF(t) = b0 [1 + (sin t / l)^2]^(s/2)   (sr-1)
Total integrated scatter of one surface:  TIS = 2 pi int_0^{pi/2} BRDF(t) cos t sin t dt.

System BRDF (paper eq. 7).  The paper writes BRDF_t = sum_i BRDF(t R / r_i) / r_i^2 with
E = pi R^2 / f^2 E_i BRDF_t; that is dimensionally consistent when r_i is in units of the
entrance-pupil radius R, so here  BRDF_t(t) = sum_i (R / r_i)^2 BRDF(t R / r_i), which makes the
scattered power of mirror i exactly its TIS (tested).  The focal-plane irradiance from a star of
irradiance E_i at the aperture, at distance d from its image (t = d / f), is
E(d) = pi R^2 / f^2 * E_i * BRDF_t(d / f)   (paper eq. 8).

PSF core: a circular Gaussian whose 80 % encircled-energy radius equals the instrument's
(CSST: 0.15 arcsec).  The paper uses the PSF near the image and the scattering model far from
it, interpolating between; here the scattering halo is multiplied by a smooth cosine taper that
is 0 inside ``core_blend_inner`` and 1 outside ``core_blend_outer``.  The near-field scatter the
taper removes belongs to the PSF, so the core carries 1 - (halo power): the far halo is exactly
the paper's BRDF curve and the star's total power is conserved.

All radial profiles are returned as the fraction of the star's power per unit focal-plane
area (m-2), so a pixel of area p^2 receives profile * p^2 of the star's e-/s.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy import integrate

from straylight.config import InstrumentSettings, instrument_settings, needed
from straylight.errors import ConfigError, InputError

__all__ = [
    "ARCSEC_RAD",
    "GAUSS_EE80_FACTOR",
    "HarveyBRDF",
    "ScatterModel",
    "scatter_model_from_instrument",
    "check_fluxes",
]

ARCSEC_RAD = np.pi / 180.0 / 3600.0
GAUSS_EE80_FACTOR = np.sqrt(2.0 * np.log(5.0))  # r80 = sigma * sqrt(2 ln 5)


@dataclass(frozen=True)
class HarveyBRDF:
    """Harvey-Shack BRDF (sr-1) at normal incidence."""

    b0: float
    l: float  # noqa: E741 - the paper's symbol
    s: float

    def __post_init__(self):
        if not (self.b0 > 0 and self.l > 0 and np.isfinite(self.s)):
            raise ConfigError(
                f"Harvey BRDF parameters b0={self.b0}, l={self.l}, s={self.s}: b0, l must be > 0"
            )
        if self.s >= 0:
            raise ConfigError(f"Harvey BRDF slope s = {self.s}: must be negative (scatter falls with angle)")
        tis = self.tis()
        if not (0 < tis < 1):
            raise ConfigError(
                f"Harvey BRDF b0={self.b0}, l={self.l}, s={self.s} gives TIS = {tis:.3g}; "
                "a mirror cannot scatter more than it receives (TIS must be < 1)"
            )

    def __call__(self, theta_rad) -> np.ndarray:
        """BRDF at scatter angles ``theta_rad`` (rad, any shape), sr-1, of the same shape."""
        t = np.asarray(theta_rad, dtype=float)
        return self.b0 * (1.0 + (np.sin(t) / self.l) ** 2) ** (self.s / 2.0)

    def tis(self, theta_max_rad: float = np.pi / 2) -> float:
        """Total integrated scatter within theta_max (2 pi int BRDF cos sin dtheta).

        Parameters
        ----------
        theta_max_rad : float, optional
            The largest scattering angle integrated over, rad (default pi/2).
        """
        # integrate in u = sin(theta): 2 pi int_0^{umax} b0 (1 + u^2/l^2)^(s/2) u du, analytic
        umax = np.sin(theta_max_rad)
        a = self.s / 2.0 + 1.0
        return float(2 * np.pi * self.b0 * self.l**2 / 2.0 * ((1.0 + (umax / self.l) ** 2) ** a - 1.0) / a)


@dataclass(frozen=True)
class ScatterModel:
    """Star image (PSF core + mirror-scattering halo) on the focal plane."""

    brdf: HarveyBRDF
    mirror_radii_m: tuple[float, ...]
    aperture_radius_m: float
    focal_length_m: float
    ee80_radius_arcsec: float
    blend_inner_arcsec: float
    blend_outer_arcsec: float

    def __post_init__(self):
        if not self.blend_inner_arcsec < self.blend_outer_arcsec:
            raise ConfigError("scattering.core_blend_inner_arcsec must be below core_blend_outer_arcsec")
        if any(r <= 0 for r in self.mirror_radii_m):
            raise ConfigError(f"scattering.mirror_radii_m must be positive, got {self.mirror_radii_m}")
        if self.tis_total >= 1:
            raise ConfigError(f"summed TIS of the mirrors = {self.tis_total:.3f} >= 1")

    @property
    def tis_total(self) -> float:
        """Summed total integrated scatter of the mirrors (each the BRDF's TIS), a fraction of the
        star's power."""
        return len(self.mirror_radii_m) * self.brdf.tis()

    def brdf_system(self, theta_rad) -> np.ndarray:
        """BRDF_t(theta) = sum_i (R / r_i)^2 BRDF(theta R / r_i), sr-1.

        Parameters
        ----------
        theta_rad : array_like
            Scattering angles, rad.
        """
        t = np.asarray(theta_rad, dtype=float)
        out = np.zeros_like(t)
        for r in self.mirror_radii_m:
            k = self.aperture_radius_m / r
            out = out + k * k * self.brdf(np.minimum(t * k, np.pi / 2))
        return out

    def halo_profile_raw(self, d_m) -> np.ndarray:
        """Paper eq. 8 per unit star power: BRDF_t(d / f) / f^2, m-2 (no taper).

        Parameters
        ----------
        d_m : array_like
            Distances from the image's centre on the focal plane, m.
        """
        return self.brdf_system(np.asarray(d_m) / self.focal_length_m) / self.focal_length_m**2

    def _taper(self, d_m):
        d_arcsec = np.asarray(d_m) / self.focal_length_m / ARCSEC_RAD
        x = np.clip(
            (d_arcsec - self.blend_inner_arcsec) / (self.blend_outer_arcsec - self.blend_inner_arcsec), 0, 1
        )
        return 0.5 - 0.5 * np.cos(np.pi * x)

    @cached_property
    def halo_power(self) -> float:
        """Fraction of the star's power in the tapered halo (to 90 deg): sum TIS minus the
        near-field part handed to the core."""
        inner = self.blend_outer_arcsec * ARCSEC_RAD * self.focal_length_m
        tapered, _ = integrate.quad(lambda d: 2 * np.pi * d * self.halo_profile(d), 0, inner, limit=200)
        raw, _ = integrate.quad(lambda d: 2 * np.pi * d * self.halo_profile_raw(d), 0, inner, limit=200)
        return self.tis_total - (raw - tapered)

    def halo_profile(self, d_m) -> np.ndarray:
        """Scattering halo (paper eq. 8) with the near-field taper, per unit star power, m-2.

        Parameters
        ----------
        d_m : array_like
            Distances from the image's centre on the focal plane, m.
        """
        return self.halo_profile_raw(d_m) * self._taper(d_m)

    @property
    def core_sigma_m(self) -> float:
        """Standard deviation of the Gaussian PSF core on the focal plane, m (its EE80 radius over
        sqrt(2 ln 5))."""
        return self.ee80_radius_arcsec / GAUSS_EE80_FACTOR * ARCSEC_RAD * self.focal_length_m

    def core_profile(self, d_m) -> np.ndarray:
        """Gaussian core carrying 1 - halo_power, m-2.

        Parameters
        ----------
        d_m : array_like
            Distances from the image's centre on the focal plane, m.
        """
        s = self.core_sigma_m
        return (1.0 - self.halo_power) * np.exp(-0.5 * (np.asarray(d_m) / s) ** 2) / (2 * np.pi * s * s)

    def profile(self, d_m) -> np.ndarray:
        """Star image: core + halo, fraction of the star's power per m2.

        Parameters
        ----------
        d_m : array_like
            Distances from the image's centre on the focal plane, m.
        """
        return self.core_profile(d_m) + self.halo_profile(d_m)

    def halo_energy_within(self, d_max_m: float) -> float:
        """Fraction of the star's power in the halo within radius d_max (numerical).

        Parameters
        ----------
        d_max_m : float
            Radius on the focal plane, m.
        """
        inner = min(d_max_m, self.blend_outer_arcsec * ARCSEC_RAD * self.focal_length_m)
        e_in, _ = integrate.quad(lambda d: 2 * np.pi * d * self.halo_profile(d), 0, inner, limit=200)
        if d_max_m <= inner:
            return e_in
        # analytic beyond the taper: each mirror's halo within angle t is TIS(t R / r_i)
        t_in, t_out = inner / self.focal_length_m, d_max_m / self.focal_length_m
        e_out = sum(
            self.brdf.tis(min(t_out * self.aperture_radius_m / r, np.pi / 2))
            - self.brdf.tis(min(t_in * self.aperture_radius_m / r, np.pi / 2))
            for r in self.mirror_radii_m
        )
        return e_in + e_out


def scatter_model_from_instrument(instrument: InstrumentSettings | dict) -> ScatterModel:
    """The instrument's star image: its ``scattering`` section, aperture, focal length and EE80
    radius.  ``instrument``: its typed settings, or its mapping
    (:func:`~straylight.config.instrument.instrument_settings`).

    Parameters
    ----------
    instrument : InstrumentSettings or dict
        The instrument's typed settings, or its mapping.
    """
    inst = instrument_settings(instrument)
    sc = needed(inst.scattering, "scattering")
    return ScatterModel(
        brdf=HarveyBRDF(sc.harvey_b0.value, sc.harvey_l.value, sc.harvey_s.value),
        mirror_radii_m=tuple(r.value for r in sc.mirror_radii_m),
        aperture_radius_m=inst.telescope.aperture_diameter_m.value / 2.0,
        focal_length_m=inst.telescope.focal_length_m.value,
        ee80_radius_arcsec=inst.detector.ee80_radius_arcsec.value,
        blend_inner_arcsec=sc.core_blend_inner_arcsec.value,
        blend_outer_arcsec=sc.core_blend_outer_arcsec.value,
    )


def check_fluxes(fluxes, name="star flux") -> np.ndarray:
    """Star fluxes as a float array, checked finite and >= 0.

    Parameters
    ----------
    fluxes : array_like
        Star fluxes, e-/s (any shape).
    name : str
        What the fluxes are, for the error message.

    Returns
    -------
    ndarray
        ``fluxes`` as float64, same shape, e-/s.

    Raises
    ------
    InputError
        For a non-finite or negative flux (naming its row).
    """
    f = np.asarray(fluxes, dtype=float)
    if not np.all(np.isfinite(f)):
        i = int(np.flatnonzero(~np.isfinite(f))[0])
        raise InputError(f"{name}: row {i} is {f.ravel()[i]!r}; fluxes must be finite")
    if np.any(f < 0):
        i = int(np.flatnonzero(f < 0)[0])
        raise InputError(f"{name}: row {i} is {f.ravel()[i]!r}; fluxes must be >= 0")
    return f
