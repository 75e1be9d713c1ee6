#!/usr/bin/env bash
# A Slurm cluster of one or more nodes on this machine, for tests and for trying the Slurm backend.
#
# Usage (as root; Debian packages slurm-wlm and munge, installed by ops/deps.sh):
#   ops/slurm/local_cluster.sh start [OPTION...] [DIR]   writes DIR/slurm.conf, starts munged,
#                                   slurmctld and one slurmd per node; prints `export SLURM_CONF=...`
#       --nodes N            N nodes (default 1): one is this machine under its own name; N > 1 are
#                            n1..nN, each a slurmd -N nI with its own port and %n spool, pid and log
#                            paths, sharing this machine's cores out (at least one CPU each)
#       --slurmd-timeout S   seconds before slurmctld sets a silent node DOWN (default 60)
#       --requeue-delay S    seconds a job requeued from a DOWN node waits before it starts again
#                            (Slurm's cred_expire, also the job credentials' lifetime; default 120)
#   ops/slurm/local_cluster.sh status [DIR]   which daemons run; exit 0 when all do
#   ops/slurm/local_cluster.sh kill-node NODE [DIR]   a node's death: SIGKILL its slurmd and
#                                   every job process on it (slurmstepd and what it started)
#   ops/slurm/local_cluster.sh stop [DIR]     stops exactly the processes start started
#   eval "$(ops/slurm/local_cluster.sh start)"; sinfo; sbatch ...; ops/slurm/local_cluster.sh stop
#   eval "$(ops/slurm/local_cluster.sh start --nodes 2 /tmp/two)"; srun -N2 hostname
# DIR defaults to $REFLCHECK_SLURM_DIR or /tmp/reflcheck-slurm. Nothing is written to /etc and
# no system service is used (no systemd): every daemon gets its own key, socket, pid, log and
# state paths under DIR, and its own free TCP ports, so that two clusters (two test runs) and a
# system Slurm can coexist. One node is this machine with the CPU count and memory `slurmd -C`
# reports; N nodes share them out, so that N nodes load the machine as one does (Slurm's
# `slurmd -N`, built into Debian's slurmd). ProctrackType=proctrack/linuxproc and
# TaskPlugin=task/none need no cgroups, so it runs in a container too. Each job's end (a requeue
# too) is a line of DIR/log/jobcomp.txt with its state and node list: where each job ran. A
# start that fails stops what it started (trap) and exits 1.
#
# A real multi-node cluster differs: see docs/slurm.md (shared run folder and cache,
# partition, accounts, what each node needs).
set -euo pipefail

usage() {
    echo "usage: $0 start [--nodes N] [--slurmd-timeout S] [--requeue-delay S] [DIR] | status [DIR] | kill-node NODE [DIR] | stop [DIR]" >&2
    exit 2
}
cmd=${1:-}
[ $# -gt 0 ] && shift
nodes=1
slurmd_timeout=60
cred_expire=120
victim=
if [ "$cmd" = kill-node ]; then
    victim=${1:-}
    [ -n "$victim" ] || usage
    shift
fi
while [ $# -gt 0 ]; do
    case $1 in
        --nodes | --slurmd-timeout | --requeue-delay)
            [ "$cmd" = start ] && [ $# -ge 2 ] && [[ $2 =~ ^[1-9][0-9]*$ ]] ||
                { echo "reflcheck local_cluster: $1 takes a whole number >= 1, with start only (e.g. start $1 2)" >&2; exit 2; }
            case $1 in
                --nodes) nodes=$2 ;;
                --slurmd-timeout) slurmd_timeout=$2 ;;
                *) cred_expire=$2 ;;
            esac
            shift 2 ;;
        --*) echo "reflcheck local_cluster: option '$1' is not known" >&2; usage ;;
        *) [ -z "${dir_arg:-}" ] || usage; dir_arg=$1; shift ;;
    esac
done
dir=${dir_arg:-${REFLCHECK_SLURM_DIR:-/tmp/reflcheck-slurm}}
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

# The node names start wrote (one per line).
node_names() {
    if [ -r "$dir/nodes" ]; then
        cat "$dir/nodes"
    fi
}

