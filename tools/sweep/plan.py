"""plan.py - which jobs a scene gets: the levels of every renderer's knobs, the two stages and why
a scene goes to stage two (deeper_reasons), and each job's expected cost for scheduling."""

from .common import (
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


def deeper_reasons(t):
    """Why a scene swept against its stage-one reference needs the top level as a point and the
    deep reference (the rule: a render is spent where it decides a slope, a crossover or an
    error). Empty when stage one decides all three:
      crossover   Cycles reaches the raster's error (as-is or best) beyond the levels measured:
                  only higher levels place it;
      slope       between the top two levels the error falls slower than spp^-0.5 by more than
                  SLOPE_TOL: a floor (reference noise, bias) may begin, and only higher levels show
                  it (faster than -0.5 is PMJ's stratification, which stage one measures);
      reference   the reference's noise is above a third of the smallest non-Cycles error it
                  measures: the quadrature subtraction would move that error by more than 5.4 %
                  (sqrt(1 + 1/9)), so the error needs a quieter reference. (Cycles' own points
                  are corrected exactly for the reference's noise, nested or independent.)"""
    why = []
    for k in ('crossover', 'crossover_best_raster'):
        c = t.get(k)
        if c and c.get('extrapolated') == 'above':
            why.append(f"{k.replace('_', ' ')} at {c['spp']:.0f} spp, above the levels measured")
            break
    cyc = next((s for s in t['series'] if s['label'] == 'cycles spp'), None)
    fs = cyc and cyc.get('fit_spp')
    if fs is None:
        why.append('no spp slope from stage one')
    else:
        top = (fs.get('local') or [{}])[-1].get('slope', fs['slope'])
        if top > -0.5 + SLOPE_TOL:
            why.append(f'spp slope {top:.2f} between the top two levels, slower than -0.5: a floor may begin there')
    noise = (t.get('reference') or {}).get('noise_nrmse')
    errs = [
        p['error']
        for s in t['series']
        for p in s['points']
        if s['renderer'] != 'cycles' and not p['is_reference'] and p.get('error')
    ]
    if noise and errs and noise > min(errs) / NOISE_MARGIN:
        why.append(f'reference noise {noise:.3g} above a third of the smallest error {min(errs):.3g}')
    elif noise and not errs:
        why.append('no error measured against the stage-one reference')
    return why


def expected_cost(job):
    """Longest jobs first keeps both workers busy to the end (LPT scheduling)."""
    if job['renderer'] == 'cycles':
        return 2.0 + job['samples'] * 0.02
    if job['renderer'] == 'eevee':  # shader compilation on llvmpipe, then about 0.1 s a sample
        return 10.0 + job['samples'] * 0.1
    return 1.5 if job['renderer'] == 'povray' else 0.1
