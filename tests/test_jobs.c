/* Render jobs when a renderer is missing, fails, crashes, hangs or writes garbage: each is a
 * record with that status and a message, never an abort, and results already written stay.
 * Broken renderers are small scripts put first on PATH in place of povray/blender. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>

#include "fileio.h"
#include "jobs.h"

static char saved_path[8192];
static const char *bin_dir = "/tmp/reflcheck-test-jobs-bin";
static const char *out_dir = "/tmp/reflcheck-test-jobs-out";

/* Installs a fake program NAME on PATH with the given shell body. */
static void fake(const char *name, const char *body)
{
    char path[512];
    mkdir(bin_dir, 0755);
    snprintf(path, sizeof path, "%s/%s", bin_dir, name);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    /* `--version` answers like the real program, so the version probe passes. */
    fprintf(f, "#!/bin/sh\ncase \"$1\" in --version) echo 'POV-Ray 3.7.0.10.fake'; echo 'Blender 3.4.1'; exit 0;; esac\n%s\n",
            body);
    fclose(f);
    chmod(path, 0755);
}

static int setup(void **state)
{
    (void)state;
    snprintf(saved_path, sizeof saved_path, "%s", getenv("PATH") ? getenv("PATH") : "");
    char p[8400];
    snprintf(p, sizeof p, "%s:%s", bin_dir, saved_path);
    setenv("PATH", p, 1);
    return system("rm -rf /tmp/reflcheck-test-jobs-bin /tmp/reflcheck-test-jobs-out") == -1;
}

static int teardown(void **state)
{
    (void)state;
    setenv("PATH", saved_path, 1);
    return 0;
}

static job_record run_job(renderer_id r, double timeout)
{
    job_spec j = {.scene_path = "scenes/d3d_spot.yaml", .renderer = r, .role = ROLE_TWIN, .variant = JOB_SMALL,
                  .out_dir = out_dir, .cache_dir = NULL, .timeout_s = timeout, .threads = 1};
    job_record rec;
    char err[1024];
    assert_int_equal(job_run(&j, &rec, err, sizeof err), RC_OK);
    /* Whatever happened, the record is on disk and says it. */
    char *text = fileio_read_all(rec.record, NULL);
    assert_non_null(text);
    assert_non_null(strstr(text, runner_status_name(rec.status)));
    free(text);
    return rec;
}

static void test_renderer_fails(void **state)
{
    (void)state;
    fake("povray", "echo 'Parse Error: broken on purpose' >&2; exit 3");
    job_record r = run_job(RENDERER_POVRAY, 30);
    assert_int_equal(r.status, RUNNER_FAILED);
    assert_non_null(strstr(r.message, "povray failed"));
    assert_non_null(strstr(r.message, ".log"));
}

static void test_renderer_crashes(void **state)
{
    (void)state;
    fake("povray", "kill -SEGV $$");
    job_record r = run_job(RENDERER_POVRAY, 30);
    assert_int_equal(r.status, RUNNER_CRASHED);
}

static void test_renderer_hangs(void **state)
{
    (void)state;
    fake("blender", "sleep 60");
    job_record r = run_job(RENDERER_CYCLES, 0.5);
    assert_int_equal(r.status, RUNNER_TIMEOUT);
    assert_true(r.wall_s < 10.0);
}

static void test_renderer_writes_garbage(void **state)
{
    (void)state;
    /* Exits 0 but the "EXR" it names is text: an unreadable image, recorded as a failure. */
    fake("povray", "for a in \"$@\"; do case \"$a\" in +O*) echo 'not an exr' > \"${a#+O}\";; esac; done; exit 0");
    job_record r = run_job(RENDERER_POVRAY, 30);
    assert_int_equal(r.status, RUNNER_FAILED);
    assert_non_null(strstr(r.message, "unreadable"));
}

static void test_renderer_missing_and_results_kept(void **state)
{
    (void)state;
    /* A result written before: the raster job. Then blender is missing from PATH entirely. */
    job_record ok = run_job(RENDERER_RASTER, 30);
    assert_int_equal(ok.status, RUNNER_OK);
    setenv("PATH", "/usr/local/nonexistent", 1);
    job_record r = run_job(RENDERER_CYCLES, 30);
    char p[8400];
    snprintf(p, sizeof p, "%s:%s", bin_dir, saved_path);
    setenv("PATH", p, 1);
    assert_int_equal(r.status, RUNNER_MISSING);
    assert_string_equal(runner_status_name(r.status), "skipped");
    assert_non_null(strstr(r.message, "apt-get install blender"));
    assert_int_equal(access(ok.exr, R_OK), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_renderer_fails),
        cmocka_unit_test(test_renderer_crashes),
        cmocka_unit_test(test_renderer_hangs),
        cmocka_unit_test(test_renderer_writes_garbage),
        cmocka_unit_test(test_renderer_missing_and_results_kept),
    };
    return cmocka_run_group_tests_name("jobs", tests, setup, teardown);
}
