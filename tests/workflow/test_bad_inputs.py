"""The bad-input corpus (tests/workflow/bad_inputs/cases.yaml, issue #9): every user mistake gives one
clear line naming the file, field and value, with exit status 2 and nothing written or changed,
or a quarantine with counted reasons; never a traceback, never a silently wrong product."""
import copy
import gzip
import hashlib
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
        if isinstance(content, dict):  # gzip, optionally cut short
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
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


def _run(argv, capsys):
    from straylight.cli import main

    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's own usage errors
        code = exc.code
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_corpus_is_large_and_ids_are_unique():
    ids = [c["id"] for c in CASES]
    assert len(ids) >= 50 and len(set(ids)) == len(ids)


@pytest.mark.parametrize("case", CASES, ids=[c["id"] for c in CASES])
def test_bad_input(case, tmp_path, capsys):
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
        code, _, err = _run(argv, capsys)
        assert code == 2, err
        assert "Traceback" not in err
        message = [ln for ln in err.splitlines() if "error:" in ln]
        assert len(message) == 1, err
        for fragment in expect["stderr_has"]:
            assert fragment in message[0], f"{fragment!r} not in {message[0]!r}"
        assert _tree_digest(tmp_path) == before  # nothing written, nothing changed
    else:
        import pyarrow.parquet as pq

        code, out, err = _run(argv, capsys)
        assert code == 0, err
        out_path = Path(argv[argv.index("--out") + 1])
        assert pq.read_metadata(out_path).num_rows == expect["stars"]
        q = out_path.with_name(out_path.stem + "_quarantine.parquet")
        reasons = {}
        if q.exists():
            for r in pq.read_table(q).column("reason").to_pylist():
                reasons[r] = reasons.get(r, 0) + 1
        assert reasons == expect["quarantine"]
