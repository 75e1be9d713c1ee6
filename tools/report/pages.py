"""pages - the HTML pages of a run: index.html, scene-<name>.html, thresholds-proposal.html.

Markup lives in templates/ (Jinja2, autoescape on: every value is HTML-escaped where it is
written, so no escaping by hand). This module only arranges the data the templates show.
Element ids, data attributes and canvas layer names come from report_assets/ids.json, which
every page also embeds for report.js (window.REFLCHECK_IDS).
"""

import functools
import math
import os

import jinja2
from markupsafe import Markup

from .answer import answer_rows
from .load import all_comparisons, run_status, verdict_counts
from .plots import is_sweep, timing_points
from .util import (
    JOB_ORDER,
    VERDICT_ORDER,
    VERDICTS,
    chan_name,
    fexp,
    finite,
    fmt_metric,
    fsec,
    fthr,
    is_num,
    json_script,
    load_ids,
    safe_name,
)

# The index page's legend of comparison roles.
ROLE_LEGEND = {
    'twin': 'the reference renderer is set up to compute exactly our model; any difference is a '
    'translation or renderer bug',
    'validate': 'our real-time approximation against a physically based render of the scene\'s one '
    'physics (printed beside the figure); the difference is the approximation\'s own error',
    'agree': 'POV-Ray\'s validate render against Cycles\' validate render, the same two jobs; how far '
    'the references agree (the floor under every validate figure)',
}

TEMPLATES = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'templates')
IDS = load_ids()


def _plain(f):
    """A template global taking Python values: a missing key (jinja2.Undefined) arrives as None,
    as dict.get would give it."""
    return lambda *a: f(*(None if isinstance(x, jinja2.Undefined) else x for x in a))


def text(v):
    return '' if v is None else str(v)


@functools.cache
def _env():
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(TEMPLATES),
        autoescape=True,
        trim_blocks=True,
        lstrip_blocks=True,
        undefined=jinja2.Undefined,
        finalize=lambda v: '' if v is None else v,
    )
    env.globals.update(
        fmt=_plain(fmt_metric),
        fthr=_plain(fthr),
        fexp=_plain(fexp),
        fsec=_plain(fsec),
        chan=_plain(chan_name),
        crossover_text=_plain(crossover_text),
        ids={k: v for k, v in IDS.items() if not k.startswith('_')},
        I=IDS['id'],
        A=IDS['attr'],
        C=IDS['cls'],
        L=IDS['layer'],
        G=IDS['global'],
    )
    env.tests.update(finite=finite, num=is_num)
    env.filters['json_script'] = lambda o: Markup(json_script(o))
    return env


def render(template, kind, **data):
    return _env().get_template(template).render(kind=IDS['page'][kind], **data)


# ---------------------------------------------------------------------------------------------
# Pieces of data several pages show


def job_rows(R, scenes):
    """Job records of the scenes, failures first, with their size text and log link."""
    rows = [(s, j) for s in scenes for j in s['jobs']]
    rows.sort(
        key=lambda sj: (
            JOB_ORDER.get(str(sj[1].get('status')), 0),
            sj[0]['name'],
            str(sj[1].get('renderer')),
            str(sj[1].get('role')),
        )
    )
    out = []
    for s, j in rows:
        size = ''
        if j.get('width'):
            size = f'{text(j.get("width"))}×{text(j.get("height"))}'
            if j.get('supersample'):
                size += f' ss{j["supersample"]}'
            if j.get('samples'):
                size += f' {j["samples"]}spp'
        out.append(
            {
                'scene': s,
                'job': j,
                'status': str(j.get('status', '?')),
                'size': size,
                'log': j.get('log') or '',
                'log_href': log_href(R, s, j),
            }
        )
    return out


