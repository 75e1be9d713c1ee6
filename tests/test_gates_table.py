"""test_gates_table.py - tools/gates.py: every gate beside its figure, at each size, loose ones flagged.

Run: REFLCHECK_BIN=build/reflcheck [RUN_DIR=build/test-run] \
     /usr/bin/python3 -m pytest -q -p no:cacheprovider tests/test_gates_table.py
The canonical scenes' small gates are checked against the run tests/run_scenes.sh wrote (RUN_DIR,
else BUILD/test-run next to REFLCHECK_BIN); without one, against a fixture run of the small
figures docs/gates.md last recorded; their full-size gates against a fixture run of its full-size
figures (no test renders at full size), so a gate loosened without a reason fails either way.
Hand-made scenes and compare.json files show the ratios, that a loose gate without a reason
fails, and that each size is judged by its own gate against its own figure.
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


def write_run(run, name, figures, size):
    """RUN/<name>/compare.json of one comparison whose thresholds applied at size."""
    (run / name).mkdir(parents=True)
    cmp = {
        'scene': name,
        'comparisons': [
            {
                'id': 'raster-vs-povray-twin',
                'status': 'pass',
                'thresholds': [{'metric': m, 'value': v, 'size': size} for m, v in figures.items()],
            }
        ],
    }
    (run / name / 'compare.json').write_text(json.dumps(cmp))


def fixture(tmp_path, name, gates, figures, size='small'):
    """A scenes folder with one scene of the given threshold lines, a run with their figures."""
    scenes, run = tmp_path / 'scenes', tmp_path / 'run'
    scenes.mkdir(parents=True)
    body = SCENE_HEAD.format(name=name) + ''.join(f'      {g}\n' for g in gates)
    (scenes / f'{name}.yaml').write_text(body)
    write_run(run, name, figures, size)
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
    assert '| fx | raster-vs-povray-twin | rel_rms | small | 0.0005 | 0.001 | 0.0001 | 10 | - | loose |' in text
    # 0.03 / 0.0101 = 2.97 against the run, 0.03 / 0.011 = 2.73 against the figure it was sized on
    assert '| nrmse | small | 0.02 | 0.03 | 0.0101 | 2.97 | 0.011 full (n1), x2.73 |  |' in text


def two_runs(tmp_path, gates, small, full):
    """One scene's gates with a small run and a full run of their figures."""
    scenes, run = fixture(tmp_path, 'fx', gates, small, 'small')
    write_run(tmp_path / 'full', 'fx', full, 'full')
    return scenes, run, str(tmp_path / 'full')


def test_each_size_is_judged_by_its_own_gate_against_its_own_figure(tmp_path):
    # real_house's Cycles validate: 0.011 small, 7.06e-4 full. A shared fail 0.03 is 2.73x the
    # small figure and 42.5x the full one; a full: block at 0.002 is 2.83x (0.002 / 7.06e-4).
    shared = 'nrmse: {warn: 0.02, fail: 0.03, why: "w"'
    block = ', full: {warn: 0.0015, fail: 0.002, sized: {figure: 7.06e-4, run: "n1"}}'
    scenes, small, full = two_runs(tmp_path, [shared + block + '}'], {'nrmse': 0.011}, {'nrmse': 7.06e-4})
    md = tmp_path / 'g.md'
    p = run_tool('--run', small, '--run', full, '--scenes', scenes, '--md', str(md))
    assert p.returncode == 0, p.stdout + p.stderr
    text = md.read_text()
    assert '| fx | raster-vs-povray-twin | nrmse | small | 0.02 | 0.03 | 0.011 | 2.73 | - |  |' in text, text
    assert '| nrmse | full (own) | 0.0015 | 0.002 | 0.000706 | 2.83 | 0.000706 full (n1), x2.83 |  |' in text, text
    # The same runs given in the other order: each still meets its own size's gate.
    assert run_tool('--run', full, '--run', small, '--scenes', scenes).returncode == 0


def test_a_shared_gate_loose_at_full_size_alone_is_flagged_there(tmp_path):
    scenes, small, full = two_runs(
        tmp_path / 'a', ['nrmse: {warn: 0.02, fail: 0.03, why: "w"}'], {'nrmse': 0.011}, {'nrmse': 7.06e-4}
    )
    p = run_tool('--run', small, '--run', full, '--scenes', scenes)
    assert p.returncode == 1, p.stdout + p.stderr
    flagged = [line for line in p.stdout.splitlines() if 'LOOSE' in line]
    assert len(flagged) == 1 and ' full ' in flagged[0] and ' 42.5 ' in flagged[0], p.stdout
    assert 'nrmse: at full size fail 0.03 is 42.5x' in p.stderr and 'full: {fail: ...}' in p.stderr
    # Only the small run: the full gate is not judged at all.
    assert run_tool('--run', small, '--scenes', scenes).returncode == 0


