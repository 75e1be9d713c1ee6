#!/usr/bin/python3
"""sweep.py - error against render time: every renderer's quality knobs, per canonical scene.

Usage (Python 3 standard library only; run from the project root after `make build/reflcheck`):
  /usr/bin/python3 tools/sweep.py --run reports/runs/<id> --cache reports/cache/sweep
                                    [--scenes scenes/a.yaml ...] [--quick] [--full-size]
                                    [--jobs 2] [--threads 1] [--clock wall|cpu] [--bin build/reflcheck]
                                    [--scheduler local|slurm] [--no-worker]

What it renders (in the scene's sweep role, below, through `reflcheck run --small --tag T
--threads 1`, two jobs at a time; outputs in RUN/timing/renders/<scene>/<tag>/):
  reference  Cycles at REF spp (4096; --quick 1024), 2 seeds: the best reference the scene has,
             as the pixel integral (--supersample 1) in every role.
  cycles     Cycles at 16, 64, 256, 1024 spp (--quick 16, 64, 256), 2 seeds each.
  Levels (--levels staged, the default): stage one renders the levels below the top against the
  top level (1024 spp, seeds 0..1) as the reference; stage two adds the deep reference (REF spp,
  seeds 4..5 with `run --seed`), the top level becoming a point, only on the scenes where stage
  one leaves a crossover beyond its levels, a slope slower than -0.5 at its top, or a reference
  noise above a third of the smallest non-Cycles error (deeper_reasons). --levels all: every
  level and the deep reference everywhere. sweep.json lists each deep scene and why.
  Second runs: a raster job's repeats (CACHE/repeats/<key>.json) and the diffs of cached renders
  (CACHE/diffs/) are kept in the cache, so a run over a warm cache renders and diffs nothing new.
  raster     as-is (the scene's small-variant supersampling and tessellation, per-pixel),
             k = 1, 2, 4, 8; tessellation 8, 16, 32, 64, 128 (every object); per-vertex shading.
             Raster jobs take milliseconds, so each is rendered RASTER_REPEATS times without the
             cache and the fastest time is kept (the usual benchmark minimum: noise only adds).
  povray     k = 1, 2, 4 where POV-Ray can express the validate scene (a skipped job is listed).
  eevee      TAA samples 1, 16, on scenes whose comparisons name eevee (it is judged there):
             Blender's real-time engine on the same Blender scene as Cycles.
Scenes: those of --scenes (default scenes/*.yaml). The role is `validate` where the comparisons
list `reference: cycles, role: validate` (the physical reference: raster error is the
approximation's), else `twin` where they list Cycles twin (the converged render of our own
model: raster error is sampling and harness error); scenes with neither are left out.
Size: the scene's small variant (`reflcheck run --small`; 96 pixels wide unless the scene says
otherwise), or the full size with --full-size (`reflcheck run` has no width/height option).
Errors: `reflcheck diff POINT.exr REFERENCE.exr --mask RASTER-AS-IS.exr`, surface region. A
partial twin (the reference's record lists `terms_left_out`: Cycles has no Blinn-Phong lobe, so
its twin leaves the specular out) is compared as compare.json compares it: on the terms both
sides render (`diff --leave-out TERMS` takes those layers off every image), so the error is the
sampling and harness error of the terms compared, not the size of the missing term.
Blender: Cycles jobs render in a pool of --jobs Blender workers (harness/renderers/cycles/
worker_pool.py), so Blender starts once per worker, not per job, and a Cycles job's time is its
scene build and render without Blender's start-up (--no-worker: one Blender per job, as before;
the images are the same bit for bit). Worker logs go to RUN/worker-N.log.
Slurm (--scheduler slurm, inside the allocation the nightly submits): every job is an srun step
of its own (its id, JOB.STEP, in its record); the workers run in the allocation's batch step.

Writes RUN/timing/<scene>.json (read by tools/report.py; format below), RUN/sweep.json (the
sweep's own cost: wall time, job count, cached jobs) and prints one line per scene.

timing/<scene>.json:
  {"format": "reflcheck-sweep-1", "scene": NAME, "size": [W, H], "error_key": "error",
   "clock": "wall_s"|"cpu_s" (what time_s holds),
   "error_doc": what "error" means (below),
   "reference": {"renderer": "cycles", "role": "validate"|"twin", "samples": N, "seeds": [0, 1],
                 "terms_left_out": [TERM, ...] (what the reference's record says it left out; every
                 diff leaves them out too), "terms_compared": [TERM, ...],
                 "noise_nrmse": its own noise (from its var.* layers), "nested": true|false,
                 "note": how the sweep's seeds relate to the reference's},
   "series": [{"label": "cycles spp", "renderer": "cycles", "knob": "samples",
               "fit": FIT, "fit_spp": FIT (cycles only), "time_model": {"t0_s", "s_per_spp"}
               (cycles only), "slope_note": text (cycles only),
               "points": [POINT, ...]}, ...],
   "as_is": POINT (the raster as-is),
   "pareto": [{"label", "renderer", "time_s", "error"}, ...]   (ascending time),
   "equal_time": [{"budget_s", "budget": "raster as-is"|"1 s"|..., "best": {renderer: {"label",
                   "time_s", "error"} | null}, "cycles_fit_error": number | null}, ...],
   "crossover": {"raster_error", "spp", "time_s", "render_s", "loglog_time_s", "extrapolated":
                 null|"below"|"above", "upper_bound_s" (with "below": the lowest level's time),
                 "note"} | null,
   "crossover_best_raster": same, against the raster's best point,
   "sweep": {"jobs", "cached", "wall_s", "job_time_sum_s"},
   "skipped": [{"label", "message"}, ...]}
  POINT: {"label", "renderer", "tag", "time_s" (the job's wall time, or with --clock cpu its CPU
          time; --threads 1), "wall_s", "cpu_s",
          "render_s" (Cycles: build + render inside Blender, without its start-up), "samples",
          "seeds", "supersample", "tessellation", "per_vertex", "cached",
          "rmse", "nrmse", "rel_rms", "psnr", "ssim" (raw, against the reference, surface),
          "error" (estimated NRMSE against the noise-free image; plotted and fitted),
          "noise_nrmse" (Cycles: the point's own noise from its var.* layers),
          "is_reference" (the reference itself; error = its noise estimate, never fitted)}
  FIT: {"slope", "intercept", "r2", "n", "x": "time_s"|"samples", "local": [{"from", "to",
        "slope"}]} - least squares of ln(error) on ln(x).

"error" and the reference's seeds: `reflcheck run` renders Cycles seeds 0..n-1 and PMJ sampling
is nested (the first n samples of a seed at 4096 spp are the n-spp render), so a sweep point is
part of the reference: measured MSE = var_n (1 - n/N) for independent samples. error =
nrmse / sqrt(1 - n/N) undoes it. With disjoint seeds (`run --seed`, when the CLI has it) the
reference noise adds instead, and error = sqrt(nrmse^2 - noise_ref^2). Non-Cycles points
subtract the reference noise the same way (negligible beside a model error).
Crossover: Cycles' spp at which its fitted error (ln error on ln spp) equals the raster as-is
error, turned into seconds by linear interpolation of the measured (spp, time) levels (below
the fewest samples: that level's time, an upper bound), and, for comparison, by the ln error on
ln time fit. The least-squares time model time = t0 + c * spp (t0: Blender's start-up and the
scene build) gives the fitted Cycles error at each equal-time budget.

Exit status: 0 every scene written (failed jobs are listed in the file), 1 a scene could not be
swept (reference or raster as-is missing), 2 bad usage.
"""

