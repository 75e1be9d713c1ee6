"""proposal - threshold proposals from the measured values (reports/README.md): the
unified-diff-like text and the rows of thresholds-proposal.html. Scene files are never edited.
"""

import math

from .util import fexp, finite, is_num, yaml_num

# A scene file's comparison leaves `test` out when it is this one (scenes/FORMAT.md).
SCENE_DEFAULT_TEST = 'raster'


def round_up_1sig(v):
    """Smallest 1-significant-digit number >= v (2.34e-4 -> 3e-4)."""
    if v <= 0:
        return v
    e = math.floor(math.log10(v))
    # Guards against 2.0000000001 / 1e-4 rounding up to 3 because of binary floating point.
    m = math.ceil(v / 10**e * (1 - 1e-12))
    if m >= 10:
        m, e = 1, e + 1
    return float(f'{m}e{e}')


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
        lines.append(
            f'+++ {path}\t(proposed: warn = 2x, fail = 4x measured, 1 significant digit up, '
            'never below the precision floor)'
        )
        for c in s['comparisons']:
            if c.get('pseudo'):
                lines.append(f'@@ {c["id"]}: {c["reason"]} @@')
                continue
            lines.append(f'@@ {c["id"]} ({c["role"]}, {c["status"]}) @@')
            test = '' if c.get('test', SCENE_DEFAULT_TEST) == SCENE_DEFAULT_TEST else f'test: {c["test"]}, '
            lines.append(f'   - {{{test}reference: {c.get("reference", "?")}, role: {c["role"]}}}')
            lines.append('     thresholds:')
            if not c['thresholds']:
                lines.append('     # no thresholds in compare.json')
            for t in c['thresholds']:
                warn, fail = t.get('warn'), t.get('fail')
                nw, nf, note = propose(c, t)
                cur = yaml_line(t, warn, fail)
                row = {
                    'scene': s['name'],
                    'comparison': c['id'],
                    'metric': t['metric'],
                    'value': t.get('value'),
                    'warn': warn,
                    'fail': fail,
                    'new_warn': nw,
                    'new_fail': nf,
                    'note': note,
                    'verdict': t.get('verdict'),
                    'floor': precision_floor(c, t),
                }
                rows.append(row)
                if nw is None or (nw == warn and nf == fail):
                    lines.append(f' {cur}    # {note}')
                else:
                    lines.append(f'-{cur}    # {note}')
                    lines.append(f'+{yaml_line(t, nw, nf)}')
    return '\n'.join(lines) + '\n', rows