def test_a_run_of_unknown_size_and_two_runs_of_one_size_are_refused(tmp_path):
    scenes, small, full = two_runs(tmp_path, ['nrmse: {warn: 0.02, fail: 0.03}'], {'nrmse': 0.01}, {'nrmse': 0.01})
    p = run_tool('--run', small, '--run', small, '--scenes', scenes)
    assert p.returncode == 2 and 'a second small run' in p.stderr, p.stderr
    bare = tmp_path / 'bare' / 'fx'
    bare.mkdir(parents=True)
    (bare / 'compare.json').write_text(json.dumps({'scene': 'fx', 'comparisons': []}))
    p = run_tool('--run', str(bare.parent), '--scenes', scenes)
    assert p.returncode == 2 and 'no image size' in p.stderr, p.stderr
    # A run written before compare.json said the size: the job records' variant tells it.
    (bare / 'raster-twin.json').write_text(json.dumps({'status': 'ok', 'variant': 'full'}))
    p = run_tool('--run', str(bare.parent), '--scenes', scenes)
    assert p.returncode == 0 and ' full ' in p.stdout, p.stdout + p.stderr


def test_higher_is_better_metrics_measure_from_the_ideal(tmp_path):
    gates = [
        'coverage_agreement: {warn: 0.9995, fail: 0.999, why: "same triangles"}',
        'psnr: {warn: 45, fail: 40, why: "guard"}',
    ]
    scenes, run = fixture(tmp_path, 'fx', gates, {'coverage_agreement': 0.9999, 'psnr': 60.0})
    p = run_tool('--run', run, '--scenes', scenes)
    assert p.returncode == 1
    # (1 - 0.999) / (1 - 0.9999) = 10; 20 dB apart = 10x in RMS error
    assert 'coverage_agreement: at small size fail 0.999 is 10x' in p.stderr
    assert 'psnr: at small size fail 40 is 10x' in p.stderr
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
            'rel_rms.lose: unknown key; allowed: warn, fail, why, loose, sized, small, full',
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
    sized = {'figure': 0.011, 'size': 'small', 'run': 'n1'}
    same = {'warn': 0.02, 'fail': 0.03, 'loose': 'l', 'own': False, 'sized': sized}
    assert t == {
        'metric': 'nrmse',
        'warn': 0.02,
        'fail': 0.03,
        'why': 'w',
        'loose': 'l',
        'sized': sized,
        'small': same,
        'full': same,
    }


def parsed(path):
    """reflcheck check --json of one scene file; a scene the parser refuses fails the test."""
    p = subprocess.run([BIN, 'check', '--json', path], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    return json.loads(p.stdout)


def recorded_figures():
    """{(scene, comparison, metric, size): figure} from docs/gates.md's first table (gates.py --md)."""
    out = {}
    with open(os.path.join(ROOT, 'docs', 'gates.md'), encoding='utf-8') as f:
        for line in f:
            if out and not line.startswith('|'):
                break
            cells = [c.strip() for c in line.strip().strip('|').split('|')]
            if len(cells) >= 7 and cells[6] not in ('-', 'figure') and not cells[6].startswith('-'):
                out[(cells[0], cells[1], cells[2], cells[3].split()[0])] = float(cells[6])
    return out


def fixture_run(run, size, figures):
    """A run of the figures docs/gates.md records for one size, in compare.json form."""
    for path in sorted(glob.glob(os.path.join(ROOT, 'scenes', '*.yaml'))):
        doc = parsed(path)
        comps = []
        for c in doc['comparisons']:
            keys = [(doc['scene'], c['id'], t['metric'], size) for t in c['thresholds']]
            values = [{'metric': k[2], 'value': figures[k], 'size': size} for k in keys if k in figures]
            comps.append({'id': c['id'], 'status': 'pass', 'thresholds': values})
        (run / doc['scene']).mkdir(parents=True)
        (run / doc['scene'] / 'compare.json').write_text(json.dumps({'scene': doc['scene'], 'comparisons': comps}))
    return str(run)


def scenes_runs(tmp_path):
    """The small run tests/run_scenes.sh wrote (else a fixture of docs/gates.md's small figures), and a
    fixture of its full-size figures."""
    figures = recorded_figures()
    assert any(k[3] == 'full' for k in figures), 'docs/gates.md lists no full-size figures'
    full = fixture_run(tmp_path / 'full', 'full', figures)
    run = os.environ.get('RUN_DIR') or os.path.join(os.path.dirname(BIN), 'test-run')
    if glob.glob(os.path.join(run, '*', 'compare.json')):
        return run, full, False
    assert any(k[3] == 'small' for k in figures), 'docs/gates.md lists no small figures'
    return fixture_run(tmp_path / 'small', 'small', figures), full, True


def test_canonical_scenes_list_every_gate_and_none_is_loose_without_reason(tmp_path):
    small, full, made = scenes_runs(tmp_path)
    p = run_tool('--run', small, '--run', full)
    expected = 0
    for path in glob.glob(os.path.join(ROOT, 'scenes', '*.yaml')):
        doc = parsed(path)
        expected += 2 * sum(len(c['thresholds']) for c in doc['comparisons'])
    rows = p.stdout.splitlines()[1:]
    assert len(rows) == expected, p.stdout
    assert p.returncode == 0, f'runs {small}{" (fixture)" if made else ""}, {full} (fixture):\n{p.stderr}'
