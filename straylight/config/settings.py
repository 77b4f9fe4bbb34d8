"""The campaign's typed settings: every section of config/schema/config.schema.yaml but the
Earth and the orbit, parsed once from the validated config with the schema's defaults
(:func:`settings_from_config`); one section alone with the schema's defaults
(:func:`section_settings`); the orbit's section (:func:`orbit_settings`); and :func:`_typed`,
which builds any settings dataclass (the instrument's too) from its mapping."""

from __future__ import annotations

import dataclasses
import functools
import os
import typing
from dataclasses import dataclass
from pathlib import Path

from straylight.errors import ConfigError


@dataclass(frozen=True)
class CampaignSection:
    """``campaign``: the campaign's name, UTC span (start inclusive, end exclusive, ISO text),
    cadence (s) and time block (h)."""

    name: str
    start: str
    end: str
    cadence_s: float
    time_block_hours: float


@dataclass(frozen=True)
class FootprintSection:
    """``footprint``: the HEALPix grid (nside, ordering, frame), the latitude cuts (deg), a
    user's mask file, and the pixels per Zarr chunk and Dask task."""

    nside: int
    ordering: str
    frame: str
    galactic_latitude_min_deg: float
    ecliptic_latitude_min_deg: float
    mask_file: str | None
    pixel_block_size: int


@dataclass(frozen=True)
class StarsSection:
    """``stars``: the catalog's inputs and cuts (mag), and how the off-field stars are summed."""

    gaia_files: tuple
    g_limit_mag: float
    hipparcos: str
    match_radius_arcsec: float
    template_classes: tuple
    luminosity_parallax_snr_min: float
    population_file: str | None
    btsettl_files: tuple
    offfield_mag_limit: float
    faint_map: bool


@dataclass(frozen=True)
class EarthshineLUTSteps:
    """``models.earthshine.lut``: the sunlit table's node steps (deg) and radius nodes."""

    sun_zenith_step_deg: float
    los_zenith_step_deg: float
    azimuth_step_deg: float
    n_radius: int


@dataclass(frozen=True)
class MoonlitLUTSteps:
    """``models.earthshine.moonlit_lut``: the moonlit table's node steps, deg."""

    moon_zenith_step_deg: float
    los_zenith_step_deg: float
    azimuth_step_deg: float
    roll_step_deg: float


@dataclass(frozen=True)
class EarthshineSection:
    """``models.earthshine``: the Earth's albedo, the Earth and door grids, the method and the
    tables' steps."""

    albedo: float
    n_gamma: int
    n_psi: int
    door_blocks: tuple
    n_aperture_door: int
    cut_block_split: int
    moonlit_grid: tuple
    moonlit_method: str
    moonlit_lut: MoonlitLUTSteps
    method: str
    lut: EarthshineLUTSteps
    albedo_spectrum: str


@dataclass(frozen=True)
class ZodiacalReddeningSection:
    """``models.zodiacal_reddening``: Leinert et al. (1998) eq. 22's colour law,
    f_co = 1 + a log10(lambda / 0.5 um), a per decade of wavelength below and above 0.5 um."""

    blue_per_dex: float
    red_per_dex: float

    def as_tuple(self) -> tuple:
        """``(blue_per_dex, red_per_dex)``, as :class:`~straylight.sources.zodiacal.ZodiacalModel`
        takes them."""
        return (self.blue_per_dex, self.red_per_dex)


@dataclass(frozen=True)
class ModelsSection:
    """``models``: the zodiacal spectrum and its colour law, the Moon's phase law and eclipse
    factor, the earthshine, the tolerance (fraction of the total) and what unobservable samples
    get."""

    zodiacal_spectrum: str
    zodiacal_reddening: ZodiacalReddeningSection
    moon_phase_law: str
    moon_eclipse_factor: float
    earthshine: EarthshineSection
    tolerance: float
    unobservable_samples: str


