#!/usr/bin/python3
"""report.py - the reflcheck report: HTML pages, summary.json/csv, JUnit XML and history of one run.

Usage (Python 3 standard library only; plots need the `gnuplot` program, screenshots `chromium`):
  python3 harness/report.py --run reports/runs/<id> [--history reports/history.jsonl]
                            [--commit SHA] [--latest reports/latest] [--screenshot]
  python3 harness/report.py --propose-thresholds --run reports/runs/<id>

Reads what the C harness wrote into the run folder (format: reports/FORMAT.md):
<scene>/compare.json, <scene>/<renderer>-<role>.json job records, <scene>/view.js, and the
optional stability.json, timing/*.json and figure1.svg. It never renders or measures.
Writes into the run folder (each file through a temporary name, then rename): index.html,
scene-<name>.html, report.css, report.js, plots/*.svg, summary.json, summary.csv, junit.xml,
and appends one line to the history file (one write() plus fsync, never truncating).
A missing or corrupt input file is listed on the page and on stderr with its name; it is never
a crash. Exit status: 0 report written (whatever the verdicts), 1 an output could not be
written, 2 bad usage (run folder missing).
"""

import argparse
import base64
import csv
import datetime as dt
import html
import io
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET

HERE = os.path.dirname(os.path.abspath(__file__))
ASSETS = os.path.join(HERE, 'report_assets')
PLOTS = os.path.join(HERE, 'plots')

VERDICTS = ('fail', 'error', 'warn', 'skipped', 'pass')
VERDICT_ORDER = {v: i for i, v in enumerate(VERDICTS)}
JOB_ORDER = {'crashed': 0, 'failed': 1, 'timeout': 2, 'error': 3, 'skipped': 4, 'ok': 5}
HIGHER_BETTER = ('psnr', 'ssim', 'coverage_agreement')
# Error-like figures spanning decades: always shown as 1.23e-4 so columns compare at a glance.
REL_METRICS = ('mae', 'rmse', 'rel_mse', 'rel_rms', 'max_abs', 'share_over', 'max_rel', 'mean_rel', 'error',
               'ref_rel_rms', 'share_fail_pixels', 'z_fail_share', 'rel')
ROLE_LEGEND = {
    'twin': 'the reference renderer is set up to compute exactly our model; any difference is a '
            'translation or renderer bug',
    'validate': 'our real-time approximation against a physically based render; the difference '
                'is the approximation\'s own error',
    'agree': 'POV-Ray against Cycles on the same physical scene; how far the references agree '
             '(the floor under every validate figure)',
}
# Trend plots show at most this many runs: older points crowd the axis without changing the story.
TREND_RUNS = 60
GNUPLOT_TIMEOUT_S = 60
CHROMIUM_TIMEOUT_S = 90


class Problems:
    """Missing or corrupt inputs: listed on the page and echoed to stderr as they are found."""

    def __init__(self):
        self.items = []

    def add(self, path, message, scene=None):
        self.items.append({'file': path, 'message': message, 'scene': scene})
        print(f'report: {path}: {message}', file=sys.stderr)


# ---------------------------------------------------------------------------------------------
# Small helpers

def esc(v):
    return html.escape('' if v is None else str(v), quote=True)


