#!/usr/bin/env bash
# The nightly through Slurm against the nightly run locally, on its own one-node cluster
# (ops/slurm/local_cluster.sh, started here and stopped on exit):
#  1. the same small plan (2 scenes, test size, no sweep) run with make and with SCHEDULER=slurm
#     gives the same verdicts and metrics in every compare.json, bit-identical rasterizer images
#     (pixels), references within noise, and every render record names its Slurm job, which
#     Slurm knows as a reflcheck-render array task;
#  2. under Slurm, a job whose renderer fails records "failed" itself, a job cancelled while
#     it renders and one cancelled before it starts get "crashed" records naming the Slurm job
#     (finish.py), and the rest of the run completes: the other jobs are ok, compare runs.
# Usage: bash tests/slurm_nightly.sh BUILD     (as root: the cluster's daemons run as root)
set -uo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
work=$build/slurm-test
rm -rf "$work"
mkdir -p "$work/bin"
pass=0
fail=0
ok() { pass=$((pass + 1)); echo "slurm: $*"; }
bad() { fail=$((fail + 1)); echo "slurm: FAILED: $*"; }

cluster=$(mktemp -d /tmp/reflcheck-slurm-test-XXXXXX)
trap 'bash ops/slurm/local_cluster.sh stop "$cluster"; rm -rf "$cluster"' EXIT
if ! eval "$(bash ops/slurm/local_cluster.sh start "$cluster")"; then
    echo "slurm: FAILED: the local cluster did not start; logs in $cluster/log" >&2
    cat "$cluster"/log/*.log >&2 2>/dev/null
    exit 1
fi
ok "local cluster up: $(sinfo -h -N -o '%N %c CPUs %m MB %t')"

scenes="scenes/lambert_calibration.yaml scenes/d3d_spot.yaml"
common() {
    export BIN=$build/reflcheck RUNS=$work/runs HISTORY=$work/history.jsonl LATEST=$work/latest
    export SMALL=1 NO_SWEEP=1 NO_SCREENSHOT=1 SCENES=$scenes
}
common
t0=$(date +%s)
CACHE=$work/cache-local RUN_ID=local bash ops/nightly.sh > "$work/local.log" 2>&1
st_local=$?
t1=$(date +%s)
CACHE=$work/cache-slurm RUN_ID=slurm SCHEDULER=slurm bash ops/nightly.sh > "$work/slurm.log" 2>&1
st_slurm=$?
t2=$(date +%s)
[ $st_local -eq 0 ] && ok "local nightly: exit 0 ($((t1 - t0)) s)" || bad "local nightly exit $st_local; see $work/local.log"
[ $st_slurm -eq 0 ] && ok "slurm nightly: exit 0 ($((t2 - t1)) s)" || bad "slurm nightly exit $st_slurm; see $work/slurm.log"

# Same verdicts and metrics; raster images bit-identical; every record names its Slurm job.
if /usr/bin/python3 tests/slurm_compare.py "$work/runs/local" "$work/runs/slurm" "$BIN"; then
    ok "local and Slurm runs agree (verdicts, metrics, images, Slurm ids)"
else
    bad "local and Slurm runs differ (above)"
fi

# Re-running through Slurm reuses the cache: every job is a cache hit.
CACHE=$work/cache-slurm RUN_ID=slurm2 SCHEDULER=slurm bash ops/nightly.sh > "$work/slurm2.log" 2>&1
st=$?
n_cached=$(grep -l '"cached":[[:space:]]*true' "$work"/runs/slurm2/*/*.json 2>/dev/null | wc -l)
# Job records name their renderer; compare.json and the fit files do not.
n_records=$(grep -l '"renderer"' "$work"/runs/slurm2/*/*.json 2>/dev/null | wc -l)
[ $st -eq 0 ] && [ "$n_cached" -eq "$n_records" ] && [ "$n_records" -gt 0 ] &&
    ok "second Slurm run: all $n_records jobs from the cache" ||
    bad "second Slurm run: exit $st, $n_cached of $n_records jobs cached; see $work/slurm2.log"

# 2. Failures under Slurm. A POV-Ray that names its version and fails every render (so the
# cache key differs and the job renders); Slurm passes our PATH to the jobs.
real_pov=$(command -v povray)
cat > "$work/bin/povray" <<SH
#!/bin/sh
case "\$1" in --version) exec $real_pov --version ;; esac
echo "povray: simulated failure" >&2
exit 1
SH
chmod +x "$work/bin/povray"
# A Blender stand-in, so that the job cancelled "while it renders" is in a known state and not in
# a race with the render's speed: it answers --version like the real one plus a suffix unique to
# this test run (so no cache, warm or not, holds its jobs), runs the real Blender for every job
# but the one array task named in $work/hold-task, and for that one writes $work/held (its pid)
# and then waits until the test writes $work/release (or Slurm ends it). The wait is bounded (10
# minutes) only so that a broken test leaves no process behind for ever.
real_blender=$(command -v blender)
cat > "$work/bin/blender" <<SH
#!/bin/sh
case "\$1" in --version) $real_blender --version | sed 's/^Blender .*/& (reflcheck test stand-in $$-$RANDOM)/'; exit 0 ;; esac
if [ "\${SLURM_ARRAY_JOB_ID:-}_\${SLURM_ARRAY_TASK_ID:-}" != "\$(cat "$PWD/$work/hold-task" 2>/dev/null)" ]; then
    exec $real_blender "\$@"
fi
echo \$\$ > "$PWD/$work/held"
i=0
while [ ! -e "$PWD/$work/release" ] && [ \$i -lt 6000 ]; do sleep 0.1; i=\$((i + 1)); done
echo "blender stand-in: released without rendering" >&2
exit 1
SH
chmod +x "$work/bin/blender"
release_standin() { : > "$work/release"; }
trap 'release_standin; bash ops/slurm/local_cluster.sh stop "$cluster"; rm -rf "$cluster"' EXIT
run=$work/runs/fail
mkdir -p "$run"
PATH=$PWD/$work/bin:$PATH "$BIN" plan $scenes --out "$run" --cache "$work/cache-fail" --bin "$BIN" --small \
    --scheduler slurm > "$run/submit.sh"
ids=$(PATH=$PWD/$work/bin:$PATH bash "$run/submit.sh" --hold)
array=${ids%%:*}
list=$(cut -d' ' -f2 "$run/slurm/arrays" | head -n1)
task_of() { grep -n -- "--renderer $1 --role $2 .*$3" "$list" | head -n1 | cut -d: -f1 | awk '{print $1 - 1}'; }
running=$(task_of cycles twin lambert_calibration)
pending=$(task_of cycles twin d3d_spot)
echo "${array}_$running" > "$work/hold-task"
# Cancelled while held (before it starts): it cannot have started, whatever the machine's speed.
scancel "${array}_$pending"
scontrol release "$array" > /dev/null
# Cancel the Lambert Cycles twin once its Blender has started: the stand-in then waits until it
# is told, so the job is certainly still rendering when scancel reaches it. A bounded wait for
# that condition (10 minutes, for a loaded machine); not finding it is a failure of its own.
for _ in $(seq 3000); do
    [ -s "$work/held" ] && break
    sleep 0.2
done
if [ -s "$work/held" ]; then
    ok "the Lambert Cycles twin (task ${array}_$running) is in Blender, held until cancelled"
else
    bad "the held Blender of task ${array}_$running never started; see $run/slurm/${array}_$running.out"
fi
scancel "${array}_$running"
cid=$(sbatch --parsable --dependency="afterany:$ids" -n1 -c1 --time=10 --output="$run/slurm/compare.out" \
    ops/slurm/compare.sh "$run" "$BIN" $scenes)
# Polled as the nightly does: sbatch --wait backs off to half a minute between its checks.
for _ in $(seq 600); do
    [ -z "$(squeue -h -j "${cid%%;*}" -o %T 2>/dev/null)" ] && break
    sleep 0.5
done
status_of() {
    /usr/bin/python3 -c 'import json,sys; r=json.load(open(sys.argv[1]))
print(r["status"], (r.get("slurm") or {}).get("job_id", ""), r["message"].replace("\n", " "), sep="|")' "$1" 2>/dev/null
}
want() {  # want RECORD STATUS JOB_ID TEXT: JOB_ID "" = any task of the array
    local got s j m
    got=$(status_of "$run/$1")
    IFS='|' read -r s j m <<< "$got"
    if [ "$s" = "$2" ] && { [ "$j" = "$3" ] || { [ -z "$3" ] && [[ $j == "${array}_"* ]]; }; } && [[ $m == *"$4"* ]]; then
        ok "$1: $s, Slurm job $j: $m"
    else
        bad "$1: got '$got', want status $2, Slurm job ${3:-${array}_*}, a message with '$4'"
    fi
}
want lambert_calibration/cycles-twin.json crashed "${array}_$running" "CANCELLED"
want d3d_spot/cycles-twin.json crashed "${array}_$pending" "cancelled while pending"
# Every POV-Ray job fails on its own and records it, in its own array task.
for rec in "$run"/*/povray-*.json; do
    want "${rec#"$run"/}" failed "" "povray failed"
done
# Every other job of the plan ran and is ok, each in its own array task.
for rec in "$run"/*/*-*.json; do
    case ${rec#"$run"/} in
        */compare.json | lambert_calibration/cycles-twin.json | d3d_spot/cycles-twin.json | */povray-*.json) ;;
        *) want "${rec#"$run"/}" ok "" "" ;;
    esac
done
[ -s "$run/lambert_calibration/cycles-twin.log" ] && ok "the cancelled job's log is its Slurm output" ||
    bad "the cancelled job has no log"
[ "$(cat "$run/compare.rc" 2>/dev/null)" = 1 ] && grep -q "lambert_calibration" "$run/compare.txt" &&
    ok "compare ran after the failures and reports them (exit 1)" ||
    bad "compare did not run or did not fail; see $run/slurm/compare.out"

echo "slurm: $pass passed, $fail failed"
[ $fail -eq 0 ]
