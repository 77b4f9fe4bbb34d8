"""The earthshine look-up table (the fast path) against the direct Earth-cap sum it
tabulates, its moonlit-Earth bound, its cache, and the automatic choice from the tolerance.
A coarse table (5 x 5 x 20 deg nodes, ~10 s to build) keeps the tests fast; the default table's
error and cost are measured by bench/run.py."""

import copy
import sys
from pathlib import Path

import numpy as np
import pytest

from straylight.config import campaign_from_dict
from straylight.model import BackgroundModel
from straylight.sky.frames import telescope_frame
from straylight.sources.earthshine.nodes import LUTSettings, lut_key
from straylight.sources.earthshine.sums import Bodies
from straylight.sources.earthshine.sunlit_build import build_earthshine_lut
from straylight.sources.earthshine.sunlit_table import EarthshineLUT

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
from _samples import random_samples  # noqa: E402

COARSE = {"sun_zenith_step_deg": 5.0, "los_zenith_step_deg": 5.0, "azimuth_step_deg": 20.0}


def _campaign(campaign, **earthshine):
    raw = campaign.config_mapping()
    raw["models"]["earthshine"].update(earthshine)
    return campaign_from_dict(raw, campaign.path)


@pytest.fixture(scope="module")
def coarse(campaign):
    c = _campaign(campaign, method="lut", lut=COARSE)
    cm = BackgroundModel(c)
    return c, cm, cm.source("sunlit_earth").model


def test_table_reproduces_the_direct_sum_at_its_nodes(coarse):
    """At a node the table returns the direct sum it stored (to the asinh round trip)."""
    c, cm, info = coarse
    lut = info["lut"]
    off = cm.earth_grid
    r = lut.radius_km[0]
    iz, il, ia = 7, 10, 4
    z, l_, a = np.radians([lut.sun_zenith_deg[iz], lut.los_zenith_deg[il], lut.azimuth_deg[ia]])
    sat = np.array([[r, 0.0, 0.0]])
    sun = 1.495978707e8 * np.array([[np.cos(z), np.sin(z), 0.0]])
    los = np.array([[np.cos(l_), np.sin(l_) * np.cos(a), np.sin(l_) * np.sin(a)]])
    for state in off.door_states_deg:
        d, g = lut.sun_coefficients(sat, sun, los, np.array([state]))
        ref = off.earthshine_coefficients(
            Bodies(sat, sun, np.array([[0, 0, -1e9]])),
            telescope_frame(los, sun - sat),
            np.array([state]),
            c.earth.radius_km,
            in_field=False,
            moon=False,
        )
        assert d[0] == pytest.approx(ref["direct_sun"][0], rel=1e-9, abs=1e-40)
        assert g[0] == pytest.approx(ref["door_sun"][0], rel=1e-9, abs=1e-40)


def test_rotation_about_the_vertical_changes_nothing(coarse):
    """The table's premise: the same (z_sun, zeta, A) anywhere on the orbit gives the same
    coefficients (direct sums agree to the cap grid's orientation, < 1e-3 of the total)."""
    c, cm, info = coarse
    sc, los, g = random_samples(c, 400, seed=1)
    obs = np.flatnonzero(g["observable"])[:40]
    sat, sun, los = sc.satellite_km[obs], sc.bodies_km["sun"][obs], los[obs]
    lut = info["lut"]
    r, zs, zl, a = lut.coordinates(sat, sun, los)
    from straylight.sources.earthshine.sunlit_build import sun_coefficients_direct

    off = cm.earth_grid
    door = g["door_opening_deg"][obs]
    frame = telescope_frame(los, sun - sat)
    real = off.earthshine_coefficients(
        Bodies(sat, sun, sc.bodies_km["moon"][obs]),
        frame,
        door,
        c.earth.radius_km,
        in_field=False,
        moon=False,
    )
    res = cm.evaluate(
        sat, {k: v[obs] for k, v in sc.bodies_km.items()}, los, {k: v[obs] for k, v in g.items()}, ["g"]
    )
    sun_irr = (
        cm.context.photometry("g").sun_at_1au_photons_s_m2
        * (1.495978707e8 / np.linalg.norm(sun - sat, axis=-1)) ** 2
    )
    for state in off.door_states_deg:
        sel = door == state
        if not sel.any():
            continue
        d, gd = sun_coefficients_direct(
            off, r[sel], *np.radians([zs[sel], zl[sel], a[sel]]), state, c.earth.radius_km
        )
        err = (
            np.abs(d + gd - real["direct_sun"][sel] - real["door_sun"][sel])
            * sun_irr[sel]
            / res["g"]["total"][sel]
        )
        assert err.max() < 1e-2