def is_num(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def finite(v):
    return is_num(v) and math.isfinite(v)


def clean(o):
    """Strict JSON: NaN/Inf become null so every consumer can parse summary.json."""
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, dict):
        return {str(k): clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [clean(v) for v in o]
    return o


def fexp(v, digits=2):
    """1.23e-4 style (short exponent), for the relative metrics spanning many decades."""
    if not is_num(v):
        return '—'
    if not math.isfinite(v):
        return str(v)
    if v == 0:
        return '0'
    s = f'{v:.{digits}e}'
    m, e = s.split('e')
    return f'{m}e{int(e)}'


def fmt_metric(name, v):
    base = name.split('.')[-1]
    if not is_num(v):
        return '—' if v is None else esc(v)
    if not math.isfinite(v):
        return str(v)
    if base in ('n_pixels', 'n_tests', 'n_fail', 'n_fail_pixels', 'max_x', 'max_y', 'samples'):
        return str(int(v))
    if base == 'psnr':
        return f'{v:.2f}'
    if base in ('ssim', 'coverage_agreement'):
        return f'{v:.6f}'
    if base in ('z_crit', 'max_abs_z'):
        return f'{v:.3g}'
    if base in REL_METRICS:
        return fexp(v)
    return f'{v:.4g}' if 1e-2 <= abs(v) < 1e5 else fexp(v)


def fthr(name, v):
    """A threshold limit as written in a scene file: 5e-3, not 5.00e-3."""
    if not finite(v) or name.split('.')[-1] in ('psnr', 'ssim', 'coverage_agreement'):
        return fmt_metric(name, v)
    return yaml_num(float(f'{v:.3g}'))


def chan_name(c):
    if is_num(c) and int(c) in (0, 1, 2, 3):
        return 'RGBA'[int(c)]
    return '' if c is None else str(c)


def safe_name(name):
    return re.sub(r'[^A-Za-z0-9_.-]', '_', name)


def json_script(o):
    """JSON for an inline <script>. No '<', '>' or '&' may appear raw: '</script' ends the element
    early and '<!--' followed by '<script' makes the parser swallow the closing tag (a scene
    named after a file such as '<!--<script>.yaml'), so all three become JSON \\u escapes."""
    text = json.dumps(clean(o), separators=(',', ':'))
    return text.replace('<', '\\u003c').replace('>', '\\u003e').replace('&', '\\u0026')


def write_atomic(path, data):
    """Readers never see a half-written file: write a temporary sibling, fsync, rename."""
    if isinstance(data, str):
        data = data.encode('utf-8')
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    tmp = f'{path}.tmp{os.getpid()}'
    with open(tmp, 'wb') as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def read_json(path, problems, what, scene=None):
    try:
        with open(path, 'rb') as f:
            raw = f.read()
    except FileNotFoundError:
        problems.add(path, f'{what} missing; run the harness step that writes it', scene)
        return None
    except OSError as e:
        problems.add(path, f'{what} unreadable: {e.strerror}', scene)
        return None
    try:
        return json.loads(raw.decode('utf-8'))
    except (UnicodeDecodeError, ValueError) as e:
        problems.add(path, f'{what} corrupt: {e}; re-run the step that writes it', scene)
        return None


# ---------------------------------------------------------------------------------------------
# Reading a run folder

def image_candidates(renderer, role):
    """view.js / job keys a comparison may use: agree uses validate renders, and the rasterizer
    has one render (its twin) that a validate comparison measures."""
    if role == 'agree':
        return [f'{renderer}-agree', f'{renderer}-validate']
    if role == 'validate':
        return [f'{renderer}-validate', f'{renderer}-twin']
    return [f'{renderer}-{role}']


def read_view(path, problems, scene):
    """Parses view.js and checks every base64 image has W*H*3 floats; returns a summary."""
    try:
        with open(path, 'r', encoding='utf-8') as f:
            text = f.read()
    except FileNotFoundError:
        problems.add(path, 'view.js missing; run `reflcheck compare` for this scene', scene)
        return None
    except (OSError, UnicodeDecodeError) as e:
        problems.add(path, f'view.js unreadable: {e}', scene)
        return None
    m = re.match(r'\s*window\.REFLCHECK_VIEW\s*=\s*(.*?);?\s*$', text, re.S)
    if not m:
        problems.add(path, 'view.js does not start with "window.REFLCHECK_VIEW ="; re-run compare', scene)
        return None
    try:
        v = json.loads(m.group(1))
        w, h = int(v['width']), int(v['height'])
        images = v.get('images') or {}
        if not isinstance(images, dict):
            raise ValueError('"images" is not an object')
    except (ValueError, KeyError, TypeError) as e:
        problems.add(path, f'view.js corrupt: {e}; re-run compare', scene)
        return None
    good = []
    for name, b64 in images.items():
        try:
            n = len(base64.b64decode(b64, validate=True))
        except (ValueError, TypeError) as e:
            problems.add(path, f'view.js image "{name}" is not base64: {e}', scene)
            continue
        if n != w * h * 3 * 4:
            problems.add(path, f'view.js image "{name}" has {n} bytes, expected {w}x{h}x3 float32 = '
                         f'{w * h * 12}', scene)
            continue
        good.append(name)
    extra = {}
    for key in ('coverage', 'ndotv'):
        if key in v:
            try:
                n = len(base64.b64decode(v[key], validate=True))
                extra[key] = n == w * h * 4
                if n != w * h * 4:
                    problems.add(path, f'view.js "{key}" has {n} bytes, expected {w * h * 4}', scene)
            except (ValueError, TypeError) as e:
                problems.add(path, f'view.js "{key}" is not base64: {e}', scene)
    return {'width': w, 'height': h, 'images': good, 'all_images': list(images), **extra}


def norm_comparison(c, path, problems, scene, index):
    if not isinstance(c, dict):
        problems.add(path, f'comparisons[{index}] is not an object', scene)
        return {'id': f'comparison {index}', 'status': 'error', 'role': '', 'test': '', 'reference': '',
                'reason': f'{os.path.basename(path)}: comparisons[{index}] is not an object',
                'regions': {}, 'aovs': {}, 'thresholds': [], 'times': {}}
    out = dict(c)
    out['id'] = str(c.get('id') or f'{c.get("test", "?")}-vs-{c.get("reference", "?")}-{c.get("role", "?")}')
    status = str(c.get('status', 'error')).lower()
    if status not in VERDICT_ORDER:
        problems.add(path, f'comparison {out["id"]}: unknown status "{status}" (pass|warn|fail|skipped|error)', scene)
        status = 'error'
    out['status'] = status
    for key in ('regions', 'aovs', 'times', 'noise'):
        if not isinstance(out.get(key), dict):
            out[key] = {}
    for key in ('regions', 'aovs'):
        out[key] = {k: v for k, v in out[key].items() if isinstance(v, dict)}
    th = out.get('thresholds')
    out['thresholds'] = [t for t in th if isinstance(t, dict) and 'metric' in t] if isinstance(th, list) else []
    for key in ('angle_bins', 'angle_bins_ndotl'):
        b = out.get(key)
        out[key] = [x for x in b if isinstance(x, dict)] if isinstance(b, list) else []
    for key in ('role', 'test', 'reference', 'reason'):
        out[key] = '' if out.get(key) is None else str(out[key])
    return out


def scene_dirs(run):
    out = []
    for name in sorted(os.listdir(run)):
        p = os.path.join(run, name)
        if name.startswith('.') or name in ('plots', 'timing') or not os.path.isdir(p):
            continue
        files = os.listdir(p)
        if 'compare.json' in files or 'view.js' in files or any(f.endswith('.json') for f in files):
            out.append(name)
    return out


JOB_FILE = re.compile(r'^([a-z0-9_]+)-([a-z0-9_]+)\.json$')


def load_scene(run, name, problems):
    d = os.path.join(run, name)
    sc = {'name': name, 'page': f'scene-{safe_name(name)}.html', 'title': '', 'scene_path': '',
          'comparisons': [], 'jobs': [], 'view': None, 'compare_ok': False}
    cpath = os.path.join(d, 'compare.json')
    comp = read_json(cpath, problems, 'compare.json', name)
    if comp is not None and not (isinstance(comp, dict) and isinstance(comp.get('comparisons', []), list)):
        problems.add(cpath, 'compare.json has no "comparisons" list; re-run compare', name)
        comp = None
    if comp is None:
        why = 'missing' if not os.path.exists(cpath) else 'corrupt'
        sc['comparisons'].append({'id': '(compare.json)', 'status': 'error', 'role': '', 'test': '',
                                  'reference': '', 'pseudo': True,
                                  'reason': f'{name}/compare.json {why}: no comparison could be read',
                                  'regions': {}, 'aovs': {}, 'thresholds': [], 'times': {}, 'noise': {},
                                  'angle_bins': [], 'angle_bins_ndotl': []})
    else:
        sc['compare_ok'] = True
        sc['title'] = str(comp.get('title') or '')
        sc['scene_path'] = str(comp.get('scene_path') or '')
        for i, c in enumerate(comp.get('comparisons', [])):
            sc['comparisons'].append(norm_comparison(c, cpath, problems, name, i))
    for f in sorted(os.listdir(d)):
        m = JOB_FILE.match(f)
        if not m or f == 'compare.json':
            continue
        p = os.path.join(d, f)
        rec = read_json(p, problems, 'job record', name)
        if rec is None:
            sc['jobs'].append({'renderer': m.group(1), 'role': m.group(2), 'status': 'error',
                               'message': f'{name}/{f}: unreadable job record', 'file': f})
            continue
        if not isinstance(rec, dict):
            problems.add(p, 'job record is not a JSON object', name)
            continue
        rec = dict(rec)
        rec.setdefault('renderer', m.group(1))
        rec.setdefault('role', m.group(2))
        rec['file'] = f
        sc['jobs'].append(rec)
    sc['view'] = read_view(os.path.join(d, 'view.js'), problems, name)
    images = sc['view']['images'] if sc['view'] else []
    for c in sc['comparisons']:
        if c.get('pseudo'):
            continue
        for side, key in (('test', 'test_key'), ('reference', 'ref_key')):
            c[key] = next((k for k in image_candidates(c[side], c['role']) if k in images), None)
        for side, key in (('test', 'test_job'), ('reference', 'ref_job')):
            cands = image_candidates(c[side], c['role'])
            c[key] = next((j for k in cands for j in sc['jobs'] if f'{j.get("renderer")}-{j.get("role")}' == k), None)
    return sc


def machine_info():
    u = os.uname()
    cpu = ''
    try:
        with open('/proc/cpuinfo', encoding='utf-8', errors='replace') as f:
            for line in f:
                if line.lower().startswith('model name'):
                    cpu = line.split(':', 1)[1].strip()
                    break
    except OSError:
        pass
    return {'uname': f'{u.sysname} {u.release} {u.version} {u.machine}', 'node': u.nodename,
            'cpu_model': cpu, 'cores': os.cpu_count()}


RUN_ID = re.compile(r'^(\d{8})-(\d{6})(?:[-_]([0-9a-fA-F]{4,40}))?')


def run_identity(run, commit_arg, scenes):
    run_id = os.path.basename(os.path.normpath(run))
    m = RUN_ID.match(run_id)
    commit = commit_arg or (m.group(3) if m and m.group(3) else '') or 'unknown'
    when = None
    if m:
        try:
            when = dt.datetime.strptime(m.group(1) + m.group(2), '%Y%m%d%H%M%S').replace(tzinfo=dt.timezone.utc)
        except ValueError:
            when = None
    if when is None:
        stamps = [j.get('finished_unix') for s in scenes for j in s['jobs'] if finite(j.get('finished_unix'))]
        when = dt.datetime.fromtimestamp(max(stamps) if stamps else os.path.getmtime(run), dt.timezone.utc)
    return run_id, commit, when.strftime('%Y-%m-%dT%H:%M:%SZ')


def renderer_versions(scenes):
    vers = {}
    for s in scenes:
        for j in s['jobs']:
            v = j.get('version')
            if v:
                vers.setdefault(str(j.get('renderer')), [])
                if v not in vers[str(j.get('renderer'))]:
                    vers[str(j.get('renderer'))].append(str(v))
    return {k: ' | '.join(v) for k, v in sorted(vers.items())}


def load_optional(run, problems):
    opt = {'stability': None, 'timing': [], 'figure1': False}
    sp = os.path.join(run, 'stability.json')
    if os.path.exists(sp):
        st = read_json(sp, problems, 'stability.json')
        rows = st.get('rows') if isinstance(st, dict) else st
        if st is not None and not isinstance(rows, list):
            problems.add(sp, 'stability.json has no "rows" list')
            rows = None
        opt['stability'] = {'meta': st if isinstance(st, dict) else {},
                            'rows': [r for r in rows if isinstance(r, dict)] if rows else []}
    td = os.path.join(run, 'timing')
    if os.path.isdir(td):
        for f in sorted(os.listdir(td)):
            if f.endswith('.json'):
                t = read_json(os.path.join(td, f), problems, 'timing file')
                if t is not None:
                    opt['timing'].append((f[:-5], t))
    opt['figure1'] = os.path.exists(os.path.join(run, 'figure1.svg'))
    return opt


def load_run(run, commit_arg=None):
    problems = Problems()
    scenes = [load_scene(run, n, problems) for n in scene_dirs(run)]
    if not scenes:
        problems.add(run, 'no scene folders (with compare.json, job records or view.js); run `reflcheck run` first')
    run_id, commit, when = run_identity(run, commit_arg, scenes)
    return {'dir': run, 'run_id': run_id, 'commit': commit, 'time': when,
            'report_time': dt.datetime.now(dt.timezone.utc).strftime('%Y-%m-%dT%H:%M:%SZ'),
            'machine': machine_info(), 'versions': renderer_versions(scenes), 'scenes': scenes,
            'problems': problems, 'optional': load_optional(run, problems)}


def all_comparisons(R):
    for s in R['scenes']:
        for c in s['comparisons']:
            yield s, c


def verdict_counts(R):
    n = {v: 0 for v in VERDICTS}
    for _, c in all_comparisons(R):
        n[c['status']] += 1
    return n


JOB_BENIGN = ('ok', 'skipped')


def run_status(R):
    """'error' when anything could not be measured (a comparison errored, a job crashed, failed,
    timed out or could not write, or the run compared nothing), else 'fail' when a comparison
    failed, else 'ok'. Warnings and skips (a renderer not installed, or unable to represent the
    scene) leave a run 'ok'."""
    n = verdict_counts(R)
    jobs_bad = any(str(j.get('status')) not in JOB_BENIGN for s in R['scenes'] for j in s['jobs'])
    if n['error'] or jobs_bad or not any(True for _ in all_comparisons(R)):
        return 'error'
    return 'fail' if n['fail'] else 'ok'


def flat_metrics(c):
    """One comparison's figures as flat keys ("surface.rel_rms", "aov.diffuse.psnr", ...)."""
    out = {}
    for reg, ms in c.get('regions', {}).items():
        for k, v in ms.items():
            if is_num(v):
                out[f'{reg}.{k}'] = v
    for aov, ms in c.get('aovs', {}).items():
        for k, v in ms.items():
            if is_num(v):
                out[f'aov.{aov}.{k}'] = v
    if is_num(c.get('coverage_agreement')):
        out['coverage_agreement'] = c['coverage_agreement']
    noise = c.get('noise') or {}
    if is_num(noise.get('ref_rel_rms')):
        out['noise.ref_rel_rms'] = noise['ref_rel_rms']
    for k, v in (noise.get('ztest') or {}).items():
        if is_num(v):
            out[f'noise.ztest.{k}'] = v
    for k, v in (c.get('times') or {}).items():
        if is_num(v):
            out[f'times.{k}'] = v
    return out


# ---------------------------------------------------------------------------------------------
# Machine-readable outputs

def summary_object(R):
    scenes = []
    for s in R['scenes']:
        comps = []
        for c in s['comparisons']:
            o = {k: c.get(k) for k in ('id', 'test', 'reference', 'role', 'status', 'reason', 'regions', 'aovs',
                                       'coverage_agreement', 'noise', 'thresholds', 'times', 'angle_bins',
                                       'angle_bins_ndotl')}
            o['test_image'] = c.get('test_key')
            o['reference_image'] = c.get('ref_key')
            comps.append(o)
        jobs = [{k: j.get(k) for k in ('renderer', 'role', 'variant', 'status', 'message', 'version', 'wall_s',
                                       'cpu_s', 'cached', 'width', 'height', 'supersample', 'samples', 'log',
                                       'exr', 'file')} for j in s['jobs']]
        scenes.append({'name': s['name'], 'title': s['title'], 'scene_path': s['scene_path'], 'page': s['page'],
                       'comparisons': comps, 'jobs': jobs})
    opt = R['optional']
    return clean({'run_id': R['run_id'], 'commit': R['commit'], 'time': R['time'],
                  'report_time': R['report_time'], 'machine': R['machine'], 'status': run_status(R),
                  'renderer_versions': R['versions'], 'counts': verdict_counts(R), 'scenes': scenes,
                  'stability': opt['stability']['rows'] if opt['stability'] else None,
                  'problems': R['problems'].items})


def summary_csv(R):
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator='\n')
    w.writerow(['run_id', 'scene', 'comparison', 'role', 'status', 'group', 'name', 'metric', 'value',
                'warn', 'fail', 'verdict'])
    for s, c in all_comparisons(R):
        base = [R['run_id'], s['name'], c['id'], c['role'], c['status']]

        def row(group, name, metric, value, warn='', fail='', verdict=''):
            w.writerow(base + [group, name, metric, '' if value is None else repr(value) if isinstance(value, float)
                               else value, warn, fail, verdict])
        for reg, ms in c['regions'].items():
            for k, v in ms.items():
                row('region', reg, k, v)
        for aov, ms in c['aovs'].items():
            for k, v in ms.items():
                row('aov', aov, k, v)
        if c.get('coverage_agreement') is not None:
            row('comparison', 'all', 'coverage_agreement', c['coverage_agreement'])
        noise = c.get('noise') or {}
        if noise.get('ref_rel_rms') is not None:
            row('noise', 'reference', 'ref_rel_rms', noise['ref_rel_rms'])
        for k, v in (noise.get('ztest') or {}).items():
            row('noise', 'ztest', k, v)
        for t in c['thresholds']:
            row('threshold', 'surface' if '.' not in str(t['metric']) else str(t['metric']).split('.')[0],
                t['metric'], t.get('value'), t.get('warn', ''), t.get('fail', ''), t.get('verdict', ''))
        if not c['regions'] and not c['thresholds']:
            row('comparison', 'all', 'status', c['status'])
    return buf.getvalue()


