#!/usr/bin/python3
"""agree.py - do two sweep runs agree? Per scene: the Cycles spp slope, the crossovers, the
Pareto frontier and the raster as-is error of RUN_A and RUN_B (their timing/<scene>.json), each
with its difference in standard errors, as a Markdown table (docs/sweep.md holds one).

Usage: /usr/bin/python3 tools/sweep/agree.py RUN_A RUN_B [--names A B] [--common] > table.md

Standard errors come from plan.point_sigma (each point's two seeds and pixel count); a run
written before n_pixels was kept borrows them from the other run's point of the same label (the
same render at the same size). A difference within AGREE_SIGMAS is "agrees"; a crossover is
compared where both runs place it inside or below their measured levels, and an extrapolated
one is compared by its side only.
"""

import argparse
import glob
import json
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from sweep.plan import error_sigma, point_sigma  # noqa: E402  (needs the path above)

# Two figures agree within 2 combined standard errors: about 1 in 20 pairs of equal figures
# would be called different by chance, which the table's explanations column then names.
AGREE_SIGMAS = 2.0


def load(run):
    """Scene name -> timing dict for every timing/<scene>.json of a run folder."""
    out = {}
    for path in sorted(glob.glob(os.path.join(run, 'timing', '*.json'))):
        with open(path, encoding='utf-8') as f:
            t = json.load(f)
        out[t['scene']] = t
    return out


def cycles_points(t):
    cyc = next((s for s in t['series'] if s['label'] == 'cycles spp'), {})
    return [p for p in cyc.get('points', []) if not p['is_reference'] and p.get('error') and p.get('samples')]


def with_pixels(p, other):
    """p with n_pixels and worst1_share from other's point of the same label where p lacks them."""
    if p.get('n_pixels'):
        return p
    twin = next((q for q in other if q['label'] == p['label'] and q.get('n_pixels')), None)
    return dict(p, n_pixels=twin['n_pixels'], worst1_share=twin.get('worst1_share')) if twin else p


def slope_fit(t, other_pts):
    """Least-squares ln(error) on ln(spp) over the Cycles points and its standard error from
    the points' own (unweighted fit: var b = sum dx^2 sigma^2 / Sxx^2); (slope, sigma, pts)."""
    ref = t.get('reference') or {}
    pts = [with_pixels(p, other_pts) for p in cycles_points(t)]
    if len(pts) < 2:
        return None
    xs = [math.log(p['samples']) for p in pts]
    ys = [math.log(p['error']) for p in pts]
    sig = [point_sigma(p, ref.get('noise_nrmse'), ref.get('nested', False)) for p in pts]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    sxx = sum((x - mx) ** 2 for x in xs)
    b = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx
    sb = math.sqrt(sum(((x - mx) ** 2) * s * s for x, s in zip(xs, sig))) / sxx
    s_mean = math.sqrt(sum(s * s for s in sig)) / len(sig)
    return {'slope': b, 'sigma': sb, 'mx': mx, 'my': my, 'sigma_mean': s_mean}


def noise_of(t):
    return (t.get('reference') or {}).get('noise_nrmse')


def crossover_sigma(c, fit):
    """ln-spp standard error of a crossover on a fit: ln n = (ln E - a) / b around the points'
    mean, so sigma^2 = (sigma_mean^2 + ((ln n - mx) sigma_b)^2) / b^2."""
    if not c or not fit or fit['slope'] >= 0:
        return None
    d = math.log(c['spp']) - fit['mx']
    return math.hypot(fit['sigma_mean'], d * fit['sigma']) / abs(fit['slope'])


def fmt(v, spec='.3g'):
    return '-' if v is None else format(v, spec)


def compare_crossover(ca, cb, fa, fb):
    """(text, agrees) for one crossover of both runs."""
    if not ca and not cb:
        return 'none in both', True
    if not ca or not cb:
        return f"{fmt(ca and ca['spp'])} / {fmt(cb and cb['spp'])}", False
    side_a, side_b = ca.get('extrapolated'), cb.get('extrapolated')
    text = f"{ca['spp']:.3g}{' ' + side_a if side_a else ''} / {cb['spp']:.3g}{' ' + side_b if side_b else ''}"
    if side_a == 'below' and side_b == 'below':
        return text, True  # both a bound under 16 spp: the reported figure is the same bound
    sa, sb = crossover_sigma(ca, fa), crossover_sigma(cb, fb)
    if sa is None or sb is None:
        return text, side_a == side_b
    z = abs(math.log(ca['spp'] / cb['spp'])) / math.hypot(sa, sb)
    return f'{text} ({z:.1f} sigma)', z <= AGREE_SIGMAS


def pareto_text(ta, tb):
    """(text, agrees): the Pareto labels only one run has; Cycles levels a run did not render
    as points (the other's 1024 point, its stage two) are named but do not count as a
    disagreement, and references are left out."""

    def labels(t):
        # A reference's point is its own noise, a different render in each run: not compared.
        return {f"{p['renderer']} {p['label']}" for p in t.get('pareto') or [] if '(reference)' not in p['label']}

    la, lb = labels(ta), labels(tb)
    levels_a = {f"cycles {p['label']}" for p in cycles_points(ta)}
    levels_b = {f"cycles {p['label']}" for p in cycles_points(tb)}
    only_a = sorted(x for x in la - lb)
    only_b = sorted(x for x in lb - la)
    real = [x for x in only_a if x in levels_b or not x.startswith('cycles')]
    real += [x for x in only_b if x in levels_a or not x.startswith('cycles')]
    if not only_a and not only_b:
        return f'same {len(la)}', True
    return f"A only: {', '.join(only_a) or '-'}; B only: {', '.join(only_b) or '-'}", not real