import argparse
import concurrent.futures as cf
import contextlib
import hashlib
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, 'harness', 'renderers', 'cycles'))
from worker_pool import WorkerPool  # noqa: E402  (needs the path above)

sys.path.insert(0, os.path.join(ROOT, 'tools'))
from progress import Progress  # noqa: E402  (needs the path above)

FORMAT = 'reflcheck-sweep-1'
CYCLES_SPP = (16, 64, 256, 1024)
REF_SPP = 4096
QUICK_SPP, QUICK_REF = (16, 64, 256), 1024
RASTER_K = (1, 2, 4, 8)
RASTER_TESS = (8, 16, 32, 64, 128)
POV_K = (1, 2, 4)
QUICK_K, QUICK_TESS, QUICK_POV = (1, 2, 4), (16, 64), (1, 2)
# EEVEE's TAA samples per pixel: deterministic, so one render per level (no seeds). Its error
# is its approximation's, not sampling's (d3d_blinn_phong: 0.0827 at 1, 0.0824 at 16) and a job
# costs 30-75 s on llvmpipe, so two levels draw its line.
EEVEE_TAA = (1, 16)
QUICK_EEVEE = (1, 16)
SEEDS = 2
# The image terms, in the order of the renderers' layers and of RENDERER_TERM_* (renderer.h).
TERMS = ('diffuse', 'specular', 'reflection', 'emission')
RASTER_REPEATS = 3
JOB_TIMEOUT_S = 3600
# Spp slope within this of -0.5 is "Monte Carlo rate": with 4 levels and 2 seeds, the scatter of
# a fitted slope is a few hundredths; 0.1 flags a real departure, not noise.
SLOPE_TOL = 0.1
# The reference's noise may be a third of the smallest error it measures: in quadrature that
# moves the error by at most 5.4 % (sqrt(1 + 1/9)), inside the scatter of two seeds.
NOISE_MARGIN = 3.0
BUDGETS_S = (1.0, 10.0, 100.0)


# ---------------------------------------------------------------------------------- maths


def fit_loglog(xs, ys):
    """Least squares of ln y on ln x over the points with x, y > 0.
    Returns {"slope", "intercept", "r2", "n"} or None with fewer than 2 distinct x."""
    pts = [(math.log(x), math.log(y)) for x, y in zip(xs, ys) if x is not None and y is not None and x > 0 and y > 0]
    if len({p[0] for p in pts}) < 2:
        return None
    n = len(pts)
    mx = sum(p[0] for p in pts) / n
    my = sum(p[1] for p in pts) / n
    sxx = sum((p[0] - mx) ** 2 for p in pts)
    sxy = sum((p[0] - mx) * (p[1] - my) for p in pts)
    syy = sum((p[1] - my) ** 2 for p in pts)
    b = sxy / sxx
    a = my - b * mx
    r2 = 1.0 if syy == 0 else (sxy * sxy) / (sxx * syy)
    return {'slope': b, 'intercept': a, 'r2': r2, 'n': n}


def fit_eval(fit, x):
    return math.exp(fit['intercept'] + fit['slope'] * math.log(x))


def fit_solve(fit, y):
    """x at which the fit reaches y; None for a flat or rising fit (it never gets there)."""
    if fit is None or fit['slope'] >= 0 or y is None or y <= 0:
        return None
    return math.exp((math.log(y) - fit['intercept']) / fit['slope'])


def local_slopes(xs, ys):
    """Slope of ln y on ln x between consecutive points (sorted by x): where a fit bends."""
    pts = sorted((x, y) for x, y in zip(xs, ys) if x and y and x > 0 and y > 0)
    return [
        {'from': a[0], 'to': b[0], 'slope': math.log(b[1] / a[1]) / math.log(b[0] / a[0])}
        for a, b in zip(pts, pts[1:])
        if b[0] != a[0]
    ]


def fit_linear(xs, ys):
    """Least squares y = a + b x. Returns (a, b) or None with fewer than 2 distinct x."""
    pts = [(x, y) for x, y in zip(xs, ys) if x is not None and y is not None]
    if len({p[0] for p in pts}) < 2:
        return None
    n = len(pts)
    mx = sum(p[0] for p in pts) / n
    my = sum(p[1] for p in pts) / n
    b = sum((p[0] - mx) * (p[1] - my) for p in pts) / sum((p[0] - mx) ** 2 for p in pts)
    return my - b * mx, b


def pareto(points):
    """Points no other point beats in both time and error (ties: the earlier in input order),
    ascending time. points: dicts with time_s and error."""
    ok = [p for p in points if p.get('time_s') is not None and p.get('error') is not None]
    ok.sort(key=lambda p: (p['time_s'], p['error']))
    front, best = [], math.inf
    for p in ok:
        if p['error'] < best:
            front.append(p)
            best = p['error']
    return front


def best_within(points, budget):
    """The lowest-error point whose time is within budget, or None."""
    ok = [p for p in points if p.get('time_s') is not None and p.get('error') is not None and p['time_s'] <= budget]
    return min(ok, key=lambda p: (p['error'], p['time_s'])) if ok else None


def nested_error(nrmse, n, n_ref):
    """Error against the noise-free image of an n-spp render whose samples are the first n of
    the n_ref-spp reference: measured MSE = var_n (1 - n/N), so divide it back out."""
    if nrmse is None or n >= n_ref:
        return None
    return nrmse / math.sqrt(1.0 - n / n_ref)


