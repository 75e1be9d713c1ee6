"""plan.py - which jobs a scene gets: the levels of every renderer's knobs, the two stages and why
a scene goes to stage two (deeper_reasons), and each job's expected cost for scheduling."""

import math

from .common import (
    CONFIDENCE,
    CYCLES_SPP,
    EEVEE_TAA,
    NOISE_MARGIN,
    POV_K,
    QUICK_EEVEE,
    QUICK_K,
    QUICK_POV,
    QUICK_REF,
    QUICK_SPP,
    QUICK_TESS,
    RASTER_K,
    RASTER_REPEATS,
    RASTER_TESS,
    REF_SPP,
    SEEDS,
    GAUSS_RATIO,
    SIGMA_NO_PIXELS,
    SLOPE_TOL,
)


# Cycles as the pixel integral (k = 1: a box over the pixel): a twin's Cycles job otherwise samples
# the model's own k x k positions (harness/renderers/cycles/cycles.h), against which the raster's
# sampling error would be nil at the as-is k and the k series would converge to nothing.
CYCLES_INTEGRAL = ['--supersample', '1']


def plan(quick, seed_opt):
    """The jobs of one scene: (key, renderer, tag, options, repeats, series labels, knob value)."""
    spp = QUICK_SPP if quick else CYCLES_SPP
    ref = QUICK_REF if quick else REF_SPP
    ks, tess, pov = (QUICK_K, QUICK_TESS, QUICK_POV) if quick else (RASTER_K, RASTER_TESS, POV_K)
    jobs = [
        dict(
            key='reference',
            renderer='cycles',
            tag=f'cycles-spp{ref}',
            label=f'{ref} spp (reference)',
            opts=['--samples', str(ref), '--seeds', str(SEEDS)] + CYCLES_INTEGRAL,
            series='cycles spp',
            samples=ref,
        )
    ]
    for n in spp:
        extra = ['--seed', str(SEEDS)] if seed_opt else []
        jobs.append(
            dict(
                key=f'cycles{n}',
                renderer='cycles',
                tag=f'cycles-spp{n}' + ('-s2' if seed_opt else ''),
                label=f'{n} spp',
                opts=['--samples', str(n), '--seeds', str(SEEDS)] + CYCLES_INTEGRAL + extra,
                series='cycles spp',
                samples=n,
            )
        )
    jobs.append(
        dict(
            key='as_is',
            renderer='raster',
            tag='raster-as-is',
            label='as-is',
            opts=[],
            series='raster shading',
            repeats=RASTER_REPEATS,
        )
    )
    jobs.append(
        dict(
            key='per_vertex',
            renderer='raster',
            tag='raster-per-vertex',
            label='per-vertex',
            opts=['--per-vertex'],
            series='raster shading',
            repeats=RASTER_REPEATS,
        )
    )
    for k in ks:
        jobs.append(
            dict(
                key=f'rk{k}',
                renderer='raster',
                tag=f'raster-k{k}',
                label=f'k={k}',
                opts=['--supersample', str(k)],
                series='raster k',
                repeats=RASTER_REPEATS,
            )
        )
    for t in tess:
        jobs.append(
            dict(
                key=f'rt{t}',
                renderer='raster',
                tag=f'raster-t{t}',
                label=f'tess={t}',
                opts=['--tessellation', str(t)],
                series='raster tessellation',
                repeats=RASTER_REPEATS,
            )
        )
    for k in pov:
        jobs.append(
            dict(
                key=f'pk{k}',
                renderer='povray',
                tag=f'povray-k{k}',
                label=f'k={k}',
                opts=['--supersample', str(k)],
                series='povray k',
            )
        )
    for n in QUICK_EEVEE if quick else EEVEE_TAA:
        jobs.append(
            dict(
                key=f'ee{n}',
                renderer='eevee',
                tag=f'eevee-taa{n}',
                label=f'{n} TAA',
                opts=['--samples', str(n)],
                series='eevee taa',
                samples=n,
            )
        )
    return jobs, ref


def stage_one(jobs, ref_spp):
    """The first stage of a scene's Cycles levels: the top level (seeds 0..1) stands in for the
    reference, the levels below it are points. Returns (jobs, reference spp). The top level is
    the same render as stage two's top point (same samples and seeds: one cache key), so a scene
    that goes on to stage two renders nothing twice."""
    levels = sorted(j['samples'] for j in jobs if j['renderer'] == 'cycles' and j['key'] != 'reference')
    if len(levels) < 2:
        return jobs, ref_spp
    top = levels[-1]
    out = []
    for j in jobs:
        if j['key'] in ('reference', f'cycles{top}'):
            continue
        out.append(j)
    out.insert(0, top_job(top, 'reference', f'{top} spp (reference)'))
    return out, top


