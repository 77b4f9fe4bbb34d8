"""Config validation: wrong keys, types and values are refused with key, value and what's allowed.

Reference numbers: the instrument's published values (the paper; Gong et al. 2019)."""

import copy

import pytest
import yaml
from conftest import REPO

from straylight.config import load_campaign, load_instrument
from straylight.errors import ConfigError

BASE = yaml.safe_load((REPO / "config" / "config.yaml").read_text())


def write(tmp_path, cfg, name="c.yaml"):
    cfg = copy.deepcopy(cfg)
    cfg["instrument"] = str(REPO / "config" / "instruments" / "csst.yaml")
    p = tmp_path / name
    p.write_text(yaml.safe_dump(cfg))
    return p


def test_default_config_loads(campaign):
    assert campaign.name == "default"
    assert campaign.bands == ["NUV", "u", "g", "r", "i", "z", "y"]
    assert len(campaign.times) == 288  # one day at 300 s
    assert campaign.constraints.sun_min_deg == 50.0
    assert campaign.instrument_value("telescope", "focal_length_m") == 28.0


@pytest.mark.parametrize(
    "mutate,expected",
    [
        (lambda c: c["campaign"].update(colour="red"), "unknown key campaign.colour"),
        (lambda c: c.update(extra=1), "unknown key extra"),
        (lambda c: c["campaign"].update(cadence_s="fast"), "campaign.cadence_s = 'fast': expected number"),
        (lambda c: c["campaign"].update(cadence_s=-5), "campaign.cadence_s = -5: must be > 0"),
        (lambda c: c["footprint"].update(nside=17), "footprint.nside = 17: must be one of"),
        (lambda c: c["orbit"].update(model="kepler"), "orbit.model = 'kepler': must be one of"),
        (lambda c: c["earth"].update(radius_km=1.0), "earth.radius_km = 1.0: must be >= 6300"),
        (lambda c: c["campaign"].update(start=None), "campaign.start = None: expected string"),
        (
            lambda c: c["campaign"].update(start="2500-01-01T00:00:00", end="2500-01-02T00:00:00"),
            "outside the DE405 range",
        ),
        (lambda c: c["campaign"].update(end="2025-01-01T00:00:00"), "must be after campaign.start"),
        (lambda c: c["campaign"].update(start="yesterday"), "cannot parse 'yesterday'"),
        (lambda c: c["campaign"].update(name="bad/name"), "campaign.name = 'bad/name'"),
    ],
)
def test_bad_campaign_configs(tmp_path, mutate, expected):
    cfg = copy.deepcopy(BASE)
    mutate(cfg)
    p = write(tmp_path, cfg)
    with pytest.raises(ConfigError) as err:
        load_campaign(p)
    assert expected in str(err.value)
    assert str(p) in str(err.value)  # names the file


def test_instrument_entries_need_a_source(tmp_path):
    inst = yaml.safe_load((REPO / "config" / "instruments" / "csst.yaml").read_text())
    del inst["telescope"]["focal_length_m"]["source"]
    p = tmp_path / "inst.yaml"
    p.write_text(yaml.safe_dump(inst))
    with pytest.raises(ConfigError, match="telescope.focal_length_m"):
        load_instrument(p)


def test_instrument_band_edges_must_be_ordered(tmp_path):
    inst = yaml.safe_load((REPO / "config" / "instruments" / "csst.yaml").read_text())
    inst["bands"]["g"]["wavelength_min_nm"] = 600
    p = tmp_path / "inst.yaml"
    p.write_text(yaml.safe_dump(inst))
    with pytest.raises(ConfigError, match="bands.g: wavelength_min_nm = 600"):
        load_instrument(p)


