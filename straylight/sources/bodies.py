"""The Sun, the Moon and the planets: solar-spectrum point sources outside the field, through
the off-field transfer (paper eq. 14: E Se Sp PST x pixel area), and the same bodies inside the
field, which the background leaves out (:class:`InFieldBodies`).

Each body's rate is band-independent until multiplied by a band's solar photon irradiance at
1 AU: the Moon and the planets have the Sun's spectrum, so their irradiance is a fraction of the
Sun's (:func:`~straylight.sources.photometry.solar_like_fraction` of their V magnitude).  The Sun
is never skipped; the Moon and each planet are skipped where their upper bound stays below 1/9
of the moon_and_planets_skip budget times the sample's floor (:class:`SolarBodySkip`).

Published brightness laws:

* Sun: ASTM E490-00a spectrum at 1 AU scaled by (1 AU / d)^2 (:mod:`straylight.sources.photometry`).
* Moon: solar spectrum scaled to V(alpha) = -12.73 + 0.026 |alpha| + 4e-9 alpha^4 at the mean
  distance 384400 km (Krisciunas & Schaefer 1991, PASP 103, 1033, eq. 9; alpha = phase angle,
  deg), or the paper's proportional rule (full-Moon brightness times elongation / 180);
  x (384400 km / d)^2; an eclipsed Moon (inside the Earth's shadow cylinder) is dimmed by
  models.moon_eclipse_factor.
* Planets: V = V0 + 5 log10(r Delta) + phase terms (Meeus 1998, "Astronomical Algorithms",
  2nd ed., ch. 41, after the Astronomical Almanac 1984), with Saturn's ring term; solar spectrum.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from straylight.errors import ConfigError
from straylight.sky.ephemeris import PLANETS
from straylight.sky.frames import TelescopeFrame
from straylight.sky.geometry import body_geometry
from straylight.sky.limb import earth_blocks
from straylight.sky.runs import rows_at, scene_rows
from straylight.sky.vectors import dot, norm, unit
from straylight.sources.context import Samples, SourceContext
from straylight.sources.photometry import AU_KM, V_SUN_VEGA, solar_like_fraction
from straylight.sources.rates import BandRates

MOON_MEAN_DISTANCE_KM = 384400.0
#: the Moon's nearest perigee in 2000-2100, km (~356,400; Meeus 1998, ch. 50): the brightest Moon
MOON_PERIGEE_KM = 356400.0
#: the Moon's farthest apogee in 2000-2100, km (~406,700; Meeus 1998, ch. 50)
MOON_APOGEE_KM = 406700.0
SATURN_POLE_RA_DEC_DEG = (40.589, 83.537)  # IAU WGCCRE 2015 (Archinal et al. 2018)

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
        ra, de = np.radians(SATURN_POLE_RA_DEC_DEG)
        pole = np.array([np.cos(de) * np.cos(ra), np.cos(de) * np.sin(ra), np.sin(de)])
        sin_b = np.abs(dot(unit(observer - planet[k]), pole))
        v[k] = v[k] - 2.60 * sin_b + 1.25 * sin_b**2
    return v


class Sun:
    """The Sun outside the field: never skipped (it sets the floor the other skips scale with)."""

    def __init__(self, context: SourceContext):
        self.context = context

    def rates(self, samples: Samples, bands) -> BandRates:
        """The Sun's coefficient on the ``sun`` lamp: the band-independent transfer Se Sp PST x
        pixel area (e-/s/pix per photon s-1 m-2 at the aperture), of the samples' shape; in
        band b the Sun gives transfer * (sun_at_1au[b] * (1 AU / distance)^2) e-/s/pix.

        Parameters
        ----------
        samples : Samples
            The batch of (time, pointing) samples (reads the Sun's angle, azimuth and Earth
            blocking from ``geometry``, and the door).
        bands : sequence of str
            Band names of the instrument (unused: the coefficient is band-independent).

        Returns
        -------
        BandRates
            ``per_lamp["sun"]["sun"]``: ndarray of the samples' shape, e-/s/pix per photon
            s-1 m-2 of the Sun at the satellite.
        """
        g = samples.geometry
        transfer = self.context.offfield.point_source(
            1.0, g["sun_angle_deg"], g["sun_phi_deg"], g["sun_earth_blocked"], samples.door_deg
        )
        return BandRates(per_lamp={"sun": {"sun": transfer}})


class SolarBodySkip:
    """The skip bound of a solar-spectrum body (the Moon, each planet): its upper bound is the
    PST at its maximum over phi from the body's angle out, with Se = Sp = 1; the body is skipped
    (0) where that bound stays below 1/9 of the moon_and_planets_skip budget of the sample's
    floor in every band, so the Moon and the eight planets together stay within it.  The floor is
    ``floor_ratio`` (>= 1, per sample) times the darkest zodiacal light: a lower bound of the
    total.  A new Moon far from the line of sight is skipped, a bright one only where the Sun or
    the sunlit Earth outshines it by ~10^4.

    Parameters
    ----------
    context : SourceContext
        The campaign's instrument as the sources see it.
    policy : FidelityPolicy
        The fidelity policy (tolerance and the moon_and_planets_skip share).
    """

    def __init__(self, context: SourceContext, policy):
        self.context, self.policy = context, policy

    def transfer(self, sun_fraction, angle_deg, phi_deg, earth_blocked, door, bands, floor_ratio=1.0):
        """The band-independent transfer (as OffFieldModel.point_source with E = 1) of a body
        whose irradiance is ``sun_fraction`` of the Sun's at 1 AU, 0 where it is skipped.

        Parameters
        ----------
        sun_fraction : array_like
            The body's irradiance over the Sun's at 1 AU, dimensionless, per sample (or one).
        angle_deg : ndarray
            The body's angle from the line of sight, deg, per sample.
        phi_deg : ndarray
            The body's azimuth in the telescope frame, deg, broadcastable with ``angle_deg``.
        earth_blocked : ndarray of bool
            True where the Earth hides the body.
        door : ndarray
            The door's opening, deg, per sample.
        bands : sequence of str
            Band names (the skip bound takes the worst).
        floor_ratio : float or ndarray
            Each sample's floor over the darkest zodiacal light, >= 1.

        Returns
        -------
        ndarray
            Transfer, e-/s/pix per photon s-1 m-2 at the aperture, of the broadcast shape of
            the angles, blocking and door (0 where skipped or hidden).
        """
        off = self.context.offfield
        rel, budget = self.scale(sun_fraction, bands)
        if np.size(angle_deg):
            # a source outside the widest radius everywhere (the Moon, often) is skipped with no
            # radius per sample
            widest = self.widest_radius_deg(rel, budget, floor_ratio)
            if widest < 180.0 and np.min(angle_deg) >= widest:
                return np.zeros(
                    np.broadcast_shapes(
                        np.shape(angle_deg), np.shape(phi_deg), np.shape(earth_blocked), np.shape(door)
                    )
                )
        # beyond each sample's radius (a radius of 180: nowhere skippable)
        far = off.pst.beyond_influence_radius(angle_deg, budget * np.asarray(floor_ratio, float) / rel)
        # a skipped source is treated as hidden: point_source then looks nothing up for it
        return off.point_source(1.0, angle_deg, phi_deg, np.asarray(earth_blocked, bool) | far, door)

    def scale(self, sun_fraction, bands) -> tuple:
        """(rel, budget): the body's e-/s/pix at PST = 1 relative to the darkest zodiacal light,
        worst band (solar spectrum), and its share of the tolerance (1/9 of moon_and_planets_skip).

        Parameters
        ----------
        sun_fraction : array_like
            The body's irradiance over the Sun's at 1 AU, dimensionless.
        bands : sequence of str
            Band names.

        Returns
        -------
        rel : ndarray
            The body's e-/s/pix at PST = 1 over the darkest zodiacal light, dimensionless, of
            ``sun_fraction``'s shape.
        budget : float
            Its share of the tolerance, a fraction of the floor.
        """
        rel = (
            self.context.offfield.pixel_area_m2
            * np.asarray(sun_fraction, float)
            / self.context.solar_floor(tuple(bands))
        )
        return rel, self.policy.share("moon_and_planets_skip") / (1 + len(PLANETS)) * self.policy.tolerance

    def widest_radius_deg(self, rel, budget, floor_ratio) -> float:
        """The largest of the samples' skip radii: the radius shrinks as its limit rises, so the
        smallest limit (the darkest floor over the brightest body; a hair smaller against
        rounding) gives a radius that bounds every sample's.

        Parameters
        ----------
        rel : array_like
            :meth:`scale`'s ``rel`` per sample (or run).
        budget : float
            :meth:`scale`'s ``budget``.
        floor_ratio : float or array_like
            The samples' floors over the darkest zodiacal light, >= 1.

        Returns
        -------
        float
            The widest skip radius, deg (180: nowhere skippable).
        """
        with np.errstate(divide="ignore"):
            smallest = budget * float(np.min(floor_ratio)) / float(np.max(rel)) * (1 - 1e-12)
        return float(self.context.offfield.pst.influence_radius_deg(smallest))


class Moon:
    """The Moon: V magnitude by models.moon_phase_law, dimmed by moon_eclipse_factor inside the
    Earth's shadow; it also lights the night side of the Earth (:meth:`lamp`).

    Parameters
    ----------
    context : SourceContext
        The campaign's instrument as the sources see it.
    skip : SolarBodySkip
        The skip bound it is skipped on.
    """

    def __init__(self, context: SourceContext, skip: SolarBodySkip):
        self.context, self.skip = context, skip

    def lamp(self, samples: Samples) -> dict:
        """The Moon's brightness and irradiance (band-independent): ``v_mag`` (at the satellite,
        uneclipsed), ``eclipse`` (1, or moon_eclipse_factor where the Earth hides the Sun from
        the Moon) and ``at_earth`` (eclipse included: the moonlit Earth's lamp).

        Parameters
        ----------
        samples : Samples
            The batch of samples (reads the Sun, the Moon, the satellite, the Moon's phase angle
            and elongation from ``geometry``, and ``runs``).

        Returns
        -------
        dict of str to ndarray
            Arrays of the samples' shape: ``v_mag``, the Moon's V magnitude (Vega) at the
            satellite's distance; ``eclipse``, dimensionless; ``at_earth``, the Moon's irradiance
            at the Earth's centre over the Sun's at 1 AU, dimensionless.
        """
        off, g = self.context.offfield, samples.geometry
        sun, moon = samples.sun_km, samples.moon_km
        rows = scene_rows(
            sun, moon, runs=samples.runs
        )  # the eclipse once per run sharing them (a cube's time step)
        eclipsed = rows.expand(
            earth_blocks(
                rows.vectors[1], rows.vectors[0] - rows.vectors[1], self.context.campaign.earth.radius_km
            )
        )
        v = moon_v_magnitude(
            g["moon_phase_angle_deg"],
            norm(moon - samples.satellite_km),
            off.moon_law,
            g["moon_elongation_deg"],
        )
        v_at_earth = moon_v_magnitude(
            g["moon_phase_angle_deg"], norm(moon), off.moon_law, g["moon_elongation_deg"]
        )
        eclipse = np.where(eclipsed, off.moon_eclipse_factor, 1.0)
        return {"v_mag": v, "eclipse": eclipse, "at_earth": solar_like_fraction(v_at_earth) * eclipse}

    def rates(self, samples: Samples, bands) -> BandRates:
        """The Moon's coefficient on the ``sun_at_1au`` lamp: e-/s/pix per photon s-1 m-2 of the
        Sun at 1 AU (times a band's solar irradiance at 1 AU: its e-/s/pix there), 0 where
        skipped against ``samples.floor_ratio``; the lamp read from ``samples.moon_lamp``
        (:meth:`lamp`'s).

        Parameters
        ----------
        samples : Samples
            The batch of (time, pointing) samples (reads ``moon_lamp``, ``floor_ratio``, the
            Moon's angles and Earth blocking from ``geometry``, and the door).
        bands : sequence of str
            Band names of the instrument (the skip bound's worst band among them).

        Returns
        -------
        BandRates
            ``per_lamp["moon"]["sun_at_1au"]``: ndarray of the samples' shape, e-/s/pix per
            photon s-1 m-2 of the Sun at 1 AU (0 where skipped).
        """
        g, lamp = samples.geometry, samples.moon_lamp
        sun_fraction = solar_like_fraction(lamp["v_mag"])
        t = self.skip.transfer(
            sun_fraction,
            g["moon_angle_deg"],
            g["moon_phi_deg"],
            g["moon_earth_blocked"],
            samples.door_deg,
            bands,
            samples.floor_ratio,
        )
        return BandRates(per_lamp={"moon": {"sun_at_1au": t * sun_fraction * lamp["eclipse"]}})


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
        for i, p in enumerate(planets):
            near_i = np.flatnonzero(near[i])
            if near_i.size:  # added at the near samples only (elsewhere the planet adds 0)
                fraction_near = np.take(fractions[i], np.take(index, near_i))
                flat_out[near_i] += (
                    self.transfer(
                        fraction_near,
                        sat,
                        bodies_km[p],
                        frame,
                        door,
                        bands,
                        floor_ratio,
                        shape,
                        near_i,
                        None if runs is None else runs.at(near_i),
                    )
                    * fraction_near
                )
        return out

    def transfer(
        self,
        fraction_near,
        satellite_km,
        planet_km,
        frame,
        door,
        bands,
        floor_ratio,
        shape,
        near,
        runs_near=None,
    ) -> np.ndarray:
        """:meth:`SolarBodySkip.transfer` of a planet at the samples ``near`` (flat indices),
        there only, (len(near),); ``fraction_near``: its fraction of the Sun's irradiance there;
        ``runs_near``: the scene runs of the samples ``near``, when known.

        Parameters
        ----------
        fraction_near : ndarray, shape (len(near),)
            The planet's irradiance over the Sun's at 1 AU at those samples, dimensionless.
        satellite_km, planet_km : ndarray, shape (..., 3)
            Geocentric ICRS positions of the satellite and the planet, km, broadcastable to
            ``shape + (3,)``.
        frame : TelescopeFrame
            The samples' telescope frames.
        door : ndarray
            The door's opening, deg, broadcastable to ``shape``.
        bands : sequence of str
            Band names.
        floor_ratio : float or ndarray
            Each sample's floor over the darkest zodiacal light, broadcastable to ``shape``.
        shape : tuple
            The samples' shape.
        near : ndarray of int, shape (m,)
            Flat indices of the samples to evaluate.
        runs_near : SceneRuns, optional
            Their scene runs; None: found here.

        Returns
        -------
        ndarray, shape (m,)
            Transfer, e-/s/pix per photon s-1 m-2 at the aperture (0 where skipped or hidden).
        """
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


class InFieldBodies:
    """The Sun, Moon and planets inside the field (within ``field_radius_deg`` of the line of
    sight), which the background leaves out (:meth:`OffFieldModel.point_source`): a body in the
    field is a point source, imaged with its halo and ghosts like a star.

    Parameters
    ----------
    context : SourceContext
        The campaign's instrument as the sources see it (field radius, bands).
    """

    def __init__(self, context: SourceContext):
        self.context = context

    def find(self, satellite_km, bodies_km, los, geometry, bands) -> dict:
        """Body -> {"in_field": bool, "angle_deg": deg from the line of sight, "v_mag": V (Vega),
        "mag_ab": {band: AB magnitude through the band (solar spectrum)}}, arrays over the
        samples; ``geometry``: :func:`~straylight.sky.observing.sample_geometry`'s (the Moon's phase).

        Parameters
        ----------
        satellite_km : ndarray, shape (..., 3)
            Geocentric ICRS satellite positions, km.
        bodies_km : dict of str to ndarray
            Body -> geocentric ICRS position, km, (..., 3); bodies missing from it are left out.
        los : ndarray, shape (..., 3)
            Lines of sight, ICRS (normalised here).
        geometry : dict of str to ndarray
            Reads ``moon_phase_angle_deg`` and ``moon_elongation_deg``, deg.
        bands : sequence of str
            Band names for ``mag_ab``.

        Returns
        -------
        dict of str to dict
            Per body present: ``in_field`` (bool), ``angle_deg`` (deg), ``v_mag`` (Vega) and
            ``mag_ab`` (band -> AB magnitude), arrays of the samples' shape.
        """
        off = self.context.offfield
        sat = np.asarray(satellite_km, float)
        z = unit(np.asarray(los, float))
        out = {}
        for body in ("sun", "moon", *PLANETS):
            if body not in bodies_km:
                continue
            pos = np.asarray(bodies_km[body], float)
            d = unit(pos - sat)
            angle = np.degrees(np.arccos(np.clip(np.sum(d * z, axis=-1), -1.0, 1.0)))
            dist = norm(pos - sat)
            if body == "sun":
                fraction = (AU_KM / dist) ** 2
                v = V_SUN_VEGA - 2.5 * np.log10(fraction)
            elif body == "moon":
                v = moon_v_magnitude(
                    geometry["moon_phase_angle_deg"], dist, off.moon_law, geometry["moon_elongation_deg"]
                )
                fraction = solar_like_fraction(v)
            else:
                v = planet_v_magnitudes([body], pos[None], np.asarray(bodies_km["sun"], float), sat)[0]
                fraction = solar_like_fraction(v)
            mags = {
                b: -2.5
                * np.log10(
                    fraction
                    * self.context.photometry(b).sun_at_1au_photons_s_m2
                    / self.context.band(b).ab_zero_point_photons_s_m2
                )
                for b in bands
            }
            out[body] = {
                "in_field": angle <= off.field_radius_deg,
                "angle_deg": angle,
                "v_mag": np.asarray(v, float),
                "mag_ab": mags,
            }
        return out


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
