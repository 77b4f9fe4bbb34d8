"""One build of a look-up table at a time (straylight.sources.earthshine.nodes._cached): two
processes of one machine needing the same table at once, as two campaigns started together on
a fresh machine or the two workers of a test run, build it once; the other waits and reads it."""

import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from straylight.errors import InputError
from straylight.sources.earthshine.nodes import _cached


class _Table:
    def save(self, path):
        Path(path).write_text("the table")


def test_two_callers_at_once_build_the_table_once(tmp_path, monkeypatch):
    """flock locks belong to the open file, so two threads contend as two processes do."""
    monkeypatch.setenv("STRAYLIGHT_CACHE", str(tmp_path))
    builds = []

    def build():
        builds.append(1)
        time.sleep(1.0)  # the other caller arrives while this build runs
        return _Table()

    def need(_):
        return _cached("test_lut", "0123456789abcdef", "test", lambda p: Path(p).read_text(), build, None)

    with ThreadPoolExecutor(2) as pool:
        results = list(pool.map(need, range(2)))
    assert len(builds) == 1
    assert sorted(type(table).__name__ for table, _ in results) == ["_Table", "str"]
    assert results[0][1] == results[1][1] == tmp_path / "test_lut_0123456789abcdef.npz"


def test_a_cache_that_cannot_take_the_table_fails_before_the_build(monkeypatch):
    """A folder that cannot be made (under /proc, even for root): one line before the build."""
    monkeypatch.setenv("STRAYLIGHT_CACHE", "/proc/1/straylight")

    def build():
        raise AssertionError("the build started")

    with pytest.raises(
        InputError, match=r"STRAYLIGHT_CACHE = /proc/1/straylight: cannot write the test table there"
    ):
        _cached("test_lut", "0123456789abcdef", "test", lambda p: None, build, None)
