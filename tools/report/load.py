"""load - a run folder -> the report's data: scenes with their comparisons, job records and
view.js summary, the run's identity, renderer versions and the optional inputs (stability,
timing). Every missing or corrupt input file becomes a Problems entry, never an exception.
"""

import base64
import datetime as dt
import json
import os
import re

from .util import TOOLS, VERDICT_ORDER, VERDICTS, Problems, finite, is_num, read_json, safe_name

# A comparison side reads its renderer's render of the comparison's role (the C harness renders
# every role separately). Run folders from before that name the render a role stood in for: an
# agree comparison read the validate renders, and a validate comparison a renderer's twin render
# when it had no other (the rasterizer's). Roles only: which renderers exist comes from the files.
ROLE_STANDS_IN = {'agree': 'validate', 'validate': 'twin'}


def pick_render(renders, renderer, role):
    """The key '<renderer>-<role>' among `renders` (the scene's view.js images or job records)
    that a comparison side of `renderer` in `role` reads, or None."""
    for r in (role, ROLE_STANDS_IN.get(role)):
        if r and f'{renderer}-{r}' in renders:
            return f'{renderer}-{r}'
    return None


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
    # The prefix by a regular expression, the rest by slicing: a lazy (.*?) up to $ over the
    # megabytes of base64 cost a second per run.
    m = re.match(r'\s*window\.REFLCHECK_VIEW\s*=\s*', text)
    if not m:
        problems.add(path, 'view.js does not start with "window.REFLCHECK_VIEW ="; re-run compare', scene)
        return None
    body = text[m.end() :].rstrip()
    body = body[:-1] if body.endswith(';') else body
    try:
        v = json.loads(body)
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
            problems.add(
                path, f'view.js image "{name}" has {n} bytes, expected {w}x{h}x3 float32 = ' f'{w * h * 12}', scene
            )
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
        return {
            'id': f'comparison {index}',
            'status': 'error',
            'role': '',
            'test': '',
            'reference': '',
            'reason': f'{os.path.basename(path)}: comparisons[{index}] is not an object',
            'regions': {},
            'aovs': {},
            'terms': {},
            'thresholds': [],
            'times': {},
        }
    out = dict(c)
    out['id'] = str(c.get('id') or f'{c.get("test", "?")}-vs-{c.get("reference", "?")}-{c.get("role", "?")}')
    status = str(c.get('status', 'error')).lower()
    if status not in VERDICT_ORDER:
        problems.add(path, f'comparison {out["id"]}: unknown status "{status}" ({"|".join(VERDICTS)})', scene)
        status = 'error'
    out['status'] = status
    for key in ('regions', 'aovs', 'terms', 'times', 'noise'):
        if not isinstance(out.get(key), dict):
            out[key] = {}
    for key in ('regions', 'aovs', 'terms'):
        out[key] = {k: v for k, v in out[key].items() if isinstance(v, dict)}
    th = out.get('thresholds')
    out['thresholds'] = [t for t in th if isinstance(t, dict) and 'metric' in t] if isinstance(th, list) else []
    for key in ('angle_bins', 'angle_bins_ndoth', 'angle_bins_ndotl'):
        b = out.get(key)
        out[key] = [x for x in b if isinstance(x, dict)] if isinstance(b, list) else []
    for key in ('role', 'test', 'reference', 'reason', 'physics'):
        out[key] = '' if out.get(key) is None else str(out[key])
    return out


def reserved_names():
    """The names a run folder holds itself: model/reserved_names.def, the list the C side checks
    scene names against (one '"name",' per line)."""
    path = os.path.join(os.path.dirname(TOOLS), 'model', 'reserved_names.def')
    with open(path, encoding='utf-8') as f:
        return {m.group(1) for m in re.finditer(r'^"([^"]+)",$', f.read(), re.M)}


def scene_dirs(run):
    out = []
    reserved = reserved_names()
    for name in sorted(os.listdir(run)):
        p = os.path.join(run, name)
        if name.startswith('.') or name in reserved or not os.path.isdir(p):
            continue
        files = os.listdir(p)
        if 'compare.json' in files or 'view.js' in files or any(f.endswith('.json') for f in files):
            out.append(name)
    return out


JOB_FILE = re.compile(r'^([a-z0-9_]+)-([a-z0-9_]+)\.json$')
# The scene folder's JSON files that are not render job records, though fit-wide.json has the
# job records' name shape: compare's output and the fit step's (load_fits reads those).
FIT_FILES = (('fit.json', 'seed'), ('fit-wide.json', 'wide'))
NOT_JOB_FILES = ('compare.json',) + tuple(f for f, _ in FIT_FILES)
# Figure 1 of the scene's own materials (`reflcheck eval materials SCENE`, written by the nightly).
FIGURE1_FILE = 'figure1.json'