def threshold_message(scene, c, t):
    metric = t['metric']
    hb = metric.split('.')[-1] in HIGHER_BETTER
    op = '<' if hb else '>'
    why = f' ({t["why"]})' if t.get('why') else ''
    return (f'{scene}: {c["id"]}: {metric} {fmt_metric(metric, t.get("value"))} {op} '
            f'{fthr(metric, t.get("fail"))}{why}')


def junit_xml(R):
    root = ET.Element('testsuites', name=f'reflcheck {R["run_id"]}')
    tot = {'tests': 0, 'failures': 0, 'errors': 0, 'skipped': 0}
    for s in R['scenes']:
        ts = ET.SubElement(root, 'testsuite', name=s['name'])
        cnt = {'tests': 0, 'failures': 0, 'errors': 0, 'skipped': 0}
        for c in s['comparisons']:
            cases = c['thresholds'] or [None]
            for k, t in enumerate(cases):
                name = c['id'] if t is None else f'{c["id"]}: {t["metric"]}'
                tc = ET.SubElement(ts, 'testcase', name=name, classname=f'reflcheck.{s["name"]}')
                # the render time belongs to the comparison: counted once, on its first testcase
                secs = sum(v for v in (c.get('times') or {}).values() if finite(v)) if k == 0 else 0.0
                tc.set('time', f'{secs:.3f}')
                cnt['tests'] += 1
                if c['status'] == 'error':
                    e = ET.SubElement(tc, 'error', message=f'{s["name"]}: {c["id"]}: {c.get("reason") or "error"}',
                                      type='error')
                    e.text = c.get('reason') or ''
                    cnt['errors'] += 1
                elif c['status'] == 'skipped' or (t is not None and str(t.get('verdict')) == 'skipped'):
                    ET.SubElement(tc, 'skipped', message=f'{s["name"]}: {c["id"]}: {c.get("reason") or "skipped"}')
                    cnt['skipped'] += 1
                elif t is None:
                    if c['status'] == 'fail':
                        f = ET.SubElement(tc, 'failure', message=f'{s["name"]}: {c["id"]}: {c.get("reason") or "fail"}',
                                          type='threshold')
                        f.text = c.get('reason') or ''
                        cnt['failures'] += 1
                elif str(t.get('verdict')) == 'fail':
                    msg = threshold_message(s['name'], c, t)
                    f = ET.SubElement(tc, 'failure', message=msg, type='threshold')
                    f.text = f'{msg}\nwarn {fthr(t["metric"], t.get("warn"))}, fail {fthr(t["metric"], t.get("fail"))}'
                    cnt['failures'] += 1
                elif str(t.get('verdict')) == 'warn':
                    so = ET.SubElement(tc, 'system-out')
                    so.text = 'WARN ' + threshold_message(s['name'], c, t).replace(
                        f' {fthr(t["metric"], t.get("fail"))}', f' warn {fthr(t["metric"], t.get("warn"))}', 1)
        for k, v in cnt.items():
            ts.set(k, str(v))
            tot[k] += v
    for k, v in tot.items():
        root.set(k, str(v))
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding='unicode') + '\n'


# ---------------------------------------------------------------------------------------------
# History: one JSON line per run, append-only

def history_record(R):
    metrics = {}
    for s, c in all_comparisons(R):
        m = {'role': c['role'], 'status': c['status']}
        m.update(flat_metrics(c))
        for t in c['thresholds']:
            m[f'verdict.{t["metric"]}'] = t.get('verdict')
        metrics.setdefault(s['name'], {})[c['id']] = m
    return clean({'run_id': R['run_id'], 'commit': R['commit'], 'time': R['time'],
                  'report_time': R['report_time'], 'versions': R['versions'], 'machine': R['machine'],
                  'status': run_status(R), 'counts': verdict_counts(R), 'metrics': metrics})


def read_history(path, problems=None):
    """Records in file order; a line that does not parse (a run killed mid-write) is skipped and
    reported. Several lines of one run id: the last one wins, at the place of the first."""
    out, order = {}, []
    try:
        with open(path, 'rb') as f:
            data = f.read()
    except FileNotFoundError:
        return []
    for no, line in enumerate(data.split(b'\n'), 1):
        if not line.strip():
            continue
        try:
            rec = json.loads(line.decode('utf-8'))
            if not isinstance(rec, dict) or 'run_id' not in rec:
                raise ValueError('not a run record')
        except (ValueError, UnicodeDecodeError) as e:
            if problems is not None:
                problems.add(f'{path}:{no}', f'history line skipped (truncated or corrupt: {str(e)[:80]}); '
                             'earlier runs are unaffected')
            continue
        if rec['run_id'] not in out:
            order.append(rec['run_id'])
        out[rec['run_id']] = rec
    return [out[k] for k in order]


def append_history(path, rec, problems):
    """One os.write of the whole line, then fsync: a kill leaves at worst a partial last line,
    which readers skip. O_APPEND never truncates. A partial line left by an earlier crash is
    closed with a newline first (in the same write) so that this record stays parseable."""
    existing = read_history(path)
    same = [r for r in existing if r.get('run_id') == rec['run_id']]
    if same and {k: v for k, v in same[-1].items() if k != 'report_time'} == \
            {k: v for k, v in rec.items() if k != 'report_time'}:
        return False
    line = json.dumps(rec, separators=(',', ':'), sort_keys=True).encode('utf-8') + b'\n'
    os.makedirs(os.path.dirname(os.path.abspath(path)) or '.', exist_ok=True)
    created = not os.path.exists(path)
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        size = os.fstat(fd).st_size
        if size > 0:
            with open(path, 'rb') as f:
                f.seek(size - 1)
                if f.read(1) != b'\n':
                    line = b'\n' + line
        n = os.write(fd, line)
        while n < len(line):
            n += os.write(fd, line[n:])
        os.fsync(fd)
    finally:
        os.close(fd)
    if created:
        dfd = os.open(os.path.dirname(os.path.abspath(path)), os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)
    return True


# ---------------------------------------------------------------------------------------------
# Plots (gnuplot SVG)

def gnuplot_q(s):
    return "'" + str(s).replace("'", "''") + "'"


def run_gnuplot(script, params, out_svg, problems):
    exe = shutil.which('gnuplot')
    if not exe:
        problems.add(out_svg, 'gnuplot not found; install gnuplot-nox to get plots')
        return False
    tmp = f'{out_svg}.tmp{os.getpid()}.svg'
    params = dict(params, outfile=tmp, dir=PLOTS + os.sep)
    expr = '; '.join(f'{k}={gnuplot_q(v) if isinstance(v, str) else v}' for k, v in params.items())
    try:
        r = subprocess.run([exe, '-e', expr, os.path.join(PLOTS, script)], capture_output=True, text=True,
                           timeout=GNUPLOT_TIMEOUT_S)
    except (OSError, subprocess.TimeoutExpired) as e:
        problems.add(out_svg, f'gnuplot failed: {e}')
        return False
    if r.returncode != 0 or not os.path.exists(tmp) or os.path.getsize(tmp) == 0:
        msg = (r.stderr.strip().splitlines() or ['no output'])[-1]
        problems.add(out_svg, f'gnuplot {script} failed: {msg}')
        if os.path.exists(tmp):
            os.unlink(tmp)
        return False
    os.replace(tmp, out_svg)
    return True


def write_table(path, header, rows):
    """gnuplot data: whitespace columns, '?' = missing, header line for columnhead()."""
    with open(path, 'w', encoding='utf-8') as f:
        f.write(' '.join(header) + '\n')
        for r in rows:
            f.write(' '.join('?' if v is None else (repr(float(v)) if is_num(v) else str(v)) for v in r) + '\n')


def plot_id(s):
    return re.sub(r'[^A-Za-z0-9_.+-]', '_', s)


def plot_angles(R, s, tmpdir, problems):
    """Two SVGs per scene (N.V and N.L): surface rel_rms per bin, one line per comparison."""
    out = {}
    for key, axis, label in (('angle_bins', 'ndotv', 'N·V'), ('angle_bins_ndotl', 'ndotl', 'N·L')):
        cols, centres = [], {}
        for c in s['comparisons']:
            pts = {}
            for b in c.get(key, []):
                lo, hi, v = b.get('ndotv_lo', b.get('ndotl_lo', b.get('lo'))), \
                    b.get('ndotv_hi', b.get('ndotl_hi', b.get('hi'))), b.get('rel_rms')
                if finite(lo) and finite(hi) and finite(v) and v > 0 and b.get('n', 1) != 0:
                    x = round((lo + hi) / 2, 6)
                    pts[x] = v
                    centres[x] = 1
            if pts:
                cols.append((c['id'], pts))
        if not cols:
            continue
        xs = sorted(centres)
        dat = os.path.join(tmpdir, f'{safe_name(s["name"])}-{axis}.dat')
        write_table(dat, ['bin'] + [plot_id(i) for i, _ in cols], [[x] + [p.get(x) for _, p in cols] for x in xs])
        svg = os.path.join(R['dir'], 'plots', f'angle-{safe_name(s["name"])}-{axis}.svg')
        if run_gnuplot('angle.gp', {'datafile': dat, 'ncols': len(cols) + 1, 'xlab': label,
                                    'ptitle': f'{s["name"]}: surface rel_rms per {label} bin'}, svg, problems):
            out[axis] = os.path.relpath(svg, R['dir'])
    return out


def plot_trends(R, history, tmpdir, problems):
    out = {}
    for s in R['scenes']:
        # A run that errored measured only part of the scene: its figures are no trend.
        runs = [h for h in history if s['name'] in (h.get('metrics') or {})
                and h.get('status') != 'error'][-TREND_RUNS:]
        ids = []
        for h in runs:
            for cid, m in h['metrics'][s['name']].items():
                if isinstance(m, dict) and finite(m.get('surface.rel_rms')) and m['surface.rel_rms'] > 0 \
                        and cid not in ids:
                    ids.append(cid)
        if not ids:
            continue
        rows = []
        for i, h in enumerate(runs):
            ms = h['metrics'][s['name']]
            label = (str(h.get('commit') or '')[:7] if h.get('commit') not in (None, '', 'unknown')
                     else str(h['run_id'])[-13:])
            vals = []
            for cid in ids:
                v = (ms.get(cid) or {}).get('surface.rel_rms') if isinstance(ms.get(cid), dict) else None
                vals.append(v if finite(v) and v > 0 else None)
            rows.append([i + 1, plot_id(label)] + vals)
        dat = os.path.join(tmpdir, f'trend-{safe_name(s["name"])}.dat')
        write_table(dat, ['run', 'label'] + [plot_id(c) for c in ids], rows)
        svg = os.path.join(R['dir'], 'plots', f'trend-{safe_name(s["name"])}.svg')
        if run_gnuplot('trend.gp', {'datafile': dat, 'ncols': len(ids) + 2,
                                    'ptitle': f'{s["name"]}: surface rel_rms over runs'}, svg, problems):
            out[s['name']] = os.path.relpath(svg, R['dir'])
    return out


