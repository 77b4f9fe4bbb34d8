"""Stray-light images of a detector from the stars in and near the field (seed paper sect. 4).

For a pointing, time, band and detector, every catalog star within the detector plus a margin
is placed on the focal plane through a TAN (gnomonic) WCS whose roll follows the telescope frame
(+x towards the Sun's projection, the door side; see :mod:`straylight.sky.frames`).  The image is
star map (e-/s) convolved with the star image (:class:`~straylight.optics.scatter.ScatterModel`):

* near field (r <= ``near_radius_px``): full-resolution FFT convolution (scipy ``oaconvolve``)
  with the core + halo kernel, tapered to zero between near_radius/2 and near_radius;
* far field: the rest of the halo, smooth, convolved on a grid binned by ``far_bin`` pixels
  (FFT, ``fftconvolve``) and interpolated back bilinearly.  ``far_bin = 1`` is the exact
  reference; the error of larger bins is measured in tests and bench/image.py.

A star off the chip is kept when its halo still exceeds ``halo_floor_e_per_s_per_pix`` somewhere
on the chip (bright stars reach far, faint ones not at all), up to ``margin_arcsec``; the binned
grid extends only as far as the kept stars need.

Ghost discs (:mod:`straylight.optics.ghosts`) are returned as a table and, optionally, painted in as
uniform discs holding exactly each ghost's energy.

Units: the image is in e- s-1 pixel-1; star fluxes from AB magnitudes with the band's AB zero
point and the unobstructed aperture pi D^2 / 4.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import signal

from straylight.errors import InputError
from straylight.image.focal_plane import FocalPlane, pointing_wcs
from straylight.optics.bandpass import Band
from straylight.optics.ghosts import GhostModel
from straylight.optics.scatter import ScatterModel, check_fluxes
from straylight.sky.vectors import radec_to_unit, unit

__all__ = [
    "STRIP_ROWS",
    "Aim",
    "DetectorImage",
    "DetectorOptics",
    "RenderSettings",
    "StarSelection",
    "Stars",
    "bodies_as_stars",
    "paint_discs",
    "render_detector",
    "select_stars",
    "star_fluxes_e_per_s",
]


def star_fluxes_e_per_s(mag_ab, band: Band, aperture_diameter_m: float) -> np.ndarray:
    """e-/s of stars of AB magnitude ``mag_ab`` in ``band`` through the full aperture.

    Parameters
    ----------
    mag_ab : array_like
        The stars' AB magnitudes in ``band``, mag.
    band : Band
        The band (throughput including QE).
    aperture_diameter_m : float
        The telescope's aperture diameter, m.
    """
    m = np.asarray(mag_ab, dtype=float)
    if not np.all(np.isfinite(m)):
        i = int(np.flatnonzero(~np.isfinite(m))[0])
        raise InputError(f"mag_{band.name}: row {i} is {m[i]!r}; magnitudes must be finite")
    area = np.pi * aperture_diameter_m**2 / 4.0
    return 10.0 ** (-0.4 * m) * band.ab_zero_point_photons_s_m2 * area


def _profile_table(fn, r_max_px: float, p_m: float):
    """fn(r_m) tabulated on a log-spaced radius grid (px) for fast interpolation."""
    r = np.concatenate([[0.0], np.geomspace(0.01, max(r_max_px, 1.0) * 1.5, 4000)])
    return r, fn(r * p_m)


def _interp_profile(table, r_px):
    r, v = table
    return np.interp(r_px, r, v)


def _reach_px(table, flux_e_per_s, floor, p_m):
    """Distance (px) beyond which a star's halo per pixel falls below ``floor``."""
    r, v = table
    per_pix = v * p_m * p_m  # fraction per pixel; beyond its peak it never increases
    k = int(np.argmax(per_pix))
    tail_r, tail_v = r[k:], per_pix[k:]
    threshold = floor / np.maximum(np.asarray(flux_e_per_s, float), 1e-300)
    # number of tail radii whose value reaches each star's threshold (tail is non-increasing)
    n_above = np.searchsorted(-tail_v, -threshold, side="right")
    return np.where(n_above > 0, tail_r[np.maximum(n_above - 1, 0)], 0.0)


