"""JPL DE405 planetary and lunar ephemeris, evaluated from its Chebyshev coefficients.

The coefficients come from the PyPI package ``de405`` (Standish 1998, JPL IOM 312.F-98-048):
one array ``jpl-<body>.npy`` per body of shape (n_sets, 3, n_coeff), the sets tiling
[JD 2305424.5, 2525008.5] TDB in equal granules.  Positions are in km, ICRS axes; the Moon is
geocentric, every other body barycentric, and the Earth follows from the Earth-Moon barycentre
and the Earth/Moon mass ratio EMRAT:  r_earth = r_emb - r_moon / (1 + EMRAT).

:class:`DE405` evaluates any number of times at once: the granule index and the Chebyshev
polynomials are computed for the whole time array, so there is no Python loop over times:
sorted time grids (the pipeline's case) take one small matrix product per 4-32 day granule;
unsorted times gather each time's coefficients and use the Clenshaw recurrence.
"""

from __future__ import annotations

import os
from functools import cached_property

import numpy as np
from astropy.time import Time

from straylight.errors import EphemerisRangeError, InputError
from straylight.sky.timeutil import quiet_dubious_years, utc_to_tdb_jd

__all__ = [
    "BODIES",
    "PLANETS",
    "DE405",
    "radec_distance",
    "default_ephemeris",
    "check_in_ephemeris",
]

#: Bodies with a position relative to the Earth's centre, in the order used in products.
BODIES = (
    "sun",
    "moon",
    "mercury",
    "venus",
    "mars",
    "jupiter",
    "saturn",
    "uranus",
    "neptune",
    "pluto",
)
PLANETS = BODIES[2:]


def __getattr__(name: str):
    """``DE405_SPAN``: the span of the JPL DE405 ephemeris as calendar dates, for messages
    (:attr:`DE405.span` of the installed package; the exact bounds: DE405.jd_start, jd_end)."""
    if name == "DE405_SPAN":
        return default_ephemeris().span
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# name in `BODIES` -> coefficient file of the de405 package (Earth-Moon barycentre is internal)
_FILES = {b: f"jpl-{b}.npy" for b in BODIES}
_FILES["earthmoon"] = "jpl-earthmoon.npy"