def independent_error(nrmse, noise_ref):
    """Error against the noise-free image of a render independent of the reference: the
    reference's noise adds in quadrature, so subtract it; None if it is all noise."""
    if nrmse is None:
        return None
    if not noise_ref:
        return nrmse
    d = nrmse * nrmse - noise_ref * noise_ref
    return math.sqrt(d) if d > 0 else None


def interp_time(levels, spp):
    """Seconds at spp from the measured (spp, seconds) levels: linear between the two levels
    around it, the last two levels' line beyond them, the first level's time below it (a
    bound: nothing measured is faster)."""
    lv = sorted((n, t) for n, t in levels if n is not None and t is not None)
    if not lv:
        return None
    if spp <= lv[0][0] or len(lv) == 1:
        return lv[0][1]
    for (n0, t0), (n1, t1) in zip(lv, lv[1:]):
        if spp <= n1:
            return t0 + (t1 - t0) * (spp - n0) / (n1 - n0)
    (n0, t0), (n1, t1) = lv[-2], lv[-1]
    return t1 + (t1 - t0) * (spp - n1) / (n1 - n0)


def crossover(fit_spp, levels, render_levels, fit_time, raster_error):
    """Where Cycles' fitted error (ln error on ln spp) falls to raster_error: the spp, its time
    interpolated between the measured levels (wall or CPU, and Blender's own render time), and
    the ln-error-on-ln-time fit's answer. None without a falling spp fit.
    levels / render_levels: [(spp, seconds)] of the measured Cycles levels."""
    spp = fit_solve(fit_spp, raster_error)
    if spp is None:
        return None
    ns = [n for n, _ in levels]
    out = {
        'raster_error': raster_error,
        'spp': spp,
        'time_s': interp_time(levels, spp),
        'render_s': interp_time(render_levels, spp),
        'loglog_time_s': fit_solve(fit_time, raster_error),
        'extrapolated': None,
    }
    if ns and spp < min(ns):
        # Under the fewest samples the answer is mostly Blender's start-up; the honest statement
        # is a bound: the lowest level measured already beats the raster.
        out['extrapolated'] = 'below'
        out['upper_bound_s'] = out['time_s']
    elif ns and spp > max(ns):
        out['extrapolated'] = 'above'
    return out


def slope_note(fit_spp, local):
    """Says whether Cycles' error falls as spp^-0.5, and where it does not."""
    if fit_spp is None:
        return 'no fit (fewer than two spp levels measured)'
    s = fit_spp['slope']
    off = [
        f"{int(l['from'])}->{int(l['to'])} spp: {l['slope']:.2f}" for l in local if abs(l['slope'] + 0.5) > SLOPE_TOL
    ]
    if abs(s + 0.5) <= SLOPE_TOL and not off:
        return f'spp^{s:.2f}: the Monte Carlo rate -0.5 throughout'
    why = (
        'faster than -0.5: stratified (PMJ) samples on a smooth integrand converge faster'
        if s < -0.5 - SLOPE_TOL
        else 'slower than -0.5: a floor (reference noise, clamping or bias) or rare bright paths'
        if s > -0.5 + SLOPE_TOL
        else 'overall -0.5'
    )
    return f'spp^{s:.2f} ({why})' + (f'; off -0.5 at {", ".join(off)}' if off else '')


# ---------------------------------------------------------------------------------- scenes


def scene_name(path):
    with open(path, encoding='utf-8') as f:
        for line in f:
            m = re.match(r'^name:\s*["\']?([A-Za-z0-9_.-]+)', line)
            if m:
                return m.group(1)
    return os.path.splitext(os.path.basename(path))[0]


# The renderer that computes the model (the default `test` of a comparison), from the
# renderer table (`reflcheck renderers --json`, read by renderer_table in main); None until
# then, so that an explicit `test:` never counts as the model.
MODEL = None


def renderer_table(bin_path):
    """The renderer table as the CLI lists it: name -> row (model, stochastic, program, ...).
    The sweep keeps no renderer list of its own."""
    out = subprocess.run(
        [bin_path, 'renderers', '--json'], capture_output=True, text=True, check=True, timeout=30
    ).stdout
    return {r['name']: r for r in json.loads(out)}


def lists_cycles(path, role):
    """True if the scene's comparisons hold {reference: cycles, role: ROLE} with the model
    renderer as the test (the default, or `test:` naming it). A line-level read of the list
    items: scenes/FORMAT.md keeps each comparison a `- ` item with plain keys."""
    with open(path, encoding='utf-8') as f:
        text = f.read()
    m = re.search(r'^comparisons:\s*\n((?:[ \t].*\n?|\s*\n)*)', text, re.M)
    if not m:
        return False
    for item in re.split(r'\n\s*-\s', '\n' + m.group(1)):
        test = re.search(r'\btest:\s*([A-Za-z0-9_-]+)', item)
        if (
            re.search(r'\breference:\s*cycles\b', item)
            and re.search(r'\brole:\s*' + role + r'\b', item)
            and (test is None or test.group(1) == MODEL)
        ):
            return True
    return False


def names_renderer(path, name):
    """True if one of the scene's comparisons names the renderer (as test or reference)."""
    with open(path, encoding='utf-8') as f:
        text = f.read()
    m = re.search(r'^comparisons:\s*\n((?:[ \t].*\n?|\s*\n)*)', text, re.M)
    return bool(m and re.search(r'\b(test|reference):\s*' + re.escape(name) + r'\b', m.group(1)))


def lists_cycles_validate(path):
    return lists_cycles(path, 'validate')


def sweep_role(path):
    """The best reference a scene offers: Cycles validate (the physics), else Cycles twin (the
    converged render of our own model: then the errors are sampling and harness error), else
    None (the scene is left out)."""
    for role in ('validate', 'twin'):
        if lists_cycles(path, role):
            return role
    return None


# ---------------------------------------------------------------------------------- jobs


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
        path = self.diff_path(keys, leave_out) if keys else None
        if path and os.path.exists(path):
            with contextlib.suppress(OSError, ValueError):
                with open(path, encoding='utf-8') as f:
                    return json.load(f)
        cmd = [self.bin, 'diff', test, ref, '--mask', mask] + (
            ['--leave-out', ','.join(leave_out)] if leave_out else []
        )
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
        if r.returncode != 0:
            raise RuntimeError(f'reflcheck diff {test} {ref}: ' + (r.stderr.strip().splitlines() or ['failed'])[-1])
        out = json.loads(r.stdout)
        if path:
            with contextlib.suppress(OSError):
                write_json(path, out)
        return out


