# crease_blender.py - renders a small ridge quad in the real Blender 3.4 Cycles and checks each
# crease rule of harness/crease.h against it: the departure a rule predicts, and a control where
# it predicts none.
#
# Usage: blender -b --factory-startup --python-exit-code 1 -P tests/crease_blender.py -- OUT_DIR
#
# The quad |x|, |y| <= 1 at z = 0 is seen straight down by an orthographic camera that spans it
# (32 x 32 pixels, pixel filter 0.01 px: each pixel is its centre sample). Its vertex normals lean
# out along x as a ridge's smoothed normals do, N(x) ~ (3x, 0, 1), so N and Ng = +z disagree more
# and more toward the sides. A white diffuse BSDF under a sun of strength pi (a delta light:
# no noise) gives radiance N.L, the model's value; each case compares Cycles with it:
#   front        Ng toward the camera. valid_reflection predicts a departure where the mirror
#                direction of the view about N drops below the quad (|x| > 0.33); control: the
#                middle, where no rule applies.
#   light_below  the same quad lit from 5.7 degrees below its plane (L.Ng < 0): no rule applies,
#                so Cycles must give N.L wherever L.N > 0 (the old 'transmission' rule said 0).
#   back         the quad wound away from the camera (Ng = -z), its vertex normals still toward
#                it: back_face predicts a departure everywhere the sun lights the sample.
#   back_flip    wound away with the normals flipped with it: Cycles turns both round, which is
#                the front case again; control for back_face.
# Prints one line per case and exits 1 (the shell test fails) when a prediction is not met.
import math
import os
import sys

import bpy

W = 32
OUT = sys.argv[sys.argv.index('--') + 1]
# A control pixel matches N.L to within 0.5 %: Cycles stores the EXR in float and the sun is a
# delta light, so only float rounding and the 0.01 px filter's offset from the centre (a lean
# change of ~3e-4 per pixel) remain.
CONTROL_TOL = 5e-3
# A departure is a difference of at least 2 % of N.L, four times the control tolerance. The bend
# grows from 0 at the rule's boundary, so the pixels next to it depart by less: two thirds of the
# predicted pixels must pass 2 % (73 % do in the valid_reflection cases, 100 % in back_face).
DEPART_MIN = 0.02
DEPART_SHARE = 2.0 / 3.0


def unit(v):
    n = math.sqrt(sum(c * c for c in v))
    return tuple(c / n for c in v)


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def departs(n, ng, v):
    '''crease.h's rules, worked here from the kernel's formulas, not read from crease.c.'''
    rules = set()
    if dot(ng, v) < 0.0:
        ng = tuple(-c for c in ng)
        n = tuple(-c for c in n)
    nv, gv = dot(n, v), dot(ng, v)
    if nv < 0.0:
        rules.add('back_face')
    r = tuple(2.0 * nv * a - b for a, b in zip(n, v))
    if dot(r, ng) < min(0.9 * gv, 0.01):
        rules.add('valid_reflection')
    return rules


def setup_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.engine = 'CYCLES'
    sc.cycles.device = 'CPU'
    sc.cycles.samples = 4
    sc.cycles.use_denoising = False
    sc.cycles.filter_width = 0.01
    sc.cycles.max_bounces = 0
    sc.cycles.seed = 1
    sc.render.resolution_x = sc.render.resolution_y = W
    sc.render.resolution_percentage = 100
    sc.render.image_settings.file_format = 'OPEN_EXR'
    sc.render.image_settings.color_depth = '32'
    sc.view_settings.view_transform = 'Standard'
    world = bpy.data.worlds.new('black')
    world.use_nodes = True
    world.node_tree.nodes['Background'].inputs['Strength'].default_value = 0.0
    sc.world = world
    cam_data = bpy.data.cameras.new('cam')
    cam_data.type = 'ORTHO'
    cam_data.ortho_scale = 2.0
    cam = bpy.data.objects.new('cam', cam_data)
    cam.location = (0.0, 0.0, 5.0)
    sc.collection.objects.link(cam)
    sc.camera = cam
    mat = bpy.data.materials.new('white')
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.clear()
    diff = nodes.new('ShaderNodeBsdfDiffuse')
    diff.inputs['Color'].default_value = (1.0, 1.0, 1.0, 1.0)
    diff.inputs['Roughness'].default_value = 0.0
    out = nodes.new('ShaderNodeOutputMaterial')
    mat.node_tree.links.new(diff.outputs['BSDF'], out.inputs['Surface'])
    sun_data = bpy.data.lights.new('sun', 'SUN')
    sun_data.energy = math.pi  # W/m^2: a white Lambert surface then has radiance N.L
    sun_data.angle = 0.0
    sun_data.cycles.cast_shadow = False
    sun = bpy.data.objects.new('sun', sun_data)
    sc.collection.objects.link(sun)
    return sc, mat, sun


