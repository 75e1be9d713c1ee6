#!/usr/bin/env python3
"""gates.py - every scene gate beside the figure it guards, and the loose ones flagged.

Usage:
  python3 tools/gates.py --run reports/runs/r1 [--bin build/reflcheck] [--scenes scenes]
                           [--md docs/gates.md] [--limit 3]
Reads each SCENES/*.yaml's thresholds through `reflcheck check --json` (the C parser, so the
YAML is read one way only) and RUN/<scene>/compare.json's measured values, and prints one row
per gate: scene, comparison, metric, warn, fail, figure, ratio, sized-on, stated reason, flag.
Ratio: how far the fail level sits from the figure. For a lower-is-better metric fail / figure;
for coverage_agreement and ssim (ideal 1) (1 - fail) / (1 - figure); for psnr (ideal +inf) the
ratio of the RMS errors the two dB levels stand for, 10^((figure - fail) / 20). A figure at the
ideal (0, or 1, or psnr null = identical) under a gate that allows more gives inf.
Flags: LOOSE when ratio > limit and the threshold states no `loose:` reason; loose when it
does; FAILS when the figure is beyond the fail level; unmeasured when the run has no figure
(scene or comparison not in the run, skipped or error).
--md writes the table as Markdown to that file as well.
Exit: 0 none loose without a reason; 1 a LOOSE gate; 2 bad input (no run, a scene the parser
refuses, a compare.json that is not JSON).
"""

import argparse
import glob
import json
import math
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
# Metrics judged as "fail below the threshold" (harness/compare.h), with their ideal value.
HIGHER_IS_BETTER = {'coverage_agreement': 1.0, 'ssim': 1.0, 'psnr': math.inf}
DEFAULT_LIMIT = 3.0


class BadInput(Exception):
    pass


def scene_gates(binary, path):
    """The comparisons and thresholds of one scene file, as the C parser reads them."""
    p = subprocess.run([binary, 'check', '--json', path], capture_output=True, text=True)
    if p.returncode != 0:
        raise BadInput(p.stderr.strip() or f'{path}: reflcheck check --json exited {p.returncode}')
    try:
        return json.loads(p.stdout)
    except json.JSONDecodeError as e:
        raise BadInput(f'{path}: reflcheck check --json printed no JSON ({e}); rebuild reflcheck') from e


def run_figures(run, scene):
    """{(comparison id, occurrence): {metric: value}} from RUN/<scene>/compare.json; {} if absent."""
    path = os.path.join(run, scene, 'compare.json')
    if not os.path.isfile(path):
        return {}
    try:
        with open(path, encoding='utf-8') as f:
            doc = json.load(f)
    except (OSError, json.JSONDecodeError) as e:
        raise BadInput(f'{path}: not readable JSON ({e}); re-run reflcheck compare on the scene') from e
    out, seen = {}, {}
    for c in doc.get('comparisons', []):
        cid = c.get('id', '')
        k = seen[cid] = seen.get(cid, -1) + 1
        if c.get('status') in ('skipped', 'error'):
            continue
        out[(cid, k)] = {t.get('metric'): t.get('value') for t in c.get('thresholds', []) if 'metric' in t}
    return out


def ratio(metric, fail, figure):
    """How far the fail level sits from the figure, >= 1 when the figure passes (module doc)."""
    base = metric.rsplit('.', 1)[-1]
    if base == 'psnr':
        # compare.json writes psnr null for identical images: the ideal, infinitely far.
        return math.inf if figure is None else 10 ** ((figure - fail) / 20)
    if figure is None:
        return None
    if base in HIGHER_IS_BETTER:
        gap, allowed = 1.0 - figure, 1.0 - fail
    else:
        gap, allowed = abs(figure), abs(fail)
    if gap <= 0:
        return 1.0 if allowed <= 0 else math.inf
    return allowed / gap


def fails(metric, fail, figure):
    if figure is None:
        return metric.rsplit('.', 1)[-1] != 'psnr'
    if metric.rsplit('.', 1)[-1] in HIGHER_IS_BETTER:
        return figure < fail
    return figure > fail