class DE405:
    """Vectorised evaluator of the DE405 ephemeris.

    Parameters
    ----------
    data_dir : directory holding the ``de405`` package's ``.npy`` files.  Default: the
        installed ``de405`` package.

    Notes
    -----
    Validity: TDB Julian dates 2305424.5 to 2525008.5 (1599-12-09 to 2201-02-20, :attr:`span`,
    from the package's constants ``jalpha`` and ``jomega``); outside,
    :class:`~straylight.errors.EphemerisRangeError`.  Accuracy is that of DE405 itself
    (inner planets ~ km, Moon ~ m over the modern era); evaluation adds < 1 mm.
    """

    def __init__(self, data_dir: str | os.PathLike | None = None):
        if data_dir is None:
            import de405  # the data package; imported here so the module loads without it

            data_dir = os.path.dirname(de405.__file__)
        self.data_dir = os.fspath(data_dir)
        constants = np.load(os.path.join(self.data_dir, "constants.npy"))
        self.constants = {k.decode("ascii"): float(v) for k, v in constants}
        self.jd_start = self.constants["jalpha"]
        self.jd_end = self.constants["jomega"]
        self.emrat = self.constants["EMRAT"]
        self.au_km = self.constants["AU"]
        self._coefficients: dict[str, np.ndarray] = {}

    @cached_property
    def span(self) -> str:
        """The ephemeris's span as TDB calendar dates, ``"YYYY-MM-DD to YYYY-MM-DD"``: the package's
        bounds (constants ``jalpha``, ``jomega``, TDB Julian dates) through astropy's calendar."""
        start, end = Time([self.jd_start, self.jd_end], format="jd", scale="tdb").iso
        return f"{start[:10]} to {end[:10]}"

    # -- raw access -------------------------------------------------------------------------
    def coefficients(self, name: str) -> np.ndarray:
        """Chebyshev coefficient array of one body, (n_sets, 3, n_coeff), loaded once.

        Parameters
        ----------
        name : str
            The body, one of :data:`BODIES` (e.g. ``"moon"``).
        """
        if name not in _FILES:
            raise InputError(f"unknown body {name!r}; known: {', '.join(BODIES)}")
        if name not in self._coefficients:
            # mmap: a few MB are touched per evaluation instead of loading 54 MB up front
            self._coefficients[name] = np.load(os.path.join(self.data_dir, _FILES[name]), mmap_mode="r")
        return self._coefficients[name]

    def _check_range(self, jd1: np.ndarray, jd2: np.ndarray) -> None:
        jd = jd1 + jd2
        bad = ~((jd >= self.jd_start) & (jd <= self.jd_end))
        if np.any(bad):
            first = float(np.asarray(jd)[bad].ravel()[0])
            raise EphemerisRangeError(
                f"time TDB JD {first:.5f} is outside the DE405 range "
                f"{self.jd_start} to {self.jd_end} ({self.span}); "
                f"{int(bad.sum())} of {bad.size} times are out of range"
            )

    def _chebyshev(self, name: str, jd1: np.ndarray, jd2: np.ndarray) -> np.ndarray:
        """Raw series value (km) for TDB JD (jd1 + jd2) of any shape -> shape + (3,)."""
        coeffs = self.coefficients(name)
        n_sets, _, n_coeff = coeffs.shape
        days_per_set = (self.jd_end - self.jd_start) / n_sets
        # Subtract the large parts first to keep precision: (jd1 - jd_start) + jd2
        elapsed = (jd1 - self.jd_start) + jd2
        index = np.floor(elapsed / days_per_set).astype(np.int64)
        index = np.clip(index, 0, n_sets - 1)  # the very last instant belongs to the last set
        offset = elapsed - index * days_per_set
        x = 2.0 * offset / days_per_set - 1.0  # in [-1, 1]
        idx = index.ravel()
        xr = x.ravel()
        steps = np.flatnonzero(np.diff(idx))
        if idx.size > 64 and np.all(np.diff(idx) >= 0) and steps.size < idx.size // 64:
            # Sorted times spanning few granules (a campaign grid): Chebyshev table T_k(x),
            # then one small matrix product per granule instead of a per-time gather.
            cheb = np.empty((xr.size, n_coeff))
            cheb[:, 0] = 1.0
            if n_coeff > 1:
                cheb[:, 1] = xr
            for k in range(2, n_coeff):
                cheb[:, k] = 2.0 * xr * cheb[:, k - 1] - cheb[:, k - 2]
            value = np.empty((xr.size, 3))
            bounds = np.concatenate([[0], steps + 1, [idx.size]])
            for lo, hi in zip(bounds[:-1], bounds[1:]):
                value[lo:hi] = cheb[lo:hi] @ np.asarray(coeffs[idx[lo]]).T
        else:
            c = np.asarray(coeffs[idx])  # (N, 3, n_coeff)
            xc = xr[:, None]
            # Clenshaw recurrence for sum_k c_k T_k(x)
            b1 = np.zeros((xc.shape[0], 3))
            b2 = np.zeros_like(b1)
            two_x = 2.0 * xc
            for k in range(n_coeff - 1, 0, -1):
                b1, b2 = c[:, :, k] + two_x * b1 - b2, b1
            value = c[:, :, 0] + xc * b1 - b2
        return value.reshape(np.shape(x) + (3,))

    # -- positions --------------------------------------------------------------------------
    def positions_tdb(self, jd1, jd2=0.0, bodies=BODIES) -> dict[str, np.ndarray]:
        """Geocentric geometric positions, km, ICRS axes, for TDB Julian dates jd1 + jd2.

        Returns a dict body -> array of shape ``np.shape(jd1 + jd2) + (3,)``.

        Parameters
        ----------
        jd1 : float or array_like
            TDB Julian date, days (first part).
        jd2 : float or array_like, optional
            Second part of the TDB Julian date, days, broadcast with ``jd1``.
        bodies : iterable of str, optional
            The bodies to compute (default :data:`BODIES`).
        """
        jd1 = np.asarray(jd1, dtype=float)
        jd2 = np.asarray(jd2, dtype=float)
        jd1, jd2 = np.broadcast_arrays(jd1, jd2)
        self._check_range(jd1, jd2)
        bodies = tuple(bodies)
        for b in bodies:
            if b not in BODIES:
                raise InputError(f"unknown body {b!r}; known: {', '.join(BODIES)}")
        moon = self._chebyshev("moon", jd1, jd2)
        out: dict[str, np.ndarray] = {}
        earth = None
        for b in bodies:
            if b == "moon":
                out[b] = moon
                continue
            if earth is None:
                emb = self._chebyshev("earthmoon", jd1, jd2)
                earth = emb - moon / (1.0 + self.emrat)
            out[b] = self._chebyshev(b, jd1, jd2) - earth
        return out

    def positions(self, times, bodies=BODIES) -> dict[str, np.ndarray]:
        """Geocentric geometric positions (km, ICRS) for UTC times (ISO strings or Time).

        Parameters
        ----------
        times : str, sequence of str or astropy.time.Time
            UTC times (ISO strings or a ``Time``), any shape.
        bodies : iterable of str, optional
            The bodies to compute (default :data:`BODIES`).
        """
        jd1, jd2 = utc_to_tdb_jd(times)
        return self.positions_tdb(jd1, jd2, bodies)

    @cached_property
    def block_boundaries_jd(self) -> np.ndarray:
        """TDB Julian dates of the 32-day record boundaries (for edge-case tests)."""
        n = int(round((self.jd_end - self.jd_start) / self.constants["jdelta"]))
        return self.jd_start + self.constants["jdelta"] * np.arange(n + 1)


