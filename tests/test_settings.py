"""The campaign's typed settings (straylight.config.Settings), generated from the schema: each
setting declared once (in config/schema/), a key added to the schema is a field, the mappings
given back as they were read (provenance and cache keys hash them), the schema's defaults
filled in, and the values of config/config.yaml."""

from __future__ import annotations

import ast
import copy
import dataclasses
import json
from pathlib import Path

import pytest

import straylight
from straylight.config import (
    CAMPAIGN_SCHEMA,
    INSTRUMENT_SCHEMA,
    apply_defaults,
    instrument_settings,
    load_campaign,
    load_instrument,
    load_schema,
    merged_config,
)
from straylight.config.instrument import _with_defaults
from straylight.config.schema_types import settings_classes, to_mapping, typed
from straylight.errors import ConfigError

REF = Path("/work/ref")  # the reference campaigns, where this machine has them


def _schema_sections(schema: dict) -> dict:
    """x-class name -> the set of its keys, for every object of a schema that names a class."""
    out = {}

    def walk(node):
        if isinstance(node, dict):
            if "x-class" in node and node.get("properties"):
                out[node["x-class"]] = set(node["properties"])
            for v in node.values():
                walk(v)
        elif isinstance(node, list):
            for v in node:
                walk(v)

    walk(schema)
    return out


def _declared_classes(root: Path):
    """(file, class name, its annotated field names) of every class in the package's source."""
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ClassDef):
                names = {
                    s.target.id
                    for s in node.body
                    if isinstance(s, ast.AnnAssign) and isinstance(s.target, ast.Name)
                }
                yield path.relative_to(root.parent), node.name, names


#: the objects the model builds from a section (with their methods and their own units), not
#: settings: each takes its values from the typed settings where it is built
BUILT_FROM_SETTINGS = {
    "BudgetTerm": "limits.budget: a depth budget term, from depth_budget's ranges",
    "EnvelopeParameter": "model.envelope: an envelope parameter, from envelope's ranges",
    "Constraints": "sky.geometry: the avoidance test, from avoidance (Campaign.constraints)",
    "EarthModel": "sky.orbit: the Earth's model, from earth (Campaign.earth)",
    "CircularOrbit": "sky.orbit: the propagator, from orbit.circular (Campaign.orbit)",
    "LUTSettings": "sources.earthshine.nodes: the sunlit table's nodes, hashed into its cache key",
    "MoonlitSettings": "sources.earthshine.nodes: the moonlit table's nodes, hashed into its cache key",
    "ZodiacalModel": "sources.zodiacal: the zodiacal model, from the telescope's aperture",
}


def _second_declarations(root: Path, built=BUILT_FROM_SETTINGS) -> list:
    sections = {}
    for schema in (CAMPAIGN_SCHEMA, INSTRUMENT_SCHEMA):
        sections.update(_schema_sections(load_schema(schema)))
    found = []
    for path, name, fields in _declared_classes(root):
        if path.parts[:2] == ("straylight", "config") and fields:
            found.append(f"{path}: class {name} declares fields in straylight.config")
        for cls, keys in sections.items():
            if len(keys) >= 2 and keys <= fields and name not in built:
                found.append(f"{path}: class {name} declares the keys of the schema's {cls}")
    return found


def test_each_setting_is_declared_once_in_the_schema():
    """straylight.config declares no settings class by hand (they are generated from
    config/schema/, straylight.config.schema_types), and no other class re-declares a schema
    section's keys but the model's objects built from them."""
    assert _second_declarations(Path(straylight.__file__).parent) == []


def test_a_section_declared_again_in_the_code_is_found(tmp_path):
    """The check above fails for a hand-written copy of a section (the storage's keys), and for
    a settings class written by hand in straylight.config."""
    (tmp_path / "straylight" / "config").mkdir(parents=True)
    storage = (
        "from dataclasses import dataclass\n\n\n@dataclass(frozen=True)\nclass StorageSection:\n"
        "    float_keepbits: int\n    magnitude_keepbits: int\n    blosc_clevel: int\n"
        "    compact_mag_step: float\n"
    )
    (tmp_path / "straylight" / "extra.py").write_text(storage)
    (tmp_path / "straylight" / "config" / "more.py").write_text("class Knob:\n    gain: float\n")
    assert _second_declarations(tmp_path / "straylight") == [
        "straylight/config/more.py: class Knob declares fields in straylight.config",
        "straylight/extra.py: class StorageSection declares the keys of the schema's StorageSection",
    ]


