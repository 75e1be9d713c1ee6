"""test_cost_table.py - tools/cost_table.py on a small run folder made here, against figures
worked out by hand: a job's CPU (a pooled Cycles job is its call plus its worker's CPU), the
list schedule of the render jobs on N nodes (each pooled Cycles pass with Blender's start-up
added, as a Slurm task pays it), the fits' schedule JOBS at a time, and the serial rest.
Run: /usr/bin/python3 -m pytest -q -p no:cacheprovider tests/test_cost_table.py
"""

import io
import json
import os
import sys
from contextlib import redirect_stdout

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, 'tools'))
import cost_table  # noqa: E402

# (renderer, role, the `reflcheck run` call's CPU s, the record's cpu_s, extra record fields),
# in plan order. The Cycles job ran a pilot of 16 samples and then 64: two Blender passes.
JOBS = [
    ('raster', 'validate', 0.5, 0.4, {}),
    ('cycles', 'validate', 0.2, 1.0, {'samples': 64, 'noise': {'pilot_samples': 16}}),
    ('povray', 'twin', 2.0, 1.5, {}),
    ('povray', 'validate', 2.0, 1.5, {}),
]
FITS = [1.0, 2.0, 3.0, 4.0]  # CPU s, in the nightly's order


def make_run(tmp_path, pooled, jobs=JOBS):
    run = tmp_path / ('pooled' if pooled else 'plain') / 'scenes-2'
    (run / 's').mkdir(parents=True)
    calls, plan = ['0.1\t0.1\t0.0\treflcheck plan s.yaml'], []
    for renderer, role, call, cpu, extra in jobs:
        rec = run / 's' / f'{renderer}-{role}.json'
        rec.write_text(
            json.dumps(
                {
                    'scene_path': 's.yaml',
                    'renderer': renderer,
                    'role': role,
                    'status': 'ok',
                    'cpu_s': cpu,
                    'samples': 0,
                    **extra,
                }
            )
        )
        plan.append(f'all: {rec}')
        calls.append(f'{call}\t{call}\t0.0\treflcheck run --renderer {renderer} --role {role} --small -- s.yaml')
    calls.append('0.3\t0.3\t0.0\treflcheck compare s.yaml')
    calls += [f'{c}\t{c}\t0.0\treflcheck fit s.yaml --bounds seed' for c in FITS]
    calls.append('1.0\t1.0\t0.0\treflcheck stability --json x')
    (run / 'calls.tsv').write_text('\n'.join(calls) + '\n')
    (run / 'jobs.mk').write_text('\n'.join(plan) + '\n')
    (run / 'stages.tsv').write_text('renders\t9\t6.0\nfits\t7\t10.5\nstability\t2\t1.0\nreport\t1\t0.5\n')
    (run / 'summary.json').write_text(json.dumps({'commit': 'abc1234', 'time': '2026-11-26T00:00:00Z'}))
    (run / 'cost.txt').write_text(
        'scenes 2\njobs_at_a_time 2\nexit 0\nwall_s 30\nuser_s 20\nsys_s 2\n'
        'load_before 1 1 1\nload_after 1 1 1\ncpus 2\nblender_start_cpu_s 0.5\n'
    )
    if pooled:
        (run / 'worker-0.log').write_text('Blender 3.4.1\n')
    return run


def table(run):
    out = io.StringIO()
    with redirect_stdout(out):
        assert cost_table.main(['cost_table.py', str(run)]) == 0
    return out.getvalue().splitlines()


def row(lines, first):
    return [x for x in lines if x.startswith(first)][-1]


