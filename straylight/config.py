"""Campaign and instrument configuration: load, validate against the JSON schemas, resolve.

The schemas in ``config/schema/`` are the single definition of what a config may hold; the
Snakefile validates with Snakemake's ``validate`` against the same files.  Errors name the
file, the key path, the value and what is allowed, e.g.::

    config/config.yaml: campaign.cadence_s = -5: must be > 0
"""
from __future__ import annotations

import copy
import math
import os
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import yaml

from straylight.errors import ConfigError, StraylightError

REPO_ROOT = Path(__file__).resolve().parents[1]
# The default config and schemas: the repository's config/ (a source checkout, where Snakemake
# reads the same files), else the copy an installed wheel carries as straylight/_config
# (pyproject.toml maps config/ to that package).
_PACKAGED_CONFIG = Path(__file__).resolve().parent / "_config"
CONFIG_DIR = REPO_ROOT / "config" if (REPO_ROOT / "config" / "schema").is_dir() else _PACKAGED_CONFIG
SCHEMA_DIR = CONFIG_DIR / "schema"
CAMPAIGN_SCHEMA = SCHEMA_DIR / "config.schema.yaml"
INSTRUMENT_SCHEMA = SCHEMA_DIR / "instrument.schema.yaml"
DEFAULT_CONFIG = CONFIG_DIR / "config.yaml"


#: libyaml's parser where PyYAML has it (the safe loader's documents, its constructors and
#: resolver: faster on the campaign's three files, which each of a run's processes reads)
_YAML_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def _read_yaml(path: Path, what: str) -> Any:
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read {what}: {exc.strerror or exc}") from exc
    except UnicodeDecodeError as exc:  # a binary file, or another encoding: YAML is UTF-8 here
        raise ConfigError(f"{path}: cannot read {what}: not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at "
                          f"offset {exc.start}); expected a YAML file") from None
    try:
        return yaml.load(text, Loader=_YAML_LOADER)  # noqa: S506 - a safe loader
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML: {_yaml_problem(exc)}") from None


def _yaml_problem(exc: yaml.YAMLError) -> str:
    """PyYAML's message on one line: where (line, column), what, and in what construct."""
    mark, problem = getattr(exc, "problem_mark", None), getattr(exc, "problem", None)
    if problem is None:  # a reader's error (a control character): its text, without the stream's name
        return " ".join(str(exc).replace(' in "<unicode string>",', " at").split())
    where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
    context = getattr(exc, "context", None)
    return f"{where}{problem}" + (f" ({context})" if context else "")


def load_schema(path: Path) -> dict:
    return _read_yaml(path, "schema")


def _key(path_parts) -> str:
    parts = [str(p) if not isinstance(p, int) else f"[{p}]" for p in path_parts]
    return ".".join(parts).replace(".[", "[") or "<top level>"


def _describe_error(err) -> str:
    """One line per jsonschema error: key, value, what is allowed."""
    key = _key(err.absolute_path)
    v = err.validator
    if v == "additionalProperties":
        allowed = sorted((err.schema.get("properties") or {}).keys())
        extra = sorted(set(err.instance) - set(allowed))
        base = _key(err.absolute_path)
        keys = ", ".join(f"{base + '.' if err.absolute_path else ''}{k}" for k in extra)
        hint = f"allowed keys: {', '.join(allowed)}" if allowed else "no keys allowed here"
        return f"unknown key {keys} ({hint})"
    if v == "required":
        missing = err.message.split("'")[1] if "'" in err.message else err.message
        where = f"{key}." if err.absolute_path else ""
        return f"missing required key {where}{missing}"
    value = f"{err.instance!r}"
    if v == "type":
        return f"{key} = {value}: expected {err.validator_value}"
    if v == "enum":
        return f"{key} = {value}: must be one of {err.validator_value}"
    if v in ("minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum"):
        op = {"minimum": ">=", "maximum": "<=", "exclusiveMinimum": ">", "exclusiveMaximum": "<"}[v]
        return f"{key} = {value}: must be {op} {err.validator_value}"
    return f"{key} = {value}: {err.message}"


