#!/usr/bin/env bash
# Cycles' shading normals are the vertex normals we send, not Blender's 16-bit copy of them:
# mirror_sphere's twin, small, in our rasterizer and the real Blender Cycles, must agree on the
# reflection term to the noise. With the custom split normals alone (stored as two 16-bit
# angles, 1.6e-4 rad off in the median) the mirror direction moves and the term's nrmse read
# 0.0065, its bias 3.9 standard errors; with the float normals 0.0019 and 0.85 (docs/physics.md,
# mirror_sphere). The bound 0.004 sits at 2x the figure and under the quantised normals' one;
# the bias is printed, not gated here: at this size noise alone moves it by 2-3.
set -uo pipefail
cd "$(dirname "$0")/.." || exit 1
build=${1:-build}
bin=$build/reflcheck
if ! command -v blender > /dev/null; then
    echo "cycles_normals: SKIP (blender not installed)"
    exit 0
fi
work=$(mktemp -d "${TMPDIR:-/tmp}/reflcheck-normals.XXXXXX") || exit 1
trap '[ -n "${KEEP:-}" ] || rm -rf "$work"' EXIT
for r in raster cycles; do
    if ! "$bin" run scenes/mirror_sphere.yaml --renderer "$r" --role twin --small -o "$work" --no-cache > "$work/$r.log" 2>&1; then
        echo "FAIL: cycles_normals: the $r twin did not render; see $work/$r.log (KEEP=1 keeps it)"
        exit 1
    fi
done
"$bin" compare scenes/mirror_sphere.yaml --run "$work" > /dev/null 2>&1
python3 - "$work/mirror_sphere/compare.json" << 'PY'
import json, sys

c = [c for c in json.load(open(sys.argv[1]))["comparisons"] if c["id"] == "raster-vs-cycles-twin"][0]
t = c["terms"]["reflection"]
bad = []
if not t["nrmse"] < 0.004:
    bad.append("reflection nrmse %.4g >= 0.004" % t["nrmse"])
msg = "reflection nrmse %.4g, bias %.3g standard errors (rel %.2g)" % (t["nrmse"], t["bias_z_trim1"], t["bias_rel_trim1"])
if bad:
    print("FAIL: cycles_normals: %s: %s; Cycles shades with other normals than ours "
          "(harness/renderers/cycles/cycles_render.py exact_normals)" % (msg, "; ".join(bad)))
    sys.exit(1)
print("ok: cycles_normals: " + msg)
PY
