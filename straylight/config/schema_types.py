"""Typed settings generated from the JSON schemas: the schemas in ``config/schema/`` are the one
declaration of every setting, and each object a schema names with ``x-class`` becomes a frozen
dataclass (:func:`settings_classes`) whose fields are its properties.

A property's field type follows the schema: ``number`` a float (a YAML integer read as a float,
unless the property says ``x-number-as-written``), ``integer`` an int, ``string`` a str,
``boolean`` a bool, an array a tuple, an object with ``x-class`` (directly, through ``$ref`` or
``allOf``) that class, an object whose entries are such objects (``additionalProperties``) a
dict of them.  A field the schema may leave out (not required, or outside the section's own
default) and that has no default of its own is None when absent (the dataclass's only
defaults); an optional section without a default whose keys have defaults is built from them.

:func:`typed` reads a mapping into a class and remembers, per object, the keys as written (and
which were YAML integers), so that :func:`to_mapping` gives the same mapping back: the record
that provenance and cache keys hash.
"""

from __future__ import annotations

import copy
import dataclasses
from collections import namedtuple
from typing import Any

from straylight.config.loading import apply_defaults
from straylight.errors import ConfigError

#: the attribute holding an object's keys as written: ((key, was a YAML integer), ...)
_LAYOUT = "_as_written"


#: how one schema property is read: ``kind`` (``class``, ``list_of``, ``map``, ``list``,
#: ``float``, ``plain``), the class of a nested object (or of a list's or a mapping's entries),
#: and whether an absent section is built from its ``schema``'s defaults (``build_empty``)
FieldSpec = namedtuple("FieldSpec", "name kind cls build_empty schema")


def _target(node: dict, root: dict) -> dict:
    """The schema node that types a property: followed through ``$ref`` and ``allOf``'s ``$ref``."""
    if "$ref" in node:
        ref = node["$ref"]
        if not ref.startswith("#/"):
            raise ConfigError(f"schema: only local references are read, not {ref!r}")
        target = root
        for part in ref[2:].split("/"):
            target = target[part]
        return _target(target, root)
    for member in node.get("allOf", []):
        if "$ref" in member:
            return _target(member, root)
    return node


def _types(node: dict) -> list:
    t = node.get("type")
    return list(t) if isinstance(t, list) else [t] if t else []


_SCALARS = {"number": float, "integer": int, "string": str, "boolean": bool, "array": tuple, "object": dict}


def _scalar_type(node: dict) -> Any:
    """The Python type of a property that is not a nested class (None allowed where the schema
    allows null)."""
    types = [t for t in _types(node) if t != "null"]
    if node.get("x-number-as-written"):
        base = int | float
    elif types:
        base = _SCALARS[types[0]]
    elif "enum" in node:
        base = type(node["enum"][0])
    elif "const" in node:
        base = type(node["const"])
    else:
        base = Any
    return base | None if "null" in _types(node) else base


class _Generator:
    """Builds the classes of one schema, each ``x-class`` once (a name used twice must name the
    same keys)."""

    def __init__(self, root: dict, module: str, bases: dict):
        self.root, self.module, self.bases = root, module, bases
        self.classes: dict[str, type] = {}

    def cls(self, node: dict, where: str) -> type:
        name = node.get("x-class")
        if not name:
            raise ConfigError(
                f"schema: {where or '<top level>'}: an object with properties needs an x-class name"
            )
        props = node.get("properties") or {}
        if name in self.classes:
            known = self.classes[name]
            if node is known.__schema__:  # one definition ($defs) referenced again
                return known
            if set(known.__dataclass_fields__) != set(props):
                raise ConfigError(f"schema: {where}: x-class {name} names other keys than its first use")
            known.__schema_paths__ += (where,)
            known.__doc__ = f"The entries {', '.join(known.__schema_paths__)}."
            return known
        optional = set(props) - set(node.get("required", []))
        if isinstance(node.get("default"), dict):  # a section that may be absent: its default's keys stay
            optional |= set(props) - set(node["default"])
        specs, required_fields, default_fields = [], [], []
        for key, sub in props.items():
            spec, hint = self.field(key, sub, f"{where}.{key}" if where else key, key in optional)
            specs.append(spec)
            if key in optional and "default" not in sub:  # None when absent
                default_fields.append((key, hint, dataclasses.field(default=None)))
            else:
                required_fields.append((key, hint))
        bases = tuple(b for b in (self.bases.get(name),) if b is not None)
        cls = dataclasses.make_dataclass(name, required_fields + default_fields, bases=bases, frozen=True)
        cls.__module__ = self.module
        cls.__doc__ = " ".join(str(node.get("description") or f"``{where}``").split())
        cls.__field_specs__ = tuple(specs)
        cls.__schema__ = node
        cls.__schema_paths__ = (where,)
        self.classes[name] = cls
        return cls

    def field(self, key: str, sub: dict, where: str, optional: bool) -> tuple[FieldSpec, Any]:
        """A property's :class:`FieldSpec` and its field type."""
        node = _target(sub, self.root)
        none = optional and "default" not in sub
        if "x-class" in node or "properties" in node:
            c = self.cls(node, where)
            empty = none and any("default" in p for p in (node.get("properties") or {}).values())
            return FieldSpec(key, "class", c, empty, node), (c | None if none and not empty else c)
        items = _target(node["items"], self.root) if isinstance(node.get("items"), dict) else {}
        if "array" in _types(node) and ("x-class" in items or "properties" in items):
            c = self.cls(items, f"{where}[]")
            hint = tuple[c, ...]
            return FieldSpec(key, "list_of", c, False, None), (hint | None if none else hint)
        extra = node.get("additionalProperties")
        if isinstance(extra, dict) and not node.get("properties"):
            inner = _target(extra, self.root)
            c = self.cls(inner, f"{where}.<name>")
            hint = dict[str, c]
            return FieldSpec(key, "map", c, False, None), (hint | None if none else hint)
        hint = _scalar_type(node)
        if none and hint is not Any and type(None) not in getattr(hint, "__args__", ()):
            hint = hint | None
        kind = "list" if "array" in _types(node) else "plain"
        if "number" in _types(node) and not node.get("x-number-as-written"):
            kind = "float"
        return FieldSpec(key, kind, None, False, None), hint


