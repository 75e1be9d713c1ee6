#!/usr/bin/env bash
# compare_cache.sh - `reflcheck compare` through a cache, so that a nightly run over an unchanged
# tree hands back each scene's measurements instead of measuring every image pair again.
#
# Usage: [COMPARE_JOBS=N] bash ops/compare_cache.sh CACHE BIN RUN SCENE.yaml...
#   prints what `BIN compare SCENE... --run RUN` prints (one summary line a scene, in the
#   scenes' order; "FAIL ..." lines on stderr) and leaves RUN/<scene>/compare.json and view.js;
#   the scenes whose inputs are unchanged come from CACHE/compare/<key>/, the others are
#   compared and kept: in one call, or split over COMPARE_JOBS calls at a time (default 1), or
#   with COMPARE_SLOTS=FIFO one call a scene, each holding a slot (one byte) of that FIFO while it
#   runs: the nightly's fits take slots from the same FIFO, so both share JOBS cores as one queue.
#   Exit status: compare's (0 every comparison passed, warned or was skipped; 1 one failed or
#   errored, or compare failed; 2 bad input), the worst of the calls.
# The key (SHA-256) covers what compare reads: the scene file's bytes (its comparisons and
# gates), the reflcheck program (path, size, modification time: a rebuilt one compares again)
# and the cache key and status of every render record in RUN/<scene>/ (each key covers the
# scene's meshes and images, the renderer and the code behind it; the status, a job that failed
# this time). A scene whose records are not there, or whose compare wrote no summary line, is
# not kept. compare.json keeps the render times of the run that measured it: a cached render's
# record carries the same times, rounded to the microsecond.
set -uo pipefail
[ $# -ge 4 ] || { echo "compare_cache.sh: usage: CACHE BIN RUN SCENE.yaml..." >&2; exit 2; }
cache=$1 bin=$2 run=$3
shift 3
binstat=$(stat -Lc '%s %Y' "$bin" 2> /dev/null) || exec "$bin" compare "$@" --run "$run"
binpath=$(readlink -f "$bin")
# key SCENE: the scene's cache key, with its folder in dir[SCENE]; empty when it has none.
declare -A dir key
for s in "$@"; do
    d=$(grep -lF "\"scene_path\":	\"$s\"" "$run"/*/*.json 2> /dev/null | head -n1)
    d=${d%/*}
    # The render records only: the fits (fit.json, fit-wide.json), which the nightly runs beside
    # the compare, and the compare's own compare.json name keys and statuses too, and whether
    # they are there yet must not change the key.
    keys=$([ -n "$d" ] && for f in "$d"/*.json; do
        case ${f##*/} in fit.json | fit-wide.json | compare.json | figure1.json) ;; *) grep -hoE '"(key|status)":[[:space:]]*"[^"]*"' "$f" ;; esac
    done 2> /dev/null | sort)
    [ -z "$d" ] || [ -z "$keys" ] || [ ! -r "$s" ] && continue
    dir[$s]=$d
    key[$s]=$({
        echo "reflcheck-compare-cache 1 $binpath $binstat"
        sha256sum < "$s"
        echo "$keys"
    } | sha256sum | cut -c1-32)
done
# The misses, compared in one call (it reads every scene first: a bad one refuses them all),
# or in COMPARE_JOBS calls of every COMPARE_JOBS-th scene, one process each: compare is one
# thread and a scene's measurement is its own (RUN/<scene>/), so the nightly, whose plan read
# and checked every scene before rendering, measures its 34 scenes in about half the 14 s.
# A bad scene then refuses its own call's scenes only.
todo=()
for s in "$@"; do
    k=${key[$s]:-}
    [ -n "$k" ] && [ -f "$cache/compare/$k/ok" ] || todo+=("$s")
