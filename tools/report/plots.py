"""plots - gnuplot SVGs: surface error per N.V / N.H / N.L bin, trends over the history, error vs time.
Scripts live in tools/plots/; each SVG is written through a temporary name.
"""

import hashlib
import os
import re
import shutil
import subprocess
import tempfile
from concurrent.futures import ThreadPoolExecutor

from .util import GNUPLOT_TIMEOUT_S, PLOTS, TREND_RUNS, finite, is_num, safe_name


def gnuplot_q(s):
    return "'" + str(s).replace("'", "''") + "'"


class PlotCache:
    """SVGs kept by the content of what draws them (set_cache): the script and every script it
    may load, the gnuplot program, the parameters and the data file's bytes. An unchanged plot
    is copied back instead of starting gnuplot (35 ms of CPU each, 180 plots in a run)."""

    def __init__(self):
        self.dir = None
        self.drawn = []  # the SVGs gnuplot drew in this process, and those copied back
        self.kept = []

    def key(self, exe, script, params):
        h = hashlib.sha256(b'reflcheck-plot-1\0')
        st = os.stat(exe)
        h.update(f'{exe} {st.st_size} {st.st_mtime_ns}\0{script}\0'.encode())
        for name in sorted(os.listdir(PLOTS)):  # common.gp and the others a script may load
            if name.endswith('.gp'):
                with open(os.path.join(PLOTS, name), 'rb') as f:
                    h.update(name.encode() + b'\0' + f.read() + b'\0')
        for k, v in sorted(params.items()):
            if k == 'datafile':  # a temporary path: its bytes below are what counts
                continue
            h.update(f'{k}={v!r}\0'.encode())
        with open(params['datafile'], 'rb') as f:
            h.update(f.read())
        return h.hexdigest()[:40]


CACHE = PlotCache()


def set_cache(folder):
    """Keep and reuse the SVGs in folder (made when missing); None: draw every plot."""
    CACHE.dir = folder


def _from_cache(path, out_svg):
    tmp = f'{out_svg}.tmp{os.getpid()}.svg'
    try:
        shutil.copyfile(path, tmp)
    except OSError:
        return False
    os.replace(tmp, out_svg)
    CACHE.kept.append(out_svg)
    return True


def _to_cache(svg, path):
    """Copied under a temporary name, then renamed: a reader sees a whole SVG or none. A cache
    that cannot be written costs the next run a redraw, nothing else."""
    try:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        tmp = f'{path}.tmp{os.getpid()}'
        shutil.copyfile(svg, tmp)
        os.replace(tmp, path)
    except OSError:
        pass


# Plots one gnuplot draws in a row (draw_queued): its start, most of a small plot's 10-20 ms of
# CPU, is paid once a batch; four batches a worker let the one that ends first take the next,
# so neither waits long for the other at the end.
BATCHES_PER_WORKER = 4
QUEUE = None  # the plots run_gnuplot deferred since queue_plots(); None: each drawn at once
DONE = 'reflcheck-plot-done'  # what a batch prints after each plot it wrote


def queue_plots():
    """From now on run_gnuplot only records the plots the cache does not hold (and answers True);
    draw_queued() draws them."""
    global QUEUE
    QUEUE = []


def run_gnuplot(script, params, out_svg, problems):
    exe = shutil.which('gnuplot')
    if not exe:
        problems.add(out_svg, 'gnuplot not found; install gnuplot-nox to get plots')
        return False
    cached = None
    if CACHE.dir and 'datafile' in params:
        try:
            cached = os.path.join(CACHE.dir, CACHE.key(exe, script, params) + '.svg')
        except OSError:
            cached = None
        if cached and _from_cache(cached, out_svg):
            return True
    tmp = f'{out_svg}.tmp{os.getpid()}.svg'
    params = dict(params, outfile=tmp, dir=PLOTS + os.sep)
    expr = '; '.join(f'{k}={gnuplot_q(v) if isinstance(v, str) else v}' for k, v in params.items())
    job = {'exe': exe, 'script': script, 'expr': expr, 'tmp': tmp, 'svg': out_svg, 'cached': cached}
    if QUEUE is not None:
        QUEUE.append(job)
        return True
    return _draw_one(job, problems)


