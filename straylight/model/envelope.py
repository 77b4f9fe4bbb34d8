"""The assumption envelope: the unmeasured parameters' ranges carried into the products.

Each source declares the parameters its value rests on in the registry
(:class:`~straylight.model.registry.Assumption`); one with an ``envelope`` key has a range in the
instrument file's ``envelope`` section.  Every parameter carried scales some parts of the
background linearly, so the background at either end of the envelope is the computed parts
times per-band factors, summed: no second evaluation.

* ``pst_tail``: a factor 10^dex on the PST beyond the tail's start (``pst_tail_from_deg``, 30 deg:
  the paper's 1e-6 anchor; beyond it the tail is a model).  Where a sample is observable, the
  Earth is at least the dark-limb angle from the axis, the Moon at least its avoidance angle, the
  Sun at least its own, all beyond the tail's start (checked here): the Sun's, the Moon's and the
  Earth's terms (direct and via the door, whose light enters at 45-90 deg) scale with it.  The
  planets and the stars also shine through the measured part of the PST: not carried.  When
  the instrument's ``pst.tail_log10_at_90deg`` has a range of some width, its ends minus its
  value replace ``pst_tail_dex``: the change at 90 deg, the largest along the log-linear tail,
  applied to all of it (the envelope is then at least as wide as the calibration's spread).
* ``door_reflectance``: the door's Lambertian-equivalent reflectance (its paint and angular law
  together), over the configured value: scales the earthshine via the door.
* ``earth_albedo``: the Earth's albedo level along the orbit over the grey albedo, times, per
  band, the spread of the published albedo spectra (``earth_albedo_spectra``, each at the same
  Bond albedo) around the configured one (:mod:`straylight.sources.earthshine.albedo`): scales the
  earthshine (sunlit and moonlit, direct and via the door).

* ``zero_point``: a band's unpublished AB zero point (the instrument's
  ``bands.<band>.zero_point_offset_mag`` range, where a band has one): a zero point fainter by
  dmag scales every part of the band by 10^(0.4 dmag) and shifts its limit by dmag.

* ``calibrated_members`` (the instrument's ``envelope.members``): the PST's tail, the door's
  reflectance and the body's radius taken together, at two joint values that keep the paper's
  median crossing within a tolerance (scripts/envelope_members.py).  The model is re-evaluated
  at each (:func:`end_campaign`: the default PST with that tail, log-linear from the 30-deg
  anchor, so the change grows from zero at 30 deg to its full value at 90 deg), and the parts it
  scales at the end are those of the re-evaluation, summed in :data:`MEMBER_GROUPS`
  (``<group>_<end>``: :func:`end_part_name`);
  ``pst_tail`` and ``door_reflectance`` are then not carried apart.

The optimistic end takes every parameter's dark end, the pessimistic end its bright end (for
the zero point: its faint end)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from straylight.errors import ConfigError

__all__ = [
    "ENDS",
    "MEMBER_GROUPS",
    "MEMBER_LEAVES",
    "Envelope",
    "EnvelopeParameter",
    "campaign_envelope",
    "end_campaign",
    "end_part_name",
    "end_parts",
]

#: the envelope's ends: every parameter at its dark end, every parameter at its bright end
ENDS = ("optimistic", "pessimistic")
#: the parts the calibrated members change (the PST's tail: the Sun, the Moon and both
#: earthshine paths; the door and the body: the earthshine via the door), re-evaluated at each end
MEMBER_LEAVES = ("sun", "moon", "earthshine_direct", "earthshine_door")
#: how the re-evaluated parts are kept at an end (the cube's ``<group>_<end>``): summed in groups
#: that the other parameters scale alike (the albedo both earthshine paths, nothing the Sun and
#: the Moon), so two variables per end instead of four
MEMBER_GROUPS = {"earthshine": ("earthshine_direct", "earthshine_door"), "sun_moon": ("sun", "moon")}


def end_part_name(leaf: str, end: str) -> str:
    """The name of a part re-evaluated at an end of the envelope (a cube variable).

    Parameters
    ----------
    leaf : str
        The part or group (e.g. ``"earthshine"``, a :data:`MEMBER_GROUPS` key).
    end : str
        One of :data:`ENDS`.

    Returns
    -------
    str
        ``<leaf>_<end>``.
    """
    return f"{leaf}_{end}"


@dataclass(frozen=True)
class EnvelopeParameter:
    """One parameter of the envelope.

    Attributes
    ----------
    key : str
        Its key in the instrument file's ``envelope`` section.
    name : str
        Where it is configured (the registry's :class:`~straylight.model.registry.Assumption`).
    leaves : tuple of str
        The background's parts (or components without parts) it scales.
    dark, bright : ndarray, shape (n_bands,)
        The factor on those parts at its dark and bright end, per band (dimensionless).
    range : tuple of float
        Its configured range (dark, bright), in ``unit``.
    unit, source : str
        The range's unit and where it comes from.
    zero_point : bool
        Whether it is a zero point's offset: then ``dark`` and ``bright`` are the offsets (mag,
        per band) from the nominal zero point at the optimistic and pessimistic ends, applied to
        every part and to the limit, and ``leaves`` is empty.
    reevaluated : bool
        Whether its ends are re-evaluations of the model (the calibrated members): then its
        ``leaves`` at an end are the groups ``<group>_<end>`` of :data:`MEMBER_GROUPS`
        (:func:`end_part_name`), and
        ``dark`` and ``bright`` are ones.
    """

    key: str
    name: str
    leaves: tuple
    dark: np.ndarray
    bright: np.ndarray
    range: tuple
    unit: str
    source: str
    zero_point: bool = False
    reevaluated: bool = False


class Envelope:
    """The campaign's envelope: its parameters and their factors in ``bands``.

    Parameters
    ----------
    parameters : sequence of EnvelopeParameter
        The parameters carried.
    bands : sequence of str
        The bands the factors are given in (their order).
    """

    def __init__(self, parameters, bands):
        self.parameters = tuple(parameters)
        self.bands = tuple(bands)

    @property
    def leaves(self) -> tuple:
        """The parts some parameter scales, in the order first met, then the parts re-evaluated
        at the ends (:func:`end_part_name`)."""
        out = []
        for p in self.parameters:
            out += [leaf for leaf in p.leaves if leaf not in out]
        if any(p.reevaluated for p in self.parameters):
            out += [end_part_name(g, e) for e in ENDS for g in MEMBER_GROUPS]
        return tuple(dict.fromkeys(out))

    def _reevaluated(self, only=None) -> tuple:
        """The re-evaluated parts (of the parameters ``only`` selects)."""
        out = []
        for p in self.parameters:
            if p.reevaluated and (only is None or p.key == only):
                out += [leaf for leaf in p.leaves if leaf not in out]
        return tuple(out)

    def factors(self, end: str, only=None) -> dict:
        """Each scaled part's factor at an end: the product of its parameters' factors.

        Parameters
        ----------
        end : str
            One of :data:`ENDS`.
        only : str or None
            A parameter's key: that parameter alone at the end, the others at their nominal
            values (None: every parameter).

        Returns
        -------
        dict of str to ndarray
            Part -> factor per band, shape (n_bands,), dimensionless.
        """
        if end not in ENDS:
            raise ValueError(f"envelope end {end!r}: one of {ENDS}")
        out = {}
        for p in self.parameters:
            if p.zero_point or (only is not None and p.key != only):
                continue
            f = p.dark if end == "optimistic" else p.bright  # ones for a re-evaluated one
            for leaf in p.leaves:
                out[leaf] = out.get(leaf, 1.0) * f
        return out

    def zero_point_shift(self, end: str, only=None) -> np.ndarray:
        """The bands' zero points at an end minus the nominal ones, mag (n_bands,): the limit's
        shift (0 without a zero-point parameter).

        Parameters
        ----------
        end : str
            One of :data:`ENDS`.
        only : str or None
            As :meth:`factors`.

        Returns
        -------
        ndarray, shape (n_bands,)
            mag.
        """
        if end not in ENDS:
            raise ValueError(f"envelope end {end!r}: one of {ENDS}")
        out = np.zeros(len(self.bands))
        for p in self.parameters:
            if p.zero_point and (only is None or p.key == only):
                out = out + (p.dark if end == "optimistic" else p.bright)
        return out

    def scaled_total(self, total, parts: Mapping, end: str, only=None) -> np.ndarray:
        """The total background at an end of the envelope: ``total`` plus each scaled part times
        its factor minus 1.

        Parameters
        ----------
        total : array_like, shape (..., n_bands)
            The nominal total, e-/s/pix.
        parts : mapping of str to array_like, shape (..., n_bands)
            The nominal parts the envelope scales and those re-evaluated at the ends
            (:attr:`leaves`), e-/s/pix.
        end : str
            One of :data:`ENDS`.
        only : str or None
            As :meth:`factors`.

        Returns
        -------
        ndarray of float64, shape (..., n_bands)
            e-/s/pix.
        """
        out = np.array(total, dtype=np.float64)
        fac = self.factors(end, only)
        done = set()
        if self._reevaluated(only):
            # the end's re-evaluated groups, times the other parameters' factors (alike in a group)
            for group, leaves in MEMBER_GROUPS.items():
                f = [np.asarray(fac.get(leaf, 1.0), np.float64) for leaf in leaves]
                if not all(np.array_equal(x, f[0]) for x in f):
                    raise ValueError(f"envelope: the parts of {group!r} are scaled unalike: {f}")
                out += np.asarray(parts[end_part_name(group, end)], np.float64) * f[0]
                for leaf in leaves:
                    out -= np.asarray(parts[leaf], np.float64)
                done.update(leaves)
        for leaf, f in fac.items():
            if leaf not in done:
                out += np.asarray(parts[leaf], np.float64) * (np.asarray(f, np.float64) - 1.0)
        shift = self.zero_point_shift(end, only)
        if np.any(shift != 0):  # the band's throughput: every part
            out *= 10.0 ** (0.4 * shift)
        return out

    def attrs(self) -> dict:
        """The envelope for a product's attributes (JSON-able): per parameter, what it is, the
        parts it scales and its factors per band at each end.

        Returns
        -------
        dict
            key -> {parameter, scales, range, unit, source, factor_dark, factor_bright (band ->
            factor)}; ``ends``: what the pessimistic and optimistic ends are.
        """
        out = {
            "ends": "pessimistic: every parameter at its bright end; optimistic: at its dark end; "
            "each scales its parts linearly (the other parts unchanged), except a re-evaluated one, "
            "whose parts at an end are the model's at that end's values",
        }
        for p in self.parameters:
            if p.reevaluated:
                out[p.key] = {
                    "parameter": p.name,
                    "scales": list(p.leaves),
                    "reevaluated": "the model re-evaluated at each end's values: background.zarr's "
                    + ", ".join(f"{g}_<end>" for g in MEMBER_GROUPS),
                    "range": [float(v) for v in p.range],
                    "unit": p.unit,
                    "source": p.source,
                }
                continue
            out[p.key] = {
                "parameter": p.name,
                "scales": ["every part (the band's throughput); the limit by the offset"]
                if p.zero_point
                else list(p.leaves),
                "range": [float(v) for v in p.range],
                "unit": p.unit,
                "source": p.source,
                ("offset_mag_dark" if p.zero_point else "factor_dark"): {
                    b: float(v) for b, v in zip(self.bands, p.dark)
                },
                ("offset_mag_bright" if p.zero_point else "factor_bright"): {
                    b: float(v) for b, v in zip(self.bands, p.bright)
                },
            }
        return out


def _leaves_of(entry) -> tuple:
    """The leaves a registry source adds to: its component's parts, or the component, or the
    part it names."""
    from straylight.model import registry

    for c in registry.COMPONENTS:
        if c.name == entry.adds_to:
            return tuple(p for p, _ in c.parts) or (c.name,)
    return (entry.adds_to,)


def _declared() -> dict:
    """Each envelope key -> (parameter name, leaves it scales), from the registry's sources."""
    from straylight.model import registry

    out = {}
    for entry in registry.SOURCES:
        for p in entry.parameters:
            if not isinstance(p, registry.Assumption) or not p.envelope:
                continue
            leaves = tuple(p.scales) or _leaves_of(entry)
            name, known = out.get(p.envelope, (p.name, ()))
            out[p.envelope] = (name, known + tuple(x for x in leaves if x not in known))
    return out


