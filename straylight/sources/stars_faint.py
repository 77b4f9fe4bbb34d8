"""The faint off-field stars' map (paper sect. 2.2): the stars fainter than the direct limit
as the spherical convolution of their fluxes with the azimuth-averaged PST, evaluated at each
line of sight (no Earth or door blocking; :class:`FaintStarMap`, a part of
:class:`~straylight.sources.stars.OffFieldStars`), summed by a compiled kernel
(:func:`_faint_star_kernel`) and optionally kept on disk."""

from __future__ import annotations

from functools import cached_property

import numpy as np

from straylight.sources.stars_table import StarTable
from straylight.util.kernel_cache import njit

__all__ = ["FAINT_MAP_FORMAT", "FaintStarMap"]


class FaintStarMap:
    """The faint stars' map of :class:`~straylight.sources.stars.OffFieldStars` (its
    ``context``: the sources' :class:`~straylight.sources.context.SourceContext`)."""

    @cached_property
    def _pst_azimuthal_table(self):
        """Natural log of the azimuth-averaged PST on a uniform 0.01 deg theta grid (for the
        faint-star map): nodes, values, and the per-cell slopes for direct-index interpolation."""
        theta = np.linspace(0.0, 180.0, 18001)
        ln_pst = np.log(self.context.offfield.pst.azimuthal_mean(theta))
        return theta, ln_pst, np.diff(ln_pst)

    def faint_star_rates(self, stars: StarTable, los, bands, saved: bool = False) -> dict:
        """e-/s/pix per band from the faint stars: sum_s E_s PSTavg(theta_s) * pixel area over the
        stars outside the field and in front of the aperture plane (theta <= 90 deg, where the
        door's Sp is not 0: :func:`~straylight.optics.door.behind_aperture_plane`), for lines of
        sight ``los`` (..., 3).  Depends on the line of sight only, so it is computed once per
        distinct set of lines of sight (cached).  Each line of sight's sum runs over the stars
        in catalog order (:func:`_faint_star_kernel`), so a line of sight's value does not
        depend on which others are computed with it, or in which process.

        ``saved``: the sums are also kept on disk (``faint_star_map_<key>.npy`` in the tables'
        cache folder, :func:`~straylight.util.io.cache_dir`), keyed by a digest of every number
        they are computed from (lines of sight, stars, fluxes, the PST table, the field and the
        kernel's :data:`FAINT_MAP_FORMAT`), and read back when the same map is asked again: a
        footprint's map (the cube's, a long sum) is the same for every campaign with the same
        catalog and instrument.

        Parameters
        ----------
        stars : StarTable
            The star table (its faint stars).
        los : ndarray, shape (..., 3)
            Lines of sight, ICRS unit vectors.
        bands : sequence of str
            Band names; those without faint magnitudes are left out of the result.
        saved : bool
            Whether to keep the map on disk and read it back.

        Returns
        -------
        dict of str to ndarray
            Band -> e-/s/pix, of the lines of sight's shape (...).
        """
        import hashlib

        los = np.asarray(los, float)
        # cached on the star table (whose lifetime bounds the entries) per model and lines of sight
        key = (hashlib.sha1(np.ascontiguousarray(los).tobytes()).hexdigest(), id(self), tuple(bands))
        cache = stars.__dict__.setdefault("_faint_cache", {})
        if key in cache:
            return cache[key]
        flat, bands, star_unit, flux, (ln_pst, slope), grid, area = self._faint_sum_inputs(stars, los, bands)
        path = self._saved_faint_map(flat, star_unit, flux, ln_pst, slope, grid, area) if saved else None
        if path is not None and path.exists():
            out = np.load(path)
        else:
            out = np.zeros((flat.shape[0], len(bands)))
            _faint_star_kernel(flat, star_unit, flux, ln_pst, slope, *grid, out)
            out *= area
            if path is not None:
                from straylight.util.io import atomic_path

                with atomic_path(path) as tmp:
                    with open(tmp, "wb") as f:  # np.save on a path would append ".npy"
                        np.save(f, out)
        res = {b: out[:, j].reshape(los.shape[:-1]) for j, b in enumerate(bands)}
        if len(cache) > 64:
            cache.clear()
        cache[key] = res
        return res

    def faint_star_map_saved(self, stars: StarTable, los, bands) -> bool:
        """Whether :meth:`faint_star_rates` (``saved=True``) finds the map of these lines of
        sight kept on disk, so that asking for it reads a file instead of summing.

        Parameters
        ----------
        stars : StarTable
            The star table.
        los : ndarray, shape (..., 3)
            Lines of sight, ICRS unit vectors.
        bands : sequence of str
            Band names.

        Returns
        -------
        bool
        """
        flat, _, star_unit, flux, (ln_pst, slope), grid, area = self._faint_sum_inputs(stars, los, bands)
        return self._saved_faint_map(flat, star_unit, flux, ln_pst, slope, grid, area).exists()

    def _faint_sum_inputs(self, stars: StarTable, los, bands) -> tuple:
        """What the faint stars' sums are computed from: the lines of sight (N, 3), the bands
        the catalog has faint magnitudes in, the stars' unit vectors, their fluxes (S, B), the
        azimuth-averaged PST's ln and slope tables, the grid (per deg, field edge, 90 deg) and
        the pixel area, m2."""
        flat = np.ascontiguousarray(np.asarray(los, float).reshape(-1, 3))
        bands = [b for b in bands if b in stars.faint_mag_ab]
        flux = np.ascontiguousarray(
            np.array([self.context.photometry(b).from_ab(stars.faint_mag_ab[b]) for b in bands]).T
        )  # (S, B)
        theta_grid, ln_pst, slope = self._pst_azimuthal_table
        per_deg = (theta_grid.size - 1) / theta_grid[-1]
        star_unit = np.ascontiguousarray(stars.faint_unit, dtype=float)
        grid = (per_deg, self.context.offfield.field_radius_deg * per_deg, 90.0 * per_deg)
        return flat, bands, star_unit, flux, (ln_pst, slope), grid, self.context.offfield.pixel_area_m2

    @staticmethod
    def _saved_faint_map(flat, star_unit, flux, ln_pst, slope, grid, area):
        """The file a faint-star map of these inputs is kept in (:meth:`faint_star_rates`)."""
        import hashlib

        from straylight.util.io import cache_dir

        h = hashlib.sha256(f"format {FAINT_MAP_FORMAT} {grid!r} {area!r}".encode())
        for a in (flat, star_unit, flux, ln_pst, slope):
            h.update(np.ascontiguousarray(a).tobytes())
        return cache_dir() / f"faint_star_map_{h.hexdigest()[:16]}.npy"


