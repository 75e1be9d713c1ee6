"""test_report.py - tools/report.py and its package tools/report/ on a synthetic run folder
(tests/fixtures/report/make_run.py).

Run: /usr/bin/python3 -m pytest -q tests/test_report.py   (Debian python3-pytest; the browser
tests need Debian's chromium and are skipped without it, the plot checks need gnuplot).
Checks the pages, summary.json/csv, JUnit XML, the append-only history (with a simulated crash),
corrupt inputs, threshold proposals, and that the pages render in headless Chromium from disk.
"""

import csv
import hashlib
import json
import math
import os
import re
import shutil
import struct
import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
REPORT = os.path.join(ROOT, 'tools', 'report.py')
sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.join(ROOT, 'tests', 'fixtures', 'report'))
from make_run import make_run  # noqa: E402

sys.path.insert(0, os.path.join(ROOT, 'tools'))
from report import browser, figures, history, load, plots, proposal, util  # noqa: E402  (the package tools/report/)

RUN1 = '20250101-120000-abc1234'
RUN2 = '20250102-120000-def5678'
RUN3 = '20250103-120000-0a1b2c3'
HAVE_CHROMIUM = browser.chromium_exe() is not None
HAVE_GNUPLOT = shutil.which('gnuplot') is not None


def run_report(*args):
    r = subprocess.run([sys.executable, REPORT] + list(args), capture_output=True, text=True, timeout=300)
    return r


def read(path):
    with open(path, encoding='utf-8') as f:
        return f.read()


@pytest.fixture(scope='module')
def built(tmp_path_factory):
    """One report of the fixture run, with history and --latest; shared by the read-only tests."""
    root = str(tmp_path_factory.mktemp('reports'))
    run = make_run(root, RUN1)
    hist = os.path.join(root, 'history.jsonl')
    r = run_report('--run', run, '--history', hist, '--latest', os.path.join(root, 'latest'))
    assert r.returncode == 0, r.stderr
    return {'root': root, 'run': run, 'hist': hist, 'proc': r}


def summary_rows(index_html):
    body = index_html.split('<table id="summary"', 1)[1].split('</table>', 1)[0]
    return re.findall(
        r'<tr data-role="([^"]*)" data-verdict="([^"]*)"[^>]*>.*?<div class="cid">([^<]*)</div>', body, re.S
    )


# ------------------------------------------------------------------------------------ pages


def test_index_lists_failures_first_and_has_filters(built):
    html = read(os.path.join(built['run'], 'index.html'))
    rows = summary_rows(html)
    assert [(v, c) for _, v, c in rows] == [
        ('fail', 'raster-vs-cycles-twin'),
        ('skipped', 'povray-vs-cycles-agree'),
        ('pass', 'raster-vs-povray-twin'),
    ]
    assert 'id="filter-text"' in html and 'id="filter-role"' in html and 'id="filter-verdict"' in html
    for role in ('twin', 'agree'):
        assert f'<option value="{role}">' in html
    # every job record is in the renderer table, the skipped one with its message and a log link
    assert html.count('<tr data-role=') == 3 + 6
    assert 'blender not found on PATH' in html
    assert '<a href="alpha/povray-twin.log">log</a>' in html
    # legend of roles, relative assets only (no network)
    assert 'the reference renderer is set up to compute exactly our model' in html
    js = read(os.path.join(built['run'], 'report.js'))
    assert 'http://' not in html and 'https://' not in html
    assert 'fetch(' not in js and 'XMLHttpRequest' not in js
    # optional sections: stability and figure 1 on pages of their own, linked with a summary
    # (the NaN row flagged there); the timing table on the index
    assert '<a href="stability.html">' in html and '1 flagged' in html and 'id="stability"' not in html
    stab = read(os.path.join(built['run'], 'stability.html'))
    assert 'Numerical stability' in stab and 'class="row-fail"' in stab
    assert '<a href="figure1.html">' in html and 'src="figure1.svg"' not in html
    assert 'src="figure1.svg"' in read(os.path.join(built['run'], 'figure1.html'))
    assert 'cycles_convergence' in html


def test_scene_pages_reference_view_js(built):
    for scene, n_images, n_heat in (('alpha', 3, 2), ('beta', 2, 0)):
        html = read(os.path.join(built['run'], f'scene-{scene}.html'))
        assert f'<script src="{scene}/view.js"></script>' in html
        assert html.count('data-layer="img:') == n_images
        assert html.count('data-layer="heat:') == n_heat
        assert 'id="ev"' in html and 'id="flip-a"' in html and 'id="probe"' in html
        assert 'href="index.html"' in html
    beta = read(os.path.join(built['run'], 'scene-beta.html'))
    assert 'povray-vs-cycles-agree (skipped: no reference image in view.js)' in beta


@pytest.mark.skipif(not HAVE_GNUPLOT, reason='gnuplot not installed')
def test_plots_are_svg(built):
    plots = os.path.join(built['run'], 'plots')
    for f in ('angle-alpha-ndotv.svg', 'angle-alpha-ndotl.svg', 'trend-alpha.svg', 'timing-cycles_convergence.svg'):
        ET.parse(os.path.join(plots, f))  # well-formed SVG
        assert f'plots/{f}' in read(os.path.join(built['run'], 'scene-alpha.html')) + read(
            os.path.join(built['run'], 'index.html')
        )
    svg = read(os.path.join(plots, 'trend-alpha.svg'))
    assert 'raster-vs-cycles-twin' in svg and 'raster-vs-povray-twin' in svg
    # beta has no measured bins: no angle plot, and the page says so
    assert not os.path.exists(os.path.join(plots, 'angle-beta-ndotv.svg'))
    assert 'no angle bins in compare.json' in read(os.path.join(built['run'], 'scene-beta.html'))


def plots_line(stdout):
    """(drawn, from the cache) of report.py's 'report: plots: ...' line."""
    m = re.search(r'report: plots: (\d+) drawn by gnuplot .*?, (\d+) from ', stdout)
    assert m, stdout
    return int(m.group(1)), int(m.group(2))


@pytest.mark.skipif(not HAVE_GNUPLOT, reason='gnuplot not installed')
def test_plot_cache_draws_only_what_changed(tmp_path):
    cache = str(tmp_path / 'cache')
    first = make_run(str(tmp_path / 'a'), RUN1)
    r = run_report('--run', first, '--cache', cache)
    drawn, kept = plots_line(r.stdout)
    assert r.returncode == 0 and drawn == 3 and kept == 0, r.stdout  # 2 angle plots, 1 timing
    # The same inputs in another run folder: every plot comes back, byte for byte.
    same = make_run(str(tmp_path / 'b'), RUN1)
    r = run_report('--run', same, '--cache', cache)
    assert plots_line(r.stdout) == (0, drawn), r.stdout
    for f in os.listdir(os.path.join(first, 'plots')):
        assert read(os.path.join(first, 'plots', f)) == read(os.path.join(same, 'plots', f)), f
    # Other figures (every error doubled): the plots of those figures are drawn again.
    changed = make_run(str(tmp_path / 'c'), RUN1, rel_scale=2.0)
    r = run_report('--run', changed, '--cache', cache)
    redrawn, _ = plots_line(r.stdout)
    assert redrawn >= 2, r.stdout
    f = 'angle-alpha-ndotv.svg'
    assert read(os.path.join(changed, 'plots', f)) != read(os.path.join(first, 'plots', f))


