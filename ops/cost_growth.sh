#!/usr/bin/env bash
# How the nightly's cost grows with the number of scenes: the nightly (local make, test-size
# renders, no sweep, no screenshot, JOBS at a time, a fresh cache each) on the first 1, 10 and
# 24 canonical scenes and on 100 generated variants of them (ops/cost_scenes.py, written to
# OUT/scenes100, never into scenes/). Each run's folder gets cost.txt: the nightly's wall time,
# its CPU time (user + sys of the nightly and every process it waited for, renderers included)
# and the load average before and after (the machine may be shared); and calls.tsv: every call
# of the reflcheck program (plan, each job's run, compare, fit, stability, eval) with its wall
# and CPU seconds, the renderer it started included, through OUT/reflcheck, a wrapper the
# nightly is given as its BIN. Then tools/cost_table.py OUT/runs/scenes-* writes the table
# (docs/cost.md). Beside them, Blender's start-up CPU seconds (the median of three
# `blender -b --factory-startup` that do nothing), which the nightly's Cycles jobs do not pay
# (a worker pool renders them) but each Cycles job under Slurm does: cost.txt's
# blender_start_cpu_s, for the table's Slurm estimate.
#
# Usage: bash ops/cost_growth.sh BUILD [OUT] [COUNT...]    (from the project root)
#   bash ops/cost_growth.sh build build/cost            # 1, 10, 24 and 100 scenes
#   bash ops/cost_growth.sh build build/cost 1 10       # only those counts (at most the
#                                                         # canonical scenes' number, or 100)
#   /usr/bin/python3 tools/cost_table.py build/cost/runs/scenes-* > docs/cost.md
#   bash ops/cost_growth.sh build build/cost blender-start   # only measure Blender's start-up
#                                                         # again, into the runs' cost.txt
# OUT defaults to BUILD/cost; everything is written there (git ignores build folders).
# The runs take an hour or more; to go on editing the tree meanwhile, run them from a copy of a
# commit and name it to the table (the nightly, in the copy, cannot):
#   d=build-cost/tree; rm -rf "$d"; mkdir -p "$d"; git archive HEAD | tar -x -C "$d"
#   cp -a build "$d/build"; (cd "$d" && bash ops/cost_growth.sh build "$PWD/../../build/cost")
#   /usr/bin/python3 tools/cost_table.py --copy-of "$(git rev-parse --short HEAD)" build/cost/runs/scenes-*
# JOBS (default 2) render jobs at a time. Exit status: 0 when every nightly ran (a nightly's
# own failed comparison does not count: the cost is what is measured), 1 otherwise, 2 bad usage.
set -uo pipefail
cd "$(dirname "$0")/.." || exit 2
build=${1:?usage: bash ops/cost_growth.sh BUILD [OUT] [COUNT...]}
out=${2:-$build/cost}
case $out in /*) ;; *) out=$PWD/$out ;; esac
shift $(($# < 2 ? $# : 2))
counts=("$@")
[ ${#counts[@]} -gt 0 ] || counts=(1 10 24 100)
jobs=${JOBS:-2}
[ -x "$build/reflcheck" ] || { echo "cost_growth: $build/reflcheck is not built; run make all" >&2; exit 2; }
mkdir -p "$out/runs"
# Blender's start-up, CPU seconds (user + sys), median of three; "-" without Blender.
blender_start() {
    command -v blender > /dev/null || { echo -; return; }
    for i in 1 2 3; do
        /usr/bin/time -f '%U %S' -o "$out/blender-start.$i" blender -b --factory-startup --python-expr pass \
            > /dev/null 2>&1 || { echo -; return; }
    done
    tail -qn 1 "$out"/blender-start.[123] | awk '{ print $1 + $2 }' | sort -g | sed -n 2p
}
bstart=$(blender_start)
echo "cost_growth: Blender's start-up: $bstart CPU-s" >&2
if [ "${counts[*]}" = blender-start ]; then
    for c in "$out"/runs/scenes-*/cost.txt; do
        [ -f "$c" ] || continue
        sed -i '/^blender_start_cpu_s /d' "$c" && echo "blender_start_cpu_s $bstart" >> "$c"
    done
    exit 0
fi
# The wrapper: one line per call, appended (O_APPEND: whole short lines from parallel jobs).
real_bin=$(cd "$(dirname "$build/reflcheck")" && pwd)/reflcheck
cat > "$out/reflcheck" << SH
#!/bin/sh
exec /usr/bin/time -a -o "\$REFLCHECK_CALLS" -f '%e\t%U\t%S\t%C' "$real_bin" "\$@"
SH
chmod +x "$out/reflcheck"
canonical=(scenes/*.yaml)
rc=0
for n in "${counts[@]}"; do
    if [ "$n" = 100 ]; then
        rm -rf "$out/scenes100"
        mapfile -t list < <(/usr/bin/python3 ops/cost_scenes.py 100 "$out/scenes100") || exit 1
    elif [ "$n" -ge 1 ] 2> /dev/null && [ "$n" -le ${#canonical[@]} ]; then
        list=("${canonical[@]:0:$n}")
    else
        echo "cost_growth: count '$n': give 1 to ${#canonical[@]} (canonical scenes) or 100 (variants)" >&2
        exit 2
    fi
    run=$out/runs/scenes-$n
    rm -rf "$run" "$out/cache-$n"
    load0=$(cut -d' ' -f1-3 /proc/loadavg)
    echo "cost_growth: $n scenes, $jobs jobs at a time (load $load0)" >&2
    rm -f "$out/calls-$n.tsv"
    /usr/bin/time -f '%e %U %S' -o "$out/time-$n" \
        env SMALL=1 NO_SWEEP=1 NO_SCREENSHOT=1 JOBS="$jobs" SCHEDULER=make BIN="$out/reflcheck" \
        REFLCHECK_CALLS="$out/calls-$n.tsv" \
        RUNS="$out/runs" RUN_ID="scenes-$n" CACHE="$out/cache-$n" HISTORY="$out/history.jsonl" \
        LATEST="$out/latest-$n" REFERENCE_HISTORY= bash ops/nightly.sh "${list[@]}" > "$out/nightly-$n.log" 2>&1
    st=$?
    load1=$(cut -d' ' -f1-3 /proc/loadavg)
    if [ ! -d "$run" ]; then
        echo "cost_growth: the $n-scene nightly made no run folder (exit $st); see $out/nightly-$n.log" >&2
        rc=1
        continue
    fi
    mv "$out/calls-$n.tsv" "$run/calls.tsv"
    # GNU time puts "Command exited with non-zero status N" before its line when the status is not 0.
    read -r wall user sys < <(tail -n 1 "$out/time-$n")
    printf 'scenes %s\njobs_at_a_time %s\nexit %s\nwall_s %s\nuser_s %s\nsys_s %s\nload_before %s\nload_after %s\ncpus %s\nblender_start_cpu_s %s\n' \
        "$n" "$jobs" "$st" "$wall" "$user" "$sys" "$load0" "$load1" "$(nproc)" "$bstart" > "$run/cost.txt"
    echo "cost_growth: $n scenes: exit $st, $wall s wall, $user + $sys CPU-s (load $load1)" >&2
done
exit $rc
