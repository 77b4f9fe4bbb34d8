"""The Earth grid of the earthshine sum (seed paper sect. 3.2): its settings
(:class:`EarthshineSettings`) and :class:`EarthCapGrid`, the part of
:class:`~straylight.sources.earthshine.engine.EarthGrid` (which inherits it) that lays the grid on
the visible cap, lights its blocks, sees them from the door and bounds the sum; the sums are
:class:`~straylight.sources.earthshine.sums.EarthshineSums`.

Earthshine (paper sect. 3.2): the Earth cap seen from the satellite is split into n_gamma x
n_psi blocks of solid angle sin(gamma) dgamma dpsi about nadir; each is a Lambertian reflector of
albedo A lit by the Sun (radiance A/pi E_sun cos z_sun) or, on the night side, by the Moon.
EA1 = sum E_i Sp_i PST(theta_i, phi_i) (direct; Sp = 0 behind the aperture plane, theta > 90
deg).  EA2 (door): each door block receives MP_i = sum_b L_b dOmega_b cos(incidence) from the
Earth blocks in front of its inner face whose ray to it misses the telescope body
(:meth:`EarthGrid.door_lit_fraction`) and re-emits as a Lambertian of reflectance r; the
aperture points j receive L_door A_i cos(e_ij) / d_ij^2 with PST(theta_ij, phi_ij), averaged
over the aperture.  This is the paper's EA2 = sum_i MP_i r sum_j PST(theta_ij, phi_ij) / d_ij^2
with the block area, the emission cosine and 1/pi written out.  The sunlit and moonlit Earth's sources
(:mod:`straylight.sources.earthshine.sunlit`, :mod:`straylight.sources.earthshine.moonlit`) call this sum or
its tables (:mod:`straylight.sources.earthshine.sunlit_table`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property, lru_cache

import numpy as np

from straylight.errors import ConfigError
from straylight.sky.runs import rows_at, scene_rows
from straylight.sky.vectors import dot, norm, perpendicular_towards, unit, wrap_360_deg
from straylight.util.gridinterp import LinearGrid

__all__ = ["EarthCapGrid", "EarthshineSettings"]


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
    cut_block_split : int
        A block the aperture plane cuts is summed as cut_block_split x cut_block_split
        sub-blocks in the direct term (1: whole, its front part linear in cos theta).

    Raises
    ------
    ConfigError
        When the grid is too coarse or the albedo or reflectance is outside [0, 1].
    """

    n_gamma: int = 24  # nadir-angle blocks of the visible cap
    n_psi: int = 48  # azimuth blocks
    albedo: float = 0.30
    door_blocks: tuple[int, int] = (24, 24)  # along x across the door plate
    door_reflectance: float = 0.02  # a bare default: SourceContext passes csst.yaml door_geometry.reflectance
    n_aperture_door: int = 256  # aperture points for the door-to-aperture path (128: 0.5 % of the total off)
    cut_block_split: int = 4  # children per side of a block the aperture plane cuts (direct term)

    def __post_init__(self):
        if self.n_gamma < 2 or self.n_psi < 4:
            raise ConfigError(
                f"earthshine grid {self.n_gamma} x {self.n_psi}: needs n_gamma >= 2, n_psi >= 4"
            )
        if self.cut_block_split < 1:
            raise ConfigError(f"earthshine cut_block_split = {self.cut_block_split}: must be >= 1")
        if not 0 <= self.albedo <= 1:
            raise ConfigError(f"earthshine albedo = {self.albedo}: must be within [0, 1]")
        if not 0 <= self.door_reflectance <= 1:
            raise ConfigError(f"door reflectance = {self.door_reflectance}: must be within [0, 1]")


class EarthCapGrid:
    """The Earth-cap grid's methods of :class:`~straylight.sources.earthshine.engine.EarthGrid`
    (a mixin: it reads the model's ``pst``, ``door``, ``earthshine``, ``pixel_area_m2``,
    ``pixel_etendue_m2_sr`` and ``field_radius_deg``)."""

    def cap_settings(self, grid: tuple[int, int] | None = None) -> EarthshineSettings:
        """The Earth grid's settings: the configured ones (:attr:`earthshine`) with the
        (n_gamma, n_psi) of ``grid`` in place of theirs.

        Parameters
        ----------
        grid : tuple of (int, int), optional
            (n_gamma, n_psi) of the Earth-cap grid; None: the configured one.

        Returns
        -------
        EarthshineSettings

        Raises
        ------
        ConfigError
            When the grid is too coarse (:class:`EarthshineSettings`).
        """
        if grid is None:
            return self.earthshine
        return replace(self.earthshine, n_gamma=int(grid[0]), n_psi=int(grid[1]))

    @staticmethod
    def _cap_nadir_angles(sat_km, earth_radius_km, s: EarthshineSettings):
        """The cap grid's nadir angles gamma and their widths (rad, (..., G)): packed towards
        the limb, where the Earth lies closest to an allowed line of sight and the terminator
        crosses it: gamma = rho sin(pi u / 2), u uniform."""
        return EarthCapGrid._cap_nadir_angles_at(norm(sat_km), earth_radius_km, s)

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
        theta, phi, _ = lit_fraction_directions()
        out = {}
        for state, (q, _, w) in self._door_weights.items():
            lit = np.concatenate([chunk @ w for chunk in _unblocked_rays(self.door, q.tobytes())])
            out[state] = LinearGrid((theta, phi), (lit / np.sum(w)).reshape(theta.size, phi.size))
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
        s = self.cap_settings(grid)
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


#: directions of the lit fraction's grid per body test (bounds its (directions, door blocks) arrays)
RAY_CHUNK = 2048


def lit_fraction_directions() -> tuple:
    """The door's lit-fraction grid (:attr:`EarthCapGrid._door_lit_fraction`): theta 90-180 deg
    (1 deg) and phi 0-360 deg (2 deg), deg, and their unit directions in the telescope frame,
    (theta x phi, 3), theta-major."""
    theta = np.arange(90.0, 180.0 + 0.5, 1.0)
    phi = np.arange(0.0, 360.0 + 1.0, 2.0)
    th, ph = np.meshgrid(np.radians(theta), np.radians(phi), indexing="ij")
    dirs = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=-1)
    return theta, phi, dirs.reshape(-1, 3)


@lru_cache(maxsize=4)
def _unblocked_rays(door, points_bytes: bytes) -> tuple:
    """Whether the ray from each door block (``points_bytes``: (M, 3) float64, m) along each
    direction of :func:`lit_fraction_directions` misses the telescope body
    (:meth:`~straylight.optics.door.Door.body_hits`), in chunks of :data:`RAY_CHUNK` directions:
    a tuple of (n, M) bool arrays.  Geometry alone, so the models of one process (the nominal one
    and the envelope's members, whose door weights differ through the PST) compute it once: 1.2 s
    and 19 MB for the default door's two states (16,471 directions x 576 blocks each)."""
    q = np.frombuffer(points_bytes, float).reshape(-1, 3)
    dirs = lit_fraction_directions()[2]
    return tuple(~door.body_hits(q, dirs[i : i + RAY_CHUNK]) for i in range(0, len(dirs), RAY_CHUNK))
