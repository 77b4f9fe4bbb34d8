"""Loading the campaign and instrument YAML and validating them against the JSON schemas.

The schemas in ``config/schema/`` are the single definition of what a config may hold; the
Snakefile validates with Snakemake's ``validate`` against the same files.  Errors name the
file, the key path, the value and what is allowed, e.g.::

    config/config.yaml: campaign.cadence_s = -5: must be > 0
"""

from __future__ import annotations

import copy
import os
from pathlib import Path
from typing import Any

import yaml

from straylight.errors import ConfigError

REPO_ROOT = Path(__file__).resolve().parents[2]
# The default config and schemas: the repository's config/ (a source checkout, where Snakemake
# reads the same files), else the copy an installed wheel carries as straylight/_config
# (pyproject.toml maps config/ to that package).
_PACKAGED_CONFIG = Path(__file__).resolve().parents[1] / "_config"
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
        raise ConfigError(
            f"{path}: cannot read {what}: not UTF-8 text (byte 0x{exc.object[exc.start]:02x} "
            f"at offset {exc.start}); expected a YAML file"
        ) from None
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
    """A JSON schema (YAML) of ``config/schema/``, as a mapping.

    Parameters
    ----------
    path : pathlib.Path
        The schema's file.
    """
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
    the file that set the key; ``source`` otherwise.

    Parameters
    ----------
    document : object
        The loaded document.
    schema : dict
        The JSON schema.
    source : str
        The document's file, named by errors when ``sources`` does not name one.
    sources : dict, optional
        Dotted key -> the file that set it (:func:`resolve_config_files`).
    """
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
    """Fill in the schema's ``default`` values for missing optional keys (recursively).

    Parameters
    ----------
    document : dict
        The document, validated against ``schema``.
    schema : dict
        The JSON schema.
    """
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


def _check_instrument(inst: dict, source: str) -> None:
    for band, b in inst["bands"].items():
        if not b["wavelength_min_nm"] < b["wavelength_max_nm"]:
            raise ConfigError(
                f"{source}: bands.{band}: wavelength_min_nm = {b['wavelength_min_nm']} must be below "
                f"wavelength_max_nm = {b['wavelength_max_nm']}"
            )


def load_instrument(path: str | os.PathLike) -> dict:
    """An instrument file, validated against its schema, as written (a mapping; its typed
    settings: :func:`straylight.config.instrument_settings`).

    Parameters
    ----------
    path : str or os.PathLike
        The instrument file (YAML).

    Raises
    ------
    ConfigError
        For a file that cannot be read, is not valid, or configures the derived pixel scale.
    """
    path = Path(path)
    inst = _read_yaml(path, "instrument file")
    if not isinstance(inst, dict):
        raise ConfigError(f"{path}: instrument file must be a mapping, got {type(inst).__name__}")
    det = inst.get("detector")
    if isinstance(det, dict) and "pixel_scale_arcsec" in det:
        raise ConfigError(
            f"{path}: detector.pixel_scale_arcsec = {det['pixel_scale_arcsec']}: the pixel scale is derived "
            f"(pixel_size_um / focal_length_m), not configured; remove it"
        )
    validate(inst, load_schema(INSTRUMENT_SCHEMA), str(path))
    _check_instrument(inst, str(path))
    return inst


#: Config keys holding file paths; relative ones are relative to the file that set them.
PATH_KEYS = (
    ("instrument",),
    ("orbit", "tle", "file"),
    ("footprint", "mask_file"),
    ("stars", "gaia_files"),
    ("stars", "population_file"),
    ("stars", "btsettl_files"),
)


def _leaf_keys(node, prefix=""):
    if isinstance(node, dict):
        for k, v in node.items():
            key = f"{prefix}.{k}" if prefix else str(k)
            yield key
            yield from _leaf_keys(v, key)


#: The name errors give a config passed as a mapping (its relative paths are the current folder's)
MAPPING_SOURCE = "<config mapping>"


def _layer(item, resolve: bool = True) -> tuple[dict, Path, Path]:
    """(document, the name errors give it, the folder its relative paths are against) of a
    config file or a mapping; ``resolve``: the file named by its absolute path, else as given."""
    from collections.abc import Mapping

    if isinstance(item, Mapping):
        return dict(item), Path(MAPPING_SOURCE), Path.cwd()
    if not isinstance(item, (str, os.PathLike)):
        raise ConfigError(
            f"config: expected a path to a campaign YAML file or a mapping, got {type(item).__name__}"
        )
    f = Path(item).resolve() if resolve else Path(item)
    doc = _read_yaml(f, "campaign config")
    if not isinstance(doc, dict):
        raise ConfigError(f"{f}: campaign config must be a mapping, got {type(doc).__name__}")
    return doc, f, Path(item).resolve().parent


def _resolve_layers(config: dict, layers) -> tuple[dict, dict]:
    """``config`` with each layer's relative file paths made absolute against the layer's folder,
    and which layer set each key (see :func:`resolve_config_files`)."""
    out = copy.deepcopy(config)
    sources: dict[str, Path] = {}
    for doc, name, base in layers:
        for key in _leaf_keys(doc):
            sources[key] = name
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

            def absolute(v, base=base):
                return str(base / v) if isinstance(v, str) and v and not os.path.isabs(v) else v

            target[keys[-1]] = [absolute(v) for v in node] if isinstance(node, list) else absolute(node)
    return out, sources


def resolve_config_files(config: dict, files) -> tuple[dict, dict, Path]:
    """A config merged from several files, as Snakemake merges its ``configfile:`` and each
    ``--configfile`` (``files`` in increasing precedence): every relative file path of
    :data:`PATH_KEYS` made absolute against the folder of the file that set it, and which file
    set each key.  Returns (config, sources: dotted key -> file, the last file).

    The config is not validated here; :func:`campaign_from_dict` does it with ``sources``.

    Parameters
    ----------
    config : dict
        The config merged from ``files``, as Snakemake holds it.
    files : sequence of str or os.PathLike
        The config files, in increasing precedence.
    """
    layers = [_layer(f) for f in files]
    out, sources = _resolve_layers(config, layers)
    return out, sources, layers[-1][1]


def merged_config(config=None, overrides: dict | None = None) -> tuple[dict, dict, Path]:
    """The campaign config every entry point runs: ``config`` (a YAML file's path, or a mapping;
    None: the default config alone) merged over the default config (``config/config.yaml``), as
    ``straylight run``'s Snakemake merges it, so a campaign file may hold only the keys it
    changes; then ``overrides`` over both.  Each layer's relative file paths (:data:`PATH_KEYS`)
    are made absolute against its own folder (a mapping's: the current folder).  Returns
    (config, sources: dotted key -> the file that set it, the campaign's file: ``config``'s, or
    :data:`MAPPING_SOURCE` for a mapping); not validated (:func:`campaign_from_dict` does it).

    Parameters
    ----------
    config : str, os.PathLike or dict, optional
        A YAML file's path, or a mapping; None: the default config alone.
    overrides : dict, optional
        Keys merged (recursively) over both.

    Raises
    ------
    ConfigError
        A file that cannot be read or is not a mapping, or ``config`` neither a path nor a
        mapping.
    """
    items = [DEFAULT_CONFIG] if config is None else [DEFAULT_CONFIG, config]
    layers = [_layer(item, resolve=False) for item in items]  # errors name the file as the user did
    merged: dict = {}
    for doc, _, _ in layers:
        merged = deep_merge(merged, doc)
    if overrides:
        merged = deep_merge(merged, overrides)
    out, sources = _resolve_layers(merged, layers)
    return out, sources, layers[-1][1]


def deep_merge(base: dict, over: dict) -> dict:
    """``over`` merged over a copy of ``base``, mappings recursively (other values replaced).

    Parameters
    ----------
    base : dict
        The mapping merged over (not changed).
    over : dict
        The mapping whose values win.
    """
    out = copy.deepcopy(base)
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = deep_merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


__all__ = [
    "REPO_ROOT",
    "CONFIG_DIR",
    "SCHEMA_DIR",
    "CAMPAIGN_SCHEMA",
    "INSTRUMENT_SCHEMA",
    "DEFAULT_CONFIG",
    "PATH_KEYS",
    "load_schema",
    "validate",
    "apply_defaults",
    "load_instrument",
    "resolve_config_files",
    "merged_config",
    "MAPPING_SOURCE",
    "deep_merge",
]
