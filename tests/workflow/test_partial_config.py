"""One campaign loader for every entry point: a campaign file holding only the keys it changes
(the README's promise) is merged over the default config the same way by `run`, `plan`,
`footprint`, `sky`, `etc`, `visibility`, `image`, `SkyModel` and `sky_background`, and a mapping
is taken wherever a path is (issue #53)."""

import json
import re

import pytest
import yaml

from straylight.config import load_campaign

#: the keys this campaign changes; everything else is the default config's
PARTIAL = {
    "campaign": {"name": "partial", "end": "2026-01-01T02:00:00", "cadence_s": 1200},
    "footprint": {"nside": 4},
    "models": {"earthshine": {"method": "direct"}},  # no table build in a test
}
T = "2026-01-01T00:30:00"


@pytest.fixture(scope="module")
def partial(tmp_path_factory):
    p = tmp_path_factory.mktemp("partial") / "partial.yaml"
    p.write_text(yaml.safe_dump(PARTIAL))
    return p


def _main(capsys, *argv):
    from straylight.cli import main

    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    assert code == 0, out.err
    return out.out


def test_the_loader_merges_a_partial_file_and_a_mapping_over_the_defaults(partial):
    from straylight.runner import check_campaign

    default = load_campaign()
    for c in (load_campaign(partial), load_campaign(PARTIAL), check_campaign(partial)):
        assert c.name == "partial"
        assert len(c.times) == 6  # 2 h at 20 min
        assert c.settings.footprint.nside == 4
        for section in ("orbit", "earth", "instrument", "stars", "storage"):  # the defaults'
            assert c.config_mapping()[section] == default.config_mapping()[section], section
        assert c.bands == default.bands
    # run (Snakemake's merge, through check_campaign), the API and the commands: one config
    assert check_campaign(partial).config == load_campaign(partial).config == load_campaign(PARTIAL).config


def test_plan_and_footprint_take_the_partial_file(partial, capsys):
    out = _main(capsys, "plan", partial)
    assert re.search(r"campaign partial: 6 times x \d+ pixels \(nside 4,", out), out
    assert "at nside 4" in _main(capsys, "footprint", "--config", partial)


def test_sky_etc_visibility_image_take_the_partial_file(partial, capsys, tmp_path):
    from astropy.table import Table

    rec = json.loads(
        _main(capsys, "sky", "--time", T, "--ra", 150, "--dec", 30, "--config", partial, "--json")
    )
    assert rec["models"]["earthshine"]["method"] == "direct"  # the partial file's (default: auto)
    out = _main(
        capsys, "etc", "--ra", 150, "--dec", 30, "--time", T, "--mag", 25, "--bands", "g", "--config", partial
    )
    assert "exposure time" in out
    out = _main(capsys, "visibility", "--ra", 150, "--dec", 30, "--band", "g", "--config", partial)
    assert "6 samples every 20 min" in out  # the partial file's cadence and end
    cat = tmp_path / "stars.ecsv"
    Table({"ra": [150.01], "dec": [30.01], "mag_g": [12.0]}).write(cat)
    img = tmp_path / "img.fits"
    argv = ("image", "--time", T, "--ra", 150, "--dec", 30, "--band", "g", "--cutout", 64, "--catalog", cat)
    _main(capsys, *argv, "--out", img, "--config", partial)
    assert img.exists()


def test_skymodel_and_sky_background_take_a_partial_file_or_a_mapping(partial):
    import astropy.units as u
    import numpy as np
    from astropy.coordinates import SkyCoord
    from astropy.time import Time

    import straylight

    by_file, by_mapping = straylight.SkyModel(config=partial), straylight.SkyModel(config=PARTIAL)
    for sky in (by_file, by_mapping):
        assert sky.campaign.name == "partial" and len(sky.campaign.times) == 6
        assert sky.campaign.settings.models.earthshine.method == "direct"
    t, c = Time(T) + [0, 20] * u.min, SkyCoord(150.0, 30.0, unit="deg")
    rows = [
        straylight.sky_background(t, c, bands=["g"], config=partial),
        straylight.sky_background(t, c, bands=["g"], config=dict(PARTIAL)),
        by_mapping.background(t, c, bands=["g"]),
    ]
    for r in rows[1:]:  # the same campaign whichever way it is given: the same numbers, bit for bit
        np.testing.assert_array_equal(r["total_g"].value, rows[0]["total_g"].value)
    assert np.all(np.isfinite(rows[0]["total_g"].value)) and np.all(rows[0]["total_g"].value > 0)