@pytest.mark.skipif(not HAVE_GNUPLOT, reason='gnuplot not installed')
def test_plots_of_one_gnuplot_are_the_bytes_of_one_gnuplot_each(tmp_path, monkeypatch):
    """Five plots queued and drawn in one gnuplot (a batch) have the bytes of the same plots drawn
    one gnuplot each: a plot's settings do not leak into the next (the share plot's linear y axis
    and its [0:*] range into the log-y plot after it). The third plot's data file is missing: it
    is named with the message it gets alone, and the two after it are still drawn."""
    d = tmp_path / 'data'
    d.mkdir()
    (d / 'share.dat').write_text('bin a:x b\n0.05 0.7 0.3\n0.15 0.6 ?\n0.55 0.1 0.9\n')
    (d / 'rel.dat').write_text('bin raster-vs-cycles\n0.05 0.2\n0.35 ?\n0.85 0.013\n')
    (d / 'trend.dat').write_text('run label c1 c2\n1 ref-abc1234 0.02 ?\n2 def5678 0.025 0.4\n')
    angle = {'xlab': 'N·V', 'ylab': 'y', 'height': 316, 'ncols': 3}
    plot_list = [
        ('angle.gp', dict(angle, datafile=str(d / 'share.dat'), logy=0, ptitle="a's share")),
        ('angle.gp', dict(angle, datafile=str(d / 'rel.dat'), logy=1, ncols=2, ptitle='rel')),
        ('angle.gp', dict(angle, datafile=str(d / 'gone.dat'), logy=1, ptitle='gone')),
        ('trend.gp', {'datafile': str(d / 'trend.dat'), 'ncols': 4, 'ptitle': 'trend'}),
        ('angle.gp', dict(angle, datafile=str(d / 'share.dat'), logy=1, ptitle='share again')),
    ]
    runs = []
    real_run = plots.subprocess.run
    monkeypatch.setattr(plots.subprocess, 'run', lambda cmd, **kw: runs.append(cmd) or real_run(cmd, **kw))

    def draw(folder, queued):
        os.makedirs(folder)
        problems = util.Problems()
        if queued:
            plots.queue_plots()
        said = [
            plots.run_gnuplot(sc, pa, os.path.join(folder, f'{i}.svg'), problems)
            for i, (sc, pa) in enumerate(plot_list)
        ]
        failed = plots.draw_queued(problems, 1, batches_per_worker=1) if queued else set()
        return said, failed, [(os.path.basename(p['file']), p['message']) for p in problems.items]

    said, _, alone_problems = draw(str(tmp_path / 'alone'), False)
    assert said == [True, True, False, True, True] and len(runs) == 5
    assert [f for f, _ in alone_problems] == ['2.svg'], alone_problems
    runs.clear()
    _, failed, batch_problems = draw(str(tmp_path / 'batch'), True)
    # one gnuplot for the batch; it stops at the missing file: that plot and the two after it alone
    assert len(runs) == 1 + 3, runs
    assert failed == {str(tmp_path / 'batch' / '2.svg')}
    assert batch_problems == alone_problems
    for i in (0, 1, 3, 4):
        alone, batch = (read(str(tmp_path / f / f'{i}.svg')) for f in ('alone', 'batch'))
        assert alone == batch, i
    assert sorted(os.listdir(tmp_path / 'batch')) == ['0.svg', '1.svg', '3.svg', '4.svg']  # no temporary left


@pytest.mark.skipif(not HAVE_GNUPLOT, reason='gnuplot not installed')
def test_a_plot_gnuplot_cannot_draw_is_named_and_left_off_the_page(tmp_path):
    """The pages are written while gnuplot draws, each plot named: a plot that then fails (here a
    gnuplot on PATH that refuses trend.gp, alone or in a batch) is listed as an input problem and
    the pages are written again without it, so none names a missing SVG."""
    fake = tmp_path / 'bin'
    fake.mkdir()
    (fake / 'gnuplot').write_text(
        '#!/bin/sh\nfor a; do case "$a" in *trend.gp) echo "no trends here" >&2; exit 1;; esac; done\n'
        'for a; do [ -f "$a" ] && grep -q "trend.gp" "$a" && { echo "a batch with a trend" >&2; exit 1; }; done\n'
        f'exec {shutil.which("gnuplot")} "$@"\n'
    )
    (fake / 'gnuplot').chmod(0o755)
    root = str(tmp_path / 'reports')
    make_run(root, RUN1)
    run = make_run(root, RUN2)
    hist = os.path.join(root, 'history.jsonl')
    assert run_report('--run', os.path.join(root, RUN1), '--history', hist).returncode == 0
    env = dict(os.environ, PATH=f'{fake}:{os.environ["PATH"]}')
    r = subprocess.run(
        [sys.executable, REPORT, '--run', run, '--history', hist], capture_output=True, text=True, env=env, timeout=300
    )
    assert r.returncode == 0, r.stderr
    assert 'trend-alpha.svg: gnuplot trend.gp failed: no trends here' in r.stderr, r.stderr
    plots_dir = os.path.join(run, 'plots')
    assert not os.path.exists(os.path.join(plots_dir, 'trend-alpha.svg'))
    assert os.path.exists(os.path.join(plots_dir, 'angle-alpha-ndotv.svg'))  # drawn alone after its batch failed
    pages = read(os.path.join(run, 'index.html')) + read(os.path.join(run, 'scene-alpha.html'))
    assert 'src="plots/angle-alpha-ndotv.svg"' in pages and 'src="plots/trend-' not in pages
    assert 'trend-alpha.svg' in read(os.path.join(run, 'index.html'))  # in the input problems' list


def test_latest_points_at_run(built):
    latest = os.path.join(built['root'], 'latest')
    assert os.path.islink(latest)
    assert os.readlink(latest) == RUN1  # relative, so the reports folder can move
    assert os.path.samefile(latest, built['run'])


# ------------------------------------------------------------------------- machine-readable


def test_summary_json(built):
    with open(os.path.join(built['run'], 'summary.json'), encoding='utf-8') as f:
        s = json.load(f)
    assert s['run_id'] == RUN1 and s['commit'] == 'abc1234' and s['time'] == '2025-01-01T12:00:00Z'
    assert s['counts'] == {'fail': 1, 'error': 0, 'warn': 0, 'skipped': 1, 'not_gated': 0, 'pass': 1}
    assert [x['name'] for x in s['scenes']] == ['alpha', 'beta']
    assert sum(len(x['comparisons']) for x in s['scenes']) == 3
    assert s['renderer_versions'] == {
        'cycles': 'Blender 3.4.1',
        'povray': 'POV-Ray 3.7.0.10.unofficial',
        'raster': 'reflcheck-raster 0.1',
    }
    assert s['machine']['cores'] == os.cpu_count() and s['machine']['uname']
    c = s['scenes'][0]['comparisons'][1]
    assert c['id'] == 'raster-vs-cycles-twin' and c['regions']['surface']['rel_rms'] == pytest.approx(3.4e-2)
    assert c['test_image'] == 'raster-twin' and c['reference_image'] == 'cycles-twin'
    assert s['scenes'][1]['comparisons'][0]['reference_image'] is None  # agree: cycles-validate was skipped
    assert s['problems'] == []


