"""The Earth grid where the aperture plane cuts the cap: the default grid, its cut blocks summed
over their children (models.earthshine.cut_block_split), against the converged 96 x 192 grid.

Reference values: the tolerance (config/config.yaml models.tolerance, 1 % of the total) and the
converged grid's sum (the 96 x 192 reference of bench/run.py and bench/earth_grid.py).  The
geometries are the eight of 520 observable samples spread over 2026 (bench/earth_grid.py, seed
20261127) where the 24 x 48 grid without the split was furthest from the reference (up to
2.4 % of the total with the PST's tail at 10^-8.6 at 90 deg), all with the line of sight
84-89 deg above the limb and the door at 135 deg."""

from dataclasses import replace

import numpy as np
import pytest

from straylight.config import load_campaign
from straylight.model import BackgroundModel
from straylight.optics.pst import load_pst
from straylight.sky.geometry import observing_geometry
from straylight.sky.observing import scene
from straylight.sky.vectors import radec_to_unit

#: (UTC, RA deg, Dec deg) of the eight samples
GEOMETRIES = [
    ("2026-01-17T16:38:56.587", 342.428319, 42.027352),
    ("2026-02-09T16:19:21.843", 256.424215, 23.339510),
    ("2026-04-04T01:29:29.240", 307.081447, 2.937613),
    ("2026-05-04T10:49:01.946", 313.794795, -1.613016),
    ("2026-06-19T01:36:22.511", 31.195827, -32.848706),
    ("2026-05-03T02:54:34.009", 120.451326, 41.156415),
    ("2026-07-11T11:35:20.130", 8.767706, 51.107581),
    ("2026-06-14T03:25:58.119", 157.419823, 17.668278),
]
TOLERANCE = 0.01  # config/config.yaml models.tolerance


def _totals(campaign, samples, grid=None, split=None, tail=None):
    """Each band's total (e-/s/pix) at the samples, the earthshine summed directly on the
    default grid or ``grid`` (n_gamma, n_psi), with ``split`` and the PST's ``tail``."""
    cm = BackgroundModel(campaign)
    off = cm.earth_grid
    es = off.earthshine
    if grid is not None:
        es = replace(es, n_gamma=grid[0], n_psi=grid[1])
    if split is not None:
        es = replace(es, cut_block_split=split)
    pst = off.pst if tail is None else load_pst(None, off.field_radius_deg, tail)
    transfer = replace(off.transfer, pst=pst)
    cm.context.__dict__["offfield"] = transfer  # before any source reads them
    cm.source("sunlit_earth").engine.__dict__["grid"] = replace(off, transfer=transfer, earthshine=es)
    sat, bodies, los, g = samples
    r = cm.evaluate(sat, bodies, los, g, list(campaign.bands))
    return np.array([r[b]["total"] for b in campaign.bands])


@pytest.fixture(scope="module")
def setup():
    campaign = load_campaign(overrides={"models": {"earthshine": {"method": "direct"}}})
    times, ra, dec = zip(*GEOMETRIES)
    sc = scene(campaign.orbit, list(times))
    los = radec_to_unit(np.array(ra), np.array(dec))
    g = observing_geometry(sc.satellite_km, sc.bodies_km, los, campaign.earth.radius_km, campaign.constraints)
    assert np.all(g["door_opening_deg"] == 135.0)
    assert np.all((g["earth_limb_angle_deg"] > 84.0) & (g["earth_limb_angle_deg"] < 89.0))
    return campaign, (sc.satellite_km, sc.bodies_km, los, g)


@pytest.mark.slow  # ~30 s a case on the shared 2-core machine: three models over 7 bands
@pytest.mark.parametrize("tail", [None, -8.6])
def test_the_default_grid_is_within_the_tolerance_where_the_aperture_plane_cuts_the_cap(setup, tail):
    """The default grid (its cut blocks split) within 1 % of the total of the 96 x 192 grid in
    every band, with the instrument's PST and with the tail at 10^-8.6 (brighter than the
    calibrated range's bright end); without the split it was 2.4 % off at the first sample
    with that tail."""
    campaign, samples = setup
    assert campaign.settings.models.earthshine.cut_block_split > 1
    ref = _totals(campaign, samples, grid=(96, 192), split=1, tail=tail)
    got = _totals(campaign, samples, tail=tail)
    err = np.abs(got - ref) / ref
    assert err.max() <= TOLERANCE
    if tail == -8.6:
        whole = _totals(campaign, samples, split=1, tail=tail)
        assert (np.abs(whole - ref) / ref).max() > 2 * TOLERANCE  # the blocks counted whole: 2.4 %