TIME_KEYS = ('time_s', 'wall_s', 'seconds', 'time')
ERR_KEYS = ('rel_rms', 'error', 'rmse', 'mae')
SWEEP_FORMAT = 'reflcheck-sweep-1'   # harness/sweep.py's timing/<scene>.json


def is_sweep(t):
    return isinstance(t, dict) and t.get('format') == SWEEP_FORMAT and isinstance(t.get('series'), list)


def timing_points(t):
    """Accepts {"series":[{"label":..,"points":[..]}]}, {"points":[..]} or a bare list of points."""
    series = []
    if isinstance(t, dict) and isinstance(t.get('series'), list):
        for i, sr in enumerate(t['series']):
            if isinstance(sr, dict) and isinstance(sr.get('points'), list):
                label = sr.get('label') or sr.get('renderer') or f'series{i + 1}'
                series.append((str(label), [p for p in sr['points'] if isinstance(p, dict)]))
    else:
        pts = t.get('points') if isinstance(t, dict) else t
        if isinstance(pts, list):
            groups = {}
            for p in pts:
                if isinstance(p, dict):
                    groups.setdefault(str(p.get('series') or p.get('renderer') or 'points'), []).append(p)
            series = list(groups.items())
    return series


def timing_xy(t, pts):
    """(time, error) pairs of points, both > 0: the file's error_key if it names one. Sorted by
    time, except a sweep's, which keeps its knob order."""
    ek = t.get('error_key') if isinstance(t, dict) and isinstance(t.get('error_key'), str) else None
    xy = []
    for p in pts:
        x = next((p[k] for k in TIME_KEYS if finite(p.get(k))), None)
        y = p.get(ek) if ek else next((p[k] for k in ERR_KEYS if finite(p.get(k))), None)
        if finite(x) and finite(y) and x > 0 and y > 0:
            xy.append((x, y))
    return xy if is_sweep(t) else sorted(xy)


def sweep_fit_text(sr):
    """The slope in a legend: error ~ t^b, and for Cycles also ~ spp^b."""
    parts = []
    for key, var in (('fit_spp', 'spp'), ('fit', 't')):
        f = sr.get(key)
        if isinstance(f, dict) and finite(f.get('slope')):
            parts.append(f'{var}^{f["slope"]:.2f}')
    return ', '.join(parts)


def plot_timing(R, tmpdir, problems):
    out = {}
    for name, t in R['optional']['timing']:
        series = timing_points(t)
        blocks, titles = [], []
        srs = [sr for sr in t['series'] if isinstance(sr, dict) and isinstance(sr.get('points'), list)] \
            if is_sweep(t) else []
        refs = []
        for i, (label, pts) in enumerate(series):
            if is_sweep(t):
                # The reference's point is its own noise estimate, not a sweep level: drawn apart.
                refs += [p for p in pts if p.get('is_reference')]
                pts = [p for p in pts if not p.get('is_reference')]
            xy = timing_xy(t, pts)
            if xy:
                blocks.append(xy)
                if is_sweep(t):
                    fit = sweep_fit_text(srs[i]) if i < len(srs) else ''
                    titles.append(re.sub(r"['\"]", '', f'{label} ({fit})' if fit else label))
                else:
                    titles.append(plot_id(label))
        if refs and timing_xy(t, refs):
            blocks.append(timing_xy(t, refs))
            titles.append('reference: own noise (est.)')
        if not blocks:
            continue
        dat = os.path.join(tmpdir, f'timing-{safe_name(name)}.dat')
        svg = os.path.join(R['dir'], 'plots', f'timing-{safe_name(name)}.svg')
        if is_sweep(t):
            front = sorted((p['time_s'], p['error']) for p in t.get('pareto') or []
                           if isinstance(p, dict) and finite(p.get('time_s')) and finite(p.get('error'))
                           and p['time_s'] > 0 and p['error'] > 0)
            blocks.insert(0, front or [(1.0, None)])
            with open(dat, 'w', encoding='utf-8') as f:
                f.write('\n\n\n'.join('\n'.join(f'{x!r} {"?" if y is None else repr(y)}' for x, y in b)
                                         for b in blocks) + '\n')
            asis = t.get('as_is') if isinstance(t.get('as_is'), dict) else {}
            cross = t.get('crossover') if isinstance(t.get('crossover'), dict) else {}
            hline = asis.get(t.get('error_key') or 'error')
            xcross = cross.get('time_s') if not cross.get('extrapolated') else cross.get('upper_bound_s')
            params = {'datafile': dat, 'nseries': len(blocks) - 1, 'titles': ' '.join(f'"{x}"' for x in titles),
                      'ptitle': f'{name}: error vs time ({"x".join(str(v) for v in t.get("size") or [])} px, '
                                f'one thread per render)',
                      'ylab': 'error: NRMSE vs noise-free (est.)' if t.get('error_key') == 'error'
                      else str(t.get('error_key')),
                      'xlab': f'{"CPU" if t.get("clock") == "cpu_s" else "wall"} time per render, 1 thread (s)',
                      'hline': float(hline) if finite(hline) and hline > 0 else 0.0,
                      'xcross': float(xcross) if finite(xcross) and xcross > 0 else 0.0}
            ok = run_gnuplot('sweep.gp', params, svg, problems)
        else:
            with open(dat, 'w', encoding='utf-8') as f:
                # Two blank lines end a gnuplot data set (`index`); one would only end a block.
                f.write('\n\n\n'.join('\n'.join(f'{x!r} {y!r}' for x, y in b) for b in blocks) + '\n')
            ok = run_gnuplot('time.gp', {'datafile': dat, 'nseries': len(blocks), 'titles': ' '.join(titles),
                                         'ptitle': f'{name}: error vs time'}, svg, problems)
        if ok:
            out[name] = os.path.relpath(svg, R['dir'])
    return out


# ---------------------------------------------------------------------------------------------
# HTML

def badge(status):
    s = esc(status or '—')
    return f'<span class="badge v-{s}">{s}</span>'


def page(title, kind, header_html, body, extra_scripts=''):
    return f'''<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{esc(title)}</title>
<link rel="stylesheet" href="report.css">
</head>
<body data-page="{kind}" data-loaded="pending">
<header class="top">{header_html}</header>
<main>
<section id="load-status" class="problems" hidden><h2>Page load errors</h2><ul id="load-errors"></ul></section>
{body}
</main>
<footer>reflcheck report · generated by harness/report.py · static files, works offline from disk</footer>
{extra_scripts}<script src="report.js"></script>
</body></html>
'''


def top_header(R, crumb=''):
    m = R['machine']
    return (f'<div class="brand"><a href="index.html">reflcheck</a>{crumb}</div>'
            f'<dl class="meta"><dt>run</dt><dd class="mono">{esc(R["run_id"])}</dd>'
            f'<dt>commit</dt><dd class="mono">{esc(R["commit"])}</dd>'
            f'<dt>time</dt><dd class="mono">{esc(R["time"])}</dd>'
            f'<dt>machine</dt><dd title="{esc(m["uname"])}">{esc(m["cpu_model"] or m["uname"])} · {esc(m["cores"])} cores</dd>'
            '</dl>')


def problems_html(items, scene=None):
    sel = [p for p in items if scene is None or p['scene'] == scene]
    if not sel:
        return ''
    lis = ''.join(f'<li><code>{esc(p["file"])}</code> — {esc(p["message"])}</li>' for p in sel)
    return f'<section class="problems"><h2>Input problems ({len(sel)})</h2><ul>{lis}</ul></section>'


def job_time(j):
    if not j:
        return '<span class="dim">—</span>'
    w = j.get('wall_s')
    if str(j.get('status', 'ok')) != 'ok':
        return f'<span class="v-{esc(j.get("status"))}-text small">{esc(j.get("status"))}</span>'
    s = f'{w:.2f}' if finite(w) else '—'
    c = ' <span class="tag">cached</span>' if j.get('cached') else ''
    return f'<span class="mono">{s}</span>{c}'


def time_cell(c, side):
    j = c.get('test_job' if side == 'test' else 'ref_job')
    if j:
        return job_time(j)
    v = (c.get('times') or {}).get('test_wall_s' if side == 'test' else 'reference_wall_s')
    return f'<span class="mono">{v:.2f}</span>' if finite(v) else '<span class="dim">—</span>'


def thresholds_cell(c):
    if not c['thresholds']:
        return '<span class="dim">none</span>'
    parts = []
    for t in c['thresholds']:
        m = t['metric']
        v = str(t.get('verdict') or 'skipped')
        parts.append(f'<div class="th v-{esc(v)}-text" title="{esc(t.get("why") or "")}">'
                     f'<span class="th-m">{esc(m)}</span> <span class="mono">{fmt_metric(m, t.get("value"))}</span>'
                     f' <span class="dim mono">w {fthr(m, t.get("warn"))} · f {fthr(m, t.get("fail"))}</span></div>')
    return ''.join(parts)


def sorted_rows(R):
    rows = list(all_comparisons(R))
    rows.sort(key=lambda sc: (VERDICT_ORDER.get(sc[1]['status'], 0), sc[0]['name'], sc[1]['id']))
    return rows


def summary_table(R):
    body = []
    for s, c in sorted_rows(R):
        surf = c['regions'].get('surface', {})
        noise = c.get('noise') or {}
        z = noise.get('ztest') or {}
        mx = surf.get('max_abs')
        where = ''
        if finite(mx) and surf.get('max_x') is not None:
            where = (f' <span class="dim">@{esc(surf.get("max_x"))},{esc(surf.get("max_y"))}'
                     f' {esc(chan_name(surf.get("max_c")))}</span>')
        ca = c.get('coverage_agreement')
        zs = z.get('share_fail_pixels')
        ids = (f'<div class="cid">{esc(c["id"])}</div>'
               f'<div class="dim small">{esc(c["test"])} vs {esc(c["reference"])}</div>' if not c.get('pseudo')
               else f'<div class="cid">{esc(c["id"])}</div>')
        body.append(
            f'<tr data-role="{esc(c["role"])}" data-verdict="{esc(c["status"])}" class="row-{esc(c["status"])}">'
            f'<td>{badge(c["status"])}</td>'
            f'<td><a href="{esc(s["page"])}">{esc(s["name"])}</a></td>'
            f'<td>{ids}</td><td>{esc(c["role"])}</td>'
            f'<td class="num">{fexp(surf.get("rel_rms"))}</td>'
            f'<td class="num">{fmt_metric("psnr", surf.get("psnr"))}</td>'
            f'<td class="num">{fexp(mx)}{where}</td>'
            f'<td class="num">{fmt_metric("ssim", surf.get("ssim"))}</td>'
            f'<td class="num">{fexp(noise.get("ref_rel_rms"))}</td>'
            f'<td class="num">{f"{100 * zs:.3g}%" if finite(zs) else "—"}</td>'
            f'<td class="num">{f"{100 * ca:.3f}%" if finite(ca) else "—"}</td>'
            f'<td class="ths">{thresholds_cell(c)}</td>'
            f'<td class="num">{time_cell(c, "test")}</td><td class="num">{time_cell(c, "ref")}</td>'
            f'<td class="reason">{esc(c.get("reason"))}</td></tr>')
    head = ('<tr><th>verdict</th><th>scene</th><th>comparison</th><th>role</th>'
            '<th title="surface relative RMS error">surf rel_rms</th><th>PSNR dB</th>'
            '<th title="largest absolute difference and its pixel (x,y,channel)">max |Δ| @px</th>'
            '<th>SSIM</th><th title="relative RMS noise of the reference (its own uncertainty)">noise floor</th>'
            '<th title="share of surface pixels failing the per-pixel z-test">z fail</th>'
            '<th title="share of pixels whose coverage class agrees">coverage</th>'
            '<th>thresholds (value · warn · fail)</th>'
            '<th title="wall seconds of the test render">test s</th>'
            '<th title="wall seconds of the reference render">ref s</th><th>reason</th></tr>')
    return (f'<table id="summary" class="grid filterable"><thead>{head}</thead>'
            f'<tbody>{"".join(body)}</tbody></table>')


