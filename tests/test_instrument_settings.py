"""The instrument's typed settings (straylight.config.InstrumentSettings), generated from the
schema, read against it: one field per schema key, a :class:`~straylight.config.Parameter` for
every {value, unit, source} entry, None only where the schema may leave a key out, and the
values of config/instruments/csst.yaml with the sources the file gives for them."""

from __future__ import annotations

import copy
import dataclasses
import typing

import pytest

from straylight.config import (
    INSTRUMENT_SCHEMA,
    InstrumentSettings,
    Parameter,
    instrument_settings,
    load_campaign,
    load_instrument,
    load_schema,
)
from straylight.errors import ConfigError

CSST = INSTRUMENT_SCHEMA.parents[1] / "instruments" / "csst.yaml"


def _is_quantity(node: dict, defs: dict) -> bool:
    """Whether a schema node is one of the {value, unit, source} entries ($defs/quantity or a
    narrowing of it)."""
    ref = node.get("$ref")
    if ref:
        target = defs[ref.rsplit("/", 1)[-1]]
        return "value" in target.get("properties", {}) or _is_quantity(target, defs)
    return any(_is_quantity(n, defs) for n in node.get("allOf", []))


def _inner(hint):
    """``X`` of ``X | None``; the hint itself otherwise."""
    args = typing.get_args(hint)
    if len(args) == 2 and type(None) in args:
        return next(a for a in args if a is not type(None))
    return hint


def _compare(node: dict, cls, where: str, defs: dict) -> list:
    """Differences between a schema object and a settings class: keys and fields, the kind of
    each (Parameter, nested section, list, mapping), and which may be absent (a key the schema
    does not require, or that the section's own default leaves out, with no default of its
    own)."""
    props = node.get("properties", {})
    required = set(node.get("required", []))
    if "default" in node:  # the section may be absent: its default's keys are the ones always there
        required = set(node["default"])
    fields = {f.name: f for f in dataclasses.fields(cls)}
    hints = typing.get_type_hints(cls)
    problems = [f"{where}: schema key {k!r} has no field" for k in props if k not in fields]
    problems += [f"{where}: field {k!r} is not in the schema" for k in fields if k not in props]
    for k, sub in props.items():
        if k not in fields:
            continue
        key, f, hint = f"{where}.{k}", fields[k], hints[k]
        may_be_absent = k not in required and "default" not in sub
        has_default = f.default is not dataclasses.MISSING
        if may_be_absent != has_default:
            problems.append(
                f"{key}: the schema {'may leave it out' if may_be_absent else 'always gives it'} "
                f"but the field {'has no default' if may_be_absent else 'has a default'}"
            )
        if has_default and f.default is not None:
            problems.append(f"{key}: the field's default {f.default!r} is not the schema's (None: absent)")
        inner = _inner(hint)
        if _is_quantity(sub, defs):
            if inner is not Parameter:
                problems.append(f"{key}: a {{value, unit, source}} entry read as {hint}")
        elif dataclasses.is_dataclass(inner):
            problems += _compare(sub, inner, key, defs)
        elif sub.get("type") == "array" and isinstance(sub.get("items"), dict):
            item = (typing.get_args(inner) or (None,))[0]
            if _is_quantity(sub["items"], defs):
                if item is not Parameter:
                    problems.append(f"{key}: a list of {{value, unit, source}} entries read as {hint}")
            elif "properties" in sub["items"]:
                problems += _compare(sub["items"], item, f"{key}[]", defs)
        elif isinstance(sub.get("additionalProperties"), dict):
            value = typing.get_args(inner)[1] if typing.get_origin(inner) is dict else None
            if not dataclasses.is_dataclass(value):
                problems.append(f"{key}: a mapping of sections read as {hint}")
            else:
                problems += _compare(sub["additionalProperties"], value, f"{key}.<name>", defs)
    return problems


def _schema() -> dict:
    return load_schema(INSTRUMENT_SCHEMA)


def test_settings_declare_every_schema_key_and_nothing_else():
    schema = _schema()
    assert _compare(schema, InstrumentSettings, "instrument", schema["$defs"]) == []


@pytest.mark.parametrize("where", ["properties", "detector", "bands", "ghosts.per_band", "door.states"])
def test_a_schema_key_without_a_field_is_found(where):
    """The comparison above fails when the schema gains a key, at the top, in a section, in a
    band, in a mapping's entries or in a list's items."""
    schema = copy.deepcopy(_schema())
    node = schema
    if where != "properties":
        for part in where.split("."):
            node = node["properties"][part]
        node = node.get("additionalProperties") or node.get("items") or node
    node["properties"]["colour"] = {"type": "string"}
    assert any(
        "'colour' has no field" in p
        for p in _compare(schema, InstrumentSettings, "instrument", schema["$defs"])
    )


