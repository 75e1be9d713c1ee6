#!/usr/bin/env bash
# The nightly through Slurm on two nodes, then with one of them lost mid-run, against the same
# nightly on one node (ops/slurm/local_cluster.sh clusters, started here, stopped on exit;
# one at a time):
#  1. one node: the small nightly of three scenes (no sweep) through Slurm;
#  2. two nodes (slurmd -N n1 and -N n2, one CPU each): srun -N2 runs on both; the same nightly
#     puts jobs on both nodes (where each job ran: Slurm's job completion log and the records),
#     and its verdicts, metrics and images equal the one-node run's;
#  3. two nodes, n2 lost: a stand-in POV-Ray and Blender (the real ones but on n2, where they
#     hold until n2 dies) puts the run in a known state: a job held on n2. Then the node dies
#     (local_cluster.sh kill-node: its slurmd and its jobs' processes, SIGKILL). Slurm sets n2
#     DOWN after SlurmdTimeout and requeues the held job (NODE_FAIL, JobRequeue=1 by default,
#     slurm.conf(5)), which runs again on n1 after cred_expire; the run completes (exit 0), every
#     file written before the kill is unchanged, and the verdicts equal the one-node run's.
# Usage: bash tests/slurm_nodes.sh BUILD     (as root: the clusters' daemons run as root)
set -uo pipefail
cd "$(dirname "$0")/.." || exit 2
build=${1:-build}
work=$PWD/$build/slurm-nodes-test
rm -rf "$work"
mkdir -p "$work/bin"
pass=0
fail=0
ok() { pass=$((pass + 1)); echo "nodes: $*"; }
bad() { fail=$((fail + 1)); echo "nodes: FAILED: $*"; }