def _draw_one(job, problems):
    """The plot in a gnuplot of its own: a failure is named with gnuplot's last message."""
    script, tmp, out_svg = job['script'], job['tmp'], job['svg']
    try:
        r = subprocess.run(
            [job['exe'], '-e', job['expr'], os.path.join(PLOTS, script)],
            capture_output=True,
            text=True,
            timeout=GNUPLOT_TIMEOUT_S,
        )
    except (OSError, subprocess.TimeoutExpired) as e:
        problems.add(out_svg, f'gnuplot failed: {e}')
        return False
    if r.returncode != 0 or not os.path.exists(tmp) or os.path.getsize(tmp) == 0:
        msg = (r.stderr.strip().splitlines() or ['no output'])[-1]
        problems.add(out_svg, f'gnuplot {script} failed: {msg}')
        if os.path.exists(tmp):
            os.unlink(tmp)
        return False
    _finish(job)
    return True


def _finish(job):
    os.replace(job['tmp'], job['svg'])
    CACHE.drawn.append(job['svg'])
    if job['cached']:
        _to_cache(job['svg'], job['cached'])


def _draw_batch(jobs, problems):
    """The plots in one gnuplot, one after another. `reset session` between two gives each the
    state of a fresh gnuplot (user variables, ranges, log scales), so each SVG has the bytes it
    has when drawn alone (tests/test_report.py checks). gnuplot stops at a script's first error:
    a plot it did not mark done is drawn again alone, which names its failure. The failed SVGs."""
    lines = []
    for i, job in enumerate(jobs):
        lines += ['reset session', job['expr'], f"load {gnuplot_q(os.path.join(PLOTS, job['script']))}"]
        lines += ['set output', f"print '{DONE} {i}'"]
    fd, batch = tempfile.mkstemp(prefix='reflcheck-plots-', suffix='.gp')
    try:
        with os.fdopen(fd, 'w', encoding='utf-8') as f:
            f.write('\n'.join(lines) + '\n')
        r = subprocess.run(
            [jobs[0]['exe'], batch], capture_output=True, text=True, timeout=GNUPLOT_TIMEOUT_S * len(jobs)
        )
        done = {int(m) for m in re.findall(DONE + r' (\d+)$', r.stderr, re.M)}
    except (OSError, subprocess.TimeoutExpired):
        done = set()
    finally:
        os.unlink(batch)
    failed = []
    for i, job in enumerate(jobs):
        if i in done and os.path.exists(job['tmp']) and os.path.getsize(job['tmp']) > 0:
            _finish(job)
        elif not _draw_one(job, problems):
            failed.append(job['svg'])
    return failed