def test_night_side_samples_skip_the_look_up_and_get_exactly_what_it_gives(coarse):
    """sun_coefficients gives 0 without a look-up where the Sun's zenith angle lies beyond
    dark_sun_zenith_deg (every table node from there on is 0).  On a cube-like batch of time
    steps over a whole orbit (day, twilight and night steps), with and without known runs, it
    equals the look-up at every sample bit for bit; the skipped samples are there, and the
    table really is 0 at every node beyond the angle."""
    from straylight.sky.observing import scene
    from straylight.sky.runs import SceneRuns
    from straylight.sky.vectors import radec_to_unit

    c, _, info = coarse
    lut = info["lut"]
    dark = lut.dark_sun_zenith_deg
    assert 90.0 < dark < 180.0
    beyond = lut.sun_zenith_deg > dark
    for table in (*lut.direct.values(), *lut.door.values()):
        assert beyond.any() and np.all(table[:, beyond] == 0) and np.any(table[:, ~beyond] != 0)
    rng = np.random.default_rng(3)
    n_los = 200
    los = radec_to_unit(rng.uniform(0, 360, n_los), np.degrees(np.arcsin(rng.uniform(-1, 1, n_los))))
    times = [f"2026-01-01T{m // 60:02d}:{m % 60:02d}:00" for m in range(0, 95, 5)]  # one orbit, 19 steps
    sc = scene(c.orbit, times)
    k = len(times)
    sat, sun = np.repeat(sc.satellite_km, n_los, axis=0), np.repeat(sc.bodies_km["sun"], n_los, axis=0)
    lines = np.tile(los, (k, 1))
    door = np.where(rng.uniform(size=k * n_los) < 0.5, 105.0, 135.0)
    full = lut._sun_lookup(sat, sun, lines, door, SceneRuns.steps(k, n_los).of(sat, sun))
    z_sun = lut.coordinates(sat, sun, lines)[1]
    assert np.any(z_sun > dark) and np.any(z_sun < 90.0)  # night and day steps both there
    for runs in (None, SceneRuns.steps(k, n_los)):
        got = lut.sun_coefficients(sat, sun, lines, door, runs)
        for g, f in zip(got, full):
            np.testing.assert_array_equal(g, f)
            assert np.all(g[z_sun > dark] == 0) and np.count_nonzero(g) > 100


def test_moonlit_earth_is_left_out_where_the_moon_is_down_and_changes_nothing(moonlit):
    """With the moonlit table, samples whose Moon zenith angle lies beyond its
    dark_moon_zenith_deg (the table is 0 at every node from there on) skip the moonlit Earth,
    bound and all.  Over one orbit with the Moon up and down the components equal, bit for bit,
    those computed with nothing left out (the angle set to inf)."""
    from straylight.sky.geometry import observing_geometry
    from straylight.sky.observing import scene
    from straylight.sky.runs import SceneRuns
    from straylight.sky.vectors import radec_to_unit

    c, cm, mlut = moonlit
    dark = mlut.dark_moon_zenith_deg
    assert 90.0 < dark < 180.0
    beyond = mlut.moon_zenith_deg > dark
    for table in (*mlut.direct.values(), *mlut.door.values()):
        assert beyond.any() and np.all(table[beyond] == 0) and np.any(table[~beyond] != 0)
    rng = np.random.default_rng(8)
    n_los = 150
    los = radec_to_unit(rng.uniform(0, 360, n_los), np.degrees(np.arcsin(rng.uniform(-1, 1, n_los))))
    sc = scene(c.orbit, [f"2026-01-01T{m // 60:02d}:{m % 60:02d}:00" for m in range(0, 95, 5)])
    k = len(sc.satellite_km)
    sat = np.repeat(sc.satellite_km, n_los, axis=0)
    bodies = {b: np.repeat(v, n_los, axis=0) for b, v in sc.bodies_km.items()}
    lines = np.tile(los, (k, 1))
    g = observing_geometry(sat, bodies, lines, c.earth.radius_km, c.constraints)
    z_moon = mlut.coordinates(sat, bodies["moon"], telescope_frame(lines, bodies["sun"] - sat))[0]
    assert np.any(z_moon > dark) and np.any(z_moon < 90.0)  # the Moon down and up
    out = {}
    for key, angle in (("skipping", dark), ("all", np.inf)):
        mlut.__dict__["dark_moon_zenith_deg"] = angle  # the cached property's value
        for runs in (None, SceneRuns.steps(k, n_los)):
            out[key, runs is None] = cm.evaluate(sat, bodies, lines, g, c.bands, runs=runs)
    mlut.__dict__["dark_moon_zenith_deg"] = dark
    for known in (False, True):
        for b in c.bands:
            for comp in ("earthshine", "earthshine_direct", "earthshine_door", "moon", "total"):
                np.testing.assert_array_equal(out["skipping", known][b][comp], out["all", known][b][comp])
    assert np.count_nonzero(out["all", True]["g"]["earthshine_door"]) > 0


def test_validation_error_is_recorded_and_measured_off_the_nodes(coarse):
    _, _, info = coarse
    assert info["method"] == "lut"
    assert 0.0 < info["lut_validation_max_rel_error"] < 1.0  # the coarse table is far from 1 %


def test_moonlit_bound_holds(coarse):
    c, cm, info = coarse
    sc, los, g = random_samples(c, 1500, seed=4)
    sat, sun, moon = sc.satellite_km, sc.bodies_km["sun"], sc.bodies_km["moon"]
    frame = telescope_frame(los, sun - sat)
    co = cm.earth_grid.earthshine_coefficients(
        Bodies(sat, sun, moon), frame, g["door_opening_deg"], c.earth.radius_km, in_field=False
    )
    bound = info["lut"].moon_bound(sat, moon, los, c.earth.radius_km)
    fin = np.isfinite(bound)
    assert fin.mean() > 0.5
    assert np.all(co["direct_moon"][fin] + co["door_moon"][fin] <= bound[fin])


