"""The :class:`Campaign`: a validated campaign config with its instrument, loaded and checked
(:func:`load_campaign`, :func:`campaign_from_dict`), and what derives from them (the orbit, the
Earth, the avoidance constraints, the typed settings of both files)."""

from __future__ import annotations

import copy
import os
from functools import cached_property
from pathlib import Path

from straylight.config.instrument import instrument_settings as _instrument_settings
from straylight.config.instrument import pixel_scale_arcsec
from straylight.config.loading import (
    CAMPAIGN_SCHEMA,
    _source_of,
    apply_defaults,
    load_instrument,
    load_schema,
    merged_config,
    validate,
)
from straylight.config.schema_types import to_mapping
from straylight.config.settings import OrbitSection, config_mapping, orbit_settings, settings_from_config
from straylight.errors import ConfigError, StraylightError


class Campaign:
    """A validated campaign: its typed settings (:attr:`settings`, every key of the campaign
    config with the schema's defaults), its instrument's (:attr:`instrument_settings`), their
    files, and the models derived from them.

    Built from the typed settings, or from the validated mappings (``config``, ``instrument``:
    read once into the settings).  The mappings, for what records or hashes them (provenance,
    cache keys, the workers), are produced from the settings: :meth:`config_mapping`,
    :meth:`instrument_mapping`.

    Parameters
    ----------
    config : dict, optional
        The validated config with the schema's defaults (or give ``settings``).
    instrument : dict, optional
        The validated instrument file, as written (or give ``instrument_settings``).
    path : path-like
        The campaign's config file.
    instrument_path : path-like
        The instrument file.
    settings : Settings, optional
        The campaign's typed settings.
    instrument_settings : InstrumentSettings, optional
        The instrument's typed settings.
    """

    def __init__(
        self,
        config=None,
        instrument=None,
        path=None,
        instrument_path=None,
        *,
        settings=None,
        instrument_settings=None,
    ):
        if (config is None) == (settings is None) or (instrument is None) == (instrument_settings is None):
            raise TypeError("Campaign: give the config or its settings, and the instrument or its settings")
        self.settings = settings if settings is not None else settings_from_config(config)
        self.instrument_settings = (
            instrument_settings if instrument_settings is not None else _instrument_settings(instrument)
        )
        self.path = Path(path)
        self.instrument_path = Path(instrument_path)

    def __eq__(self, other) -> bool:
        if not isinstance(other, Campaign):
            return NotImplemented
        return (self.settings, self.instrument_settings, self.path, self.instrument_path) == (
            other.settings,
            other.instrument_settings,
            other.path,
            other.instrument_path,
        )

    def __repr__(self) -> str:
        return f"Campaign({self.name!r}, path={str(self.path)!r})"

    def config_mapping(self) -> dict:
        """The campaign config as validated, with the schema's defaults, produced from
        :attr:`settings` (the same mapping, keys in its order): for provenance, cache keys
        and the workers."""
        return copy.deepcopy(self._config_mapping)

    def instrument_mapping(self) -> dict:
        """The instrument file as written (without the schema's defaults), produced from
        :attr:`instrument_settings`: for provenance and cache keys."""
        return copy.deepcopy(self._instrument_mapping)

    @cached_property
    def _config_mapping(self) -> dict:
        return config_mapping(self.settings)

    @cached_property
    def _instrument_mapping(self) -> dict:
        return to_mapping(self.instrument_settings)

    @property
    def config(self) -> dict:
        """:meth:`config_mapping` (kept for straylight.model.envelope, which builds a changed
        campaign from it)."""
        return self.config_mapping()

    @property
    def instrument(self) -> dict:
        """:meth:`instrument_mapping` (kept for straylight.model.envelope)."""
        return self.instrument_mapping()

    @property
    def name(self) -> str:
        """The campaign's name (campaign.name: its products' folder)."""
        return self.settings.campaign.name

    @cached_property
    def earth(self):
        """The Earth's model (radius, GM, J2) of the config's ``earth`` section."""
        from straylight.sky.orbit import EarthModel

        e = self.settings.earth
        return EarthModel(radius_km=float(e.radius_km), gm_km3_s2=float(e.gm_km3_s2), j2=float(e.j2))

    @cached_property
    def orbit_settings(self) -> OrbitSection:
        """The config's ``orbit`` section, typed (:class:`OrbitSection`; a relative TLE file
        resolved against the config's folder)."""
        return orbit_settings(self.settings.orbit, self.path.parent)

    @cached_property
    def orbit(self):
        """The satellite's orbit (circular or TLE; a relative TLE file is the config's)."""
        from straylight.sky.orbit import orbit_from_settings

        return orbit_from_settings(self.orbit_settings, self.earth)

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
        """The avoidance constraints and the door's states, of the instrument."""
        from straylight.sky.geometry import Constraints, DoorState

        inst = self.instrument_settings
        av = inst.avoidance
        states = tuple(
            DoorState(s.opening_deg, s.sun_angle_min_deg, s.min_inclusive) for s in inst.door.states
        )
        return Constraints(
            sun_min_deg=av.sun_min_deg.value,
            moon_min_deg=av.moon_min_deg.value,
            bright_limb_min_deg=av.bright_limb_min_deg.value,
            dark_limb_min_deg=av.dark_limb_min_deg.value,
            door_states=states,
            limb_height_km=av.limb_height_km.value,
        )

    @property
    def bands(self) -> list[str]:
        """The instrument's bands, in the file's order."""
        return list(self.instrument_settings.bands)

    @cached_property
    def times(self):
        """The campaign's UTC sample times (astropy Time, 1-D)."""
        from straylight.sky.timeutil import campaign_times

        c = self.settings.campaign
        return campaign_times(c.start, c.end, float(c.cadence_s))

    @property
    def pixel_scale_arcsec(self) -> float:
        """Arcsec per pixel, derived from the pixel size and focal length (:func:`pixel_scale_arcsec`)."""
        return pixel_scale_arcsec(self.instrument_settings)

    def instrument_value(self, section: str, key: str) -> float:
        """The value of the instrument's parameter ``section.key`` (e.g. ``"telescope",
        "aperture_diameter_m"``), in its unit.

        Parameters
        ----------
        section : str
            The instrument file's section (e.g. ``"telescope"``).
        key : str
            The parameter's key in that section (e.g. ``"aperture_diameter_m"``).
        """
        return getattr(getattr(self.instrument_settings, section), key).value


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
            parse_utc(
                cfg["orbit"]["circular"]["epoch"], f"{src('orbit.circular.epoch')}: orbit.circular.epoch"
            )
    except StraylightError as exc:
        raise ConfigError(str(exc)) from exc
    if not end > start:
        raise ConfigError(
            f"{src('campaign.end')}: campaign.end = {c['end']!r} must be after "
            f"campaign.start = {c['start']!r}"
        )
    eph = default_ephemeris()
    for key, t in (("start", start), ("end", end)):
        with quiet_dubious_years():  # our line below, not ERFA's warnings before it
            jd = float(t.tdb.jd)
        if not eph.jd_start <= jd <= eph.jd_end:
            raise ConfigError(
                f"{src('campaign.' + key)}: campaign.{key} = {c[key]!r} is outside the DE405 range "
                f"({eph.span})"
            )
    if cfg["orbit"]["model"] == "circular" and "circular" not in cfg["orbit"]:
        raise ConfigError(f"{src('orbit.model')}: orbit.model is 'circular' but orbit.circular is missing")
    if cfg["orbit"]["model"] == "tle" and not cfg["orbit"].get("tle"):
        raise ConfigError(f"{src('orbit.model')}: orbit.model is 'tle' but orbit.tle is missing")
    # an orbit propagated far from its epoch: a warning, before any work (the TLE read once more
    # when the orbit is built)
    from straylight.sky.orbit import warn_if_epoch_far

    orbit = orbit_settings(cfg["orbit"], Path(source).parent)  # as Campaign.orbit_settings
    key = "orbit.circular.epoch" if orbit.model == "circular" else "orbit.tle"
    warn_if_epoch_far(orbit, start, end, src(key))


