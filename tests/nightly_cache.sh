#!/usr/bin/env bash
# A second nightly run over the same cache does none of the work again: the fits come back from
# CACHE/fits (ops/fit_cache.sh) and the stability table from CACHE/stability, equal to the
# first run's; a changed scene file fits again; stages.tsv holds each stage's CPU seconds; the
# second run renders, measures, fits, tabulates and plots nothing anew (job records, cache entries and
# report.py's plot line say so), and a run with the cache bypassed is seen to do each of them.
# Scene: d3d_scaled (raster against POV-Ray and the
# exact renderer: validate references to fit, no Blender), small, no sweep.
# Usage: bash tests/nightly_cache.sh BUILD
set -uo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
work=$PWD/$build/nightly-cache-test
rm -rf "$work"
mkdir -p "$work"
pass=0
fail=0
ok() { pass=$((pass + 1)); echo "cache: $*"; }
bad() { fail=$((fail + 1)); echo "cache: FAILED: $*"; }
nightly() { # RUN_ID SCENE [OPTION...]: one run into $work, its stderr in $work/RUN_ID.err
    REFLCHECK_PROGRESS=log bash ops/nightly.sh --small --no-sweep --no-screenshot --bin "$build/reflcheck" \
        --runs "$work/runs" --cache "$work/cache" --history "$work/history.jsonl" --latest "$work/latest" \
        --run-id "$1" "${@:2}" > "$work/$1.out" 2> "$work/$1.err"
}
entries() { find "$work/cache/fits" -mindepth 2 -maxdepth 2 -name ok 2> /dev/null | wc -l; }
scene=scenes/d3d_scaled.yaml
nightly first "$scene" && ok "first run exit 0" || bad "first run exit $? ($work/first.err)"
n1=$(entries)
[ "$n1" = 2 ] && ok "two fits (seed and wide bounds) kept in the cache" || bad "$n1 fits kept, not 2"
nightly second "$scene" && ok "second run exit 0" || bad "second run exit $? ($work/second.err)"
# A fit that ran again would print its own timing ("(N evaluations, M renders, T s)"): the same text is the kept one.
if cmp -s "$work/runs/first/fit.txt" "$work/runs/second/fit.txt" && [ "$(entries)" = 2 ]; then
    ok "second run: the fits came back from the cache"
else
    bad "second run fitted again (fit.txt differs or new cache entries)"
fi
# One job at a time: the seed fit comes back (its fit.json rewritten into this run) before the
# wide fit takes its key, which must not read that file: no new entry.
nightly serial "$scene" --jobs 1 || bad "serial run: exit $?"
[ "$(entries)" = 2 ] && ok "one fit at a time: both fits from the cache" ||
    bad "one fit at a time: $(($(entries) - 2)) fits ran again (the key read the other fit's record)"
# The kept record equals the first run's but for its references, which name the second run's
# records (the renders this run holds) of the same cache keys.
same_fit='
import json, os, sys
first, second, folder = sys.argv[1:]
a, b = (json.load(open(p, encoding="utf-8")) for p in (first, second))
refs = []
for fit in b["fits"]:
    job = fit.pop("reference_job", None) or {}
    refs.append((job, fit.pop("reference_exr", None)))
for fit in a["fits"]:
    fit.pop("reference_job", None), fit.pop("reference_exr", None)
assert a == b, "the fit differs"
for job, exr in refs:
    rec = json.load(open(job["record"], encoding="utf-8"))
    assert os.path.dirname(job["record"]) == folder, job["record"]
    assert job["key"] == rec["key"] and exr == rec["exr"], job
'
for f in fit.json fit-wide.json; do
    /usr/bin/python3 -c "$same_fit" "$work/runs/first/d3d_scaled/$f" "$work/runs/second/d3d_scaled/$f" \
        "$work/runs/second/d3d_scaled" &&
        ok "$f equal to the first run's, its references the second run's records" ||
        bad "$f differs from the first run's, or its references are not the second run's records"
done
grep -q "stability: unchanged program" "$work/second.err" && ! grep -q "stability: unchanged" "$work/first.err" &&
    cmp -s "$work/runs/first/stability.json" "$work/runs/second/stability.json" &&
    ok "second run: the stability table from the cache, equal" || bad "stability table not taken from the cache"
cmp -s <(grep -v '^reflcheck' "$work/runs/first/compare.txt") <(grep -v '^reflcheck' "$work/runs/second/compare.txt") &&
    ok "same verdicts" || bad "verdicts differ between the runs"
