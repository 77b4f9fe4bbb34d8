"""The Earth-grid sums of earthshine (seed paper sect. 3.2): :class:`EarthshineSums`, the part
of :class:`~straylight.sources.earthshine.engine.EarthGrid` (which inherits it) that sums the sunlit
and moonlit Earth over the cap grid of :class:`~straylight.sources.earthshine.grid.EarthCapGrid`
(the coefficients, a scene's lit blocks and sums, the lamp bound and the compiled kernel's
tables).
"""

from __future__ import annotations

from dataclasses import replace
from functools import cached_property
from typing import NamedTuple

import numpy as np

from straylight.optics.door import door_state_index
from straylight.sky.runs import shared_vectors
from straylight.sky.vectors import dot, wrap_360_deg
from straylight.sources.earthshine.grid import EarthshineSettings

#: the children of cut blocks computed at once, bytes (their directions, spans and
#: luminances in float64): bounds the direct sum's memory on fine grids and many samples
CUT_CHILDREN_BYTES = 64 * 2**20


class _Frame:
    """Telescope axes of some samples (x, y, z: (M, 3) unit vectors)."""

    def __init__(self, x, y, z):
        self.x, self.y, self.z = x, y, z


class Bodies(NamedTuple):
    """Geocentric ICRS positions (km, (..., 3) or one scene's (3,)) of the satellite and of the
    two lamps that light the Earth, the Sun and the Moon."""

    sat_km: np.ndarray
    sun_km: np.ndarray
    moon_km: np.ndarray


__all__ = ["Bodies", "EarthshineSums"]