cluster=
stop_cluster() {
    [ -n "$cluster" ] && bash ops/slurm/local_cluster.sh stop "$cluster" && rm -rf "$cluster"
    cluster=
}
# The stand-ins' hold ends with the test, whatever happens to it.
trap ': > "$work/release"; stop_cluster' EXIT
# start ARG...: a fresh cluster in a temporary folder, SLURM_CONF exported; exit 1 if it fails.
start_cluster() {
    cluster=$(mktemp -d /tmp/reflcheck-slurm-nodes-XXXXXX)
    if ! eval "$(bash ops/slurm/local_cluster.sh start "$@" "$cluster")"; then
        echo "nodes: FAILED: the local cluster ($*) did not start; logs in $cluster/log" >&2
        cat "$cluster"/log/*.log >&2 2> /dev/null
        exit 1
    fi
}

scenes="scenes/lambert_calibration.yaml scenes/d3d_spot.yaml scenes/ct_cube.yaml"
export BIN=$build/reflcheck RUNS=$work/runs HISTORY=$work/history.jsonl LATEST=$work/latest
export SMALL=1 NO_SWEEP=1 NO_SCREENSHOT=1 SCENES=$scenes SCHEDULER=slurm
# run_nightly ID: the nightly through the running cluster, fresh cache; its exit status.
run_nightly() {
    CACHE=$work/cache-$1 RUN_ID=$1 /usr/bin/time -f '%e %U %S' -o "$work/$1.time" bash ops/nightly.sh \
        > "$work/$1.log" 2>&1
}
# nightly_ok ID STATUS: the nightly's exit status, wall and CPU seconds (the nightly's own
# processes; the jobs run under slurmd and count there).
nightly_ok() {
    local times
    times=$(awk '{printf "%.0f s wall, %.1f CPU-s in the nightly itself", $1, $2 + $3}' "$work/$1.time")
    [ "$2" -eq 0 ] && ok "$1 nightly: exit 0 ($times)" || bad "$1 nightly exit $2; see $work/$1.log"
}
nightly() {
    run_nightly "$1"
    nightly_ok "$1" $?
}

# 1. One node.
start_cluster --nodes 1
ok "one-node cluster: $(sinfo -h -N -o '%N %c CPUs %t' | paste -sd';')"
nightly one
stop_cluster

# 2. Two nodes, all well. A node is set DOWN 10 s after its slurmd falls silent and a job
# requeued from it waits 30 s (not 120) before it starts again: the test's length, no more.
start_cluster --nodes 2 --slurmd-timeout 10 --requeue-delay 30
ok "two-node cluster: $(sinfo -h -N -o '%N %c CPUs %t' | paste -sd';')"
where=$(timeout 120 srun -N2 -l printenv SLURMD_NODENAME | sort | cut -d' ' -f2 | paste -sd' ')
[ "$where" = "n1 n2" ] && ok "srun -N2 runs on both nodes: $where" || bad "srun -N2 ran on '$where', not n1 n2"
nightly two
/usr/bin/python3 tests/slurm_where.py "$work/runs/two" "$cluster/log/jobcomp.txt" --nodes n1,n2 &&
    ok "two-node run: jobs on both nodes, each completed where its record says" ||
    bad "two-node run: jobs not where expected (above)"
/usr/bin/python3 tests/slurm_compare.py --both-slurm "$work/runs/one" "$work/runs/two" "$BIN" > "$work/cmp-two.txt" &&
    ok "two-node run: verdicts, metrics and images equal the one-node run's" ||
    bad "two-node run differs from the one-node run: $(tail -n 5 "$work/cmp-two.txt")"

# written RUN: one line per job record RUN holds: its path, status, cache key and the SHA-256 of
# its image. (Not the record's bytes: the fits stage rewrites a validate record as a cache hit,
# the same job with the same key and image; see tests/slurm_where.py.)
written() {
    /usr/bin/python3 - "$1" << 'PY'
import glob, hashlib, json, os, sys
for path in sorted(glob.glob(os.path.join(sys.argv[1], '*', '*-*.json'))):
    rec = json.load(open(path))
    if 'renderer' in rec:
        digest = hashlib.sha256(open(rec['exr'], 'rb').read()).hexdigest() if os.path.isfile(rec['exr']) else '-'
        print(os.path.relpath(path, sys.argv[1]), rec['status'], rec['key'], digest)
PY
}

# 3. n2 lost mid-run. The stand-ins answer --version as the real programs do, run them for every
# job off n2, and on n2 write $work/held (array task, node, pid) and wait until n2 dies with them.
# The wait is bounded (10 minutes) only so that a broken test leaves no process behind for ever.
for prog in povray blender; do
    real=$(command -v "$prog")
    cat > "$work/bin/$prog" << SH
#!/bin/sh
if [ "\${SLURMD_NODENAME:-}" != n2 ] || [ "\$1" = --version ]; then
    exec $real "\$@"
fi
echo "\${SLURM_ARRAY_JOB_ID}_\${SLURM_ARRAY_TASK_ID} \$SLURMD_NODENAME \$\$" > "$work/held.tmp"
mv "$work/held.tmp" "$work/held"
i=0
while [ ! -e "$work/release" ] && [ \$i -lt 6000 ]; do sleep 0.1; i=\$((i + 1)); done
echo "$prog stand-in: released without rendering" >&2
exit 1
SH
    chmod +x "$work/bin/$prog"
done
(
    export PATH=$work/bin:$PATH
    run_nightly lost
) &
night=$!
# A bounded wait (10 minutes, for a loaded machine) for the known state: a job held on n2.
for _ in $(seq 3000); do
    [ -s "$work/held" ] && break
    kill -0 $night 2> /dev/null || break
    sleep 0.2
done
read -r held_task held_node _ < "$work/held" 2> /dev/null
if [ "${held_node:-}" = n2 ]; then
    ok "task $held_task is held on n2 (its renderer waits for the node's death)"
    # What the run has written so far, to find unchanged at the end.
    written "$work/runs/lost" > "$work/before-kill.txt"
    ok "$(bash ops/slurm/local_cluster.sh kill-node n2 "$cluster")"
    ok "$(wc -l < "$work/before-kill.txt") jobs written before the kill: $(cut -d' ' -f1 "$work/before-kill.txt" | paste -sd' ')"
else
    bad "no job was held on n2 (held: '$(cat "$work/held" 2> /dev/null)'); see $work/lost.log"
fi
wait $night
nightly_ok lost $?
state=$(sinfo -h -N -n n2 -o '%t')
[[ $state == down* ]] && ok "Slurm set n2 $state (SlurmdTimeout)" || bad "n2 is '$state', not down"
restarts=$(scontrol -o show job "$held_task" 2> /dev/null | grep -o 'Restarts=[0-9]*')
[ "$restarts" = Restarts=1 ] && ok "Slurm requeued task $held_task once ($restarts)" ||
    bad "task $held_task: '$restarts', not Restarts=1"
grep "ArrayJobId=${held_task%_*} ArrayTaskId=${held_task#*_} " "$cluster/log/jobcomp.txt" |
    grep -o 'JobState=[A-Z_]* .*NodeList=[^ ]*' | sed 's/ Partition.*NodeList/ NodeList/; s/^/nodes: Slurm logged /'
/usr/bin/python3 tests/slurm_where.py "$work/runs/lost" "$cluster/log/jobcomp.txt" --lost n2 "$held_task" &&
    ok "killed-node run: every job completed, the held one requeued from n2 to n1" ||
    bad "killed-node run: jobs not where expected (above)"
written "$work/runs/lost" > "$work/after-run.txt"
lost_lines=$(grep -vxF -f "$work/after-run.txt" "$work/before-kill.txt")
if [ -s "$work/before-kill.txt" ] && [ -z "$lost_lines" ]; then
    ok "every job written before the kill is there at the end: same status, key and image bytes"
else
    bad "jobs written before the kill are gone or changed: ${lost_lines:-none was written}"
fi
/usr/bin/python3 tests/slurm_compare.py --both-slurm "$work/runs/one" "$work/runs/lost" "$BIN" > "$work/cmp-lost.txt" &&
    ok "killed-node run: verdicts, metrics and images equal the one-node run's" ||
    bad "killed-node run differs from the one-node run: $(tail -n 5 "$work/cmp-lost.txt")"
stop_cluster

echo "nodes: $pass passed, $fail failed"
[ $fail -eq 0 ]
