/* test_gates.c - gates that count everything: the value gate of every comparison (NaN, Inf,
 * negative values in any layer fail by themselves), job statuses mapped to comparison
 * statuses (only a skipped job skips), duplicate scene names refused, the exit status of
 * compare and diff (check's is in test_env.c, with the environment it now loads), the
 * scene name escaped in the report viewer's view.js, and the crease region against Cycles
 * counted per rule and failing the comparison when it sets too much of the surface apart.
 * Run folders are built by hand (job records and EXRs written here), so every expected count
 * is known exactly: the images are 16x8, all covered by one object, so every pixel is surface. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cJSON.h>

#include "check.h"
#include "cli_exec.h"
#include "exr.h"
#include "jobs.h"
#include "scene_file.h"

enum { W = 16, H = 8, NP = W * H };

static char dir[256];

/* One render: R, G, B, the three term layers, var.*, coverage and object, all planes NP, and
 * the model's crease layer (harness/crease.h's rule bits) when has_crease. */
typedef struct {
    float rgb[3][NP], terms[3][3][NP], var[3][NP], cov[NP], obj[NP], crease[NP];
    int has_crease;
} gate_image;

static void image_flat(gate_image *im, float v)
{
    for (int i = 0; i < NP; i++) {
        for (int c = 0; c < 3; c++) {
            im->rgb[c][i] = v;
            im->terms[0][c][i] = v; /* all light in diffuse, as a Lambert scene */
            im->terms[1][c][i] = 0.0f;
            im->terms[2][c][i] = 0.0f;
            im->var[c][i] = 0.0f;
        }
        im->cov[i] = 1.0f;
        im->obj[i] = 0.0f;
        im->crease[i] = 0.0f;
    }
    im->has_crease = 0;
}

static void image_write(const char *path, const gate_image *im)
{
    static const char *const names[] = {
        "R",          "G",          "B",          "diffuse.R",    "diffuse.G",    "diffuse.B",
        "specular.R", "specular.G", "specular.B", "reflection.R", "reflection.G", "reflection.B",
        "var.R",      "var.G",      "var.B",      "coverage",     "object",       "crease"};
    const float *planes[18] = {im->rgb[0], im->rgb[1], im->rgb[2]};
    for (int t = 0; t < 3; t++)
        for (int c = 0; c < 3; c++)
            planes[3 + 3 * t + c] = im->terms[t][c];
    for (int c = 0; c < 3; c++)
        planes[12 + c] = im->var[c];
    planes[15] = im->cov;
    planes[16] = im->obj;
    planes[17] = im->crease;
    int n = im->has_crease ? 18 : 17;
    exr_channel ch[18];
    for (int i = 0; i < n; i++)
        ch[i] = (exr_channel){names[i], planes[i]};
    char err[512];
    assert_int_equal(exr_write(path, W, H, ch, n, NULL, 0, err, sizeof err), RC_OK);
}

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    assert_int_equal(fclose(f), 0);
}

/* The job record and image of one side of scene `name` in run `run`; status NULL: no record. */
static void put_job(const char *run, const char *name, int r, comparison_role role, const char *status,
                    const gate_image *im)
{
    char sd[600], path[1024], text[512];
    snprintf(sd, sizeof sd, "%s/%s", run, name);
    mkdir(run, 0755);
    mkdir(sd, 0755);
    job_output_path(run, name, r, role, "json", path, sizeof path);
    unlink(path);
    if (status != NULL) {
        snprintf(text, sizeof text, "{\"status\": \"%s\", \"message\": \"the %s message\", \"wall_s\": 0.5}\n", status,
                 status);
        write_text(path, text);
    }
    job_output_path(run, name, r, role, "exr", path, sizeof path);
    unlink(path);
    if (im != NULL)
        image_write(path, im);
}

/* Adds the scene's physics to a reference's validate record, as a real job writes it
 * (harness/jobs.c): compare holds a validate reference's record to the scene's physics. */
static void put_physics(const char *run, const char *name, int r, const char *scene_path)
{
    char path[1024], err[600], text[400];
    scene *s = malloc(sizeof *s);
    assert_non_null(s);
    assert_int_equal(scene_file_load(scene_path, s, err, sizeof err), RC_OK);
    physics_describe(&s->physics, s->n_lights, text, sizeof text);
    free(s);
    job_output_path(run, name, r, ROLE_VALIDATE, "json", path, sizeof path);
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    char buf[2048];
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = '\0';
    cJSON *o = cJSON_Parse(buf);
    assert_non_null(o);
    cJSON_AddStringToObject(o, "physics", text);
    char *out = cJSON_Print(o);
    write_text(path, out);
    free(out);
    cJSON_Delete(o);
}

/* A scene comparing raster against POV-Ray in `role`, with a rel_rms gate the flat images
 * pass by far; `extra` is more YAML for the material (e.g. a D3D9Client block). */
static void put_scene(const char *path, const char *name, const char *role, const char *model, const char *extra)
{
    char text[2048];
    snprintf(text, sizeof text,
             "name: %s\n"
             "image: {width: %d, height: %d}\n"
             "camera: {eye: [0, 0, 4], target: [0, 0, 0], hfov: 40}\n"
             "lights:\n  - {type: sun, direction: [0, 0, -1], irradiance: [1, 1, 1]}\n"
             "materials:\n  m: {model: %s%s}\n"
             "objects:\n  - {shape: quad, size: [10, 10], rotate: [90, 0, 0], material: m}\n"
             "comparisons:\n"
             "  - reference: povray\n    role: %s\n    thresholds:\n"
             "      rel_rms: {warn: 5e-4, fail: 1e-3, why: \"twin precision floor\"}\n",
             name, W, H, model, extra, role);
    write_text(path, text);
}

