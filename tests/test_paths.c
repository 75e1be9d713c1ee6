/* Bad input, third round (issue 20): a renderer that is there but broken, paths a renderer
 * cannot take (a space in the cache folder, an environment and a texture named with non-ASCII
 * and a space), runs from another working folder, and a damaged cache entry.
 * - A broken install (--version crashes, exits 127 as a missing library does, or prints no
 *   version) is a failed job with the reason, never "not installed": stand-in scripts on PATH.
 * - The real POV-Ray and Blender render a 16 x 12 scene whose cache folder, environment and
 *   texture have such names; each image is held against our rasterizer's of the same scene.
 * - `reflcheck run --renderer cycles` and `--renderer eevee` work from a folder that is not the
 *   source tree.
 * - A truncated cached EXR is rendered again, and the record says so.
 * Everything is written under the scratch folder (tests/tmpdir.h). */
#include <limits.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include <cmocka.h>

#include <cJSON.h>

#include "exr.h"
#include "fileio.h"
#include "jobs.h"
#include "runner.h"
#include "tmpdir.h"

/* stdlib.h declares realpath only under XSI; the project builds at the POSIX level. */
char *realpath(const char *restrict path, char *restrict resolved);

static char saved_path[8192];

/* A stand-in NAME in TMPDIR/bin, first on PATH, with the given shell body. */
static void stand_in(const char *name, const char *body)
{
    char dir[PATH_MAX], path[PATH_MAX + 64], p[PATH_MAX + 8300];
    snprintf(dir, sizeof dir, "%s/bin", tmpdir);
    mkdir(dir, 0755);
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fprintf(f, "#!/bin/sh\n%s\n", body);
    fclose(f);
    chmod(path, 0755);
    snprintf(p, sizeof p, "%s:%s", dir, saved_path);
    setenv("PATH", p, 1);
}

static void restore_path(void)
{
    char path[PATH_MAX];
    snprintf(path, sizeof path, "%s/bin/povray", tmpdir);
    unlink(path);
    setenv("PATH", saved_path, 1);
}

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
}

/* An RGB EXR of w x h: value v, with a ramp along x when ramp is set (so a texture's lookup
 * shows in the image). */
static void write_exr(const char *path, int w, int h, float v, int ramp)
{
    size_t n = (size_t)w * (size_t)h;
    float *p = malloc(3 * n * sizeof *p);
    assert_non_null(p);
    for (size_t i = 0; i < n; i++) {
        float x = ramp ? (float)(i % (size_t)w) / (float)w : 0.0f;
        p[i] = v + 0.5f * x;
        p[n + i] = v;
        p[2 * n + i] = v + 0.25f * x;
    }
    exr_channel ch[3] = {{"R", p}, {"G", p + n}, {"B", p + 2 * n}};
    char err[512];
    assert_int_equal(exr_write(path, w, h, ch, 3, NULL, 0, err, sizeof err), RC_OK);
    free(p);
}

/* TMPDIR/<folder>/paths.yaml: a textured quad and an environment image whose names hold a
 * space and non-ASCII bytes; returns the scene's path. */