def test_pooled_cycles_job_counts_its_worker_and_pays_blender_start_under_slurm(tmp_path):
    lines = table(make_run(tmp_path, pooled=True))
    # Cycles: call 0.2 + worker 1.0 = 1.2 CPU-s; the renderer's alone 1.0.
    assert row(lines, '| cycles |') == '| cycles | 1; 1.2; 1.0 | 1.20 (1.00) |'
    # The nightly: 22 CPU-s; jobs 0.5 + 1.2 + 2 + 2 = 5.7; compare 0.3, fits 10, stability 1; the
    # rest 22 - 5.7 - plan 0.1 - 0.3 - 10 - 1 = 4.9 (the worker's 1.0 counted once, in the jobs).
    assert (
        row(lines, '| 2 | 4 | 30.0')
        == '| 2 | 4 | 30.0 | 22.0 | 5.7 | 0.3 | 10.0 | 1.0 | 4.9 | 11.00 | 1, 1 | 2 | abc1234 | 0 |'
    )
    # Slurm durations: 0.5, 1.2 + 2 passes x 0.5 = 2.2, 2.0, 2.0. On 2 CPUs: 0.5 | 2.2; the first
    # povray to the CPU free at 0.5 (2.5), the second to the one free at 2.2 (4.2). On 4: 2.2.
    # Fits 1, 2, 3, 4 two at a time: 1 | 2, 3 after 1 (4), 4 after 2 (6): 6.0.
    # The rest: 22 CPU-s - jobs 5.7 - compare 0.3 - fits 10 = 6.0.
    assert row(lines, '| 1 | 2 |') == '| 1 | 2 | 4.2 | 0.3 | 6.0 | 6.0 | 16.5 | 1.00x |'
    assert row(lines, '| 2 | 4 |') == '| 2 | 4 | 2.2 | 0.3 | 6.0 | 6.0 | 14.5 | 1.91x |'
    assert any('each of their 2 Blender passes' in x for x in lines)


def test_a_job_that_stepped_twice_pays_blender_start_three_times(tmp_path):
    # The record says 3 passes (a pilot of 16, then 64, then 256): the samples alone (256 > 16)
    # would say 2. Slurm durations: 0.5, 1.2 + 3 x 0.5 = 2.7, 2.0, 2.0. On 2 CPUs: 0.5 | 2.7;
    # the first povray at 0.5 (2.5), the second at 2.5 (4.5). On 4: 2.7 (4.5 / 2.7 = 1.67x).
    stepped = {'samples': 256, 'noise': {'pilot_samples': 16, 'passes': 3}}
    jobs = [j if j[0] != 'cycles' else j[:4] + (stepped,) for j in JOBS]
    lines = table(make_run(tmp_path, pooled=True, jobs=jobs))
    assert row(lines, '| 1 | 2 |') == '| 1 | 2 | 4.5 | 0.3 | 6.0 | 6.0 | 16.8 | 1.00x |'
    assert row(lines, '| 2 | 4 |') == '| 2 | 4 | 2.7 | 0.3 | 6.0 | 6.0 | 15.0 | 1.67x |'
    assert any('each of their 3 Blender passes' in x for x in lines)


def test_without_a_pool_the_call_holds_the_render(tmp_path):
    lines = table(make_run(tmp_path, pooled=False))
    # Cycles is its call alone (0.2), no start-up added: 0.5 | 0.2, 2.0 after 0.2 (2.2), 2.0 after
    # 0.5 (2.5). The rest: 22 - 4.7 - 0.3 - 10 = 7.0.
    assert row(lines, '| cycles |') == '| cycles | 1; 0.2; 1.0 | 0.20 (1.00) |'
    assert row(lines, '| 1 | 2 |') == '| 1 | 2 | 2.5 | 0.3 | 6.0 | 7.0 | 15.8 | 1.00x |'


def test_stages_show_wall_and_cpu_and_the_copy_is_named(tmp_path):
    run = make_run(tmp_path, pooled=True)
    assert row(table(run), '| 2 | 9;') == '| 2 | 9; 6.0 | 7; 10.5 | 2; 1.0 | 1; 0.5 |'
    out = io.StringIO()
    with redirect_stdout(out):
        assert cost_table.main(['cost_table.py', '--copy-of', 'def5678', str(run)]) == 0
    assert '| def5678 (a copy) | 0 |' in out.getvalue()