def settings_classes(schema: dict, module: str, bases: dict | None = None) -> dict[str, type]:
    """The frozen dataclasses of a JSON schema: one per ``x-class`` name, the root's included.

    Parameters
    ----------
    schema : dict
        The JSON schema (its root an object with an ``x-class``).
    module : str
        The module the classes are attributes of (pickling finds them there).
    bases : dict, optional
        Class name -> a base class giving it methods.

    Returns
    -------
    dict
        Class name -> class, the root's first.
    """
    gen = _Generator(schema, module, bases or {})
    root = gen.cls(schema, "")
    return {root.__name__: root, **gen.classes}


def typed(settings_class, node: dict, where: str, written: dict | None = None):
    """An instance of a generated class from a mapping with the schema's defaults filled in
    (``node``); ``written``: the mapping as written (``node`` by default), whose keys and YAML
    integers :func:`to_mapping` gives back.  Keys the class does not declare are ignored (the
    schema checks them).

    Parameters
    ----------
    settings_class : type
        A class of :func:`settings_classes`.
    node : dict
        The validated mapping, the schema's defaults filled in.
    where : str
        Its dotted key, named by errors.
    written : dict, optional
        The mapping as written.

    Raises
    ------
    ConfigError
        For a key the schema requires and gives no default for, missing from ``node``.
    """
    written = node if not isinstance(written, dict) else written
    fields = settings_class.__dataclass_fields__
    values = {}
    for spec in settings_class.__field_specs__:
        key = f"{where}.{spec.name}" if where else spec.name
        if spec.name in node:
            values[spec.name] = _value(spec, node[spec.name], key, written.get(spec.name))
        elif spec.build_empty:
            values[spec.name] = typed(spec.cls, apply_defaults({}, spec.schema), key, {})
        elif fields[spec.name].default is dataclasses.MISSING:
            raise ConfigError(f"{key}: missing (no default in the schema)")
    obj = settings_class(**values)
    layout = tuple((k, type(v) is int) for k, v in written.items() if k in fields)
    object.__setattr__(obj, _LAYOUT, layout)
    return obj


def _value(spec: FieldSpec, v, where: str, written):
    """One value as its field reads it (see :func:`typed`)."""
    if v is None:
        return None
    if spec.kind == "class":
        return typed(spec.cls, v, where, written)
    if spec.kind == "list_of":
        w = written if isinstance(written, list) and len(written) == len(v) else v
        return tuple(typed(spec.cls, x, f"{where}[{i}]", wx) for i, (x, wx) in enumerate(zip(v, w)))
    if spec.kind == "map":
        w = written if isinstance(written, dict) else {}
        return {k: typed(spec.cls, x, f"{where}.{k}", w.get(k)) for k, x in v.items()}
    if isinstance(v, list):
        return tuple(tuple(x) if isinstance(x, list) else x for x in v)
    if spec.kind == "float" and isinstance(v, int) and not isinstance(v, bool):
        return float(v)  # YAML's 300 for a number of seconds
    return v


def to_mapping(obj) -> dict:
    """The mapping a generated object was read from: its keys as written, in their order, and
    YAML integers as integers (an object built otherwise: every field).

    Parameters
    ----------
    obj : object
        An instance of a class of :func:`settings_classes`.
    """
    layout = getattr(obj, _LAYOUT, None)
    if layout is None:
        layout = tuple((f.name, False) for f in dataclasses.fields(obj))
    out = {}
    for name, was_int in layout:
        v = getattr(obj, name)
        out[name] = int(v) if was_int and type(v) is float and v.is_integer() else _plain(v)
    return out


def _plain(v):
    if dataclasses.is_dataclass(v) and not isinstance(v, type):
        return to_mapping(v)
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, tuple):
        return [_plain(x) for x in v]
    return copy.deepcopy(v)


__all__ = ["FieldSpec", "settings_classes", "typed", "to_mapping"]
