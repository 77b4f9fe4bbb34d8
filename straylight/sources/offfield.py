"""The off-field transfer every source outside the field goes through (seed paper sects. 2.2,
3.1-3.2): :class:`OffFieldModel`.  The Earth's grid over it is the earthshine's
(:class:`~straylight.sources.earthshine.engine.EarthGrid`).

Point sources (paper eq. 14):  E_p = sum_i E_i Se_i Sp_i PST(theta_i, phi_i), with E_i the band
photon irradiance at the aperture (photons s-1 m-2), Se_i = 0 when the Earth hides the source
(two-condition test), Sp_i the door's unshaded fraction (:mod:`straylight.optics.door`) and PST from
:mod:`straylight.optics.pst`.  The focal-plane rate is E * PST * (pixel area), with the band's total
throughput (mirrors x filter x QE) turning photons into electrons; the PST is taken as the
geometric transfer.  The sources' brightness laws are with the sources: the Sun, Moon and
planets in :mod:`straylight.sources.bodies`, :mod:`straylight.sources.planets` and
:mod:`straylight.sources.body_magnitudes`, the band photometry in
:mod:`straylight.sources.photometry`, the stars in :mod:`straylight.sources.stars`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from straylight.optics.door import Door, DoorTable, behind_aperture_plane, door_state_index
from straylight.optics.pst import PST
from straylight.util.gridinterp import LinearGrid

__all__ = ["OffFieldModel"]


@dataclass
class OffFieldModel:
    """The off-field transfer of one instrument (PST, door, pixel, field radius): e-/s/pix per
    photon s-1 m-2 at the aperture, band-independent.

    Attributes
    ----------
    pst : PST
        The point source transmittance PST(theta, phi).
    door : Door
        The door's geometry (its Sp tables per state).
    door_states_deg : tuple of float
        The door's allowed openings, deg.
    pixel_area_m2 : float
        Detector pixel area, m2.
    pixel_etendue_m2_sr : float
        Aperture area times pixel solid angle, m2 sr (the Earth seen inside the field).
    field_radius_deg : float
        Radius of the field of view, deg.
    moon_law : str
        The Moon's phase law (:func:`~straylight.sources.body_magnitudes.moon_v_magnitude`).
    moon_eclipse_factor : float
        The eclipsed Moon's brightness over the uneclipsed one's, dimensionless.
    """

    pst: PST
    door: Door
    door_states_deg: tuple[float, ...]
    pixel_area_m2: float
    pixel_etendue_m2_sr: float = 0.0  # pi D^2 / 4 * (p / f)^2, for the Earth seen inside the field
    field_radius_deg: float = 0.59  # radius of the field of view, sqrt(FoV / pi); from the instrument
    moon_law: str = "krisciunas_schaefer"
    moon_eclipse_factor: float = 1e-4

    @cached_property
    def door_tables(self) -> dict[float, DoorTable]:
        """Door state (opening, deg) -> its Sp table over (theta, phi)."""
        return {s: self.door.table(s) for s in self.door_states_deg}

    @cached_property
    def _door_grid(self):
        """(door states ascending, one LinearGrid holding every state's Sp table as a channel):
        the tables share their (theta, phi) nodes, so a batch with mixed door states locates
        its points once."""
        states = np.array(sorted(self.door_tables), float)
        tables = [self.door_tables[s] for s in states]
        for t in tables[1:]:
            if not (
                np.array_equal(t.theta_deg, tables[0].theta_deg)
                and np.array_equal(t.phi_deg, tables[0].phi_deg)
            ):
                raise ValueError("door tables of different states must share their theta and phi nodes")
        return states, LinearGrid(
            (tables[0].theta_deg, tables[0].phi_deg), np.stack([t.values for t in tables], -1)
        )

    def door_factor(self, theta_deg, phi_deg, opening_deg) -> np.ndarray:
        """Sp for each sample's door state; the narrowest state when none is allowed (door 0);
        0 for an opening that is none of the door states.

        Parameters
        ----------
        theta_deg, phi_deg : array_like
            Source directions in the telescope frame (angle from the line of sight, azimuth),
            deg.
        opening_deg : array_like
            Each sample's door opening, deg; broadcast with the angles.

        Returns
        -------
        ndarray
            Sp, the door's unshaded fraction in [0, 1], of the broadcast shape (0 behind the
            aperture plane, theta > 90 deg).
        """
        th, ph, op = np.broadcast_arrays(
            np.asarray(theta_deg, float), np.asarray(phi_deg, float), np.asarray(opening_deg, float)
        )
        states, grid = self._door_grid
        state, known = door_state_index(states, op)
        return np.where(
            known & ~behind_aperture_plane(th), grid(*DoorTable.coordinates(th, ph), channel=state), 0.0
        )

    # -- point sources ----------------------------------------------------------------------
    def point_source(self, irradiance, theta_deg, phi_deg, earth_blocked, opening_deg) -> np.ndarray:
        """e-/s/pix of point sources: E * Se * Sp * PST * pixel area (broadcast arrays); the door
        table is looked up only where the Earth does not hide the source (Se = 1), and the PST
        only where the door lets it in (Sp > 0): the Sun, whose angle sets the door's state,
        gets past the door at ~5 % of a default region's samples.

        A source inside the field (theta <= field_radius_deg) adds nothing here: it is imaged
        as a point source with its own scattering halo and ghosts (:mod:`straylight.image.detector`),
        not spread as a uniform background (PST = 1 over every pixel); it is reported by
        :meth:`~straylight.sources.bodies.InFieldBodies.find`.

        Parameters
        ----------
        irradiance : array_like
            E, the source's photon irradiance at the aperture, photons s-1 m-2 (1: the
            transfer itself).
        theta_deg, phi_deg : array_like
            The source's direction in the telescope frame, deg.
        earth_blocked : array_like of bool
            True where the Earth hides the source (Se = 0).
        opening_deg : array_like
            Each sample's door opening, deg.

        Returns
        -------
        ndarray
            e-/s/pix (per photon s-1 m-2 for ``irradiance`` = 1), of the broadcast shape.
        """
        in_field = np.asarray(theta_deg, float) <= self.field_radius_deg
        th, ph, blocked, op = np.broadcast_arrays(
            theta_deg, phi_deg, np.asarray(earth_blocked, bool) | in_field, opening_deg
        )
        if not np.any(blocked):  # nothing hidden (every star pair): no masked copies
            t = self._door_times_pst(th, ph, op)
        else:
            seen = np.flatnonzero(~blocked)
            t = np.zeros(th.shape)
            if seen.size:
                t.reshape(-1)[seen] = self._door_times_pst(
                    np.take(th, seen), np.take(ph, seen), np.take(op, seen)
                )
        return np.asarray(irradiance) * t * self.pixel_area_m2

    def _door_times_pst(self, theta_deg, phi_deg, opening_deg) -> np.ndarray:
        """Sp * PST (new array), the PST looked up only where the door lets the source in."""
        t = self.door_factor(theta_deg, phi_deg, opening_deg)
        lit = np.flatnonzero(t > 0.0)
        if lit.size == t.size:  # the door hides none (the Moon, mostly; every star pair)
            t *= self.pst(theta_deg, phi_deg)
        elif lit.size:
            flat = t.reshape(-1)
            flat[lit] *= self.pst(np.take(theta_deg, lit), np.take(phi_deg, lit))
        return t
