"""`straylight etc` as a user runs it: the numbers are SkyModel.exposure_time's (the API), the
text shows them, a window gives its summary, bad input gives one line and exit 2; and every
command of the parser (etc among them) has its help."""

import json

import astropy.units as u
import numpy as np
import pytest
from conftest import run_cli, run_clis

T0 = "2026-01-01T00:30:00"
ARGS = ("etc", "--ra", "150", "--dec", "30", "--time", T0)


def test_every_command_has_help(capsys):
    """Every sub-command the parser builds answers --help (exit 0, a usage line and its options)."""
    from straylight.cli import main
    from straylight.cli.parser import build_parser

    sub = next(a for a in build_parser()._actions if a.__class__.__name__ == "_SubParsersAction")
    assert "etc" in sub.choices
    for cmd in sub.choices:
        with pytest.raises(SystemExit) as exc:
            main([cmd, "--help"])
        out = capsys.readouterr().out
        assert exc.value.code == 0 and out.startswith("usage: straylight " + cmd), cmd
    main_help = build_parser().format_help()
    assert "etc" in main_help and "exposure time" in main_help


def test_etc_help_says_how_the_time_is_split():
    r = run_cli("etc", "--help")
    assert r.returncode == 0, r.stderr
    text = " ".join(r.stdout.split())
    for fragment in ("--exptime", "--snr", "--step-min", "split into the band's survey number of exposures"):
        assert fragment in text


def test_etc_json_and_text_equal_the_api(tmp_path, default_tables):
    """--json rows equal SkyModel.exposure_time for the same sample (1e-9 relative: the same code
    path, the JSON's float repr); the text shows the same times to 0.1 s and the exposure split."""
    from astropy.coordinates import SkyCoord
    from astropy.table import QTable
    from astropy.time import Time

    from straylight.skymodel import cached_sky_model

    r, text = run_clis(  # side by side
        (*ARGS, "--mag", "25", "--bands", "g,NUV", "--json"),
        (*ARGS, "--mag", "25", "--bands", "g,NUV", "--out", tmp_path / "etc.ecsv"),
    )
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    api = cached_sky_model().exposure_time(
        Time(T0), SkyCoord(150.0, 30.0, unit="deg"), 25.0, bands=["g", "NUV"]
    )
    assert [s["band"] for s in out["samples"]] == ["g", "NUV"]
    assert out["units"]["exposure_time"] == "s" and out["request"]["mode"] == "exposure_time"
    for row, ref in zip(out["samples"], api):
        assert row["exposure_time"] == pytest.approx(ref["exposure_time"].to_value(u.s), rel=1e-9)
        assert row["dominant"] == ref["dominant"] and row["n_exposures"] == ref["n_exposures"]
    assert text.returncode == 0, text.stderr
    for ref in api:
        line = next(ln for ln in text.stdout.splitlines() if ln.split()[:1] == [ref["band"]])
        assert f"{ref['exposure_time'].value:.1f} s" in line
        assert f"{ref['n_exposures']} x {ref['single_exposure'].value:.1f} s" in line
        assert ref["dominant"] in line
    written = QTable.read(tmp_path / "etc.ecsv")
    assert written["exposure_time"].unit == u.s
    np.testing.assert_allclose(written["exposure_time"].value, api["exposure_time"].value, rtol=1e-12)


def test_etc_exptime_at_the_limit_gives_snr_5(default_tables):
    """--exptime 300 at the g limit `straylight sky` prints for that sample: SNR 5.00."""
    r = run_cli("sky", "--time", T0, "--ra", "150", "--dec", "30", "--bands", "g", "--json")
    assert r.returncode == 0, r.stderr
    lim = json.loads(r.stdout)["bands"]["g"]["limit_mag"]
    r = run_cli(*ARGS, "--mag", repr(lim), "--exptime", "300", "--bands", "g", "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["samples"][0]["snr"] == pytest.approx(5.0, rel=1e-9)


def test_etc_window_summary_and_unobservable(default_tables):
    """A 3-h window at 10-min steps: 18 samples; the printed shortest g time is the minimum of
    the JSON's observable samples.  At the Sun: NOT observable, no time."""
    win = (*ARGS, "--end", "2026-01-01T03:30:00", "--step-min", "10", "--mag", "25.5", "--bands", "g")
    r, text, at_sun = run_clis(  # side by side
        (*win, "--json"),
        win,
        ("etc", "--ra", "281.3", "--dec", "-23", "--time", T0, "--mag", "22", "--bands", "r"),
    )
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    times = [s["exposure_time"] for s in out["samples"] if s["observable"]]
    assert len(out["samples"]) == 18 and 0 < len(times) < 18
    assert out["summary"][0]["exposure_time_min"] == min(times)
    assert text.returncode == 0, text.stderr
    assert "18 samples every 10 min" in text.stdout and f"{min(times):.1f} s" in text.stdout
    assert at_sun.returncode == 0, at_sun.stderr
    assert "NOT observable" in at_sun.stdout and "sun" in at_sun.stdout


@pytest.mark.parametrize(
    "extra,fragment",
    [
        (("--mag", "nan"), "--mag must be finite"),
        (("--mag", "25", "--snr", "-1"), "--snr: must be finite and > 0"),
        (("--mag", "25", "--exptime", "0"), "--exptime: must be finite and > 0"),
        (("--mag", "25", "--snr", "5", "--exptime", "300"), "not allowed with argument"),
        (("--mag", "25", "--bands", "V"), "--bands: 'V' is a diagnostic band without survey exposures"),
        (("--mag", "25", "--bands", "w"), "--bands: unknown band 'w'"),
        (("--mag", "25", "--n-exp", "0"), "--n-exp: expected a whole number >= 1"),
        (("--mag", "25", "--step-min", "10"), "--step-min needs --end"),
        (("--mag", "25", "--end", "2026-01-01T00:00:00"), "must be after --time"),
        (("--mag", "25", "--out", "x.txt"), "must end in .csv or .ecsv"),
    ],
)
def test_etc_bad_input_one_line_exit_2(extra, fragment):
    r = run_cli(*ARGS, *extra)
    assert r.returncode == 2
    assert fragment in r.stderr and "Traceback" not in r.stderr
    assert "np.float" not in r.stderr  # the value as the user wrote it, not numpy's repr


def test_etc_bad_time_and_pointing():
    r = run_cli("etc", "--ra", "150", "--dec", "95", "--time", T0, "--mag", "25")
    assert r.returncode == 2 and "--dec = 95.0 outside [-90, 90] deg" in r.stderr
    r = run_cli("etc", "--ra", "150", "--dec", "30", "--time", "tomorrow", "--mag", "25")
    assert r.returncode == 2 and "cannot parse 'tomorrow'" in r.stderr and "Traceback" not in r.stderr
