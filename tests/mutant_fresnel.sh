#!/usr/bin/env bash
# The gates must catch a broken model, and only where the model is used: build a copy of
# reflcheck whose D3D9Client Fresnel has a wrong exponent (p + 1), run the scene tests with
# it, and require that exactly the scenes using that term (m > 0) fail.
set -uo pipefail
cd "$(dirname "$0")/.."
work=${1:-build}/mutant
expected="d3d9_glass d3d9_metal grazing_plane"

rm -rf "$work"
mkdir -p "$work"
cp -r model harness scenes tests Makefile "$work"/
# fresnel_d3d9_power is the one definition of the exponent, used by the scalar model and the
# SIMD kernels the renders run (model/shade_batch.c).
sed -i 's/static inline float fresnel_d3d9_power(float p) { return p < 0.0f ? 0.0f : p; }/static inline float fresnel_d3d9_power(float p) { return p < 0.0f ? 0.0f : p + 1.0f; }/' \
    "$work/model/fresnel.h"
if ! grep -q 'return p < 0.0f ? 0.0f : p + 1.0f; }' "$work/model/fresnel.h"; then
    echo "mutant: the Fresnel exponent line was not found in model/fresnel.h; update this test" >&2
    exit 1
fi
make -s -C "$work" build/reflcheck >/dev/null || { echo "mutant: build failed" >&2; exit 1; }

failed=()
for s in "$work"/scenes/*.yaml; do
    name=$(basename "$s" .yaml)
    (cd "$work" && SCENES="scenes/$name.yaml" RUN_DIR=build/run-$name bash tests/run_scenes.sh build >/dev/null 2>&1) \
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
