#!/usr/bin/env bash
# Runs every unit-test binary in BUILD/tests, prints one summary line, fails if any failed.
set -u
build=${1:-build}
cd "$(dirname "$0")/.."
pass=0; fail=0; failed=()
for t in "$build"/tests/test_*; do
    [ -x "$t" ] || continue
    case "$t" in *.d|*.o) continue;; esac
    if REFLCHECK_BIN="$build/reflcheck" "$t"; then pass=$((pass + 1)); else fail=$((fail + 1)); failed+=("$(basename "$t")"); fi
done
echo "unit test programs ($build): ${failed[*]:+failed: ${failed[*]}}"
echo "unit: $pass passed, $fail failed"
[ "$fail" -eq 0 ]
