/* test_partial_twin.c - a twin whose reference cannot reproduce one term compares the terms
 * both sides computed and says which it left out (issue 11, item 3).
 *
 * The scene a new user would write: a Lambert floor and a sphere with a D3D Blinn-Phong
 * highlight in the infinite-viewer mode, twinned in POV-Ray (no infinite viewer) and Cycles
 * (no Blinn-Phong lobe). Both references leave the specular out; the comparisons must pass
 * as partial twins naming it, where the full images would have failed. Runs the real POV-Ray
 * and Blender through the production job path (harness/jobs.c) and compare_scene.
 */
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

#include "compare.h"
#include "exr.h"
#include "fileio.h"
#include "jobs.h"

static char work[128], scene_path[256], run_dir[256];

/* Thresholds as the canonical twins have them (scenes/lambert_calibration.yaml). */
static const char scene_text[] =
    "name: partial\n"
    "image: {width: 64, height: 48, supersample: 2, samples: 32}\n"
    "camera: {eye: [0.2, 1.3, 3.4], target: [0, 0.45, 0], hfov: 42}\n"
    "lights:\n"
    "  - {type: point, position: [1.8, 2.6, 2.2], intensity: [20, 20, 20]}\n"
    "materials:\n"
    "  shiny: {albedo: [0.6, 0.25, 0.15], model: d3d,\n"
    "          d3d: {specular: [0.6, 0.6, 0.6], power: 20, local_viewer: false}}\n"
    "  floor: {albedo: [0.35, 0.45, 0.55], model: d3d}\n"
    "objects:\n"
    "  - {shape: sphere, center: [0, 0.5, 0], radius: 0.5, tessellation: 64, material: shiny}\n"
    "  - {shape: quad, center: [0, 0, 0], size: [4, 4], material: floor}\n"
    "comparisons:\n"
    "  - reference: povray\n"
    "    role: twin\n"
    "    thresholds:\n"
    "      rel_rms: {warn: 5.0e-4, fail: 1.0e-3, why: \"POV-Ray writes half-float EXR\"}\n"
    "  - reference: cycles\n"
    "    role: twin\n"
    "    thresholds:\n"
    "      z_fail_share: {warn: 0.0005, fail: 0.002, why: \"error beyond Cycles noise\"}\n";

static int setup(void **state)
{
    (void)state;
    snprintf(work, sizeof work, "/tmp/reflcheck-test-partial-%ld", (long)getpid());
    snprintf(scene_path, sizeof scene_path, "%s/partial.yaml", work);
    snprintf(run_dir, sizeof run_dir, "%s/run", work);
    mkdir(work, 0755);
    FILE *f = fopen(scene_path, "w");
    if (f == NULL)
        return 1;
    fputs(scene_text, f);
    return fclose(f) != 0;
}

static int teardown(void **state)
{
    (void)state;
    if (getenv("REFLCHECK_KEEP"))
        return 0;
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf %s", work);
    return system(cmd) != 0;
}

static void run_job(const char *renderer)
{
    job_spec j = {.scene_path = scene_path,
                  .renderer = registry_find(renderer),
                  .role = ROLE_TWIN,
                  .variant = JOB_FULL,
                  .out_dir = run_dir,
                  .threads = 2};
    job_record r;
    char err[1024];
    rc_status st = job_run(&j, &r, err, sizeof err);
    if (st != RC_OK)
        fail_msg("%s job: %s", renderer, err);
    if (r.status != RUNNER_OK)
        fail_msg("%s job: %s: %s", renderer, runner_status_name(r.status), r.message);
}

static cJSON *read_json(const char *path)
{
    char *text = fileio_read_all(path, NULL);
    assert_non_null(text);
    cJSON *j = cJSON_Parse(text);
    free(text);
    assert_non_null(j);
    return j;
}

static const char *str_of(const cJSON *o, const char *key)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
    return cJSON_IsString(v) ? v->valuestring : "";
}

/* The record lists exactly one left-out term, specular, with a reason holding `because`. */
static void check_record(const char *renderer, const char *because)
{
    char path[400];
    snprintf(path, sizeof path, "%s/partial/%s-twin.json", run_dir, renderer);
    cJSON *rec = read_json(path);
    const cJSON *gaps = cJSON_GetObjectItemCaseSensitive(rec, "terms_left_out");
    assert_int_equal(cJSON_GetArraySize(gaps), 1);
    assert_string_equal(str_of(cJSON_GetArrayItem(gaps, 0), "term"), "specular");
    if (strstr(str_of(cJSON_GetArrayItem(gaps, 0), "reason"), because) == NULL)
        fail_msg("%s: reason '%s' does not say '%s'", renderer, str_of(cJSON_GetArrayItem(gaps, 0), "reason"), because);
    cJSON_Delete(rec);
}

/* Relative RMS over fully covered pixels, computed here apart from compare.c: the reference's
 * R, G, B against the sum of the rasterizer's layers named in `layers` (NULL-terminated; ""
 * = its R, G, B). */
static double rel_rms_against(const exr_image *ras, const exr_image *ref, const char *const *layers)
{
    const float *cov = exr_image_channel(ras, "coverage");
    assert_non_null(cov);
    double num = 0.0, den = 0.0;
    for (int c = 0; c < 3; c++) {
        char name[64];
        snprintf(name, sizeof name, "%c", "RGB"[c]);
        const float *r = exr_image_channel(ref, name);
        assert_non_null(r);
        for (int p = 0; p < ras->width * ras->height; p++) {
            if (cov[p] < 1.0f)
                continue;
            double t = 0.0;
            for (int l = 0; layers[l] != NULL; l++) {
                if (layers[l][0])
                    snprintf(name, sizeof name, "%s.%c", layers[l], "RGB"[c]);
                else
                    snprintf(name, sizeof name, "%c", "RGB"[c]);
                const float *ch = exr_image_channel(ras, name);
                assert_non_null(ch);
                t += ch[p];
            }
            num += (t - r[p]) * (t - r[p]);
            den += (double)r[p] * r[p];
        }
    }
    return sqrt(num / den);
}