def test_csst_values_and_their_sources():
    """config/instruments/csst.yaml as the settings read it; each number's source is the
    file's."""
    s = load_campaign().instrument_settings
    assert s.telescope.aperture_diameter_m == Parameter(2.0, "m", "seed paper sect. 3.3 (D); Zhan 2021")
    assert isinstance(s.telescope.aperture_diameter_m.value, float)
    assert s.telescope.focal_length_m.value == 28.0  # seed paper sect. 3.3 (f)
    assert s.detector.pixel_size_um.value == 10.0 and "Gong et al. 2019" in s.detector.pixel_size_um.source
    assert s.detector.read_noise_e.value == 5.0  # Gong et al. 2019 Table 1
    assert s.detector.nx_pixels.value == 9216 and s.detector.ny_pixels.value == 9232  # Zhan 2021
    assert (s.scattering.harvey_b0.value, s.scattering.harvey_b0.unit) == (139257000.0, "1 / sr")  # paper 4.2
    assert [r.value for r in s.scattering.mirror_radii_m] == [1.0, 0.25, 0.5, 0.1]
    assert s.scattering.mirror_radii_m[0].source.startswith("primary: D/2")
    assert s.ghosts.chief_ray_angle_deg.value == 3.9  # paper sect. 4.3
    nuv = s.ghosts.per_band["NUV"]
    assert nuv.R1 == 0.0093 and nuv.source == "seed paper sect. 4.3 NUV example"
    assert s.door_geometry.length_m.value == 2.4713 and s.door_geometry.length_m.source.startswith("derived")
    assert s.door_geometry.reflectance.value == 0.02  # pi x the paint's measured BRDF (docs/pst.md)
    assert s.door_geometry.body_radius_m.value == 1.5  # the middle of 1.0-2.1 m (docs/pst.md)
    assert s.avoidance.sun_min_deg == Parameter(
        50.0, "deg", "seed paper sect. 1 (minimum 50 deg from the Sun)"
    )
    assert [(d.opening_deg, d.sun_angle_min_deg, d.min_inclusive) for d in s.door.states] == [
        (135.0, 65.0, False),
        (105.0, 50.0, True),
    ]  # paper sect. 2.2
    assert s.pst.file is None
    g = s.bands["g"]
    assert (g.wavelength_min_nm, g.wavelength_max_nm, g.n_exposures, g.exposure_s) == (400.0, 550.0, 2, 150)
    assert g.zero_point_ab_mag == 26.23 and g.peak_throughput == 0.73  # sim_csst_lens; Wen et al. 2024
    assert g.throughput_wavelength_unit == "angstrom" and g.throughput_file is None  # schema default
    # NUV: the AB zero point of Wen et al. 2024's curve (csst.yaml), no longer None (flat top)
    assert s.bands["NUV"].zero_point_ab_mag == 24.87
    assert list(s.bands) == ["NUV", "u", "g", "r", "i", "z", "y"]
    # y: the zero point that alone closes the residual to Gong et al. 2019 (test_published_depths.py)
    assert s.bands["y"].zero_point_ab_mag is None and s.bands["y"].zero_point_offset_mag.range == (-0.26, 0.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.telescope.focal_length_m = Parameter(1.0, "m", "x")


def test_a_file_without_the_optional_sections_takes_the_schema_defaults():
    """No door_geometry, pst, edge widths: the schema's defaults (the door's reflectance, its
    aperture points, no body, the embedded PST, 5 nm edges); the door's plate from the paper."""
    from straylight.optics.door import door_from_instrument, door_length_from_paper

    raw = load_instrument(CSST)
    for key in ("door_geometry", "pst", "scattering"):
        del raw[key]
    del raw["bands"]["u"]["edge_width_nm"]
    s = instrument_settings(raw)
    assert s.door_geometry.length_m is None and s.door_geometry.reflectance.value == 0.02
    assert (s.door_geometry.n_aperture.value, s.door_geometry.body_radius_m.value) == (256, 0.0)
    assert s.pst.file is None and s.scattering is None and s.bands["u"].edge_width_nm == 5.0
    d = door_from_instrument(s)
    assert d.length_m == d.width_m == door_length_from_paper(1.0) and d.body_length_m == 0.0
    from straylight.optics.scatter import scatter_model_from_instrument

    with pytest.raises(ConfigError, match="scattering"):
        scatter_model_from_instrument(s)


def test_readers_give_the_same_objects_from_the_mapping_and_the_settings():
    from straylight.image.focal_plane import focal_plane_from_instrument
    from straylight.optics.bandpass import load_band
    from straylight.optics.door import door_from_instrument
    from straylight.optics.ghosts import ghost_model_from_instrument
    from straylight.optics.scatter import scatter_model_from_instrument
    from straylight.sources.zodiacal import zodiacal_model_from_instrument

    c = load_campaign()
    raw, typed = c.instrument_mapping(), c.instrument_settings
    assert instrument_settings(raw) == typed and instrument_settings(typed) is typed
    for reader in (
        door_from_instrument,
        scatter_model_from_instrument,
        focal_plane_from_instrument,
        zodiacal_model_from_instrument,
    ):
        assert reader(raw) == reader(typed)
    assert ghost_model_from_instrument(raw, "g") == ghost_model_from_instrument(typed, "g")
    a, b = load_band(raw, "g"), load_band(typed, "g")
    assert a.origin == b.origin and a.throughput.tobytes() == b.throughput.tobytes()