def load_campaign(config=None, overrides: dict | None = None) -> Campaign:
    """Load, validate and resolve a campaign: the one loader of every entry point (the commands,
    :class:`~straylight.SkyModel`, :func:`~straylight.sky_background`, ``straylight run``).

    ``config`` (a YAML file's path or a mapping; None: the default ``config/config.yaml``) is
    merged over the default config, so it may hold only the keys it changes (as Snakemake merges
    ``--configfile`` over the Snakefile's); ``overrides`` is merged (recursively) over both
    before validation.  Errors name the file that set the key (``<config mapping>`` for a
    mapping).  A :class:`Campaign` is returned as it is.

    Parameters
    ----------
    config : str, os.PathLike, dict or Campaign, optional
        A YAML file's path, a mapping, or a :class:`Campaign` (returned as it is); None: the default
        ``config/config.yaml``.
    overrides : dict, optional
        Keys merged (recursively) over the config before validation.
    """
    if isinstance(config, Campaign) and not overrides:
        return config
    merged, sources, path = merged_config(config, overrides)
    return campaign_from_dict(merged, path, sources)


def campaign_from_dict(raw: dict, path: str | os.PathLike, sources: dict | None = None) -> Campaign:
    """Validate an already-loaded config dict (as Snakemake holds it); ``path`` locates files.

    ``sources`` (from :func:`resolve_config_files`): errors name the file that set each key.

    Parameters
    ----------
    raw : dict
        The config, already loaded and merged.
    path : str or os.PathLike
        The config file; relative file paths are resolved against its folder.
    sources : dict, optional
        Dotted key -> the file that set it (:func:`resolve_config_files`), named by errors.
    """
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
        raise ConfigError(
            f"{_source_of(sources, 'report.sky_map_bands', source)}: "
            f"report.sky_map_bands = {chosen!r}: "
            f"{unknown[0]!r} is not a band of the instrument ({', '.join(bands)})"
        )


__all__ = ["Campaign", "load_campaign", "campaign_from_dict"]
