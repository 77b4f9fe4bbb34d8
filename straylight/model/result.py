"""The background at a batch of (time, pointing) samples as one typed value
(:class:`BackgroundResult`), and its three shapes: an astropy table with units
(:meth:`~BackgroundResult.to_table`), an xarray Dataset whose variables carry ``units`` and
``long_name`` (:meth:`~BackgroundResult.to_dataset`), a JSON-ready record of one sample
(:meth:`~BackgroundResult.to_record`) and a cube region's grid of samples
(:meth:`~BackgroundResult.on_grid`).  ``straylight sky``, the pointing tables (the API's,
visibility's, the targets' and the exposure-time calculator's) and the cube's regions read it."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from straylight.model import registry
from straylight.sky.ephemeris import PLANETS
from straylight.sky.geometry import VIOLATION_BITS, violation_names

__all__ = [
    "BackgroundResult",
    "GEOMETRY_COLUMNS",
    "TABLE_VIOLATION_BITS",
    "VIOLATIONS_DESCRIPTION",
    "violation_mask",
    "violation_text",
]

#: the bits of a result's ``violations`` (uint8): the geometry's constraints and ``door`` (no
#: allowed state of the aperture door)
TABLE_VIOLATION_BITS = {**VIOLATION_BITS, "door": 1 << len(VIOLATION_BITS)}
VIOLATIONS_DESCRIPTION = "violated constraints, bit mask (0: observable): " + ", ".join(
    f"{k}={v}" for k, v in TABLE_VIOLATION_BITS.items()
)

#: the geometry a pointing table reports per sample: name -> unit ("" for flags and masks)
GEOMETRY_COLUMNS = {
    "observable": "",
    "violations": "",
    "sun_angle_deg": "deg",
    "moon_angle_deg": "deg",
    "moon_illuminated_fraction": "1",
    "earth_limb_angle_deg": "deg",
    "limb_is_bright": "",
    "door_opening_deg": "deg",
}

#: the geometry of one sample's record (:meth:`BackgroundResult.to_record`), in its order
_RECORD_GEOMETRY = (
    "sun_angle_deg",
    "moon_angle_deg",
    "moon_phase_angle_deg",
    "moon_illuminated_fraction",
    "earth_limb_angle_deg",
    "limb_is_bright",
    "bright_limb_angle_deg",
    "dark_limb_angle_deg",
    "zenith_angle_deg",
    "door_opening_deg",
    "sun_phi_deg",
    "moon_phi_deg",
    "moon_earth_blocked",
)

_FLAGS = ("limb_is_bright", "moon_earth_blocked")

RATE_UNIT = "electron / (s pix)"
SURFACE_UNIT = "mag / arcsec2"


def violation_mask(flags, door_opening_deg) -> np.ndarray:
    """The ``violations`` bit mask (uint8) of :data:`TABLE_VIOLATION_BITS`: the geometry's
    constraint ``flags`` with the ``door`` bit set where no door state is allowed.

    Parameters
    ----------
    flags : array_like of int
        The geometry's violation bit mask (:data:`~straylight.sky.geometry.VIOLATION_BITS`).
    door_opening_deg : array_like of float
        The door's opening, deg (0: no allowed state).

    Returns
    -------
    ndarray of uint8
    """
    door = np.where(np.asarray(door_opening_deg) > 0, 0, TABLE_VIOLATION_BITS["door"])
    return (np.asarray(flags, np.uint8) | door.astype(np.uint8)).astype(np.uint8, copy=False)


def violation_text(mask) -> np.ndarray:
    """The violated constraints' names, comma-separated ("" when none), of each
    :func:`violation_mask` (the names made once per distinct mask).

    Parameters
    ----------
    mask : array_like of int
        Bit masks of :data:`TABLE_VIOLATION_BITS`.

    Returns
    -------
    ndarray of str
        Of ``mask``'s shape.
    """
    mask = np.asarray(mask, np.int64)
    keys, inverse = np.unique(mask.ravel(), return_inverse=True)
    names = [",".join(k for k, bit in TABLE_VIOLATION_BITS.items() if int(key) & bit) for key in keys]
    return (
        np.array(names or [""], dtype=str)[inverse].reshape(mask.shape)
        if mask.size
        else np.zeros(mask.shape, str)
    )


@dataclass(frozen=True)
class BackgroundResult:
    """The background at ``n`` (time, pointing) samples, flat.

    Attributes
    ----------
    bands : tuple of str
        The bands evaluated.
    rates : dict
        Band -> component -> e-/s/pix, float64 (n,): every name of
        :func:`~straylight.model.registry.band_components` (parts, components, total).
    geometry : dict
        :func:`~straylight.sky.geometry.observing_geometry`'s arrays (n,): angles (deg), the
        door's opening (deg; 0: none allowed), the constraints' bit mask ``violations``,
        ``observable``.
    zero_points : dict
        Band -> AB surface-brightness zero point, mag/arcsec2 at 1 e-/s/pix.
    limits : dict
        Band -> the 5-sigma point-source limit of the survey exposures at the total, AB mag
        (n,); every band but V.
    flags : dict
        What a source reports per sample, name -> bool (n,) (``zodiacal_no_data``: no
        zodiacal data this near the Sun).
    in_field : dict
        Body -> the Sun, the Moon or a planet inside the field (point sources, not in the
        background): ``in_field`` (bool), ``angle_deg`` (deg), ``v_mag`` (Vega V mag),
        ``mag_ab`` (band -> AB mag), arrays (n,); empty when not looked for.
    time : astropy.time.Time or None
        The samples' UTC times (n,).
    ra_deg, dec_deg : ndarray or None
        The samples' ICRS pointing (n,), deg.
    """

    bands: tuple
    rates: dict
    geometry: dict
    zero_points: dict
    limits: dict = field(default_factory=dict)
    flags: dict = field(default_factory=dict)
    in_field: dict = field(default_factory=dict)
    time: object = None
    ra_deg: np.ndarray | None = None
    dec_deg: np.ndarray | None = None

    @property
    def n(self) -> int:
        """The number of samples."""
        return int(np.size(self.geometry["observable"]))

    def at(self, time, ra_deg, dec_deg) -> BackgroundResult:
        """The result with its samples' times and pointing.

        Parameters
        ----------
        time : astropy.time.Time, shape (n,)
            UTC times.
        ra_deg : ndarray, shape (n,)
            ICRS right ascension, deg.
        dec_deg : ndarray, shape (n,)
            ICRS declination, deg.

        Returns
        -------
        BackgroundResult
        """
        return replace(self, time=time, ra_deg=np.asarray(ra_deg), dec_deg=np.asarray(dec_deg))

    def on_grid(self, shape: tuple, names) -> dict:
        """Per-sample geometry on a grid of the samples (a cube region's time steps x pixels:
        the samples step-major), as a cube stores it.

        Parameters
        ----------
        shape : tuple of int
            The grid's shape, its product ``n``.
        names : iterable of str
            Entries of the geometry (``observable``, ``violations``: the constraints' bit mask,
            the angles and ``door_opening_deg`` in deg).

        Returns
        -------
        dict of str to ndarray
            Name -> array of ``shape`` (a view of the result's where it can be).
        """
        return {k: np.broadcast_to(self.geometry[k], (self.n,)).reshape(shape) for k in names}

    def mag_per_arcsec2(self, component: str, band: str) -> np.ndarray:
        """A component's surface brightness (inf where 0).

        Parameters
        ----------
        component : str
            A name of :func:`~straylight.model.registry.band_components`.
        band : str
            A band of the result.

        Returns
        -------
        ndarray, shape (n,)
            AB mag/arcsec2.
        """
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.zero_points[band] - 2.5 * np.log10(np.asarray(self.rates[band][component], float))

    @property
    def violations(self) -> np.ndarray:
        """The violated constraints per sample, bit mask of :data:`TABLE_VIOLATION_BITS`
        (uint8; 0: observable)."""
        return violation_mask(self.geometry["violations"], self.geometry["door_opening_deg"])

    def brightest_in_field(self) -> tuple[np.ndarray, np.ndarray]:
        """The brightest Sun, Moon or planet inside the field per sample.

        Returns
        -------
        names : ndarray of str, shape (n,)
            The body ("" where none).
        v_mag : ndarray of float, shape (n,)
            Its Vega V magnitude (NaN where none).
        """
        if not self.in_field:
            return np.full(self.n, "", dtype=object), np.full(self.n, np.nan)
        v_in = np.stack([np.where(v["in_field"], v["v_mag"], np.inf) for v in self.in_field.values()])
        brightest = np.argmin(v_in, axis=0)
        names = np.array(list(self.in_field), dtype=object)
        found = np.isfinite(np.min(v_in, axis=0))
        return np.where(found, names[brightest], ""), np.where(found, np.min(v_in, axis=0), np.nan)

    def columns(self) -> dict:
        """The pointing table's columns as plain arrays (n,) (see
        :func:`~straylight.planning.pointings.pointing_table`): ``ra_deg``, ``dec_deg`` (deg,
        when known), the geometry of
        :data:`GEOMETRY_COLUMNS`, ``planet_in_field`` and ``planet_in_field_v_mag``, per band
        ``<component>_<band>`` (e-/s/pix), ``total_mag_per_arcsec2_<band>`` and
        ``limit_mag_<band>`` (AB mag).

        Returns
        -------
        dict of str to ndarray
        """
        cols = {} if self.ra_deg is None else {"ra_deg": self.ra_deg, "dec_deg": self.dec_deg}
        cols.update({k: np.asarray(self.geometry[k]) for k in GEOMETRY_COLUMNS})
        cols["planet_in_field"], cols["planet_in_field_v_mag"] = self.brightest_in_field()
        components = registry.component_names(total=True)
        for b in self.bands:
            for c in components:
                cols[f"{c}_{b}"] = np.asarray(self.rates[b][c], float)
        for b in self.bands:
            cols[f"total_mag_per_arcsec2_{b}"] = np.asarray(self.mag_per_arcsec2("total", b), float)
        for b in self.bands:
            if b in self.limits:
                cols[f"limit_mag_{b}"] = self.limits[b]
        return cols

    @classmethod
    def concatenate(cls, parts: list) -> BackgroundResult:
        """One result of several results' samples, in order.

        Parameters
        ----------
        parts : list of BackgroundResult
            Results of the same bands (and the same fields given).

        Returns
        -------
        BackgroundResult
        """
        if len(parts) == 1:
            return parts[0]
        first = parts[0]

        def cat(get):
            return np.concatenate([np.asarray(get(p)) for p in parts])

        def cat_dict(get, keys):
            return {k: cat(lambda p, k=k: get(p)[k]) for k in keys}

        in_field = {
            body: {
                k: (
                    {b: cat(lambda p, body=body, k=k, b=b: p.in_field[body][k][b]) for b in v}
                    if isinstance(v, dict)
                    else cat(lambda p, body=body, k=k: p.in_field[body][k])
                )
                for k, v in first.in_field[body].items()
            }
            for body in first.in_field
        }
        return cls(
            bands=first.bands,
            rates={b: cat_dict(lambda p, b=b: p.rates[b], first.rates[b]) for b in first.bands},
            geometry=cat_dict(lambda p: p.geometry, first.geometry),
            zero_points=first.zero_points,
            limits=cat_dict(lambda p: p.limits, first.limits),
            flags=cat_dict(lambda p: p.flags, first.flags),
            in_field=in_field,
            time=None if first.time is None else _concatenate_times([p.time for p in parts]),
            ra_deg=None if first.ra_deg is None else cat(lambda p: p.ra_deg),
            dec_deg=None if first.dec_deg is None else cat(lambda p: p.dec_deg),
        )

    def to_table(self, models: dict | None = None):
        """The result as a table with units, one row a sample (the columns and ``meta`` that
        :func:`straylight.sky_background` documents).

        Parameters
        ----------
        models : dict, optional
            Which models ran and their error budget, kept in ``meta["models"]``.

        Returns
        -------
        astropy.table.QTable
            ``time`` (when known), ``ra``, ``dec`` (deg, when known), ``observable``,
            ``violations`` (uint8 bit mask), the angles (deg), per band ``<component>_<band>``
            (electron / (s pix)), ``<component>_mag_<band>`` (mag / arcsec2) and but for V
            ``limit_mag_<band>`` (mag); ``meta``: ``mag_zero_point``, ``violation_bits``,
            ``models``.
        """
        return _table(self, models or {})

    def to_dataset(self):
        """The result as an xarray Dataset: dims ``sample`` and ``band``; each component and
        the total a (sample, band) variable in e-/s/pix, the geometry (sample) variables,
        ``zero_point`` and ``limit_mag``; every variable with ``units`` and ``long_name``.

        Returns
        -------
        xarray.Dataset
        """
        return _dataset(self)

    def to_record(self, i: int = 0) -> dict:
        """Sample ``i`` as a JSON-ready record (what ``straylight sky`` prints).

        Parameters
        ----------
        i : int, optional
            The sample.

        Returns
        -------
        dict
            ``geometry`` (deg; ``door_opening_deg`` None where no door state is allowed;
            ``planet_angles_deg``), ``observable``, ``violations`` (names), ``bands``: band ->
            each component -> ``e_per_s_per_pix`` and ``mag_per_arcsec2`` (None where not
            finite), ``mag_zero_point`` and ``limit_mag`` (AB mag; None for V);
            ``in_field_point_sources``; ``zodiacal_no_data_near_sun``.
        """
        g = {k: np.ravel(v)[i] for k, v in self.geometry.items()}
        door = float(g["door_opening_deg"])
        geometry = {k: bool(g[k]) if k in _FLAGS else float(g[k]) for k in _RECORD_GEOMETRY}
        geometry["door_opening_deg"] = door if door > 0 else None
        geometry["planet_angles_deg"] = {
            p: float(g[f"{p}_angle_deg"]) for p in PLANETS if f"{p}_angle_deg" in g
        }
        return {
            "geometry": geometry,
            "observable": bool(g["observable"]),
            "violations": violation_names(int(g["violations"])) + ([] if door > 0 else ["door"]),
            "bands": {b: self._band_record(b, i) for b in self.bands},
            "in_field_point_sources": [
                {
                    "body": k,
                    "angle_deg": float(np.ravel(v["angle_deg"])[i]),
                    "v_mag": float(np.ravel(v["v_mag"])[i]),
                    "mag_ab": {b: float(np.ravel(m)[i]) for b, m in v["mag_ab"].items()},
                }
                for k, v in self.in_field.items()
                if bool(np.ravel(v["in_field"])[i])
            ],
            "zodiacal_no_data_near_sun": bool(np.ravel(self.flags["zodiacal_no_data"])[i]),
        }

    def _band_record(self, band: str, i: int) -> dict:
        entry = {}
        for comp in self.rates[band]:
            e = float(np.ravel(self.rates[band][comp])[i])
            with np.errstate(divide="ignore", invalid="ignore"):
                m = float(self.zero_points[band] - 2.5 * np.log10(np.asarray(e, dtype=float)))
            entry[comp] = {"e_per_s_per_pix": e, "mag_per_arcsec2": m if np.isfinite(m) else None}
        entry["mag_zero_point"] = self.zero_points[band]
        entry["limit_mag"] = float(np.ravel(self.limits[band])[i]) if band in self.limits else None
        return entry


def _concatenate_times(times: list):
    from astropy.time import Time

    return times[0] if len(times) == 1 else Time(times)


def _table(result: BackgroundResult, models: dict):
    """:meth:`BackgroundResult.to_table`."""
    import astropy.units as u
    from astropy.table import QTable
    from astropy.time import Time

    rate, surf = u.electron / (u.s * u.pix), u.mag / u.arcsec**2
    g = result.geometry
    # the columns made first and the table once (adding them one by one costs more than computing them)
    columns = {}
    if result.time is not None:
        columns["time"] = Time(result.time, format="isot", precision=3)
    if result.ra_deg is not None:
        columns["ra"] = u.Quantity(np.asarray(result.ra_deg, float), u.deg)
        columns["dec"] = u.Quantity(np.asarray(result.dec_deg, float), u.deg)
    columns["observable"] = np.asarray(g["observable"], bool)
    columns["violations"] = result.violations
    formats, descriptions = {}, {"violations": VIOLATIONS_DESCRIPTION}
    for name in ("sun_angle", "moon_angle", "earth_limb_angle", "door_opening"):
        columns[name] = u.Quantity(np.asarray(g[f"{name}_deg"], float), u.deg)
        formats[name] = ".3f"
    components, long_name = registry.component_names(total=True), registry.long_names()
    for b in result.bands:
        for c in components:
            columns[f"{c}_{b}"] = u.Quantity(np.asarray(result.rates[b][c], float), rate)
            formats[f"{c}_{b}"] = ".3g"
            descriptions[f"{c}_{b}"] = f"{long_name[c]}, band {b}"
        for c in components:
            columns[f"{c}_mag_{b}"] = u.Quantity(result.mag_per_arcsec2(c, b), surf)
            formats[f"{c}_mag_{b}"] = ".3f"
        if b in result.limits:
            columns[f"limit_mag_{b}"] = u.Quantity(np.asarray(result.limits[b], float), u.mag)
            formats[f"limit_mag_{b}"] = ".3f"
            descriptions[f"limit_mag_{b}"] = "5-sigma point-source limit, AB, survey exposures"
    meta = {
        "mag_zero_point": {b: result.zero_points[b] * surf for b in result.bands},
        "violation_bits": dict(TABLE_VIOLATION_BITS),
        "models": models,
    }
    out = QTable(columns, copy=False, meta=meta)
    for name, f in formats.items():
        out[name].info.format = f
    for name, d in descriptions.items():
        out[name].info.description = d
    return out


def _dataset(result: BackgroundResult):
    """:meth:`BackgroundResult.to_dataset`."""
    import xarray as xr

    long_name = registry.long_names()
    data = {}
    for c in result.rates[result.bands[0]]:
        values = np.stack([np.asarray(result.rates[b][c], float) for b in result.bands], axis=-1)
        data[c] = xr.Variable(("sample", "band"), values, {"units": RATE_UNIT, "long_name": long_name[c]})
    for k, unit in GEOMETRY_COLUMNS.items():
        attrs = {"units": unit or "1", "long_name": k.replace("_", " ")}
        data[k] = xr.Variable(("sample",), np.asarray(result.geometry[k]), attrs)
    data["violations"] = xr.Variable(
        ("sample",), result.violations, {"units": "1", "long_name": VIOLATIONS_DESCRIPTION}
    )
    data["zero_point"] = xr.Variable(
        ("band",),
        np.array([result.zero_points[b] for b in result.bands], float),
        {"units": SURFACE_UNIT, "long_name": "AB surface-brightness zero point at 1 e-/s/pix"},
    )
    limit = np.stack(
        [np.asarray(result.limits.get(b, np.full(result.n, np.nan)), float) for b in result.bands], -1
    )
    data["limit_mag"] = xr.Variable(
        ("sample", "band"), limit, {"units": "mag", "long_name": "5-sigma point-source limit, AB (NaN for V)"}
    )
    coords = {"band": list(result.bands)}
    if result.ra_deg is not None:
        coords["ra"] = (
            "sample",
            np.asarray(result.ra_deg, float),
            {"units": "deg", "long_name": "ICRS right ascension"},
        )
        coords["dec"] = (
            "sample",
            np.asarray(result.dec_deg, float),
            {"units": "deg", "long_name": "ICRS declination"},
        )
    if result.time is not None:
        coords["time"] = (
            "sample",
            np.asarray(result.time.isot, dtype=str),
            {"long_name": "UTC time, ISO 8601"},
        )
    return xr.Dataset(data, coords=coords)
