"""The earthshine look-up tables' nodes and cache keys.

The nodes of the sunlit Earth's table (:class:`LUTSettings`: the Sun's zenith angle, the line
of sight's zenith angle and its azimuth from the Sun, and the satellite's radius) and of the
moonlit Earth's (:class:`MoonlitSettings`: the Moon's zenith angle, the line of sight's zenith
angle and azimuth, and the roll), whether the instrument is mirror-symmetric about the lamp's
vertical plane (:func:`mirror_symmetric`: the azimuth then runs over 0-180 deg only), the
tables' formats and build times per node, and where a table is cached: under a digest of
everything it depends on (:func:`cache_path`, :func:`lut_key`, :func:`moonlit_key`).  The
builds are :mod:`straylight.sources.earthshine.sunlit_build` (sunlit) and
:mod:`straylight.sources.earthshine.moonlit_build` (moonlit).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from straylight.errors import InputError
from straylight.util.io import cache_dir

__all__ = [
    "LUT_FORMAT",
    "MOONLIT_FORMAT",
    "LUT_BUILD_SECONDS_PER_NODE",
    "MOONLIT_LUT_BUILD_SECONDS_PER_NODE",
    "LOS_RISE_WIDTH_DEG",
    "LUTSettings",
    "MoonlitInputs",
    "MoonlitSettings",
    "mirror_symmetric",
    "cache_path",
    "lut_key",
    "moonlit_key",
]

# -- the sunlit Earth ---------------------------------------------------------------------------
#: bumped whenever the table's content or layout changes: part of the cache key
LUT_FORMAT = 5

#: The tables' build with its validation, CPU seconds per (node, door state) at the default
#: config: the sunlit table's nodes each sum the full Earth grid, the moonlit table's its coarse
#: grid, the blocks the aperture plane cuts split ``models.earthshine.cut_block_split`` times per
#: side in both.  The build is announced with the time they give over the cores it runs on, and
#: ``straylight plan`` quotes it.  Measured by ``bench/table_build.py`` (docs/performance.md);
#: a change to the Earth grids, their split or the nodes wants them measured again.
LUT_BUILD_SECONDS_PER_NODE = 0.042e-3
MOONLIT_LUT_BUILD_SECONDS_PER_NODE = 0.009e-3


class _TableNodes:
    """What the two tables' node settings share: counting their nodes (a subclass gives
    ``nodes(radius_km, earth_radius_km, symmetric)``, the node arrays of its angles)."""

    def radius_nodes(self) -> int:
        """Nodes along the satellite's geocentric radius: 1 (the table is built at one radius)."""
        return 1

    def node_count(self, radius_km: float, earth_radius_km: float, symmetric: bool = True) -> int:
        """Nodes of the table (per door state): its angles' nodes times :meth:`radius_nodes`;
        ``symmetric``: the instrument mirror-symmetric about the lamp's vertical plane
        (:func:`mirror_symmetric`: azimuth 0-180 deg, else 0-360).

        Parameters
        ----------
        radius_km : float
            The orbit's smallest geocentric radius, km (sets the cap's edge).
        earth_radius_km : float
            The Earth's radius, km.
        symmetric : bool
            Whether the azimuth runs over 0-180 deg only.

        Returns
        -------
        int
        """
        sizes = [a.size for a in self.nodes(radius_km, earth_radius_km, symmetric)]
        return int(np.prod(sizes)) * self.radius_nodes()


