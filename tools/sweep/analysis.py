"""analysis.py - a scene's diffs and noise estimates, and its timing JSON: points, fits, Pareto
frontier, equal-time budgets and crossovers (everything but the rendering)."""

import os
import shutil
import subprocess

from .common import BUDGETS_S, FORMAT, SEEDS, TERMS
from .fitmath import (
    best_within,
    crossover,
    fit_eval,
    fit_linear,
    fit_loglog,
    independent_error,
    local_slopes,
    nested_error,
    pareto,
    slope_note,
)


def scene_diffs(runner, jobs, recs, zero):
    """Every ok job's diff against the reference (masked by the raster as-is) and the Cycles
    points' own noise; returns (diffs, noises, terms left out). A partial twin is compared on the
    terms the reference renders, as compare.json compares it; the reference's own noise needs no
    such care: its image holds no left-out term. All of a scene's diffs go to the runner at
    once (runner.diff_many: one process for those its cache does not answer)."""
    ref, mask = recs['reference']['exr'], recs['as_is']['exr']
    left = terms_left_out(recs['reference'])
    items, slots = [], []
    for j in jobs:
        if recs[j['key']].get('status') != 'ok':
            continue
        keys = (recs[j['key']].get('key'), recs['reference'].get('key'), recs['as_is'].get('key'))
        items.append((recs[j['key']]['exr'], ref, mask, left, keys))
        slots.append(('diff', j['key']))
        if j['renderer'] == 'cycles' and zero is not None:
            # The zero image is made from the mask's render: 'zero-' and its key name it.
            zkeys = (f'zero-{keys[2]}', keys[0], keys[2]) if keys[0] and keys[2] else None
            items.append((zero, recs[j['key']]['exr'], mask, (), zkeys))
            slots.append(('noise', j['key']))
        elif j['renderer'] == 'cycles':
            slots.append(('noise', j['key']))
            items.append(None)
    answers = runner.diff_many([it for it in items if it is not None])
    diffs, noises, it = {}, {}, iter(answers)
    for (kind, key), item in zip(slots, items):
        d = next(it) if item is not None else None
        if kind == 'diff':
            if isinstance(d, Exception):
                diffs[key + ':err'] = str(d)
            else:
                diffs[key] = d
        else:
            noises[key] = noise_of(d)
    return diffs, noises, left


def noise_of(d):
    """A render's own noise, as NRMSE (RMS of the var.* std-dev over the mean of the image), from
    `diff ZERO X` (None: no zero image, or that diff failed): it gives rmse = rms(X) and nrmse =
    rms/mean over the surface, and its noise.ref_rel_rms = sqrt(sum var / sum X^2); so
    noise/mean = ref_rel_rms * nrmse."""
    if not isinstance(d, dict):
        return None
    rel = (d.get('noise') or {}).get('ref_rel_rms')
    nr = (d.get('surface') or {}).get('nrmse')
    return rel * nr if rel is not None and nr else None


def make_zero(like, path):
    """An all-zero R, G, B image of like's size (oiiotool): the 'test' that turns diff into a
    norm. None if oiiotool is missing (noise estimates are then left out)."""
    exe = shutil.which('oiiotool')
    if not exe:
        return None
    r = subprocess.run(
        [exe, like, '--ch', 'R,G,B', '--mulc', '0', '-o', path], capture_output=True, text=True, timeout=120
    )
    return path if r.returncode == 0 and os.path.exists(path) else None


def point_of(job, rec, d, noise, err, clock='wall_s'):
    s = (d or {}).get('surface') or {}
    return {
        'label': job['label'],
        'renderer': job['renderer'],
        'tag': job['tag'],
        'time_s': rec.get(clock),
        'wall_s': rec.get('wall_s'),
        'cpu_s': rec.get('cpu_s'),
        'render_s': rec.get('render_s'),
        # The job's own knob where it has one: EEVEE's record keeps no samples (not stochastic).
        'samples': job.get('samples', rec.get('samples')),
        'seeds': rec.get('seeds'),
        'supersample': rec.get('supersample'),
        'tessellation': rec.get('tessellation'),
        'per_vertex': rec.get('per_vertex'),
        'cached': rec.get('cached'),
        'rmse': s.get('rmse'),
        'nrmse': s.get('nrmse'),
        'rel_rms': s.get('rel_rms'),
        'psnr': s.get('psnr'),
        'ssim': s.get('ssim'),
        # Surface pixels measured and the worst 1 %'s share of the squared error: a point's
        # uncertainty (plan.point_sigma).
        'n_pixels': s.get('n_pixels'),
        'worst1_share': s.get('worst1_share'),
        'error': err,
        'noise_nrmse': noise,
        'is_reference': job['key'] == 'reference',
    }


