#!/usr/bin/env bash
# Runs every unit-test program in BUILD/tests (cmocka), sums their test counts into one
# closing line, and fails if any test or program failed.
set -u
build=${1:-build}
cd "$(dirname "$0")/.."
passed=0; failed=0; bad=()
for t in "$build"/tests/test_*; do
    [ -x "$t" ] || continue
    case "$t" in *.d|*.o) continue;; esac
    out=$(REFLCHECK_BIN="$build/reflcheck" "$t" 2>&1); rc=$?
    printf '%s\n' "$out"
    p=$(printf '%s\n' "$out" | sed -n 's/^\[  PASSED  \] \([0-9]*\) test(s)\.$/\1/p' | tail -n 1)
    f=$(printf '%s\n' "$out" | sed -n 's/^\[  FAILED  \] \([0-9]*\) test(s), listed below:$/\1/p' | tail -n 1)
    passed=$((passed + ${p:-0})); failed=$((failed + ${f:-0}))
    # A program that crashed or failed without a cmocka summary still counts as a failure.
    if [ "$rc" -ne 0 ]; then bad+=("$(basename "$t")"); [ -z "$f" ] && failed=$((failed + 1)); fi
done
[ ${#bad[@]} -gt 0 ] && echo "failing programs ($build): ${bad[*]}"
echo "unit ($build): $passed passed, $failed failed"
[ "$failed" -eq 0 ] && [ ${#bad[@]} -eq 0 ]