def _source_of(sources: dict | None, key: str, default) -> str:
    """The file that set ``key`` (dotted), or of its nearest parent key; ``default`` otherwise."""
    while sources and key:
        if key in sources:
            return str(sources[key])
        key = key.rpartition(".")[0]
    return str(default)


def validate(document: Any, schema: dict, source: str, sources: dict | None = None) -> None:
    """Validate a loaded document against a JSON schema; raise ConfigError listing all faults.

    ``sources`` (dotted key -> file, see :func:`resolve_config_files`) names, for each fault,
    the file that set the key; ``source`` otherwise."""
    import jsonschema

    cls = jsonschema.validators.validator_for(schema)
    validator = cls(schema)
    errors = sorted(validator.iter_errors(document), key=lambda e: list(map(str, e.absolute_path)))
    if errors:
        # allOf/$ref produce nested copies of the same fault; keep the most specific message
        lines = []
        for err in errors:
            leaf = err
            while leaf.context:
                leaf = sorted(leaf.context, key=lambda e: len(e.absolute_path))[-1]
            msg = f"{_source_of(sources, _key(leaf.absolute_path), source)}: {_describe_error(leaf)}"
            if msg not in lines:
                lines.append(msg)
        raise ConfigError("; ".join(lines))


def apply_defaults(document: dict, schema: dict) -> dict:
    """Fill in the schema's ``default`` values for missing optional keys (recursively)."""
    out = copy.deepcopy(document)

    def fill(node, sch):
        if not isinstance(node, dict) or not isinstance(sch, dict):
            return
        for name, sub in (sch.get("properties") or {}).items():
            if name not in node and "default" in sub:
                node[name] = copy.deepcopy(sub["default"])
            if name in node:
                fill(node[name], sub)

    fill(out, schema)
    return out


@dataclass
class Campaign:
    """A validated campaign: the raw config, the instrument and the derived models."""

    config: dict
    instrument: dict
    path: Path
    instrument_path: Path

    @property
    def name(self) -> str:
        return self.config["campaign"]["name"]

    @cached_property
    def settings(self) -> "Settings":
        """The campaign's sections, typed (:class:`Settings`): read ``settings.stars.faint_map``,
        not the raw config."""
        return settings_from_config(self.config)

    @cached_property
    def earth(self):
        from straylight.sky.orbit import EarthModel

        e = self.config["earth"]
        return EarthModel(radius_km=float(e["radius_km"]), gm_km3_s2=float(e["gm_km3_s2"]), j2=float(e["j2"]))

    @cached_property
    def orbit(self):
        from straylight.sky.orbit import orbit_from_config

        orbit_cfg = copy.deepcopy(self.config["orbit"])
        tle = orbit_cfg.get("tle") or {}
        if "file" in tle and not os.path.isabs(tle["file"]):
            tle["file"] = str(self.path.parent / tle["file"])
        return orbit_from_config(orbit_cfg, self.earth)

    @cached_property
    def orbit_radius_range_km(self) -> tuple[float, float]:
        """The satellite's smallest and largest geocentric distance over the campaign, km
        (one value for a circular orbit; sampled at the campaign times for a TLE)."""
        from straylight.sky.orbit import CircularOrbit

        if isinstance(self.orbit, CircularOrbit):
            r = self.earth.radius_km + self.orbit.altitude_km
            return (r, r)
        import numpy as np

        r = np.linalg.norm(self.orbit.position_gcrs_km(self.times), axis=-1)
        return (float(r.min()), float(r.max()))

    @cached_property
    def constraints(self):
        from straylight.sky.geometry import Constraints, DoorState

        av = self.instrument["avoidance"]
        states = tuple(
            DoorState(float(s["opening_deg"]), float(s["sun_angle_min_deg"]), bool(s["min_inclusive"]))
            for s in self.instrument["door"]["states"]
        )
        return Constraints(
            sun_min_deg=float(av["sun_min_deg"]["value"]),
            moon_min_deg=float(av["moon_min_deg"]["value"]),
            bright_limb_min_deg=float(av["bright_limb_min_deg"]["value"]),
            dark_limb_min_deg=float(av["dark_limb_min_deg"]["value"]),
            door_states=states,
        )

    @property
    def bands(self) -> list[str]:
        return list(self.instrument["bands"])

    @cached_property
    def times(self):
        """The campaign's UTC sample times (astropy Time, 1-D)."""
        from straylight.sky.timeutil import campaign_times

        c = self.config["campaign"]
        return campaign_times(c["start"], c["end"], float(c["cadence_s"]))

    @property
    def pixel_scale_arcsec(self) -> float:
        """Arcsec per pixel, derived from the pixel size and focal length (:func:`pixel_scale_arcsec`)."""
        return pixel_scale_arcsec(self.instrument)

    def instrument_value(self, section: str, key: str) -> float:
        return float(self.instrument[section][key]["value"])