done
out=$(mktemp) && errs=$(mktemp) && parts=$(mktemp -d) || exit 1
trap 'rm -rf "$out" "$errs" "$parts"' EXIT
st=0
calls=${COMPARE_JOBS:-1}
[[ $calls =~ ^[1-9][0-9]*$ ]] || { echo "compare_cache.sh: COMPARE_JOBS '$calls': give a count >= 1" >&2; exit 2; }
slots=${COMPARE_SLOTS:-}
if [ -n "$slots" ]; then
    [ -p "$slots" ] || { echo "compare_cache.sh: COMPARE_SLOTS '$slots' is not a FIFO; give the nightly's slot FIFO or unset it" >&2; exit 2; }
    exec {slot_fd}<> "$slots" || exit 2
    calls=${#todo[@]}
fi
# slot_run CMD...: CMD while holding one byte (a slot) of COMPARE_SLOTS, handed back after.
slot_run() {
    local tok st
    [ -z "$slots" ] && { "$@"; return; }
    read -r -N1 -u "$slot_fd" tok
    "$@"
    st=$?
    printf '%s' "$tok" >&"$slot_fd"
    return $st
}
if [ ${#todo[@]} -gt 0 ]; then
    pids=()
    for ((c = 0; c < calls && c < ${#todo[@]}; c++)); do
        part=()
        for ((i = c; i < ${#todo[@]}; i += calls)); do part+=("${todo[i]}"); done
        slot_run "$bin" compare "${part[@]}" --run "$run" > "$parts/$c.out" 2> "$parts/$c.err" &
        pids+=($!)
    done
    for c in "${!pids[@]}"; do
        wait "${pids[c]}"
        rc=$?
        [ $rc -gt $st ] && st=$rc
        cat "$parts/$c.out" >> "$out"
        cat "$parts/$c.err" >> "$errs"
    done
    cat "$errs" >&2
    [ $st = 2 ] && { cat "$out"; exit 2; }
fi
# summary LINE: 1 when it counts a failed or errored comparison.
failing() { [[ $1 =~ fail\ ([0-9]+)\ +skipped\ [0-9]+\ +error\ ([0-9]+) ]] && [ $((BASH_REMATCH[1] + BASH_REMATCH[2])) -gt 0 ]; }
for s in "$@"; do
    k=${key[$s]:-}
    entry=$cache/compare/$k
    if [ -n "$k" ] && [ -f "$entry/ok" ] && cp "$entry/compare.json" "${dir[$s]}/compare.json.tmp.$$" 2> /dev/null &&
        cp "$entry/view.js" "${dir[$s]}/view.js.tmp.$$" 2> /dev/null; then
        mv "${dir[$s]}/compare.json.tmp.$$" "${dir[$s]}/compare.json"
        mv "${dir[$s]}/view.js.tmp.$$" "${dir[$s]}/view.js"
        line=$(cat "$entry/line")
        echo "$line"
        [ -s "$entry/fail" ] && cat "$entry/fail" >&2
        failing "$line" && [ $st = 0 ] && st=1
        continue
    fi
    rm -f "${dir[$s]:-/nonexistent}/compare.json.tmp.$$" "${dir[$s]:-/nonexistent}/view.js.tmp.$$"
    line=
    while IFS= read -r l; do # the scene's line: its path, spaces, "pass N ..."
        if [[ $l == "$s "* ]] && [[ ${l#"$s"} =~ ^\ +pass\  ]]; then
            line=$l
            break
        fi
    done < "$out"
    [ -n "$line" ] && echo "$line"
    # A scene measured now and whole (its line printed, both files there) is kept for the next
    # run, published by rename; a concurrent run that published first keeps its entry.
    if [ -n "$k" ] && [ -n "$line" ] && [ -f "${dir[$s]}/compare.json" ] && [ -f "${dir[$s]}/view.js" ] &&
        mkdir -p "$cache/compare" && tmp=$(mktemp -d "$cache/compare/tmp-$k-XXXXXX"); then
        # compare's "FAIL <scene name>: ..." line on stderr, replayed with the entry.
        if cp "${dir[$s]}/compare.json" "${dir[$s]}/view.js" "$tmp/" && echo "$line" > "$tmp/line" &&
            { grep -F -- "FAIL ${dir[$s]##*/}: " "$errs" > "$tmp/fail" || true; } && : > "$tmp/ok"; then
            mv -T "$tmp" "$entry" 2> /dev/null || rm -rf "$tmp"
        else
            rm -rf "$tmp"
        fi
    fi
done
exit $st
