#!/usr/bin/env bash
# EEVEE's Blender workers (worker_pool.py --eevee-threads, eevee_worker.py, eevee.c):
#  - an EEVEE job rendered by a worker gives the image a fresh Blender under xvfb-run gives, bit
#    for bit in every pixel and channel, and the same record but for times and the command;
#  - two different scenes in a row in one worker are both right (nothing of the first stays);
#  - a job asking for other llvmpipe threads than the workers' starts its own Blender;
#  - a pool that got no job started no Blender and no Xvfb.
# Usage: bash tests/eevee_worker.sh BUILD
set -uo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
work=$build/eevee-worker-test
rm -rf "$work"
mkdir -p "$work"
exec /usr/bin/python3 - "$build/reflcheck" "$work" <<'PY'
import json, os, subprocess, sys
sys.path.insert(0, 'harness/renderers/cycles')
from worker_pool import WorkerPool

bin_path, work = sys.argv[1], sys.argv[2]
failures = []


def check(ok, text):
    print('eevee worker: ' + ('' if ok else 'FAILED: ') + text)
    if not ok:
        failures.append(text)


def run(scene, role, tag, env=None, threads=1):
    cmd = [bin_path, 'run', f'scenes/{scene}.yaml', '--renderer', 'eevee', '--role', role, '--small',
           '--no-cache', '--threads', str(threads), '--out', work, '--tag', tag]
    subprocess.run(cmd, capture_output=True, text=True, env=env)
    with open(os.path.join(work, scene, tag, f'eevee-{role}.json')) as f:
        return json.load(f)


def same_pixels(a, b):
    r = subprocess.run(['oiiotool', '--fail', '0', '--warn', '0', a, b, '--diff'], capture_output=True, text=True)
    return r.returncode == 0


with WorkerPool(1, log_dir=work, renderer='eevee', threads=1) as idle:
    pass
check(idle.starts == 0 and idle.xvfb is None, 'a pool that got no job started no Blender and no Xvfb')
jobs = (('eevee_calibration', 'twin'), ('d3d9_metal', 'validate'))
fresh = {s: run(s, role, 'fresh') for s, role in jobs}
for s, rec in fresh.items():
    check(rec['status'] == 'ok' and '(blender worker' not in rec['command'], f'{s}: a fresh Blender renders it: {rec["status"]}')
keep = ('status', 'message', 'key', 'width', 'height', 'samples', 'version')
with WorkerPool(1, log_dir=work, renderer='eevee', threads=1) as pool:
    env = dict(os.environ, **pool.env())
    for s, role in jobs:
        w = run(s, role, 'worker', env)
        check(w['status'] == 'ok' and '(blender worker ' in w['command'], f'{s}: the worker renders it: {w["status"]} {w["message"]}')
        check(same_pixels(fresh[s]['exr'], w['exr']), f"{s}: every pixel and channel equals the fresh Blender's")
        check(all(w[k] == fresh[s][k] for k in keep), f'{s}: the records agree but for times, paths and the command')
    other = run('eevee_calibration', 'twin', 'threads2', env, threads=2)
    check(other['status'] == 'ok' and '(blender worker' not in other['command'],
          'a job asking for 2 llvmpipe threads (the workers draw with 1) starts its own Blender')
    check(pool.starts == 1, f'one worker started for the jobs ({pool.starts})')
print(f'eevee worker: {len(failures)} failed')
sys.exit(1 if failures else 0)
PY