def _check_campaign(cfg: dict, source: str, sources: dict | None = None) -> None:
    from straylight.sky.ephemeris import default_ephemeris
    from straylight.sky.timeutil import parse_utc, quiet_dubious_years

    def src(key):
        return _source_of(sources, key, source)

    c = cfg["campaign"]
    try:
        start = parse_utc(c["start"], f"{src('campaign.start')}: campaign.start")
        end = parse_utc(c["end"], f"{src('campaign.end')}: campaign.end")
        if cfg["orbit"]["model"] == "circular" and "circular" in cfg["orbit"]:
            parse_utc(cfg["orbit"]["circular"]["epoch"], f"{src('orbit.circular.epoch')}: orbit.circular.epoch")
    except StraylightError as exc:
        raise ConfigError(str(exc)) from exc
    if not end > start:
        raise ConfigError(f"{src('campaign.end')}: campaign.end = {c['end']!r} must be after campaign.start = "
                          f"{c['start']!r}")
    eph = default_ephemeris()
    for key, t in (("start", start), ("end", end)):
        with quiet_dubious_years():  # our line below, not ERFA's warnings before it
            jd = float(t.tdb.jd)
        if not eph.jd_start <= jd <= eph.jd_end:
            raise ConfigError(
                f"{src('campaign.' + key)}: campaign.{key} = {c[key]!r} is outside the DE405 range "
                "(1600-12-21 to 2200-02-02)"
            )
    if cfg["orbit"]["model"] == "circular" and "circular" not in cfg["orbit"]:
        raise ConfigError(f"{src('orbit.model')}: orbit.model is 'circular' but orbit.circular is missing")
    if cfg["orbit"]["model"] == "tle" and not cfg["orbit"].get("tle"):
        raise ConfigError(f"{src('orbit.model')}: orbit.model is 'tle' but orbit.tle is missing")
    # an orbit propagated far from its epoch: a warning, before any work (the TLE read once more
    # when the orbit is built)
    from straylight.sky.orbit import warn_if_epoch_far

    orbit_cfg = copy.deepcopy(cfg["orbit"])
    tle = orbit_cfg.get("tle") or {}
    if "file" in tle and not os.path.isabs(tle["file"]):  # as Campaign.orbit resolves it
        tle["file"] = str(Path(source).parent / tle["file"])
    key = "orbit.circular.epoch" if orbit_cfg["model"] == "circular" else "orbit.tle"
    warn_if_epoch_far(orbit_cfg, start, end, src(key))


def _check_instrument(inst: dict, source: str) -> None:
    for band, b in inst["bands"].items():
        if not b["wavelength_min_nm"] < b["wavelength_max_nm"]:
            raise ConfigError(
                f"{source}: bands.{band}: wavelength_min_nm = {b['wavelength_min_nm']} must be below "
                f"wavelength_max_nm = {b['wavelength_max_nm']}"
            )


ARCSEC_PER_RAD = 648000.0 / math.pi