def _linear_upsample_matrix(n_fine: int, n_coarse: int, offset: float, b: int):
    """Sparse (n_fine x n_coarse) bilinear weights; fine pixel i sits at coarse
    (i + offset + 0.5) / b - 0.5."""
    from scipy import sparse

    pos = (np.arange(n_fine) + offset + 0.5) / b - 0.5
    j0 = np.clip(np.floor(pos).astype(int), 0, n_coarse - 2)
    w1 = np.clip(pos - j0, 0.0, 1.0)
    rows = np.repeat(np.arange(n_fine), 2)
    cols = np.stack([j0, j0 + 1], axis=1).ravel()
    vals = np.stack([1.0 - w1, w1], axis=1).ravel()
    return sparse.csr_matrix((vals, (rows, cols)), shape=(n_fine, n_coarse))


def _radial_grid(half: int, step_px: float = 1.0) -> np.ndarray:
    y, x = np.mgrid[-half : half + 1, -half : half + 1].astype(float) * step_px
    return np.hypot(x, y)


def _taper_up(r, r0, r1):
    x = np.clip((r - r0) / (r1 - r0), 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * x)


def _deposit(shape, x, y, w) -> np.ndarray:
    """Cloud-in-cell deposit of weights at (x, y) (0-based pixel centres) on a grid."""
    grid = np.zeros(shape, dtype=np.float64)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - x0, y - y0
    for dx, dy, ww in (
        (0, 0, (1 - fx) * (1 - fy)),
        (1, 0, fx * (1 - fy)),
        (0, 1, (1 - fx) * fy),
        (1, 1, fx * fy),
    ):
        xi, yi = x0 + dx, y0 + dy
        ok = (xi >= 0) & (xi < shape[1]) & (yi >= 0) & (yi < shape[0])
        np.add.at(grid, (yi[ok], xi[ok]), (w * ww)[ok])
    return grid


@dataclass
class RenderSettings:
    """Approximation knobs of the renderer (each has a measured error, see bench/image.py)."""

    near_radius_px: int = 128
    far_bin: int = 8
    margin_arcsec: float = 1800.0  # hard cap on how far off the chip a star may sit
    halo_floor_e_per_s_per_pix: float = 1e-4  # a star counts where its halo exceeds this
    paint_ghosts: bool = True
    ghost_min_e_per_s_per_pix: float = 0.0


@dataclass
class DetectorImage:
    """A detector's stray-light image, e- s-1 pixel-1, float32 (rows, columns) of the rendered
    window (binned by ``meta["bin"]``, its corner at ``meta["cut_x0"]``, ``meta["cut_y0"]``),
    with its ghost table and the stars used (column -> array), its WCS and the settings used
    (``meta``)."""

    image_e_per_s_per_pix: np.ndarray
    ghosts: dict  # column -> array
    stars: dict  # column -> array (stars used)
    wcs: object
    meta: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Aim:
    """Where a detector looks: the boresight (ICRS, deg), the Sun's direction (unit vector from
    the telescope, ICRS axes: it sets the roll) and the detector (0-based, row-major)."""

    ra_deg: float
    dec_deg: float
    sun_direction: np.ndarray
    detector: int


@dataclass(frozen=True)
class Stars:
    """Catalog stars: positions (ICRS, deg) and detected rates through the full aperture (e-/s)."""

    ra_deg: np.ndarray
    dec_deg: np.ndarray
    flux_e_per_s: np.ndarray


@dataclass(frozen=True)
class DetectorOptics:
    """What images a star on a detector: the focal plane, the star image (core and scattering
    halo), the band's ghosts (None: no ghosts) and the chief ray's angle of incidence on the
    detector in deg (it sets the ghosts' offsets)."""

    fp: FocalPlane
    scatter: ScatterModel
    ghosts: GhostModel | None
    chief_ray_angle_deg: float


