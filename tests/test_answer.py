"""test_answer.py - tools/report/answer.py: the index's first table, from hand-made records.

Run: /usr/bin/python3 -m pytest -q -p no:cacheprovider tests/test_answer.py
"""

import os
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, 'tools'))
from report.answer import answer_rows, physics_short  # noqa: E402

PHYS = (
    'diffuse_lights=all specular_lights=all env_diffuse=0 env_specular=1 bounces=1 shadows=0 '
    'interreflection=0 fresnel_specular=nv fresnel_reflection=exact diffuse_weight=one_minus_f'
)


def bins(rel):
    """Angle bins 0.0-0.1 ... with 10 pixels each and the given rel_rms."""
    return [{'lo': i / 10, 'hi': (i + 1) / 10, 'n': 10, 'rel_rms': r} for i, r in enumerate(rel)]


def validate(**kw):
    c = {
        'id': 'raster-vs-cycles-validate',
        'test': 'raster',
        'reference': 'cycles',
        'role': 'validate',
        'status': 'pass',
        'physics': PHYS,
        'regions': {'surface': {'rel_median': 0.2, 'rel_p95': 0.6, 'nrmse': 0.4, 'nrmse_trim1': 0.3}},
        # squared shares: diffuse 0.01, glossy 0.09 -> glossy holds 90 %
        'terms': {'diffuse': {'nrmse': 0.1}, 'glossy': {'nrmse': 0.3}},
        # n * rel^2: 10*(0.1^2, 0.3^2, 0.2^2) = 0.1, 0.9, 0.4 -> bin 0.1-0.2 holds 0.9/1.4
        'angle_bins': bins([0.1, 0.3, 0.2]),
        'angle_bins_ndotl': bins([0.5, 0.0]),
        'times': {'test_wall_s': 0.02, 'reference_wall_s': 2.5},
    }
    c.update(kw)
    return c


def scene(name, comparisons, fits=()):
    return {'name': name, 'page': f'scene-{name}.html', 'comparisons': comparisons, 'fits': list(fits)}


def test_one_row_with_where_fit_cost_and_twins():
    twin = {'id': 'raster-vs-povray-twin', 'reference': 'povray', 'role': 'twin', 'status': 'pass'}
    bad = {
        'id': 'raster-vs-cycles-twin',
        'reference': 'cycles',
        'role': 'twin',
        'status': 'fail',
        'noise': {'ztest': {'n_fail_pixels': 7}},
    }
    fits = [
        {'id': 'raster-vs-cycles-validate', 'bounds': 'wide', 'status': 'ok', 'best': {'nrmse': 0.05}},
        {
            'id': 'raster-vs-cycles-validate',
            'bounds': 'seed',
            'status': 'ok',
            'best': {'nrmse': 0.25, 'median_rel': 0.1},
        },
    ]
    R = {'scenes': [scene('glass', [twin, bad, validate()], fits)]}
    (r,) = answer_rows(R, {'glass': {'spp': 64}})
    assert (r['median'], r['p95'], r['nrmse'], r['trim1']) == (0.2, 0.6, 0.4, 0.3)
    assert r['term'][0] == 'glossy' and r['term'][1] == pytest.approx(0.9)
    assert r['nv'][:2] == (0.1, 0.2) and r['nv'][2] == pytest.approx(0.9 / 1.4)
    assert r['nl'][:2] == (0.0, 0.1) and r['nl'][2] == pytest.approx(1.0)
    assert (r['fit_nrmse'], r['fit_median']) == (0.25, 0.1)  # the source-range fit, not the wide one
    assert (r['test_s'], r['ref_s'], r['crossover']) == (0.02, 2.5, {'spp': 64})
    assert r['twins'] == [('povray', 'at floor', 'pass'), ('cycles', '7 pixels off', 'fail')]
    assert r['physics'] == 'F lamp nv, F env exact, diffuse × (1 − F)'