def terms_left_out(rec):
    """The terms a reference's job record says it left out (a partial twin), in TERMS order. The
    record lists {"term": NAME, "reason": TEXT} (a bare name is taken too)."""
    left = {e.get('term') if isinstance(e, dict) else e for e in rec.get('terms_left_out') or []}
    return [t for t in TERMS if t in left]


def scene_points(jobs, recs, diffs, noises, ref_spp, nested, clock):
    """Every ok job's point, by series (keyed by label), the jobs skipped, and all points in job
    order."""
    noise_ref = noises.get('reference')
    series, skipped, all_pts = {}, [], []
    for job in jobs:
        rec = recs[job['key']]
        if rec.get('status') != 'ok' or job['key'] not in diffs:
            skipped.append(
                {
                    'label': f"{job['series']} {job['label']}",
                    'message': rec.get('message') or diffs.get(job['key'] + ':err', 'no diff'),
                }
            )
            continue
        nr = diffs[job['key']]['surface'].get('nrmse')
        if job['key'] == 'reference':
            err = noise_ref
        elif job['renderer'] == 'cycles' and nested:
            err = nested_error(nr, job['samples'], ref_spp)
        else:
            err = independent_error(nr, noise_ref)
        p = point_of(job, rec, diffs[job['key']], noises.get(job['key']), err, clock)
        series.setdefault(
            job['series'],
            {
                'label': job['series'],
                'renderer': job['renderer'],
                'knob': {
                    'cycles spp': 'samples',
                    'raster k': 'supersample',
                    'povray k': 'supersample',
                    'raster tessellation': 'tessellation',
                    'raster shading': 'per_vertex',
                    'eevee taa': 'samples',
                }[job['series']],
                'points': [],
            },
        )['points'].append(p)
        all_pts.append(p)
    return series, skipped, all_pts


# The series in the order the timing JSON lists them.
SERIES_ORDER = ('cycles spp', 'raster k', 'raster tessellation', 'raster shading', 'povray k', 'eevee taa')


def fit_series(series):
    """Each series' points in knob order with its fits (and Cycles' spp fit and time model)."""
    out_series = []
    for label in SERIES_ORDER:
        sr = series.get(label)
        if not sr:
            continue
        # Knob order (not time order): a plot line then follows the knob even where timing
        # noise at the millisecond level swaps two neighbours.
        knob = sr['knob']
        sr['points'].sort(key=lambda p: (p['is_reference'], p.get(knob) is None, p.get(knob) or 0))
        fitted = [p for p in sr['points'] if not p['is_reference']]
        sr['fit'] = fit_loglog([p['time_s'] for p in fitted], [p['error'] for p in fitted])
        if sr['fit']:
            sr['fit']['x'] = 'time_s'
            sr['fit']['local'] = local_slopes([p['time_s'] for p in fitted], [p['error'] for p in fitted])
        if label == 'cycles spp':
            xs, ys = [p['samples'] for p in fitted], [p['error'] for p in fitted]
            sr['fit_spp'] = fit_loglog(xs, ys)
            local = local_slopes(xs, ys)
            if sr['fit_spp']:
                sr['fit_spp']['x'] = 'samples'
                sr['fit_spp']['local'] = local
            sr['slope_note'] = slope_note(sr['fit_spp'], local)
            every = sr['points']
            lin = fit_linear([p['samples'] for p in every], [p['time_s'] for p in every])
            rlin = fit_linear([p['samples'] for p in every], [p['render_s'] for p in every])
            sr['time_model'] = (
                None
                if lin is None
                else {
                    't0_s': lin[0],
                    's_per_spp': lin[1],
                    'render_t0_s': rlin[0] if rlin else None,
                    'render_s_per_spp': rlin[1] if rlin else None,
                }
            )
        out_series.append(sr)
    return out_series


def equal_time(jobs, all_pts, as_is, cyc):
    """Each renderer's best point within each budget (the raster as-is time, then BUDGETS_S), and
    Cycles' fitted error there."""
    budgets = ([('raster as-is', as_is['time_s'])] if as_is else []) + [(f'{b:g} s', b) for b in BUDGETS_S]
    equal = []
    for name, b in budgets:
        best = {}
        for r in dict.fromkeys(j['renderer'] for j in jobs):  # the plan's renderers, in order
            p = best_within([q for q in all_pts if q['renderer'] == r], b)
            best[r] = None if p is None else {'label': p['label'], 'time_s': p['time_s'], 'error': p['error']}
        fe = None
        if cyc and cyc.get('time_model') and cyc.get('fit_spp'):
            tm = cyc['time_model']
            if tm['s_per_spp'] > 0 and b > tm['t0_s']:
                fe = fit_eval(cyc['fit_spp'], (b - tm['t0_s']) / tm['s_per_spp'])
        equal.append({'budget': name, 'budget_s': b, 'best': best, 'cycles_fit_error': fe})
    return equal


