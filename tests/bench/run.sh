#!/usr/bin/env bash
# make bench: reflcheck's rasterizer against llvmpipe, POV-Ray and Cycles on the benchmark
# scene (tests/bench/README.md). Usage: tests/bench/run.sh BUILD_DIR
#   BENCH_QUICK=1    the small smoke set instead of the measurement
#   BENCH_REFS=0     skip the POV-Ray/Cycles reference renders (their columns read "pending")
# Writes reports/bench/bench.json (generated, not versioned) and prints the tables.
set -euo pipefail
build=${1:-build}
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
cd "$root"
out=reports/bench
mkdir -p "$out"
tmp=$(mktemp -d "${TMPDIR:-/tmp}/reflcheck-bench.XXXXXX")
trap 'rm -rf "$tmp"' EXIT

for bin in "$build/bench/bench_raster" "$build/bench/bench_llvmpipe"; do
    if [ ! -x "$bin" ]; then
        echo "tests/bench/run.sh: $bin is missing; build it with 'make bench' (Makefile bench recipe)" >&2
        exit 2
    fi
done

# POV-Ray and Cycles through the lead's harness, at the scene's full size; reflcheck run caches
# by content, so only the first make bench (or a changed scene/renderer) pays for them.
refs_arg=()
if [ "${BENCH_REFS:-1}" != 0 ] && [ -x "$build/reflcheck" ]; then
    for r in povray cycles; do
        if ! "$build/reflcheck" run tests/bench/bench_scene.yaml --renderer "$r" --role twin --threads 2 \
                --out "$out/refs"; then
            echo "tests/bench/run.sh: the $r reference failed; its column stays pending (see $out/refs)" >&2
        fi
    done
    refs_arg=(--refs "$out/refs")
elif [ "${BENCH_REFS:-1}" != 0 ]; then
    echo "tests/bench/run.sh: $build/reflcheck not built; POV-Ray/Cycles columns stay pending" >&2
fi

quick=()
[ "${BENCH_QUICK:-0}" != 0 ] && quick=(--quick)
# The llvmpipe rows once more through `reflcheck render` as a user runs it (README "The command line").
cli_arg=()
if [ -x "$build/reflcheck" ]; then
    cli_arg=(--cli "$build/reflcheck")
else
    echo "tests/bench/run.sh: $build/reflcheck not built; the CLI rows are not run ('make bench' builds it)" >&2
fi
status=0
"$build/bench/bench_raster" --scene tests/bench/bench_scene.yaml --llvmpipe "$build/bench/bench_llvmpipe" \
    --json "$out/bench.json" --tmp "$tmp" "${refs_arg[@]}" "${cli_arg[@]}" "${quick[@]}" || status=$?
exit $status
