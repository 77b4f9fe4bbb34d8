"""The background model's two jobs (straylight.model): the per-band sum of the sources, and the
fidelity policy that splits models.tolerance among the fast paths and picks the earthshine path.

Reference numbers: the sum is the seed paper's total background (sect. 2: the sum of the in-field
and off-field contributions), checked against the components the model returns, to float64
rounding; the budget's shares add up to 1 (the tolerance is the error allowed to all the fast
paths together, docs/physics.md); auto takes the earthshine table, direct only on request."""

import numpy as np
import pytest

from straylight.config import campaign_from_dict, deep_merge
from straylight.model import ERROR_BUDGET_SHARES, BackgroundModel, FidelityPolicy
from straylight.model.registry import band_components
from straylight.sky.geometry import observing_geometry
from straylight.sky.observing import scene
from straylight.sky.vectors import radec_to_unit

SUMMED = ("zodiacal", "sun", "moon", "planets", "stars", "earthshine_direct", "earthshine_door")
BAND_COMPONENTS = band_components()


def test_total_is_the_sum_of_the_sources_in_every_band(campaign):
    """total = zodiacal + Sun + Moon + planets + stars + earthshine (direct and door), per band
    and sample, to float64 rounding (1e-12 relative)."""
    assert set(SUMMED) <= set(BAND_COMPONENTS)
    model = BackgroundModel(campaign)
    times = ["2026-01-01T00:50:00", "2026-01-01T03:10:00"]
    sc = scene(campaign.orbit, times)
    rng = np.random.default_rng(3)
    ra, dec = rng.uniform(0, 360, 64), np.degrees(np.arcsin(rng.uniform(-1, 1, 64)))
    los = radec_to_unit(ra, dec)[None, :, :]
    sat = sc.satellite_km[:, None, :]
    bodies = {k: v[:, None, :] for k, v in sc.bodies_km.items()}
    g = observing_geometry(sat, bodies, los, campaign.earth.radius_km, campaign.constraints)
    res = model.evaluate(sat, bodies, los, g, campaign.bands)
    for band in campaign.bands:
        parts = sum(np.asarray(res[band][c], float) for c in SUMMED)
        total = np.asarray(res[band]["total"], float)
        assert total.shape == (2, 64)
        np.testing.assert_allclose(total, parts, rtol=1e-12, atol=0.0)
        assert np.all(total > 0)


def test_error_budget_shares_add_up_to_the_tolerance(campaign):
    """The fast paths' shares add up to exactly the tolerance (models.tolerance, 0.01 by default)."""
    assert sum(ERROR_BUDGET_SHARES.values()) == pytest.approx(1.0, abs=1e-15)
    policy = FidelityPolicy(campaign)
    assert policy.tolerance == pytest.approx(0.01)
    assert sum(policy.budget(s) for s in ERROR_BUDGET_SHARES) == pytest.approx(policy.tolerance, rel=1e-12)
    assert policy.accepts_table("earthshine_lut", 0.5 * policy.tolerance)
    assert not policy.accepts_table("earthshine_lut", 0.5 * policy.tolerance * 1.001)


def test_auto_takes_the_table(campaign):
    """auto: the table whatever the campaign (one sample, as `straylight sky`, or a survey), so
    a sample has the same value everywhere; direct only on request (fidelity.earthshine_method)."""
    policy = FidelityPolicy(campaign)
    assert policy.earthshine_method("auto")[0] == "lut"
    assert policy.earthshine_method("lut")[0] == "lut"
    assert policy.earthshine_method("direct")[0] == "direct"


def test_tolerance_is_read_from_the_campaign(campaign):
    tight = campaign_from_dict(
        deep_merge(campaign.config_mapping(), {"models": {"tolerance": 0.002}}), campaign.path
    )
    assert FidelityPolicy(tight).budget("stars_skip") == pytest.approx(0.125 * 0.002, rel=1e-12)


def test_the_model_has_no_getattr_and_answers_through_its_own_methods(campaign):
    """No ``__getattr__``: a source is reached only by ``model.source(name)``, and what callers
    need of the instrument and the tables comes from the model's own methods, equal to the
    sources' values (the same objects, or the same numbers to the bit)."""
    assert "__getattr__" not in vars(BackgroundModel)
    model = BackgroundModel(campaign)
    with pytest.raises(AttributeError):
        model.stars  # noqa: B018
    engine = model.source("sunlit_earth").engine
    assert model.earth_grid is engine.grid
    assert model.earthshine_choice["method"] == "lut"
    paths = model.table_paths()
    assert paths["sunlit"] == model.source("sunlit_earth").lut_path()
    assert paths["moonlit"] == model.source("moonlit_earth").lut_path()
    assert model.offfield is model.context.offfield
    for b in campaign.bands:
        assert model.darkest_zodiacal_e_per_s(b) == model.context.darkest_zodiacal_e_per_s(b) > 0
        assert model.photometry(b).sun_at_1au_photons_s_m2 > 0
