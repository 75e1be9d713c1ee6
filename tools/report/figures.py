"""figures - one run's figures as the Markdown tables the README quotes (figures.md).

Every figure the README states comes from one named run; report.py writes this file into the
run folder, so the tables are copied, never retyped. Input: the summary object
(outputs.summary_object). Sections: twins (harness error), validates (the approximation's
error, with the physics each reference renders), agrees (reference against reference), error
by term, and the fitted parameters. Missing values print as a dash.
"""

from .util import finite

DASH = '—'


def num(v, digits=3):
    """A figure to `digits` significant digits; small and large ones in exponent form."""
    if not finite(v):
        return DASH
    if v == 0:
        return '0'
    a = abs(v)
    if a < 1e-3 or a >= 1e5:
        return f'{v:.{digits - 1}e}'
    return f'{v:.{digits}g}'


def pct(v):
    return DASH if not finite(v) else f'{100 * v:.3g} %'


def surface(c):
    return ((c.get('regions') or {}).get('surface')) or {}


def beyond_noise(c):
    """Pixels failing the noise-aware z-test, as 'n of N (share)'; a dash without a test."""
    z = ((c.get('noise') or {}).get('ztest')) or {}
    n = z.get('n_fail_pixels')
    total = surface(c).get('n_pixels')
    if not finite(n) or not finite(total) or total <= 0:
        return DASH
    crease = (c.get('crease') or {}).get('pixels') if isinstance(c.get('crease'), dict) else None
    apart = f'; {int(crease)} crease px apart' if finite(crease) and crease > 0 else ''
    return f'{int(n)} of {int(total)} ({pct(n / total)}){apart}'


def terms_cell(c):
    left = c.get('terms_left_out') or []
    if not left:
        return 'all'
    names = ', '.join(t if isinstance(t, str) else t.get('term', '?') for t in left)
    return f'partial: {names} left out'


def variant(scene):
    sizes = {
        f'{j["width"]} × {j["height"]}'
        for j in scene.get('jobs', [])
        if j.get('renderer') == 'raster' and finite(j.get('width'))
    }
    return ', '.join(sorted(sizes)) or DASH


def comparisons(S, role):
    for s in S['scenes']:
        for c in s['comparisons']:
            if c.get('role') == role:
                yield s, c


def table(head, rows):
    out = ['| ' + ' | '.join(head) + ' |', '| ' + ' | '.join('---' for _ in head) + ' |']
    out += ['| ' + ' | '.join(str(x).replace('|', '/') for x in r) + ' |' for r in rows]
    return '\n'.join(out)


def robust(c):
    m = surface(c)
    return [
        num(m.get('nrmse')),
        num(m.get('nrmse_trim1')),
        pct(m.get('worst1_share')),
        pct(m.get('rel_median')),
        pct(m.get('rel_p95')),
    ]


def fit_cell(e):
    e = e or {}
    return ', '.join(
        [num(e.get('nrmse')), pct(e.get('median_rel')), num(e.get('nrmse_trim1')), pct(e.get('worst1_share'))]
    )


def fit_values(f):
    vals = []
    for p in f.get('parameters') or []:
        b = ' (b)' if p.get('at_bound') else ''
        vals.append(f'{p.get("material", "?")}.{p.get("name", "?")} = {num(p.get("fitted"))}{b}')
    return '; '.join(vals) or DASH


# The physics manifest's defaults (scenes/FORMAT.md): a scene's line names only what differs.
PHYSICS_DEFAULTS = (
    'diffuse_lights=all specular_lights=all env_diffuse=0 env_specular=1 bounces=1 shadows=0 '
    'interreflection=0 fresnel_specular=exact fresnel_reflection=exact diffuse_weight=plain'
)