def _pst_tail(campaign, spec, bands):
    """(dark, bright) factors and (range, unit, source) of the PST's tail."""
    inst = campaign.instrument_settings
    env = inst.envelope
    k = campaign.constraints
    start = float(env.pst_tail_from_deg.value) if env.pst_tail_from_deg is not None else 30.0
    nearest = min(k.dark_limb_min_deg, k.moon_min_deg, k.sun_min_deg)
    if start > nearest:
        raise ConfigError(
            f"envelope.pst_tail_from_deg = {start:g}: beyond the nearest avoidance angle "
            f"({nearest:g} deg): observable light would pass through the PST before the tail"
        )
    tail = getattr(inst.pst, "tail_log10_at_90deg", None)
    if tail is not None and float(max(tail.range) - min(tail.range)) > 0:
        dex = (float(min(tail.range)) - float(tail.value), float(max(tail.range)) - float(tail.value))
        rng, unit, source = dex, "dex", f"pst.tail_log10_at_90deg's range minus its value: {tail.source}"
    else:
        dex = tuple(float(v) for v in spec.range)
        rng, unit, source = dex, spec.unit, spec.source
    lo, hi = 10.0 ** min(dex), 10.0 ** max(dex)
    return np.full(len(bands), lo), np.full(len(bands), hi), (rng, unit, source)


