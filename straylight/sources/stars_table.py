"""The off-field stars' table (:class:`StarTable`): the direct stars, summed one by one through
the exact transfer, and the faint ones, summed as a smoothed map; read from the catalog
(:func:`load_offfield_stars`) and split at the direct stars' magnitude limit (:func:`split_stars`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

__all__ = ["StarTable", "load_offfield_stars", "split_stars"]


@dataclass
class StarTable:
    """Off-field stars: ``ra_deg, dec_deg, mag_ab`` are summed one by one through the exact
    transfer (Earth, door, PST(theta, phi)); the optional ``faint_*`` stars (fainter than the
    direct limit) enter as a smoothed map, the spherical convolution of their fluxes with the
    azimuth-averaged PST, evaluated at each line of sight (no Earth or door blocking).

    Attributes
    ----------
    ra_deg, dec_deg : ndarray, shape (S,)
        ICRS positions of the direct stars, deg.
    mag_ab : dict of str to ndarray
        Band -> AB magnitudes (S,), +inf where the star is not a direct star in that band.
    faint_ra_deg, faint_dec_deg : ndarray, shape (F,)
        ICRS positions of the faint stars, deg (empty: no faint-star map).
    faint_mag_ab : dict of str to ndarray
        Band -> AB magnitudes (F,) of the faint stars, +inf where not faint in that band.
    """

    ra_deg: np.ndarray
    dec_deg: np.ndarray
    mag_ab: dict  # band -> array (AB mag; +inf where the star is not in this part in that band)
    faint_ra_deg: np.ndarray = field(default_factory=lambda: np.zeros(0))
    faint_dec_deg: np.ndarray = field(default_factory=lambda: np.zeros(0))
    faint_mag_ab: dict = field(default_factory=dict)

    @cached_property
    def unit(self) -> np.ndarray:
        """ICRS unit vectors (S, 3), computed once (the cube reuses the table for every time step)."""
        from straylight.sky.vectors import radec_to_unit

        return np.atleast_2d(radec_to_unit(self.ra_deg, self.dec_deg, "star catalog"))

    @cached_property
    def faint_unit(self) -> np.ndarray:
        """ICRS unit vectors of the faint stars (F, 3), computed once; (0, 3) without them."""
        from straylight.sky.vectors import radec_to_unit

        if not len(self.faint_ra_deg):
            return np.zeros((0, 3))
        return np.atleast_2d(radec_to_unit(self.faint_ra_deg, self.faint_dec_deg, "star catalog"))


def load_offfield_stars(path, bands, mag_limit: float, faint_map: bool = False) -> StarTable:
    """Catalog stars (``stars_csst.parquet`` or any table with ra, dec, mag_<band>), split by
    :func:`split_stars`.  Positions are taken at the catalog epoch: proper motions move bright
    stars by < 1 arcmin in a century, far below the PST's angular structure.

    Parameters
    ----------
    path : str or Path
        The catalog table.
    bands : sequence of str
        Band names to read (``V`` left out).
    mag_limit : float
        The direct stars' limit, AB mag (:func:`split_stars`).
    faint_map : bool
        Whether the fainter stars make the faint-star map.

    Returns
    -------
    StarTable
        Empty when no band but ``V`` is asked for.
    """
    from straylight.catalog.star_table import read_star_columns

    bands = [b for b in bands if b != "V"]
    if not bands:
        return StarTable(np.zeros(0), np.zeros(0), {})
    ra, dec, by_band = read_star_columns(path, bands)
    return split_stars(ra, dec, by_band, mag_limit, faint_map)


def split_stars(ra_deg, dec_deg, mag_by_band: dict, mag_limit: float, faint_map: bool) -> StarTable:
    """Stars brighter than ``mag_limit`` (AB) in at least one band are summed directly (in each
    band only those brighter than the limit count; the others get +inf mag there).  With
    ``faint_map`` every other star enters the smoothed faint-star map
    (:meth:`~straylight.sources.stars.OffFieldStars.faint_star_rates`), so each star counts
    exactly once in each band; without it they are left out.

    Parameters
    ----------
    ra_deg, dec_deg : ndarray, shape (S,)
        ICRS positions, deg.
    mag_by_band : dict of str to ndarray
        Band -> AB magnitudes (S,) (non-finite: no magnitude in that band).
    mag_limit : float
        The direct stars' limit, AB mag.
    faint_map : bool
        Whether the other stars make the faint-star map.

    Returns
    -------
    StarTable
    """
    bands = list(mag_by_band)
    mags = np.array([mag_by_band[b] for b in bands])  # (B, S)
    bright = mags <= mag_limit
    keep = np.any(bright, axis=0)
    direct = np.where(bright, mags, np.inf)[:, keep]
    if not faint_map:
        return StarTable(ra_deg[keep], dec_deg[keep], {b: direct[i] for i, b in enumerate(bands)})
    rest = np.any(~bright & np.isfinite(mags), axis=0)
    faint = np.where(~bright, mags, np.inf)[:, rest]
    return StarTable(
        ra_deg[keep],
        dec_deg[keep],
        {b: direct[i] for i, b in enumerate(bands)},
        ra_deg[rest],
        dec_deg[rest],
        {b: faint[i] for i, b in enumerate(bands)},
    )