def add_quad(sc, mat, wound_away, normals_sign):
    verts = [(-1.0, -1.0, 0.0), (1.0, -1.0, 0.0), (1.0, 1.0, 0.0), (-1.0, 1.0, 0.0)]
    faces = [(0, 1, 2, 3)] if not wound_away else [(0, 3, 2, 1)]
    me = bpy.data.meshes.new('quad')
    me.from_pydata(verts, [], faces)
    me.update()
    me.materials.append(mat)
    me.use_auto_smooth = True
    for p in me.polygons:
        p.use_smooth = True
    lean = []
    for loop in me.loops:
        x = me.vertices[loop.vertex_index].co.x
        lean.append(tuple(normals_sign * c for c in unit((3.0 * x, 0.0, 1.0))))
    me.normals_split_custom_set(lean)
    ob = bpy.data.objects.new('quad', me)
    sc.collection.objects.link(ob)
    return ob


def sun_towards(sun, l):
    '''Points the sun so that light arrives from direction l (unit, away from the surface).'''
    # A sun shines along its local -z: rotate -z onto -l.
    from mathutils import Vector

    sun.rotation_mode = 'QUATERNION'
    sun.rotation_quaternion = Vector((0.0, 0.0, -1.0)).rotation_difference(-Vector(l))


def render(sc, name):
    path = os.path.join(OUT, name + '.exr')
    sc.render.filepath = path
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(path)
    px = list(img.pixels)
    bpy.data.images.remove(img)
    return px


def check(name, px, l, n_sign, ng, want_rule, want_control):
    '''Compares each pixel with N.L; returns a failure line or None.'''
    v = (0.0, 0.0, 1.0)
    control = [0, 0.0]  # pixels, worst relative difference
    below = 0  # control pixels lit from below the triangle (L.Ng < 0 < L.N)
    depart = [0, 0]  # pixels predicted, of them beyond DEPART_MIN
    for j in range(W):
        for i in range(W):
            x = -1.0 + (i + 0.5) * 2.0 / W
            n = tuple(n_sign * c for c in unit((3.0 * x, 0.0, 1.0)))
            m = n if dot(n, v) >= 0.0 else tuple(-c for c in n)  # the model turns N to the viewer
            nl = max(0.0, dot(m, l))
            got = px[4 * (j * W + i)]
            rules = departs(n, ng, v)
            diff = abs(got - nl) / max(nl, 0.05)
            if want_rule in rules and nl > 0.05:
                depart[0] += 1
                depart[1] += diff > DEPART_MIN
            elif not rules:
                control[0] += 1
                control[1] = max(control[1], abs(got - nl) / max(nl, 0.05))
                ngv = ng if dot(ng, v) >= 0.0 else tuple(-c for c in ng)  # Ng toward the viewer
                below += dot(l, ngv) < 0.0 and nl > 0.05
    line = (
        '%s: control %d px (%d lit from below the triangle), worst %.2e of N.L; '
        '%s predicted at %d px, %d beyond %.0f %%'
        % (
            name,
            control[0],
            below,
            control[1],
            want_rule or 'no rule',
            depart[0],
            depart[1],
            100 * DEPART_MIN,
        )
    )
    print('crease_blender: ' + line)
    if want_control and (control[0] < W or control[1] > CONTROL_TOL):
        return line + ': the control does not match N.L'
    if want_control == 'below' and below < W:
        return line + ': too few samples lit from below the triangle to show the light is answered'
    if want_rule and (depart[0] < W or depart[1] < DEPART_SHARE * depart[0]):
        return line + ': the predicted departure is not in the render'
    return None


def main():
    os.makedirs(OUT, exist_ok=True)
    failures = []
    cases = [
        # name, wound away, normals sign, light direction, Ng, rule that must show, control
        ('front', False, 1.0, unit((-1.0, 0.0, 1.0)), (0.0, 0.0, 1.0), 'valid_reflection', 'plain'),
        ('light_below', False, 1.0, unit((1.0, 0.0, -0.1)), (0.0, 0.0, 1.0), None, 'below'),
        # Every lit sample has N.V < 0 once turned with Ng: no control pixel (back_flip is it).
        ('back', True, 1.0, unit((-1.0, 0.0, 1.0)), (0.0, 0.0, -1.0), 'back_face', None),
        ('back_flip', True, -1.0, unit((-1.0, 0.0, 1.0)), (0.0, 0.0, -1.0), 'valid_reflection', 'plain'),
    ]
    for name, away, sign, l, ng, rule, ctl in cases:
        sc, mat, sun = setup_scene()
        add_quad(sc, mat, away, sign)
        sun_towards(sun, l)
        px = render(sc, name)
        bad = check(name, px, l, sign, ng, rule, ctl)
        if bad:
            failures.append(bad)
    for f in failures:
        print('crease_blender: FAIL ' + f)
    sys.exit(1 if failures else 0)


main()
