#!/usr/bin/env bash
# A Cycles job's set-up, in the real Blender (docs/samples.md, "Where a Cycles job's CPU goes").
# The seeds share one session (cycles_render.py, persistent data):
#  - the second seed's render reuses the first's set-up: the log builds the world's importance
#    map and loads the environment once for two seeds (twice before);
#  - each seed still renders its own seed: the two-seed image's mean and variance equal those
#    worked out here from two one-seed renders in fresh Blenders (the mean (a + b) / 2, the
#    variance of the mean (a - b)^2 / 4), within float rounding; a session that rendered the
#    old seed again gives a variance of 0 and a mean of seed 0's image;
#  - a worker's next job, after a job that kept its session, starts clean: its image equals a
#    fresh Blender's in every pixel and channel, and it loads its environment itself.
# The scene is ct_env's validate (the courtyard, light-sampled), small, 16 spp.
# The world's importance map is as wide as the environment's detail: ct_env's courtyard image's
# width; ct_cube's 64 x 64 cube map's 4 x 64 = 256, not its 4096-wide conversion's.
# Usage: bash tests/cycles_setup.sh BUILD
set -uo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
bin=$build/reflcheck
if ! command -v blender > /dev/null; then
    echo "cycles_setup: SKIP (blender not installed)"
    exit 0
fi
work=$(mktemp -d "${TMPDIR:-/tmp}/reflcheck-setup.XXXXXX") || exit 1
trap '[ -n "${KEEP:-}" ] || rm -rf "$work"' EXIT
fails=0 passes=0
ok() { passes=$((passes + 1)); echo "ok: $*"; }
bad() { fails=$((fails + 1)); echo "FAIL: $*"; }

# run TAG [OPTION...]: ct_env's Cycles validate, small, one thread, into $work/TAG.
run() {
    local tag=$1
    shift
    "$bin" run scenes/ct_env.yaml --renderer cycles --role validate --small --no-cache --threads 1 \
        --samples 16 -o "$work/$tag" "$@" > /dev/null 2>&1
}
exr() { echo "$work/$1/ct_env/cycles-validate.exr"; }
log() { echo "$work/$1/ct_env/cycles-validate.log"; }

run two --seeds 2 --seed 0 && run s0 --seeds 1 --seed 0 && run s1 --seeds 1 --seed 1 ||
    bad "a render failed: see $work (KEEP=1 keeps it)"

n=$(grep -c 'Updating Lights | Importance map' "$(log two)")
l=$(grep -c 'Updating Images | Loading courtyard' "$(log two)")
if [ "$n" -eq 1 ] && [ "$l" -eq 1 ]; then
    ok "two seeds: one importance map, one environment load"
else
    bad "two seeds: $n importance maps, $l environment loads (want 1 and 1)"
fi

# The layers without the var. ones, in the file's order; then the same names with var.
chans=$(oiiotool --info -v "$(exr s0)" | sed -n 's/^ *channel list: //p' | tr -d ' ')
vchans=$(echo "$chans" | tr ',' '\n' | sed 's/^/var./' | paste -sd, -)
oiiotool "$(exr two)" --ch "$chans" -o "$work/mean.exr" && oiiotool "$(exr two)" --ch "$vchans" --chnames "$chans" -o "$work/var.exr" &&
    oiiotool "$(exr s0)" "$(exr s1)" --add --mulc 0.5 -o "$work/mean_want.exr" &&
    oiiotool "$(exr s0)" "$(exr s1)" --sub --powc 2 --mulc 0.25 -o "$work/var_want.exr" ||
    bad "oiiotool could not split the images"
# Float rounding of a sum of two: a few ulps of values up to ~10; the bug's error is the whole
# seed-to-seed difference (0.1 and more in a 16-spp render).
for what in mean var; do
    if oiiotool --fail 1e-4 --warn 1e-5 "$work/$what.exr" "$work/${what}_want.exr" --diff > "$work/$what.diff" 2>&1; then
        ok "two seeds: the $what equals the one-seed renders' (max error $(sed -n 's/^ *Max error *= *//p' "$work/$what.diff" | grep . || echo 0))"
    else
        bad "two seeds: the $what differs from the one-seed renders': $(sed -n 's/^ *Max error *= *//p' "$work/$what.diff")"
    fi
done

# A worker: the two-seed job, then the one-seed job; the second equals the fresh Blender's.
if /usr/bin/python3 - "$work" "$bin" <<'PY'; then
import os, subprocess, sys
sys.path.insert(0, 'harness/renderers/cycles')
from worker_pool import WorkerPool

work, bin_path = sys.argv[1], sys.argv[2]
with WorkerPool(1, log_dir=work) as pool:
    env = dict(os.environ, **pool.env())
    for tag, seeds in (('wa', '2'), ('wb', '1')):
        subprocess.run([bin_path, 'run', 'scenes/ct_env.yaml', '--renderer', 'cycles', '--role', 'validate', '--small',
                        '--no-cache', '--threads', '1', '--samples', '16', '-o', os.path.join(work, tag), '--seeds',
                        seeds, '--seed', '1'], capture_output=True, env=env)
a = os.path.join(work, 'wb', 'ct_env', 'cycles-validate.exr')
b = os.path.join(work, 's1', 'ct_env', 'cycles-validate.exr')
r = subprocess.run(['oiiotool', '--fail', '0', '--warn', '0', a, b, '--diff'], capture_output=True, text=True)
log = open(os.path.join(work, 'wb', 'ct_env', 'cycles-validate.log')).read()
sys.exit(0 if r.returncode == 0 and '(blender worker' in open(a[:-4] + '.json').read()
         and 'Loading courtyard' in log else 1)
PY
    ok "a worker's job after a kept session equals a fresh Blender's and loads its own environment"
else
    bad "the worker's job after a kept session differs from a fresh Blender's, or did not load its environment"
fi
# The importance map's width, from the log's last line.
cw=$(oiiotool --info scenes/envs/courtyard.exr | sed -n 's/.*: *\([0-9]*\) x.*/\1/p')
map=$(sed -n 's/^reflcheck-cycles: .*, world map \([0-9]*\)$/\1/p' "$(log two)")
[ "$map" = "$cw" ] && ok "ct_env: world map $map, the image's width" || bad "ct_env: world map '$map', want $cw"
"$bin" run scenes/ct_cube.yaml --renderer cycles --role validate --small --no-cache --threads 1 --samples 16 \
    -o "$work/cube" > /dev/null 2>&1
map=$(sed -n 's/^reflcheck-cycles: .*, world map \([0-9]*\)$/\1/p' "$work/cube/ct_cube/cycles-validate.log")
[ "$map" = 256 ] && ok "ct_cube: world map 256, its cube's 4 x 64" || bad "ct_cube: world map '$map', want 256"
echo "$passes passed, $fails failed"
[ "$fails" -eq 0 ]