def gate_rows(binary, scenes_dir, run, limit):
    rows = []
    for path in sorted(glob.glob(os.path.join(scenes_dir, '*.yaml'))):
        doc = scene_gates(binary, path)
        scene = doc['scene']
        figures = run_figures(run, scene)
        seen = {}
        for c in doc['comparisons']:
            k = seen[c['id']] = seen.get(c['id'], -1) + 1
            measured = figures.get((c['id'], k))
            for t in c['thresholds']:
                row = dict(scene=scene, comparison=c['id'], **t)
                if measured is None or t['metric'] not in measured:
                    row.update(figure=None, ratio=None, flag='unmeasured')
                else:
                    fig = measured[t['metric']]
                    r = ratio(t['metric'], t['fail'], fig)
                    flag = ''
                    if fails(t['metric'], t['fail'], fig):
                        flag = 'FAILS'
                    elif r is not None and r > limit:
                        flag = 'loose' if t['loose'] else 'LOOSE'
                    row.update(figure=fig, ratio=r, flag=flag)
                rows.append(row)
    return rows


def fnum(v, digits=4):
    """A level or figure to 4 significant digits (0.9995 and 0.999 stay apart), a ratio to 3."""
    if v is None:
        return '-'
    if isinstance(v, float) and math.isinf(v):
        return 'inf'
    return f'{v:.{digits}g}'


def sized_text(t):
    z = t.get('sized')
    if not z:
        return '-'
    return f"{fnum(z['figure'])} {z['size']} ({z['run']}), x{fnum(ratio(t['metric'], t['fail'], z['figure']), 3)}"


COLUMNS = ('scene', 'comparison', 'metric', 'warn', 'fail', 'figure', 'ratio', 'sized on', 'flag', 'stated reason')


def cells(r):
    return (
        r['scene'],
        r['comparison'],
        r['metric'],
        fnum(r['warn']),
        fnum(r['fail']),
        fnum(r['figure']),
        fnum(r['ratio'], 3),
        sized_text(r),
        r['flag'],
        r['loose'],
    )


def markdown(rows, run, limit):
    loose = sum(r['flag'] == 'LOOSE' for r in rows)
    out = [
        '# Gates and the figures they guard',
        '',
        f'Written by `python3 tools/gates.py --run {run} --md ...` from the scene files\' thresholds and the',
        f'run\'s compare.json. Ratio: fail level / figure (distance from the ideal for coverage_agreement,',
        f'ssim, psnr); LOOSE: ratio over {limit:g} with no `loose:` reason in the scene file. {len(rows)} gates,',
        f'{loose} LOOSE.',
        '',
        '| ' + ' | '.join(COLUMNS) + ' |',
        '|' + '---|' * len(COLUMNS),
    ]
    for r in rows:
        out.append('| ' + ' | '.join(str(c).replace('|', '\\|') for c in cells(r)) + ' |')
    return '\n'.join(out) + '\n'


def main(argv=None):
    ap = argparse.ArgumentParser(description='Every scene gate beside the figure it guards.')
    ap.add_argument('--run', required=True, help='a run folder holding <scene>/compare.json')
    ap.add_argument('--bin', default=os.environ.get('REFLCHECK_BIN', os.path.join(ROOT, 'build', 'reflcheck')))
    ap.add_argument('--scenes', default=os.path.join(ROOT, 'scenes'))
    ap.add_argument('--md', help='also write the table as Markdown here')
    ap.add_argument('--limit', type=float, default=DEFAULT_LIMIT, help='the ratio above which a gate is loose')
    a = ap.parse_args(argv)
    try:
        if not os.path.isdir(a.run):
            raise BadInput(f'{a.run}: no such run folder; give --run the folder reflcheck run wrote')
        if not os.access(a.bin, os.X_OK):
            raise BadInput(f'{a.bin}: no reflcheck binary; build it (make BUILD=x all) and give --bin x/reflcheck')
        rows = gate_rows(a.bin, a.scenes, a.run, a.limit)
    except BadInput as e:
        print(f'gates.py: {e}', file=sys.stderr)
        return 2
    widths = [max(len(COLUMNS[i]), *(len(str(cells(r)[i])) for r in rows)) for i in range(len(COLUMNS))]
    print('  '.join(c.ljust(w) for c, w in zip(COLUMNS, widths)).rstrip())
    for r in rows:
        print('  '.join(str(c).ljust(w) for c, w in zip(cells(r), widths)).rstrip())
    if a.md:
        with open(a.md, 'w', encoding='utf-8') as f:
            f.write(markdown(rows, a.run, a.limit))
    loose = [r for r in rows if r['flag'] == 'LOOSE']
    for r in loose:
        print(
            f"gates.py: {r['scene']}: {r['comparison']}: {r['metric']}: fail {fnum(r['fail'])} is "
            f"{fnum(r['ratio'], 3)}x its figure {fnum(r['figure'])}; tighten it to about {a.limit:g}x, or state "
            f"loose: \"reason\" in scenes/{r['scene']}.yaml",
            file=sys.stderr,
        )
    return 1 if loose else 0


if __name__ == '__main__':
    sys.exit(main())