def log_link(R, s, j):
    p = j.get('log') or ''
    if not p:
        return '<span class="dim">—</span>'
    cands = [p] if os.path.isabs(p) else [p, os.path.join(R['dir'], p), os.path.join(R['dir'], s['name'], p)]
    for cpath in cands:
        if os.path.exists(cpath):
            rel = os.path.relpath(os.path.abspath(cpath), os.path.abspath(R['dir']))
            return f'<a href="{esc(rel)}">log</a>'
    return f'<span class="dim" title="{esc(p)}">log missing</span>'


def jobs_rows(R, scenes):
    rows = [(s, j) for s in scenes for j in s['jobs']]
    rows.sort(key=lambda sj: (JOB_ORDER.get(str(sj[1].get('status')), 0), sj[0]['name'],
                              str(sj[1].get('renderer')), str(sj[1].get('role'))))
    out = []
    for s, j in rows:
        st = str(j.get('status', '?'))
        size = ''
        if j.get('width'):
            size = f'{esc(j.get("width"))}×{esc(j.get("height"))}'
            if j.get('supersample'):
                size += f' ss{esc(j.get("supersample"))}'
            if j.get('samples'):
                size += f' {esc(j.get("samples"))}spp'
        cpu = j.get('cpu_s')
        out.append(
            f'<tr data-role="{esc(j.get("role"))}" data-status="{esc(st)}">'
            f'<td>{badge(st)}</td><td><a href="{esc(s["page"])}">{esc(s["name"])}</a></td>'
            f'<td>{esc(j.get("renderer"))}</td><td>{esc(j.get("role"))}</td><td>{esc(j.get("variant", ""))}</td>'
            f'<td class="small">{esc(j.get("version"))}</td>'
            f'<td class="num">{job_time(j)}</td><td class="num">{f"{cpu:.2f}" if finite(cpu) else "—"}</td>'
            f'<td class="num">{size}</td><td class="reason" title="{esc(j.get("command"))}">{esc(j.get("message"))}</td>'
            f'<td>{log_link(R, s, j)}</td></tr>')
    head = ('<tr><th>status</th><th>scene</th><th>renderer</th><th>role</th><th>variant</th><th>version</th>'
            '<th>wall s</th><th>cpu s</th><th>size</th><th>message</th><th>log</th></tr>')
    return f'<table class="grid filterable jobs"><thead>{head}</thead><tbody>{"".join(out)}</tbody></table>'


def role_legend():
    items = ''.join(f'<li><b>{r}</b> — {esc(t)}</li>' for r, t in ROLE_LEGEND.items())
    return f'<ul class="legend">{items}</ul>'


def stability_html(opt):
    st = opt['stability']
    if st is None:
        return ''
    rows = []
    for r in st['rows']:
        bad = any(finite(r.get(k)) and r.get(k) > 0 for k in ('nan', 'inf', 'negative')) or \
            (r.get('expect_ok') == 1 and r.get('check_ok') == 0)
        cells = [esc(r.get('function')), esc(r.get('case', r.get('case_name'))),
                 f'<span class="mono">{esc(r.get("samples"))}</span>',
                 f'<span class="mono">{fmt_metric("max_ulp", r.get("max_ulp")) if is_num(r.get("max_ulp")) else "—"}</span>',
                 f'<span class="mono">{fexp(r.get("max_rel"))}</span>']
        cells += [f'<span class="mono">{esc(r.get(k, "—"))}</span>' for k in ('nan', 'inf', 'negative')]
        cells.append(esc(r.get('note')))
        rows.append(f'<tr class="{"row-fail" if bad else ""}">' + ''.join(
            f'<td class="{"num" if 2 <= i <= 7 else ""}">{c}</td>' for i, c in enumerate(cells)) + '</tr>')
    head = ''.join(f'<th>{h}</th>' for h in ('function', 'case', 'samples', 'max_ulp', 'max_rel', 'nan', 'inf',
                                              'negative', 'note'))
    return (f'<section id="stability"><h2>Numerical stability <span class="dim small">stability.json · '
            f'{len(st["rows"])} rows; red rows: NaN/Inf/negative output or a gating check broken</span></h2>'
            f'<table class="grid filterable"><thead><tr>{head}</tr></thead><tbody>{"".join(rows)}</tbody></table>'
            '</section>')


def fsec(v):
    """Seconds: 3 significant digits, '—' when absent."""
    return '—' if not finite(v) else (f'{v:.3g}' if v >= 1e-3 else fexp(v))


def timing_generic_html(name, t, plots):
    series = timing_points(t)
    keys = []
    for _, pts in series:
        for p in pts:
            for k in p:
                if k not in keys:
                    keys.append(k)
    rows = ''.join('<tr><td>' + esc(label) + '</td>' + ''.join(
        f'<td class="num">{fmt_metric(k, p.get(k)) if is_num(p.get(k)) else esc(p.get(k, ""))}</td>' for k in keys)
        + '</tr>' for label, pts in series for p in pts)
    out = (f'<h3>{esc(name)}</h3><div class="flexrow"><table class="grid"><thead><tr><th>series</th>'
           + ''.join(f'<th>{esc(k)}</th>' for k in keys) + f'</tr></thead><tbody>{rows}</tbody></table>')
    if name in plots:
        out += f'<img class="plot" src="{esc(plots[name])}" alt="error vs time, {esc(name)}">'
    return out + '</div>'


def crossover_text(c):
    if not isinstance(c, dict) or not finite(c.get('spp')):
        return '— (Cycles\' fit does not fall)'
    if c.get('extrapolated') == 'below':
        return (f'&le; {fsec(c.get("upper_bound_s"))} s (Cycles\' fewest samples already beat it; fit: '
                f'{c["spp"]:.2g} spp)')
    txt = f'{fsec(c.get("time_s"))} s at {c["spp"]:.3g} spp'
    if finite(c.get('render_s')):
        txt += f' ({fsec(c["render_s"])} s inside Blender)'
    if c.get('extrapolated') == 'above':
        txt += ' extrapolated'
    return txt


def sweep_overview_html(sweeps):
    """One row per scene: the headline numbers of every sweep."""
    rows = []
    for name, t in sweeps:
        cyc = next((sr for sr in t['series'] if isinstance(sr, dict) and sr.get('renderer') == 'cycles'), {})
        fs = cyc.get('fit_spp') if isinstance(cyc.get('fit_spp'), dict) else {}
        ft = cyc.get('fit') if isinstance(cyc.get('fit'), dict) else {}
        asis = t.get('as_is') if isinstance(t.get('as_is'), dict) else {}
        ref = t.get('reference') if isinstance(t.get('reference'), dict) else {}
        cb = t.get('crossover_best_raster') if isinstance(t.get('crossover_best_raster'), dict) else None
        off = finite(fs.get('slope')) and abs(fs['slope'] + 0.5) > 0.1
        rows.append(
            f'<tr><td><a href="#timing-{esc(safe_name(name))}">{esc(name)}</a></td>'
            f'<td class="num">{fexp(asis.get("error"))}</td><td class="num">{fsec(asis.get("time_s"))}</td>'
            f'<td class="num">{fexp(ref.get("noise_nrmse"))}</td>'
            f'<td class="num{" v-warn" if off else ""}">{fs.get("slope", float("nan")):.2f}</td>'
            f'<td class="num">{ft.get("slope", float("nan")):.2f}</td>'
            f'<td>{esc(cyc.get("slope_note", ""))}</td>'
            f'<td>{crossover_text(t.get("crossover"))}</td>'
            f'<td>{crossover_text(cb)}{" vs " + esc(cb.get("raster_label")) if cb else ""}</td></tr>')
    return ('<table class="grid"><thead><tr><th>scene</th><th>raster as-is error</th><th>its time (s)</th>'
            '<th>reference noise</th><th>Cycles slope / spp</th><th>Cycles slope / time</th><th>where not spp^-0.5</th>'
            '<th>crossover (vs raster as-is)</th><th>crossover (vs raster best)</th></tr></thead><tbody>'
            + ''.join(rows) + '</tbody></table>')