def physics_lines(S):
    default = dict(w.split('=', 1) for w in PHYSICS_DEFAULTS.split())
    out = [f'Defaults: `{PHYSICS_DEFAULTS}`; each scene with a validate or agree, what it sets otherwise:', '']
    for s in S['scenes']:
        texts = {
            c.get('physics') for c in s['comparisons'] if c.get('role') in ('validate', 'agree') and c.get('physics')
        }
        for p in sorted(texts):
            words = [w for w in p.split() if '=' in w and default.get(w.split('=', 1)[0]) != w.split('=', 1)[1]]
            out.append(f'- {s["name"]}: ' + (' '.join(f'`{w}`' for w in words) if words else 'the defaults'))
    return out


def figures_md(S):
    """The Markdown text of figures.md for summary object S."""
    out = [
        f'# Figures of run {S.get("run_id", "?")}',
        '',
        f'Commit {S.get("commit", "?")}, started {S.get("time", "?")}; '
        f'{(S.get("machine") or {}).get("cores", "?")} cores; renderers: '
        + ', '.join(f'{k} {v}' for k, v in sorted((S.get('renderer_versions') or {}).items())),
        'Surface pixels only (silhouettes apart). NRMSE = RMSE / mean reference; trim 1 % = NRMSE without '
        'the worst 1 % of pixels; worst 1 % = their share of the squared error; median and p95 = '
        'per-pixel relative error.',
        '',
        '## Twins (harness error)',
        '',
    ]
    rows = []
    for s, c in comparisons(S, 'twin'):
        m = surface(c)
        rows.append(
            [
                s['name'],
                c.get('reference', '?'),
                terms_cell(c),
                num(m.get('rel_rms')),
                beyond_noise(c),
                num(m.get('nrmse')),
                c.get('status', '?'),
            ]
        )
    out.append(
        table(['scene', 'reference', 'terms compared', 'relative RMS', 'pixels beyond noise', 'NRMSE', 'verdict'], rows)
    )
    for role, title in (
        ('validate', "Validates (the approximation's error)"),
        ('agree', 'Agrees (validate reference against validate reference)'),
    ):
        out += ['', f'## {title}', '']
        rows = [
            [s['name'], f'{c.get("test", "?")} vs {c.get("reference", "?")}']
            + robust(c)
            + [beyond_noise(c), c.get('status', '?')]
            for s, c in comparisons(S, role)
        ]
        out.append(
            table(
                ['scene', 'comparison', 'NRMSE', 'trim 1 %', 'worst 1 %', 'median', 'p95', 'beyond noise', 'verdict'],
                rows,
            )
        )
    out += ['', '## Physics each validate reference renders (scene.physics)', '']
    out += physics_lines(S)
    out += ['', '## Validate error by term (mean radiance, test against reference; NRMSE of the term)', '']
    rows = []
    for s, c in comparisons(S, 'validate'):
        for t, v in sorted((c.get('terms') or {}).items()):
            if not finite(v.get('ref_mean')) or (v.get('ref_mean') == 0 and v.get('test_mean') == 0):
                continue
            rows.append(
                [
                    s['name'],
                    f'{c.get("test", "?")} vs {c.get("reference", "?")}',
                    t,
                    num(v.get('test_mean')),
                    num(v.get('ref_mean')),
                    num(v.get('nrmse')),
                ]
            )
    out.append(table(['scene', 'comparison', 'term', 'test mean', 'reference mean', 'NRMSE'], rows))
    out += [
        '',
        '## Fitted parameters (each cell: NRMSE, median, trim 1 %, worst 1 %; (b): at a bound)',
        '',
    ]
    rows = []
    for f in S.get('fits') or []:
        if f.get('status') != 'ok':
            continue
        rows.append(
            [
                f.get('scene', '?'),
                f.get('reference', '?'),
                f.get('bounds', '?'),
                fit_cell(f.get('authored')),
                fit_cell(f.get('best')),
                fit_values(f),
            ]
        )
    out.append(table(['scene', 'reference', 'bounds', 'as authored', 'best fit', 'fitted values'], rows))
    out += ['', '## Sizes (our rasterizer, width × height)', '']
    out += [f'- {s["name"]}: {variant(s)}' for s in S['scenes']]
    return '\n'.join(out) + '\n'