static const char *odd_scene(const char *folder)
{
    static char yaml_path[PATH_MAX];
    char dir[PATH_MAX], p[PATH_MAX + 32];
    snprintf(dir, sizeof dir, "%s/%s", tmpdir, folder);
    mkdir(dir, 0755);
    snprintf(p, sizeof p, "%s/\xc3\xbc \"env\".exr", dir); /* 'ü "env".exr' */
    write_exr(p, 16, 8, 0.3f, 0);
    snprintf(p, sizeof p, "%s/t\xc3\xa9x ture.exr", dir); /* "téx ture.exr" */
    write_exr(p, 8, 8, 0.2f, 1);
    snprintf(yaml_path, sizeof yaml_path, "%s/paths.yaml", dir);
    write_text(yaml_path,
               "name: paths\n"
               "image: {width: 16, height: 12, supersample: 1, samples: 16, timeout: 300}\n"
               "camera: {eye: [0, 1.2, 3], target: [0, 0, 0], hfov: 50}\n"
               "environment: {image: \"\xc3\xbc \\\"env\\\".exr\"}\n"
               "lights:\n  - {type: point, position: [1, 3, 2], intensity: [20, 20, 20]}\n"
               "materials:\n  tex: {albedo: [1, 1, 1], model: d3d, texture: {diffuse: \"t\xc3\xa9x ture.exr\"}}\n"
               "objects:\n  - {shape: quad, center: [0, 0, 0], size: [2, 2], material: tex}\n"
               "comparisons:\n  - reference: povray\n    role: twin\n"
               "    thresholds: {rel_rms: {warn: 1e-3, fail: 2e-3, why: \"test\"}}\n");
    return yaml_path;
}

static job_record run(const char *yaml_path, const char *renderer, const char *out, const char *cache)
{
    job_spec j = {.scene_path = yaml_path,
                  .renderer = registry_find(renderer),
                  .role = ROLE_TWIN,
                  .variant = JOB_FULL,
                  .out_dir = out,
                  .cache_dir = cache,
                  .threads = 1,
                  .seeds = 1};
    job_record rec;
    char err[1024];
    assert_int_equal(job_run(&j, &rec, err, sizeof err), RC_OK);
    return rec;
}

/* The mean of channel R of an EXR over its pixels. */
static double mean_r(const char *path)
{
    exr_image img;
    char err[512];
    assert_int_equal(exr_read(path, &img, err, sizeof err), RC_OK);
    const float *r = exr_image_channel(&img, "R");
    assert_non_null(r);
    double sum = 0.0;
    for (int i = 0; i < img.width * img.height; i++)
        sum += r[i];
    double m = sum / (img.width * img.height);
    exr_image_free(&img);
    return m;
}

/* ---- item 1: installed but broken is a failure, not a skip ---- */

static void test_version_crash_is_a_failure(void **state)
{
    (void)state;
    stand_in("povray", "kill -SEGV $$");
    char v[256], why[400];
    assert_int_equal(runner_version("povray", v, sizeof v, why, sizeof why), RUNNER_CRASHED);
    assert_non_null(strstr(why, "signal 11"));
    job_record r = run(odd_scene("crash"), "povray", tmpdir, NULL);
    restore_path();
    assert_int_equal(r.status, RUNNER_CRASHED);
    assert_int_equal(job_exit_status(RC_OK, &r), 1);
    assert_null(strstr(r.message, "not installed"));
    assert_non_null(strstr(r.message, "povray --version crashed (signal 11)"));
    assert_non_null(strstr(r.message, "apt-get install --reinstall povray"));
}

static void test_version_missing_library_is_a_failure(void **state)
{
    (void)state;
    /* What the dynamic loader prints and exits with when a library is gone. */
    stand_in("povray", "echo 'povray: error while loading shared libraries: libboost_thread.so.1.74.0: cannot "
                       "open shared object file: No such file or directory' >&2; exit 127");
    job_record r = run(odd_scene("lib"), "povray", tmpdir, NULL);
    char v[256], why[400];
    runner_status vs = runner_version("povray", v, sizeof v, why, sizeof why);
    restore_path();
    assert_int_equal(vs, RUNNER_FAILED);
    assert_int_equal(r.status, RUNNER_FAILED);
    assert_int_equal(job_exit_status(RC_OK, &r), 1);
    assert_non_null(strstr(r.message, "povray --version failed (exit status 127)"));
    assert_non_null(strstr(r.message, "error while loading shared libraries: libboost_thread"));
}

