"""The campaign's typed settings (straylight.config.Settings) against the schema they are read
with: one field per schema key (so neither can gain a key the other lacks), the schema's
defaults filled in, and the values of config/config.yaml."""

from __future__ import annotations

import dataclasses
import typing

import pytest

from straylight.config import DEFAULT_CONFIG, Settings, load_campaign, load_schema

#: schema sections the settings leave to the Campaign's own objects (EarthModel, the orbit) or
#: to loading (the instrument file's path)
NOT_IN_SETTINGS = {"earth", "orbit", "instrument"}


def _fields(cls) -> dict:
    return typing.get_type_hints(cls)


def _compare(schema_node: dict, cls, where: str) -> list:
    """Differences between a schema object's properties and a settings class's fields."""
    props = schema_node.get("properties", {})
    hints = _fields(cls)
    problems = [f"{where}: schema key {k!r} has no field" for k in props if k not in hints]
    problems += [f"{where}: field {k!r} is not in the schema" for k in hints if k not in props]
    for k, hint in hints.items():
        if k in props and dataclasses.is_dataclass(hint):
            problems += _compare(props[k], hint, f"{where}.{k}")
    return problems


def test_settings_declare_every_schema_key_and_nothing_else():
    from pathlib import Path

    schema = load_schema(Path(DEFAULT_CONFIG).parent / "schema" / "config.schema.yaml")
    top = {k: v for k, v in schema["properties"].items() if k not in NOT_IN_SETTINGS}
    assert _compare({"properties": top}, Settings, "config") == []


def test_settings_of_the_default_campaign():
    """config/config.yaml's values and the schema's defaults (config/schema/config.schema.yaml)."""
    s = load_campaign().settings
    assert s.campaign.cadence_s == 300.0 and isinstance(s.campaign.cadence_s, float)
    assert s.campaign.time_block_hours == 6
    assert s.footprint.nside == 16 and s.footprint.ordering == "ring"
    assert s.stars.faint_map is True and s.stars.offfield_mag_limit == pytest.approx(2.0)
    assert s.models.tolerance == pytest.approx(0.01)  # schema default
    assert s.models.earthshine.albedo == pytest.approx(0.3)  # Stephens et al. 2015, config comment
    assert s.models.earthshine.lut.sun_zenith_step_deg == pytest.approx(0.5)  # schema default
    assert s.models.earthshine.moonlit_grid == (8, 16)
    assert s.compute.dask_scheduler is None
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.stars.faint_map = False
