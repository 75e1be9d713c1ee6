#!/bin/bash
# Regenerates scenes/envs/{city,courtyard}_cube_*.exr from city.exr and courtyard.exr (see
# make_cube.c); run from the
# repository root after `make`. BUILD names the build folder (default build).
set -euo pipefail
BUILD=${BUILD:-build}
cc -std=c11 -O2 -Imodel -Iharness scenes/envs/make_cube.c "$BUILD/libreflcheck_harness.a" \
    "$BUILD/libreflcheck_model.a" $(pkg-config --libs OpenEXR) -lm -o "$BUILD/make_cube"
for sky in city courtyard; do
    "$BUILD/make_cube" "scenes/envs/$sky.exr" "scenes/envs/${sky}_cube"
done