@dataclass
class StarSelection:
    """The stars that reach a detector (see :func:`select_stars`): catalog indices, chip pixel
    positions (0-based, full chip) and fluxes (e-/s)."""

    wcs: object
    index: np.ndarray
    x_pix: np.ndarray
    y_pix: np.ndarray
    flux_e_per_s: np.ndarray
    used_margin_px: float
    halo_table: tuple

    @property
    def n_on_chip(self) -> int:
        """Stars whose centre falls on the chip (0-based pixel centres, edges at -0.5 and n - 0.5)."""
        nx = self.wcs.pixel_shape[0] if self.wcs.pixel_shape else None
        ny = self.wcs.pixel_shape[1] if self.wcs.pixel_shape else None
        return int(
            np.sum(
                (self.x_pix >= -0.5)
                & (self.x_pix < nx - 0.5)
                & (self.y_pix >= -0.5)
                & (self.y_pix < ny - 0.5)
            )
        )


def select_stars(
    aim: Aim, stars: Stars, fp: FocalPlane, scatter: ScatterModel, settings: RenderSettings
) -> StarSelection:
    """Stars within the detector plus margin whose halo still exceeds the floor on the chip
    (or that sit within the near-field radius of it).  Cheap: no image is made.

    Parameters
    ----------
    aim : Aim
        The boresight, the Sun's direction (the roll) and the detector.
    stars : Stars
        The catalog stars and their detected rates through the full aperture, e-/s.
    fp : FocalPlane
        The focal plane.
    scatter : ScatterModel
        The star image (core and scattering halo).
    settings : RenderSettings
        The renderer's approximation knobs.
    """
    s = settings
    flux = check_fluxes(stars.flux_e_per_s, "star flux (e-/s)")
    wcs = pointing_wcs(aim.ra_deg, aim.dec_deg, aim.sun_direction, fp, aim.detector)
    wcs.pixel_shape = (fp.nx, fp.ny)
    ny, nx = fp.ny, fp.nx
    p_m = fp.pixel_size_mm / 1000.0
    sra, sdec = np.asarray(stars.ra_deg, float), np.asarray(stars.dec_deg, float)
    if sra.size:
        cen = wcs.pixel_to_world_values((nx - 1) / 2.0, (ny - 1) / 2.0)
        cvec = radec_to_unit(float(cen[0]), float(cen[1]))
        svec = radec_to_unit(sra, sdec, "star catalog")
        radius_deg = (np.hypot(nx, ny) / 2 * fp.pixel_scale_arcsec + s.margin_arcsec) / 3600.0
        near = svec @ cvec > np.cos(np.radians(min(radius_deg, 30.0)))
    else:
        near = np.zeros(0, bool)
    idx = np.flatnonzero(near)
    x, y = wcs.world_to_pixel_values(sra[idx], sdec[idx]) if idx.size else (np.zeros(0), np.zeros(0))
    x, y = np.asarray(x, float), np.asarray(y, float)
    margin_px = s.margin_arcsec / fp.pixel_scale_arcsec
    inside = (x > -margin_px) & (x < nx - 1 + margin_px) & (y > -margin_px) & (y < ny - 1 + margin_px)
    idx, x, y = idx[inside], x[inside], y[inside]
    f = flux[idx]
    halo_tab = _profile_table(scatter.halo_profile, np.hypot(nx, ny) + margin_px, p_m)
    reach = np.minimum(_reach_px(halo_tab, f, s.halo_floor_e_per_s_per_pix, p_m), margin_px)
    dx = np.maximum(np.maximum(-x, x - (nx - 1)), 0.0)
    dy = np.maximum(np.maximum(-y, y - (ny - 1)), 0.0)
    keep = np.hypot(dx, dy) <= np.maximum(reach, s.near_radius_px)
    used_margin_px = float(np.max(np.hypot(dx, dy)[keep], initial=0.0)) + s.near_radius_px
    return StarSelection(wcs, idx[keep], x[keep], y[keep], f[keep], used_margin_px, halo_tab)