do_stop() {
    local n
    # slurmd first: it kills the job steps it runs (linuxproc tracks them) as it stops.
    for n in $(node_names); do
        stop_one "$dir/slurmd-$n.pid" slurmd
    done
    stop_one "$dir/slurmd.pid" slurmd # a cluster started before nodes had their own pid files
    stop_one "$dir/slurmctld.pid" slurmctld
    stop_one "$dir/munged.pid" munged
}

do_status() {
    local rc=0 p n pid
    for p in munged slurmctld; do
        if pid=$(alive_pid "$dir/$p.pid" "$p"); then
            echo "$p running (pid $pid)"
        else
            echo "$p not running"
            rc=1
        fi
    done
    [ -n "$(node_names)" ] || { echo "slurmd: no node started in $dir"; rc=1; }
    for n in $(node_names); do
        if pid=$(alive_pid "$dir/slurmd-$n.pid" slurmd); then
            echo "slurmd -N $n running (pid $pid)"
        else
            echo "slurmd -N $n not running"
            rc=1
        fi
    done
    [ -r "$conf" ] && echo "export SLURM_CONF=$conf"
    return $rc
}

# The process and every descendant of it, deepest first.
tree_of() {
    local c
    for c in $(pgrep -P "$1" 2> /dev/null); do
        tree_of "$c"
    done
    echo "$1"
}

