"""Stray-light images of a detector from the stars in and near the field (seed paper sect. 4).

For a pointing, time, band and detector, every catalog star within the detector plus a margin
is placed on the focal plane through a TAN (gnomonic) WCS whose roll follows the telescope frame
(+x towards the Sun's projection, the door side; see :mod:`straylight.geometry`).  The image is
star map (e-/s) convolved with the star image (:class:`~straylight.scatter.ScatterModel`):

* near field (r <= ``near_radius_px``): full-resolution FFT convolution (scipy ``oaconvolve``)
  with the core + halo kernel, tapered to zero between near_radius/2 and near_radius;
* far field: the rest of the halo, smooth, convolved on a grid binned by ``far_bin`` pixels
  (FFT, ``fftconvolve``) and interpolated back bilinearly.  ``far_bin = 1`` is the exact
  reference; the error of larger bins is measured in tests and bench/image.py.

A star off the chip is kept when its halo still exceeds ``halo_floor_e_per_s_per_pix`` somewhere
on the chip (bright stars reach far, faint ones not at all), up to ``margin_arcsec``; the binned
grid extends only as far as the kept stars need.

Ghost discs (:mod:`straylight.ghosts`) are returned as a table and, optionally, painted in as
uniform discs holding exactly each ghost's energy.

Units: the image is in e- s-1 pixel-1; star fluxes from AB magnitudes with the band's AB zero
point and the unobstructed aperture pi D^2 / 4.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import signal

from .bandpass import Band
from .config import pixel_scale_arcsec
from .errors import InputError
from .geometry import radec_to_unit, telescope_frame, unit
from .ghosts import GhostModel
from .scatter import ScatterModel, check_fluxes


@dataclass(frozen=True)
class FocalPlane:
    nx: int
    ny: int
    pixel_scale_arcsec: float
    pixel_size_mm: float
    columns: int
    rows: int
    gap_px: float

    @property
    def n_detectors(self) -> int:
        return self.columns * self.rows

    def detector_offset_px(self, detector: int) -> tuple[float, float]:
        """Centre of detector ``detector`` (0-based, row-major) from the optical axis, pixels."""
        if not 0 <= detector < self.n_detectors:
            raise InputError(f"--detector {detector}: must be within 0..{self.n_detectors - 1}")
        row, col = divmod(detector, self.columns)
        pitch_x, pitch_y = self.nx + self.gap_px, self.ny + self.gap_px
        return ((col - (self.columns - 1) / 2) * pitch_x, (row - (self.rows - 1) / 2) * pitch_y)


def focal_plane_from_instrument(instrument: dict) -> FocalPlane:
    d = instrument["detector"]
    nx, ny = int(d["nx_pixels"]["value"]), int(d["ny_pixels"]["value"])
    if nx <= 0 or ny <= 0:
        raise InputError(f"detector size {nx} x {ny}: must be positive")
    return FocalPlane(
        nx=nx, ny=ny, pixel_scale_arcsec=pixel_scale_arcsec(instrument),
        pixel_size_mm=float(d["pixel_size_um"]["value"]) / 1000.0,
        columns=int(d["layout_columns"]["value"]), rows=int(d["layout_rows"]["value"]),
        gap_px=float(d["layout_gap_pixels"]["value"]),
    )


def pointing_wcs(ra_deg: float, dec_deg: float, sun_direction: np.ndarray, fp: FocalPlane, detector: int):
    """astropy WCS of one detector: TAN about the boresight, axes along the telescope frame."""
    from astropy.wcs import WCS

    z = radec_to_unit(ra_deg, dec_deg)
    frame = telescope_frame(z, np.asarray(sun_direction, dtype=float))
    a, d = np.radians(ra_deg), np.radians(dec_deg)
    east = np.array([-np.sin(a), np.cos(a), 0.0])
    north = np.array([-np.sin(d) * np.cos(a), -np.sin(d) * np.sin(a), np.cos(d)])
    scale_deg = fp.pixel_scale_arcsec / 3600.0
    cd = scale_deg * np.array([[frame.x @ east, frame.y @ east], [frame.x @ north, frame.y @ north]])
    ox, oy = fp.detector_offset_px(detector)
    w = WCS(naxis=2)
    w.wcs.ctype = ["RA---TAN", "DEC--TAN"]
    w.wcs.crval = [ra_deg % 360.0, dec_deg]
    # boresight falls at pixel (centre - offset); FITS pixels are 1-based
    w.wcs.crpix = [(fp.nx + 1) / 2.0 - ox, (fp.ny + 1) / 2.0 - oy]
    w.wcs.cd = cd
    w.wcs.cunit = ["deg", "deg"]
    return w


def star_fluxes_e_per_s(mag_ab, band: Band, aperture_diameter_m: float) -> np.ndarray:
    """e-/s of stars of AB magnitude ``mag_ab`` in ``band`` through the full aperture."""
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
    """Sparse (n_fine x n_coarse) bilinear weights; fine pixel i sits at coarse (i + offset + 0.5) / b - 0.5."""
    from scipy import sparse

    pos = (np.arange(n_fine) + offset + 0.5) / b - 0.5
    j0 = np.clip(np.floor(pos).astype(int), 0, n_coarse - 2)
    w1 = np.clip(pos - j0, 0.0, 1.0)
    rows = np.repeat(np.arange(n_fine), 2)
    cols = np.stack([j0, j0 + 1], axis=1).ravel()
    vals = np.stack([1.0 - w1, w1], axis=1).ravel()
    return sparse.csr_matrix((vals, (rows, cols)), shape=(n_fine, n_coarse))


def _radial_grid(half: int, step_px: float = 1.0) -> np.ndarray:
    y, x = np.mgrid[-half:half + 1, -half:half + 1].astype(float) * step_px
    return np.hypot(x, y)


def _taper_up(r, r0, r1):
    x = np.clip((r - r0) / (r1 - r0), 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * x)


def _deposit(shape, x, y, w) -> np.ndarray:
    """Cloud-in-cell deposit of weights at (x, y) (0-based pixel centres) on a grid."""
    grid = np.zeros(shape, dtype=np.float64)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - x0, y - y0
    for dx, dy, ww in ((0, 0, (1 - fx) * (1 - fy)), (1, 0, fx * (1 - fy)), (0, 1, (1 - fx) * fy), (1, 1, fx * fy)):
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
    image_e_per_s_per_pix: np.ndarray
    ghosts: dict  # column -> array
    stars: dict  # column -> array (stars used)
    wcs: object
    meta: dict = field(default_factory=dict)


def render_detector(
    ra_deg, dec_deg, star_ra_deg, star_dec_deg, star_flux_e_per_s, sun_direction, fp: FocalPlane, detector: int,
    scatter: ScatterModel, ghosts: GhostModel | None, chief_ray_angle_deg: float,
    settings: RenderSettings | None = None, size_override: tuple[int, int] | None = None,
) -> DetectorImage:
    """Render the in-field stray light (core + scattering halo, ghosts) of one detector.

    ``size_override`` (ny, nx) renders a smaller image with the same pixel scale (tests).
    """
    s = settings or RenderSettings()
    if s.far_bin < 1 or s.near_radius_px < 4:
        raise InputError(f"render settings far_bin={s.far_bin}, near_radius_px={s.near_radius_px} out of range")
    if size_override:
        fp = FocalPlane(size_override[1], size_override[0], fp.pixel_scale_arcsec, fp.pixel_size_mm,
                        fp.columns, fp.rows, fp.gap_px)
    flux = check_fluxes(star_flux_e_per_s, "star flux (e-/s)")
    wcs = pointing_wcs(ra_deg, dec_deg, sun_direction, fp, detector)
    ny, nx = fp.ny, fp.nx
    p_m = fp.pixel_size_mm / 1000.0

    # stars within the detector plus margin (angular pre-cut, then pixel cut)
    sra, sdec = np.asarray(star_ra_deg, float), np.asarray(star_dec_deg, float)
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
    # a star off the chip counts only where its halo still exceeds the floor on the chip
    halo_tab = _profile_table(scatter.halo_profile, np.hypot(nx, ny) + margin_px, p_m)
    reach = np.minimum(_reach_px(halo_tab, f, s.halo_floor_e_per_s_per_pix, p_m), margin_px)
    dx = np.maximum(np.maximum(-x, x - (nx - 1)), 0.0)
    dy = np.maximum(np.maximum(-y, y - (ny - 1)), 0.0)
    keep = np.hypot(dx, dy) <= np.maximum(reach, s.near_radius_px)
    idx, x, y, f = idx[keep], x[keep], y[keep], f[keep]
    used_margin_px = float(np.max(np.hypot(dx, dy)[keep], initial=0.0)) + s.near_radius_px

    # near field, full resolution
    rn = s.near_radius_px
    r_px = _radial_grid(rn)
    # float64: the core's peak is ~1e7 x the kernel's tail, beyond float32 FFT round-off
    k_near = scatter.profile(r_px * p_m) * p_m * p_m * (1.0 - _taper_up(r_px, rn / 2, rn))
    pad = rn
    star_map = _deposit((ny + 2 * pad, nx + 2 * pad), x + pad, y + pad, f)
    image = signal.oaconvolve(star_map, k_near, mode="same")[pad:pad + ny, pad:pad + nx].astype(np.float32)
    del star_map

    # far field, binned grid covering detector + the margin the kept stars need
    b = s.far_bin
    mpx = int(np.ceil(used_margin_px))
    cny, cnx = int(np.ceil((ny + 2 * mpx) / b)) + 1, int(np.ceil((nx + 2 * mpx) / b)) + 1
    coarse_map = _deposit((cny, cnx), (x + mpx + 0.5) / b - 0.5, (y + mpx + 0.5) / b - 0.5, f)
    half_y = int(np.ceil((ny + mpx) / b)) + 1
    half_x = int(np.ceil((nx + mpx) / b)) + 1
    yk, xk = np.mgrid[-half_y:half_y + 1, -half_x:half_x + 1].astype(float) * b
    rc = np.hypot(xk, yk)
    del xk, yk
    k_far = _interp_profile(halo_tab, rc) * (b * p_m) ** 2 * _taper_up(rc, rn / 2, rn)
    del rc
    far_coarse = signal.fftconvolve(coarse_map, k_far, mode="same") / (b * b)  # per fine pixel
    del k_far, coarse_map
    wy = _linear_upsample_matrix(ny, cny, mpx, b)
    wx = _linear_upsample_matrix(nx, cnx, mpx, b)
    far = (wx @ (wy @ far_coarse).T).T
    image = image + far.astype(np.float32)
    del far, far_coarse

    # ghosts
    gtab = {k: np.zeros(0) for k in ("star_index", "path", "x_pix", "y_pix", "radius_pix", "e_per_s_per_pix", "energy_e_per_s")}
    if ghosts is not None and idx.size:
        ox, oy = fp.detector_offset_px(detector)
        fx, fy = x - (nx - 1) / 2.0 + ox, y - (ny - 1) / 2.0 + oy  # focal-plane position from the axis
        rr = np.hypot(fx, fy)
        ux = np.where(rr > 0, fx / np.where(rr > 0, rr, 1), 1.0)
        uy = np.where(rr > 0, fy / np.where(rr > 0, rr, 1), 0.0)
        th = np.radians(chief_ray_angle_deg)
        off = ghosts.centre_offsets_mm(th * ux, th * uy) / fp.pixel_size_mm  # (3, 2, n)
        radii = ghosts.radii_mm() / fp.pixel_size_mm
        # f is the detected rate (filter included): ghosts relative to the nominal image
        irr = ghosts.irradiance_relative_to_image_per_mm2() * fp.pixel_size_mm**2
        frac = ghosts.energy_relative_to_image()
        rows = []
        for k in range(3):
            rows.append(dict(
                star_index=idx, path=np.full(idx.size, k + 1), x_pix=x + off[k, 0], y_pix=y + off[k, 1],
                radius_pix=np.full(idx.size, radii[k]), e_per_s_per_pix=f * irr[k], energy_e_per_s=f * frac[k],
            ))
        gtab = {c: np.concatenate([r[c] for r in rows]) for c in rows[0]}
        if s.paint_ghosts:
            image = image + _paint_discs(ny, nx, gtab, s.ghost_min_e_per_s_per_pix)

    stars = {"catalog_index": idx, "x_pix": x, "y_pix": y, "flux_e_per_s": f}
    return DetectorImage(image.astype(np.float32), gtab, stars, wcs,
                         meta={"far_bin": b, "near_radius_px": rn, "margin_arcsec": s.margin_arcsec,
                               "halo_floor": s.halo_floor_e_per_s_per_pix})


def _paint_discs(ny, nx, g, min_irr) -> np.ndarray:
    """Uniform discs; each holds exactly its energy over the pixels whose centres it covers."""
    out = np.zeros((ny, nx))
    for xc, yc, r, e in zip(g["x_pix"], g["y_pix"], g["radius_pix"], g["energy_e_per_s"]):
        if e / (np.pi * r * r) < min_irr:
            continue
        x0, x1 = int(np.floor(xc - r)), int(np.ceil(xc + r)) + 1
        y0, y1 = int(np.floor(yc - r)), int(np.ceil(yc + r)) + 1
        yy, xx = np.mgrid[y0:y1, x0:x1]
        disc = (xx - xc) ** 2 + (yy - yc) ** 2 <= r * r
        n_in = disc.sum()
        if n_in == 0:
            continue
        ok = disc & (xx >= 0) & (xx < nx) & (yy >= 0) & (yy < ny)
        out[yy[ok], xx[ok]] += e / n_in
    return out


def bodies_as_stars(campaign, time, ra_deg: float, dec_deg: float, band: str) -> tuple:
    """The Sun, Moon and planets inside the field at ``time`` as extra catalog stars:
    (ra_deg, dec_deg, mag_ab, names), arrays; a body in the field is a point source, left out of
    the background (:meth:`~straylight.components.ComponentModel.in_field_point_sources`)."""
    from .components import ComponentModel
    from .sky import sample_geometry, scene

    sc = scene(campaign, time)
    g = sample_geometry(campaign, sc, np.array([ra_deg]), np.array([dec_deg]), grid=False)
    los = radec_to_unit(np.array([ra_deg]), np.array([dec_deg]))
    found = ComponentModel(campaign).in_field_point_sources(sc.satellite_km, sc.bodies_km, los, g, [band])
    names = [k for k, v in found.items() if bool(np.ravel(v["in_field"])[0])]
    ra, dec = [], []
    for k in names:
        d = unit(sc.bodies_km[k][0] - sc.satellite_km[0])
        ra.append(float(np.degrees(np.arctan2(d[1], d[0])) % 360.0))
        dec.append(float(np.degrees(np.arcsin(d[2]))))
    mags = [float(np.ravel(found[k]["mag_ab"][band])[0]) for k in names]
    return np.array(ra), np.array(dec), np.array(mags), names


def sun_direction_at(campaign, time) -> np.ndarray:
    """Unit vector from the satellite to the Sun at ``time`` (for the roll)."""
    from .sky import scene

    sc = scene(campaign, time)
    return unit(sc.bodies_km["sun"][0] - sc.satellite_km[0])


def write_fits(result: DetectorImage, path, provenance: dict) -> None:
    """FITS: primary image (e-/s/pixel) with WCS and provenance; GHOSTS and STARS tables."""
    from astropy.io import fits
    from astropy.table import Table

    from .io import atomic_path

    hdr = result.wcs.to_header()
    hdr["BUNIT"] = ("electron/s", "stray light per pixel")
    for k, v in provenance.items():
        key = k.upper()[:8]
        hdr[key] = v if not isinstance(v, float) else float(v)
    for k, v in result.meta.items():
        hdr[k.upper()[:8]] = v
    prim = fits.PrimaryHDU(result.image_e_per_s_per_pix, header=hdr)
    gt = fits.BinTableHDU(Table(result.ghosts), name="GHOSTS")
    st = fits.BinTableHDU(Table(result.stars), name="STARS")
    with atomic_path(path) as tmp:
        fits.HDUList([prim, gt, st]).writeto(tmp)


def read_star_columns(path, bands) -> tuple[np.ndarray, np.ndarray, dict]:
    """Read ra, dec and mag_<band> for every band in one pass (Parquet, FITS, CSV, ECSV);
    returns (ra_deg, dec_deg, {band: mag}); clear errors otherwise."""
    from pathlib import Path

    from astropy.table import Table

    p = Path(path)
    if not p.exists():
        raise InputError(f"{p}: star catalog does not exist")
    try:
        if p.suffix.lower() == ".parquet":
            import pyarrow.parquet as pq

            t = pq.read_table(p)
            names = t.column_names
        else:
            t = Table.read(p)
            names = t.colnames
    except Exception as exc:
        raise InputError(f"{p}: cannot read star catalog ({exc})") from exc
    cols = {c.lower(): c for c in names}
    need = ["ra", "dec"] + [f"mag_{b.lower()}" for b in bands]
    missing = [c for c in need if c not in cols]
    if missing:
        raise InputError(f"{p}: missing column(s) {', '.join(missing)}; have {', '.join(cols.values())}")

    def get(c):
        col = t[cols[c]]
        return np.asarray(col.to_numpy() if hasattr(col, "to_numpy") else col, dtype=float)

    ra, dec = get("ra"), get("dec")
    for name, v, lo, hi in (("ra", ra, -360.0, 360.0), ("dec", dec, -90.0, 90.0)):
        bad = np.flatnonzero(~np.isfinite(v) | (v < lo) | (v > hi))
        if bad.size:
            raise InputError(f"{p}: row {bad[0]}: {cols[name]} = {v[bad[0]]} must be finite and within "
                             f"[{lo:g}, {hi:g}] deg")
    return ra % 360.0, dec, {b: get(f"mag_{b.lower()}") for b in bands}


def read_star_table(path, band: str):
    """Read ra, dec and mag_<band> columns (Parquet, FITS, CSV, ECSV); clear errors otherwise."""
    ra, dec, mags = read_star_columns(path, [band])
    return ra, dec, mags[band]
