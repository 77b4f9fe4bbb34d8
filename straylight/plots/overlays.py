"""What the all-sky maps draw over the data: the ecliptic and the Galactic plane as ICRS lines,
and the Sun's position at a map's time or along a campaign.

The lines come from astropy's frames (the J2000 ecliptic, ``BarycentricMeanEcliptic``, at
latitude 0; the Galactic plane, ``Galactic``, at b = 0), transformed to ICRS, the maps' frame.
The Sun comes from the project's DE405 ephemeris (:mod:`straylight.sky.ephemeris`), the positions
the background model itself uses.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

__all__ = [
    "ECLIPTIC_STYLE",
    "GALACTIC_STYLE",
    "SUN_END_STYLE",
    "SUN_START_STYLE",
    "SUN_TRACK_STYLE",
    "ecliptic_radec_deg",
    "galactic_plane_radec_deg",
    "sun_radec_deg",
    "sun_track_times",
]

#: The ecliptic's and the Galactic plane's line styles (matplotlib keyword arguments): black,
#: dashed and dotted, distinct from every colour of the maps' colour scales
ECLIPTIC_STYLE = {"color": "k", "linestyle": (0, (5, 3)), "linewidth": 0.9, "label": "ecliptic (J2000)"}
GALACTIC_STYLE = {
    "color": "k",
    "linestyle": (0, (1, 1.5)),
    "linewidth": 1.2,
    "label": "Galactic plane (b = 0)",
}
#: The Sun's marker (at the map's time, or at the end of a campaign) and, for maps over a
#: campaign, its track and a larger ring at the start (a ring around the disc where the Sun has
#: moved less than its size, as in a campaign of a day)
SUN_END_STYLE = {
    "marker": "o",
    "markersize": 7,
    "markerfacecolor": "gold",
    "markeredgecolor": "k",
    "markeredgewidth": 1.0,
}
SUN_START_STYLE = {**SUN_END_STYLE, "markersize": 11, "markerfacecolor": "none", "markeredgewidth": 1.2}
SUN_TRACK_STYLE = {"color": "k", "linewidth": 1.0}


def _to_icrs_deg(frame, lon_deg: np.ndarray, lat_deg: np.ndarray) -> np.ndarray:
    import astropy.units as u
    from astropy.coordinates import SkyCoord

    c = SkyCoord(lon_deg * u.deg, lat_deg * u.deg, frame=frame).icrs
    out = np.column_stack([c.ra.deg, c.dec.deg])
    out.setflags(write=False)
    return out


@lru_cache(maxsize=4)
def ecliptic_radec_deg(n_points: int = 721) -> np.ndarray:
    """ICRS RA, Dec (deg; shape (n_points, 2)) of the J2000 ecliptic (ecliptic latitude 0,
    longitude 0 to 360 deg), through astropy's ``BarycentricMeanEcliptic``: the plane the Sun
    moves in, within 0.01 deg over the decades the maps cover (the ecliptic itself precesses by
    47 arcsec a century).

    Parameters
    ----------
    n_points : int, optional
        Number of points along the ecliptic (default 721: 0.5 deg apart).
    """
    from astropy.coordinates import BarycentricMeanEcliptic

    lon = np.linspace(0.0, 360.0, n_points)
    return _to_icrs_deg(BarycentricMeanEcliptic(equinox="J2000"), lon, np.zeros_like(lon))


@lru_cache(maxsize=4)
def galactic_plane_radec_deg(n_points: int = 721) -> np.ndarray:
    """ICRS RA, Dec (deg; shape (n_points, 2)) of the Galactic plane (b = 0, l from 0 to 360 deg),
    through astropy's ``Galactic`` frame.

    Parameters
    ----------
    n_points : int, optional
        Number of points along the plane (default 721: 0.5 deg apart).
    """
    lon = np.linspace(0.0, 360.0, n_points)
    return _to_icrs_deg("galactic", lon, np.zeros_like(lon))


def sun_radec_deg(times) -> np.ndarray:
    """The Sun's geocentric ICRS RA, Dec (deg; shape (n, 2)) at UTC ``times`` (ISO strings, an
    astropy Time or UTC Julian dates; n of them), from the DE405 ephemeris the model uses.

    Parameters
    ----------
    times : str, sequence of str, astropy.time.Time or array_like
        UTC times (ISO strings, a ``Time``, or UTC Julian dates, days).
    """
    from straylight.sky.ephemeris import default_ephemeris, radec_distance

    sun = default_ephemeris().positions(times, bodies=("sun",))["sun"]
    ra, dec, _ = radec_distance(np.atleast_2d(sun))
    return np.column_stack([ra, dec])


def sun_track_times(times, n_max: int = 49):
    """At most ``n_max`` of ``times`` (an astropy Time, 1-D) evenly spread from the first to the
    last (both kept): enough for the Sun's track over a campaign to be a smooth line (the Sun
    moves about 1 deg a day).

    Parameters
    ----------
    times : astropy.time.Time
        Times, 1-D.
    n_max : int, optional
        The most times returned (default 49).
    """
    n = len(times)
    return times[np.unique(np.linspace(0, n - 1, min(n, max(int(n_max), 2))).round().astype(int))]
