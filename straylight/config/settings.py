"""The campaign's typed settings, generated from config/schema/config.schema.yaml (the one
declaration of every setting: :mod:`straylight.config.schema_types`): parsed once from the
validated config with the schema's defaults (:func:`settings_from_config`); one section alone
with the schema's defaults (:func:`section_settings`); the orbit's section with its TLE file
resolved (:func:`orbit_settings`)."""

from __future__ import annotations

import dataclasses
import functools
import os
from pathlib import Path

from straylight.config.loading import CAMPAIGN_SCHEMA, apply_defaults, load_schema
from straylight.config.schema_types import settings_classes, to_mapping, typed


@functools.lru_cache(maxsize=1)
def _campaign_schema() -> dict:
    """config/schema/config.schema.yaml, read once (callers copy what they fill in)."""
    return load_schema(CAMPAIGN_SCHEMA)


class _ZodiacalReddening:
    """Methods of ``models.zodiacal_reddening``'s class."""

    def as_tuple(self) -> tuple:
        """``(blue_per_dex, red_per_dex)``, as :class:`~straylight.sources.zodiacal.ZodiacalModel`
        takes them."""
        return (self.blue_per_dex, self.red_per_dex)


_CLASSES = settings_classes(
    _campaign_schema(), __name__, bases={"ZodiacalReddeningSection": _ZodiacalReddening}
)
#: a campaign config, typed: one field per key of the schema (``campaign.settings.stars.faint_map``)
Settings = _CLASSES["Settings"]
CampaignSection = _CLASSES["CampaignSection"]
EarthSection = _CLASSES["EarthSection"]
OrbitSection = _CLASSES["OrbitSection"]
CircularOrbitSection = _CLASSES["CircularOrbitSection"]
TLESection = _CLASSES["TLESection"]
FootprintSection = _CLASSES["FootprintSection"]
StarsSection = _CLASSES["StarsSection"]
ModelsSection = _CLASSES["ModelsSection"]
ZodiacalReddeningSection = _CLASSES["ZodiacalReddeningSection"]
EarthshineSection = _CLASSES["EarthshineSection"]
MoonlitLUTSteps = _CLASSES["MoonlitLUTSteps"]
EarthshineLUTSteps = _CLASSES["EarthshineLUTSteps"]
ReportSection = _CLASSES["ReportSection"]
SchedulingSection = _CLASSES["SchedulingSection"]
StorageSection = _CLASSES["StorageSection"]
ComputeSection = _CLASSES["ComputeSection"]


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
    return typed(Settings, config, "")


def config_mapping(settings) -> dict:
    """The config mapping :class:`Settings` were read from (its keys as written, the schema's
    defaults included): what provenance records and cache keys hash.

    Parameters
    ----------
    settings : Settings
        A campaign's typed settings (:func:`settings_from_config`).
    """
    return to_mapping(settings)


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
    schema = _campaign_schema()["properties"][name]
    spec = next(s for s in Settings.__field_specs__ if s.name == name)
    return typed(spec.cls, apply_defaults(dict(node or {}), schema), name)


def orbit_settings(node, config_dir=None) -> OrbitSection:
    """The config's ``orbit`` section, typed (:class:`OrbitSection`), a relative
    ``orbit.tle.file`` resolved against ``config_dir``.

    Parameters
    ----------
    node : dict or OrbitSection
        The validated ``orbit`` section, or its settings.
    config_dir : path-like or None
        The campaign config's folder; None: a relative TLE file is left as written.

    Returns
    -------
    OrbitSection
        The orbit's model and elements.
    """
    orbit = node if isinstance(node, OrbitSection) else typed(OrbitSection, node, "orbit")
    tle = orbit.tle
    if tle is not None and tle.file is not None and config_dir is not None and not os.path.isabs(tle.file):
        orbit = dataclasses.replace(
            orbit, tle=dataclasses.replace(tle, file=str(Path(config_dir) / tle.file))
        )
    return orbit


__all__ = [
    "CampaignSection",
    "EarthSection",
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
    "config_mapping",
    "section_settings",
    "orbit_settings",
]
