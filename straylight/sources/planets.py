"""The planets outside the field (:class:`Planets`): solar-spectrum point sources through the
off-field transfer, each skipped on its bound like the Moon
(:class:`~straylight.sources.bodies.SolarBodySkip`), with Meeus's V magnitudes
(:mod:`straylight.sources.body_magnitudes`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from straylight.sky.ephemeris import PLANETS
from straylight.sky.frames import TelescopeFrame
from straylight.sky.geometry import body_geometry
from straylight.sky.runs import rows_at, scene_rows
from straylight.sky.vectors import unit
from straylight.sources.bodies import SolarBodySkip
from straylight.sources.body_magnitudes import planet_v_magnitudes
from straylight.sources.context import Samples, SourceContext
from straylight.sources.photometry import solar_like_fraction
from straylight.sources.rates import BandRates
from straylight.util.kernel_cache import njit

__all__ = ["PlanetSamples", "Planets"]


class PlanetSamples(NamedTuple):
    """The samples the planets are summed at."""

    satellite_km: np.ndarray
    """Geocentric ICRS satellite positions, km, broadcastable to ``shape + (3,)``."""
    frame: TelescopeFrame
    """The samples' telescope frames."""
    door_deg: np.ndarray
    """The door's opening, deg, broadcastable to ``shape``."""
    floor_ratio: np.ndarray
    """Each sample's floor over the darkest zodiacal light, broadcastable to ``shape``."""
    shape: tuple
    """The samples' shape."""


