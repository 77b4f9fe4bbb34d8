"""Benchmark of ``straylight visibility --targets``: a year at hourly steps for many targets.

A day of two targets runs first, untimed (the earthshine tables built if not cached, the
compiled kernels' cache filled).  For each size (default 100 and 10
targets) a target list is written (packaged fields by name,
the rest uniform on the sky from a fixed seed) and the command is run as a user runs it, in a
fresh process, with ``--out`` (summary and every target's windows and days written).  Reported
per size:

* the command's wall seconds, from start to exit (interpreter start, imports, model, scenes,
  evaluation, tables and files), and the CPU seconds of the process;
* the kernel: samples per CPU-second of the background evaluation alone (the scenes and the
  background at every sample, as the command reports it in the same run), i.e. samples/s/core.

Prints the figures (with the machine's load average) and writes bench/results/targets.json.
Run:  python bench/targets.py [--sizes 100 10] [--days 365] [--step-min 60]
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import write_results  # noqa: E402

NAMES = ("COSMOS", "HDF-N", "GOODS-S", "HUDF", "SXDS", "EGS", "Stripe 82", "M31", "M101", "LMC")


def target_csv(path: Path, n: int, seed: int = 1) -> None:
    """A list of ``n`` targets: the packaged fields by name first, then random sky positions."""
    rng = np.random.default_rng(seed)
    lines = ["name,ra,dec"]
    for i in range(n):
        if i < len(NAMES):
            lines.append(f"{NAMES[i]},,")
        else:
            ra, dec = rng.uniform(0.0, 360.0), np.degrees(np.arcsin(rng.uniform(-1.0, 1.0)))
            lines.append(f"T{i:03d},{ra:.5f},{dec:.5f}")
    path.write_text("\n".join(lines) + "\n")


def run(n: int, days: float, step_min: float, workdir: Path) -> dict:
    """Run the command once for ``n`` targets; its wall and CPU seconds and its kernel figure."""
    csv = workdir / f"targets_{n}.csv"
    out = workdir / f"out_{n}"
    target_csv(csv, n)
    end = np.datetime64("2026-01-01T00:00:00") + np.timedelta64(int(round(days * 86400)), "s")
    cmd = [
        sys.executable,
        "-m",
        "straylight.cli",
        "visibility",
        "--targets",
        str(csv),
        "--band",
        "g",
        "--start",
        "2026-01-01T00:00:00",
        "--end",
        str(end),
        "--step-min",
        str(step_min),
        "--threshold",
        "26.5",
        "--out",
        str(out),
    ]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    load = os.getloadavg()
    w0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - w0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"command failed ({proc.returncode}): {proc.stderr.strip()}")
    first = proc.stdout.splitlines()[0]
    m = re.search(
        r"([\d,]+) samples in .*?evaluation ([\d.]+) s wall, ([\d.]+) CPU-s: ([\d,]+) samples/s/core", first
    )
    if m is None:
        raise SystemExit(f"cannot read the command's timing line: {first}")
    samples = int(m.group(1).replace(",", ""))
    files = len(list(out.iterdir()))
    return {
        "targets": n,
        "samples": samples,
        "command_wall_s": wall,
        "command_cpu_s": (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime),
        "evaluation_wall_s": float(m.group(2)),
        "evaluation_cpu_s": float(m.group(3)),
        "kernel_samples_per_s_per_core": float(m.group(4).replace(",", "")),
        "files_written": files,
        "loadavg_before": list(load),
        "loadavg_after": list(os.getloadavg()),
        "first_line": first,
    }


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 10], help="target counts (default 100 10)")
    ap.add_argument("--days", type=float, default=365.0, help="span from 2026-01-01, days (default 365)")
    ap.add_argument("--step-min", type=float, default=60.0, help="step, minutes (default 60)")
    args = ap.parse_args(argv)
    results = {"days": args.days, "step_min": args.step_min, "band": "g", "cpus": os.cpu_count(), "runs": []}
    with tempfile.TemporaryDirectory() as tmp:
        # a day of 2 targets first, untimed: the earthshine tables built if not cached and the
        # compiled kernels' on-disk cache filled (a source edited since recompiles them)
        w0 = time.perf_counter()
        run(2, 1.0, args.step_min, Path(tmp))
        results["warm_up_s"] = time.perf_counter() - w0
        for n in args.sizes:
            r = run(n, args.days, args.step_min, Path(tmp))
            results["runs"].append(r)
            print(
                f"{n:4d} targets, {r['samples']:,} samples: command {r['command_wall_s']:.1f} s wall, "
                f"{r['command_cpu_s']:.1f} CPU-s; evaluation {r['evaluation_wall_s']:.1f} s wall, "
                f"{r['evaluation_cpu_s']:.1f} CPU-s = {r['kernel_samples_per_s_per_core']:,.0f} "
                f"samples/s/core; {r['files_written']} files; "
                f"load {r['loadavg_before'][0]:.2f} -> {r['loadavg_after'][0]:.2f}"
            )
    write_results("targets", results)
    return results


if __name__ == "__main__":
    main()