def top_job(top, key, label):
    """The top Cycles level at seeds 0..1: stage one's reference, stage two's top point. The
    pixel integral like every other Cycles level: a twin's default (the model's k x k positions)
    differs from the integral by a bias, which against the points reads as an error floor."""
    return dict(
        key=key,
        renderer='cycles',
        tag=f'cycles-spp{top}',
        label=label,
        opts=['--samples', str(top), '--seeds', str(SEEDS)] + CYCLES_INTEGRAL,
        series='cycles spp',
        samples=top,
    )


# Stage two's reference seeds (with `run --seed`): past the points' 2..3 and the top level's
# 0..1, so that it is independent of every point it measures.
DEEP_SEED = 2 * SEEDS


def stage_two(jobs1, top, ref_spp, seed_opt):
    """Stage one's jobs with the deep reference added: the stage-one reference becomes the top
    point, the reference is ref_spp at seeds DEEP_SEED.. (with --seed; else 0.., nested as
    before). Returns (jobs, ref_spp)."""
    out = [dict(j) for j in jobs1 if j['key'] != 'reference']
    out.append(top_job(top, f'cycles{top}', f'{top} spp'))
    extra = ['--seed', str(DEEP_SEED)] if seed_opt else []
    ref = dict(
        key='reference',
        renderer='cycles',
        tag=f'cycles-spp{ref_spp}' + (f'-s{DEEP_SEED}' if seed_opt else ''),
        label=f'{ref_spp} spp (reference)',
        opts=['--samples', str(ref_spp), '--seeds', str(SEEDS)] + CYCLES_INTEGRAL + extra,
        series='cycles spp',
        samples=ref_spp,
    )
    return [ref] + out, ref_spp


def point_sigma(p, noise_ref=None, nested=False):
    """A Cycles point's standard error in ln(error). Its error is a mean square over n surface
    pixels: m^2 (measured against the reference) less r^2 (the reference's noise, from its two
    seeds' variance) where the two are independent. A mean of n terms has a relative standard
    error sqrt((E[x^2]/E[x]^2 - 1) / n); E[x^2]/E[x]^2 is 3 for a squared Gaussian, and at least
    100 w^2 when the worst 1 % of the pixels hold a share w of the sum (Cauchy-Schwarz over those
    pixels), so a few bright outliers widen it. r^2 is a two-seed variance, one degree of freedom
    a pixel: relative error sqrt(2 / n). Half the relative error of e^2 is that of e."""
    m, n, w = p.get('nrmse'), p.get('n_pixels') or 0, p.get('worst1_share') or 0.0
    e = p.get('error')
    if not m or not e or n <= 0:
        return SIGMA_NO_PIXELS
    rel_m2 = math.sqrt((max(GAUSS_RATIO, 100.0 * w * w) - 1.0) / n)
    if nested or not noise_ref:
        return rel_m2 / 2.0
    var_e2 = (m * m * rel_m2) ** 2 + (noise_ref * noise_ref * math.sqrt(2.0 / n)) ** 2
    return math.sqrt(var_e2) / (2.0 * e * e)


def top_slope(t):
    """The spp slope between stage one's top two points and its standard error: (slope, sigma,
    (n_top, error_top)), or None without two points."""
    cyc = next((s for s in t['series'] if s['label'] == 'cycles spp'), None)
    pts = sorted(
        (p for p in (cyc or {}).get('points', []) if not p['is_reference'] and p.get('error') and p.get('samples')),
        key=lambda p: p['samples'],
    )
    if len(pts) < 2 or pts[-1]['samples'] == pts[-2]['samples']:
        return None
    a, b = pts[-2], pts[-1]
    ref = t.get('reference') or {}
    noise, nested = ref.get('noise_nrmse'), ref.get('nested', False)
    span = math.log(b['samples'] / a['samples'])
    slope = math.log(b['error'] / a['error']) / span
    sigma = math.hypot(point_sigma(a, noise, nested), point_sigma(b, noise, nested)) / span
    return slope, sigma, (b['samples'], b['error'])


