"""test_fit_costs.py - ops/fit_costs.py: the last run's fit seconds, else the scene's estimate.

Run: /usr/bin/python3 -m pytest -q -p no:cacheprovider tests/test_fit_costs.py
"""

import json
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, 'ops'))
import fit_costs  # noqa: E402

SCENE = '''name: b
image: {width: 10, height: 20, supersample: 2, small: {width: 4, height: 2, supersample: 1}}
materials:
  glass: {model: d3d9client}
  metal: {model: cook_torrance}
  unused: {model: d3d9client}
  plastic: {model: d3d}
objects:
  - {shape: sphere, material: glass}
  - {shape: sphere, material: metal}
  - {shape: sphere, material: plastic}
comparisons:
  - {reference: cycles, role: validate}
  - {reference: exact, role: validate}
  - {reference: povray}
  - {test: exact, reference: cycles, role: agree}
'''


def test_last_runs_seconds_first_then_the_scenes_estimate(tmp_path):
    latest = tmp_path / 'latest'
    (latest / 'a').mkdir(parents=True)
    doc = {'scene_path': 'scenes/a.yaml', 'variant': 'full', 'fits': [{'seconds': 1.5}, {'seconds': 2.25}]}
    (latest / 'a' / 'fit.json').write_text(json.dumps(doc))
    (latest / 'a' / 'fit-wide.json').write_text(json.dumps({**doc, 'fits': [{'seconds': 7.0}]}))
    b = tmp_path / 'b.yaml'
    b.write_text(SCENE)
    items = ['seed\tscenes/a.yaml', 'wide\tscenes/a.yaml', f'seed\t{b}']
    got = fit_costs.costs(str(latest), items, small=False)
    # b by hand: 2 validate fits of the model (the twin and the agree are not fitted); free
    # parameters glass 2 + metal 1 (unused is no object's, plain d3d has no specular) = 3, so
    # 180 evaluations; 10 x 20 x 2^2 = 800 pixels; 1.2e-8 s each.
    assert got[:2] == [3.75, 7.0]
    assert abs(got[2] - 2 * 180 * 800 * 1.2e-8) < 1e-12
    # --small: the small image (8 pixels), and the last run's full-size fits do not count.
    small = fit_costs.costs(str(latest), items, small=True)
    assert abs(small[2] - 2 * 180 * 8 * 1.2e-8) < 1e-12
    assert small[0] == fit_costs.static_seconds('scenes/a.yaml', True) == 0.0  # no such file here


def test_a_user_model_counts_its_parameters_and_costs_more(tmp_path):
    s = tmp_path / 'u.yaml'
    s.write_text(
        SCENE.replace(
            'glass: {model: d3d9client}', 'glass: {model: user, user: {path: x.so, params: {a: 1, b: 2, c: 3}}}'
        )
    )
    # glass 3 + metal 1 = 4 parameters: 240 evaluations, 3.5 times the seconds per pixel.
    assert abs(fit_costs.static_seconds(str(s), False) - 2 * 240 * 800 * 1.2e-8 * 3.5) < 1e-12