def test_a_key_added_to_the_schema_is_a_field():
    """A key added to the schema alone (with its default) is read, typed and given back: a
    section's key, a band's, a door state's."""
    schema = copy.deepcopy(load_schema(CAMPAIGN_SCHEMA))
    schema["properties"]["storage"]["properties"]["chunk_bytes"] = {"type": "integer", "default": 7}
    classes = settings_classes(schema, __name__)
    merged, _, _ = merged_config()
    s = typed(classes["Settings"], apply_defaults(merged, schema), "")
    assert s.storage.chunk_bytes == 7 and to_mapping(s)["storage"]["chunk_bytes"] == 7

    schema = copy.deepcopy(load_schema(INSTRUMENT_SCHEMA))
    schema["properties"]["bands"]["additionalProperties"]["properties"]["colour"] = {"type": "string"}
    schema["properties"]["door"]["properties"]["states"]["items"]["properties"]["speed_deg_s"] = {
        "type": "number"
    }
    classes = settings_classes(schema, __name__)
    raw = load_instrument(INSTRUMENT_SCHEMA.parents[1] / "instruments" / "csst.yaml")
    raw["bands"]["g"]["colour"] = "green"
    raw["door"]["states"][0]["speed_deg_s"] = 2
    inst = typed(classes["InstrumentSettings"], _with_defaults(raw, schema), "instrument", raw)
    assert inst.bands["g"].colour == "green" and inst.bands["u"].colour is None
    assert inst.door.states[0].speed_deg_s == 2.0 and isinstance(inst.door.states[0].speed_deg_s, float)
    assert to_mapping(inst) == raw


def test_an_object_without_a_class_name_is_refused():
    schema = copy.deepcopy(load_schema(CAMPAIGN_SCHEMA))
    del schema["properties"]["storage"]["x-class"]
    with pytest.raises(ConfigError, match=r"schema: storage: an object with properties needs an x-class"):
        settings_classes(schema, __name__)


@pytest.mark.parametrize("config", [None, REF / "default.yaml", REF / "month32.yaml"])
def test_the_mappings_are_given_back_as_read(config):
    """Campaign.config_mapping and instrument_mapping, produced from the typed settings, are the
    validated config (with the schema's defaults) and the instrument file as written, to the
    byte of their JSON (key order, YAML integers such as cadence_s: 300): provenance and the
    cache keys hash them."""
    if config is not None and not config.exists():
        pytest.skip(f"{config}: not on this machine")
    merged, _, _ = merged_config(config)
    validated = apply_defaults(merged, load_schema(CAMPAIGN_SCHEMA))
    c = load_campaign(config)
    assert json.dumps(c.config_mapping()) == json.dumps(validated)
    assert c.config_mapping()["campaign"]["cadence_s"] == 300 and c.settings.campaign.cadence_s == 300.0
    raw = load_instrument(c.instrument_path)
    assert json.dumps(c.instrument_mapping()) == json.dumps(raw)


def test_an_instrument_without_its_optional_sections_is_given_back_without_them():
    """The schema's defaults are in the settings (pst, door_geometry) and not in the mapping."""
    raw = load_instrument(INSTRUMENT_SCHEMA.parents[1] / "instruments" / "csst.yaml")
    for key in ("door_geometry", "pst", "scattering"):
        del raw[key]
    s = instrument_settings(raw)
    assert s.door_geometry.reflectance.value == 0.02 and s.pst.file is None  # schema defaults
    assert json.dumps(to_mapping(s)) == json.dumps(raw)


def test_settings_of_the_default_campaign():
    """config/config.yaml's values and the schema's defaults (config/schema/config.schema.yaml)."""
    s = load_campaign().settings
    assert s.campaign.cadence_s == 300.0 and isinstance(s.campaign.cadence_s, float)
    assert s.campaign.time_block_hours == 6 and isinstance(s.campaign.time_block_hours, float)
    assert s.earth.radius_km == 6378.137 and s.orbit.circular.inclination_deg == 41.5
    assert s.orbit.tle is None and s.instrument.endswith("instruments/csst.yaml")
    assert s.footprint.nside == 16 and s.footprint.ordering == "ring"
    assert s.stars.faint_map is True and s.stars.offfield_mag_limit == pytest.approx(2.0)
    assert s.models.tolerance == pytest.approx(0.01)  # schema default
    assert s.models.earthshine.albedo == pytest.approx(0.3)  # Stephens et al. 2015, config comment
    assert s.models.earthshine.lut.sun_zenith_step_deg == pytest.approx(0.5)  # schema default
    assert s.models.earthshine.moonlit_grid == (8, 16)
    assert s.models.zodiacal_reddening.as_tuple() == (0.9, 0.6)  # Leinert et al. 1998 eq. 22
    assert s.compute.dask_scheduler is None  # no compute section: its keys' defaults
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.stars.faint_map = False
