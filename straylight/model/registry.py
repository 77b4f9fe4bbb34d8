"""The sources of light and the product components they add to, each declared once.

Everything that lists the components reads them from here: the background model's sum and its
compiled kernel, the cube's variables and long names, the pointing tables, ``straylight sky``'s
table, the API's columns and the benchmarks.

- :data:`COMPONENTS`: the product's per-band variables (e-/s/pix), in the order they are added
  into the total; a component may be the sum of named parts (the earthshine: direct + via the
  door).
- :data:`SOURCES`: the sources of light, in the order they are evaluated and their terms added;
  each adds to one component (or to one of its parts).  A source that is ``skippable`` is
  evaluated after the others, against the floor they make (see
  :class:`~straylight.model.background.BackgroundModel`).

Adding a source: a module in ``straylight/sources/`` with a class whose
``rates(samples, bands) -> BandRates`` follows :class:`Source`, and one :class:`SourceEntry`
line below (plus a :class:`Component` line when it adds to a new component).
docs/architecture.md gives the steps."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

from straylight.sources.context import Source

__all__ = [
    "COMPONENTS",
    "SOURCES",
    "Component",
    "Assumption",
    "Source",
    "SourceEntry",
    "TOTAL",
    "band_components",
    "check_config_paths",
    "component_names",
    "leaves",
    "long_names",
    "register",
]

#: the per-band sum of every component
TOTAL = "total"
#: the unit of every per-band component
E_PER_S_PER_PIXEL = "electron / (s pixel)"


@dataclass(frozen=True)
class Component:
    """A per-band product variable, e-/s/pix.

    Attributes
    ----------
    name, long_name : str
        The variable's name and its ``long_name`` attribute.
    parts : tuple of (str, str)
        (name, long_name) of the parts it is the sum of, in order; () for a component the
        sources add to directly.
    units : str
        The variable's ``units`` attribute.
    """

    name: str
    long_name: str
    parts: tuple = ()
    units: str = E_PER_S_PER_PIXEL


@dataclass(frozen=True)
class Assumption:
    """An unmeasured parameter a source's value rests on.

    Attributes
    ----------
    name : str
        What it is and where it is configured, as the products' envelope attributes name it.
    config : tuple of str
        Its settings, each a config path (:func:`check_config_paths`): ``models.earthshine.albedo``
        in the campaign config, ``instrument.door_geometry.reflectance`` in the instrument file.
    envelope : str
        The key of the instrument's ``envelope`` section that gives its range, carried into the
        products' pessimistic and optimistic depths (:mod:`straylight.model.envelope`); "" for a
        parameter declared but not carried.
    scales : tuple of str
        The parts or components (of those the source adds to) the parameter scales linearly;
        () for all of them.
    """

    name: str
    config: tuple = ()
    envelope: str = ""
    scales: tuple = ()


@dataclass(frozen=True)
class SourceEntry:
    """One source of light.

    Attributes
    ----------
    name : str
        The source's name (``BackgroundModel.sources[name]``).
    adds_to : str
        The component its rates go to (for a component with parts: to its parts, named in
        the source's :class:`~straylight.sources.rates.BandRates`), or one part of it.
    factory : callable
        ``factory(model) -> Source``; ``model`` is the :class:`BackgroundModel` being built
        (its ``context``, ``policy``, ``build_workers``, and ``shared(name, make)`` for a part
        several sources share, built once; a source never reaches another).
    skippable : bool
        Whether it may be skipped where its bound is below its share of the sample's floor
        (then evaluated after the sources that are never skipped, which make the floor).
    error_budget : tuple of str
        The keys of :data:`~straylight.model.fidelity.ERROR_BUDGET_SHARES` its fast paths spend
        (declared here for the products' uncertainty; the policy holds the shares).
    parameters : tuple of (Assumption or str)
        The unmeasured model and instrument parameters its value rests on; an
        :class:`Assumption` with an ``envelope`` key is carried into the products' assumption
        envelope (the components it scales, from ``adds_to`` and its ``scales``), a plain str
        (a config path) is declared only.  Every config path is checked when a
        :class:`~straylight.model.BackgroundModel` is built (:func:`check_config_paths`).
    """

    name: str
    adds_to: str
    factory: Callable
    skippable: bool = False
    error_budget: tuple = ()
    parameters: tuple = ()


def _zodiacal(model):
    from straylight.sources.zodiacal import ZodiacalLight

    return ZodiacalLight(model.context)


def _sun(model):
    from straylight.sources.bodies import Sun

    return Sun(model.context)


def _moon(model):
    from straylight.sources.bodies import Moon

    return Moon(model.context, model.body_skip)


def _planets(model):
    from straylight.sources.planets import Planets

    return Planets(model.context, model.body_skip)


def _stars(model):
    from straylight.sources.stars import OffFieldStars

    return OffFieldStars(model.context, model.policy)


def _earthshine(model):
    """The earthshine engine the sunlit and the moonlit Earth share, built once per model."""
    from straylight.sources.earthshine.engine import Earthshine

    return model.shared("earthshine", lambda: Earthshine(model.context, model.policy, model.build_workers))


def _sunlit_earth(model):
    from straylight.sources.earthshine.sunlit import SunlitEarth

    return SunlitEarth(_earthshine(model))


def _moonlit_earth(model):
    from straylight.sources.earthshine.moonlit import MoonlitEarth

    return MoonlitEarth(_earthshine(model))


#: the per-band components, in the order they are added into the total
COMPONENTS = [
    Component("zodiacal", "in-field zodiacal light (Leinert 1998)"),
    Component("sun", "sunlight through the PST (door-shaded)"),
    Component("moon", "moonlight through the PST"),
    Component("planets", "planets (Mercury-Pluto) through the PST"),
    Component("stars", "off-field bright stars through the PST"),
    Component(
        "earthshine",
        "earthshine through the PST, direct + via the aperture door",
        parts=(
            ("earthshine_direct", "earthshine reaching the aperture directly (EA1)"),
            ("earthshine_door", "earthshine reflected by the aperture door (EA2)"),
        ),
    ),
]

_PST = "instrument pst (measured to 30 deg; the tail beyond is a model)"
#: the PST's tail: scales every term whose light reaches the aperture beyond the tail's start
#: only (where observable: the Sun, the Moon, the Earth); the planets and stars also shine
#: through the measured part, so their dependence is declared, not carried
_TAIL = Assumption(_PST, config=("instrument.pst.tail_log10_at_90deg",), envelope="pst_tail")
#: the PST's curve, declared: the planets and stars shine through its measured part too
_PST_CURVE = Assumption(_PST, config=("instrument.pst",))
_ALBEDO = Assumption(
    "models.earthshine.albedo, albedo_spectrum",
    config=("models.earthshine.albedo", "models.earthshine.albedo_spectrum"),
    envelope="earth_albedo",
)
_DOOR_REFLECTANCE = Assumption(
    "instrument door_geometry reflectance",
    config=("instrument.door_geometry.reflectance",),
    envelope="door_reflectance",
    scales=("earthshine_door",),
)
#: the sources of light, in the order they are evaluated and their terms added
SOURCES = [
    SourceEntry(
        "zodiacal",
        "zodiacal",
        _zodiacal,
        parameters=("models.zodiacal_spectrum", "models.zodiacal_reddening"),
    ),
    SourceEntry("sun", "sun", _sun, parameters=(_TAIL, "instrument.door_geometry")),
    SourceEntry(
        "moon",
        "moon",
        _moon,
        skippable=True,
        error_budget=("moon_and_planets_skip",),
        parameters=(_TAIL, "models.moon_phase_law", "models.moon_eclipse_factor"),
    ),
    SourceEntry(
        "planets",
        "planets",
        _planets,
        skippable=True,
        error_budget=("moon_and_planets_skip",),
        parameters=(_PST_CURVE,),
    ),
    SourceEntry(
        "stars",
        "stars",
        _stars,
        skippable=True,
        error_budget=("stars_skip",),
        parameters=(_PST_CURVE, "stars.template_classes"),
    ),
    SourceEntry(
        "sunlit_earth",
        "earthshine",
        _sunlit_earth,
        error_budget=("earthshine_lut",),
        parameters=(_TAIL, _ALBEDO, _DOOR_REFLECTANCE),
    ),
    SourceEntry(
        "moonlit_earth",
        "earthshine",
        _moonlit_earth,
        skippable=True,
        error_budget=("moonlit_earthshine_skip", "moonlit_earthshine_grid"),
        parameters=(_TAIL, _ALBEDO, _DOOR_REFLECTANCE, "models.moon_phase_law"),
    ),
]


def _config_paths(entry: SourceEntry) -> tuple:
    """The config paths a source's parameters name."""
    paths = ()
    for p in entry.parameters:
        paths += (p,) if isinstance(p, str) else tuple(p.config)
    return paths


def check_config_paths(entries: Sequence[SourceEntry]) -> None:
    """Every config path the sources' parameters name is a setting the schemas declare.

    A path is dotted: ``models.earthshine.albedo`` is a key of the campaign config
    (``config/schema/config.schema.yaml``), ``instrument.door_geometry.reflectance`` one of the
    instrument file (``config/schema/instrument.schema.yaml``).

    Parameters
    ----------
    entries : sequence of SourceEntry
        The sources (:data:`SOURCES`, as a model takes them).

    Raises
    ------
    straylight.errors.ConfigError
        Naming the source, the path and the first key the schema does not declare.
    """
    from straylight.config.loading import CAMPAIGN_SCHEMA, INSTRUMENT_SCHEMA, load_schema
    from straylight.errors import ConfigError

    schemas = {}
    for entry in entries:
        for path in _config_paths(entry):
            keys = path.split(".")
            which = INSTRUMENT_SCHEMA if keys[0] == "instrument" else CAMPAIGN_SCHEMA
            keys = keys[1:] if which is INSTRUMENT_SCHEMA else keys
            if which not in schemas:
                schemas[which] = load_schema(which)
            node, done = schemas[which], []
            for key in keys:
                props = node.get("properties", {}) if isinstance(node, dict) else {}
                if key not in props:
                    where = ".".join(done) or "the top level"
                    raise ConfigError(
                        f"straylight/model/registry.py: source {entry.name!r} rests on {path!r}, "
                        f"but {which.name} declares no key {key!r} in {where}"
                    )
                node, done = props[key], done + [key]


def component_names(total: bool = False) -> tuple:
    """The components' names, in the order they are added into the total (no parts): the
    cube's (time, pixel, band) variables, the pointing tables' and ``straylight sky``'s
    columns, the API's, with ``total=True``.

    Parameters
    ----------
    total : bool
        Whether :data:`TOTAL` follows them.

    Returns
    -------
    tuple of str
        The names of :data:`COMPONENTS` (then :data:`TOTAL`).
    """
    return tuple(c.name for c in COMPONENTS) + ((TOTAL,) if total else ())


def band_components() -> tuple:
    """Every per-band output of the model: each component's parts before it, then the total.

    Returns
    -------
    tuple of str
        The outputs' names (each e-/s/pix per band), ending with :data:`TOTAL`.
    """
    names = []
    for c in COMPONENTS:
        names += [p for p, _ in c.parts] + [c.name]
    return tuple(names) + (TOTAL,)


def long_names() -> dict:
    """Name -> long_name of every per-band output (components, parts and the total).

    Returns
    -------
    dict of str to str
        The outputs' ``long_name`` attributes.
    """
    out = {}
    for c in COMPONENTS:
        out.update(dict(c.parts))
        out[c.name] = c.long_name
    out[TOTAL] = "total stray light and sky background"
    return out


def leaves() -> tuple:
    """The names sources add to: each component's parts, or the component itself.

    Returns
    -------
    tuple of str
        The leaves, in the order of :data:`COMPONENTS`.
    """
    return tuple(n for c in COMPONENTS for n in ([p for p, _ in c.parts] or [c.name]))


def register(source: SourceEntry, component: Component | None = None) -> None:
    """Add a source (and, for a new component, the component) at the end of the registry.

    Parameters
    ----------
    source : SourceEntry
        The source; its ``adds_to`` names a declared component or part, or ``component`` or
        one of its parts.
    component : Component or None
        A new component the source adds to (None: it adds to one already declared).

    Raises
    ------
    ValueError
        For a name already taken, or a source that adds to no declared component nor part.
    """
    if any(s.name == source.name for s in SOURCES):
        raise ValueError(f"a source named {source.name!r} is already registered")
    if component is not None and {component.name, *dict(component.parts)} & set(band_components()):
        raise ValueError(
            f"a component or part named like {component.name!r} or its parts is already registered"
        )
    targets = band_components()[:-1] + ((component.name, *dict(component.parts)) if component else ())
    if source.adds_to not in targets:
        raise ValueError(
            f"source {source.name!r} adds to {source.adds_to!r}, which is not a component "
            f"nor a part: {targets}"
        )
    if component is not None:
        COMPONENTS.append(component)
    SOURCES.append(source)
