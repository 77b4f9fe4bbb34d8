#!/usr/bin/env bash
# A real single-node SLURM on localhost, for testing the SLURM profile (tests/workflow/test_slurm.py).
#
#   scripts/dev/slurm_local.sh start [DIR]   install slurm-wlm and munge if missing (apt-get, as root),
#                                            write DIR/slurm.conf, start munged, slurmctld and slurmd,
#                                            wait until the node is idle; print the lines to export
#                                            (SLURM_CONF, the partition's name)
#   scripts/dev/slurm_local.sh stop [DIR]    stop the three daemons started from DIR
#   scripts/dev/slurm_local.sh status [DIR]  sinfo of the cluster in DIR
#
# DIR (default /tmp/straylight-slurm) holds everything: munge key and socket, slurm.conf, state,
# spool, logs and pid files.  Free TCP ports are chosen at start.  The clients (sinfo, sbatch,
# squeue) find this cluster through SLURM_CONF; inside a job, Snakemake's SLURM job step removes
# every SLURM_* variable before its `srun`, so srun finds the configuration where a configless
# slurmd would cache it, /run/slurm/conf (a link to DIR, removed at stop).  Refused (status 3)
# where the machine has its own SLURM configuration in /etc/slurm or /run/slurm.
#
# Made to run as root inside a container or VM: processes are tracked through /proc
# (proctrack/linuxproc) and tasks are not confined (task/none), so no cgroup is needed; memory is
# not a consumable resource (CR_Core), so nothing measures or enforces it.  The node offers
# CPUS (default 2) cores and the machine's memory as reported by `slurmd -C`.
# Exit status: 0 on success, 3 when SLURM or munge cannot be installed or started (the reason is
# the last line on stderr).
set -euo pipefail

cmd="${1:-}"
DIR="$(realpath -m "${2:-${SLURM_LOCAL_DIR:-/tmp/straylight-slurm}}")"
CPUS="${SLURM_LOCAL_CPUS:-2}"
PARTITION="${SLURM_LOCAL_PARTITION:-debug}"
START_TIMEOUT_S="${SLURM_LOCAL_TIMEOUT_S:-60}"
export PATH="$PATH:/usr/sbin:/sbin"  # the daemons live in sbin, outside a plain user's PATH

fail() { echo "slurm_local: $*" >&2; exit 3; }

install_if_needed() {
    local missing=()
    for exe in slurmctld slurmd munged sinfo sbatch squeue srun; do
        command -v "$exe" >/dev/null 2>&1 || missing+=("$exe")
    done
    [ "${#missing[@]}" -eq 0 ] && return 0
    [ "$(id -u)" -eq 0 ] || fail "not installed (${missing[*]}) and not root, cannot apt-get install slurm-wlm munge"
    command -v apt-get >/dev/null 2>&1 || fail "not installed (${missing[*]}) and no apt-get on this machine"
    echo "slurm_local: installing slurm-wlm and munge with apt-get" >&2
    timeout 900 bash -c 'apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq slurm-wlm munge' \
        >"$DIR/apt.log" 2>&1 || fail "apt-get install slurm-wlm munge failed (see $DIR/apt.log)"
}

