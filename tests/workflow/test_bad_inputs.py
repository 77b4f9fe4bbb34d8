"""The bad-input corpus (tests/workflow/bad_inputs/cases.yaml): every user mistake gives one
clear line naming the file, field and value, with exit status 2 and nothing written or changed,
or a quarantine with counted reasons; never a traceback, never a silently wrong product."""

import copy
import gzip
import hashlib
import importlib
import random
import warnings
from pathlib import Path

import pytest
import yaml
from conftest import REPO, tiny_config

CASES = yaml.safe_load((Path(__file__).parent / "bad_inputs" / "cases.yaml").read_text())
OUTPUT_FLAGS = ("--out", "--fits")


def _fill(obj, subs):
    if isinstance(obj, str):
        for k, v in subs.items():
            obj = obj.replace("{" + k + "}", v)
        return obj
    if isinstance(obj, dict):
        return {_fill(k, subs): _fill(v, subs) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_fill(v, subs) for v in obj]
    return obj


def _set(tree, dotted, value):
    *head, last = dotted.split(".")
    for k in head:
        tree = tree.setdefault(k, {})
    tree[last] = value


def _del(tree, dotted):
    *head, last = dotted.split(".")
    for k in head:
        tree = tree[k]
    del tree[last]


def _prepare(case, tmp: Path) -> dict:
    subs = {"tmp": str(tmp), "config": str(tmp / "campaign.yaml")}
    case = _fill(copy.deepcopy(case), subs)
    for name, content in (case.get("files") or {}).items():
        p = tmp / name
        if isinstance(content, dict) and "random_bytes" in content:  # noise, the same every run
            p.write_bytes(random.Random(content.get("seed", 0)).randbytes(content["random_bytes"]))
        elif isinstance(content, dict):  # gzip, optionally cut short
            data = gzip.compress(content["gzip"].encode())
            p.write_bytes(data[: content.get("truncate", len(data))])
        else:
            p.write_bytes(content.encode("latin-1"))
    inst = yaml.safe_load((REPO / "config" / "instruments" / "csst.yaml").read_text())
    for k, v in (case.get("instrument_set") or {}).items():
        _set(inst, k, v)
    for k in case.get("instrument_del") or ():
        _del(inst, k)
    (tmp / "instrument.yaml").write_text(yaml.safe_dump(inst))
    cfg = yaml.safe_load(tiny_config(tmp, name="tiny").read_text())
    (tmp / "tiny.yaml").unlink()
    cfg["instrument"] = str(tmp / "instrument.yaml")
    for k, v in (case.get("config_set") or {}).items():
        _set(cfg, k, v)
    for k in case.get("config_del") or ():
        _del(cfg, k)
    (tmp / "campaign.yaml").write_text(yaml.safe_dump(cfg))
    return case


def _tree_digest(root: Path) -> dict:
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file()
    }


def _run(argv, capsys, monkeypatch=None, no_work=()):
    """Run the command in-process; returns (exit status, stdout, stderr, warnings raised).

    ``no_work``: dotted names of the expensive steps, each replaced by a function that fails
    the test: the command must refuse its input before it gets there."""
    from straylight.cli import main

    for dotted in no_work:
        module, name = dotted.rsplit(".", 1)

        def started(*_a, _what=dotted, **_k):
            raise AssertionError(f"{_what} ran before the bad input was refused")

        monkeypatch.setattr(importlib.import_module(module), name, started)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse's own usage errors
            code = exc.code
    cap = capsys.readouterr()
    return code, cap.out, cap.err, [f"{w.category.__name__}: {w.message}" for w in caught]


def test_corpus_is_large_and_ids_are_unique():
    ids = [c["id"] for c in CASES]
    assert len(ids) >= 50 and len(set(ids)) == len(ids)


@pytest.mark.parametrize("case", CASES, ids=[c["id"] for c in CASES])
def test_bad_input(case, tmp_path, capsys, monkeypatch):
    case = _prepare(case, tmp_path)
    argv, expect = case["run"], case["expect"]
    if expect["exit"] == 2:
        # a product from an earlier run sits where the output goes: it must survive untouched
        # (and the user allowed it to be replaced: the bad input, not the existing file, is refused)
        for i, a in enumerate(list(argv[:-1])):
            if a in OUTPUT_FLAGS and not Path(argv[i + 1]).exists():
                Path(argv[i + 1]).write_bytes(b"product of an earlier run")
                if "--overwrite" not in argv:
                    argv = [*argv, "--overwrite"]
        before = _tree_digest(tmp_path)
        code, _, err, caught = _run(argv, capsys, monkeypatch, expect.get("no_work", ()))
        assert code == 2, err
        assert "Traceback" not in err
        # our line is the only one: no library warning (ERFA's "dubious year") printed before it
        assert not [w for w in caught if "ErfaWarning" in w], caught
        message = [ln for ln in err.splitlines() if "error:" in ln]
        assert len(message) == 1, err
        for fragment in expect["stderr_has"]:
            assert fragment in message[0], f"{fragment!r} not in {message[0]!r}"
        if "stderr_lines" in expect:
            assert len(err.strip().splitlines()) == expect["stderr_lines"], err
        assert _tree_digest(tmp_path) == before  # nothing written, nothing changed
    else:
        import pyarrow.parquet as pq

        code, out, err, _ = _run(argv, capsys)
        assert code == 0, err
        out_path = Path(argv[argv.index("--out") + 1])
        assert pq.read_metadata(out_path).num_rows == expect["stars"]
        q = out_path.with_name(out_path.stem + "_quarantine.parquet")
        reasons = {}
        if q.exists():
            for r in pq.read_table(q).column("reason").to_pylist():
                reasons[r] = reasons.get(r, 0) + 1
        assert reasons == expect["quarantine"]


