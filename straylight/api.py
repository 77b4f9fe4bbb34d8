"""The Python API in astropy's terms: :func:`sky_background` and :func:`open_campaign`.

* :func:`sky_background` - every background component, the total, the 5-sigma limit and the
  observability of any (time, pointing), from astropy ``Time`` and ``SkyCoord``, as an astropy
  ``QTable`` with units.  It runs the per-pointing table code of ``straylight sky --input``
  (:func:`straylight.planning.pointings.pointing_table`), vectorised over the samples, on a
  :class:`~straylight.skymodel.SkyModel` kept warm per config and catalog (the first call
  builds it; later ones only compute).
* :func:`open_campaign` - a finished campaign's products (``results/<campaign>/``) as xarray
  objects, with :meth:`CampaignProducts.to_mag_per_arcsec2` for the conversion to surface
  brightness through the zero points stored with the cube.

Example (a dark-sky pointing in the default campaign's orbit)::

    >>> from astropy.time import Time
    >>> from astropy.coordinates import SkyCoord
    >>> import straylight
    >>> t = Time("2026-01-01T00:30:00", scale="utc")
    >>> sky = straylight.sky_background(t, SkyCoord(150.0, 30.0, unit="deg"), bands=["g"])
    >>> sky["total_g"].unit
    Unit("electron / (pix s)")
    >>> names = straylight.violation_names(sky["violations"][0])   # the violated constraints
    >>> print(sky["time"][0], sky["observable"][0], names or "none")
    2026-01-01T00:30:00.000 True none
    >>> bool(21.5 < sky["total_mag_g"][0].value < 23.8)   # g-band dark sky, AB mag/arcsec2
    True
    >>> bool(25.5 < sky["limit_mag_g"][0].value < 27.5)   # 5-sigma point-source depth, AB mag
    True
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from straylight.errors import InputError

__all__ = ["sky_background", "violation_names", "CampaignProducts", "to_mag_per_arcsec2", "open_campaign"]


def sky_background(time, coord, bands=None, config=None, catalog=None, columns=None, dtype="float64"):
    """Background, 5-sigma depth and observability at the given times and pointings.

    Parameters
    ----------
    time : astropy.time.Time
        Observation time(s), any scale (converted to UTC); scalar or array.  Valid within the
        DE405 ephemeris range (1599-12-09 to 2201-02-20); the satellite follows the campaign's
        orbit (``config``), so for a circular orbit only times near its epoch are meaningful.
        A masked entry is refused (there is no time to compute at): drop or fill it first.
    coord : astropy.coordinates.SkyCoord
        Pointing(s) (any frame; converted to ICRS); scalar or array, broadcast against ``time``.
    bands : list of str, optional
        Bands to evaluate (default: every band of the instrument); ``"V"`` is the Bessell V
        diagnostic band (no limit for it).
    config : str, path or mapping, optional
        Campaign config (default: the packaged ``config/config.yaml``) giving the orbit, the
        instrument and the models; a file or a mapping holding only the keys it changes is
        merged over the default config, as ``straylight run`` does.
    catalog : str or path, optional
        Star table (``ra``, ``dec``, ``mag_<band>``; e.g. ``results/<campaign>/stars_csst.parquet``)
        for the off-field star term, with the cube's selection (``stars.offfield_mag_limit``).
        Without it the ``stars`` component is 0.
    columns : list of str, optional
        The columns to return (None: all those below); fewer columns, less memory.
    dtype : {"float64", "float32"}
        Of the float columns: float32 halves their memory (7 significant digits).

    Returns
    -------
    astropy.table.QTable
        One row per broadcast sample, columns:

        * ``time`` (Time, UTC), ``ra``, ``dec`` (deg, ICRS);
        * ``observable`` (bool) and ``violations`` (uint8 bit mask of the violated constraints,
          0 when observable: sun = 1, moon = 2, bright_limb = 4, dark_limb = 8,
          earth_occultation = 16, door = 32; the column's description and
          ``meta["violation_bits"]`` give the bits, :func:`violation_names` the names);
        * ``sun_angle``, ``moon_angle``, ``earth_limb_angle``, ``door_opening`` (deg);
        * per band ``b``: ``<component>_<b>`` in electron / (s pix) for zodiacal, earthshine,
          moon, sun, planets, stars and ``total``; ``<component>_mag_<b>`` the same in AB
          mag/arcsec2 (inf where a component is 0); ``limit_mag_<b>`` the 5-sigma
          point-source limit in AB mag for the band's survey exposures (EE80 aperture).

        ``meta`` holds each band's zero point (``mag_zero_point``, mag/arcsec2 at
        1 e-/s/pixel) and the record of which models ran.

        No samples (an empty ``time`` or ``coord``) give an empty table with the same columns
        and units, so a scheduler's loop needs no special case; the config and bands are still
        checked, nothing is evaluated and ``meta["models"]`` is empty.

        The samples are evaluated in chunks into a table allocated once, so the peak memory is
        the table's own size plus the chunk's work and the samples' copies, under 0.5 GB at any
        number of samples.  The table of 2 million samples in one band is 0.37 GB (float64;
        0.20 GB in float32), in all seven bands 1.81 GB (0.92 GB); ``columns`` makes it smaller.

    Raises
    ------
    straylight.InputError
        Arguments of the wrong type, non-finite coordinates, a masked time, shapes that do not
        broadcast, a time outside the ephemeris, an unknown band or an empty list of bands.
    straylight.ConfigError
        A config that does not validate (the message names the file, key and value).

    Examples
    --------
    >>> import astropy.units as u
    >>> from astropy.time import Time
    >>> from astropy.coordinates import SkyCoord
    >>> t = Time("2026-01-01T00:00:00") + [0, 30, 60] * u.min
    >>> sky = sky_background(t, SkyCoord(150.0, 30.0, unit="deg"), bands=["g", "r"])
    >>> len(sky), sky["zodiacal_r"].unit, sky["total_mag_r"].unit
    (3, Unit("electron / (pix s)"), Unit("mag / arcsec2"))
    """
    from straylight.skymodel import cached_sky_model, checked_band_list, checked_samples

    checked_samples(time, coord)  # bad input refused before a model (or its tables) is built
    checked_band_list(bands)
    return cached_sky_model(config, catalog).background(time, coord, bands, columns, dtype)


def violation_names(mask):
    """The violated constraints' names of :func:`sky_background`'s ``violations`` bit mask.

    Parameters
    ----------
    mask : int or array_like of int
        One bit mask or many (a column of the table).

    Returns
    -------
    str or numpy.ndarray of str
        The names, comma-separated in the order sun, moon, bright_limb, dark_limb,
        earth_occultation, door ("" when none is violated); an array of the mask's shape for an
        array.

    Examples
    --------
    >>> violation_names(33), violation_names(0)
    ('sun,door', '')
    """
    from straylight.planning.pointings import violation_text

    names = violation_text(mask)
    return str(names) if names.ndim == 0 else names


class CampaignProducts:
    """A finished campaign's products as xarray objects, opened lazily on first use.

    Attributes (each raises :class:`straylight.InputError` naming the path if it is missing):

    * ``background`` - ``background.zarr``: (time, pixel, band) components and total,
      e-/s/pixel; observability on (time, pixel); the ``mag_zero_point`` (band) coordinate.
    * ``limits`` - ``limits.zarr``: 5-sigma limits (AB mag) per sample and per pixel.
    * ``observability`` - ``observability.zarr``: observable flag, violated-constraint mask, angles.
    * ``ephemeris`` - ``ephemeris.zarr``: body and satellite positions on the time grid.
    * ``footprint`` - ``footprint.fits`` as a (pixel) DataArray of the footprint's HEALPix
      pixels (value 1), with ``nside`` and ``nest`` attributes.
    * ``provenance`` - ``provenance.json`` as a dict.
    * ``compact`` - ``sky_compact.zarr`` as a :class:`straylight.SkyMaps`: the total background
      per band in AB mag/arcsec2 and the observability, for fast look-ups.
    """

    #: the products; a folder holding none of them is not a campaign's
    PRODUCTS = (
        "background.zarr",
        "limits.zarr",
        "observability.zarr",
        "ephemeris.zarr",
        "footprint.fits",
        "provenance.json",
    )

    def __init__(self, path):
        if not isinstance(path, (str, os.PathLike)):
            raise InputError(
                f"path: expected a campaign results folder (str or path), got {type(path).__name__}"
            )
        self.path = Path(path)
        if not self.path.is_dir():
            raise InputError(f"{self.path}: not a campaign results folder (expected results/<campaign>/)")
        if not any((self.path / p).exists() for p in self.PRODUCTS):
            raise InputError(
                f"{self.path}: no campaign product in this folder (none of {', '.join(self.PRODUCTS)}); "
                "expected results/<campaign>/ of a run"
            )
        self._cache: dict = {}

    def _zarr(self, name):
        import xarray as xr

        if name not in self._cache:
            p = self.path / name
            if not p.exists():
                raise InputError(f"{p}: product missing (has the campaign finished?)")
            self._cache[name] = xr.open_zarr(p)
        return self._cache[name]

    @property
    def background(self):
        """``background.zarr`` (Dataset, lazy): (time, pixel, band) components and total, e-/s/pixel."""
        return self._zarr("background.zarr")

    @property
    def limits(self):
        """``limits.zarr`` (Dataset, lazy): 5-sigma point-source limits, AB mag."""
        return self._zarr("limits.zarr")

    @property
    def observability(self):
        """``observability.zarr`` (Dataset, lazy): observable flag, violations mask, angles in deg."""
        return self._zarr("observability.zarr")

    @property
    def ephemeris(self):
        """``ephemeris.zarr`` (Dataset, lazy): body and satellite positions on the time grid."""
        return self._zarr("ephemeris.zarr")

    @property
    def footprint(self):
        """``footprint.fits``: (pixel) DataArray of the footprint's HEALPix pixels (1), RA/Dec in deg."""
        import xarray as xr
        from astropy.io import fits

        from straylight.util.healpix import healpy

        hp = healpy()

        p = self.path / "footprint.fits"
        if not p.exists():
            raise InputError(f"{p}: product missing (has the campaign finished?)")
        with fits.open(p) as hdul:
            nest = str(hdul[1].header.get("ORDERING", "RING")).upper() == "NESTED"
        m = hp.read_map(str(p), nest=nest)
        pix = np.flatnonzero(m > 0)
        nside = hp.npix2nside(m.size)
        ra, dec = hp.pix2ang(nside, pix, nest=nest, lonlat=True)
        return xr.DataArray(
            m[pix],
            dims="pixel",
            name="footprint",
            coords={"pixel": pix, "ra_deg": ("pixel", ra), "dec_deg": ("pixel", dec)},
            attrs={
                "units": "1",
                "long_name": "survey footprint (1 inside)",
                "nside": nside,
                "nest": int(nest),
            },
        )

    @property
    def compact(self):
        """``sky_compact.zarr`` (:class:`straylight.SkyMaps`): total background per band, AB
        mag/arcsec2, and observability; its chunks decoded on first use."""
        from straylight.cube.compact import COMPACT_NAME
        from straylight.cube.skymaps import SkyMaps

        if COMPACT_NAME not in self._cache:
            p = self.path / COMPACT_NAME
            if not p.exists():
                raise InputError(f"{p}: product missing (has the campaign finished?)")
            self._cache[COMPACT_NAME] = SkyMaps(p)
        return self._cache[COMPACT_NAME]

    @property
    def provenance(self) -> dict:
        """``provenance.json`` as a dict."""
        import json

        p = self.path / "provenance.json"
        if not p.exists():
            raise InputError(f"{p}: product missing (has the campaign finished?)")
        return json.loads(p.read_text())

    def to_mag_per_arcsec2(self, rate):
        """AB mag/arcsec2 of a background DataArray in e-/s/pixel (``background[...]``), through
        the ``mag_zero_point`` coordinate stored with the cube: ``zp - 2.5 log10(rate)``; +inf
        where the rate is 0, NaN where it is NaN.  ``rate`` must keep its ``band`` dimension
        (select bands with ``sel(band=[...])``, not ``sel(band="g")``) or carry the scalar
        ``mag_zero_point`` coordinate.

        Parameters
        ----------
        rate : xarray.DataArray
            Background, e-/s/pixel (``units`` ``electron / (s pixel)``), any dimensions.

        Returns
        -------
        xarray.DataArray
            The same shape and dimensions, AB mag/arcsec2.

        Raises
        ------
        straylight.InputError
            No zero point for ``rate``, or other units.
        """
        return to_mag_per_arcsec2(rate, self.background)

    def __repr__(self):
        return f"CampaignProducts({str(self.path)!r})"


