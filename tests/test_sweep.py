"""test_sweep.py - tools/sweep.py's maths on synthetic data, and report.py showing its output.

Run: /usr/bin/python3 -m pytest -q -p no:cacheprovider tests/test_sweep.py   (no renderer needed;
the plot check needs gnuplot). Expected values are worked by hand in the comments, or checked
by a seeded Monte Carlo simulation (the nested-reference correction).
"""

import importlib.util
import json
import math
import os
import random
import shutil
import subprocess
import sys
import threading
import xml.etree.ElementTree as ET

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.dont_write_bytecode = True  # no __pycache__ in the source tree
spec = importlib.util.spec_from_file_location('reflcheck_sweep', os.path.join(ROOT, 'tools', 'sweep.py'))
sweep = importlib.util.module_from_spec(spec)
spec.loader.exec_module(sweep)
sweep_schedule = importlib.import_module('sweep.schedule')
REPORT = os.path.join(ROOT, 'tools', 'report.py')
L2 = math.log(2.0)


# The scene around a fixture's comparisons: the sweep asks `reflcheck check --json` (the C parser),
# which reads only whole scenes, so each fixture is this floor under a light plus its comparisons.
SCENE_BODY = (
    'image: {width: 8, height: 6}\ncamera: {eye: [0, 1, 3], target: [0, 0, 0], hfov: 40}\n'
    'lights:\n  - {type: point, position: [0, 1, 0], intensity: [1, 1, 1]}\n'
    'materials:\n  floor: {albedo: [0.5, 0.5, 0.5], model: d3d}\n'
    'objects:\n  - {shape: quad, center: [0, 0, 0], size: [4, 4], material: floor}\n'
)


def scene_text(text):
    """text (a name line and comparisons) with SCENE_BODY before its comparisons."""
    return text.replace('\ncomparisons:', '\n' + SCENE_BODY + 'comparisons:', 1)


# ------------------------------------------------------------------------------------ fits


def test_fit_exact_power_law():
    # y = 8 x^-0.5 through (1, 8), (4, 4), (16, 2): slope -0.5, intercept ln 8, r2 1
    f = sweep.fit_loglog([1, 4, 16], [8, 4, 2])
    assert f['slope'] == pytest.approx(-0.5, abs=1e-12)
    assert f['intercept'] == pytest.approx(math.log(8), abs=1e-12)
    assert f['r2'] == pytest.approx(1.0, abs=1e-12) and f['n'] == 3


def test_fit_least_squares_by_hand():
    # ln x = 0, L, 2L (L = ln 2); ln y = 0, -1, -1. dx = (-L, 0, L), dy = (2/3, -1/3, -1/3):
    # sum dx dy = -L, sum dx^2 = 2L^2 -> slope -1/(2L); intercept -2/3 - slope L = -1/6;
    # r2 = L^2 / (2L^2 * 2/3) = 3/4
    f = sweep.fit_loglog([1, 2, 4], [1, math.exp(-1), math.exp(-1)])
    assert f['slope'] == pytest.approx(-1 / (2 * L2), rel=1e-12)
    assert f['intercept'] == pytest.approx(-1 / 6, abs=1e-12)
    assert f['r2'] == pytest.approx(0.75, rel=1e-12)


def test_fit_ignores_non_positive_and_needs_two_x():
    f = sweep.fit_loglog([1, 4, 16, 5, None], [8, 4, 2, 0, 3])  # (5, 0) and (None, 3) dropped
    assert f['n'] == 3 and f['slope'] == pytest.approx(-0.5)
    assert sweep.fit_loglog([2, 2], [1, 3]) is None
    assert sweep.fit_loglog([2], [1]) is None


def test_fit_solve_and_eval():
    f = {'slope': -0.5, 'intercept': math.log(8)}
    assert sweep.fit_solve(f, 1.0) == pytest.approx(64.0)  # 8 / sqrt(64) = 1
    assert sweep.fit_eval(f, 16) == pytest.approx(2.0)
    assert sweep.fit_solve({'slope': 0.1, 'intercept': 0.0}, 0.5) is None  # rising: never
    assert sweep.fit_solve({'slope': 0.0, 'intercept': 0.0}, 0.5) is None  # flat: never
    assert sweep.fit_solve(None, 0.5) is None


def test_local_slopes_show_the_bend():
    # 8 -> 4 over x 1 -> 4: -0.5; 4 -> 1 over 4 -> 16: -1 (unsorted input)
    ls = sweep.local_slopes([16, 1, 4], [1, 8, 4])
    assert [(l['from'], l['to']) for l in ls] == [(1, 4), (4, 16)]
    assert ls[0]['slope'] == pytest.approx(-0.5) and ls[1]['slope'] == pytest.approx(-1.0)


def test_fit_linear_by_hand():
    # x = 16, 64, 256; y = 2, 3, 6: mx 112, my 11/3, dx (-96, -48, 144), dy (-5/3, -2/3, 7/3);
    # sum dx dy = 160 + 32 + 336 = 528, sum dx^2 = 32256 -> b = 11/672, a = 11/3 - 112 b = 11/6
    a, b = sweep.fit_linear([16, 64, 256], [2, 3, 6])
    assert b == pytest.approx(11 / 672, rel=1e-12) and a == pytest.approx(11 / 6, rel=1e-12)
    assert sweep.fit_linear([3, 3], [1, 2]) is None


# ------------------------------------------------------------------------------------ frontier

PTS = [
    {'label': 'A', 'time_s': 1.0, 'error': 0.5},
    {'label': 'B', 'time_s': 2.0, 'error': 0.6},  # slower and worse than A
    {'label': 'C', 'time_s': 2.0, 'error': 0.3},
    {'label': 'D', 'time_s': 0.5, 'error': 0.9},
    {'label': 'E', 'time_s': 3.0, 'error': 0.3},  # same error as C, slower
    {'label': 'F', 'time_s': 10.0, 'error': 0.01},
    {'label': 'G', 'time_s': 0.7, 'error': None},
]  # no error: never on the frontier


def test_pareto_frontier():
    assert [p['label'] for p in sweep.pareto(PTS)] == ['D', 'A', 'C', 'F']


def test_best_within_budget():
    assert sweep.best_within(PTS, 2.0)['label'] == 'C'
    assert sweep.best_within(PTS, 2.5)['label'] == 'C'
    assert sweep.best_within(PTS, 0.9)['label'] == 'D'
    assert sweep.best_within(PTS, 0.4) is None
    assert sweep.best_within(PTS, 100)['label'] == 'F'


# ------------------------------------------------------------------------------------ noise


def test_nested_and_independent_error_by_hand():
    assert sweep.nested_error(0.03, 1024, 4096) == pytest.approx(0.03 / math.sqrt(0.75))
    assert sweep.nested_error(0.03, 4096, 4096) is None
    assert sweep.independent_error(0.05, 0.03) == pytest.approx(0.04)  # 3-4-5
    assert sweep.independent_error(0.02, 0.03) is None  # all reference noise
    assert sweep.independent_error(0.02, None) == 0.02


