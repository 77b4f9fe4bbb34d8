"""A warm background model for callers that ask many times: :class:`SkyModel`.

A scheduler asks for the sky thousands of times a night.  :class:`SkyModel` loads the campaign,
builds its :class:`~straylight.model.BackgroundModel` and reads the earthshine tables once; each
:meth:`SkyModel.background` call then only computes.  :func:`straylight.sky_background` keeps
one per (config, catalog) and reuses it.
"""

from __future__ import annotations

import os
import threading
from pathlib import Path

import numpy as np

from straylight.errors import InputError

__all__ = ["SkyModel", "cached_sky_model", "checked_band_list", "checked_samples"]


class SkyModel:
    """The background of one campaign's orbit, instrument and models, built once.

    Parameters
    ----------
    config : str, path or mapping, optional
        Campaign config (default: the packaged ``config/config.yaml``): the orbit, the
        instrument and the models; a file or a mapping holding only the keys it changes is
        merged over the default config (:func:`straylight.config.load_campaign`).
    catalog : str or path, optional
        Star table (``ra``, ``dec``, ``mag_<band>``) for the off-field star term, read once per
        set of bands asked for; without it the ``stars`` component is 0.

    Notes
    -----
    Under ``models.earthshine.method: auto`` the earthshine comes from its tables, as in the
    campaigns' products: the first use on a machine builds them once (a warning says so, with
    the expected time, and a progress bar follows) and every later one reads them from the
    cache (``STRAYLIGHT_CACHE``, else ``~/.cache/straylight``).
    One SkyModel serves one thread at a time (its time conversions silence ERFA's warnings
    through Python's warnings filters, which are not thread-safe).

    Examples
    --------
    >>> from astropy.time import Time
    >>> from astropy.coordinates import SkyCoord
    >>> sky = SkyModel()
    >>> t = Time("2026-01-01T00:30:00", scale="utc")
    >>> row = sky.background(t, SkyCoord(150.0, 30.0, unit="deg"), bands=["g"])
    >>> bool(25.5 < row["limit_mag_g"][0].value < 27.5)   # 5-sigma point-source depth, AB mag
    True
    """

    def __init__(self, config=None, catalog=None):
        from straylight.config import load_campaign
        from straylight.model import BackgroundModel
        from straylight.sky.timeutil import configure_offline

        configure_offline()
        self.campaign = load_campaign(config)
        self.model = BackgroundModel(self.campaign)  # a table not cached yet: built on every core
        self.model.models_record()  # the tables this model uses read (or built) now, not on the first call
        self.catalog = catalog
        self._stars: dict = {}
        self._stars_lock = threading.Lock()

    @property
    def bands(self) -> list[str]:
        """The instrument's bands (``"V"``, the Bessell V diagnostic band, is accepted too)."""
        return list(self.campaign.bands)

    def background(self, time, coord, bands=None, columns=None, dtype="float64"):
        """Background, 5-sigma depth and observability at the given times and pointings.

        Parameters, result and errors: :func:`straylight.sky_background` (without its
        ``config`` and ``catalog``, which this model holds).

        Parameters
        ----------
        time : astropy.time.Time
            Observation time(s), any scale; scalar or array.
        coord : astropy.coordinates.SkyCoord
            Pointing(s), any frame; scalar or array, broadcast against ``time``.
        bands : list of str or None
            Bands to evaluate (None: every band of the instrument; ``"V"`` is accepted).
        columns : list of str or None
            The columns to return (None: all); fewer columns, less memory.
        dtype : {"float64", "float32"}
            Of the float columns (float32: half their memory, 7 significant digits).

        Returns
        -------
        astropy.table.QTable
            One row per broadcast sample: the angles (deg), observability, each component and
            the total in electron / (s pix), in AB mag/arcsec2, and the 5-sigma limits (AB
            mag), as :func:`straylight.sky_background` gives them.

        Raises
        ------
        straylight.InputError
            Bad samples (see :func:`checked_samples`), an unknown band, an empty list of bands,
            an unknown column or dtype.

        Notes
        -----
        The samples are evaluated :data:`~straylight.planning.pointings.CHUNK_ROWS` at a time into
        a table allocated once: the peak memory is the table plus one chunk's work and the samples'
        copies (``python bench/api_memory.py``).
        """
        from straylight.planning.pointings import TableLayout, background_table

        t, ra, dec = checked_samples(time, coord)
        campaign = self.campaign
        if bands is not None and len(bands) == 0:
            raise InputError(
                f"bands: no band given; valid bands: {', '.join(campaign.bands)}, V "
                "(None for all the instrument's)"
            )
        bands = list(bands or campaign.bands)
        unknown = [b for b in bands if b not in campaign.bands and b != "V"]
        if unknown:
            raise InputError(f"bands: unknown band {unknown[0]!r}; known: {', '.join(campaign.bands)}, V")
        checked_band_list(bands)
        empty = _empty_table(campaign, t[:0], bands)
        columns, dtype = _checked_columns(columns, dtype, empty.colnames)
        if not t.size:
            return _empty_table(campaign, t, bands)[columns or empty.colnames]
        layout = TableLayout(None if columns is None else tuple(columns), dtype)
        return background_table(campaign, t, ra, dec, bands, self._stars_for(bands), self.model, layout)

    def exposure_time(self, time, coord, mag_ab, snr=5.0, bands=None, n_exposures=None, observable_only=True):
        """Total exposure time a point source needs to reach ``snr``, per sample and band, at the
        background :meth:`background` gives (:mod:`straylight.planning.exposure_time`: the 5-sigma limits'
        CCD equation, EE80 aperture, read noise, dark current and zero points).

        The time is split into the band's survey number of exposures (2; NUV and y 4) unless
        ``n_exposures`` says otherwise; the read noise counts once per exposure.

        Parameters
        ----------
        time : astropy.time.Time
            Observation time(s), scalar or array (a window: ``t0 + np.arange(n) * step``).
        coord : astropy.coordinates.SkyCoord
            Pointing(s), any frame, broadcast against ``time``.
        mag_ab : float or astropy.units.Quantity
            Source AB magnitude, scalar (``mag`` or ``ABmag``).
        snr : float
            Signal-to-noise ratio to reach in the EE80 aperture (default 5).
        bands : list of str or None
            Survey bands (None: all; ``"V"`` has no survey exposures and is refused).
        n_exposures : int, optional
            Exposures the time is split into; None: each band's survey count.
        observable_only : bool
            True: NaN where a constraint is violated; False: computed there too (flagged), e.g.
            50-80 deg from the bright limb, where the paper (sect. 1) suggests longer exposures.

        Returns
        -------
        astropy.table.QTable
            One row per sample and band (:func:`straylight.planning.exposure_time.etc_table`): the
            ``exposure_time`` (s; NaN where not observable unless ``observable_only`` is
            False; ``observable`` and ``violations`` say why), ``n_exposures``, the background
            per component and its total (e-/s/pix), the ``dominant`` component, the survey's
            5-sigma ``limit_mag``; units and descriptions on every column.
            :func:`straylight.planning.exposure_time.etc_summary` gives the shortest, median and longest
            over a window.

        Raises
        ------
        straylight.InputError
            Bad samples (:func:`checked_samples`), a bad magnitude, SNR or count, or a band
            that is not a survey band; checked before anything is computed.

        Examples
        --------
        >>> from astropy.time import Time
        >>> from astropy.coordinates import SkyCoord
        >>> sky = SkyModel()
        >>> t = Time("2026-01-01T00:30:00", scale="utc")
        >>> etc = sky.exposure_time(t, SkyCoord(150.0, 30.0, unit="deg"), 25.0, bands=["g"])
        >>> bool(10 < etc["exposure_time"][0].value < 300)   # 25 mag is above the g limit
        True
        """
        from straylight.planning.exposure_time import checked_request

        request = checked_request(mag_ab, snr=snr, n_exposures=n_exposures, observable_only=observable_only)
        return self._etc(time, coord, bands, request)

    def snr(self, time, coord, mag_ab, exposure_time, bands=None, n_exposures=None, observable_only=True):
        """Signal-to-noise ratio a point source reaches in ``exposure_time`` (all exposures
        together), per sample and band: the inverse of :meth:`exposure_time`, same model.

        Parameters
        ----------
        time, coord, mag_ab, bands, n_exposures, observable_only
            As :meth:`exposure_time`.
        exposure_time : astropy.units.Quantity
            Total exposure time (a time unit, scalar), split into the band's survey number of
            exposures (or ``n_exposures``), read noise once per exposure.

        Returns
        -------
        astropy.table.QTable
            As :meth:`exposure_time`, with ``snr`` computed (NaN where not observable, unless
            ``observable_only`` is False) and
            ``exposure_time`` the one given.

        Raises
        ------
        straylight.InputError
            As :meth:`exposure_time`; an exposure time without a time unit or <= 0.
        """
        from straylight.planning.exposure_time import checked_request

        request = checked_request(
            mag_ab, exposure_time=exposure_time, n_exposures=n_exposures, observable_only=observable_only
        )
        return self._etc(time, coord, bands, request)

    def _etc(self, time, coord, bands, request):
        """The exposure-time calculator's table for a checked request."""
        from straylight.planning.exposure_time import checked_bands, etc_table

        bands = checked_bands(bands, self.campaign)
        table = etc_table(self.background(time, coord, bands), bands, self.campaign, request)
        _warn_magnitude(table, self.campaign)
        return table

    def _stars_for(self, bands: list[str]):
        """The catalog's off-field stars for these bands (read once per band set), or None."""
        if self.catalog is None:
            return None
        key = tuple(bands)
        with self._stars_lock:
            if key not in self._stars:
                from straylight.sources.stars_table import load_offfield_stars

                sc = self.campaign.settings.stars
                self._stars[key] = load_offfield_stars(
                    self.catalog, bands, float(sc.offfield_mag_limit), sc.faint_map
                )
            return self._stars[key]


