"""The off-field transfer every source outside the field goes through (seed paper sects. 2.2,
3.1-3.2), and the Earth-grid sum of earthshine.

Point sources (paper eq. 14):  E_p = sum_i E_i Se_i Sp_i PST(theta_i, phi_i), with E_i the band
photon irradiance at the aperture (photons s-1 m-2), Se_i = 0 when the Earth hides the source
(two-condition test), Sp_i the door's unshaded fraction (:mod:`straylight.optics.door`) and PST from
:mod:`straylight.optics.pst`.  The focal-plane rate is E * PST * (pixel area), with the band's total
throughput (mirrors x filter x QE) turning photons into electrons; the PST is taken as the
geometric transfer.  The sources' brightness laws are with the sources: the Sun, Moon and
planets in :mod:`straylight.sources.bodies`, the band photometry in
:mod:`straylight.sources.photometry`, the stars in :mod:`straylight.sources.stars`.

Earthshine (paper sect. 3.2): the Earth cap seen from the satellite is split into n_gamma x
n_psi blocks of solid angle sin(gamma) dgamma dpsi about nadir; each is a Lambertian reflector of
albedo A lit by the Sun (radiance A/pi E_sun cos z_sun) or, on the night side, by the Moon.
EA1 = sum E_i Sp_i PST(theta_i, phi_i) (direct; Sp = 0 behind the aperture plane, theta > 90
deg).  EA2 (door): each door block receives MP_i = sum_b L_b dOmega_b cos(incidence) from the
Earth blocks in front of its inner face whose ray to it misses the telescope body
(:meth:`OffFieldModel.door_lit_fraction`) and re-emits as a Lambertian of reflectance r; the
aperture points j receive L_door A_i cos(e_ij) / d_ij^2 with PST(theta_ij, phi_ij), averaged
over the aperture.  This is the paper's EA2 = sum_i MP_i r sum_j PST(theta_ij, phi_ij) / d_ij^2
with the block area, the emission cosine and 1/pi written out.  The sunlit and moonlit Earth's sources
(:mod:`straylight.sources.sunlit_earth`, :mod:`straylight.sources.moonlit_earth`) call this sum or
its tables (:mod:`straylight.sources.earthshine_table`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from straylight.errors import ConfigError
from straylight.optics.door import Door, DoorTable, behind_aperture_plane, door_state_index
from straylight.optics.pst import PST
from straylight.sky.runs import rows_at, scene_rows, shared_vectors
from straylight.sky.vectors import dot, norm, perpendicular_towards, unit, wrap_360_deg
from straylight.util.gridinterp import LinearGrid


@dataclass
class EarthshineSettings:
    """The Earth grid of the earthshine sum and the Earth's and door's reflection.

    Attributes
    ----------
    n_gamma : int
        Nadir-angle blocks of the visible cap (>= 2).
    n_psi : int
        Azimuth blocks (>= 4).
    albedo : float
        The Earth's grey Lambertian albedo, in [0, 1].
    door_blocks : tuple of (int, int)
        Blocks along and across the door plate.
    door_reflectance : float
        The door's inner face's Lambertian reflectance, in [0, 1].
    n_aperture_door : int
        Aperture points for the door-to-aperture path.

    Raises
    ------
    ConfigError
        When the grid is too coarse or the albedo or reflectance is outside [0, 1].
    """

    n_gamma: int = 24  # nadir-angle blocks of the visible cap
    n_psi: int = 48  # azimuth blocks
    albedo: float = 0.30
    door_blocks: tuple[int, int] = (24, 24)  # along x across the door plate
    door_reflectance: float = 0.05
    n_aperture_door: int = 256  # aperture points for the door-to-aperture path (128: 0.5 % of the total off)

    def __post_init__(self):
        if self.n_gamma < 2 or self.n_psi < 4:
            raise ConfigError(
                f"earthshine grid {self.n_gamma} x {self.n_psi}: needs n_gamma >= 2, n_psi >= 4"
            )
        if not 0 <= self.albedo <= 1:
            raise ConfigError(f"earthshine albedo = {self.albedo}: must be within [0, 1]")
        if not 0 <= self.door_reflectance <= 1:
            raise ConfigError(f"door reflectance = {self.door_reflectance}: must be within [0, 1]")


@dataclass
class OffFieldModel:
    """The off-field transfer of one instrument (PST, door, pixel, field radius) and its Earth
    grid: e-/s/pix per photon s-1 m-2 at the aperture, band-independent.

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
    earthshine : EarthshineSettings
        The Earth grid, albedo and door reflection.
    moon_law : str
        The Moon's phase law (:func:`~straylight.sources.bodies.moon_v_magnitude`).
    moon_eclipse_factor : float
        The eclipsed Moon's brightness over the uneclipsed one's, dimensionless.
    """

    pst: PST
    door: Door
    door_states_deg: tuple[float, ...]
    pixel_area_m2: float
    pixel_etendue_m2_sr: float = 0.0  # pi D^2 / 4 * (p / f)^2, for the Earth seen inside the field
    field_radius_deg: float = 0.59  # radius of the field of view, sqrt(FoV / pi); from the instrument
    earthshine: EarthshineSettings = field(default_factory=EarthshineSettings)
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

    # -- earthshine -------------------------------------------------------------------------
    @staticmethod
    def _cap_nadir_angles(sat_km, earth_radius_km, s: EarthshineSettings):
        """The cap grid's nadir angles gamma and their widths (rad, (..., G)): packed towards
        the limb, where the Earth lies closest to an allowed line of sight and the terminator
        crosses it: gamma = rho sin(pi u / 2), u uniform."""
        return OffFieldModel._cap_nadir_angles_at(norm(sat_km), earth_radius_km, s)

    @staticmethod
    def _cap_nadir_angles_at(radius_km, earth_radius_km, s: EarthshineSettings):
        """:meth:`_cap_nadir_angles` of satellites at ``radius_km`` from the Earth's centre."""
        rho = np.arcsin(np.clip(earth_radius_km / radius_km, 0, 1))
        u = (np.arange(s.n_gamma) + 0.5) / s.n_gamma
        gamma = rho[..., None] * np.sin(0.5 * np.pi * u)
        dgamma = rho[..., None] * 0.5 * np.pi * np.cos(0.5 * np.pi * u) / s.n_gamma
        return gamma, dgamma

    def _cap_axes(self, sat_km, earth_radius_km, s: EarthshineSettings):
        """The cap grid's frame and nodes: nadir, e1, e2 (..., 3); gamma, dgamma (..., G);
        cos and sin of gamma (..., G, 1, 1) and of the block-centre azimuths psi (P, 1)."""
        nadir = -unit(sat_km)
        e1 = perpendicular_towards(nadir, np.broadcast_to(np.array([0.0, 0.0, 1.0]), nadir.shape))
        e2 = np.cross(nadir, e1)
        gamma, dgamma = self._cap_nadir_angles(sat_km, earth_radius_km, s)  # (..., G)
        psi = (np.arange(s.n_psi) + 0.5) * 2 * np.pi / s.n_psi
        cg, sg = np.cos(gamma)[..., :, None, None], np.sin(gamma)[..., :, None, None]
        cp, spp = np.cos(psi)[:, None], np.sin(psi)[:, None]
        return nadir, e1, e2, gamma, dgamma, cg, sg, cp, spp

    def _cap_grid(self, sat_km, earth_radius_km, s: EarthshineSettings):
        """Block directions (..., G, P, 3), solid angles, surface points for each sample."""
        nadir, e1, e2, gamma, dgamma, cg, sg, cp, spp = self._cap_axes(sat_km, earth_radius_km, s)
        d = cg * nadir[..., None, None, :] + sg * (cp * e1[..., None, None, :] + spp * e2[..., None, None, :])
        d_omega = (np.sin(gamma) * dgamma)[..., :, None] * (2 * np.pi / s.n_psi)
        rr = norm(sat_km)[..., None]  # (..., 1)
        t = rr * np.cos(gamma) - np.sqrt(np.maximum(earth_radius_km**2 - (rr * np.sin(gamma)) ** 2, 0))
        points = sat_km[..., None, None, :] + t[..., :, None, None] * d
        return d, np.broadcast_to(d_omega, d.shape[:-1]), points

    def _cap_block_spans(self, sat_km, earth_radius_km, s: EarthshineSettings):
        """Each cap block's extent as two vectors (..., G, P, 3): the change of its direction
        across the block in nadir angle (d(dir)/d(gamma) dgamma) and in azimuth (d(dir)/d(psi)
        dpsi), for :meth:`front_fraction`."""
        nadir, e1, e2, gamma, dgamma, cg, sg, cp, spp = self._cap_axes(sat_km, earth_radius_km, s)
        horiz = cp * e1[..., None, None, :] + spp * e2[..., None, None, :]
        span_gamma = (-sg * nadir[..., None, None, :] + cg * horiz) * dgamma[..., :, None, None]
        span_psi = sg * (-spp * e1[..., None, None, :] + cp * e2[..., None, None, :]) * (2 * np.pi / s.n_psi)
        return span_gamma, span_psi

    @staticmethod
    def front_fraction(cos_theta, span_gamma_z, span_psi_z) -> np.ndarray:
        """The fraction of a cap block in front of the aperture plane (cos theta > 0), from its
        centre's cos theta and the change of cos theta across it in nadir angle and in azimuth
        (its spans' z components): linear between the block wholly behind (0) and wholly in
        front (1).  The aperture plane cuts the blocks near theta = 90 deg, where Sp steps to 0;
        resolving the cut within the block keeps the Earth grid's sum converged there (a block
        counted whole or not at all made the 24 x 48 grid's sum 4-10 % off 85-88 deg from the
        limb).

        Parameters
        ----------
        cos_theta : ndarray
            cos theta of the block's centre (its direction's z in the telescope frame).
        span_gamma_z, span_psi_z : ndarray
            The z components of the block's spans in nadir angle and azimuth, broadcastable.

        Returns
        -------
        ndarray
            The fraction in front, in [0, 1], of the broadcast shape.
        """
        half = 0.5 * (np.abs(span_gamma_z) + np.abs(span_psi_z))
        with np.errstate(divide="ignore", invalid="ignore"):
            f = np.clip(0.5 + 0.5 * cos_theta / half, 0.0, 1.0)
        return np.where(half > 0, f, (cos_theta > 0).astype(float))

    def _lit_cap(self, sat_km, earth_radius_km, s, sun_km, moon_km, with_sun: bool, with_moon: bool):
        """The visible cap's blocks (:meth:`_cap_grid`: d, d_omega, pts) and their Sun and Moon
        cosines (:meth:`lamp_cosines`), a lamp left out set to zero."""
        d, d_omega, pts = self._cap_grid(sat_km, earth_radius_km, s)
        mu_sun, mu_moon = self.lamp_cosines(pts, sun_km, moon_km, earth_radius_km)
        if not with_moon:
            mu_moon = np.zeros_like(mu_sun)
        if not with_sun:
            mu_sun = np.zeros_like(mu_moon)
        return d, d_omega, pts, mu_sun, mu_moon

    @staticmethod
    def lamp_cosines(points_km, sun_km, moon_km, earth_radius_km):
        """cos(zenith angle) of the Sun and of the Moon at surface points, clipped at 0.

        Parameters
        ----------
        points_km : ndarray, shape (..., G, P, 3)
            Geocentric ICRS surface points, km.
        sun_km, moon_km : ndarray, shape (..., 3)
            Geocentric ICRS positions of the Sun and the Moon, km (the Sun taken at infinity).
        earth_radius_km : float
            The Earth's radius, km.

        Returns
        -------
        mu_sun, mu_moon : ndarray, shape (..., G, P)
            cos(zenith angle), clipped at 0.
        """
        n = points_km / earth_radius_km
        # the Sun is at 23,000 Earth radii: its direction is the same from every point (< 0.003 deg)
        mu_sun = np.maximum(dot(n, unit(sun_km)[..., None, None, :]), 0.0)
        mu_moon = np.maximum(dot(n, unit(moon_km[..., None, None, :] - points_km)), 0.0)
        return mu_sun, mu_moon

    @cached_property
    def _door_weights(self):
        """Per door state: (door block positions, inner normal, weight W_i) with
        W_i = A_i / pi * mean_j [cos(e_ij) PST(theta_ij, phi_ij) / d_ij^2] (m-2 sr-1 * m2)."""
        from straylight.optics.door import aperture_points

        s = self.earthshine
        out = {}
        nu, nv = s.door_blocks
        ap = aperture_points(self.door.aperture_radius_m, s.n_aperture_door)
        ap3 = np.concatenate([ap, np.zeros((ap.shape[0], 1))], axis=1)
        for state in self.door_states_deg:
            hinge, along, axis = self.door.plate(state)
            a = np.radians(state)
            n_in = np.array([-np.sin(a), 0.0, -np.cos(a)])
            uu = (np.arange(nu) + 0.5) / nu * self.door.length_m
            vv = ((np.arange(nv) + 0.5) / nv - 0.5) * self.door.width_m
            q = hinge + uu[:, None, None] * along + vv[None, :, None] * axis  # (nu, nv, 3)
            area = self.door.length_m * self.door.width_m / (nu * nv)
            vec = q[:, :, None, :] - ap3[None, None, :, :]  # aperture -> door block
            dist = norm(vec)
            u_in = vec / dist[..., None]  # incoming direction as seen from the aperture point
            cos_e = np.maximum(dot(-u_in, n_in), 0.0)
            theta = np.degrees(np.arccos(np.clip(u_in[..., 2], -1, 1)))
            phi = np.degrees(np.arctan2(u_in[..., 1], u_in[..., 0])) % 360.0
            w = area / np.pi * np.mean(cos_e * self.pst(theta, phi) / dist**2 * (u_in[..., 2] > 0), axis=-1)
            out[state] = (q.reshape(-1, 3), n_in, w.reshape(-1))
        return out

    @cached_property
    def _door_lit_fraction(self):
        """Per door state: the fraction f(theta, phi) of the door's weight (:attr:`_door_weights`)
        on door blocks that an Earth block in direction (theta, phi) of the telescope frame
        lights, the ray from the door block towards it not passing through the body
        (:meth:`Door.body_hits`), as a LinearGrid over theta 90-180 deg (1 deg) x phi 0-360 deg
        (2 deg); a direction at theta <= 90 deg never meets the body below the aperture plane
        (f = 1: the grid's clipped edge row).  None without a body."""
        if self.door.body_radius_m <= 0 or self.door.body_length_m <= 0:
            return None
        theta = np.arange(90.0, 180.0 + 0.5, 1.0)
        phi = np.arange(0.0, 360.0 + 1.0, 2.0)
        th, ph = np.meshgrid(np.radians(theta), np.radians(phi), indexing="ij")
        dirs = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=-1).reshape(
            -1, 3
        )
        out = {}
        for state, (q, _, w) in self._door_weights.items():
            lit = np.concatenate(
                [(~self.door.body_hits(q, dirs[i : i + 2048])) @ w for i in range(0, len(dirs), 2048)]
            )
            out[state] = LinearGrid((theta, phi), (lit / np.sum(w)).reshape(th.shape))
        return out

    def door_lit_fraction(self, state: float, theta_deg, phi_deg) -> np.ndarray | float:
        """F of :attr:`_door_lit_fraction` for door state ``state`` at directions (theta, phi),
        deg (broadcast); 1.0 without a body.

        Parameters
        ----------
        state : float
            The door state (opening), deg, one of :attr:`door_states_deg`.
        theta_deg, phi_deg : array_like
            Directions in the telescope frame, deg (theta clipped to [90, 180]).

        Returns
        -------
        ndarray or float
            The lit fraction in [0, 1], of the broadcast shape; 1.0 without a body.
        """
        tables = self._door_lit_fraction
        if tables is None:
            return 1.0
        th, ph = np.broadcast_arrays(np.asarray(theta_deg, float), np.asarray(phi_deg, float))
        return tables[state](np.clip(th, 90.0, 180.0), wrap_360_deg(ph))

    def earth_in_field(self, sat_km, sun_km, moon_km, frame, earth_radius_km):
        """Where the line of sight hits the Earth, its surface is imaged like any extended
        source: radiance x pixel etendue.  Returns (per unit solar irradiance, per unit lunar
        irradiance at the Earth), e-/s/pix per photon s-1 m-2, both lamps in one pass over the
        samples that hit the Earth; 0 elsewhere.

        Parameters
        ----------
        sat_km : ndarray, shape (..., 3)
            Geocentric ICRS satellite positions, km.
        sun_km, moon_km : ndarray, shape (..., 3)
            Geocentric ICRS positions of the Sun and the Moon, km.
        frame : TelescopeFrame
            The samples' telescope frames (``frame.z`` the line of sight).
        earth_radius_km : float
            The Earth's radius, km.

        Returns
        -------
        per_sun, per_moon : ndarray
            e-/s/pix per photon s-1 m-2 of the Sun and of the Moon at the Earth, of the
            samples' broadcast shape.
        """
        los = np.broadcast_to(frame.z, np.broadcast(np.asarray(sat_km), frame.z).shape)
        sat = np.broadcast_to(np.asarray(sat_km, float), los.shape)
        b = dot(sat, los)
        c = dot(sat, sat) - earth_radius_km**2
        disc = b * b - c
        hits = (disc > 0) & (b < 0)
        per_sun, per_moon = np.zeros(hits.shape), np.zeros(hits.shape)
        at = np.flatnonzero(hits)  # the rows by index (geometry.rows_at: faster than a boolean mask)
        if at.size:
            shape = hits.shape
            t = -b.ravel()[at] - np.sqrt(disc.ravel()[at])
            pts = rows_at(sat, shape, at) + t[:, None] * rows_at(los, shape, at)
            sun, moon = rows_at(sun_km, shape, at), rows_at(moon_km, shape, at)
            mu_sun, mu_moon = self.lamp_cosines(pts[:, None, None, :], sun, moon, earth_radius_km)
            lambert = self.earthshine.albedo / np.pi  # Lambertian radiance per unit irradiance and cos z
            per_sun.ravel()[at] = lambert * mu_sun[:, 0, 0] * self.pixel_etendue_m2_sr
            per_moon.ravel()[at] = lambert * mu_moon[:, 0, 0] * self.pixel_etendue_m2_sr
        return per_sun, per_moon

    def earthshine_cap_bound(self, sat_km, earth_radius_km, grid: tuple[int, int], runs=None) -> np.ndarray:
        """Upper bound of the direct coefficient (outside the field) that the sum on an Earth-cap
        ``grid`` (n_gamma, n_psi) gives for any line of sight, lamp and roll: the whole cap
        fully lit (cos z = 1), at the PST's largest value outside the field, Sp = 1, times the
        grid's own solid angle (so the bound holds for the sum, not only for the integral).
        ``runs``: the samples' scene runs when known.

        Parameters
        ----------
        sat_km : ndarray, shape (n, 3)
            Geocentric ICRS satellite positions, km.
        earth_radius_km : float
            The Earth's radius, km.
        grid : tuple of (int, int)
            (n_gamma, n_psi) of the Earth-cap grid.
        runs : SceneRuns, optional
            The samples' scene runs; None: found here.

        Returns
        -------
        ndarray, shape (n,)
            The bound, e-/s/pix per photon s-1 m-2 of the lamp (writable).
        """
        s = replace(self.earthshine, n_gamma=int(grid[0]), n_psi=int(grid[1]))
        # it depends on the satellite's radius alone: once per run of samples sharing the
        # satellite (a cube's time step)
        rows = scene_rows(np.asarray(sat_km, float), runs=runs)
        gamma, dgamma = self._cap_nadir_angles_at(norm(rows.vectors[0]), earth_radius_km, s)
        cap_sr = 2.0 * np.pi * np.sum(np.sin(gamma) * dgamma, axis=-1)  # the grid's sum of d_omega
        return np.array(
            rows.expand(
                self.earthshine.albedo / np.pi * self._pst_max_outside_field * cap_sr * self.pixel_area_m2
            )
        )  # a writable array, not a read-only view

    @cached_property
    def _pst_max_outside_field(self) -> float:
        """The PST's largest node from the field's edge out (the interpolant is bounded by its
        cell's corners, so the node before the edge is included)."""
        th = self.pst.theta_deg
        first = max(int(np.searchsorted(th, self.field_radius_deg, side="right")) - 1, 0)
        return float(self.pst.values[first:].max())

    def earthshine_coefficients(
        self,
        sat_km,
        sun_km,
        moon_km,
        frame,
        opening_deg,
        earth_radius_km,
        in_field: bool = True,
        moon: bool = True,
        sun: bool = True,
        grid: tuple[int, int] | None = None,
    ) -> dict:
        """Band-independent earthshine per unit photon irradiance of the Sun and of the Moon (at
        the Earth): keys direct_sun, direct_moon, door_sun, door_moon, in e-/s/pix per
        (photons s-1 m-2).  The albedo is grey, so a band's earthshine is
        c_sun * E_sun,band + c_moon * E_moon,band; the geometry is computed once for all bands.
        ``in_field=False`` leaves out the line of sight hitting the Earth; ``moon=False`` the
        moonlit terms (zeros), as the look-up table does (:mod:`straylight.sources.earthshine_table`);
        ``sun=False`` the sunlit ones (the table's path sums only the moonlit Earth directly);
        ``grid`` = (n_gamma, n_psi) replaces the configured Earth-cap grid.

        Parameters
        ----------
        sat_km : ndarray, shape (..., 3)
            Geocentric ICRS satellite positions, km.
        sun_km, moon_km : ndarray, shape (..., 3)
            Geocentric ICRS positions of the Sun and the Moon, km.
        frame : TelescopeFrame
            The samples' telescope frames, axes (..., 3).
        opening_deg : array_like
            Each sample's door opening, deg.
        earth_radius_km : float
            The Earth's radius, km.
        in_field : bool
            Whether to add the Earth seen inside the field (:meth:`earth_in_field`).
        moon, sun : bool
            Whether to sum the moonlit and the sunlit terms (else zeros).
        grid : tuple of (int, int), optional
            (n_gamma, n_psi) of the Earth-cap grid; None: the configured one.

        Returns
        -------
        dict of str to ndarray
            ``direct_sun``, ``direct_moon``, ``door_sun``, ``door_moon``: arrays of the
            samples' broadcast shape, e-/s/pix per photon s-1 m-2 of the lamp (the Sun at the
            satellite, the Moon at the Earth).
        """
        s = (
            self.earthshine
            if grid is None
            else replace(self.earthshine, n_gamma=int(grid[0]), n_psi=int(grid[1]))
        )
        one = shared_vectors(sat_km, sun_km, moon_km)
        if one is not None:
            out = self._earthshine_one_scene(*one, frame, opening_deg, earth_radius_km, moon, sun, s)
            if in_field:
                per_sun, per_moon = self.earth_in_field(sat_km, sun_km, moon_km, frame, earth_radius_km)
                out["direct_sun"] = out["direct_sun"] + per_sun
                out["direct_moon"] = out["direct_moon"] + per_moon
            return out
        d, d_omega, pts, mu_sun, mu_moon = self._lit_cap(
            sat_km, earth_radius_km, s, sun_km, moon_km, sun, moon
        )
        lum_sun, lum_moon = s.albedo / np.pi * mu_sun, s.albedo / np.pi * mu_moon
        dx = dot(d, frame.x[..., None, None, :])
        dy = dot(d, frame.y[..., None, None, :])
        dz = dot(d, frame.z[..., None, None, :])
        theta = np.degrees(np.arctan2(np.hypot(dx, dy), dz))
        phi = wrap_360_deg(np.degrees(np.arctan2(dy, dx)))
        op = np.broadcast_to(np.asarray(opening_deg, float)[..., None, None], theta.shape)
        # blocks inside the field are replaced by the in-field term (a grid block cannot resolve
        # the 0.6 deg field, where the PST jumps to 1); a block the aperture plane cuts counts
        # its part in front, at the door's Sp from in front (theta <= 90 deg)
        span_g, span_p = self._cap_block_spans(sat_km, earth_radius_km, s)
        front = self.front_fraction(
            dz, dot(span_g, frame.z[..., None, None, :]), dot(span_p, frame.z[..., None, None, :])
        )
        w_direct = (
            self.door_factor(np.minimum(theta, 90.0), phi, op)
            * front
            * self.pst(theta, phi)
            * (theta > self.field_radius_deg)
            * d_omega
            * self.pixel_area_m2
        )
        out = {
            "direct_sun": np.sum(lum_sun * w_direct, axis=(-2, -1)),
            "direct_moon": np.sum(lum_moon * w_direct, axis=(-2, -1)),
        }
        if in_field:
            per_sun, per_moon = self.earth_in_field(sat_km, sun_km, moon_km, frame, earth_radius_km)
            out["direct_sun"] = out["direct_sun"] + per_sun
            out["direct_moon"] = out["direct_moon"] + per_moon
        # door path: irradiance on the door's inner face from the Earth blocks in front of it
        door_sun = np.zeros(out["direct_sun"].shape)
        door_moon = np.zeros(out["direct_sun"].shape)
        states = sorted(self._door_weights)
        state_of, known = door_state_index(states, opening_deg)
        for i, state in enumerate(states):
            _, n_in, w = self._door_weights[state]
            sel = np.broadcast_to(known & (state_of == i), door_sun.shape)
            if not np.any(sel):
                continue
            # d . n_in > 0: in front of the inner face; f: the share of the door the body leaves lit
            cos_inc = np.maximum(dx * n_in[0] + dy * n_in[1] + dz * n_in[2], 0.0) * self.door_lit_fraction(
                state, theta, phi
            )
            k = s.door_reflectance * np.sum(w) * self.pixel_area_m2
            door_sun = np.where(sel, k * np.sum(lum_sun * d_omega * cos_inc, axis=(-2, -1)), door_sun)
            door_moon = np.where(sel, k * np.sum(lum_moon * d_omega * cos_inc, axis=(-2, -1)), door_moon)
        out["door_sun"], out["door_moon"] = door_sun, door_moon
        return out

    def _earthshine_one_scene(
        self,
        sat,
        sun,
        moon,
        frame,
        opening_deg,
        earth_radius_km,
        with_moon: bool,
        with_sun: bool = True,
        s: EarthshineSettings | None = None,
    ) -> dict:
        """earthshine_coefficients (without the in-field term) for many lines of sight sharing one
        satellite, Sun and Moon (a time step of a survey cube): the Earth cap is gridded once,
        its dark blocks (lit by neither lamp) dropped, and the sums over the rest compiled
        (:func:`~straylight.sources.earthshine_kernel.cap_sums`).  Same sums as the general path,
        so the same values up to rounding (tests/sources/test_offfield.py)."""
        from straylight.sky.frames import TelescopeFrame

        shape = np.broadcast_shapes(frame.z.shape[:-1], np.shape(opening_deg))
        op = np.broadcast_to(np.asarray(opening_deg, float), shape).ravel()
        state_of, known = door_state_index(sorted(self.door_tables), op)
        frame = TelescopeFrame(
            *(np.broadcast_to(a, shape + (3,)).reshape(-1, 3) for a in (frame.x, frame.y, frame.z))
        )
        direct, door = self.earthshine_scene_sums(
            sat,
            sun,
            moon,
            frame,
            earth_radius_km,
            np.where(known, state_of, -1)[:, None],
            with_sun,
            with_moon,
            s,
        )
        return {
            "direct_sun": direct[:, 0, 0].reshape(shape),
            "direct_moon": direct[:, 0, 1].reshape(shape),
            "door_sun": door[:, 0, 0].reshape(shape),
            "door_moon": door[:, 0, 1].reshape(shape),
        }

    def lit_cap_blocks(
        self,
        sat,
        sun,
        moon,
        earth_radius_km,
        s: EarthshineSettings | None = None,
        with_sun: bool = True,
        with_moon: bool = True,
    ):
        """The cap blocks of one scene (satellite, Sun, Moon: (3,) km) lit by either lamp: their
        directions from the satellite, their spans (:meth:`_cap_block_spans`), all (K, 3), and
        their luminance times solid angle per lamp, albedo / pi cos(zenith) dOmega (K, 2: Sun,
        Moon; sr per unit irradiance).

        Parameters
        ----------
        sat, sun, moon : ndarray, shape (3,)
            Geocentric ICRS positions of the satellite, the Sun and the Moon, km.
        earth_radius_km : float
            The Earth's radius, km.
        s : EarthshineSettings, optional
            The Earth grid; None: :attr:`earthshine`.
        with_sun, with_moon : bool
            Whether each lamp lights the cap (a lamp left out gives zeros).

        Returns
        -------
        directions : ndarray, shape (K, 3)
            Unit vectors from the satellite to the lit blocks, ICRS.
        span_gamma, span_psi : ndarray, shape (K, 3)
            The blocks' spans in nadir angle and in azimuth (dimensionless direction changes).
        lum : ndarray, shape (K, 2)
            albedo / pi cos(zenith) dOmega for the Sun and the Moon: radiance per unit
            irradiance (sr-1) times solid angle (sr), dimensionless.
        """
        s = s or self.earthshine
        d, d_omega, pts, mu_sun, mu_moon = self._lit_cap(
            sat, earth_radius_km, s, sun, moon, with_sun, with_moon
        )
        lit = (mu_sun > 0) | (mu_moon > 0)
        span_g, span_p = (
            np.ascontiguousarray(v[lit]) for v in self._cap_block_spans(sat, earth_radius_km, s)
        )
        lum = s.albedo / np.pi * np.stack([mu_sun[lit], mu_moon[lit]], axis=-1) * d_omega[lit][:, None]
        return np.ascontiguousarray(d[lit]), span_g, span_p, np.ascontiguousarray(lum)

    def earthshine_scene_sums(
        self,
        sat,
        sun,
        moon,
        frame,
        earth_radius_km,
        state_sel,
        with_sun: bool = True,
        with_moon: bool = True,
        s: EarthshineSettings | None = None,
    ):
        """(direct, door) coefficients (M, J, 2: lit by the Sun, by the Moon), e-/s/pix per photon
        s-1 m-2 of the lamp, outside the field, for M lines of sight of one scene (``frame``'s
        axes broadcast to (M, 3)) and J door states each (``state_sel`` (M, J): indices into the
        ascending door states, -1 for none, which gives 0).

        Parameters
        ----------
        sat, sun, moon : ndarray, shape (3,)
            Geocentric ICRS positions of the satellite, the Sun and the Moon, km.
        frame : TelescopeFrame
            The lines of sight's frames, axes broadcastable to (M, 3).
        earth_radius_km : float
            The Earth's radius, km.
        state_sel : ndarray of int, shape (M, J)
            Indices into the ascending door states, -1 for none.
        with_sun, with_moon : bool
            Whether each lamp lights the cap.
        s : EarthshineSettings, optional
            The Earth grid; None: :attr:`earthshine`.

        Returns
        -------
        direct, door : ndarray, shape (M, J, 2)
            e-/s/pix per photon s-1 m-2 of the Sun (``[..., 0]``) and of the Moon at the Earth
            (``[..., 1]``).
        """
        blocks, span_g, span_p, lum = self.lit_cap_blocks(
            sat, sun, moon, earth_radius_km, s, with_sun, with_moon
        )
        sel = np.ascontiguousarray(np.asarray(state_sel, np.intp))
        n = sel.shape[0]
        fx, fy, fz = (
            np.ascontiguousarray(np.broadcast_to(a, (n, 3)), dtype=float) for a in (frame.x, frame.y, frame.z)
        )
        direct, door = np.zeros((n, sel.shape[1], 2)), np.zeros((n, sel.shape[1], 2))
        if blocks.shape[0] and n:
            from straylight.sources.earthshine_kernel import cap_sums

            normals, door_weight, pst, sp, lit = self._kernel_tables
            door_k = (s or self.earthshine).door_reflectance * door_weight
            cap_sums(
                fx,
                fy,
                fz,
                blocks,
                span_g,
                span_p,
                lum,
                sel,
                normals,
                door_k,
                float(self.field_radius_deg),
                float(self.pixel_area_m2),
                *pst,
                *sp,
                *lit,
                direct,
                door,
            )
        return direct, door

    @cached_property
    def _kernel_tables(self):
        """What :func:`~straylight.sources.earthshine_kernel.cap_sums` reads, door states ascending:
        the door's inner normals (S, 3), the sum of the door's weights x pixel area per state
        (times the reflectance: the door term's factor k), the PST's and the Sp tables' grids,
        and the lit-fraction tables' grids with whether there is a body (else the lit fraction
        is 1) and their value in front of the aperture plane
        (:func:`~straylight.sources.earthshine_kernel.cap_sums`)."""
        from straylight.sources.earthshine_kernel import GridPack

        states = sorted(self.door_tables)
        normals = np.ascontiguousarray([self._door_weights[st][1] for st in states], dtype=float)
        door_weight = np.array([np.sum(self._door_weights[st][2]) * self.pixel_area_m2 for st in states])
        sp = GridPack([self.door_tables[st]._interp for st in states]).arrays()
        lit_tables = self._door_lit_fraction
        lit = sp if lit_tables is None else GridPack([lit_tables[st] for st in states]).arrays()
        # the lit fraction in front of the aperture plane: its grid's first row (theta 90 deg),
        # where that row's nodes are all equal (the body cannot shade a direction from there)
        at_plane = np.full(len(states), -1.0)
        if lit_tables is not None:
            for i, st in enumerate(states):
                grid = lit_tables[st]
                row = np.asarray(grid._flat).reshape(grid.axes[0].nodes.size, -1)[0]
                if np.ptp(row) == 0.0:
                    at_plane[i] = float(row[0])
        return (
            normals,
            door_weight,
            GridPack([self.pst._interp]).arrays(),
            sp,
            (*lit, lit_tables is not None, at_plane),
        )

    def lamp_bound_one_scene(self, sat, lamp_direction, los, earth_radius_km) -> np.ndarray:
        """Upper bound of the direct coefficient of a cap lit from ``lamp_direction`` (unit vector,
        (3,), the lamp at infinity) whatever the telescope's roll and door, for lines of sight
        ``los`` (M, 3, unit) from one satellite: radiance albedo/pi cos(z_lamp), the PST at its
        maximum over phi (the larger neighbouring theta row), Sp = 1, summed over the cap's lit
        blocks (compiled: :func:`~straylight.sources.earthshine_kernel.lamp_bound_sums`).

        Parameters
        ----------
        sat : ndarray, shape (3,)
            Geocentric ICRS satellite position, km.
        lamp_direction : ndarray, shape (3,)
            Unit vector towards the lamp, ICRS.
        los : ndarray, shape (M, 3)
            Lines of sight, ICRS unit vectors.
        earth_radius_km : float
            The Earth's radius, km.

        Returns
        -------
        ndarray, shape (M,)
            The bound, e-/s/pix per photon s-1 m-2 of the lamp.
        """
        from straylight.sources.earthshine_kernel import lamp_bound_sums

        s = self.earthshine
        sat = np.asarray(sat, float)
        d, d_omega, pts = self._cap_grid(sat, earth_radius_km, s)
        mu = np.maximum(dot(pts / earth_radius_km, np.asarray(lamp_direction, float)), 0.0)
        lit = mu > 0
        lum = s.albedo / np.pi * mu[lit] * d_omega[lit] * self.pixel_area_m2
        out = np.zeros(len(los))
        if lum.size:
            row_max = np.ascontiguousarray(self.pst.values.max(axis=1))
            lamp_bound_sums(
                np.ascontiguousarray(los, dtype=float),
                np.ascontiguousarray(d[lit]),
                lum,
                float(np.cos(np.radians(self.field_radius_deg))),
                -np.cos(np.radians(self.pst.theta_deg)),
                row_max,
                out,
            )
        return out

    def earthshine_terms(
        self, sat_km, sun_km, moon_km, frame, opening_deg, sun_irr, moon_irr_at_earth, earth_radius_km
    ) -> tuple[np.ndarray, np.ndarray]:
        """(EA1 direct, EA2 via the door) in e-/s/pix for samples (leading shapes broadcast).

        Parameters
        ----------
        sat_km : ndarray, shape (..., 3)
            Geocentric ICRS satellite positions, km.
        sun_km, moon_km : ndarray, shape (..., 3)
            Geocentric ICRS positions of the Sun and the Moon, km.
        frame : TelescopeFrame
            The samples' telescope frames.
        opening_deg : array_like
            Each sample's door opening, deg.
        sun_irr : array_like
            The Sun's photon irradiance at the satellite in a band, photons s-1 m-2.
        moon_irr_at_earth : array_like
            The Moon's photon irradiance at the Earth in the band, photons s-1 m-2.
        earth_radius_km : float
            The Earth's radius, km.

        Returns
        -------
        direct, door : ndarray
            EA1 and EA2, e-/s/pix, of the samples' broadcast shape.
        """
        c = self.earthshine_coefficients(sat_km, sun_km, moon_km, frame, opening_deg, earth_radius_km)
        return (
            c["direct_sun"] * sun_irr + c["direct_moon"] * moon_irr_at_earth,
            c["door_sun"] * sun_irr + c["door_moon"] * moon_irr_at_earth,
        )
