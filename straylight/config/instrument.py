"""The instrument's typed settings, generated from config/schema/instrument.schema.yaml (the one
declaration of every instrument setting: :mod:`straylight.config.schema_types`):
config/instruments/*.yaml parsed once with the schema's defaults filled in.

Every instrument number keeps what the file gives it: a :class:`Parameter` holds its value,
unit and source (``settings.telescope.aperture_diameter_m.value``).  The bands, the ghosts'
per-band reflectances and the door's states are plain numbers with a ``source`` per entry, as in
the file.  Optional sections and keys without a schema default are None when the file leaves
them out (:func:`needed` names one a computation needs).

The optics, sources and image layers build their objects (the door, the scattering and ghost
models, the zodiacal model, the focal plane, the bands) from these settings; the raw instrument
mapping as written, for what records or hashes the file, is produced from these settings
(:meth:`straylight.config.Campaign.instrument_mapping`).
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from functools import lru_cache

from straylight.config.loading import INSTRUMENT_SCHEMA, load_schema
from straylight.config.schema_types import settings_classes, typed
from straylight.errors import ConfigError


@lru_cache(maxsize=1)
def _schema() -> dict:
    return load_schema(INSTRUMENT_SCHEMA)


_CLASSES = settings_classes(_schema(), __name__)
#: an instrument file, typed: one field per key of the schema
InstrumentSettings = _CLASSES["InstrumentSettings"]
Parameter = _CLASSES["Parameter"]
TelescopeSettings = _CLASSES["TelescopeSettings"]
DetectorSettings = _CLASSES["DetectorSettings"]
BandSettings = _CLASSES["BandSettings"]
ZeroPointOffset = _CLASSES["ZeroPointOffset"]
ScatteringSettings = _CLASSES["ScatteringSettings"]
GhostSettings = _CLASSES["GhostSettings"]
GhostBandSettings = _CLASSES["GhostBandSettings"]
PSTSettings = _CLASSES["PSTSettings"]
PSTTail = _CLASSES["PSTTail"]
PSTTailCalibration = _CLASSES["PSTTailCalibration"]
DoorGeometrySettings = _CLASSES["DoorGeometrySettings"]
AvoidanceSettings = _CLASSES["AvoidanceSettings"]
EnvelopeSettings = _CLASSES["EnvelopeSettings"]
EnvelopeRange = _CLASSES["EnvelopeRange"]
EnvelopeMembers = _CLASSES["EnvelopeMembers"]
EnvelopeMember = _CLASSES["EnvelopeMember"]
DepthBudgetSettings = _CLASSES["DepthBudgetSettings"]
DoorSettings = _CLASSES["DoorSettings"]
DoorStateSettings = _CLASSES["DoorStateSettings"]


def _with_defaults(document: Mapping, schema: dict) -> dict:
    """A copy of ``document`` with the schema's ``default`` values for missing keys: in objects'
    properties, in the values of a mapping (``additionalProperties``) and in list items."""
    out = copy.deepcopy(dict(document))

    def fill(node, sch):
        if not isinstance(sch, dict):
            return
        if isinstance(node, dict):
            props = sch.get("properties") or {}
            for name, sub in props.items():
                if name not in node and "default" in sub:
                    node[name] = copy.deepcopy(sub["default"])
                if name in node:
                    fill(node[name], sub)
            extra = sch.get("additionalProperties")
            if isinstance(extra, dict):
                for name, value in node.items():
                    if name not in props:
                        fill(value, extra)
        elif isinstance(node, list) and isinstance(sch.get("items"), dict):
            for item in node:
                fill(item, sch["items"])

    fill(out, schema)
    return out


def instrument_settings(instrument: InstrumentSettings | Mapping) -> InstrumentSettings:
    """The typed settings of an instrument: ``instrument`` itself when it is already
    :class:`InstrumentSettings`, else parsed from an instrument mapping as
    :func:`~straylight.config.load_instrument` returns it (validated; the schema's defaults are
    filled in here, on a copy).

    Parameters
    ----------
    instrument : InstrumentSettings or Mapping
        Typed settings (returned as they are), or an instrument mapping.

    Raises
    ------
    ConfigError
        For a key the schema requires and gives no default for, missing from the mapping.
    """
    if isinstance(instrument, InstrumentSettings):
        return instrument
    return typed(InstrumentSettings, _with_defaults(instrument, _schema()), "instrument", dict(instrument))


def needed(value, key: str):
    """``value``, an optional instrument setting a computation needs; a ConfigError naming the
    instrument file's ``key`` when the file does not give it (None).

    Parameters
    ----------
    value : object or None
        The setting's value.
    key : str
        The setting's key in the instrument file, named by the error.
    """
    if value is None:
        raise ConfigError(f"instrument: {key} is needed here and the instrument file does not give it")
    return value


ARCSEC_PER_RAD = 648000.0 / math.pi


def pixel_scale_arcsec(instrument: InstrumentSettings | Mapping) -> float:
    """The one pixel scale, arcsec per pixel: pixel size / focal length (10 um / 28 m =
    0.07367 arcsec for CSST; published rounded as 0.074).  Rates (the pixel's etendue),
    surface brightness, apertures and the image WCS all use it.  ``instrument``: its typed
    settings, or its mapping (:func:`instrument_settings`).

    Parameters
    ----------
    instrument : InstrumentSettings or Mapping
        The instrument's typed settings, or its mapping.
    """
    inst = instrument_settings(instrument)
    p_m = inst.detector.pixel_size_um.value * 1e-6
    return p_m / inst.telescope.focal_length_m.value * ARCSEC_PER_RAD


__all__ = [
    "Parameter",
    "TelescopeSettings",
    "DetectorSettings",
    "BandSettings",
    "ZeroPointOffset",
    "ScatteringSettings",
    "GhostBandSettings",
    "GhostSettings",
    "PSTTail",
    "PSTTailCalibration",
    "PSTSettings",
    "DoorGeometrySettings",
    "AvoidanceSettings",
    "DoorStateSettings",
    "DoorSettings",
    "EnvelopeRange",
    "EnvelopeMember",
    "EnvelopeMembers",
    "EnvelopeSettings",
    "DepthBudgetSettings",
    "InstrumentSettings",
    "instrument_settings",
    "needed",
    "ARCSEC_PER_RAD",
    "pixel_scale_arcsec",
]