@dataclass(frozen=True)
class ReportSection:
    """``report``: the report's maps (times, bands) and time series (pointings)."""

    sky_map_times: int
    sky_map_bands: tuple | None
    series_pointings: int
    times: tuple
    pointings: tuple


@dataclass(frozen=True)
class SchedulingSection:
    """``scheduling``: the scheduling tables' threshold, a fraction of the zodiacal light."""

    fraction_of_zodiacal: float


@dataclass(frozen=True)
class StorageSection:
    """``storage``: the products' kept mantissa bits and Blosc level; the compact product's
    magnitude step (mag)."""

    float_keepbits: int
    magnitude_keepbits: int
    blosc_clevel: int
    compact_mag_step: float


@dataclass(frozen=True)
class ComputeSection:
    """``compute``: a Dask scheduler's address, a measured pipeline rate (samples/s/core) for
    ``straylight plan``, and time blocks per Snakemake job."""

    dask_scheduler: str | None = None
    pipeline_samples_per_s_per_core: float | None = None
    time_blocks_per_job: int | None = None


@dataclass(frozen=True)
class CircularOrbitSection:
    """``orbit.circular``: the circular orbit's altitude (km), inclination, RAAN and argument of
    latitude at epoch (deg), and its epoch (UTC, ISO text)."""

    altitude_km: float
    inclination_deg: float
    raan_deg: float
    arg_latitude_deg: float
    epoch: str


@dataclass(frozen=True)
class TLESection:
    """``orbit.tle``: a file holding a TLE (its path resolved against the config's folder by
    :func:`orbit_settings`), or the two lines; the schema has no default for any of them, so
    a key the config lacks is None."""

    file: str | None = None
    line1: str | None = None
    line2: str | None = None


@dataclass(frozen=True)
class OrbitSection:
    """``orbit``: the model (``circular`` or ``tle``) and its elements; the section the model
    does not use may be absent (None).  Not a field of :class:`Settings`: the orbit is
    :attr:`Campaign.orbit`, built from this (:func:`orbit_settings`)."""

    model: str
    circular: CircularOrbitSection | None = None
    tle: TLESection | None = None


@dataclass(frozen=True)
class Settings:
    """A campaign's settings, typed: every section of config/schema/config.schema.yaml but the
    Earth and the orbit (:attr:`Campaign.earth`, :attr:`Campaign.orbit`) and the instrument's
    path.  Built once from the validated config with the schema's defaults filled in
    (:func:`settings_from_config`); read as ``campaign.settings.stars.faint_map``."""

    campaign: CampaignSection
    footprint: FootprintSection
    stars: StarsSection
    models: ModelsSection
    report: ReportSection
    scheduling: SchedulingSection
    storage: StorageSection
    compute: ComputeSection


def _typed(cls, node: dict, where: str):
    """A settings dataclass from a config mapping: nested sections recursively (:func:`_value`).
    Keys the class does not declare are ignored (the schema checks them); a key it declares and
    the config lacks is taken from the class's default or is an error naming it."""
    hints, fields = _fields(cls)
    values = {}
    for f in fields:
        if f.name not in node:
            if f.default is dataclasses.MISSING:
                raise ConfigError(f"{where}.{f.name}: missing (no default in the schema)")
            continue
        values[f.name] = _value(node[f.name], hints[f.name], f"{where}.{f.name}")
    return cls(**values)


@functools.lru_cache(maxsize=None)
def _fields(cls) -> tuple[dict, tuple]:
    """A settings class's type hints (its annotations evaluated: the costly part of reading a
    config) and its fields, once per class."""
    return typing.get_type_hints(cls), dataclasses.fields(cls)