def pixel_scale_arcsec(instrument: dict) -> float:
    """The one pixel scale, arcsec per pixel: pixel size / focal length (10 um / 28 m =
    0.07367 arcsec for CSST; published rounded as 0.074).  Rates (the pixel's etendue),
    surface brightness, apertures and the image WCS all use it."""
    p_m = float(instrument["detector"]["pixel_size_um"]["value"]) * 1e-6
    return p_m / float(instrument["telescope"]["focal_length_m"]["value"]) * ARCSEC_PER_RAD


def load_instrument(path: str | os.PathLike) -> dict:
    path = Path(path)
    inst = _read_yaml(path, "instrument file")
    if not isinstance(inst, dict):
        raise ConfigError(f"{path}: instrument file must be a mapping, got {type(inst).__name__}")
    det = inst.get("detector")
    if isinstance(det, dict) and "pixel_scale_arcsec" in det:
        raise ConfigError(
            f"{path}: detector.pixel_scale_arcsec = {det['pixel_scale_arcsec']}: the pixel scale is derived "
            f"(pixel_size_um / focal_length_m), not configured; remove it")
    validate(inst, load_schema(INSTRUMENT_SCHEMA), str(path))
    _check_instrument(inst, str(path))
    return inst


def load_campaign(path: str | os.PathLike | None = None, overrides: dict | None = None) -> Campaign:
    """Load, validate and resolve a campaign config (default: ``config/config.yaml``).

    ``overrides`` is merged (recursively) over the file's content before validation.
    """
    path = Path(path) if path is not None else DEFAULT_CONFIG
    raw = _read_yaml(path, "campaign config")
    if not isinstance(raw, dict):
        raise ConfigError(f"{path}: campaign config must be a mapping, got {type(raw).__name__}")
    if overrides:
        raw = deep_merge(raw, overrides)
    return campaign_from_dict(raw, path)


def campaign_from_dict(raw: dict, path: str | os.PathLike, sources: dict | None = None) -> Campaign:
    """Validate an already-loaded config dict (as Snakemake holds it); ``path`` locates files.

    ``sources`` (from :func:`resolve_config_files`): errors name the file that set each key."""
    path = Path(path)
    schema = load_schema(CAMPAIGN_SCHEMA)
    validate(raw, schema, str(path), sources)
    cfg = apply_defaults(raw, schema)
    _check_campaign(cfg, str(path), sources)
    inst_path = Path(cfg["instrument"])
    if not inst_path.is_absolute():
        inst_path = path.parent / inst_path
    instrument = load_instrument(inst_path)
    _check_report(cfg, list(instrument["bands"]), str(path), sources)
    return Campaign(config=cfg, instrument=instrument, path=path, instrument_path=inst_path)


def _check_report(cfg: dict, bands: list[str], source: str, sources: dict | None = None) -> None:
    """The report's bands are the instrument's (the schema cannot know them): refused here, not
    after the cube is computed."""
    chosen = (cfg.get("report") or {}).get("sky_map_bands") or []
    unknown = [b for b in chosen if b not in bands]
    if unknown:
        raise ConfigError(f"{_source_of(sources, 'report.sky_map_bands', source)}: report.sky_map_bands = {chosen!r}: "
                          f"{unknown[0]!r} is not a band of the instrument ({', '.join(bands)})")


#: Config keys holding file paths; relative ones are relative to the file that set them.
PATH_KEYS = (("instrument",), ("orbit", "tle", "file"), ("footprint", "mask_file"), ("stars", "gaia_files"),
             ("stars", "population_file"), ("stars", "btsettl_files"))


def _leaf_keys(node, prefix=""):
    if isinstance(node, dict):
        for k, v in node.items():
            key = f"{prefix}.{k}" if prefix else str(k)
            yield key
            yield from _leaf_keys(v, key)