#: Rows of the chip rendered at a time: bounds memory to ~ (rows + 2 near_radius) x width
#: float64 arrays, a few hundred MB for a 9216-pixel-wide chip, whatever the chip's height.
STRIP_ROWS = 512


def render_detector(
    aim: Aim,
    stars: Stars,
    optics: DetectorOptics,
    settings: RenderSettings | None = None,
    size_override: tuple[int, int] | None = None,
    window: tuple[int, int, int, int] | None = None,
    bin_factor: int = 1,
) -> DetectorImage:
    """Render the in-field stray light (core + scattering halo, ghosts) of one detector.

    ``size_override`` (ny, nx) renders a smaller image with the same pixel scale (tests).
    ``window`` (x0, y0, width, height), 0-based chip pixels: render only that cutout.
    ``bin_factor`` N: the image is the mean of N x N pixels (still e-/s per chip pixel); the
    window is trimmed to a multiple of N.  The WCS follows the window and the binning.
    The chip is rendered in strips of :data:`STRIP_ROWS` rows, so memory does not grow with
    the chip's height; the result equals a whole-chip rendering to FFT round-off.

    Parameters
    ----------
    aim : Aim
        The boresight, the Sun's direction (the roll) and the detector.
    stars : Stars
        The catalog stars and their detected rates through the full aperture, e-/s.
    optics : DetectorOptics
        The focal plane, the star image, the ghosts and the chief ray's angle.
    settings : RenderSettings, optional
        The renderer's approximation knobs (default: :class:`RenderSettings`).
    size_override : tuple of int, optional
        (ny, nx): a smaller image at the same pixel scale (tests).
    window : tuple of int, optional
        (x0, y0, width, height), 0-based chip pixels: only that cutout is rendered.
    bin_factor : int, optional
        N: each image pixel is the mean of N x N chip pixels (default 1).
    """
    s = settings or RenderSettings()
    if s.far_bin < 1 or s.near_radius_px < 4:
        raise InputError(
            f"render settings far_bin={s.far_bin}, near_radius_px={s.near_radius_px} out of range"
        )
    fp = optics.fp
    if size_override:
        fp = FocalPlane(
            size_override[1],
            size_override[0],
            fp.pixel_scale_arcsec,
            fp.pixel_size_mm,
            fp.columns,
            fp.rows,
            fp.gap_px,
        )
    nb = int(bin_factor)
    if nb < 1:
        raise InputError(f"--bin {bin_factor}: must be a positive integer")
    sel = select_stars(aim, stars, fp, optics.scatter, s)
    win = _window_in_chip(window, fp, nb)
    far = _far_field(sel, fp, s, win)
    gtab = _ghost_table(sel, fp, optics, aim.detector)
    paint = gtab if optics.ghosts is not None and s.paint_ghosts and sel.index.size else None
    out = _render_strips(sel, fp, _near_kernel(optics.scatter, s.near_radius_px, fp), far, paint, win, nb, s)
    wcs = _output_wcs(sel.wcs, win if window is not None or nb > 1 else None, nb, out.shape)
    stars_used = {
        "catalog_index": sel.index,
        "x_pix": sel.x_pix,
        "y_pix": sel.y_pix,
        "flux_e_per_s": sel.flux_e_per_s,
    }
    meta = {
        "far_bin": s.far_bin,
        "near_radius_px": s.near_radius_px,
        "margin_arcsec": s.margin_arcsec,
        "halo_floor": s.halo_floor_e_per_s_per_pix,
        "bin": nb,
        "cut_x0": win[0],
        "cut_y0": win[1],
    }
    return DetectorImage(out, gtab, stars_used, wcs, meta=meta)