def test_rows_per_material_when_the_surface_is_split_and_none_measured_without_validate():
    objs = [
        {'object': 0, 'material': 'skin', 'rel_median': 0.1, 'nrmse': 0.2},
        {'object': 1, 'material': 'legs', 'rel_median': 0.3, 'nrmse': 0.5},
    ]
    R = {'scenes': [scene('spider', [validate(objects=objs)]), scene('spot', [])]}
    rows = answer_rows(R)
    assert [(r['scene']['name'], r['material']) for r in rows] == [
        ('spider', 'skin'),
        ('spider', 'legs'),
        ('spot', None),
    ]
    assert rows[1]['median'] == 0.3 and rows[1]['nrmse'] == 0.5
    assert rows[0]['nv'] is None and rows[0]['fit_nrmse'] is None  # whole-surface figures only
    assert rows[2]['no_validate'] and rows[2]['twins'] == []
    assert rows[0]['crossover'] is None


def shares(per_bin):
    """Angle bins 0.0-0.1 ... in compare.json's split form: each bin's share of the surface's
    squared error, and per material {name: share}."""
    return [
        {
            'lo': i / 10,
            'hi': (i + 1) / 10,
            'n': 10,
            'rel_rms': 1.0,
            'share': sum(m.values()),
            'materials': {k: {'n': 5, 'share': v} for k, v in m.items()},
        }
        for i, m in enumerate(per_bin)
    ]


def test_where_names_the_n_dot_h_bin_and_each_materials_own_bins():
    objs = [
        {'object': 0, 'material': 'skin', 'rel_median': 0.1, 'nrmse': 0.2},
        {'object': 1, 'material': 'legs', 'rel_median': 0.3, 'nrmse': 0.5},
    ]
    # N.V: skin's error in bin 0.0-0.1 (0.3 of 0.4), legs' in 0.1-0.2 (0.5 of 0.6); the surface's
    # largest bin is 0.1-0.2 with 0.5 + 0.1 = 0.6 of 1.0, although rel_rms is equal everywhere.
    nv = shares([{'skin': 0.3, 'legs': 0.1}, {'skin': 0.1, 'legs': 0.5}])
    # N.H: everything in the top bin but 0.05.
    nh = shares([{'skin': 0.05}] + [{}] * 8 + [{'skin': 0.15, 'legs': 0.8}])
    c = validate(objects=objs, angle_bins=nv, angle_bins_ndoth=nh)
    whole = validate(angle_bins=nv, angle_bins_ndoth=nh)
    skin, legs = answer_rows({'scenes': [scene('spider', [c])]})
    (r,) = answer_rows({'scenes': [scene('spider', [whole])]})
    assert r['nv'][:2] == (0.1, 0.2) and r['nv'][2] == pytest.approx(0.6)
    assert r['nh'][:2] == (0.9, 1.0) and r['nh'][2] == pytest.approx(0.95)
    assert skin['nv'][:2] == (0.0, 0.1) and skin['nv'][2] == pytest.approx(0.75)
    assert legs['nv'][:2] == (0.1, 0.2) and legs['nv'][2] == pytest.approx(0.5 / 0.6)
    assert skin['nh'][:2] == (0.9, 1.0) and skin['nh'][2] == pytest.approx(0.75)
    assert legs['nh'][2] == pytest.approx(1.0)
    assert r['term'][0] == 'glossy'


def test_physics_short_names_what_departs_from_the_defaults():
    text = PHYS.replace('bounces=1', 'bounces=4').replace('env_diffuse=0', 'env_diffuse=1')
    assert physics_short(text) == 'F lamp nv, F env exact, diffuse × (1 − F), env_diffuse 1, bounces 4'


