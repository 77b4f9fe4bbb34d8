"""The instrument's typed settings: config/instruments/*.yaml parsed once, against
config/schema/instrument.schema.yaml, with the schema's defaults filled in.

Every instrument number keeps what the file gives it: a :class:`Parameter` holds its value,
unit and source (``settings.telescope.aperture_diameter_m.value``).  The bands, the ghosts'
per-band reflectances and the door's states are plain numbers with a ``source`` per entry, as in
the file.  Optional sections and keys without a schema default are None when the file leaves
them out (:func:`needed` names one a computation needs).

The optics, sources and image layers build their objects (the door, the scattering and ghost
models, the zodiacal model, the focal plane, the bands) from these settings; the raw instrument
mapping (``Campaign.instrument``) stays as written for what records or hashes the file.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache

from straylight.config.loading import INSTRUMENT_SCHEMA, load_schema
from straylight.config.settings import _typed
from straylight.errors import ConfigError


@dataclass(frozen=True)
class Parameter:
    """One instrument number as the instrument file gives it: ``value`` in ``unit``, and where
    it comes from (``source``: a paper's section, a datasheet, or "assumption: ...")."""

    value: float
    unit: str
    source: str


@dataclass(frozen=True)
class TelescopeSettings:
    """``telescope``: the aperture's diameter and the focal length, m."""

    aperture_diameter_m: Parameter
    focal_length_m: Parameter


@dataclass(frozen=True)
class DetectorSettings:
    """``detector``: the pixel (um), the noise (e-, e-/s), the PSF's EE80 radius (arcsec), and,
    for the detector images and the off-field model, the field of view (deg2), the CCD format
    (pixels) and the focal plane's layout (detectors, gap in pixels)."""

    pixel_size_um: Parameter
    read_noise_e: Parameter
    dark_current_e_per_s: Parameter
    ee80_radius_arcsec: Parameter
    field_of_view_deg2: Parameter | None = None
    nx_pixels: Parameter | None = None
    ny_pixels: Parameter | None = None
    layout_columns: Parameter | None = None
    layout_rows: Parameter | None = None
    layout_gap_pixels: Parameter | None = None


@dataclass(frozen=True)
class ZeroPointOffset:
    """``bands.<name>.zero_point_offset_mag``: an offset added to the band's AB zero point
    (``value``, mag), its ``range`` [low, high] (the assumption envelope's ends) and ``source``."""

    value: float
    unit: str
    range: tuple
    source: str


@dataclass(frozen=True)
class BandSettings:
    """``bands.<name>``: the band's edges (nm), survey exposures (count, s), its throughput (a
    parametric curve's peak and edge width, nm, or a measured curve's file and wavelength unit)
    and its published AB zero point (mag giving 1 e-/s through the aperture) with its source, and
    where none is published the zero point's offset range (:class:`ZeroPointOffset`).

    ``exposure_s`` keeps the file's number as written (integer or not): the limits' long name
    quotes it."""

    wavelength_min_nm: float
    wavelength_max_nm: float
    n_exposures: int
    exposure_s: int | float
    edge_width_nm: float
    throughput_wavelength_unit: str
    source: str
    peak_throughput: float | None = None
    zero_point_ab_mag: float | None = None
    zero_point_source: str | None = None
    zero_point_offset_mag: ZeroPointOffset | None = None
    throughput_file: str | None = None


@dataclass(frozen=True)
class ScatteringSettings:
    """``scattering``: the mirrors' Harvey-Shack BRDF (b0 in sr-1, l in rad, s), each mirror's
    clear-aperture radius (m) and where the PSF core hands over to the scattering halo (arcsec)."""

    harvey_b0: Parameter
    harvey_l: Parameter
    harvey_s: Parameter
    mirror_radii_m: tuple[Parameter, ...]
    core_blend_inner_arcsec: Parameter
    core_blend_outer_arcsec: Parameter


@dataclass(frozen=True)
class GhostBandSettings:
    """``ghosts.per_band.<name>``: the filter's surface reflectances and transmittances and the
    detector's reflectance (fractions)."""

    R1: float
    R2: float
    T1: float
    T2: float
    Rd: float
    source: str


@dataclass(frozen=True)
class GhostSettings:
    """``ghosts``: the filter (thickness and distance to the detector, mm; refractive index),
    the beam's marginal-ray angle (rad) and chief-ray incidence (deg), and each band's
    reflectances."""

    filter_thickness_mm: Parameter
    filter_detector_distance_mm: Parameter
    filter_refractive_index: Parameter
    marginal_ray_angle_rad: Parameter
    chief_ray_angle_deg: Parameter
    per_band: dict[str, GhostBandSettings]


@dataclass(frozen=True)
class PSTTail:
    """``pst.tail_log10_at_90deg``: log10 PST of the embedded default at 90 deg (``value``,
    dex), its ``range`` [low, high] (the calibration's spread over orbital phases) and
    ``source``."""

    value: float
    unit: str
    range: tuple
    source: str


@dataclass(frozen=True)
class PSTTailCalibration:
    """``pst.tail_calibration``: HST's earthshine at its 20-deg limit (V mag/arcsec2) and the
    crossing angle the tail is set to (deg)."""

    hst_earthshine_v_mag_per_arcsec2: Parameter
    crossing_limb_angle_deg: Parameter


@dataclass(frozen=True)
class PSTSettings:
    """``pst``: the PST matrix's file (relative to the instrument file; None: the embedded
    default), its source, the default's tail at 90 deg and the tail's calibration reference."""

    file: str | None
    source: str
    tail_log10_at_90deg: PSTTail
    tail_calibration: PSTTailCalibration | None = None


@dataclass(frozen=True)
class DoorGeometrySettings:
    """``door_geometry``: the door plate (m; None: the length the paper's door implies and a
    square plate, :func:`straylight.optics.door.door_from_instrument`), its reflectance, the
    aperture points of its shadow, and the telescope body that shades it (m)."""

    reflectance: Parameter
    n_aperture: Parameter
    body_radius_m: Parameter
    body_length_m: Parameter
    length_m: Parameter | None = None
    width_m: Parameter | None = None


@dataclass(frozen=True)
class AvoidanceSettings:
    """``avoidance``: the smallest angles to the Sun, the Moon and the Earth's bright and dark
    limbs, deg, and the limb's height above the surface (the top of the atmosphere), km."""

    sun_min_deg: Parameter
    moon_min_deg: Parameter
    bright_limb_min_deg: Parameter
    dark_limb_min_deg: Parameter
    limb_height_km: Parameter


@dataclass(frozen=True)
class DoorStateSettings:
    """``door.states[i]``: an opening (deg) and the smallest Sun angle it serves (deg; included
    or not)."""

    opening_deg: float
    sun_angle_min_deg: float
    min_inclusive: bool
    source: str


@dataclass(frozen=True)
class DoorSettings:
    """``door``: the aperture door's states."""

    states: tuple[DoorStateSettings, ...]


@dataclass(frozen=True)
class EnvelopeRange:
    """One parameter's range in the assumption envelope: its dark and bright ends (``range``, in
    ``unit``) and where they come from."""

    range: tuple
    unit: str
    source: str


@dataclass(frozen=True)
class EnvelopeMember:
    """One end of the assumption envelope: the PST's tail (log10 PST at 90 deg, dex), the door's
    reflectance and the body's radius (m) taken together, and the median crossing they give
    (deg; the paper's 70 deg within the tolerance)."""

    tail_log10_at_90deg: float
    door_reflectance: float
    body_radius_m: float
    median_crossing_deg: float


@dataclass(frozen=True)
class EnvelopeMembers:
    """``envelope.members``: the envelope's ends as joint values that keep the paper's median
    crossing within ``tolerance_deg`` (scripts/envelope_members.py), and their source."""

    tolerance_deg: Parameter
    pessimistic: EnvelopeMember
    optimistic: EnvelopeMember
    source: str


@dataclass(frozen=True)
class EnvelopeSettings:
    """``envelope``: the ranges of the unmeasured parameters carried into the products
    (:mod:`straylight.model.envelope`); None where the file gives no range."""

    pst_tail_dex: EnvelopeRange | None = None
    pst_tail_from_deg: Parameter | None = None
    door_reflectance: EnvelopeRange | None = None
    earth_albedo: EnvelopeRange | None = None
    earth_albedo_spectra: tuple | None = None
    body_radius_m: EnvelopeRange | None = None
    members: EnvelopeMembers | None = None


@dataclass(frozen=True)
class DepthBudgetSettings:
    """``depth_budget``: the ranges of the depth's unmeasured inputs besides the envelope's
    (:mod:`straylight.limits.budget`): read noise (e-), dark current (e-/s/pixel), per
    band the EE80 radius (arcsec) and a factor on the zodiacal light, factors on the Moon's and
    the off-field stars' light; None where the file gives no range."""

    read_noise_e: EnvelopeRange | None = None
    dark_current_e_per_s: EnvelopeRange | None = None
    ee80_radius_arcsec: dict[str, EnvelopeRange] | None = None
    zodiacal_level: dict[str, EnvelopeRange] | None = None
    moon_level: EnvelopeRange | None = None
    stars_pst_core: EnvelopeRange | None = None


@dataclass(frozen=True)
class InstrumentSettings:
    """An instrument file, typed: one field per key of config/schema/instrument.schema.yaml,
    built once from the validated file with the schema's defaults (:func:`instrument_settings`;
    a campaign's: :attr:`straylight.config.Campaign.instrument_settings`)."""

    name: str
    telescope: TelescopeSettings
    detector: DetectorSettings
    bands: dict[str, BandSettings]
    pst: PSTSettings
    door_geometry: DoorGeometrySettings
    avoidance: AvoidanceSettings
    door: DoorSettings
    scattering: ScatteringSettings | None = None
    ghosts: GhostSettings | None = None
    envelope: EnvelopeSettings | None = None
    depth_budget: DepthBudgetSettings | None = None


@lru_cache(maxsize=1)
def _schema() -> dict:
    return load_schema(INSTRUMENT_SCHEMA)


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
    return _typed(InstrumentSettings, _with_defaults(instrument, _schema()), "instrument")


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