def checked_band_list(bands) -> None:
    """InputError for a list of bands that names a band twice (the table's columns are named by
    band), before any model is built; None (every band) passes.

    Parameters
    ----------
    bands : sequence of str or None
        Band names; None: every band.
    """
    if bands is None or isinstance(bands, str):
        return
    bands = [str(b) for b in bands]
    twice = [b for i, b in enumerate(bands) if b in bands[:i]]
    if twice:
        raise InputError(f"bands: band {twice[0]!r} given twice ({', '.join(bands)}); give each band once")


def _warn_magnitude(table, campaign) -> None:
    """The ETC's warnings for a magnitude its noise model does not cover, one logged line each."""
    import logging

    from straylight.planning.exposure_time import magnitude_warnings

    for line in magnitude_warnings(table, campaign):
        logging.getLogger(__name__).warning("warning: %s", line)


def checked_samples(time, coord):
    """(UTC times, RA, Dec deg) of the samples, flattened after broadcasting ``time`` (astropy
    Time) against ``coord`` (SkyCoord, any frame; ICRS out).  InputError for a wrong type, shapes
    that do not broadcast, a non-finite coordinate, a masked time or a time outside DE405, before
    any model is built.

    Parameters
    ----------
    time : astropy.time.Time
        Observation time(s), any scale; scalar or array.
    coord : astropy.coordinates.SkyCoord
        Pointing(s), any frame; scalar or array, broadcast against ``time``.

    Returns
    -------
    t : astropy.time.Time, shape (n,)
        The samples' times, UTC.
    ra, dec : ndarray, shape (n,)
        The samples' ICRS right ascension and declination, deg.

    Raises
    ------
    straylight.InputError
        As above.
    """
    from astropy.coordinates import SkyCoord
    from astropy.time import Time

    from straylight.sky.ephemeris import check_in_ephemeris
    from straylight.sky.timeutil import configure_offline, quiet_dubious_years

    configure_offline()  # before the scale conversion below: no leap-second download
    if not isinstance(time, Time):
        raise InputError(f"time: expected an astropy.time.Time, got {type(time).__name__}")
    if not isinstance(coord, SkyCoord):
        raise InputError(f"coord: expected an astropy.coordinates.SkyCoord, got {type(coord).__name__}")
    ra, dec = _icrs_radec_deg(coord)
    try:
        shape = np.broadcast_shapes(time.shape, ra.shape)
    except ValueError:
        raise InputError(f"time {time.shape} and coord {ra.shape}: shapes do not broadcast") from None
    ra, dec = (np.broadcast_to(a, shape).ravel() for a in (ra, dec))
    bad = np.flatnonzero(~(np.isfinite(ra) & np.isfinite(dec)))
    if bad.size:
        raise InputError(f"coord: sample {bad[0]}: ra = {ra[bad[0]]}, dec = {dec[bad[0]]} is not finite")
    masked = np.flatnonzero(np.broadcast_to(np.asarray(time.mask, bool), shape).ravel())
    if masked.size:
        raise InputError(
            f"time: sample {masked[0]} is masked ({masked.size} of {ra.size} samples): no time to "
            "compute at; drop or fill the masked entries"
        )
    _check_raw_jd(time, shape)  # far outside DE405 (JD 1e10): our line, before ERFA fails to convert it
    with quiet_dubious_years():  # a time outside DE405 gets our line below, not ERFA's warnings first
        t = time.utc
        t = Time(
            np.broadcast_to(t.jd1, shape).ravel(),
            np.broadcast_to(t.jd2, shape).ravel(),
            format="jd",
            scale="utc",
        )
    if t.size:
        check_in_ephemeris(t, "time")
        del t.cache  # its TT, kept by astropy, is 16 bytes a sample that nothing reads again
    return t, ra, dec