def crossovers(cyc, as_is, all_pts):
    """Cycles' crossover with the raster as-is error and with the raster's best error."""
    cross = cross_best = None
    if cyc and as_is:
        lv = [(p['samples'], p['time_s']) for p in cyc['points'] if not p['is_reference']]
        rlv = [(p['samples'], p['render_s']) for p in cyc['points'] if not p['is_reference']]
        cross = crossover(cyc.get('fit_spp'), lv, rlv, cyc.get('fit'), as_is['error'])
        rast = [p for p in all_pts if p['renderer'] == 'raster' and p['error']]
        if rast:
            b = min(rast, key=lambda p: p['error'])
            cross_best = crossover(cyc.get('fit_spp'), lv, rlv, cyc.get('fit'), b['error'])
            if cross_best:
                cross_best['raster_label'] = b['label']
    for c in (cross, cross_best):
        if c:
            c['note'] = {
                None: 'interpolated between measured spp levels',
                'below': 'below the fewest samples measured: Cycles at its lowest level is already '
                'closer to the reference than the raster',
                'above': 'beyond the most samples measured: extrapolated on the fit',
            }[c['extrapolated']]
    return cross, cross_best


def analyse(
    scene, jobs, recs, diffs, noises, ref_spp, nested, size, clock='wall_s', role='validate', left_out=(), ref_seed=0
):
    """Everything but the rendering: points, fits, Pareto frontier, equal time, crossover.
    left_out: the terms the reference left out, which every diff left out too."""
    noise_ref = noises.get('reference')
    series, skipped, all_pts = scene_points(jobs, recs, diffs, noises, ref_spp, nested, clock)
    # The as-is raster point is also the k = (small default) point of the k series.
    as_is = next((p for p in all_pts if p['tag'] == 'raster-as-is'), None)
    out_series = fit_series(series)
    front = pareto(all_pts)
    cyc = series.get('cycles spp')
    equal = equal_time(jobs, all_pts, as_is, cyc)
    cross, cross_best = crossovers(cyc, as_is, all_pts)
    return {
        'format': FORMAT,
        'scene': scene,
        'size': size,
        'error_key': 'error',
        'clock': clock,
        'error_doc': 'estimated NRMSE (surface RMSE over the reference mean) against the noise-free '
        'image: the measured NRMSE against the reference with the reference noise taken '
        'out (see tools/sweep.py)'
        + (
            f'; a partial {role}: {", ".join(left_out)} left out of every image, as the reference '
            f'leaves it out; terms compared: {", ".join(t for t in TERMS if t not in left_out)}'
            if left_out
            else ''
        ),
        'reference': {
            'renderer': 'cycles',
            'role': role,
            'terms_left_out': list(left_out),
            'terms_compared': [t for t in TERMS if t not in left_out],
            'samples': ref_spp,
            'seeds': list(range(ref_seed, ref_seed + SEEDS)),
            'noise_nrmse': noise_ref,
            'nested': nested,
            'note': (
                'sweep points use seeds 0..1 too: they are the first n samples of the '
                'reference (PMJ is nested); error corrects the measured NRMSE by '
                '1/sqrt(1 - n/N)'
            )
            if nested
            else (
                'sweep points use seeds 2..3, disjoint from the reference\'s; error takes '
                'the reference noise out in quadrature'
            )
            if ref_seed == 0
            else (
                f'sweep points use seeds 2..3, and the levels that were references in earlier '
                f'stages seeds 0..1, 4..5, ..., all disjoint from the reference\'s '
                f'{ref_seed}..{ref_seed + SEEDS - 1}; error takes the reference noise out in quadrature'
            ),
        },
        'series': out_series,
        'as_is': as_is,
        'pareto': [
            {'label': p['label'], 'renderer': p['renderer'], 'time_s': p['time_s'], 'error': p['error']} for p in front
        ],
        'equal_time': equal,
        'crossover': cross,
        'crossover_best_raster': cross_best,
        'skipped': skipped,
    }


def fmt(v, spec='.3g'):
    return '-' if v is None else format(v, spec)


def one_line(t):
    cyc = next((s for s in t['series'] if s['label'] == 'cycles spp'), {})
    fs, c = cyc.get('fit_spp'), t.get('crossover')
    ref = t.get('reference') or {}
    left = ref.get('terms_left_out') or []
    role = f"role {ref.get('role', '?')}" + (
        f" on {'+'.join(ref.get('terms_compared') or [])} ({'+'.join(left)} left out)" if left else ''
    )
    return (
        f"{t['scene']} ({role}): raster as-is error {fmt((t['as_is'] or {}).get('error'))}; cycles slope "
        f"{fmt(fs and fs['slope'], '.2f')}/spp, {fmt(cyc.get('fit') and cyc['fit']['slope'], '.2f')}/s; "
        f"crossover {fmt(c and c['spp'], '.3g')} spp = {fmt(c and c['time_s'], '.3g')} s"
        + (f" ({c['extrapolated']} the measured range)" if c and c['extrapolated'] else '')
    )
