/* Render jobs when a renderer is missing, fails, crashes, hangs or writes garbage: each is a
 * record with that status and a message, never an abort, results already written stay, and
 * `reflcheck run` exits 0 only for ok and skipped. The cache key covers the bytes of every
 * file a scene references; runs sharing a cache render a job once; a killed run leaves no
 * renderer and no lock behind.
 * Broken renderers are small scripts put first on PATH in place of povray/blender. Folders
 * carry the test's pid, so test programs of other builds may run beside this one. */
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>

#include "procs.h"

#include <cJSON.h>

#include "cli_exec.h"
#include "exr.h"
#include "fileio.h"
#include "frame.h"
#include "jobs.h"

static char saved_path[8192];
static char bin_dir[128], out_dir[128], work[128];

/* Installs a fake program NAME on PATH with the given shell body. */
static void fake(const char *name, const char *body)
{
    char path[512];
    mkdir(bin_dir, 0755);
    snprintf(path, sizeof path, "%s/%s", bin_dir, name);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    /* `--version` answers like the real program, so the version probe passes. */
    fprintf(
        f,
        "#!/bin/sh\ncase \"$1\" in --version) echo 'POV-Ray 3.7.0.10.fake'; echo 'Blender 3.4.1'; exit 0;; esac\n%s\n",
        body);
    fclose(f);
    chmod(path, 0755);
}

static void use_path(const char *p) { setenv("PATH", p, 1); }

static void use_fake_path(void)
{
    char p[8400];
    snprintf(p, sizeof p, "%s:%s", bin_dir, saved_path);
    use_path(p);
}

static int setup(void **state)
{
    (void)state;
    long pid = (long)getpid();
    snprintf(bin_dir, sizeof bin_dir, "/tmp/reflcheck-test-jobs-%ld-bin", pid);
    snprintf(out_dir, sizeof out_dir, "/tmp/reflcheck-test-jobs-%ld-out", pid);
    snprintf(work, sizeof work, "/tmp/reflcheck-test-jobs-%ld", pid);
    snprintf(saved_path, sizeof saved_path, "%s", getenv("PATH") ? getenv("PATH") : "");
    use_fake_path();
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf %s %s %s; mkdir -p %s", bin_dir, out_dir, work, work);
    return system(cmd) != 0;
}

static int teardown(void **state)
{
    (void)state;
    setenv("PATH", saved_path, 1);
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf %s %s %s", bin_dir, out_dir, work);
    return system(cmd) != 0;
}

static job_record run_job(int r, double timeout)
{
    job_spec j = {.scene_path = "scenes/d3d_spot.yaml",
                  .renderer = r,
                  .role = ROLE_TWIN,
                  .variant = JOB_SMALL,
                  .out_dir = out_dir,
                  .cache_dir = NULL,
                  .timeout_s = timeout,
                  .threads = 1};
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
    job_record r = run_job(registry_find("povray"), 30);
    assert_int_equal(r.status, RUNNER_FAILED);
    assert_non_null(strstr(r.message, "povray failed"));
    assert_non_null(strstr(r.message, "exit status 3"));
    assert_non_null(strstr(r.message, ".log"));
}

/* A job record parsed (the caller deletes it); fails the test when it is missing or not JSON. */
static cJSON *record_json(const char *path)
{
    char *text = fileio_read_all(path, NULL);
    assert_non_null(text);
    cJSON *o = cJSON_Parse(text);
    free(text);
    assert_non_null(o);
    return o;
}

/* A stochastic render's record takes the samples and the noise from its log's last
 * reflcheck-samples line (cycles_samples.h), the passes from its last reflcheck-passes line:
 * here a fake Blender prints two of each, then fails. */
static void test_record_samples_and_noise(void **state)
{
    (void)state;
    fake("blender", "echo 'reflcheck-samples: samples 5 noise 1 target 0 pilot 0 pilot_noise 0 gate none'\n"
                    "echo 'reflcheck-passes: 1'\n"
                    "echo 'reflcheck-samples: samples 77 noise 0.03 target 0.02 pilot 16 pilot_noise 0.066 gate "
                    "comparisons[1] raster/validate nrmse fail 0.06'\n"
                    "echo 'reflcheck-passes: 3'; exit 1");
    job_record r = run_job(registry_find("cycles"), 30);
    assert_int_equal(r.status, RUNNER_FAILED);
    cJSON *o = record_json(r.record);
    assert_int_equal(cJSON_GetObjectItem(o, "samples")->valueint, 77);
    cJSON *n = cJSON_GetObjectItem(o, "noise");
    assert_non_null(n);
    assert_true(cJSON_GetObjectItem(n, "nrmse")->valuedouble == 0.03);
    assert_true(cJSON_GetObjectItem(n, "target")->valuedouble == 0.02);
    assert_true(cJSON_IsFalse(cJSON_GetObjectItem(n, "reached"))); /* 0.03 > 0.02 */
    assert_string_equal(cJSON_GetObjectItem(n, "gate")->valuestring, "comparisons[1] raster/validate nrmse fail 0.06");
    assert_string_equal(cJSON_GetObjectItem(n, "samples_from")->valuestring, "auto");
    assert_int_equal(cJSON_GetObjectItem(n, "pilot_samples")->valueint, 16);
    assert_int_equal(cJSON_GetObjectItem(n, "passes")->valueint, 3);
    cJSON_Delete(o);
}