/* The fixture most tests share: scene file DIR/<name>.yaml comparing raster with POV-Ray
 * (put_scene), run folder DIR/run-<name>, and both sides' images flat at 0.5. */
typedef struct {
    char name[64], scn[512], run[512];
    gate_image t, r; /* the test (raster) and the reference (POV-Ray) image */
} gate_fixture;

static gate_fixture *fixture_make(const char *name, const char *role, const char *model, const char *extra)
{
    static gate_fixture f;
    snprintf(f.name, sizeof f.name, "%s", name);
    snprintf(f.scn, sizeof f.scn, "%s/%s.yaml", dir, name);
    snprintf(f.run, sizeof f.run, "%s/run-%s", dir, name);
    put_scene(f.scn, name, role, model, extra);
    image_flat(&f.t, 0.5f);
    image_flat(&f.r, 0.5f);
    return &f;
}

/* Both sides' job records (ok) and images, in role. */
static void fixture_jobs(const gate_fixture *f, comparison_role role)
{
    put_job(f->run, f->name, registry_find("raster"), role, "ok", &f->t);
    put_job(f->run, f->name, registry_find("povray"), role, "ok", &f->r);
}

static cJSON *read_compare(const char *run, const char *name)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/%s/compare.json", run, name);
    FILE *f = fopen(path, "r");
    if (f == NULL)
        fail_msg("no %s", path);
    static char buf[1 << 20];
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = '\0';
    cJSON *j = cJSON_Parse(buf);
    assert_non_null(j);
    return j;
}

static const cJSON *first_comparison(const cJSON *j)
{
    const cJSON *c = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(j, "comparisons"), 0);
    assert_non_null(c);
    return c;
}

static const char *jstr(const cJSON *o, const char *key)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
    return cJSON_IsString(v) ? v->valuestring : "";
}

static double jnum(const cJSON *o, const char *key)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
    if (!cJSON_IsNumber(v))
        fail_msg("key %s is not a number", key);
    return v->valuedouble;
}

static int setup(void **state)
{
    (void)state;
    snprintf(dir, sizeof dir, "/tmp/reflcheck-gates-%ld", (long)getpid());
    mkdir(dir, 0755);
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    return system(cmd) == 0 ? 0 : -1;
}

/* The issue's case: a test image 86 % NaN on the surface passed a twin rel_rms gate, because
 * the metrics skip NaN pixels and the 14 % left agree exactly. */
static void test_nan_surface_fails_twin(void **state)
{
    (void)state;
    char err[2048];
    gate_fixture *f = fixture_make("nan", "twin", "d3d", "");
    for (int i = 0; i < 110; i++) /* 110 of 128 pixels: 86 % */
        f->t.rgb[0][i] = NAN;
    fixture_jobs(f, ROLE_TWIN);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", f->scn, f->run), 1);
    assert_non_null(strstr(err, "110 non-finite (first R at (x 0, y 0) = nan)"));
    cJSON *j = read_compare(f->run, "nan");
    const cJSON *c = first_comparison(j);
    assert_string_equal(jstr(c, "status"), "fail");
    assert_non_null(strstr(jstr(c, "reason"), "test raster: 110 non-finite"));
    assert_int_equal((long)jnum(c, "test_nonfinite"), 110);
    assert_int_equal((long)jnum(c, "ref_nonfinite"), 0);
    const cJSON *vt = cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(c, "values"), "test");
    /* R, G, B, 9 term layers (a twin reads them), 3 var layers, coverage, object: 17 x 128. */
    assert_int_equal((long)jnum(vt, "channels"), 17);
    assert_int_equal((long)jnum(vt, "values"), 17 * NP);
    /* The metrics say how many pixels they used: 18 finite of 128. */
    const cJSON *surf = cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(c, "regions"), "surface");
    assert_int_equal((long)jnum(surf, "n_pixels"), 18);
    assert_int_equal((long)jnum(surf, "n_nonfinite"), 110);
    /* The rel_rms threshold itself still passes: the gate alone fails the comparison. */
    const cJSON *th = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(c, "thresholds"), 0);
    assert_string_equal(jstr(th, "verdict"), "pass");
    cJSON_Delete(j);
}

/* An Inf in a layer the RGB metrics never look at (the reference's specular term in a twin),
 * and negative radiance in the reference, each fail the comparison. */
