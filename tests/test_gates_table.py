"""test_gates_table.py - tools/gates.py: every gate beside its figure, loose ones flagged.

Run: REFLCHECK_BIN=build/reflcheck [RUN_DIR=build/test-run] \
     /usr/bin/python3 -m pytest -q -p no:cacheprovider tests/test_gates_table.py
The canonical scenes are checked against the run tests/run_scenes.sh wrote (RUN_DIR, else
BUILD/test-run next to REFLCHECK_BIN); without one, against a fixture run of the figures
docs/gates.md last recorded, so a gate loosened without a reason fails either way. Hand-made
scenes and compare.json files show the ratios and that a loose gate without a reason fails.
"""

import glob
import json
import math
import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TOOL = os.path.join(ROOT, 'tools', 'gates.py')
BIN = os.environ.get('REFLCHECK_BIN', os.path.join(ROOT, 'build', 'reflcheck'))
sys.path.insert(0, os.path.join(ROOT, 'tools'))
from gates import ratio  # noqa: E402

SCENE_HEAD = """name: {name}
image: {{width: 16, height: 16, supersample: 1, samples: 4}}
camera: {{eye: [0, 1, 4], target: [0, 0, 0], hfov: 40}}
lights:
  - {{type: point, position: [1, 2, 2], intensity: [5, 5, 5]}}
materials:
  m: {{albedo: [0.5, 0.5, 0.5], model: d3d}}
objects:
  - {{shape: sphere, center: [0, 0, 0], radius: 0.5, material: m}}
comparisons:
  - reference: povray
    role: twin
    thresholds:
"""


def run_tool(*args):
    return subprocess.run([sys.executable, TOOL, '--bin', BIN, *args], capture_output=True, text=True)


def fixture(tmp_path, name, gates, figures):
    """A scenes folder with one scene of the given threshold lines, a run with their figures."""
    scenes, run = tmp_path / 'scenes', tmp_path / 'run'
    scenes.mkdir()
    (run / name).mkdir(parents=True)
    body = SCENE_HEAD.format(name=name) + ''.join(f'      {g}\n' for g in gates)
    (scenes / f'{name}.yaml').write_text(body)
    cmp = {
        'scene': name,
        'comparisons': [
            {
                'id': 'raster-vs-povray-twin',
                'status': 'pass',
                'thresholds': [{'metric': m, 'value': v} for m, v in figures.items()],
            }
        ],
    }
    (run / name / 'compare.json').write_text(json.dumps(cmp))
    return str(scenes), str(run)


@pytest.fixture(autouse=True)
def need_binary():
    assert os.access(BIN, os.X_OK), f'{BIN}: build reflcheck first (make BUILD=x all), or set REFLCHECK_BIN'


def test_loose_gate_without_reason_fails(tmp_path):
    scenes, run = fixture(
        tmp_path, 'fx', ['rel_rms: {warn: 5.0e-4, fail: 1.0e-3, why: "half-float"}'], {'rel_rms': 1.0e-4}
    )
    p = run_tool('--run', run, '--scenes', scenes)
    assert p.returncode == 1, p.stdout + p.stderr
    row = [line for line in p.stdout.splitlines() if line.startswith('fx ')]
    assert len(row) == 1 and 'LOOSE' in row[0] and ' 10 ' in row[0], p.stdout
    assert 'fx: raster-vs-povray-twin: rel_rms' in p.stderr and 'scenes/fx.yaml' in p.stderr


def test_stated_reason_and_a_gate_within_3x_pass(tmp_path):
    gates = [
        'rel_rms: {warn: 5.0e-4, fail: 1.0e-3, why: "half-float", loose: "precision floor: half-float EXR"}',
        'nrmse: {warn: 0.02, fail: 0.03, why: "guard", sized: {figure: 0.011, size: full, run: "n1"}}',
    ]
    scenes, run = fixture(tmp_path, 'fx', gates, {'rel_rms': 1.0e-4, 'nrmse': 0.0101})
    md = tmp_path / 'gates.md'
    p = run_tool('--run', run, '--scenes', scenes, '--md', str(md))
    assert p.returncode == 0, p.stdout + p.stderr
    text = md.read_text()
    assert '| fx | raster-vs-povray-twin | rel_rms | 0.0005 | 0.001 | 0.0001 | 10 | - | loose |' in text
    # 0.03 / 0.0101 = 2.97 against the run, 0.03 / 0.011 = 2.73 against the figure it was sized on
    assert '| nrmse | 0.02 | 0.03 | 0.0101 | 2.97 | 0.011 full (n1), x2.73 |  |' in text


def test_higher_is_better_metrics_measure_from_the_ideal(tmp_path):
    gates = [
        'coverage_agreement: {warn: 0.9995, fail: 0.999, why: "same triangles"}',
        'psnr: {warn: 45, fail: 40, why: "guard"}',
    ]
    scenes, run = fixture(tmp_path, 'fx', gates, {'coverage_agreement': 0.9999, 'psnr': 60.0})
    p = run_tool('--run', run, '--scenes', scenes)
    assert p.returncode == 1
    # (1 - 0.999) / (1 - 0.9999) = 10; 20 dB apart = 10x in RMS error
    assert 'coverage_agreement: fail 0.999 is 10x' in p.stderr
    assert 'psnr: fail 40 is 10x' in p.stderr
    assert ratio('psnr', 50.0, 55.0) == pytest.approx(10**0.25)
    assert ratio('ssim', 0.99, 1.0) == math.inf
    assert ratio('test_nonfinite', 0, 0) == 1.0
    assert ratio('bias.z_trim1_max', 21, 7.0) == pytest.approx(3.0)