/* The z-test rule's line (pixel_q, ztarget, the pilot's pixel_q): the record gives them, and
 * "reached" needs both noises at their targets: nrmse 0.01 <= 0.02 but pixel_q 0.03 > 0.025. */
static void test_record_ztest_noise(void **state)
{
    (void)state;
    fake("blender", "echo 'reflcheck-samples: samples 64 noise 0.01 target 0.02 pilot 32 pilot_noise 0.02 "
                    "pilot_pixel_q 0.05 pixel_q 0.03 ztarget 0.025 gate comparisons[0] raster/twin z_fail_share bias "
                    "0.1 (image.samples bias)'; exit 1");
    job_record r = run_job(registry_find("cycles"), 30);
    cJSON *o = record_json(r.record);
    assert_int_equal(cJSON_GetObjectItem(o, "samples")->valueint, 64);
    cJSON *n = cJSON_GetObjectItem(o, "noise");
    assert_non_null(n);
    assert_true(cJSON_GetObjectItem(n, "pixel_q")->valuedouble == 0.03);
    assert_true(cJSON_GetObjectItem(n, "z_target")->valuedouble == 0.025);
    assert_true(cJSON_GetObjectItem(n, "pilot_pixel_q")->valuedouble == 0.05);
    assert_null(cJSON_GetObjectItem(n, "passes")); /* a log from before the passes line */
    assert_true(cJSON_IsFalse(cJSON_GetObjectItem(n, "reached")));
    assert_string_equal(cJSON_GetObjectItem(n, "gate")->valuestring,
                        "comparisons[0] raster/twin z_fail_share bias 0.1 (image.samples bias)");
    cJSON_Delete(o);
}

/* With a cache, a renderer's version line is asked once per install (CACHE/versions): a fake
 * POV-Ray counts its --version calls; two jobs ask once, a reinstalled one (new size) again. */
static void test_version_asked_once_per_install(void **state)
{
    (void)state;
    char script[512], count[256], cache[256], body[1024];
    snprintf(count, sizeof count, "%s/version-calls", work);
    snprintf(cache, sizeof cache, "%s/cache", work);
    snprintf(script, sizeof script, "%s/povray", bin_dir);
    snprintf(body, sizeof body,
             "#!/bin/sh\ncase \"$1\" in --version) echo x >> %s; echo 'POV-Ray 3.7.0.10.fake'; exit 0;; esac\nexit 3\n",
             count);
    mkdir(bin_dir, 0755);
    for (int round = 0; round < 2; round++) {
        FILE *f = fopen(script, "w");
        assert_non_null(f);
        fprintf(f, "%s%s", body, round ? "# reinstalled\n" : "");
        fclose(f);
        chmod(script, 0755);
        for (int i = 0; i < 2; i++) {
            job_spec j = {.scene_path = "scenes/d3d_spot.yaml",
                          .renderer = registry_find("povray"),
                          .role = ROLE_TWIN,
                          .variant = JOB_SMALL,
                          .out_dir = out_dir,
                          .cache_dir = cache,
                          .timeout_s = 30,
                          .threads = 1};
            job_record rec;
            char err[1024];
            assert_int_equal(job_run(&j, &rec, err, sizeof err), RC_OK);
            assert_int_equal(rec.status, RUNNER_FAILED); /* the fake renders nothing */
        }
        char *calls = fileio_read_all(count, NULL);
        assert_non_null(calls);
        assert_int_equal((int)strlen(calls), 2 * (round + 1)); /* "x\n" per call */
        free(calls);
    }
}

static void test_renderer_crashes(void **state)
{
    (void)state;
    fake("povray", "kill -SEGV $$");
    job_record r = run_job(registry_find("povray"), 30);
    assert_int_equal(r.status, RUNNER_CRASHED);
    assert_non_null(strstr(r.message, "signal 11"));
}

static void test_renderer_hangs(void **state)
{
    (void)state;
    fake("blender", "sleep 60");
    job_record r = run_job(registry_find("cycles"), 0.5);
    assert_int_equal(r.status, RUNNER_TIMEOUT);
    /* Killed at its limit, not waited for (the fake's 60 s); no tighter bound, which would
     * depend on the machine's load. */
    assert_true(r.wall_s < 60.0);
}

/* A stand-in's shell words that write both frames POV-Ray renders from one process (the scene
 * and the coverage pass, povray.h: +O base.exr gives base1.exr and base2.exr), each by WRITE
 * followed by the frame's file name. */
#define POV_FRAMES(WRITE) "o=${a#+O}; " WRITE " \"${o%.exr}1.exr\"; " WRITE " \"${o%.exr}2.exr\""

static void test_renderer_writes_garbage(void **state)
{
    (void)state;
    /* Exits 0 but the "EXR" it names is text: an unreadable image, recorded as a failure. */
    fake("povray",
         "for a in \"$@\"; do case \"$a\" in +O*) " POV_FRAMES("echo 'not an exr' >") ";; esac; done; exit 0");
    job_record r = run_job(registry_find("povray"), 30);
    assert_int_equal(r.status, RUNNER_FAILED);
    assert_non_null(strstr(r.message, "unreadable"));
}

