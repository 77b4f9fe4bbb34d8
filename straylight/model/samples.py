"""A batch of (time, pointing) samples as one typed value, built once where a caller's input
enters (:meth:`SampleBatch.at_times`: ``straylight sky``, ``sky --input``, the API's
:func:`straylight.sky_background`, the pointing tables; a cube region's time steps x pixels) and
passed down to :func:`~straylight.model.pointing.background_at`: the distinct times' scene
(UTC times, their TDB Julian dates, the satellite and the bodies), the lines of sight, each
sample's row of the scene; the positions at the samples and the telescope frame are computed on
first use and kept.

What the sources read is :class:`~straylight.sources.context.Samples`, made from a batch with
its observing geometry (:meth:`SampleBatch.source_samples`)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from straylight.sky.frames import TelescopeFrame, telescope_frame
from straylight.sky.observing import Scene, scene_utc
from straylight.sky.vectors import radec_to_unit
from straylight.sources.context import Samples

__all__ = ["SampleBatch", "distinct_times"]


@dataclass(frozen=True, eq=False)
class SampleBatch:
    """n (time, pointing) samples at the m distinct times of a scene.

    Attributes
    ----------
    scene : Scene
        The m distinct times (UTC :class:`~astropy.time.Time`, their TDB Julian dates), the
        satellite's and the bodies' geocentric ICRS positions there, km, (m, 3).
    los : ndarray, shape (n, 3)
        Unit lines of sight, ICRS.
    scene_index : ndarray of int, shape (n,), or None
        Each sample's row of ``scene``; None: sample i at row i (m = n).
    runs : SceneRuns or None
        The samples' scene runs when the caller knows them (a cube region's time steps over its
        pixels, :meth:`~straylight.sky.runs.SceneRuns.steps`), else None (found where needed).
    faint_rates : dict or None
        The faint stars' map at the lines of sight, band -> e-/s/pix (n,), when known.
    """

    scene: Scene
    los: np.ndarray
    scene_index: np.ndarray | None = None
    runs: object = None
    faint_rates: dict | None = None

    @classmethod
    def at_times(cls, orbit, times, ra_deg, dec_deg) -> SampleBatch:
        """The samples at UTC ``times`` (already parsed and checked, 1-D) and ICRS pointings:
        the scene computed once per distinct time (a scheduler asks for many pointings at few
        times), nothing parsed again.

        Parameters
        ----------
        orbit : CircularOrbit or TLEOrbit
            The telescope's orbit (a campaign's ``orbit``).
        times : astropy.time.Time, shape (n,)
            UTC times.
        ra_deg, dec_deg : array_like, shape (n,)
            ICRS pointing, deg.

        Returns
        -------
        SampleBatch
        """
        first, inverse = distinct_times(
            np.asarray(times.jd1, float).ravel(), np.asarray(times.jd2, float).ravel()
        )
        los = np.atleast_2d(radec_to_unit(ra_deg, dec_deg))
        return cls(scene_utc(orbit, times[first]), los, inverse)

    @property
    def n(self) -> int:
        """The number of samples."""
        return int(self.los.shape[0])

    @property
    def times(self):
        """The samples' UTC times (n,)."""
        t = self.scene.times
        return t if self.scene_index is None else t[self.scene_index]

    def __getitem__(self, sl: slice) -> SampleBatch:
        """The samples ``sl`` (a slice), on the same scene."""
        rows = np.arange(self.n)[sl]
        return SampleBatch(
            self.scene,
            self.los[sl],
            rows if self.scene_index is None else self.scene_index[sl],
            None if self.runs is None else self.runs.at(rows),
            None if self.faint_rates is None else {b: v[sl] for b, v in self.faint_rates.items()},
        )

    def at_samples(self, rows) -> np.ndarray:
        """Rows of the scene (m, ...) at the samples (n, ...).

        Parameters
        ----------
        rows : array_like, shape (m, ...)
            Per distinct time (the satellite's or a body's position).

        Returns
        -------
        ndarray, shape (n, ...)
        """
        rows = np.asarray(rows, float)
        # rows by index with np.take, faster than numpy's fancy indexing of (N, 3) rows
        return rows if self.scene_index is None else np.take(rows, self.scene_index, axis=0)

    @cached_property
    def satellite_km(self) -> np.ndarray:
        """The satellite at the samples, geocentric ICRS km, (n, 3)."""
        return self.at_samples(self.scene.satellite_km)

    @cached_property
    def _bodies(self) -> dict:
        return {}

    def body_km(self, name: str) -> np.ndarray:
        """A body at the samples, geocentric ICRS km, (n, 3), computed once.

        Parameters
        ----------
        name : str
            A body of the scene (``sun``, ``moon``, a planet).

        Returns
        -------
        ndarray, shape (n, 3)
        """
        if name not in self._bodies:
            self._bodies[name] = self.at_samples(self.scene.bodies_km[name])
        return self._bodies[name]

    @property
    def bodies_km(self) -> dict:
        """Every body of the scene at the samples, body -> geocentric ICRS km (n, 3)."""
        return {b: self.body_km(b) for b in self.scene.bodies_km}

    @cached_property
    def frame(self) -> TelescopeFrame:
        """The samples' telescope frame, ``telescope_frame(los, sun - satellite)``."""
        return telescope_frame(self.los, self.body_km("sun") - self.satellite_km)

    def take(self, sel: np.ndarray) -> SampleBatch:
        """The samples ``sel`` (increasing indices) as a batch of their own, on the same scene;
        what this batch has computed (positions, frame) taken along, not computed again.

        Parameters
        ----------
        sel : ndarray of int
            Sample indices.

        Returns
        -------
        SampleBatch
        """
        index = sel if self.scene_index is None else np.take(self.scene_index, sel)
        sub = replace(
            self,
            los=np.take(self.los, sel, axis=0),
            scene_index=index,
            runs=None if self.runs is None else self.runs.at(sel),
            faint_rates=None
            if self.faint_rates is None
            else {b: v[sel] for b, v in self.faint_rates.items()},
        )
        done = self.__dict__
        if "satellite_km" in done:
            sub.__dict__["satellite_km"] = np.take(done["satellite_km"], sel, axis=0)
        sub.__dict__["_bodies"] = {b: np.take(v, sel, axis=0) for b, v in done.get("_bodies", {}).items()}
        if "frame" in done:
            f = done["frame"]
            sub.__dict__["frame"] = TelescopeFrame(*(np.take(a, sel, axis=0) for a in (f.x, f.y, f.z)))
        return sub

    def source_samples(self, geometry: dict, stars=None) -> Samples:
        """What the sources read of these samples (:class:`~straylight.sources.context.Samples`):
        the positions, the frame, the observing ``geometry`` (arrays (n,)) and the off-field
        ``stars`` (None: none).

        Parameters
        ----------
        geometry : dict
            :func:`~straylight.sky.geometry.observing_geometry`'s arrays at the samples.
        stars : StarTable or None
            The off-field stars.

        Returns
        -------
        Samples
        """
        return Samples(
            self.satellite_km,
            self.bodies_km,
            self.frame,
            geometry,
            self.runs,
            stars=stars,
            faint_rates=self.faint_rates,
        )


def distinct_times(jd1: np.ndarray, jd2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(index of each distinct two-part Julian date, in increasing order; each sample's distinct
    time): np.unique over the (jd1, jd2) pairs, by one lexsort.

    Parameters
    ----------
    jd1, jd2 : ndarray, shape (n,)
        The two parts of the samples' Julian dates, days.

    Returns
    -------
    first : ndarray of int
        A sample of each distinct time, in increasing time.
    inverse : ndarray of int, shape (n,)
        Each sample's distinct time (index into ``first``).
    """
    order = np.lexsort((jd2, jd1))
    a, b = jd1[order], jd2[order]
    new = np.ones(order.size, bool)
    new[1:] = (a[1:] != a[:-1]) | (b[1:] != b[:-1])
    inverse = np.empty(order.size, np.intp)
    inverse[order] = np.cumsum(new) - 1
    return order[new], inverse