def test_nested_correction_matches_simulation():
    """The mean of the first n of N iid samples against the mean of all N: MSE = s^2/n (1 - n/N).
    Seeded simulation, n = 4 of N = 16, s = 1: expected 0.25 * 0.75 = 0.1875; with 20000 trials
    the estimate's relative standard error is sqrt(2/20000) = 1%, so 5% is a safe bound."""
    rng = random.Random(12345)
    n, big, trials = 4, 16, 20000
    acc = 0.0
    for _ in range(trials):
        xs = [rng.gauss(0.0, 1.0) for _ in range(big)]
        acc += (sum(xs[:n]) / n - sum(xs) / big) ** 2
    measured_rms = math.sqrt(acc / trials)
    truth_rms = 1.0 / math.sqrt(n)
    assert sweep.nested_error(measured_rms, n, big) == pytest.approx(truth_rms, rel=0.05)


# ------------------------------------------------------------------------------------ crossover

LEVELS = [(16, 2.16), (64, 2.64), (256, 4.56), (1024, 12.24)]  # 2 + 0.01 spp
RENDER = [(16, 0.26), (64, 0.74), (256, 2.66), (1024, 10.34)]  # 0.1 + 0.01 spp


def test_interp_time():
    assert sweep.interp_time(LEVELS, 256) == pytest.approx(4.56)  # a level
    assert sweep.interp_time(LEVELS, 160) == pytest.approx(2.64 + (4.56 - 2.64) * 96 / 192)  # 3.6
    assert sweep.interp_time(LEVELS, 8) == pytest.approx(2.16)  # below: the first level
    assert sweep.interp_time(LEVELS, 2048) == pytest.approx(12.24 + 7.68 * 1024 / 768)  # 22.48
    assert sweep.interp_time([], 5) is None


def test_crossover_interpolated():
    # error 0.8 / sqrt(spp); raster 0.05 -> spp (0.8/0.05)^2 = 256 -> 4.56 s (2.66 in Blender);
    # raster 0.08 -> 100 spp -> 2.64 + 1.92 * 36/192 = 3.0 s; the ln-time fit 0.1/t -> 2 s
    fs = {'slope': -0.5, 'intercept': math.log(0.8)}
    ft = {'slope': -1.0, 'intercept': math.log(0.1)}
    c = sweep.crossover(fs, LEVELS, RENDER, ft, 0.05)
    assert c['spp'] == pytest.approx(256.0)
    assert c['time_s'] == pytest.approx(4.56) and c['render_s'] == pytest.approx(2.66)
    assert c['loglog_time_s'] == pytest.approx(2.0)
    assert c['extrapolated'] is None
    assert sweep.crossover(fs, LEVELS, RENDER, ft, 0.08)['time_s'] == pytest.approx(3.0)


def test_crossover_out_of_range_and_none():
    fs = {'slope': -0.5, 'intercept': math.log(0.8)}
    below = sweep.crossover(fs, LEVELS, [], None, 0.5)  # spp 2.56 < 16
    assert below['spp'] == pytest.approx(2.56) and below['extrapolated'] == 'below'
    assert below['upper_bound_s'] == pytest.approx(2.16)  # the 16-spp level
    assert below['render_s'] is None and below['loglog_time_s'] is None
    above = sweep.crossover(fs, LEVELS, [], None, 0.001)  # spp 640000
    assert above['spp'] == pytest.approx(640000.0) and above['extrapolated'] == 'above'
    assert above['time_s'] == pytest.approx(12.24 + 0.01 * (640000 - 1024))
    assert sweep.crossover({'slope': 0.2, 'intercept': 0.0}, LEVELS, [], None, 0.05) is None


def test_slope_note():
    on = {'slope': -0.52}
    assert 'Monte Carlo rate' in sweep.slope_note(on, [{'from': 16, 'to': 64, 'slope': -0.55}])
    steep = sweep.slope_note({'slope': -0.96}, [{'from': 16, 'to': 64, 'slope': -0.99}])
    assert 'faster' in steep and '16->64 spp: -0.99' in steep
    flat = sweep.slope_note(
        {'slope': -0.37}, [{'from': 64, 'to': 256, 'slope': -0.24}, {'from': 256, 'to': 1024, 'slope': -0.5}]
    )
    assert 'slower' in flat and '64->256' in flat and '256->1024' not in flat
    # on average -0.5 but bent: still says where
    assert 'off -0.5 at 16->64' in sweep.slope_note(on, [{'from': 16, 'to': 64, 'slope': -0.8}])


# ------------------------------------------------------------------------------------ scenes


def test_lists_cycles_validate(tmp_path):
    yes = tmp_path / 'yes.yaml'
    yes.write_text(
        scene_text(
            'name: yes\ncomparisons:\n  - reference: povray\n    role: twin\n'
            '  - reference: cycles\n    role: validate\n    thresholds:\n      nrmse: {warn: 1, fail: 2}\n'
        )
    )
    agree = tmp_path / 'agree.yaml'
    agree.write_text(
        scene_text(
            'name: agree\ncomparisons:\n  - reference: cycles\n    role: twin\n'
            '  - test: povray\n    reference: cycles\n    role: validate\n'
        )
    )
    mixed = tmp_path / 'mixed.yaml'  # cycles twin + povray validate: no cycles validate item
    mixed.write_text(
        scene_text(
            'name: mixed\ncomparisons:\n  - reference: cycles\n    role: twin\n'
            '  - reference: povray\n    role: validate\n'
        )
    )
    assert sweep.lists_cycles_validate(str(yes))
    assert not sweep.lists_cycles_validate(str(agree))
    assert not sweep.lists_cycles_validate(str(mixed))
    assert sweep.scene_name(str(yes)) == 'yes'
    # The sweep's role: the physical reference where there is one, else the Cycles twin.
    assert sweep.sweep_role(str(yes)) == 'validate'
    assert sweep.sweep_role(str(agree)) == 'twin'
    assert sweep.sweep_role(str(mixed)) == 'twin'
    # Quoted values and a flow-style item are YAML the C parser reads like any other.
    quoted = tmp_path / 'quoted.yaml'
    quoted.write_text(scene_text('name: "quoted"\ncomparisons:\n  - {reference: "cycles", role: \'validate\'}\n'))
    assert sweep.sweep_role(str(quoted)) == 'validate' and sweep.scene_name(str(quoted)) == 'quoted'
    none = tmp_path / 'none.yaml'
    none.write_text(scene_text('name: none\ncomparisons:\n  - reference: povray\n    role: twin\n'))
    assert sweep.sweep_role(str(none)) is None


def test_renderers_from_cli(tmp_path):
    """The sweep takes the renderers from `reflcheck renderers --json`, not from a list: the
    model renderer counts as a comparison's test whether or not the scene names it."""
    fake = tmp_path / 'reflcheck'
    fake.write_text(
        '#!/bin/sh\n[ "$1 $2" = "renderers --json" ] || exit 2\n'
        'echo \'[{"name": "ours", "model": true}, {"name": "cycles", "model": false}]\'\n'
    )
    fake.chmod(0o755)
    table = sweep.renderer_table(str(fake))
    assert list(table) == ['ours', 'cycles'] and table['ours']['model']
    named = tmp_path / 'named.yaml'
    # The C parser resolves the test: the model renderer named explicitly counts as the default.
    named.write_text(
        scene_text('name: named\ncomparisons:\n  - test: raster\n    reference: cycles\n    role: validate\n')
    )
    assert sweep.lists_cycles_validate(str(named))
    other = tmp_path / 'other.yaml'
    other.write_text(
        scene_text('name: other\ncomparisons:\n  - test: povray\n    reference: cycles\n    role: validate\n')
    )
    assert not sweep.lists_cycles_validate(str(other))


