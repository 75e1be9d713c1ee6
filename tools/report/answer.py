"""answer - the index page's first table: how wrong each approximation is, where, at what cost.

answer_rows(R, crossovers) -> list of rows, one per material as used in a scene (per material
where the comparison splits its surface by object, else one for the scene's whole surface) and
validate reference; a scene with no validate comparison gets one row that says so. Each row:
  scene, material, test, reference, physics    what is judged against what (physics in short)
  median, p95, nrmse, trim1                    surface figures (per material where split)
  status                                       the comparison's verdict
  term, nv, nh, nl                             where the error sits: the term with the largest
                                               share, and the N.V, N.H and N.L bins holding most of
                                               the squared error, (lo, hi, share); a material row's
                                               bins from its own pixels (compare.json's split by
                                               material); None: not measured
  fit_nrmse, fit_median                        the same after the best fit of fit.json (None)
  test_s, ref_s, crossover                     one frame's seconds each side; the sweep's
                                               crossover text (None: no sweep of this scene)
  twins                                        [(reference, text, status)] of the scene's twins
  kinds, physics_differs                       the material kinds of the row (compare.json
                                               material_kinds); [(scene, physics)] of other scenes'
                                               rows of the same one kind and test under another
                                               physics: the figures are not comparable
  agrees                                       [(other reference, nrmse, status)]: the scene's agree
                                               comparisons that measure this validate's reference
                                               against a second one; empty: agree_none says that
                                               the figure rests on that reference alone
Nothing here measures: it picks from compare.json, fit.json and timing/*.json as loaded.
"""

from .util import finite


def _bin_error(b, material):
    """A bin's squared error: its share of the surface's (compare.json since the split by term
    and material: the material's part where one is named), else, from older runs, n x rel_rms^2
    (whole surface only); None when not measured."""
    if material is not None:
        return ((b.get('materials') or {}).get(material) or {}).get('share')
    if finite(b.get('share')):
        return b['share']
    if finite(b.get('rel_rms')) and finite(b.get('n')):
        return b['n'] * b['rel_rms'] ** 2
    return None


def _dominant_bin(bins, material=None):
    """(lo, hi, share) of the angle bin holding the most squared error (of MATERIAL's pixels when
    given), or None."""
    if not isinstance(bins, list):
        return None
    parts = []
    for b in bins:
        e = _bin_error(b, material) if isinstance(b, dict) else None
        if finite(e) and finite(b.get('lo')) and finite(b.get('hi')):
            parts.append((b['lo'], b['hi'], e))
    total = sum(p[2] for p in parts)
    if not parts or total <= 0:
        return None
    lo, hi, sq = max(parts, key=lambda p: p[2])
    return lo, hi, sq / total


def _dominant_term(terms):
    """(name, share of the summed squared term error) of the term with the most, or None."""
    if not isinstance(terms, dict):
        return None
    sq = {k: v['nrmse'] ** 2 for k, v in terms.items() if isinstance(v, dict) and finite(v.get('nrmse'))}
    total = sum(sq.values())
    if total <= 0:
        return None
    name = max(sq, key=sq.get)
    return name, sq[name] / total


def _twin_text(c):
    """A twin's state: 'at floor' when it passes its gates, else the pixels off or its verdict."""
    z = ((c.get('noise') or {}).get('ztest')) or {}
    if c.get('status') == 'pass':
        return 'at floor'
    if finite(z.get('n_fail_pixels')) and z['n_fail_pixels'] > 0:
        return f'{int(z["n_fail_pixels"])} pixels off'
    return c.get('status', '?')


def _fit_of(scene, cid):
    """The best fit within the seeds' ranges (fit.json) of comparison CID, or None."""
    for f in scene.get('fits', []):
        if f.get('id') == cid and f.get('bounds') == 'seed' and f.get('status') == 'ok' and f.get('best'):
            return f['best']
    return None


def _material_parts(c):
    """[(material, metrics)] per material where the comparison splits its surface by object,
    else [(None, surface metrics)]. Objects of one material are not merged: the first object
    of each material stands for it only when it is the only one (so no figure is averaged here)."""
    objs = c.get('objects') if isinstance(c.get('objects'), list) else []
    by_mat = {}
    for o in objs:
        if isinstance(o, dict) and o.get('material'):
            by_mat.setdefault(o['material'], []).append(o)
    if len(by_mat) > 1 and all(len(v) == 1 for v in by_mat.values()):
        return [(m, v[0]) for m, v in by_mat.items()]
    return [(None, (c.get('regions') or {}).get('surface') or {})]


# The physics a validate renders, read back from compare.json's "key=value ..." line: what it
# sets beyond the defaults a real-time model shares (one bounce, no shadows, no inter-reflection,
# every light on both lobes, the environment on the lobe only).
PHYSICS_DEFAULTS = {
    'diffuse_lights': 'all',
    'specular_lights': 'all',
    'env_diffuse': '0',
    'env_specular': '1',
    'bounces': '1',
    'shadows': '0',
    'interreflection': '0',
}


