"""The survey footprint on a HEALPix grid (ICRS pixel centres) and its work plan."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from straylight.errors import ConfigError, InputError

if TYPE_CHECKING:
    from straylight.config.settings import FootprintSection

__all__ = [
    "Footprint",
    "pixel_block_length",
    "pixel_centres",
    "latitude_cut_mask",
    "read_mask",
    "footprint_from_config",
    "footprint_from_store",
]


@dataclass
class Footprint:
    """Pixels of the survey footprint.

    ``pixels`` are HEALPix indices in ``ordering`` at ``nside``; ``ra_deg``/``dec_deg`` their
    ICRS centres.

    Attributes
    ----------
    nside : int
        HEALPix resolution parameter.
    ordering : str
        ``"ring"`` or ``"nested"`` (lower case).
    pixels : ndarray of int, shape (n_pixel,)
        HEALPix indices of the footprint, increasing.
    ra_deg, dec_deg : ndarray of float, shape (n_pixel,)
        ICRS RA and Dec of the pixel centres, deg.
    """

    nside: int
    ordering: str
    pixels: np.ndarray
    ra_deg: np.ndarray
    dec_deg: np.ndarray

    @property
    def nest(self) -> bool:
        """Whether the pixels are in NESTED ordering (else RING)."""
        return self.ordering == "nested"

    @property
    def area_deg2(self) -> float:
        """Area of the footprint, deg2 (pixel count x the HEALPix pixel area)."""
        from straylight.util.healpix import healpy

        hp = healpy()

        return float(self.pixels.size * hp.nside2pixarea(self.nside, degrees=True))

    def blocks(self, block_size: int) -> list[tuple[int, int]]:
        """(start, stop) index ranges into ``pixels`` of :func:`pixel_block_length` pixels each
        (the last one shorter when they do not divide the footprint).

        Parameters
        ----------
        block_size : int
            Pixels per block asked for (``footprint.pixel_block_size``).

        Returns
        -------
        list of tuple of int
            ``(start, stop)`` indices into ``pixels``, covering them in order.
        """
        n = self.pixels.size
        step = pixel_block_length(n, block_size)
        return [(i, min(i + step, n)) for i in range(0, n, step)]


def pixel_block_length(n_pixels: int, block_size: int) -> int:
    """Pixels per block (and per Zarr chunk) of a footprint of ``n_pixels`` split in blocks of
    about ``block_size`` (``footprint.pixel_block_size``): round(n_pixels / block_size) blocks,
    at least one, of equal length.  So no block is a sliver (5286 pixels at 660 are 8 blocks of
    661, not 8 of 660 and one of 6): a chunk costs nearly as much to encode and write however
    few of its pixels are filled.

    Parameters
    ----------
    n_pixels : int
        Pixels in the footprint.
    block_size : int
        Pixels per block asked for (> 0).

    Returns
    -------
    int
        Pixels per block, at least 1.
    """
    n_blocks = max(1, round(int(n_pixels) / int(block_size)))
    return max(1, -(-int(n_pixels) // n_blocks))


def pixel_centres(nside: int, nest: bool, pixels=None) -> tuple[np.ndarray, np.ndarray]:
    """ICRS centres of HEALPix pixels (healpy's ``pix2ang``).

    Parameters
    ----------
    nside : int
        HEALPix resolution parameter.
    nest : bool
        NESTED ordering if True, else RING.
    pixels : array_like of int, shape (n,), optional
        Pixel indices; None: every pixel of the sphere (n = 12 nside**2).

    Returns
    -------
    ra : ndarray of float, shape (n,)
        RA of the centres, deg, in [0, 360).
    dec : ndarray of float, shape (n,)
        Dec of the centres, deg.
    """
    # healpy where it is used (a slow import): the jobs that read a footprint
    # from a store (footprint_from_store) do without it
    from straylight.util.healpix import healpy

    hp = healpy()

    if pixels is None:
        pixels = np.arange(hp.nside2npix(nside))
    ra, dec = hp.pix2ang(nside, pixels, nest=nest, lonlat=True)
    return ra, dec


def latitude_cut_mask(nside: int, nest: bool, galactic_min_deg: float, ecliptic_min_deg: float) -> np.ndarray:
    """Boolean map: |b| >= galactic_min_deg and |ecliptic latitude| >= ecliptic_min_deg.

    Galactic latitude from astropy's Galactic frame; ecliptic latitude from the mean ecliptic
    and equinox of J2000 (``BarycentricMeanEcliptic``; the geocentric and barycentric
    directions of a star are the same).

    Parameters
    ----------
    nside : int
        HEALPix resolution parameter.
    nest : bool
        NESTED ordering if True, else RING.
    galactic_min_deg : float
        Least absolute Galactic latitude kept, deg.
    ecliptic_min_deg : float
        Least absolute ecliptic latitude kept, deg.

    Returns
    -------
    ndarray of bool, shape (12 nside**2,)
        True for pixels whose centre passes both cuts.
    """
    import astropy.units as u
    from astropy.coordinates import BarycentricMeanEcliptic, SkyCoord

    ra, dec = pixel_centres(nside, nest)
    c = SkyCoord(ra * u.deg, dec * u.deg, frame="icrs")
    b = c.galactic.b.deg
    beta = c.transform_to(BarycentricMeanEcliptic()).lat.deg
    return (np.abs(b) >= galactic_min_deg) & (np.abs(beta) >= ecliptic_min_deg)


def read_mask(path: str | Path, nside: int, nest: bool) -> np.ndarray:
    """A HEALPix FITS mask (a user's, or the footprint rule's footprint.fits), resampled to
    ``nside``/ordering; non-zero = in footprint.

    Parameters
    ----------
    path : str or path-like
        HEALPix FITS map (healpy's UNSEEN counts as 0).
    nside : int
        Resolution to resample to.
    nest : bool
        Ordering of the result: NESTED if True, else RING.

    Returns
    -------
    ndarray of bool, shape (12 nside**2,)
        True where the (resampled) map exceeds 0.5.

    Raises
    ------
    InputError
        When the file is missing, not a HEALPix FITS map, or holds non-finite values.
    """
    from straylight.util.healpix import healpy

    hp = healpy()

    path = Path(path)
    if not path.exists():
        raise InputError(f"footprint.mask_file: {path} does not exist")
    try:
        m = hp.read_map(str(path), nest=nest, dtype=np.float64)
    except Exception as exc:
        raise InputError(f"footprint.mask_file: {path} is not a HEALPix FITS map ({exc})") from exc
    if not np.all(np.isfinite(m) | (m == hp.UNSEEN)):
        raise InputError(f"footprint.mask_file: {path} holds non-finite values")
    m = np.where(m == hp.UNSEEN, 0.0, m)
    if hp.get_nside(m) != nside:
        m = hp.ud_grade(
            m, nside, order_in="NESTED" if nest else "RING", order_out="NESTED" if nest else "RING"
        )
    return m > 0.5


def footprint_from_config(footprint: FootprintSection | Mapping, config_dir: Path | None = None) -> Footprint:
    """The footprint a config's ``footprint`` section describes: a mask file's pixels, or the
    Galactic and ecliptic latitude cuts (:func:`latitude_cut_mask`) without one.

    Parameters
    ----------
    footprint : FootprintSection or mapping
        The typed ``footprint`` section (``campaign.settings.footprint``), or its mapping, typed
        here with the schema's defaults for the keys it lacks
        (:func:`~straylight.config.settings.section_settings`): ``nside``, ``ordering``
        (``"ring"`` or ``"nested"``), ``mask_file``, ``galactic_latitude_min_deg`` and
        ``ecliptic_latitude_min_deg`` (deg).
    config_dir : pathlib.Path, optional
        Folder a relative ``mask_file`` is resolved against; None: the working directory.

    Returns
    -------
    Footprint
        The pixels kept, with their ICRS centres.

    Raises
    ------
    ConfigError
        When no pixel is left.
    InputError
        When the mask file cannot be read (:func:`read_mask`).
    """
    if isinstance(footprint, Mapping):
        from straylight.config.settings import section_settings

        footprint = section_settings("footprint", footprint)
    nside = int(footprint.nside)
    ordering = footprint.ordering
    nest = ordering == "nested"
    if footprint.mask_file:
        p = Path(footprint.mask_file)
        if not p.is_absolute() and config_dir is not None:
            p = config_dir / p
        mask = read_mask(p, nside, nest)
    else:
        mask = latitude_cut_mask(
            nside,
            nest,
            float(footprint.galactic_latitude_min_deg),
            float(footprint.ecliptic_latitude_min_deg),
        )
    pixels = np.flatnonzero(mask)
    if pixels.size == 0:
        raise ConfigError("footprint: the cuts or mask leave no pixel in the footprint")
    ra, dec = pixel_centres(nside, nest, pixels)
    return Footprint(nside=nside, ordering=ordering, pixels=pixels, ra_deg=ra, dec_deg=dec)


def footprint_from_store(store) -> Footprint:
    """The footprint a product store was laid down for (background.zarr's skeleton once
    ``background_init`` has written it): its ``pixel``, ``ra_deg`` and ``dec_deg`` coordinates,
    stored exactly, and its ``healpix_nside`` and ``healpix_ordering`` attributes.  The values
    :func:`footprint_from_config` computed, read without healpy or astropy's frames (a cube
    worker's start).  KeyError if the store lacks one of them.

    Parameters
    ----------
    store : str or path-like
        A Zarr product store (e.g. background.zarr).

    Returns
    -------
    Footprint
        The store's footprint.

    Raises
    ------
    KeyError
        When the store lacks one of the coordinates or attributes.
    """
    import zarr

    group = zarr.open_group(str(store), mode="r", use_consolidated=False)
    return Footprint(
        nside=int(group.attrs["healpix_nside"]),
        ordering=str(group.attrs["healpix_ordering"]).lower(),
        pixels=group["pixel"][...],
        ra_deg=group["ra_deg"][...],
        dec_deg=group["dec_deg"][...],
    )
