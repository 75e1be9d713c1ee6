/* A cache key that cannot go stale (issue 21): a renderer's key covers the files the build says
 * its translator and the scene pipeline are made of and call (BUILD/key-sources, written by
 * harness/renderers/key_sources.py from the objects and their .d files), not a hand list.
 * In a scratch copy of the tree (REFLCHECK_DATA_DIR), one byte of model/formula.h (a header
 * povray.c includes) and then of model/d3d9client.c (a file povray.c calls) is changed: each time
 * the POV-Ray job renders again. A byte of Cycles' script, which POV-Ray does not use, leaves
 * the entry served. */
#include <limits.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>

#include "exr.h"
#include "fileio.h"
#include "jobs.h"
#include "runner.h"
#include "tmpdir.h"

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
}

/* Changes one byte of TREE/rel: its first 'e' becomes 'E'. */
static void edit_one_byte(const char *rel)
{
    char path[PATH_MAX];
    snprintf(path, sizeof path, "%s/tree/%s", tmpdir, rel);
    size_t n = 0;
    char *text = fileio_read_all(path, &n);
    assert_non_null(text);
    char *e = memchr(text, 'e', n);
    assert_non_null(e);
    *e = 'E';
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(text, 1, n, f), n);
    fclose(f);
    free(text);
}

static job_record run_povray(const char *yaml)
{
    char out[PATH_MAX], cache[PATH_MAX], err[1024];
    snprintf(out, sizeof out, "%s/out", tmpdir);
    snprintf(cache, sizeof cache, "%s/cache", tmpdir);
    job_spec j = {.scene_path = yaml,
                  .renderer = registry_find("povray"),
                  .role = ROLE_TWIN,
                  .out_dir = out,
                  .cache_dir = cache,
                  .threads = 1};
    job_record rec;
    assert_int_equal(job_run(&j, &rec, err, sizeof err), RC_OK);
    if (rec.status != RUNNER_OK)
        print_error("povray: %s\n", rec.message);
    assert_int_equal(rec.status, RUNNER_OK);
    return rec;
}

static void test_translator_header_edit_renders_again(void **state)
{
    (void)state;
    if (!runner_available("povray")) {
        skip();
        return;
    }
    char cmd[3 * PATH_MAX], yaml[PATH_MAX];
    /* The scratch tree: the folders the key lists name. */
    snprintf(cmd, sizeof cmd, "mkdir -p '%s/tree' && cp -r core model scene render harness '%s/tree/'", tmpdir, tmpdir);
    assert_int_equal(system(cmd), 0);
    snprintf(cmd, sizeof cmd, "%s/tree", tmpdir);
    setenv("REFLCHECK_DATA_DIR", cmd, 1);
    snprintf(yaml, sizeof yaml, "%s/key.yaml", tmpdir);
    write_text(yaml, "name: key\n"
                     "image: {width: 8, height: 6, supersample: 1, timeout: 120}\n"
                     "camera: {eye: [0, 1.2, 3], target: [0, 0, 0], hfov: 50}\n"
                     "lights:\n  - {type: point, position: [1, 3, 2], intensity: [20, 20, 20]}\n"
                     "materials:\n  m: {albedo: [0.8, 0.8, 0.8], model: d3d}\n"
                     "objects:\n  - {shape: quad, center: [0, 0, 0], size: [2, 2], material: m}\n"
                     "comparisons:\n  - reference: povray\n    role: twin\n"
                     "    thresholds: {rel_rms: {warn: 1e-3, fail: 2e-3, why: \"test\"}}\n");
    assert_int_equal(run_povray(yaml).cached, 0);
    assert_int_equal(run_povray(yaml).cached, 1);
    edit_one_byte("model/formula.h");
    assert_int_equal(run_povray(yaml).cached, 0);
    assert_int_equal(run_povray(yaml).cached, 1);
    edit_one_byte("model/d3d9client.c");
    assert_int_equal(run_povray(yaml).cached, 0);
    edit_one_byte("harness/renderers/cycles/cycles_render.py");
    assert_int_equal(run_povray(yaml).cached, 1);
    unsetenv("REFLCHECK_DATA_DIR");
}

/* The lists the build wrote: POV-Ray's names the files povray.c calls and includes, and its
 * own, and not Cycles' script; EEVEE's names Cycles' translation, which it renders. */
static void test_lists_follow_the_build(void **state)
{
    (void)state;
    const char *bin = getenv("REFLCHECK_BIN");
    char dir[PATH_MAX], path[PATH_MAX + 32];
    snprintf(dir, sizeof dir, "%s", bin != NULL ? bin : "build/reflcheck");
    char *slash = strrchr(dir, '/');
    assert_non_null(slash);
    *slash = '\0';
    snprintf(path, sizeof path, "%s/key-sources/povray.list", dir);
    char *pov = fileio_read_all(path, NULL);
    assert_non_null(pov);
    const char *want[] = {"harness/renderers/povray/povray.c\n",
                          "harness/renderers/povray/povray.h\n",
                          "model/formula.h\n",
                          "model/d3d9client.c\n",
                          "model/scene.c\n",
                          "harness/jobs.c\n"};
    for (size_t i = 0; i < sizeof want / sizeof want[0]; i++)
        assert_non_null(strstr(pov, want[i]));
    assert_null(strstr(pov, "cycles"));
    free(pov);
    snprintf(path, sizeof path, "%s/key-sources/eevee.list", dir);
    char *eevee = fileio_read_all(path, NULL);
    assert_non_null(eevee);
    assert_non_null(strstr(eevee, "harness/renderers/cycles/cycles.c\n"));
    assert_non_null(strstr(eevee, "harness/renderers/cycles/cycles_render.py\n"));
    assert_non_null(strstr(eevee, "harness/renderers/eevee/eevee_render.py\n"));
    free(eevee);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_lists_follow_the_build),
        cmocka_unit_test(test_translator_header_edit_renders_again),
    };
    return cmocka_run_group_tests(tests, tmpdir_setup, tmpdir_teardown);
}