def test_summary_csv(built):
    with open(os.path.join(built['run'], 'summary.csv'), encoding='utf-8', newline='') as f:
        rows = list(csv.DictReader(f))
    # alpha pass: 3 regions + 1 aov x 12 metrics; alpha fail: 2 regions x 12; each +coverage;
    # noise 1 + 6 z-test figures; 5 thresholds in all; the skipped comparison has its threshold row
    assert len(rows) == 4 * 12 + 2 * 12 + 2 + 1 + 6 + 5
    th = [r for r in rows if r['group'] == 'threshold']
    assert len(th) == 5
    bad = [r for r in th if r['verdict'] == 'fail']
    assert len(bad) == 1 and bad[0]['scene'] == 'alpha' and bad[0]['comparison'] == 'raster-vs-cycles-twin'
    assert float(bad[0]['value']) == pytest.approx(3.4e-2) and float(bad[0]['fail']) == pytest.approx(1e-2)
    surf = [
        r
        for r in rows
        if r['comparison'] == 'raster-vs-povray-twin'
        and r['group'] == 'region'
        and r['name'] == 'surface'
        and r['metric'] == 'rel_rms'
    ]
    assert len(surf) == 1 and float(surf[0]['value']) == pytest.approx(1.2e-4)


def test_junit(built):
    root = ET.parse(os.path.join(built['run'], 'junit.xml')).getroot()
    assert root.tag == 'testsuites'
    assert (root.get('tests'), root.get('failures'), root.get('errors'), root.get('skipped')) == ('5', '1', '0', '1')
    suites = root.findall('testsuite')
    assert [t.get('name') for t in suites] == ['alpha', 'beta']
    assert len(suites[0].findall('testcase')) == 4
    fails = root.findall('.//failure')
    assert len(fails) == 1
    msg = fails[0].get('message')
    assert msg == 'alpha: raster-vs-cycles-twin: rel_rms 3.40e-2 > 1e-2 (Monte Carlo noise budget)'
    assert len(root.findall('.//skipped')) == 1


def test_figures_md_of_the_run(built):
    """figures.md carries the run's own numbers: the README copies it, never retypes."""
    md = read(os.path.join(built['run'], 'figures.md'))
    assert md.startswith(f'# Figures of run {RUN1}\n')
    assert '| alpha | povray | all | 1.20e-04 | — | — | pass |' in md
    # the Cycles twin's z-test: 3 pixels of the 36 surface pixels beyond the noise
    # ... and the crease pixels compare moved out of the surface, carried through summary.json
    assert '| alpha | cycles | all | 0.034 | 3 of 36 (8.33 %); 2 crease px apart | — | fail |' in md


def test_figures_md_validate_partial_and_fit():
    """Worked by hand: a partial twin names its left-out term, a validate shows its robust
    figures and physics, a fit its two error cells and the value at a bound."""
    surface = {
        'n_pixels': 200,
        'nrmse': 0.1581,
        'nrmse_trim1': 0.137,
        'worst1_share': 0.26,
        'rel_median': 0.046,
        'rel_p95': 0.31,
        'rel_rms': 0.2,
    }
    S = {
        'run_id': 'r1',
        'commit': 'c0ffee1',
        'time': 't',
        'machine': {'cores': 2},
        'renderer_versions': {'cycles': 'Blender 3.4.1'},
        'scenes': [
            {
                'name': 'blinn',
                'jobs': [{'renderer': 'raster', 'width': 96, 'height': 72}],
                'comparisons': [
                    {
                        'role': 'twin',
                        'test': 'raster',
                        'reference': 'cycles',
                        'status': 'pass',
                        'regions': {'surface': {'n_pixels': 200, 'rel_rms': 0.01}},
                        'noise': {'ztest': {'n_fail_pixels': 1}},
                        'crease': {'pixels': 12, 'share_of_surface': 0.057},
                        'terms_left_out': [{'term': 'specular', 'reason': 'no Blinn lobe'}],
                    },
                    {
                        'role': 'validate',
                        'test': 'raster',
                        'reference': 'exact',
                        'status': 'pass',
                        'physics': 'bounces=1',
                        'regions': {'surface': surface},
                        'terms': {
                            'diffuse': {'test_mean': 0.5, 'ref_mean': 0.48, 'nrmse': 0.152},
                            'glossy': {'test_mean': 0, 'ref_mean': 0, 'nrmse': 0},
                        },
                    },
                ],
            }
        ],
        'fits': [
            {
                'scene': 'blinn',
                'reference': 'exact',
                'bounds': 'seed',
                'status': 'ok',
                'authored': {'nrmse': 0.158, 'median_rel': 0.047, 'nrmse_trim1': 0.137, 'worst1_share': 0.26},
                'best': {'nrmse': 0.152, 'median_rel': 0.045, 'nrmse_trim1': 0.13, 'worst1_share': 0.22},
                'parameters': [{'material': 'plastic', 'name': 'P', 'fitted': 43.3, 'at_bound': True}],
            }
        ],
    }
    md = figures.figures_md(S)
    # the crease pixels compare moved out of the surface are named beside the z-test
    assert (
        '| blinn | cycles | partial: specular left out | 0.01 | 1 of 200 (0.5 %); 12 crease px apart | — | pass |' in md
    )
    assert '| blinn | raster vs exact | 0.158 | 0.137 | 26 % | 4.6 % | 31 % | — | pass |' in md
    assert '- blinn: the defaults' in md  # bounces=1 is the default
    assert '| blinn | raster vs exact | diffuse | 0.5 | 0.48 | 0.152 |' in md
    assert 'glossy' not in md  # a term both sides left at zero is not a figure
    assert (
        '| blinn | exact | seed | 0.158, 4.7 %, 0.137, 26 % | 0.152, 4.5 %, 0.13, 22 % | plastic.P = 43.3 (b) |' in md
    )
    assert '- blinn: 96 × 72' in md


# --------------------------------------------------------------------------------- history


def test_history_append_only_survives_crash(tmp_path):
    root = str(tmp_path)
    hist = os.path.join(root, 'history.jsonl')
    r = run_report('--run', make_run(root, RUN1), '--history', hist)
    assert r.returncode == 0, r.stderr
    with open(hist, 'rb') as f:
        one = f.read()
    assert one.count(b'\n') == 1 and one.endswith(b'\n')

    r = run_report('--run', make_run(root, RUN2, rel_scale=2.0), '--history', hist)
    assert r.returncode == 0, r.stderr
    with open(hist, 'rb') as f:
        two = f.read()
    assert two.startswith(one) and two.count(b'\n') == 2

    # a run killed in the middle of its write: a partial line without a newline
    with open(hist, 'ab') as f:
        f.write(b'{"run_id":"20250102-130000-dead","commit":"dead","metrics":{"alpha":{"raster-vs')
    r = run_report('--run', make_run(root, RUN3, rel_scale=0.5), '--history', hist)
    assert r.returncode == 0, r.stderr
    assert 'history.jsonl:3' in r.stderr and 'skipped' in r.stderr
    with open(hist, 'rb') as f:
        data = f.read()
    assert data.startswith(two)  # earlier records byte-for-byte intact
    lines = data.split(b'\n')
    assert len(lines) == 5 and lines[-1] == b''  # 2 good, 1 broken, 1 new, final newline
    recs = history.read_history(hist)
    assert [x['run_id'] for x in recs] == [RUN1, RUN2, RUN3]
    assert recs[1]['metrics']['alpha']['raster-vs-povray-twin']['surface.rel_rms'] == pytest.approx(2.4e-4)
    assert recs[2]['metrics']['alpha']['raster-vs-cycles-twin']['status'] == 'fail'

    # the same run reported again adds nothing
    r = run_report('--run', os.path.join(root, RUN3), '--history', hist)
    assert r.returncode == 0 and 'not appended again' in r.stderr
    with open(hist, 'rb') as f:
        assert f.read() == data

    # the trend plot now has the three good runs, and the broken line is listed on the page
    if HAVE_GNUPLOT:
        svg = read(os.path.join(root, RUN3, 'plots', 'trend-alpha.svg'))
        for commit in ('abc1234', 'def5678', '0a1b2c3'):
            assert commit in svg
    assert 'history line skipped' in read(os.path.join(root, RUN3, 'index.html'))