static void test_inf_layer_and_negative_fail(void **state)
{
    (void)state;
    char err[2048];
    gate_fixture *f = fixture_make("inf", "twin", "d3d", "");
    const char *scn = f->scn, *run = f->run;
    gate_image *r = &f->r;
    r->terms[1][2][5 * W + 3] = INFINITY; /* specular.B at (x 3, y 5) */
    fixture_jobs(f, ROLE_TWIN);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), 1);
    cJSON *j = read_compare(run, "inf");
    const cJSON *c = first_comparison(j);
    assert_string_equal(jstr(c, "status"), "fail");
    assert_int_equal((long)jnum(c, "ref_nonfinite"), 1);
    assert_non_null(strstr(jstr(c, "reason"), "ref povray: 1 non-finite (first specular.B at (x 3, y 5) = inf)"));
    cJSON_Delete(j);

    image_flat(r, 0.5f);
    for (int i = 0; i < 3; i++)
        r->rgb[1][W + i] = -1e-3f; /* G at (0..2, 1) */
    put_job(run, "inf", registry_find("povray"), ROLE_TWIN, "ok", r);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), 1);
    j = read_compare(run, "inf");
    c = first_comparison(j);
    assert_string_equal(jstr(c, "status"), "fail");
    assert_int_equal((long)jnum(c, "ref_negative"), 3);
    assert_non_null(strstr(jstr(c, "reason"), "3 negative (first G at (x 0, y 1) = -0.001)"));
    cJSON_Delete(j);

    /* A negative variance is never allowed, and its NaN noise_rel_rms = sqrt(< 0) fails its
     * threshold instead of passing it (NaN compares false with both limits). */
    char text[1024];
    snprintf(text, sizeof text,
             "name: inf\nimage: {width: %d, height: %d}\ncamera: {eye: [0, 0, 4], target: [0, 0, 0], hfov: 40}\n"
             "materials:\n  m: {model: d3d}\n"
             "objects:\n  - {shape: quad, size: [10, 10], rotate: [90, 0, 0], material: m}\n"
             "comparisons:\n  - reference: povray\n    thresholds:\n"
             "      noise_rel_rms: {warn: 1, fail: 2, why: \"any finite noise passes\"}\n",
             W, H);
    write_text(scn, text);
    image_flat(r, 0.5f);
    for (int c3 = 0; c3 < 3; c3++)
        for (int i = 0; i < NP; i++)
            r->var[c3][i] = -1.0f;
    put_job(run, "inf", registry_find("povray"), ROLE_TWIN, "ok", r);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), 1);
    j = read_compare(run, "inf");
    c = first_comparison(j);
    const cJSON *th = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(c, "thresholds"), 0);
    assert_string_equal(jstr(th, "metric"), "noise_rel_rms");
    assert_string_equal(jstr(th, "verdict"), "fail");
    assert_true(cJSON_IsNull(cJSON_GetObjectItemCaseSensitive(th, "value")));
    assert_int_equal((long)jnum(c, "ref_negative"), 3 * NP);
    cJSON_Delete(j);
}

/* Negative radiance is the model's own where a D3D9Client |reflect| exceeds 1 (diffuse weight
 * 1 - |lambda| < 0): counted, allowed in our render and the twin, still refused in a
 * physical (validate) reference. */
static void test_negative_allowed_only_where_model_allows(void **state)
{
    (void)state;
    char err[2048];
    gate_fixture *f = fixture_make("neg", "twin", "d3d9client", ", d3d9client: {reflect: [1, 1, 1], norm: euclid}");
    const char *scn = f->scn, *run = f->run;
    /* The same negative pixel on both sides. */
    f->t.rgb[0][7] = -0.25f;
    f->r = f->t;
    fixture_jobs(f, ROLE_TWIN);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), 0);
    cJSON *j = read_compare(run, "neg");
    const cJSON *c = first_comparison(j);
    assert_string_equal(jstr(c, "status"), "pass");
    assert_int_equal((long)jnum(c, "test_negative"), 1);
    assert_int_equal((long)jnum(c, "ref_negative"), 1);
    cJSON_Delete(j);

    put_scene(scn, "neg", "validate", "d3d9client", ", d3d9client: {reflect: [1, 1, 1], norm: euclid}");
    fixture_jobs(f, ROLE_VALIDATE);
    put_physics(run, "neg", registry_find("povray"), scn);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), 1);
    j = read_compare(run, "neg");
    c = first_comparison(j);
    assert_string_equal(jstr(c, "status"), "fail");
    assert_non_null(strstr(jstr(c, "reason"), "ref povray: 1 negative"));
    assert_null(strstr(jstr(c, "reason"), "test raster"));
    cJSON_Delete(j);

    /* The same negative value in a scene whose model cannot go negative fails on both sides. */
    put_scene(scn, "neg", "twin", "d3d", "");
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), 1);
    j = read_compare(run, "neg");
    c = first_comparison(j);
    assert_non_null(strstr(jstr(c, "reason"), "test raster: 1 negative (first R at (x 7, y 0) = -0.25)"));
    cJSON_Delete(j);
}

/* Only a job whose record says skipped skips; failed, crashed, timeout, error, a missing
 * record and an unreadable image are errors, and compare exits 1 for them. */