static void read_exr(const char *renderer, exr_image *img)
{
    char path[400], err[512];
    snprintf(path, sizeof path, "%s/partial/%s-twin.exr", run_dir, renderer);
    if (exr_read(path, img, err, sizeof err) != RC_OK)
        fail_msg("%s", err);
}

static void test_partial_twins(void **state)
{
    (void)state;
    run_job("raster");
    run_job("povray");
    run_job("cycles");
    check_record("povray", "infinite viewer");
    check_record("cycles", "Blinn-Phong");

    exr_image ras, pov, cyc;
    read_exr("raster", &ras);
    read_exr("povray", &pov);
    read_exr("cycles", &cyc);
    /* The left-out term is no small part of the image: the highlight carries light. */
    const float *spec = exr_image_channel(&ras, "specular.G"), *cov = exr_image_channel(&ras, "coverage");
    double smax = 0.0;
    for (int p = 0; p < ras.width * ras.height; p++)
        if (cov[p] >= 1.0f && spec[p] > smax)
            smax = spec[p];
    printf("# raster specular.G peak %.4f\n", smax);
    assert_true(smax > 0.1);
    /* POV-Ray's image is the sum of the terms it rendered: against the rasterizer's diffuse +
     * reflection + emission it sits at the half-float floor, against the full image it is far
     * off. */
    static const char *const rest[] = {"diffuse", "reflection", "emission", NULL};
    static const char *const full[] = {"", NULL};
    double pov_rest = rel_rms_against(&ras, &pov, rest), pov_full = rel_rms_against(&ras, &pov, full);
    printf("# povray: rel_rms %.3g against diffuse + reflection + emission, %.3g against the full image\n", pov_rest,
           pov_full);
    assert_true(pov_rest < 1.0e-3);
    assert_true(pov_full > 1.0e-2);
    exr_image_free(&pov);
    exr_image_free(&cyc);
    exr_image_free(&ras);

    /* The full images, judged as compare.c judged them before: both fail their gates. */
    char t[400], r[400], err[1024];
    snprintf(t, sizeof t, "%s/partial/raster-twin.exr", run_dir);
    snprintf(r, sizeof r, "%s/partial/cycles-twin.exr", run_dir);
    char *buf = NULL;
    size_t len = 0;
    FILE *out = open_memstream(&buf, &len);
    int failed = 0;
    assert_int_equal(compare_images(t, r, NULL, out, &failed, err, sizeof err), RC_OK);
    fclose(out);
    cJSON *d = cJSON_Parse(buf);
    free(buf);
    assert_non_null(d);
    const cJSON *z = cJSON_GetObjectItemCaseSensitive(
        cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(d, "noise"), "ztest"), "share_fail_pixels");
    assert_true(cJSON_IsNumber(z));
    printf("# cycles full image: %.1f %% of surface pixels beyond noise (fail above 0.2 %%)\n", 100.0 * z->valuedouble);
    assert_true(z->valuedouble > 0.002);
    cJSON_Delete(d);

    /* The comparisons: both pass as partial twins and say what they left out and why. */
    compare_summary sum;
    assert_int_equal(compare_scene(scene_path, run_dir, &sum, err, sizeof err), RC_OK);
    if (sum.fail + sum.error + sum.warn != 0)
        fail_msg("partial twins: %d fail, %d error, %d warn: %s", sum.fail, sum.error, sum.warn, sum.first_failure);
    assert_int_equal(sum.pass, 2);
    char path[400];
    snprintf(path, sizeof path, "%s/partial/compare.json", run_dir);
    cJSON *cmp = read_json(path);
    const cJSON *c;
    int n = 0;
    cJSON_ArrayForEach(c, cJSON_GetObjectItemCaseSensitive(cmp, "comparisons"))
    {
        n++;
        assert_string_equal(str_of(c, "status"), "pass");
        const cJSON *tc = cJSON_GetObjectItemCaseSensitive(c, "terms_compared");
        assert_int_equal(cJSON_GetArraySize(tc), 3);
        assert_string_equal(cJSON_GetArrayItem(tc, 0)->valuestring, "diffuse");
        assert_string_equal(cJSON_GetArrayItem(tc, 1)->valuestring, "reflection");
        assert_string_equal(cJSON_GetArrayItem(tc, 2)->valuestring, "emission");
        const cJSON *lo = cJSON_GetObjectItemCaseSensitive(c, "terms_left_out");
        assert_int_equal(cJSON_GetArraySize(lo), 1);
        assert_string_equal(str_of(cJSON_GetArrayItem(lo, 0), "term"), "specular");
        const char *why = str_of(cJSON_GetArrayItem(lo, 0), "reason");
        assert_true(strncmp(why, str_of(c, "reference"), strlen(str_of(c, "reference"))) == 0);
        assert_non_null(strstr(str_of(c, "reason"), "partial twin: compared diffuse, reflection, emission; left out "
                                                    "specular"));
        /* No specular layer metric: that term was not compared. */
        assert_null(cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(c, "aovs"), "specular"));
        printf("# %s: %s\n", str_of(c, "id"), str_of(c, "reason"));
    }
    assert_int_equal(n, 2);
    cJSON_Delete(cmp);
}

int main(void)
{
    if (!runner_available("povray") || !runner_available("blender")) {
        fprintf(stderr, "test_partial_twin: povray and blender must be on PATH (CI installs both)\n");
        return 1;
    }
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_partial_twins),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
