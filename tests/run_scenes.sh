#!/usr/bin/env bash
# Threshold-gated scene tests: every canonical scene, small, in every renderer it lists
# (the real POV-Ray and Blender), compared against the thresholds in the scene files.
# Fails naming the scene, comparison, metric, value and threshold.
set -uo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
bin=$build/reflcheck
run=${RUN_DIR:-$build/test-run}
scenes=${SCENES:-$(ls scenes/*.yaml)}
cache=${CACHE:-$build/cache}
rm -rf "$run"
mkdir -p "$run"
# shellcheck disable=SC2086
"$bin" plan $scenes --out "$run" --cache "$cache" --small --bin "$bin" > "$run/jobs.mk" || exit 2
make -s -k -j"${JOBS:-2}" -f "$run/jobs.mk" all
pass=0; fail=0
for s in $scenes; do
    if "$bin" compare "$s" --run "$run"; then pass=$((pass + 1)); else fail=$((fail + 1)); fi
done
echo "scenes: $pass passed, $fail failed"
[ "$fail" -eq 0 ]
