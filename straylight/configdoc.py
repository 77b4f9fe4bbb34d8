"""The campaign-config reference, generated from the JSON schema (config/schema/config.schema.yaml)
so that it cannot drift from what is validated: one Markdown table row per key with its type,
allowed values or range, default and description.  ``straylight config-doc`` prints it;
docs/config.md holds a copy (tests/test_config.py checks they agree)."""

from __future__ import annotations

from straylight.config import CAMPAIGN_SCHEMA, load_schema

__all__ = ["config_reference"]


def _type(node: dict) -> str:
    if "enum" in node:
        return " \\| ".join(f"`{v}`" for v in node["enum"])
    t = node.get("type", "")
    t = " or ".join(t) if isinstance(t, list) else t
    if t == "array" and isinstance(node.get("items"), dict) and "type" in node["items"]:
        t = f"array of {node['items']['type']}"
    return t


def _range(node: dict) -> str:
    parts = []
    for key, sym in (
        ("minimum", ">="),
        ("exclusiveMinimum", ">"),
        ("maximum", "<="),
        ("exclusiveMaximum", "<"),
    ):
        if key in node:
            parts.append(f"{sym} {node[key]}")
    if "pattern" in node:
        parts.append(f"matches `{node['pattern']}`")
    if "minItems" in node and node.get("minItems") == node.get("maxItems"):
        parts.append(f"{node['minItems']} items")
    return ", ".join(parts)


def _rows(node: dict, prefix: str, required: set, out: list) -> None:
    for name, child in (node.get("properties") or {}).items():
        key = f"{prefix}{name}"
        desc = " ".join(str(child.get("description", "")).split())
        default = child.get("default")
        default_s = "" if default is None or (isinstance(default, dict) and not default) else f"`{default}`"
        req = "yes" if name in required else ""
        out.append(f"| `{key}` | {_type(child)} | {_range(child)} | {default_s} | {req} | {desc} |")
        if child.get("type") == "object" and child.get("properties"):
            _rows(child, key + ".", set(child.get("required", [])), out)


def config_reference() -> str:
    """The campaign config reference (docs' Markdown: one table row per key, with type, allowed
    values, default and description) generated from the config schema."""
    schema = load_schema(CAMPAIGN_SCHEMA)
    out = [
        "# Campaign config reference",
        "",
        "Generated from `config/schema/config.schema.yaml` by `straylight config-doc`; do not edit by hand.",
        " ".join(str(schema.get("description", "")).split()),
        "",
        "| key | type | allowed | default | required | description |",
        "|---|---|---|---|---|---|",
    ]
    _rows(schema, "", set(schema.get("required", [])), out)
    return "\n".join(out) + "\n"