@dataclass(frozen=True)
class LUTSettings(_TableNodes):
    """Node spacing (deg).  The Sun's zenith angle is sampled at ``sun_zenith_step_deg`` where the
    terminator crosses the visible cap (60 deg to the cap's edge) and 2.5 times coarser above;
    beyond the cap's edge the cap is dark (one node at 180).  The line of sight's zenith angle at
    ``los_zenith_step_deg`` above the limb and 2.5 times coarser below it (never observable).

    Attributes
    ----------
    sun_zenith_step_deg, los_zenith_step_deg, azimuth_step_deg : float
        Node steps, deg, each within [0.05, 30].
    n_radius : int
        Radius nodes between the orbit's extremes (1: one node at the mean radius).

    Raises
    ------
    InputError
        When a step is outside [0.05, 30] deg or ``n_radius`` < 1.
    """

    # the defaults validate within the table's share of the tolerance with the default PST (the
    # build's validation, in the products' models record; figures in docs/performance.md); a
    # coarser azimuth step cuts the peaks near 0 and 180 deg
    sun_zenith_step_deg: float = 0.5
    los_zenith_step_deg: float = 1.0
    azimuth_step_deg: float = 2.5
    n_radius: int = 1  # radius nodes between the orbit's extremes (1: a circular orbit)

    def __post_init__(self):
        for k in ("sun_zenith_step_deg", "los_zenith_step_deg", "azimuth_step_deg"):
            v = getattr(self, k)
            if not 0.05 <= v <= 30.0:
                raise InputError(f"models.earthshine.lut.{k} = {v}: must be within [0.05, 30] deg")
        if self.n_radius < 1:
            raise InputError(f"models.earthshine.lut.n_radius = {self.n_radius}: needs >= 1")

    def radius_nodes(self) -> int:
        """Nodes along the satellite's geocentric radius: :attr:`n_radius`."""
        return self.n_radius

    def nodes(self, radius_km: float, earth_radius_km: float, symmetric: bool):
        """(sun zenith, line-of-sight zenith, azimuth) node arrays, deg.

        Parameters
        ----------
        radius_km : float
            The orbit's smallest geocentric radius, km (sets the cap's edge).
        earth_radius_km : float
            The Earth's radius, km.
        symmetric : bool
            Whether the azimuth runs over 0-180 deg only (else 0-360).

        Returns
        -------
        sun_zenith_deg, los_zenith_deg, azimuth_deg : ndarray
            Ascending node arrays, deg.
        """
        cap = np.degrees(
            np.arccos(earth_radius_km / radius_km)
        )  # the cap's edge beyond nadir, = limb depression
        hs, hl, ha = self.sun_zenith_step_deg, self.los_zenith_step_deg, self.azimuth_step_deg

        zs = np.unique(np.r_[_steps(0.0, 60.0, 2.5 * hs), _steps(60.0, 90.0 + cap + hs, hs), 180.0])
        limb = 90.0 + cap
        # the aperture plane meets the Earth's edge at a line-of-sight zenith angle of ``cap``:
        # there the direct earthshine starts from 0 (nothing enters from behind the plane) and
        # grows steeply, so the nodes are 4 times finer over the first degrees of that rise
        rise = _steps(max(cap - 0.5, 0.0), cap + LOS_RISE_WIDTH_DEG, hl / 4.0)
        zl = np.unique(np.r_[_steps(0.0, limb, hl), rise, _steps(limb, 180.0, 2.5 * hl)])
        az = _steps(0.0, 180.0 if symmetric else 360.0, ha)
        return zs, zl, az


#: deg above the zenith angle where the Earth's edge crosses the aperture plane over which the
#: line-of-sight nodes are finer: the coefficients rise steeply there, and the regular nodes
#: alone err by a large part of the total (docs/performance.md)
LOS_RISE_WIDTH_DEG = 6.0


def _steps(a: float, b: float, h: float) -> np.ndarray:
    """Nodes from a to b (both included) at most h apart, evenly spaced."""
    n = max(int(np.ceil((b - a) / h - 1e-9)), 1)
    return np.linspace(a, b, n + 1)


def mirror_symmetric(off) -> bool:
    """PST(theta, phi) == PST(theta, -phi) and the door shade likewise (sampled check).

    Parameters
    ----------
    off : EarthGrid
        The off-field transfer and Earth grid.

    Returns
    -------
    bool
    """
    th = np.r_[np.linspace(0.0, 89.0, 90), np.linspace(91.0, 180.0, 90)][:, None]  # 90: grazing, noise
    ph = np.linspace(0.0, 360.0, 73)[None, :]
    if not np.allclose(off.pst(th, ph), off.pst(th, 360.0 - ph), rtol=1e-9):
        return False
    return all(
        np.allclose(off.door_factor(th, ph, s), off.door_factor(th, 360.0 - ph, s), atol=1e-9)
        for s in off.door_states_deg
    )


# -- the moonlit Earth --------------------------------------------------------------------------
#: bumped whenever the moonlit table's content or layout changes: part of its cache key
MOONLIT_FORMAT = 3


