#!/usr/bin/env python3
"""gates.py - every scene gate beside the figure it guards, at each image size, loose ones flagged.

Usage:
  python3 tools/gates.py --run SMALL_RUN [--run FULL_RUN] [--bin build/reflcheck] [--scenes scenes]
                           [--md docs/gates.md] [--limit 3]
Reads each SCENES/*.yaml's thresholds through `reflcheck check --json` (the C parser, so the
YAML is read one way only, with each size's gate resolved: a small: or full: block, else the
threshold's own levels) and each RUN/<scene>/compare.json's measured values. A run is one image
size: the "size" compare.json gives each threshold, else the "variant" of the scene's job records
(RUN/<scene>/*.json). Prints one row per gate and size of the runs given: scene, comparison,
metric, size, warn, fail, figure, ratio, sized-on, flag, stated reason; a gate is judged against
the figure of its own size only.
Ratio: how far the fail level sits from the figure. For a lower-is-better metric fail / figure;
for coverage_agreement and ssim (ideal 1) (1 - fail) / (1 - figure); for psnr (ideal +inf) the
ratio of the RMS errors the two dB levels stand for, 10^((figure - fail) / 20). A figure at the
ideal (0, or 1, or psnr null = identical) under a gate that allows more gives inf.
Flags: LOOSE when ratio > limit and the gate at that size states no `loose:` reason; loose when
it does; FAILS when the figure is beyond the fail level; unmeasured when the run has no figure
(scene or comparison not in the run, skipped or error).
--md writes the table as Markdown to that file as well.
Exit: 0 none loose without a reason; 1 a LOOSE gate; 2 bad input (no run, two runs of one size,
a run whose size cannot be told, a scene the parser refuses, a compare.json that is not JSON).
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


SIZES = ('small', 'full')


def read_compare(run, scene):
    """RUN/<scene>/compare.json as a dict; None when the run has no such scene."""
    path = os.path.join(run, scene, 'compare.json')
    if not os.path.isfile(path):
        return None
    try:
        with open(path, encoding='utf-8') as f:
            return json.load(f)
    except (OSError, json.JSONDecodeError) as e:
        raise BadInput(f'{path}: not readable JSON ({e}); re-run reflcheck compare on the scene') from e


def run_size(run):
    """'small' or 'full': the size compare.json says a gate applied to, else the job records' variant."""
    found = set()
    for path in sorted(glob.glob(os.path.join(run, '*', 'compare.json'))):
        doc = read_compare(run, os.path.basename(os.path.dirname(path)))
        found |= {t['size'] for c in doc.get('comparisons', []) for t in c.get('thresholds', []) if 'size' in t}
    if not found:
        for path in sorted(glob.glob(os.path.join(run, '*', '*.json'))):
            try:
                with open(path, encoding='utf-8') as f:
                    v = json.load(f).get('variant')
            except (OSError, ValueError, AttributeError):
                continue
            if v in SIZES:
                found.add(v)
    if len(found) != 1:
        raise BadInput(
            f'{run}: {"no image size" if not found else "sizes " + ", ".join(sorted(found))} in its compare.json '
            'files and job records; give --run a run of one size (reflcheck compare rewrites compare.json)'
        )
    return found.pop()


def run_figures(run, scene):
    """{(comparison id, occurrence): {metric: value}} from RUN/<scene>/compare.json; {} if absent."""
    doc = read_compare(run, scene)
    if doc is None:
        return {}
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


def gate_row(scene, cid, t, size, measured, limit):
    """One gate at one size: that size's levels (check --json resolves them) against its figure."""
    g = t[size]
    row = dict(scene=scene, comparison=cid, metric=t['metric'], size=size, warn=g['warn'], fail=g['fail'])
    row.update(loose=g['loose'], sized=g.get('sized'), own=g['own'])
    if measured is None or t['metric'] not in measured:
        row.update(figure=None, ratio=None, flag='unmeasured')
        return row
    fig = measured[t['metric']]
    r = ratio(t['metric'], g['fail'], fig)
    flag = ''
    if fails(t['metric'], g['fail'], fig):
        flag = 'FAILS'
    elif r is not None and r > limit:
        flag = 'loose' if g['loose'] else 'LOOSE'
    row.update(figure=fig, ratio=r, flag=flag)
    return row


def gate_rows(docs, runs, limit):
    """docs: scene_gates of each scene file; runs: {size: run folder}. Rows per gate, one per
    size given, small first."""
    rows = []
    for doc in docs:
        scene = doc['scene']
        figures = {size: run_figures(run, scene) for size, run in runs.items()}
        seen = {}
        for c in doc['comparisons']:
            k = seen[c['id']] = seen.get(c['id'], -1) + 1
            for t in c['thresholds']:
                for size in SIZES:
                    if size in runs:
                        rows.append(gate_row(scene, c['id'], t, size, figures[size].get((c['id'], k)), limit))
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


