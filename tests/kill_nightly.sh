#!/usr/bin/env bash
# Killing the nightly run at a random point loses no earlier history record, leaves the
# latest report whole and leaves no process behind (no renderer, no `reflcheck run`): one
# complete run first, then runs killed after a random delay (SIGKILL to the whole process
# group twice, SIGTERM to the nightly alone once), each followed by those checks.
set -uo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
work=$build/kill-test
rm -rf "$work"
mkdir -p "$work"
export BIN=$build/reflcheck RUNS=$work/runs HISTORY=$work/history.jsonl LATEST=$work/latest
export CACHE=$work/cache SMALL=1 NO_SCREENSHOT=1 SCENES="scenes/lambert_calibration.yaml scenes/d3d_spot.yaml"

RUN_ID=complete bash ops/nightly.sh > "$work/complete.log" 2>&1 || { echo "kill: the complete run failed; see $work/complete.log"; exit 1; }
[ -s "$HISTORY" ] || { echo "kill: no history after a complete run"; exit 1; }
cp "$HISTORY" "$work/history.before"

pass=0; fail=0
for i in 1 2 3; do
    delay=$(awk -v s="$RANDOM" 'BEGIN { srand(s); printf "%.2f", 0.3 + rand() * 6 }')
    setsid env RUN_ID="killed-$i" bash ops/nightly.sh > "$work/killed-$i.log" 2>&1 &
    pid=$!
    sleep "$delay"
    if [ "$i" -eq 3 ]; then
        how=SIGTERM; kill -TERM "$pid" 2>/dev/null
    else
        how=SIGKILL; kill -KILL -- -"$pid" 2>/dev/null
    fi
    wait "$pid" 2>/dev/null
    # Every process the run started names the test folder on its command line (scene, output
    # or cache paths). A renderer may take a moment to see its parent die.
    left=""
    for _ in $(seq 50); do
        left=$(pgrep -f -a -- "$work/" | grep -v -- "pgrep" || true)
        [ -z "$left" ] && break
        sleep 0.2
    done
    if [ -n "$left" ]; then
        fail=$((fail + 1)); echo "kill $i ($how after ${delay}s): processes left behind:"; echo "$left"
        pkill -KILL -f -- "$work/" 2>/dev/null
        cp "$HISTORY" "$work/history.before"
        continue
    fi
    # Every earlier record is still there, byte for byte, and every complete line parses.
    if cmp -s "$work/history.before" <(head -c "$(stat -c %s "$work/history.before")" "$HISTORY") &&
       /usr/bin/python3 - "$HISTORY" <<'PY'
import json, sys
lines = open(sys.argv[1], encoding="utf-8").read().split("\n")
for line in lines[:-1]:
    json.loads(line)
PY
    then
        # latest still points at a whole report.
        if [ -f "$LATEST/index.html" ] && [ -f "$LATEST/summary.json" ]; then
            pass=$((pass + 1)); echo "kill $i ($how after ${delay}s): history and latest intact, no process left"
        else
            fail=$((fail + 1)); echo "kill $i ($how after ${delay}s): latest report broken"
        fi
    else
        fail=$((fail + 1)); echo "kill $i ($how after ${delay}s): history lost or corrupted a record"
    fi
    cp "$HISTORY" "$work/history.before"
done
echo "kill: $pass passed, $fail failed"
[ "$fail" -eq 0 ]