@dataclass(frozen=True)
class MoonlitSettings(_TableNodes):
    """Node spacing (deg) of the moonlit Earth's table.  Its coefficients depend on one angle
    more than the sunlit Earth's: the telescope's roll is set by the Sun, not by the lamp, so
    the table runs over the Moon's zenith angle at the satellite, the line of sight's zenith
    angle, its azimuth from the Moon's about the vertical, and the roll (the angle about the
    line of sight from its upward vertical to the telescope's +x axis).  The defaults validate
    within the moonlit grid's share of the tolerance at full Moon (:func:`build_moonlit_lut`;
    figures in docs/performance.md, measured by bench/run.py moonlit_grid).

    Attributes
    ----------
    moon_zenith_step_deg, los_zenith_step_deg, azimuth_step_deg, roll_step_deg : float
        Node steps, deg, each within [0.5, 45].

    Raises
    ------
    InputError
        When a step is outside [0.5, 45] deg.
    """

    moon_zenith_step_deg: float = 5.0
    los_zenith_step_deg: float = 4.0
    azimuth_step_deg: float = 10.0
    roll_step_deg: float = 15.0

    def __post_init__(self):
        for k in ("moon_zenith_step_deg", "los_zenith_step_deg", "azimuth_step_deg", "roll_step_deg"):
            v = getattr(self, k)
            if not 0.5 <= v <= 45.0:
                raise InputError(f"models.earthshine.moonlit_lut.{k} = {v}: must be within [0.5, 45] deg")

    def nodes(self, radius_km: float, earth_radius_km: float, symmetric: bool):
        """(Moon zenith, line-of-sight zenith, azimuth, roll) node arrays, deg.  Beyond the cap's
        edge plus one step the Moon lights none of the visible cap (one node at 180).

        Parameters
        ----------
        radius_km : float
            The orbit's smallest geocentric radius, km (sets the cap's edge).
        earth_radius_km : float
            The Earth's radius, km.
        symmetric : bool
            Whether the azimuth runs over 0-180 deg only (else 0-360).

        Returns
        -------
        moon_zenith_deg, los_zenith_deg, azimuth_deg, roll_deg : ndarray
            Ascending node arrays, deg.
        """
        cap = np.degrees(np.arccos(earth_radius_km / radius_km))

        hz, hl = self.moon_zenith_step_deg, self.los_zenith_step_deg
        zm = np.unique(np.r_[_steps(0.0, min(90.0 + cap + hz, 180.0), hz), 180.0])
        limb = 90.0 + cap
        # the aperture plane meets the Earth's edge at a line-of-sight zenith angle of ``cap``:
        # there the direct earthshine starts from 0 (nothing enters from behind the plane) and
        # grows steeply, so the nodes are 4 times finer over the first degrees of that rise
        rise = _steps(max(cap - 0.5, 0.0), cap + LOS_RISE_WIDTH_DEG, hl / 4.0)
        zl = np.unique(np.r_[_steps(0.0, limb, hl), rise, _steps(limb, 180.0, 2.5 * hl)])
        az = _steps(0.0, 180.0 if symmetric else 360.0, self.azimuth_step_deg)
        roll = _steps(0.0, 360.0, self.roll_step_deg)
        return zm, zl, az, roll


# -- the cache ------------------------------------------------------------------------------------
def cache_path(prefix: str, key: str) -> Path:
    """Where the table ``prefix`` with digest ``key`` is cached (it may not exist yet).

    Parameters
    ----------
    prefix : str
        The table's kind (``"earthshine_lut"``, ``"moonlit_lut"``).
    key : str
        Its digest (:func:`lut_key`, :func:`moonlit_key`).

    Returns
    -------
    Path
        ``<cache dir>/<prefix>_<key>.npz``.
    """
    return cache_dir() / f"{prefix}_{key}.npz"


def _digest(prefix: str, off, earth_radius_km, radius_range_km, settings, *items) -> str:
    """16 hex digits of sha256 over ``prefix``, the PST, the door and Earth settings, the Earth's
    radius and the orbit's radii (km), the node ``settings``, and the table's own ``items``."""
    items = (round(earth_radius_km, 6), tuple(round(r, 3) for r in radius_range_km), settings) + items
    h = hashlib.sha256(prefix.encode())
    h.update(np.ascontiguousarray(off.pst.values).tobytes())
    h.update(
        np.ascontiguousarray(off.pst.theta_deg).tobytes() + np.ascontiguousarray(off.pst.phi_deg).tobytes()
    )
    h.update(
        repr(
            (off.door, off.door_states_deg, off.pixel_area_m2, off.field_radius_deg, off.earthshine) + items
        ).encode()
    )
    return h.hexdigest()[:16]


