#!/usr/bin/env bash
# The nightly's exit status and the run status it records: a clean run exits 0 and records ok;
# a run whose comparison fails exits 1 and records fail; a run whose renderer crashes exits 1
# and records error (the crash is not a skip); a Slurm run whose submission sbatch refuses exits 1
# and records failed with sbatch's reason. NO_SCREENSHOT=1 is honoured throughout.
set -uo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
work=$build/status-test
rm -rf "$work"
mkdir -p "$work/bin"
export BIN=$build/reflcheck RUNS=$work/runs HISTORY=$work/history.jsonl LATEST=$work/latest
export CACHE=$work/cache SMALL=1 NO_SWEEP=1 NO_SCREENSHOT=1
pass=0; fail=0
ok() { pass=$((pass + 1)); echo "status: $*"; }
bad() { fail=$((fail + 1)); echo "status: FAILED: $*"; }

# A Lambert quad under a sun, raster against its POV-Ray twin; $1 is the rel_rms fail threshold.
. tests/quad_scene.sh
scene() { quad_scene "$work/$2.yaml" "$2" 24 "$1"; }
record_status() {
    /usr/bin/python3 -c 'import json,sys; print(json.loads(open(sys.argv[1]).read().splitlines()[-1])["status"])' \
        "$HISTORY"
}
expect() {   # expect NAME WANT_EXIT WANT_STATUS GOT_EXIT
    local st
    st=$(record_status)
    if [ "$4" -eq "$2" ] && [ "$st" = "$3" ]; then ok "$1: exit $4, recorded $st"
    else bad "$1: exit $4 (want $2), recorded $st (want $3); see $work/$1.log"; fi
}

scene 1.0e-2 clean
RUN_ID=clean SCENES="$work/clean.yaml" bash ops/nightly.sh > "$work/clean.log" 2>&1
expect clean 0 ok $?
# No screenshot was asked for: none was taken.
[ ! -e "$RUNS/clean/screenshot.png" ] && ok "NO_SCREENSHOT=1: no screenshot" || bad "NO_SCREENSHOT=1 took a screenshot"

# The half-float floor alone is about 1e-4: a threshold of 1e-12 fails the twin.
scene 1.0e-12 tight
RUN_ID=tight SCENES="$work/tight.yaml" bash ops/nightly.sh > "$work/tight.log" 2>&1
expect tight 1 fail $?
# The failure names the scene key that holds the threshold.
grep -q 'rel_rms = .* > fail threshold 1e-12 at [a-z]* size (test threshold); scene key comparisons\[0\]\.thresholds\.rel_rms$' \
    "$work/tight.log" && ok "tight: the failure names comparisons[0].thresholds.rel_rms" ||
    bad "tight: the failure does not name its key: $(grep FAIL "$work/tight.log")"

# The same run again: its comparison comes back from the compare cache (ops/compare_cache.sh)
# and fails all the same, naming its key.
RUN_ID=tight-again SCENES="$work/tight.yaml" bash ops/nightly.sh > "$work/tight-again.log" 2>&1
expect tight-again 1 fail $?
grep -q 'scene key comparisons\[0\]\.thresholds\.rel_rms$' "$work/tight-again.log" &&
    cmp -s "$RUNS/tight/tight/compare.json" "$RUNS/tight-again/tight/compare.json" &&
    ok "tight again: the cached comparison fails the same, names its key, same compare.json" ||
    bad "tight again: the cached comparison differs or does not name its key; see $work/tight-again.log"

# A POV-Ray that names its version and then crashes on every render.
cat > "$work/bin/povray" <<'SH'
#!/bin/sh
case "$*" in *--version*) echo "POV-Ray 3.7.0.10 (fake, crashes)"; exit 0;; esac
kill -SEGV $$
SH
chmod +x "$work/bin/povray"
scene 1.0e-2 crash
RUN_ID=crash SCENES="$work/crash.yaml" PATH="$PWD/$work/bin:$PATH" bash ops/nightly.sh > "$work/crash.log" 2>&1
rc=$?
expect crash 1 error $rc
grep -q '"status":[[:space:]]*"crashed"' "$RUNS/crash/crash/povray-twin.json" && ok "crash: job record says crashed" ||
    bad "crash: job record does not say crashed"

# A Slurm that answers (sinfo) but refuses every submission, as a full queue or a bad account does.
mkdir -p "$work/slurmbin"
printf '#!/bin/sh\nexit 0\n' > "$work/slurmbin/sinfo"
printf '#!/bin/sh\necho "sbatch: error: Batch job submission failed: Job violates accounting/QOS policy" >&2\nexit 1\n' \
    > "$work/slurmbin/sbatch"