def sweep_scene_html(name, t, plots):
    ek = t.get('error_key') if isinstance(t.get('error_key'), str) else 'error'
    parts = [f'<h3 id="timing-{esc(safe_name(name))}">{esc(name)} <span class="dim small">'
             f'{esc("x".join(str(v) for v in t.get("size") or []))}, reference: Cycles validate '
             f'{esc((t.get("reference") or {}).get("samples"))} spp</span></h3><div class="flexrow">']
    if name in plots:
        parts.append(f'<img class="plot wide" src="{esc(plots[name])}" alt="error vs time, {esc(name)}">')
    fits = []
    for sr in t['series']:
        if not isinstance(sr, dict):
            continue
        cells = []
        for key in ('fit', 'fit_spp'):
            f = sr.get(key) if isinstance(sr.get(key), dict) else {}
            cells.append(f'<td class="num">{f["slope"]:.3f}</td><td class="num">{f.get("r2", float("nan")):.3f}</td>'
                         if finite(f.get('slope')) else '<td>—</td><td>—</td>')
        tm = sr.get('time_model') if isinstance(sr.get('time_model'), dict) else None
        tmt = f'{fsec(tm.get("t0_s"))} s + {fexp(tm.get("s_per_spp"))} s/spp' if tm else ''
        fits.append(f'<tr><td>{esc(sr.get("label"))}</td>{"".join(cells)}<td>{esc(tmt)}</td>'
                    f'<td>{esc(sr.get("slope_note", ""))}</td></tr>')
    parts.append('<div><table class="grid"><thead><tr><th>series</th><th>slope / time</th><th>r²</th>'
                 '<th>slope / spp</th><th>r²</th><th>time model</th><th>note</th></tr></thead><tbody>'
                 + ''.join(fits) + '</tbody></table>')
    eq = []
    for e in t.get('equal_time') or []:
        if not isinstance(e, dict):
            continue
        best = e.get('best') if isinstance(e.get('best'), dict) else {}
        cells = ''.join(
            f'<td class="num">{fexp(b.get("error"))} <span class="dim">{esc(b.get("label"))}, {fsec(b.get("time_s"))} s</span></td>'
            if isinstance(b, dict) else '<td class="dim">none within budget</td>'
            for b in (best.get(r) for r in ('raster', 'povray', 'cycles')))
        bname = esc(e.get('budget'))
        if not str(e.get('budget', '')).endswith(' s'):
            bname += f' ({fsec(e.get("budget_s"))} s)'
        eq.append(f'<tr><td>{bname}</td>{cells}'
                  f'<td class="num">{fexp(e.get("cycles_fit_error"))}</td></tr>')
    parts.append('<p class="small"><b>Equal time</b>: the lowest error each renderer reaches within the budget.</p>'
                 '<table class="grid"><thead><tr><th>budget</th><th>raster</th><th>POV-Ray</th><th>Cycles</th>'
                 '<th>Cycles (fit)</th></tr></thead><tbody>' + ''.join(eq) + '</tbody></table>')
    front = ', '.join(f'{esc(p.get("renderer"))} {esc(p.get("label"))}' for p in t.get('pareto') or []
                      if isinstance(p, dict))
    parts.append(f'<p class="small"><b>Pareto frontier</b> (fastest first): {front or "—"}</p>')
    parts.append(f'<p class="small"><b>Crossover</b> (Cycles\' noise below the raster as-is error): '
                 f'{crossover_text(t.get("crossover"))}</p>')
    skipped = t.get('skipped') or []
    if skipped:
        parts.append('<p class="small dim">Not measured: ' + '; '.join(
            f'{esc(k.get("label"))}: {esc(k.get("message"))}' for k in skipped if isinstance(k, dict)) + '</p>')
    parts.append('</div></div>')
    rows = []
    for sr in t['series']:
        for p in sr.get('points') or [] if isinstance(sr, dict) else []:
            if isinstance(p, dict):
                rows.append(f'<tr><td>{esc(sr.get("label"))}</td><td>{esc(p.get("label"))}</td>'
                            f'<td class="num">{fsec(p.get("time_s"))}</td><td class="num">{fsec(p.get("render_s"))}</td>'
                            + ''.join(f'<td class="num">{fexp(p.get(k))}</td>'
                                      for k in (ek, 'nrmse', 'rmse', 'rel_rms', 'noise_nrmse'))
                            + f'<td>{"cached" if p.get("cached") else ""}</td></tr>')
    parts.append('<details><summary class="small">every point</summary><table class="grid"><thead><tr>'
                 '<th>series</th><th>point</th><th>time (s)</th><th>in Blender (s)</th>'
                 f'<th>{esc(ek)}</th><th>nrmse</th><th>rmse</th><th>rel_rms</th><th>own noise</th><th></th>'
                 '</tr></thead><tbody>' + ''.join(rows) + '</tbody></table></details>')
    return ''.join(parts)


def timing_html(R, plots):
    tm = R['optional']['timing']
    if not tm:
        return ''
    parts = ['<section id="timing"><h2>Error vs time <span class="dim small">timing/*.json</span></h2>']
    sweeps = [(n, t) for n, t in tm if is_sweep(t)]
    if sweeps:
        doc = sweeps[0][1].get('error_doc')
        clock = 'CPU' if sweeps[0][1].get('clock') == 'cpu_s' else 'wall'
        parts.append('<p class="small">Every renderer\'s quality knobs, role validate, against Cycles at the highest '
                     f'spp (harness/sweep.py). Time: one job\'s {clock} time on one thread (POV-Ray and Cycles '
                     'include their start-up). Error: ' + esc(doc or 'see harness/sweep.py') + '. A Cycles slope '
                     'more than 0.1 from -0.5 is marked.</p>')
        parts.append(sweep_overview_html(sweeps))
    for name, t in tm:
        parts.append(sweep_scene_html(name, t, plots) if is_sweep(t) else timing_generic_html(name, t, plots))
    parts.append('</section>')
    return ''.join(parts)


def index_html(R, trends, timing_plots, history_note):
    n = verdict_counts(R)
    chips = ''.join(f'<span class="chip v-{v}"><b>{n[v]}</b> {v}</span>' for v in VERDICTS)
    vers = ''.join(f'<span class="chip plain"><b>{esc(k)}</b> {esc(v)}</span>' for k, v in R['versions'].items())
    roles = sorted({c['role'] for _, c in all_comparisons(R) if c['role']})
    role_opts = ''.join(f'<option value="{esc(r)}">{esc(r)}</option>' for r in roles)
    verdict_opts = ''.join(f'<option value="{v}">{v}</option>' for v in VERDICTS)
    trend_html = ''
    if trends:
        figs = ''.join(f'<figure><a href="{esc(s["page"])}"><img class="plot" src="{esc(trends[s["name"]])}" '
                       f'alt="trend {esc(s["name"])}"></a><figcaption>{esc(s["name"])}</figcaption></figure>'
                       for s in R['scenes'] if s['name'] in trends)
        trend_html = f'<section id="trends"><h2>Trends <span class="dim small">{esc(history_note)}</span></h2><div class="plots">{figs}</div></section>'
    else:
        trend_html = f'<section id="trends"><h2>Trends</h2><p class="dim">{esc(history_note)}</p></section>'
    fig1 = ('<section id="figure1"><h2>Figure 1</h2><img class="plot wide" src="figure1.svg" alt="figure 1"></section>'
            if R['optional']['figure1'] else '')
    body = f'''
<section class="overview"><p class="run-status">run status {badge(run_status(R))}</p>
<div class="chips">{chips}</div><div class="chips">{vers}</div></section>
{problems_html(R['problems'].items)}
<section id="comparisons">
<h2>Comparisons <span class="dim small">{sum(n.values())} rows · failures first</span></h2>
{role_legend()}
<div class="filters">
<input id="filter-text" type="search" placeholder="filter: scene, comparison, metric, message…" autocomplete="off">
<label>role <select id="filter-role"><option value="">all</option>{role_opts}</select></label>
<label>verdict <select id="filter-verdict"><option value="">all</option>{verdict_opts}</select></label>
<span id="filter-count" class="dim"></span>
</div>
<div class="scroll">{summary_table(R)}</div>
<p class="dim small">Metrics are on the surface region (interior pixels) unless a threshold names another region or layer.
Verdicts: <b>pass</b> within every threshold · <b>warn</b> over a warn threshold · <b>fail</b> over a fail threshold
· <b>skipped</b> a renderer is not installed or cannot represent the scene (see the renderer table)
· <b>error</b> a render crashed, failed, timed out or could not be written or read, so the comparison could not be
computed. Run status: <b>error</b> if anything errored, else <b>fail</b> if a comparison failed, else <b>ok</b>.</p>
</section>
<section id="renderers"><h2>Renderer jobs <span class="dim small">every job record; failures first</span></h2>
<div class="scroll">{jobs_rows(R, R['scenes'])}</div></section>
{trend_html}
{stability_html(R['optional'])}
{timing_html(R, timing_plots)}
{fig1}
'''
    return page(f'reflcheck {R["run_id"]}', 'index', top_header(R), body)


def metrics_table(c):
    groups = [('region', k, v) for k, v in c['regions'].items()] + [('aov', k, v) for k, v in c['aovs'].items()]
    objs = c.get('objects') if isinstance(c.get('objects'), list) else []
    groups += [('object', f'{o.get("object")} {o.get("material", "")}',
                {k: v for k, v in o.items() if k not in ('object', 'material')})
               for o in objs if isinstance(o, dict)]
    if not groups:
        return '<p class="dim">no metrics (comparison not measured)</p>'
    keys = []
    for _, _, ms in groups:
        for k in ms:
            if k not in keys and k not in ('max_x', 'max_y', 'max_c'):
                keys.append(k)
    head = '<tr><th></th><th></th>' + ''.join(f'<th>{esc(k)}</th>' for k in keys) + '<th>max at</th></tr>'
    rows = ''
    for g, name, ms in groups:
        at = f'{esc(ms.get("max_x"))},{esc(ms.get("max_y"))} {esc(chan_name(ms.get("max_c")))}' if 'max_x' in ms else ''
        rows += (f'<tr><td class="dim">{g}</td><td>{esc(name)}</td>' +
                 ''.join(f'<td class="num">{fmt_metric(k, ms.get(k))}</td>' for k in keys) +
                 f'<td class="num">{at}</td></tr>')
    return f'<table class="grid metrics"><thead>{head}</thead><tbody>{rows}</tbody></table>'


def comparison_block(s, c):
    th_rows = ''.join(
        f'<tr><td>{badge(t.get("verdict"))}</td><td>{esc(t["metric"])}</td>'
        f'<td class="num">{fmt_metric(t["metric"], t.get("value"))}</td>'
        f'<td class="num">{fthr(t["metric"], t.get("warn"))}</td>'
        f'<td class="num">{fthr(t["metric"], t.get("fail"))}</td><td>{esc(t.get("why"))}</td></tr>'
        for t in c['thresholds'])
    th = (f'<table class="grid"><thead><tr><th>verdict</th><th>metric</th><th>value</th><th>warn</th><th>fail</th>'
          f'<th>why</th></tr></thead><tbody>{th_rows}</tbody></table>' if th_rows else '<p class="dim">no thresholds</p>')
    noise = c.get('noise') or {}
    extra = []
    if finite(c.get('coverage_agreement')):
        extra.append(f'coverage agreement <span class="mono">{100 * c["coverage_agreement"]:.3f}%</span>')
    if finite(noise.get('ref_rel_rms')):
        extra.append(f'reference noise floor <span class="mono">{fexp(noise["ref_rel_rms"])}</span>')
    z = noise.get('ztest') or {}
    if z:
        extra.append('z-test ' + ' · '.join(f'{esc(k)} <span class="mono">{fmt_metric(k, v)}</span>'
                                            for k, v in z.items()))
    if finite(c.get('test_max')) and finite(c.get('ref_max')):
        # How each side copes with extremes: a half-float EXR (POV-Ray) turns values above
        # 65504 into Inf; Cycles' fireflies show as a reference maximum far above ours.
        extra.append(f'extremes: test max <span class="mono">{fexp(c["test_max"])}</span> '
                     f'({int(c.get("test_nonfinite") or 0)} NaN/Inf) · reference max '
                     f'<span class="mono">{fexp(c["ref_max"])}</span> ({int(c.get("ref_nonfinite") or 0)} NaN/Inf)')
    t = c.get('times') or {}
    if t:
        extra.append('times ' + ' · '.join(f'{esc(k)} <span class="mono">{v:.2f}</span>' for k, v in t.items()
                                           if finite(v)))
    return (f'<div class="comp" id="c-{esc(c["id"])}"><h3>{badge(c["status"])} {esc(c["id"])} '
            f'<span class="dim small">{esc(c["role"])} · test {esc(c["test"])} ({esc(c.get("test_key") or "no image")})'
            f' · reference {esc(c["reference"])} ({esc(c.get("ref_key") or "no image")})</span></h3>'
            + (f'<p class="reason">{esc(c["reason"])}</p>' if c.get('reason') else '')
            + (f'<p class="small">{" · ".join(extra)}</p>' if extra else '')
            + f'<div class="flexrow">{metrics_table(c)}{th}</div></div>')


