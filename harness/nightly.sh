#!/usr/bin/env bash
# The nightly run (`make report`): every canonical scene in every renderer its comparisons
# list, full size; then metrics, the stability table and the report. A run writes only into
# its own folder reports/runs/<id>; reports/latest moves to it at the very end and the
# history gets one appended line, so a run killed midway leaves both as they were.
#
# Usage: harness/nightly.sh [SCENE.yaml ...]   (default: $SCENES, else scenes/*.yaml)
# Scene paths given as arguments may hold spaces and any other character. SCENES holds one
# path per line when it holds a line break, else space-separated paths; a word that is not a
# file is refused (exit 2).
#
# History: a run appends its line to reports/local/history.jsonl (ignored by git: a user's own
# runs never change a versioned file); the report's trend plots show the project's reference
# history (reports/history.jsonl, read only) and then the local runs, told apart. REFERENCE=1
# names this run the project's reference run on purpose: its line goes to reports/history.jsonl.
# A Slurm run that fails to submit records a line with status "failed" and the reason.
#
# Exit status: 0 when every job ran (or was skipped: renderer not installed, or it cannot
# represent the scene) and no comparison failed; 1 when a job or step failed or a comparison
# failed or errored (the run is still reported and recorded, with its status); 2 bad input.
# Killed or interrupted (SIGINT, SIGTERM, SIGHUP), it stops every process it started,
# renderers included, before it exits.
#
# Settings (environment): BIN, JOBS, RUNS, HISTORY (the file this run appends to),
# REFERENCE_HISTORY (read for the trends only; empty: none), REFERENCE=1, LATEST, CACHE, SCENES,
# RUN_ID, SMALL=1 (test-size renders), NO_SWEEP=1, NO_SCREENSHOT=1 (any non-empty value), SCHEDULER.
#
# SCHEDULER=slurm (default make): the render jobs, the sweep and the compare step run as Slurm
# jobs (docs/slurm.md): `plan --scheduler slurm` submits one array task per render; the sweep
# is one job of JOBS CPUs on one node (SWEEP_MINUTES, default 240) whose renders are srun steps;
# compare runs after all of them (afterany), first writing the records of jobs Slurm ended;
# stability, the plot and the report run here. RUN and CACHE must be on a filesystem every node
# shares, at the same path. Interrupted, the nightly cancels its Slurm jobs (scancel).
set -uo pipefail
cd "$(dirname "$0")/.."
bin=${BIN:-build/reflcheck}
jobs=${JOBS:-2}
runs=${RUNS:-reports/runs}              # where run folders go
say() { echo "reflcheck nightly: $*" >&2; }
# The versioned history is the project's reference; a run writes there only when named so.
if [ -n "${REFERENCE:-}" ]; then
    history=${HISTORY:-reports/history.jsonl}
    reference_history=${REFERENCE_HISTORY-}
else
    history=${HISTORY:-reports/local/history.jsonl}
    reference_history=${REFERENCE_HISTORY-reports/history.jsonl}
fi
case $jobs in
    *[!0-9]* | "" | 0*)
        say "JOBS '$jobs': give a whole number of parallel jobs, 1 or more (e.g. JOBS=2)"
        exit 2 ;;