#: set once the process has been told that a coordinate's distance is not used
_DISTANCE_WARNED: list = []


def _icrs_radec_deg(coord):
    """(RA, Dec) in deg of ``coord`` in ICRS, or InputError when its frame lacks what the
    conversion needs (an AltAz frame without its location or time); a coordinate with a distance
    is taken as a direction, said once per process (a scheduler's loop is not flooded)."""
    import astropy.units as u
    from astropy.coordinates import ConvertError, SphericalRepresentation

    frame = coord.frame
    if frame.name in ("altaz", "hadec"):  # local frames: the observer's place and time fix them
        for attr, what in (("location", "an EarthLocation"), ("obstime", "a time")):
            if getattr(frame, attr, None) is None:
                raise InputError(
                    f"coord: its {frame.name} frame has no {attr}: it needs {what} to be converted "
                    f"to ICRS (SkyCoord(..., frame='{frame.name}', {attr}=...)), or give ICRS RA/Dec"
                )
    try:
        icrs = coord.icrs
    except (AttributeError, ValueError, TypeError, ConvertError) as exc:
        text = " ".join(str(exc).split())
        raise InputError(f"coord: cannot convert the {frame.name} coordinate to ICRS: {text}") from None
    # from the coordinate's data, not the frame's cached views (kept on the caller's object)
    sph = icrs.data.represent_as(SphericalRepresentation)
    dist = sph.distance
    if dist.unit.physical_type == "length" and dist.size and not _DISTANCE_WARNED:
        import logging

        _DISTANCE_WARNED.append(True)

        logging.getLogger(__name__).warning(
            "warning: coord: has a distance (%s for the first sample): only its direction is used, "
            "as seen from the frame's origin (the satellite's parallax is not applied); give a "
            "direction without distance to silence this",
            np.ravel(dist)[0],
        )
    return np.asarray(sph.lon.to_value(u.deg), float), np.asarray(sph.lat.to_value(u.deg), float)