COLUMNS = (
    'scene',
    'comparison',
    'metric',
    'size',
    'warn',
    'fail',
    'figure',
    'ratio',
    'sized on',
    'flag',
    'stated reason',
)


def cells(r):
    return (
        r['scene'],
        r['comparison'],
        r['metric'],
        r['size'] + (' (own)' if r['own'] else ''),
        fnum(r['warn']),
        fnum(r['fail']),
        fnum(r['figure']),
        fnum(r['ratio'], 3),
        sized_text(r),
        r['flag'],
        r['loose'],
    )


def markdown(rows, runs, limit):
    loose = sum(r['flag'] == 'LOOSE' for r in rows)
    given = ' '.join(f'--run {runs[z]}' for z in SIZES if z in runs)
    out = [
        '# Gates and the figures they guard',
        '',
        f'Written by `python3 tools/gates.py {given} --md ...` from the scene files\' thresholds and the',
        'runs\' compare.json, each gate at each size against the figure of that size ("own": the scene file',
        'gives that size a small: or full: block). Ratio: fail level / figure (distance from the ideal for',
        f'coverage_agreement, ssim, psnr); LOOSE: ratio over {limit:g} with no `loose:` reason for that size.',
        f'{len(rows)} rows, {loose} LOOSE.',
        '',
        '| ' + ' | '.join(COLUMNS) + ' |',
        '|' + '---|' * len(COLUMNS),
    ]
    for r in rows:
        out.append('| ' + ' | '.join(str(c).replace('|', '\\|') for c in cells(r)) + ' |')
    return '\n'.join(out) + '\n'


def main(argv=None):
    ap = argparse.ArgumentParser(description='Every scene gate beside the figure it guards.')
    ap.add_argument(
        '--run',
        required=True,
        action='append',
        help='a run folder holding <scene>/compare.json; give it once per size (a small and a full run)',
    )
    ap.add_argument('--bin', default=os.environ.get('REFLCHECK_BIN', os.path.join(ROOT, 'build', 'reflcheck')))
    ap.add_argument('--scenes', default=os.path.join(ROOT, 'scenes'))
    ap.add_argument('--md', help='also write the table as Markdown here')
    ap.add_argument('--limit', type=float, default=DEFAULT_LIMIT, help='the ratio above which a gate is loose')
    a = ap.parse_args(argv)
    try:
        if not os.access(a.bin, os.X_OK):
            raise BadInput(f'{a.bin}: no reflcheck binary; build it (make BUILD=x all) and give --bin x/reflcheck')
        # The scene files first: a gate the parser refuses is the error to report, whatever the runs.
        docs = [scene_gates(a.bin, p) for p in sorted(glob.glob(os.path.join(a.scenes, '*.yaml')))]
        runs = {}
        for run in a.run:
            if not os.path.isdir(run):
                raise BadInput(f'{run}: no such run folder; give --run the folder reflcheck run wrote')
            size = run_size(run)
            if size in runs:
                raise BadInput(f'{run}: a second {size} run (first {runs[size]}); give one run per size')
            runs[size] = run
        rows = gate_rows(docs, runs, a.limit)
    except BadInput as e:
        print(f'gates.py: {e}', file=sys.stderr)
        return 2
    widths = [max(len(COLUMNS[i]), *(len(str(cells(r)[i])) for r in rows)) for i in range(len(COLUMNS))]
    print('  '.join(c.ljust(w) for c, w in zip(COLUMNS, widths)).rstrip())
    for r in rows:
        print('  '.join(str(c).ljust(w) for c, w in zip(cells(r), widths)).rstrip())
    if a.md:
        with open(a.md, 'w', encoding='utf-8') as f:
            f.write(markdown(rows, runs, a.limit))
    loose = [r for r in rows if r['flag'] == 'LOOSE']
    for r in loose:
        print(
            f"gates.py: {r['scene']}: {r['comparison']}: {r['metric']}: at {r['size']} size fail {fnum(r['fail'])} "
            f"is {fnum(r['ratio'], 3)}x its figure {fnum(r['figure'])}; tighten it to about {a.limit:g}x (a "
            f"{r['size']}: {{fail: ...}} block sets that size alone), or state loose: \"reason\" in "
            f"scenes/{r['scene']}.yaml",
            file=sys.stderr,
        )
    return 1 if loose else 0


if __name__ == '__main__':
    sys.exit(main())
