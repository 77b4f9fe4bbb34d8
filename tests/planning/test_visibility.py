"""`straylight visibility`: samples equal `straylight sky`, windows and days follow from the
samples, table and plot written; bad input gives one line and exit 2 before any work."""

import json

import numpy as np
import pytest
from conftest import run_cli


def test_visibility_table_windows_days_and_plot(tmp_path):
    from astropy.table import Table

    out, fig = tmp_path / "vis.ecsv", tmp_path / "vis.png"
    r = run_cli(
        "visibility",
        "--ra",
        "150",
        "--dec",
        "30",
        "--band",
        "g",
        "--start",
        "2026-01-01T00:00:00",
        "--end",
        "2026-01-01T03:00:00",
        "--step-min",
        "10",
        "--threshold",
        "26.7",
        "--out",
        out,
        "--plot",
        fig,
    )
    assert r.returncode == 0, r.stderr
    s = Table.read(out)
    w = Table.read(tmp_path / "vis_windows.ecsv")
    d = Table.read(tmp_path / "vis_days.ecsv")
    assert len(s) == 18 and fig.stat().st_size > 10_000
    assert str(s["total_e_per_s_per_pix"].unit) == "electron / (pix s)" and str(s["limit_mag"].unit) == "mag"
    # a sample equals the single-pointing command (same time, pointing, band)
    i = 3
    one = json.loads(
        run_cli(
            "sky", "--time", str(s["time"][i]), "--ra", "150", "--dec", "30", "--bands", "g", "--json"
        ).stdout
    )
    assert s["total_e_per_s_per_pix"][i] == pytest.approx(
        one["bands"]["g"]["total"]["e_per_s_per_pix"], rel=1e-6
    )
    assert s["limit_mag"][i] == pytest.approx(one["bands"]["g"]["limit_mag"], abs=1e-6)
    assert bool(s["observable"][i]) == one["observable"]
    # windows are the runs of observable samples; each sample stands for 10 min
    obs = np.asarray(s["observable"], bool)
    assert len(w) >= 1 and np.sum(w["duration_h"]) == pytest.approx(obs.sum() / 6.0)
    runs = np.diff(np.concatenate([[0], obs.astype(int), [0]]))
    assert len(w) == int((runs == 1).sum())
    assert d["observable_hours"][0] == pytest.approx(obs.sum() / 6.0)
    deep = obs & (np.asarray(s["limit_mag"]) >= 26.7)
    assert d["hours_deeper_than_threshold"][0] == pytest.approx(deep.sum() / 6.0)
    assert d["limit_mag_best"][0] == pytest.approx(np.max(np.asarray(s["limit_mag"])[obs]), abs=1e-9)
    assert "observable windows" in r.stdout and "days with the limit deeper than 26.70 mag" in r.stdout


@pytest.mark.parametrize(
    "extra, fragment",
    [
        (("--dec", "95"), "--dec = 95.0 outside [-90, 90] deg"),
        (("--ra", "1e308"), "--ra = 1e+308 outside [-360, 360] deg"),
        (("--band", "w"), "--band: 'w' is not one of"),
        (("--start", "2026-01-02", "--end", "2026-01-01"), "must be after --start"),
        (("--step-min", "0"), "--step-min: must be > 0"),
        (("--out", "no/such/dir/vis.csv"), "folder"),
        (("--plot", "vis.gif"), "--plot vis.gif: must end in"),
    ],
)
def test_visibility_bad_input_one_line_exit_2(tmp_path, extra, fragment):
    args = {"--ra": "150", "--dec": "30", "--band": "g"}
    rest = []
    for k, v in zip(extra[::2], extra[1::2]):
        if k in args:
            args[k] = v
        else:
            rest += [k, v]
    r = run_cli("visibility", *[x for kv in args.items() for x in kv], *rest, cwd=tmp_path)
    assert r.returncode == 2, r.stdout + r.stderr
    assert fragment in r.stderr and "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []
