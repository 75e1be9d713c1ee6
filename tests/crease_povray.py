# crease_povray.py - renders the ridge quad of tests/crease_blender.py in the real POV-Ray 3.7
# and checks its crease rule set: none (harness/crease.h). POV-Ray flips the interpolated normal
# toward the ray by that normal itself, as the model does, so every pixel, those where Cycles'
# back_face and valid_reflection rules depart included, must be the model's N.L.
#
# Usage: python3 tests/crease_povray.py OUT_DIR      (povray on the PATH)
#
# The quad |x|, |y| <= 1 at z = 0 under an orthographic camera at -z that spans it (32 x 32, no
# antialiasing: one ray through each pixel's centre), a white finish {diffuse 1 brilliance 1
# ambient 0} under a parallel light of colour 1: radiance N.L, written as a 16-bit linear PPM.
# Vertex normals lean out along x, N(x) ~ (3x, 0, -1) toward the camera, or flipped away from it.
# Cases, each with the Cycles rule that departs there as the would-be departure, and the middle
# of the quad (no rule anywhere) as the control:
#   front       normals toward the camera: Cycles' valid_reflection at |x| > 0.33;
#   light_below the light 5.7 degrees behind the quad's plane: the old transmission rule;
#   back        normals away from the camera: Cycles' back_face (the model turns N round).
# Prints one line per case; exits 1 when any pixel is not N.L.
import math
import os
import subprocess
import sys

W = 32
# 16-bit output rounds to 1.5e-5; POV-Ray computes in double. 0.5 % is the Blender test's
# control tolerance, so both renderers are held to the same line.
TOL = 5e-3


def unit(v):
    n = math.sqrt(sum(c * c for c in v))
    return tuple(c / n for c in v)


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def cycles_rules(n, ng, v, l):
    """The Cycles rules of crease.h and the dropped light rule, to name where they would depart."""
    if dot(ng, v) < 0.0:
        ng, n = tuple(-c for c in ng), tuple(-c for c in n)
    nv, gv = dot(n, v), dot(ng, v)
    r = tuple(2.0 * nv * a - b for a, b in zip(n, v))
    rules = set()
    if nv < 0.0:
        rules.add('back_face')
    if dot(r, ng) < min(0.9 * gv, 0.01):
        rules.add('valid_reflection')
    if dot(l, ng) < 0.0 < dot(l, n):
        rules.add('light_below')
    return rules


def write_pov(path, sign, l):
    xs = [-1.0, 1.0, 1.0, -1.0]
    ys = [-1.0, -1.0, 1.0, 1.0]
    with open(path, 'w') as f:
        f.write('#version 3.7;\nglobal_settings { assumed_gamma 1.0 ambient_light 0 }\n')
        f.write('camera { orthographic location <0, 0, -5> look_at <0, 0, 0> right x * 2 up y * 2 }\n')
        f.write('light_source { <%.9f, %.9f, %.9f> * 1000 color rgb 1 parallel point_at <0, 0, 0> }\n' % l)
        f.write('mesh2 {\n  vertex_vectors { 4')
        for x, y in zip(xs, ys):
            f.write(', <%g, %g, 0>' % (x, y))
        f.write(' }\n  normal_vectors { 4')
        for x in xs:
            n = unit((3.0 * x, 0.0, -1.0))
            f.write(', <%.9f, %.9f, %.9f>' % tuple(sign * c for c in n))
        f.write(' }\n  face_indices { 2, <0, 1, 2>, <0, 2, 3> }\n')
        f.write('  pigment { color rgb 1 } finish { ambient 0 diffuse 1 brilliance 1 specular 0 phong 0 }\n}\n')


def read_ppm16(path):
    with open(path, 'rb') as f:
        data = f.read()
    fields, pos = [], 0
    while len(fields) < 4:
        while data[pos : pos + 1].isspace():
            pos += 1
        if data[pos : pos + 1] == b'#':  # a header comment (POV-Ray writes its version) runs to the line end
            pos = data.index(b'\n', pos)
            continue
        start = pos
        while not data[pos : pos + 1].isspace():
            pos += 1
        fields.append(data[start:pos])
    pos += 1
    w, h, maxval = int(fields[1]), int(fields[2]), int(fields[3])
    if fields[0] != b'P6' or w != W or h != W or maxval != 65535:
        raise SystemExit('crease_povray: %s: expected a %dx%d 16-bit P6 image, got %r' % (path, W, W, fields))
    px = data[pos : pos + 6 * w * h]
    return [(px[2 * i] << 8 | px[2 * i + 1]) / 65535.0 for i in range(0, 3 * w * h, 3)]


def run_case(out, name, sign, l):
    pov = os.path.join(out, name + '.pov')
    img = os.path.join(out, name + '.ppm')
    write_pov(pov, sign, l)
    cmd = ['povray', '+I' + pov, '+O' + img, '+W%d' % W, '+H%d' % W, '-A', '+FP16', 'File_Gamma=1.0', '-D', '+Q9']
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit('crease_povray: %s: povray exited %d: %s' % (pov, r.returncode, r.stderr.strip()[-300:]))
    return read_ppm16(img)


def check(name, px, sign, l, would):
    v = (0.0, 0.0, -1.0)
    ng = (0.0, 0.0, -1.0)
    worst = {'control': [0, 0.0], 'would': [0, 0.0]}
    for j in range(W):
        for i in range(W):
            x = -1.0 + (i + 0.5) * 2.0 / W
            n = tuple(sign * c for c in unit((3.0 * x, 0.0, -1.0)))
            m = n if dot(n, v) >= 0.0 else tuple(-c for c in n)
            nl = max(0.0, dot(m, l))
            got = px[j * W + i]
            rules = cycles_rules(n, ng, v, l)
            key = 'would' if would in rules else ('control' if not rules else None)
            if key is None or (key == 'would' and nl < 0.05):
                continue
            worst[key][0] += 1
            worst[key][1] = max(worst[key][1], abs(got - nl) / max(nl, 0.05))
    line = '%s: control %d px worst %.2e of N.L; where Cycles\' %s departs: %d px worst %.2e' % (
        name,
        worst['control'][0],
        worst['control'][1],
        would,
        worst['would'][0],
        worst['would'][1],
    )
    print('crease_povray: ' + line)
    # The back case has no rule-free pixel (every lit one is back_face for Cycles): its control
    # is the front case, the same quad with the normals turned.
    if (worst['control'][0] < W and name != 'back') or worst['would'][0] < W:
        return line + ': too few pixels to judge'
    if worst['control'][1] > TOL or worst['would'][1] > TOL:
        return line + ': POV-Ray departs from N.L (a crease rule crease.h does not have)'
    return None


def main():
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    cases = [
        ('front', 1.0, unit((-1.0, 0.0, -1.0)), 'valid_reflection'),
        ('light_below', 1.0, unit((1.0, 0.0, 0.1)), 'light_below'),
        ('back', -1.0, unit((-1.0, 0.0, -1.0)), 'back_face'),
    ]
    failures = []
    for name, sign, l, would in cases:
        bad = check(name, run_case(out, name, sign, l), sign, l, would)
        if bad:
            failures.append(bad)
    for f in failures:
        print('crease_povray: FAIL ' + f)
    sys.exit(1 if failures else 0)


main()