def _door(campaign, spec, bands):
    """(dark, bright) factors and (range, unit, source) of the door's reflectance."""
    nominal = float(campaign.instrument_settings.door_geometry.reflectance.value)
    lo, hi = (float(min(spec.range)), float(max(spec.range)))
    if nominal <= 0:
        return np.ones(len(bands)), np.ones(len(bands)), (tuple(spec.range), spec.unit, spec.source)
    return (
        np.full(len(bands), lo / nominal),
        np.full(len(bands), hi / nominal),
        (tuple(spec.range), spec.unit, spec.source),
    )


def _albedo(campaign, spec, bands, context):
    """(dark, bright) factors and (range, unit, source) of the Earth's albedo: the level's range
    over the grey albedo, times per band the published spectra's spread about the configured
    one."""
    from straylight.sources.earthshine.albedo import band_albedo_factors

    es = campaign.settings.models.earthshine
    grey = float(es.albedo)
    if grey <= 0:
        return np.ones(len(bands)), np.ones(len(bands)), (tuple(spec.range), spec.unit, spec.source)
    band_objs = [context.band(b) for b in bands]
    configured = band_albedo_factors(band_objs, es.albedo_spectrum, grey)
    ratios = [np.ones(len(bands))]
    for name in campaign.instrument_settings.envelope.earth_albedo_spectra or ():
        ratios.append(band_albedo_factors(band_objs, name, grey) / configured)
    ratios = np.array(ratios)
    lo, hi = float(min(spec.range)) / grey, float(max(spec.range)) / grey
    return lo * ratios.min(axis=0), hi * ratios.max(axis=0), (tuple(spec.range), spec.unit, spec.source)


