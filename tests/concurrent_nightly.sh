#!/usr/bin/env bash
# Two nightlies at once on one cache, one history and one `latest`, with default run ids (both
# start in the same second): both complete and exit 0 in distinct run folders, every shared
# render job ran once (the other run waited on its cache entry's lock and reused it), the two
# runs' images are byte-identical and their comparisons identical, and both history lines parse.
set -uo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
work=$build/concurrent-test
rm -rf "$work"
mkdir -p "$work"
export BIN=$build/reflcheck RUNS=$work/runs HISTORY=$work/history.jsonl LATEST=$work/latest
export CACHE=$work/cache SMALL=1 NO_SCREENSHOT=1 NO_SWEEP=1
export SCENES="scenes/lambert_calibration.yaml scenes/d3d_spot.yaml"
unset RUN_ID

bash ops/nightly.sh > "$work/a.log" 2>&1 & a=$!
bash ops/nightly.sh > "$work/b.log" 2>&1 & b=$!
wait $a; rc_a=$?
wait $b; rc_b=$?
fail=0
check() { if "$@"; then :; else fail=$((fail + 1)); fi; }
say() { echo "concurrent: $*"; }
[ $rc_a -eq 0 ] && [ $rc_b -eq 0 ] || { say "nightly exits $rc_a and $rc_b (want 0 and 0); see $work/a.log, $work/b.log"; fail=$((fail + 1)); }

/usr/bin/python3 - "$RUNS" "$HISTORY" <<'PY' || fail=$((fail + 1))
import filecmp, json, os, sys
runs, history = sys.argv[1], sys.argv[2]
ids = sorted(os.listdir(runs))
bad = []
if len(ids) != 2:
    bad.append(f'{len(ids)} run folders, want 2 distinct ones: {ids}')
else:
    a, b = (os.path.join(runs, i) for i in ids)
    scenes = sorted(d for d in os.listdir(a) if os.path.isfile(os.path.join(a, d, 'compare.json')))
    if scenes != ['d3d_spot', 'lambert_calibration']:
        bad.append(f'scenes {scenes}')
    n_jobs = 0
    for s in scenes:
        for f in sorted(os.listdir(os.path.join(a, s))):
            pa, pb = os.path.join(a, s, f), os.path.join(b, s, f)
            if f.endswith('.exr'):
                if not filecmp.cmp(pa, pb, shallow=False):
                    bad.append(f'{s}/{f} differs between the runs')
            elif f.endswith('.json'):
                ra, rb = (json.load(open(p, encoding='utf-8')) for p in (pa, pb))
                if 'renderer' not in ra:  # compare.json, fit.json: not render job records
                    continue
                n_jobs += 1
                if ra['status'] != 'ok' or rb['status'] != 'ok':
                    bad.append(f'{s}/{f}: status {ra["status"]} and {rb["status"]}')
                elif ra['cached'] == rb['cached']:
                    # one run renders, the other waits on the entry's lock and copies its result
                    bad.append(f'{s}/{f}: cached {ra["cached"]} in both runs (want exactly one render)')
                if ra['key'] != rb['key']:
                    bad.append(f'{s}/{f}: cache keys differ')
        ca, cb = (json.load(open(os.path.join(r, s, 'compare.json'), encoding='utf-8')) for r in (a, b))
        strip = lambda c: [{k: v for k, v in x.items() if k not in ('times',)} for x in c['comparisons']]
        if strip(ca) != strip(cb):
            bad.append(f'{s}: comparisons differ between the runs')
        if any(x['status'] not in ('pass', 'not_gated', 'warn') for x in ca['comparisons']):
            bad.append(f'{s}: verdicts {[x["status"] for x in ca["comparisons"]]}')
    if n_jobs < 4:
        bad.append(f'only {n_jobs} job records')
lines = open(history, encoding='utf-8').read().split('\n')
recs = [json.loads(l) for l in lines if l.strip()]
if sorted(r['run_id'] for r in recs) != ids or lines[-1] != '':
    bad.append(f'history: {[r["run_id"] for r in recs]} against runs {ids}')
for m in bad:
    print('concurrent:', m)
print(f'concurrent: {len(ids)} runs, {len(recs)} history lines, {len(bad)} problems')
sys.exit(1 if bad else 0)
PY
say "$((1 - (fail > 0))) passed, $((fail > 0)) failed"
[ "$fail" -eq 0 ]