#: bumped whenever :func:`_faint_star_kernel`'s arithmetic changes: part of the key of the faint
#: maps kept on disk (:meth:`FaintStarMap.faint_star_rates`)
FAINT_MAP_FORMAT = 1


@njit(cache=True, nogil=True)
def _faint_star_kernel(los, star_unit, flux, ln_pst, slope, per_deg, x_field, x_max, out):
    """:meth:`OffFieldStars.faint_star_rates`' sums: ``out[a] += sum_s flux[s] PSTavg(theta_as)``
    over the stars with ``x_field < theta * per_deg <= x_max``, PSTavg linear in ln on the
    uniform theta grid (``ln_pst``, ``slope``: per-node values and per-cell differences, as
    np.interp on that grid).  One pass per (line of sight, star) instead of numpy's pass per
    operation over every pair; the stars of each line of sight in catalog order."""
    nb = flux.shape[1]
    last = slope.size - 1
    to_grid = 180.0 / np.pi * per_deg
    acc = np.empty(nb)
    for a in range(los.shape[0]):
        lx, ly, lz = los[a, 0], los[a, 1], los[a, 2]
        acc[:] = 0.0
        for s in range(star_unit.shape[0]):
            c = lx * star_unit[s, 0] + ly * star_unit[s, 1] + lz * star_unit[s, 2]
            if c < -1e-6:  # well behind the aperture plane (theta > 90 deg): no acos needed
                continue
            x = np.arccos(min(max(c, -1.0), 1.0)) * to_grid  # position on the uniform grid
            if not (x > x_field and x <= x_max):
                continue
            k = min(int(x), last)
            t = np.exp(ln_pst[k] + (x - k) * slope[k])
            for b in range(nb):
                acc[b] += t * flux[s, b]
        for b in range(nb):
            out[a, b] += acc[b]