static void test_version_without_version_line_is_a_failure(void **state)
{
    (void)state;
    stand_in("povray", "echo 'hello'; exit 0");
    char v[256], why[400];
    runner_status vs = runner_version("povray", v, sizeof v, why, sizeof why);
    restore_path();
    assert_int_equal(vs, RUNNER_FAILED);
    assert_non_null(strstr(why, "no version line"));
    assert_non_null(strstr(why, "hello"));
}

static void test_absent_is_not_installed(void **state)
{
    (void)state;
    char v[256], why[400];
    setenv("PATH", "/nonexistent-reflcheck", 1);
    job_record r = run(odd_scene("absent"), "povray", tmpdir, NULL);
    runner_status vs = runner_version("povray", v, sizeof v, why, sizeof why);
    /* On PATH but not executable: not a program, so not installed either. */
    char path[PATH_MAX];
    stand_in("povray", "exit 0");
    snprintf(path, sizeof path, "%s/bin/povray", tmpdir);
    chmod(path, 0644);
    char only[PATH_MAX];
    snprintf(only, sizeof only, "%s/bin", tmpdir);
    setenv("PATH", only, 1); /* the real one further on must not answer instead */
    runner_status vs2 = runner_version("povray", v, sizeof v, why, sizeof why);
    restore_path();
    assert_int_equal(vs, RUNNER_MISSING);
    assert_int_equal(vs2, RUNNER_MISSING);
    assert_int_equal(r.status, RUNNER_MISSING);
    assert_int_equal(job_exit_status(RC_OK, &r), 0);
    assert_non_null(strstr(r.message, "is not installed"));
}

/* ---- items 12, 13: paths with spaces and non-ASCII, in the real renderers ---- */

/* The renderer's image of the odd scene, cached in a folder with a space and non-ASCII, against
 * the rasterizer's: the mean of R within tol (relative). */
static void odd_paths_render(const char *renderer, double tol)
{
    if (!runner_available(renderer[0] == 'p' ? "povray" : "blender")) {
        skip();
        return;
    }
    const char *yaml_path = odd_scene("odd");
    char out[PATH_MAX], cache[PATH_MAX];
    snprintf(out, sizeof out, "%s/out dir", tmpdir);
    snprintf(cache, sizeof cache, "%s/cache d\xc3\xafr 'q' $x", tmpdir); /* "cache dïr 'q' $x" */
    job_record ref = run(yaml_path, "raster", out, NULL);
    assert_int_equal(ref.status, RUNNER_OK);
    job_record r = run(yaml_path, renderer, out, cache);
    if (r.status != RUNNER_OK)
        print_error("%s: %s\n", renderer, r.message);
    assert_int_equal(r.status, RUNNER_OK);
    double a = mean_r(r.exr), b = mean_r(ref.exr);
    print_message("%s mean R %.5f, raster %.5f\n", renderer, a, b);
    assert_true(b > 0.05);
    assert_true(fabs(a - b) <= tol * b);
}

/* POV-Ray writes half floats, and its twin is exact: 1% is far above its error. */
static void test_odd_paths_povray(void **state)
{
    (void)state;
    odd_paths_render("povray", 0.01);
}

/* Cycles with 16 samples, one seed, at 16 x 12: its mean is within a few per cent. */
static void test_odd_paths_cycles(void **state)
{
    (void)state;
    odd_paths_render("cycles", 0.08);
}

/* A relative --cache: the texture path in Cycles' job is absolute all the same, so a Blender
 * worker, which runs in another folder, finds it. */