static void test_job_status_vocabulary(void **state)
{
    (void)state;
    char err[2048], path[1024];
    gate_fixture *f = fixture_make("st", "twin", "d3d", "");
    const char *scn = f->scn, *run = f->run;
    fixture_jobs(f, ROLE_TWIN);

    static const char *const bad[] = {"failed", "crashed", "timeout", "error"};
    for (int i = 0; i < 4; i++) {
        put_job(run, "st", registry_find("povray"), ROLE_TWIN, bad[i], NULL);
        assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), 1);
        cJSON *j = read_compare(run, "st");
        const cJSON *c = first_comparison(j);
        assert_string_equal(jstr(c, "status"), "error");
        char want[128];
        snprintf(want, sizeof want, "povray twin job %s: the %s message", bad[i], bad[i]);
        if (strstr(jstr(c, "reason"), want) == NULL)
            fail_msg("status %s: reason '%s' lacks '%s'", bad[i], jstr(c, "reason"), want);
        assert_non_null(strstr(err, want));
        cJSON_Delete(j);
    }

    put_job(run, "st", registry_find("povray"), ROLE_TWIN, "skipped", NULL);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), 0);
    cJSON *j = read_compare(run, "st");
    assert_string_equal(jstr(first_comparison(j), "status"), "skipped");
    assert_non_null(strstr(jstr(first_comparison(j), "reason"), "povray twin skipped: the skipped message"));
    cJSON_Delete(j);

    put_job(run, "st", registry_find("povray"), ROLE_TWIN, NULL, NULL);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), 1);
    j = read_compare(run, "st");
    assert_string_equal(jstr(first_comparison(j), "status"), "error");
    assert_non_null(strstr(jstr(first_comparison(j), "reason"), "no job record"));
    cJSON_Delete(j);

    /* A record saying ok beside an image that is not an EXR. */
    put_job(run, "st", registry_find("povray"), ROLE_TWIN, "ok", NULL);
    job_output_path(run, "st", registry_find("povray"), ROLE_TWIN, "exr", path, sizeof path);
    write_text(path, "not an exr\n");
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), 1);
    j = read_compare(run, "st");
    assert_string_equal(jstr(first_comparison(j), "status"), "error");
    assert_non_null(strstr(jstr(first_comparison(j), "reason"), "image cannot be read"));
    cJSON_Delete(j);

    /* The test side's own error wins over a skipped reference. */
    put_job(run, "st", registry_find("raster"), ROLE_TWIN, "crashed", NULL);
    put_job(run, "st", registry_find("povray"), ROLE_TWIN, "skipped", NULL);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), 1);
    j = read_compare(run, "st");
    assert_string_equal(jstr(first_comparison(j), "status"), "error");
    cJSON_Delete(j);
}

/* Exit status of compare: 0 ok (pass), 1 fail (a threshold), 2 bad input. */
static void test_compare_exit_status(void **state)
{
    (void)state;
    char err[2048];
    gate_fixture *f = fixture_make("ex", "twin", "d3d", "");
    const char *scn = f->scn, *run = f->run;
    fixture_jobs(f, ROLE_TWIN);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), 0);
    cJSON *j = read_compare(run, "ex");
    assert_string_equal(jstr(first_comparison(j), "status"), "pass");
    assert_int_equal((long)jnum(first_comparison(j), "test_nonfinite"), 0);
    cJSON_Delete(j);

    image_flat(&f->r, 0.6f); /* rel_rms 0.1 / sqrt(0.36 + 1e-8) = 0.167 > 1e-3 */
    put_job(run, "ex", registry_find("povray"), ROLE_TWIN, "ok", &f->r);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), 1);
    assert_non_null(strstr(err, "rel_rms = 0.1667 > fail threshold"));

    assert_int_equal(cli_exec(err, sizeof err, "compare %s", scn), 2);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s/missing.yaml --run %s", dir, run), 2);
    assert_non_null(strstr(err, "missing.yaml"));
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s/no-such-run", scn, dir), 2);
    assert_non_null(strstr(err, "no-such-run: No such file or directory"));
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, scn), 2);
    assert_non_null(strstr(err, "not a directory"));
}

/* Two scene files with one name would share RUN/<name>/: refused before anything is written. */
static void test_duplicate_scene_names(void **state)
{
    (void)state;
    char a[512], b[512], run[512], err[2048], path[1024];
    snprintf(a, sizeof a, "%s/a.yaml", dir);
    snprintf(b, sizeof b, "%s/b.yaml", dir);
    snprintf(run, sizeof run, "%s/run-dup", dir);
    put_scene(a, "same", "twin", "d3d", "");
    put_scene(b, "same", "twin", "d3d", "");
    static gate_image t;
    image_flat(&t, 0.5f);
    put_job(run, "same", registry_find("raster"), ROLE_TWIN, "ok", &t);
    put_job(run, "same", registry_find("povray"), ROLE_TWIN, "ok", &t);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s %s --run %s", a, b, run), 2);
    assert_non_null(strstr(err, "a.yaml"));
    assert_non_null(strstr(err, "b.yaml"));
    assert_non_null(strstr(err, "'same'"));
    snprintf(path, sizeof path, "%s/same/compare.json", run);
    assert_int_equal(access(path, F_OK), -1);
    /* One of them alone is fine. */
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", b, run), 0);
}