# ---------------------------------------------------------------------------- bad inputs


def test_corrupt_compare_json_is_an_error_entry(tmp_path):
    run = make_run(str(tmp_path), RUN1)
    with open(os.path.join(run, 'beta', 'compare.json'), 'w') as f:
        f.write('{"scene": "beta", "comparisons": [{"id": "povray-vs')
    os.remove(os.path.join(run, 'alpha', 'view.js'))
    with open(os.path.join(run, 'alpha', 'povray-twin.json'), 'w') as f:
        f.write('not json')
    r = run_report('--run', run)
    assert r.returncode == 0, r.stderr
    assert 'beta/compare.json: compare.json corrupt' in r.stderr
    assert 'alpha/view.js: view.js missing' in r.stderr
    assert 'alpha/povray-twin.json: job record corrupt' in r.stderr
    with open(os.path.join(run, 'summary.json'), encoding='utf-8') as f:
        s = json.load(f)
    beta = s['scenes'][1]['comparisons']
    assert len(beta) == 1 and beta[0]['status'] == 'error' and 'compare.json corrupt' in beta[0]['reason']
    assert s['counts']['error'] == 1 and len(s['problems']) == 3
    html = read(os.path.join(run, 'index.html'))
    assert 'Input problems (3)' in html and summary_rows(html)[0][1] == 'fail'
    assert summary_rows(html)[1][1:] == ('error', '(compare.json)')
    root = ET.parse(os.path.join(run, 'junit.xml')).getroot()
    assert root.get('errors') == '1'
    assert 'view.js is missing or corrupt' in read(os.path.join(run, 'scene-alpha.html'))


def test_view_js_with_wrong_image_size_is_reported(tmp_path):
    run = make_run(str(tmp_path), RUN1)
    p = os.path.join(run, 'alpha', 'view.js')
    text = read(p).replace('"width": 8', '"width": 9')
    with open(p, 'w') as f:
        f.write(text)
    r = run_report('--run', run)
    assert r.returncode == 0
    assert 'view.js image "raster-twin" has 576 bytes, expected 9x6x3 float32 = 648' in r.stderr


def test_missing_run_folder_is_usage_error(tmp_path):
    r = run_report('--run', os.path.join(str(tmp_path), 'nope'))
    assert r.returncode == 2 and 'no such run folder' in r.stderr


# ------------------------------------------------------------------------- thresholds


@pytest.mark.parametrize(
    'v,want',
    [
        (2.4e-4, 3e-4),
        (3e-4, 3e-4),
        (4.8e-4, 5e-4),
        (9.5e-3, 1e-2),
        (0.136, 0.2),
        (0.068, 0.07),
        (41.0, 50.0),
        (1.0, 1.0),
    ],
)
def test_round_up_1sig(v, want):
    assert proposal.round_up_1sig(v) == pytest.approx(want, rel=1e-12)


def test_propose_thresholds(tmp_path):
    run = make_run(str(tmp_path), RUN1)
    digest = hashlib.sha256(read(os.path.join(run, 'alpha', 'compare.json')).encode()).hexdigest()
    r = run_report('--propose-thresholds', '--run', run)
    assert r.returncode == 0, r.stderr
    out = r.stdout
    assert '--- scenes/alpha.yaml' in out and '+++ scenes/alpha.yaml' in out
    # 3.4e-2 measured: 2x = 6.8e-2 -> 7e-2, 4x = 0.136 -> 0.2
    assert '-      rel_rms: {warn: 5e-3, fail: 1e-2, why: "Monte Carlo noise budget"}' in out
    assert '+      rel_rms: {warn: 7e-2, fail: 0.2, why: "Monte Carlo noise budget"}' in out
    # 2e-2 -> 4e-2 / 8e-2
    assert '+      z_fail_share: {warn: 4e-2, fail: 8e-2' in out
    # PSNR 78.4 dB: -6.02 dB -> 72, -12.04 dB -> 66
    assert '+      psnr: {warn: 72, fail: 66' in out
    # 1.2e-4 measured would give 3e-4 / 5e-4, but the precision floor 4.9e-4 raises warn to 5e-4
    # and fail to 2 x 5e-4: equal to the current line, so it is unchanged (leading space)
    assert re.search(r'^ {7}rel_rms: \{warn: 5e-4, fail: 1e-3.*raised to the precision floor', out, re.M)
    # skipped comparison: no measurement, unchanged
    assert re.search(r'^ {7}rel_rms: \{warn: 2e-2, fail: 5e-2.*no measurement', out, re.M)
    page = read(os.path.join(run, 'thresholds-proposal.html'))
    assert 'Threshold proposal' in page and 'class="d add"' in page
    assert hashlib.sha256(read(os.path.join(run, 'alpha', 'compare.json')).encode()).hexdigest() == digest
    assert not os.path.exists(os.path.join(run, 'index.html'))  # proposal mode writes nothing else


# ------------------------------------------------------------------------ headless browser


def body_attrs(dom):
    m = re.search(r'<body([^>]*)>', dom)
    assert m, dom[:500]
    return dict(re.findall(r'([\w-]+)="([^"]*)"', m.group(1)))


@pytest.mark.skipif(not HAVE_CHROMIUM, reason='chromium not installed (apt-get install chromium)')
def test_index_renders_in_chromium(built):
    page = os.path.join(built['run'], 'index.html')
    n_img = read(page).count('<img ')
    dom = browser.dump_dom(page)
    a = body_attrs(dom)
    assert a.get('data-ready') == '1', a
    assert a.get('data-loaded') == f'{n_img}/{n_img}' and a.get('data-failed') == '0', (
        a,
        re.findall(r'<li>[^<]*', dom),
    )
    assert len(summary_rows(dom)) == 3
    assert '3 of 3 comparisons shown' in dom
    assert re.search(r'<section id="load-status" class="problems" hidden', dom)


@pytest.mark.skipif(not HAVE_CHROMIUM, reason='chromium not installed (apt-get install chromium)')
def test_scene_page_renders_in_chromium(built):
    page = os.path.join(built['run'], 'scene-alpha.html')
    html = read(page)
    n = html.count('class="view"') + html.count('<img ')
    assert n == 3 + 1 + 2 + (3 if HAVE_GNUPLOT else 0)  # images, flip, heatmaps, plots
    dom = browser.dump_dom(page)
    a = body_attrs(dom)
    assert a.get('data-ready') == '1' and a.get('data-loaded') == f'{n}/{n}' and a.get('data-failed') == '0', (
        a,
        re.findall(r'<li>[^<]*', dom),
    )
    # the probe shows the centre pixel (4, 3) of every image: raster R = 0.05 + 0.1 * 4
    assert '(4, 3)' in dom and '<td>raster-twin</td><td>0.45000</td>' in dom
    assert 'EV +0.00' in dom


