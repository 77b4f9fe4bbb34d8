"""Point Source Transmission PST(theta, phi) (seed paper sect. 3): focal-plane irradiance over
the irradiance at the aperture, for a point source at off-axis angle theta and azimuth phi of
the telescope frame (phi = 0 towards the Sun's projection, the door side).

The matrix is read from a file and interpolated bilinearly in log10(PST), periodic in phi:

* CSV/ECSV table in long form with columns ``theta_deg, phi_deg, pst`` on a full grid;
* FITS: a 2-D image (theta rows x phi columns) with 1-D tables ``THETA`` and ``PHI`` extensions;
* Zarr: an xarray Dataset with variable ``pst`` on dims (theta_deg, phi_deg).

On load it must be finite and positive, with strictly increasing grids covering theta 0-180 deg
and phi 0-360 deg (phi 360, if present, equal to phi 0).  Anything else is refused with the
file, the field and the value.  Rows at theta 0 and 180 (the poles of the frame, where phi is
undefined) that vary with phi are replaced by their phi mean, with a logged warning.

No measured CSST matrix is public.  :func:`default_pst_grid` builds the embedded default from
the paper's anchors; it is an assumption to be replaced by the measured matrix (config
``pst.file``).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from straylight.errors import ConfigError, InputError
from straylight.sky.vectors import wrap_360_deg
from straylight.util.gridinterp import AxisCells, LinearGrid
from straylight.util.kernel_cache import njit

__all__ = [
    "DEFAULT_FIELD_RADIUS_DEG",
    "TAIL_90_LOG10",
    "BEHIND_APERTURE_DROP_DEX",
    "DEFAULT_ANCHORS_DEG_LOG10",
    "FIELD_EDGE_LOG10",
    "FIELD_EDGE_WIDTH_DEG",
    "DEFAULT_DOOR_SIDE_DEX",
    "default_anchors",
    "default_pst_grid",
    "PST",
    "load_pst",
    "write_pst_csv",
]

#: radius of the default field (deg): the 1.1 deg2 field of view (seed paper sect. 1) as a disc,
#: sqrt(1.1 / pi); :func:`load_pst` takes the instrument's own
DEFAULT_FIELD_RADIUS_DEG = float(np.sqrt(1.1 / np.pi))

# Anchors of the default PST, log10 PST (azimuthal mean) against theta (deg); log-linear between
# them.  Each anchor, its source, and the part of the curve it fixes (docs/pst.md):
#  - inside the field, PST = 1 by definition (the on-axis image); the field is imaged, not
#    scattered, so the direct path never takes the PST there (offfield.py: theta > field radius);
#  - field edge: out-of-field light 4-6 orders below in-field "at small incident angles" (paper
#    sect. 2.1): the field stop, PST = 1e-4 at the field radius (the top of the range) and no
#    ramp past it: PST <= 1e-4 everywhere outside the field;
#  - 5 deg: 1e-5, the middle of the paper's 4-6 orders (assumption: log-linear between the
#    edge and 30 deg would give 1e-4.2 at 5 deg; the baffle falls faster near the field);
#  - 30 deg: 1e-6 (paper sect. 2.1: "30 deg separation from Earth's limb, where the PST value is
#    approximately 1e-6");
#  - 30-90 deg: the large-angle tail, one log-linear segment to the instrument's
#    pst.tail_log10_at_90deg at 90 deg, fixed by the paper's CSST-versus-HST conclusion (sect.
#    3.3): CSST's median earthshine falls to HST's at 20 deg from the bright limb (WFC3 IHB fig.
#    9.2) 70 deg from the bright limb.  The paper does not give CSST's orbital phase, so the tail
#    is the value at which the median over the satellite's sunlit orbital phases of that
#    crossing is 70 deg (straylight.paper.tail_calibration, scripts/calibrate_pst_tail.py);
#    the Earth fills theta from the limb angle to 90 deg of the direct path, so this segment
#    sets the crossing;
#  - theta > 90 deg: behind the aperture plane, the door's Sp is 0 (door.py): these values are
#    never used by the direct path; they keep falling (3.6 dex over 90-180 deg) so that the PST's
#    tail bounds (PST.tail_max, influence_radius_deg) stay tight.
#: log10 PST at 90 deg for callers without an instrument file: the value of csst.yaml's
#: pst.tail_log10_at_90deg (tests/optics/test_pst_tail.py holds them equal)
TAIL_90_LOG10 = -9.57
#: drop of log10 PST from 90 to 180 deg (behind the aperture plane; never used by the direct path)
BEHIND_APERTURE_DROP_DEX = 3.6
#: the anchors the tail does not move: (theta deg, log10 PST)
DEFAULT_ANCHORS_DEG_LOG10 = (
    (5.0, -5.0),
    (30.0, -6.0),
)
#: the field edge's step: PST 1 up to this far inside the field radius (deg), 1e-4 at the radius
FIELD_EDGE_LOG10 = -4.0
FIELD_EDGE_WIDTH_DEG = 0.01
#: Door-side asymmetry: up to this many dex darker towards phi = 0 (assumption: the door and its
#: frame shade the sunward half of the sunshade; the paper says the PST is asymmetric in phi).
DEFAULT_DOOR_SIDE_DEX = 0.3


def default_anchors(
    field_radius_deg: float = DEFAULT_FIELD_RADIUS_DEG, tail_log10_at_90deg: float = TAIL_90_LOG10
) -> np.ndarray:
    """The default PST's anchors (theta deg, log10 PST).

    Parameters
    ----------
    field_radius_deg : float
        Radius of the field, deg.
    tail_log10_at_90deg : float
        log10 PST (azimuthal mean) at 90 deg, below the 30-deg anchor's -6 (the instrument's
        ``pst.tail_log10_at_90deg``).

    Returns
    -------
    ndarray, shape (n, 2)
        PST 1 in the field, the field stop's step to 1e-4 at its edge,
        :data:`DEFAULT_ANCHORS_DEG_LOG10`, the tail at 90 deg and
        :data:`BEHIND_APERTURE_DROP_DEX` below it at 180 deg.

    Raises
    ------
    ConfigError
        For a field radius outside the anchors, or a tail not below the 30-deg anchor.
    """
    r = float(field_radius_deg)
    if not FIELD_EDGE_WIDTH_DEG < r < DEFAULT_ANCHORS_DEG_LOG10[0][0]:
        raise ConfigError(
            f"detector.field_of_view_deg2: a field of radius {r:g} deg; the default PST needs "
            f"{FIELD_EDGE_WIDTH_DEG} < radius < {DEFAULT_ANCHORS_DEG_LOG10[0][0]} deg"
        )
    tail = float(tail_log10_at_90deg)
    if not (np.isfinite(tail) and tail < DEFAULT_ANCHORS_DEG_LOG10[-1][1]):
        raise ConfigError(
            f"pst.tail_log10_at_90deg: {tail_log10_at_90deg!r}; the default PST needs a finite value "
            f"below the 30-deg anchor's {DEFAULT_ANCHORS_DEG_LOG10[-1][1]:g}"
        )
    return np.array(
        ((0.0, 0.0), (r - FIELD_EDGE_WIDTH_DEG, 0.0), (r, FIELD_EDGE_LOG10))
        + DEFAULT_ANCHORS_DEG_LOG10
        + ((90.0, tail), (180.0, tail - BEHIND_APERTURE_DROP_DEX))
    )


def default_pst_grid(
    theta_step_deg: float = 0.5,
    phi_step_deg: float = 5.0,
    door_side_dex: float = DEFAULT_DOOR_SIDE_DEX,
    field_radius_deg: float = DEFAULT_FIELD_RADIUS_DEG,
    tail_log10_at_90deg: float = TAIL_90_LOG10,
):
    """The embedded default PST on a (theta, phi) grid: (theta_deg, phi_deg, pst[theta, phi]);
    its anchors: :func:`default_anchors` (assumptions with their sources beside them).

    Parameters
    ----------
    theta_step_deg, phi_step_deg : float
        Grid steps, deg (the anchors are nodes too).
    door_side_dex : float
        The door side's asymmetry, dex.
    field_radius_deg : float
        Radius of the field, deg.
    tail_log10_at_90deg : float
        log10 PST (azimuthal mean) at 90 deg.

    Returns
    -------
    theta_deg : ndarray, shape (n_theta,)
    phi_deg : ndarray, shape (n_phi,)
    pst : ndarray, shape (n_theta, n_phi)
        Dimensionless.
    """
    a = default_anchors(field_radius_deg, tail_log10_at_90deg)
    # the anchors and the asymmetry's break points are grid nodes: log10 PST is piecewise linear in
    # theta between them, so the bilinear interpolation is exact in theta (the field edge's step
    # is not smeared over a grid cell)
    theta = np.union1d(
        np.arange(0.0, 180.0 + theta_step_deg / 2, theta_step_deg), np.r_[a[:, 0], 10.0, 170.0]
    )
    phi = np.arange(0.0, 360.0 + phi_step_deg / 2, phi_step_deg)
    log_azavg = np.interp(theta, a[:, 0], a[:, 1])
    # asymmetry grows from 0 at the field edge to its full value beyond 10 deg; the azimuthal mean
    # of -(dex/2)(1 + cos phi) is -dex/2, so add dex/2 back to keep the azimuthal mean on the
    # anchors; and falls back to 0 over the last 10 deg: at theta = 180 phi is undefined (the pole
    # of the frame), so a phi-dependent value there would make the PST jump with direction
    r = float(field_radius_deg)
    ramp = (np.clip((theta - r) / (10.0 - r), 0.0, 1.0) * np.clip((180.0 - theta) / 10.0, 0.0, 1.0))[:, None]
    asym = door_side_dex * ramp * (0.5 - 0.5 * (1.0 + np.cos(np.radians(phi)))[None, :])
    return theta, phi, 10.0 ** (log_azavg[:, None] + asym)


@dataclass
class PST:
    """A Point Source Transmission matrix, interpolated bilinearly in log10(PST), periodic in phi.

    Parameters
    ----------
    theta_deg : ndarray, shape (n_theta,)
        Off-axis angles of the grid, strictly increasing over 0-180 deg.
    phi_deg : ndarray, shape (n_phi,)
        Azimuths of the grid, strictly increasing over 0-360 deg (phi = 0: the door side).
    values : ndarray, shape (n_theta, n_phi)
        PST, focal-plane over aperture irradiance (dimensionless, finite and > 0).
    source : str
        Where the matrix comes from (a file path, or the default), for error messages and records.

    Raises
    ------
    InputError
        For a matrix or grid that breaks the rules of the module doc.
    """

    theta_deg: np.ndarray
    phi_deg: np.ndarray
    values: np.ndarray  # (n_theta, n_phi)
    source: str = "default"

    def __post_init__(self):
        src = self.source
        th, ph, v = (
            np.asarray(self.theta_deg, float),
            np.asarray(self.phi_deg, float),
            np.asarray(self.values, float),
        )
        if v.shape != (th.size, ph.size):
            raise InputError(f"{src}: pst has shape {v.shape}, grids need ({th.size}, {ph.size})")
        for name, g, lo, hi in (("theta_deg", th, 0.0, 180.0), ("phi_deg", ph, 0.0, 360.0)):
            if not np.all(np.isfinite(g)):
                raise InputError(f"{src}: {name} holds non-finite values")
            if np.any(np.diff(g) <= 0):
                i = int(np.flatnonzero(np.diff(g) <= 0)[0])
                raise InputError(f"{src}: {name} is not strictly increasing at {g[i]} -> {g[i + 1]}")
        if th[0] > 0.0 or th[-1] < 180.0:
            raise InputError(f"{src}: theta_deg covers {th[0]}-{th[-1]}; it must cover 0-180 deg")
        if ph[0] > 0.0 or ph[-1] < 360.0 - (ph[1] - ph[0]) - 1e-9 or ph[-1] > 360.0:
            raise InputError(
                f"{src}: phi_deg covers {ph[0]}-{ph[-1]}; it must span 0-360 deg with a uniform step"
            )
        bad = ~np.isfinite(v) | (v <= 0)
        if bad.any():
            i, j = np.argwhere(bad)[0]
            raise InputError(
                f"{src}: pst = {float(v[i, j])} at theta {th[i]}, phi {ph[j]}: must be finite and > 0"
            )
        if ph[-1] == 360.0 and not np.allclose(v[:, -1], v[:, 0], rtol=1e-9):
            j = int(np.flatnonzero(~np.isclose(v[:, -1], v[:, 0], rtol=1e-9))[0])
            raise InputError(
                f"{src}: pst at theta {th[j]}, phi 360 = {v[j, -1]:g} differs from phi 0 = {v[j, 0]:g}; "
                "the matrix must be periodic"
            )
        for i in (0, th.size - 1):
            if th[i] in (0.0, 180.0) and np.ptp(np.log10(v[i])) > 1e-9:
                # theta 0 and 180 are the poles of the frame: one direction, whatever phi says.
                # A measured row that varies there would make the PST jump with direction, so it
                # is replaced by its (geometric) phi mean, and the change logged.
                mean = 10.0 ** np.mean(np.log10(v[i, :-1] if ph[-1] == 360.0 else v[i]))
                logging.getLogger(__name__).warning(
                    "%s: pst at theta %g varies with phi (%.3g-%.3g); replaced by its phi mean %.3g",
                    src,
                    th[i],
                    v[i].min(),
                    v[i].max(),
                    mean,
                )
                v = v.copy()
                v[i] = mean
        self.theta_deg, self.phi_deg, self.values = th, ph, v

    @cached_property
    def _interp(self):
        th, ph, v = self.theta_deg, self.phi_deg, np.log10(self.values)
        if ph[-1] < 360.0:  # close the period
            ph = np.append(ph, 360.0)
            v = np.concatenate([v, v[:, :1]], axis=1)
        return LinearGrid((th, ph), v * np.log(10.0))  # natural log: exp is cheaper than 10**

    def __call__(self, theta_deg, phi_deg) -> np.ndarray:
        """PST at (theta, phi) in degrees (any broadcastable shapes); phi wraps, theta clips."""
        th, ph = np.broadcast_arrays(np.asarray(theta_deg, float), np.asarray(phi_deg, float))
        th = np.clip(th, 0.0, 180.0)
        ph = wrap_360_deg(ph)
        return np.exp(self._interp(th, ph))

    @cached_property
    def _tail_max_reversed(self) -> np.ndarray:
        """The PST's largest value at or beyond each theta node, over phi (non-increasing in
        theta), in reverse order (increasing)."""
        return np.maximum.accumulate(self.values.max(axis=1)[::-1])

    def tail_max(self, theta_deg) -> np.ndarray:
        """The PST's largest value over every phi at ``theta_deg`` or beyond (any shape): the
        interpolant is bounded by its cell's corners, so this bounds it everywhere from theta
        out (from the node at or below theta).

        Parameters
        ----------
        theta_deg : array_like
            Off-axis angles, deg.
        """
        th = np.clip(np.asarray(theta_deg, float), 0.0, 180.0)
        k = np.searchsorted(self.theta_deg, th, side="right") - 1
        return self._tail_max_reversed[::-1][k]

    def influence_radius_deg(self, pst_limit) -> np.ndarray:
        """The smallest theta node beyond which the PST stays at or below ``pst_limit`` at every
        phi (array-valued): the interpolant is bounded by its cell's corners, so the bound holds
        between nodes too.  180 where no node qualifies (the limit is below the PST's tail).

        Parameters
        ----------
        pst_limit : array_like
            PST values, dimensionless.
        """
        # first node k with tail_max[k] <= limit (searchsorted on the reversed, increasing array)
        k = self.theta_deg.size - np.searchsorted(
            self._tail_max_reversed, np.asarray(pst_limit, float), side="right"
        )
        return np.where(
            k < self.theta_deg.size, self.theta_deg[np.minimum(k, self.theta_deg.size - 1)], 180.0
        )

    def beyond_influence_radius(self, theta_deg, pst_limit) -> np.ndarray:
        """Whether each ``theta_deg`` lies at or beyond :meth:`influence_radius_deg` of its
        ``pst_limit`` (broadcast), a radius of 180 counting as nowhere (False; NaN too): the
        same flags as ``(theta >= radius) & (radius < 180)``, found in one compiled pass with
        no search (theta's node from a table of uniform bins, as gridinterp locates cells; the
        node's tail maximum against the limit), faster than numpy's searchsorted over the
        nodes (docs/performance.md).

        Parameters
        ----------
        theta_deg : array_like
            Off-axis angles, deg.
        pst_limit : array_like
            PST values, dimensionless, broadcast with ``theta_deg``.
        """
        th, lim = np.broadcast_arrays(np.asarray(theta_deg, float), np.asarray(pst_limit, float))
        out = np.empty(th.size, np.bool_)
        ax, tail = self._node_finder
        # a radius at the last node counts only when that node is short of 180
        last_ok = ax.nodes.size - (2 if ax.nodes[-1] >= 180.0 else 1)
        _beyond_kernel(
            np.ascontiguousarray(th.ravel()),
            np.ascontiguousarray(lim.ravel()),
            ax.lo,
            ax.inv_width,
            ax.bin_cell,
            ax.nodes,
            tail,
            last_ok,
            out,
        )
        return out.reshape(th.shape)

    @cached_property
    def _node_finder(self):
        """(theta's cell finder, the tail maximum at each node, non-increasing)."""
        return AxisCells(self.theta_deg), np.ascontiguousarray(self._tail_max_reversed[::-1])

    def azimuthal_mean(self, theta_deg) -> np.ndarray:
        """The PST averaged over azimuth (72 azimuths, 5 deg apart) at off-axis angles ``theta_deg``
        (deg, any shape): dimensionless, of the shape of ``theta_deg``.

        Parameters
        ----------
        theta_deg : array_like
            Off-axis angles, deg.
        """
        phi = np.linspace(0.0, 360.0, 73)[:-1]
        return self(np.asarray(theta_deg)[..., None], phi).mean(axis=-1)


def load_pst(
    path: str | Path | None,
    field_radius_deg: float = DEFAULT_FIELD_RADIUS_DEG,
    tail_log10_at_90deg: float = TAIL_90_LOG10,
) -> PST:
    """Read a PST matrix file (see module doc).

    Parameters
    ----------
    path : str, Path or None
        The matrix file; None gives the embedded default.
    field_radius_deg : float
        Radius of the field, deg (the default's field stop).
    tail_log10_at_90deg : float
        log10 PST at 90 deg of the default (the instrument's ``pst.tail_log10_at_90deg``);
        not used with a file.

    Returns
    -------
    PST
    """
    if path is None:
        th, ph, v = default_pst_grid(
            field_radius_deg=field_radius_deg, tail_log10_at_90deg=tail_log10_at_90deg
        )
        return PST(th, ph, v, source="default (assumption, straylight.optics.pst.default_pst_grid)")
    p = Path(path)
    if not p.exists():
        raise InputError(f"pst.file: {p} does not exist")
    suffix = p.suffix.lower()
    try:
        if suffix == ".zarr" or p.is_dir():
            import xarray as xr

            ds = xr.open_zarr(p)
            da = ds["pst"].transpose("theta_deg", "phi_deg")
            return PST(da["theta_deg"].values, da["phi_deg"].values, da.values, source=str(p))
        if suffix in (".fits", ".fit"):
            from astropy.io import fits

            with fits.open(p) as h:
                return PST(
                    np.asarray(h["THETA"].data["theta_deg"]),
                    np.asarray(h["PHI"].data["phi_deg"]),
                    np.asarray(h[0].data, float),
                    source=str(p),
                )
        from astropy.table import Table

        from straylight.util.io import without_bom

        t = Table.read(without_bom(p), format="ascii.ecsv" if suffix == ".ecsv" else "ascii.csv", comment="#")
    except InputError:
        raise
    except Exception as exc:
        raise InputError(f"{p}: cannot read PST matrix ({exc})") from exc
    missing = [c for c in ("theta_deg", "phi_deg", "pst") if c not in t.colnames]
    if missing:
        raise InputError(f"{p}: missing column(s) {', '.join(missing)}; have {', '.join(t.colnames)}")
    th_all = np.asarray(t["theta_deg"], float)
    ph_all = np.asarray(t["phi_deg"], float)
    th, ph = np.unique(th_all), np.unique(ph_all)
    if th.size * ph.size != len(t):
        raise InputError(f"{p}: {len(t)} rows do not form a full theta x phi grid ({th.size} x {ph.size})")
    v = np.full((th.size, ph.size), np.nan)
    v[np.searchsorted(th, th_all), np.searchsorted(ph, ph_all)] = np.asarray(t["pst"], float)
    return PST(th, ph, v, source=str(p))


def write_pst_csv(pst: PST, path: str | Path) -> None:
    """Write ``pst`` to ``path`` as the CSV :func:`load_pst` reads (long form: ``theta_deg``,
    ``phi_deg``, ``pst``).

    Parameters
    ----------
    pst : PST
        The matrix.
    path : str or Path
        The CSV file to write (replaced if present).
    """
    th, ph = np.meshgrid(pst.theta_deg, pst.phi_deg, indexing="ij")
    lines = ["theta_deg,phi_deg,pst"] + [
        f"{a:.12g},{b:.12g},{c:.6e}" for a, b, c in zip(th.ravel(), ph.ravel(), pst.values.ravel())
    ]
    Path(path).write_text("\n".join(lines) + "\n")


@njit(cache=True, nogil=True)
def _beyond_kernel(theta, limit, lo, inv_width, bin_cell, nodes, tail, last_ok, out):
    """:meth:`PST.beyond_influence_radius` per sample: j, the node at or below theta (its bin's
    cell or the next); beyond the radius iff tail[min(j, last_ok)] <= limit (the tail maximum
    does not increase, so the first node within the limit is at or below j)."""
    n = nodes.size
    for p in range(theta.size):
        x = theta[p]
        if not x >= lo:  # NaN, or short of the first node: within every radius
            out[p] = False
            continue
        if x >= nodes[n - 1]:
            j = n - 1
        else:
            j = bin_cell[min(int((x - lo) * inv_width), bin_cell.size - 1)]
            if x >= nodes[j + 1]:
                j += 1
        out[p] = tail[min(j, last_ok)] <= limit[p]