def scene_html(R, s, angle_plots, trend):
    v = s['view']
    W, H = (v['width'], v['height']) if v else (4, 3)
    cw = 300
    ch = max(1, round(cw * H / W))
    images = v['images'] if v else []
    comps = [c for c in s['comparisons'] if not c.get('pseudo')]
    page_data = {'scene': s['name'], 'run_id': R['run_id'], 'view_src': f'{s["name"]}/view.js',
                 'images': images,
                 'comparisons': [{'id': c['id'], 'test': c['test'], 'reference': c['reference'], 'role': c['role'],
                                  'status': c['status'], 'testKey': c.get('test_key'), 'refKey': c.get('ref_key'),
                                  'rel_rms': c['regions'].get('surface', {}).get('rel_rms')} for c in comps]}
    panels = ''.join(f'<figure class="panel"><canvas class="view" width="{cw}" height="{ch}" data-layer="img:{esc(k)}">'
                     f'</canvas><figcaption>{esc(k)}</figcaption></figure>' for k in images)
    opts = ''.join(f'<option value="{esc(k)}">{esc(k)}</option>' for k in images)
    heats, noheat = '', []
    for c in comps:
        if c.get('test_key') and c.get('ref_key'):
            heats += (f'<figure class="panel"><canvas class="view" width="{cw}" height="{ch}" data-layer="heat:{esc(c["id"])}">'
                      f'</canvas><figcaption>{badge(c["status"])} {esc(c["id"])} <span class="dim">'
                      f'({esc(c["test_key"])} − {esc(c["ref_key"])}) surf rel_rms '
                      f'{fexp(c["regions"].get("surface", {}).get("rel_rms"))}</span></figcaption></figure>')
        else:
            noheat.append(f'{esc(c["id"])} ({esc(c["status"])}: '
                          f'{"no test image" if not c.get("test_key") else "no reference image"} in view.js)')
    flip = ''
    if len(images) >= 2:
        flip = (f'<figure class="panel flip"><canvas class="view" width="{cw}" height="{ch}" data-layer="flip"></canvas>'
                f'<figcaption>flip: <b id="flip-shown"></b> <span class="dim">(hover or press F to show B)</span>'
                f'</figcaption></figure>')
    angle = ''.join(f'<img class="plot" src="{esc(p)}" alt="error vs {esc(a)}">' for a, p in angle_plots.items())
    trend_img = (f'<img class="plot" src="{esc(trend)}" alt="trend of {esc(s["name"])}">' if trend
                 else '<p class="dim">no history yet (pass --history)</p>')
    viewer = ''
    if v:
        viewer = f'''
<section id="viewer"><h2>Images <span class="dim small">{W}×{H} linear RGB from {esc(s["name"])}/view.js</span></h2>
<div class="controls">
<label>exposure <input id="ev" type="range" min="-10" max="10" step="0.25" value="0"></label>
<span id="ev-label" class="mono">EV +0.00 (×1)</span>
<button id="ev-reset" type="button">EV 0</button>
<button id="view-reset" type="button" title="or double-click an image">fit</button>
<label>A <select id="flip-a">{opts}</select></label>
<label>B <select id="flip-b">{opts}</select></label>
<label>flip <select id="flip-mode"><option value="hover">on hover</option><option value="toggle">toggle (F)</option></select></label>
<button id="flip-toggle" type="button">flip A/B</button>
<label><input id="mask-bg" type="checkbox"> grey out background in heatmaps</label>
</div>
<p class="dim small">Display: value × 2<sup>EV</sup>, clamped to [0, 1], then the sRGB transfer curve (linear ≤ 0.0031308 × 12.92,
else 1.055 v<sup>1/2.4</sup> − 0.055); NaN/Inf shown magenta. All views share zoom and pan: wheel zooms at the cursor,
drag pans, double-click fits. Pixels are drawn nearest-neighbour.</p>
<div class="viewer-wrap"><div class="panels">{panels}{flip}</div>
<aside id="probe-box"><h3>pixel probe <span id="probe-xy" class="mono dim"></span></h3><table id="probe" class="grid"></table>
<p class="dim small">hover an image: linear values of every image, N·V, coverage, relative error per comparison.</p></aside></div>
<h3>Error heatmaps</h3>
<p class="dim small">Per pixel: max over R,G,B of |test − ref| / √(ref² + 10<sup>−8</sup>) (the compare step's relative
error), log<sub>10</sub> colour scale fixed from 10<sup>−5</sup> to 1 for every comparison and renderer; below the scale
(including exact 0) = darkest, above = brightest, NaN = magenta.</p>
<canvas id="heat-legend" width="420" height="42"></canvas>
<div class="panels">{heats}</div>
{'<p class="dim small">no heatmap: ' + '; '.join(noheat) + '</p>' if noheat else ''}
</section>'''
    else:
        viewer = '<section id="viewer"><h2>Images</h2><p class="problem-text">view.js is missing or corrupt: no images (see the problems above).</p></section>'
    body = f'''
<section class="overview"><h1>{esc(s["name"])} <span class="dim small">{esc(s["title"])}</span></h1>
<p class="dim small mono">{esc(s["scene_path"])}</p></section>
{problems_html(R['problems'].items, s['name'])}
<section id="comparisons"><h2>Comparisons</h2>{''.join(comparison_block(s, c) for c in sorted(s['comparisons'], key=lambda c: VERDICT_ORDER.get(c['status'], 0)))}</section>
{viewer}
<section id="angles"><h2>Error vs angle <span class="dim small">surface rel_rms per N·V and N·L bin (compare.json angle_bins)</span></h2>
<div class="plots">{angle or '<p class="dim">no angle bins in compare.json</p>'}</div></section>
<section id="trend"><h2>Trend</h2><div class="plots">{trend_img}</div></section>
<section id="renderers"><h2>Renderer jobs</h2><div class="scroll">{jobs_rows(R, [s])}</div></section>
'''
    scripts = (f'<script src="{esc(s["name"])}/view.js"></script>\n' if v else '') + \
        f'<script>window.REFLCHECK_PAGE = {json_script(page_data)};</script>\n'
    crumb = f' <span class="sep">/</span> <a href="index.html">{esc(R["run_id"])}</a> <span class="sep">/</span> {esc(s["name"])}'
    return page(f'{s["name"]} · reflcheck {R["run_id"]}', 'scene', top_header(R, crumb), body, scripts)


# ---------------------------------------------------------------------------------------------
# Threshold proposals

def round_up_1sig(v):
    """Smallest 1-significant-digit number >= v (2.34e-4 -> 3e-4)."""
    if v <= 0:
        return v
    e = math.floor(math.log10(v))
    # Guards against 2.0000000001 / 1e-4 rounding up to 3 because of binary floating point.
    m = math.ceil(v / 10 ** e * (1 - 1e-12))
    if m >= 10:
        m, e = 1, e + 1
    return float(f'{m}e{e}')


def yaml_num(v):
    if not is_num(v):
        return str(v)
    if v == 0:
        return '0'
    if 0.1 <= abs(v) < 1e4:
        return f'{v:.6g}'
    s = f'{v:.6e}'
    m, e = s.split('e')
    m = m.rstrip('0').rstrip('.')
    return f'{m}e{int(e)}'


def precision_floor(c, t):
    for k in ('floor', 'precision_floor'):
        if is_num(t.get(k)):
            return t[k]
    pf = c.get('precision_floor')
    if is_num(pf):
        return pf
    if isinstance(pf, dict) and is_num(pf.get(t['metric'])):
        return pf[t['metric']]
    return None


def propose(c, t):
    """(warn, fail, note) for one threshold. Error-like metrics: warn = 2x, fail = 4x the measured
    value, rounded up to 1 significant digit, never below the precision floor. psnr: 2x / 4x the
    RMS error is -6.02 / -12.04 dB. ssim, coverage_agreement: the same on 1 - value."""
    metric = t['metric']
    base = metric.split('.')[-1]
    v = t.get('value')
    floor = precision_floor(c, t)
    if not finite(v):
        return None, None, 'no measurement: unchanged'
    if base == 'psnr':
        warn, fail = math.floor(v - 20 * math.log10(2)), math.floor(v - 20 * math.log10(4))
        if floor is not None:
            warn, fail = min(warn, floor), min(fail, floor)
        return warn, fail, f'measured {v:.2f} dB'
    if base in ('ssim', 'coverage_agreement'):
        d = 1 - v
        if d <= 0:
            return None, None, f'measured {v}: no room below 1: unchanged'
        warn, fail = 1 - round_up_1sig(2 * d), 1 - round_up_1sig(4 * d)
        if floor is not None:
            warn, fail = min(warn, floor), min(fail, floor)
        return round(warn, 12), round(fail, 12), f'measured {v:.6f}'
    if v <= 0 and floor is None:
        return None, None, 'measured 0 and no precision floor: unchanged'
    warn, fail = round_up_1sig(2 * v), round_up_1sig(4 * v)
    note = f'measured {fexp(v)}'
    if floor is not None and floor > 0:
        fl = round_up_1sig(floor)
        if warn < fl:
            warn = fl
            note += f', raised to the precision floor {fexp(floor)}'
        if fail <= warn:
            fail = round_up_1sig(2 * warn)
    return warn, fail, note


def yaml_line(t, warn, fail):
    """One threshold as the scene files write it (scenes/FORMAT.md): metric: {warn, fail, why}."""
    extra = f', why: "{t["why"]}"' if t.get('why') else ''
    return f'      {t["metric"]}: {{warn: {yaml_num(warn)}, fail: {yaml_num(fail)}{extra}}}'