esac
if ! { [ -f "$bin" ] && [ -x "$bin" ]; } && { [[ $bin == */* ]] || ! command -v "$bin" > /dev/null; }; then
    say "BIN '$bin' is not an executable file; build it (make all) or set BIN to build*/reflcheck"
    exit 2
fi
latest=${LATEST:-reports/latest}
cache=${CACHE:-reports/cache}
small=${SMALL:+--small}                 # SMALL=1: the test-size renders (used by the kill test)
screenshot=--screenshot
[ -n "${NO_SCREENSHOT:-}" ] && screenshot=
scheduler=${SCHEDULER:-make}
case $scheduler in
    make | slurm) ;;
    *)
        echo "reflcheck nightly: SCHEDULER '$scheduler': use make (the default) or slurm" >&2
        exit 2 ;;
esac
if [ "$scheduler" = slurm ] && ! sinfo -h > /dev/null 2>&1; then
    echo "reflcheck nightly: SCHEDULER=slurm, but no Slurm cluster answers (sinfo failed); set SLURM_CONF," \
        "or start a local one: eval \"\$(harness/slurm/local_cluster.sh start)\"" >&2
    exit 2
fi
commit=$(git rev-parse --short HEAD 2>/dev/null || echo nogit)
# Two runs started in the same second (two users, a cluster) must not share a folder: the
# pid and a random number follow the time and commit (report.py reads those two).
id=${RUN_ID:-$(date -u +%Y%m%d-%H%M%S)-$commit-$$-$(printf '%04x' "$RANDOM")}
case $id in
    "" | *[!A-Za-z0-9_.-]*)
        echo "reflcheck nightly: RUN_ID '$id': use letters, digits, _ . and -" >&2
        exit 2 ;;
