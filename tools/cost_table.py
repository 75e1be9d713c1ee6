#!/usr/bin/python3
"""cost_table.py - docs/cost.md from the runs of ops/cost_growth.sh: how the nightly's cost
grows with the number of scenes, and what a Slurm cluster of N nodes would take.

Usage: /usr/bin/python3 tools/cost_table.py [--cpus C] [--copy-of COMMIT] RUN... > docs/cost.md
  RUN: a run folder of ops/cost_growth.sh (RUN/cost.txt, RUN/calls.tsv, RUN/stages.tsv, the
  job records RUN/<scene>/<renderer>-<role>.json and the plan RUN/jobs.mk). --cpus: CPUs per
  node of the estimate (default 2, this machine's). --copy-of: the runs were made in a copy of
  the tree at COMMIT (`git archive`, so that edits to the working tree during a long run do not
  reach it), which the nightly cannot name (outside git, or inside another checkout whose HEAD
  it would give).

Everything printed comes from those files: the nightly's wall and CPU time (cost.txt); each
job's CPU seconds, whole (its `reflcheck run` call in calls.tsv, the renderer it started
included) and the renderer's alone (its record's cpu_s); the CPU seconds of every other call
of the reflcheck program (compare, fit, stability, ...; calls.tsv); each stage's wall time
(stages.tsv). The estimate for the largest run is a list schedule over its measured jobs (see
`estimate`).
"""

import glob
import heapq
import json
import os
import re
import sys

NODES = (1, 2, 4, 8, 16, 32)


def read_cost(run):
    out = {}
    with open(os.path.join(run, 'cost.txt'), encoding='utf-8') as f:
        for line in f:
            k, _, v = line.rstrip('\n').partition(' ')
            out[k] = v
    return out


def read_summary(run):
    """The run's summary.json ({} when the run stopped before its report)."""
    try:
        with open(os.path.join(run, 'summary.json'), encoding='utf-8') as f:
            return json.load(f)
    except (OSError, ValueError):
        return {}


def read_stages(run):
    """{stage: (wall s, CPU s or None)} from stages.tsv (name, wall, and the CPU seconds of the
    processes the stage waited for where the nightly wrote them)."""
    stages = {}
    try:
        with open(os.path.join(run, 'stages.tsv'), encoding='utf-8') as f:
            for line in f:
                k, wall, *cpu = line.rstrip('\n').split('\t')
                stages[k] = (float(wall), float(cpu[0]) if cpu else None)
    except OSError:
        pass
    return stages


def plan_order(run):
    """The record paths in the plan's order (the order make and Slurm take the jobs in)."""
    with open(os.path.join(run, 'jobs.mk'), encoding='utf-8') as f:
        return [m.group(1) for m in re.finditer(r'^all: (\S+)$', f.read(), re.M)]


def read_calls(run):
    """{subcommand: [(cpu_s, wall_s, words)]}: calls.tsv's lines (wall, user, sys, command line);
    GNU time's own notes ("Command exited with non-zero status 1") are skipped."""
    calls = {}
    with open(os.path.join(run, 'calls.tsv'), encoding='utf-8') as f:
        for line in f:
            parts = line.rstrip('\n').split('\t')
            if len(parts) != 4:
                continue
            words = parts[3].split()
            sub = words[1] if len(words) > 1 else '?'
            calls.setdefault(sub, []).append((float(parts[1]) + float(parts[2]), float(parts[0]), words))
    return calls


def run_cpu(calls):
    """{(scene path, renderer, role): CPU s} of the `reflcheck run` calls."""
    out = {}
    for cpu, _, words in calls.get('run', []):
        opt = {words[i]: words[i + 1] for i in range(len(words) - 1) if words[i].startswith('--')}
        out[(words[-1], opt.get('--renderer'), opt.get('--role'))] = cpu
    return out


def pooled(run):
    """Whether the run's Cycles jobs rendered in the nightly's Blender workers (worker_pool.py,
    which leaves RUN/worker-N.log): then a job's `reflcheck run` call holds none of its render."""
    return bool(glob.glob(os.path.join(glob.escape(run), 'worker-*.log')))


