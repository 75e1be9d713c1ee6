#!/usr/bin/env bash
# The nightly on a user's own scene, in a scratch copy of the tree that is a git repository of
# its own (so the real checkout is never touched), with every output at its default place:
#  1. a scene in a folder whose name holds a space and non-ASCII letters, given with the
#     documented command (bash ops/nightly.sh --small --no-sweep --no-screenshot --scenes
#     PATH, no environment settings) and as a one-per-line SCENES list, runs and compares (exit 0);
#  2. a space-separated SCENES whose words are not files is refused (exit 2) with one line
#     naming the word and the fix;
#  3. the runs leave `git status --porcelain` empty: run folders, cache, latest and the local
#     history (reports/local/history.jsonl) are generated output, the reference history
#     reports/history.jsonl is unchanged, and the report says which history its trends show;
#  4. --reference (REFERENCE=1) names a run the project's reference run on purpose: it, and only
#     it, appends to reports/history.jsonl.
# Usage: bash tests/nightly_paths.sh BUILD
set -uo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
work=$PWD/$build/paths-test
rm -rf "$work"
tree=$work/tree
mkdir -p "$tree"
pass=0
fail=0
ok() { pass=$((pass + 1)); echo "paths: $*"; }
bad() { fail=$((fail + 1)); echo "paths: FAILED: $*"; }

# The tree as it is in this checkout (uncommitted edits and new files that git does not ignore
# included), committed there.
git ls-files -z --cached --others --exclude-standard |
    while IFS= read -r -d '' f; do [ -f "$f" ] && printf '%s\0' "$f"; done |
    xargs -0 cp -p --parents -t "$tree" || { echo "paths: copying the tree failed" >&2; exit 1; }
(cd "$tree" && git init -q && git add -A && git -c user.name=t -c user.email=t@t commit -qm tree) ||
    { echo "paths: git init in the scratch tree failed" >&2; exit 1; }
dir="my scènes à tester"
mkdir -p "$tree/$dir"
# A cheap scene (raster against POV-Ray and the exact renderer, no Blender), under its own name.
cp scenes/d3d_scaled.yaml "$tree/$dir/d3d scaled é.yaml"
printf '%s/\n' "$dir" >> "$tree/.git/info/exclude" # the user's own scenes are not the project's
export BIN=$PWD/$build/reflcheck SMALL=1 NO_SWEEP=1 NO_SCREENSHOT=1
unset RUNS HISTORY LATEST CACHE SCENES REFERENCE REFERENCE_HISTORY RUN_ID SCHEDULER
cd "$tree" || exit 1
ref_before=$(sha256sum reports/history.jsonl)

# 1. With the documented command and its options alone, then as a SCENES list of one path per line.
env -u SMALL -u NO_SWEEP -u NO_SCREENSHOT bash ops/nightly.sh --small --no-sweep --no-screenshot \
    --scenes "$dir/d3d scaled é.yaml" > "$work/arg.log" 2>&1
st=$?
[ $st -eq 0 ] && [ -f "$(ls -d reports/runs/*/d3d_scaled | head -n1)/compare.json" ] &&
    [ ! -e "$(ls -d reports/runs/*/d3d_scaled | head -n1)/../screenshot.png" ] &&
    ok "the documented command on a scene path with a space and non-ASCII letters: exit 0, compared" ||
    bad "scene path as an argument: exit $st; see $work/arg.log"
RUN_ID=listed SCENES=$'\n'"$dir/d3d scaled é.yaml"$'\n' bash ops/nightly.sh > "$work/list.log" 2>&1
st=$?
[ $st -eq 0 ] && [ -f reports/runs/listed/d3d_scaled/compare.json ] &&
    ok "the same path in a one-per-line SCENES: exit 0, compared" ||
    bad "scene path in a SCENES list: exit $st; see $work/list.log"

# 2. Space-separated SCENES split the path: refused before anything runs, naming the word.
RUN_ID=split SCENES="$dir/d3d scaled é.yaml" bash ops/nightly.sh > "$work/split.log" 2>&1
st=$?
[ $st -eq 2 ] && [ "$(grep -c "scene 'my' is not a file.*one path per line in SCENES" "$work/split.log")" = 1 ] &&
    [ ! -e reports/runs/split ] && ok "a SCENES word that is not a file: exit 2, one line naming it and the fix" ||
    bad "split SCENES: exit $st (want 2), message: $(cat "$work/split.log")"

# 3. Nothing versioned changed; the local history has both runs; the report names its histories.
changed=$(git status --porcelain)
[ -z "$changed" ] && ok "git status --porcelain is empty after the user's runs" ||
    bad "the user's runs changed the tree: $changed"
[ "$ref_before" = "$(sha256sum reports/history.jsonl)" ] && ok "reports/history.jsonl unchanged" ||
    bad "reports/history.jsonl changed"
n_local=$(grep -c '"run_id"' reports/local/history.jsonl 2>/dev/null)
[ "$n_local" = 2 ] && ok "reports/local/history.jsonl holds the 2 runs" || bad "local history holds ${n_local:-no} runs (want 2)"
grep -q "reference runs\? from reports/history.jsonl" reports/runs/listed/index.html &&
    grep -q "2 runs of this history, reports/local/history.jsonl" reports/runs/listed/index.html &&
    ok "the report says its trends show the reference history, then the local one" ||
    bad "the report does not name the histories its trends show; see reports/runs/listed/index.html"

# 4. On purpose: REFERENCE=1 appends to the versioned history, and the local one is untouched.
bash ops/nightly.sh --run-id reference --reference "$dir/d3d scaled é.yaml" > "$work/ref.log" 2>&1
st=$?
[ $st -eq 0 ] && [ "$(git status --porcelain)" = " M reports/history.jsonl" ] &&
    [ "$(tail -n1 reports/history.jsonl | grep -c '"run_id":"reference"')" = 1 ] &&
    [ "$(grep -c '"run_id"' reports/local/history.jsonl)" = 2 ] &&
    ok "--reference: the run's line goes to reports/history.jsonl only" ||
    bad "--reference: exit $st, git status '$(git status --porcelain)'; see $work/ref.log"

echo "paths: $pass passed, $fail failed"
[ $fail -eq 0 ]