printf '#!/bin/sh\nexit 0\n' > "$work/slurmbin/scancel"
chmod +x "$work/slurmbin"/*
RUN_ID=refused SCHEDULER=slurm SCENES="$work/clean.yaml" PATH="$PWD/$work/slurmbin:$PATH" bash ops/nightly.sh \
    > "$work/refused.log" 2>&1
rc=$?
expect refused 1 failed $rc
/usr/bin/python3 -c 'import json,sys; r=json.loads(open(sys.argv[1]).read().splitlines()[-1])
sys.exit(not (r["run_id"] == "refused" and "render jobs" in r["reason"] and "QOS policy" in r["reason"]))' "$HISTORY" &&
    ok "refused: the history line names the run and sbatch's reason" ||
    bad "refused: the history line lacks the run id or the reason: $(tail -n1 "$HISTORY")"

# Interrupted while sbatch submits: a fake sbatch that writes its pid and then waits until the
# test releases it (bounded, so a broken test leaves nothing behind), so the signal certainly
# lands during the submission. The nightly exits 130, says so on its own stderr (not in a step's
# log), leaves no sbatch behind and records nothing.
cat > "$work/slurmbin/sbatch" <<SH
#!/bin/sh
echo \$\$ > "$PWD/$work/sbatch.pid"
i=0
while [ ! -e "$PWD/$work/sbatch.release" ] && [ \$i -lt 3000 ]; do sleep 0.1; i=\$((i + 1)); done
echo 101
SH
RUN_ID=interrupted SCHEDULER=slurm SCENES="$work/clean.yaml" PATH="$PWD/$work/slurmbin:$PATH" bash ops/nightly.sh \
    > "$work/interrupted.log" 2>&1 &
pid=$!
for _ in $(seq 1500); do [ -s "$work/sbatch.pid" ] && break; sleep 0.2; done
kill -TERM "$pid"
wait "$pid"
rc=$?
gone=0
for _ in $(seq 100); do kill -0 "$(cat "$work/sbatch.pid")" 2> /dev/null || { gone=1; break; }; sleep 0.1; done
: > "$work/sbatch.release"
if [ $rc -eq 130 ] && [ $gone = 1 ] && grep -q "interrupted; run interrupted left incomplete" "$work/interrupted.log" &&
    ! grep -q '"run_id":"interrupted"' "$HISTORY"; then
    ok "interrupted during sbatch: exit 130, said so, no sbatch left, nothing recorded"
else
    bad "interrupted during sbatch: exit $rc (want 130), sbatch gone $gone; see $work/interrupted.log"
fi

# A full disk under the run folder (a 64 KiB tmpfs; mounting needs root): the report cannot be
# written, the nightly exits 1 and the history still records the run, as failed.
mkdir -p "$work/full"
if [ "$(id -u)" = 0 ] && mount -t tmpfs -o size=64k reflcheck-test-full "$work/full" 2> /dev/null; then
    RUN_ID=full RUNS="$work/full" SCENES="$work/clean.yaml" bash ops/nightly.sh > "$work/full.log" 2>&1
    rc=$?
    umount "$work/full"
    expect full 1 failed $rc
    [ "$(tail -n1 "$HISTORY" | grep -c '"run_id":"full"')" = 1 ] && ok "full: the failed line is the run's own" ||
        bad "full: the last history line is not run full's: $(tail -n1 "$HISTORY")"
else
    echo "status: full disk: not tested (mounting a small tmpfs needs root)"
fi

# Careless settings are refused before anything runs: exit 2, one line naming the setting and
# the fix, no run folder.
: > "$work/a-file"
refuse() {  # refuse NAME WANT_TEXT ENV...
    local name=$1 text=$2 out
    shift 2
    out=$(env RUN_ID="bad-$name" SCENES="$work/clean.yaml" "$@" bash ops/nightly.sh 2>&1)
    local st=$?
    if [ $st -eq 2 ] && [ "$(printf '%s\n' "$out" | wc -l)" -eq 1 ] && [[ $out == *"$text"* ]] &&
        [ ! -e "$RUNS/bad-$name" ]; then
        ok "$name: exit 2: $out"
    else
        bad "$name: exit $st (want 2 and one line with '$text'): $out"
    fi
}
refuse jobs0 "JOBS '0'" JOBS=0
refuse jobs-abc "JOBS 'abc'" JOBS=abc
refuse runs-file "RUNS '$work/a-file' is not a folder" RUNS="$work/a-file"
refuse no-bin "BIN '$work/no-such-reflcheck' is not an executable" BIN="$work/no-such-reflcheck"
refuse history-folder "HISTORY '$work' is a folder" HISTORY="$work"
refuse no-scene "scene '$work/none.yaml' is not a file" SCENES="$work/none.yaml"
echo "status: $pass passed, $fail failed"
[ "$fail" -eq 0 ]
