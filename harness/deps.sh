#!/usr/bin/env bash
# Installs the Debian packages reflcheck needs, only those missing. Run by `make test`,
# `make report` and .ci/run; safe to run again (it checks before it installs).
set -euo pipefail

pkgs=(build-essential pkg-config libopenexr-dev libyaml-dev libcmocka-dev libcjson-dev
      povray blender openimageio-tools gnuplot-nox chromium
      libosmesa6-dev libmpfr-dev clang libclang-rt-14-dev python3 python3-pytest python3-jinja2
      procps)

missing=()
for p in "${pkgs[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
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
