#!/usr/bin/env bash
# The nightly's progress and its options:
#  1. in a log (stderr not a terminal) every stage writes plain done/total lines with the time
#     left: renders, fits, stability, report;
#  2. a render job that fails is named in the log while another job still runs: a stand-in
#     POV-Ray fails at once on one scene and holds the other scene's render until the test has
#     seen the failure named (bounded waits; no sleep-then-assert);
#  3. a skipped or errored comparison's reason names the scene key to change: the renderer's
#     own (materials[0]) and the comparison's (comparisons[0]);
#  4. the options set what their environment variables set (--runs, --cache, --history,
#     --latest, --run-id, --no-screenshot), an option wins over its variable, and --help lists
#     every option with its default and its variable.
# Usage: bash tests/nightly_progress.sh BUILD
set -uo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
work=$PWD/$build/progress-test
rm -rf "$work"
mkdir -p "$work/bin"
unset RUNS HISTORY LATEST CACHE SCENES REFERENCE REFERENCE_HISTORY RUN_ID SCHEDULER SMALL NO_SWEEP NO_SCREENSHOT
unset REFLCHECK_PROGRESS JOBS
export BIN=$PWD/$build/reflcheck
pass=0
fail=0
ok() { pass=$((pass + 1)); echo "progress: $*"; }
bad() { fail=$((fail + 1)); echo "progress: FAILED: $*"; }

# A Lambert quad under a sun, raster against its POV-Ray twin, WIDTH pixels wide (the stand-in
# POV-Ray tells the two scenes apart by the width it is asked for: +W<2 * WIDTH>).
. tests/quad_scene.sh
scene() { quad_scene "$work/$1.yaml" "$1" "$2"; }
scene fast 24
scene slow 26
# POV-Ray has no twin of Cook-Torrance: its render is skipped before POV-Ray is asked.
sed -e 's/^name: fast/name: ct/' -e 's/model: d3d}/model: cook_torrance, roughness: 0.3}/' "$work/fast.yaml" \
    > "$work/ct.yaml"
# fast fails at once; slow writes its pid and waits for the release file (at most 300 s, so a
# broken test leaves nothing behind), then fails too.
cat > "$work/bin/povray" <<SH
#!/bin/sh
case "\$*" in *--version*) echo "POV-Ray 3.7.0.10 (fake, fails)"; exit 0;; esac
case "\$*" in *+W52*)
    echo \$\$ > "$work/slow.pid"
    i=0
    while [ ! -e "$work/release" ] && [ \$i -lt 3000 ]; do sleep 0.1; i=\$((i + 1)); done ;;
esac
echo "fake povray: no render" >&2
exit 1
SH
chmod +x "$work/bin/povray"

PATH="$work/bin:$PATH" bash ops/nightly.sh --small --no-sweep --no-screenshot --jobs 2 --run-id r1 \
    --runs "$work/runs" --cache "$work/cache" --history "$work/history.jsonl" --latest "$work/latest" \
    --scenes "$work/fast.yaml" "$work/slow.yaml" "$work/ct.yaml" > "$work/run.log" 2>&1 &
pid=$!
named=0
for _ in $(seq 1500); do
    grep -q '^renders: FAILED fast/povray-twin: failed: ' "$work/run.log" && { named=1; break; }
    kill -0 "$pid" 2> /dev/null || break
    sleep 0.2
done
# The failure is named while slow's render is still held: the run has not reached its end.
held=0
[ -s "$work/slow.pid" ] && kill -0 "$(cat "$work/slow.pid")" 2> /dev/null && held=1
[ $named = 1 ] && [ $held = 1 ] && ! grep -q 'report at' "$work/run.log" &&
    ok "a failed render is named while another render still runs" ||
    bad "failure named $named, other render held $held; see $work/run.log"
: > "$work/release"
wait "$pid"
st=$?
[ $st -eq 1 ] && ok "the run with failed renders exits 1" || bad "exit $st (want 1); see $work/run.log"
for stage in 'renders: 6/6' 'fits: 6/6' 'stability: 1/1' 'report: 1/1'; do
    grep -Eq "^$stage done(, [0-9]+ failed)?, [0-9]+ s elapsed, (about [0-9]+ s left|time left unknown)\$" \
        "$work/run.log" && ok "log line: $stage done, elapsed, time left" ||
        bad "no plain '$stage done ... left' line in $work/run.log"
done
grep -q $'\r' "$work/run.log" && bad "a log got terminal rewrites (carriage returns)" ||
    ok "a log gets plain lines only"