def test_cap_bound_holds_for_any_line_of_sight(coarse):
    """Within 1 deg of the limb and below it the table gives no moonlit bound; there the whole
    cap fully lit at the PST's largest value outside the field (OffFieldModel.earthshine_cap_bound)
    must bound the coarse grid's sum: 1500 random samples, a third of them aimed into the Earth."""
    c, cm, info = coarse
    sc, los, g = random_samples(c, 1500, seed=8)
    sat, sun, moon = sc.satellite_km, sc.bodies_km["sun"], sc.bodies_km["moon"]
    rng = np.random.default_rng(3)
    into = rng.random(len(los)) < 1 / 3  # towards a random point of the visible cap
    nadir = -sat / np.linalg.norm(sat, axis=1, keepdims=True)
    tilt = np.cross(nadir, rng.normal(size=sat.shape))
    tilt /= np.linalg.norm(tilt, axis=1, keepdims=True)
    a = np.radians(rng.uniform(0.0, 69.0, len(los)))[:, None]
    los = np.where(into[:, None], np.cos(a) * nadir + np.sin(a) * tilt, los)
    frame = telescope_frame(los, sun - sat)
    door = c.constraints.door_opening_deg(
        np.degrees(
            np.arccos(np.clip(np.sum(los * (sun - sat), axis=1) / np.linalg.norm(sun - sat, axis=1), -1, 1))
        )
    )
    co = cm.earth_grid.earthshine_coefficients(
        Bodies(sat, sun, moon),
        frame,
        door,
        c.earth.radius_km,
        in_field=False,
        sun=False,
        grid=cm.source("moonlit_earth").grid,
    )
    bound = (
        cm.earth_grid.earthshine_cap_bound(sat, c.earth.radius_km, cm.source("moonlit_earth").grid)
        + info["lut"].moon_door_bound
    )
    assert np.all(np.isfinite(bound)) and into.sum() > 400
    assert np.all(co["direct_moon"] + co["door_moon"] <= bound)
    assert np.max((co["direct_moon"] + co["door_moon"]) / bound) > 1e-3  # a bound, not a wild one


def test_moonlit_earth_stays_within_its_share_of_the_tolerance(campaign, tmp_path):
    """On the table path the moonlit Earth is skipped on its bound or taken from its table of the
    coarse default grid's sum; together they must stay within their two shares of the tolerance
    (1/8 + 1/8) at observable samples.  Cube access on a full-Moon day (2026-01-03: the moonlit Earth at
    its brightest), against a 48 x 96 grid with nothing skipped; both runs share the same table,
    so the difference is the moonlit treatment alone.  Measured 3.9e-4 of the total (bench
    moonlit_grid row 6 x 12).  The instrument without the envelope's members: the total is the
    nominal model's, and the cube would re-evaluate each member's moonlit Earth too (on the
    48 x 96 grid, or from the members' own tables)."""
    import yaml

    from straylight.cube.footprint import footprint_from_config
    from straylight.cube.region import compute_region
    from straylight.model import ERROR_BUDGET_SHARES

    instrument = campaign.instrument_mapping()
    instrument["envelope"].pop("members")
    (tmp_path / "instrument.yaml").write_text(yaml.safe_dump(instrument))
    raw = campaign.config_mapping()
    raw["instrument"] = str(tmp_path / "instrument.yaml")
    raw["campaign"].update(start="2026-01-03T00:00:00", end="2026-01-03T23:59:59")
    raw["models"]["earthshine"].update(method="lut", lut=COARSE)
    # observable samples only (the error is taken there): each comes out bit-identical to
    # evaluating every sample (test_cube_region_skipping_unobservable_samples_changes_no_observable_value)
    raw["models"]["unobservable_samples"] = "skip"
    fp = footprint_from_config(raw["footprint"])
    t_slice = slice(0, 288, 48)

    def total(**kw):
        raw2 = copy.deepcopy(raw)
        if "grid" in kw:
            raw2["models"]["earthshine"]["moonlit_grid"] = list(kw.pop("grid"))
        if "moonlit_method" in kw:
            raw2["models"]["earthshine"]["moonlit_method"] = kw.pop("moonlit_method")
        c = campaign_from_dict(raw2, campaign.path)
        ds = compute_region(c, fp, t_slice, slice(None), model=BackgroundModel(c, **kw))
        return ds["total"].values.astype(float), ds["observable"].values

    ref, obs = total(grid=(48, 96), moonlit_method="direct", moonlit_skip_share=0.0)
    default, _ = total()
    err = float(np.max(np.abs(default - ref)[obs] / ref[obs]))
    share = ERROR_BUDGET_SHARES["moonlit_earthshine_skip"] + ERROR_BUDGET_SHARES["moonlit_earthshine_grid"]
    print(
        f"moonlit Earth, default treatment: {err:.2e} of the total at {obs.sum()} observable samples "
        f"(share {share * campaign.settings.models.tolerance:.1e})"
    )
    assert obs.sum() > 500
    assert 0.0 < err <= share * float(campaign.settings.models.tolerance)


