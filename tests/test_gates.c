/* test_gates.c - gates that count everything: job statuses mapped to comparison statuses
 * (only a skipped job skips; a crash, a timeout, a missing record or an unreadable image is
 * an error).
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

#include "cli_exec.h"
#include "exr.h"
#include "jobs.h"

enum { W = 16, H = 8, NP = W * H };

static char dir[256];

/* One render: R, G, B, the three term layers, var.*, coverage and object, all planes NP. */
typedef struct {
    float rgb[3][NP], terms[3][3][NP], var[3][NP], cov[NP], obj[NP];
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
    }
}

static void image_write(const char *path, const gate_image *im)
{
    static const char *const names[] = {"R", "G", "B", "diffuse.R", "diffuse.G", "diffuse.B", "specular.R",
                                        "specular.G", "specular.B", "reflection.R", "reflection.G",
                                        "reflection.B", "var.R", "var.G", "var.B", "coverage", "object"};
    const float *planes[17] = {im->rgb[0], im->rgb[1], im->rgb[2]};
    for (int t = 0; t < 3; t++)
        for (int c = 0; c < 3; c++)
            planes[3 + 3 * t + c] = im->terms[t][c];
    for (int c = 0; c < 3; c++)
        planes[12 + c] = im->var[c];
    planes[15] = im->cov;
    planes[16] = im->obj;
    exr_channel ch[17];
    for (int i = 0; i < 17; i++)
        ch[i] = (exr_channel){names[i], planes[i]};
    char err[512];
    assert_int_equal(exr_write(path, W, H, ch, 17, NULL, 0, err, sizeof err), RC_OK);
}

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    assert_int_equal(fclose(f), 0);
}

/* The job record and image of one side of scene `name` in run `run`; status NULL: no record. */
static void put_job(const char *run, const char *name, renderer_id r, comparison_role role, const char *status,
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

/* Only a job whose record says skipped skips; failed, crashed, timeout, error, a missing
 * record and an unreadable image are errors, and compare exits 1 for them. */
static void test_job_status_vocabulary(void **state)
{
    (void)state;
    char scn[512], run[512], err[2048], path[1024];
    snprintf(scn, sizeof scn, "%s/st.yaml", dir);
    snprintf(run, sizeof run, "%s/run-st", dir);
    put_scene(scn, "st", "twin", "d3d", "");
    static gate_image t;
    image_flat(&t, 0.5f);
    put_job(run, "st", RENDERER_RASTER, ROLE_TWIN, "ok", &t);

    static const char *const bad[] = {"failed", "crashed", "timeout", "error"};
    for (int i = 0; i < 4; i++) {
        put_job(run, "st", RENDERER_POVRAY, ROLE_TWIN, bad[i], NULL);
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

    put_job(run, "st", RENDERER_POVRAY, ROLE_TWIN, "skipped", NULL);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), 0);
    cJSON *j = read_compare(run, "st");
    assert_string_equal(jstr(first_comparison(j), "status"), "skipped");
    assert_non_null(strstr(jstr(first_comparison(j), "reason"), "povray twin skipped: the skipped message"));
    cJSON_Delete(j);

    put_job(run, "st", RENDERER_POVRAY, ROLE_TWIN, NULL, NULL);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), 1);
    j = read_compare(run, "st");
    assert_string_equal(jstr(first_comparison(j), "status"), "error");
    assert_non_null(strstr(jstr(first_comparison(j), "reason"), "no job record"));
    cJSON_Delete(j);

    /* A record saying ok beside an image that is not an EXR. */
    put_job(run, "st", RENDERER_POVRAY, ROLE_TWIN, "ok", NULL);
    job_output_path(run, "st", RENDERER_POVRAY, ROLE_TWIN, "exr", path, sizeof path);
    write_text(path, "not an exr\n");
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), 1);
    j = read_compare(run, "st");
    assert_string_equal(jstr(first_comparison(j), "status"), "error");
    assert_non_null(strstr(jstr(first_comparison(j), "reason"), "image cannot be read"));
    cJSON_Delete(j);

    /* The test side's own error wins over a skipped reference. */
    put_job(run, "st", RENDERER_RASTER, ROLE_TWIN, "crashed", NULL);
    put_job(run, "st", RENDERER_POVRAY, ROLE_TWIN, "skipped", NULL);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), 1);
    j = read_compare(run, "st");
    assert_string_equal(jstr(first_comparison(j), "status"), "error");
    cJSON_Delete(j);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_job_status_vocabulary),
    };
    return cmocka_run_group_tests_name("gates", tests, setup, teardown);
}