reason() { # reason SCENE: the first comparison's status and reason
    /usr/bin/python3 -c 'import json,sys; c=json.load(open(sys.argv[1]))["comparisons"][0]
print(c["status"] + ": " + c.get("reason", ""))' "$work/runs/r1/$1/compare.json" 2> /dev/null
}
r=$(reason ct)
[[ $r == "skipped: "*"materials[0] 'm': model cook_torrance has no POV-Ray twin"*"; scene key comparisons[0]" ]] &&
    ok "a skipped comparison names the keys: $r" || bad "skipped comparison's reason: $r"
r=$(reason fast)
[[ $r == "error: "*"; scene key comparisons[0]" ]] && ok "an errored comparison names its key: $r" ||
    bad "errored comparison's reason: $r"
# A physics refusal names the physics keys: EEVEE asked for shadows (refused before Blender runs).
sed -e 's/^name: fast/name: eph/' -e 's/^comparisons:/physics: {shadows: true}\ncomparisons:/' \
    -e 's/reference: povray/reference: eevee/' -e 's/role: twin/role: validate/' "$work/fast.yaml" > "$work/eph.yaml"
"$BIN" run "$work/eph.yaml" --renderer eevee --role validate --small --out "$work/eph" > /dev/null 2>&1
r=$(/usr/bin/python3 -c 'import json,sys; r=json.load(open(sys.argv[1])); print(r["status"] + ": " + r["message"])' \
    "$work/eph/eph/eevee-validate.json" 2> /dev/null)
[[ $r == "skipped: "*"set physics.shadows and physics.interreflection false and physics.bounces 1"* ]] &&
    ok "a physics refusal names the physics keys" || bad "physics refusal: $r"
# Every option landed where it points.
[ -f "$work/runs/r1/index.html" ] && [ -L "$work/latest" ] && [ -d "$work/cache" ] &&
    grep -q '"run_id":"r1"' "$work/history.jsonl" && [ ! -e "$work/runs/r1/screenshot.png" ] &&
    ok "--runs --run-id --cache --latest --history --no-screenshot are honoured" ||
    bad "an option was not honoured; see $work/runs/r1"
grep -q $'^stability\t[0-9]' "$work/runs/r1/stages.tsv" && ok "stage times recorded for the next run's estimate" ||
    bad "no stage times in $work/runs/r1/stages.tsv"

# An option wins over its variable: JOBS=0 alone is refused; with --jobs 1 the run gets past it
# (to the refusal of a missing --bin, which names the option, not BIN).
out=$(JOBS=0 bash ops/nightly.sh --jobs 1 --bin "$work/none" "$work/fast.yaml" 2>&1)
[ $? -eq 2 ] && [[ $out == "reflcheck nightly: --bin '$work/none' is not an executable"* ]] &&
    ok "--jobs wins over JOBS, --bin over BIN" || bad "option over variable: $out"
out=$(JOBS=0 bash ops/nightly.sh "$work/fast.yaml" 2>&1)
[ $? -eq 2 ] && [[ $out == *"JOBS '0'"* ]] && ok "JOBS is the fallback" || bad "JOBS fallback: $out"
refuse() { # refuse WANT_TEXT ARG...: exit 2, one line holding WANT_TEXT
    local want=$1 out st
    shift
    out=$(bash ops/nightly.sh "$@" "$work/fast.yaml" 2>&1)
    st=$?
    [ $st -eq 2 ] && [ "$(printf '%s\n' "$out" | wc -l)" -eq 1 ] && [[ $out == *"$want"* ]] &&
        ok "$*: exit 2: $out" || bad "$* (want exit 2 and one line with '$want'): exit $st: $out"
}
refuse "--jobs '0': give a whole number" --jobs=0
refuse "--scheduler 'pbs': use make" --scheduler pbs
refuse "--run-id 'a/b': use letters" --run-id a/b
refuse "option '--bogus' is not known" --bogus
refuse "--jobs needs a value" --jobs --small
refuse "option --small takes no '=VALUE'" --small=1
help=$(bash ops/nightly.sh --help)
missing=
for o in "--scenes PATH.*SCENES" "--small.*SMALL=1" "--no-sweep.*NO_SWEEP=1" "--no-screenshot.*NO_SCREENSHOT=1" \
    "--jobs N.*default 2.*JOBS" "--runs DIR.*default reports/runs.*RUNS" "--cache DIR.*default reports/cache.*CACHE" \
    "--run-id ID.*RUN_ID" "--scheduler NAME.*make \\(default\\).*SCHEDULER" "--reference.*REFERENCE=1" \
    "--bin PATH.*default build/reflcheck.*BIN" "--history FILE.*HISTORY" "--latest PATH.*default reports/latest.*LATEST"; do
    grep -Eq -- "^  $o\$" <<< "$help" || missing="$missing '$o'"
done
[ -z "$missing" ] && ok "--help lists every option with its default and variable" || bad "--help lacks:$missing"

echo "progress: $pass passed, $fail failed"
[ $fail -eq 0 ]