def blender_passes(rec):
    """Blender passes of a Cycles job: the record's noise.passes (a pilot and each step of
    image.samples auto, cycles.c); a record from before it: a pilot and one more pass when the
    samples exceed the pilot's (a lower bound: a job may step more than once), else one."""
    noise = rec.get('noise') or {}
    if noise.get('passes'):
        return int(noise['passes'])
    pilot = noise.get('pilot_samples') or 0
    return 2 if pilot and rec.get('samples', 0) > pilot else 1


def read_jobs(run, calls):
    """[(record path, renderer, status, whole job's CPU s, renderer's CPU s, Blender passes that a
    worker saved)] in plan order. A job the worker pool rendered is its call and its record's
    cpu_s (the worker's CPU for it, harness/renderers/cycles/worker.py)."""
    jobs = []
    whole = run_cpu(calls)
    pool = pooled(run)
    for path in plan_order(run):
        try:
            with open(path, encoding='utf-8') as f:
                rec = json.load(f)
        except (OSError, ValueError):
            jobs.append((path, '?', 'missing', 0.0, 0.0, 0))
            continue
        key = (rec['scene_path'], rec['renderer'], rec['role'])
        if key not in whole:
            raise ValueError(f'{path}: no `reflcheck run` call for it in calls.tsv')
        cpu = float(rec['cpu_s'])
        in_worker = pool and rec['renderer'] == 'cycles' and rec['status'] == 'ok'
        saved = blender_passes(rec) if in_worker else 0
        jobs.append((path, rec['renderer'], rec['status'], whole[key] + (cpu if in_worker else 0.0), cpu, saved))
    return jobs


def failed_comparisons(run):
    """'scene id metric value > fail' for each comparison of the run whose status is fail or
    error (RUN/<scene>/compare.json)."""
    out = []
    for path in sorted(glob.glob(os.path.join(glob.escape(run), '*', 'compare.json'))):
        try:
            with open(path, encoding='utf-8') as f:
                doc = json.load(f)
        except (OSError, ValueError):
            continue
        scene = os.path.basename(os.path.dirname(path))
        for c in doc.get('comparisons', []):
            if c.get('status') not in ('fail', 'error'):
                continue
            gates = [t for t in c.get('thresholds', []) if t.get('verdict') == 'fail']
            said = ', '.join(f'{t["metric"]} {t["value"]:.3g} > {t["fail"]:.3g}' for t in gates) or c['status']
            out.append(f'`{scene}` {c.get("id", "?")} {said}')
    return out


def estimate(durations, cpus):
    """Makespan of a list schedule: each job, in order, to the CPU that frees first (what
    Slurm's FIFO scheduler does with one-CPU array tasks on idle nodes)."""
    free = [0.0] * cpus
    heapq.heapify(free)
    end = 0.0
    for d in durations:
        t = heapq.heappop(free) + d
        end = max(end, t)
        heapq.heappush(free, t)
    return end


def fmt(x, digits=1):
    return f'{x:,.{digits}f}'


def complete(run):
    """A run that got to its report (not stopped on the way: exit 130 or 143)."""
    return run[2]['exit'] not in ('130', '143') and 'report' in run[3]


def head_time(runs):
    """(fit CPU times in the nightly's order, serial CPU s, how they were found) for the largest
    run: what runs on the submitting machine besides compare. The fits run JOBS at a time there;
    the rest (plan, stability, the report, make and the shell) one after another. For a run stopped
    on the way they come from the largest complete run: its CPU per fit call (two calls a scene),
    its stability (once) and the rest per scene."""
    n, _, cost, _, jobs = runs[-1]
    if complete(runs[-1]):
        total = float(cost['user_s']) + float(cost['sys_s'])
        compare = sum(c[0] for c in cost['calls'].get('compare', []))
        fits = [c[0] for c in cost['calls'].get('fit', [])]
        return (
            fits,
            total - sum(j[3] for j in jobs) - compare - sum(fits),
            f'{len(fits)} fits measured, {fmt(sum(fits))} CPU-s; plan, stability, the report, make and the '
            'shell measured',
        )
    done = [r for r in runs if complete(r)][-1]
    d_total = float(done[2]['user_s']) + float(done[2]['sys_s'])
    d_parts = {k: sum(c[0] for c in v) for k, v in done[2]['calls'].items()}
    d_rest = d_total - sum(d_parts.values())
    per_fit = d_parts.get('fit', 0.0) / max(1, len(done[2]['calls'].get('fit', [])))
    stability = d_parts.get('stability', 0.0)
    return (
        [per_fit] * (2 * n),
        stability + d_rest / done[0] * n,
        f'the {n}-scene run was stopped in its fits, so from the {done[0]}-scene run: {2 * n} fits at '
        f'{fmt(per_fit, 2)} CPU-s each, stability {fmt(stability)}, and the report, make and the shell at '
        f'{fmt(d_rest / done[0], 2)} per scene',
    )