def log_href(R, s, j):
    """The job's log relative to the run folder, or None when it names none or it is gone."""
    p = j.get('log') or ''
    if not p:
        return None
    cands = [p] if os.path.isabs(p) else [p, os.path.join(R['dir'], p), os.path.join(R['dir'], s['name'], p)]
    for cpath in cands:
        if os.path.exists(cpath):
            return os.path.relpath(os.path.abspath(cpath), os.path.abspath(R['dir']))
    return None


def crossover_text(c):
    if not isinstance(c, dict) or not finite(c.get('spp')):
        return '— (Cycles\' fit does not fall)'
    if c.get('extrapolated') == 'below':
        return (
            f'≤ {fsec(c.get("upper_bound_s"))} s (Cycles\' fewest samples already beat it; fit: ' f'{c["spp"]:.2g} spp)'
        )
    txt = f'{fsec(c.get("time_s"))} s at {c["spp"]:.3g} spp'
    if finite(c.get('render_s')):
        txt += f' ({fsec(c["render_s"])} s inside Blender)'
    if c.get('extrapolated') == 'above':
        txt += ' extrapolated'
    return txt


def _dict(v):
    return v if isinstance(v, dict) else {}


# ---------------------------------------------------------------------------------------------
# Index page


def stability_rows(opt):
    st = opt['stability']
    if st is None:
        return None
    return [
        (
            r,
            any(finite(r.get(k)) and r.get(k) > 0 for k in ('nan', 'inf', 'negative'))
            or (r.get('expect_ok') == 1 and r.get('check_ok') == 0),
        )
        for r in st['rows']
    ]


def fit_rows(R):
    """One row per fitted validate comparison (RUN/<scene>/fit.json): the scene's page, its
    record, the fitted values as text and whether any value sits at a bound of its range."""
    rows = []
    for s in R['scenes']:
        for f in s.get('fits', []):
            params = [
                f'{q.get("material", "?")}.{q.get("name", "?")} {fmt_metric("value", q.get("authored"))}'
                f' → {fmt_metric("value", q.get("fitted"))}{" (at bound)" if q.get("at_bound") else ""}'
                for q in f['parameters']
            ]
            rows.append({'scene': s, 'fit': f, 'params': params})
    return rows


def sweep_overview(sweeps):
    """One row per scene: the headline numbers of every sweep."""
    rows = []
    for name, t in sweeps:
        ref = _dict(t.get('reference'))
        # the reference renderer's own series (spp levels) carries the fits against samples
        cyc = next((sr for sr in t['series'] if isinstance(sr, dict) and sr.get('renderer') == ref.get('renderer')), {})
        fs, ft = _dict(cyc.get('fit_spp')), _dict(cyc.get('fit'))
        cb = t.get('crossover_best_raster') if isinstance(t.get('crossover_best_raster'), dict) else None
        rows.append(
            {
                'name': name,
                'anchor': safe_name(name),
                'asis': _dict(t.get('as_is')),
                'ref': ref,
                'off': finite(fs.get('slope')) and abs(fs['slope'] + 0.5) > 0.1,
                'slope_spp': fs.get('slope', math.nan),
                'slope_t': ft.get('slope', math.nan),
                'note': cyc.get('slope_note', ''),
                'crossover': t.get('crossover'),
                'best': cb,
            }
        )
    return rows


