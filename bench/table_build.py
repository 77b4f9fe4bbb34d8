"""The earthshine tables' cold build: CPU seconds per (node, door state), against the figures
``straylight plan`` and the build's announcement use.

Builds the default campaign's moonlit and sunlit tables into an empty cache (a temporary
folder, so the user's cache is untouched), each with ``--workers`` threads, the model set up
and its door tables made before the clocks start.  Per table: its (node, door state) pairs, the
process's CPU seconds (user + system, every thread) and wall seconds for the build with its
validation, CPU seconds per pair, and the figure assumed
(``earthshine.nodes.LUT_BUILD_SECONDS_PER_NODE``, ``MOONLIT_LUT_BUILD_SECONDS_PER_NODE``).
CPU seconds, not wall, because the machine is shared: the wall depends on the load (recorded).

Writes bench/results/table_build.json.

    python bench/table_build.py [--workers 2]
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))
from _results import write_results  # noqa: E402


def _cpu_seconds() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _loadavg() -> list[str]:
    return Path("/proc/loadavg").read_text().split()[:3]


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--workers", type=int, default=2, help="threads per build")
    a = ap.parse_args()
    os.environ["STRAYLIGHT_CACHE"] = tempfile.mkdtemp(prefix="straylight-bench-tables-")

    from straylight.config import load_campaign
    from straylight.model import BackgroundModel
    from straylight.sources.earthshine import nodes as nodes

    campaign = load_campaign()
    model = BackgroundModel(campaign, build_workers=a.workers)
    off = model.earth_grid
    nodes.mirror_symmetric(off)
    off._kernel_tables  # the model's set-up, not the build's
    moonlit, sunlit = model.source("moonlit_earth"), model.source("sunlit_earth")
    out = {
        "workers": a.workers,
        "cut_block_split": int(off.earthshine.cut_block_split),
        "grid": [int(off.earthshine.n_gamma), int(off.earthshine.n_psi)],
        "loadavg_start": _loadavg(),
        "tables": {},
    }
    runs = (
        ("moonlit", moonlit, moonlit.node_states(), nodes.MOONLIT_LUT_BUILD_SECONDS_PER_NODE),
        ("sunlit", sunlit, sunlit.choice["node_states"], nodes.LUT_BUILD_SECONDS_PER_NODE),
    )
    for name, source, node_states, assumed in runs:
        cpu0, wall0 = _cpu_seconds(), time.perf_counter()
        source.model  # builds the table (with its validation) into the empty cache
        cpu, wall = _cpu_seconds() - cpu0, time.perf_counter() - wall0
        out["tables"][name] = {
            "node_states": int(node_states),
            "cpu_seconds": cpu,
            "wall_seconds": wall,
            "cpu_seconds_per_node_state": cpu / node_states,
            "assumed_seconds_per_node_state": assumed,
            "loadavg_end": _loadavg(),
        }
        print(name, out["tables"][name], flush=True)
    write_results("table_build", out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
