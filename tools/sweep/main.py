"""main.py - the command line: scenes chosen, jobs planned and run (a Blender worker pool, local
or Slurm) in one queue where a scene goes a stage deeper as soon as its analysis asks for it
(Pipeline), and the files written."""

import argparse
import contextlib
import os
import subprocess
import sys
import threading
import time

from .analysis import analyse, make_zero, one_line, scene_diffs
from .common import ROOT, clean_nan, write_json
from .plan import expected_cost, ladder, plan, stage_decision, stage_next, stage_one, stage_seed
from .runner import Runner
from .schedule import TaskQueue
from .scenes import SceneError, names_renderer, renderer_table, scene_name, sweep_role, use_bin

sys.path.insert(0, os.path.join(ROOT, 'harness', 'renderers', 'cycles'))
from worker_pool import WorkerPool  # noqa: E402  (needs the path above)

sys.path.insert(0, os.path.join(ROOT, 'tools'))
from progress import Progress  # noqa: E402  (needs the path above)


def scene_order(scenes, roles):
    """Scenes in the order their stage-one jobs are queued: twins first, so that the scenes
    likely to go deeper (a twin's Cycles error is sampling alone: in the nightly of 2026-11-27
    all 13 twins went to 1024 or 4096 spp, 3 of the 13 validate scenes did) finish stage one
    early and their deeper references overlap the other scenes' stage one instead of trailing
    it. Only the order: every scene gets the same jobs."""
    return sorted(scenes, key=lambda sp: (roles.get(sp) != 'twin', scenes.index(sp)))


def job_slot(job, args):
    """The kind of slot a job takes (schedule.TaskQueue): POV-Ray waits, it does not compute."""
    return 'wait' if job['renderer'] == 'povray' and args.scheduler == 'local' else 'cpu'


def run_one(runner, sp, job):
    """One job's record; a job that could not start or timed out is an error record."""
    try:
        return runner.run(sp, scene_name(sp), job['renderer'], job['tag'], job['opts'], job.get('repeats', 1))
    except (OSError, subprocess.TimeoutExpired) as e:
        return {'status': 'error', 'message': str(e)}


class Pipeline:
    """Every scene's stages in one queue: a scene is analysed the moment its last job lands,
    and a deeper stage's reference is queued at once (first in line), so no slot waits for
    other scenes' stages. Priorities: analyses, then deeper references (longest first), then
    stage-one jobs scene by scene (scene_order), longest first within a scene."""

    def __init__(self, runner, args, plans, full, recs, state, nested):
        self.runner, self.args, self.plans, self.full = runner, args, plans, full
        self.recs, self.state, self.nested = recs, state, nested
        self.lock = threading.Lock()
        self.left = {}  # scene path -> jobs not yet landed
        self.final = {}  # scene path -> its last analysis (timing dict or why there is none)
        self.added = []  # the deeper stages' jobs
        self.rank = {}
        self.queue = self.progress = None

    def run(self, scenes, roles):
        work = [(sp, j) for sp in scene_order(scenes, roles) for j in self.plans[sp][1]]
        self.rank = {sp: i for i, sp in enumerate(scene_order(scenes, roles))}
        self.progress = Progress('sweep', len(work), sum(expected_cost(j) for _, j in work))
        slots = {'cpu': self.args.jobs, 'wait': self.args.jobs if self.args.scheduler == 'local' else 0}
        self.queue = TaskQueue(slots)
        for sp in scenes:
            self.left[sp] = len(self.plans[sp][1])
        try:
            for sp, j in work:
                self.put_job(sp, j, (2, self.rank[sp], -expected_cost(j)))
            while not self.queue.wait_idle(self.progress.every):
                with self.lock:
                    self.progress.tick()
        finally:
            self.queue.close()
        self.progress.close()
        return self.final

    def put_job(self, sp, job, priority):
        self.queue.put(job_slot(job, self.args), priority, lambda: self.land(sp, job, run_one(self.runner, sp, job)))

    def land(self, sp, job, rec):
        bad = rec.get('status') not in ('ok', 'skipped')
        why = ''.join(str(rec.get('message') or '').splitlines()[:1])
        with self.lock:
            self.recs[(sp, job['key'])] = rec
            failed = f'{scene_name(sp)}/{job["key"]}: {rec.get("status")}: {why}' if bad else None
            self.progress.done(expected_cost(job), failed)
            self.left[sp] -= 1
            last = self.left[sp] == 0
        if last:
            self.queue.put('cpu', (0, self.rank[sp]), lambda: self.analyse(sp))

    def analyse(self, sp):
        name, jobs, top = self.plans[sp]
        with self.lock:
            r = {j['key']: self.recs[(sp, j['key'])] for j in jobs}
        t = sweep_scene(self.runner, self.args, name, jobs, r, top, self.nested, self.state['seeds'].get(sp, 0))
        ref = None
        if self.args.levels == 'staged':
            ref = next_stage(self.runner, sp, self.plans, self.full, self.recs, self.state, t, self.lock)
        if ref is None:
            # This analysis is the scene's last: its plan and records stay as they are.
            self.final[sp] = t
            return
        with self.lock:
            self.added.append((sp, name, ref))
            self.left[sp] = 1
            self.progress.total += 1
            self.progress.total_weight += expected_cost(ref)
        self.put_job(sp, ref, (1, -expected_cost(ref), self.rank[sp]))