def _output_wcs(wcs, win, nb: int, shape):
    """The image's WCS: the chip's, moved to the window ``win`` (None: the chip, unbinned) and
    binned by ``nb``, for an image of ``shape`` (rows, columns)."""
    if win is not None:
        wx0, wy0 = win[0], win[1]
        wcs = wcs.deepcopy()
        wcs.wcs.crpix = [(wcs.wcs.crpix[0] - wx0 - 0.5) / nb + 0.5, (wcs.wcs.crpix[1] - wy0 - 0.5) / nb + 0.5]
        wcs.wcs.cd = wcs.wcs.cd * nb
    wcs.pixel_shape = (shape[1], shape[0])
    return wcs


def _window_in_chip(window, fp: FocalPlane, nb: int) -> tuple[int, int, int, int]:
    """(x0, y0, width, height), 0-based chip pixels: ``window`` (default the chip) clipped to the
    chip and trimmed to a multiple of the binning ``nb``."""
    ny, nx = fp.ny, fp.nx
    wx0, wy0, ww, wh = window if window is not None else (0, 0, nx, ny)
    wx0, wy0 = max(int(wx0), 0), max(int(wy0), 0)
    ww, wh = min(int(ww), nx - wx0), min(int(wh), ny - wy0)
    ww, wh = ww - ww % nb, wh - wh % nb
    if ww <= 0 or wh <= 0:
        raise InputError(f"cutout {window} with --bin {nb}: no pixel of the {nx} x {ny} chip left")
    return wx0, wy0, ww, wh


def _near_kernel(scatter: ScatterModel, rn: int, fp: FocalPlane) -> np.ndarray:
    """The near-field kernel (core + halo, tapered to 0 between ``rn``/2 and ``rn`` pixels), full
    resolution, fraction of a star's flux per pixel."""
    p_m = fp.pixel_size_mm / 1000.0
    r_px = _radial_grid(rn)
    # float64: the core's peak is ~1e7 x the kernel's tail, beyond float32 FFT round-off
    return scatter.profile(r_px * p_m) * p_m * p_m * (1.0 - _taper_up(r_px, rn / 2, rn))


def _far_field(sel: StarSelection, fp: FocalPlane, s: RenderSettings, win) -> tuple:
    """The far field (the halo beyond ``near_radius_px``/2) convolved on a grid binned by
    ``far_bin`` covering the chip and the margin the kept stars need, e-/s per fine pixel, with
    the sparse bilinear weights back to the chip's rows and the window's columns."""
    x, y, f = sel.x_pix, sel.y_pix, sel.flux_e_per_s
    ny, nx = fp.ny, fp.nx
    p_m = fp.pixel_size_mm / 1000.0
    b, rn = s.far_bin, s.near_radius_px
    mpx = int(np.ceil(sel.used_margin_px))
    cny, cnx = int(np.ceil((ny + 2 * mpx) / b)) + 1, int(np.ceil((nx + 2 * mpx) / b)) + 1
    coarse_map = _deposit((cny, cnx), (x + mpx + 0.5) / b - 0.5, (y + mpx + 0.5) / b - 0.5, f)
    half_y = int(np.ceil((ny + mpx) / b)) + 1
    half_x = int(np.ceil((nx + mpx) / b)) + 1
    rc = np.hypot(
        np.arange(-half_x, half_x + 1, dtype=float)[None, :] * b,
        np.arange(-half_y, half_y + 1, dtype=float)[:, None] * b,
    )
    k_far = _interp_profile(sel.halo_table, rc)
    k_far *= (b * p_m) ** 2
    k_far *= _taper_up(rc, rn / 2, rn)
    del rc
    far_coarse = signal.fftconvolve(coarse_map, k_far, mode="same") / (b * b)  # per fine pixel
    del k_far, coarse_map
    wy = _linear_upsample_matrix(ny, cny, mpx, b)
    wx = _linear_upsample_matrix(nx, cnx, mpx, b)[win[0] : win[0] + win[2]]
    return far_coarse, wy, wx


