"""Samples of the sky: for (time, pointing) pairs or grids, the full observing geometry.

This is the Python API behind ``straylight sky`` and the pipeline's cubes.  Later physics
(stray-light components per band) adds to the dict returned by :func:`sample_geometry`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from astropy.time import Time

from straylight.sky.ephemeris import BODIES, default_ephemeris
from straylight.sky.geometry import observing_geometry, radec_to_unit
from straylight.sky.timeutil import parse_utc, utc_to_tdb_jd

if TYPE_CHECKING:  # the type only: config builds on sky
    from straylight.config import Campaign


@dataclass
class Scene:
    """Positions at a set of times: satellite and bodies, geocentric GCRS/ICRS km, (T, 3)."""

    times: Time
    satellite_km: np.ndarray
    bodies_km: dict[str, np.ndarray]


def scene(campaign: Campaign, times, bodies=BODIES) -> Scene:
    """Satellite (from the campaign's orbit) and body positions (DE405) at UTC times."""
    t = parse_utc(times)
    t1 = t.reshape(-1) if t.shape else t.reshape((1,))
    jd1, jd2 = utc_to_tdb_jd(t1)
    bodies_km = default_ephemeris().positions_tdb(jd1, jd2, bodies)
    sat = campaign.orbit.position_gcrs_km(t1)
    return Scene(times=t1, satellite_km=sat, bodies_km=bodies_km)


def sample_geometry(campaign: Campaign, sc: Scene, ra_deg, dec_deg, grid: bool = True) -> dict:
    """Observing geometry for the scene's times and the pointings (ICRS deg).

    grid=True: every time against every pointing, arrays (T, P).
    grid=False: paired samples, time i with pointing i, arrays (N,).
    """
    los = radec_to_unit(ra_deg, dec_deg)
    los = np.atleast_2d(los)
    if grid:
        sat = sc.satellite_km[:, None, :]
        bodies = {k: v[:, None, :] for k, v in sc.bodies_km.items()}
        los_b = los[None, :, :]
    else:
        sat, bodies, los_b = sc.satellite_km, sc.bodies_km, los
    return observing_geometry(sat, bodies, los_b, campaign.earth.radius_km, campaign.constraints)