@pytest.mark.skipif(not HAVE_CHROMIUM, reason='chromium not installed (apt-get install chromium)')
def test_missing_view_js_is_reported_by_the_page(tmp_path):
    run = make_run(str(tmp_path), RUN1)
    assert run_report('--run', run).returncode == 0
    os.remove(os.path.join(run, 'alpha', 'view.js'))  # removed after the page was written
    dom = browser.dump_dom(os.path.join(run, 'scene-alpha.html'))
    a = body_attrs(dom)
    assert a.get('data-ready') == '1' and a.get('data-failed') == '6', a
    assert 'alpha/view.js did not load' in dom


@pytest.mark.skipif(not HAVE_CHROMIUM, reason='chromium not installed (apt-get install chromium)')
def test_screenshot_option(tmp_path):
    run = make_run(str(tmp_path), RUN1)
    r = run_report('--run', run, '--screenshot')
    assert r.returncode == 0, r.stderr
    for name, size in (('screenshot.png', (1400, 1000)), ('screenshot-scene.png', (1400, 1400))):
        with open(os.path.join(run, name), 'rb') as f:
            head = f.read(24)
        assert head[:8] == b'\x89PNG\r\n\x1a\n'
        assert struct.unpack('>II', head[16:24]) == size


@pytest.mark.skipif(not HAVE_CHROMIUM, reason='chromium not installed (apt-get install chromium)')
def test_one_browser_checks_each_page_on_its_own_dom(tmp_path):
    """The report's check opens every page in one Chromium, one to three tabs at a time: a broken
    page is named whichever page came before it or loads beside it, and a good page after a
    broken one is not blamed for it. A screenshot the check takes of a page as it loads it, beside
    the other tabs, has the bytes of one taken of that page alone."""
    run = make_run(str(tmp_path), RUN1)
    assert run_report('--run', run).returncode == 0
    os.remove(os.path.join(run, 'alpha', 'view.js'))  # the scene page's images cannot draw
    pages = ['index.html', 'scene-alpha.html', 'scene-beta.html', 'index.html']
    with browser.Browser() as b:
        b.screenshot(os.path.join(run, 'scene-beta.html'), os.path.join(run, 'alone.png'), (700, 500))
        for tabs in (1, 2, 3):
            shot = os.path.join(run, f'beta-{tabs}.png')
            bad = b.check_pages(run, pages, tabs, shots={'scene-beta.html': (shot, (700, 500))})
            assert [p for p, _ in bad] == ['scene-alpha.html'], (tabs, bad)
            assert 'failed 6' in bad[0][1], (tabs, bad)
            with open(shot, 'rb') as f, open(os.path.join(run, 'alone.png'), 'rb') as g:
                assert f.read() == g.read(), tabs
        b.screenshot(os.path.join(run, 'index.html'), os.path.join(run, 'shot.png'), (640, 480))
    with open(os.path.join(run, 'shot.png'), 'rb') as f:
        head = f.read(24)
    assert struct.unpack('>II', head[16:24]) == (640, 480)


INTERACT = r'''<script>
(function () {
  function px(cv, x, y) { return Array.prototype.slice.call(cv.getContext('2d').getImageData(x, y, 1, 1).data, 0, 3); }
  function at(cv, type, ix, iy, extra) {
    /* client position of the centre of display pixel (ix, iy) of the canvas */
    var r = cv.getBoundingClientRect(), s = r.width / cv.width;
    var o = Object.assign({ bubbles: true, cancelable: true, clientX: r.left + (ix + 0.5) * s,
                            clientY: r.top + (iy + 0.5) * s }, extra || {});
    cv.dispatchEvent(type === 'wheel' ? new WheelEvent(type, o) : new MouseEvent(type, o));
  }
  function run() {
    var cvs = document.querySelectorAll('canvas.view'), raster = cvs[0], flip = document.querySelector('canvas[data-layer=flip]');
    var out = {}, fit = raster.width / 8;
    out.before = px(raster, 1, 1);
    at(raster, 'mousemove', Math.floor(2.5 * fit), Math.floor(1.5 * fit));
    out.probe = document.getElementById('probe-xy').textContent;
    at(raster, 'wheel', 0, 0, { deltaY: -100 });  /* zoom x1.25 about the top-left corner */
    at(raster, 'wheel', 0, 0, { deltaY: -100 });
    out.zoomedEdge = [px(raster, Math.floor(fit * 1.5625) - 1, 5), px(raster, Math.floor(fit * 1.5625) + 1, 5)];
    out.sameAsFlip = JSON.stringify(raster.getContext('2d').getImageData(0, 0, raster.width, raster.height).data.slice(0, 4000))
      === JSON.stringify(flip.getContext('2d').getImageData(0, 0, flip.width, flip.height).data.slice(0, 4000));
    var ev = document.getElementById('ev');
    var dark = px(raster, 5, 5);
    ev.value = '2'; ev.dispatchEvent(new Event('input'));
    out.ev = [dark, px(raster, 5, 5), document.getElementById('ev-label').textContent];
    document.dispatchEvent(new KeyboardEvent('keydown', { key: 'f', bubbles: true }));
    out.flip = document.getElementById('flip-shown').textContent;
    document.body.setAttribute('data-test', JSON.stringify(out));
  }
  function wait() { if (document.body.getAttribute('data-ready') === '1') run(); else setTimeout(wait, 20); }
  wait();
})();
</script>
'''


@pytest.mark.skipif(not HAVE_CHROMIUM, reason='chromium not installed (apt-get install chromium)')
def test_viewer_interactions_in_chromium(built):
    """Synthetic events on the real page: probe, shared zoom, exposure, flip."""
    src = read(os.path.join(built['run'], 'scene-alpha.html'))
    test_page = os.path.join(built['run'], 'scene-alpha-interact.html')
    with open(test_page, 'w', encoding='utf-8') as f:
        f.write(src.replace('</body>', INTERACT + '</body>'))
    dom = browser.dump_dom(test_page)
    os.remove(test_page)
    m = re.search(r'data-test="([^"]*)"', dom)
    assert m, body_attrs(dom)
    out = json.loads(m.group(1).replace('&quot;', '"'))
    assert out['probe'] == '(2, 1)'
    # after two x1.25 zooms about the corner an image pixel spans 1.5625 fit pixels: the edge between
    # image columns 0 and 1 moved from fit to 1.5625 fit, and both sides differ (R steps by 0.1)
    assert out['zoomedEdge'][0] != out['zoomedEdge'][1]
    assert out['sameAsFlip'] is True  # the flip view (A = raster-twin) shares the zoom
    dark, bright, label = out['ev']
    assert label.startswith('EV +2.00') and all(b > d for b, d in zip(bright, dark))
    assert out['flip'] == 'povray-twin (B)'


# ------------------------------------------------------------------ run status and hostile names


def test_run_status_recorded(tmp_path):
    """A run with a failing comparison is 'fail'; a crashed job makes the next run 'error', which is
    recorded as such in the history and summary.json and left out of the trends."""
    root = str(tmp_path)
    hist = os.path.join(root, 'history.jsonl')
    r = run_report('--run', make_run(root, RUN1), '--history', hist)
    assert r.returncode == 0, r.stderr
    run2 = make_run(root, RUN2, rel_scale=2.0)
    rec_path = os.path.join(run2, 'alpha', 'povray-twin.json')
    rec = json.loads(read(rec_path))
    rec.update(status='crashed', message='povray crashed (signal 11)', exr='')
    with open(rec_path, 'w', encoding='utf-8') as f:
        json.dump(rec, f)
    r = run_report('--run', run2, '--history', hist)
    assert r.returncode == 0, r.stderr
    recs = history.read_history(hist)
    assert [h['status'] for h in recs] == ['fail', 'error']
    assert json.loads(read(os.path.join(run2, 'summary.json')))['status'] == 'error'
    assert re.search(r'run status <span class="badge v-error">error</span>', read(os.path.join(run2, 'index.html')))
    R = load.load_run(run2)
    assert load.run_status(R) == 'error'
    # the errored run's figures are no trend: only RUN1 is eligible, and one point draws no trend line
    recs = history.read_history(hist)
    assert [h['run_id'] for h in recs if h.get('status') != 'error'] == [RUN1]