_BUILDERS = {
    "pst_tail": "pst_tail_dex",
    "door_reflectance": "door_reflectance",
    "earth_albedo": "earth_albedo",
}


def campaign_envelope(campaign, bands=None, context=None) -> Envelope:
    """The campaign's envelope: the parameters the registry declares with an envelope key and
    the instrument file gives a range (cached on the campaign per set of bands).

    Parameters
    ----------
    campaign : Campaign
        Loaded campaign (instrument, models, avoidance).
    bands : sequence of str, optional
        Bands of the factors; None: the campaign's.
    context : SourceContext, optional
        The sources' context (its loaded bands); None: made here.

    Returns
    -------
    Envelope
        Empty (no parameter) without an ``envelope`` section.

    Raises
    ------
    ConfigError
        When the PST's tail would start beyond an avoidance angle.
    """
    bands = tuple(campaign.bands if bands is None else bands)
    cache = campaign.__dict__.setdefault("_envelope", {})
    if bands in cache:
        return cache[bands]
    env = campaign.instrument_settings.envelope
    params = []
    if env is not None:
        if context is None:
            from straylight.sources.context import SourceContext

            context = SourceContext(campaign)
        # the members move the default PST's tail: with a PST file their tail would not apply
        members = env.members if campaign.instrument_settings.pst.file is None else None
        declared = _declared()
        if members is not None:
            leaves = tuple(
                x for key in ("pst_tail", "door_reflectance") for x in declared.get(key, ("", ()))[1]
            )
            params.append(_members(campaign, members, tuple(dict.fromkeys(leaves)), bands))
        for key, (name, leaves) in declared.items():
            if members is not None and key in ("pst_tail", "door_reflectance"):
                continue  # within the members
            spec = getattr(env, _BUILDERS.get(key, key), None)
            if spec is None:
                continue
            if key == "pst_tail":
                dark, bright, meta = _pst_tail(campaign, spec, bands)
            elif key == "door_reflectance":
                dark, bright, meta = _door(campaign, spec, bands)
            elif key == "earth_albedo":
                dark, bright, meta = _albedo(campaign, spec, bands, context)
            else:
                continue
            params.append(EnvelopeParameter(key, name, leaves, dark, bright, *meta))
    zp = _zero_point(campaign, bands)
    if zp is not None:
        params.append(zp)
    cache[bands] = Envelope(params, bands)
    return cache[bands]


