#!/usr/bin/env bash
# The gates must catch a broken model, and only where the model is used: build a copy of
# reflcheck whose D3D9Client Fresnel has a wrong exponent (p + 1), run the scene tests with
# it, and require that exactly the scenes using that term (m > 0) fail.
set -uo pipefail
export LC_ALL=C  # one order for the glob and sort below
cd "$(dirname "$0")/.."
build=${1:-build}
work=$build/mutant
# The scenes that use the term: a D3D9Client material whose m is not set to 0 (m defaults to
# nonzero), in a scene whose plan has a twin of our model. Only a twin pins the model: a
# validate bounds the approximation's error from above, and a mutation that happens to move
# the model nearer the physics passes it (d3d9_dissolve, whose noise no renderer twins, has
# validates only). Read from the scene files and their plans, so a new scene joins the
# expectation by itself.
# A material's d3d9client map may stand on its own line or inline in the material's own map.
expected=$(for s in scenes/*.yaml; do
    grep -E '\bd3d9client:\s*\{' "$s" | grep -qvE '\bm:\s*0(\.0*)?\s*[,}]' &&
        "$build/reflcheck" plan "$s" --out "$build/mutant-plan" --small | grep -q '/raster-twin\.json:' &&
        basename "$s" .yaml
done | sort | tr '\n' ' ' | sed 's/ $//')
[ -n "$expected" ] || { echo "mutant: no scene uses the D3D9Client Fresnel; update this test" >&2; exit 1; }

rm -rf "$work"
# With the build's objects: only what includes formula.h (and so its body) compiles again.
. tests/scratch_tree.sh
scratch_tree "$work" "$build" || { echo "mutant: copying the tree failed" >&2; exit 1; }
# formula_d3d9_power (model/formula_body.h) is the one definition of the exponent: every instance
# of it (the scalar model's double, the SIMD kernels' float, the long-double check) is compiled
# from that line.
sed -i 's/FORMULA_INLINE FT FN(formula_d3d9_power)(FT p) { return p < 0 ? 0 : p; }/FORMULA_INLINE FT FN(formula_d3d9_power)(FT p) { return p < 0 ? 0 : p + 1; }/' \
    "$work/model/formula_body.h"
if ! grep -q 'FN(formula_d3d9_power)(FT p) { return p < 0 ? 0 : p + 1; }' "$work/model/formula_body.h"; then
    echo "mutant: the Fresnel exponent line was not found in model/formula_body.h; update this test" >&2
    exit 1
fi
make -s -C "$work" build/reflcheck build/examples/ggx/ggx.so >/dev/null || { echo "mutant: build failed" >&2; exit 1; }

# The references do not depend on the model, and their cache keys hash the translators' sources
# (the same bytes in the copy), so the scene tests' cache serves them: only our renders are
# redone with the mutant binary, whose bytes are in its jobs' keys.
cache=$(cd "$build" && pwd)/cache
failed=()
for s in "$work"/scenes/*.yaml; do
    name=$(basename "$s" .yaml)
    (cd "$work" && CACHE="$cache" SCENES="scenes/$name.yaml" RUN_DIR=build/run-$name bash tests/run_scenes.sh build >/dev/null 2>&1) \
        || failed+=("$name")
done
got="${failed[*]}"
echo "mutant (Fresnel exponent p + 1): failing scenes: ${got:-none}; expected: $expected"
if [ "$got" = "$expected" ]; then
    echo "mutant: 1 passed, 0 failed"
else
    echo "mutant: 0 passed, 1 failed"
    exit 1
fi