def next_stage(runner, sp, plans, full, recs, state, t, lock):
    """The stage after a scene's analysis t (plan.stage_decision): its next reference job, or
    None where this stage decides (or the ladder ends). Keeps the reasons (state['deeper'],
    prefixed with the level they were found at), what is left open (state['undecided']), the
    stage and the reference's first seed, and renames the reference's record to the point it
    becomes."""
    name, jobs, top = plans[sp]
    steps = ladder(*full[sp])
    # The highest level a deeper stage can make a point: the ladder's last but one.
    reach = steps[-2] if len(steps) > 1 else top
    decision = stage_decision(t, top, reach, steps[-1]) if isinstance(t, dict) else {}
    why = decision.get('deep') or []
    with lock:
        state['undecided'][sp] = decision.get('not_deep', [])
        if why and top >= steps[-1]:
            state['undecided'][sp] += [f'{w} (no level above {top} spp)' for w in why]
            return None
        if not why:
            return None
        state['deeper'].setdefault(sp, []).extend(f'at {top} spp: {w}' for w in why)
        state['stage'][sp] += 1
        recs[(sp, f'cycles{top}')] = recs.pop((sp, 'reference'))
        jobs2, new_top = stage_next(jobs, top, steps, runner.seed_opt, state['stage'][sp])
        if runner.seed_opt:
            state['seeds'][sp] = stage_seed(state['stage'][sp])
        plans[sp] = (name, jobs2, new_top)
    return next(j for j in jobs2 if j['key'] == 'reference')


def sweep_scene(runner, args, name, jobs, r, ref_spp, nested, ref_seed=0):
    """One scene's timing JSON from its records r (job key -> record), or the reason it has
    none (its reference or raster as-is failed)."""
    if r['reference'].get('status') != 'ok' or r['as_is'].get('status') != 'ok':
        bad = 'reference' if r['reference'].get('status') != 'ok' else 'as_is'
        return f'the {bad} render failed: {r[bad].get("message")}; see its log under {runner.renders}/{name}'
    # The zero image has the as-is render's size, which no stage changes: made once a size
    # (an oiiotool run of ~0.26 CPU-s; the 26 swept scenes have a handful of sizes), under the
    # runner's lock, since two scenes' analyses may run at once.
    size = (r['as_is'].get('width'), r['as_is'].get('height'))
    if None in size:
        size = name
    with runner.zero_lock:
        zero = runner.zeros.get(size)
        if zero is None:
            path = os.path.join(runner.renders, name, 'zero.exr')
            if size != name:
                path = os.path.join(runner.renders, f'zero-{size[0]}x{size[1]}.exr')
            zero = runner.zeros[size] = make_zero(r['as_is']['exr'], path)
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


def parser():
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
    ap.add_argument(
        '--jobs',
        type=int,
        default=2,
        help='CPU jobs at a time (default 2; POV-Ray jobs, which wait, take as many slots again)',
    )
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
        help="staged (default): 16 and 64 spp against 256, then 1024 and 4096 as references one "
        "level at a time, only where a deeper level can change a figure (plan.stage_decision, "
        "docs/sweep.md); all: every level and the 4096-spp reference on every scene",
    )
    ap.add_argument(
        '--no-worker',
        action='store_true',
        help='start Blender for every Cycles job (the way before the worker pool; for comparisons)',
    )
    return ap


def usage_error(args):
    """The one line that says what is wrong with the options, or None."""
    if args.scheduler == 'slurm' and not os.environ.get('SLURM_JOB_ID'):
        return (
            '--scheduler slurm runs inside a Slurm allocation; submit it with sbatch '
            '(SCHEDULER=slurm make report does)'
        )
    if not os.path.isfile(args.bin) or not os.access(args.bin, os.X_OK):
        return f'--bin {args.bin}: not an executable; build it with `make build/reflcheck`'
    if args.jobs < 1 or args.threads < 1:
        return '--jobs and --threads must be at least 1'
    # The run folder holds the Blender workers' logs from the start: a missing one was a
    # traceback from the worker pool.
    if not os.path.isdir(args.run):
        return f'--run {args.run}: no such folder; create it (mkdir -p) or name a run folder'
    return None


