"""Benchmark of what users wait for: a campaign end to end, `snakemake` to the last product.

Runs `snakemake --cores N` in a temporary directory on config/config.yaml with the campaign's
length, nside and cadence changed, and writes to bench/results/pipeline.json:

* samples/s/core wall to wall: (time, pixel) samples / wall seconds of the whole run / cores,
  the campaign's earthshine tables built (and cached) before the run and timed on their own;
* each rule's seconds and share of the wall time (from Snakemake's job start and finish lines,
  1 s resolution; jobs run side by side, so the shares can add up to more than 1);
* CPU seconds (user + system) of every process of the run, and samples per CPU second: on a
  machine shared with other jobs the wall time grows with their load, the CPU time much less;
* peak memory: the largest sum of the resident set sizes of Snakemake and all its descendant
  processes, polled every 0.2 s (pages shared between processes are counted once per process);
* bytes per sample of the products on disk (background.zarr, limits.zarr, observability.zarr);
* the kernel's figure in the same run (bench/run.py's production_region_rates: the cube's
  compute alone on the default day's time blocks, one core), labelled as the kernel.

straylight.planning.plan's PIPELINE_* figures are fitted to such runs.  Run:
    python bench/pipeline.py --days 30 --nside 32            # a month at nside 32
    python bench/pipeline.py --days 3 --nside 32 --cold      # as on a fresh machine (empty table cache)
    python bench/pipeline.py --days 0.25 --nside 4 --no-kernel   # a smoke run, seconds
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from datetime import datetime, timedelta
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import write_results  # noqa: E402

#: the products counted in bytes per sample (the archive's product set)
PRODUCTS = ("background.zarr", "limits.zarr", "observability.zarr")


def campaign_config(
    days: float,
    nside: int,
    cadence_s: float,
    name: str = "bench",
    base: Path = REPO / "config" / "config.yaml",
) -> dict:
    """The ``base`` config (config/config.yaml) with the campaign's length (days from its start),
    cadence and nside changed, the instrument path made absolute."""
    import yaml

    base = Path(base).resolve()
    cfg = yaml.safe_load(base.read_text())
    start = datetime.fromisoformat(cfg["campaign"]["start"])
    cfg["campaign"].update(
        name=name, cadence_s=cadence_s, end=(start + timedelta(days=days)).isoformat(timespec="seconds")
    )
    cfg["footprint"]["nside"] = int(nside)
    cfg["instrument"] = str((base.parent / cfg["instrument"]).resolve())
    return cfg


class TreeMemory:
    """Peak of the summed resident set size of a process and its descendants (psutil polling)."""

    def __init__(self, pid: int, interval_s: float = 0.2):
        import psutil

        self.root = psutil.Process(pid)
        self.interval_s = interval_s
        self.peak_bytes = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._poll, daemon=True)
        self._thread.start()

    def _poll(self):
        import psutil

        while not self._stop.is_set():
            try:
                procs = [self.root] + self.root.children(recursive=True)
            except psutil.Error:
                break
            total = 0
            for p in procs:
                try:
                    total += p.memory_info().rss
                except psutil.Error:
                    pass
            self.peak_bytes = max(self.peak_bytes, total)
            self._stop.wait(self.interval_s)

    def stop(self) -> int:
        self._stop.set()
        self._thread.join()
        return self.peak_bytes


_STAMP = re.compile(r"^\[(\w{3} \w{3} +\d+ \d\d:\d\d:\d\d \d{4})\]$")


def job_spans(snakemake_log: str) -> list[tuple[str, datetime, datetime]]:
    """(rule, start, finish) of every job in Snakemake's log: from the time stamp before its
    ``rule <name>:`` block to the one before its ``Finished jobid: <id>`` line (1 s resolution)."""
    stamp, pending_rule, started, rule_of = None, None, {}, {}
    spans = []
    for line in snakemake_log.splitlines():
        line = line.strip()
        m = _STAMP.match(line)
        if m:
            stamp = datetime.strptime(m.group(1), "%a %b %d %H:%M:%S %Y")
            continue
        m = re.match(r"^(?:local)?rule (\w+):$", line)
        if m:
            pending_rule = (m.group(1), stamp)
            continue
        m = re.match(r"^jobid: (\d+)$", line)
        if m and pending_rule is not None:
            rule_of[m.group(1)], started[m.group(1)] = pending_rule
            pending_rule = None
            continue
        m = re.match(r"^Finished jobid: (\d+)", line)
        if m and m.group(1) in started and stamp is not None:
            spans.append((rule_of[m.group(1)], started[m.group(1)], stamp))
    return spans


def rule_seconds(snakemake_log: str) -> dict:
    """Seconds per rule from Snakemake's log (:func:`job_spans`), summed over the rule's jobs."""
    out: dict = {}
    for name, start, finish in job_spans(snakemake_log):
        rec = out.setdefault(name, {"jobs": 0, "seconds": 0.0})
        rec["jobs"] += 1
        rec["seconds"] += (finish - start).total_seconds()
    return out


def timeline(snakemake_log: str, started: datetime) -> list[dict]:
    """Every job's rule, start and finish in seconds after ``started`` (the command's start,
    local time as Snakemake stamps it), in order of start: where the wall time went."""
    return [
        {
            "rule": name,
            "start_s": round((a - started).total_seconds(), 1),
            "finish_s": round((b - started).total_seconds(), 1),
        }
        for name, a, b in sorted(job_spans(snakemake_log), key=lambda j: (j[1], j[0]))
    ]


def directory_bytes(path: Path) -> int:
    return sum(p.stat().st_size for p in Path(path).rglob("*") if p.is_file()) if Path(path).exists() else 0


def build_tables(cfg_path: Path, workers: int) -> float:
    """Build the campaign's earthshine tables if they are not cached yet (``workers``
    processes), before the timed run: the run then starts as every run after a machine's first
    does, and the build (once per machine and model settings) is reported on its own.
    Seconds taken (~0 when cached)."""
    from straylight.config import load_campaign
    from straylight.model import BackgroundModel

    t0 = time.perf_counter()
    c = load_campaign(cfg_path)
    model = BackgroundModel(c, build_workers=workers)
    # the record the cube's skeleton stores names both tables: building it loads (or builds) the
    # sunlit table and, on the table's path, the moonlit one, which is built lazily otherwise
    model.models_record()
    return time.perf_counter() - t0


def run_campaign(
    days: float,
    nside: int,
    cadence_s: float,
    cores: int,
    keep: Path | None = None,
    base: Path = REPO / "config" / "config.yaml",
    cold: bool = False,
) -> dict:
    """Run the campaign end to end in a temporary directory; the figures above (no kernel).
    ``cold``: as on a fresh machine, with an empty table cache (STRAYLIGHT_CACHE): the earthshine
    tables, the star catalog and the faint-star map are built inside the timed run."""
    import yaml

    tmp = Path(tempfile.mkdtemp(prefix="straylight-pipeline-bench-"))
    env = dict(os.environ)
    try:
        cfg = campaign_config(days, nside, cadence_s, base=base)
        cfg_path = tmp / "bench.yaml"
        cfg_path.write_text(yaml.safe_dump(cfg))
        if cold:
            env["STRAYLIGHT_CACHE"] = str(tmp / "empty-cache")
            table_s = 0.0
        else:
            table_s = build_tables(cfg_path, cores)
        snakemake = str(Path(sys.executable).with_name("snakemake"))
        cmd = [
            snakemake,
            "-s",
            str(REPO / "workflow" / "Snakefile"),
            "-d",
            str(tmp),
            "--configfile",
            str(cfg_path),
            "--cores",
            str(cores),
        ]
        load_before = os.getloadavg()
        cpu_before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        started = datetime.now().replace(microsecond=0)
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
        mem = TreeMemory(proc.pid)
        log, _ = proc.communicate()
        wall = time.perf_counter() - t0
        peak = mem.stop()
        # user + system seconds of Snakemake and every process it (and they) waited for: a
        # figure the machine's other load moves much less than the wall time
        cpu_after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (cpu_after.ru_utime - cpu_before.ru_utime) + (cpu_after.ru_stime - cpu_before.ru_stime)
        if proc.returncode != 0:
            sys.stderr.write(log[-5000:])
            raise SystemExit(f"bench/pipeline.py: snakemake failed (exit {proc.returncode})")
        out = tmp / "results" / "bench"
        init = json.loads((out / "work" / "background_blocks" / "init.json").read_text())
        samples = int(init["times"]) * int(init["pixels"])
        products = {p: directory_bytes(out / p) for p in PRODUCTS}
        rules = rule_seconds(log)
        for rec in rules.values():
            rec["share_of_wall"] = rec["seconds"] / wall
        result = {
            "campaign": {
                "base_config": str(base),
                "days": days,
                "nside": nside,
                "cadence_s": cadence_s,
                "times": int(init["times"]),
                "pixels": int(init["pixels"]),
                "bands": len(init["bands"]),
                "samples": samples,
                "chunks": init["chunks"],
            },
            "cores": cores,
            "cold_cache": cold,
            "table_build_seconds_before_run": table_s,
            "wall_seconds": wall,
            "samples_per_s_per_core": samples / wall / cores,
            "cpu_seconds": cpu,
            "samples_per_cpu_second": samples / cpu,
            "rules": dict(sorted(rules.items(), key=lambda kv: -kv[1]["seconds"])),
            "timeline": timeline(log, started),
            "peak_memory_bytes": peak,
            "products_bytes": products,
            "bytes_per_sample": sum(products.values()) / samples,
            "load_average_1min_before_after": [load_before[0], os.getloadavg()[0]],
        }
        if keep is not None:
            shutil.copytree(out, keep, dirs_exist_ok=True)
            (Path(keep) / "snakemake.log").write_text(log)
        return result
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def kernel_figure() -> dict:
    """The kernel's production figure, as bench/run.py --only cube measures it: the cube's
    compute alone over the default campaign's time blocks on the table path, one core."""
    from knobs.common import Bench
    from knobs.cube import production_region_rates

    from straylight.catalog.campaign_catalog import write_catalog
    from straylight.config import load_campaign
    from straylight.cube.footprint import footprint_from_config

    base = load_campaign()
    fp = footprint_from_config(base.settings.footprint)
    with tempfile.TemporaryDirectory() as tmp:
        stars_path = Path(tmp) / "stars.parquet"
        write_catalog(Bench(1).catalog, stars_path, {})
        rates = production_region_rates(base, fp, stars_path)
    return {
        "samples_per_s_per_core": rates["campaign"]["lut"]["samples_per_s_per_core"],
        "what": "bench/run.py production_region_rates: the default day's time blocks on the table path, "
        "compute only, one core",
    }


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--days", type=float, default=30.0, help="campaign length, days (default 30)")
    ap.add_argument("--nside", type=int, default=32, help="HEALPix nside (default 32)")
    ap.add_argument("--cadence-s", type=float, default=300.0, help="cadence, seconds (default 300)")
    ap.add_argument("--cores", type=int, default=2, help="snakemake --cores (default 2)")
    ap.add_argument(
        "--base",
        type=Path,
        default=REPO / "config" / "config.yaml",
        help="the config the campaign is derived from (default config/config.yaml)",
    )
    ap.add_argument("--no-kernel", action="store_true", help="skip the kernel figure (a smoke run)")
    ap.add_argument(
        "--cold",
        action="store_true",
        help="an empty table cache, as on a fresh machine: the tables' build is inside the wall time",
    )
    ap.add_argument("--keep", type=Path, default=None, help="copy the campaign's results here")
    ap.add_argument(
        "--out", type=Path, default=None, help="results file (default bench/results/pipeline.json)"
    )
    args = ap.parse_args(argv)
    result = run_campaign(args.days, args.nside, args.cadence_s, args.cores, args.keep, args.base, args.cold)
    result["kernel"] = None if args.no_kernel else kernel_figure()
    c = result["campaign"]
    print(
        f"pipeline, wall to wall: {c['samples']:,} samples ({args.days:g} days, nside {args.nside}, "
        f"{args.cadence_s:g} s) in {result['wall_seconds']:.1f} s on {args.cores} cores = "
        f"{result['samples_per_s_per_core']:,.0f} samples/s/core"
    )
    print(
        f"CPU (user + system, every process of the run): {result['cpu_seconds']:.0f} s = "
        f"{result['samples_per_cpu_second']:,.0f} samples per CPU second"
    )
    if args.cold:
        print(
            "empty table cache: the earthshine tables, the catalog and the faint-star map built in the "
            "wall time"
        )
    else:
        print(
            f"earthshine tables built before the run (not in the wall time): "
            f"{result['table_build_seconds_before_run']:.0f} s"
        )
    if result["kernel"]:
        print(
            "kernel (cube compute alone, one core): "
            f"{result['kernel']['samples_per_s_per_core']:,.0f} samples/s/core"
        )
    print(
        f"peak memory {result['peak_memory_bytes'] / 2**30:.2f} GiB; products "
        f"{sum(result['products_bytes'].values()) / 1e9:.3f} GB = "
        f"{result['bytes_per_sample']:.1f} bytes/sample"
    )
    for name, rec in result["rules"].items():
        print(
            f"  {name:<18} {rec['jobs']:3d} job(s) {rec['seconds']:8.0f} s  "
            f"{100 * rec['share_of_wall']:5.1f} % of wall"
        )
    print("timeline (s after the command):")
    for job in result["timeline"]:
        print(f"  {job['start_s']:6.0f} {job['finish_s']:6.0f}  {job['rule']}")
    if args.out is None:
        write_results("pipeline", result)
    else:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main()