def test_instrument_values_match_the_paper():
    inst = load_instrument(REPO / "config" / "instruments" / "csst.yaml")
    assert inst["telescope"]["aperture_diameter_m"]["value"] == 2.0
    edges = {b: (v["wavelength_min_nm"], v["wavelength_max_nm"]) for b, v in inst["bands"].items()}
    assert edges == {
        "NUV": (255, 320),
        "u": (320, 400),
        "g": (400, 550),
        "r": (550, 690),
        "i": (690, 820),
        "z": (820, 1000),
        "y": (940, 1000),
    }
    assert {b: v["n_exposures"] for b, v in inst["bands"].items()} == {
        "NUV": 4,
        "u": 2,
        "g": 2,
        "r": 2,
        "i": 2,
        "z": 2,
        "y": 4,
    }
    # one pixel scale, derived: pixel / focal length = 10 um / 28 m = 0.073665 arcsec (the
    # published 0.074, Gong et al. 2019, is it rounded); a configured one is refused
    from straylight.config import pixel_scale_arcsec

    assert "pixel_scale_arcsec" not in inst["detector"]
    assert pixel_scale_arcsec(inst) == pytest.approx(10e-6 / 28.0 * 206264.806247, rel=1e-9)
    assert pixel_scale_arcsec(inst) == pytest.approx(0.074, abs=0.0005)


def test_configured_pixel_scale_is_refused(tmp_path):
    import yaml

    from straylight.config import load_instrument

    inst = yaml.safe_load((REPO / "config" / "instruments" / "csst.yaml").read_text())
    inst["detector"]["pixel_scale_arcsec"] = {"value": 0.074, "unit": "arcsec", "source": "x"}
    p = tmp_path / "inst.yaml"
    p.write_text(yaml.safe_dump(inst))
    with pytest.raises(ConfigError, match="pixel_scale_arcsec = .*derived"):
        load_instrument(p)


def test_missing_config_file_is_clear(tmp_path):
    with pytest.raises(ConfigError, match="cannot read campaign config"):
        load_campaign(tmp_path / "nope.yaml")


def test_tle_orbit_from_config(tmp_path):
    from conftest import ISS_L1, ISS_L2

    (tmp_path / "iss.tle").write_text(f"ISS\n{ISS_L1}\n{ISS_L2}\n")
    cfg = copy.deepcopy(BASE)
    cfg["orbit"] = {"model": "tle", "tle": {"file": "iss.tle"}}
    c = load_campaign(write(tmp_path, cfg))
    import numpy as np

    r = np.linalg.norm(c.orbit.position_gcrs_km("2008-09-20T12:00:00"))
    assert 6600 < r < 6800


def test_config_reference_is_generated_from_the_schema_and_covers_the_default_config():
    """docs/config.md is `straylight config-doc`'s output (regenerate it when the schema
    changes), and every key of the default config has a row."""
    from straylight.configdoc import config_reference

    ref = config_reference()
    assert (REPO / "docs" / "config.md").read_text() == ref

    def keys(tree, prefix=""):
        for k, v in tree.items():
            yield prefix + k
            if isinstance(v, dict):
                yield from keys(v, prefix + k + ".")

    for k in keys(BASE):
        assert f"| `{k}` |" in ref, k


def test_a_config_of_random_bytes_is_one_line_naming_the_file(tmp_path):
    """Not text: one ConfigError naming the file and the first byte that is not UTF-8 (the
    campaign, the instrument and Snakemake's merged files all go through the same reader)."""
    import random

    from straylight.config import resolve_config_files

    noise = tmp_path / "noise.yaml"
    noise.write_bytes(b"campaign:\n" + random.Random(5).randbytes(2000))
    for call in (
        lambda: load_campaign(noise),
        lambda: load_instrument(noise),
        lambda: resolve_config_files({}, [noise]),
    ):
        with pytest.raises(ConfigError) as err:
            call()
        msg = str(err.value)
        assert msg.startswith(f"{noise}: ") and "not UTF-8 text" in msg and "\n" not in msg, msg


def test_broken_yaml_is_one_line():
    """YAML's own message spans lines: the reader makes it one, with the line and column."""
    import tempfile
    from pathlib import Path

    from straylight.config import _read_yaml

    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "broken.yaml"
        p.write_text("campaign: {name: x\n  start: [\n")
        with pytest.raises(ConfigError) as err:
            _read_yaml(p, "campaign config")
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(f"{p}: not valid YAML") and "line 2, column 8" in msg, msg


