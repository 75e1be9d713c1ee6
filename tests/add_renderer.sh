#!/usr/bin/env bash
# Adding a renderer is its folder plus one row (README, "Adding a renderer"): in a scratch copy
# of the tree, add a renderer `fake` that way (a folder with its entry, an #include and a row in
# harness/renderers/registry.c), build, and check that the CLI, scene files, plans, job records
# and deps.sh know it, and that no other file changed.
set -uo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
work=$build/add-renderer
rm -rf "$work"
mkdir -p "$work/orig"
cp -r core model scene render harness cli tools ops examples scenes tests Makefile "$work/orig"/
# The tree to change, with the build's objects, so its build compiles only the new renderer.
. tests/scratch_tree.sh
scratch_tree "$work/tree" "$build" || { echo "add-renderer: copying the tree failed" >&2; exit 1; }
t=$work/tree
fail() { echo "add-renderer: $*" >&2; echo "add-renderer: 0 passed, 1 failed"; exit 1; }

mkdir -p "$t/harness/renderers/fake"
cat > "$t/harness/renderers/fake/fake.h" <<'H'
/* fake.h - a renderer that writes a grey image: proves adding one is a folder and a row.
 * Usage: fake_render_job(&job, &result). */
#ifndef REFLCHECK_FAKE_H
#define REFLCHECK_FAKE_H
#include "../renderer.h"
void fake_render_job(const renderer_job *j, renderer_result *r);
#endif
H
cat > "$t/harness/renderers/fake/fake.c" <<'C'
#include "fake.h"

#include <stdio.h>
#include <stdlib.h>

#include "exr.h"

void fake_render_job(const renderer_job *j, renderer_result *r)
{
    size_t n = (size_t)j->s->width * (size_t)j->s->height;
    float *grey = malloc(n * sizeof *grey);
    char err[512];
    if (grey == NULL) {
        renderer_fail(r, RUNNER_ERROR, "out of memory");
        return;
    }
    for (size_t i = 0; i < n; i++)
        grey[i] = 0.5f;
    exr_channel ch[3] = {{"R", grey}, {"G", grey}, {"B", grey}};
    snprintf(r->command, sizeof r->command, "fake (in process)");
    if (exr_write(j->exr, j->s->width, j->s->height, ch, 3, NULL, 0, err, sizeof err) != RC_OK)
        renderer_fail(r, RUNNER_ERROR, "%s", err);
    free(grey);
}
C
reg=$t/harness/renderers/registry.c
sed -i 's|^#include "raster/raster_render.h"$|&\n#include "fake/fake.h"|' "$reg"
sed -i 's|^static const renderer_row registry_rows\[\] = {$|&\n    {.name = "fake", .title = "a grey image", .version = "fake 1", .package = "fake-pkg", .render = fake_render_job},|' "$reg"
grep -q 'fake_render_job}' "$reg" || fail "the row was not added to registry.c; update this test"

changed=$(cd "$work" && diff -rq -x build orig tree | sed -e 's|^Files orig/\([^ ]*\) and .*|\1|' -e 's|^Only in tree/\(.*\): \(.*\)|\1/\2|')
[ "$(printf '%s\n' "$changed" | sort)" = "$(printf 'harness/renderers/fake\nharness/renderers/registry.c')" ] ||
    fail "files touched: $changed"
make -s -C "$t" BUILD=build build/reflcheck >/dev/null 2>"$work/build.log" || fail "build failed: see $work/build.log"
bin=$t/build/reflcheck

"$bin" renderers --json | grep -q '"name":[[:space:]]*"fake"' || fail "reflcheck renderers does not list fake"
"$bin" --help | tr '\n' ' ' | grep -Eq 'renderers: [a-z_, ]*fake' || fail "usage does not name fake"
DEPS_LIST=1 bash "$t/ops/deps.sh" | grep -qw 'fake-pkg' || fail "deps.sh does not install the row's package"
cat > "$work/s.yaml" <<'Y'
name: addr
image: {width: 8, height: 6}
camera: {eye: [0, 0, 4], target: [0, 0, 0], hfov: 40}
objects:
  - {shape: sphere, radius: 0.5, material: m}
materials:
  m: {albedo: [0.5, 0.5, 0.5]}
comparisons:
  - reference: fake
    role: validate
Y
"$bin" check "$work/s.yaml" >/dev/null || fail "a scene file cannot name fake"
"$bin" plan "$work/s.yaml" --out "$work/run" --bin "$bin" | grep -q -- '--renderer fake --role validate' ||
    fail "plan has no fake job"
(cd "$t" && build/reflcheck run ../s.yaml --renderer fake --role validate --out ../run --no-cache >/dev/null) ||
    fail "run --renderer fake failed"
grep -q '"renderer":[[:space:]]*"fake"' "$work/run/addr/fake-validate.json" || fail "no fake job record"
grep -q '"status":[[:space:]]*"ok"' "$work/run/addr/fake-validate.json" || fail "the fake job is not ok"
echo "add-renderer: files touched: $(printf '%s ' $changed)"
echo "add-renderer: 1 passed, 0 failed"
