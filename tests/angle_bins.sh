#!/usr/bin/env bash
# Where the error sits, on scenes whose answer is known (compare.json's angle bins, by N.V, N.H
# and N.L, split by term and material; reports/FORMAT.md):
#  - a D3D9Client mirror plane seen from grazing to steep against `exact`: the p = 3 power law
#    overshoots the exact dielectric Fresnel most at N.V ~ 0.1-0.3 (0.04 + 0.96 (1 - c)^3
#    against F(c): 0.59 vs 0.40 at c = 0.17, 0.16 vs 0.09 at 0.5, equal at 1), so the lowest
#    N.V bins must hold most of the squared error although the plane reaches N.V > 0.6;
#  - a D3D Blinn-Phong (power 40) against exact's Beckmann lobe (m = sqrt(2 / (P + 2))) of the
#    same peak: the shapes differ inside the highlight only, so the top N.H bin (0.9-1] must
#    hold nearly all of it, though the sphere covers N.H from below 0.5.
# Scenes are written here (not canonical ones), rendered by `reflcheck run` (raster, exact) and
# compared by `reflcheck compare`; the bins that dominate are printed.
set -uo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
bin=$build/reflcheck
work=$(mktemp -d "${TMPDIR:-/tmp}/reflcheck-angle.XXXXXX") || exit 1
trap 'rm -rf "$work"' EXIT

cat >"$work/graze.yaml" <<'EOF'
name: graze_plane
image: {width: 64, height: 48, supersample: 2}
camera: {eye: [0, 1.0, 2.0], target: [0, 0, -1.0], hfov: 90}
environment: {constant: [1, 1, 1]}
materials:
  glass: {albedo: [0, 0, 0], ior: 1.5, roughness: 0, model: d3d9client, d3d9client: {p: 3}}
objects:
  - {shape: quad, size: [60, 60], material: glass}
comparisons:
  - reference: exact
    role: validate
    thresholds:
      nrmse: {warn: 100, fail: 200, why: "a known-answer test of where the error sits, not a gate"}
EOF
cat >"$work/blinn.yaml" <<'EOF'
name: blinn_beckmann
image: {width: 64, height: 48, supersample: 2}
camera: {eye: [0, 0.4, 3.2], target: [0, 0, 0], hfov: 45}
physics: {fresnel_specular: nv}
lights:
  - {type: point, position: [1.6, 2.2, 2.4], intensity: [12, 12, 12]}
materials:
  plastic:
    albedo: [0, 0, 0]
    ior: 1.5
    roughness: 0.218
    model: d3d
    d3d: {specular: [0.21, 0.21, 0.21], power: 40, local_viewer: true}
objects:
  - {shape: sphere, center: [0, 0, 0], radius: 1, tessellation: 64, material: plastic}
comparisons:
  - reference: exact
    role: validate
    thresholds:
      nrmse: {warn: 100, fail: 200, why: "a known-answer test of where the error sits, not a gate"}
EOF

fail=0
for s in graze blinn; do
    for r in raster exact; do
        "$bin" run "$work/$s.yaml" --renderer "$r" --role validate -o "$work/run" --no-cache >"$work/$s-$r.log" 2>&1 ||
            { echo "angle_bins: $s: reflcheck run --renderer $r failed:" >&2; cat "$work/$s-$r.log" >&2; fail=1; }
    done
    "$bin" compare "$work/$s.yaml" --run "$work/run" >"$work/$s-compare.log" 2>&1 ||
        { echo "angle_bins: $s: reflcheck compare failed:" >&2; cat "$work/$s-compare.log" >&2; fail=1; }
done
[ "$fail" = 0 ] || exit 1

/usr/bin/python3 - "$work/run" <<'EOF' || exit 1
import json, math, sys

run = sys.argv[1]
bad = []


def check(ok, what):
    if not ok:
        bad.append(what)


