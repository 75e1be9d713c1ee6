"""runner.py - one render job (`reflcheck run`, repeats and their cache) and one diff (`reflcheck
diff`, cached by the images' keys), as a Runner the planner and the analysis share."""

import contextlib
import hashlib
import json
import math
import os
import re
import subprocess
import threading
import time

from .common import JOB_TIMEOUT_S, write_json


class Runner:
    def __init__(self, args):
        self.bin = args.bin
        self.cache = args.cache
        self.threads = args.threads
        # Under Slurm (inside the sweep's allocation) every job is a step of its own.
        self.prefix = (
            ['srun', '--exact', '--quiet', '-N1', '-n1', f'-c{args.threads}', '--job-name=reflcheck-sweep']
            if args.scheduler == 'slurm'
            else []
        )
        self.env = None  # the Blender worker pool's variable, once it runs (main)
        self.small = not args.full_size
        self.renders = os.path.join(args.run, 'timing', 'renders')
        self.seed_opt = self.cli_has_seed()
        self.roles = {}  # scene name -> 'validate' or 'twin' (sweep_role)
        # (width, height), or a scene name whose size is unknown -> its all-zero image
        # (analysis.make_zero), made once a run
        self.zeros = {}
        self.zero_lock = threading.Lock()

    def cli_has_seed(self):
        """`reflcheck run --seed N` (first Cycles seed): lets sweep points avoid the reference's
        seeds. Probed with seed 0 before any scene is read: getopt_long takes `--seed` as an
        abbreviation of `--seeds` while no exact --seed exists, and --seeds rejects 0."""
        try:
            r = subprocess.run([self.bin, 'run', '--seed', '0'], capture_output=True, text=True, timeout=30)
        except OSError:
            return False
        return "--seeds '0'" not in r.stderr and 'unknown option' not in r.stderr

    def out(self, scene, tag, renderer):
        return os.path.join(self.renders, scene, tag, f'{renderer}-{self.roles.get(scene, "validate")}')

    def run(self, scene_path, scene, renderer, tag, opts, repeats=1):
        """One job; returns the record dict (with 'wall_s' the fastest of the repeats)."""
        cmd = (
            [
                self.bin,
                'run',
                scene_path,
                '--renderer',
                renderer,
                '--role',
                self.roles.get(scene, 'validate'),
                '--out',
                self.renders,
                '--tag',
                tag,
                '--threads',
                str(self.threads),
            ]
            + (['--small'] if self.small else [])
            + opts
        )
        best, t0 = None, time.monotonic()
        for i in range(repeats):
            # The first render goes through the cache (its key names the repeats' times below);
            # the repeats must render, so they skip it.
            extra = ['--cache', self.cache] if i == 0 else ['--no-cache']
            if i == 1 and self.repeats_known(best, repeats):
                break
            r = subprocess.run(
                self.prefix + cmd + extra, capture_output=True, text=True, timeout=JOB_TIMEOUT_S, env=self.env
            )
            rec_path = self.out(scene, tag, renderer) + '.json'
            try:
                with open(rec_path, encoding='utf-8') as f:
                    rec = json.load(f)
            except (OSError, ValueError):
                rec = {
                    'status': 'error',
                    'message': (r.stderr.strip() or r.stdout.strip() or f'no record {rec_path}').splitlines()[-1],
                }
            if r.returncode != 0 and rec.get('status') == 'ok':
                rec = {
                    'status': 'error',
                    'message': r.stderr.strip().splitlines()[-1] if r.stderr.strip() else f'exit {r.returncode}',
                }
            if rec.get('status') != 'ok':
                best = rec
                break
            if best is None or rec.get('wall_s', math.inf) < best.get('wall_s', math.inf):
                best = dict(rec, key=(best or rec).get('key'), cached=(best or rec).get('cached'))
        if repeats > 1 and best.get('status') == 'ok':
            self.repeats_store(best, repeats)
        best['sweep_elapsed_s'] = time.monotonic() - t0
        best['exr'] = self.out(scene, tag, renderer) + '.exr'
        if renderer == 'cycles':
            best['render_s'] = cycles_render_s(self.out(scene, tag, renderer) + '.log')
        return best

    def repeats_path(self, rec):
        """Where the fastest of a cached job's repeats is kept: CACHE/repeats/<key>.json. A
        second run over the same cache takes the time from there instead of rendering again."""
        key = rec.get('key') if rec else None
        return os.path.join(self.cache, 'repeats', key + '.json') if key and re.fullmatch(r'[0-9a-f]+', key) else None

    def repeats_known(self, rec, repeats):
        """True (and rec takes the kept times) when the repeats of rec's key were timed before."""
        path = self.repeats_path(rec)
        try:
            with open(path, encoding='utf-8') as f:
                kept = json.load(f)
        except (OSError, TypeError, ValueError):
            return False
        if kept.get('repeats', 0) < repeats or not isinstance(kept.get('wall_s'), (int, float)):
            return False
        rec.update(wall_s=kept['wall_s'], cpu_s=kept.get('cpu_s'), repeats_cached=True)
        return True

    def repeats_store(self, rec, repeats):
        path = self.repeats_path(rec)
        if path and not rec.get('repeats_cached'):
            with contextlib.suppress(OSError):
                write_json(path, {'repeats': repeats, 'wall_s': rec.get('wall_s'), 'cpu_s': rec.get('cpu_s')})

    def diff_path(self, keys, leave_out):
        """CACHE/diffs/<hash>.json for a diff of three cached renders (test, reference, mask: their
        cache keys) by this reflcheck (path, size and time: a rebuilt one diffs again)."""
        if not all(k and re.fullmatch(r'[0-9a-z-]+', k) for k in keys):
            return None
        st = os.stat(self.bin)
        ident = f'{os.path.abspath(self.bin)} {st.st_size} {st.st_mtime_ns} {" ".join(keys)} {",".join(leave_out)}'
        return os.path.join(self.cache, 'diffs', hashlib.sha256(ident.encode()).hexdigest()[:32] + '.json')

    def diff(self, test, ref, mask, leave_out=(), keys=None):
        """`reflcheck diff` of two images (masked); keys: the three images' cache keys, with which
        the answer is kept in the cache and a second run reads it instead of diffing again."""
        (out,) = self.diff_many([(test, ref, mask, leave_out, keys)])
        if isinstance(out, Exception):
            raise out
        return out

    def diff_many(self, items):
        """diff for every (test, ref, mask, leave_out, keys) of items; the pairs the cache does not
        answer go to one `reflcheck diff --pairs` process (a process a pair cost more CPU than
        the comparisons: ~20 ms each, hundreds a nightly). Returns a list in items' order: each
        the metrics, or the RuntimeError diff alone raises for it."""
        out, paths, batch = [None] * len(items), [None] * len(items), []
        for i, (test, ref, mask, leave_out, keys) in enumerate(items):
            paths[i] = self.diff_path(keys, leave_out) if keys else None
            out[i] = kept_json(paths[i])
            if out[i] is not None:
                continue
            # A tab or line break cannot go on a --pairs line: such a pair is diffed alone.
            if any(c in f for f in (test, ref, mask or '') for c in '\t\n'):
                out[i] = self.diff_alone(test, ref, mask, leave_out)
            else:
                batch.append(i)
        if batch:
            for i, a in zip(batch, self.diff_pairs([items[i] for i in batch])):
                out[i] = a
        for i, a in enumerate(out):
            if paths[i] and isinstance(a, dict) and not os.path.exists(paths[i]):
                with contextlib.suppress(OSError):
                    write_json(paths[i], a)
        return out

    def diff_alone(self, test, ref, mask, leave_out):
        """`reflcheck diff TEST REF`: its metrics, or the RuntimeError that names why not."""
        cmd = [self.bin, 'diff', test, ref] + (['--mask', mask] if mask else [])
        cmd += ['--leave-out', ','.join(leave_out)] if leave_out else []
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
        if r.returncode != 0:
            return RuntimeError(f'reflcheck diff {test} {ref}: ' + (r.stderr.strip().splitlines() or ['failed'])[-1])
        try:
            return json.loads(r.stdout)
        except ValueError as e:
            return RuntimeError(f'reflcheck diff {test} {ref}: {e}')

    def diff_pairs(self, pairs):
        """`reflcheck diff --pairs -` of pairs: a list of metrics or RuntimeErrors, in order; a
        pair's error reads as diff alone gives it (its stderr line, 'reflcheck: ...')."""
        lines = ''.join('\t'.join([t, r, m or '', ','.join(lo)]) + '\n' for t, r, m, lo, _ in pairs)
        p = subprocess.run(
            [self.bin, 'diff', '--pairs', '-'], input=lines, capture_output=True, text=True, timeout=300 * len(pairs)
        )
        why = (p.stderr.strip().splitlines() or [f'diff --pairs exit {p.returncode}'])[-1]
        answers = json_stream(p.stdout) if p.returncode == 0 else []
        out = []
        for k, (test, ref, *_) in enumerate(pairs):
            a = answers[k] if k < len(answers) else {'error': why}
            if isinstance(a, dict) and 'error' in a and set(a) <= {'error', 'exit'}:
                msg = a['error'] if a['error'].startswith('reflcheck:') else 'reflcheck: ' + a['error']
                a = RuntimeError(f'reflcheck diff {test} {ref}: {msg}')
            out.append(a)
        return out


def kept_json(path):
    """The JSON a cache file holds, or None (no path, no file, not JSON)."""
    if not path or not os.path.exists(path):
        return None
    with contextlib.suppress(OSError, ValueError):
        with open(path, encoding='utf-8') as f:
            return json.load(f)
    return None


def json_stream(text):
    """The JSON values of text, one after the other (`diff --pairs` prints one a pair)."""
    dec, i, out = json.JSONDecoder(), 0, []
    while True:
        while i < len(text) and text[i].isspace():
            i += 1
        if i >= len(text):
            return out
        try:
            v, i = dec.raw_decode(text, i)
        except ValueError:
            return out
        out.append(v)


def cycles_render_s(log_path):
    """Build + render seconds inside Blender (without its start-up), from the script's last line."""
    try:
        with open(log_path, encoding='utf-8', errors='replace') as f:
            text = f.read()
    except OSError:
        return None
    m = re.findall(r'reflcheck-cycles: build ([0-9.]+) s, render ([0-9. ]+) s', text)
    if not m:
        return None
    return float(m[-1][0]) + sum(float(v) for v in m[-1][1].split())