def resolve_config_files(config: dict, files) -> tuple[dict, dict, Path]:
    """A config merged from several files, as Snakemake merges its ``configfile:`` and each
    ``--configfile`` (``files`` in increasing precedence): every relative file path of
    :data:`PATH_KEYS` made absolute against the folder of the file that set it, and which file
    set each key.  Returns (config, sources: dotted key -> file, the last file).

    The config is not validated here; :func:`campaign_from_dict` does it with ``sources``.
    """
    files = [Path(f).resolve() for f in files]
    out = copy.deepcopy(config)
    sources: dict[str, Path] = {}
    for f in files:
        doc = _read_yaml(f, "campaign config")
        if not isinstance(doc, dict):
            raise ConfigError(f"{f}: campaign config must be a mapping, got {type(doc).__name__}")
        for key in _leaf_keys(doc):
            sources[key] = f
        for keys in PATH_KEYS:
            node = doc
            for k in keys:
                node = node.get(k) if isinstance(node, dict) else None
            if node is None:
                continue
            target = out
            for k in keys[:-1]:
                target = target.get(k) if isinstance(target, dict) else None
            if not isinstance(target, dict) or target.get(keys[-1]) != node:
                continue  # a later file (or --config) set it; its own pass resolves it

            def absolute(v, base=f.parent):
                return str(base / v) if isinstance(v, str) and v and not os.path.isabs(v) else v

            target[keys[-1]] = [absolute(v) for v in node] if isinstance(node, list) else absolute(node)
    return out, sources, files[-1]


def deep_merge(base: dict, over: dict) -> dict:
    out = copy.deepcopy(base)
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = deep_merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


__all__ = ["Campaign", "load_campaign", "campaign_from_dict", "resolve_config_files", "load_instrument", "validate", "StraylightError"]


# --- typed settings: the campaign's sections parsed once, defaults from the schema only -------


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
    moonlit_grid: tuple
    moonlit_method: str
    moonlit_lut: MoonlitLUTSteps
    method: str
    lut: EarthshineLUTSteps


@dataclass(frozen=True)
class ModelsSection:
    """``models``: the zodiacal spectrum, the Moon's phase law and eclipse factor, the
    earthshine, the tolerance (fraction of the total) and what unobservable samples get."""

    zodiacal_spectrum: str
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
    """``storage``: the products' kept mantissa bits and Blosc level."""

    float_keepbits: int
    magnitude_keepbits: int
    blosc_clevel: int


@dataclass(frozen=True)
class ComputeSection:
    """``compute``: a Dask scheduler's address, a measured pipeline rate (samples/s/core) for
    ``straylight plan``, and time blocks per Snakemake job."""

    dask_scheduler: str | None = None
    pipeline_samples_per_s_per_core: float | None = None
    time_blocks_per_job: int | None = None


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
    """A settings dataclass from a config mapping: nested sections recursively, lists as tuples.
    Keys the class does not declare are ignored (the schema checks them); a key it declares and
    the config lacks is taken from the class's default or is an error naming it."""
    import dataclasses
    import typing

    hints = typing.get_type_hints(cls)
    values = {}
    for f in dataclasses.fields(cls):
        if f.name not in node:
            if f.default is dataclasses.MISSING:
                raise ConfigError(f"{where}.{f.name}: missing (no default in the schema)")
            continue
        v, hint = node[f.name], hints[f.name]
        if dataclasses.is_dataclass(hint):
            v = _typed(hint, v or {}, f"{where}.{f.name}")
        elif isinstance(v, list):
            v = tuple(tuple(x) if isinstance(x, list) else x for x in v)
        elif isinstance(v, int) and not isinstance(v, bool) and hint in (float, float | None):
            v = float(v)  # YAML's 300 for a number of seconds
        values[f.name] = v
    return cls(**values)


def settings_from_config(config: dict) -> Settings:
    """:class:`Settings` from a campaign config validated and completed by the schema
    (:func:`apply_defaults`).

    Raises
    ------
    ConfigError
        For a section or key the schema gives no default for and the config lacks.
    """
    import typing

    return Settings(**{name: _typed(cls, config.get(name) or {}, name)
                       for name, cls in typing.get_type_hints(Settings).items()})
