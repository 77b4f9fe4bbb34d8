"""provenance.json's record without a pipeline run: the code's revision, the run's command line
and cores handed from Snakemake's main process to its jobs, and paths an archive can keep
(none absolute).  The record of a real run: tests/cube/test_cube.py, and from an install
tests/workflow/test_packaging.py."""

import json
import os
import subprocess

from conftest import REPO


def _strings(node):
    if isinstance(node, dict):
        for k, v in node.items():
            yield str(k)
            yield from _strings(v)
    elif isinstance(node, list):
        for v in node:
            yield from _strings(v)
    elif isinstance(node, str):
        yield node


def test_portable_path_labels_shipped_files_and_relates_the_rest(tmp_path):
    from straylight.cube.provenance import portable_path

    roots = {"straylight:config": REPO / "config", "straylight:workflow": REPO / "workflow"}
    base = tmp_path / "results" / "c"
    assert (
        portable_path(REPO / "config" / "instruments" / "csst.yaml", base, roots)
        == "straylight:config/instruments/csst.yaml"
    )
    assert portable_path(REPO / "workflow" / "Snakefile", base, roots) == "straylight:workflow/Snakefile"
    assert portable_path(tmp_path / "c.yaml", base, roots) == "../../c.yaml"
    assert portable_path(base / "maps" / "x.fits", base, roots) == "maps/x.fits"
    assert portable_path(tmp_path, base, roots) == "../.."


def test_run_of_the_main_process_reaches_the_jobs(monkeypatch, tmp_path):
    """Snakemake's main process records its command line and cores and hands them on through the
    environment; a cluster job's Snakemake (another command line) records the main one's."""
    from straylight.cube import provenance as pv

    monkeypatch.delenv(pv.RUN_ENV, raising=False)
    monkeypatch.setenv(pv.LAUNCHER_ENV, json.dumps(["straylight", "run", "c.yaml"]))
    main = pv.snakemake_run(["/venv/bin/snakemake", "--cores", "4", "--configfile", "c.yaml"], 4, True)
    assert main == pv.RunInfo(
        ("snakemake", "--cores", "4", "--configfile", "c.yaml"), 4, ("straylight", "run", "c.yaml")
    )
    assert json.loads(os.environ[pv.RUN_ENV])["cores"] == 4
    job = pv.snakemake_run(
        ["/venv/bin/python", "-m", "snakemake", "--mode", "remote", "--cores", "16"], 16, False
    )
    assert job == main
    # no --cores (a cluster run's main process), no straylight run
    monkeypatch.delenv(pv.LAUNCHER_ENV)
    assert pv.snakemake_run(["snakemake", "-n"], None, True) == pv.RunInfo(("snakemake", "-n"), None, None)


def test_source_revision_from_this_checkout():
    from straylight import __version__
    from straylight.cube.provenance import source_revision

    rev = source_revision()
    head = subprocess.run(
        ["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True
    ).stdout.strip()
    status = subprocess.run(
        ["git", "status", "--porcelain", "--untracked-files=no"], cwd=REPO, capture_output=True, text=True
    ).stdout
    assert rev["from"] == "checkout" and rev["version"] == __version__
    assert rev["commit"] == head and len(head) == 40
    assert rev["dirty"] == bool(status.strip()) and len(rev["modified"]) == len(status.splitlines())


def test_source_revision_without_git_is_still_a_checkout(monkeypatch):
    from straylight.cube import provenance as pv

    monkeypatch.setenv("PATH", "/nonexistent")  # no git program
    assert pv.source_revision() == {
        "version": pv.__version__,
        "from": "checkout",
        "commit": None,
        "dirty": None,
        "modified": [],
    }


def test_record_keeps_checksums_and_no_absolute_path(tmp_path):
    import yaml
    from conftest import tiny_config

    from straylight.config import load_campaign
    from straylight.cube.provenance import RunInfo, provenance_record, sha256_path

    cfg = tiny_config(tmp_path, name="rec")
    raw = yaml.safe_load(cfg.read_text())
    raw["footprint"]["mask_file"] = str(tmp_path / "masks" / "mask.fits")  # an absolute input path
    cfg.write_text(yaml.safe_dump(raw))
    campaign = load_campaign(cfg)
    out = tmp_path / "results" / "rec"
    (out / "maps").mkdir(parents=True)
    (out / "footprint.fits").write_bytes(b"fits")
    (out / "maps" / "a.fits").write_bytes(b"map")
    run = RunInfo(
        (
            "snakemake",
            "-s",
            str(REPO / "workflow" / "Snakefile"),
            "-d",
            str(tmp_path),
            f"--configfile={cfg}",
            "--cores",
            "2",
        ),
        2,
        ("straylight", "run", str(cfg)),
    )
    rec = provenance_record(
        campaign,
        {},
        {"footprint.fits": out / "footprint.fits", "maps": out / "maps"},
        results=out,
        run=run,
        workflow_dir=REPO / "workflow",
    )
    assert rec["outputs_sha256"] == {
        "footprint.fits": sha256_path(out / "footprint.fits"),
        "maps": sha256_path(out / "maps"),
    }
    assert len(rec["outputs_digest_sha256"]) == 64 and rec["inputs_sha256"]["config"] == sha256_path(cfg)
    assert rec["config_file"] == "../../rec.yaml"
    assert rec["config"]["footprint"]["mask_file"] == "masks/mask.fits"  # against the config's folder
    assert rec["instrument_file"] == rec["config"]["instrument"] == "straylight:config/instruments/csst.yaml"
    assert rec["run"] == {
        "command": [
            "snakemake",
            "-s",
            "straylight:workflow/Snakefile",
            "-d",
            "../..",
            "--configfile=../../rec.yaml",
            "--cores",
            "2",
        ],
        "cores": 2,
        "started_by": ["straylight", "run", "../../rec.yaml"],
    }
    assert rec["source"]["from"] == "checkout" and rec["versions"]["straylight"] == rec["source"]["version"]
    text = json.dumps(rec)
    assert str(tmp_path) not in text and str(REPO) not in text
    assert [s for s in _strings(rec) if os.path.isabs(s)] == []