def physics_short(text):
    """'F lamp exact, F env exact, diffuse plain' plus every field that departs from the defaults."""
    if not isinstance(text, str) or '=' not in text:
        return text or ''
    kv = dict(p.split('=', 1) for p in text.split() if '=' in p)
    out = [f'F lamp {kv.get("fresnel_specular", "?")}', f'F env {kv.get("fresnel_reflection", "?")}']
    out.append('diffuse × (1 − F)' if kv.get('diffuse_weight') == 'one_minus_f' else 'diffuse plain')
    out += [f'{k} {v}' for k, v in kv.items() if k in PHYSICS_DEFAULTS and PHYSICS_DEFAULTS[k] != v]
    return ', '.join(out)


def _agrees(measured, ref):
    """The agree comparisons of a scene that hold validate reference REF beside another
    reference: [(the other, surface NRMSE, status)]."""
    out = []
    for a in measured:
        if a.get('role') != 'agree' or ref not in (a.get('test'), a.get('reference')):
            continue
        other = a.get('reference') if a.get('test') == ref else a.get('test')
        out.append((other, ((a.get('regions') or {}).get('surface') or {}).get('nrmse'), a.get('status')))
    return out


def _physics_for_kind(text, kind):
    """The physics fields that bear on a material of KIND: a material without specular has no
    lobe, so the lobes' Fresnel and lights are moot for it."""
    parts = text.split(', ') if text else []
    if kind and kind.endswith('without specular'):
        parts = [p for p in parts if not p.startswith(('F lamp', 'F env', 'specular_lights', 'env_specular'))]
    return ', '.join(parts)


def _name_physics_differences(rows):
    """One physics per material kind across scenes, or the difference named beside both: each
    row of one kind gets the other scenes' rows of that kind and test whose physics differ."""
    for r in rows:
        r['physics_differs'] = []
    single = [r for r in rows if not r.get('no_validate') and len(r.get('kinds') or ()) == 1]
    for r in single:
        (kind,) = r['kinds']
        mine = _physics_for_kind(r['physics'], kind)
        seen = set()
        for o in single:
            if o['scene']['name'] == r['scene']['name'] or o['kinds'] != r['kinds'] or o['test'] != r['test']:
                continue
            theirs = _physics_for_kind(o['physics'], kind)
            if theirs != mine and (o['scene']['name'], theirs) not in seen:
                seen.add((o['scene']['name'], theirs))
                r['physics_differs'].append((o['scene']['name'], theirs))


def answer_rows(R, crossovers=None, fold=True):
    crossovers = crossovers or {}
    rows = []
    for s in R['scenes']:
        measured = [c for c in s['comparisons'] if not c.get('pseudo')]
        twins = [(c.get('reference'), _twin_text(c), c.get('status')) for c in measured if c.get('role') == 'twin']
        validates = [c for c in measured if c.get('role') == 'validate']
        if not validates:
            rows.append({'scene': s, 'material': None, 'reference': None, 'twins': twins, 'no_validate': True})
            continue
        for c in validates:
            times = c.get('times') or {}
            fit = _fit_of(s, c.get('id'))
            term = _dominant_term(c.get('terms'))
            agrees = _agrees(measured, c.get('reference'))
            agree_none = (
                None
                if agrees
                else f'none: {c.get("reference")} alone renders this physics here, no second reference measures it'
            )
            kinds = c.get('material_kinds') if isinstance(c.get('material_kinds'), dict) else {}
            for mat, m in _material_parts(c):
                rows.append(
                    {
                        'scene': s,
                        'material': mat,
                        'reference': c.get('reference'),
                        'physics': physics_short(c.get('physics')),
                        'test': c.get('test'),
                        'status': c.get('status'),
                        'median': m.get('rel_median'),
                        'p95': m.get('rel_p95'),
                        'nrmse': m.get('nrmse'),
                        'trim1': m.get('nrmse_trim1'),
                        'term': term,
                        'nv': _dominant_bin(c.get('angle_bins'), mat),
                        'nh': _dominant_bin(c.get('angle_bins_ndoth'), mat),
                        'nl': _dominant_bin(c.get('angle_bins_ndotl'), mat),
                        'fit_nrmse': fit.get('nrmse') if fit and mat is None else None,
                        'fit_median': fit.get('median_rel') if fit and mat is None else None,
                        'test_s': times.get('test_wall_s'),
                        'ref_s': times.get('reference_wall_s'),
                        'crossover': crossovers.get(s['name']),
                        'twins': twins,
                        'agrees': agrees,
                        'kinds': sorted(
                            {kinds[mat]} if mat in kinds else set(kinds.values()) if mat is None else set()
                        ),
                        'agree_none': agree_none,
                        'no_validate': False,
                    }
                )
    _name_physics_differences(rows)
    return _fold_references(rows) if fold else rows


def _fold_references(rows):
    """One row per material as used in a scene and test renderer: the first validate reference
    gives the row's figures, each further one joins it as (reference, nrmse, median, status) in
    'others', so the table's length is the number of approximations, not of comparisons."""
    out, first = [], {}
    for r in rows:
        key = (r['scene']['name'], r.get('material'), r.get('test'))
        if r.get('no_validate') or key not in first:
            r['others'] = []
            first[key] = r
            out.append(r)
        else:
            first[key]['others'].append((r['reference'], r.get('nrmse'), r.get('median'), r.get('status')))
    return out