def proposal(R):
    """Unified-diff-like text per scene file and the structured rows for the HTML page."""
    lines, rows = [], []
    for s in R['scenes']:
        path = s['scene_path'] or f'scenes/{s["name"]}.yaml'
        lines.append(f'--- {path}\t(current thresholds, from {s["name"]}/compare.json)')
        lines.append(f'+++ {path}\t(proposed: warn = 2x, fail = 4x measured, 1 significant digit up, '
                     'never below the precision floor)')
        for c in s['comparisons']:
            if c.get('pseudo'):
                lines.append(f'@@ {c["id"]}: {c["reason"]} @@')
                continue
            lines.append(f'@@ {c["id"]} ({c["role"]}, {c["status"]}) @@')
            test = '' if c.get('test', 'raster') == 'raster' else f'test: {c["test"]}, '
            lines.append(f'   - {{{test}reference: {c.get("reference", "?")}, role: {c["role"]}}}')
            lines.append('     thresholds:')
            if not c['thresholds']:
                lines.append('     # no thresholds in compare.json')
            for t in c['thresholds']:
                warn, fail = t.get('warn'), t.get('fail')
                nw, nf, note = propose(c, t)
                cur = yaml_line(t, warn, fail)
                row = {'scene': s['name'], 'comparison': c['id'], 'metric': t['metric'], 'value': t.get('value'),
                       'warn': warn, 'fail': fail, 'new_warn': nw, 'new_fail': nf, 'note': note,
                       'verdict': t.get('verdict'), 'floor': precision_floor(c, t)}
                rows.append(row)
                if nw is None or (nw == warn and nf == fail):
                    lines.append(f' {cur}    # {note}')
                else:
                    lines.append(f'-{cur}    # {note}')
                    lines.append(f'+{yaml_line(t, nw, nf)}')
    return '\n'.join(lines) + '\n', rows


def proposal_html(R, text, rows):
    diff = ''.join(f'<div class="d{" add" if ln.startswith("+") and not ln.startswith("+++") else " del" if ln.startswith("-") and not ln.startswith("---") else " hunk" if ln.startswith("@@") else " file" if ln.startswith(("---", "+++")) else ""}">{esc(ln)}</div>'
                   for ln in text.splitlines())
    trs = ''.join(
        f'<tr><td>{esc(r["scene"])}</td><td>{esc(r["comparison"])}</td><td>{esc(r["metric"])}</td>'
        f'<td>{badge(r["verdict"])}</td><td class="num">{fmt_metric(r["metric"], r["value"])}</td>'
        f'<td class="num">{fmt_metric(r["metric"], r["floor"])}</td>'
        f'<td class="num">{fthr(r["metric"], r["warn"])}</td><td class="num">{fthr(r["metric"], r["fail"])}</td>'
        f'<td class="num new">{fthr(r["metric"], r["new_warn"])}</td>'
        f'<td class="num new">{fthr(r["metric"], r["new_fail"])}</td><td class="small">{esc(r["note"])}</td></tr>'
        for r in rows)
    body = f'''
<section><h1>Threshold proposal</h1>
<p class="small">For every measured threshold: warn = 2× and fail = 4× the measured value, rounded up to one significant digit and
never below the precision floor in compare.json (PSNR: −6.02 / −12.04 dB; SSIM and coverage: the same on 1 − value).
This page only proposes: scene files are never edited — copy the <span class="add-text">+</span> lines into the scene YAML by hand.</p>
<table class="grid"><thead><tr><th>scene</th><th>comparison</th><th>metric</th><th>verdict</th><th>measured</th><th>floor</th>
<th>warn</th><th>fail</th><th>new warn</th><th>new fail</th><th>note</th></tr></thead><tbody>{trs}</tbody></table>
<h2>Diff</h2><pre class="diff">{diff}</pre></section>'''
    crumb = f' <span class="sep">/</span> <a href="index.html">{esc(R["run_id"])}</a> <span class="sep">/</span> thresholds'
    return page(f'thresholds · reflcheck {R["run_id"]}', 'proposal', top_header(R, crumb), body)


# ---------------------------------------------------------------------------------------------
# Chromium (headless): screenshots and DOM dumps of the pages from disk

def chromium_exe():
    for n in ('chromium', 'chromium-browser', 'google-chrome'):
        p = shutil.which(n)
        if p:
            return p
    return None


def chromium(args, page_path, timeout=CHROMIUM_TIMEOUT_S):
    """Runs headless chromium on a file:// page; returns CompletedProcess (stdout = DOM if asked)."""
    exe = chromium_exe()
    if not exe:
        raise FileNotFoundError('chromium not found; apt-get install chromium')
    with tempfile.TemporaryDirectory(prefix='reflcheck-chromium-') as prof:
        cmd = [exe, '--headless', '--no-sandbox', '--disable-gpu', '--disable-background-networking',
               '--disable-component-update', '--disable-sync', '--no-first-run', '--hide-scrollbars',
               f'--user-data-dir={prof}', '--virtual-time-budget=5000'] + args + \
            ['file://' + os.path.abspath(page_path)]
        return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)


def screenshot(page_path, png, size='1400,1000'):
    tmp = f'{png}.tmp{os.getpid()}.png'
    r = chromium([f'--screenshot={tmp}', f'--window-size={size}'], page_path)
    if not os.path.exists(tmp):
        raise RuntimeError(f'chromium wrote no screenshot ({r.returncode}): {r.stderr.strip()[-300:]}')
    os.replace(tmp, png)


def dump_dom(page_path):
    return chromium(['--dump-dom'], page_path).stdout


def check_pages(run, pages):
    """[(page, why)] for every page whose DOM in headless Chromium does not show all of its
    images loaded (data-loaded="n/n", data-failed="0") or, for the index, no table rows."""
    bad = []
    for name in pages:
        dom = dump_dom(os.path.join(run, name))
        m = re.search(r'data-loaded="(\d+)/(\d+)"', dom)
        failed = re.search(r'data-failed="(\d+)"', dom)
        if not m or m.group(1) != m.group(2) or (failed and failed.group(1) != '0'):
            bad.append((name, f'images loaded {m.group(0) if m else "marker missing"}, '
                              f'failed {failed.group(1) if failed else "?"}'))
        elif name == 'index.html' and '<tr' not in dom:
            bad.append((name, 'the comparisons table has no rows'))
    return bad


# ---------------------------------------------------------------------------------------------

def copy_assets(run):
    for f in ('report.css', 'report.js'):
        with open(os.path.join(ASSETS, f), 'rb') as src:
            write_atomic(os.path.join(run, f), src.read())


def make_report(args):
    R = load_run(args.run, args.commit)
    problems = R['problems']
    copy_assets(args.run)
    os.makedirs(os.path.join(args.run, 'plots'), exist_ok=True)
    history = []
    if args.history:
        rec = history_record(R)
        try:
            if not append_history(args.history, rec, problems):
                print(f'report: {args.history}: run {R["run_id"]} already recorded with the same figures; '
                      'not appended again', file=sys.stderr)
        except OSError as e:
            problems.add(args.history, f'cannot append to history: {e.strerror}')
        history = read_history(args.history, problems)
        note = f'{args.history}: {len(history)} run{"" if len(history) == 1 else "s"}'
    else:
        note = 'no --history file given: trends need reports/history.jsonl'
    with tempfile.TemporaryDirectory(prefix='reflcheck-report-') as tmp:
        angles = {s['name']: plot_angles(R, s, tmp, problems) for s in R['scenes']}
        trends = plot_trends(R, history, tmp, problems) if history else {}
        timing = plot_timing(R, tmp, problems)
    for s in R['scenes']:
        write_atomic(os.path.join(args.run, s['page']), scene_html(R, s, angles[s['name']], trends.get(s['name'])))
    write_atomic(os.path.join(args.run, 'summary.json'),
                 json.dumps(summary_object(R), indent=1, allow_nan=False) + '\n')
    write_atomic(os.path.join(args.run, 'summary.csv'), summary_csv(R))
    write_atomic(os.path.join(args.run, 'junit.xml'), junit_xml(R))
    write_atomic(os.path.join(args.run, 'index.html'), index_html(R, trends, timing, note))
    if args.latest:
        point_latest(args.run, args.latest, problems)
    if args.screenshot:
        try:
            screenshot(os.path.join(args.run, 'index.html'), os.path.join(args.run, 'screenshot.png'))
            if R['scenes']:
                screenshot(os.path.join(args.run, R['scenes'][0]['page']),
                           os.path.join(args.run, 'screenshot-scene.png'), '1400,1400')
            # The report as a person opens it: every page in headless Chromium, every table row
            # and image loaded (report.js's markers); a page that fails is named, not ignored.
            bad = check_pages(args.run, ['index.html'] + [sc['page'] for sc in R['scenes']])
            for page_name, why in bad:
                print(f'report: {page_name}: {why}', file=sys.stderr)
            print(f'report: opened {1 + len(R["scenes"]) - len(bad)} of {1 + len(R["scenes"])} pages in '
                  f'headless Chromium with every image loaded')
            if bad:
                return 1
        except (OSError, RuntimeError, subprocess.TimeoutExpired) as e:
            print(f'report: screenshot failed: {e}', file=sys.stderr)
    n = verdict_counts(R)
    print(f'report: {os.path.join(args.run, "index.html")}: ' + ', '.join(f'{n[v]} {v}' for v in VERDICTS)
          + f'; {len(problems.items)} input problems')
    return 0


def point_latest(run, latest, problems):
    """Symlink to a temporary name, then rename over the old link: readers see old or new."""
    target = os.path.relpath(os.path.abspath(run), os.path.dirname(os.path.abspath(latest)))
    tmp = f'{latest}.tmp{os.getpid()}'
    try:
        if os.path.lexists(tmp):
            os.unlink(tmp)
        os.symlink(target, tmp)
        if os.path.isdir(latest) and not os.path.islink(latest):
            os.unlink(tmp)
            problems.add(latest, 'is a real folder, not a symlink; remove it so --latest can point it at the run')
            return
        os.replace(tmp, latest)
    except OSError as e:
        problems.add(latest, f'cannot point at the run: {e.strerror}')


def propose_main(args):
    R = load_run(args.run, args.commit)
    text, rows = proposal(R)
    sys.stdout.write(text)
    copy_assets(args.run)
    write_atomic(os.path.join(args.run, 'thresholds-proposal.html'), proposal_html(R, text, rows))
    print(f'report: wrote {os.path.join(args.run, "thresholds-proposal.html")} (scene files unchanged)',
          file=sys.stderr)
    return 0


def main(argv=None):
    ap = argparse.ArgumentParser(description='Write the reflcheck report of one run folder.')
    ap.add_argument('--run', required=True, help='run folder, e.g. reports/runs/20250101-120000-abc1234')
    ap.add_argument('--history', help='append-only JSON-lines history, e.g. reports/history.jsonl')
    ap.add_argument('--commit', help='commit of the run (default: from the run id, else "unknown")')
    ap.add_argument('--latest', help='symlink to point at this run, e.g. reports/latest')
    ap.add_argument('--screenshot', action='store_true',
                    help='after writing, save screenshot.png (index) and screenshot-scene.png with headless chromium')
    ap.add_argument('--propose-thresholds', action='store_true',
                    help='print current and proposed thresholds, write thresholds-proposal.html, nothing else')
    args = ap.parse_args(argv)
    if not os.path.isdir(args.run):
        print(f'report: {args.run}: no such run folder; pass --run reports/runs/<id>', file=sys.stderr)
        return 2
    try:
        return propose_main(args) if args.propose_thresholds else make_report(args)
    except OSError as e:
        print(f'report: {getattr(e, "filename", "") or args.run}: cannot write: {e.strerror or e}', file=sys.stderr)
        return 1


if __name__ == '__main__':
    sys.exit(main())