def test_fit_files_are_not_job_records(tmp_path):
    """fit-wide.json has a job record's name shape (renderer-role.json); read as one, it had no
    status and turned every nightly with a fit step into an 'error' run."""
    run = make_run(str(tmp_path), RUN1)
    for fname, bounds in (('fit.json', 'seed'), ('fit-wide.json', 'wide')):
        with open(os.path.join(run, 'alpha', fname), 'w', encoding='utf-8') as f:
            json.dump({'scene': 'alpha', 'bounds': bounds, 'fits': []}, f)
    r = run_report('--run', run)
    assert r.returncode == 0, r.stderr
    s = json.loads(read(os.path.join(run, 'summary.json')))
    assert not [j['file'] for sc in s['scenes'] for j in sc['jobs'] if j['file'].startswith('fit')]
    assert s['status'] == 'fail'  # the fixture's failing comparison, as without the fit files


def test_run_with_nothing_compared_is_error(tmp_path):
    run = make_run(str(tmp_path), RUN1)
    for scene in ('alpha', 'beta'):
        with open(os.path.join(run, scene, 'compare.json'), 'w', encoding='utf-8') as f:
            json.dump({'scene': scene, 'comparisons': []}, f)
    assert load.run_status(load.load_run(run)) == 'error'


def test_json_script_has_no_markup():
    text = util.json_script({'scene': '<!--<script>', 'x': '</script><b>&amp;'})
    assert not set('<>&') & set(text)
    assert json.loads(text) == {'scene': '<!--<script>', 'x': '</script><b>&amp;'}


@pytest.mark.skipif(not HAVE_CHROMIUM, reason='chromium not installed (apt-get install chromium)')
def test_hostile_scene_name_page_loads(tmp_path):
    """A scene folder named after a file like '<!--<script>.yaml': its page still runs report.js
    and loads every image (an unescaped '<!--<script>' in the inline JSON swallowed the page script)."""
    run = make_run(str(tmp_path), RUN1)
    hostile = '<!--<script>'
    os.rename(os.path.join(run, 'alpha'), os.path.join(run, hostile))
    r = run_report('--run', run)
    assert r.returncode == 0, r.stderr
    page = os.path.join(run, f'scene-{util.safe_name(hostile)}.html')
    html = read(page)
    n = html.count('class="view"') + html.count('<img ')
    dom = browser.dump_dom(page)
    a = body_attrs(dom)
    assert a.get('data-ready') == '1' and a.get('data-loaded') == f'{n}/{n}' and a.get('data-failed') == '0', (
        a,
        re.findall(r'<li>[^<]*', dom),
    )


# ------------------------------------------------------------------ templates and shared names

TOOLS = os.path.join(ROOT, 'tools')


def test_no_hand_escaping_in_the_package():
    """Pages come from Jinja2 templates with autoescape on: no Python module escapes HTML by hand,
    and no template switches escaping off. json_script (inline <script> JSON) is the one exception."""
    for d, _, files in os.walk(os.path.join(TOOLS, 'report')):
        for f in files:
            text = read(os.path.join(d, f))
            assert 'html.escape' not in text and 'esc(' not in text, f
            assert '|safe' not in text and 'autoescape false' not in text, f
    assert 'import report' not in ''.join(
        read(os.path.join(TOOLS, 'report', f)) for f in os.listdir(os.path.join(TOOLS, 'report')) if f.endswith('.py')
    )


def test_hostile_text_is_escaped(tmp_path):
    """Text from the run's files lands escaped in element text and attributes."""
    run = make_run(str(tmp_path), RUN1)
    p = os.path.join(run, 'alpha', 'compare.json')
    comp = json.loads(read(p))
    comp['title'] = '<b>bold</b> & "quoted"'
    comp['comparisons'][1]['reason'] = '<img src=x onerror=alert(1)>'
    comp['comparisons'][1]['thresholds'][0]['why'] = '"><script>alert(2)</script>'
    with open(p, 'w', encoding='utf-8') as f:
        json.dump(comp, f)
    assert run_report('--run', run).returncode == 0
    for page in ('index.html', 'scene-alpha.html'):
        html = read(os.path.join(run, page))
        assert '<img src=x' not in html and '<script>alert' not in html, page
        assert '&lt;img src=x onerror=alert(1)&gt;' in html
    scene = read(os.path.join(run, 'scene-alpha.html'))
    assert '&lt;b&gt;bold&lt;/b&gt; &amp; &#34;quoted&#34;' in scene
    assert 'title="&#34;&gt;&lt;script&gt;alert(2)&lt;/script&gt;"' in read(os.path.join(run, 'index.html'))


def test_ids_come_from_one_file(built):
    """report.js spells no element id or data attribute: it takes them from window.REFLCHECK_IDS,
    which every page embeds from report_assets/ids.json, the file the templates use."""
    with open(os.path.join(TOOLS, 'report_assets', 'ids.json'), encoding='utf-8') as f:
        ids = json.load(f)
    ids.pop('_doc')
    js = read(os.path.join(TOOLS, 'report_assets', 'report.js'))
    code = re.sub(r'/\*.*?\*/', '', js, flags=re.S)
    assert 'getElementById(\'' not in code and not re.search(r"'data-[a-z]", code)
    for key in re.findall(r"\bel\('(\w+)'\)", code):
        assert key in ids['id'], key
    for page in ['index.html', 'scene-alpha.html', 'scene-beta.html']:
        html = read(os.path.join(built['run'], page))
        m = re.search(r'<script>window\.REFLCHECK_IDS = (.*?);</script>', html)
        assert m and json.loads(m.group(1)) == ids, page
    # every element id report.js looks up is on a page that needs it
    index, scene = (read(os.path.join(built['run'], p)) for p in ('index.html', 'scene-alpha.html'))
    for key, name in ids['id'].items():
        assert f'id="{name}"' in index + scene, key


def test_renderers_come_from_the_run(tmp_path):
    """No renderer list in the report: a renderer it has never heard of ('eevee') is shown and
    compared like the others, from its job record, its view.js image and the comparison."""
    run = make_run(str(tmp_path), RUN1)
    alpha = os.path.join(run, 'alpha')
    rec = json.loads(read(os.path.join(alpha, 'cycles-twin.json')))
    rec.update(renderer='eevee', version='Blender 3.4.1 EEVEE', wall_s=0.7)
    with open(os.path.join(alpha, 'eevee-twin.json'), 'w', encoding='utf-8') as f:
        json.dump(rec, f)
    comp = json.loads(read(os.path.join(alpha, 'compare.json')))
    c = dict(comp['comparisons'][0], id='raster-vs-eevee-twin', reference='eevee')
    comp['comparisons'].append(c)
    with open(os.path.join(alpha, 'compare.json'), 'w', encoding='utf-8') as f:
        json.dump(comp, f)
    view = read(os.path.join(alpha, 'view.js'))
    m = re.search(r'"povray-twin": ("[^"]*")', view)
    with open(os.path.join(alpha, 'view.js'), 'w', encoding='utf-8') as f:
        f.write(view.replace('"images": {', '"images": {"eevee-twin": ' + m.group(1) + ', ', 1))
    assert run_report('--run', run).returncode == 0
    s = json.loads(read(os.path.join(run, 'summary.json')))
    assert s['renderer_versions']['eevee'] == 'Blender 3.4.1 EEVEE'
    c = next(x for x in s['scenes'][0]['comparisons'] if x['id'] == 'raster-vs-eevee-twin')
    assert (c['test_image'], c['reference_image']) == ('raster-twin', 'eevee-twin')
    index = read(os.path.join(run, 'index.html'))
    assert '<td>eevee</td><td>twin</td>' in index and '<span class="mono">0.70</span>' in index
    scene = read(os.path.join(run, 'scene-alpha.html'))
    assert 'data-layer="heat:raster-vs-eevee-twin"' in scene and 'data-layer="img:eevee-twin"' in scene