def _check_raw_jd(time, shape) -> None:
    """EphemerisRangeError for a time whose Julian date (in its own scale: within minutes of TDB)
    is more than a day outside DE405 or not finite, before ERFA converts it (which fails far out,
    JD 1e10); named as ISO text where astropy can write it, else by its Julian date."""
    from astropy.time import Time

    from straylight.errors import EphemerisRangeError
    from straylight.sky.ephemeris import default_ephemeris
    from straylight.sky.timeutil import quiet_dubious_years

    eph = default_ephemeris()
    jd1 = np.broadcast_to(np.asarray(time.jd1, float), shape).ravel()
    jd2 = np.broadcast_to(np.asarray(time.jd2, float), shape).ravel()
    jd = jd1 + jd2
    with np.errstate(invalid="ignore"):
        bad = np.flatnonzero(~((jd >= eph.jd_start - 1.0) & (jd <= eph.jd_end + 1.0)))
    if not bad.size:
        return
    i = int(bad[0])
    try:
        with quiet_dubious_years():
            value = Time(jd1[i], jd2[i], format="jd", scale=time.scale).utc.isot
    except Exception:  # noqa: BLE001 - ERFA (or astropy) cannot convert or write it: its Julian date
        value = f"JD {jd[i]:.10g} ({time.scale})"
    where = f"time: sample {i}" if jd.size > 1 else "time"
    count = f"; {bad.size} of {jd.size} samples are outside it" if jd.size > 1 else ""
    raise EphemerisRangeError(f"{where} = {value} is outside the DE405 range ({eph.span}){count}")