class Planets:
    """The planets in the samples' ``bodies_km`` (Meeus's V magnitudes), each skipped on its
    bound like the Moon; their angles are computed only at the samples within a planet's widest
    skip radius (:func:`_near_runs_kernel`): most planets, most of the time, reach no sample.

    Parameters
    ----------
    context : SourceContext
        The campaign's instrument as the sources see it.
    skip : SolarBodySkip
        The skip bound each planet is skipped on.
    """

    def __init__(self, context: SourceContext, skip: SolarBodySkip):
        self.context, self.skip = context, skip

    def rates(self, samples: Samples, bands) -> BandRates:
        """The planets together on the ``sun_at_1au`` lamp: e-/s/pix per photon s-1 m-2 of the
        Sun at 1 AU, of the samples' shape, each skipped against ``samples.floor_ratio``.

        Parameters
        ----------
        samples : Samples
            The batch of (time, pointing) samples (reads ``bodies_km``, the planets among them,
            ``floor_ratio``, ``frame``, the door and ``runs``).
        bands : sequence of str
            Band names of the instrument (the skip bound's worst band among them).

        Returns
        -------
        BandRates
            ``per_lamp["planets"]["sun_at_1au"]``: ndarray of the samples' shape, e-/s/pix per
            photon s-1 m-2 of the Sun at 1 AU (0 without planets or where each is skipped).
        """
        return BandRates(
            per_lamp={
                "planets": {
                    "sun_at_1au": self.fraction(
                        samples.satellite_km,
                        samples.bodies_km,
                        samples.frame,
                        samples.door_deg,
                        bands,
                        samples.floor_ratio,
                        samples.shape,
                        samples.runs,
                    )
                }
            }
        )

    def fraction(self, sat, bodies_km, frame, door, bands, floor_ratio, shape, runs=None) -> np.ndarray:
        """:meth:`rates` from its parts: the sum of each planet's :meth:`transfer` times its
        fraction of the Sun's irradiance at 1 AU.  Each planet's magnitude and direction are
        computed once per run of samples that share a scene (a cube's time step; else once per
        sample), and one compiled pass finds every planet's samples within its widest skip radius:
        the only ones whose angles (two arctangents each, most of the geometry's cost) are computed.

        Parameters
        ----------
        sat : ndarray, shape (..., 3)
            Geocentric ICRS satellite positions, km, broadcastable to ``shape + (3,)``.
        bodies_km : dict of str to ndarray
            Body -> geocentric ICRS position, km, (..., 3); the Sun and any planets.
        frame : TelescopeFrame
            The samples' telescope frames.
        door : ndarray
            The door's opening, deg, broadcastable to ``shape``.
        bands : sequence of str
            Band names.
        floor_ratio : float or ndarray
            Each sample's floor over the darkest zodiacal light, >= 1.
        shape : tuple
            The samples' shape.
        runs : SceneRuns, optional
            The samples' scene runs; None: found here.

        Returns
        -------
        ndarray, shape ``shape``
            e-/s/pix per photon s-1 m-2 of the Sun at 1 AU, summed over the planets.
        """
        out = np.zeros(shape)
        planets = [p for p in PLANETS if p in bodies_km]
        if not planets or not out.size:
            return out
        rows = scene_rows(
            *(
                np.broadcast_to(np.asarray(v, float), shape + (3,))
                for v in (sat, bodies_km["sun"], *(bodies_km[p] for p in planets))
            ),
            runs=runs,
        )
        vectors, index = rows.vectors, rows.index
        fractions = solar_like_fraction(
            planet_v_magnitudes(planets, np.stack(vectors[2:]), vectors[1], vectors[0])
        )  # (planets, runs)
        min_floor = float(np.min(floor_ratio))
        widest = np.array(
            [self.skip.widest_radius_deg(*self.skip.scale(f, bands), min_floor) for f in fractions]
        )
        # a margin of 1e-6 deg: the samples left out lie beyond the widest radius whatever the
        # rounding, and the others get the per-sample rule; a radius of 180 deg: every sample
        cos_limit = np.where(widest < 180.0, np.cos(np.radians(widest + 1e-6)), -np.inf)
        directions = np.ascontiguousarray(unit(np.stack(vectors[2:]) - vectors[0]))  # (planets, runs, 3)
        fz = np.ascontiguousarray(np.broadcast_to(frame.z, shape + (3,)).reshape(-1, 3), dtype=float)
        near = _near_runs_kernel(fz, directions, np.ascontiguousarray(index, dtype=np.intp), cos_limit)
        flat_out = out.reshape(-1)  # a view: the sums land in out
        samples = PlanetSamples(sat, frame, door, floor_ratio, shape)
        for i, p in enumerate(planets):
            near_i = np.flatnonzero(near[i])
            if near_i.size:  # added at the near samples only (elsewhere the planet adds 0)
                fraction_near = np.take(fractions[i], np.take(index, near_i))
                flat_out[near_i] += (
                    self.transfer(
                        fraction_near,
                        bodies_km[p],
                        samples,
                        bands,
                        near_i,
                        None if runs is None else runs.at(near_i),
                    )
                    * fraction_near
                )
        return out

    def transfer(
        self, fraction_near, planet_km, samples: PlanetSamples, bands, near, runs_near=None
    ) -> np.ndarray:
        """:meth:`SolarBodySkip.transfer` of a planet at the samples ``near`` (flat indices),
        there only, (len(near),); ``fraction_near``: its fraction of the Sun's irradiance there;
        ``runs_near``: the scene runs of the samples ``near``, when known.

        Parameters
        ----------
        fraction_near : ndarray, shape (len(near),)
            The planet's irradiance over the Sun's at 1 AU at those samples, dimensionless.
        planet_km : ndarray, shape (..., 3)
            Geocentric ICRS positions of the planet, km, broadcastable to ``samples.shape + (3,)``.
        samples : PlanetSamples
            The samples' satellite positions, frames, door openings, floors and shape.
        bands : sequence of str
            Band names.
        near : ndarray of int, shape (m,)
            Flat indices of the samples to evaluate.
        runs_near : SceneRuns, optional
            Their scene runs; None: found here.

        Returns
        -------
        ndarray, shape (m,)
            Transfer, e-/s/pix per photon s-1 m-2 at the aperture (0 where skipped or hidden).
        """
        satellite_km, frame, door, floor_ratio, shape = samples
        sat, planet, fx, fy, fz = (
            rows_at(v, shape, near) for v in (satellite_km, planet_km, frame.x, frame.y, frame.z)
        )
        g = body_geometry(
            sat,
            {"planet": planet},
            TelescopeFrame(fx, fy, fz),
            self.context.campaign.earth.radius_km,
            runs=runs_near,
        )
        door_near, floor_near = (
            np.broadcast_to(np.asarray(v, float), shape).ravel()[near] for v in (door, floor_ratio)
        )
        return self.skip.transfer(
            fraction_near,
            g["planet_angle_deg"],
            g["planet_phi_deg"],
            g["planet_earth_blocked"],
            door_near,
            bands,
            floor_near,
        )


@njit(cache=True, nogil=True)
def _near_runs_kernel(fz, directions, run_index, cos_limit):
    """(bodies, samples) bool: sample n's line of sight ``fz[n]`` has a cosine over
    ``cos_limit[b]`` with body b's direction in the sample's run, ``directions[b, run_index[n]]``
    (the products summed in :func:`~straylight.sky.vectors.dot`'s order, so the same cosines)."""
    n_bodies, n = directions.shape[0], fz.shape[0]
    out = np.zeros((n_bodies, n), np.bool_)
    for b in range(n_bodies):
        limit = cos_limit[b]
        for i in range(n):
            r = run_index[i]
            c = (
                fz[i, 0] * directions[b, r, 0]
                + fz[i, 1] * directions[b, r, 1]
                + fz[i, 2] * directions[b, r, 2]
            )
            out[b, i] = c > limit
    return out