free_port() {
    python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

pid_alive() { [ -s "$1" ] && kill -0 "$(cat "$1")" 2>/dev/null; }

stop() {
    # jobs still running (a run interrupted or failed) are cancelled while the controller is up
    if pid_alive "$DIR/run/slurmctld.pid"; then
        export SLURM_CONF="$DIR/slurm.conf"
        scancel --quiet --user "$(id -un)" 2>/dev/null || true
        for _ in $(seq 1 100); do
            [ -z "$(squeue -h -t PENDING,RUNNING,COMPLETING -o %i 2>/dev/null)" ] && break
            sleep 0.1
        done
    fi
    # the daemons started from DIR, each by its pid file; slurmd first, munged last
    for name in slurmd slurmctld munged; do
        local pidfile="$DIR/run/$name.pid"
        if pid_alive "$pidfile"; then
            local pid
            pid="$(cat "$pidfile")"
            kill -TERM "$pid" 2>/dev/null || true
            for _ in $(seq 1 100); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
            kill -0 "$pid" 2>/dev/null && kill -KILL "$pid" 2>/dev/null || true
        fi
        rm -f "$pidfile"
    done
    if [ "$(readlink /run/slurm/conf 2>/dev/null)" = "$DIR" ]; then rm -f /run/slurm/conf; fi
}

start() {
    [ "$(id -u)" -eq 0 ] || fail "must run as root (slurmd launches jobs as their users)"
    mkdir -p "$DIR"
    install_if_needed
    stop  # a cluster left over in DIR by an earlier, interrupted run
    mkdir -p "$DIR"/{munge,run,log,state,spool}
    chmod 700 "$DIR/munge"

    # srun inside a job reads /etc/slurm/slurm.conf, else /run/slurm/conf/slurm.conf
    [ -e /etc/slurm/slurm.conf ] && fail "this machine has its own SLURM (/etc/slurm/slurm.conf); not starting another"
    # /run/slurm/conf may be reused only when it is a link left by this script (or dangling)
    if [ -L /run/slurm/conf ]; then
        [ ! -e /run/slurm/conf/slurm.conf ] || grep -qs "^# written by scripts/dev/slurm_local.sh" \
            /run/slurm/conf/slurm.conf || fail "/run/slurm/conf belongs to another SLURM; not starting another"
    elif [ -e /run/slurm/conf ]; then
        fail "/run/slurm/conf belongs to another SLURM (configless slurmd); not starting another"
    fi

    # munge: a fresh key and a private socket
    local key="$DIR/munge/munge.key" socket="$DIR/munge/munge.socket"
    [ "${#socket}" -lt 100 ] || fail "the munge socket's path is too long for a unix socket: $socket"
    [ -s "$key" ] || dd if=/dev/urandom of="$key" bs=1024 count=1 status=none
    chmod 400 "$key"
    munged --force --key-file="$key" --socket="$socket" --pid-file="$DIR/run/munged.pid" \
        --log-file="$DIR/log/munged.log" --seed-file="$DIR/munge/munge.seed" \
        || fail "munged did not start (see $DIR/log/munged.log)"
    for _ in $(seq 1 50); do [ -S "$socket" ] && break; sleep 0.1; done
    munge -n --socket="$socket" | unmunge --socket="$socket" >/dev/null 2>&1 \
        || fail "munge cannot encode and decode a credential (see $DIR/log/munged.log)"

    local mem ctld_port slurmd_port
    mem="$(slurmd -C | sed -n 's/.*RealMemory=\([0-9]*\).*/\1/p')"
    [ -n "$mem" ] || fail "slurmd -C did not report the machine's memory"
    ctld_port="$(free_port)"
    slurmd_port="$(free_port)"
    while [ "$slurmd_port" = "$ctld_port" ]; do slurmd_port="$(free_port)"; done
    cat >"$DIR/slurm.conf" <<EOF
# written by scripts/dev/slurm_local.sh: a single node on localhost, no cgroups, no accounting
ClusterName=straylight-local
SlurmctldHost=localhost
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$socket
StateSaveLocation=$DIR/state
SlurmdSpoolDir=$DIR/spool
SlurmctldPidFile=$DIR/run/slurmctld.pid
SlurmdPidFile=$DIR/run/slurmd.pid
SlurmctldLogFile=$DIR/log/slurmctld.log
SlurmdLogFile=$DIR/log/slurmd.log
PlugStackConfig=$DIR/plugstack.conf
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SwitchType=switch/none
MpiDefault=none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
# finished jobs stay visible to squeue for 10 minutes (the executor polls squeue, there is no sacct)
MinJobAge=600
MailProg=/bin/true
SchedulerType=sched/backfill
SlurmctldTimeout=30
SlurmdTimeout=30
InactiveLimit=0
KillWait=5
NodeName=localhost NodeHostname=localhost NodeAddr=127.0.0.1 CPUs=$CPUS RealMemory=$mem State=UNKNOWN
PartitionName=$PARTITION Nodes=localhost Default=YES MaxTime=INFINITE State=UP
EOF
    : >"$DIR/plugstack.conf"
    export SLURM_CONF="$DIR/slurm.conf"
    mkdir -p /run/slurm
    ln -sfn "$DIR" /run/slurm/conf

    slurmctld -f "$SLURM_CONF" -c || fail "slurmctld did not start (see $DIR/log/slurmctld.log)"
    slurmd -f "$SLURM_CONF" -N localhost || fail "slurmd did not start (see $DIR/log/slurmd.log)"

    local state=""
    for _ in $(seq 1 $((START_TIMEOUT_S * 2))); do
        state="$(sinfo -h -n localhost -o '%T' 2>/dev/null | head -1 || true)"
        [ "$state" = "idle" ] && break
        sleep 0.5
    done
    if [ "$state" != "idle" ]; then
        {
            echo "--- $DIR/log/slurmctld.log"; tail -n 20 "$DIR/log/slurmctld.log" 2>/dev/null || true
            echo "--- $DIR/log/slurmd.log"; tail -n 20 "$DIR/log/slurmd.log" 2>/dev/null || true
        } >&2
        stop
        fail "the node did not become idle within ${START_TIMEOUT_S} s (state '${state:-none}')"
    fi
    echo "SLURM_CONF=$SLURM_CONF"
    echo "SLURM_LOCAL_PARTITION=$PARTITION"
}

case "$cmd" in
    start) start ;;
    stop) stop ;;
    status) SLURM_CONF="$DIR/slurm.conf" sinfo ;;
    *) echo "usage: $0 start|stop|status [DIR]" >&2; exit 2 ;;
esac