def lut_key(
    off,
    earth_radius_km,
    radius_range_km,
    settings: LUTSettings,
    floor: float = 0.0,
    avoidance_deg: tuple = (30.0, 80.0, 50.0),
) -> str:
    """Digest of everything the table depends on (PST, door, cap grid, albedo, radii, nodes).

    Parameters
    ----------
    off, earth_radius_km, radius_range_km, settings, floor, avoidance_deg
        As for :func:`build_earthshine_lut` (radii in km, floor in e-/s/pix per photon s-1 m-2
        of the Sun at 1 AU, angles in deg).

    Returns
    -------
    str
        16 hex digits.
    """
    return _digest(
        f"format {LUT_FORMAT}",
        off,
        earth_radius_km,
        radius_range_km,
        settings,
        f"{floor:.6g}",
        tuple(float(a) for a in avoidance_deg),
    )


class MoonlitInputs(NamedTuple):
    """Everything the moonlit table depends on (in :func:`moonlit_key`'s order)."""

    off: object
    """The off-field transfer and Earth grid (an EarthGrid)."""
    earth_radius_km: float
    radius_range_km: tuple
    """The orbit's smallest and largest geocentric radius, km."""
    settings: MoonlitSettings
    grid: tuple
    """(n_gamma, n_psi) of the coarse Earth-cap grid."""
    floor: float
    """The darkest sky, e-/s/pix per photon s-1 m-2 of the Sun at 1 AU; 0: no validation."""
    moon_max: float
    """The brightest Moon's irradiance over the Sun's at 1 AU, dimensionless."""
    dark_limb_min_deg: float = 30.0
    """The dark-limb avoidance angle, deg."""


def moonlit_key(
    off,
    earth_radius_km,
    radius_range_km,
    settings: MoonlitSettings,
    grid,
    floor: float,
    moon_max: float,
    dark_limb_min_deg: float,
) -> str:
    """Digest of everything the moonlit table depends on.

    Parameters
    ----------
    off, earth_radius_km, radius_range_km, settings, grid, floor, moon_max, dark_limb_min_deg
        As for :func:`build_moonlit_lut` (radii in km, floor in e-/s/pix per photon s-1 m-2 of
        the Sun at 1 AU, moon_max dimensionless, angle in deg).

    Returns
    -------
    str
        16 hex digits.
    """
    return _digest(
        f"moonlit format {MOONLIT_FORMAT}",
        off,
        earth_radius_km,
        radius_range_km,
        settings,
        tuple(int(g) for g in grid),
        f"{floor:.6g}",
        f"{moon_max:.6g}",
        float(dark_limb_min_deg),
    )


def _cached(
    prefix: str, key: str, what: str, load, build, log, expected_cpu_s: float | None = None, workers: int = 1
):
    """load(path) of the cached table ``prefix_key.npz``, else build(), saved there.  A build is
    announced once, as a warning (so a command with no logging set up shows it too), with its
    expected time from ``expected_cpu_s`` (seconds on one core) over ``workers`` cores.  One
    process at a time builds a table (a lock file beside it): another one that needs the same
    table waits for that build and reads it."""
    import fcntl

    path = cache_path(prefix, key)
    if path.exists():
        return load(path), path
    try:  # before the build: a folder that cannot take the table fails now, not minutes later
        path.parent.mkdir(parents=True, exist_ok=True)
        lock = open(path.with_suffix(".lock"), "w")
    except OSError as exc:
        raise InputError(
            f"STRAYLIGHT_CACHE = {path.parent}: cannot write the {what} table there ({exc.strerror})"
        ) from exc
    with lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes, or the process dies
        if path.exists():  # built by the process that held the lock
            return load(path), path
        return _build_and_save(path, what, build, log, expected_cpu_s, workers), path


def _build_and_save(path: Path, what: str, build, log, expected_cpu_s, workers: int):
    """build() announced (as :func:`_cached` says) and saved at ``path``; the table."""
    if log is not None:
        eta = (
            f", ~{expected_cpu_s / max(workers, 1):.0f} s on {workers} core{'s' if workers > 1 else ''}"
            if expected_cpu_s
            else ""
        )
        log.warning(
            "building the %s look-up table once%s; later runs read it from %s", what, eta, path.parent
        )
    lut = build()
    lut.save(path)
    return lut
