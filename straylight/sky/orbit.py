"""The telescope's orbit: position in GCRS (km) for arrays of UTC times.

Two models:

* :class:`CircularOrbit` - a circular orbit with secular J2 perturbations: the node regresses at
  the analytic rate dOmega/dt = -3/2 n J2 (Re/a)^2 cos i, and the argument of latitude advances
  at n + domega/dt + dM/dt (Vallado 2013, "Fundamentals of Astrodynamics", eqs. 9-41 to 9-43,
  e = 0).  Axes: the equator and equinox of J2000 (GCRS to within the ~0.02 deg frame bias and
  precession since 2000, which a mean-element orbit model does not resolve anyway).
* :class:`TLEOrbit` - a two-line element set propagated with SGP4 (the ``sgp4`` package), TEME
  rotated to GCRS with astropy.

Both give ``position_gcrs_km(times) -> (..., 3)``, ``epoch_time`` and ``period_s``.  A campaign
far from the orbit's epoch is warned about when its config is validated
(:func:`warn_if_epoch_far`).
"""

from __future__ import annotations

import hashlib
import logging
import os
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from straylight.errors import ConfigError, InputError
from straylight.sky.timeutil import parse_utc

__all__ = [
    "TLE_EPOCH_WARN_DAYS",
    "CIRCULAR_EPOCH_WARN_DAYS",
    "EPOCH_WARNED_ENV",
    "EarthModel",
    "CircularOrbit",
    "TLEOrbit",
    "orbit_from_settings",
    "epoch_gap_warning",
    "warn_if_epoch_far",
]

#: Days between a TLE's epoch and a campaign time beyond which we warn.  A TLE's mean elements
#: put a low orbit within about a km at epoch, but SGP4 cannot predict the drag (solar activity),
#: whose along-track error grows with time: after weeks it reaches the order of a minute of the
#: orbit (hundreds of km), which moves the Earth-limb angles and the observable windows' edges.
#: A warning threshold, not a model parameter (the positions do not depend on it).
TLE_EPOCH_WARN_DAYS = 30.0
#: Days between a circular orbit's epoch and a campaign time beyond which we warn.  The circular
#: model is mean elements with J2 alone (no drag, no reboosts): over a year its node regresses
#: ~2200 deg at 400 km and 41.5 deg, so a 10 km difference of altitude (the station's decay and
#: reboosts) moves the node by ~11 deg, and the phase along the orbit is lost entirely.
#: A warning threshold, not a model parameter.
CIRCULAR_EPOCH_WARN_DAYS = 365.0
#: Environment variable holding the last epoch warning's key: a warning given by the workflow's
#: parse (or `straylight run`) is not repeated by every job and worker process it starts.
EPOCH_WARNED_ENV = "STRAYLIGHT_ORBIT_EPOCH_WARNED"


