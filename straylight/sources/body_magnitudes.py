"""The Moon's and the planets' V magnitudes and the Moon's distances: the brightness laws of
:mod:`straylight.sources.bodies` and :mod:`straylight.sources.planets`.

Published brightness laws:

* Moon: solar spectrum scaled to V(alpha) = -12.73 + 0.026 |alpha| + 4e-9 alpha^4 at the mean
  distance 384400 km (Krisciunas & Schaefer 1991, PASP 103, 1033, eq. 9; alpha = phase angle,
  deg), or the paper's proportional rule (full-Moon brightness times elongation / 180);
  x (384400 km / d)^2; an eclipsed Moon (inside the Earth's shadow cylinder) is dimmed by
  models.moon_eclipse_factor.
* Planets: V = V0 + 5 log10(r Delta) + phase terms (Meeus 1998, "Astronomical Algorithms",
  2nd ed., ch. 41, after the Astronomical Almanac 1984); solar spectrum.  Saturn's terms are
  those of its ring: + 0.044 |Delta U| - 2.60 sin|B| + 1.25 sin^2 B, with B the Saturnicentric
  latitude of the observer referred to the ring plane and Delta U the difference of the
  Saturnicentric longitudes of the Sun and the observer in that plane (Meeus ch. 45), the ring
  plane being Saturn's equator (its pole from the IAU WGCCRE, Archinal et al. 2018).
"""

from __future__ import annotations

import numpy as np

from straylight.errors import ConfigError
from straylight.sky.vectors import dot, norm, unit
from straylight.sources.photometry import AU_KM

__all__ = [
    "MOON_APOGEE_KM",
    "MOON_MEAN_DISTANCE_KM",
    "MOON_PERIGEE_KM",
    "PLANET_V",
    "SATURN_POLE_RA_DEC_DEG",
    "SATURN_RING_COEFFS",
    "moon_v_magnitude",
    "saturn_ring_angles_deg",
    "planet_v_magnitude",
    "planet_v_magnitudes",
]

MOON_MEAN_DISTANCE_KM = 384400.0
#: the Moon's nearest perigee in 2000-2100, km (~356,400; Meeus 1998, ch. 50): the brightest Moon
MOON_PERIGEE_KM = 356400.0
#: the Moon's farthest apogee in 2000-2100, km (~406,700; Meeus 1998, ch. 50)
MOON_APOGEE_KM = 406700.0
#: Saturn's north pole, ICRS RA and Dec at J2000, deg (IAU WGCCRE 2015, Archinal et al. 2018,
#: Celest. Mech. Dyn. Astr. 130, 22, Table 2); its drift, -0.036 and -0.004 deg per century,
#: moves B and Delta U by < 0.02 deg over 1950-2050 and is left out
SATURN_POLE_RA_DEC_DEG = (40.589, 83.537)
#: Saturn's ring coefficients (Meeus 1998 ch. 41): mag per deg of |Delta U|, per sin|B|, per sin^2 B
SATURN_RING_COEFFS = (0.044, -2.60, 1.25)

# Meeus (1998) ch. 41: V0 and phase coefficients (i in degrees)
PLANET_V = {
    "mercury": (-0.42, (0.0380, -0.000273, 0.000002)),
    "venus": (-4.40, (0.0009, 0.000239, -0.00000065)),
    "mars": (-1.52, (0.016, 0.0, 0.0)),
    "jupiter": (-9.40, (0.005, 0.0, 0.0)),
    "saturn": (-8.88, (0.0, 0.0, 0.0)),
    "uranus": (-7.19, (0.0, 0.0, 0.0)),
    "neptune": (-6.87, (0.0, 0.0, 0.0)),
    "pluto": (-1.00, (0.0, 0.0, 0.0)),
}


def moon_v_magnitude(phase_angle_deg, distance_km, law: str = "krisciunas_schaefer", elongation_deg=None):
    """Lunar V magnitude at ``distance_km`` for the phase angle (deg, 0 = full).

    Parameters
    ----------
    phase_angle_deg : array_like
        Sun-Moon-observer phase angle, deg (0 = full Moon; its absolute value is used).
    distance_km : array_like
        Moon-observer distance, km.
    law : str
        ``"krisciunas_schaefer"`` (Krisciunas & Schaefer 1991) or ``"proportional"`` (the
        full Moon's brightness times elongation / 180).
    elongation_deg : array_like, optional
        The Moon's elongation from the Sun, deg, for ``"proportional"``; None: 180 - |phase|.

    Returns
    -------
    ndarray
        V magnitude (Vega), of the broadcast shape of the inputs.

    Raises
    ------
    ConfigError
        When ``law`` is not one of the two.
    """
    a = np.abs(np.asarray(phase_angle_deg, dtype=float))
    dist_term = 5.0 * np.log10(np.asarray(distance_km, dtype=float) / MOON_MEAN_DISTANCE_KM)
    if law == "krisciunas_schaefer":
        return -12.73 + 0.026 * a + 4e-9 * a**4 + dist_term
    if law == "proportional":
        e = np.asarray(elongation_deg if elongation_deg is not None else 180.0 - a, dtype=float)
        ratio = np.clip(e / 180.0, 1e-6, 1.0)
        return -12.73 - 2.5 * np.log10(ratio) + dist_term
    raise ConfigError(f"moon phase law {law!r} is not one of 'krisciunas_schaefer', 'proportional'")