def _ghost_table(sel: StarSelection, fp: FocalPlane, optics: DetectorOptics, detector: int) -> dict:
    """The table of every ghost disc of the kept stars (column -> array; empty without ghosts)."""
    idx, x, y, f = sel.index, sel.x_pix, sel.y_pix, sel.flux_e_per_s
    ghosts = optics.ghosts
    columns = ("star_index", "path", "x_pix", "y_pix", "radius_pix", "e_per_s_per_pix", "energy_e_per_s")
    if ghosts is None or not idx.size:
        return {k: np.zeros(0) for k in columns}
    ny, nx = fp.ny, fp.nx
    ox, oy = fp.detector_offset_px(detector)
    fx, fy = x - (nx - 1) / 2.0 + ox, y - (ny - 1) / 2.0 + oy  # focal-plane position from the axis
    rr = np.hypot(fx, fy)
    ux = np.where(rr > 0, fx / np.where(rr > 0, rr, 1), 1.0)
    uy = np.where(rr > 0, fy / np.where(rr > 0, rr, 1), 0.0)
    th = np.radians(optics.chief_ray_angle_deg)
    off = ghosts.centre_offsets_mm(th * ux, th * uy) / fp.pixel_size_mm  # (3, 2, n)
    radii = ghosts.radii_mm() / fp.pixel_size_mm
    # f is the detected rate (filter included): ghosts relative to the nominal image
    irr = ghosts.irradiance_relative_to_image_per_mm2() * fp.pixel_size_mm**2
    frac = ghosts.energy_relative_to_image()
    rows = []
    for k in range(3):
        rows.append(
            dict(
                star_index=idx,
                path=np.full(idx.size, k + 1),
                x_pix=x + off[k, 0],
                y_pix=y + off[k, 1],
                radius_pix=np.full(idx.size, radii[k]),
                e_per_s_per_pix=f * irr[k],
                energy_e_per_s=f * frac[k],
            )
        )
    return {c: np.concatenate([r[c] for r in rows]) for c in rows[0]}


