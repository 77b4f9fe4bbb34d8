"""Observing geometry of (time, pointing) samples and the avoidance constraints it is judged by.

:func:`observing_geometry` gathers, for broadcastable samples, every geometric quantity the
stray-light physics needs: the bodies in the telescope frame (:mod:`straylight.sky.frames`),
the Earth's limb and blockage (:mod:`straylight.sky.limb`), the lunar phase, the door opening
and the violated constraints (:class:`Constraints`, from the instrument config).  Vectors are
Cartesian, GCRS/ICRS axes, last axis of length 3, broadcast over the leading axes
(:mod:`straylight.sky.vectors`): a (T, 1, 3) satellite position against (1, P, 3) pointing
vectors gives (T, P) results, and (N, 3) against (N, 3) gives N paired samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from straylight.sky.frames import TelescopeFrame, telescope_frame
from straylight.sky.limb import earth_blocks, limb_geometry
from straylight.sky.runs import SceneRuns, scene_rows
from straylight.sky.vectors import angle_between_deg, unit

__all__ = [
    "VIOLATION_BITS",
    "VIOLATION_NAMES",
    "Constraints",
    "DoorState",
    "body_geometry",
    "moon_phase",
    "observing_geometry",
    "violation_mask_attrs",
    "violation_names",
]


# -- constraints ------------------------------------------------------------------------------
#: Violation bit flags, in the order of :data:`VIOLATION_NAMES`.
VIOLATION_NAMES = ("sun", "moon", "bright_limb", "dark_limb", "earth_occultation")
VIOLATION_BITS = {name: 1 << i for i, name in enumerate(VIOLATION_NAMES)}


def violation_mask_attrs() -> dict:
    """CF attributes of a violated-constraint bit mask: ``flag_masks`` with the bits and
    ``flag_meanings`` with their names, blank-separated in the same order (CF 1.11 sect. 3.5)."""
    return {
        "units": "1",
        "long_name": "violated-constraint bit mask (0 = no constraint violated)",
        "flag_masks": np.array(list(VIOLATION_BITS.values()), dtype=np.uint8),
        "flag_meanings": " ".join(VIOLATION_BITS),
    }


@dataclass(frozen=True)
class DoorState:
    """One state of the aperture door: its opening (deg) and the Sun's smallest off-axis angle
    (deg) that allows it, itself allowed or not (``min_inclusive``)."""

    opening_deg: float
    sun_angle_min_deg: float
    min_inclusive: bool


@dataclass(frozen=True)
class Constraints:
    """Avoidance angles (deg), door rules and the limb's height above the surface (km: the top
    of the atmosphere the bright and dark limb angles are measured to) from the instrument
    config."""

    sun_min_deg: float
    moon_min_deg: float
    bright_limb_min_deg: float
    dark_limb_min_deg: float
    door_states: tuple[DoorState, ...]
    limb_height_km: float = 0.0

    def door_opening_deg(self, sun_angle_deg: np.ndarray) -> np.ndarray:
        """Door opening angle for the Sun's off-axis angle; 0 where no state is allowed.

        States are tried from the widest opening down; a state is allowed when the Sun is
        beyond its minimum angle (``>`` or ``>=`` as the state says).

        Parameters
        ----------
        sun_angle_deg : ndarray
            The Sun's off-axis angle, deg.
        """
        s = np.asarray(sun_angle_deg, dtype=float)
        out = np.zeros_like(s)
        for state in sorted(self.door_states, key=lambda d: d.opening_deg):  # widest last wins
            ok = s >= state.sun_angle_min_deg if state.min_inclusive else s > state.sun_angle_min_deg
            out = np.where(ok, state.opening_deg, out)
        return out

    def violations(
        self,
        sun_angle_deg,
        moon_angle_deg,
        bright_limb_angle_deg,
        dark_limb_angle_deg,
        earth_limb_angle_deg,
    ) -> np.ndarray:
        """Bit mask of violated constraints (see :data:`VIOLATION_BITS`); 0 = observable.

        Each constraint is violated strictly below its threshold: a pointing exactly at the
        avoidance angle is allowed (the paper gives minimum angles).

        Parameters
        ----------
        sun_angle_deg : array_like
            Angle between the line of sight and the Sun, deg.
        moon_angle_deg : array_like
            Angle between the line of sight and the Moon, deg.
        bright_limb_angle_deg : array_like
            Angle between the line of sight and the Earth's sunlit limb, deg.
        dark_limb_angle_deg : array_like
            Angle between the line of sight and the Earth's dark limb, deg.
        earth_limb_angle_deg : array_like
            Angle between the line of sight and the Earth's limb, deg (negative below it).
        """
        flags = np.zeros(np.broadcast(sun_angle_deg, moon_angle_deg).shape, dtype=np.uint8)
        flags |= np.where(np.asarray(sun_angle_deg) < self.sun_min_deg, VIOLATION_BITS["sun"], 0).astype(
            np.uint8
        )
        flags |= np.where(np.asarray(moon_angle_deg) < self.moon_min_deg, VIOLATION_BITS["moon"], 0).astype(
            np.uint8
        )
        flags |= np.where(
            np.asarray(bright_limb_angle_deg) < self.bright_limb_min_deg, VIOLATION_BITS["bright_limb"], 0
        ).astype(np.uint8)
        flags |= np.where(
            np.asarray(dark_limb_angle_deg) < self.dark_limb_min_deg, VIOLATION_BITS["dark_limb"], 0
        ).astype(np.uint8)
        flags |= np.where(
            np.asarray(earth_limb_angle_deg) <= 0.0, VIOLATION_BITS["earth_occultation"], 0
        ).astype(np.uint8)
        return flags


def violation_names(flags: int) -> list[str]:
    """Names of the constraints set in one violation bit mask.

    Parameters
    ----------
    flags : int
        A violation bit mask (:data:`VIOLATION_BITS`).
    """
    return [name for name in VIOLATION_NAMES if int(flags) & VIOLATION_BITS[name]]


# -- the whole geometry of a sample ------------------------------------------------------------
def moon_phase(sun_km: np.ndarray, moon_km: np.ndarray, observer_km: np.ndarray):
    """Lunar phase angle (Sun-Moon-observer, deg; 0 = full) and illuminated fraction.

    The illuminated fraction of the disc is k = (1 + cos(alpha)) / 2 (Meeus 1998, eq. 48.1).
    Also returns the elongation Sun-observer-Moon (deg; 180 at full Moon, the paper's "phase").

    Parameters
    ----------
    sun_km : ndarray
        Geocentric position of the Sun, km, shape (..., 3).
    moon_km : ndarray
        Geocentric position of the Moon, km, shape (..., 3).
    observer_km : ndarray
        Geocentric position of the observer, km, shape (..., 3).
    """
    alpha = angle_between_deg(sun_km - moon_km, observer_km - moon_km)
    fraction = 0.5 * (1.0 + np.cos(np.radians(alpha)))
    elongation = angle_between_deg(sun_km - observer_km, moon_km - observer_km)
    return alpha, fraction, elongation


def body_geometry(
    satellite_km: np.ndarray,
    bodies_km: dict[str, np.ndarray],
    frame: TelescopeFrame,
    earth_radius_km: float,
    runs: SceneRuns | None = None,
) -> dict[str, np.ndarray]:
    """Each body's off-axis angle, azimuth and Earth test in the telescope ``frame`` (see
    :func:`observing_geometry`): ``<body>_angle_deg``, ``<body>_phi_deg`` and
    ``<body>_earth_blocked``, arrays of the samples' shape.  ``runs``: the samples' scene runs
    when known (:class:`SceneRuns`).

    Parameters
    ----------
    satellite_km : ndarray
        Geocentric position of the telescope, km, shape (..., 3).
    bodies_km : dict of str to ndarray
        Geocentric position of each body, km, shape (..., 3).
    frame : TelescopeFrame
        The telescope frame of each sample.
    earth_radius_km : float
        The Earth's radius used for the Earth-blocking test, km.
    runs : SceneRuns, optional
        The samples' scene runs when known (found otherwise).
    """
    sat = np.asarray(satellite_km, dtype=float)
    # a cube time step shares the satellite and the bodies: each body's direction once per step
    return _body_geometry(bodies_km, frame, earth_radius_km, scene_rows(sat, *bodies_km.values(), runs=runs))


def _body_geometry(bodies_km, frame, earth_radius_km, rows: SceneRuns) -> dict[str, np.ndarray]:
    """:func:`body_geometry` with the samples' ``scene_rows(satellite, *bodies_km.values())``:
    every body's direction and Earth test once per run, then all bodies' angles in one pass."""
    d_run = unit(np.stack(rows.vectors[1:]) - rows.vectors[0])  # (bodies, runs, 3)
    shape = np.broadcast_shapes(rows.shape, frame.z.shape[:-1])
    index = (
        rows.index if shape == rows.shape else np.broadcast_to(rows.index.reshape(rows.shape), shape).ravel()
    )
    blocked_run = earth_blocks(rows.vectors[0], d_run, earth_radius_km)  # (bodies, runs)
    blocked = np.take(blocked_run, index, axis=1).reshape(
        (len(bodies_km),) + shape
    )  # np.take: faster than [:, index]
    theta, phi = frame.theta_phi_runs_deg(d_run, index, shape)
    out: dict[str, np.ndarray] = {}
    for i, name in enumerate(bodies_km):
        out[f"{name}_angle_deg"] = theta[i]  # = off-axis angle theta in the telescope frame
        out[f"{name}_phi_deg"] = phi[i]
        out[f"{name}_earth_blocked"] = blocked[i]
    return out


def observing_geometry(
    satellite_km: np.ndarray,
    bodies_km: dict[str, np.ndarray],
    los: np.ndarray,
    earth_radius_km: float,
    constraints: Constraints,
    frame: TelescopeFrame | None = None,
    runs: SceneRuns | None = None,
) -> dict[str, np.ndarray]:
    """Every geometric quantity the stray-light physics needs, for broadcastable samples.

    Parameters
    ----------
    satellite_km : (..., 3) geocentric satellite position, km.
    bodies_km : body name -> (..., 3) geocentric position, km (must include 'sun' and 'moon').
    los : (..., 3) unit line-of-sight vectors.
    earth_radius_km : spherical Earth radius, km.
    constraints : avoidance angles, door rules and the limb's height.
    frame : the samples' ``telescope_frame(los, sun - satellite)`` when the caller already has
        it (it is then not computed again).
    runs : the samples' scene runs when the caller knows them (:class:`SceneRuns`, e.g. a cube
        region's time steps): runs of samples that share the satellite and every body.

    Returns
    -------
    dict of arrays of the broadcast sample shape: angles in deg (``*_deg``), booleans, the
    door opening (deg, 0 = not allowed), the violation bit mask and ``observable``.
    ``earth_limb_angle_deg`` is the LOS's elevation above the solid Earth's limb;
    ``bright_limb_angle_deg`` the angle to the nearest sunlit point of the Earth's disc and
    ``dark_limb_angle_deg`` to the nearest dark point of its limb, both seen at the top of the
    atmosphere (``constraints.limb_height_km``; :func:`~straylight.sky.limb.limb_geometry`).
    For every body: ``<body>_angle_deg`` (from the LOS, = the off-axis angle theta),
    ``<body>_phi_deg`` (azimuth in the telescope frame) and ``<body>_earth_blocked``.
    """
    sat = np.asarray(satellite_km, dtype=float)
    sun = bodies_km["sun"]
    if frame is None:
        frame = telescope_frame(los, sun - sat)
    limb = limb_geometry(
        sat, frame.z, sun, earth_radius_km, runs=runs, limb_height_km=constraints.limb_height_km
    )
    rows = scene_rows(sat, *bodies_km.values(), runs=runs)
    out = _body_geometry(bodies_km, frame, earth_radius_km, rows)
    names = list(bodies_km)
    alpha, fraction, elongation = (
        rows.expand(v)
        for v in moon_phase(
            rows.vectors[1 + names.index("sun")], rows.vectors[1 + names.index("moon")], rows.vectors[0]
        )
    )
    shape = out["sun_angle_deg"].shape
    out["moon_phase_angle_deg"] = np.broadcast_to(alpha, shape)
    out["moon_illuminated_fraction"] = np.broadcast_to(fraction, shape)
    out["moon_elongation_deg"] = np.broadcast_to(elongation, shape)
    out["earth_limb_angle_deg"] = limb.earth_limb_angle_deg
    out["zenith_angle_deg"] = limb.zenith_angle_deg
    out["limb_is_bright"] = limb.limb_is_bright
    out["bright_limb_angle_deg"] = limb.bright_limb_angle_deg
    out["dark_limb_angle_deg"] = limb.dark_limb_angle_deg
    out["door_opening_deg"] = constraints.door_opening_deg(out["sun_angle_deg"])
    flags = constraints.violations(
        out["sun_angle_deg"],
        out["moon_angle_deg"],
        limb.bright_limb_angle_deg,
        limb.dark_limb_angle_deg,
        limb.earth_limb_angle_deg,
    )
    out["violations"] = flags
    out["observable"] = (flags == 0) & (out["door_opening_deg"] > 0)
    return out
