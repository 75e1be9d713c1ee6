#!/usr/bin/env bash
# A one-node Slurm cluster on this machine, for tests and for trying the Slurm backend.
#
# Usage (as root; Debian packages slurm-wlm and munge, installed by ops/deps.sh):
#   ops/slurm/local_cluster.sh start [DIR]    writes DIR/slurm.conf, starts munged, slurmctld,
#                                                 slurmd; prints `export SLURM_CONF=DIR/slurm.conf`
#   ops/slurm/local_cluster.sh status [DIR]   which of the three run; exit 0 when all do
#   ops/slurm/local_cluster.sh stop [DIR]     stops exactly the processes start started
#   eval "$(ops/slurm/local_cluster.sh start)"; sinfo; sbatch ...; ops/slurm/local_cluster.sh stop
# DIR defaults to $REFLCHECK_SLURM_DIR or /tmp/reflcheck-slurm. Nothing is written to /etc and
# no system service is used (no systemd): every daemon gets its own key, socket, pid, log and
# state paths under DIR, and its own free TCP ports, so that two clusters (two test runs) and a
# system Slurm can coexist. The node is this machine with the CPU count and memory `slurmd -C`
# reports; ProctrackType=proctrack/linuxproc and TaskPlugin=task/none need no cgroups, so it
# runs in a container too. A start that fails stops what it started (trap) and exits 1.
#
# A real multi-node cluster differs: see docs/slurm.md (shared run folder and cache,
# partition, accounts, what each node needs).
set -euo pipefail

cmd=${1:-}
dir=${2:-${REFLCHECK_SLURM_DIR:-/tmp/reflcheck-slurm}}
case $dir in /*) ;; *) dir=$PWD/$dir ;; esac
conf=$dir/slurm.conf

die() {
    echo "reflcheck local_cluster: $*" >&2
    exit 1
}

# The pid in FILE if that process is alive and is the program named (a reused pid is not ours).
alive_pid() {
    local file=$1 prog=$2 pid
    [ -r "$file" ] || return 1
    pid=$(tr -dc '0-9' < "$file")
    [ -n "$pid" ] && [ -r "/proc/$pid/comm" ] || return 1
    [ "$(cat "/proc/$pid/comm")" = "$prog" ] || return 1
    echo "$pid"
}

stop_one() {
    local file=$1 prog=$2 pid i
    pid=$(alive_pid "$file" "$prog") || { rm -f "$file"; return 0; }
    kill -TERM "$pid" 2>/dev/null || true
    # Daemons save state on SIGTERM; 10 s is far beyond what an idle one-node cluster needs.
    for i in $(seq 100); do
        [ -d "/proc/$pid" ] || break
        sleep 0.1
    done
    [ -d "/proc/$pid" ] && kill -KILL "$pid" 2>/dev/null
    rm -f "$file"
}

do_stop() {
    # slurmd first: it kills the job steps it runs (linuxproc tracks them) as it stops.
    stop_one "$dir/slurmd.pid" slurmd
    stop_one "$dir/slurmctld.pid" slurmctld
    stop_one "$dir/munged.pid" munged
}

do_status() {
    local rc=0 p
    for p in munged slurmctld slurmd; do
        if pid=$(alive_pid "$dir/$p.pid" "$p"); then
            echo "$p running (pid $pid)"
        else
            echo "$p not running"
            rc=1
        fi
    done
    [ -r "$conf" ] && echo "export SLURM_CONF=$conf"
    return $rc
}

free_port() {
    /usr/bin/python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

do_start() {
    [ "$(id -u)" -eq 0 ] || die "start runs munged, slurmctld and slurmd as root; run it as root"
    local p
    for p in munged mungekey slurmctld slurmd; do
        command -v "$p" >/dev/null || [ -x "/usr/sbin/$p" ] ||
            die "$p is not installed; install it with: apt-get install slurm-wlm munge"
    done
    export PATH=$PATH:/usr/sbin
    if do_status >/dev/null 2>&1; then
        echo "export SLURM_CONF=$conf"
        return 0
    fi
    trap 'do_stop' EXIT
    do_stop
    mkdir -p "$dir"
    chmod 0700 "$dir"
    mkdir -p "$dir/munge" "$dir/state" "$dir/spool" "$dir/log"
    chmod 0700 "$dir/munge"
    # munged checks that its key and socket folders are not writable by others.
    [ -s "$dir/munge/munge.key" ] || mungekey --create --keyfile="$dir/munge/munge.key" >/dev/null
    chmod 0400 "$dir/munge/munge.key"
    munged --force --key-file="$dir/munge/munge.key" --socket="$dir/munge/munge.socket" \
        --pid-file="$dir/munged.pid" --log-file="$dir/log/munged.log" --seed-file="$dir/munge/munged.seed" ||
        die "munged did not start; see $dir/log/munged.log"

    # The node as slurmd sees it: name, CPUs, sockets, cores, threads, memory.
    local node
    node=$(slurmd -C | head -n1)
    [[ $node == NodeName=* ]] || die "slurmd -C gave no node line: $node"
    local name=${node%% *}
    name=${name#NodeName=}
    local ctl_port slurmd_port
    ctl_port=$(free_port)
    slurmd_port=$(free_port)
    [ "$ctl_port" != "$slurmd_port" ] || slurmd_port=$(free_port)
    cat > "$conf.tmp" <<EOF
# Written by ops/slurm/local_cluster.sh: a one-node cluster on $name, private to $dir.
ClusterName=reflcheck
SlurmctldHost=$name(127.0.0.1)
SlurmctldPort=$ctl_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$dir/munge/munge.socket
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
ReturnToService=2
# No accounting database here: finished jobs stay visible to scontrol for an hour instead.
MinJobAge=3600
# Seconds between SIGTERM and SIGKILL when a job is cancelled or runs out of time.
KillWait=10
SlurmctldTimeout=60
SlurmdTimeout=60
$node State=UNKNOWN NodeAddr=127.0.0.1
PartitionName=reflcheck Nodes=$name Default=YES MaxTime=INFINITE State=UP
EOF
    mv "$conf.tmp" "$conf"
    export SLURM_CONF=$conf
    # -i: ignore any state a former cluster in this folder left; a fresh start has no jobs.
    slurmctld -i -f "$conf" || die "slurmctld did not start; see $dir/log/slurmctld.log"
    slurmd -f "$conf" -N "$name" || die "slurmd did not start; see $dir/log/slurmd.log"
    local i
    for i in $(seq 150); do
        if sinfo -h -N -o '%t' 2>/dev/null | grep -qE '^(idle|mix|alloc)'; then
            trap - EXIT
            echo "export SLURM_CONF=$conf"
            return 0
        fi
        sleep 0.2
    done
    die "the node did not become idle in 30 s; see $dir/log/slurmctld.log and $dir/log/slurmd.log"
}

case $cmd in
    start) do_start ;;
    stop) do_stop ;;
    status) do_status ;;
    *)
        echo "usage: $0 start|stop|status [DIR]" >&2
        exit 2
        ;;
esac