def test_sweep_columns_come_from_the_sweep(tmp_path):
    """The equal-time table has a column per renderer the sweep file names, in its order."""
    run = make_run(str(tmp_path), RUN1)
    sweep = {
        'format': 'reflcheck-sweep-1',
        'scene': 'alpha',
        'size': [8, 6],
        'error_key': 'error',
        'reference': {'renderer': 'cycles', 'role': 'twin', 'samples': 4096},
        'series': [
            {'label': 'eevee taa', 'renderer': 'eevee', 'points': [{'label': '16 taa', 'time_s': 0.5, 'error': 0.01}]}
        ],
        'equal_time': [
            {
                'budget': '1 s',
                'budget_s': 1.0,
                'best': {'raster': None, 'eevee': {'label': '16 taa', 'time_s': 0.5, 'error': 0.01}},
            }
        ],
    }
    with open(os.path.join(run, 'timing', 'alpha.json'), 'w', encoding='utf-8') as f:
        json.dump(sweep, f)
    assert run_report('--run', run).returncode == 0
    html = read(os.path.join(run, 'index.html'))
    assert '<th>budget</th><th>raster</th><th>eevee</th><th>Cycles (fit)</th>' in html
    assert 'reference: cycles twin 4096 spp' in html and '16 taa, 0.5 s' in html


def test_stylesheet_ids_are_on_the_pages(built):
    """report.css cannot read ids.json: every #id its selectors name must be one the pages carry."""
    css = re.sub(r'/\*.*?\*/', '', read(os.path.join(TOOLS, 'report_assets', 'report.css')), flags=re.S)
    names = {n for sel in re.findall(r'([^{}]*)\{', css) for n in re.findall(r'#([A-Za-z][\w-]*)', sel)}
    pages = ''.join(read(os.path.join(built['run'], p)) for p in ('index.html', 'scene-alpha.html'))
    assert names and all(f'id="{n}"' in pages for n in names), names


def test_partial_twin_terms_shown(tmp_path):
    """A partial twin's compared and left-out terms reach summary.json and the scene page."""
    run = make_run(str(tmp_path), RUN1)
    cpath = os.path.join(run, 'alpha', 'compare.json')
    comp = json.loads(read(cpath))
    c = comp['comparisons'][1]
    c['terms_compared'] = ['diffuse', 'reflection', 'emission']
    c['terms_left_out'] = [{'term': 'specular', 'reason': 'cycles: Cycles has no Blinn-Phong lobe'}]
    with open(cpath, 'w', encoding='utf-8') as f:
        json.dump(comp, f)
    r = run_report('--run', run)
    assert r.returncode == 0, r.stderr
    summ = json.loads(read(os.path.join(run, 'summary.json')))
    got = summ['scenes'][0]['comparisons'][1]
    assert got['terms_left_out'] == c['terms_left_out'] and got['terms_compared'] == c['terms_compared']
    assert 'terms_left_out' not in summ['scenes'][0]['comparisons'][0]
    page = read(os.path.join(run, 'scene-alpha.html'))
    assert re.search(
        r'partial twin: compared <span class="mono">diffuse, reflection, emission</span>;\s*left out '
        r'<span class="mono">specular</span> \(cycles: Cycles has no Blinn-Phong lobe\)',
        page,
    )


def test_physics_robust_and_terms_shown(tmp_path):
    """A validate's physics manifest, its robust figures and its error by term reach the index,
    the scene page, summary.json and summary.csv."""
    run = make_run(str(tmp_path), RUN1)
    cpath = os.path.join(run, 'alpha', 'compare.json')
    comp = json.loads(read(cpath))
    c = comp['comparisons'][1]
    physics = 'diffuse_lights=all specular_lights=all env_diffuse=0 env_specular=1 bounces=1'
    c['physics'] = physics
    c['regions']['surface'].update({'nrmse': 0.75, 'nrmse_trim1': 0.25, 'worst1_share': 0.875, 'rel_median': 0.0625})
    c['terms'] = {'diffuse': {'test_mean': 0.032, 'ref_mean': 0.06, 'nrmse': 0.5, 'n_pixels': 10}}
    with open(cpath, 'w', encoding='utf-8') as f:
        json.dump(comp, f)
    r = run_report('--run', run)
    assert r.returncode == 0, r.stderr
    page = read(os.path.join(run, 'scene-alpha.html'))
    assert f'<span class="mono physics">{physics}</span>' in page
    assert re.search(r'<td class="dim">term</td><td>diffuse</td>', page)
    index = read(os.path.join(run, 'index.html'))
    assert f'title="physics: {physics}"' in index
    assert '87.5%' in index  # worst 1 % share
    summ = json.loads(read(os.path.join(run, 'summary.json')))
    got = summ['scenes'][0]['comparisons'][1]
    assert got['physics'] == physics and got['terms'] == c['terms']
    assert got['regions']['surface']['nrmse_trim1'] == 0.25
    with open(os.path.join(run, 'summary.csv'), encoding='utf-8') as f:
        rows = list(csv.DictReader(f))
    mine = [x for x in rows if x['comparison'] == c['id']]
    assert any(x['group'] == 'term' and x['name'] == 'diffuse' and x['metric'] == 'ref_mean' for x in mine)
    assert any(x['metric'] == 'physics' and x['value'] == physics for x in mine)
    assert any(x['metric'] == 'worst1_share' and float(x['value']) == 0.875 for x in mine)


