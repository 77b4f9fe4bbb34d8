"""A campaign through a real SLURM cluster gives the same products as a local run.

scripts/dev/slurm_local.sh starts a single-node SLURM on localhost (Debian's slurmctld, slurmd and
munged, installed with apt-get when missing); the campaign then runs through
`snakemake --executor slurm` (snakemake-executor-plugin-slurm) with workflow/profiles/slurm, and its
products' checksums must equal those of `snakemake --cores 2` on the same config.  Skipped, with
the reason printed, only where SLURM cannot be installed or started on the machine.
"""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml

from conftest import REPO, tiny_config

pytestmark = pytest.mark.slow

SNAKEMAKE = str(Path(sys.executable).with_name("snakemake"))
BIN = Path(sys.executable).parent
SLURM_LOCAL = REPO / "scripts" / "dev" / "slurm_local.sh"
PROFILE = REPO / "workflow" / "profiles" / "slurm"
CAMPAIGN = "slurm"
# the products whose checksums provenance.json records (figures and scheduling tables are not built)
TARGET = f"results/{CAMPAIGN}/provenance.json"


@pytest.fixture(scope="module")
def slurm_cluster(tmp_path_factory):
    """A running single-node SLURM; yields the environment its clients need, stops it afterwards."""
    state = tmp_path_factory.mktemp("slurm-cluster")
    try:
        r = subprocess.run(["bash", str(SLURM_LOCAL), "start", str(state)], capture_output=True, text=True,
                           timeout=900)
        if r.returncode == 3:  # the script's status for "cannot install or start SLURM here"
            reason = "SLURM unavailable: " + (r.stderr.strip().splitlines() or ["no reason given"])[-1]
            print(reason)
            pytest.skip(reason)
        assert r.returncode == 0, r.stdout + r.stderr
        exported = dict(line.split("=", 1) for line in r.stdout.split() if "=" in line)
        yield {**os.environ, "SLURM_CONF": exported["SLURM_CONF"], "PATH": f"{BIN}:/usr/sbin:{os.environ['PATH']}",
               "SLURM_LOCAL_PARTITION": exported["SLURM_LOCAL_PARTITION"]}
    finally:
        subprocess.run(["bash", str(SLURM_LOCAL), "stop", str(state)], capture_output=True, timeout=120)


def _campaign(tmp):
    """The kill-and-resume test's campaign: 1 h at 10-min cadence in two time blocks, nside 4."""
    return tiny_config(tmp, name=CAMPAIGN, campaign={"end": "2026-01-01T01:00:00", "time_block_hours": 0.5},
                       footprint={"pixel_block_size": 40}, compute={"dask_scheduler": None})


def _site_overrides(partition):
    """Command-line settings that fit the profile to this one 2-CPU node, as a site would edit it:
    the local partition, no account, and every rule the profile sizes for big nodes cut to 2 CPUs and
    2 GB (the rules are read from the profile, so none is named here)."""
    profile = yaml.safe_load((PROFILE / "config.yaml").read_text())
    rules = set(profile.get("set-threads", {})) | set(profile.get("set-resources", {}))
    defaults = {**profile["default-resources"], "slurm_partition": partition, "mem_mb": 2000, "cpus_per_task": 1,
                "runtime": 30}
    defaults.pop("slurm_account", None)
    resources = [f"{rule}:{key}={value}" for rule in sorted(rules)
                 for key, value in {**profile.get("set-resources", {}).get(rule, {}),
                                    "cpus_per_task": 2, "mem_mb": 2000, "runtime": 30}.items()]
    return ["--default-resources", *(f"{k}={v}" for k, v in defaults.items()),
            "--set-threads", *(f"{rule}=2" for rule in sorted(rules)),
            "--set-resources", *resources,
            "--slurm-no-account",
            # no slurmdbd here: job states come from squeue (the cluster keeps finished jobs 10 min)
            "--slurm-status-command", "squeue",
            "--slurm-init-seconds-before-status-checks", "2",
            "--latency-wait", "5"]


def _snakemake(workdir, cfg, *args, env=None, timeout=900):
    return subprocess.run([SNAKEMAKE, "-s", str(REPO / "Snakefile"), "-d", str(workdir), "--configfile", str(cfg),
                           *args, TARGET], cwd=REPO, capture_output=True, text=True, timeout=timeout,
                          env=env or {**os.environ, "PATH": f"{BIN}:{os.environ['PATH']}"})


def test_campaign_on_slurm_equals_local_run(tmp_path, slurm_cluster):
    env = slurm_cluster
    local, cluster = tmp_path / "local", tmp_path / "cluster"
    local.mkdir()
    cluster.mkdir()
    r = _snakemake(local, _campaign(local), "--cores", "2")
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]

    r = _snakemake(cluster, _campaign(cluster), "--profile", str(PROFILE), "--jobs", "2",
                   *_site_overrides(env["SLURM_LOCAL_PARTITION"]), env=env)
    log = r.stdout[-4000:] + r.stderr[-4000:]
    assert r.returncode == 0, log
    # the jobs really went through SLURM: sbatch logs, and the cluster saw them all complete
    assert list((cluster / ".snakemake" / "slurm_logs").rglob("*.log")), log
    states = subprocess.run(["squeue", "--states=all", "--noheader", "--format=%T"], capture_output=True,
                            text=True, env=env, timeout=60).stdout.split()
    assert states and set(states) == {"COMPLETED"}, states

    # the products' checksums (provenance.json) and their arrays, exactly
    ref = json.loads((local / TARGET).read_text())
    got = json.loads((cluster / TARGET).read_text())
    assert got["outputs_sha256"] == ref["outputs_sha256"]
    assert got["outputs_digest_sha256"] == ref["outputs_digest_sha256"]
    for store in ("background.zarr", "limits.zarr"):
        a = xr.open_zarr(local / "results" / CAMPAIGN / store)
        b = xr.open_zarr(cluster / "results" / CAMPAIGN / store)
        assert set(a.data_vars) == set(b.data_vars) and a.data_vars
        for v in a.data_vars:
            np.testing.assert_array_equal(b[v].values, a[v].values, err_msg=f"{store}:{v}")