def _render_strips(sel, fp, k_near, far, paint, win, nb, s) -> np.ndarray:
    """The window's image, float32, binned by ``nb``, rendered :data:`STRIP_ROWS` rows at a time:
    near field (``k_near``) + far field (``far``: :func:`_far_field`) + ghost discs (``paint``: the
    ghost table, None for none)."""
    x, y, f = sel.x_pix, sel.y_pix, sel.flux_e_per_s
    far_coarse, wy, wx = far
    wx0, wy0, ww, wh = win
    rn = s.near_radius_px
    out = np.zeros((wh // nb, ww // nb), dtype=np.float32)
    strip = max(nb, STRIP_ROWS // nb * nb)
    for y0 in range(wy0, wy0 + wh, strip):
        y1 = min(y0 + strip, wy0 + wh)
        # near field: stars within rn of the strip, on a grid padded by rn
        gy0, gx0 = y0 - rn, wx0 - rn
        near = (y >= gy0 - 1) & (y < y1 + rn + 1) & (x >= gx0 - 1) & (x < wx0 + ww + rn + 1)
        grid = _deposit((y1 - y0 + 2 * rn, ww + 2 * rn), x[near] - gx0, y[near] - gy0, f[near])
        part = signal.oaconvolve(grid, k_near, mode="same")[rn : rn + y1 - y0, rn : rn + ww]
        del grid
        part += (wx @ (wy[y0:y1] @ far_coarse).T).T
        if paint is not None:
            part += paint_discs(
                fp.ny, fp.nx, paint, s.ghost_min_e_per_s_per_pix, rows=(y0, y1), cols=(wx0, wx0 + ww)
            )
        if nb > 1:
            part = part.reshape((y1 - y0) // nb, nb, ww // nb, nb).mean(axis=(1, 3))
        out[(y0 - wy0) // nb : (y1 - wy0) // nb] = part
        del part
    return out


def paint_discs(ny, nx, g, min_irr, rows=None, cols=None) -> np.ndarray:
    """Uniform discs; each holds exactly its energy over the pixels whose centres it covers
    (on the whole chip).  ``rows`` (y0, y1) and ``cols`` (x0, x1) restrict the returned array
    to that part of the chip.

    Parameters
    ----------
    ny : int
        The chip's rows.
    nx : int
        The chip's columns.
    g : dict of str to ndarray
        The discs: ``x_pix``, ``y_pix`` (centres, chip pixels), ``radius_pix`` (chip pixels) and
        ``energy_e_per_s`` (e-/s).
    min_irr : float
        Discs fainter than this mean irradiance, e-/s per pixel, are left out.
    rows : tuple of int, optional
        (y0, y1): the chip rows returned (default: all).
    cols : tuple of int, optional
        (x0, x1): the chip columns returned (default: all).
    """
    ry0, ry1 = rows if rows is not None else (0, ny)
    rx0, rx1 = cols if cols is not None else (0, nx)
    out = np.zeros((ry1 - ry0, rx1 - rx0))
    for xc, yc, r, e in zip(g["x_pix"], g["y_pix"], g["radius_pix"], g["energy_e_per_s"]):
        if e / (np.pi * r * r) < min_irr:
            continue
        x0, x1 = int(np.floor(xc - r)), int(np.ceil(xc + r)) + 1
        y0, y1 = int(np.floor(yc - r)), int(np.ceil(yc + r)) + 1
        if y1 <= ry0 or y0 >= ry1 or x1 <= rx0 or x0 >= rx1:
            continue
        yy, xx = np.mgrid[y0:y1, x0:x1]
        disc = (xx - xc) ** 2 + (yy - yc) ** 2 <= r * r
        n_in = disc.sum()
        if n_in == 0:
            continue
        ok = disc & (xx >= max(rx0, 0)) & (xx < min(rx1, nx)) & (yy >= max(ry0, 0)) & (yy < min(ry1, ny))
        out[yy[ok] - ry0, xx[ok] - rx0] += e / n_in
    return out


def bodies_as_stars(campaign, time, ra_deg: float, dec_deg: float, band: str) -> tuple:
    """The Sun, Moon and planets inside the field at ``time`` as extra catalog stars:
    (ra_deg, dec_deg, mag_ab, names), arrays; a body in the field is a point source, left out of
    the background (:meth:`~straylight.sources.bodies.InFieldBodies.find`).

    Parameters
    ----------
    campaign : Campaign
        The campaign (its orbit and instrument).
    time : str or astropy.time.Time
        The time (UTC).
    ra_deg : float
        The boresight's right ascension, ICRS, deg.
    dec_deg : float
        The boresight's declination, ICRS, deg.
    band : str
        The band's name.
    """
    from straylight.sky.observing import sample_geometry, scene
    from straylight.sources.bodies import InFieldBodies
    from straylight.sources.context import SourceContext

    sc = scene(campaign.orbit, time)
    g = sample_geometry(
        sc,
        np.array([ra_deg]),
        np.array([dec_deg]),
        campaign.earth.radius_km,
        campaign.constraints,
        grid=False,
    )
    los = radec_to_unit(np.array([ra_deg]), np.array([dec_deg]))
    found = InFieldBodies(SourceContext(campaign)).find(sc.satellite_km, sc.bodies_km, los, g, [band])
    names = [k for k, v in found.items() if bool(np.ravel(v["in_field"])[0])]
    ra, dec = [], []
    for k in names:
        d = unit(sc.bodies_km[k][0] - sc.satellite_km[0])
        ra.append(float(np.degrees(np.arctan2(d[1], d[0])) % 360.0))
        dec.append(float(np.degrees(np.arcsin(d[2]))))
    mags = [float(np.ravel(found[k]["mag_ab"][band])[0]) for k in names]
    return np.array(ra), np.array(dec), np.array(mags), names
