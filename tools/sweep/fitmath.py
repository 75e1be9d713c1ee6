"""fitmath.py - the sweep's maths: log-log and linear least squares, Pareto frontier, the
nested/independent reference corrections, time interpolation and the crossover."""

import math

from .common import SLOPE_TOL


def fit_loglog(xs, ys):
    """Least squares of ln y on ln x over the points with x, y > 0.
    Returns {"slope", "intercept", "r2", "n"} or None with fewer than 2 distinct x."""
    pts = [(math.log(x), math.log(y)) for x, y in zip(xs, ys) if x is not None and y is not None and x > 0 and y > 0]
    if len({p[0] for p in pts}) < 2:
        return None
    n = len(pts)
    mx = sum(p[0] for p in pts) / n
    my = sum(p[1] for p in pts) / n
    sxx = sum((p[0] - mx) ** 2 for p in pts)
    sxy = sum((p[0] - mx) * (p[1] - my) for p in pts)
    syy = sum((p[1] - my) ** 2 for p in pts)
    b = sxy / sxx
    a = my - b * mx
    r2 = 1.0 if syy == 0 else (sxy * sxy) / (sxx * syy)
    return {'slope': b, 'intercept': a, 'r2': r2, 'n': n}


def fit_eval(fit, x):
    return math.exp(fit['intercept'] + fit['slope'] * math.log(x))


def fit_solve(fit, y):
    """x at which the fit reaches y; None for a flat or rising fit (it never gets there)."""
    if fit is None or fit['slope'] >= 0 or y is None or y <= 0:
        return None
    return math.exp((math.log(y) - fit['intercept']) / fit['slope'])


def local_slopes(xs, ys):
    """Slope of ln y on ln x between consecutive points (sorted by x): where a fit bends."""
    pts = sorted((x, y) for x, y in zip(xs, ys) if x and y and x > 0 and y > 0)
    return [
        {'from': a[0], 'to': b[0], 'slope': math.log(b[1] / a[1]) / math.log(b[0] / a[0])}
        for a, b in zip(pts, pts[1:])
        if b[0] != a[0]
    ]


def fit_linear(xs, ys):
    """Least squares y = a + b x. Returns (a, b) or None with fewer than 2 distinct x."""
    pts = [(x, y) for x, y in zip(xs, ys) if x is not None and y is not None]
    if len({p[0] for p in pts}) < 2:
        return None
    n = len(pts)
    mx = sum(p[0] for p in pts) / n
    my = sum(p[1] for p in pts) / n
    b = sum((p[0] - mx) * (p[1] - my) for p in pts) / sum((p[0] - mx) ** 2 for p in pts)
    return my - b * mx, b


def pareto(points):
    """Points no other point beats in both time and error (ties: the earlier in input order),
    ascending time. points: dicts with time_s and error."""
    ok = [p for p in points if p.get('time_s') is not None and p.get('error') is not None]
    ok.sort(key=lambda p: (p['time_s'], p['error']))
    front, best = [], math.inf
    for p in ok:
        if p['error'] < best:
            front.append(p)
            best = p['error']
    return front


def best_within(points, budget):
    """The lowest-error point whose time is within budget, or None."""
    ok = [p for p in points if p.get('time_s') is not None and p.get('error') is not None and p['time_s'] <= budget]
    return min(ok, key=lambda p: (p['error'], p['time_s'])) if ok else None


def nested_error(nrmse, n, n_ref):
    """Error against the noise-free image of an n-spp render whose samples are the first n of
    the n_ref-spp reference: measured MSE = var_n (1 - n/N), so divide it back out."""
    if nrmse is None or n >= n_ref:
        return None
    return nrmse / math.sqrt(1.0 - n / n_ref)


def independent_error(nrmse, noise_ref):
    """Error against the noise-free image of a render independent of the reference: the
    reference's noise adds in quadrature, so subtract it; None if it is all noise."""
    if nrmse is None:
        return None
    if not noise_ref:
        return nrmse
    d = nrmse * nrmse - noise_ref * noise_ref
    return math.sqrt(d) if d > 0 else None


def interp_time(levels, spp):
    """Seconds at spp from the measured (spp, seconds) levels: linear between the two levels
    around it, the last two levels' line beyond them, the first level's time below it (a
    bound: nothing measured is faster)."""
    lv = sorted((n, t) for n, t in levels if n is not None and t is not None)
    if not lv:
        return None
    if spp <= lv[0][0] or len(lv) == 1:
        return lv[0][1]
    for (n0, t0), (n1, t1) in zip(lv, lv[1:]):
        if spp <= n1:
            return t0 + (t1 - t0) * (spp - n0) / (n1 - n0)
    (n0, t0), (n1, t1) = lv[-2], lv[-1]
    return t1 + (t1 - t0) * (spp - n1) / (n1 - n0)


def crossover(fit_spp, levels, render_levels, fit_time, raster_error):
    """Where Cycles' fitted error (ln error on ln spp) falls to raster_error: the spp, its time
    interpolated between the measured levels (wall or CPU, and Blender's own render time), and
    the ln-error-on-ln-time fit's answer. None without a falling spp fit.
    levels / render_levels: [(spp, seconds)] of the measured Cycles levels."""
    spp = fit_solve(fit_spp, raster_error)
    if spp is None:
        return None
    ns = [n for n, _ in levels]
    out = {
        'raster_error': raster_error,
        'spp': spp,
        'time_s': interp_time(levels, spp),
        'render_s': interp_time(render_levels, spp),
        'loglog_time_s': fit_solve(fit_time, raster_error),
        'extrapolated': None,
    }
    if ns and spp < min(ns):
        # Under the fewest samples the answer is mostly Blender's start-up; the honest statement
        # is a bound: the lowest level measured already beats the raster.
        out['extrapolated'] = 'below'
        out['upper_bound_s'] = out['time_s']
    elif ns and spp > max(ns):
        out['extrapolated'] = 'above'
    return out


def slope_note(fit_spp, local):
    """Says whether Cycles' error falls as spp^-0.5, and where it does not."""
    if fit_spp is None:
        return 'no fit (fewer than two spp levels measured)'
    s = fit_spp['slope']
    off = [
        f"{int(l['from'])}->{int(l['to'])} spp: {l['slope']:.2f}" for l in local if abs(l['slope'] + 0.5) > SLOPE_TOL
    ]
    if abs(s + 0.5) <= SLOPE_TOL and not off:
        return f'spp^{s:.2f}: the Monte Carlo rate -0.5 throughout'
    why = (
        'faster than -0.5: stratified (PMJ) samples on a smooth integrand converge faster'
        if s < -0.5 - SLOPE_TOL
        else 'slower than -0.5: a floor (reference noise, clamping or bias) or rare bright paths'
        if s > -0.5 + SLOPE_TOL
        else 'overall -0.5'
    )
    return f'spp^{s:.2f} ({why})' + (f'; off -0.5 at {", ".join(off)}' if off else '')
