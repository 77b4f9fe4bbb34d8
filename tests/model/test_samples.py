"""The sample batch (straylight.model.samples.SampleBatch): built once where a caller's times and
pointings enter, its scene once per distinct time, and nothing below parses a time again.

Reference numbers: the positions at each sample are those of the scene computed at that sample's
own time (:func:`straylight.sky.observing.scene`, DE405 and the orbit), exactly (one code path,
the same float64 operations); the TDB Julian dates are
:func:`straylight.sky.timeutil.utc_to_tdb_jd`'s, exactly."""

import sys

import numpy as np
import pytest
from astropy.coordinates import SkyCoord
from astropy.time import Time

import straylight.sky.timeutil as timeutil
from straylight.sky.observing import scene
from straylight.sky.vectors import radec_to_unit

#: a small model: the earthshine summed directly (no look-up table read or built)
DIRECT = {"models": {"earthshine": {"method": "direct"}}}
TIMES = ["2026-01-01T00:50:00", "2026-01-01T03:10:00", "2026-01-01T00:50:00", "2026-01-01T03:10:00"]


def _count_parses(monkeypatch) -> list:
    """Every call of parse_utc on the samples' times from now on (whichever module imported
    it), with what it was given (the objects kept, so that no two are the same object by a
    reused id); the orbit's epoch, a config value parsed once per orbit, is not counted."""
    original, calls = timeutil.parse_utc, []

    def counting(times, field="time"):
        if field != "orbit.circular.epoch":
            calls.append(times)
        return original(times, field)

    for name, module in list(sys.modules.items()):
        if name.startswith("straylight") and getattr(module, "parse_utc", None) is original:
            monkeypatch.setattr(module, "parse_utc", counting)
    return calls


def test_sky_model_background_parses_each_time_once(monkeypatch):
    """SkyModel.background reads its Time once at the boundary and passes it down: parse_utc
    runs once per Time object, twice in all: the boundary's DE405 range check of the samples'
    times, and the orbit reading the distinct times' Time (before the sample batch it ran five
    times on three objects: the range check and the pointing table on the samples' Time, the
    scene on the distinct times', its TDB and the orbit on the scene's own)."""
    from straylight.skymodel import SkyModel

    sky = SkyModel(DIRECT)
    t = Time(TIMES, scale="utc")
    coord = SkyCoord([10.0, 120.0, 250.0, 300.0], [-20.0, 5.0, 60.0, -75.0], unit="deg")
    calls = _count_parses(monkeypatch)
    table = sky.background(t, coord, bands=["g"])
    assert len(table) == 4
    assert len({id(c) for c in calls}) == len(calls), [type(c).__name__ for c in calls]
    assert len(calls) == 2


def test_pointing_table_parses_text_once(monkeypatch, campaign):
    """``sky --input``'s times (text) are parsed once, and no Time made of them is parsed
    again: three calls, each on its own object (the text; the parsed times' range check; the
    orbit reading the distinct times)."""
    from straylight.config import campaign_from_dict, deep_merge
    from straylight.planning.pointings import pointing_table

    ra, dec = np.array([10.0, 120.0, 250.0, 300.0]), np.array([-20.0, 5.0, 60.0, -75.0])
    direct = campaign_from_dict(deep_merge(campaign.config_mapping(), DIRECT), campaign.path)
    calls = _count_parses(monkeypatch)
    cols = pointing_table(direct, {"time": np.array(TIMES, dtype=object), "ra": ra, "dec": dec}, ["g"])
    assert len(cols["time"]) == 4
    assert len({id(c) for c in calls}) == len(calls) == 3, [type(c).__name__ for c in calls]


def test_batch_positions_equal_the_scene_at_each_samples_time(campaign):
    """A batch at 4 samples of 2 distinct times holds a 2-row scene, and its positions and frame
    at each sample equal the scene computed at that sample's own time (exactly); its TDB Julian
    dates are utc_to_tdb_jd's; a subset (take) carries the same values."""
    from straylight.model.samples import SampleBatch

    t = Time(TIMES, scale="utc")
    ra, dec = np.array([10.0, 120.0, 250.0, 300.0]), np.array([-20.0, 5.0, 60.0, -75.0])
    batch = SampleBatch.at_times(campaign.orbit, t, ra, dec)
    assert len(batch.scene.times) == 2 and batch.n == 4
    each = scene(campaign.orbit, t)
    np.testing.assert_array_equal(batch.satellite_km, each.satellite_km)
    for body in ("sun", "moon", "jupiter"):
        np.testing.assert_array_equal(batch.body_km(body), each.bodies_km[body])
    jd1, jd2 = timeutil.utc_to_tdb_jd(t[[0, 1]])
    np.testing.assert_array_equal(batch.scene.tdb_jd[0], jd1)
    np.testing.assert_array_equal(batch.scene.tdb_jd[1], jd2)
    np.testing.assert_array_equal(batch.los, radec_to_unit(ra, dec))
    frame = batch.frame
    sub = batch.take(np.array([1, 3]))
    np.testing.assert_array_equal(sub.satellite_km, each.satellite_km[[1, 3]])
    np.testing.assert_array_equal(sub.body_km("moon"), each.bodies_km["moon"][[1, 3]])
    np.testing.assert_array_equal(sub.frame.z, frame.z[[1, 3]])
    assert [x[:19] for x in sub.times.isot] == [TIMES[1], TIMES[3]]
    assert batch[1::2].times.isot.tolist() == sub.times.isot.tolist()


@pytest.mark.parametrize("index", [None, np.array([0, 0, 1])])
def test_a_slice_of_a_batch_is_its_samples(campaign, index):
    """batch[a:b] holds samples a..b-1: their times and lines of sight, on the same scene."""
    from straylight.model.samples import SampleBatch

    sc = scene(campaign.orbit, ["2026-01-01T00:50:00", "2026-01-01T03:10:00", "2026-01-01T05:00:00"])
    los = radec_to_unit(np.array([10.0, 20.0, 30.0]), np.array([0.0, 10.0, 20.0]))
    batch = SampleBatch(sc, los, index)
    part = batch[1:3]
    times = sc.times if index is None else sc.times[index]
    assert part.scene is sc and part.n == 2
    assert part.times.isot.tolist() == times[1:3].isot.tolist()
    np.testing.assert_array_equal(part.los, los[1:3])
    np.testing.assert_array_equal(part.satellite_km, batch.satellite_km[1:3])