# ------------------------------------------------------------------------------------ analyse


def synthetic(nested=True):
    """A quick plan with made-up records: Cycles error 0.8/sqrt(spp) against the truth, wall
    2 + 0.01 spp; raster as-is NRMSE 0.1 with reference noise 0.06 -> error 0.08 (6-8-10)."""
    jobs, ref = sweep.plan(quick=True, seed_opt=not nested)
    recs, diffs, noises = {}, {}, {'reference': 0.06}
    for j in jobs:
        if j['renderer'] == 'cycles':
            n = j['samples']
            t = 2.0 + 0.01 * n
            nr = 0.0 if j['key'] == 'reference' else 0.8 / math.sqrt(n) * math.sqrt(1 - n / ref)
            recs[j['key']] = {'status': 'ok', 'wall_s': t, 'render_s': t - 1.9, 'samples': n, 'seeds': 2}
        elif j['renderer'] == 'raster':
            recs[j['key']] = {'status': 'ok', 'wall_s': 0.01, 'supersample': 2}
            nr = 0.1
        elif j['renderer'] == 'eevee':
            # Not stochastic: its record keeps samples 0, the knob comes from the job.
            recs[j['key']] = {'status': 'ok', 'wall_s': 12.0 + 0.1 * j['samples'], 'samples': 0}
            nr = {1: 0.3, 16: 0.13}[j['samples']]
        else:
            recs[j['key']] = {'status': 'skipped', 'message': 'povray cannot represent this'}
            continue
        diffs[j['key']] = {'surface': {'nrmse': nr, 'rmse': nr / 10, 'rel_rms': nr * 2}}
    recs['rk1']['wall_s'] = 0.005
    diffs['rk1']['surface']['nrmse'] = 0.2  # k = 1: faster, worse
    return sweep.analyse('synth', jobs, recs, diffs, noises, ref, True, [96, 72])


def test_analyse_end_to_end():
    t = synthetic()
    json.dumps(t, allow_nan=False)
    cyc = next(s for s in t['series'] if s['label'] == 'cycles spp')
    assert cyc['fit_spp']['slope'] == pytest.approx(-0.5, abs=1e-9)  # the correction undid 1 - n/N
    assert cyc['time_model']['t0_s'] == pytest.approx(2.0) and cyc['time_model']['s_per_spp'] == pytest.approx(0.01)
    ref_pt = next(p for p in cyc['points'] if p['is_reference'])
    assert ref_pt['error'] == 0.06 and cyc['fit_spp']['n'] == 3  # the reference is not fitted
    assert t['as_is']['error'] == pytest.approx(0.08)
    # crossover: (0.8 / 0.08)^2 = 100 spp -> 2 + 1 = 3 s, inside 16..256
    assert t['crossover']['spp'] == pytest.approx(100.0)
    assert t['crossover']['time_s'] == pytest.approx(3.0)
    assert t['crossover']['extrapolated'] is None
    # equal time at the raster's 0.01 s: only the raster; at 10 s: Cycles 256 spp, 0.8/16 = 0.05
    eq = {e['budget']: e for e in t['equal_time']}
    assert eq['raster as-is']['best']['cycles'] is None and eq['raster as-is']['best']['raster'][
        'error'
    ] == pytest.approx(0.08)
    assert eq['10 s']['best']['cycles']['label'] == '256 spp'
    assert eq['10 s']['best']['cycles']['error'] == pytest.approx(0.05)
    assert eq['10 s']['cycles_fit_error'] == pytest.approx(0.8 / math.sqrt(800))  # (10 - 2)/0.01 spp
    assert eq['1 s']['cycles_fit_error'] is None  # inside start-up
    assert [s['label'] for s in t['skipped']] == ['povray k k=1', 'povray k k=2']
    # EEVEE: its own series over TAA samples; a deterministic point takes the reference noise
    # out in quadrature: sqrt(0.13^2 - 0.06^2) = 0.1153; none fits a 10 s budget (12.1 s).
    ee = next(s for s in t['series'] if s['label'] == 'eevee taa')
    assert ee['knob'] == 'samples' and [p['samples'] for p in ee['points']] == [1, 16]
    assert ee['points'][1]['error'] == pytest.approx(math.sqrt(0.13**2 - 0.06**2))
    assert eq['10 s']['best']['eevee'] is None
    # frontier: raster k=1 (0.005 s, 0.2), a raster 0.01 s point (0.08); Cycles 16 and 64 spp
    # (0.2, 0.1) lose to it, 256 spp (0.05) wins, the reference (its noise 0.06) loses to 256
    front = [(p['renderer'], p['label']) for p in t['pareto']]
    assert front[0] == ('raster', 'k=1') and front[1][0] == 'raster'
    assert front[2:] == [('cycles', '256 spp')]


# ------------------------------------------------------------------------------------ report