def cmp_of(scene):
    c = json.load(open(f'{run}/{scene}/compare.json'))['comparisons'][0]
    for key in ('angle_bins', 'angle_bins_ndoth', 'angle_bins_ndotl'):
        bins = c.get(key)
        if not isinstance(bins, list) or not all(isinstance(b.get('share'), (int, float)) for b in bins):
            bad.append(f'{scene}: {key} missing, or a bin without its share of the squared error')
            c[key] = []
    return c


def dominant(bins):
    return max(bins, key=lambda b: b['share']) if bins else None


def show(scene, key, bins):
    d = dominant(bins)
    print(
        f'angle_bins: {scene} {key}: dominant bin {d["lo"]:.1f}-{d["hi"]:.1f} holds {100 * d["share"]:.1f} % '
        f'of the squared error; per bin: ' + ' '.join(f'{b["lo"]:.1f}:{100 * b["share"]:.1f}%' for b in bins)
    )


def consistent(scene, key, bins, material):
    """Every bin's material split adds up to its share (one material); shares are fractions."""
    for b in bins:
        check(0.0 <= b['share'] <= 1.0 + 1e-12, f'{scene} {key}: share {b["share"]} outside [0, 1]')
        m = b.get('materials', {}).get(material)
        check(m is not None and abs(m['share'] - b['share']) <= 1e-9 and m['n'] == b['n'],
              f'{scene} {key} bin {b["lo"]}: material {material} split {m} != the bin ({b["share"]}, {b["n"]})')


# The D3D9Client plane: the lowest N.V bins hold it, though the plane reaches far steeper views.
g = cmp_of('graze_plane')
nv = g.get('angle_bins', [])
check(len(nv) >= 7 and max(b['hi'] for b in nv) >= 0.7, f'graze: N.V bins {[b["lo"] for b in nv]} do not reach 0.6')
if nv:
    show('graze_plane', 'N.V', nv)
    consistent('graze_plane', 'N.V', nv, 'glass')
    low = sum(b['share'] for b in nv if b['hi'] <= 0.3 + 1e-9)
    check(dominant(nv)['hi'] <= 0.3 + 1e-9, f'graze: dominant N.V bin {dominant(nv)["lo"]} is not below 0.3')
    check(low > 0.5, f'graze: bins below N.V 0.3 hold {low:.3f} of the squared error, not most of it')
    # Every surface pixel of a plane under the eye has N.V > 0: the bins share out the whole error.
    check(abs(sum(b['share'] for b in nv) - 1.0) < 1e-9, f'graze: N.V shares sum to {sum(b["share"] for b in nv)}')
    glossy = sum(b['terms'].get('glossy', {}).get('share', 0.0) for b in nv)
    check(abs(glossy - 1.0) < 1e-9, f'graze: the glossy term (a black mirror) holds {glossy} of the term error')
check(g.get('angle_bins_ndoth') == [] and g.get('angle_bins_ndotl') == [], 'graze: N.H, N.L bins without a light')

# The Blinn-Phong lobe against Beckmann: the top N.H bin holds it.
b = cmp_of('blinn_beckmann')
nh = b.get('angle_bins_ndoth', [])
check(len(nh) >= 6 and min(x['lo'] for x in nh) < 0.5, f'blinn: N.H bins {[x["lo"] for x in nh]} miss low N.H')
if nh:
    show('blinn_beckmann', 'N.H', nh)
    consistent('blinn_beckmann', 'N.H', nh, 'plastic')
    d = dominant(nh)
    check(d['lo'] >= 0.9 - 1e-9 and d['share'] > 0.9, f'blinn: dominant N.H bin {d["lo"]} holds {d["share"]:.3f}')
for key, name in (('angle_bins', 'N.V'), ('angle_bins_ndotl', 'N.L')):
    if b.get(key):
        show('blinn_beckmann', name, b[key])
        consistent('blinn_beckmann', name, b[key], 'plastic')
for s in bad:
    print('angle_bins: FAIL ' + s, file=sys.stderr)
sys.exit(1 if bad else 0)
EOF
echo "angle_bins: ok"
