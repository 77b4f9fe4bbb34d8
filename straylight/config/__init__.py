"""Campaign and instrument configuration: load, validate against the JSON schemas, resolve, and
parse once into typed settings.

The schemas in ``config/schema/`` are the single definition of what a config may hold; the
Snakefile validates with Snakemake's ``validate`` against the same files.  Errors name the
file, the key path, the value and what is allowed, e.g.::

    config/config.yaml: campaign.cadence_s = -5: must be > 0

Modules: :mod:`~straylight.config.loading` (reading, validating, defaults, merging config
files), :mod:`~straylight.config.schema_types` (the typed settings' classes, generated from the
schemas), :mod:`~straylight.config.settings` (the campaign's typed settings),
:mod:`~straylight.config.instrument` (the instrument's typed settings and its pixel scale),
:mod:`~straylight.config.campaign` (:class:`Campaign`, :func:`load_campaign`).  Every public
name is importable from ``straylight.config``.
"""

from straylight.config.campaign import Campaign, campaign_from_dict, load_campaign
from straylight.config.instrument import (
    ARCSEC_PER_RAD,
    AvoidanceSettings,
    BandSettings,
    DetectorSettings,
    DoorGeometrySettings,
    DoorSettings,
    DoorStateSettings,
    GhostBandSettings,
    GhostSettings,
    InstrumentSettings,
    Parameter,
    PSTSettings,
    ScatteringSettings,
    TelescopeSettings,
    instrument_settings,
    needed,
    pixel_scale_arcsec,
)
from straylight.config.loading import (
    CAMPAIGN_SCHEMA,
    CONFIG_DIR,
    DEFAULT_CONFIG,
    INSTRUMENT_SCHEMA,
    PATH_KEYS,
    REPO_ROOT,
    SCHEMA_DIR,
    _read_yaml,  # noqa: F401 - read by tests
    apply_defaults,
    deep_merge,
    load_instrument,
    load_schema,
    merged_config,
    resolve_config_files,
    validate,
)
from straylight.config.settings import (
    CampaignSection,
    CircularOrbitSection,
    ComputeSection,
    EarthSection,
    EarthshineLUTSteps,
    EarthshineSection,
    FootprintSection,
    ModelsSection,
    MoonlitLUTSteps,
    OrbitSection,
    ReportSection,
    SchedulingSection,
    Settings,
    StarsSection,
    StorageSection,
    TLESection,
    config_mapping,
    orbit_settings,
    section_settings,
    settings_from_config,
)
from straylight.errors import StraylightError

__all__ = [
    "Campaign",
    "load_campaign",
    "campaign_from_dict",
    "resolve_config_files",
    "merged_config",
    "load_instrument",
    "validate",
    "StraylightError",
    "REPO_ROOT",
    "CONFIG_DIR",
    "SCHEMA_DIR",
    "CAMPAIGN_SCHEMA",
    "INSTRUMENT_SCHEMA",
    "DEFAULT_CONFIG",
    "PATH_KEYS",
    "load_schema",
    "apply_defaults",
    "deep_merge",
    "Settings",
    "CampaignSection",
    "EarthSection",
    "FootprintSection",
    "StarsSection",
    "EarthshineLUTSteps",
    "MoonlitLUTSteps",
    "EarthshineSection",
    "ModelsSection",
    "ReportSection",
    "SchedulingSection",
    "StorageSection",
    "ComputeSection",
    "CircularOrbitSection",
    "TLESection",
    "OrbitSection",
    "settings_from_config",
    "config_mapping",
    "section_settings",
    "orbit_settings",
    "InstrumentSettings",
    "Parameter",
    "TelescopeSettings",
    "DetectorSettings",
    "BandSettings",
    "ScatteringSettings",
    "GhostSettings",
    "GhostBandSettings",
    "PSTSettings",
    "DoorGeometrySettings",
    "AvoidanceSettings",
    "DoorSettings",
    "DoorStateSettings",
    "instrument_settings",
    "needed",
    "ARCSEC_PER_RAD",
    "pixel_scale_arcsec",
]