# Each stage's wall and CPU seconds: the first run's fits column holds at least the CPU time the
# fits themselves measured in their processes (their records' cpu_seconds; CPU against CPU, so
# the machine's load moves neither side: wall seconds would), less 0.1 s for the column's one
# decimal; the second's almost none (copying two files: under 1 s even on a loaded machine).
fit_cpu=$(grep -ho '"cpu_seconds":[[:space:]]*[0-9.eE+-]*' "$work/runs/first/d3d_scaled"/fit*.json 2> /dev/null |
    awk -F: '{ s += $2 } END { print s + 0 }')
awk -F'\t' -v need="$fit_cpu" '$1 == "fits" && NF == 3 && need > 0 && $3 >= need - 0.1 { f = 1 } END { exit !f }' \
    "$work/runs/first/stages.tsv" &&
    awk -F'\t' '$1 == "fits" && NF == 3 && $3 < 1.0 { f = 1 } END { exit !f }' "$work/runs/second/stages.tsv" &&
    ok "stages.tsv: the fits' CPU seconds, first run (the fits' own $fit_cpu CPU-s) and (less than 1 s) second" ||
    bad "stages.tsv lacks the fits' CPU seconds (the fits say $fit_cpu CPU-s) or the second run's fits took CPU: first $(tr '\n\t' '; ' < "$work/runs/first/stages.tsv") second $(tr '\n\t' '; ' < "$work/runs/second/stages.tsv")"
# What a run did anew rather than take from its cache, one line each (none: all reused), by
# markers, not time: a job record not "cached": true; a fit or compare entry CACHE/fits or
# CACHE/compare gained (arguments 3 and 4: the counts before the run); a stability table not
# taken from CACHE/stability; a plot report.py drew other than the trend (which gains the
# run's own history line).
reran() { # RUN_ID CACHE FITS_BEFORE COMPARES_BEFORE
    local r=$work/runs/$1 f
    for f in "$r"/*/*.json; do
        grep -q '"cached":' "$f" && ! grep -qE '"cached":[[:space:]]*true' "$f" && echo "render ${f#"$r"/}"
    done
    local fits compares
    fits=$(find "$2/fits" -mindepth 2 -maxdepth 2 -name ok 2> /dev/null | wc -l)
    [ "$fits" != "$3" ] && echo "fits: $((fits - $3)) new cache entries"
    compares=$(find "$2/compare" -mindepth 2 -maxdepth 2 -name ok 2> /dev/null | wc -l)
    [ "$compares" != "$4" ] && echo "compare: $((compares - $4)) new cache entries"
    grep -q "stability: unchanged program" "$work/$1.err" || echo "stability table computed"
    grep -q '^report: plots: ' "$r/report.txt" || echo "report: no plot cache line"
    sed -n 's/^report: plots: [0-9]* drawn by gnuplot (\(.*\)), .*/\1/p' "$r/report.txt" | tr ',' '\n' |
        grep -vE '^ *([0-9]+ trend|none)$' | sed 's/^ */report plots drawn: /'
}
again=$(reran second "$work/cache" 2 1)
[ -z "$again" ] && ok "second run: no render, compare, fit, stability table or plot (but the trend) done again" ||
    bad "second run did again: $(echo "$again" | head -n5 | paste -sd';')"
# The control: the same run with every cache bypassed (a new, empty one) shows each kind of work.
nightly bypass "$scene" --cache "$work/cache-bypass" || bad "bypass run: exit $?"
again=$(reran bypass "$work/cache-bypass" 0 0)
for what in "^render " "^fits: " "^compare: " "^stability table" "^report plots drawn: "; do
    echo "$again" | grep -q "$what" && ok "bypassed cache: seen ($what)" || bad "bypassed cache: not seen ($what): $again"
done
# The scene changed (one comment line more): its fits run again.
mkdir -p "$work/scenes"
{ echo "# changed"; cat "$scene"; } > "$work/scenes/d3d_scaled.yaml"
nightly third "$work/scenes/d3d_scaled.yaml" && ok "changed scene: exit 0" || bad "changed scene: exit $?"
[ "$(entries)" = 4 ] && ok "changed scene: fitted again" || bad "changed scene: $(entries) cache entries, not 4"
echo "cache: $pass passed, $fail failed"
[ $fail -eq 0 ]