def test_report_bands_must_be_the_instruments(tmp_path):
    """report.sky_map_bands is checked with the config, not after the cube is computed."""
    cfg = copy.deepcopy(BASE)
    cfg["report"] = {"sky_map_bands": ["g", "Q"]}
    p = write(tmp_path, cfg)
    with pytest.raises(ConfigError) as err:
        load_campaign(p)
    assert str(err.value) == (
        f"{p}: report.sky_map_bands = ['g', 'Q']: 'Q' is not a band of the instrument (NUV, u, g, r, i, z, y)"
    )
    cfg["report"] = {"sky_map_bands": ["g", "r"]}
    assert load_campaign(write(tmp_path, cfg)).settings.report.sky_map_bands == ("g", "r")


def _tle_with_epoch(epoch: str) -> tuple[str, str]:
    """The conftest ISS element set with its epoch (YYDDD.DDDDDDDD, columns 19-32) replaced."""
    from conftest import ISS_L1, ISS_L2

    body = ISS_L1[:18] + epoch + ISS_L1[32:68]
    return body + str((sum(int(c) for c in body if c.isdigit()) + body.count("-")) % 10), ISS_L2


@pytest.fixture
def fresh_epoch_warnings(monkeypatch):
    from straylight.sky.orbit import EPOCH_WARNED_ENV

    monkeypatch.delenv(EPOCH_WARNED_ENV, raising=False)


def test_a_tle_far_from_the_campaign_warns_once(tmp_path, caplog, fresh_epoch_warnings):
    """A 7-year-old TLE: SGP4 that far from its epoch is unreliable; one warning line naming the
    epoch, the campaign's start and the gap, at validation (before any propagation)."""
    line1, line2 = _tle_with_epoch("19001.00000000")
    (tmp_path / "old.tle").write_text(f"CSS\n{line1}\n{line2}\n")
    cfg = copy.deepcopy(BASE)
    cfg["orbit"] = {"model": "tle", "tle": {"file": "old.tle"}}
    p = write(tmp_path, cfg)
    with caplog.at_level("WARNING"):
        load_campaign(p)
        load_campaign(p)  # the same campaign again (a job of the same run): not repeated
    lines = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert len(lines) == 1 and "\n" not in lines[0], lines
    assert (
        f"{p}: orbit.tle ({tmp_path / 'old.tle'}) epoch 2019-01-01T00:00:00 is 2557 days before "
        "campaign.start 2026-01-01T00:00:00 (up to 2558 days over the campaign)"
    ) in lines[0]
    assert "beyond 30 days" in lines[0]


def test_a_recent_tle_gives_no_warning(tmp_path, caplog, fresh_epoch_warnings):
    line1, line2 = _tle_with_epoch("25355.00000000")  # 2025-12-21: 11 days before the start
    cfg = copy.deepcopy(BASE)
    cfg["orbit"] = {"model": "tle", "tle": {"line1": line1, "line2": line2}}
    with caplog.at_level("WARNING"):
        load_campaign(write(tmp_path, cfg))
    assert not [r for r in caplog.records if r.levelname == "WARNING"]


@pytest.mark.parametrize(
    "epoch, warns",
    [("2024-06-01T00:00:00", True), ("2025-06-01T00:00:00", False), ("2027-03-01T00:00:00", True)],
)
def test_a_circular_orbit_epoch_more_than_a_year_away_warns(
    tmp_path, caplog, fresh_epoch_warnings, epoch, warns
):
    cfg = copy.deepcopy(BASE)
    cfg["orbit"]["circular"]["epoch"] = epoch
    p = write(tmp_path, cfg)
    with caplog.at_level("WARNING"):
        load_campaign(p)
    lines = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert len(lines) == int(warns), lines
    if warns:
        assert (
            f"{p}: orbit.circular.epoch {epoch} is" in lines[0]
            and "campaign.start 2026-01-01T00:00:00" in lines[0]
        )
        assert "beyond 365 days" in lines[0]
