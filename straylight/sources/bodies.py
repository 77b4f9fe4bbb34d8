"""The Sun, the Moon and the planets: solar-spectrum point sources outside the field, through
the off-field transfer (paper eq. 14: E Se Sp PST x pixel area), and the same bodies inside the
field, which the background leaves out (:class:`InFieldBodies`); the planets are in
:mod:`straylight.sources.planets`, the brightness laws in :mod:`straylight.sources.body_magnitudes`.

Each body's rate is band-independent until multiplied by a band's solar photon irradiance at
1 AU: the Moon and the planets have the Sun's spectrum, so their irradiance is a fraction of the
Sun's (:func:`~straylight.sources.photometry.solar_like_fraction` of their V magnitude).  The Sun
is never skipped; the Moon and each planet are skipped where their upper bound stays below 1/9
of the moon_and_planets_skip budget times the sample's floor (:class:`SolarBodySkip`).

Published brightness laws:

* Sun: ASTM E490-00a spectrum at 1 AU scaled by (1 AU / d)^2 (:mod:`straylight.sources.photometry`).
* Moon and planets: :mod:`straylight.sources.body_magnitudes`.
"""

from __future__ import annotations

import numpy as np

from straylight.sky.ephemeris import PLANETS
from straylight.sky.limb import earth_blocks
from straylight.sky.runs import scene_rows
from straylight.sky.vectors import norm, unit
from straylight.sources.body_magnitudes import moon_v_magnitude, planet_v_magnitudes
from straylight.sources.context import Samples, SourceContext
from straylight.sources.photometry import AU_KM, V_SUN_VEGA, solar_like_fraction
from straylight.sources.rates import BandRates

__all__ = ["InFieldBodies", "Moon", "SolarBodySkip", "Sun"]


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
