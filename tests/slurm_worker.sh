#!/usr/bin/env bash
# The Blender worker pool (harness/renderers/cycles/worker_pool.py, worker.py, cycles_worker.c):
#  - a Cycles job rendered by a worker gives the image a fresh Blender gives, bit for bit in
#    every pixel and channel, and the same record but for times and the command;
#  - two jobs in a row in one worker (the scene reset between them) are both right;
#  - a pool that gets no job starts no Blender (the workers start at the first job);
#  - a job that exceeds its time limit in a worker records "timeout", the worker ends itself,
#    the pool starts another, and the next job is ok again.
# Usage: bash tests/slurm_worker.sh BUILD
set -uo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
work=$build/worker-test
rm -rf "$work"
mkdir -p "$work"
exec /usr/bin/python3 - "$build/reflcheck" "$work" <<'PY'
import json, os, subprocess, sys, time
sys.path.insert(0, 'harness/renderers/cycles')
from worker_pool import WorkerPool

bin_path, work = sys.argv[1], sys.argv[2]
scene = 'scenes/lambert_calibration.yaml'
failures = []


def check(ok, text):
    print('worker: ' + ('' if ok else 'FAILED: ') + text)
    if not ok:
        failures.append(text)


def run(tag, env=None, extra=()):
    cmd = [bin_path, 'run', scene, '--renderer', 'cycles', '--role', 'twin', '--small', '--no-cache',
           '--threads', '1', '--out', work, '--tag', tag, *extra]
    t = time.monotonic()
    r = subprocess.run(cmd, capture_output=True, text=True, env=env)
    with open(os.path.join(work, 'lambert_calibration', tag, 'cycles-twin.json')) as f:
        rec = json.load(f)
    return rec, time.monotonic() - t


def same_pixels(a, b):
    r = subprocess.run(['oiiotool', '--fail', '0', '--warn', '0', a, b, '--diff'], capture_output=True, text=True)
    return r.returncode == 0


# No job, no Blender: the workers start when the first job connects.
with WorkerPool(1, log_dir=work) as idle:
    pass
check(idle.starts == 0, f'a pool that got no job started no Blender ({idle.starts} started)')
fresh, t_fresh = run('fresh')
check(fresh['status'] == 'ok', f"a fresh Blender renders the job: {fresh['status']} {fresh['message']}")
with WorkerPool(1, log_dir=work) as pool:
    env = dict(os.environ, **pool.env())
    w1, t1 = run('w1', env)
    w2, t2 = run('w2', env)
    check(w1['status'] == 'ok' and w2['status'] == 'ok', f"the worker renders two jobs in a row: {w1['status']}, {w2['status']}")
    check('(blender worker ' in w1['command'], 'the record says the job went to the worker')
    for tag in ('w1', 'w2'):
        check(same_pixels(fresh['exr'], os.path.join(work, 'lambert_calibration', tag, 'cycles-twin.exr')),
              f'{tag}: every pixel and channel equals the fresh Blender\'s')
    keep = ('status', 'message', 'key', 'width', 'height', 'samples', 'seeds', 'seed', 'terms_left_out', 'version')
    check(all(w1[k] == fresh[k] for k in keep), 'the records agree but for times, paths and the command')
    print(f'worker: wall per job: fresh Blender {t_fresh:.2f} s, worker {t1:.2f} s then {t2:.2f} s')
    # A time limit far below the render: the client hangs up, the worker ends itself.
    pid_before = [p.pid for p in pool.procs]
    slow, _ = run('slow', env, ['--timeout', '0.3', '--samples', '4096'])
    check(slow['status'] == 'timeout', f"a job over its time limit in a worker records timeout: {slow['status']}")
    # The worker ends itself when it sees the client gone, and the pool's monitor then starts
    # another: both take as long as the machine takes, so wait for that (bounded, for a loaded
    # machine) instead of a fixed time.
    t = time.monotonic()
    while [p.pid for p in pool.procs] == pid_before and time.monotonic() < t + 300:
        time.sleep(0.1)
    check([p.pid for p in pool.procs] != pid_before,
          f'the timed-out worker was replaced ({time.monotonic() - t:.1f} s after the job returned)')
    after, _ = run('after', env)
    check(after['status'] == 'ok' and same_pixels(fresh['exr'], after['exr']),
          'the next job renders right in the new worker')
print(f'worker: {len(failures)} failed')
sys.exit(1 if failures else 0)
PY
