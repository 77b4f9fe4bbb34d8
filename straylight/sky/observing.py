"""Samples of the sky: for (time, pointing) pairs or grids, the full observing geometry.

This is the Python API behind ``straylight sky`` and the pipeline's cubes.  Later physics
(stray-light components per band) adds to the dict returned by :func:`sample_geometry`.
The functions take what they need (an orbit, the Earth's radius, the avoidance constraints), not
the campaign: a caller with a :class:`~straylight.config.Campaign` passes ``campaign.orbit``,
``campaign.earth.radius_km`` and ``campaign.constraints``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from astropy.time import Time

from straylight.sky.ephemeris import BODIES, default_ephemeris
from straylight.sky.geometry import Constraints, observing_geometry
from straylight.sky.orbit import CircularOrbit, TLEOrbit
from straylight.sky.timeutil import parse_utc, quiet_dubious_years, tdb_minus_tt_s
from straylight.sky.vectors import radec_to_unit

__all__ = ["Scene", "sample_geometry", "scene", "scene_utc"]


@dataclass
class Scene:
    """Positions at a set of times: satellite and bodies, geocentric GCRS/ICRS km, (T, 3);
    ``times`` UTC (T,), and ``tdb_jd`` their TDB Julian dates (two parts, days, (T,) each) the
    bodies were read at (None when not given)."""

    times: Time
    satellite_km: np.ndarray
    bodies_km: dict[str, np.ndarray]
    tdb_jd: tuple | None = None

    def rows(self, sl: slice) -> Scene:
        """The scene at its times ``sl`` (views of its arrays).

        Parameters
        ----------
        sl : slice
            The times kept.

        Returns
        -------
        Scene
        """
        tdb = None if self.tdb_jd is None else tuple(a[sl] for a in self.tdb_jd)
        bodies = {b: v[sl] for b, v in self.bodies_km.items()}
        return Scene(times=self.times[sl], satellite_km=self.satellite_km[sl], bodies_km=bodies, tdb_jd=tdb)


def scene(orbit: CircularOrbit | TLEOrbit, times, bodies=BODIES) -> Scene:
    """Satellite (from ``orbit``, e.g. a campaign's ``orbit``) and body positions (DE405) at
    UTC times.

    Parameters
    ----------
    orbit : CircularOrbit or TLEOrbit
        The telescope's orbit (e.g. a campaign's ``orbit``).
    times : str, sequence of str or astropy.time.Time
        UTC times, any shape.
    bodies : iterable of str, optional
        The bodies whose positions are computed (default :data:`BODIES`).
    """
    t = parse_utc(times)
    return scene_utc(orbit, t.reshape(-1) if t.shape else t.reshape((1,)), bodies)


def scene_utc(orbit: CircularOrbit | TLEOrbit, times: Time, bodies=BODIES) -> Scene:
    """:func:`scene` at UTC times already parsed (a 1-D :class:`~astropy.time.Time` of scale
    UTC), read as they are: converted to TDB here (UTC -> TT by astropy, TT -> TDB by
    :func:`~straylight.sky.timeutil.tdb_minus_tt_s`, as
    :func:`~straylight.sky.timeutil.utc_to_tdb_jd`) and given to the orbit as they are.

    Parameters
    ----------
    orbit : CircularOrbit or TLEOrbit
        The telescope's orbit.
    times : astropy.time.Time, shape (T,)
        UTC times.
    bodies : iterable of str, optional
        The bodies whose positions are computed (default :data:`BODIES`).

    Returns
    -------
    Scene
        With the times' TDB Julian dates.
    """
    with quiet_dubious_years():
        tt = times.tt
    jd1 = np.asarray(tt.jd1, dtype=float)
    jd2 = np.asarray(tt.jd2, dtype=float)
    jd2 = jd2 + tdb_minus_tt_s(jd1, jd2) / 86400.0
    bodies_km = default_ephemeris().positions_tdb(jd1, jd2, bodies)
    sat = orbit.position_gcrs_km(times)
    return Scene(times=times, satellite_km=sat, bodies_km=bodies_km, tdb_jd=(jd1, jd2))


def sample_geometry(
    sc: Scene, ra_deg, dec_deg, earth_radius_km: float, constraints: Constraints, grid: bool = True
) -> dict:
    """Observing geometry for the scene's times and the pointings (ICRS deg), with the Earth's
    radius (km) and the avoidance constraints (a campaign's ``earth.radius_km`` and
    ``constraints``).

    grid=True: every time against every pointing, arrays (T, P).
    grid=False: paired samples, time i with pointing i, arrays (N,).

    Parameters
    ----------
    sc : Scene
        The times' satellite and body positions (:func:`scene`).
    ra_deg : array_like
        Right ascension of the pointings, ICRS, deg.
    dec_deg : array_like
        Declination of the pointings, ICRS, deg.
    earth_radius_km : float
        The Earth's radius, km (a campaign's ``earth.radius_km``).
    constraints : Constraints
        The avoidance constraints (a campaign's ``constraints``).
    grid : bool, optional
        True (default): every time against every pointing, arrays (T, P); False: time i with
        pointing i, arrays (N,).
    """
    los = radec_to_unit(ra_deg, dec_deg)
    los = np.atleast_2d(los)
    if grid:
        sat = sc.satellite_km[:, None, :]
        bodies = {k: v[:, None, :] for k, v in sc.bodies_km.items()}
        los_b = los[None, :, :]
    else:
        sat, bodies, los_b = sc.satellite_km, sc.bodies_km, los
    return observing_geometry(sat, bodies, los_b, earth_radius_km, constraints)