def scene_diffs(runner, jobs, recs, zero):
    """Every ok job's diff against the reference (masked by the raster as-is) and the Cycles
    points' own noise; returns (diffs, noises, terms left out). A partial twin is compared on the
    terms the reference renders, as compare.json compares it; the reference's own noise needs no
    such care: its image holds no left-out term."""
    ref, mask = recs['reference']['exr'], recs['as_is']['exr']
    left = terms_left_out(recs['reference'])
    diffs, noises = {}, {}
    for j in jobs:
        if recs[j['key']].get('status') != 'ok':
            continue
        keys = (recs[j['key']].get('key'), recs['reference'].get('key'), recs['as_is'].get('key'))
        try:
            diffs[j['key']] = runner.diff(recs[j['key']]['exr'], ref, mask, left, keys=keys)
        except (RuntimeError, ValueError) as e:
            diffs[j['key'] + ':err'] = str(e)
        if j['renderer'] == 'cycles':
            # The zero image is made from the mask's render: 'zero-' and its key name it.
            zkeys = (f'zero-{keys[2]}', keys[0], keys[2]) if keys[0] and keys[2] else None
            noises[j['key']] = noise_nrmse(runner, recs[j['key']]['exr'], mask, zero, zkeys)
    return diffs, noises, left


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


def noise_nrmse(runner, exr, mask, zero, keys=None):
    """A render's own noise, as NRMSE (RMS of the var.* std-dev over the mean of the image):
    `diff ZERO X` gives rmse = rms(X) and nrmse = rms/mean over the surface, and its
    noise.ref_rel_rms = sqrt(sum var / sum X^2); so noise/mean = ref_rel_rms * nrmse."""
    if zero is None:
        return None
    try:
        d = runner.diff(zero, exr, mask, keys=keys)
    except (RuntimeError, ValueError):
        return None
    rel = (d.get('noise') or {}).get('ref_rel_rms')
    nr = (d.get('surface') or {}).get('nrmse')
    return rel * nr if rel is not None and nr else None


def make_zero(like, path):
    """An all-zero R, G, B image of like's size (oiiotool): the 'test' that turns diff into a
    norm. None if oiiotool is missing (noise estimates are then left out)."""
    exe = shutil.which('oiiotool')
    if not exe:
        return None
    r = subprocess.run(
        [exe, like, '--ch', 'R,G,B', '--mulc', '0', '-o', path], capture_output=True, text=True, timeout=120
    )
    return path if r.returncode == 0 and os.path.exists(path) else None


# ---------------------------------------------------------------------------------- plan


# Cycles as the pixel integral (k = 1: a box over the pixel): a twin's Cycles job otherwise samples
# the model's own k x k positions (harness/renderers/cycles/cycles.h), against which the raster's
# sampling error would be nil at the as-is k and the k series would converge to nothing.
CYCLES_INTEGRAL = ['--supersample', '1']


def plan(quick, seed_opt):
    """The jobs of one scene: (key, renderer, tag, options, repeats, series labels, knob value)."""
    spp = QUICK_SPP if quick else CYCLES_SPP
    ref = QUICK_REF if quick else REF_SPP
    ks, tess, pov = (QUICK_K, QUICK_TESS, QUICK_POV) if quick else (RASTER_K, RASTER_TESS, POV_K)
    jobs = [
        dict(
            key='reference',
            renderer='cycles',
            tag=f'cycles-spp{ref}',
            label=f'{ref} spp (reference)',
            opts=['--samples', str(ref), '--seeds', str(SEEDS)] + CYCLES_INTEGRAL,
            series='cycles spp',
            samples=ref,
        )
    ]
    for n in spp:
        extra = ['--seed', str(SEEDS)] if seed_opt else []
        jobs.append(
            dict(
                key=f'cycles{n}',
                renderer='cycles',
                tag=f'cycles-spp{n}' + ('-s2' if seed_opt else ''),
                label=f'{n} spp',
                opts=['--samples', str(n), '--seeds', str(SEEDS)] + CYCLES_INTEGRAL + extra,
                series='cycles spp',
                samples=n,
            )
        )
    jobs.append(
        dict(
            key='as_is',
            renderer='raster',
            tag='raster-as-is',
            label='as-is',
            opts=[],
            series='raster shading',
            repeats=RASTER_REPEATS,
        )
    )
    jobs.append(
        dict(
            key='per_vertex',
            renderer='raster',
            tag='raster-per-vertex',
            label='per-vertex',
            opts=['--per-vertex'],
            series='raster shading',
            repeats=RASTER_REPEATS,
        )
    )
    for k in ks:
        jobs.append(
            dict(
                key=f'rk{k}',
                renderer='raster',
                tag=f'raster-k{k}',
                label=f'k={k}',
                opts=['--supersample', str(k)],
                series='raster k',
                repeats=RASTER_REPEATS,
            )
        )
    for t in tess:
        jobs.append(
            dict(
                key=f'rt{t}',
                renderer='raster',
                tag=f'raster-t{t}',
                label=f'tess={t}',
                opts=['--tessellation', str(t)],
                series='raster tessellation',
                repeats=RASTER_REPEATS,
            )
        )
    for k in pov:
        jobs.append(
            dict(
                key=f'pk{k}',
                renderer='povray',
                tag=f'povray-k{k}',
                label=f'k={k}',
                opts=['--supersample', str(k)],
                series='povray k',
            )
        )
    for n in QUICK_EEVEE if quick else EEVEE_TAA:
        jobs.append(
            dict(
                key=f'ee{n}',
                renderer='eevee',
                tag=f'eevee-taa{n}',
                label=f'{n} TAA',
                opts=['--samples', str(n)],
                series='eevee taa',
                samples=n,
            )
        )
    return jobs, ref


def stage_one(jobs, ref_spp):
    """The first stage of a scene's Cycles levels: the top level (seeds 0..1) stands in for the
    reference, the levels below it are points. Returns (jobs, reference spp). The top level is
    the same render as stage two's top point (same samples and seeds: one cache key), so a scene
    that goes on to stage two renders nothing twice."""
    levels = sorted(j['samples'] for j in jobs if j['renderer'] == 'cycles' and j['key'] != 'reference')
    if len(levels) < 2:
        return jobs, ref_spp
    top = levels[-1]
    out = []
    for j in jobs:
        if j['key'] in ('reference', f'cycles{top}'):
            continue
        out.append(j)
    out.insert(0, top_job(top, 'reference', f'{top} spp (reference)'))
    return out, top