def other_errors(ta, tb):
    """(text, agrees): the largest difference, in combined standard errors (plan.error_sigma),
    between the errors of the non-Cycles points both runs measured: a Pareto point that moved
    with an agreeing error moved along the time axis."""

    def points(t):
        return {
            f"{s['renderer']} {p['label']}": p
            for s in t['series']
            if s['renderer'] != 'cycles'
            for p in s['points']
            if p.get('error')
        }

    pa, pb = points(ta), points(tb)
    worst = None
    for k in sorted(set(pa) & set(pb)):
        # The same scene at the same size: a run without pixel counts borrows the other's.
        n = pixels(ta, pa[k]) or pixels(tb, pb[k])
        sa = error_sigma(pa[k]['error'], noise_of(ta), pixels(ta, pa[k]) or n)
        sb = error_sigma(pb[k]['error'], noise_of(tb), pixels(tb, pb[k]) or n)
        z = abs(math.log(pa[k]['error'] / pb[k]['error'])) / max(math.hypot(sa, sb), 1e-12)
        if worst is None or z > worst[0]:
            worst = (z, k)
    if worst is None:
        return '-', True
    return f'{len(set(pa) & set(pb))}; worst {worst[1]} {worst[0]:.1f} sigma', worst[0] <= AGREE_SIGMAS


def pixels(t, p):
    """A point's surface pixels, else the as-is point's or a Cycles point's (the same mask)."""
    return (
        p.get('n_pixels')
        or (t.get('as_is') or {}).get('n_pixels')
        or next((q.get('n_pixels') for q in cycles_points(t) if q.get('n_pixels')), 0)
    )


def row(name, ta, tb):
    pa, pb = cycles_points(ta), cycles_points(tb)
    fa, fb = slope_fit(ta, pb), slope_fit(tb, pa)
    cells, ok = [name, (ta.get('reference') or {}).get('role', '?')], []
    cells.append(f"{(ta.get('sweep') or {}).get('stage', '?')} / {(tb.get('sweep') or {}).get('stage', '?')}")
    if fa and fb:
        z = abs(fa['slope'] - fb['slope']) / math.hypot(fa['sigma'], fb['sigma'])
        cells.append(f"{fa['slope']:.2f}±{fa['sigma']:.2f} / {fb['slope']:.2f}±{fb['sigma']:.2f} ({z:.1f} sigma)")
        ok.append(('slope', z <= AGREE_SIGMAS))
    else:
        cells.append('-')
    for key in ('crossover', 'crossover_best_raster'):
        text, good = compare_crossover(ta.get(key), tb.get(key), fa, fb)
        cells.append(text)
        ok.append((key.replace('_', ' '), good))
    text, good = pareto_text(ta, tb)
    cells.append(text)
    ok.append(('pareto', good))
    ea, eb = (ta.get('as_is') or {}).get('error'), (tb.get('as_is') or {}).get('error')
    if ea and eb:
        aa, ab = ta['as_is'], tb['as_is']
        n = pixels(ta, aa) or pixels(tb, ab)
        sa = error_sigma(ea, noise_of(ta), pixels(ta, aa) or n)
        sb = error_sigma(eb, noise_of(tb), pixels(tb, ab) or n)
        z = abs(math.log(ea / eb)) / max(math.hypot(sa, sb), 1e-12)
        cells.append(f'{ea:.3g} / {eb:.3g} ({z:.1f} sigma)')
        ok.append(('as-is', z <= AGREE_SIGMAS))
    else:
        cells.append(f'{fmt(ea)} / {fmt(eb)}')
        ok.append(('as-is', ea == eb))
    text, good = other_errors(ta, tb)
    cells.append(text)
    ok.append(('non-Cycles errors', good))
    bad = [k for k, g in ok if not g]
    cells.append('agrees' if not bad else 'differs: ' + ', '.join(bad))
    return cells, bad


def table(run_a, run_b, names=('A', 'B'), common=False):
    a, b = load(run_a), load(run_b)
    if common:
        a = {k: v for k, v in a.items() if k in b}
        b = {k: v for k, v in b.items() if k in a}
    head = [
        'scene',
        'role',
        'stage',
        f'spp slope {names[0]} / {names[1]}',
        'crossover as-is (spp)',
        'crossover best raster (spp)',
        'Pareto',
        'as-is error',
        'non-Cycles errors in both',
        'verdict',
    ]
    lines = ['| ' + ' | '.join(head) + ' |', '|' + '---|' * len(head)]
    n_bad = 0
    for name in sorted(set(a) | set(b)):
        if name not in a or name not in b:
            lines.append(f"| {name} | only in {names[0] if name in a else names[1]} |" + ' |' * (len(head) - 2))
            n_bad += 1
            continue
        cells, bad = row(name, a[name], b[name])
        n_bad += bool(bad)
        lines.append('| ' + ' | '.join(cells) + ' |')
    lines.append('')
    lines.append(
        f'{len(set(a) | set(b)) - n_bad} of {len(set(a) | set(b))} scenes agree within {AGREE_SIGMAS:g} sigma.'
    )
    return '\n'.join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description='per-scene agreement of two sweep runs (a Markdown table)')
    ap.add_argument('run_a')
    ap.add_argument('run_b')
    ap.add_argument('--names', nargs=2, default=('A', 'B'))
    ap.add_argument('--common', action='store_true', help='only the scenes both runs swept')
    args = ap.parse_args(argv)
    for run in (args.run_a, args.run_b):
        if not glob.glob(os.path.join(run, 'timing', '*.json')):
            print(f'agree.py: {run}: no timing/*.json; name a run folder the sweep wrote', file=sys.stderr)
            return 2
    print(table(args.run_a, args.run_b, tuple(args.names), args.common))
    return 0


if __name__ == '__main__':
    sys.exit(main())