static void test_renderer_missing_and_results_kept(void **state)
{
    (void)state;
    /* A result written before: the raster job. Then blender is missing from PATH entirely. */
    job_record ok = run_job(registry_model(), 30);
    assert_int_equal(ok.status, RUNNER_OK);
    use_path("/usr/local/nonexistent");
    job_record r = run_job(registry_find("cycles"), 30);
    use_fake_path();
    assert_int_equal(r.status, RUNNER_MISSING);
    assert_string_equal(runner_status_name(r.status), "skipped");
    assert_non_null(strstr(r.message, "is not installed"));
    assert_non_null(strstr(r.message, "apt-get install blender"));
    assert_int_equal(access(ok.exr, R_OK), 0);
}

/* ---- A tiny scene of our own (8 x 6 px, a triangle mesh, an environment image) ---- */

static const char *tiny_obj = "v -1 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

/* An RGB image of w x h with every value v, written with our EXR writer. */
static void write_exr(const char *path, int w, int h, float v)
{
    size_t n = (size_t)w * (size_t)h;
    float *p = malloc(n * sizeof *p);
    assert_non_null(p);
    for (size_t i = 0; i < n; i++)
        p[i] = v;
    exr_channel ch[3] = {{"R", p}, {"G", p}, {"B", p}};
    char err[512];
    assert_int_equal(exr_write(path, w, h, ch, 3, NULL, 0, err, sizeof err), RC_OK);
    free(p);
}

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
}

/* work/NAME.yaml (w x h px) with tri.obj and env.exr beside it; returns the scene's path. */
static const char *sized_scene(const char *name, int w, int h)
{
    static char path[256];
    char p[256], yaml[1024];
    snprintf(p, sizeof p, "%s/tri.obj", work);
    if (access(p, R_OK) != 0)
        write_text(p, tiny_obj);
    snprintf(p, sizeof p, "%s/env.exr", work);
    if (access(p, R_OK) != 0)
        write_exr(p, 8, 4, 0.25f);
    snprintf(yaml, sizeof yaml,
             "name: %s\n"
             "image: {width: %d, height: %d, supersample: 1, timeout: 60}\n"
             "camera: {eye: [0, 0.5, 4], target: [0, 0.5, 0], hfov: 40}\n"
             "environment: {image: env.exr}\n"
             "lights:\n  - {type: point, position: [2, 4, 3], intensity: [30, 30, 30]}\n"
             "materials:\n  white: {albedo: [0.8, 0.8, 0.8]}\n"
             "objects:\n  - {shape: mesh, path: tri.obj, material: white}\n"
             "comparisons:\n  - reference: povray\n    role: twin\n"
             "    thresholds: {rel_rms: {warn: 1e-3, fail: 2e-3, why: \"test\"}}\n",
             name, w, h);
    snprintf(path, sizeof path, "%s/%s.yaml", work, name);
    write_text(path, yaml);
    return path;
}

static const char *tiny_scene(const char *name) { return sized_scene(name, 8, 6); }

/* A fake POV-Ray that renders by copying an 8 x 6 image (what the tiny scene asks for). */
static void fake_povray_ok(const char *extra)
{
    char img[256], body[1024];
    snprintf(img, sizeof img, "%s/fake-render.exr", work);
    if (access(img, R_OK) != 0)
        write_exr(img, 8, 6, 0.5f);
    /* The frames' loop is not a format (its ${o%.exr}): appended after the printf'd part. */
    int n = snprintf(body, sizeof body, "%s\nimg='%s'\n", extra, img);
    assert_true(n > 0 && (size_t)n < sizeof body);
    snprintf(body + n, sizeof body - (size_t)n, "%s",
             "for a in \"$@\"; do case \"$a\" in +O*) " POV_FRAMES("cp \"$img\"") ";; esac; done; exit 0");
    fake("povray", body);
}

/* A field of the record OUT/tiny/<renderer>-twin.json: its string, or "true"/"false". */
static void record_field(const char *out, const char *name, const char *renderer, const char *key, char *buf,
                         size_t len)
{
    char path[512];
    snprintf(path, sizeof path, "%s/%s/%s-twin.json", out, name, renderer);
    char *text = fileio_read_all(path, NULL);
    buf[0] = '\0';
    if (text == NULL)
        return;
    cJSON *doc = cJSON_Parse(text);
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(doc, key);
    if (cJSON_IsString(v))
        snprintf(buf, len, "%s", v->valuestring);
    else if (cJSON_IsBool(v))
        snprintf(buf, len, "%s", cJSON_IsTrue(v) ? "true" : "false");
    cJSON_Delete(doc);
    free(text);
}

typedef struct {
    const char *body;  /* the fake povray; NULL: none on PATH */
    const char *extra; /* more options */
    int exit_status;
    const char *status; /* the record's */
} exit_case;