def sweep_view(name, t, plots):
    ek = t.get('error_key') if isinstance(t.get('error_key'), str) else 'error'
    fits = []
    for sr in t['series']:
        if not isinstance(sr, dict):
            continue
        pair = []
        for key in ('fit', 'fit_spp'):
            f = _dict(sr.get(key))
            pair.append((f['slope'], f.get('r2', math.nan)) if finite(f.get('slope')) else None)
        tm = sr.get('time_model') if isinstance(sr.get('time_model'), dict) else None
        fits.append(
            {
                'label': sr.get('label'),
                'fits': pair,
                'note': sr.get('slope_note', ''),
                'time_model': f'{fsec(tm.get("t0_s"))} s + {fexp(tm.get("s_per_spp"))} s/spp' if tm else '',
            }
        )
    # one column per renderer the sweep names, in its order
    equal_time = [e for e in t.get('equal_time') or [] if isinstance(e, dict)]
    renderers = []
    for e in equal_time:
        renderers += [r for r in _dict(e.get('best')) if r not in renderers]
    equal = []
    for e in equal_time:
        best = _dict(e.get('best'))
        budget = text(e.get('budget'))
        if not str(e.get('budget', '')).endswith(' s'):
            budget += f' ({fsec(e.get("budget_s"))} s)'
        equal.append(
            {
                'budget': budget,
                'fit_error': e.get('cycles_fit_error'),
                'best': [b if isinstance(b, dict) else None for b in (best.get(r) for r in renderers)],
            }
        )
    points = [
        (sr.get('label'), p)
        for sr in t['series']
        if isinstance(sr, dict)
        for p in sr.get('points') or []
        if isinstance(p, dict)
    ]
    skipped = t.get('skipped') or []
    return {
        'sweep': True,
        'name': name,
        'anchor': safe_name(name),
        'plot': plots.get(name),
        'size': 'x'.join(str(v) for v in t.get('size') or []),
        'ref': t.get('reference') or {},
        'fits': fits,
        'eq_renderers': renderers,
        'equal_time': equal,
        'pareto': ', '.join(
            f'{text(p.get("renderer"))} {text(p.get("label"))}' for p in t.get('pareto') or [] if isinstance(p, dict)
        ),
        'crossover': t.get('crossover'),
        'error_key': ek,
        'points': points,
        'skipped': '; '.join(
            f'{text(k.get("label"))}: {text(k.get("message"))}' for k in skipped if isinstance(k, dict)
        ),
    }


def timing_view(name, t, plots):
    series = timing_points(t)
    keys = []
    for _, pts in series:
        for p in pts:
            for k in p:
                if k not in keys:
                    keys.append(k)
    return {
        'sweep': False,
        'name': name,
        'keys_': keys,
        'points': [(label, p) for label, pts in series for p in pts],
        'plot': plots.get(name),
    }


def index_html(R, trends, timing_plots, history_note):
    rows = list(all_comparisons(R))
    rows.sort(key=lambda sc: (VERDICT_ORDER.get(sc[1]['status'], 0), sc[0]['name'], sc[1]['id']))
    tm = R['optional']['timing']
    sweeps = [(n, t) for n, t in tm if is_sweep(t)]
    timing = [sweep_view(n, t, timing_plots) if is_sweep(t) else timing_view(n, t, timing_plots) for n, t in tm]
    return render(
        'index.html',
        'index',
        R=R,
        status=run_status(R),
        counts=verdict_counts(R),
        verdicts=VERDICTS,
        rows=rows,
        roles=sorted({c['role'] for _, c in rows if c['role']}),
        role_legend=list(ROLE_LEGEND.items()),
        jobs=job_rows(R, R['scenes']),
        trends=trends,
        history_note=history_note,
        stability=stability_rows(R['optional']),
        fits=fit_rows(R),
        timing=timing,
        sweeps=sweeps,
        overview=sweep_overview(sweeps),
        answer=answer_rows(R, {n: t.get('crossover') for n, t in sweeps}),
        sweep_plots=[(n, timing_plots[n]) for n, _ in sweeps if timing_plots.get(n)],
    )


# ---------------------------------------------------------------------------------------------
# Scene page


def metric_table(c):
    """(groups, keys): one row per region, AOV and object; one column per figure."""
    groups = [('region', k, v) for k, v in c['regions'].items()] + [('aov', k, v) for k, v in c['aovs'].items()]
    groups += [('term', k, v) for k, v in c.get('terms', {}).items()]
    objs = c.get('objects') if isinstance(c.get('objects'), list) else []
    groups += [
        (
            'object',
            f'{o.get("object")} {o.get("material", "")}',
            {k: v for k, v in o.items() if k not in ('object', 'material')},
        )
        for o in objs
        if isinstance(o, dict)
    ]
    keys = []
    for _, _, ms in groups:
        for k in ms:
            if k not in keys and k not in ('max_x', 'max_y', 'max_c'):
                keys.append(k)
    return groups, keys