def draw_queued(problems, workers, batches_per_worker=BATCHES_PER_WORKER):
    """Draws the plots queued since queue_plots() in batches, workers gnuplots at a time, and
    stops queueing; the SVG paths that could not be drawn (each named in problems)."""
    global QUEUE
    jobs, QUEUE = QUEUE or [], None
    if not jobs:
        return set()
    size = -(-len(jobs) // (batches_per_worker * workers))
    with ThreadPoolExecutor(workers) as ex:
        failed = ex.map(lambda b: _draw_batch(b, problems), [jobs[i : i + size] for i in range(0, len(jobs), size)])
        return {svg for batch in failed for svg in batch}


def write_table(path, header, rows):
    """gnuplot data: whitespace columns, '?' = missing, header line for columnhead()."""
    with open(path, 'w', encoding='utf-8') as f:
        f.write(' '.join(header) + '\n')
        for r in rows:
            f.write(' '.join('?' if v is None else (repr(float(v)) if is_num(v) else str(v)) for v in r) + '\n')


def plot_id(s):
    return re.sub(r'[^A-Za-z0-9_.+-]', '_', s)


# The angle axes of compare.json: key, file suffix, label.
ANGLE_AXES = (
    ('angle_bins', 'ndotv', 'N·V'),
    ('angle_bins_ndoth', 'ndoth', 'N·H'),
    ('angle_bins_ndotl', 'ndotl', 'N·L'),
)


def _bin_centre(b):
    lo = b.get('ndotv_lo', b.get('ndotl_lo', b.get('lo')))
    hi = b.get('ndotv_hi', b.get('ndotl_hi', b.get('hi')))
    return round((lo + hi) / 2, 6) if finite(lo) and finite(hi) else None


def _angle_rel_cols(s, key):
    """[(column title, {centre: rel_rms})], one per comparison with a measured bin."""
    cols = []
    for c in s['comparisons']:
        pts = {}
        for b in c.get(key) or []:
            x, v = (_bin_centre(b), b.get('rel_rms')) if isinstance(b, dict) else (None, None)
            if x is not None and finite(v) and v > 0 and b.get('n', 1) != 0:
                pts[x] = v
        if pts:
            cols.append((c['id'], pts))
    return cols


def _angle_share_cols(s, key):
    """[(column title, {centre: share})] of each validate comparison: its bins' share of the
    surface's squared error per term, and per material where the surface holds more than one."""
    cols = []
    for c in s['comparisons']:
        if c.get('role') != 'validate':
            continue
        bins = [b for b in c.get(key) or [] if isinstance(b, dict) and _bin_centre(b) is not None]
        for group in ('terms', 'materials'):
            parts = [(_bin_centre(b), b[group]) for b in bins if isinstance(b.get(group), dict)]
            names = sorted({n for _, g in parts for n, v in g.items() if isinstance(v, dict)})
            if group == 'materials' and len(names) < 2:
                continue
            for n in names:
                pts = {x: g[n]['share'] for x, g in parts if isinstance(g.get(n), dict) and finite(g[n].get('share'))}
                if pts:
                    cols.append((f'{c["id"]}:{n}', pts))
    return cols


def _plot_angle_cols(R, s, tmpdir, problems, cols, name, params):
    """One angle SVG of cols (one line each) as plots/angle-<scene>-<name>.svg, or None."""
    if not cols:
        return None
    xs = sorted({x for _, p in cols for x in p})
    dat = os.path.join(tmpdir, f'{safe_name(s["name"])}-{name}.dat')
    write_table(dat, ['bin'] + [plot_id(i) for i, _ in cols], [[x] + [p.get(x) for _, p in cols] for x in xs])
    svg = os.path.join(R['dir'], 'plots', f'angle-{safe_name(s["name"])}-{name}.svg')
    # The key sits below the plot, two entries a row: the SVG grows by a row's height per pair,
    # so the plot area keeps its size however many lines there are.
    params = dict(params, datafile=dat, ncols=len(cols) + 1, height=300 + 16 * ((len(cols) + 1) // 2))
    return os.path.relpath(svg, R['dir']) if run_gnuplot('angle.gp', params, svg, problems) else None


def plot_angles(R, s, tmpdir, problems):
    """Per angle (N.V, N.H, N.L) up to two SVGs per scene: surface rel_rms per bin, one line per
    comparison; and each validate's share of the squared error per bin, by term and material."""
    out = {}
    for key, axis, label in ANGLE_AXES:
        rel = _plot_angle_cols(
            R,
            s,
            tmpdir,
            problems,
            _angle_rel_cols(s, key),
            axis,
            {
                'xlab': label,
                'ylab': 'surface rel_rms',
                'logy': 1,
                'ptitle': f'{s["name"]}: surface rel_rms per {label} bin',
            },
        )
        if rel:
            out[axis] = rel
        share = _plot_angle_cols(
            R,
            s,
            tmpdir,
            problems,
            _angle_share_cols(s, key),
            f'{axis}-share',
            {
                'xlab': label,
                'ylab': 'share of squared error',
                'logy': 0,
                'ptitle': f'{s["name"]}: share of the squared error per {label} bin, by term and material',
            },
        )
        if share:
            out[f'{axis} share'] = share
    return out


def plot_figure1(R, s, tmpdir, problems):
    """Figure 1 of the scene's own materials as plots/figure1-<scene>.svg: per material its model's
    reflectance against angle (solid) and its physics' (dashed, same colour); None without data."""
    f1 = s.get('figure1')
    if not f1 or not f1['materials']:
        return None
    mats = f1['materials']
    dat = os.path.join(tmpdir, f'figure1-{safe_name(s["name"])}.dat')
    header = ['angle'] + [plot_id(f'{m["name"]}:{k}') for m in mats for k in ('model', 'physics')]
    rows = [[a] + [m[k][i] for m in mats for k in ('model', 'physics')] for i, a in enumerate(f1['angle_deg'])]
    write_table(dat, header, rows)
    svg = os.path.join(R['dir'], 'plots', f'figure1-{safe_name(s["name"])}.svg')
    params = {
        'datafile': dat,
        'nmat': len(mats),
        'height': 340 + 16 * len(mats),
        'ptitle': f'{s["name"]}: reflectance against angle, model (solid) and physics (dashed)',
    }
    return os.path.relpath(svg, R['dir']) if run_gnuplot('figure1_scene.gp', params, svg, problems) else None


def plot_trends(R, history, tmpdir, problems):
    out = {}
    for s in R['scenes']:
        # A run that errored measured only part of the scene: its figures are no trend.
        runs = [h for h in history if s['name'] in (h.get('metrics') or {}) and h.get('status') != 'error'][
            -TREND_RUNS:
        ]
        ids = []
        for h in runs:
            for cid, m in h['metrics'][s['name']].items():
                if (
                    isinstance(m, dict)
                    and finite(m.get('surface.rel_rms'))
                    and m['surface.rel_rms'] > 0
                    and cid not in ids
                ):
                    ids.append(cid)
        if not ids:
            continue
        rows = []
        for i, h in enumerate(runs):
            ms = h['metrics'][s['name']]
            label = ('ref-' if h.get('reference') else '') + (
                str(h.get('commit') or '')[:7]
                if h.get('commit') not in (None, '', 'unknown')
                else str(h['run_id'])[-13:]
            )
            vals = []
            for cid in ids:
                v = (ms.get(cid) or {}).get('surface.rel_rms') if isinstance(ms.get(cid), dict) else None
                vals.append(v if finite(v) and v > 0 else None)
            rows.append([i + 1, plot_id(label)] + vals)
        dat = os.path.join(tmpdir, f'trend-{safe_name(s["name"])}.dat')
        write_table(dat, ['run', 'label'] + [plot_id(c) for c in ids], rows)
        svg = os.path.join(R['dir'], 'plots', f'trend-{safe_name(s["name"])}.svg')
        if run_gnuplot(
            'trend.gp',
            {'datafile': dat, 'ncols': len(ids) + 2, 'ptitle': f'{s["name"]}: surface rel_rms over runs'},
            svg,
            problems,
        ):
            out[s['name']] = os.path.relpath(svg, R['dir'])
    return out


TIME_KEYS = ('time_s', 'wall_s', 'seconds', 'time')
ERR_KEYS = ('rel_rms', 'error', 'rmse', 'mae')
SWEEP_FORMAT = 'reflcheck-sweep-1'  # tools/sweep.py's timing/<scene>.json


def is_sweep(t):
    return isinstance(t, dict) and t.get('format') == SWEEP_FORMAT and isinstance(t.get('series'), list)


def timing_points(t):
    """Accepts {"series":[{"label":..,"points":[..]}]}, {"points":[..]} or a bare list of points."""
    series = []
    if isinstance(t, dict) and isinstance(t.get('series'), list):
        for i, sr in enumerate(t['series']):
            if isinstance(sr, dict) and isinstance(sr.get('points'), list):
                label = sr.get('label') or sr.get('renderer') or f'series{i + 1}'
                series.append((str(label), [p for p in sr['points'] if isinstance(p, dict)]))
    else:
        pts = t.get('points') if isinstance(t, dict) else t
        if isinstance(pts, list):
            groups = {}
            for p in pts:
                if isinstance(p, dict):
                    groups.setdefault(str(p.get('series') or p.get('renderer') or 'points'), []).append(p)
            series = list(groups.items())
    return series


def timing_xy(t, pts):
    """(time, error) pairs of points, both > 0: the file's error_key if it names one. Sorted by
    time, except a sweep's, which keeps its knob order."""
    ek = t.get('error_key') if isinstance(t, dict) and isinstance(t.get('error_key'), str) else None
    xy = []
    for p in pts:
        x = next((p[k] for k in TIME_KEYS if finite(p.get(k))), None)
        y = p.get(ek) if ek else next((p[k] for k in ERR_KEYS if finite(p.get(k))), None)
        if finite(x) and finite(y) and x > 0 and y > 0:
            xy.append((x, y))
    return xy if is_sweep(t) else sorted(xy)


def sweep_fit_text(sr):
    """The slope in a legend: error ~ t^b, and for Cycles also ~ spp^b."""
    parts = []
    for key, var in (('fit_spp', 'spp'), ('fit', 't')):
        f = sr.get(key)
        if isinstance(f, dict) and finite(f.get('slope')):
            parts.append(f'{var}^{f["slope"]:.2f}')
    return ', '.join(parts)


def plot_timing(R, tmpdir, problems):
    out = {}
    for name, t in R['optional']['timing']:
        series = timing_points(t)
        blocks, titles = [], []
        srs = (
            [sr for sr in t['series'] if isinstance(sr, dict) and isinstance(sr.get('points'), list)]
            if is_sweep(t)
            else []
        )
        refs = []
        for i, (label, pts) in enumerate(series):
            if is_sweep(t):
                # The reference's point is its own noise estimate, not a sweep level: drawn apart.
                refs += [p for p in pts if p.get('is_reference')]
                pts = [p for p in pts if not p.get('is_reference')]
            xy = timing_xy(t, pts)
            if xy:
                blocks.append(xy)
                if is_sweep(t):
                    fit = sweep_fit_text(srs[i]) if i < len(srs) else ''
                    titles.append(re.sub(r"['\"]", '', f'{label} ({fit})' if fit else label))
                else:
                    titles.append(plot_id(label))
        if refs and timing_xy(t, refs):
            blocks.append(timing_xy(t, refs))
            titles.append('reference: own noise (est.)')
        if not blocks:
            continue
        dat = os.path.join(tmpdir, f'timing-{safe_name(name)}.dat')
        svg = os.path.join(R['dir'], 'plots', f'timing-{safe_name(name)}.svg')
        if is_sweep(t):
            front = sorted(
                (p['time_s'], p['error'])
                for p in t.get('pareto') or []
                if isinstance(p, dict)
                and finite(p.get('time_s'))
                and finite(p.get('error'))
                and p['time_s'] > 0
                and p['error'] > 0
            )
            blocks.insert(0, front or [(1.0, None)])
            with open(dat, 'w', encoding='utf-8') as f:
                f.write(
                    '\n\n\n'.join('\n'.join(f'{x!r} {"?" if y is None else repr(y)}' for x, y in b) for b in blocks)
                    + '\n'
                )
            asis = t.get('as_is') if isinstance(t.get('as_is'), dict) else {}
            cross = t.get('crossover') if isinstance(t.get('crossover'), dict) else {}
            hline = asis.get(t.get('error_key') or 'error')
            xcross = cross.get('time_s') if not cross.get('extrapolated') else cross.get('upper_bound_s')
            params = {
                'datafile': dat,
                'nseries': len(blocks) - 1,
                'titles': ' '.join(f'"{x}"' for x in titles),
                'ptitle': f'{name}: error vs time ({"x".join(str(v) for v in t.get("size") or [])} px, '
                f'one thread per render)',
                'ylab': 'error: NRMSE vs noise-free (est.)'
                if t.get('error_key') == 'error'
                else str(t.get('error_key')),
                'xlab': f'{"CPU" if t.get("clock") == "cpu_s" else "wall"} time per render, 1 thread (s)',
                'hline': float(hline) if finite(hline) and hline > 0 else 0.0,
                'xcross': float(xcross) if finite(xcross) and xcross > 0 else 0.0,
            }
            ok = run_gnuplot('sweep.gp', params, svg, problems)
        else:
            with open(dat, 'w', encoding='utf-8') as f:
                # Two blank lines end a gnuplot data set (`index`); one would only end a block.
                f.write('\n\n\n'.join('\n'.join(f'{x!r} {y!r}' for x, y in b) for b in blocks) + '\n')
            ok = run_gnuplot(
                'time.gp',
                {
                    'datafile': dat,
                    'nseries': len(blocks),
                    'titles': ' '.join(titles),
                    'ptitle': f'{name}: error vs time',
                },
                svg,
                problems,
            )
        if ok:
            out[name] = os.path.relpath(svg, R['dir'])
    return out