def write_scenes(args, scenes, plans, recs, state, final, summary):
    """RUN/timing/<scene>.json for every scene analysed (final), with its own cost, and one line
    each; a scene without one is named on stderr. Returns the exit status (1: one is missing)."""
    rc = 0
    deeper, undecided, stages = state['deeper'], state['undecided'], state['stage']
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
            'stage': 'all' if args.levels == 'all' else stages[sp],
            'deep_reference_why': deeper.get(sp, []),
            # What stage one left open without a deeper level being able to decide it.
            'not_deep': undecided.get(sp, []),
        }
        write_json(os.path.join(args.run, 'timing', f'{name}.json'), clean_nan(t))
        summary['scenes'][name] = t['sweep']
        print(one_line(t))
        print(f"  {stage_line(t['sweep'], args.levels)}")
    return rc


def stage_line(sw, levels):
    """Why the scene went to stage two or stayed at stage one (plan.stage_decision)."""
    if levels == 'all':
        return 'stage two: --levels all'
    why = '; '.join(sw['deep_reference_why'])
    left = '; '.join(sw['not_deep']) if sw['not_deep'] else f"stage {sw['stage']} decides every figure"
    return f"stage {sw['stage']}" + (f' (deeper because {why})' if why else '') + f': {left}'


def main(argv=None):
    args = parser().parse_args(argv)
    bad = usage_error(args)
    if bad:
        print(f'sweep.py: {bad}', file=sys.stderr)
        return 2
    try:
        table = renderer_table(args.bin)
    except (OSError, ValueError, subprocess.SubprocessError) as e:
        print(
            f'sweep.py: {args.bin} renderers --json: {e}; build a reflcheck that lists its renderers', file=sys.stderr
        )
        return 2
    use_bin(args.bin)
    scenes = args.scenes or sorted(os.path.join('scenes', f) for f in os.listdir('scenes') if f.endswith('.yaml'))
    for s in scenes:
        if not os.path.isfile(s):
            print(f'sweep.py: --scenes {s}: no such scene file; list scenes/*.yaml', file=sys.stderr)
            return 2
    # The best reference each scene has: Cycles validate, else Cycles twin (sweep_role), as the
    # C parser reads the scene (scenes.py).
    try:
        roles = {s: sweep_role(s) for s in scenes}
    except SceneError as e:
        print(f'sweep.py: {e}', file=sys.stderr)
        return 2
    left_out = [s for s in scenes if roles[s] is None]
    scenes = [s for s in scenes if s not in left_out]
    if left_out:
        print(f'sweep: left out (no cycles comparison): {" ".join(left_out)}')

    runner = Runner(args)
    for sp in scenes:
        runner.roles[scene_name(sp)] = roles[sp]
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
    n_stage_one = sum(len(jobs) for _, jobs, _ in plans.values())
    recs = {}
    state = {'deeper': {}, 'undecided': {}, 'stage': {sp: 1 for sp in scenes}, 'seeds': {}}
    deeper, undecided = state['deeper'], state['undecided']
    # One Blender per parallel job renders every Cycles job in turn (worker_pool.py): Blender's
    # start-up is paid once per worker, not once per job, and job times no longer include it.
    use_pool = (
        not args.no_worker
        and 'cycles' in table
        and any(j['renderer'] == 'cycles' for _, jobs, _ in plans.values() for j in jobs)
    )
    pool = WorkerPool(args.jobs, log_dir=args.run) if use_pool else contextlib.nullcontext()
    pipe = Pipeline(runner, args, plans, full, recs, state, nested)
    with pool:
        if use_pool:
            runner.env = dict(os.environ, **pool.env())
        final = pipe.run(scenes, roles)
    t_render = time.monotonic() - t_start

    summary = {
        'scenes': {},
        # Renders and analyses overlap now (a scene is analysed as its jobs land): the time
        # until the last of them.
        'render_wall_s': t_render,
        'jobs': n_stage_one + len(pipe.added),
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
        'not_deep': {scene_name(sp): why for sp, why in undecided.items() if why and sp not in deeper},
    }
    rc = write_scenes(args, scenes, plans, recs, state, final, summary)
    summary['wall_s'] = time.monotonic() - t_start
    write_json(os.path.join(args.run, 'sweep.json'), clean_nan(summary))
    print(
        f"sweep: {len(scenes)} scenes, {summary['jobs']} jobs ({summary['cached']} cached), "
        f"{summary['wall_s']:.1f} s wall on {args.jobs} workers x {args.threads} thread(s); "
        f"serial job time {summary['job_time_sum_s']:.1f} s"
    )
    return rc