def test_save_load_round_trip_and_cache_key(coarse, tmp_path, campaign):
    c, cm, info = coarse
    lut = info["lut"]
    p = tmp_path / "t.npz"
    lut.save(p)
    back = EarthshineLUT.load(p)
    for s in lut.direct:
        assert np.array_equal(back.direct[s], lut.direct[s]) and np.array_equal(back.door[s], lut.door[s])
    assert back.validation_max_rel_error == lut.validation_max_rel_error
    off = cm.earth_grid
    k = lut_key(off, 6378.137, (6778.137, 6778.137), LUTSettings(5, 5, 20), 1e-20)
    assert k != lut_key(off, 6378.137, (6778.137, 6778.137), LUTSettings(5, 5, 10), 1e-20)
    from dataclasses import replace

    assert k != lut_key(
        replace(off, earthshine=replace(off.earthshine, albedo=0.31)),
        6378.137,
        (6778.137, 6778.137),
        LUTSettings(5, 5, 20),
        1e-20,
    )
    # the tables are built from the PST and the door (with the body that shades it): another PST
    # or body is another table
    from straylight.optics.pst import PST

    darker = PST(
        off.pst.theta_deg,
        off.pst.phi_deg,
        off.pst.values * np.where(off.pst.theta_deg > 60.0, 0.5, 1.0)[:, None],
    )
    assert k != lut_key(
        replace(off, transfer=replace(off.transfer, pst=darker)),
        6378.137,
        (6778.137, 6778.137),
        LUTSettings(5, 5, 20),
        1e-20,
    )
    assert k != lut_key(
        replace(
            off,
            transfer=replace(
                off.transfer, door=replace(off.door, body_radius_m=off.door.body_radius_m + 0.5)
            ),
        ),
        6378.137,
        (6778.137, 6778.137),
        LUTSettings(5, 5, 20),
        1e-20,
    )
    assert k == lut_key(replace(off), 6378.137, (6778.137, 6778.137), LUTSettings(5, 5, 20), 1e-20)
    (tmp_path / "bad.npz").write_bytes(b"not a table")
    from straylight.errors import InputError

    with pytest.raises(InputError, match="bad.npz: not a valid earthshine look-up table"):
        EarthshineLUT.load(tmp_path / "bad.npz")


def test_parallel_build_gives_the_same_table(coarse):
    """Two worker processes build the same table, byte for byte, as one (the coarse steps)."""
    c, cm, info = coarse
    k = c.constraints
    args = (
        cm.earth_grid,
        c.earth.radius_km,
        c.orbit_radius_range_km,
        LUTSettings(**COARSE),
        cm.source("sunlit_earth").engine.floor,
    )
    kw = {"avoidance_deg": (k.dark_limb_min_deg, k.bright_limb_min_deg, k.sun_min_deg)}
    two = build_earthshine_lut(*args, **kw, workers=2)
    one = info["lut"]
    for s in one.direct:
        assert np.array_equal(two.direct[s], one.direct[s]) and np.array_equal(two.door[s], one.door[s])
    assert np.array_equal(two.moon_direct_bound, one.moon_direct_bound)
    assert two.validation_max_rel_error == one.validation_max_rel_error


def test_automatic_choice(coarse, campaign):
    """auto takes the table for one pointing as for a survey, unless the table's validated error
    exceeds its share of the tolerance (then the direct sum, with the reason)."""
    c, _, _ = coarse
    coarse_auto = BackgroundModel(_campaign(campaign, method="auto", lut=COARSE)).source("sunlit_earth").model
    assert (
        coarse_auto["method"] == "direct" and "> 0.5 x the tolerance" in coarse_auto["reason"]
    )  # too coarse for 1 %
    raw = c.config_mapping()
    raw["models"]["tolerance"] = 1.0
    raw["models"]["earthshine"]["method"] = "auto"
    loose = BackgroundModel(campaign_from_dict(raw, c.path)).source("sunlit_earth").model
    assert loose["method"] == "lut"


def test_build_estimate_counts_both_tables(coarse):
    """The build's estimate (plan, the build's announcement): the sunlit table's (node, door
    state) pairs and the moonlit table's, each at its per-node figure (earthshine_lut.*_PER_NODE)."""
    from straylight.sources.earthshine import nodes as lut_mod

    c, _, _ = coarse
    raw = c.config_mapping()
    raw["models"]["earthshine"]["method"] = "auto"
    model = BackgroundModel(campaign_from_dict(raw, c.path))
    settings = LUTSettings(**COARSE)
    n_nodes = model.source("sunlit_earth").node_states(settings)
    # the coarse table's nodes (LUTSettings.nodes: 18 Sun zenith x 36 line-of-sight zenith, 29 at
    # the coarse step and 7 over the rise above the aperture plane, x 10 azimuth) x 2 door states
    assert n_nodes == 18 * 36 * 10 * 2
    moonlit_nodes = model.source("moonlit_earth").node_states()
    assert moonlit_nodes > 0
    both, moonlit = model.policy.tables_build_seconds(n_nodes, moonlit_nodes)
    assert moonlit == pytest.approx(lut_mod.MOONLIT_LUT_BUILD_SECONDS_PER_NODE * moonlit_nodes, rel=1e-12)
    assert both == pytest.approx(lut_mod.LUT_BUILD_SECONDS_PER_NODE * n_nodes + moonlit, rel=1e-12)


def test_lut_path_agrees_with_direct_within_its_validated_error(coarse, campaign):
    """The whole model with the table against the direct sum, at random observable samples:
    the difference stays within the table's validated error (fraction of the total)."""
    c, cm, info = coarse
    direct = BackgroundModel(_campaign(campaign, method="direct"))
    sc, los, g = random_samples(c, 1500, seed=8)
    obs = g["observable"]
    a = cm.evaluate(sc.satellite_km, sc.bodies_km, los, g, ["g", "z"])
    b = direct.evaluate(sc.satellite_km, sc.bodies_km, los, g, ["g", "z"])
    for band in ("g", "z"):
        err = np.abs(a[band]["total"] - b[band]["total"]) / b[band]["total"]
        assert err[obs].max() <= info["lut_validation_max_rel_error"] + 0.25 * cm.policy.tolerance
        assert np.all(np.isfinite(a[band]["total"]))
    rec = cm.models_record()
    assert rec["earthshine"]["method"] == "lut" and "lut_build_seconds" not in rec["earthshine"]


# -- the moonlit Earth's table ------------------------------------------------------------------
@pytest.fixture(scope="module")
def moonlit(coarse):
    c, cm, _ = coarse
    info = cm.source("moonlit_earth").model
    assert info["method"] == "lut", info.get("reason")
    return c, cm, info["lut"]


