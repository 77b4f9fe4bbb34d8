"""The moonlit Earth's look-up table, read and interpolated at samples.

The moonlit-Earth coefficients are bounded
(:meth:`~straylight.sources.earthshine_table.EarthshineLUT.moon_bound`: the cap fully lit, PST at
its azimuthal maximum, door fully open), skipped where the bound is below their share of the
tolerance, and elsewhere taken from a table of their own (:class:`MoonlitLUT`), which runs over
one angle more than the sunlit Earth's, the telescope's roll: it is set by the Sun, not by the
Moon.  The table is interpolated as the sunlit Earth's is
(:mod:`straylight.sources.earthshine_table_lookup`); it is built with the coarse Earth-cap grid,
validated against the direct sum and cached by :mod:`straylight.sources.moonlit_table_build`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from straylight.sources.earthshine_table_lookup import (
    _asinh_grids,
    _beyond_dark_zenith,
    _dark_lamp_zenith_deg,
    _lamp_coordinates,
    _load_tables,
    _per_door_state,
    _save_tables,
)

__all__ = ["MoonlitLUT"]


@dataclass
class MoonlitLUT:
    """The moonlit Earth's coefficients (direct and via the door, per unit lunar irradiance at
    the Earth, outside the field) on the coarse Earth-cap ``grid`` the direct path sums
    (models.earthshine.moonlit_grid), tabulated over (Moon zenith, line-of-sight zenith,
    azimuth from the Moon, roll) per door state and interpolated linearly in asinh(c / scale).
    The satellite's radius and the Moon's distance are fixed at the orbit's mean and the
    Moon's mean; the validation draws both over their ranges.  Built and validated by
    :func:`~straylight.sources.earthshine_table_build.build_moonlit_lut`."""

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

    def _interpolators(self):
        if not hasattr(self, "_interp"):
            axes = (self.moon_zenith_deg, self.los_zenith_deg, self.azimuth_deg, self.roll_deg)
            self._interp = _asinh_grids(axes, self.direct, self.door, self.scale)
        return self._interp

    @cached_property
    def dark_moon_zenith_deg(self) -> float:
        """The Moon zenith angle beyond which the table is 0, deg (:func:`_dark_lamp_zenith_deg`)."""
        return _dark_lamp_zenith_deg(
            self.moon_zenith_deg, (*self.direct.values(), *self.door.values()), axis=0
        )

    def dark_runs(self, rows) -> np.ndarray:
        """Per run of ``rows`` (scene runs of (satellite, Moon)): no moonlit Earth in view, the
        table 0 (beyond :attr:`dark_moon_zenith_deg`).

        Parameters
        ----------
        rows : SceneRuns
            Scene runs of (satellite, Moon) positions, km.

        Returns
        -------
        ndarray of bool, shape (runs,)
        """
        return _beyond_dark_zenith(rows, self.dark_moon_zenith_deg)

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

    def save(self, path) -> None:
        """Write the table to ``path``.

        Parameters
        ----------
        path : str or Path
            The .npz file, written atomically (its axes, one direct and one door table per door
            state, and the metadata as JSON).
        """
        _save_tables(
            path,
            {
                "moon_zenith_deg": self.moon_zenith_deg,
                "los_zenith_deg": self.los_zenith_deg,
                "azimuth_deg": self.azimuth_deg,
                "roll_deg": self.roll_deg,
            },
            self.direct,
            self.door,
            {
                "symmetric": self.symmetric,
                "scale": self.scale,
                "grid": list(self.grid),
                "validation_max_rel_error": self.validation_max_rel_error,
                "build_seconds": self.build_seconds,
            },
        )

    @classmethod
    def load(cls, path) -> "MoonlitLUT":
        """Read a table :meth:`save` wrote.

        Parameters
        ----------
        path : str or Path
            A .npz file :meth:`save` wrote.

        Returns
        -------
        MoonlitLUT

        Raises
        ------
        InputError
            When the file cannot be read or is not such a table.
        """
        z, meta, direct, door = _load_tables(path, "moonlit-Earth")
        return cls(
            z["moon_zenith_deg"],
            z["los_zenith_deg"],
            z["azimuth_deg"],
            z["roll_deg"],
            direct,
            door,
            bool(meta["symmetric"]),
            float(meta["scale"]),
            tuple(meta["grid"]),
            float(meta["validation_max_rel_error"]),
            float(meta["build_seconds"]),
        )
