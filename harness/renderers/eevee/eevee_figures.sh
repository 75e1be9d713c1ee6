#!/usr/bin/env bash
# EEVEE's figures for the README: per scene, EEVEE and our model against Cycles (validate), the
# total and per term (diffuse, specular: the layers both Blender engines fill alike, since
# they render one translation), surface pixels of the rasterizer's mask.
#
# Usage: bash harness/renderers/eevee/eevee_figures.sh RUN_DIR SCENE...
#   RUN_DIR holds SCENE/{eevee,cycles,raster}-validate.exr (reflcheck run, or a nightly run).
# Prints one line per scene and term; needs oiiotool (openimageio-tools) to cut out a layer.
set -euo pipefail
cd "$(dirname "$0")/../../.."
bin=${REFLCHECK_BIN:-build/reflcheck}
run=$1
shift
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# Surface figures: NRMSE, and the robust ones (NRMSE without the worst 1 % of pixels, median
# relative error); "-" where the reference is black there (a conductor has no diffuse).
nrmse() {
    "$bin" diff "$1" "$2" --mask "$3" | python3 -c 'import json, sys
s = json.load(sys.stdin)["surface"]
f = lambda k: "%.3g" % s[k] if s.get(k) is not None else "?"
print("-" if s["max_ref"] == 0 else "%s %s %s" % (f("nrmse"), f("nrmse_trim1"), f("rel_median")))'
}
layer() { oiiotool "$1" --ch "R=$2.R,G=$2.G,B=$2.B,coverage=coverage" -o "$3"; }
echo "each cell: NRMSE, NRMSE without the worst 1 %, median relative error"
printf '%-18s %-9s %24s %24s\n' scene term eevee raster
for name in "$@"; do
    d=$run/$name
    for f in eevee cycles raster; do
        [ -f "$d/$f-validate.exr" ] || { echo "eevee_figures.sh: $d/$f-validate.exr missing; render it with reflcheck run --role validate" >&2; exit 1; }
    done
    mask=$d/raster-validate.exr
    printf '%-18s %-9s %24s %24s\n' "$name" total "$(nrmse "$d/eevee-validate.exr" "$d/cycles-validate.exr" "$mask")" \
        "$(nrmse "$d/raster-validate.exr" "$d/cycles-validate.exr" "$mask")"
    for term in diffuse specular; do
        layer "$d/eevee-validate.exr" "$term" "$tmp/e.exr"
        layer "$d/cycles-validate.exr" "$term" "$tmp/c.exr"
        printf '%-18s %-9s %24s %24s\n' "$name" "$term" "$(nrmse "$tmp/e.exr" "$tmp/c.exr" "$mask")" -
    done
done