def top_job(top, key, label):
    """The top Cycles level at seeds 0..1: stage one's reference, stage two's top point."""
    return dict(
        key=key,
        renderer='cycles',
        tag=f'cycles-spp{top}',
        label=label,
        opts=['--samples', str(top), '--seeds', str(SEEDS)],
        series='cycles spp',
        samples=top,
    )


# Stage two's reference seeds (with `run --seed`): past the points' 2..3 and the top level's
# 0..1, so that it is independent of every point it measures.
DEEP_SEED = 2 * SEEDS


def stage_two(jobs1, top, ref_spp, seed_opt):
    """Stage one's jobs with the deep reference added: the stage-one reference becomes the top
    point, the reference is ref_spp at seeds DEEP_SEED.. (with --seed; else 0.., nested as
    before). Returns (jobs, ref_spp)."""
    out = [dict(j) for j in jobs1 if j['key'] != 'reference']
    out.append(top_job(top, f'cycles{top}', f'{top} spp'))
    extra = ['--seed', str(DEEP_SEED)] if seed_opt else []
    ref = dict(
        key='reference',
        renderer='cycles',
        tag=f'cycles-spp{ref_spp}' + (f'-s{DEEP_SEED}' if seed_opt else ''),
        label=f'{ref_spp} spp (reference)',
        opts=['--samples', str(ref_spp), '--seeds', str(SEEDS)] + extra,
        series='cycles spp',
        samples=ref_spp,
    )
    return [ref] + out, ref_spp


def deeper_reasons(t):
    """Why a scene swept against its stage-one reference needs the top level as a point and the
    deep reference (the rule: a render is spent where it decides a slope, a crossover or an
    error). Empty when stage one decides all three:
      crossover   Cycles reaches the raster's error (as-is or best) beyond the levels measured:
                  only higher levels place it;
      slope       between the top two levels the error falls slower than spp^-0.5 by more than
                  SLOPE_TOL: a floor (reference noise, bias) may begin, and only higher levels show
                  it (faster than -0.5 is PMJ's stratification, which stage one measures);
      reference   the reference's noise is above a third of the smallest non-Cycles error it
                  measures: the quadrature subtraction would move that error by more than 5.4 %
                  (sqrt(1 + 1/9)), so the error needs a quieter reference. (Cycles' own points
                  are corrected exactly for the reference's noise, nested or independent.)"""
    why = []
    for k in ('crossover', 'crossover_best_raster'):
        c = t.get(k)
        if c and c.get('extrapolated') == 'above':
            why.append(f"{k.replace('_', ' ')} at {c['spp']:.0f} spp, above the levels measured")
            break
    cyc = next((s for s in t['series'] if s['label'] == 'cycles spp'), None)
    fs = cyc and cyc.get('fit_spp')
    if fs is None:
        why.append('no spp slope from stage one')
    else:
        top = (fs.get('local') or [{}])[-1].get('slope', fs['slope'])
        if top > -0.5 + SLOPE_TOL:
            why.append(f'spp slope {top:.2f} between the top two levels, slower than -0.5: a floor may begin there')
    noise = (t.get('reference') or {}).get('noise_nrmse')
    errs = [
        p['error']
        for s in t['series']
        for p in s['points']
        if s['renderer'] != 'cycles' and not p['is_reference'] and p.get('error')
    ]
    if noise and errs and noise > min(errs) / NOISE_MARGIN:
        why.append(f'reference noise {noise:.3g} above a third of the smallest error {min(errs):.3g}')
    elif noise and not errs:
        why.append('no error measured against the stage-one reference')
    return why


def expected_cost(job):
    """Longest jobs first keeps both workers busy to the end (LPT scheduling)."""
    if job['renderer'] == 'cycles':
        return 2.0 + job['samples'] * 0.02
    if job['renderer'] == 'eevee':  # shader compilation on llvmpipe, then about 0.1 s a sample
        return 10.0 + job['samples'] * 0.1
    return 1.5 if job['renderer'] == 'povray' else 0.1


# ---------------------------------------------------------------------------------- analysis


def point_of(job, rec, d, noise, err, clock='wall_s'):
    s = (d or {}).get('surface') or {}
    return {
        'label': job['label'],
        'renderer': job['renderer'],
        'tag': job['tag'],
        'time_s': rec.get(clock),
        'wall_s': rec.get('wall_s'),
        'cpu_s': rec.get('cpu_s'),
        'render_s': rec.get('render_s'),
        # The job's own knob where it has one: EEVEE's record keeps no samples (not stochastic).
        'samples': job.get('samples', rec.get('samples')),
        'seeds': rec.get('seeds'),
        'supersample': rec.get('supersample'),
        'tessellation': rec.get('tessellation'),
        'per_vertex': rec.get('per_vertex'),
        'cached': rec.get('cached'),
        'rmse': s.get('rmse'),
        'nrmse': s.get('nrmse'),
        'rel_rms': s.get('rel_rms'),
        'psnr': s.get('psnr'),
        'ssim': s.get('ssim'),
        'error': err,
        'noise_nrmse': noise,
        'is_reference': job['key'] == 'reference',
    }


def terms_left_out(rec):
    """The terms a reference's job record says it left out (a partial twin), in TERMS order. The
    record lists {"term": NAME, "reason": TEXT} (a bare name is taken too)."""
    left = {e.get('term') if isinstance(e, dict) else e for e in rec.get('terms_left_out') or []}
    return [t for t in TERMS if t in left]