def test_every_validate_figure_stands_beside_its_agree_or_says_it_has_none():
    """A validate figure shows the agree that measures its reference by a second one; a
    validate with none says so (ct_env: Cycles alone), and an agree of other references is not
    counted for it."""
    agree = {
        'id': 'exact-vs-cycles-agree',
        'test': 'exact',
        'reference': 'cycles',
        'role': 'agree',
        'status': 'pass',
        'regions': {'surface': {'nrmse': 0.03}},
    }
    other = dict(agree, id='povray-vs-exact-agree', test='povray', reference='exact', status='warn')
    R = {
        'scenes': [
            scene('toaster', [validate(), validate(id='raster-vs-exact-validate', reference='exact'), agree, other]),
            scene('ct_env', [validate()]),
            scene('glass', [validate(reference='povray'), agree]),
        ]
    }
    rows = answer_rows(R, fold=False)
    by = {(r['scene']['name'], r['reference']): r for r in rows}
    assert by[('toaster', 'cycles')]['agrees'] == [('exact', 0.03, 'pass')]
    assert by[('toaster', 'exact')]['agrees'] == [('cycles', 0.03, 'pass'), ('povray', 0.03, 'warn')]
    assert by[('toaster', 'cycles')]['agree_none'] is None
    assert by[('ct_env', 'cycles')]['agrees'] == []
    assert 'cycles alone' in by[('ct_env', 'cycles')]['agree_none']
    assert by[('glass', 'povray')]['agrees'] == [] and 'povray alone' in by[('glass', 'povray')]['agree_none']


def test_one_physics_per_material_kind_or_the_difference_named():
    """The same plastic under two physics (d3d_blinn_phong: F(N.V), 1 - F diffuse; d3d_scaled:
    exact F, plain diffuse): both rows name the other's physics. A floor without specular is
    compared on its diffuse only, so lambert's specular_lights none is no difference."""
    exact = PHYS.replace('fresnel_specular=nv', 'fresnel_specular=exact').replace('one_minus_f', 'plain')
    lambert = exact.replace('specular_lights=all', 'specular_lights=none')
    objs = [
        {'object': 0, 'material': 'plastic', 'nrmse': 0.2},
        {'object': 1, 'material': 'floor', 'nrmse': 1e-5},
    ]
    plastic = {'plastic': 'd3d dielectric'}
    both = {'plastic': 'd3d dielectric', 'floor': 'd3d without specular'}
    floor = {'floor': 'd3d without specular'}
    R = {
        'scenes': [
            scene('blinn', [validate(material_kinds=plastic)]),
            scene('scaled', [validate(reference='exact', physics=exact, objects=objs, material_kinds=both)]),
            scene('lambert', [validate(physics=lambert, material_kinds=floor)]),
            scene('glass', [validate(physics=exact, material_kinds={'glass': 'd3d9client dielectric'})]),
        ]
    }
    by = {(r['scene']['name'], r['material']): r for r in answer_rows(R)}
    assert by[('blinn', None)]['kinds'] == ['d3d dielectric']
    assert by[('blinn', None)]['physics_differs'] == [('scaled', 'F lamp exact, F env exact, diffuse plain')]
    assert by[('scaled', 'plastic')]['physics_differs'] == [('blinn', 'F lamp nv, F env exact, diffuse × (1 − F)')]
    assert by[('scaled', 'floor')]['physics_differs'] == [] and by[('lambert', None)]['physics_differs'] == []
    assert by[('glass', None)]['physics_differs'] == []


def test_one_row_per_approximation_with_the_other_references_under_it():
    """Two validate references of one material fold into one row: the first gives the figures,
    the second stands under its NRMSE; another test renderer (eevee) keeps a row of its own."""
    ex = validate(id='raster-vs-exact-validate', reference='exact', status='warn')
    ex['regions'] = {'surface': {'rel_median': 0.25, 'nrmse': 0.5}}
    ee = validate(id='eevee-vs-cycles-validate', test='eevee')
    R = {'scenes': [scene('toaster', [validate(), ex, ee])]}
    rows = answer_rows(R)
    assert [(r['reference'], r['test']) for r in rows] == [('cycles', 'raster'), ('cycles', 'eevee')]
    assert rows[0]['nrmse'] == 0.4 and rows[0]['others'] == [('exact', 0.5, 0.25, 'warn')]
    assert rows[1]['others'] == []