def _zero_point(campaign, bands) -> EnvelopeParameter | None:
    """The bands' zero-point offsets' ranges (instrument ``bands.<band>.zero_point_offset_mag``),
    as offsets from the nominal value at each end; None where no band has a range of some width."""
    inst = campaign.instrument_settings.bands
    dark, bright, sources = np.zeros(len(bands)), np.zeros(len(bands)), []
    for i, b in enumerate(bands):
        z = getattr(inst.get(b), "zero_point_offset_mag", None) if b in inst else None
        if z is None or max(z.range) - min(z.range) <= 0:
            continue
        # the optimistic end: the brighter zero point (more signal per photon); pessimistic: fainter
        dark[i], bright[i] = float(max(z.range)) - z.value, float(min(z.range)) - z.value
        sources.append(f"{b}: {z.source}")
    if not sources:
        return None
    rng = (float(bright.min()), float(dark.max()))
    return EnvelopeParameter(
        "zero_point",
        "instrument bands.<band>.zero_point_offset_mag",
        (),
        dark,
        bright,
        rng,
        "mag",
        "; ".join(sources),
        True,
    )


def _members(campaign, members, leaves, bands) -> EnvelopeParameter:
    """The calibrated members as one re-evaluated parameter."""
    ends = (members.optimistic, members.pessimistic)
    tails = [m.tail_log10_at_90deg for m in ends]
    return EnvelopeParameter(
        "calibrated_members",
        "instrument pst.tail_log10_at_90deg, door_geometry reflectance and body_radius_m, jointly "
        "(envelope.members)",
        leaves,
        np.ones(len(bands)),
        np.ones(len(bands)),
        tuple(tails),
        "dex (the tail at each end; the door and the body with it)",
        f"optimistic {_describe(members.optimistic)}; pessimistic {_describe(members.pessimistic)}; "
        f"median crossing within {members.tolerance_deg.value:g} deg of the paper's: {members.source}",
        reevaluated=True,
    )


def _describe(m) -> str:
    return (
        f"tail {m.tail_log10_at_90deg:.2f} dex, door {m.door_reflectance:g}, body {m.body_radius_m:g} m "
        f"(median crossing {m.median_crossing_deg:.1f} deg)"
    )


def end_campaign(campaign, end: str):
    """``campaign`` with the instrument's tail, door reflectance and body radius at an end's
    member (``envelope.members``): the model evaluated through it is the end's re-evaluation.

    Parameters
    ----------
    campaign : Campaign
        The campaign.
    end : str
        One of :data:`ENDS`.

    Returns
    -------
    Campaign

    Raises
    ------
    ConfigError
        When the instrument has no ``envelope.members``.
    """
    from straylight.config import Campaign
    from straylight.config.loading import deep_merge

    if end not in ENDS:
        raise ValueError(f"envelope end {end!r}: one of {ENDS}")
    env = campaign.instrument_settings.envelope
    if env is None or env.members is None:
        raise ConfigError("instrument envelope.members: needed for the envelope's re-evaluated ends")
    m = getattr(env.members, end)
    inst = campaign.instrument
    src = f"envelope.members.{end}"

    def q(section, key, value):
        d = dict(inst.get(section, {}).get(key) or {})
        d.update(value=float(value), source=src)
        d.setdefault("unit", "1")
        return d

    change = {
        "pst": {"tail_log10_at_90deg": q("pst", "tail_log10_at_90deg", m.tail_log10_at_90deg)},
        "door_geometry": {
            "reflectance": q("door_geometry", "reflectance", m.door_reflectance),
            "body_radius_m": q("door_geometry", "body_radius_m", m.body_radius_m),
        },
    }
    return Campaign(
        config=campaign.config,
        instrument=deep_merge(inst, change),
        path=campaign.path,
        instrument_path=campaign.instrument_path,
    )


def end_parts(end_model, sat_km, bodies_km, los, geometry, bands) -> dict:
    """The parts the members change, evaluated by ``end_model`` (the model of
    :func:`end_campaign`) at some samples.

    Parameters
    ----------
    end_model : BackgroundModel
        The model at the end.
    sat_km, bodies_km, los, geometry
        The samples, as :meth:`BackgroundModel.evaluate` takes them.
    bands : sequence of str
        Bands.

    Returns
    -------
    dict of str to ndarray, shape (n, n_bands)
        :data:`MEMBER_GROUPS` -> the sum of the group's parts, e-/s/pix.
    """
    res = end_model.evaluate(sat_km, bodies_km, los, geometry, list(bands))
    return {
        g: np.stack([sum(np.asarray(res[b][leaf], float) for leaf in leaves) for b in bands], axis=-1)
        for g, leaves in MEMBER_GROUPS.items()
    }