esac
run=$runs/$id
# The scene paths as one array, so that a path with a space reaches every command whole.
scenes=()
if [ $# -gt 0 ]; then
    scenes=("$@")
elif [ -n "${SCENES:-}" ]; then
    if [[ $SCENES == *$'\n'* ]]; then
        mapfile -t scenes <<< "$SCENES"
    else
        read -r -a scenes <<< "$SCENES"
    fi
else
    scenes=(scenes/*.yaml)
fi
for i in "${!scenes[@]}"; do
    [ -z "${scenes[$i]}" ] && unset "scenes[$i]" # an empty line of a SCENES list
done
scenes=("${scenes[@]}")
[ ${#scenes[@]} -eq 0 ] && { say "no scene given; pass scene paths as arguments or in SCENES"; exit 2; }
for s in "${scenes[@]}"; do
    if [ ! -f "$s" ]; then
        say "scene '$s' is not a file; check the path, and give a path holding spaces as an argument" \
            "(harness/nightly.sh 'my scenes/a.yaml') or one path per line in SCENES"
        exit 2
    fi
done
if [ -d "$history" ]; then
    say "HISTORY '$history' is a folder; point HISTORY at a file (default reports/local/history.jsonl)"
    exit 2
fi
if [ -e "$runs" ] && [ ! -d "$runs" ]; then
    say "RUNS '$runs' is not a folder; point RUNS at a folder (default reports/runs)"
    exit 2
fi
mkdir -p "$runs" || { say "RUNS '$runs': cannot create the folder; point RUNS at a writable folder"; exit 2; }
if ! mkdir "$run" 2>/dev/null; then
    if [ -e "$run" ]; then
        say "$run exists already; give another RUN_ID (or leave it unset)"
    else
        say "$run: cannot create the run folder in RUNS '$runs'; make it writable or set RUNS"
    fi
    exit 2
fi
echo "reflcheck nightly: run $id -> $run"

# Children run in the background and are waited for, so that a signal reaches the trap at
# once; the trap stops every descendant (make forwards SIGTERM to its jobs, and a renderer
# also dies with the `reflcheck run` that started it), then exits.
descendants() {
    local c
    for c in $(pgrep -P "$1" 2>/dev/null); do
        echo "$c"
        descendants "$c"
    done
}
# The Slurm jobs this run submitted: render arrays (RUN/slurm/arrays), sweep and compare.
slurm_jobs() {
    [ -r "$run/slurm/arrays" ] && cut -d' ' -f1 "$run/slurm/arrays"
    [ -r "$run/slurm/steps" ] && cat "$run/slurm/steps"
}
stop_all() {
    trap '' INT TERM HUP
    local pids ids
    if [ "$scheduler" = slurm ]; then
        ids=$(slurm_jobs 2>/dev/null)
        # shellcheck disable=SC2086
        [ -n "$ids" ] && scancel $ids 2>/dev/null
    fi
    pids=$(descendants $$)
    # shellcheck disable=SC2086
    [ -n "$pids" ] && kill -TERM $pids 2>/dev/null
    sleep 2
    pids=$(descendants $$)
    # shellcheck disable=SC2086
    [ -n "$pids" ] && kill -KILL $pids 2>/dev/null
    echo "reflcheck nightly: interrupted; run $id left incomplete in $run (history and latest unchanged)" >&9
    exit 130
}
# The trap runs inside whatever step was waiting, with that step's redirections: fd 9 keeps the
# nightly's own stderr, so the message above reaches the user and not a step's log file.
exec 9>&2
trap stop_all INT TERM HUP
step() {
    "$@" &
    wait $!
}

# A run that ended before its report (Slurm refused a submission): one history line with status
# failed and the reason, so that the history lists every run that was started.
record_failed() {
    echo "reflcheck nightly: $1" >&2
    /usr/bin/python3 harness/report.py --run "$run" --history "$history" --commit "$commit" --failed "$1" ||
        echo "reflcheck nightly: could not record the failed run in $history" >&2
}

# Waits until Slurm job $1 has left the queue (finished in any way).
# squeue failing for 10 minutes in a row (the controller gone) ends the wait with status 1: the
# jobs may still finish, and the run's folder holds whatever they wrote.
slurm_wait() {
    local state failures=0
    while :; do
        if state=$(squeue -h -j "$1" -o %T 2>/dev/null); then
            failures=0
            [ -z "$state" ] && return 0
        else
            failures=$((failures + 1))
            [ $failures -ge 300 ] && return 1
        fi
        step sleep 2
    done
}

rc=0
t0=$(date +%s)
plan_out=$run/jobs.mk
[ "$scheduler" = slurm ] && plan_out=$run/submit.sh
step "$bin" plan "${scenes[@]}" --out "$run" --cache "$cache" --bin "$bin" $small --scheduler "$scheduler" > "$plan_out"
st=$?
if [ $st -ne 0 ]; then
    echo "reflcheck nightly: plan refused the scenes (exit $st); nothing rendered" >&2
    exit $st
fi
sweep_args=(--run "$run" --cache "$cache/sweep" --bin "$bin" --jobs "$jobs" --scenes "${scenes[@]}" ${SMALL:+--quick})
if [ "$scheduler" = make ]; then
    step make -k -j"$jobs" -f "$run/jobs.mk" all || { echo "reflcheck nightly: some render jobs failed" >&2; rc=1; }
    t1=$(date +%s)
    echo "$((t1 - t0))" > "$run/render_wall_s"
    # Error against time (harness/sweep.py): quality knobs of every renderer on the scenes that list
    # cycles validate, small size, one thread per job, $jobs jobs at a time.
    if [ -z "${NO_SWEEP:-}" ]; then
        step /usr/bin/python3 harness/sweep.py "${sweep_args[@]}" > "$run/sweep.txt" 2>&1 ||
            { echo "reflcheck nightly: sweep failed; see $run/sweep.txt" >&2; rc=1; }
    fi
    step "$bin" compare "${scenes[@]}" --run "$run" > "$run/compare.txt"
    st=$?
else
    mkdir -p "$run/slurm"
    step bash "$run/submit.sh" > "$run/slurm/render_ids" 2> "$run/slurm/submit.err"
    st=$?
    cat "$run/slurm/submit.err" >&2
    deps=$(cat "$run/slurm/render_ids")
    if [ $st -ne 0 ] || [ -z "$deps" ]; then
        ids=$(slurm_jobs)
        # shellcheck disable=SC2086
        [ -n "$ids" ] && scancel $ids
        record_failed "submitting the render jobs to Slurm failed (exit $st): $(tail -n1 "$run/slurm/submit.err" 2>/dev/null)"
        exit 1
    fi
    if [ -z "${NO_SWEEP:-}" ]; then
        # One node, JOBS CPUs: the sweep's Blender workers and their srun steps share the node.
        sweep_id=$(sbatch --parsable -N1 -n1 -c "$jobs" --time="${SWEEP_MINUTES:-240}" --job-name=reflcheck-sweep \
            --output="$run/sweep.txt" harness/slurm/step.sh "$run/sweep.rc" \
            /usr/bin/python3 harness/sweep.py "${sweep_args[@]}" --scheduler slurm) ||
            { echo "reflcheck nightly: submitting the sweep to Slurm failed" >&2; rc=1; }
        sweep_id=${sweep_id%%;*}
        [ -n "$sweep_id" ] && { echo "$sweep_id" >> "$run/slurm/steps"; deps=$deps:$sweep_id; }
    fi
    compare_id=$(sbatch --parsable --dependency="afterany:$deps" -n1 -c1 --time=60 --job-name=reflcheck-compare \
        --output="$run/slurm/compare.out" harness/slurm/compare.sh "$run" "$bin" "${scenes[@]}" 2> "$run/slurm/submit.err")
    compare_id=${compare_id%%;*}
    if [ -z "$compare_id" ]; then
        ids=$(slurm_jobs)
        # shellcheck disable=SC2086
        [ -n "$ids" ] && scancel $ids
        record_failed "submitting the compare step to Slurm failed: $(tail -n1 "$run/slurm/submit.err" 2>/dev/null)"
        exit 1
    fi
    echo "$compare_id" >> "$run/slurm/steps"
    echo "reflcheck nightly: Slurm jobs: renders $(cut -d' ' -f1 "$run/slurm/arrays" | paste -sd' '), sweep ${sweep_id:--}, compare $compare_id"
    if ! slurm_wait "$compare_id"; then
        record_failed "Slurm stopped answering (squeue failed for 10 minutes) while job $compare_id was queued"
        exit 1
    fi
    t1=$(date +%s)
    echo "$((t1 - t0))" > "$run/render_wall_s"
    [ "$(cat "$run/slurm/finish.rc" 2>/dev/null)" = 0 ] ||
        { echo "reflcheck nightly: some render jobs failed; see $run/slurm/finish.txt" >&2; rc=1; }
    if [ -n "${sweep_id:-}" ] && [ "$(cat "$run/sweep.rc" 2>/dev/null)" != 0 ]; then
        echo "reflcheck nightly: sweep failed; see $run/sweep.txt" >&2
        rc=1
    fi
    st=$(cat "$run/compare.rc" 2>/dev/null || echo 1)
fi
cat "$run/compare.txt"
[ $st -ne 0 ] && { echo "reflcheck nightly: comparisons failed or errored (compare exit $st)" >&2; rc=1; }
# The best each approximation can do (harness/fit.h): its parameters fitted to every validate
# reference, which the job cache hands back without rendering again, within the seeds' ranges
# (RUN/<scene>/fit.json) and within wide ones (fit-wide.json).
: > "$run/fit.txt"
for bounds in seed wide; do
    step "$bin" fit "${scenes[@]}" --out "$run" --cache "$cache" --bounds $bounds $small >> "$run/fit.txt" 2>&1
    st=$?
    [ $st -ne 0 ] && { echo "reflcheck nightly: a fit failed (fit --bounds $bounds exit $st); see $run/fit.txt" >&2; rc=1; }
done
cat "$run/fit.txt"
step "$bin" stability --json "$run/stability.json" > "$run/stability.txt" ||
    { echo "reflcheck nightly: stability failed; see $run/stability.txt" >&2; rc=1; }
if [ -f harness/plots/figure1.gp ]; then
    for p in 2 4 5; do step "$bin" eval fresnel --ior 1.5 --p $p --steps 900 > "$run/p$p.csv"; done
    step gnuplot -e "dir='$run'" harness/plots/figure1.gp > /dev/null 2>&1 || echo "figure1 plot failed" >&2
fi
step /usr/bin/python3 harness/report.py --run "$run" --history "$history" --commit "$commit" \
    ${reference_history:+--reference-history "$reference_history"} --latest "$latest" $screenshot ||
    { echo "reflcheck nightly: the report failed" >&2; rc=1; }
# A report that failed before it appended the run's line (a full disk): the run is still recorded.
grep -qF "\"run_id\":\"$id\"" "$history" 2> /dev/null ||
    { record_failed "the report failed before it recorded the run; see the messages above"; rc=1; }
echo "reflcheck nightly: report at $run/index.html ($latest/index.html); exit $rc"
exit $rc
