#!/usr/bin/python3
"""slurm_compare.py - a run made with make and the same plan made through Slurm agree.

Usage: /usr/bin/python3 tests/slurm_compare.py [--both-slurm] LOCAL_RUN SLURM_RUN [BIN]
       (tests/slurm_nightly.sh; tests/slurm_nodes.sh with --both-slurm: LOCAL_RUN is a run through
       another Slurm cluster, since stopped, whose records name Slurm jobs too)

Checks, printing one line per difference and exiting 1 if there is any:
  - every RUN/<scene>/compare.json: the same verdicts and the same metrics (every number but
    times, to 1e-9 relative: the images below are the same, so their metrics are);
  - every image: the deterministic renderers' (`reflcheck renderers --json`: not stochastic; our
    rasterizer, POV-Ray) bit-identical in every pixel of every channel (oiiotool --diff with
    zero tolerance); the stochastic ones' (Cycles) within their noise: `reflcheck diff` finds no
    pixel beyond its noise-aware z-test (Cycles with fixed seeds repeats itself, so in practice
    they are identical too);
  - every render record of the Slurm run names its Slurm job, and Slurm knows that job as a
    reflcheck-render array task; the local records name none (--both-slurm: name one each);
    but a validate record the fits stage rewrote as a cache hit names none (noted, not counted).
"""

import glob
import json
import os
import subprocess
import sys

problems = []


def problem(text):
    problems.append(text)
    print('slurm_compare: ' + text)


def load(path):
    with open(path, encoding='utf-8') as f:
        return json.load(f)


def is_time(key):
    return any(w in key for w in ('wall', 'time', 'cpu', 'finished', 'seconds')) or key.endswith('_s')


def same(a, b, where, runs):
    """Walks two compare.json documents; strings compared with the run folders made equal."""
    if isinstance(a, dict) and isinstance(b, dict):
        if set(a) != set(b):
            problem(f'{where}: keys differ: {sorted(set(a) ^ set(b))}')
        for k in set(a) & set(b):
            if not is_time(k):
                same(a[k], b[k], f'{where}.{k}', runs)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            problem(f'{where}: {len(a)} against {len(b)} items')
        for i, (x, y) in enumerate(zip(a, b)):
            same(x, y, f'{where}[{i}]', runs)
    elif isinstance(a, str) and isinstance(b, str):
        if a.replace(runs[0], 'RUN') != b.replace(runs[1], 'RUN'):
            problem(f'{where}: "{a}" against "{b}"')
    elif isinstance(a, bool) or isinstance(b, bool) or a is None or b is None:
        if a != b:
            problem(f'{where}: {a} against {b}')
    elif isinstance(a, (int, float)) and isinstance(b, (int, float)):
        if abs(a - b) > 1e-9 * max(abs(a), abs(b)):
            problem(f'{where}: {a!r} against {b!r}')
    elif a != b:
        problem(f'{where}: {a!r} against {b!r}')


def slurm_job_name(job_id):
    r = subprocess.run(['scontrol', '-o', 'show', 'job', job_id], capture_output=True, text=True)
    fields = dict(w.split('=', 1) for w in r.stdout.split() if '=' in w)
    return fields.get('JobName') if r.returncode == 0 else None


def main(argv):
    both = '--both-slurm' in argv
    argv = [a for a in argv if a != '--both-slurm']
    if len(argv) not in (3, 4):
        print(__doc__, file=sys.stderr)
        return 2
    local, slurm = argv[1].rstrip('/'), argv[2].rstrip('/')
    bin_path = argv[3] if len(argv) == 4 else 'build/reflcheck'
    table = {
        r['name']: r
        for r in json.loads(subprocess.run([bin_path, 'renderers', '--json'], capture_output=True, text=True).stdout)
    }
    compares = sorted(glob.glob(os.path.join(local, '*', 'compare.json')))
    if not compares:
        problem(f'{local}: no compare.json')
    for c in compares:
        scene = os.path.basename(os.path.dirname(c))
        other = os.path.join(slurm, scene, 'compare.json')
        if not os.path.isfile(other):
            problem(f'{other}: missing')
            continue
        same(load(c), load(other), f'{scene}/compare.json', (local, slurm))
    records = [
        p
        for p in sorted(glob.glob(os.path.join(local, '*', '*-*.json')))
        if os.path.basename(p).split('-', 1)[0] in table
    ]
    for rec_path in records:
        rel = os.path.relpath(rec_path, local)
        rec_l, rec_s = load(rec_path), load(os.path.join(slurm, rel))
        # The fits stage runs a scene's validate job again, locally, through the cache
        # (cli_fit.c), and that rewrites the run's record as a cache hit naming no Slurm job.
        refit = [r.get('role') == 'validate' and r.get('cached') and r.get('slurm') is None for r in (rec_l, rec_s)]
        if refit[1]:
            print(f'slurm_compare: {rel}: rewritten by the fits stage as a cache hit (no Slurm job named)')
        if both and not refit[0] and not (rec_l.get('slurm') or {}).get('job_id'):
            problem(f'{rel}: the first run\'s record names no Slurm job')
        if not both and rec_l.get('slurm') is not None:
            problem(f'{rel}: the local record names a Slurm job {rec_l["slurm"]}')
        job = (rec_s.get('slurm') or {}).get('job_id')
        if refit[1]:
            pass
        elif not job:
            problem(f'{rel}: the Slurm record names no Slurm job')
        elif '_' not in job or slurm_job_name(job) != 'reflcheck-render':
            problem(f'{rel}: Slurm job {job} is no reflcheck-render array task Slurm knows')
        if rec_l.get('status') != 'ok' or rec_s.get('status') != 'ok':
            problem(f'{rel}: status {rec_l.get("status")} locally, {rec_s.get("status")} under Slurm')
            continue
        a, b = rec_l['exr'], rec_s['exr']
        if table[rec_l['renderer']].get('stochastic'):
            d = subprocess.run([bin_path, 'diff', b, a], capture_output=True, text=True)
            z = (json.loads(d.stdout or '{}').get('noise') or {}).get('ztest') or {}
            if d.returncode != 0 or z.get('n_fail') != 0:
                problem(f'{rel}: {z.get("n_fail")} values beyond the noise (exit {d.returncode})')
        else:
            d = subprocess.run(
                ['oiiotool', '--fail', '0', '--warn', '0', a, b, '--diff'], capture_output=True, text=True
            )
            if d.returncode != 0:
                problem(f'{rel}: images differ: ' + ' '.join(d.stdout.split()[-12:]))
    print(
        f'slurm_compare: {len(compares)} compare.json, {len(records)} records and images; {len(problems)} differences'
    )
    return 1 if problems else 0


if __name__ == '__main__':
    sys.exit(main(sys.argv))
