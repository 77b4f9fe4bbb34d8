"""The moonlit Earth (paper sect. 3.2, the night side lit by the Moon) on the table's path:
~1e-5 of the sunlit Earth, so it is skipped where its upper bound (:meth:`MoonlitEarth.bound`)
times the Moon's irradiance stays below the moonlit_earthshine_skip budget of the sample's
floor, and elsewhere summed on a coarse Earth grid (models.earthshine.moonlit_grid), from its
own table (:class:`~straylight.sources.earthshine.moonlit_table.MoonlitLUT`,
models.earthshine.moonlit_method = lut, when it validates within the moonlit_earthshine_grid
budget) or directly.  On the direct sum's path the sunlit Earth's grid carries the Moon's light
too (:mod:`straylight.sources.earthshine.sunlit`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from straylight.sky.frames import TelescopeFrame
from straylight.sky.runs import rows_at, scene_rows
from straylight.sources.context import Samples, SourceContext
from straylight.sources.earthshine.engine import EARTH_PARTS, Earthshine
from straylight.sources.earthshine.sums import Bodies
from straylight.sources.rates import BandRates

__all__ = ["MoonlitEarth"]


@dataclass
class _Considered:
    """The samples the moonlit Earth considers, flattened: satellite, Sun, Moon (km) and line of
    sight (n, 3); door (deg) and floor (band -> e-/s/pix) (n,); their scene runs; ``cand``: their
    flat indices among all samples (None: all)."""

    sat: np.ndarray
    sun: np.ndarray
    moon: np.ndarray
    los: np.ndarray
    door: np.ndarray
    floor: dict
    runs: object
    cand: np.ndarray | None


class MoonlitEarth:
    """The moonlit Earth outside the field: its bound and its sum, over the engine's coarse grid
    and tables (the sunlit table decides the path and bounds this one).

    Parameters
    ----------
    engine : Earthshine
        The earthshine engine (Earth grid, tables) the sunlit Earth shares.
    """

    def __init__(self, engine: Earthshine):
        self.engine = engine

    @property
    def context(self) -> SourceContext:
        """The campaign's instrument as the sources see it."""
        return self.engine.context

    @property
    def policy(self):
        """The fidelity policy (tolerance, moonlit shares)."""
        return self.engine.policy

    @property
    def grid(self) -> tuple[int, int]:
        """models.earthshine.moonlit_grid: (n_gamma, n_psi) of the coarse Earth grid."""
        return self.engine.moonlit_grid

    def settings(self):
        """:meth:`Earthshine.moonlit_settings
        <straylight.sources.earthshine.engine.Earthshine.moonlit_settings>`.

        Returns
        -------
        MoonlitSettings or None
        """
        return self.engine.moonlit_settings()

    def node_states(self) -> int:
        """:meth:`Earthshine.moonlit_node_states
        <straylight.sources.earthshine.engine.Earthshine.moonlit_node_states>`.

        Returns
        -------
        int
        """
        return self.engine.moonlit_node_states()

    def lut_path(self) -> Path | None:
        """Where the table is cached; None when the moonlit Earth is summed directly
        (:meth:`~straylight.sources.earthshine.engine.Earthshine.moonlit_lut_path`).

        Returns
        -------
        Path or None
        """
        return self.engine.moonlit_lut_path()

    @property
    def model(self) -> dict:
        """How the moonlit Earth is summed where its bound does not let it be skipped
        (:attr:`~straylight.sources.earthshine.engine.Earthshine.moonlit_model`)."""
        return self.engine.moonlit_model

    def bound(self, sunlit_lut, sat_km, moon_km, los, runs=None) -> np.ndarray:
        """Upper bound of the moonlit Earth's coefficient (direct and door, e-/s/pix per photon
        s-1 m-2 of the Moon at the Earth) at flat samples: the sunlit table's
        :meth:`~straylight.sources.earthshine.sunlit_table.EarthshineLUT.moon_bound`; within 1 deg of the
        limb and below it, where the table has none, the whole cap fully lit at the PST's largest
        value outside the field.

        Parameters
        ----------
        sunlit_lut : EarthshineLUT
            The sunlit table.
        sat_km, moon_km : ndarray, shape (n, 3)
            Geocentric ICRS positions of the satellite and the Moon, km.
        los : ndarray, shape (n, 3)
            Lines of sight, ICRS unit vectors.
        runs : SceneRuns, optional
            The samples' scene runs; None: found here.

        Returns
        -------
        ndarray, shape (n,)
            The bound, e-/s/pix per photon s-1 m-2 of the Moon at the Earth (finite).
        """
        off, re_km = self.engine.grid, self.context.campaign.earth.radius_km
        bound = sunlit_lut.moon_bound(sat_km, moon_km, los, re_km, runs)
        no_bound = ~np.isfinite(bound)
        if np.any(no_bound):  # the cap's bound only where needed (it grids each sample's cap)
            unbounded = np.flatnonzero(no_bound)
            bound[no_bound] = (
                off.earthshine_cap_bound(
                    np.take(sat_km, unbounded, axis=0),
                    re_km,
                    self.grid,
                    None if runs is None else runs.at(unbounded),
                )
                + sunlit_lut.moon_door_bound
            )
        return bound

    def rates(self, samples: Samples, bands) -> BandRates:
        """On the table's path, the moonlit Earth outside the field: its coefficients on the
        ``moon_at_earth`` lamp, direct and via the door, arrays of the samples' shape (nothing on
        the direct sum's path, where the sunlit Earth's grid carries the Moon's light).  Skipped
        (0) where :meth:`bound` times the Moon's irradiance at the Earth is below
        ``moonlit_skip_share`` x the tolerance x the sample's floor (``samples.floor``, band ->
        e-/s/pix, a lower bound of its total) in every band, elsewhere the coarse grid's sum.  With the
        table, samples whose Moon zenith angle lies beyond its ``dark_moon_zenith_deg`` (no
        moonlit Earth in view: the table is 0 there) are left out from the start, bound and all:
        they would add exactly 0.

        Parameters
        ----------
        samples : Samples
            The batch of (time, pointing) samples (reads ``moon_lamp``, ``floor``, the
            satellite, the Sun, the Moon, ``frame``, the door and ``runs``).
        bands : sequence of str
            Band names of the instrument (the skip needs the coefficient below its
            share of the floor in every one).

        Returns
        -------
        BandRates
            ``per_lamp["earthshine_direct"]["moon_at_earth"]`` and
            ``per_lamp["earthshine_door"]["moon_at_earth"]``: ndarrays of the samples' shape,
            e-/s/pix per photon s-1 m-2 of the Moon's lamp, with the Earth's band factors
            (``band_factors``, as the sunlit Earth's); empty on the direct sum's path or where
            every sample is skipped.
        """
        sunlit_lut = self.engine.sunlit_lut
        if sunlit_lut is None:
            return BandRates()
        # the Earth's band albedo over the grey one: the skip compares the band's earthshine
        factors = self.engine.band_factors(bands)
        moon_at_earth_unit = {
            name: self.context.photometry(name).sun_at_1au_photons_s_m2
            * (1.0 if factors is None else float(factors[i]))
            * samples.moon_lamp["at_earth"]
            for i, name in enumerate(bands)
        }
        flat = self._considered(samples, moon_at_earth_unit)
        if flat is None:
            return BandRates()
        at = self._needed(sunlit_lut, samples.shape, flat, moon_at_earth_unit)
        if not at.size:
            return BandRates()
        direct_moon, door_moon = self._coarse_sum(samples, flat, at)
        shape = samples.shape
        rows = np.unravel_index(at if flat.cand is None else np.take(flat.cand, at), shape)
        direct, door = np.zeros(shape), np.zeros(shape)
        direct[rows], door[rows] = direct_moon, door_moon
        return BandRates(
            per_lamp={
                "earthshine_direct": {"moon_at_earth": direct},
                "earthshine_door": {"moon_at_earth": door},
            },
            band_factors={} if factors is None else {p: factors for p in EARTH_PARTS},
        )

    def _considered(self, samples: Samples, bands) -> _Considered | None:
        """The samples flattened, less (with the table) those whose Moon zenith angle lies beyond
        its ``dark_moon_zenith_deg``; None when every sample is dark."""
        shape, runs, mlut = samples.shape, samples.runs, self.model["lut"]
        sat_b, sun_b, moon_b, los_b = (
            np.broadcast_to(np.asarray(v, float), shape + (3,)).reshape(-1, 3)
            for v in (samples.satellite_km, samples.sun_km, samples.moon_km, samples.frame.z)
        )
        door_b = np.broadcast_to(np.asarray(samples.door_deg, float), shape).reshape(-1)
        floor_b = {b: np.broadcast_to(samples.floor[b], shape).reshape(-1) for b in bands}
        cand = None  # the samples considered (flat indices; None: all)
        if mlut is not None:
            runs = scene_rows(sat_b, moon_b, runs=runs)  # found once here if not known
            dark = mlut.dark_runs(runs)
            if np.all(dark):
                return None
            if np.any(dark):
                cand = np.flatnonzero(~np.take(dark, runs.index))
                # (the Sun's rows serve the direct moonlit sum only, which has no dark test)
                sat_b, moon_b, los_b = (np.take(v, cand, axis=0) for v in (sat_b, moon_b, los_b))
                door_b = np.take(door_b, cand)
                floor_b = {b: np.take(v, cand) for b, v in floor_b.items()}
                runs = runs.at(cand)
        return _Considered(sat_b, sun_b, moon_b, los_b, door_b, floor_b, runs, cand)

    def _needed(self, sunlit_lut, shape: tuple, flat: _Considered, moon_at_earth_unit: dict) -> np.ndarray:
        """Indices among the considered samples where :meth:`bound` times the Moon's light in
        some band exceeds ``moonlit_skip_share`` x the tolerance x the sample's floor."""
        bound = self.bound(sunlit_lut, flat.sat, flat.moon, flat.los, flat.runs)
        need = np.zeros(bound.shape, bool)
        for b, e_moon in moon_at_earth_unit.items():
            e_moon = np.broadcast_to(e_moon, shape).reshape(-1)
            need |= bound * (e_moon if flat.cand is None else np.take(e_moon, flat.cand)) > (
                self.policy.moonlit_skip_share * self.policy.tolerance * flat.floor[b]
            )
        return np.flatnonzero(need)

    def _coarse_sum(self, samples: Samples, flat: _Considered, at: np.ndarray) -> tuple:
        """(direct, door) coefficients of the moonlit Earth on the coarse grid at the considered
        samples ``at``, from its table or summed directly.

        A coarse grid is enough where a line of sight can be observable (>= the dark-limb angle
        above the limb).  Nearer the limb and below it no Earth grid converges (blocks next to
        the field edge meet the PST's jump), so the configured grid would cost several times
        more for numbers no better than indicative: the coarse grid runs there too."""
        shape, frame, mlut = samples.shape, samples.frame, self.model["lut"]
        sub = TelescopeFrame(
            *(
                rows_at(a, shape, at if flat.cand is None else np.take(flat.cand, at))
                for a in (frame.x, frame.y, frame.z)
            )
        )
        door_need = np.take(flat.door, at)
        if mlut is not None:  # the coarse grid's sum, tabulated
            return mlut.coefficients(
                np.take(flat.sat, at, axis=0),
                np.take(flat.moon, at, axis=0),
                sub,
                door_need,
                None if flat.runs is None else flat.runs.at(at),
            )
        c = self.engine.grid.earthshine_coefficients(
            Bodies(*(np.take(v, at, axis=0) for v in (flat.sat, flat.sun, flat.moon))),
            sub,
            door_need,
            self.context.campaign.earth.radius_km,
            in_field=False,
            sun=False,
            grid=self.grid,
        )
        return c["direct_moon"], c["door_moon"]

    def record(self, sunlit_table_runs: bool) -> str:
        """How the moonlit Earth was summed, for a product's attributes.

        Parameters
        ----------
        sunlit_table_runs : bool
            Whether the sunlit Earth's table ran (else the direct sum carried the Moon's light).

        Returns
        -------
        str
        """
        if not sunlit_table_runs:
            return "summed directly"
        m = self.model
        return (
            f"skipped where its bound < {self.policy.moonlit_skip_share:g} x tolerance x the "
            "sample's floor, else "
            + (
                f"from its table of the grid {list(self.grid)} sum (steps {m['lut_steps_deg']} deg, "
                f"validated {m['lut_validation_max_rel_error']:.2g} of the total at full Moon)"
                if m["method"] == "lut"
                else f"summed directly on grid {list(self.grid)}"
            )
        )