def scene_html(R, s, angle_plots, trend):
    v = s['view']
    W, H = (v['width'], v['height']) if v else (4, 3)
    cw = 300
    measured = [c for c in s['comparisons'] if not c.get('pseudo')]
    page_data = {
        'scene': s['name'],
        'run_id': R['run_id'],
        'view_src': f'{s["name"]}/view.js',
        'images': v['images'] if v else [],
        'comparisons': [
            {
                'id': c['id'],
                'test': c['test'],
                'reference': c['reference'],
                'role': c['role'],
                'status': c['status'],
                'testKey': c.get('test_key'),
                'refKey': c.get('ref_key'),
                'rel_rms': c['regions'].get('surface', {}).get('rel_rms'),
            }
            for c in measured
        ],
    }
    comparisons = []
    for c in sorted(s['comparisons'], key=lambda c: VERDICT_ORDER.get(c['status'], 0)):
        groups, keys = metric_table(c)
        comparisons.append(dict(c, metric_groups=groups, metric_keys=keys))
    return render(
        'scene.html',
        'scene',
        R=R,
        s=s,
        v=v,
        cw=cw,
        ch=max(1, round(cw * H / W)),
        scene_problems=[p for p in R['problems'].items if p['scene'] == s['name']],
        comparisons=comparisons,
        measured=measured,
        heats=[c for c in measured if c.get('test_key') and c.get('ref_key')],
        noheat=[c for c in measured if not (c.get('test_key') and c.get('ref_key'))],
        angle_plots=angle_plots,
        trend=trend,
        jobs=job_rows(R, [s]),
        page_data=page_data,
    )


# ---------------------------------------------------------------------------------------------
# Threshold proposal page


def diff_class(ln):
    if ln.startswith('+') and not ln.startswith('+++'):
        return ' add'
    if ln.startswith('-') and not ln.startswith('---'):
        return ' del'
    if ln.startswith('@@'):
        return ' hunk'
    if ln.startswith(('---', '+++')):
        return ' file'
    return ''


def proposal_html(R, text_, rows):
    return render('proposal.html', 'proposal', R=R, rows=rows, diff=[(diff_class(ln), ln) for ln in text_.splitlines()])


# ---------------------------------------------------------------------------------------------
# Pages of their own: the stability table and Figure 1


def stability_html(R):
    return render('stability_page.html', 'stability', R=R, stability=stability_rows(R['optional']))


def figure1_html(R):
    return render('figure1_page.html', 'figure1', R=R)


# The angles the scene's Figure 1 page lists as numbers beside its plot (degrees).
FIGURE1_TABLE_DEG = (0, 30, 45, 60, 75, 85, 90)


def figure1_scene_html(R, s, svg):
    """Figure 1 of a scene's own materials: the plot and, at FIGURE1_TABLE_DEG, each material's
    model and physics reflectance (the angles the data holds, to 1e-6 degree)."""
    f1 = s['figure1']
    cols = []
    for deg in FIGURE1_TABLE_DEG:
        hit = [i for i, a in enumerate(f1['angle_deg']) if abs(a - deg) < 1e-6]
        if hit:
            cols.append((deg, hit[0]))
    rows = [
        dict(m, points=[(m['model'][i], m['physics'][i], m['model'][i] - m['physics'][i]) for _, i in cols])
        for m in f1['materials']
    ]
    return render('figure1_scene.html', 'figure1', R=R, s=s, svg=svg, cols=[d for d, _ in cols], rows=rows, f1=f1)