static void test_cycles_texture_path_is_absolute(void **state)
{
    (void)state;
    if (!runner_available("blender")) {
        skip();
        return;
    }
    const char *yaml_path = odd_scene("rel");
    char here[PATH_MAX], abs_scene[PATH_MAX];
    assert_non_null(realpath(yaml_path, abs_scene));
    assert_non_null(getcwd(here, sizeof here));
    assert_int_equal(chdir(tmpdir), 0);
    job_record r = run(abs_scene, "cycles", "rel-out", "rel cache");
    char *text = NULL;
    char cmd[PATH_MAX];
    snprintf(cmd, sizeof cmd, "cat 'rel cache'/*/job.json > rel-job.json");
    int rc = system(cmd);
    text = fileio_read_all("rel-job.json", NULL);
    assert_int_equal(chdir(here), 0);
    assert_int_equal(r.status, RUNNER_OK);
    assert_int_equal(rc, 0);
    assert_non_null(text);
    const char *t = strstr(text, "\"texture\"");
    assert_non_null(t);
    t = strchr(t + 9, '"');
    assert_non_null(t);
    assert_int_equal(t[1], '/');
    free(text);
}

/* ---- item 16: from another working folder ---- */

/* `reflcheck run SCENE --renderer R --small` in TMPDIR/elsewhere; the record's status. */
static void run_elsewhere(const char *scene_rel, const char *renderer, char *status, size_t len)
{
    char bin[PATH_MAX], yaml_path[PATH_MAX], here[PATH_MAX], dir[PATH_MAX], cmd[4 * PATH_MAX];
    assert_non_null(realpath(getenv("REFLCHECK_BIN") ? getenv("REFLCHECK_BIN") : "build/reflcheck", bin));
    assert_non_null(realpath(scene_rel, yaml_path));
    assert_non_null(getcwd(here, sizeof here));
    snprintf(dir, sizeof dir, "%s/elsewhere-%s", tmpdir, renderer);
    mkdir(dir, 0755);
    assert_int_equal(chdir(dir), 0);
    snprintf(cmd, sizeof cmd, "'%s' run '%s' --renderer %s --role twin --small --out out --no-cache > run.txt 2>&1",
             bin, yaml_path, renderer);
    int rc = system(cmd);
    char rec[PATH_MAX + 64], *name = strrchr(yaml_path, '/') + 1;
    snprintf(rec, sizeof rec, "out/%.*s/%s-twin.json", (int)(strlen(name) - 5), name, renderer);
    char *text = fileio_read_all(rec, NULL);
    assert_int_equal(chdir(here), 0);
    status[0] = '\0';
    cJSON *doc = text != NULL ? cJSON_Parse(text) : NULL;
    const cJSON *st = cJSON_GetObjectItemCaseSensitive(doc, "status");
    const cJSON *msg = cJSON_GetObjectItemCaseSensitive(doc, "message");
    if (cJSON_IsString(st))
        snprintf(status, len, "%s", st->valuestring);
    if (cJSON_IsString(msg) && msg->valuestring[0] != '\0')
        print_message("%s: %s\n", renderer, msg->valuestring);
    cJSON_Delete(doc);
    free(text);
    assert_true(WIFEXITED(rc));
    assert_int_equal(WEXITSTATUS(rc), 0);
}

static void test_cycles_from_another_folder(void **state)
{
    (void)state;
    if (!runner_available("blender")) {
        skip();
        return;
    }
    char status[32];
    run_elsewhere("scenes/lambert_calibration.yaml", "cycles", status, sizeof status);
    assert_string_equal(status, "ok");
}

static void test_eevee_from_another_folder(void **state)
{
    (void)state;
    if (!runner_available("blender") || !runner_available("xvfb-run")) {
        skip();
        return;
    }
    char status[32];
    run_elsewhere("scenes/eevee_calibration.yaml", "eevee", status, sizeof status);
    assert_string_equal(status, "ok");
}

/* ---- a damaged cache entry ---- */