/* diff: 0 ok, 1 the value gate fails or the output cannot be written, 2 bad input. */
static void test_diff_exit_status(void **state)
{
    (void)state;
    char a[512], b[512], c[512], small[512], err[2048], cmd[2048];
    snprintf(a, sizeof a, "%s/d-a.exr", dir);
    snprintf(b, sizeof b, "%s/d-b.exr", dir);
    snprintf(c, sizeof c, "%s/d-c.exr", dir);
    snprintf(small, sizeof small, "%s/d-small.exr", dir);
    static gate_image im;
    image_flat(&im, 0.5f);
    image_write(a, &im);
    im.rgb[2][W * H - 1] = NAN;
    image_write(b, &im);
    static float px[4] = {0.5f, 0.5f, 0.5f, 0.5f};
    exr_channel tiny[3] = {{"R", px}, {"G", px}, {"B", px}};
    assert_int_equal(exr_write(small, 2, 2, tiny, 3, NULL, 0, err, sizeof err), RC_OK);
    snprintf(c, sizeof c, "%s/d-missing.exr", dir);

    assert_int_equal(cli_exec(err, sizeof err, "diff %s %s", a, a), 0);
    assert_int_equal(cli_exec(err, sizeof err, "diff %s %s", b, a), 1);
    assert_non_null(strstr(err, "test "));
    assert_non_null(strstr(err, "1 non-finite (first B at (x 15, y 7) = nan)"));
    assert_int_equal(cli_exec(err, sizeof err, "diff %s %s", a, c), 2);
    assert_int_equal(cli_exec(err, sizeof err, "diff %s %s", a, small), 2);
    assert_int_equal(cli_exec(err, sizeof err, "diff %s", a), 2);
    assert_int_equal(cli_exec(err, sizeof err, "diff %s %s --bogus", a, a), 2);

    /* stdout on a full disk: the metrics are lost, so the command failed. */
    snprintf(cmd, sizeof cmd, "%s diff %s %s >/dev/full 2>/dev/null", cli_bin(), a, a);
    int st = system(cmd);
    assert_true(WIFEXITED(st));
    assert_int_equal(WEXITSTATUS(st), 1);
}

/* A scene named after its file `<!--<script>.yaml` broke the report's image viewer: view.js
 * is a script file, where `<!--` opens a comment. The name is written escaped (and the scene
 * parser now also maps such characters in a default name to '_'). */
static void test_view_js_escapes_scene_name(void **state)
{
    (void)state;
    char scn[512], run[512], err[2048], path[1200];
    snprintf(scn, sizeof scn, "%s/<!--<script>.yaml", dir);
    snprintf(run, sizeof run, "%s/run-js", dir);
    put_scene(scn, "x", "twin", "d3d", "");
    /* put_scene writes a name: key; drop it so the name comes from the file name. */
    char text[2048];
    FILE *f = fopen(scn, "r");
    assert_non_null(f);
    size_t n = fread(text, 1, sizeof text - 1, f);
    fclose(f);
    text[n] = '\0';
    write_text(scn, strchr(text, '\n') + 1);
    static scene sc;
    assert_int_equal(scene_file_load(scn, &sc, err, sizeof err), RC_OK);
    static gate_image t;
    image_flat(&t, 0.5f);
    put_job(run, sc.name, registry_find("raster"), ROLE_TWIN, "ok", &t);
    put_job(run, sc.name, registry_find("povray"), ROLE_TWIN, "ok", &t);
    assert_int_equal(cli_exec(err, sizeof err, "compare '%s' --run %s", scn, run), 0);
    snprintf(path, sizeof path, "%s/%s/view.js", run, sc.name);
    f = fopen(path, "r");
    assert_non_null(f);
    static char js[1 << 16];
    n = fread(js, 1, sizeof js - 1, f);
    fclose(f);
    js[n] = '\0';
    assert_null(strchr(js, '<'));
    /* The object after the assignment is JSON whose scene is the name, whatever its characters
     * (the parser may also map them to safe ones: then this holds trivially). */
    const char *prefix = "window.REFLCHECK_VIEW = ";
    assert_memory_equal(js, prefix, strlen(prefix));
    char *end = strrchr(js, ';');
    assert_non_null(end);
    *end = '\0';
    cJSON *view = cJSON_Parse(js + strlen(prefix));
    assert_non_null(view);
    assert_string_equal(jstr(view, "scene"), sc.name);
    cJSON_Delete(view);
}

/* Against Cycles (crease rules back_face and valid_reflection), the model's crease layer sets
 * pixels apart as the crease region, counted per rule and gated: 2 of 128 surface pixels
 * (1.6 %) pass, 3 (2.3 %) exceed COMPARE_CREASE_MAX_SHARE (2 %) and fail the comparison by
 * themselves, though its rel_rms passes, unless the scene states its own limit. A layer value
 * that is no layer bit (8) sets nothing apart. */
