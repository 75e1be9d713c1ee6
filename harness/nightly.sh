#!/usr/bin/env bash
# The nightly run (`make report`): every canonical scene in every renderer its comparisons
# list, full size; then metrics, the stability table and the report. A run writes only into
# its own folder reports/runs/<id>; reports/latest moves to it at the very end and the
# history gets one appended line, so a run killed midway leaves both as they were.
#
# Exit status: 0 when every job ran (or was skipped: renderer not installed, or it cannot
# represent the scene) and no comparison failed; 1 when a job or step failed or a comparison
# failed or errored (the run is still reported and recorded, with its status); 2 bad input.
# Killed or interrupted (SIGINT, SIGTERM, SIGHUP), it stops every process it started,
# renderers included, before it exits.
#
# Settings (environment): BIN, JOBS, RUNS, HISTORY, LATEST, CACHE, SCENES, RUN_ID, SMALL=1
# (test-size renders), NO_SWEEP=1, NO_SCREENSHOT=1 (any non-empty value).
set -uo pipefail
cd "$(dirname "$0")/.."
bin=${BIN:-build/reflcheck}
jobs=${JOBS:-2}
runs=${RUNS:-reports/runs}              # where run folders go
history=${HISTORY:-reports/history.jsonl}
latest=${LATEST:-reports/latest}
cache=${CACHE:-reports/cache}
small=${SMALL:+--small}                 # SMALL=1: the test-size renders (used by the kill test)
screenshot=--screenshot
[ -n "${NO_SCREENSHOT:-}" ] && screenshot=
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
scenes=${SCENES:-$(ls scenes/*.yaml)}
mkdir -p "$runs" || exit 1
if ! mkdir "$run" 2>/dev/null; then
    echo "reflcheck nightly: $run exists already; give another RUN_ID (or leave it unset)" >&2
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
stop_all() {
    trap '' INT TERM HUP
    local pids
    pids=$(descendants $$)
    # shellcheck disable=SC2086
    [ -n "$pids" ] && kill -TERM $pids 2>/dev/null
    sleep 2
    pids=$(descendants $$)
    # shellcheck disable=SC2086
    [ -n "$pids" ] && kill -KILL $pids 2>/dev/null
    echo "reflcheck nightly: interrupted; run $id left incomplete in $run (history and latest unchanged)" >&2
    exit 130
}
trap stop_all INT TERM HUP
step() {
    "$@" &
    wait $!
}

rc=0
t0=$(date +%s)
# shellcheck disable=SC2086
step "$bin" plan $scenes --out "$run" --cache "$cache" --bin "$bin" $small > "$run/jobs.mk"
st=$?
if [ $st -ne 0 ]; then
    echo "reflcheck nightly: plan refused the scenes (exit $st); nothing rendered" >&2
    exit $st
fi
step make -k -j"$jobs" -f "$run/jobs.mk" all || { echo "reflcheck nightly: some render jobs failed" >&2; rc=1; }
t1=$(date +%s)
echo "$((t1 - t0))" > "$run/render_wall_s"
# Error against time (harness/sweep.py): quality knobs of every renderer on the scenes that list
# cycles validate, small size, one thread per job, $jobs jobs at a time.
if [ -z "${NO_SWEEP:-}" ]; then
    # shellcheck disable=SC2086
    step /usr/bin/python3 harness/sweep.py --run "$run" --cache "$cache/sweep" --bin "$bin" --jobs "$jobs" \
        --scenes $scenes ${SMALL:+--quick} > "$run/sweep.txt" 2>&1 ||
        { echo "reflcheck nightly: sweep failed; see $run/sweep.txt" >&2; rc=1; }
fi
# shellcheck disable=SC2086
step "$bin" compare $scenes --run "$run" > "$run/compare.txt"
st=$?
cat "$run/compare.txt"
[ $st -ne 0 ] && { echo "reflcheck nightly: comparisons failed or errored (compare exit $st)" >&2; rc=1; }
step "$bin" stability --json "$run/stability.json" > "$run/stability.txt" ||
    { echo "reflcheck nightly: stability failed; see $run/stability.txt" >&2; rc=1; }
if [ -f harness/plots/figure1.gp ]; then
    for p in 2 4 5; do step "$bin" eval fresnel --ior 1.5 --p $p --steps 900 > "$run/p$p.csv"; done
    step gnuplot -e "dir='$run'" harness/plots/figure1.gp > /dev/null 2>&1 || echo "figure1 plot failed" >&2
fi
step /usr/bin/python3 harness/report.py --run "$run" --history "$history" --commit "$commit" \
    --latest "$latest" $screenshot || { echo "reflcheck nightly: the report failed" >&2; rc=1; }
echo "reflcheck nightly: report at $run/index.html ($latest/index.html); exit $rc"
exit $rc
