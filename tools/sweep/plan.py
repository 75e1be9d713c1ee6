"""plan.py - which jobs a scene gets: the levels of every renderer's knobs, the two stages and why
a scene goes to stage two (deeper_reasons), and each job's expected cost for scheduling."""

import math

from .common import (
    CONFIDENCE,
    CYCLES_SPP,
    FIRST_REF_SPP,
    EEVEE_TAA,
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
    SIGMA_DECIDED,
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


def ladder(jobs, ref_spp):
    """The Cycles levels of a plan, the reference's last: 16, 64, 256, 1024, 4096 (quick: 16, 64,
    256, 1024)."""
    return sorted({j['samples'] for j in jobs if j['renderer'] == 'cycles' and j['key'] != 'reference'} | {ref_spp})


def stage_one(jobs, ref_spp, first=FIRST_REF_SPP):
    """The first stage of a scene's Cycles levels: level `first` (seeds 0..1) stands in for the
    reference, the levels below it are points, the levels above it wait for a later stage
    (stage_next). Returns (jobs, reference spp). A reference becomes the next stage's top point
    as the same render (same samples, seeds and tag: one cache key), so a scene that goes on
    renders nothing twice."""
    steps = ladder(jobs, ref_spp)
    if first not in steps or steps.index(first) < 2:
        first = steps[-2] if len(steps) >= 3 else ref_spp
    out = [j for j in jobs if j['key'] != 'reference' and not (j['renderer'] == 'cycles' and j['samples'] >= first)]
    if len(out) == len(jobs) - 1:
        return jobs, ref_spp
    out.insert(0, top_job(first, 'reference', f'{first} spp (reference)'))
    return out, first


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


def stage_seed(stage):
    """The first seed of stage `stage`'s reference (with `run --seed`): stage one's is 0 and
    its points use SEEDS (2..3); stage s > 1 uses 2 s (4..5, then 6..7), past every seed a point
    of it holds (the earlier references, now points), so that it is independent of them all."""
    return 0 if stage == 1 else SEEDS * stage


def stage_next(jobs, top, steps, seed_opt, stage):
    """The jobs of stage `stage` (2, 3, ...) from the previous stage's: its reference (at top)
    becomes a point, the reference is the next of the levels `steps` (the plan's ladder) above
    top, at seeds stage_seed(stage).. with --seed (else 0.., nested as before). Returns (jobs,
    new top spp); (jobs, top) unchanged where no level is above top."""
    new_top = min((n for n in steps if n > top), default=None)
    if new_top is None:
        return jobs, top
    old = next(j for j in jobs if j['key'] == 'reference')
    out = [dict(j) for j in jobs if j['key'] != 'reference']
    out.append(dict(old, key=f'cycles{top}', label=f'{top} spp'))
    seed = stage_seed(stage)
    extra = ['--seed', str(seed)] if seed_opt else []
    ref = dict(
        key='reference',
        renderer='cycles',
        tag=f'cycles-spp{new_top}' + (f'-s{seed}' if seed_opt else ''),
        label=f'{new_top} spp (reference)',
        opts=['--samples', str(new_top), '--seeds', str(SEEDS)] + CYCLES_INTEGRAL + extra,
        series='cycles spp',
        samples=new_top,
    )
    return [ref] + out, new_top


def stage_two(jobs1, top, ref_spp, seed_opt):
    """Stage two straight to ref_spp (the two-stage sweep before FIRST_REF_SPP): stage_next
    with ref_spp as the only level above top. Returns (jobs, ref_spp)."""
    return stage_next(jobs1, top, [ref_spp], seed_opt, 2)


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


def error_sigma(e, r, n):
    """Standard error in ln of a deterministic render's error e measured against a reference of
    noise r over n surface pixels: m^2 = mean (d + eps)^2 = e^2 + 2 mean(d eps) + mean eps^2, less
    r^2 from the reference's two seeds. The cross term scatters by 2 e r / sqrt(n), the noise
    term and its two-seed estimate by r^2 sqrt(2 / n) each: var(e^2) = 4 r^2 (e^2 + r^2) / n, and
    half of e^2's relative error is e's: (r / e) sqrt((1 + r^2 / e^2) / n). SIGMA_NO_PIXELS
    without a pixel count."""
    if not e or e <= 0 or not r:
        return 0.0
    if n <= 0:
        return SIGMA_NO_PIXELS
    q = r / e
    return q * math.sqrt((1.0 + q * q) / n)


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


def stage_decision(t, top, reach=None, last=None):
    """Whether stage one's figures need stage two (the top level as a point, the deep
    reference): {'deep': [why, ...], 'not_deep': [what stage one leaves open, ...]}.
    The rule: a deeper level is rendered only where it can change a reported figure:
      crossover   Cycles reaches a raster error (as-is or best) above stage one's points, and
                  the crossover's CONFIDENCE-sigma range (the top slope's own uncertainty from
                  the two seeds) reaches down to `reach`, the highest level the ladder can make
                  a point (1024 of 16..4096; default top); a crossover whose range lies wholly
                  above it stays extrapolated whatever is rendered, and is reported so
                  (not_deep), with its range;
      slope       the top slope is slower than the Monte Carlo rate -0.5 by more than
                  CONFIDENCE sigma (a floor may begin; the 1024 point shows it); within it, the
                  departure is the seeds' scatter (not_deep); faster is stratification;
      reference   the reference's noise leaves an error the sweep reports as a decision (raster
                  as-is, raster best, a non-Cycles Pareto point) uncertain by more than
                  SIGMA_DECIDED (error_sigma: the quadrature correction is unbiased, its scatter
                  is what a quieter reference removes), and the ladder's last level `last`
                  (4096; default top) would decide it (reference_reason);
      no slope    stage one has no two Cycles points (a failed level)."""
    deep, open_ = [], []
    reach = top if reach is None else reach
    last = top if last is None else last
    ts = top_slope(t)
    if ts is None:
        return {'deep': ['no spp slope from stage one'], 'not_deep': []}
    slope, sigma, top_point = ts
    for k in ('crossover', 'crossover_best_raster'):
        c = t.get(k)
        if not (c and c.get('extrapolated') == 'above'):
            continue
        low, high = crossover_range(c.get('raster_error'), slope, sigma, top_point)
        mid = crossover_range(c.get('raster_error'), slope, 0.0, top_point)[0]
        what = (
            f"{k.replace('_', ' ')} at {c['spp']:.3g} spp (fit; from the top slope {mid:.3g}, "
            f"{CONFIDENCE:g}-sigma range {low:.3g}..{high:.3g})"
        )
        if low <= reach:
            deep.append(f'{what}: within the {reach}-spp level a deeper stage adds as a point')
        else:
            open_.append(f'{what}: above the measured range; not decidable within {reach} spp')
    if slope - CONFIDENCE * sigma > -0.5:
        deep.append(f'spp slope {slope:.2f} +/- {sigma:.2f} at the top, slower than -0.5: a floor may begin there')
    elif slope > -0.5 + SLOPE_TOL:
        open_.append(f'spp slope {slope:.2f} +/- {sigma:.2f} at the top: -0.5 within {CONFIDENCE:g} sigma')
    d, o = reference_reason(t, top, last, slope)
    deep += d
    open_ += o
    return {'deep': deep, 'not_deep': open_}


def reference_reason(t, top, last, slope):
    """The reference part of stage_decision: (deep, not_deep). The smallest decision error's
    uncertainty now (error_sigma with the reference's noise r) and at the ladder's last level,
    where the noise is predicted as r (last / top)^s, s the Cycles top slope or the Monte Carlo
    rate -0.5, whichever falls faster (a floor in the points is no floor in a two-seed variance)."""
    noise = (t.get('reference') or {}).get('noise_nrmse')
    errs = decision_errors(t)
    n = (t.get('as_is') or {}).get('n_pixels') or 0
    if noise and not errs:
        return ['no error measured against the stage-one reference'], []
    if not noise:
        return [], []
    name, low_err = min(errs.items(), key=lambda kv: kv[1])
    sig = error_sigma(low_err, noise, n)
    if sig <= SIGMA_DECIDED:
        return [], []
    what = f'reference noise {noise:.3g} leaves the {name} error {low_err:.3g} uncertain by {100 * sig:.0f} %'
    if last <= top:
        return [], [f'{what} (no level above {top} spp)']
    then = error_sigma(low_err, noise * (last / top) ** min(slope, -0.5), n)
    if then > SIGMA_DECIDED:
        return [], [f'{what}; {100 * then:.0f} % predicted at {last} spp: not decidable within the ladder']
    return [f'{what} (over {100 * SIGMA_DECIDED:.0f} %; {100 * then:.0f} % predicted at {last} spp)'], []


def deeper_reasons(t, top=1024, reach=None, last=REF_SPP):
    """Why a scene needs a deeper stage (stage_decision's 'deep'): empty when this one decides."""
    return stage_decision(t, top, reach, last)['deep']


def expected_cost(job):
    """Longest jobs first keeps both workers busy to the end (LPT scheduling)."""
    if job['renderer'] == 'cycles':
        return 2.0 + job['samples'] * 0.02
    if job['renderer'] == 'eevee':  # shader compilation on llvmpipe, then about 0.1 s a sample
        return 10.0 + job['samples'] * 0.1
    return 1.5 if job['renderer'] == 'povray' else 0.1
