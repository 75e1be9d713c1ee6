"""outputs - the machine-readable files of a run: summary.json, summary.csv and JUnit XML."""

import csv
import io
import xml.etree.ElementTree as ET

from .load import all_comparisons, run_status, verdict_counts
from .util import HIGHER_BETTER, clean, finite, fmt_metric, fthr


def summary_object(R):
    scenes = []
    for s in R['scenes']:
        comps = []
        for c in s['comparisons']:
            o = {
                k: c.get(k)
                for k in (
                    'id',
                    'test',
                    'reference',
                    'role',
                    'status',
                    'reason',
                    'physics',
                    'regions',
                    'aovs',
                    'terms',
                    'coverage_agreement',
                    'noise',
                    'thresholds',
                    'times',
                    'angle_bins',
                    'angle_bins_ndoth',
                    'angle_bins_ndotl',
                    'bias',
                )
            }
            o['test_image'] = c.get('test_key')
            o['reference_image'] = c.get('ref_key')
            # partial twins, and comparisons with a renderer that has crease rules, only
            for k in ('terms_compared', 'terms_left_out', 'crease'):
                if k in c:
                    o[k] = c[k]
            comps.append(o)
        jobs = [
            {
                k: j.get(k)
                for k in (
                    'renderer',
                    'role',
                    'variant',
                    'status',
                    'message',
                    'version',
                    'wall_s',
                    'cpu_s',
                    'cached',
                    'width',
                    'height',
                    'supersample',
                    'samples',
                    'log',
                    'exr',
                    'file',
                )
            }
            for j in s['jobs']
        ]
        scenes.append(
            {
                'name': s['name'],
                'title': s['title'],
                'scene_path': s['scene_path'],
                'page': s['page'],
                'comparisons': comps,
                'jobs': jobs,
            }
        )
    opt = R['optional']
    return clean(
        {
            'run_id': R['run_id'],
            'commit': R['commit'],
            'time': R['time'],
            'report_time': R['report_time'],
            'machine': R['machine'],
            'status': run_status(R),
            'renderer_versions': R['versions'],
            'counts': verdict_counts(R),
            'scenes': scenes,
            'stability': opt['stability']['rows'] if opt['stability'] else None,
            'fits': [dict(f, scene=s['name']) for s in R['scenes'] for f in s.get('fits', [])],
            'problems': R['problems'].items,
        }
    )


def summary_csv(R):
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator='\n')
    w.writerow(
        [
            'run_id',
            'scene',
            'comparison',
            'role',
            'status',
            'group',
            'name',
            'metric',
            'value',
            'warn',
            'fail',
            'verdict',
        ]
    )
    for s, c in all_comparisons(R):
        base = [R['run_id'], s['name'], c['id'], c['role'], c['status']]

        def row(group, name, metric, value, warn='', fail='', verdict=''):
            w.writerow(
                base
                + [
                    group,
                    name,
                    metric,
                    '' if value is None else repr(value) if isinstance(value, float) else value,
                    warn,
                    fail,
                    verdict,
                ]
            )

        for reg, ms in c['regions'].items():
            for k, v in ms.items():
                row('region', reg, k, v)
        for aov, ms in c['aovs'].items():
            for k, v in ms.items():
                row('aov', aov, k, v)
        for term, ms in c.get('terms', {}).items():
            for k, v in ms.items():
                row('term', term, k, v)
        if c.get('physics'):
            row('comparison', 'all', 'physics', c['physics'])
        if c.get('coverage_agreement') is not None:
            row('comparison', 'all', 'coverage_agreement', c['coverage_agreement'])
        noise = c.get('noise') or {}
        if noise.get('ref_rel_rms') is not None:
            row('noise', 'reference', 'ref_rel_rms', noise['ref_rel_rms'])
        for k, v in (noise.get('ztest') or {}).items():
            row('noise', 'ztest', k, v)
        for t in c['thresholds']:
            row(
                'threshold',
                'surface' if '.' not in str(t['metric']) else str(t['metric']).split('.')[0],
                t['metric'],
                t.get('value'),
                t.get('warn', ''),
                t.get('fail', ''),
                t.get('verdict', ''),
            )
        if not c['regions'] and not c['thresholds']:
            row('comparison', 'all', 'status', c['status'])
    return buf.getvalue()


def threshold_message(scene, c, t):
    metric = t['metric']
    hb = metric.split('.')[-1] in HIGHER_BETTER
    op = '<' if hb else '>'
    why = f' ({t["why"]})' if t.get('why') else ''
    return (
        f'{scene}: {c["id"]}: {metric} {fmt_metric(metric, t.get("value"))} {op} ' f'{fthr(metric, t.get("fail"))}{why}'
    )


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
                    e = ET.SubElement(
                        tc, 'error', message=f'{s["name"]}: {c["id"]}: {c.get("reason") or "error"}', type='error'
                    )
                    e.text = c.get('reason') or ''
                    cnt['errors'] += 1
                elif c['status'] == 'skipped' or (t is not None and str(t.get('verdict')) == 'skipped'):
                    ET.SubElement(tc, 'skipped', message=f'{s["name"]}: {c["id"]}: {c.get("reason") or "skipped"}')
                    cnt['skipped'] += 1
                elif t is None and c['status'] == 'not_gated':
                    ET.SubElement(tc, 'skipped', message=f'{s["name"]}: {c["id"]}: not gated (no accuracy threshold)')
                    cnt['skipped'] += 1
                elif t is None:
                    if c['status'] == 'fail':
                        f = ET.SubElement(
                            tc,
                            'failure',
                            message=f'{s["name"]}: {c["id"]}: {c.get("reason") or "fail"}',
                            type='threshold',
                        )
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
                        f' {fthr(t["metric"], t.get("fail"))}', f' warn {fthr(t["metric"], t.get("warn"))}', 1
                    )
        for k, v in cnt.items():
            ts.set(k, str(v))
            tot[k] += v
    for k, v in tot.items():
        root.set(k, str(v))
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding='unicode') + '\n'