def test_moonlit_table_reproduces_the_coarse_sum_at_its_nodes(moonlit):
    """At a node (Moon zenith, line-of-sight zenith, azimuth, roll) the table returns the coarse
    grid's direct sum it stored, for every door state: the table's coordinates invert the
    scene it was built from (including the roll, measured from the upward vertical)."""
    from straylight.sources.body_magnitudes import MOON_MEAN_DISTANCE_KM
    from straylight.sources.earthshine.moonlit_build import _moonlit_scene

    c, cm, lut = moonlit
    off = cm.earth_grid
    r = np.array([np.mean(c.orbit_radius_range_km)])
    for iz, il, ia, ip in ((3, 5, 2, 4), (8, 12, 9, 17), (1, 20, 15, 11)):
        node = [
            np.radians([v[i]])
            for v, i in (
                (lut.moon_zenith_deg, iz),
                (lut.los_zenith_deg, il),
                (lut.azimuth_deg, ia),
                (lut.roll_deg, ip),
            )
        ]
        sat, moon, frame = _moonlit_scene(r, np.array([MOON_MEAN_DISTANCE_KM]), *node)
        for state in off.door_states_deg:
            d, g = lut.coefficients(sat, moon, frame, np.array([state]))
            ref = off.earthshine_coefficients(
                Bodies(sat, moon, moon),
                frame,
                np.array([state]),
                c.earth.radius_km,
                in_field=False,
                sun=False,
                grid=cm.source("moonlit_earth").grid,
            )
            assert d[0] == pytest.approx(ref["direct_moon"][0], rel=1e-9, abs=1e-40)
            assert g[0] == pytest.approx(ref["door_moon"][0], rel=1e-9, abs=1e-40)


def test_moonlit_table_matches_the_coarse_sum_in_real_scenes(moonlit):
    """The table's premise (the coefficients depend on the four angles and the door state
    only, and mirror about the Moon's vertical plane): at 300 observable samples of the campaign
    (the real satellite, Moon and Sun-set roll, every orientation) the table agrees with the
    coarse grid's direct sum to within the moonlit grid's share of the tolerance (1/8 of 1 %),
    the error taken at full Moon at perigee as a fraction of the total (the table's validation
    measure; its recorded validation, 400 random scenes, within the same share)."""
    from straylight.model import ERROR_BUDGET_SHARES
    from straylight.sources.body_magnitudes import MOON_PERIGEE_KM, moon_v_magnitude
    from straylight.sources.photometry import solar_like_fraction

    c, cm, lut = moonlit
    # 2,400 random samples: ~15 % are observable (the bright limb at the top of the atmosphere)
    sc, los, g = random_samples(c, 2400, seed=12)
    obs = np.flatnonzero(g["observable"])[:300]
    sat, sun, moon = sc.satellite_km[obs], sc.bodies_km["sun"][obs], sc.bodies_km["moon"][obs]
    frame = telescope_frame(los[obs], sun - sat)
    door = g["door_opening_deg"][obs]
    ref = cm.earth_grid.earthshine_coefficients(
        Bodies(sat, sun, moon),
        frame,
        door,
        c.earth.radius_km,
        in_field=False,
        sun=False,
        grid=cm.source("moonlit_earth").grid,
    )
    d, gd = lut.coefficients(sat, moon, frame, door)
    moon_max = solar_like_fraction(moon_v_magnitude(0.0, MOON_PERIGEE_KM))
    direct = ref["direct_moon"] + ref["door_moon"]
    err = np.abs(d + gd - direct) * moon_max / (direct * moon_max + cm.source("sunlit_earth").engine.floor)
    share = ERROR_BUDGET_SHARES["moonlit_earthshine_grid"] * cm.policy.tolerance
    print(
        f"moonlit table vs coarse sum at {obs.size} observable samples: {err.max():.2e} (validated "
        f"{lut.validation_max_rel_error:.2e}, share {share:.2e})"
    )
    assert obs.size == 300 and np.count_nonzero(direct > 0) > 100
    assert err.max() <= share
    assert 0.0 < lut.validation_max_rel_error <= share


def test_moonlit_table_is_finite_at_the_singular_directions(moonlit):
    """Line of sight at the zenith and the nadir (the roll's reference undefined), the Moon at
    the zenith and on the line of sight: finite, non-negative coefficients."""
    from straylight.sky.frames import telescope_frame as tf

    c, cm, lut = moonlit
    r = np.mean(c.orbit_radius_range_km)
    sat = np.array([[r, 0, 0]] * 4, float)
    moon = 384400.0 * np.array([[1, 0, 0], [0, 1, 0], [0.6, 0.8, 0], [1, 0, 0]], float)
    los = np.array([[1, 0, 0], [-1, 0, 0], [0.6, 0.8, 0], [0, 0, 1]], float)
    sun = 1.495978707e8 * np.array([[0, 0, 1], [0, 0, 1], [0, 1, 0], [1, 0, 0]], float)
    d, g = lut.coefficients(sat, moon, tf(los, sun - sat), np.array([135.0, 90.0, 0.0, 135.0]))
    assert np.all(np.isfinite(d)) and np.all(np.isfinite(g)) and np.all(d >= 0) and np.all(g >= 0)


