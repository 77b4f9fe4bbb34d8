"""The source registry (straylight.model.registry): every list of components comes from it,
and a source registered there reaches the model's sum, the pointing tables and the API's
columns with nothing else changed."""

from __future__ import annotations

import numpy as np
import pytest

from straylight.model import registry
from straylight.sources.rates import BandRates

#: the dummy source's e-/s/pix in every band: a round number, so the total moves by exactly it
GLOW_E_PER_S = 0.25


class ConstantGlow:
    """A dummy source: GLOW_E_PER_S e-/s/pix in every band, everywhere."""

    def __init__(self, context):
        self.context = context

    def rates(self, samples, bands) -> BandRates:
        n = int(np.prod(samples.shape))
        return BandRates(per_band={"glow": np.full((len(bands), n), GLOW_E_PER_S)})


@pytest.fixture
def glow(monkeypatch):
    """The registry with the dummy source appended (restored after the test)."""
    monkeypatch.setattr(registry, "COMPONENTS", list(registry.COMPONENTS))
    monkeypatch.setattr(registry, "SOURCES", list(registry.SOURCES))
    registry.register(
        # skippable: evaluated after the floor, so it leaves the other sources' skips (and the
        # totals without it) as they are; a never-skipped one would raise the floor they skip
        # against (docs/architecture.md) and move the totals within their error budgets
        registry.SourceEntry("glow", "glow", lambda model: ConstantGlow(model.context), skippable=True),
        registry.Component("glow", "a constant test glow"),
    )
    yield


def test_components_in_one_place():
    """The six components of the paper's sum (zodiacal light, Sun, Moon, planets, stars,
    earthshine: seed paper sect. 3-4), the earthshine as direct + via the door (EA1, EA2)."""
    assert registry.component_names() == ("zodiacal", "sun", "moon", "planets", "stars", "earthshine")
    assert registry.band_components() == (
        "zodiacal",
        "sun",
        "moon",
        "planets",
        "stars",
        "earthshine_direct",
        "earthshine_door",
        "earthshine",
        "total",
    )
    names = registry.long_names()
    assert set(names) == set(registry.band_components()) and all(names.values())
    # every source adds to a declared component, every component has a source
    assert {s.adds_to for s in registry.SOURCES} == set(registry.component_names())


def test_register_refuses_a_taken_name_or_an_unknown_target():
    entry = registry.SourceEntry("sun", "sun", lambda model: None)
    with pytest.raises(ValueError, match="already registered"):
        registry.register(entry)
    with pytest.raises(ValueError, match="not a component"):
        registry.register(registry.SourceEntry("glow", "nowhere", lambda model: None))
    assert [s.name for s in registry.SOURCES][-1] == "moonlit_earth"  # nothing half-registered


@pytest.mark.parametrize(
    "path, missing",
    [
        ("models.earthshine.albedo_spectra", "no key 'albedo_spectra' in models.earthshine"),
        ("instrument.door_geometry.reflectivity", "no key 'reflectivity' in door_geometry"),
        ("instrument.pupil", "no key 'pupil' in the top level"),
    ],
)
def test_a_wrong_config_path_fails_when_the_model_is_built(monkeypatch, path, missing):
    """Every config path a source's parameters name is checked against the schemas when a
    BackgroundModel is built: a misspelt one is a ConfigError naming the source, the path and
    the key the schema lacks (the registry's own paths all pass)."""
    from straylight.config import load_campaign
    from straylight.errors import ConfigError
    from straylight.model import BackgroundModel

    registry.check_config_paths(registry.SOURCES)
    monkeypatch.setattr(registry, "COMPONENTS", list(registry.COMPONENTS))
    monkeypatch.setattr(registry, "SOURCES", list(registry.SOURCES))
    wrong = registry.Assumption("a misspelt setting", config=(path,))
    registry.register(
        registry.SourceEntry("glow", "glow", lambda model: ConstantGlow(model.context), parameters=(wrong,)),
        registry.Component("glow", "a constant test glow"),
    )
    with pytest.raises(ConfigError, match=f"source 'glow' rests on '{path}'") as err:
        BackgroundModel(load_campaign(), build_workers=1)
    assert missing in str(err.value)
    assert "\n" not in str(err.value)


def test_a_registered_source_reaches_the_sum_the_tables_and_the_api(glow):
    """With the dummy registered: the model returns its component and adds it into the total
    (exactly GLOW_E_PER_S more than without it at the same samples); the API's table (the
    pointing tables' columns) has its columns with units and a description."""
    import astropy.units as u
    from astropy.coordinates import SkyCoord
    from astropy.time import Time

    import straylight
    from straylight.skymodel import SkyModel

    BAND_COMPONENTS = registry.band_components()

    assert "glow" in BAND_COMPONENTS and registry.component_names()[-1] == "glow"
    t = Time(["2026-01-01T03:00:00", "2026-01-01T09:00:00"])
    coord = SkyCoord([10.0, 200.0] * u.deg, [-30.0, 45.0] * u.deg)
    with_glow = SkyModel().background(t, coord, bands=["g", "r"])
    assert with_glow["glow_g"].unit == u.electron / (u.s * u.pix)
    assert "test glow" in with_glow["glow_r"].info.description
    np.testing.assert_array_equal(with_glow["glow_g"].value, GLOW_E_PER_S)
    registry.SOURCES.pop()
    registry.COMPONENTS.pop()
    without = SkyModel().background(t, coord, bands=["g", "r"])
    assert "glow_g" not in without.colnames
    for b in ("g", "r"):
        np.testing.assert_allclose(
            with_glow[f"total_{b}"].value, without[f"total_{b}"].value + GLOW_E_PER_S, rtol=1e-15
        )
    assert straylight.sky_background  # the API's function is the same table (test_api covers it)


def test_a_registered_source_reaches_the_cube_and_the_sky_record(glow):
    """With the dummy registered: a cube region has its variable (GLOW_E_PER_S everywhere, long
    name from the registry) and a total GLOW_E_PER_S above the same region without it; the new
    store's skeleton declares it; ``straylight sky``'s record lists it in every band."""
    from straylight.cli.sky import sky_record
    from straylight.config import load_campaign
    from straylight.cube.footprint import footprint_from_config
    from straylight.cube.region import compute_region
    from straylight.cube.store import empty_cube
    from straylight.model import BackgroundModel

    campaign = load_campaign()
    fp = footprint_from_config(campaign.settings.footprint)
    region = (campaign, fp, slice(0, 2), slice(0, 5))
    model = BackgroundModel(campaign, build_workers=1)
    with_glow = compute_region(*region, model=model)
    assert with_glow["glow"].dims == ("time", "pixel", "band")
    np.testing.assert_array_equal(with_glow["glow"].values, np.float32(GLOW_E_PER_S))
    skeleton = empty_cube(campaign, fp, campaign.times[:2], model)
    assert skeleton["glow"].attrs["long_name"] == "a constant test glow"
    record = sky_record(campaign, campaign.times[0], 150.0, 20.0, bands=["g"])
    assert record["bands"]["g"]["glow"]["e_per_s_per_pix"] == GLOW_E_PER_S
    registry.SOURCES.pop()
    registry.COMPONENTS.pop()
    without = compute_region(*region, model=BackgroundModel(campaign, build_workers=1))
    assert "glow" not in without
    # float32 totals: within one rounding of the float32 sum
    np.testing.assert_allclose(with_glow["total"].values, without["total"].values + GLOW_E_PER_S, rtol=2e-7)