def test_a_failing_figure_and_an_absent_one_are_not_loose(tmp_path):
    gates = ['rel_rms: {warn: 5.0e-4, fail: 1.0e-3, why: "x"}', 'nrmse: {warn: 0.02, fail: 0.03, why: "x"}']
    scenes, run = fixture(tmp_path, 'fx', gates, {'rel_rms': 2.0e-3})
    p = run_tool('--run', run, '--scenes', scenes)
    assert p.returncode == 0, p.stderr
    assert 'FAILS' in p.stdout and 'unmeasured' in p.stdout


@pytest.mark.parametrize(
    'gate, message',
    [
        ('rel_rms: {warn: 1, fail: 2, loose: ""}', 'thresholds.rel_rms.loose: expected text, got nothing'),
        ('rel_rms: {warn: 1, fail: 2, loose: [a]}', 'thresholds.rel_rms.loose: expected text, got a list'),
        ('rel_rms: {warn: 1, fail: 2, sized: {figure: 1, size: full}}', 'thresholds.rel_rms.sized.run: missing'),
        (
            'rel_rms: {warn: 1, fail: 2, sized: {figure: 1, size: medium, run: r}}',
            "sized.size: unknown value 'medium'; allowed: small, full",
        ),
        ('rel_rms: {warn: 1, fail: 2, sized: {figure: "1", size: full, run: r}}', 'sized.figure: expected a number'),
        ('rel_rms: {warn: 1, fail: 2, sized: {figure: 1, size: full, run: r, at: 3}}', 'sized.at: unknown key'),
        (
            'rel_rms: {warn: 1, fail: 2, lose: "x"}',
            'rel_rms.lose: unknown key; allowed: warn, fail, why, loose, sized',
        ),
    ],
)
def test_parser_refuses_bad_loose_and_sized(tmp_path, gate, message):
    scenes, run = fixture(tmp_path, 'fx', [gate], {})
    p = run_tool('--run', run, '--scenes', scenes)
    assert p.returncode == 2, p.stdout + p.stderr
    assert message in p.stderr and 'fx.yaml:' in p.stderr, p.stderr
    assert len(p.stderr.strip().splitlines()) == 1


def test_check_json_prints_what_the_file_says(tmp_path):
    gate = 'nrmse: {warn: 0.02, fail: 0.03, why: "w", loose: "l", sized: {figure: 0.011, size: small, run: "n1"}}'
    scenes, _ = fixture(tmp_path, 'fx', [gate], {})
    p = subprocess.run([BIN, 'check', '--json', os.path.join(scenes, 'fx.yaml')], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    doc = json.loads(p.stdout)
    assert doc['scene'] == 'fx'
    t = doc['comparisons'][0]['thresholds'][0]
    assert doc['comparisons'][0]['id'] == 'raster-vs-povray-twin'
    assert t == {
        'metric': 'nrmse',
        'warn': 0.02,
        'fail': 0.03,
        'why': 'w',
        'loose': 'l',
        'sized': {'figure': 0.011, 'size': 'small', 'run': 'n1'},
    }


def parsed(path):
    """reflcheck check --json of one scene file; a scene the parser refuses fails the test."""
    p = subprocess.run([BIN, 'check', '--json', path], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    return json.loads(p.stdout)


def recorded_figures():
    """{(scene, comparison, metric): figure} from docs/gates.md's first table (gates.py --md)."""
    out = {}
    with open(os.path.join(ROOT, 'docs', 'gates.md'), encoding='utf-8') as f:
        for line in f:
            if out and not line.startswith('|'):
                break
            cells = [c.strip() for c in line.strip().strip('|').split('|')]
            if len(cells) >= 6 and cells[5] not in ('-', 'figure') and not cells[5].startswith('-'):
                out[(cells[0], cells[1], cells[2])] = float(cells[5])
    return out


def scenes_run(tmp_path):
    """The run tests/run_scenes.sh wrote, else a fixture run of the figures docs/gates.md records."""
    run = os.environ.get('RUN_DIR') or os.path.join(os.path.dirname(BIN), 'test-run')
    if glob.glob(os.path.join(run, '*', 'compare.json')):
        return run, False
    run, figures = tmp_path / 'run', recorded_figures()
    assert figures, 'docs/gates.md lists no figures'
    for path in sorted(glob.glob(os.path.join(ROOT, 'scenes', '*.yaml'))):
        doc = parsed(path)
        comps = []
        for c in doc['comparisons']:
            keys = [(doc['scene'], c['id'], t['metric']) for t in c['thresholds']]
            values = [{'metric': k[2], 'value': figures[k]} for k in keys if k in figures]
            comps.append({'id': c['id'], 'status': 'pass', 'thresholds': values})
        (run / doc['scene']).mkdir(parents=True)
        (run / doc['scene'] / 'compare.json').write_text(json.dumps({'scene': doc['scene'], 'comparisons': comps}))
    return str(run), True


def test_canonical_scenes_list_every_gate_and_none_is_loose_without_reason(tmp_path):
    run, made = scenes_run(tmp_path)
    p = run_tool('--run', run)
    expected = 0
    for path in glob.glob(os.path.join(ROOT, 'scenes', '*.yaml')):
        doc = parsed(path)
        expected += sum(len(c['thresholds']) for c in doc['comparisons'])
    rows = p.stdout.splitlines()[1:]
    assert len(rows) == expected, p.stdout
    assert p.returncode == 0, f'run {run}{" (fixture)" if made else ""}:\n{p.stderr}'