def _value(v, hint, where: str):
    """One config value as its field's type ``hint`` reads it: a settings dataclass (or one or
    None) from its mapping, ``tuple[<dataclass>, ...]`` from a list of mappings,
    ``dict[str, <dataclass>]`` from a mapping of them; another list as a tuple (its lists as
    tuples); a YAML integer as a float where the field is a float."""
    args = typing.get_args(hint)
    if v is not None and len(args) == 2 and type(None) in args:
        inner = next(a for a in args if a is not type(None))
        if dataclasses.is_dataclass(inner) or typing.get_origin(inner) in (dict, tuple):
            hint = inner
            args = typing.get_args(hint)
    if dataclasses.is_dataclass(hint):
        return _typed(hint, v or {}, where)
    origin = typing.get_origin(hint)
    if origin is tuple and args and dataclasses.is_dataclass(args[0]):
        return tuple(_typed(args[0], x, f"{where}[{i}]") for i, x in enumerate(v))
    if origin is dict and len(args) == 2 and dataclasses.is_dataclass(args[1]):
        return {k: _typed(args[1], x, f"{where}.{k}") for k, x in v.items()}
    if isinstance(v, list):
        return tuple(tuple(x) if isinstance(x, list) else x for x in v)
    if isinstance(v, int) and not isinstance(v, bool) and hint in (float, float | None):
        return float(v)  # YAML's 300 for a number of seconds
    return v


def settings_from_config(config: dict) -> Settings:
    """:class:`Settings` from a campaign config validated and completed by the schema
    (:func:`apply_defaults`).

    Parameters
    ----------
    config : dict
        A campaign config, validated and completed by the schema.

    Raises
    ------
    ConfigError
        For a section or key the schema gives no default for and the config lacks.
    """
    return Settings(
        **{
            name: _typed(cls, config.get(name) or {}, name)
            for name, cls in typing.get_type_hints(Settings).items()
        }
    )


def section_settings(name: str, node: dict | None):
    """One section of the campaign config, typed, with the schema's defaults filled in: for a
    caller that holds the section alone (a footprint or storage mapping written by hand), so
    that the defaults are the schema's, as in :attr:`Campaign.settings`.

    Parameters
    ----------
    name : str
        A section of :class:`Settings` (``"footprint"``, ``"storage"``, ...).
    node : dict or None
        The section's mapping (not validated here; None: the schema's defaults alone).

    Returns
    -------
    The section's settings dataclass (e.g. :class:`FootprintSection`).

    Raises
    ------
    ConfigError
        For a key the schema gives no default for and ``node`` lacks.
    """
    from straylight.config.loading import apply_defaults

    schema = _campaign_schema()["properties"][name]
    cls = typing.get_type_hints(Settings)[name]
    return _typed(cls, apply_defaults(dict(node or {}), schema), name)


@functools.lru_cache(maxsize=1)
def _campaign_schema() -> dict:
    """config/schema/config.schema.yaml, read once (callers copy what they fill in)."""
    from straylight.config.loading import CAMPAIGN_SCHEMA, load_schema

    return load_schema(CAMPAIGN_SCHEMA)


def orbit_settings(node: dict, config_dir=None) -> OrbitSection:
    """The config's ``orbit`` section, typed (:class:`OrbitSection`), a relative
    ``orbit.tle.file`` resolved against ``config_dir``.

    Parameters
    ----------
    node : dict
        The validated ``orbit`` section.
    config_dir : path-like or None
        The campaign config's folder; None: a relative TLE file is left as written.

    Returns
    -------
    OrbitSection
        The orbit's model and elements.
    """
    orbit = _typed(OrbitSection, node, "orbit")
    tle = orbit.tle
    if tle is not None and tle.file is not None and config_dir is not None and not os.path.isabs(tle.file):
        orbit = dataclasses.replace(
            orbit, tle=dataclasses.replace(tle, file=str(Path(config_dir) / tle.file))
        )
    return orbit


__all__ = [
    "CampaignSection",
    "FootprintSection",
    "StarsSection",
    "EarthshineLUTSteps",
    "MoonlitLUTSteps",
    "EarthshineSection",
    "ModelsSection",
    "ZodiacalReddeningSection",
    "ReportSection",
    "SchedulingSection",
    "StorageSection",
    "ComputeSection",
    "CircularOrbitSection",
    "TLESection",
    "OrbitSection",
    "Settings",
    "settings_from_config",
    "section_settings",
    "orbit_settings",
]
