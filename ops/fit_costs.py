"""fit_costs.py - the expected seconds of each of the nightly's fits, so that the longest start
first and the fits stage does not end on one core (progress.py each --costs).

Usage: python3 ops/fit_costs.py LATEST [--small] -- ITEM...
  ITEM: BOUNDS<tab>SCENE.yaml, as ops/nightly.sh queues the fits (BOUNDS seed or wide).
  Prints one number a line, an item's expected seconds, in the items' order.

The cost of an item is, first, the seconds its fits took in the last run (LATEST/<scene>/fit.json,
fit-wide.json for wide bounds: the sum of its fits' "seconds", found by scene path and variant).
A scene the last run did not fit (the first run of a clone, a new scene) gets a static estimate
from its scene file: fits x evaluations x pixels x seconds per evaluated pixel, where
  fits: its validate comparisons of the model (agree and twin are not fitted);
  evaluations: 60 per free parameter, at most 400 (the fit's budget, max_evaluations): the
    nightly at 1df56f8 took 52-89 evaluations for one parameter, 63-161 for two, 127-400 for
    four, 400 for eight;
  free parameters: per material an object uses, 2 for d3d9client (p, r0) and for d3d with a
    specular colour (Vs, P), 1 for cook_torrance (m), a user model's declared parameters;
  pixels: width x height x supersample^2 of the image (image.small with --small);
  seconds per evaluated pixel: 1.2e-8, a user model 3.5 times that (a call through its shared
    object per sample): the medians of that run's 31 fits (1.0-2.1e-8, user_ggx 7.3-7.6e-8),
    user_ggx's then times 0.56, its fits' CPU after shade_batch_user (9.5-9.9 against 16.7-17.7
    CPU-s, docs/fits.md): 4.1-4.3e-8.
The order is all that is used: a wrong estimate costs at most a tail, never a result.
"""

import glob
import json
import os
import sys

import yaml

PIXEL_S = 1.2e-8
USER_FACTOR = 3.5
EVALS_PER_PARAM = 60
MAX_EVALS = 400


def last_seconds(latest, small):
    """{(scene path, bounds): seconds} of the fits LATEST holds in the variant asked for."""
    out = {}
    variant = 'small' if small else 'full'
    for bounds, name in (('seed', 'fit.json'), ('wide', 'fit-wide.json')):
        for path in glob.glob(os.path.join(glob.escape(latest), '*', name)):
            try:
                with open(path, encoding='utf-8') as f:
                    doc = json.load(f)
                secs = [x['seconds'] for x in doc.get('fits', []) if isinstance(x.get('seconds'), (int, float))]
            except (OSError, ValueError, AttributeError, TypeError):
                continue
            if doc.get('variant', variant) == variant and doc.get('scene_path'):
                out[(doc['scene_path'], bounds)] = float(sum(secs))
    return out


def free_params(material):
    """The fit's free parameters of one material (harness/fit.h fit_default_params)."""
    model = material.get('model', 'd3d')
    if model == 'd3d9client':
        return 2
    if model == 'cook_torrance':
        return 1
    if model == 'user':
        return len((material.get('user') or {}).get('params') or {})
    return 2 if 'd3d' in material and 'specular' in (material.get('d3d') or {}) else 0


def static_seconds(scene_path, small):
    """The estimate from the scene file alone (the module's docstring); 0 when it cannot be read."""
    try:
        with open(scene_path, encoding='utf-8') as f:
            doc = yaml.safe_load(f)
        image = doc.get('image') or {}
        if small:
            image = {**image, **(image.get('small') or {})}
        pixels = image.get('width', 0) * image.get('height', 0) * image.get('supersample', 1) ** 2
        materials = doc.get('materials') or {}
        used = {o.get('material') for o in doc.get('objects') or [] if isinstance(o, dict)}
        mats = [m for k, m in materials.items() if k in used and isinstance(m, dict)]
        fits = sum(
            1
            for c in doc.get('comparisons') or []
            if c.get('role', 'twin') == 'validate' and c.get('test', 'raster') == 'raster'
        )
    except (OSError, ValueError, AttributeError, TypeError, yaml.YAMLError):
        return 0.0
    n = sum(free_params(m) for m in mats)
    user = any(m.get('model') == 'user' for m in mats)
    evals = min(MAX_EVALS, EVALS_PER_PARAM * n)
    return fits * evals * pixels * PIXEL_S * (USER_FACTOR if user else 1.0)


def costs(latest, items, small):
    known = last_seconds(latest, small) if latest else {}
    out = []
    for item in items:
        bounds, _, scene = item.partition('\t')
        c = known.get((scene, bounds))
        out.append(c if c is not None else static_seconds(scene, small))
    return out


def main(argv):
    if '--' not in argv or argv.index('--') < 1:
        print('fit_costs.py: usage: fit_costs.py LATEST [--small] -- BOUNDS<tab>SCENE...', file=sys.stderr)
        return 2
    cut = argv.index('--')
    opts, items = argv[:cut], argv[cut + 1 :]
    for c in costs(opts[0], items, '--small' in opts[1:]):
        print(f'{c:.3f}')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