def to_mag_per_arcsec2(rate, background=None):
    """AB mag/arcsec2 of an xarray background in e-/s/pixel, through its ``mag_zero_point``
    coordinate (or ``background``'s, aligned on ``band``).  See
    :meth:`CampaignProducts.to_mag_per_arcsec2`.

    Parameters
    ----------
    rate : xarray.DataArray
        Background, e-/s/pixel (``units`` ``electron / (s pixel)`` or ``e-/s/pixel``), any
        dimensions; with a ``mag_zero_point`` coordinate, or a ``band`` coordinate.
    background : xarray.Dataset or None
        The cube whose ``mag_zero_point`` (band), mag/arcsec2 at 1 e-/s/pixel, is used when
        ``rate`` has none (None: ``rate``'s own only).

    Returns
    -------
    xarray.DataArray
        ``zp - 2.5 log10(rate)``, AB mag/arcsec2, with ``rate``'s dimensions (+inf where the
        rate is 0, NaN where it is NaN).

    Raises
    ------
    straylight.InputError
        No zero point found, or units other than e-/s/pixel.
    """
    from straylight.limits.point_source import ZERO_POINT_NAME

    if ZERO_POINT_NAME in rate.coords:
        zp = rate.coords[ZERO_POINT_NAME]
    elif background is not None and ZERO_POINT_NAME in background.coords and "band" in rate.coords:
        zp = background[ZERO_POINT_NAME].sel(band=rate["band"])
    else:
        raise InputError(
            f"{getattr(rate, 'name', 'rate')}: no {ZERO_POINT_NAME} coordinate (products from an older "
            "straylight, or the band was dropped); re-run the campaign's background"
        )
    units = str(rate.attrs.get("units", "electron / (s pixel)"))
    if units not in ("electron / (s pixel)", "e-/s/pixel"):
        raise InputError(f"{getattr(rate, 'name', 'rate')}: units {units!r}, expected electron / (s pixel)")
    import xarray as xr

    mag = xr.apply_ufunc(
        _mag_of_rate,
        rate,
        zp.drop_vars(list(zp.coords)) if "band" not in zp.dims else zp,
        dask="parallelized",
        output_dtypes=[np.float64],
        keep_attrs=False,
    )
    mag = mag.transpose(*rate.dims).drop_vars(ZERO_POINT_NAME, errors="ignore")
    long_name = rate.attrs.get("long_name", getattr(rate, "name", "background"))
    mag.attrs = {"units": "mag(AB) arcsec-2", "long_name": f"{long_name}, AB surface brightness"}
    return mag


def _mag_of_rate(rate, zero_point):
    with np.errstate(divide="ignore", invalid="ignore"):
        return zero_point - 2.5 * np.log10(rate)


def open_campaign(path) -> CampaignProducts:
    """A finished campaign's products (``results/<campaign>/``) as xarray objects.

    Parameters
    ----------
    path : str or path
        The campaign's results folder, ``results/<campaign.name>/`` of the Snakemake run.

    Returns
    -------
    CampaignProducts
        ``background``, ``limits``, ``observability``, ``ephemeris`` (xarray Datasets opened
        lazily with dask), ``footprint`` (DataArray), ``provenance`` (dict) and
        ``to_mag_per_arcsec2(rate)``.

    Raises
    ------
    straylight.InputError
        ``path`` not a path, a folder that does not exist or holds none of the products, or (on
        access) a product that is missing.

    Examples
    --------
    >>> import straylight
    >>> straylight.open_campaign("no/such/folder")
    Traceback (most recent call last):
    ...
    straylight.errors.InputError: no/such/folder: not a campaign results folder (expected results/<campaign>/)
    """
    return CampaignProducts(path)