def radec_distance(position_km: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """RA (deg, [0, 360)), Dec (deg) and distance (km) of Cartesian ICRS vectors (..., 3).

    Parameters
    ----------
    position_km : ndarray
        Cartesian ICRS vectors, km, shape (..., 3).
    """
    x, y, z = np.moveaxis(np.asarray(position_km, dtype=float), -1, 0)
    rho = np.hypot(x, y)
    ra = np.degrees(np.arctan2(y, x)) % 360.0
    dec = np.degrees(np.arctan2(z, rho))
    return ra, dec, np.sqrt(rho * rho + z * z)


_DEFAULT: DE405 | None = None


def default_ephemeris() -> DE405:
    """A shared :class:`DE405` instance (coefficient files are memory-mapped once)."""
    global _DEFAULT
    if _DEFAULT is None:
        _DEFAULT = DE405()
    return _DEFAULT


def check_in_ephemeris(t: Time, field: str, given=None) -> None:
    """Refuse times outside DE405 in one line, without ERFA's warnings before it.

    ``field`` names the input (``--time``, ``time``); for several times the message names the
    first one out of range by its index (``sample i``).  ``given``: the text the user typed,
    quoted in place of the parsed time.

    Parameters
    ----------
    t : astropy.time.Time
        The time or times to check.
    field : str
        The input's name in the message (``--time``, ``time``).
    given : str, optional
        The text the user typed, quoted in the message in place of the parsed time.

    Raises
    ------
    EphemerisRangeError
    """
    eph = default_ephemeris()
    with quiet_dubious_years():
        jd1, jd2 = utc_to_tdb_jd(t, field)  # TDB through the spline of tdb_minus_tt_s for many times
        jd = np.ravel(jd1 + jd2)
        bad = np.flatnonzero(~((jd >= eph.jd_start) & (jd <= eph.jd_end)))
        if not bad.size:
            return
        i = int(bad[0])
        value = given if given is not None else t.ravel()[i].isot if t.shape else t.isot
    where = f"{field}: sample {i}" if jd.size > 1 else field
    count = f"; {bad.size} of {jd.size} samples are outside it" if jd.size > 1 else ""
    raise EphemerisRangeError(f"{where} = {value} is outside the DE405 range ({eph.span}){count}")