def test_report_shows_sweep(tmp_path):
    run = tmp_path / '20250101-120000-abc1234'
    (run / 'timing').mkdir(parents=True)
    (run / 'timing' / 'synth.json').write_text(json.dumps(sweep.clean_nan(synthetic())))
    r = subprocess.run([sys.executable, REPORT, '--run', str(run)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    html = (run / 'index.html').read_text(encoding='utf-8')
    assert 'id="timing-synth"' in html
    assert '3 s at 100 spp' in html  # the crossover
    assert 'Pareto frontier' in html and 'none within budget' in html
    assert '-0.50' in html  # the spp slope in the overview
    if shutil.which('gnuplot'):
        svg = run / 'plots' / 'timing-synth.svg'
        ET.parse(str(svg))
        text = svg.read_text(encoding='utf-8')
        assert 'Pareto frontier' in text and 'spp^-0.50' in text and 'raster as-is error' in text
        assert 'plots/timing-synth.svg' in html


def test_eevee_swept_only_where_named(tmp_path):
    """EEVEE jobs go to the scenes whose comparisons name it, not to one that only mentions it."""
    named = tmp_path / 'named.yaml'
    named.write_text(
        scene_text(
            'name: a\ncomparisons:\n  - reference: cycles\n    role: validate\n  - test: eevee\n    reference: cycles\n'
        )
    )
    other = tmp_path / 'other.yaml'
    other.write_text(
        scene_text(
            '# eevee is not judged here; test: eevee in a comment\nname: b\ncomparisons:\n  - reference: cycles\n'
        )
    )
    assert sweep.names_renderer(str(named), 'eevee') and not sweep.names_renderer(str(other), 'eevee')
    assert [j['samples'] for j in sweep.plan(quick=False, seed_opt=False)[0] if j['renderer'] == 'eevee'] == [1, 16]


# ------------------------------------------------------------------------------ partial twin


class _Runner:
    """Records each diff's arguments; the model's image differs from the reference by the
    missing specular alone (0.0814 NRMSE), the shared terms by sampling (0.0079)."""

    def __init__(self):
        self.calls = []

    def diff(self, test, ref, mask, leave_out=(), keys=None):
        self.calls.append((test, tuple(leave_out)))
        return {'surface': {'nrmse': 0.0079 if 'specular' in leave_out else 0.0814}}

    def diff_many(self, items):
        return [self.diff(*it[:4], keys=it[4]) for it in items]


def test_partial_twin_compares_the_shared_terms():
    """A partial twin (Cycles leaves the Blinn-Phong specular out, its record says so) is swept
    on the terms both sides render, as its compare.json is: every diff leaves the specular out,
    and the timing JSON and the printed line name the role and the terms compared."""
    jobs = [
        {'key': 'reference', 'renderer': 'cycles'},
        {'key': 'as_is', 'renderer': 'raster'},
    ]
    recs = {
        # As a Cycles job record writes it.
        'reference': {
            'status': 'ok',
            'exr': 'ref.exr',
            'terms_left_out': [{'term': 'specular', 'reason': "materials[0] 'skin': Cycles has no Blinn-Phong lobe"}],
        },
        'as_is': {'status': 'ok', 'exr': 'asis.exr'},
    }
    runner = _Runner()
    diffs, _, left = sweep.scene_diffs(runner, jobs, recs, None)
    assert left == ['specular']
    assert runner.calls == [('ref.exr', ('specular',)), ('asis.exr', ('specular',))]
    assert diffs['as_is']['surface']['nrmse'] == 0.0079
    # A whole reference: nothing is left out.
    recs['reference'].pop('terms_left_out')
    runner = _Runner()
    diffs, _, left = sweep.scene_diffs(runner, jobs, recs, None)
    assert left == [] and all(c[1] == () for c in runner.calls)
    assert diffs['as_is']['surface']['nrmse'] == 0.0814


def test_partial_twin_says_so(tmp_path):
    jobs, ref = sweep.plan(quick=True, seed_opt=False)
    t = synthetic()
    recs = {j['key']: {'status': 'skipped', 'message': 'x'} for j in jobs}
    recs['as_is'] = {'status': 'ok', 'wall_s': 0.01}
    diffs = {'as_is': {'surface': {'nrmse': 0.0079}}}
    t = sweep.analyse('partial', jobs, recs, diffs, {}, ref, True, [96, 72], role='twin', left_out=['specular'])
    assert t['reference']['role'] == 'twin'
    assert t['reference']['terms_left_out'] == ['specular']
    assert t['reference']['terms_compared'] == ['diffuse', 'reflection', 'emission']
    assert 'specular left out' in t['error_doc']
    assert '(role twin on diffuse+reflection+emission (specular left out))' in sweep.one_line(t)
    whole = synthetic()
    assert whole['reference']['terms_left_out'] == [] and 'left out' not in sweep.one_line(whole)
    run = tmp_path / '20250101-120000-abc1234'
    (run / 'timing').mkdir(parents=True)
    t['series'] = whole['series']
    (run / 'timing' / 'partial.json').write_text(json.dumps(sweep.clean_nan(t)))
    r = subprocess.run([sys.executable, REPORT, '--run', str(run)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    html = (run / 'index.html').read_text(encoding='utf-8')
    assert 'cycles twin' in html and 'terms compared: diffuse + reflection + emission (specular left out' in html


# ------------------------------------------------------------------------------ staged levels


def test_stage_plans():
    """Stage one: 16 and 64 spp against 256 (seeds 0..1) as the reference; each later stage turns
    the reference into the top point (same tag, options: one cache key) and renders the next
    level as the reference, at seeds 4..5, then 6..7 with --seed (disjoint from the points' 2..3
    and from every earlier reference)."""
    integral = ['--supersample', '1']
    jobs, ref = sweep.plan(quick=False, seed_opt=True)
    steps = sweep.ladder(jobs, ref)
    assert steps == [16, 64, 256, 1024, 4096]
    one, top = sweep.stage_one(jobs, ref)
    cyc = {j['key']: j for j in one if j['renderer'] == 'cycles'}
    assert top == 256 and sorted(cyc) == ['cycles16', 'cycles64', 'reference']
    # The pixel integral (--supersample 1) like the points: a twin's default k x k positions
    # would differ from the points by a bias, an error floor.
    assert cyc['reference']['opts'] == ['--samples', '256', '--seeds', '2'] + integral
    assert all(j['opts'][4:6] == integral for j in cyc.values())
    assert [j for j in one if j['renderer'] != 'cycles'] == [j for j in jobs if j['renderer'] != 'cycles']
    two, top2 = sweep.stage_next(one, top, steps, True, 2)
    cyc2 = {j['key']: j for j in two if j['renderer'] == 'cycles'}
    assert top2 == 1024 and sorted(cyc2) == ['cycles16', 'cycles256', 'cycles64', 'reference']
    assert cyc2['cycles256']['tag'] == cyc['reference']['tag'] and cyc2['cycles256']['opts'] == cyc['reference']['opts']
    assert cyc2['reference']['opts'] == ['--samples', '1024', '--seeds', '2'] + integral + ['--seed', '4']
    three, top3 = sweep.stage_next(two, top2, steps, True, 3)
    cyc3 = {j['key']: j for j in three if j['renderer'] == 'cycles'}
    assert top3 == 4096 and cyc3['cycles1024']['tag'] == 'cycles-spp1024-s4'
    assert cyc3['reference']['tag'] == 'cycles-spp4096-s6'
    assert cyc3['reference']['opts'] == ['--samples', '4096', '--seeds', '2'] + integral + ['--seed', '6']
    # No level above 4096: unchanged.
    assert sweep.stage_next(three, top3, steps, True, 4) == (three, 4096)
    # The two-stage sweep (stage one at 1024, stage two at 4096 seeds 4..5) is still expressible.
    one_b, top_b = sweep.stage_one(jobs, ref, first=1024)
    two_b, ref_b = sweep.stage_two(one_b, top_b, ref, seed_opt=True)
    assert top_b == 1024 and ref_b == 4096
    assert next(j for j in two_b if j['key'] == 'reference')['tag'] == 'cycles-spp4096-s4'
    # Without --seed (nested): every reference is seeds 0..1.
    two_n, _ = sweep.stage_next(*sweep.stage_one(*sweep.plan(quick=False, seed_opt=False)), steps, False, 2)
    assert next(j for j in two_n if j['key'] == 'reference')['opts'] == ['--samples', '1024', '--seeds', '2'] + integral
    # --quick: 16, 64 against 256, then 1024.
    q, qref = sweep.plan(quick=True, seed_opt=True)
    assert sweep.ladder(q, qref) == [16, 64, 256, 1024] and sweep.stage_one(q, qref)[1] == 256


def _staged(noise_ref=0.01, raster=0.1, cycles_errors=(0.2, 0.1, 0.05), n_pixels=4000, as_is=None):
    """A stage-one analysis dict as stage_decision reads it: Cycles points at 16, 64, 256 spp
    measured against a reference of noise noise_ref (independent seeds: nrmse^2 = e^2 + r^2),
    over n_pixels surface pixels with no outliers (worst 1 % hold 1 %); a raster k point of error
    raster; the raster as-is error as_is (default raster), also on the Pareto frontier."""
    cyc = [
        {
            'samples': n,
            'error': e,
            'nrmse': math.hypot(e, noise_ref),
            'n_pixels': n_pixels,
            'worst1_share': 0.01,
            'is_reference': False,
            'time_s': 1.0 + n / 100,
        }
        for n, e in zip((16, 64, 256), cycles_errors)
    ]
    local = sweep.local_slopes([p['samples'] for p in cyc], [p['error'] for p in cyc])
    fit = sweep.fit_loglog([p['samples'] for p in cyc], [p['error'] for p in cyc])
    fit['local'] = local
    as_is = raster if as_is is None else as_is
    return {
        'reference': {'noise_nrmse': noise_ref, 'nested': False},
        'series': [
            {'label': 'cycles spp', 'renderer': 'cycles', 'fit_spp': fit, 'points': cyc},
            {
                'label': 'raster k',
                'renderer': 'raster',
                'points': [{'label': 'k=8', 'error': raster, 'is_reference': False}],
            },
        ],
        'as_is': {'error': as_is, 'n_pixels': n_pixels},
        'pareto': [{'label': 'as-is', 'renderer': 'raster', 'error': as_is, 'time_s': 0.01}],
        'crossover': {'spp': 64.0, 'extrapolated': None, 'raster_error': as_is},
        'crossover_best_raster': None,
    }


def test_deeper_reasons_rule():
    # Errors 0.2, 0.1, 0.05 at 16, 64, 256: slope ln(1/2)/ln 4 = -0.5 throughout; crossover
    # inside; reference noise 0.01 < 0.1 / 3: stage one decides everything.
    assert sweep.deeper_reasons(_staged()) == []
    # 64 -> 256: 0.1 -> 0.08, slope ln(0.8)/ln 4 = -0.161; over 4000 pixels a point's sigma is
    # about sqrt(2/4000)/2 = 0.011, the slope's 0.011 sqrt(2)/ln 4 = 0.012: a floor.
    assert any('slower than -0.5' in w for w in sweep.deeper_reasons(_staged(cycles_errors=(0.2, 0.1, 0.08))))
    # Faster than -0.5 (0.2 -> 0.05 -> 0.0125: -1.0) is stratification, decided in stage one.
    assert sweep.deeper_reasons(_staged(cycles_errors=(0.2, 0.05, 0.0125))) == []
    # Raster as-is 0.02, reference noise 0.05 over 4000 pixels: q = 2.5, sigma = 2.5 sqrt(7.25 /
    # 4000) = 0.106 > 0.1: deep. Noise 0.04: q = 2, 2 sqrt(5 / 4000) = 0.071: decided.
    assert any('reference noise 0.05' in w for w in sweep.deeper_reasons(_staged(noise_ref=0.05, raster=0.02)))
    assert sweep.deeper_reasons(_staged(noise_ref=0.04, raster=0.02)) == []


def test_point_sigma_by_hand():
    # Nested (no subtraction), 200 pixels, no outliers: sqrt((3 - 1) / 200) / 2 = 0.05.
    p = {'nrmse': 0.1, 'error': 0.1, 'n_pixels': 200, 'worst1_share': 0.01}
    assert sweep.point_sigma(p, None, True) == pytest.approx(0.05, rel=1e-12)
    # The worst 1 % hold half the sum: E[x^2]/E[x]^2 >= 100 * 0.25 = 25: sqrt(24 / 200) / 2.
    p2 = dict(p, worst1_share=0.5)
    assert sweep.point_sigma(p2, None, True) == pytest.approx(math.sqrt(24 / 200) / 2, rel=1e-12)
    # Independent: m = 0.05, r = 0.03, e = 0.04, n = 200: var(e^2) = (0.0025 * 0.1)^2 +
    # (0.0009 * 0.1)^2 = 6.25e-8 + 8.1e-9 = 7.06e-8; sigma = sqrt(7.06e-8) / (2 * 0.0016).
    p3 = {'nrmse': 0.05, 'error': 0.04, 'n_pixels': 200, 'worst1_share': 0.01}
    assert sweep.point_sigma(p3, 0.03, False) == pytest.approx(math.sqrt(7.06e-8) / 0.0032, rel=1e-9)


def test_stage_decision_slope_within_its_uncertainty():
    # 64 -> 256: 0.1 -> 0.06, slope ln(0.6)/ln 4 = -0.368, slower than -0.5 by 0.13 (the old rule
    # went deep on anything past 0.1). Over 100 pixels each point's sigma is about
    # sqrt(2/100)/2 = 0.071, the slope's 0.071 sqrt(2)/ln 4 = 0.072: -0.368 - 2 * 0.072 = -0.51,
    # so -0.5 is within 2 sigma: reported, not rendered. Over 4000 pixels (sigma 0.011) the same
    # slope is a departure: deep.
    small = sweep.stage_decision(_staged(cycles_errors=(0.2, 0.1, 0.06), n_pixels=100), 1024)
    assert small['deep'] == []
    assert any('-0.5 within 2 sigma' in w for w in small['not_deep'])
    big = sweep.stage_decision(_staged(cycles_errors=(0.2, 0.1, 0.06), n_pixels=4000), 1024)
    assert any('slower than -0.5' in w for w in big['deep'])


def test_stage_decision_crossover_within_reach():
    # Errors 0.16, 0.04, 0.01 at 16, 64, 256: slope -1 (sigma about 0.01). Raster as-is 0.004:
    # 256 * (0.004 / 0.01)^(1 / -1) = 640 spp, under the 1024-spp level stage two adds: deep.
    t = _staged(cycles_errors=(0.16, 0.04, 0.01), raster=0.1, as_is=0.004, noise_ref=0.0001)
    t['crossover'] = {'spp': 640.0, 'extrapolated': 'above', 'raster_error': 0.004}
    d = sweep.stage_decision(t, 1024)
    assert any('within the 1024-spp level a deeper stage' in w for w in d['deep'])
    # Raster as-is 0.001: 2560 spp, range about 256 * 10^(1 / 1.02) = 2440 and up, wholly above
    # 1024: no deeper level places it; reported with its range, not rendered.
    t = _staged(cycles_errors=(0.16, 0.04, 0.01), raster=0.1, as_is=0.001, noise_ref=0.0001)
    t['crossover'] = {'spp': 2560.0, 'extrapolated': 'above', 'raster_error': 0.001}
    d = sweep.stage_decision(t, 1024)
    assert d['deep'] == []
    assert any('not decidable within 1024 spp' in w for w in d['not_deep'])
    low, high = sweep.crossover_range(0.001, -1.0, 0.0, (256, 0.01))
    assert low == pytest.approx(2560.0) and high == pytest.approx(2560.0)
    # A flat top slope (within 2 sigma of 0) never reaches it: the range is open above.
    assert sweep.crossover_range(0.001, -0.05, 0.05, (256, 0.01))[1] == math.inf


def test_error_sigma_by_hand():
    # e = 0.01, r = 0.02, n = 500: q = 2, 2 sqrt(5 / 500) = 0.2.
    assert sweep.error_sigma(0.01, 0.02, 500) == pytest.approx(0.2, rel=1e-12)
    assert sweep.error_sigma(0.01, 0.0, 500) == 0.0


def test_error_sigma_matches_simulation():
    # A deterministic error d (+-e per pixel) against a reference of Gaussian noise r whose
    # variance is estimated from two seeds: the scatter of ln sqrt(m^2 - r_hat^2) over 400
    # seeded trials is error_sigma's within 15 %.
    rng = random.Random(7)
    n, e, r = 400, 0.01, 0.015
    logs = []
    for _ in range(400):
        m2 = v2 = 0.0
        for i in range(n):
            a, b = rng.gauss(0, r * math.sqrt(2)), rng.gauss(0, r * math.sqrt(2))
            eps = (a + b) / 2  # the two seeds' mean: noise r
            d = e if i % 2 else -e
            m2 += (d + eps) ** 2
            v2 += (a - b) ** 2 / 4  # its two-seed variance estimate: E = r^2
        logs.append(0.5 * math.log((m2 - v2) / n))
    mean = sum(logs) / len(logs)
    sd = math.sqrt(sum((x - mean) ** 2 for x in logs) / (len(logs) - 1))
    assert sd == pytest.approx(sweep.error_sigma(e, r, n), rel=0.15)


def test_stage_decision_reference_noise_on_decision_figures_only():
    # Reference noise 0.05 against a raster k point of 0.02 that is no decision (the as-is is
    # 0.1, the only Pareto point): the old rule went deep (0.05 > 0.02 / 3); now stage one.
    t = _staged(noise_ref=0.05, raster=0.02, as_is=0.1)
    assert sweep.stage_decision(t, 1024, last=4096)['deep'] == []
    # The same noise against an as-is error of 0.02: uncertain by 10.6 % (see above); at 4096
    # the noise is 0.05 / 2 (slope -0.5): q = 1.25, 1.25 sqrt(2.5625 / 4000) = 3.2 %: deep.
    t = _staged(noise_ref=0.05, raster=0.1, as_is=0.02)
    d = sweep.stage_decision(t, 1024, last=4096)
    assert any('raster as-is error 0.02 uncertain' in w and '3 % predicted' in w for w in d['deep'])
    # At the top of the ladder there is nothing to render: reported.
    d = sweep.stage_decision(t, 4096, last=4096)
    assert d['deep'] == [] and any('no level above 4096' in w for w in d['not_deep'])
    # Noise 0.2 against 0.02: q = 10 now, 5 at 4096: 5 sqrt(26 / 4000) = 40 %: no level of the
    # ladder decides it, so none is rendered for it.
    d = sweep.stage_decision(_staged(noise_ref=0.2, raster=0.1, as_is=0.02), 1024, last=4096)
    assert d['deep'] == [] and any('40 % predicted at 4096 spp' in w for w in d['not_deep'])


def _fake_stage_analysis(sp, top):
    """A scene's analysis at reference `top` for the pipeline tests: scene a has a crossover
    within reach at 256 spp and none at 1024 (two stages), scene b a slope 2 sigma off at every
    level (to the top of the ladder, then reported open), any other scene nothing (stage one)."""
    if sp == 'a':
        # 16, 64 against 256; then 16, 64, 256 against 1024: the crossover at 640 spp is above
        # the points both times, within the ladder's reach (1024) both times.
        errors = (0.16, 0.04) if top == 256 else (0.16, 0.04, 0.01)
        t = _staged(cycles_errors=errors, as_is=0.004, noise_ref=0.0001)
        above = top < 4096
        t['crossover'] = {'spp': 640.0, 'extrapolated': 'above' if above else None, 'raster_error': 0.004}
        return t
    if sp == 'b':
        return _staged(cycles_errors=(0.2, 0.1, 0.08))
    return _staged()


def _pipeline(monkeypatch, scenes, roles, levels='staged', jobs=1, renderers=('cycles', 'raster', 'povray', 'eevee')):
    """main.Pipeline over `scenes` (the jobs of `renderers`) with the renders and the analysis
    stood in for: returns the pipeline, the state, the records and the log of (event, scene,
    tag) in the order run."""
    main_mod = sys.modules['sweep.main']
    log, lock = [], threading.Lock()

    def fake_run(runner, sp, job):
        with lock:
            log.append(('run', sp, job['tag']))
        return {'status': 'ok', 'tag': job['tag']}

    def fake_scene(runner, args, name, jobs_, r, ref_spp, nested, ref_seed=0):
        with lock:
            log.append(('analyse', name, f'cycles-spp{ref_spp}'))
        assert all(r[j['key']]['status'] == 'ok' for j in jobs_)  # every job of the stage landed
        return _fake_stage_analysis(name, ref_spp)

    monkeypatch.setattr(main_mod, 'run_one', fake_run)
    monkeypatch.setattr(main_mod, 'sweep_scene', fake_scene)
    monkeypatch.setattr(main_mod, 'scene_name', lambda sp: sp)
    jobs_all, ref = sweep.plan(quick=False, seed_opt=True)
    jobs_all = [j for j in jobs_all if j['renderer'] in renderers]
    plans, full = {}, {}
    for sp in scenes:
        full[sp] = (jobs_all, ref)
        plans[sp] = (sp, jobs_all, ref) if levels == 'all' else (sp, *sweep.stage_one(jobs_all, ref))
    state = {'deeper': {}, 'undecided': {}, 'stage': dict.fromkeys(scenes, 1), 'seeds': {}}
    recs = {}

    class _R:
        seed_opt = True

    class _A:
        scheduler = 'local'

    _A.jobs, _A.levels = jobs, levels
    pipe = main_mod.Pipeline(_R(), _A(), plans, full, recs, state, False)
    final = pipe.run(list(scenes), roles)
    return pipe, final, state, recs, log


def test_deeper_stages_go_one_level_at_a_time(monkeypatch):
    """main.Pipeline: a goes to 4096 spp by the crossover (two stages), b by the slope (to the
    top of the ladder, then reported open), c stays at stage one; each deeper reference is
    rendered after its scene's analysis and each analysis after every job of its stage."""
    roles = dict.fromkeys('abc', 'twin')
    pipe, final, state, recs, log = _pipeline(monkeypatch, 'abc', roles)
    assert state['stage'] == {'a': 3, 'b': 3, 'c': 1}
    assert state['seeds'] == {'a': 6, 'b': 6}
    assert sorted((sp, j['tag']) for sp, _n, j in pipe.added) == [
        ('a', 'cycles-spp1024-s4'),
        ('a', 'cycles-spp4096-s6'),
        ('b', 'cycles-spp1024-s4'),
        ('b', 'cycles-spp4096-s6'),
    ]
    for sp in 'ab':
        i1024, i4096 = log.index(('run', sp, 'cycles-spp1024-s4')), log.index(('run', sp, 'cycles-spp4096-s6'))
        assert log.index(('analyse', sp, 'cycles-spp256')) < i1024 < log.index(('analyse', sp, 'cycles-spp1024'))
        assert log.index(('analyse', sp, 'cycles-spp1024')) < i4096 < log.index(('analyse', sp, 'cycles-spp4096'))
    # One analysis a stage, the last one the scene's figures (no second analysis at the end).
    assert [e for e in log if e[0] == 'analyse' and e[1] == 'c'] == [('analyse', 'c', 'cycles-spp256')]
    assert final['a']['crossover']['extrapolated'] is None and set(final) == set('abc')
    # Stage one's reference is a's 256 point now, the same record.
    assert recs[('a', 'cycles256')] == {'status': 'ok', 'tag': 'cycles-spp256'}
    assert [w.split(':')[0] for w in state['deeper']['a']] == ['at 256 spp', 'at 1024 spp']
    assert all('within the 1024-spp level' in w for w in state['deeper']['a'])
    assert any('no level above 4096 spp' in w for w in state['undecided']['b'])
    assert 'c' not in state['deeper'] and state['undecided']['c'] == []


def test_pipeline_queues_a_deeper_stage_before_other_scenes_stage_one(monkeypatch):
    """With one slot, twin a's 1024-spp reference runs right after a's stage-one analysis,
    before validate scene c's stage one (scene_order puts twins first), and every job of c
    still runs; --levels all analyses each scene once and goes no deeper. Without POV-Ray,
    whose jobs take slots of their own and would race the one slot."""
    roles = {'c': 'validate', 'a': 'twin'}
    no_pov = ('cycles', 'raster', 'eevee')
    pipe, final, state, recs, log = _pipeline(monkeypatch, ['c', 'a'], roles, renderers=no_pov)
    runs = [e for e in log if e[0] == 'run']
    assert runs.index(('run', 'a', 'cycles-spp1024-s4')) < min(i for i, e in enumerate(runs) if e[1] == 'c')
    n_c = sum(1 for e in runs if e[1] == 'c')
    assert n_c == sum(1 for j in sweep.stage_one(*sweep.plan(quick=False, seed_opt=True))[0] if j['renderer'] in no_pov)
    pipe, final, state, recs, log = _pipeline(monkeypatch, ['c', 'a'], roles, levels='all', jobs=2)
    assert pipe.added == [] and state['stage'] == {'c': 1, 'a': 1}
    assert sorted(e for e in log if e[0] == 'analyse') == [
        ('analyse', 'a', 'cycles-spp4096'),
        ('analyse', 'c', 'cycles-spp4096'),
    ]


def test_task_queue_order_and_follow_ups():
    """schedule.TaskQueue: one slot takes the lowest priority first (then the first put); a
    task's follow-up counts as work (wait_idle only after it); a task's exception reaches
    close(); POV-Ray jobs take the 'wait' slots (local scheduler only)."""
    q = sweep_schedule.TaskQueue({'cpu': 1})
    order, gate = [], threading.Event()
    q.put('cpu', (0,), gate.wait)  # holds the slot while the rest is queued
    q.put('cpu', (2, 1), lambda: order.append('late'))
    q.put('cpu', (2, 0), lambda: order.append('early'))
    q.put('cpu', (1,), lambda: (order.append('first'), q.put('cpu', (0,), lambda: order.append('follow-up'))))
    gate.set()
    assert q.wait_idle(30.0)
    q.close()
    assert order == ['first', 'follow-up', 'early', 'late']
    # Closed while a task runs (an interrupt): what is still queued is dropped, not run.
    q = sweep_schedule.TaskQueue({'cpu': 1})
    started, gate, ran = threading.Event(), threading.Event(), []
    q.put('cpu', (0,), lambda: (started.set(), gate.wait()))
    q.put('cpu', (1,), lambda: ran.append('queued'))
    assert started.wait(30.0)

    def open_gate_once_closed():
        with q.cond:
            q.cond.wait_for(lambda: q.closed)
        gate.set()

    threading.Thread(target=open_gate_once_closed).start()
    q.close()
    assert ran == [] and q.wait_idle(0.0)
    q = sweep_schedule.TaskQueue({'cpu': 2})
    q.put('cpu', (0,), lambda: 1 / 0)
    assert q.wait_idle(30.0)
    with pytest.raises(ZeroDivisionError):
        q.close()
    main_mod = sys.modules['sweep.main']

    class _A:
        scheduler = 'local'

    assert main_mod.job_slot({'renderer': 'povray'}, _A()) == 'wait'
    assert main_mod.job_slot({'renderer': 'cycles'}, _A()) == 'cpu'
    _A.scheduler = 'slurm'
    assert main_mod.job_slot({'renderer': 'povray'}, _A()) == 'cpu'


def _timing(tmp_path, run, errors, as_is):
    """RUN/timing/s.json for agree.py: Cycles points at 16, 64, 256 of the given errors (over
    4000 pixels), raster as-is error as_is on the Pareto frontier, no crossover."""
    t = _staged(cycles_errors=errors, as_is=as_is, noise_ref=0.001)
    for p in t['series'][0]['points']:
        p['label'] = f"{p['samples']} spp"
    t.update(scene='s', crossover=None, crossover_best_raster=None)
    d = tmp_path / run / 'timing'
    d.mkdir(parents=True)
    (d / 's.json').write_text(json.dumps(t))
    return str(tmp_path / run)


def test_agree_table(tmp_path):
    agree = sys.modules.get('sweep.agree') or importlib.import_module('sweep.agree')
    a = _timing(tmp_path, 'a', (0.2, 0.1, 0.05), 0.1)
    # Slope -0.5 in both (0 sigma); as-is 0.1 against 0.1: agrees.
    b = _timing(tmp_path, 'b', (0.2, 0.1, 0.05), 0.1)
    assert agree.table(a, b).splitlines()[-1] == '1 of 1 scenes agree within 2 sigma.'
    # 64 -> 256 falling to 0.025 instead: slope -0.75 against -0.5, each known to ~0.01: differs.
    c = _timing(tmp_path, 'c', (0.2, 0.1, 0.025), 0.1)
    text = agree.table(a, c)
    assert 'differs: slope' in text and text.splitlines()[-1] == '0 of 1 scenes agree within 2 sigma.'


# ------------------------------------------------------------------------------ second run


class _Args:
    def __init__(self, cache, binary):
        self.bin, self.cache, self.threads, self.scheduler, self.full_size = binary, cache, 1, 'local', False
        self.run = os.path.dirname(cache)


def _fake_bin(tmp_path):
    """A stand-in reflcheck: `run` writes a record (key k1, wall_s from a counter: 0.3, 0.2,
    0.1, ...) and `diff` prints a JSON naming its call number; both count their calls."""
    counter = tmp_path / 'calls'
    counter.write_text('0')
    exe = tmp_path / 'reflcheck'
    exe.write_text(
        '#!/usr/bin/python3\n'
        'import json, os, sys\n'
        f'c = {str(counter)!r}\n'
        'n = int(open(c).read()) + 1\n'
        'open(c, "w").write(str(n))\n'
        'a = sys.argv[1:]\n'
        'if a[0] == "run" and "--seed" in a and a[a.index("--seed") + 1] == "0" and len(a) == 3:\n'
        '    sys.exit(2)\n'
        'if a[0] == "run":\n'
        '    out, tag, r = a[a.index("--out") + 1], a[a.index("--tag") + 1], a[a.index("--renderer") + 1]\n'
        '    d = os.path.join(out, "s", tag)\n'
        '    os.makedirs(d, exist_ok=True)\n'
        '    rec = {"status": "ok", "key": "00000000000000k1".replace("k", "a"), "wall_s": 0.4 - 0.1 * n,\n'
        '           "cpu_s": 0.01, "cached": "--cache" in a}\n'
        '    json.dump(rec, open(os.path.join(d, r + "-validate.json"), "w"))\n'
        'else:\n'
        '    print(json.dumps({"surface": {"nrmse": n}}))\n'
    )
    exe.chmod(0o755)
    return str(exe), counter


def test_second_run_reads_repeats_and_diffs_from_the_cache(tmp_path):
    """A raster job's repeats and a diff of cached renders are kept in the cache: the second run
    over it renders the job once (through the cache) and diffs nothing."""
    exe, counter = _fake_bin(tmp_path)
    runner = sweep.Runner(_Args(str(tmp_path / 'cache'), exe))
    runner.roles['s'] = 'validate'
    calls0 = int(counter.read_text())  # the --seed probe
    rec = runner.run('s.yaml', 's', 'raster', 'raster-k1', [], repeats=3)
    assert int(counter.read_text()) - calls0 == 3  # first through the cache, two repeats
    assert rec['wall_s'] == pytest.approx(0.4 - 0.1 * (calls0 + 3))  # the fastest: the last
    keys = ('00000000000000a1', '00000000000000b2', '00000000000000c3')
    d1 = runner.diff('t.exr', 'r.exr', 'm.exr', ['specular'], keys=keys)
    n1 = int(counter.read_text())
    # Second run: one cached render, the kept repeat time, and the kept diff.
    rec2 = runner.run('s.yaml', 's', 'raster', 'raster-k1', [], repeats=3)
    assert int(counter.read_text()) == n1 + 1 and rec2['wall_s'] == pytest.approx(rec['wall_s'])
    assert runner.diff('t.exr', 'r.exr', 'm.exr', ['specular'], keys=keys) == d1
    assert int(counter.read_text()) == n1 + 1
    # Other terms left out, or no keys: a diff of its own.
    runner.diff('t.exr', 'r.exr', 'm.exr', [], keys=keys)
    runner.diff('t.exr', 'r.exr', 'm.exr', ['specular'])
    assert int(counter.read_text()) == n1 + 3


def test_diffs_of_a_scene_in_one_process(tmp_path):
    """A scene's diffs go to one `reflcheck diff --pairs` process: each answer equals what `diff`
    alone gives for its pair (a partial twin's terms left out, a noise diff against the zero
    image, a missing image's error in its own slot), and the cache keeps them as before."""
    real = os.environ.get('REFLCHECK_BIN') or os.path.join(ROOT, 'build', 'reflcheck')
    log = tmp_path / 'calls.log'
    exe = tmp_path / 'reflcheck'
    exe.write_text(f'#!/bin/sh\necho "$*" >> {str(log)!r}\nexec {os.path.abspath(real)!r} "$@"\n')
    exe.chmod(0o755)
    img = {}
    for name, scene in (('a', 'd3d9_glass'), ('b', 'd3d_spot'), ('m', 'stiff_blinn')):
        img[name] = str(tmp_path / f'{name}.exr')
        subprocess.run(
            [real, 'render', os.path.join(ROOT, 'scenes', scene + '.yaml'), '-o', img[name], '--width', '16']
            + ['--height', '12', '-q'],
            check=True,
            cwd=ROOT,
        )
    keys = ('00000000000000a1', '00000000000000b2', '00000000000000c3')
    items = [
        (img['a'], img['b'], img['m'], ['specular'], keys),
        (img['b'], img['a'], img['m'], (), None),
        (img['a'], str(tmp_path / 'nosuch.exr'), img['m'], (), None),
    ]
    runner = sweep.Runner(_Args(str(tmp_path / 'cache'), str(exe)))
    log.write_text('')
    got = runner.diff_many(items)
    assert log.read_text().count('diff --pairs') == 1 and len(log.read_text().splitlines()) == 1
    for (test, ref, mask, left, _), answer in zip(items[:2], got):
        cmd = [real, 'diff', test, ref, '--mask', mask] + (['--leave-out', ','.join(left)] if left else [])
        assert answer == json.loads(subprocess.run(cmd, capture_output=True, text=True, check=True).stdout)
    assert isinstance(got[2], RuntimeError) and 'nosuch.exr' in str(got[2])
    alone = subprocess.run([real, 'diff', img['a'], items[2][1], '--mask', img['m']], capture_output=True, text=True)
    assert str(got[2]) == f"reflcheck diff {img['a']} {items[2][1]}: " + alone.stderr.strip().splitlines()[-1]
    # The keyed pair is kept: asked again, only the other two are diffed.
    log.write_text('')
    again = runner.diff_many(items)
    assert again[0] == got[0] and log.read_text().count('diff --pairs') == 1
    assert runner.diff(*items[0][:4], keys=keys) == got[0] and log.read_text().count('diff') == 1


def test_missing_run_folder_is_one_line(tmp_path):
    """`--run DIR` with no DIR: exit 2 and one line naming it (it was a traceback from the Blender
    worker pool's log), before any scene is read or job started."""
    exe = os.environ.get('REFLCHECK_BIN') or os.path.join(ROOT, 'build', 'reflcheck')
    missing = tmp_path / 'missing'
    p = subprocess.run(
        [
            sys.executable,
            os.path.join(ROOT, 'tools', 'sweep.py'),
            '--run',
            str(missing),
            '--bin',
            exe,
            '--cache',
            str(tmp_path / 'cache'),
            '--scenes',
            os.path.join(ROOT, 'scenes', 'stiff_near_light.yaml'),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode == 2 and p.stderr.count('\n') == 1, p.stderr
    assert f'--run {missing}: no such folder' in p.stderr and not missing.exists()


def test_zero_image_made_once_a_size(monkeypatch):
    """sweep_scene makes a zero image (oiiotool) at the first analysis of its size only: each
    later stage's analysis takes the same image (its size is the as-is render's, which no stage
    changes), and so does another scene of that size; a scene whose size its record does not
    give gets its own."""
    main_mod = sys.modules['sweep.main']
    made, used = [], []
    monkeypatch.setattr(main_mod, 'make_zero', lambda like, path: made.append(path) or path)
    monkeypatch.setattr(main_mod, 'scene_diffs', lambda runner, jobs, r, zero: used.append(zero) or ({}, {}, []))
    monkeypatch.setattr(main_mod, 'analyse', lambda *a: {})

    class _A:
        clock = 'wall'

    runner = sweep.Runner.__new__(sweep.Runner)
    runner.renders, runner.roles, runner.zeros, runner.zero_lock = '/r', {}, {}, threading.Lock()
    r = {'reference': {'status': 'ok'}, 'as_is': {'status': 'ok', 'exr': '/r/s/as_is.exr'}}
    for name in ('s', 's', 's', 't'):
        main_mod.sweep_scene(runner, _A(), name, [], r, 256, False)
    assert made == ['/r/s/zero.exr', '/r/t/zero.exr']
    assert used == ['/r/s/zero.exr'] * 3 + ['/r/t/zero.exr']
    # With the size in the records: one zero image a size, whichever scene needs it first.
    made.clear(), used.clear()
    runner.zeros = {}
    for name, w, h in (('s', 96, 48), ('t', 96, 48), ('u', 96, 72), ('s', 96, 48)):
        r['as_is'].update(width=w, height=h, exr=f'/r/{name}/as_is.exr')
        main_mod.sweep_scene(runner, _A(), name, [], r, 256, False)
    assert made == ['/r/zero-96x48.exr', '/r/zero-96x72.exr']
    assert used == ['/r/zero-96x48.exr'] * 2 + ['/r/zero-96x72.exr', '/r/zero-96x48.exr']
