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
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from conftest import REPO, tiny_config

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
        r = subprocess.run(
            ["bash", str(SLURM_LOCAL), "start", str(state)], capture_output=True, text=True, timeout=900
        )
        if r.returncode == 3:  # the script's status for "cannot install or start SLURM here"
            reason = "SLURM unavailable: " + (r.stderr.strip().splitlines() or ["no reason given"])[-1]
            print(reason)
            pytest.skip(reason)
        assert r.returncode == 0, r.stdout + r.stderr
        exported = dict(line.split("=", 1) for line in r.stdout.split() if "=" in line)
        yield {
            **os.environ,
            "SLURM_CONF": exported["SLURM_CONF"],
            "PATH": f"{BIN}:/usr/sbin:{os.environ['PATH']}",
            "SLURM_LOCAL_PARTITION": exported["SLURM_LOCAL_PARTITION"],
        }
    finally:
        subprocess.run(["bash", str(SLURM_LOCAL), "stop", str(state)], capture_output=True, timeout=120)


def _campaign(tmp):
    """The kill-and-resume test's campaign: 1 h at 10-min cadence in two time blocks, nside 4."""
    return tiny_config(
        tmp,
        name=CAMPAIGN,
        campaign={"end": "2026-01-01T01:00:00", "time_block_hours": 0.5},
        footprint={"pixel_block_size": 40},
        compute={"dask_scheduler": None},
    )


def _site_env(env):
    """The profile's site settings for this one 2-CPU node (as a site sets them): the local
    partition, no account, 2 cores per background job, as many as the local run gives them (the
    products do not depend on it: each region, and each pixel's faint-star sum, is computed on
    its own, in a fixed order)."""
    return {
        **env,
        "STRAYLIGHT_SLURM_PARTITION": env["SLURM_LOCAL_PARTITION"],
        "STRAYLIGHT_SLURM_ACCOUNT": "",
        "STRAYLIGHT_SLURM_CPUS": "2",
    }


# no slurmdbd on the local cluster, so no sacct: job states come from squeue (finished jobs stay
# there 10 min).  The executor polls after 1 s, then 10 s longer each time no job has finished, so
# every level of the DAG costs a poll interval: the steps before and after the cube's time blocks
# are grouped into one SLURM job each (rules this workflow lacks are ignored by --groups).
LOCAL_CLUSTER_ARGS = (
    "--slurm-status-command",
    "squeue",
    "--slurm-init-seconds-before-status-checks",
    "1",
    "--latency-wait",
    "5",
    "--jobs",
    "3",
    "--groups",
    "footprint=prepare",
    "stars_catalog=prepare",
    "background_init=prepare",
    "background=finish",
    "limits=finish",
    "sky_compact=finish",
    "provenance=finish",
)


def _command(workdir, cfg, *args):
    # the target first: options taking several values (--groups, --configfile) would swallow it
    return [
        SNAKEMAKE,
        TARGET,
        "-s",
        str(REPO / "workflow" / "Snakefile"),
        "-d",
        str(workdir),
        "--configfile",
        str(cfg),
        *args,
    ]


def test_profile_takes_site_settings_from_the_environment(monkeypatch):
    """The profile as Snakemake reads it: its documented defaults, and a site's partition, account
    (empty: none) and cores from the environment, the cube jobs' memory following the cores."""
    from snakemake.profiles import ProfileConfigFileParser

    def read():
        with open(PROFILE / "config.yaml") as f:
            return ProfileConfigFileParser().parse(f)

    for var in ("STRAYLIGHT_SLURM_PARTITION", "STRAYLIGHT_SLURM_ACCOUNT", "STRAYLIGHT_SLURM_CPUS"):
        monkeypatch.delenv(var, raising=False)
    default = read()
    assert default["executor"] == "slurm"
    assert {"slurm_partition=normal", "slurm_account=csst"} <= set(default["default-resources"])
    assert "background_blocks=16" in default["set-threads"]
    assert "background_blocks:mem_mb=32000" in default["set-resources"]
    monkeypatch.setenv("STRAYLIGHT_SLURM_PARTITION", "debug")
    monkeypatch.setenv("STRAYLIGHT_SLURM_ACCOUNT", "")
    monkeypatch.setenv("STRAYLIGHT_SLURM_CPUS", "2")
    site = read()
    assert "slurm_partition=debug" in site["default-resources"]
    assert not any(r.startswith("slurm_account") for r in site["default-resources"])
    assert "background_blocks=2" in site["set-threads"]
    assert {"background_blocks:cpus_per_task=2", "background_blocks:mem_mb=4000"} <= set(
        site["set-resources"]
    )


@pytest.mark.slow
def test_campaign_on_slurm_equals_local_run(tmp_path, slurm_cluster):
    env = slurm_cluster
    local, cluster = tmp_path / "local", tmp_path / "cluster"
    local.mkdir()
    cluster.mkdir()
    # the local run beside the cluster's: the cluster's jobs spend most of their time waiting
    start = time.perf_counter()
    with open(tmp_path / "local.log", "w") as local_log:
        local_run = subprocess.Popen(
            _command(local, _campaign(local), "--cores", "2"),
            cwd=REPO,
            stdout=local_log,
            stderr=subprocess.STDOUT,
            env={**os.environ, "PATH": f"{BIN}:{os.environ['PATH']}"},
        )
        try:
            r = subprocess.run(
                _command(cluster, _campaign(cluster), "--profile", str(PROFILE), *LOCAL_CLUSTER_ARGS),
                cwd=REPO,
                capture_output=True,
                text=True,
                timeout=900,
                env=_site_env(env),
            )
            print(f"SLURM run: {time.perf_counter() - start:.0f} s wall")
            local_run.wait(timeout=900)
        finally:
            if local_run.poll() is None:
                local_run.kill()
                local_run.wait()
    assert local_run.returncode == 0, (tmp_path / "local.log").read_text()[-3000:]
    log = r.stdout[-4000:] + r.stderr[-4000:]
    assert r.returncode == 0, log
    # the jobs really went through SLURM (this cluster has run nothing else): all completed
    states = subprocess.run(
        ["squeue", "--states=all", "--noheader", "--format=%T"],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
    ).stdout.split()
    assert len(states) >= 3 and set(states) == {"COMPLETED"}, states

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