def test_fit_table(tmp_path):
    """A scene's fit.json (reflcheck fit) becomes a row of the index's fit table and of
    summary.json: as-authored and best-fit NRMSE and median, the fitted values with their bound
    flag; an errored fit shows its reason; a corrupt record is a problem, not a crash."""
    run = make_run(str(tmp_path), RUN1)
    fit = {
        'scene': 'alpha',
        'variant': 'small',
        'fits': [
            {
                'id': 'raster-vs-povray-validate',
                'reference': 'povray',
                'status': 'ok',
                'authored': {
                    'nrmse': 0.8887,
                    'median_rel': 0.2254,
                    'nrmse_trim1': 0.5125,
                    'worst1_share': 0.6625,
                    'n_pixels': 2774,
                },
                'best': {'nrmse': 0.4248, 'median_rel': 0.04528, 'nrmse_trim1': 0.1875, 'worst1_share': 0.8125},
                'parameters': [
                    {'material': 'glass', 'name': 'p', 'authored': 3, 'fitted': 3.5, 'at_bound': True},
                    {'material': 'glass', 'name': 'r0', 'authored': 0.04, 'fitted': 0.04053, 'at_bound': False},
                ],
                'evaluations': 33,
                'seconds': 2.1,
                'stop': 'converged: x tolerance reached',
            },
            {'id': 'raster-vs-cycles-validate', 'status': 'error', 'reason': 'cycles validate job failed: boom'},
        ],
    }
    with open(os.path.join(run, 'alpha', 'fit.json'), 'w', encoding='utf-8') as f:
        json.dump(fit, f)
    wide = dict(fit, bounds='wide', fits=[dict(fit['fits'][0], best={'nrmse': 0.2071, 'median_rel': 0.03})])
    with open(os.path.join(run, 'alpha', 'fit-wide.json'), 'w', encoding='utf-8') as f:
        json.dump(wide, f)
    with open(os.path.join(run, 'beta', 'fit.json'), 'w', encoding='utf-8') as f:
        f.write('{"fits": 3}')
    r = run_report('--run', run)
    assert 'fit.json has no "fits" list' in r.stderr
    html = read(os.path.join(run, 'index.html'))
    table = html.split('<section id="fit">', 1)[1].split('</section>', 1)[0]
    assert re.search(
        r'raster-vs-povray-validate</td><td>seed</td><td>ok</td>\s*<td class="num"><span class="mono">0\.8887<', table
    )
    assert re.search(
        r'raster-vs-povray-validate</td><td>wide</td><td>ok</td>\s*<td.*?>0\.8887<.*?>0\.2071<', table, re.S
    )
    assert '>0.4248<' in table and '>0.2254<' in table and '>0.04528<' in table
    assert '0.5125 → 0.1875' in table and '0.6625 → 0.8125' in table
    assert 'glass.p 3 → 3.5 (at bound)' in table and 'glass.r0 0.04 → 0.04053<' in table
    assert 'cycles validate job failed: boom' in table
    summ = json.loads(read(os.path.join(run, 'summary.json')))
    assert [(f['id'], f['bounds']) for f in summ['fits']] == [
        ('raster-vs-povray-validate', 'seed'),
        ('raster-vs-cycles-validate', 'seed'),
        ('raster-vs-povray-validate', 'wide'),
    ]
    assert summ['fits'][0]['best']['nrmse'] == 0.4248


# ------------------------------------------------------------------------- Figure 1 of a scene

FIG1_SCENE = """name: alpha
image: {width: 16, height: 16}
camera: {eye: [0, 0, 4], target: [0, 0, 0], hfov: 40}
materials:
  glass: {albedo: [0, 0, 0], ior: 1.5, roughness: 0, model: d3d9client, d3d9client: {p: 4, r0: 0.05}}
  plastic: {albedo: [0.5, 0.5, 0.5], ior: 1.33, model: d3d, d3d: {specular: [0.2, 0.3, 0.4], power: 20}}
objects:
  - {shape: sphere, center: [0, 0, 0], radius: 1, material: glass}
  - {shape: sphere, center: [1.5, 0, 0], radius: 0.5, material: plastic}
"""


def fresnel_dielectric(cos_i, n):
    """Unpolarised Fresnel reflectance from Snell's law and the s and p amplitudes (Hecht 4.42-4.43)."""
    sin_t = math.sqrt(1 - cos_i * cos_i) / n
    cos_t = math.sqrt(1 - sin_t * sin_t)
    rs = (cos_i - n * cos_t) / (cos_i + n * cos_t)
    rp = (n * cos_i - cos_t) / (n * cos_i + cos_t)
    return (rs * rs + rp * rp) / 2


def test_figure1_of_a_scenes_own_materials(tmp_path):
    """`reflcheck eval materials` writes the scene's figure1.json; the report draws one model curve
    and one physics curve per material on figure1-<scene>.html, linked from the scene's page, and
    lists their values: at 60 degrees the glass's D3D9Client eq. 3, R0 + m(1 - cos)^p = 0.05 +
    0.95 * 0.5^4 = 0.109375, beside the exact dielectric of n = 1.5 (0.0891867); the plastic's
    Blinn-Phong has no Fresnel, its specular colour's mean 0.3, beside n = 1.33's exact value."""
    binary = os.environ.get('REFLCHECK_BIN', os.path.join(ROOT, 'build', 'reflcheck'))
    assert os.access(binary, os.X_OK), f'{binary}: build reflcheck first, or set REFLCHECK_BIN'
    run = make_run(str(tmp_path), RUN1)
    scene = tmp_path / 'alpha.yaml'
    scene.write_text(FIG1_SCENE)
    p = subprocess.run([binary, 'eval', 'materials', str(scene), '--out', run], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    r = run_report('--run', run)
    assert r.returncode == 0, r.stderr
    assert '<a href="figure1-alpha.html">' in read(os.path.join(run, 'scene-alpha.html'))
    assert '<a href="figure1-alpha.html">alpha</a>.' in read(os.path.join(run, 'figure1.html'))
    assert not os.path.exists(os.path.join(run, 'figure1-beta.html'))  # beta has no figure1.json
    html = read(os.path.join(run, 'figure1-alpha.html'))
    rows = re.findall(r'<tr data-material="([^"]*)">(.*?)</tr>\s*<tr>(.*?)</tr>', html, re.S)
    assert [name for name, _, _ in rows] == ['glass', 'plastic'], html
    assert '<td rowspan="3">d3d9client</td>' in rows[0][1] and '<td rowspan="3">d3d</td>' in rows[1][1]
    heads = re.findall(r'<th>(\d+)°</th>', html)
    at60 = heads.index('60')

    def value(cells, curve):
        return float(re.findall(rf'data-curve="{curve}">([^<]*)</td>', cells)[at60])

    (_, glass_model, glass_phys), (_, plastic_model, plastic_phys) = rows
    assert value(glass_model, 'model') == pytest.approx(0.05 + 0.95 * 0.5**4, abs=1e-6)
    assert value(glass_phys, 'physics') == pytest.approx(fresnel_dielectric(0.5, 1.5), abs=2e-6)
    assert value(plastic_model, 'model') == pytest.approx((0.2 + 0.3 + 0.4) / 3, abs=1e-6)
    assert value(plastic_phys, 'physics') == pytest.approx(fresnel_dielectric(0.5, 1.33), abs=2e-6)
    if HAVE_GNUPLOT:
        svg = read(os.path.join(run, 'plots', 'figure1-alpha.svg'))
        # one gnuplot plot per curve, titled <material>_<curve> (plot_id makes ':' a '_')
        titles = re.findall(r'<g id="gnuplot_plot_\d+" ><title>([a-z]+_(?:model|physics))</title>', svg)
        assert sorted(titles) == ['glass_model', 'glass_physics', 'plastic_model', 'plastic_physics'], titles
        assert 'src="plots/figure1-alpha.svg"' in html


def test_scene_page_says_which_gate_applied(tmp_path):
    """compare.json's per-size gate (size, own or shared levels, the figure it was sized on) is on
    the scene page beside the threshold."""
    run = make_run(str(tmp_path), RUN1)
    cpath = os.path.join(run, 'alpha', 'compare.json')
    comp = json.loads(read(cpath))
    t = comp['comparisons'][0]['thresholds'][0]
    t.update(size='full', levels='full', loose='', sized={'figure': 0.000706, 'size': 'full', 'run': 'n1'})
    with open(cpath, 'w', encoding='utf-8') as f:
        json.dump(comp, f)
    r = run_report('--run', run)
    assert r.returncode == 0, r.stderr
    page = read(os.path.join(run, 'scene-alpha.html'))
    assert 'full size, its own levels; sized on <span class="mono">0.000706</span> full (n1)' in page
