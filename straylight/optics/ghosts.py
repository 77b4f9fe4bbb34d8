"""Second-order ghosts between the filter and the detector (seed paper sect. 4.3, eqs. 10-13).

Three paths, from nearest to farthest from the nominal image:
  1. filter back surface -> filter front surface:   Phi_1 = Phi T1 T2 R1 R2,    r_1 = 2 D1 u / n
  2. detector -> filter back surface:                Phi_2 = Phi T1 T2 Rd R2,    r_2 = 2 D2 u
  3. detector -> filter front surface:               Phi_3 = Phi T1 T2^3 R1 Rd,  r_3 = 2 u (D1/n + D2)
Centres, with the chief-ray inclinations theta_x, theta_y (small angles):
  x_1 = x_0 + 2 D1 theta_x / n,  x_2 = x_0 + 2 D2 theta_x,  x_3 = x_0 + 2 D1 theta_x / n + 2 D2 theta_x
Each ghost is a uniform disc (the paper's circ function) of irradiance Phi_k / (pi r_k^2).

Phi is the star's energy incident on the filter; the nominal image receives Phi T1 T2.  A star's
detected rate (its AB magnitude through the band's total throughput, which includes the filter)
is therefore Phi T1 T2 QE, and the ghosts of that rate are Phi_k / (Phi T1 T2) of it:
R1 R2, Rd R2 and T2^2 R1 Rd (:meth:`GhostModel.energy_relative_to_image`).  Multiplying the
detected rate by Phi_k / Phi would count the filter's transmission twice.

Lengths here are in mm on the detector; ``pixel_size_mm`` converts to pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from straylight.config import InstrumentSettings, instrument_settings, needed
from straylight.errors import ConfigError, InputError

__all__ = ["GhostModel", "ghost_model_from_instrument"]


@dataclass(frozen=True)
class GhostModel:
    """The filter-detector ghosts of one band (module doc; paper eqs. 10-13): the filter's
    thickness ``d1_mm`` and its back surface's distance to the detector ``d2_mm`` (mm), its
    refractive index ``n``, the marginal-ray angle on the detector ``u_rad`` (rad), the filter's
    surface reflectances ``r1``, ``r2`` and transmissions ``t1``, ``t2`` and the detector's
    reflectance ``rd`` (each 0-1)."""

    d1_mm: float  # filter thickness
    d2_mm: float  # filter back surface to detector
    n: float  # filter refractive index
    u_rad: float  # marginal-ray angle on the detector
    r1: float
    r2: float
    t1: float
    t2: float
    rd: float

    def __post_init__(self):
        for k in ("d1_mm", "d2_mm", "n"):
            if not getattr(self, k) > 0:
                raise ConfigError(f"ghosts: {k} = {getattr(self, k)} must be > 0")
        for k in ("r1", "r2", "t1", "t2", "rd"):
            v = getattr(self, k)
            if not 0 <= v <= 1:
                raise ConfigError(f"ghosts: {k} = {v} must be within [0, 1]")
        if not (np.isfinite(self.u_rad) and self.u_rad >= 0):
            raise ConfigError(f"ghosts: marginal ray angle u = {self.u_rad} must be >= 0")

    def energy_fractions(self) -> np.ndarray:
        """(Phi_1, Phi_2, Phi_3) / Phi, Phi the energy incident on the filter (paper eq. 10)."""
        return np.array(
            [
                self.t1 * self.t2 * self.r1 * self.r2,
                self.t1 * self.t2 * self.rd * self.r2,
                self.t1 * self.t2**3 * self.r1 * self.rd,
            ]
        )

    def energy_relative_to_image(self) -> np.ndarray:
        """(Phi_1, Phi_2, Phi_3) / (Phi T1 T2): each ghost's energy per unit energy of the nominal
        image, i.e. per detected e- of the star (the band throughput already holds T1 T2)."""
        return self.energy_fractions() / (self.t1 * self.t2)

    def radii_mm(self) -> np.ndarray:
        """(r_1, r_2, r_3) in mm."""
        u = self.u_rad
        return np.array(
            [2 * self.d1_mm * u / self.n, 2 * self.d2_mm * u, 2 * u * (self.d1_mm / self.n + self.d2_mm)]
        )

    def centre_offsets_mm(self, theta_x_rad, theta_y_rad) -> np.ndarray:
        """Offsets (3, 2, ...) of the ghost centres from the nominal image, mm.

        Parameters
        ----------
        theta_x_rad : array_like
            The source's field angle along the detector's x axis, rad.
        theta_y_rad : array_like
            The source's field angle along the detector's y axis, rad.
        """
        tx, ty = np.asarray(theta_x_rad, dtype=float), np.asarray(theta_y_rad, dtype=float)
        k = np.array([2 * self.d1_mm / self.n, 2 * self.d2_mm, 2 * self.d1_mm / self.n + 2 * self.d2_mm])
        k = k.reshape((3,) + (1,) * tx.ndim)
        return np.stack([k * tx, k * ty], axis=1)

    def irradiance_relative_to_image_per_mm2(self) -> np.ndarray:
        """Phi_k / (pi r_k^2) / (Phi T1 T2), mm-2: ghost irradiance per unit energy of the
        nominal image (per detected e-/s of the star).  Infinite (a point) when u = 0: refused."""
        r = self.radii_mm()
        if np.any(r <= 0):
            raise InputError(
                "ghosts: the marginal-ray angle u is 0, so every ghost collapses to a point of "
                "infinite irradiance (paper eq. 12); u must be > 0 to render ghosts"
            )
        return self.energy_relative_to_image() / (np.pi * r * r)


def ghost_model_from_instrument(instrument: InstrumentSettings | dict, band: str) -> GhostModel:
    """The ghosts of ``band``: the instrument's ``ghosts`` section and the band's entry in it.
    ``instrument``: its typed settings, or its mapping
    (:func:`~straylight.config.instrument.instrument_settings`).

    Parameters
    ----------
    instrument : InstrumentSettings or dict
        The instrument's typed settings, or its mapping.
    band : str
        The band's name.
    """
    g = needed(instrument_settings(instrument).ghosts, "ghosts")
    per = g.per_band.get(band)
    if per is None:
        raise ConfigError(f"ghosts.per_band has no entry for band {band!r}")
    return GhostModel(
        d1_mm=g.filter_thickness_mm.value,
        d2_mm=g.filter_detector_distance_mm.value,
        n=g.filter_refractive_index.value,
        u_rad=g.marginal_ray_angle_rad.value,
        r1=per.R1,
        r2=per.R2,
        t1=per.T1,
        t2=per.T2,
        rd=per.Rd,
    )