def exit_text(cost, n):
    """The nightly's exit status; a run stopped on the way says where."""
    if cost['exit'] not in ('130', '143'):
        return cost['exit']
    fits = len(cost['calls'].get('fit', []))
    return f'{cost["exit"]}: stopped in the fits ({fits} of {2 * n} done)'


def main(argv):
    args = argv[1:]
    cpus, copy_of = 2, None
    if '--cpus' in args:
        i = args.index('--cpus')
        cpus = int(args[i + 1])
        del args[i : i + 2]
    if '--copy-of' in args:
        i = args.index('--copy-of')
        copy_of = args[i + 1]
        del args[i : i + 2]
    if not args:
        print(__doc__, file=sys.stderr)
        return 2
    runs = []
    for run in args:
        try:
            cost = read_cost(run)
            calls = read_calls(run)
            cost['calls'] = calls
            commit = read_summary(run).get('commit', '?')
            # The nightly names a tree outside git (a copied checkout) "nogit".
            # A copy inside a checkout names that checkout's HEAD, which may have moved on.
            if copy_of:
                commit = f'{copy_of} (a copy)'
            cost['commit'] = 'a copy outside git' if commit == 'nogit' else commit
            runs.append((int(cost['scenes']), run, cost, read_stages(run), read_jobs(run, calls)))
        except (OSError, KeyError, ValueError) as e:
            print(f'cost_table.py: {run}: {e}; give run folders of ops/cost_growth.sh', file=sys.stderr)
            return 1
    runs.sort()
    summary = read_summary(runs[0][1])
    renderers = sorted({j[1] for r in runs for j in r[4]})
    p = print
    first = runs[0][2]
    p("# How the nightly's cost grows")
    p()
    p('<!-- Generated by tools/cost_table.py from the runs of ops/cost_growth.sh; do not edit by hand. -->')
    p()
    p(
        'The nightly (local make, test-size renders, no sweep, '
        'no screenshot, a fresh cache each) on the first 1, 10 and 24 canonical scenes (sorted by name) and '
        'on 100 variants of them (`ops/cost_scenes.py`: the canonical scenes in turn, renamed, field of view '
        f'widened 0.1 % per round), {summary.get("time", "?")[:10]}, '
        f'{first["cpus"]} CPUs shared with other work. The load average is beside each run: wall times are '
        'inflated by it, CPU times (user + sys) much less, so CPU time is the measure. Regenerate: '
        '`bash ops/cost_growth.sh build build/cost && /usr/bin/python3 tools/cost_table.py '
        'build/cost/runs/scenes-* > docs/cost.md`.'
    )
    p()
    p('## The nightly against the number of scenes (CPU seconds but where named wall)')
    p()
    p(
        '| scenes | render jobs | nightly wall | nightly CPU | render jobs | compare | fits | stability '
        '| the rest | CPU per scene | load before, after | jobs at a time | commit | exit |'
    )
    p('| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- | ---: | --- | ---: |')
    for n, run, cost, stages, jobs in runs:
        cpu = float(cost['user_s']) + float(cost['sys_s'])
        part = {k: sum(c[0] for c in v) for k, v in cost['calls'].items()}
        jcpu = sum(j[3] for j in jobs)
        # The pooled Cycles renders are in jcpu, not in the `run` calls: the rest is what neither holds.
        rest = cpu - jcpu - sum(v for k, v in part.items() if k != 'run')
        p(
            f'| {n} | {len(jobs)} | {fmt(float(cost["wall_s"]))} | {fmt(cpu)} | {fmt(jcpu)} '
            f'| {fmt(part.get("compare", 0))} | {fmt(part.get("fit", 0))} | {fmt(part.get("stability", 0))} '
            f'| {fmt(rest)} | {fmt(cpu / n, 2)} '
            f'| {cost["load_before"].split()[0]}, {cost["load_after"].split()[0]} | {cost["jobs_at_a_time"]} '
            f'| {cost.get("commit", "?")} | {exit_text(cost, n)} |'
        )
    p()
    p(
        'The nightly\'s CPU time is the nightly and every process it waited for. Render jobs: their '
        '`reflcheck run` calls, the renderer each started included, and a pooled Cycles job\'s worker CPU; compare, fits (seed and wide bounds, one '
        'call per scene each) and stability: their calls; the rest: the plan, the Blender workers\' start-up, '
        'the report (Python), progress, make, the shell and the Figure 1 plots. Exit 1 is a comparison that failed or a job not ok (listed below): '
        'its time is counted as measured.'
    )
    p()
    p('## By renderer: jobs; CPU seconds of the whole jobs; of the renderer alone (records\' `cpu_s`)')
    p()
    p('| renderer | ' + ' | '.join(f'{r[0]} scenes' for r in runs) + ' | CPU s per job, whole (renderer) |')
    p('| --- | ' + ' | '.join('---:' for _ in runs) + ' | ---: |')
    for name in renderers:
        cells = []
        for _, _, _, _, jobs in runs:
            mine = [j for j in jobs if j[1] == name]
            cells.append(
                f'{len(mine)}; {fmt(sum(j[3] for j in mine))}; {fmt(sum(j[4] for j in mine))}' if mine else '-'
            )
        mine = [j for j in runs[-1][4] if j[1] == name]
        per = (
            f'{fmt(sum(j[3] for j in mine) / len(mine), 2)} ({fmt(sum(j[4] for j in mine) / len(mine), 2)})'
            if mine
            else '-'
        )
        p(f'| {name} | ' + ' | '.join(cells) + f' | {per} |')
    p()
    p(
        f'The last column is the {runs[-1][0]}-scene run\'s. A job\'s time beyond its renderer\'s is '
        '`reflcheck run`\'s own: the scene, the cache key (which reads the renderer\'s version), the '
        'image and the record. A Cycles job rendered in the nightly\'s Blender worker pool is its call plus '
        'its record\'s `cpu_s` (the worker\'s CPU for it): the call itself holds none of the render. The '
        'renderers that run inside `reflcheck run` (raster, exact, exact_point) record the render\'s wall '
        'time as `cpu_s`, which the load inflates past the whole job\'s CPU time.'
    )
    p()
    p('## Stages: wall seconds (inflated by the load); CPU seconds (stages.tsv)')
    p()
    names = [s for s in ('renders', 'sweep', 'fits', 'stability', 'report') if any(s in r[3] for r in runs)]
    p('| scenes | ' + ' | '.join(names) + ' |')
    p('| ---: | ' + ' | '.join('---:' for _ in names) + ' |')

    def stage_cell(stage):
        wall, cpu = stage
        return fmt(wall, 0) + ('' if cpu is None else f'; {fmt(cpu)}')

    for n, _, _, stages, _ in runs:
        p(f'| {n} | ' + ' | '.join(stage_cell(stages[s]) if s in stages else '-' for s in names) + ' |')
    p()
    p(
        'A stage\'s CPU seconds are those of the processes the nightly waited for in it (`times`); the '
        'renders\' hold the plan and the render jobs, the Blender workers included; the fits\' hold '
        'compare, which runs just before them. The fits run JOBS at a time (`progress.py each --jobs`), so '
        'their wall time can be below their CPU time.'
    )
    p()
    n, run, cost, stages, jobs = runs[-1]
    start = cost.get('blender_start_cpu_s', '-')
    start = float(start) if start not in ('', '-') else None
    # Under Slurm no worker pool runs: each Cycles pass a worker rendered starts Blender there.
    durations = [j[3] + (j[5] * start if start else 0.0) for j in jobs]
    passes = sum(j[5] for j in jobs)
    compare = sum(c[0] for c in cost['calls'].get('compare', []))
    fits, head, how = head_time(runs)
    host = int(cost['jobs_at_a_time'])
    fits_span = estimate(fits, host)
    p(f'## {n} scenes on a Slurm cluster of N nodes (estimate from the measured jobs)')
    p()
    p(
        'Model: under `SCHEDULER=slurm` every render job is a one-CPU array task, and Slurm starts pending '
        'tasks in submission order (the plan\'s) on whichever CPU frees first; so the renders take the '
        f'makespan of a list schedule of the {len(durations)} measured job CPU times (whole jobs as in the '
        f'table above, in plan order) on N x {cpus} CPUs. '
        + (
            f'The nightly rendered its Cycles jobs in a worker pool, which Slurm\'s tasks do not have, so each '
            f'of their {passes} Blender passes gets Blender\'s start-up, {fmt(start, 2)} CPU-s measured '
            f'(`blender_start_cpu_s`), added (the rest below still holds the local workers\' own start-up, '
            'a second or two too much). '
            if passes and start
            else (
                f'The nightly rendered its Cycles jobs in a worker pool; Blender\'s start-up, which each of '
                f'their {passes} passes would pay as a Slurm task, was not measured and is left out. '
                if passes
                else ''
            )
        )
        + f'Compare waits for every render (afterany) and runs as one '
        f'one-CPU job: {fmt(compare)} CPU-s measured. Then the submitting machine ({how}): the fits '
        f'{host} at a time as the nightly runs them (JOBS={host}), a list schedule of their CPU times in '
        f'the nightly\'s order on {host} CPUs ({fmt(fits_span)} s), and the rest one after another '
        f'({fmt(head)} CPU-s). So: total = renders\' makespan on N x {cpus} CPUs + compare + fits\' '
        f'makespan on {host} + the rest. CPU seconds stand for seconds: on an idle node a job takes about '
        'its CPU time (the render jobs are one thread each). Left out: Slurm\'s launch cost per task '
        '(about 0.4 s more than a fork, docs/slurm.md), a shared filesystem\'s latency, and the sweep '
        '(skipped in these runs; under Slurm one job on one node).'
    )
    p()
    p(
        '| nodes | CPUs | renders (makespan) s | + compare s | + fits s | + the rest (serial) s | total s '
        '| renders\' speed-up over 1 node |'
    )
    p('| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |')
    base = estimate(durations, cpus)
    for nodes in NODES:
        m = estimate(durations, nodes * cpus)
        p(
            f'| {nodes} | {nodes * cpus} | {fmt(m)} | {fmt(compare)} | {fmt(fits_span)} | {fmt(head)} '
            f'| {fmt(m + compare + fits_span + head)} '
            f'| {fmt(base / m, 2)}x |'
        )
    at = max(range(len(jobs)), key=lambda i: durations[i])
    longest = (jobs[at][0], durations[at])
    p()
    p(
        f'No schedule ends the renders before the longest job ({fmt(longest[1], 2)} CPU-s, '
        f'`{os.path.relpath(longest[0], run)}`) nor before their CPU total shared by the CPUs '
        f'({fmt(sum(durations))} CPU-s); past about {max(1, round(sum(durations) / max(longest[1], 1e-9) / cpus))} '
        'nodes the longest job, compare, the fits and the rest set the time.'
    )
    failed = [(r[0], f) for r in runs for f in failed_comparisons(r[1])]
    if failed:
        p()
        p(
            'Comparisons that failed (so the exit 1; their time is counted as measured): '
            + '; '.join(f'{n} scenes: {f}' for n, f in failed)
            + '.'
        )
    bad = [(r[0], os.path.relpath(j[0], r[1]), j[2]) for r in runs for j in r[4] if j[2] != 'ok']
    if bad:
        p()
        p('Jobs not ok: ' + '; '.join(f'{n} scenes: `{path}` {st}' for n, path, st in bad) + '.')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv))