class EarthshineSums:
    """The earthshine sums' methods of :class:`~straylight.sources.earthshine.engine.EarthGrid` (a
    mixin: it reads the model's fields and the cap grid of
    :class:`~straylight.sources.earthshine.grid.EarthCapGrid`)."""

    def earthshine_coefficients(
        self,
        bodies: Bodies,
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
        moonlit terms (zeros), as the look-up table does (:mod:`straylight.sources.earthshine.sunlit_table`);
        ``sun=False`` the sunlit ones (the table's path sums only the moonlit Earth directly);
        ``grid`` = (n_gamma, n_psi) replaces the configured Earth-cap grid.

        Parameters
        ----------
        bodies : Bodies
            Geocentric ICRS positions of the satellite, the Sun and the Moon, km, (..., 3).
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
        s = self.cap_settings(grid)
        one = shared_vectors(*bodies)
        if one is None:
            return self._coefficients_general(
                bodies, frame, opening_deg, earth_radius_km, s, (sun, moon), in_field
            )
        out = self._earthshine_one_scene(Bodies(*one), frame, opening_deg, earth_radius_km, moon, sun, s)
        if in_field:
            self._add_in_field(out, bodies, frame, earth_radius_km)
        return out

    def _add_in_field(self, out: dict, bodies: Bodies, frame, earth_radius_km) -> None:
        """Add the Earth seen inside the field (:meth:`earth_in_field`) to ``out``'s direct terms."""
        per_sun, per_moon = self.earth_in_field(*bodies, frame, earth_radius_km)
        out["direct_sun"] = out["direct_sun"] + per_sun
        out["direct_moon"] = out["direct_moon"] + per_moon

    def _coefficients_general(self, bodies, frame, opening_deg, earth_radius_km, s, lamps, in_field) -> dict:
        """:meth:`earthshine_coefficients` for samples that do not share one scene, over the whole
        cap grid of each (``lamps``: whether the Sun and the Moon light it)."""
        sat_km, sun_km, moon_km = bodies
        sun, moon = lamps
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
        )
        cut = (front > 0.0) & (front < 1.0) if s.cut_block_split > 1 else np.zeros(front.shape, bool)
        w_direct = np.where(cut, 0.0, w_direct) * d_omega * self.pixel_area_m2
        out = {
            "direct_sun": np.sum(lum_sun * w_direct, axis=(-2, -1)),
            "direct_moon": np.sum(lum_moon * w_direct, axis=(-2, -1)),
        }
        if np.any(cut):
            cut_sun, cut_moon = self._cut_blocks_direct(cut, bodies, frame, op, earth_radius_km, s, lamps)
            out["direct_sun"] = out["direct_sun"] + cut_sun
            out["direct_moon"] = out["direct_moon"] + cut_moon
        if in_field:
            self._add_in_field(out, bodies, frame, earth_radius_km)
        lum_d_omega = (lum_sun * d_omega, lum_moon * d_omega)
        out["door_sun"], out["door_moon"] = self._door_coefficients(
            out["direct_sun"].shape, opening_deg, (dx, dy, dz, theta, phi), lum_d_omega, s
        )
        return out

    def _door_coefficients(self, shape, opening_deg, angles, lum_d_omega, s) -> tuple:
        """The door path of :meth:`_coefficients_general`: irradiance on the door's inner face from
        the Earth blocks in front of it, (sun, moon) of ``shape``; ``angles`` (dx, dy, dz, theta
        deg, phi deg) of the blocks in the telescope frame, ``lum_d_omega`` per lamp."""
        dx, dy, dz, theta, phi = angles
        lum_sun, lum_moon = lum_d_omega
        door_sun = np.zeros(shape)
        door_moon = np.zeros(shape)
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
            door_sun = np.where(sel, k * np.sum(lum_sun * cos_inc, axis=(-2, -1)), door_sun)
            door_moon = np.where(sel, k * np.sum(lum_moon * cos_inc, axis=(-2, -1)), door_moon)
        return door_sun, door_moon

    def cut_children(
        self, sat_km, sun_km, moon_km, earth_radius_km, s: EarthshineSettings, with_sun=True, with_moon=True
    ):
        """The cap grid's blocks split into their n x n children (n = ``s.cut_block_split``):
        the blocks of the n G x n P grid, which nests in the G x P one (the same nadir-angle map
        over n times the steps, n times the azimuths), grouped by parent.

        Parameters
        ----------
        sat_km, sun_km, moon_km : ndarray, shape (..., 3)
            Geocentric ICRS positions of the satellite, the Sun and the Moon, km.
        earth_radius_km : float
            The Earth's radius, km.
        s : EarthshineSettings
            The cap grid (G = ``s.n_gamma``, P = ``s.n_psi``) and the split n.
        with_sun, with_moon : bool
            Whether each lamp lights the cap (a lamp left out gives zeros).

        Returns
        -------
        directions, span_gamma, span_psi : ndarray, shape (..., G, P, n * n, 3)
            The children's unit directions from the satellite and spans (:meth:`_cap_block_spans`).
        lum : ndarray, shape (..., G, P, n * n, 2)
            albedo / pi cos(zenith) dOmega of each child for the Sun and the Moon (dimensionless).
        """
        n = int(s.cut_block_split)
        fine = replace(s, n_gamma=n * s.n_gamma, n_psi=n * s.n_psi)
        d, d_omega, pts, mu_sun, mu_moon = self._lit_cap(
            sat_km, earth_radius_km, fine, sun_km, moon_km, with_sun, with_moon
        )
        span_g, span_p = self._cap_block_spans(sat_km, earth_radius_km, fine)
        lum = fine.albedo / np.pi * np.stack([mu_sun, mu_moon], axis=-1) * d_omega[..., None]
        lead = d.shape[:-3]

        def nest(v):  # (..., nG, nP, k) -> (..., G, P, n n, k)
            v = np.broadcast_to(v, lead + v.shape[-3:]).reshape(
                lead + (s.n_gamma, n, s.n_psi, n, v.shape[-1])
            )
            return np.moveaxis(v, len(lead) + 2, len(lead) + 1).reshape(
                lead + (s.n_gamma, s.n_psi, n * n, -1)
            )

        return nest(d), nest(span_g), nest(span_p), nest(lum)

    def _cut_blocks_direct(self, cut, bodies: Bodies, frame, op, earth_radius_km, s, lamps):
        """The direct term (e-/s/pix per photon s-1 m-2 of the Sun, of the Moon; arrays of the
        samples' shape) of the blocks the aperture plane cuts (``cut``, (..., G, P)), each summed
        over its children (:meth:`cut_children`) with their own angles, Sp, PST and front part,
        as :func:`~straylight.sources.earthshine.kernel.cap_sums` does.  The children of a
        sample's whole grid are n^2 times its blocks, so the samples with a cut block go through
        in groups of about :data:`CUT_CHILDREN_BYTES` of children each; ``lamps``: whether the
        Sun and the Moon light the cap."""
        shape = cut.shape
        lead, (g, p) = shape[:-2], shape[-2:]
        size = int(np.prod(lead))
        flat_cut = cut.reshape(size, g, p)
        rows = np.flatnonzero(flat_cut.any(axis=(1, 2)))
        out_sun, out_moon = np.zeros(size), np.zeros(size)

        def flat(v):  # a (..., 3) vector of the samples as (size, 3)
            return np.broadcast_to(v, lead + (3,)).reshape(size, 3)

        sat, sun, moon = (flat(v) for v in bodies)
        fx, fy, fz = flat(frame.x), flat(frame.y), flat(frame.z)
        flat_op = np.broadcast_to(op, shape).reshape(size, g, p)
        n = int(s.cut_block_split)
        per_row = max(1, int(CUT_CHILDREN_BYTES // (g * p * n * n * 11 * 8)))
        for start in range(0, rows.size, per_row):
            r = rows[start : start + per_row]
            part = _Frame(fx[r], fy[r], fz[r])
            c_sun, c_moon = self._cut_rows_direct(
                flat_cut[r], Bodies(sat[r], sun[r], moon[r]), part, flat_op[r], earth_radius_km, s, lamps
            )
            out_sun[r], out_moon[r] = c_sun, c_moon
        return out_sun.reshape(lead), out_moon.reshape(lead)

    def _cut_rows_direct(self, cut, bodies: Bodies, frame, op, earth_radius_km, s, lamps):
        """:meth:`_cut_blocks_direct` of samples in rows: ``cut`` (M, G, P), vectors (M, 3)."""
        cd, cg, cp, cl = self.cut_children(*bodies, earth_radius_km, s, *lamps)
        shape = cut.shape
        idx = np.nonzero(cut)
        k = cd.shape[-2]

        def at(v, tail):  # the cut blocks' rows of v broadcast to the blocks' shape + tail
            return np.broadcast_to(v, shape + tail)[idx]

        dk, gk, pk, lk = at(cd, (k, 3)), at(cg, (k, 3)), at(cp, (k, 3)), at(cl, (k, 2))
        fx, fy, fz = (at(a[..., None, None, :], (3,))[:, None, :] for a in (frame.x, frame.y, frame.z))
        ux, uy, uz = dot(dk, fx), dot(dk, fy), dot(dk, fz)
        theta = np.degrees(np.arctan2(np.hypot(ux, uy), uz))
        phi = wrap_360_deg(np.degrees(np.arctan2(uy, ux)))
        front = self.front_fraction(uz, dot(gk, fz), dot(pk, fz))
        opk = np.broadcast_to(np.broadcast_to(op, shape)[idx][:, None], theta.shape)
        w = (
            self.door_factor(np.minimum(theta, 90.0), phi, opk)
            * front
            * self.pst(theta, phi)
            * (theta > self.field_radius_deg)
            * self.pixel_area_m2
        )
        sample = (
            np.ravel_multi_index(idx[:-2], shape[:-2]) if len(shape) > 2 else np.zeros(idx[0].size, np.intp)
        )
        size = int(np.prod(shape[:-2]))
        return tuple(
            np.bincount(sample, weights=np.sum(w * lk[..., c], axis=-1), minlength=size).reshape(shape[:-2])
            for c in (0, 1)
        )

    def _earthshine_one_scene(
        self,
        bodies: Bodies,
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
        (:func:`~straylight.sources.earthshine.kernel.cap_sums`).  Same sums as the general path,
        so the same values up to rounding (tests/sources/test_offfield.py)."""
        from straylight.sky.frames import TelescopeFrame

        shape = np.broadcast_shapes(frame.z.shape[:-1], np.shape(opening_deg))
        op = np.broadcast_to(np.asarray(opening_deg, float), shape).ravel()
        state_of, known = door_state_index(sorted(self.door_tables), op)
        frame = TelescopeFrame(
            *(np.broadcast_to(a, shape + (3,)).reshape(-1, 3) for a in (frame.x, frame.y, frame.z))
        )
        direct, door = self.earthshine_scene_sums(
            bodies,
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
        children: bool = False,
    ):
        """The cap blocks of one scene (satellite, Sun, Moon: (3,) km) lit by either lamp: their
        directions from the satellite, their spans (:meth:`_cap_block_spans`), all (K, 3), and
        their luminance times solid angle per lamp, albedo / pi cos(zenith) dOmega (K, 2: Sun,
        Moon; sr per unit irradiance); with ``children``, also each block's children
        (:meth:`cut_children`: directions, spans (K, n n, 3), lum (K, n n, 2); n n = 0 where
        ``cut_block_split`` is 1).

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
        children : bool
            Whether to return the blocks' children too.

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
        kids = None
        if children and s.cut_block_split > 1:
            # a block dark at its centre may have lit children: kept for them (its own lum is 0)
            kids = self.cut_children(sat, sun, moon, earth_radius_km, s, with_sun, with_moon)
            lit = lit | np.any(kids[3] > 0, axis=(-2, -1))
        span_g, span_p = (
            np.ascontiguousarray(v[lit]) for v in self._cap_block_spans(sat, earth_radius_km, s)
        )
        lum = s.albedo / np.pi * np.stack([mu_sun[lit], mu_moon[lit]], axis=-1) * d_omega[lit][:, None]
        out = (np.ascontiguousarray(d[lit]), span_g, span_p, np.ascontiguousarray(lum))
        if not children:
            return out
        if kids is None:
            k = int(lit.sum())
            return out + (np.zeros((k, 0, 3)), np.zeros((k, 0, 3)), np.zeros((k, 0, 3)), np.zeros((k, 0, 2)))
        return out + tuple(np.ascontiguousarray(v[lit]) for v in kids)

    def earthshine_scene_sums(
        self,
        bodies: Bodies,
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
        bodies : Bodies
            Geocentric ICRS positions of the satellite, the Sun and the Moon, km, (3,) each.
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
        blocks, span_g, span_p, lum, *kids = self.lit_cap_blocks(
            *bodies, earth_radius_km, s, with_sun, with_moon, children=True
        )
        sel = np.ascontiguousarray(np.asarray(state_sel, np.intp))
        n = sel.shape[0]
        fx, fy, fz = (
            np.ascontiguousarray(np.broadcast_to(a, (n, 3)), dtype=float) for a in (frame.x, frame.y, frame.z)
        )
        direct, door = np.zeros((n, sel.shape[1], 2)), np.zeros((n, sel.shape[1], 2))
        if blocks.shape[0] and n:
            from straylight.sources.earthshine.kernel import CapBlocks, Sightlines, cap_sums

            optics, door_arrays = self._kernel_tables
            door_k = (s or self.earthshine).door_reflectance * door_arrays.k
            cap_sums(
                Sightlines(fx, fy, fz, sel),
                CapBlocks(blocks, span_g, span_p, lum, *kids),
                optics,
                door_arrays._replace(k=door_k),
                direct,
                door,
            )
        return direct, door

    @cached_property
    def _kernel_tables(self):
        """What :func:`~straylight.sources.earthshine.kernel.cap_sums` reads, door states ascending:
        the field's radius, the pixel area and the PST's grid
        (:class:`~straylight.sources.earthshine.kernel.OpticsArrays`), and the door's
        (:class:`~straylight.sources.earthshine.kernel.DoorArrays`) with ``k`` the sum of the
        door's weights x pixel area per state, m2 (the door term's factor at unit reflectance)."""
        from straylight.sources.earthshine.kernel import DoorArrays, GridPack, OpticsArrays

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
        optics = OpticsArrays(
            float(self.field_radius_deg), float(self.pixel_area_m2), GridPack([self.pst._interp]).arrays()
        )
        return optics, DoorArrays(normals, door_weight, sp, lit, lit_tables is not None, at_plane)

    def lamp_bound_one_scene(self, sat, lamp_direction, los, earth_radius_km) -> np.ndarray:
        """Upper bound of the direct coefficient of a cap lit from ``lamp_direction`` (unit vector,
        (3,), the lamp at infinity) whatever the telescope's roll and door, for lines of sight
        ``los`` (M, 3, unit) from one satellite: radiance albedo/pi cos(z_lamp), the PST at its
        maximum over phi (the larger neighbouring theta row), Sp = 1, summed over the cap's lit
        blocks (compiled: :func:`~straylight.sources.earthshine.kernel.lamp_bound_sums`).

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
        from straylight.sources.earthshine.kernel import lamp_bound_sums

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
        c = self.earthshine_coefficients(Bodies(sat_km, sun_km, moon_km), frame, opening_deg, earth_radius_km)
        return (
            c["direct_sun"] * sun_irr + c["direct_moon"] * moon_irr_at_earth,
            c["door_sun"] * sun_irr + c["door_moon"] * moon_irr_at_earth,
        )