def crossover_range(target, slope, sigma, top_point):
    """The spp at which Cycles reaches target, extrapolated from the top point on the top slope
    at slope -/+ CONFIDENCE sigma: (low, high); high is inf where the slope may be flat."""
    n, e = top_point
    if not target or target <= 0 or e <= target:
        return n, n
    steep, shallow = slope - CONFIDENCE * sigma, slope + CONFIDENCE * sigma
    low = n * (target / e) ** (1.0 / steep) if steep < 0 else math.inf
    high = n * (target / e) ** (1.0 / shallow) if shallow < 0 else math.inf
    return low, high


def decision_errors(t):
    """The non-Cycles errors the sweep reports as decisions: the raster as-is, the raster's best
    (the two crossovers' targets) and every non-Cycles point on the Pareto frontier."""
    errs = {}
    if (t.get('as_is') or {}).get('error'):
        errs['raster as-is'] = t['as_is']['error']
    for c in (t.get('crossover'), t.get('crossover_best_raster')):
        if c and c.get('raster_error'):
            errs.setdefault(f"raster {c.get('raster_label', 'as-is')}", c['raster_error'])
    for p in t.get('pareto') or []:
        if p['renderer'] != 'cycles' and p.get('error'):
            errs.setdefault(f"{p['renderer']} {p['label']}", p['error'])
    return errs


def stage_decision(t, top):
    """Whether stage one's figures need stage two (the top level as a point, the deep
    reference): {'deep': [why, ...], 'not_deep': [what stage one leaves open, ...]}.
    The rule: a deeper level is rendered only where it can change a reported figure:
      crossover   Cycles reaches a raster error (as-is or best) above stage one's points, and
                  the crossover's CONFIDENCE-sigma range (the top slope's own uncertainty from
                  the two seeds) reaches down to the top level, which stage two adds as a point;
                  a crossover whose range lies wholly above it stays extrapolated whatever
                  stage two renders, and is reported so (not_deep), with its range;
      slope       the top slope is slower than the Monte Carlo rate -0.5 by more than
                  CONFIDENCE sigma (a floor may begin; the 1024 point shows it); within it, the
                  departure is the seeds' scatter (not_deep); faster is stratification;
      reference   the reference's noise is above a third (NOISE_MARGIN) of an error the sweep
                  reports as a decision (raster as-is, raster best, a non-Cycles Pareto point):
                  its quadrature correction moves that error by more than 5.4 %
                  (sqrt(1 + 1/9)), more than the two seeds resolve;
      no slope    stage one has no two Cycles points (a failed level)."""
    deep, open_ = [], []
    ts = top_slope(t)
    if ts is None:
        return {'deep': ['no spp slope from stage one'], 'not_deep': []}
    slope, sigma, top_point = ts
    for k in ('crossover', 'crossover_best_raster'):
        c = t.get(k)
        if not (c and c.get('extrapolated') == 'above'):
            continue
        low, high = crossover_range(c.get('raster_error'), slope, sigma, top_point)
        what = f"{k.replace('_', ' ')} at {c['spp']:.3g} spp ({CONFIDENCE:g}-sigma range {low:.3g}..{high:.3g})"
        if low <= top:
            deep.append(f'{what}: within the {top}-spp level stage two adds')
        else:
            open_.append(f'{what}: above the measured range; not decidable within {top} spp')
    if slope - CONFIDENCE * sigma > -0.5:
        deep.append(f'spp slope {slope:.2f} +/- {sigma:.2f} at the top, slower than -0.5: a floor may begin there')
    elif slope > -0.5 + SLOPE_TOL:
        open_.append(f'spp slope {slope:.2f} +/- {sigma:.2f} at the top: -0.5 within {CONFIDENCE:g} sigma')
    noise = (t.get('reference') or {}).get('noise_nrmse')
    errs = decision_errors(t)
    if noise and errs:
        name, low_err = min(errs.items(), key=lambda kv: kv[1])
        if noise > low_err / NOISE_MARGIN:
            deep.append(f'reference noise {noise:.3g} above a third of the {name} error {low_err:.3g}')
    elif noise and not errs:
        deep.append('no error measured against the stage-one reference')
    return {'deep': deep, 'not_deep': open_}


def deeper_reasons(t, top=1024):
    """Why a scene needs stage two (stage_decision's 'deep'): empty when stage one decides."""
    return stage_decision(t, top)['deep']


def expected_cost(job):
    """Longest jobs first keeps both workers busy to the end (LPT scheduling)."""
    if job['renderer'] == 'cycles':
        return 2.0 + job['samples'] * 0.02
    if job['renderer'] == 'eevee':  # shader compilation on llvmpipe, then about 0.1 s a sample
        return 10.0 + job['samples'] * 0.1
    return 1.5 if job['renderer'] == 'povray' else 0.1