def test_moonlit_table_save_load_round_trip(moonlit, tmp_path):
    from straylight.sources.earthshine.moonlit_table import MoonlitLUT

    c, cm, lut = moonlit
    p = tmp_path / "m.npz"
    lut.save(p)
    back = MoonlitLUT.load(p)
    assert back.grid == lut.grid and back.symmetric == lut.symmetric
    for s in lut.direct:
        np.testing.assert_array_equal(back.direct[s], lut.direct[s])
    (tmp_path / "bad.npz").write_bytes(b"not a table")
    with pytest.raises(Exception, match="bad.npz"):
        MoonlitLUT.load(tmp_path / "bad.npz")


def test_a_batch_of_time_steps_equals_each_step_alone(coarse):
    """On the table's path the cube evaluates whole time steps as one flat batch, computing each
    step's scene quantities (bodies' directions, planets' magnitudes, the Earth hiding each
    star) once per step (geometry.scene_runs).  The batch must give what each step alone gives,
    to float rounding: nothing may leak from one step's scene into another's."""
    from straylight.sky.geometry import observing_geometry
    from straylight.sky.observing import scene
    from straylight.sky.runs import SceneRuns
    from straylight.sky.vectors import radec_to_unit
    from straylight.sources.stars_table import split_stars

    c, cm, _ = coarse
    rng = np.random.default_rng(11)
    n_los, n_star = 150, 400
    los = radec_to_unit(rng.uniform(0, 360, n_los), np.degrees(np.arcsin(rng.uniform(-1, 1, n_los))))
    s_ra, s_dec = rng.uniform(0, 360, n_star), np.degrees(np.arcsin(rng.uniform(-1, 1, n_star)))
    stars = split_stars(s_ra, s_dec, {b: rng.uniform(-1.0, 4.0, n_star) for b in c.bands}, 2.0, False)
    sc = scene(c.orbit, ["2026-01-01T00:00:00", "2026-01-01T00:35:00", "2026-01-01T03:10:00"])
    k = len(sc.satellite_km)

    def run(sat, bodies, lines, runs=None):
        g = observing_geometry(sat, bodies, lines, c.earth.radius_km, c.constraints, runs=runs)
        return g, cm.evaluate(sat, bodies, lines, g, c.bands, stars, runs=runs)

    batch_args = (
        np.repeat(sc.satellite_km, n_los, axis=0),
        {b: np.repeat(v, n_los, axis=0) for b, v in sc.bodies_km.items()},
        np.tile(los, (k, 1)),
    )
    g_batch, batch = run(*batch_args)
    # the steps passed as known runs (as the cube passes them) change nothing, bit for bit
    g_known, known = run(*batch_args, runs=SceneRuns.steps(k, n_los))
    for key in g_batch:
        np.testing.assert_array_equal(g_known[key], g_batch[key])
    for b in c.bands:
        for comp in ("zodiacal", "sun", "moon", "planets", "stars", "earthshine", "total"):
            np.testing.assert_array_equal(known[b][comp], batch[b][comp])
    checked = 0
    for it in range(k):
        sl = slice(it * n_los, (it + 1) * n_los)
        g, alone = run(
            np.broadcast_to(sc.satellite_km[it], los.shape),
            {b: np.broadcast_to(v[it], los.shape) for b, v in sc.bodies_km.items()},
            los,
        )
        for key in (
            "sun_angle_deg",
            "moon_earth_blocked",
            "jupiter_phi_deg",
            "door_opening_deg",
            "observable",
        ):
            np.testing.assert_array_equal(g_batch[key][sl], g[key])
        for b in c.bands:
            for comp in ("moon", "planets", "stars", "earthshine", "total"):
                np.testing.assert_allclose(batch[b][comp][sl], alone[b][comp], rtol=1e-12, atol=0)
                checked += int(np.count_nonzero(alone[b][comp]))
    assert checked > 1000  # the stars and planets were summed, not all skipped
    assert np.count_nonzero(batch["g"]["stars"]) > 50


def test_cube_region_batches_steps_in_time_pixel_order(coarse):
    """compute_region on the table's path (its steps in one batch) puts each value at its own
    time and pixel: the same as evaluating each step alone."""
    from straylight.cube.footprint import footprint_from_config
    from straylight.cube.region import compute_region
    from straylight.sky.geometry import observing_geometry
    from straylight.sky.observing import scene
    from straylight.sky.vectors import radec_to_unit

    c, cm, _ = coarse
    fp = footprint_from_config(c.settings.footprint)
    t_slice, p_slice = slice(0, 30, 10), slice(100, 160)
    ds = compute_region(c, fp, t_slice, p_slice, model=cm)
    los = radec_to_unit(fp.ra_deg[p_slice], fp.dec_deg[p_slice])
    sc = scene(c.orbit, c.times[t_slice])
    for it in range(3):
        sat = np.broadcast_to(sc.satellite_km[it], los.shape)
        bodies = {b: np.broadcast_to(v[it], los.shape) for b, v in sc.bodies_km.items()}
        g = observing_geometry(sat, bodies, los, c.earth.radius_km, c.constraints)
        alone = cm.evaluate(sat, bodies, los, g, c.bands)
        np.testing.assert_array_equal(ds["observable"].values[it], g["observable"])
        for ib, b in enumerate(c.bands):
            np.testing.assert_allclose(ds["total"].values[it, :, ib], alone[b]["total"], rtol=1e-6)