def load_scene(run, name, problems):
    d = os.path.join(run, name)
    sc = {
        'name': name,
        'page': f'scene-{safe_name(name)}.html',
        'title': '',
        'scene_path': '',
        'comparisons': [],
        'jobs': [],
        'view': None,
        'compare_ok': False,
    }
    cpath = os.path.join(d, 'compare.json')
    comp = read_json(cpath, problems, 'compare.json', name)
    if comp is not None and not (isinstance(comp, dict) and isinstance(comp.get('comparisons', []), list)):
        problems.add(cpath, 'compare.json has no "comparisons" list; re-run compare', name)
        comp = None
    if comp is None:
        why = 'missing' if not os.path.exists(cpath) else 'corrupt'
        sc['comparisons'].append(
            {
                'id': '(compare.json)',
                'status': 'error',
                'role': '',
                'test': '',
                'reference': '',
                'pseudo': True,
                'reason': f'{name}/compare.json {why}: no comparison could be read',
                'regions': {},
                'aovs': {},
                'terms': {},
                'thresholds': [],
                'times': {},
                'noise': {},
                'angle_bins': [],
                'angle_bins_ndoth': [],
                'angle_bins_ndotl': [],
            }
        )
    else:
        sc['compare_ok'] = True
        sc['title'] = str(comp.get('title') or '')
        sc['scene_path'] = str(comp.get('scene_path') or '')
        for i, c in enumerate(comp.get('comparisons', [])):
            sc['comparisons'].append(norm_comparison(c, cpath, problems, name, i))
    for f in sorted(os.listdir(d)):
        m = JOB_FILE.match(f)
        if not m or f in NOT_JOB_FILES:
            continue
        p = os.path.join(d, f)
        rec = read_json(p, problems, 'job record', name)
        if rec is None:
            sc['jobs'].append(
                {
                    'renderer': m.group(1),
                    'role': m.group(2),
                    'status': 'error',
                    'message': f'{name}/{f}: unreadable job record',
                    'file': f,
                }
            )
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
    sc['fits'] = load_fits(d, problems, name)
    sc['figure1'] = load_figure1(d, problems, name)
    sc['figure1_page'] = f'figure1-{safe_name(name)}.html' if sc['figure1'] else None
    images = sc['view']['images'] if sc['view'] else []
    jobs = {}
    for j in sc['jobs']:
        jobs.setdefault(f'{j.get("renderer")}-{j.get("role")}', j)
    for c in sc['comparisons']:
        if c.get('pseudo'):
            continue
        for side, image_key, job_key in (('test', 'test_key', 'test_job'), ('reference', 'ref_key', 'ref_job')):
            c[image_key] = pick_render(images, c[side], c['role'])
            c[job_key] = jobs.get(pick_render(jobs, c[side], c['role']))
    return sc


def load_figure1(d, problems, name):
    """The scene's materials' reflectance against angle (model beside physics), as
    {'angle_deg': [...], 'value': text, 'materials': [{name, kind, model_curve, physics_curve,
    model: [...], physics: [...]}]}; None when the run has no figure1.json (an older run) or it
    does not hold one finite value per angle for each curve (listed as a problem)."""
    path = os.path.join(d, FIGURE1_FILE)
    if not os.path.exists(path):
        return None
    doc = read_json(path, problems, 'Figure 1 data', name)
    if doc is None:
        return None
    angles = doc.get('angle_deg') if isinstance(doc, dict) else None
    mats = doc.get('materials') if isinstance(doc, dict) else None
    ok = isinstance(angles, list) and angles and all(finite(a) for a in angles) and isinstance(mats, list)
    for m in mats if ok else []:
        ok = ok and isinstance(m, dict) and isinstance(m.get('name'), str)
        for key in ('model', 'physics'):
            v = m.get(key) if isinstance(m, dict) else None
            ok = ok and isinstance(v, list) and len(v) == len(angles) and all(finite(x) for x in v)
    if not ok:
        problems.add(
            path,
            'Figure 1 data without one finite value per angle for each curve; re-run ' 'reflcheck eval materials SCENE',
            name,
        )
        return None
    return {'angle_deg': angles, 'value': str(doc.get('value') or ''), 'materials': mats}


def load_fits(d, problems, name):
    """The fit records of a scene (`reflcheck fit`: fit.json within the seeds' ranges,
    fit-wide.json within wide ones), one dict per validate comparison and bounds; [] when the
    run has none (the fit step is optional)."""
    out = []
    for fname, bounds in FIT_FILES:
        path = os.path.join(d, fname)
        if not os.path.exists(path):
            continue
        rec = read_json(path, problems, 'fit record', name)
        if rec is None:
            continue
        if not isinstance(rec, dict) or not isinstance(rec.get('fits'), list):
            problems.add(path, f'{fname} has no "fits" list; re-run reflcheck fit', name)
            continue
        for f in rec['fits']:
            if not isinstance(f, dict):
                continue
            f = dict(f)
            f['variant'] = str(rec.get('variant') or '')
            f['bounds'] = str(rec.get('bounds') or bounds)
            f['parameters'] = [q for q in f.get('parameters') or [] if isinstance(q, dict)]
            for k in ('authored', 'best'):
                f[k] = f[k] if isinstance(f.get(k), dict) else {}
            out.append(f)
    return out


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
    return {
        'uname': f'{u.sysname} {u.release} {u.version} {u.machine}',
        'node': u.nodename,
        'cpu_model': cpu,
        'cores': os.cpu_count(),
    }


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
        opt['stability'] = {
            'meta': st if isinstance(st, dict) else {},
            'rows': [r for r in rows if isinstance(r, dict)] if rows else [],
        }
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
    return {
        'dir': run,
        'run_id': run_id,
        'commit': commit,
        'time': when,
        'report_time': dt.datetime.now(dt.timezone.utc).strftime('%Y-%m-%dT%H:%M:%SZ'),
        'machine': machine_info(),
        'versions': renderer_versions(scenes),
        'scenes': scenes,
        'problems': problems,
        'optional': load_optional(run, problems),
    }


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
    for term, ms in c.get('terms', {}).items():
        for k, v in ms.items():
            if is_num(v):
                out[f'term.{term}.{k}'] = v
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