static void test_damaged_cache_entry_renders_again(void **state)
{
    (void)state;
    const char *yaml_path = odd_scene("damaged");
    char out[PATH_MAX], cache[PATH_MAX], entry[PATH_MAX + 64];
    snprintf(out, sizeof out, "%s/damaged-out", tmpdir);
    snprintf(cache, sizeof cache, "%s/damaged-cache", tmpdir);
    job_record first = run(yaml_path, "raster", out, cache);
    assert_int_equal(first.status, RUNNER_OK);
    job_record again = run(yaml_path, "raster", out, cache);
    assert_int_equal(again.cached, 1);
    /* The record names the key: the entry is CACHE/<key>/out.exr. */
    char *text = fileio_read_all(again.record, NULL);
    assert_non_null(text);
    cJSON *doc = cJSON_Parse(text);
    const cJSON *key = cJSON_GetObjectItemCaseSensitive(doc, "key");
    assert_true(cJSON_IsString(key));
    snprintf(entry, sizeof entry, "%s/%s/out.exr", cache, key->valuestring);
    cJSON_Delete(doc);
    free(text);
    struct stat st;
    assert_int_equal(stat(entry, &st), 0);
    assert_int_equal(truncate(entry, st.st_size / 2), 0);
    job_record third = run(yaml_path, "raster", out, cache);
    assert_int_equal(third.status, RUNNER_OK);
    assert_int_equal(third.cached, 0);
    assert_non_null(strstr(third.message, "rendered again: the cache entry"));
    assert_non_null(strstr(third.message, "damaged"));
    exr_image img;
    char err[512];
    assert_int_equal(exr_read(third.exr, &img, err, sizeof err), RC_OK);
    assert_int_equal(img.width, 16);
    exr_image_free(&img);
    assert_int_equal(stat(entry, &st), 0);
    assert_int_equal(exr_read(entry, &img, err, sizeof err), RC_OK);
    exr_image_free(&img);
    job_record fourth = run(yaml_path, "raster", out, cache);
    assert_int_equal(fourth.cached, 1);
}

/* A --cache longer than a job's path buffers is refused with nothing written; it was cut
 * instead, and the cut path named another folder. */
static void test_long_cache_folder_refused(void **state)
{
    (void)state;
    const char *yaml_path = odd_scene("long");
    char cache[4200];
    int n = snprintf(cache, sizeof cache, "%s/long", tmpdir);
    while (n < 4000)
        n += snprintf(cache + n, sizeof cache - (size_t)n, "/%s", "dddddddddddddddddddddddddddddddddddddddddddddddddd");
    job_spec j = {.scene_path = yaml_path,
                  .renderer = registry_model(),
                  .role = ROLE_TWIN,
                  .out_dir = tmpdir,
                  .cache_dir = cache};
    job_record rec;
    char err[1024], cut[1100];
    assert_int_equal(job_run(&j, &rec, err, sizeof err), RC_ERR_RANGE);
    assert_int_equal(job_exit_status(RC_ERR_RANGE, &rec), 2);
    assert_non_null(strstr(err, "--cache of"));
    assert_non_null(strstr(err, "use a shorter folder"));
    snprintf(cut, sizeof cut, "%s/long/%s", tmpdir, "dddddddddddddddddddddddddddddddddddddddddddddddddd");
    assert_int_not_equal(access(cut, F_OK), 0);
}

int main(void)
{
    snprintf(saved_path, sizeof saved_path, "%s", getenv("PATH") ? getenv("PATH") : "");
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_version_crash_is_a_failure),
        cmocka_unit_test(test_version_missing_library_is_a_failure),
        cmocka_unit_test(test_version_without_version_line_is_a_failure),
        cmocka_unit_test(test_absent_is_not_installed),
        cmocka_unit_test(test_damaged_cache_entry_renders_again),
        cmocka_unit_test(test_long_cache_folder_refused),
        cmocka_unit_test(test_odd_paths_povray),
        cmocka_unit_test(test_odd_paths_cycles),
        cmocka_unit_test(test_cycles_texture_path_is_absolute),
        cmocka_unit_test(test_cycles_from_another_folder),
        cmocka_unit_test(test_eevee_from_another_folder),
    };
    return cmocka_run_group_tests(tests, tmpdir_setup, tmpdir_teardown);
}