def test_step_batches_are_even_and_within_the_cap():
    """cube._step_batches: consecutive slices covering every step once, each within the cap
    (or one step where a step alone exceeds it), sizes within one step of each other."""
    from straylight.cube.region import _step_batches

    for n_steps, n_pixels, cap in [
        (72, 1024, 65536),
        (72, 660, 131072),
        (7, 60, 150),
        (5, 10**6, 1000),
        (72, 1024, 131072),
        (13, 1, 4),
        (0, 660, 65536),
    ]:
        batches = _step_batches(n_steps, n_pixels, cap)
        sizes = [b.stop - b.start for b in batches]
        assert [b.start for b in batches] == [sum(sizes[:i]) for i in range(len(sizes))] and sum(
            sizes
        ) == n_steps
        assert all(s * n_pixels <= cap or s == 1 for s in sizes)
        assert not sizes or max(sizes) - min(sizes) <= 1
        # no more calls than the cap needs: ceil(steps / steps that fit)
        assert len(batches) == -(-n_steps // max(1, cap // n_pixels))
    assert [(b.start, b.stop) for b in _step_batches(72, 1024, 65536)] == [(0, 36), (36, 72)]  # not 64 + 8


def test_cube_region_split_into_calls_gives_the_same_values(coarse, monkeypatch):
    """A region evaluated in several calls (a small SAMPLES_PER_EVALUATION) equals the region in
    one call, value for value: each sample depends on that sample alone."""
    import straylight.cube.region as cube
    from straylight.cube.footprint import footprint_from_config
    from straylight.model import registry

    c, cm, _ = coarse
    fp = footprint_from_config(c.settings.footprint)
    t_slice, p_slice = slice(0, 35, 5), slice(200, 260)
    whole = cube.compute_region(c, fp, t_slice, p_slice, model=cm)
    monkeypatch.setattr(
        cube, "SAMPLES_PER_EVALUATION", 150
    )  # 7 steps of 60 pixels: calls of 1, 2, 2, 2 steps
    split = cube.compute_region(c, fp, t_slice, p_slice, model=cm)
    for name in list(registry.component_names()) + ["total", "observable", "violations", "door_opening_deg"]:
        np.testing.assert_array_equal(split[name].values, whole[name].values, err_msg=name)
    assert np.count_nonzero(whole["total"].values) == whole["total"].size


def test_cube_region_with_its_time_blocks_scene_gives_the_same_values(coarse):
    """A pixel block given its time block's scene (cube.run_time_blocks computes it once for
    all its pixel blocks) equals one that computes its own; a scene at other times is refused."""
    import straylight.cube.region as cube
    from straylight.cube.footprint import footprint_from_config
    from straylight.model import registry
    from straylight.sky.observing import scene

    c, cm, _ = coarse
    fp = footprint_from_config(c.settings.footprint)
    t_slice = slice(0, 12, 4)
    block_scene = scene(c.orbit, c.times[t_slice])
    for p_slice in (slice(0, 40), slice(300, 340)):
        own = cube.compute_region(c, fp, t_slice, p_slice, model=cm)
        shared = cube.compute_region(c, fp, t_slice, p_slice, model=cm, scene=block_scene)
        for name in list(registry.component_names()) + ["total", "observable", "door_opening_deg"]:
            np.testing.assert_array_equal(shared[name].values, own[name].values, err_msg=name)
    with pytest.raises(ValueError, match="not at the region's"):
        cube.compute_region(c, fp, slice(1, 13, 4), slice(0, 40), model=cm, scene=block_scene)
    with pytest.raises(ValueError, match="not at the region's"):
        cube.compute_region(c, fp, slice(0, 8, 4), slice(0, 40), model=cm, scene=block_scene)


def test_evaluate_into_a_given_array_writes_the_same_values(coarse):
    """BackgroundModel.evaluate(into=(names, array)) (the cube's float32 region) writes each
    asked-for component's values, in the order asked, the float64 ones of a plain call rounded
    to float32, and returns no other; an unknown name or a wrongly shaped array is refused."""
    from straylight.model.registry import band_components
    from straylight.sky.geometry import observing_geometry
    from straylight.sky.observing import scene
    from straylight.sky.vectors import radec_to_unit

    BAND_COMPONENTS = band_components()
    c, cm, _ = coarse
    sc = scene(c.orbit, c.times[0:20:5])
    los = radec_to_unit(np.linspace(0.0, 350.0, 50), np.linspace(-60.0, 70.0, 50))
    sat = np.repeat(sc.satellite_km, 50, axis=0)
    bodies = {b: np.repeat(v, 50, axis=0) for b, v in sc.bodies_km.items()}
    los_k = np.tile(los, (4, 1))
    g = observing_geometry(sat, bodies, los_k, c.earth.radius_km, c.constraints)
    plain = cm.evaluate(sat, bodies, los_k, g, c.bands)
    asked = ("total", "earthshine", "zodiacal", "stars")
    into = np.full((len(asked), 200, len(c.bands)), np.nan, np.float32)
    res = cm.evaluate(sat, bodies, los_k, g, c.bands, into=(asked, into))
    for ib, b in enumerate(c.bands):
        assert set(res[b]) & set(BAND_COMPONENTS) == set(asked)
        for k, comp in enumerate(asked):
            np.testing.assert_array_equal(into[k, :, ib], plain[b][comp].astype(np.float32), err_msg=comp)
            assert np.shares_memory(res[b][comp], into)
        # the plain call's components add up to its total (to rounding: the same order of sums)
        parts = sum(plain[b][k] for k in ("zodiacal", "sun", "moon", "planets", "stars", "earthshine"))
        np.testing.assert_allclose(plain[b]["total"], parts, rtol=1e-15)
        np.testing.assert_array_equal(
            plain[b]["earthshine"], plain[b]["earthshine_direct"] + plain[b]["earthshine_door"]
        )
    assert np.count_nonzero(into[1]) > 0 and np.all(into[0] > 0)
    with pytest.raises(ValueError, match="not \\(components, samples, bands\\) = \\(1, 200, 7\\)"):
        cm.evaluate(
            sat, bodies, los_k, g, c.bands, into=(("total",), np.zeros((1, 199, len(c.bands)), np.float32))
        )
    with pytest.raises(ValueError, match="unknown: \\['sky'\\]"):
        cm.evaluate(
            sat, bodies, los_k, g, c.bands, into=(("sky",), np.zeros((1, 200, len(c.bands)), np.float32))
        )
    with pytest.raises(ValueError, match="each at most once"):
        cm.evaluate(
            sat, bodies, los_k, g, c.bands, into=(("total", "total"), np.zeros((2, 200, 7), np.float32))
        )


def test_cube_region_skipping_unobservable_samples_changes_no_observable_value(coarse):
    """models.unobservable_samples: skip evaluates only the observable samples: they come out
    bit-identical to evaluating every sample, every other sample is NaN in every component, and
    the flags are the same."""
    from straylight.cube.footprint import footprint_from_config
    from straylight.cube.region import compute_region
    from straylight.model.registry import component_names

    c, cm, _ = coarse
    raw = c.config_mapping()
    raw["models"]["unobservable_samples"] = "skip"
    c_skip = campaign_from_dict(raw, c.path)
    fp = footprint_from_config(c.settings.footprint)
    t_slice, p_slice = slice(0, 60, 6), slice(0, 400)
    every = compute_region(c, fp, t_slice, p_slice, model=cm)
    skip = compute_region(c_skip, fp, t_slice, p_slice, model=cm)
    obs = every["observable"].values
    assert 200 < obs.sum() < 0.9 * obs.size  # both kinds of sample present
    for v in ("observable", "violations", "door_opening_deg"):
        np.testing.assert_array_equal(skip[v].values, every[v].values)
    for comp in component_names(total=True):
        np.testing.assert_array_equal(skip[comp].values[obs], every[comp].values[obs])
        assert np.all(np.isnan(skip[comp].values[~obs]))
    assert np.count_nonzero(every["moon"].values[obs]) > 0  # a skippable term was summed somewhere
    assert cm.models_record()["unobservable_samples"] == "evaluated"
    assert (
        BackgroundModel(c_skip).models_record()["unobservable_samples"] == "skipped: NaN in every component"
    )


def test_scene_runs_group_consecutive_samples_that_share_a_scene():
    from straylight.sky.runs import scene_runs, shared_vectors

    a = np.repeat(
        np.array([[1.0, 0, 0], [0, 1.0, 0], [1.0, 0, 0]]), 4, axis=0
    )  # 3 runs; the third repeats the first
    b = np.repeat(np.array([[0, 0, 1.0], [0, 0, 1.0], [0, 0, 2.0]]), 4, axis=0)
    runs = scene_runs(a, b)
    assert runs.count == 3 and runs.index.tolist() == [0] * 4 + [1] * 4 + [2] * 4
    np.testing.assert_array_equal(runs.expand(runs.vectors[0]), a)
    np.testing.assert_array_equal(
        runs.expand(np.arange(3.0)).reshape(3, 4), np.repeat(np.arange(3.0)[:, None], 4, 1)
    )
    b2 = b.copy()
    b2[5, 2] = 3.0  # one sample differs: a run of its own, and the next sample starts another
    assert scene_runs(a, b2).count == 5
    assert scene_runs(a[:1], b[:1]) is None  # a single sample
    assert scene_runs(np.eye(3), np.eye(3)) is None  # every sample its own scene: no saving
    one = np.broadcast_to([7.0, 0, 0], (5, 3))
    assert shared_vectors(one)[0].tolist() == [7.0, 0, 0] and shared_vectors(a) is None
    assert scene_runs(one).expand(np.array([[1.0, 2.0]])).shape == (5, 2)  # one run: broadcast


def test_known_runs_read_what_the_scan_finds():
    """SceneRuns.steps (a cube's time steps, known to the caller) gives the runs that scanning
    the vectors finds: the same vectors, index and starts; restricted to a subset of the
    samples (SceneRuns.at), the runs that scanning the subset finds; the wrong number of
    samples is refused."""
    from straylight.sky.runs import SceneRuns, scene_rows, scene_runs

    rng = np.random.default_rng(5)
    steps, per_step = 4, 6
    a = np.repeat(rng.normal(size=(steps, 3)), per_step, axis=0)
    b = np.repeat(rng.normal(size=(steps, 3)), per_step, axis=0)
    known = SceneRuns.steps(steps, per_step)
    for found, given in (
        (scene_runs(a, b), known.of(a, b)),
        (scene_runs(a, b), scene_runs(a, b, runs=known)),
        (scene_rows(b), scene_rows(b, runs=known)),
    ):
        assert given.count == found.count == steps and given.shape == found.shape
        np.testing.assert_array_equal(given.index, found.index)
        np.testing.assert_array_equal(given.starts, found.starts)
        for v, w in zip(given.vectors, found.vectors):
            np.testing.assert_array_equal(v, w)
    subset = np.array([1, 2, 9, 20, 21, 23])  # steps 0, 0, 1, 3, 3, 3: three runs
    sub = known.at(subset).of(a[subset], b[subset])
    scanned = scene_rows(a[subset], b[subset])
    assert sub.count == scanned.count == 3
    np.testing.assert_array_equal(sub.index, scanned.index)
    np.testing.assert_array_equal(sub.vectors[1], scanned.vectors[1])
    with pytest.raises(ValueError, match="24 samples"):
        known.of(a[:-1])
