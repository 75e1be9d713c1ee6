#!/usr/bin/env bash
# image.samples auto in the real Blender Cycles (docs/samples.md, cycles_samples.h):
#  - a render a z-test judges, with no bias stated, is refused at once, naming the scene's line
#    and the fix; so is one a bias gate in standard errors judges, bias stated or not;
#  - with a bias stated, a 16-spp pilot, then the count the rule gives from the pilot's own
#    per-value noise (pilot_pixel_q) and the z-test's target: ceil(16 (pilot_pixel_q /
#    z_target)^2) > 16, recomputed here from the record, reached in steps of powers of two;
#    the render reaches that noise within the estimate's spread (two seeds, a few hundred
#    values: 30 %).
# The scene is ct_env's (two Cook-Torrance spheres under the courtyard), small, its validate
# judged by a z-test; b = 0.8 makes the rule ask a few dozen samples of this noisy render.
set -uo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
bin=$build/reflcheck
if ! command -v blender > /dev/null; then
    echo "cycles_auto: SKIP (blender not installed)"
    exit 0
fi
work=$(mktemp -d "${TMPDIR:-/tmp}/reflcheck-auto.XXXXXX") || exit 1
trap '[ -n "${KEEP:-}" ] || rm -rf "$work"' EXIT
fails=0 passes=0
ok() { passes=$((passes + 1)); echo "ok: $*"; }
bad() { fails=$((fails + 1)); echo "FAIL: $*"; }

# scene NAME SAMPLES THRESHOLDS: ct_env at 48 x 24, its environment by absolute path.
scene() {
    sed -n '/^name:/,/^comparisons:/p' scenes/ct_env.yaml |
        sed -e "s|^name: .*|name: $1|" -e "s|^image: .*|image: {width: 48, height: 24, supersample: 2, samples: $2}|" \
            -e "s|envs/|$PWD/scenes/envs/|g" > "$work/$1.yaml"
    printf '  - reference: cycles\n    role: validate\n    thresholds:\n      %s\n' "$3" >> "$work/$1.yaml"
}
field() { python3 -c "import json,sys; j=json.load(open(sys.argv[1])); print(eval(sys.argv[2]))" "$@"; }

z='z_fail_share: {warn: 0.01, fail: 0.02, why: "a test gate"}'
scene refuse auto "$z"
line=$(grep -n '^image:' "$work/refuse.yaml" | cut -d: -f1)
"$bin" run "$work/refuse.yaml" --renderer cycles --small -o "$work/out" --no-cache > /dev/null 2>&1
msg=$(field "$work/out/refuse/cycles-validate.json" 'j["message"]')
want="$work/refuse.yaml:$line: image.samples auto: comparisons[0] raster/validate z_fail_share is a z-test with no bias size; write image.samples: {auto: true, bias: B"
case $msg in "$want"*) ok "no bias stated: refused, naming line $line" ;; *) bad "no bias stated: '$msg'" ;; esac

scene biasgate '{auto: true, bias: 0.8, why: "a test"}' 'bias.z_max: {warn: 4, fail: 5, why: "a test gate"}'
"$bin" run "$work/biasgate.yaml" --renderer cycles --small -o "$work/out" --no-cache > /dev/null 2>&1
msg=$(field "$work/out/biasgate/cycles-validate.json" 'j["message"]')
case $msg in *"comparisons[0] raster/validate bias.z_max counts standard errors"*) ok "bias gate: refused" ;;
    *) bad "bias gate: '$msg'" ;; esac

scene stated '{auto: true, bias: 0.8, why: "a test"}' "$z"
if "$bin" run "$work/stated.yaml" --renderer cycles --small -o "$work/out" --no-cache > /dev/null 2>&1; then
    rec=$work/out/stated/cycles-validate.json
    # The pilot asks n0 = ceil(pilot (pilot_pixel_q / z_target)^2) > 16; the render steps up by
    # powers of two (at most 4 x a step), each predicted from the last: a power of two over 16.
    read -r n ask q zt from < <(field "$rec" '"%d %d %g %g %s" % (j["samples"], -(-j["noise"]["pilot_samples"] * (j["noise"]["pilot_pixel_q"] / j["noise"]["z_target"]) ** 2 // 1), j["noise"]["pixel_q"], j["noise"]["z_target"], j["noise"]["samples_from"])')
    if [ "$from" = auto ] && [ "$ask" -gt 16 ] && [ "$n" -gt 16 ] && [ $((n & (n - 1))) -eq 0 ]; then
        ok "stated bias: the pilot asked $ask, $n samples rendered"
    else
        bad "stated bias: the pilot asked $ask, $n samples rendered (from $from)"
    fi
    if python3 -c "import sys; sys.exit(0 if float(sys.argv[1]) <= 1.3 * float(sys.argv[2]) else 1)" "$q" "$zt"; then
        ok "stated bias: pixel_q $q reached against $zt"
    else
        bad "stated bias: pixel_q $q against $zt"
    fi
else
    bad "stated bias: the render failed: $(field "$work/out/stated/cycles-validate.json" 'j["message"]')"
fi
echo "$passes passed, $fails failed"
[ "$fails" -eq 0 ]
