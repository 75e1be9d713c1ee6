#!/bin/bash
# crease_renderers.sh - the crease rules of harness/crease.h, shown by the real renderers: a ridge
# quad rendered small in Blender 3.4 Cycles (tests/crease_blender.py: each Cycles rule's departure
# and a control) and in POV-Ray 3.7 (tests/crease_povray.py: no rule, every pixel N.L).
#
# Usage: bash tests/crease_renderers.sh BUILD      (from the repository root; a few seconds)
# Writes its renders under BUILD/crease_renderers/; exits 1 when a renderer's render does not
# show its rule set, 2 when a renderer is not installed (bash ops/deps.sh installs them).
set -u
build=${1:?usage: bash tests/crease_renderers.sh BUILD}
out="$build/crease_renderers"
rm -rf "$out"
mkdir -p "$out/blender" "$out/povray"
for prog in blender povray; do
    if ! command -v "$prog" >/dev/null 2>&1; then
        echo "crease_renderers: $prog is not installed; run: bash ops/deps.sh" >&2
        exit 2
    fi
done
rc=0
blender -b --factory-startup --python-exit-code 1 -P tests/crease_blender.py -- "$out/blender" >"$out/blender.log" 2>&1 ||
    rc=1
grep '^crease_blender' "$out/blender.log"
if [ "$rc" -ne 0 ] && ! grep -q '^crease_blender: FAIL' "$out/blender.log"; then
    echo "crease_renderers: blender failed before judging; see $out/blender.log" >&2
fi
python3 tests/crease_povray.py "$out/povray" || rc=1
[ "$rc" -eq 0 ] && echo "crease_renderers: ok"
exit "$rc"