static void crease_case(const char *name, int n_crease, const char *stated, int want_fail)
{
    char scn[512], run[512], text[1024], err[2048];
    snprintf(scn, sizeof scn, "%s/%s.yaml", dir, name);
    snprintf(run, sizeof run, "%s/run-%s", dir, name);
    snprintf(text, sizeof text,
             "name: %s\nimage: {width: %d, height: %d}\n"
             "camera: {eye: [0, 0, 4], target: [0, 0, 0], hfov: 40}\n"
             "lights:\n  - {type: sun, direction: [0, 0, -1], irradiance: [1, 1, 1]}\n"
             "materials:\n  m: {model: d3d}\n"
             "objects:\n  - {shape: quad, size: [10, 10], rotate: [90, 0, 0], material: m}\n"
             "comparisons:\n  - reference: cycles\n    role: twin\n    thresholds:\n"
             "      rel_rms: {warn: 5e-4, fail: 1e-3, why: \"twin precision floor\"}\n%s",
             name, W, H, stated);
    write_text(scn, text);
    static gate_image t, r;
    image_flat(&t, 0.5f);
    image_flat(&r, 0.5f);
    t.has_crease = 1;
    for (int i = 0; i < n_crease; i++)
        t.crease[40 + i] = 2.0f; /* valid_reflection */
    t.crease[100] = 8.0f;
    put_job(run, name, registry_find("raster"), ROLE_TWIN, "ok", &t);
    put_job(run, name, registry_find("cycles"), ROLE_TWIN, "ok", &r);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), want_fail);
    cJSON *j = read_compare(run, name);
    const cJSON *c = first_comparison(j);
    const cJSON *cr = cJSON_GetObjectItemCaseSensitive(c, "crease");
    assert_int_equal((long)jnum(cr, "pixels"), n_crease);
    const cJSON *pr = cJSON_GetObjectItemCaseSensitive(cr, "per_rule");
    assert_int_equal((long)jnum(pr, "valid_reflection"), n_crease);
    assert_int_equal((long)jnum(pr, "back_face"), 0);
    const cJSON *reg = cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(c, "regions"), "crease");
    assert_int_equal((long)jnum(reg, "n_pixels"), n_crease);
    const cJSON *surf = cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(c, "regions"), "surface");
    assert_int_equal((long)jnum(surf, "n_pixels"), NP - n_crease);
    assert_int_equal((long)jnum(surf, "crease_pixels"), n_crease); /* beside the surface figures */
    assert_string_equal(jstr(c, "status"), want_fail ? "fail" : "pass");
    if (want_fail)
        assert_non_null(strstr(jstr(c, "reason"), "crease region 3 of 128 surface pixels"));
    cJSON_Delete(j);
}

static void test_crease_region_gated(void **state)
{
    (void)state;
    crease_case("crease_small", 2, "", 0);
    crease_case("crease_large", 3, "", 1);
    /* A scene that states its own limit is judged by it: 2.3 % under 5 % passes. */
    crease_case("crease_stated", 3,
                "      crease.share_of_surface: {warn: 0.03, fail: 0.05, why: \"the mesh's own creases\"}\n", 0);
}

/* A twin against POV-Ray (no crease rules) moves the pixels whose crease layer has the tie bit
 * (4, harness/crease.h CREASE_TIE) to the edges and reports them as the region "ties": 1 of 128
 * surface pixels (0.78 %) exceeds COMPARE_TIE_MAX_SHARE (0.5 %) and fails by itself, though the
 * images are equal, unless the scene states ties.share_of_surface. */
static void ties_case(const char *name, const char *stated, int want_fail)
{
    char scn[512], run[512], text[1024], err[2048];
    snprintf(scn, sizeof scn, "%s/%s.yaml", dir, name);
    snprintf(run, sizeof run, "%s/run-%s", dir, name);
    snprintf(text, sizeof text,
             "name: %s\nimage: {width: %d, height: %d}\n"
             "camera: {eye: [0, 0, 4], target: [0, 0, 0], hfov: 40}\n"
             "lights:\n  - {type: sun, direction: [0, 0, -1], irradiance: [1, 1, 1]}\n"
             "materials:\n  m: {model: d3d}\n"
             "objects:\n  - {shape: quad, size: [10, 10], rotate: [90, 0, 0], material: m}\n"
             "comparisons:\n  - reference: povray\n    role: twin\n    thresholds:\n"
             "      rel_rms: {warn: 5e-4, fail: 1e-3, why: \"twin precision floor\"}\n%s",
             name, W, H, stated);
    write_text(scn, text);
    static gate_image t, r;
    image_flat(&t, 0.5f);
    image_flat(&r, 0.5f);
    t.has_crease = 1;
    t.crease[70] = 4.0f;
    put_job(run, name, registry_find("raster"), ROLE_TWIN, "ok", &t);
    put_job(run, name, registry_find("povray"), ROLE_TWIN, "ok", &r);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), want_fail);
    cJSON *j = read_compare(run, name);
    const cJSON *c = first_comparison(j);
    const cJSON *regions = cJSON_GetObjectItemCaseSensitive(c, "regions");
    const cJSON *ties = cJSON_GetObjectItemCaseSensitive(regions, "ties");
    assert_int_equal((long)jnum(ties, "pixels"), 1);
    assert_int_equal((long)jnum(cJSON_GetObjectItemCaseSensitive(regions, "surface"), "n_pixels"), NP - 1);
    assert_string_equal(jstr(c, "status"), want_fail ? "fail" : "pass");
    if (want_fail)
        assert_non_null(strstr(jstr(c, "reason"), "tie region 1 of 128 surface pixels"));
    cJSON_Delete(j);
}

static void test_ties_region_gated(void **state)
{
    (void)state;
    ties_case("ties_default", "", 1);
    ties_case("ties_stated", "      ties.share_of_surface: {warn: 0.01, fail: 0.02, why: \"a crack\"}\n", 0);
}

/* A comparison whose thresholds only guard its inputs (finite values, coverage) is measured and
 * shown but never called pass: "not_gated"; one accuracy threshold makes it pass again. */