# ---- visibility: the step against the window and the orbit ------------------------------------
def _always_observable(campaign, t, ra_deg, dec_deg, bands, stars=None, source=""):
    """background_table's stand-in: every sample observable, 1 e-/s/pixel (the windows' arithmetic
    without the model)."""
    import astropy.units as u
    import numpy as np
    from astropy.table import QTable

    n, b = len(t), bands[0]
    return QTable(
        {
            "time": t,
            "observable": np.ones(n, bool),
            "violations": np.zeros(n, np.uint8),
            f"total_{b}": np.ones(n) * u.electron / (u.s * u.pix),
            f"total_mag_{b}": np.full(n, 22.0) * u.mag / u.arcsec**2,
            f"limit_mag_{b}": np.full(n, 26.0) * u.mag,
        },
        meta={"mag_zero_point": {b: 25.0 * u.mag / u.arcsec**2}},
    )


def test_visibility_windows_end_at_end(tmp_path, monkeypatch):
    """The last sample stands for [t, t + step) cut at --end: a window never runs past it, and the
    observable hours count only the time inside [start, end)."""
    import straylight.planning.pointings as pointings
    from straylight.config import load_campaign
    from straylight.planning.visibility import visibility

    monkeypatch.setattr(pointings, "background_table", _always_observable)
    campaign = load_campaign(tiny_config(tmp_path))
    res = visibility(
        campaign, 150.0, 30.0, "g", "2026-01-01T00:00:00", "2026-01-01T01:00:00", 25 * 60.0, 25.0
    )
    w, d = res["windows"], res["days"]
    assert len(res["samples"]) == 3 and len(w) == 1
    assert w["start"][0].isot == "2026-01-01T00:00:00" and w["end"][0].isot == "2026-01-01T01:00:00"
    assert w["duration_h"][0].value == pytest.approx(1.0)
    assert d["observable_hours"][0].value == pytest.approx(1.0)
    assert d["hours_deeper_than_threshold"][0].value == pytest.approx(1.0)


@pytest.mark.parametrize(
    "step_min, expect",
    [
        ("10", None),
        ("30", "longer than a quarter of the orbital period (92.4 min)"),
        ("93", "within 0.7 % of 1 x the orbital period (92.4 min)"),
        ("184", "within 0.4 % of 2 x the orbital period (92.4 min)"),
    ],
)
def test_visibility_step_against_the_orbit_warns(tmp_path, monkeypatch, capsys, caplog, step_min, expect):
    """Observability changes within an orbit (Earth occultation, the limbs): a step over a quarter
    period can miss a window, and one near a multiple of the period samples the same orbital phase
    each time (aliasing). One warning line; the command still runs."""
    import straylight.planning.pointings as pointings

    monkeypatch.setattr(pointings, "background_table", _always_observable)
    cfg = tiny_config(tmp_path)
    with caplog.at_level("WARNING"):
        code, _, err, _ = _run(
            [
                "visibility",
                "--config",
                str(cfg),
                "--ra",
                "150",
                "--dec",
                "30",
                "--band",
                "g",
                "--start",
                "2026-01-01T00:00",
                "--end",
                "2026-01-02T00:00",
                "--step-min",
                step_min,
            ],
            capsys,
        )
    assert code == 0, err
    lines = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    if expect is None:
        assert lines == []
    else:
        assert len(lines) == 1 and "\n" not in lines[0], lines
        assert lines[0].startswith(f"warning: --step-min {step_min}: ") and expect in lines[0], lines[0]
        assert "use --step-min 23.1 or less" in lines[0]


def test_visibility_aliasing_warning_is_one_line_on_stderr(tmp_path, default_tables):
    """As a user runs it: the warning is one line on stderr, and the results are printed."""
    from conftest import run_cli

    r = run_cli(
        "visibility",
        "--config",
        tiny_config(tmp_path),
        "--ra",
        "150",
        "--dec",
        "30",
        "--band",
        "g",
        "--start",
        "2026-01-01T00:00",
        "--end",
        "2026-01-01T04:00",
        "--step-min",
        "93",
    )
    assert r.returncode == 0, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and "aliasing" in r.stderr and "Traceback" not in r.stderr
    assert "3 samples every 93 min" in r.stdout
