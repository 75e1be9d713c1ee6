#!/usr/bin/env bash
# The nightly run (`make report`): every canonical scene in every renderer its comparisons
# list, full size; then metrics, the stability table and the report. A run writes only into
# its own folder reports/runs/<id>; reports/latest moves to it at the very end and the
# history gets one appended line, so a run killed midway leaves both as they were.
set -uo pipefail
cd "$(dirname "$0")/.."
bin=${BIN:-build/reflcheck}
jobs=${JOBS:-2}
runs=${RUNS:-reports/runs}              # where run folders go
history=${HISTORY:-reports/history.jsonl}
latest=${LATEST:-reports/latest}
cache=${CACHE:-reports/cache}
small=${SMALL:+--small}                 # SMALL=1: the test-size renders (used by the kill test)
commit=$(git rev-parse --short HEAD 2>/dev/null || echo nogit)
id=${RUN_ID:-$(date -u +%Y%m%d-%H%M%S)-$commit}
run=$runs/$id
scenes=${SCENES:-$(ls scenes/*.yaml)}
mkdir -p "$run"
echo "reflcheck nightly: run $id -> $run"

t0=$(date +%s)
# shellcheck disable=SC2086
"$bin" plan $scenes --out "$run" --cache "$cache" --bin "$bin" $small > "$run/jobs.mk" || exit 2
make -k -j"$jobs" -f "$run/jobs.mk" all
t1=$(date +%s)
echo "$((t1 - t0))" > "$run/render_wall_s"
# Error against time (harness/sweep.py): quality knobs of every renderer on the scenes that list
# cycles validate, small size, one thread per job, $jobs jobs at a time.
if [ -z "${NO_SWEEP:-}" ]; then
    # shellcheck disable=SC2086
    /usr/bin/python3 harness/sweep.py --run "$run" --cache "$cache/sweep" --bin "$bin" --jobs "$jobs" \
        --scenes $scenes ${SMALL:+--quick} > "$run/sweep.txt" 2>&1 || echo "sweep failed; see $run/sweep.txt" >&2
fi
# shellcheck disable=SC2086
"$bin" compare $scenes --run "$run" | tee "$run/compare.txt"
"$bin" stability --json "$run/stability.json" > "$run/stability.txt" || true
if [ -f harness/plots/figure1.gp ]; then
    for p in 2 4 5; do "$bin" eval fresnel --ior 1.5 --p $p --steps 900 > "$run/p$p.csv"; done
    gnuplot -e "dir='$run'" harness/plots/figure1.gp > /dev/null 2>&1 || echo "figure1 plot failed" >&2
fi
/usr/bin/python3 harness/report.py --run "$run" --history "$history" --commit "$commit" \
    --latest "$latest" ${NO_SCREENSHOT:---screenshot}
rc=$?
echo "reflcheck nightly: report at $run/index.html ($latest/index.html)"
exit $rc