def planet_v_magnitude(name: str, planet_km, sun_km, observer_km) -> np.ndarray:
    """Meeus (1998) ch. 41 V magnitude of a planet (geocentric inputs, km).

    Parameters
    ----------
    name : str
        The planet, a key of :data:`PLANET_V`.
    planet_km, sun_km, observer_km : ndarray, shape (..., 3)
        Geocentric ICRS positions of the planet, the Sun and the observer, km, broadcastable.

    Returns
    -------
    ndarray, shape (...)
        V magnitude (Vega).
    """
    return planet_v_magnitudes([name], np.asarray(planet_km, float)[None], sun_km, observer_km)[0]


def planet_v_magnitudes(names, planets_km, sun_km, observer_km) -> np.ndarray:
    """:func:`planet_v_magnitude` of several planets at once: ``planets_km`` (planets, ..., 3),
    one row per name, -> (planets, ...) (one numpy pass for all of them, not one per planet:
    a cube batch's per-step magnitudes are small arrays, where numpy's per-call cost dominates).

    Parameters
    ----------
    names : sequence of str
        The planets, keys of :data:`PLANET_V`.
    planets_km : ndarray, shape (planets, ..., 3)
        Geocentric ICRS positions of the planets, km, one row per name.
    sun_km, observer_km : ndarray, shape (..., 3)
        Geocentric ICRS positions of the Sun and the observer, km.

    Returns
    -------
    ndarray, shape (planets, ...)
        V magnitudes (Vega).
    """
    v0 = np.array([PLANET_V[n][0] for n in names], float)
    c1, c2, c3 = np.array([PLANET_V[n][1] for n in names], float).T
    planet = np.asarray(planets_km, float)
    sun, observer = np.asarray(sun_km, float), np.asarray(observer_km, float)
    extra = (slice(None),) + (None,) * (planet.ndim - 2)  # each planet's constants over its samples
    v0, c1, c2, c3 = v0[extra], c1[extra], c2[extra], c3[extra]
    r = norm(planet - sun) / AU_KM
    delta = norm(planet - observer) / AU_KM
    i = np.degrees(
        np.arctan2(norm(np.cross(sun - planet, observer - planet)), dot(sun - planet, observer - planet))
    )
    v = v0 + 5.0 * np.log10(r * delta) + c1 * i + c2 * i**2 + c3 * i**3
    if "saturn" in names:
        k = list(names).index("saturn")
        b_deg, delta_u_deg = saturn_ring_angles_deg(planet[k], sun, observer)
        sin_b = np.sin(np.radians(np.abs(b_deg)))
        cu, cb, cb2 = SATURN_RING_COEFFS
        v[k] = v[k] + cu * delta_u_deg + cb * sin_b + cb2 * sin_b**2
    return v


def saturn_ring_angles_deg(saturn_km, sun_km, observer_km) -> tuple[np.ndarray, np.ndarray]:
    """Saturn's ring as seen by the observer (Meeus 1998 ch. 45): B and |Delta U|.

    Parameters
    ----------
    saturn_km, sun_km, observer_km : ndarray, shape (..., 3)
        Geocentric ICRS positions of Saturn, the Sun and the observer, km, broadcastable.

    Returns
    -------
    b_deg : ndarray, shape (...)
        The Saturnicentric latitude of the observer referred to the ring plane (Saturn's
        equator, pole :data:`SATURN_POLE_RA_DEC_DEG`), deg, positive north.
    delta_u_deg : ndarray, shape (...)
        |Delta U|: the angle between the Sun's and the observer's directions from Saturn
        projected on the ring plane (the difference of their Saturnicentric longitudes), deg,
        in [0, 180].
    """
    ra, de = np.radians(SATURN_POLE_RA_DEC_DEG)
    pole = np.array([np.cos(de) * np.cos(ra), np.cos(de) * np.sin(ra), np.sin(de)])
    saturn = np.asarray(saturn_km, float)
    to_observer = unit(np.asarray(observer_km, float) - saturn)
    to_sun = unit(np.asarray(sun_km, float) - saturn)
    sin_b = dot(to_observer, pole)
    obs_in_plane = to_observer - sin_b[..., None] * pole
    sun_in_plane = to_sun - dot(to_sun, pole)[..., None] * pole
    delta_u = np.arctan2(norm(np.cross(obs_in_plane, sun_in_plane)), dot(obs_in_plane, sun_in_plane))
    return np.degrees(np.arcsin(np.clip(sin_b, -1.0, 1.0))), np.degrees(delta_u)
