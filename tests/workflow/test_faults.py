"""Faults while writing (issue #9): a disk that fills during a Zarr write.  The failure is one
clear error naming the store and region, finished time blocks keep their bytes, and re-running
the failed block gives a store bit-identical to an uninterrupted run."""
import errno

import pytest

from conftest import tiny_config
from straylight.config import load_campaign
from straylight.survey.cube import init_store, run_time_blocks
from straylight.errors import OutputError
from straylight.survey.footprint import footprint_from_config
from straylight.survey.provenance import sha256_path


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("faults")
    c = load_campaign(tiny_config(tmp, name="faults", campaign={"end": "2026-01-01T01:00:00",
                                                                 "time_block_hours": 0.5},
                                  footprint={"pixel_block_size": 40}))
    fp = footprint_from_config(c.config["footprint"], c.path.parent)
    ref = tmp / "reference.zarr"
    init_store(c, fp, ref)
    run_time_blocks(c, fp, ref, [0, 1], tmp / "reference_done")
    return tmp, c, fp, sha256_path(ref)


def _files(store):
    return {str(p.relative_to(store)): p.read_bytes() for p in sorted(store.rglob("*")) if p.is_file()}


@pytest.mark.parametrize("fail_after_writes", [0, 2, 5, 11])
def test_disk_full_during_a_zarr_write_then_rerun(small, tmp_path, monkeypatch, fail_after_writes):
    import straylight.survey.storage as storage

    _, c, fp, ref_digest = small
    store, done = tmp_path / "background.zarr", tmp_path / "done"
    init_store(c, fp, store)
    run_time_blocks(c, fp, store, [0], done)
    block0 = _files(store)

    # the workers' chunk files go through storage._write_file (storage.ChunkWriter)
    real_write = storage._write_file
    calls = {"n": 0}

    def full_disk_write(path, data):
        # worst case for a non-atomic file system: half the chunk reaches the disk, then ENOSPC
        calls["n"] += 1
        if calls["n"] > fail_after_writes:
            data = bytes(memoryview(data).cast("B"))
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data[: len(data) // 2])
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        return real_write(path, data)

    monkeypatch.setattr(storage, "_write_file", full_disk_write)
    with pytest.raises(OutputError) as err:
        run_time_blocks(c, fp, store, [0, 1], done)
    msg = str(err.value)
    assert str(store) in msg and "No space left on device" in msg and "re-run" in msg
    assert "times 3:6" in msg  # the failed block's region is named
    after = _files(store)
    # the finished block 0 is untouched: every file it wrote still has its bytes
    assert all(after.get(k) == v for k, v in block0.items() if "/c/0/" in k or k.endswith("zarr.json"))
    assert not (done / "block_1.json").exists()  # the failed block is not marked done
    monkeypatch.setattr(storage, "_write_file", real_write)  # space freed
    # and a chunk file a killed writer left half written (never renamed into place) in block 1
    partial = store / "total" / "c" / "1" / "0" / f"0.0123abcd{storage.PARTIAL_SUFFIX}"
    partial.parent.mkdir(parents=True, exist_ok=True)
    partial.write_bytes(b"half a chunk")
    run_time_blocks(c, fp, store, [0, 1], done)  # block 0 skipped (its sentinel), block 1 redone
    assert not partial.exists()
    assert sha256_path(store) == ref_digest


def test_job_script_reports_a_full_disk_in_one_line(tmp_path):
    """A job script's uncaught StraylightError, or OSError refusing a named file (here ENOSPC):
    one line "error: ..." on stderr and in the rule's log, exit status 2, no traceback
    (scripts/_common.setup_logging's hook); any other exception (a bug, a wrong path) keeps its
    traceback."""
    import subprocess
    import sys

    from conftest import REPO

    def job(raise_line):
        log = tmp_path / "rule.log"
        code = ("import errno, sys, types\n"
                f"sys.path.insert(0, {str(REPO / 'workflow' / 'scripts')!r})\n"
                "from _common import setup_logging\n"
                f"log = setup_logging(types.SimpleNamespace(log=[{str(log)!r}], rule='report_front'))\n"
                "log.info('started')\n"
                f"{raise_line}\n")
        r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
        return r, log.read_text()

    r, log = job("raise OSError(errno.ENOSPC, 'No space left on device', '/results/x/summary.rst.tmp')")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    errors = [ln for ln in r.stderr.splitlines() if "error:" in ln]
    assert len(errors) == 1 and "/results/x/summary.rst.tmp: No space left on device" in errors[0]
    assert errors[0].split("straylight.report_front ", 1)[1] in log
    r, _ = job("from straylight.errors import InputError; raise InputError('gaia_0.csv.gz: row 3: ra = nan')")
    assert r.returncode == 2 and "Traceback" not in r.stderr and "error: gaia_0.csv.gz: row 3: ra = nan" in r.stderr
    r, _ = job("raise ValueError('a bug')")
    assert r.returncode == 1 and "Traceback" in r.stderr and "ValueError: a bug" in r.stderr
    r, _ = job("open('/nonexistent/folder/file.png')")  # a wrong path is a bug, not the disk's refusal
    assert r.returncode == 1 and "Traceback" in r.stderr and "FileNotFoundError" in r.stderr