@dataclass(frozen=True)
class EarthModel:
    """Spherical Earth and its gravity field, values from the campaign config."""

    radius_km: float
    gm_km3_s2: float
    j2: float

    def __post_init__(self):
        for name in ("radius_km", "gm_km3_s2"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ConfigError(f"earth.{name}: must be a positive number, got {v!r}")
        if not (np.isfinite(self.j2) and 0 <= self.j2 < 0.01):
            raise ConfigError(f"earth.j2: must be in [0, 0.01), got {self.j2!r}")


@dataclass(frozen=True)
class CircularOrbit:
    """Circular orbit with secular J2 nodal precession.

    Parameters
    ----------
    altitude_km : height above the spherical Earth, km.
    inclination_deg : orbit inclination, deg.
    raan_deg : right ascension of the ascending node at ``epoch``, deg.
    arg_latitude_deg : argument of latitude (angle from the node along the orbit) at ``epoch``.
    epoch : UTC epoch, ISO 8601.
    earth : :class:`EarthModel`.
    """

    altitude_km: float
    inclination_deg: float
    raan_deg: float
    arg_latitude_deg: float
    epoch: str
    earth: EarthModel

    def __post_init__(self):
        if not (np.isfinite(self.altitude_km) and self.altitude_km > 100.0):
            raise ConfigError(
                f"orbit.circular.altitude_km: must be > 100 km (below that the orbit decays), "
                f"got {self.altitude_km!r}"
            )
        if not (0.0 <= self.inclination_deg <= 180.0):
            raise ConfigError(
                f"orbit.circular.inclination_deg: must be in [0, 180], got {self.inclination_deg!r}"
            )
        parse_utc(self.epoch, "orbit.circular.epoch")

    @property
    def semi_major_axis_km(self) -> float:
        """Semi-major axis a, the Earth's radius plus the altitude, km."""
        return self.earth.radius_km + self.altitude_km

    @property
    def mean_motion_rad_s(self) -> float:
        """Keplerian mean motion n = sqrt(GM / a^3), rad/s."""
        return float(np.sqrt(self.earth.gm_km3_s2 / self.semi_major_axis_km**3))

    @property
    def _j2_factor(self) -> float:
        return 1.5 * self.earth.j2 * (self.earth.radius_km / self.semi_major_axis_km) ** 2

    @property
    def nodal_rate_rad_s(self) -> float:
        """Secular J2 regression of the node, dOmega/dt = -3/2 n J2 (Re/a)^2 cos i."""
        return -self.mean_motion_rad_s * self._j2_factor * np.cos(np.radians(self.inclination_deg))

    @property
    def arg_latitude_rate_rad_s(self) -> float:
        """du/dt = n [1 + 3/4 J2 (Re/a)^2 ((5 cos^2 i - 1) + (3 cos^2 i - 1))] for e = 0."""
        c2 = np.cos(np.radians(self.inclination_deg)) ** 2
        return self.mean_motion_rad_s * (1.0 + 0.5 * self._j2_factor * ((5 * c2 - 1) + (3 * c2 - 1)))

    @property
    def period_s(self) -> float:
        """Nodal (draconic) period 2 pi / (du/dt), s."""
        return float(2 * np.pi / self.arg_latitude_rate_rad_s)

    @cached_property
    def _epoch_time(self):
        """The epoch as an astropy Time, parsed once (a cube region asks for it once)."""
        return parse_utc(self.epoch, "orbit.circular.epoch")

    @property
    def epoch_time(self):
        """The epoch (UTC Time)."""
        return self._epoch_time

    def position_gcrs_km(self, times) -> np.ndarray:
        """Position (km, GCRS axes) for UTC times of any shape -> shape + (3,).

        Parameters
        ----------
        times : str, sequence of str or astropy.time.Time
            UTC times, any shape.
        """
        t = parse_utc(times)
        dt_s = np.asarray((t - self._epoch_time).to_value("s"), dtype=float)
        raan = np.radians(self.raan_deg) + self.nodal_rate_rad_s * dt_s
        u = np.radians(self.arg_latitude_deg) + self.arg_latitude_rate_rad_s * dt_s
        inc = np.radians(self.inclination_deg)
        a = self.semi_major_axis_km
        cu, su = np.cos(u), np.sin(u)
        co, so = np.cos(raan), np.sin(raan)
        ci, si = np.cos(inc), np.sin(inc)
        x = a * (co * cu - so * su * ci)
        y = a * (so * cu + co * su * ci)
        z = a * (su * si)
        return np.stack([x, y, z], axis=-1)


class TLEOrbit:
    """SGP4 propagation of a two-line element set, output rotated from TEME to GCRS.

    Raises
    ------
    InputError
        For a TLE that does not parse (bad checksum or format) or whose propagation fails
        (decayed orbit, eccentricity out of range); the message gives the SGP4 error code.
    """

    _SGP4_ERRORS = {
        1: "mean eccentricity out of range",
        2: "mean motion negative",
        3: "perturbed eccentricity out of range",
        4: "semi-latus rectum negative",
        5: "epoch elements are sub-orbital",
        6: "satellite has decayed",
    }

    def __init__(self, line1: str, line2: str, source: str = "orbit.tle"):
        from sgp4.api import Satrec

        self.source = source
        line1, line2 = line1.strip(), line2.strip()
        for i, line in enumerate((line1, line2), start=1):
            if len(line) < 69 or not line[68].isdigit():
                raise InputError(f"{source}: line {i} is not a 69-column TLE line: {line!r}")
            digits = sum(int(c) for c in line[:68] if c.isdigit()) + line[:68].count("-")
            if digits % 10 != int(line[68]):
                raise InputError(
                    f"{source}: line {i} checksum {line[68]} does not match computed {digits % 10}: {line!r}"
                )
        try:
            self.satrec = Satrec.twoline2rv(line1, line2)
        except Exception as exc:
            raise InputError(f"{source}: cannot parse TLE ({exc})") from exc
        self.line1, self.line2 = line1, line2

    @property
    def epoch_time(self):
        """The element set's epoch (UTC Time; SGP4 counts its epochs in UTC)."""
        from astropy.time import Time

        return Time(self.satrec.jdsatepoch, self.satrec.jdsatepochF, format="jd", scale="utc")

    @property
    def period_s(self) -> float:
        """Period from the TLE's mean motion (SGP4's no_kozai, rad/min), s."""
        return float(2 * np.pi / self.satrec.no_kozai * 60.0)

    def position_teme_km(self, times) -> np.ndarray:
        """SGP4 position in TEME, km, shape + (3,).

        Parameters
        ----------
        times : str, sequence of str or astropy.time.Time
            UTC times, any shape.
        """
        t = parse_utc(times)
        jd1 = np.atleast_1d(np.asarray(t.jd1, dtype=float)).ravel()
        jd2 = np.atleast_1d(np.asarray(t.jd2, dtype=float)).ravel()
        err, r, _ = self.satrec.sgp4_array(jd1, jd2)
        if np.any(err != 0):
            code = int(err[err != 0][0])
            when = t.ravel()[np.argmax(err != 0)].isot if t.shape else t.isot
            raise InputError(
                f"{self.source}: SGP4 error {code} ({self._SGP4_ERRORS.get(code, 'unknown')}) at {when}"
            )
        return r.reshape(np.shape(t.jd1) + (3,))

    def position_gcrs_km(self, times) -> np.ndarray:
        """Position in GCRS, km, shape + (3,) (TEME -> GCRS with astropy, offline IERS).

        Parameters
        ----------
        times : str, sequence of str or astropy.time.Time
            UTC times, any shape.
        """
        from astropy import units as u
        from astropy.coordinates import GCRS, TEME, CartesianRepresentation

        t = parse_utc(times)
        r = self.position_teme_km(t)
        rep = CartesianRepresentation(np.moveaxis(r, -1, 0) * u.km)
        gcrs = TEME(rep, obstime=t).transform_to(GCRS(obstime=t))
        xyz = gcrs.cartesian.xyz.to_value(u.km)
        return np.moveaxis(xyz, 0, -1)


def orbit_from_settings(orbit, earth: EarthModel):
    """The orbit model named by the campaign's ``orbit.model``.

    Parameters
    ----------
    orbit : straylight.config.settings.OrbitSection
        The config's typed ``orbit`` section (a TLE file's path already resolved): ``model``,
        ``circular`` (``altitude_km``, km; ``inclination_deg``, ``raan_deg``,
        ``arg_latitude_deg``, deg; ``epoch``, UTC) or ``tle`` (``file``, or ``line1`` and
        ``line2``).
    earth : EarthModel
        The Earth (radius, GM, J2) the circular orbit precesses about.

    Returns
    -------
    CircularOrbit or TLEOrbit
        The orbit.

    Raises
    ------
    ConfigError
        For an unknown model, or a TLE that cannot be read.
    """
    if orbit.model == "circular":
        c = orbit.circular
        return CircularOrbit(
            altitude_km=float(c.altitude_km),
            inclination_deg=float(c.inclination_deg),
            raan_deg=float(c.raan_deg),
            arg_latitude_deg=float(c.arg_latitude_deg),
            epoch=str(c.epoch),
            earth=earth,
        )
    if orbit.model == "tle":
        return TLEOrbit(*_tle_lines(orbit.tle))
    raise ConfigError(f"orbit.model: {orbit.model!r} is not one of 'circular', 'tle'")


def _tle_lines(tle) -> tuple[str, str, str]:
    """(line 1, line 2, source) of the config's typed ``orbit.tle`` (None when absent): a file
    (its path absolute or as the caller resolved it) or the two lines."""
    if tle is not None and tle.file is not None:
        path = tle.file
        try:
            lines = [ln for ln in open(path, encoding="ascii").read().splitlines() if ln.strip()]
        except OSError as exc:
            raise ConfigError(f"orbit.tle.file: cannot read {path!r}: {exc}") from exc
        ones = [ln for ln in lines if ln.startswith("1 ")]
        twos = [ln for ln in lines if ln.startswith("2 ")]
        if not ones or not twos:
            raise InputError(f"{path}: no TLE line pair (lines starting '1 ' and '2 ') found")
        return ones[0], twos[0], str(path)
    if tle is not None and tle.line1 is not None and tle.line2 is not None:
        return tle.line1, tle.line2, "orbit.tle"
    raise ConfigError("orbit.tle: give either 'file' or both 'line1' and 'line2'")


def epoch_gap_warning(what: str, epoch, start, end, limit_days: float, reason: str) -> str | None:
    """The warning for a campaign [start, end] whose farthest time is more than ``limit_days``
    from the orbit's ``epoch`` (Times), else None: ``what`` (e.g. ``orbit.tle epoch``), the
    epoch, its gap to campaign.start and the largest gap, then ``reason``.

    Parameters
    ----------
    what : str
        What the epoch is, first in the message (e.g. ``orbit.tle epoch``).
    epoch : astropy.time.Time
        The orbit's epoch.
    start : astropy.time.Time
        The campaign's start.
    end : astropy.time.Time
        The campaign's end.
    limit_days : float
        The largest gap that is not warned about, days.
    reason : str
        Why the gap matters, last in the message.
    """
    to_start = float((start - epoch).to_value("day"))
    largest = max(abs(to_start), abs(float((end - epoch).to_value("day"))))
    if largest <= limit_days:
        return None
    side = "before" if to_start >= 0 else "after"
    return (
        f"{what} {epoch.isot[:19]} is {abs(to_start):.0f} days {side} campaign.start {start.isot[:19]} "
        f"(up to {largest:.0f} days over the campaign): {reason}"
    )


def warn_if_epoch_far(orbit, start, end, where: str) -> str | None:
    """Warn (one logged line) when the campaign [start, end] reaches farther from the orbit's
    epoch than :data:`TLE_EPOCH_WARN_DAYS` (a TLE) or :data:`CIRCULAR_EPOCH_WARN_DAYS` (a
    circular orbit); ``where`` (the config file) starts the line.  Once per run: a process that
    inherits :data:`EPOCH_WARNED_ENV` with this warning's key stays quiet.  Returns the warning.

    ``orbit``: the config's typed ``orbit`` section (:func:`orbit_from_settings`), a TLE
    file's path already resolved.

    Parameters
    ----------
    orbit : OrbitSection
        The config's typed ``orbit`` section, a TLE file's path already resolved.
    start : str or astropy.time.Time
        The campaign's start (UTC).
    end : str or astropy.time.Time
        The campaign's end (UTC).
    where : str
        What starts the logged line (the config file).
    """
    if orbit.model == "circular":
        epoch = parse_utc(orbit.circular.epoch, "orbit.circular.epoch")
        msg = epoch_gap_warning(
            "orbit.circular.epoch",
            epoch,
            start,
            end,
            CIRCULAR_EPOCH_WARN_DAYS,
            "the circular orbit is propagated from its epoch with J2 alone (no drag, no reboosts), "
            f"so beyond {CIRCULAR_EPOCH_WARN_DAYS:g} days its node and phase say little about the real "
            "orbit; set the epoch near the campaign",
        )
    else:
        line1, line2, source = _tle_lines(orbit.tle)
        label = "orbit.tle epoch" if source == "orbit.tle" else f"orbit.tle ({source}) epoch"
        msg = epoch_gap_warning(
            label,
            TLEOrbit(line1, line2, source).epoch_time,
            start,
            end,
            TLE_EPOCH_WARN_DAYS,
            f"SGP4 positions of a low orbit are unreliable beyond {TLE_EPOCH_WARN_DAYS:g} days of the TLE's "
            "epoch (the drag it cannot predict); use a TLE from the campaign's weeks",
        )
    if msg is None:
        return None
    msg = f"{where}: {msg}"
    key = hashlib.sha256(msg.encode()).hexdigest()[:16]
    if os.environ.get(EPOCH_WARNED_ENV) != key:
        logging.getLogger(__name__).warning("warning: %s", msg)
        os.environ[EPOCH_WARNED_ENV] = key
    return msg
