#!/usr/bin/env bash
# Runs every unit-test program in BUILD/tests (cmocka), JOBS of them at a time (default: the
# CPU count; many wait on a renderer they started), prints each program's output whole and in
# name order, sums their test counts into one closing line, and fails if any test or program
# failed. The programs are independent: each works in folders named by its own pid.
set -u
build=${1:-build}
cd "$(dirname "$0")/.."
jobs=${JOBS:-$(nproc 2>/dev/null || echo 2)}
out=$(mktemp -d "${TMPDIR:-/tmp}/reflcheck-unit-XXXXXX") || exit 1
trap 'rm -rf "$out"' EXIT
progs=()
for t in "$build"/tests/test_*; do
    [ -x "$t" ] || continue
    case "$t" in *.d|*.o) continue;; esac
    progs+=("$t")
done
running=0
for t in "${progs[@]}"; do
    if [ "$running" -ge "$jobs" ]; then wait -n; running=$((running - 1)); fi
    n=$(basename "$t")
    ( REFLCHECK_BIN="$build/reflcheck" "$t" > "$out/$n.out" 2>&1; echo $? > "$out/$n.rc" ) &
    running=$((running + 1))
done
wait
passed=0; failed=0; bad=()
for t in "${progs[@]}"; do
    n=$(basename "$t")
    cat "$out/$n.out"
    rc=$(cat "$out/$n.rc" 2>/dev/null || echo 1)
    p=$(sed -n 's/^\[  PASSED  \] \([0-9]*\) test(s)\.$/\1/p' "$out/$n.out" | tail -n 1)
    f=$(sed -n 's/^\[  FAILED  \] \([0-9]*\) test(s), listed below:$/\1/p' "$out/$n.out" | tail -n 1)
    passed=$((passed + ${p:-0})); failed=$((failed + ${f:-0}))
    # A program that crashed or failed without a cmocka summary still counts as a failure.
    if [ "$rc" -ne 0 ]; then bad+=("$n"); [ -z "$f" ] && failed=$((failed + 1)); fi
done
[ ${#bad[@]} -gt 0 ] && echo "failing programs ($build): ${bad[*]}"
echo "unit ($build): $passed passed, $failed failed"
[ "$failed" -eq 0 ] && [ ${#bad[@]} -eq 0 ]