static void test_run_exit_status(void **state)
{
    (void)state;
    const char *yaml = tiny_scene("tiny");
    char ok_body[1024];
    fake_povray_ok("");
    snprintf(ok_body, sizeof ok_body, "%s/povray", bin_dir);
    char *ok_script = fileio_read_all(ok_body, NULL);
    assert_non_null(ok_script);
    /* The body after the --version line of fake(). */
    const char *ok_render = strstr(ok_script, "esac\n") + 5;
    const exit_case cases[] = {
        {ok_render, "", 0, "ok"},
        {"kill -SEGV $$", "", 1, "crashed"},
        {"exit 3", "", 1, "failed"},
        {"exit 127", "", 1, "failed"},
        {"sleep 30", "--timeout 0.5", 1, "timeout"},
        {"for a in \"$@\"; do case \"$a\" in +O*) " POV_FRAMES("echo garbage >") ";; esac; done", "", 1, "failed"},
        {NULL, "", 0, "skipped"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char out[256], err[1024], status[64];
        snprintf(out, sizeof out, "%s/exit%zu", out_dir, i);
        if (cases[i].body != NULL)
            fake("povray", cases[i].body);
        else
            use_path("/usr/local/nonexistent");
        int rc = cli_exec(err, sizeof err, "run %s --renderer povray --role twin --no-cache --out %s %s", yaml, out,
                          cases[i].extra);
        use_fake_path();
        record_field(out, "tiny", "povray", "status", status, sizeof status);
        print_message("case %zu (%s): exit %d, status %s, stderr %s\n", i, cases[i].status, rc, status, err);
        assert_string_equal(status, cases[i].status);
        assert_int_equal(rc, cases[i].exit_status);
        if (rc == 1)
            assert_non_null(strstr(err, cases[i].status));
    }
    free(ok_script);
}

/* A mesh the reader repairs: the record says how many triangles were left out, stderr notes it. */
static void test_record_mesh_repairs(void **state)
{
    (void)state;
    char err[1024], path[256], rec[512], cwd[400];
    assert_non_null(getcwd(cwd, sizeof cwd));
    snprintf(path, sizeof path, "%s/repaired.yaml", work);
    char text[1024];
    snprintf(text, sizeof text,
             "image: {width: 8, height: 6}\ncamera: {eye: [0, 0, 4], target: [0, 0, 0], hfov: 40}\n"
             "materials: {m: {}}\nobjects:\n  - {shape: mesh, path: %s/tests/fixtures/meshes/degenerate.obj, "
             "material: m}\n",
             cwd);
    write_text(path, text);
    assert_int_equal(cli_exec(err, sizeof err, "run %s --renderer raster --no-cache --out %s", path, out_dir), 0);
    assert_non_null(strstr(err, "note:"));
    assert_non_null(strstr(err, "1 zero-area triangle left out"));
    snprintf(rec, sizeof rec, "%s/repaired/raster-validate.json", out_dir);
    cJSON *doc = record_json(rec);
    const cJSON *mo = cJSON_GetObjectItemCaseSensitive(doc, "mesh");
    assert_int_equal(cJSON_GetObjectItemCaseSensitive(mo, "triangles")->valueint, 1);
    assert_int_equal(cJSON_GetObjectItemCaseSensitive(mo, "degenerate_dropped")->valueint, 1);
    assert_int_equal(cJSON_GetObjectItemCaseSensitive(mo, "normals_recomputed")->valueint, 0);
    cJSON_Delete(doc);
}

static void test_run_bad_input_is_2(void **state)
{
    (void)state;
    char err[1024], path[256];
    snprintf(path, sizeof path, "%s/bad.yaml", work);
    write_text(path, "image: {width: 8, height: 6}\ncamera: {eye: [0, 0, 4], target: [0, 0, 0], hfov: 40}\nbogus: 1\n");
    assert_int_equal(cli_exec(err, sizeof err, "run %s --renderer raster --out %s", path, out_dir), 2);
    assert_non_null(strstr(err, "bogus"));
    /* An unreadable scene file is bad input too (it was 1, as if our side had failed). */
    assert_int_equal(cli_exec(err, sizeof err, "run %s/missing.yaml --renderer raster --out %s", work, out_dir), 2);
    assert_non_null(strstr(err, "missing.yaml"));
    /* A mesh path that names a folder: refused before any render. */
    snprintf(path, sizeof path, "%s/folder.obj", work);
    mkdir(path, 0755);
    snprintf(path, sizeof path, "%s/foldermesh.yaml", work);
    write_text(path, "image: {width: 8, height: 6}\ncamera: {eye: [0, 0, 4], target: [0, 0, 0], hfov: 40}\n"
                     "materials:\n  white: {}\nobjects:\n  - {shape: mesh, path: folder.obj, material: white}\n");
    assert_int_equal(cli_exec(err, sizeof err, "run %s --renderer raster --out %s", path, out_dir), 2);
    assert_non_null(strstr(err, "folder.obj"));
    assert_int_equal(cli_exec(err, sizeof err, "run %s --renderer nosuch --out %s", tiny_scene("tiny"), out_dir), 2);
}

static void test_cache_folder_error_is_recorded(void **state)
{
    (void)state;
    /* A cache under a regular file cannot be created: our side's error, in the record, exit 1. */
    const char *yaml = tiny_scene("tiny");
    char err[1024], status[64], msg[600], out[256];
    snprintf(out, sizeof out, "%s/cacheerr", out_dir);
    int rc = cli_exec(err, sizeof err, "run %s --renderer raster --role twin --out %s --cache %s/tri.obj/cache", yaml,
                      out, work);
    record_field(out, "tiny", "raster", "status", status, sizeof status);
    record_field(out, "tiny", "raster", "message", msg, sizeof msg);
    assert_int_equal(rc, 1);
    assert_string_equal(status, "error");
    assert_non_null(strstr(msg, "cache"));
}

static void test_full_disk_is_an_error(void **state)
{
    (void)state;
    /* A file size limit stands in for a full disk: the image (tens of KB at 64 x 48) cannot
     * be written, the record (under 1 KB) can. Our side's error: exit 1, status error. */
    const char *yaml = sized_scene("big", 64, 48);
    char out[256], cmd[1200], status[64], msg[600];
    snprintf(out, sizeof out, "%s/full", out_dir);
    snprintf(cmd, sizeof cmd,
             "sh -c 'ulimit -f 4; trap \"\" XFSZ; exec %s run %s --renderer raster --role twin --no-cache --out %s' "
             ">/dev/null 2>&1",
             cli_bin(), yaml, out);
    int st = system(cmd);
    assert_true(WIFEXITED(st));
    record_field(out, "big", "raster", "status", status, sizeof status);
    record_field(out, "big", "raster", "message", msg, sizeof msg);
    assert_string_equal(status, "error");
    assert_non_null(strstr(msg, "too large"));
    assert_int_equal(WEXITSTATUS(st), 1);
}

/* Runs the tiny scene's raster job on a cache; returns the record's "cached". */
static int cached_run(const char *yaml, const char *cache)
{
    char err[1024], cached[16], out[256];
    snprintf(out, sizeof out, "%s/keyed", out_dir);
    assert_int_equal(
        cli_exec(err, sizeof err, "run %s --renderer raster --role twin --out %s --cache %s", yaml, out, cache), 0);
    record_field(out, "tiny", "raster", "cached", cached, sizeof cached);
    assert_true(strcmp(cached, "true") == 0 || strcmp(cached, "false") == 0);
    return strcmp(cached, "true") == 0;
}

static void test_cache_key_covers_referenced_files(void **state)
{
    (void)state;
    const char *yaml = tiny_scene("tiny");
    char cache[256], obj[256], env[256];
    snprintf(cache, sizeof cache, "%s/cache", work);
    snprintf(obj, sizeof obj, "%s/tri.obj", work);
    snprintf(env, sizeof env, "%s/env.exr", work);
    assert_false(cached_run(yaml, cache));
    assert_true(cached_run(yaml, cache));
    /* One byte of the mesh: 1 0 0 -> 1 0 1 (the scene file itself unchanged). */
    write_text(obj, "v -1 0 0\nv 1 0 1\nv 0 1 0\nf 1 2 3\n");
    assert_false(cached_run(yaml, cache));
    assert_true(cached_run(yaml, cache));
    /* The environment image: every texel 0.25 -> 0.5. */
    write_exr(env, 8, 4, 0.5f);
    assert_false(cached_run(yaml, cache));
    assert_true(cached_run(yaml, cache));
    write_text(obj, tiny_obj);
}

static int files_equal(const char *a, const char *b)
{
    size_t na, nb;
    char *ta = fileio_read_all(a, &na), *tb = fileio_read_all(b, &nb);
    int eq = ta != NULL && tb != NULL && na == nb && memcmp(ta, tb, na) == 0;
    free(ta);
    free(tb);
    return eq;
}

/* A raster twin job of the tiny scene into OUT/reuse over CACHE, with reuse_record and slurm_job
 * as given; returns its record. */
static job_record reuse_run(const char *yaml, const char *cache, int reuse, const char *slurm)
{
    char out[256], err[1024];
    snprintf(out, sizeof out, "%s/reuse", out_dir);
    job_spec j = {.scene_path = yaml,
                  .renderer = registry_find("raster"),
                  .role = ROLE_TWIN,
                  .out_dir = out,
                  .cache_dir = cache,
                  .threads = 1,
                  .slurm_job = slurm,
                  .reuse_record = reuse};
    job_record rec;
    assert_int_equal(job_run(&j, &rec, err, sizeof err), RC_OK);
    assert_int_equal(rec.status, RUNNER_OK);
    return rec;
}

/* reuse_record hands back OUT's record of the same key untouched (the Slurm id of the job that
 * made it kept); without it a cache hit rewrites the record; a record of another key or not ok
 * is not reused. */
static void test_reuse_record(void **state)
{
    (void)state;
    const char *yaml = tiny_scene("tiny");
    char cache[256], record[256], saved[256], text[64];
    snprintf(cache, sizeof cache, "%s/reuse-cache", work);
    snprintf(saved, sizeof saved, "%s/reuse-saved.json", work);
    job_record r = reuse_run(yaml, cache, 0, "4240_2");
    snprintf(record, sizeof record, "%s", r.record);
    assert_int_equal(fileio_copy(record, saved), 0);
    r = reuse_run(yaml, cache, 1, "");
    assert_true(r.reused);
    assert_false(r.cached);
    assert_string_equal(r.record, record);
    assert_true(files_equal(record, saved));
    /* Control: the same job without reuse_record is a cache hit that rewrites the record. */
    r = reuse_run(yaml, cache, 0, "");
    assert_false(r.reused);
    assert_true(r.cached);
    assert_false(files_equal(record, saved));
    /* Another key: the record names key 0, so the job runs (a cache hit) and writes its own. */
    char *t = fileio_read_all(saved, NULL);
    assert_non_null(t);
    char *k = strstr(t, "\"key\":");
    assert_non_null(k);
    k = strchr(k + 6, '"');
    memset(k + 1, '0', 16);
    write_text(record, t);
    free(t);
    r = reuse_run(yaml, cache, 1, "");
    assert_false(r.reused);
    record_field(out_dir, "reuse/tiny", "raster", "cached", text, sizeof text);
    assert_string_equal(text, "true");
    /* Not ok: a failed job's record is no image to read. */
    t = fileio_read_all(saved, NULL);
    char *st = strstr(t, "\"status\":");
    assert_non_null(st);
    st = strchr(st + 9, '"');
    memcpy(st + 1, "no", 2);
    write_text(record, t);
    free(t);
    assert_false(reuse_run(yaml, cache, 1, "").reused);
}

static int count_lines(const char *path)
{
    char *t = fileio_read_all(path, NULL);
    int n = 0;
    for (const char *p = t; p != NULL && *p; p++)
        n += *p == '\n';
    free(t);
    return n;
}

static void test_two_runs_share_a_cache(void **state)
{
    (void)state;
    const char *yaml = tiny_scene("tiny");
    char count[256], extra[512], cmd[4096];
    snprintf(count, sizeof count, "%s/invocations", work);
    unlink(count);
    /* Each render takes a second, so the second run arrives while the first renders. */
    snprintf(extra, sizeof extra, "echo run >> %s; sleep 1", count);
    fake_povray_ok(extra);
    snprintf(cmd, sizeof cmd,
             "for i in 1 2; do (%s run %s --renderer povray --role twin --out %s/share$i --cache %s/sharedcache "
             ">/dev/null 2>&1; echo $? > %s/share$i.rc) & done; wait",
             cli_bin(), yaml, work, work, work);
    assert_int_equal(system(cmd), 0);
    char a[256], b[256], status[64];
    for (int i = 1; i <= 2; i++) {
        char rc[256], out[256];
        snprintf(rc, sizeof rc, "%s/share%d.rc", work, i);
        char *t = fileio_read_all(rc, NULL);
        assert_non_null(t);
        assert_int_equal(atoi(t), 0);
        free(t);
        snprintf(out, sizeof out, "%s/share%d", work, i);
        record_field(out, "tiny", "povray", "status", status, sizeof status);
        assert_string_equal(status, "ok");
    }
    /* One job is one POV-Ray process (image and coverage as two frames, povray.h): the renderer
     * ran for one job only. */
    assert_int_equal(count_lines(count), 1);
    snprintf(a, sizeof a, "%s/share1/tiny/povray-twin.exr", work);
    snprintf(b, sizeof b, "%s/share2/tiny/povray-twin.exr", work);
    assert_true(files_equal(a, b));
}

/* Starts `reflcheck run` on the tiny scene with a POV-Ray that writes its pid and sleeps, kills
 * the run with sig once the renderer is up, and checks the renderer is gone. Then a second run
 * on the same cache is not blocked by the killed run's lock and leaves no work folder. */
/* Counts the work folders (tmp-*) in dir. */
static int work_folders(const char *dir)
{
    char cmd[1200], path[256];
    snprintf(path, sizeof path, "%s/tmpcount", work);
    snprintf(cmd, sizeof cmd, "ls %s | grep -c '^tmp-' > %s", dir, path);
    assert_true(system(cmd) != -1);
    char *n = fileio_read_all(path, NULL);
    assert_non_null(n);
    int count = atoi(n);
    free(n);
    return count;
}

/* Starts `reflcheck run` on the tiny scene with a POV-Ray that writes its pid and sleeps, kills
 * the run with sig once the renderer is up, and checks the renderer is gone. Then a second run
 * (on the same cache, or none) is not blocked by the killed run's lock, and no work folder is
 * left where the job works (the cache, or the output folder). */
static void kill_run(int sig, int cached)
{
    const char *yaml = tiny_scene("tiny");
    char pidfile[256], body[768], cache[256], out[256], where[300], cache_opt[300];
    snprintf(pidfile, sizeof pidfile, "%s/renderer.pid", work);
    snprintf(cache, sizeof cache, "%s/killcache%d", work, sig);
    snprintf(out, sizeof out, "%s/kill%d-%d", out_dir, sig, cached);
    snprintf(where, sizeof where, "%s/tiny", out);
    if (cached)
        snprintf(where, sizeof where, "%s", cache);
    snprintf(cache_opt, sizeof cache_opt, "%s", cached ? cache : "");
    char flag[256];
    snprintf(flag, sizeof flag, "%s/hang", work);
    unlink(pidfile);
    write_text(flag, "");
    /* One script for both runs (the renderer's executable is part of the cache key): it hangs
     * while the flag file exists, and renders once it is gone. */
    snprintf(body, sizeof body, "if [ -f %s ]; then echo $$ > %s; exec sleep 60; fi", flag, pidfile);
    fake_povray_ok(body);
    pid_t run = fork();
    assert_true(run >= 0);
    if (run == 0) {
        if (freopen("/dev/null", "w", stdout) == NULL || freopen("/dev/null", "w", stderr) == NULL)
            _exit(126);
        execl(cli_bin(), "reflcheck", "run", yaml, "--renderer", "povray", "--role", "twin", "--out", out,
              cached ? "--cache" : "--no-cache", cached ? cache : NULL, (char *)NULL);
        _exit(127);
    }
    pid_t renderer = proc_read_pid(pidfile);
    assert_true(renderer > 0);
    kill(run, sig);
    int st;
    assert_int_equal(waitpid(run, &st, 0), run);
    assert_true(WIFSIGNALED(st));
    assert_int_equal(WTERMSIG(st), sig);
    int gone = proc_gone_within(renderer);
    if (!gone)
        kill(renderer, SIGKILL);
    assert_true(gone);
    assert_int_equal(work_folders(where), 1);

    /* The lock died with the run: the next run is not blocked and renders, and the killed
     * run's work folder is gone. */
    unlink(flag);
    char err[1024];
    assert_int_equal(cli_exec(err, sizeof err, "run %s --renderer povray --role twin --out %s %s %s", yaml, out,
                              cached ? "--cache" : "--no-cache", cache_opt),
                     0);
    assert_int_equal(work_folders(where), 0);
}

static void test_killed_run_sigkill(void **state)
{
    (void)state;
    kill_run(SIGKILL, 1);
}

static void test_killed_run_sigterm(void **state)
{
    (void)state;
    kill_run(SIGTERM, 1);
}

static void test_killed_run_without_cache(void **state)
{
    (void)state;
    kill_run(SIGKILL, 0);
}

/* ---- The cube map's conversion, kept in the cache (job_env_cube_file) ---- */

/* Six 4 x 4 faces, every texel and channel its own value (base + its index / 1000). */
static float *cube_texels(float base)
{
    size_t n = 6 * 4 * 4 * 3;
    float *rgb = malloc(n * sizeof *rgb);
    assert_non_null(rgb);
    for (size_t i = 0; i < n; i++)
        rgb[i] = base + (float)i / 1000.0f;
    return rgb;
}

static void file_id(const char *path, struct stat *st) { assert_int_equal(stat(path, st), 0); }

/* The kept file is frame_env_cube_write's bytes, written once for the same faces, another file
 * for other faces, and written again when damaged. */
static void test_env_cube_file_kept_once(void **state)
{
    (void)state;
    char cache[256], direct[256], p1[1200], p2[1200], again[1200], err[1024];
    snprintf(cache, sizeof cache, "%s/envcache", work);
    snprintf(direct, sizeof direct, "%s/direct-cube.exr", work);
    float *rgb = cube_texels(0.25f);
    env_map cube = {.kind = ENV_CUBE, .width = 4, .height = 4, .rgb = rgb, .scale = v3s(1)};
    assert_int_equal(job_env_cube_file(cache, registry_find("cycles"), &cube, p1, sizeof p1, err, sizeof err), RC_OK);
    assert_non_null(strstr(p1, "/envcache/env/cube-"));
    assert_int_equal(frame_env_cube_write(direct, &cube, err, sizeof err), RC_OK);
    assert_true(files_equal(p1, direct));

    /* The same faces again: the same file, not written again (same inode and change time). */
    struct stat a, b;
    file_id(p1, &a);
    assert_int_equal(job_env_cube_file(cache, registry_find("cycles"), &cube, again, sizeof again, err, sizeof err),
                     RC_OK);
    assert_string_equal(again, p1);
    file_id(p1, &b);
    assert_true(a.st_ino == b.st_ino && a.st_mtim.tv_sec == b.st_mtim.tv_sec && a.st_mtim.tv_nsec == b.st_mtim.tv_nsec);

    /* One texel changed: another file, the new faces' conversion, never the old one. */
    rgb[6 * 4 * 4 * 3 - 1] += 0.5f;
    assert_int_equal(job_env_cube_file(cache, registry_find("cycles"), &cube, p2, sizeof p2, err, sizeof err), RC_OK);
    assert_string_not_equal(p2, p1);
    assert_int_equal(frame_env_cube_write(direct, &cube, err, sizeof err), RC_OK);
    assert_true(files_equal(p2, direct));
    assert_false(files_equal(p2, p1));

    /* REFLCHECK_ENV_CACHE: another cache's job finds the same file there. */
    char shared[256], other[256], s1[1200], s2[1200];
    snprintf(shared, sizeof shared, "%s/envshared", work);
    snprintf(other, sizeof other, "%s/othercache", work);
    setenv("REFLCHECK_ENV_CACHE", shared, 1);
    assert_int_equal(job_env_cube_file(cache, registry_find("cycles"), &cube, s1, sizeof s1, err, sizeof err), RC_OK);
    assert_int_equal(job_env_cube_file(other, registry_find("cycles"), &cube, s2, sizeof s2, err, sizeof err), RC_OK);
    unsetenv("REFLCHECK_ENV_CACHE");
    assert_string_equal(s1, s2);
    assert_int_equal(strncmp(s1, shared, strlen(shared)), 0);
    assert_true(files_equal(s1, direct));

    /* A kept file cut short is written again, whole. */
    assert_int_equal(truncate(p2, 100), 0);
    assert_int_equal(job_env_cube_file(cache, registry_find("cycles"), &cube, again, sizeof again, err, sizeof err),
                     RC_OK);
    assert_string_equal(again, p2);
    assert_true(files_equal(p2, direct));
    free(rgb);
}

/* A cube-map scene of the tiny triangle (six 4 x 4 faces beside it); returns its path. */
static const char *cube_scene(void)
{
    static char path[256];
    static const char *faces[6] = {"px", "nx", "py", "ny", "pz", "nz"};
    char p[256], yaml[1400];
    int n = snprintf(yaml, sizeof yaml,
                     "name: cubey\nimage: {width: 8, height: 6, supersample: 1, timeout: 60}\n"
                     "camera: {eye: [0, 0.5, 4], target: [0, 0.5, 0], hfov: 40}\nenvironment:\n  cube: {");
    for (int f = 0; f < 6; f++) {
        snprintf(p, sizeof p, "%s/face_%s.exr", work, faces[f]);
        write_exr(p, 4, 4, 0.1f * (float)(f + 1));
        n += snprintf(yaml + n, sizeof yaml - (size_t)n, "%s%s: face_%s.exr", f ? ", " : "", faces[f], faces[f]);
    }
    snprintf(yaml + n, sizeof yaml - (size_t)n,
             "}\nlights:\n  - {type: point, position: [2, 4, 3], intensity: [30, 30, 30]}\n"
             "materials:\n  white: {albedo: [0.8, 0.8, 0.8]}\n"
             "objects:\n  - {shape: mesh, path: tri.obj, material: white}\n"
             "comparisons:\n  - reference: cycles\n    role: twin\n"
             "    thresholds: {rel_rms: {warn: 1e-3, fail: 2e-3, why: \"test\"}}\n");
    snprintf(p, sizeof p, "%s/tri.obj", work);
    write_text(p, tiny_obj);
    snprintf(path, sizeof path, "%s/cubey.yaml", work);
    write_text(path, yaml);
    return path;
}

/* Cycles jobs of a cube-map scene: with a cache, every job gets the cache's one conversion;
 * without, its own work folder's file (removed after), byte for byte the same. A fake Blender
 * copies the environment its job names (seen-N.exr, its path in seen-N.path), then fails. */
static void test_cycles_jobs_share_the_cube_conversion(void **state)
{
    (void)state;
    const char *yaml = cube_scene();
    char body[1024];
    snprintf(body, sizeof body,
             "for a in \"$@\"; do job=$prev; prev=$a; done\n"
             "env=$(sed -n 's/.*\"path\":[[:space:]]*\"\\([^\"]*\\.exr\\)\".*/\\1/p' \"$job\" | head -n1)\n"
             "n=$(ls %s | grep -c '^seen-.*\\.exr$')\n"
             "cp \"$env\" %s/seen-$n.exr; echo \"$env\" > %s/seen-$n.path; exit 3",
             work, work, work);
    fake("blender", body);
    char cache[256], err[1024];
    snprintf(cache, sizeof cache, "%s/cubecache", work);
    const char *opts[3] = {"--cache", "--cache", "--no-cache"};
    const char *seeds[3] = {"1", "2", "1"};
    for (int i = 0; i < 3; i++)
        cli_exec(err, sizeof err, "run %s --renderer cycles --role twin --out %s/cube%d --seed %s %s %s", yaml, out_dir,
                 i, seeds[i], opts[i], i < 2 ? cache : "");
    char seen[3][256], *where[3];
    for (int i = 0; i < 3; i++) {
        char p[256];
        snprintf(seen[i], sizeof seen[i], "%s/seen-%d.exr", work, i);
        snprintf(p, sizeof p, "%s/seen-%d.path", work, i);
        where[i] = fileio_read_all(p, NULL);
        assert_non_null(where[i]);
    }
    assert_string_equal(where[0], where[1]);
    assert_non_null(strstr(where[0], "/cubecache/env/cube-"));
    assert_null(strstr(where[2], "/cubecache/"));
    where[2][strcspn(where[2], "\n")] = '\0';
    assert_int_not_equal(access(where[2], F_OK), 0); /* the work folder's copy is gone */
    assert_true(files_equal(seen[0], seen[2]));
    assert_true(files_equal(seen[1], seen[2]));
    for (int i = 0; i < 3; i++)
        free(where[i]);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_renderer_fails),
        cmocka_unit_test(test_record_samples_and_noise),
        cmocka_unit_test(test_record_ztest_noise),
        cmocka_unit_test(test_version_asked_once_per_install),
        cmocka_unit_test(test_renderer_crashes),
        cmocka_unit_test(test_renderer_hangs),
        cmocka_unit_test(test_renderer_writes_garbage),
        cmocka_unit_test(test_renderer_missing_and_results_kept),
        cmocka_unit_test(test_run_exit_status),
        cmocka_unit_test(test_run_bad_input_is_2),
        cmocka_unit_test(test_record_mesh_repairs),
        cmocka_unit_test(test_cache_folder_error_is_recorded),
        cmocka_unit_test(test_full_disk_is_an_error),
        cmocka_unit_test(test_cache_key_covers_referenced_files),
        cmocka_unit_test(test_reuse_record),
        cmocka_unit_test(test_two_runs_share_a_cache),
        cmocka_unit_test(test_killed_run_sigkill),
        cmocka_unit_test(test_killed_run_sigterm),
        cmocka_unit_test(test_killed_run_without_cache),
        cmocka_unit_test(test_env_cube_file_kept_once),
        cmocka_unit_test(test_cycles_jobs_share_the_cube_conversion),
    };
    return cmocka_run_group_tests_name("jobs", tests, setup, teardown);
}