def _checked_columns(columns, dtype, names: list[str]):
    """(the columns asked for, or None for all; the float dtype), InputError for an unknown one."""
    if dtype not in ("float64", "float32", np.float64, np.float32):
        raise InputError(f"dtype: {dtype!r}; expected 'float64' or 'float32'")
    if columns is None:
        return None, np.dtype(dtype)
    if isinstance(columns, str) or not isinstance(columns, (list, tuple)) or not columns:
        raise InputError(f"columns: {columns!r}; expected a non-empty list of column names")
    if not all(isinstance(c, str) for c in columns):
        raise InputError(f"columns: {columns!r}; expected a non-empty list of column names")
    unknown = [c for c in columns if c not in names]
    if unknown:
        raise InputError(f"columns: unknown column {unknown[0]!r}; known: {', '.join(names)}")
    return list(dict.fromkeys(columns)), np.dtype(dtype)


def _empty_table(campaign, t, bands):
    """:meth:`SkyModel.background`'s table with no rows: an empty
    :class:`~straylight.model.result.BackgroundResult`'s, through the same conversion to a QTable
    (so columns and units cannot differ from a computed one's)."""
    from straylight.limits.point_source import sky_zero_points
    from straylight.model import registry
    from straylight.model.result import GEOMETRY_COLUMNS, BackgroundResult

    none = np.zeros(0)
    geometry = {k: none for k in GEOMETRY_COLUMNS}
    geometry.update(observable=np.zeros(0, bool), violations=np.zeros(0, np.int64))
    empty = BackgroundResult(
        bands=tuple(bands),
        rates={b: {c: none for c in registry.component_names(total=True)} for b in bands},
        geometry=geometry,
        zero_points=sky_zero_points(campaign, bands),
        limits={b: none for b in bands if b != "V"},  # the diagnostic band has no limit
        time=t,
        ra_deg=none,
        dec_deg=none,
    )
    return empty.to_table()


_MODELS: dict = {}
_MODELS_LOCK = threading.Lock()
#: SkyModels kept by :func:`cached_sky_model` (each holds the earthshine tables, ~60 MB)
_MAX_CACHED_MODELS = 4


def _file_key(path) -> tuple | None:
    """(resolved path, modification time, size) of a file, so that an edited file gives a new model;
    a mapping's content (and the folder its relative paths are against)."""
    if path is None:
        return None
    from collections.abc import Mapping

    if isinstance(path, Mapping):
        import json

        return ("mapping", json.dumps(path, sort_keys=True, default=str), str(Path.cwd()))
    if not isinstance(path, (str, os.PathLike)):
        return ("object", id(path))  # refused by the loader, naming its type
    p = Path(path).resolve()
    try:
        st = os.stat(p)
    except OSError:
        return (str(p), None, None)  # let the loader name the missing file
    return (str(p), st.st_mtime_ns, st.st_size)


def cached_sky_model(config=None, catalog=None) -> SkyModel:
    """The :class:`SkyModel` of this config and catalog, built on first use and kept (a config
    or catalog file edited since gives a new one; the files a config names, such as its
    instrument, are not watched).

    Parameters
    ----------
    config : str, path or mapping, optional
        Campaign config (None: the packaged ``config/config.yaml``; a partial one is merged
        over it).
    catalog : str or path, optional
        Star table for the off-field star term (None: stars = 0).

    Returns
    -------
    SkyModel
        The kept model (at most a few are kept; the oldest is dropped first).
    """
    key = (_file_key(config), _file_key(catalog))
    with _MODELS_LOCK:
        model = _MODELS.get(key)
        if model is None:
            model = SkyModel(config, catalog)
            if len(_MODELS) >= _MAX_CACHED_MODELS:
                _MODELS.pop(next(iter(_MODELS)))
            _MODELS[key] = model
        return model