static void test_guards_alone_are_not_gated(void **state)
{
    (void)state;
    char err[2048], scn[512], run[512], text[1024];
    snprintf(scn, sizeof scn, "%s/guards.yaml", dir);
    snprintf(run, sizeof run, "%s/run-guards", dir);
    static const char *const gates[2] = {
        "      test_nonfinite: {warn: 0, fail: 0, why: \"finite output\"}\n"
        "      coverage_agreement: {warn: 0.9995, fail: 0.999, why: \"same triangles\"}\n",
        "      test_nonfinite: {warn: 0, fail: 0, why: \"finite output\"}\n"
        "      rel_rms: {warn: 5e-4, fail: 1e-3, why: \"twin precision floor\"}\n"};
    static const char *const want[2] = {"not_gated", "pass"};
    static gate_image im;
    image_flat(&im, 0.5f);
    for (int k = 0; k < 2; k++) {
        snprintf(text, sizeof text,
                 "name: guards\nimage: {width: %d, height: %d}\ncamera: {eye: [0, 0, 4], target: [0, 0, 0], hfov: 40}\n"
                 "materials:\n  m: {model: d3d}\n"
                 "objects:\n  - {shape: quad, size: [10, 10], rotate: [90, 0, 0], material: m}\n"
                 "comparisons:\n  - reference: povray\n    role: twin\n    thresholds:\n%s",
                 W, H, gates[k]);
        write_text(scn, text);
        put_job(run, "guards", registry_find("raster"), ROLE_TWIN, "ok", &im);
        put_job(run, "guards", registry_find("povray"), ROLE_TWIN, "ok", &im);
        assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), 0);
        cJSON *j = read_compare(run, "guards");
        assert_string_equal(jstr(first_comparison(j), "status"), want[k]);
        cJSON_Delete(j);
    }
}

/* Sets the variant ("small" or "full") of a side's job record, as jobs.c writes it. */
static void put_variant(const char *run, const char *name, int r, comparison_role role, const char *variant)
{
    char path[1024], buf[2048];
    job_output_path(run, name, r, role, "json", path, sizeof path);
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = '\0';
    cJSON *o = cJSON_Parse(buf);
    assert_non_null(o);
    cJSON_AddStringToObject(o, "variant", variant);
    char *out = cJSON_Print(o);
    write_text(path, out);
    free(out);
    cJSON_Delete(o);
}

/* A gate given per size: the same images (rel_rms 0.002: 0.001 apart on 0.5, over
 * sqrt(0.25 + 1e-4)) pass the shared fail 0.02 the small variant is judged by and fail the
 * full: block's 0.001; compare.json says which size and which levels applied, and the figure
 * the gate was sized on. A record without a variant (an older run) is the full size. */
static void test_gate_per_size(void **state)
{
    (void)state;
    char err[2048], text[1024];
    gate_fixture *f = fixture_make("sizes", "twin", "d3d", "");
    snprintf(text, sizeof text,
             "name: sizes\nimage: {width: %d, height: %d}\ncamera: {eye: [0, 0, 4], target: [0, 0, 0], hfov: 40}\n"
             "materials:\n  m: {model: d3d}\n"
             "objects:\n  - {shape: quad, size: [10, 10], rotate: [90, 0, 0], material: m}\n"
             "comparisons:\n  - reference: povray\n    role: twin\n    thresholds:\n"
             "      rel_rms: {warn: 0.01, fail: 0.02, why: \"guard\", sized: {figure: 0.008, size: small, run: s1},\n"
             "                full: {warn: 5e-4, fail: 1e-3, sized: {figure: 4e-4, run: n1}}}\n",
             W, H);
    write_text(f->scn, text);
    for (int c = 0; c < 3; c++)
        for (int i = 0; i < NP; i++)
            f->t.rgb[c][i] = 0.501f;
    static const struct {
        const char *variant, *status, *size, *levels, *sized_size;
        double fail;
    } want[] = {
        {"small", "pass", "small", "shared", "small", 0.02},
        {"full", "fail", "full", "full", "full", 1e-3},
        {NULL, "fail", "full", "full", "full", 1e-3},
    };
    for (size_t k = 0; k < sizeof want / sizeof want[0]; k++) {
        fixture_jobs(f, ROLE_TWIN);
        if (want[k].variant != NULL) {
            put_variant(f->run, "sizes", registry_find("raster"), ROLE_TWIN, want[k].variant);
            put_variant(f->run, "sizes", registry_find("povray"), ROLE_TWIN, want[k].variant);
        }
        int rc = cli_exec(err, sizeof err, "compare %s --run %s", f->scn, f->run);
        cJSON *j = read_compare(f->run, "sizes");
        const cJSON *c = first_comparison(j);
        const cJSON *th = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(c, "thresholds"), 0);
        if (strcmp(jstr(c, "status"), want[k].status) != 0)
            fail_msg("variant %s: status %s, want %s", want[k].variant, jstr(c, "status"), want[k].status);
        assert_int_equal(rc, strcmp(want[k].status, "fail") == 0);
        close_rel(jnum(cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(c, "regions"), "surface"),
                       "rel_rms"),
                  0.001 / sqrt(0.25 + 1e-4), 1e-3);
        assert_string_equal(jstr(th, "size"), want[k].size);
        assert_string_equal(jstr(th, "levels"), want[k].levels);
        close_rel(jnum(th, "fail"), want[k].fail, 1e-12);
        assert_string_equal(jstr(cJSON_GetObjectItemCaseSensitive(th, "sized"), "size"), want[k].sized_size);
        if (strcmp(want[k].status, "fail") == 0)
            assert_non_null(strstr(err, "at full size (guard); scene key comparisons[0].thresholds.rel_rms.full"));
        cJSON_Delete(j);
    }
}