# A node's death as its jobs see it: its slurmd and every slurmstepd of a job on it (with all
# they started) get SIGKILL at once, nothing saved, nothing told. A slurmstepd names its step,
# "slurmstepd: [JOB.STEP]", and outlives its slurmd, so the jobs on the node come from
# slurmctld (squeue, which has not noticed the death yet).
do_kill_node() {
    local pid job jobs procs=() p comm
    node_names | grep -qx -- "$victim" || die "$victim is not a node of the cluster in $dir; see $dir/nodes"
    export SLURM_CONF=$conf PATH=$PATH:/usr/sbin
    pid=$(alive_pid "$dir/slurmd-$victim.pid" slurmd) ||
        die "slurmd -N $victim is not running; see $dir/log/slurmd-$victim.log"
    # Raw job ids (an array task's own id) of what runs on the node.
    jobs=" $(squeue -h -w "$victim" -t RUNNING,COMPLETING -o %A | paste -sd' ') "
    procs+=("$pid")
    for p in $(pgrep -x slurmstepd); do
        comm=$(tr '\0' ' ' 2> /dev/null < "/proc/$p/cmdline") || continue
        job=${comm#*[}
        job=${job%%.*}
        # shellcheck disable=SC2207
        [[ $jobs == *" $job "* ]] && procs+=($(tree_of "$p"))
    done
    kill -KILL "${procs[@]}" 2> /dev/null || true
    rm -f "$dir/slurmd-$victim.pid"
    echo "killed node $victim: slurmd (pid $pid) and $((${#procs[@]} - 1)) job processes; its jobs:${jobs% }"
}

free_port() {
    /usr/bin/python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

# The node lines of slurm.conf, each with its own slurmd port: this machine as slurmd -C sees
# it (one node), or n1..nN each with an equal share of its cores and memory (one CPU at least).
node_lines() {
    local node=$1 n=$2 name=${1%% *}
    if [ "$n" -eq 1 ]; then
        echo "$node State=UNKNOWN NodeAddr=127.0.0.1 Port=$(free_port)"
        return
    fi
    local cpus mem i
    cpus=$(sed -n 's/.* CPUs=\([0-9]*\).*/\1/p' <<< "$node")
    mem=$(sed -n 's/.* RealMemory=\([0-9]*\).*/\1/p' <<< "$node")
    cpus=$((cpus / n))
    [ "$cpus" -ge 1 ] || cpus=1
    for i in $(seq "$n"); do
        echo "NodeName=n$i NodeHostname=${name#NodeName=} NodeAddr=127.0.0.1 Port=$(free_port)" \
            "CPUs=$cpus RealMemory=$((mem / n)) State=UNKNOWN"
    done
}

write_conf() {
    local host=$1 ctl_port=$2 lines=$3 names
    names=$(sed 's/^NodeName=\([^ ]*\).*/\1/' <<< "$lines" | paste -sd,)
    cat > "$conf.tmp" << CONF
# Written by ops/slurm/local_cluster.sh: a $nodes-node cluster on $host, private to $dir.
ClusterName=reflcheck
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctl_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
# cred_expire: how long a job credential lives, and how long a requeued job waits to start again.
AuthInfo=socket=$dir/munge/munge.socket,cred_expire=$cred_expire
StateSaveLocation=$dir/state
# %n is the node's name: several slurmd on one machine (slurmd -N) keep their files apart.
SlurmdSpoolDir=$dir/spool/%n
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd-%n.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd-%n.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
# No accounting database: each job's end (state, node list, times; a requeue too) goes to one
# line of a text file (sacct -c reads it, but not in 22.05 once it holds array tasks).
JobCompType=jobcomp/filetxt
JobCompLoc=$dir/log/jobcomp.txt
ReturnToService=2
# Finished jobs stay visible to scontrol for an hour (no accounting database to ask).
MinJobAge=3600
# Seconds between SIGTERM and SIGKILL when a job is cancelled or runs out of time.
KillWait=10
SlurmctldTimeout=60
# A node silent this long is set DOWN and its batch jobs requeued (JobRequeue=1, the default).
SlurmdTimeout=$slurmd_timeout
$lines
PartitionName=reflcheck Nodes=$names Default=YES MaxTime=INFINITE State=UP
CONF
    mv "$conf.tmp" "$conf"
}

do_start() {
    [ "$(id -u)" -eq 0 ] || die "start runs munged, slurmctld and slurmd as root; run it as root"
    local p
    for p in munged mungekey slurmctld slurmd; do
        command -v "$p" > /dev/null || [ -x "/usr/sbin/$p" ] ||
            die "$p is not installed; install it with: apt-get install slurm-wlm munge"
    done
    export PATH=$PATH:/usr/sbin
    if do_status > /dev/null 2>&1; then
        [ "$(node_names | wc -l)" -eq "$nodes" ] ||
            die "a cluster of $(node_names | wc -l) node(s) runs in $dir; stop it first ($0 stop $dir)"
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
    [ -s "$dir/munge/munge.key" ] || mungekey --create --keyfile="$dir/munge/munge.key" > /dev/null
    chmod 0400 "$dir/munge/munge.key"
    munged --force --key-file="$dir/munge/munge.key" --socket="$dir/munge/munge.socket" \
        --pid-file="$dir/munged.pid" --log-file="$dir/log/munged.log" --seed-file="$dir/munge/munged.seed" ||
        die "munged did not start; see $dir/log/munged.log"

    # The machine as slurmd sees it: name, CPUs, sockets, cores, threads, memory.
    local node host lines ctl_port n i
    node=$(slurmd -C | head -n1)
    [[ $node == NodeName=* ]] || die "slurmd -C gave no node line: $node"
    host=${node%% *}
    host=${host#NodeName=}
    lines=$(node_lines "$node" "$nodes")
    sed 's/^NodeName=\([^ ]*\).*/\1/' <<< "$lines" > "$dir/nodes"
    ctl_port=$(free_port)
    while grep -q "Port=$ctl_port " <<< "$lines"; do ctl_port=$(free_port); done
    write_conf "$host" "$ctl_port" "$lines"
    export SLURM_CONF=$conf
    # -i: ignore any state a former cluster in this folder left; a fresh start has no jobs.
    slurmctld -i -f "$conf" || die "slurmctld did not start; see $dir/log/slurmctld.log"
    for n in $(node_names); do
        mkdir -p "$dir/spool/$n"
        slurmd -f "$conf" -N "$n" || die "slurmd -N $n did not start; see $dir/log/slurmd-$n.log"
    done
    for i in $(seq 150); do
        if [ "$(sinfo -h -N -o '%t' 2> /dev/null | grep -cE '^(idle|mix|alloc)')" -eq "$nodes" ]; then
            trap - EXIT
            echo "export SLURM_CONF=$conf"
            return 0
        fi
        sleep 0.2
    done
    die "not every node became idle in 30 s; see $dir/log/slurmctld.log and $dir/log/slurmd-*.log"
}

case $cmd in
    start) do_start ;;
    stop) do_stop ;;
    status) do_status ;;
    kill-node) do_kill_node ;;
    *) usage ;;
esac
