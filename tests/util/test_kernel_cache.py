"""The compiled kernels' cache (straylight.util.kernel_cache): kept in the table cache under the
module's path in the package, and read by another install of the same code (a copy of the
package elsewhere, as a new venv or wheel gives).

Reference values: numba's own counters (a dispatcher's ``stats.cache_hits`` and
``cache_misses``) and the cache's files."""

import os
import shutil
import subprocess
import sys

from conftest import REPO

#: the child: bitround's kernel run once; its cache hits and misses and the module's file
_RUN = (
    "import numpy as np, straylight.storage.bitround as b; "
    "b.bitround(np.linspace(1, 2, 5), 10); s = b._bitround_bits.stats; "
    "print(sum(s.cache_hits.values()), sum(s.cache_misses.values()), b.__file__)"
)


def _run(pythonpath, cache, **env):
    base = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env = {**base, "STRAYLIGHT_CACHE": str(cache), "PYTHONPATH": str(pythonpath), **env}
    r = subprocess.run(
        [sys.executable, "-c", _RUN], capture_output=True, text=True, env=env, timeout=300, cwd=cache.parent
    )
    assert r.returncode == 0, r.stderr
    hits, misses, path = r.stdout.split()
    return int(hits), int(misses), path


def test_a_second_install_reads_the_kernels_the_first_compiled(tmp_path):
    """A first process compiles bitround's kernel into <cache>/numba/straylight/storage (a miss);
    a copy of the package at another path (fresh files, another folder: numba's own cache, keyed
    by the folder, would miss) reads it (a hit, no miss).  With NUMBA_CACHE_DIR set, numba's
    locator is used and the table cache gets no kernel."""
    cache = tmp_path / "cache"
    first = _run(REPO, cache)
    assert first[:2] == (0, 1) and first[2].startswith(str(REPO))
    files = list((cache / "numba" / "straylight" / "storage").glob("bitround._bitround_bits-*.nbi"))
    assert len(files) == 1
    copy = tmp_path / "install2"
    shutil.copytree(REPO / "straylight", copy / "straylight", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(REPO / "config", copy / "config")
    second = _run(copy, cache)
    assert second[:2] == (1, 0) and second[2].startswith(str(copy))
    other = tmp_path / "other"
    third = _run(copy, other, NUMBA_CACHE_DIR=str(tmp_path / "numba_own"))
    assert third[:2] == (0, 1) and not (other / "numba").exists()
    assert list((tmp_path / "numba_own").rglob("*.nbi"))