/* An offset of 0.8 standard deviations on every pixel passes the per-pixel z-test (its Holm
 * limit is near 4), and the mean's z is 0.8 sqrt(N) on the N surface pixels: its gate fails. */
static void test_bias_over_every_pixel_fails(void **state)
{
    (void)state;
    char err[2048];
    gate_fixture *f = fixture_make("bias", "twin", "d3d", "");
    put_scene(f->scn, "bias", "twin", "d3d", "");
    FILE *fp = fopen(f->scn, "a");
    assert_non_null(fp);
    fputs("      bias.z_max: {warn: 3, fail: 5, why: \"no offset beyond the mean's noise\"}\n", fp);
    fclose(fp);
    for (int c = 0; c < 3; c++)
        for (int i = 0; i < NP; i++) {
            f->r.var[c][i] = 1e-4f; /* sd 0.01 */
            f->t.rgb[c][i] = 0.5f + 0.008f;
        }
    fixture_jobs(f, ROLE_TWIN);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", f->scn, f->run), 1);
    cJSON *j = read_compare(f->run, "bias");
    const cJSON *c = first_comparison(j);
    const cJSON *z = cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(c, "noise"), "ztest");
    assert_true(jnum(z, "n_fail_pixels") == 0.0);
    double n =
        jnum(cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(c, "regions"), "surface"), "n_pixels");
    const cJSON *b = cJSON_GetObjectItemCaseSensitive(c, "bias");
    /* float offsets: 0.508f - 0.5f is 0.008 to 1e-6 relative; the float floor adds 1e-10 of
     * variance per pixel to the 1e-4 */
    close_rel(jnum(b, "z_max"), 0.008 * n / sqrt(n * (1e-4f + 25e-12)), 1e-4);
    close_rel(jnum(b, "rel"), 0.008 / 0.5, 1e-4);
    assert_true(jnum(b, "z_max") > 5.0);
    assert_string_equal(jstr(b, "term"), "image");
    const cJSON *th = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(c, "thresholds"), 1);
    assert_string_equal(jstr(th, "metric"), "bias.z_max");
    assert_string_equal(jstr(th, "verdict"), "fail");
    cJSON_Delete(j);

    /* The same images as a twin against a path tracer that states no bias threshold: the
     * built-in gate (5 standard errors without the worst 1 %) fails it, and the reason says so. */
    char text[1024];
    snprintf(text, sizeof text,
             "name: bias\nimage: {width: %d, height: %d}\ncamera: {eye: [0, 0, 4], target: [0, 0, 0], hfov: 40}\n"
             "materials:\n  m: {model: d3d}\n"
             "objects:\n  - {shape: quad, size: [10, 10], rotate: [90, 0, 0], material: m}\n"
             "comparisons:\n  - reference: cycles\n    role: twin\n    thresholds:\n"
             "      z_fail_share: {warn: 0.0005, fail: 0.002, why: \"beyond Cycles noise\"}\n",
             W, H);
    write_text(f->scn, text);
    put_job(f->run, "bias", registry_find("raster"), ROLE_TWIN, "ok", &f->t);
    put_job(f->run, "bias", registry_find("cycles"), ROLE_TWIN, "ok", &f->r);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", f->scn, f->run), 1);
    j = read_compare(f->run, "bias");
    c = first_comparison(j);
    assert_string_equal(jstr(c, "status"), "fail");
    assert_non_null(strstr(jstr(c, "reason"), "bias: the image term's mean"));
    cJSON_Delete(j);

    /* A twin whose test image covers half the pixels (a camera the reference cannot take)
     * fails the built-in coverage gate though its surface figures agree. */
    for (int i = 0; i < NP; i++) {
        for (int k = 0; k < 3; k++)
            f->t.rgb[k][i] = 0.5f;
        f->r.var[0][i] = f->r.var[1][i] = f->r.var[2][i] = 1e-4f;
        f->t.cov[i] = i < NP / 2 ? 1.0f : 0.0f;
    }
    put_job(f->run, "bias", registry_find("raster"), ROLE_TWIN, "ok", &f->t);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", f->scn, f->run), 1);
    j = read_compare(f->run, "bias");
    c = first_comparison(j);
    assert_string_equal(jstr(c, "status"), "fail");
    assert_non_null(strstr(jstr(c, "reason"), "coverage: 0.5 of the pixels agree"));
    cJSON_Delete(j);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_nan_surface_fails_twin),
        cmocka_unit_test(test_inf_layer_and_negative_fail),
        cmocka_unit_test(test_negative_allowed_only_where_model_allows),
        cmocka_unit_test(test_job_status_vocabulary),
        cmocka_unit_test(test_compare_exit_status),
        cmocka_unit_test(test_duplicate_scene_names),
        cmocka_unit_test(test_diff_exit_status),
        cmocka_unit_test(test_view_js_escapes_scene_name),
        cmocka_unit_test(test_crease_region_gated),
        cmocka_unit_test(test_ties_region_gated),
        cmocka_unit_test(test_guards_alone_are_not_gated),
        cmocka_unit_test(test_gate_per_size),
        cmocka_unit_test(test_bias_over_every_pixel_fails),
    };
    return cmocka_run_group_tests_name("gates", tests, setup, teardown);
}