def analyse(
    scene, jobs, recs, diffs, noises, ref_spp, nested, size, clock='wall_s', role='validate', left_out=(), ref_seed=0
):
    """Everything but the rendering: points, fits, Pareto frontier, equal time, crossover.
    left_out: the terms the reference left out, which every diff left out too."""
    noise_ref = noises.get('reference')
    series, skipped, all_pts = {}, [], []
    for job in jobs:
        rec = recs[job['key']]
        if rec.get('status') != 'ok' or job['key'] not in diffs:
            skipped.append(
                {
                    'label': f"{job['series']} {job['label']}",
                    'message': rec.get('message') or diffs.get(job['key'] + ':err', 'no diff'),
                }
            )
            continue
        nr = diffs[job['key']]['surface'].get('nrmse')
        if job['key'] == 'reference':
            err = noise_ref
        elif job['renderer'] == 'cycles' and nested:
            err = nested_error(nr, job['samples'], ref_spp)
        else:
            err = independent_error(nr, noise_ref)
        p = point_of(job, rec, diffs[job['key']], noises.get(job['key']), err, clock)
        series.setdefault(
            job['series'],
            {
                'label': job['series'],
                'renderer': job['renderer'],
                'knob': {
                    'cycles spp': 'samples',
                    'raster k': 'supersample',
                    'povray k': 'supersample',
                    'raster tessellation': 'tessellation',
                    'raster shading': 'per_vertex',
                    'eevee taa': 'samples',
                }[job['series']],
                'points': [],
            },
        )['points'].append(p)
        all_pts.append(p)
    # The as-is raster point is also the k = (small default) point of the k series.
    as_is = next((p for p in all_pts if p['tag'] == 'raster-as-is'), None)
    out_series = []
    for label in ('cycles spp', 'raster k', 'raster tessellation', 'raster shading', 'povray k', 'eevee taa'):
        sr = series.get(label)
        if not sr:
            continue
        # Knob order (not time order): a plot line then follows the knob even where timing
        # noise at the millisecond level swaps two neighbours.
        knob = sr['knob']
        sr['points'].sort(key=lambda p: (p['is_reference'], p.get(knob) is None, p.get(knob) or 0))
        fitted = [p for p in sr['points'] if not p['is_reference']]
        sr['fit'] = fit_loglog([p['time_s'] for p in fitted], [p['error'] for p in fitted])
        if sr['fit']:
            sr['fit']['x'] = 'time_s'
            sr['fit']['local'] = local_slopes([p['time_s'] for p in fitted], [p['error'] for p in fitted])
        if label == 'cycles spp':
            xs, ys = [p['samples'] for p in fitted], [p['error'] for p in fitted]
            sr['fit_spp'] = fit_loglog(xs, ys)
            local = local_slopes(xs, ys)
            if sr['fit_spp']:
                sr['fit_spp']['x'] = 'samples'
                sr['fit_spp']['local'] = local
            sr['slope_note'] = slope_note(sr['fit_spp'], local)
            every = sr['points']
            lin = fit_linear([p['samples'] for p in every], [p['time_s'] for p in every])
            rlin = fit_linear([p['samples'] for p in every], [p['render_s'] for p in every])
            sr['time_model'] = (
                None
                if lin is None
                else {
                    't0_s': lin[0],
                    's_per_spp': lin[1],
                    'render_t0_s': rlin[0] if rlin else None,
                    'render_s_per_spp': rlin[1] if rlin else None,
                }
            )
        out_series.append(sr)

    front = pareto(all_pts)
    cyc = series.get('cycles spp')
    budgets = ([('raster as-is', as_is['time_s'])] if as_is else []) + [(f'{b:g} s', b) for b in BUDGETS_S]
    equal = []
    for name, b in budgets:
        best = {}
        for r in dict.fromkeys(j['renderer'] for j in jobs):  # the plan's renderers, in order
            p = best_within([q for q in all_pts if q['renderer'] == r], b)
            best[r] = None if p is None else {'label': p['label'], 'time_s': p['time_s'], 'error': p['error']}
        fe = None
        if cyc and cyc.get('time_model') and cyc.get('fit_spp'):
            tm = cyc['time_model']
            if tm['s_per_spp'] > 0 and b > tm['t0_s']:
                fe = fit_eval(cyc['fit_spp'], (b - tm['t0_s']) / tm['s_per_spp'])
        equal.append({'budget': name, 'budget_s': b, 'best': best, 'cycles_fit_error': fe})

    cross = cross_best = None
    if cyc and as_is:
        lv = [(p['samples'], p['time_s']) for p in cyc['points'] if not p['is_reference']]
        rlv = [(p['samples'], p['render_s']) for p in cyc['points'] if not p['is_reference']]
        cross = crossover(cyc.get('fit_spp'), lv, rlv, cyc.get('fit'), as_is['error'])
        rast = [p for p in all_pts if p['renderer'] == 'raster' and p['error']]
        if rast:
            b = min(rast, key=lambda p: p['error'])
            cross_best = crossover(cyc.get('fit_spp'), lv, rlv, cyc.get('fit'), b['error'])
            if cross_best:
                cross_best['raster_label'] = b['label']
    for c in (cross, cross_best):
        if c:
            c['note'] = {
                None: 'interpolated between measured spp levels',
                'below': 'below the fewest samples measured: Cycles at its lowest level is already '
                'closer to the reference than the raster',
                'above': 'beyond the most samples measured: extrapolated on the fit',
            }[c['extrapolated']]
    return {
        'format': FORMAT,
        'scene': scene,
        'size': size,
        'error_key': 'error',
        'clock': clock,
        'error_doc': 'estimated NRMSE (surface RMSE over the reference mean) against the noise-free '
        'image: the measured NRMSE against the reference with the reference noise taken '
        'out (see tools/sweep.py)'
        + (
            f'; a partial {role}: {", ".join(left_out)} left out of every image, as the reference '
            f'leaves it out; terms compared: {", ".join(t for t in TERMS if t not in left_out)}'
            if left_out
            else ''
        ),
        'reference': {
            'renderer': 'cycles',
            'role': role,
            'terms_left_out': list(left_out),
            'terms_compared': [t for t in TERMS if t not in left_out],
            'samples': ref_spp,
            'seeds': list(range(ref_seed, ref_seed + SEEDS)),
            'noise_nrmse': noise_ref,
            'nested': nested,
            'note': (
                'sweep points use seeds 0..1 too: they are the first n samples of the '
                'reference (PMJ is nested); error corrects the measured NRMSE by '
                '1/sqrt(1 - n/N)'
            )
            if nested
            else (
                'sweep points use seeds 2..3, disjoint from the reference\'s; error takes '
                'the reference noise out in quadrature'
            )
            if ref_seed == 0
            else (
                f'sweep points use seeds 2..3 and the top level seeds 0..1, disjoint from the '
                f'reference\'s {ref_seed}..{ref_seed + SEEDS - 1}; error takes the reference noise out '
                'in quadrature'
            ),
        },
        'series': out_series,
        'as_is': as_is,
        'pareto': [
            {'label': p['label'], 'renderer': p['renderer'], 'time_s': p['time_s'], 'error': p['error']} for p in front
        ],
        'equal_time': equal,
        'crossover': cross,
        'crossover_best_raster': cross_best,
        'skipped': skipped,
    }


# ---------------------------------------------------------------------------------- main


