#!/usr/bin/env bash
# Installs the Debian packages reflcheck needs, only those missing. Run by `make test`,
# `make report` and .ci/run; safe to run again (it checks before it installs).
set -euo pipefail

pkgs=(build-essential pkg-config libopenexr-dev libyaml-dev libcmocka-dev libcjson-dev
      openimageio-tools gnuplot-nox chromium
      libosmesa6-dev libmpfr-dev clang libclang-rt-14-dev python3 python3-pytest python3-jinja2
      procps time)
# Textures (scene/texture.c: PNG and JPEG) and the real-content scenes' assets (scenes/real_*.yaml
# read /usr/share/assimp/models/...; tests/test_mesh.c loads three of them: docs/meshes.md).
pkgs+=(libpng-dev libjpeg-dev assimp-testmodels)
# Users' own assets (glTF, FBX, COLLADA, DirectX .x, ...): Open Asset Import Library's C API
# (scene/mesh_assimp.c).
pkgs+=(libassimp-dev)
# DDS textures and cube maps (scene/image_oiio.cpp: a C shim over OpenImageIO's C++ API).
pkgs+=(libopenimageio-dev)
# The Slurm backend and its local test cluster (ops/slurm/, docs/slurm.md).
pkgs+=(slurm-wlm munge)
# EEVEE's OpenGL context (harness/renderers/eevee/): Xvfb with Mesa's llvmpipe.
pkgs+=(xvfb xauth libgl1-mesa-dri)
# reflcheck fit (harness/fit.c): NLopt's bounded derivative-free optimiser.
pkgs+=(libnlopt-dev)
# The nightly's fit order (ops/fit_costs.py reads the scene files) and its test.
pkgs+=(python3-yaml)
# The manual page's check in tests/install.sh (groff -man; tools/gen_man.c writes the page itself).
pkgs+=(groff-base)
# The renderers' packages come from their rows in the renderer table (.package = "..."), read
# from the source because this runs before anything is built.
registry="$(dirname "$0")/../harness/renderers/registry.c"
renderer_pkgs=$(sed -n 's/.*\.package = "\([a-z0-9.+-]*\)".*/\1/p' "$registry")
[ -n "$renderer_pkgs" ] || { echo "reflcheck: deps: no renderer packages found in $registry" >&2; exit 1; }
for p in $(printf "%s\n" $renderer_pkgs | sort -u); do pkgs+=("$p"); done

# One dpkg-query for the whole list (one per package cost a process pair each, most of this
# script's time when nothing is missing); a package it does not know is missing.
declare -A have=()
while IFS=$'\t' read -r name status; do
    [ "$status" = "install ok installed" ] && have[$name]=1
done < <(dpkg-query -W -f='${Package}\t${Status}\n' "${pkgs[@]}" 2>/dev/null)
missing=()
for p in "${pkgs[@]}"; do
    [ -n "${have[$p]:-}" ] || missing+=("$p")
done
# DEPS_LIST=1: print the package list and install nothing (what a new renderer adds shows here).
[ -n "${DEPS_LIST:-}" ] && { echo "${pkgs[*]}"; exit 0; }
[ ${#missing[@]} -eq 0 ] && exit 0

echo "reflcheck: installing missing Debian packages: ${missing[*]}" >&2
sudo=""
if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || {
        echo "reflcheck: not root and no sudo; run as root: apt-get install ${missing[*]}" >&2
        exit 1
    }
    sudo=sudo
fi
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
