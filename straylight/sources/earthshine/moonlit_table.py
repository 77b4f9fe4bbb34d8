"""The moonlit Earth's look-up table, read and interpolated at samples.

The moonlit-Earth coefficients are bounded
(:meth:`~straylight.sources.earthshine.sunlit_table.EarthshineLUT.moon_bound`: the cap fully lit, PST at
its azimuthal maximum, door fully open), skipped where the bound is below their share of the
tolerance, and elsewhere taken from a table of their own (:class:`MoonlitLUT`), which runs over
one angle more than the sunlit Earth's, the telescope's roll: it is set by the Sun, not by the
Moon.  The table is interpolated as the sunlit Earth's is
(:mod:`straylight.sources.earthshine.lookup`); it is built with the coarse Earth-cap grid,
validated against the direct sum and cached by :mod:`straylight.sources.earthshine.moonlit_build`;
its file and dark runs are :class:`~straylight.sources.earthshine.table.LampTable`'s.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from straylight.sources.earthshine.lookup import _asinh_grids, _lamp_coordinates, _per_door_state
from straylight.sources.earthshine.table import LampTable

__all__ = ["MoonlitLUT"]


@dataclass
class MoonlitLUT(LampTable):
    """The moonlit Earth's coefficients (direct and via the door, per unit lunar irradiance at
    the Earth, outside the field) on the coarse Earth-cap ``grid`` the direct path sums
    (models.earthshine.moonlit_grid), tabulated over (Moon zenith, line-of-sight zenith,
    azimuth from the Moon, roll) per door state and interpolated linearly in asinh(c / scale).
    The satellite's radius and the Moon's distance are fixed at the orbit's mean and the
    Moon's mean; the validation draws both over their ranges.  Built and validated by
    :func:`~straylight.sources.earthshine.sunlit_build.build_moonlit_lut`."""

    moon_zenith_deg: np.ndarray
    los_zenith_deg: np.ndarray
    azimuth_deg: np.ndarray
    roll_deg: np.ndarray
    direct: dict  # door state -> (Zm, L, A, P)
    door: dict
    symmetric: bool
    scale: float
    grid: tuple
    validation_max_rel_error: float = float("nan")
    build_seconds: float = float("nan")

    FILE_ARRAYS = ("moon_zenith_deg", "los_zenith_deg", "azimuth_deg", "roll_deg")
    FILE_META = {
        "symmetric": bool,
        "scale": float,
        "grid": tuple,
        "validation_max_rel_error": float,
        "build_seconds": float,
    }
    WHAT = "moonlit-Earth"
    DARK_ZENITH = "dark_moon_zenith_deg"

    def _interpolators(self):
        if not hasattr(self, "_interp"):
            axes = (self.moon_zenith_deg, self.los_zenith_deg, self.azimuth_deg, self.roll_deg)
            self._interp = _asinh_grids(axes, self.direct, self.door, self.scale)
        return self._interp

    @cached_property
    def dark_moon_zenith_deg(self) -> float:
        """The Moon zenith angle beyond which the table is 0, deg (every node from there on is 0)."""
        return self._dark_zenith_deg(self.moon_zenith_deg, axis=0)

    def coordinates(self, sat_km, moon_km, frame, runs=None):
        """(Moon zenith, line-of-sight zenith, azimuth from the Moon, roll) of samples, deg;
        ``runs``: the samples' scene runs when known.

        Parameters
        ----------
        sat_km, moon_km : ndarray, shape (..., 3)
            Geocentric ICRS positions of the satellite and the Moon, km.
        frame : TelescopeFrame
            The samples' telescope frames, axes (..., 3).
        runs : SceneRuns, optional
            The samples' scene runs; None: found here.

        Returns
        -------
        z_moon_deg, zeta_deg, azimuth_deg, roll_deg : ndarray, shape (...)
            Angles, deg.
        """
        return _lamp_coordinates(sat_km, moon_km, frame.z, self.symmetric, (frame.x, frame.y), runs)[1:]

    def coefficients(self, sat_km, moon_km, frame, opening_deg, runs=None):
        """(direct_moon, door_moon) per unit lunar irradiance at the Earth, outside the field;
        ``runs``: the samples' scene runs when known.

        Parameters
        ----------
        sat_km, moon_km : ndarray, shape (..., 3)
            Geocentric ICRS positions of the satellite and the Moon, km.
        frame : TelescopeFrame
            The samples' telescope frames, axes (..., 3).
        opening_deg : array_like
            Each sample's door opening, deg.
        runs : SceneRuns, optional
            The samples' scene runs; None: found here.

        Returns
        -------
        direct_moon, door_moon : ndarray, shape (...)
            e-/s/pix per photon s-1 m-2 of the Moon at the Earth, >= 0.
        """
        zm, zeta, a, roll = self.coordinates(sat_km, moon_km, frame, runs)
        shape = zm.shape
        return _per_door_state(
            self._interpolators(), [v.ravel() for v in (zm, zeta, a, roll)], opening_deg, shape, self.scale
        )