def write_json(path, obj):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=os.path.dirname(path), prefix='.sweep', suffix='.tmp')
    with os.fdopen(fd, 'w', encoding='utf-8') as f:
        json.dump(obj, f, indent=1, allow_nan=False, default=lambda o: None)
        f.write('\n')
    os.replace(tmp, path)


def clean_nan(o):
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, dict):
        return {k: clean_nan(v) for k, v in o.items()}
    if isinstance(o, list):
        return [clean_nan(v) for v in o]
    return o


def collect(futs, recs, progress, cost):
    """Gathers the jobs' records as they finish, showing progress at least every 10 s and
    naming a failed job when it fails (tools/progress.py)."""
    pending = set(futs)
    while pending:
        finished, pending = cf.wait(pending, timeout=progress.every, return_when=cf.FIRST_COMPLETED)
        progress.tick()
        for f in finished:
            sp, key = futs[f]
            try:
                rec = f.result()
            except (OSError, subprocess.TimeoutExpired) as e:
                rec = {'status': 'error', 'message': str(e)}
            recs[(sp, key)] = rec
            bad = rec.get('status') not in ('ok', 'skipped')
            why = str(rec.get('message') or '').splitlines()[:1]
            failed = f'{scene_name(sp)}/{key}: {rec.get("status")}: {"".join(why)}' if bad else None
            progress.done(cost[(sp, key)], failed)
    progress.close()


def run_work(runner, n, work, recs, label):
    """Renders the (scene path, name, job) list, n at a time, longest first (LPT), into recs."""
    work = sorted(work, key=lambda w: -expected_cost(w[2]))
    if not work:
        return
    with cf.ThreadPoolExecutor(max_workers=n) as ex:
        futs = {
            ex.submit(runner.run, sp, name, j['renderer'], j['tag'], j['opts'], j.get('repeats', 1)): (sp, j['key'])
            for sp, name, j in work
        }
        cost = {(sp, j['key']): expected_cost(j) for sp, name, j in work}
        collect(futs, recs, Progress(label, len(work), sum(cost.values())), cost)


def analyse_all(runner, args, scenes, plans, recs, nested, ref_seeds):
    """sweep_scene for every scene, --jobs at a time (the diffs are processes of their own, so
    threads overlap them): scene path -> timing dict or the reason there is none."""

    def one(sp):
        name, jobs, ref_spp = plans[sp]
        r = {j['key']: recs[(sp, j['key'])] for j in jobs}
        return sweep_scene(runner, args, name, jobs, r, ref_spp, nested, ref_seeds.get(sp, 0))

    with cf.ThreadPoolExecutor(max_workers=args.jobs) as ex:
        return dict(zip(scenes, ex.map(one, scenes)))


def sweep_scene(runner, args, name, jobs, r, ref_spp, nested, ref_seed=0):
    """One scene's timing JSON from its records r (job key -> record), or the reason it has
    none (its reference or raster as-is failed)."""
    if r['reference'].get('status') != 'ok' or r['as_is'].get('status') != 'ok':
        bad = 'reference' if r['reference'].get('status') != 'ok' else 'as_is'
        return f'the {bad} render failed: {r[bad].get("message")}; see its log under {runner.renders}/{name}'
    zero = make_zero(r['as_is']['exr'], os.path.join(runner.renders, name, 'zero.exr'))
    diffs, noises, left = scene_diffs(runner, jobs, r, zero)
    rec0 = r['as_is']
    return analyse(
        name,
        jobs,
        r,
        diffs,
        noises,
        ref_spp,
        nested,
        [rec0.get('width'), rec0.get('height')],
        args.clock + '_s',
        runner.roles.get(name, 'validate'),
        left,
        ref_seed,
    )


def main(argv=None):
    ap = argparse.ArgumentParser(description='error against render time for every renderer knob (see the docstring)')
    ap.add_argument('--run', required=True, help='run folder; writes RUN/timing/<scene>.json')
    ap.add_argument(
        '--cache',
        default=os.path.join('reports', 'cache', 'sweep'),
        help='job cache (keep it apart from the nightly cache: its records were timed with other threads)',
    )
    ap.add_argument('--scenes', nargs='*', help='scene files (default: every scene listing cycles validate)')
    ap.add_argument('--quick', action='store_true', help='fewer levels, reference at 1024 spp')
    ap.add_argument('--full-size', action='store_true', help="the scenes' full size instead of the small variant")
    ap.add_argument('--jobs', type=int, default=2, help='jobs at a time (default 2)')
    ap.add_argument('--threads', type=int, default=1, help='threads per job (default 1, for comparable times)')
    ap.add_argument('--bin', default=os.path.join('build', 'reflcheck'))
    ap.add_argument(
        '--clock',
        choices=('wall', 'cpu'),
        default='wall',
        help="time_s: the job's wall time (default) or its CPU time (robust when other work "
        "shares the cores; equal to wall on an idle core with --threads 1)",
    )
    ap.add_argument(
        '--scheduler',
        choices=('local', 'slurm'),
        default='local',
        help='slurm: run inside a Slurm allocation (the nightly submits the sweep), each job an srun step',
    )
    ap.add_argument(
        '--levels',
        choices=('staged', 'all'),
        default='staged',
        help="staged (default): every level below the top against the top level, then the top "
        "level and the deep reference only where a slope, crossover or error needs them "
        "(deeper_reasons); all: every level and the deep reference on every scene (as before)",
    )
    ap.add_argument(
        '--no-worker',
        action='store_true',
        help='start Blender for every Cycles job (the way before the worker pool; for comparisons)',
    )
    args = ap.parse_args(argv)
    if args.scheduler == 'slurm' and not os.environ.get('SLURM_JOB_ID'):
        print(
            'sweep.py: --scheduler slurm runs inside a Slurm allocation; submit it with sbatch '
            '(SCHEDULER=slurm make report does)',
            file=sys.stderr,
        )
        return 2
    if not os.path.isfile(args.bin) or not os.access(args.bin, os.X_OK):
        print(f'sweep.py: --bin {args.bin}: not an executable; build it with `make build/reflcheck`', file=sys.stderr)
        return 2
    if args.jobs < 1 or args.threads < 1:
        print('sweep.py: --jobs and --threads must be at least 1', file=sys.stderr)
        return 2
    global MODEL
    try:
        table = renderer_table(args.bin)
    except (OSError, ValueError, subprocess.SubprocessError) as e:
        print(
            f'sweep.py: {args.bin} renderers --json: {e}; build a reflcheck that lists its renderers', file=sys.stderr
        )
        return 2
    MODEL = next((n for n, r in table.items() if r.get('model')), None)
    scenes = args.scenes or sorted(os.path.join('scenes', f) for f in os.listdir('scenes') if f.endswith('.yaml'))
    for s in scenes:
        if not os.path.isfile(s):
            print(f'sweep.py: --scenes {s}: no such scene file; list scenes/*.yaml', file=sys.stderr)
            return 2
    # The best reference each scene has: Cycles validate, else Cycles twin (sweep_role).
    left_out = [s for s in scenes if sweep_role(s) is None]
    scenes = [s for s in scenes if s not in left_out]
    if left_out:
        print(f'sweep: left out (no cycles comparison): {" ".join(left_out)}')

    runner = Runner(args)
    for sp in scenes:
        runner.roles[scene_name(sp)] = sweep_role(sp)
    nested = not runner.seed_opt
    t_start = time.monotonic()
    plans, full = {}, {}
    for sp in scenes:
        name = scene_name(sp)
        jobs, ref_spp = plan(args.quick, runner.seed_opt)
        # Knobs of a renderer this reflcheck does not have are not swept.
        jobs = [j for j in jobs if j['renderer'] in table]
        # EEVEE is swept where it is judged: a scene without an EEVEE comparison would spend
        # 30-75 s a job on figures nobody asked for.
        jobs = [j for j in jobs if j['renderer'] != 'eevee' or names_renderer(sp, 'eevee')]
        full[sp] = (jobs, ref_spp)
        plans[sp] = (name, jobs, ref_spp) if args.levels == 'all' else (name, *stage_one(jobs, ref_spp))
    work = [(sp, name, j) for sp, (name, jobs, _) in plans.items() for j in jobs]
    recs, deeper = {}, {}
    # One Blender per parallel job renders every Cycles job in turn (worker_pool.py): Blender's
    # start-up is paid once per worker, not once per job, and job times no longer include it.
    use_pool = not args.no_worker and 'cycles' in table and any(w[2]['renderer'] == 'cycles' for w in work)
    pool = WorkerPool(args.jobs, log_dir=args.run) if use_pool else contextlib.nullcontext()
    with pool:
        if use_pool:
            runner.env = dict(os.environ, **pool.env())
        run_work(runner, args.jobs, work, recs, 'sweep')
        if args.levels == 'staged':
            # Stage two: the top level and the deep reference, only where stage one left a
            # slope, a crossover or an error undecided (deeper_reasons).
            more = []
            first = analyse_all(runner, args, scenes, plans, recs, nested, {})
            for sp in scenes:
                name, jobs, top = plans[sp]
                why = deeper_reasons(first[sp]) if isinstance(first[sp], dict) else []
                if not why:
                    continue
                deeper[sp] = why
                recs[(sp, f'cycles{top}')] = recs.pop((sp, 'reference'))
                jobs2, ref_spp = stage_two(jobs, top, full[sp][1], runner.seed_opt)
                plans[sp] = (name, jobs2, ref_spp)
                more += [(sp, name, j) for j in jobs2 if j['key'] == 'reference']
            run_work(runner, args.jobs, more, recs, 'sweep, deep references')
            work += more
    t_render = time.monotonic() - t_start

    rc = 0
    summary = {
        'scenes': {},
        'render_wall_s': t_render,
        'jobs': len(work),
        'cached': sum(1 for r in recs.values() if r.get('cached')),
        'job_time_sum_s': sum(r.get('sweep_elapsed_s') or 0 for r in recs.values()),
        'threads_per_job': args.threads,
        'parallel_jobs': args.jobs,
        'blender_worker': use_pool,
        'scheduler': args.scheduler,
        'quick': args.quick,
        'size': 'full' if args.full_size else 'small',
        'nested_reference': nested,
        'levels': args.levels,
        'deep_reference': {scene_name(sp): why for sp, why in deeper.items()},
    }
    seeds = {sp: DEEP_SEED for sp in deeper if runner.seed_opt}
    final = analyse_all(runner, args, scenes, plans, recs, nested, seeds)
    for sp in scenes:
        name, jobs, ref_spp = plans[sp]
        r = {j['key']: recs[(sp, j['key'])] for j in jobs}
        t = final[sp]
        if not isinstance(t, dict):
            print(f'sweep.py: {sp}: {t}', file=sys.stderr)
            rc = 1
            continue
        t['sweep'] = {
            'jobs': len(jobs),
            'cached': sum(1 for v in r.values() if v.get('cached')),
            'job_time_sum_s': sum(v.get('sweep_elapsed_s') or 0 for v in r.values()),
            'threads_per_job': args.threads,
            'stage': 2 if sp in deeper or args.levels == 'all' else 1,
            'deep_reference_why': deeper.get(sp, []),
        }
        write_json(os.path.join(args.run, 'timing', f'{name}.json'), clean_nan(t))
        summary['scenes'][name] = t['sweep']
        print(one_line(t))
    summary['wall_s'] = time.monotonic() - t_start
    write_json(os.path.join(args.run, 'sweep.json'), clean_nan(summary))
    print(
        f"sweep: {len(scenes)} scenes, {summary['jobs']} jobs ({summary['cached']} cached), "
        f"{summary['wall_s']:.1f} s wall on {args.jobs} workers x {args.threads} thread(s); "
        f"serial job time {summary['job_time_sum_s']:.1f} s"
    )
    return rc


def fmt(v, spec='.3g'):
    return '-' if v is None else format(v, spec)


def one_line(t):
    cyc = next((s for s in t['series'] if s['label'] == 'cycles spp'), {})
    fs, c = cyc.get('fit_spp'), t.get('crossover')
    ref = t.get('reference') or {}
    left = ref.get('terms_left_out') or []
    role = f"role {ref.get('role', '?')}" + (
        f" on {'+'.join(ref.get('terms_compared') or [])} ({'+'.join(left)} left out)" if left else ''
    )
    return (
        f"{t['scene']} ({role}): raster as-is error {fmt((t['as_is'] or {}).get('error'))}; cycles slope "
        f"{fmt(fs and fs['slope'], '.2f')}/spp, {fmt(cyc.get('fit') and cyc['fit']['slope'], '.2f')}/s; "
        f"crossover {fmt(c and c['spp'], '.3g')} spp = {fmt(c and c['time_s'], '.3g')} s"
        + (f" ({c['extrapolated']} the measured range)" if c and c['extrapolated'] else '')
    )


if __name__ == '__main__':
    sys.exit(main())
