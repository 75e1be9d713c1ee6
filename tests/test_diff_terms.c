/* test_diff_terms.c - `reflcheck diff --leave-out`: a partial twin's sweep compares the terms
 * both sides render. A test image whose specular layer the reference lacks (Cycles' twin of a
 * Blinn-Phong lobe) differs from it by that layer alone; left out, the pair is equal. Images are
 * flat 8 x 4 EXRs written here, so every metric is known by hand. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cJSON.h>

#include "cli_exec.h"
#include "diff_terms.h"
#include "exr.h"

#define W 8
#define H 4

static char dir[64];

/* A flat image: R = G = B = diffuse + specular, its four term layers, full coverage, object 0;
 * with_specular 0 writes no specular layer at all. */
static void put_image(const char *name, float diffuse, float specular, int with_specular)
{
    static float d[W * H], s[W * H], z[W * H], one[W * H], total[W * H];
    for (int i = 0; i < W * H; i++) {
        d[i] = diffuse;
        s[i] = specular;
        z[i] = 0.0f;
        one[i] = 1.0f;
        total[i] = diffuse + specular;
    }
    exr_channel ch[] = {{"R", total},        {"G", total},        {"B", total},        {"coverage", one},
                        {"object", z},       {"diffuse.R", d},    {"diffuse.G", d},    {"diffuse.B", d},
                        {"reflection.R", z}, {"reflection.G", z}, {"reflection.B", z}, {"emission.R", z},
                        {"emission.G", z},   {"emission.B", z},   {"specular.R", s},   {"specular.G", s},
                        {"specular.B", s}};
    char path[128], err[512];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    int n = (int)(sizeof ch / sizeof ch[0]) - (with_specular ? 0 : 3);
    if (exr_write(path, W, H, ch, n, NULL, 0, err, sizeof err) != RC_OK)
        fail_msg("%s", err);
}

/* The surface RMSE `reflcheck diff` prints for the pair, with --leave-out opt (NULL: none). */
static double diff_rmse(const char *test, const char *ref, const char *opt)
{
    char err[1024], out[128];
    snprintf(out, sizeof out, "%s/diff.json", dir);
    int rc = sh_exec(err, sizeof err, "%s diff %s/%s %s/%s%s%s > %s", cli_bin(), dir, test, dir, ref,
                     opt ? " --leave-out " : "", opt ? opt : "", out);
    if (rc != 0)
        fail_msg("diff exited %d: %s", rc, err);
    FILE *f = fopen(out, "r");
    assert_non_null(f);
    static char buf[1 << 16];
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = '\0';
    cJSON *j = cJSON_Parse(buf);
    assert_non_null(j);
    const cJSON *r = cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(j, "surface"), "rmse");
    assert_true(cJSON_IsNumber(r));
    double v = r->valuedouble;
    cJSON_Delete(j);
    return v;
}

static void test_leave_out_compares_the_shared_terms(void **state)
{
    (void)state;
    put_image("model.exr", 0.5f, 0.25f, 1);
    put_image("twin.exr", 0.5f, 0.0f, 1);
    /* Whole image: the missing lobe, 0.25 in every channel. */
    assert_true(fabs(diff_rmse("model.exr", "twin.exr", NULL) - 0.25) < 1e-6);
    /* The shared terms: equal. */
    assert_true(diff_rmse("model.exr", "twin.exr", "specular") < 1e-7);
    /* Leaving out a term both render alike changes nothing. */
    assert_true(fabs(diff_rmse("model.exr", "twin.exr", "emission") - 0.25) < 1e-6);
}

static void test_refusals(void **state)
{
    (void)state;
    char err[1024];
    unsigned bits;
    put_image("bare.exr", 0.5f, 0.0f, 0);
    put_image("model.exr", 0.5f, 0.25f, 1);
    assert_int_equal(diff_terms_parse("specular,emission", &bits, err, sizeof err), RC_OK);
    assert_int_equal(bits, 2u | 8u);
    assert_int_equal(diff_terms_parse("specular,glow", &bits, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, "'glow' is not a term"));
    assert_int_equal(diff_terms_parse("diffuse,specular,reflection,emission", &bits, err, sizeof err), RC_ERR_PARSE);
    /* An image without the layer cannot give the term up: named, and the CLI says bad input. */
    int rc = cli_exec(err, sizeof err, "diff %s/model.exr %s/bare.exr --leave-out specular", dir, dir);
    assert_int_equal(rc, 2);
    assert_non_null(strstr(err, "bare.exr: no specular.R channel"));
    /* A message about a stripped image names the user's file, not the private copy. */
    put_image("neg.exr", -0.1f, 0.25f, 1);
    rc = cli_exec(err, sizeof err, "diff %s/neg.exr %s/model.exr --leave-out specular", dir, dir);
    assert_int_equal(rc, 1);
    if (!strstr(err, "test_diff_terms.") || !strstr(err, "/neg.exr: ") || strstr(err, "reflcheck-diff-"))
        fail_msg("%s", err);
    rc = cli_exec(err, sizeof err, "diff %s/model.exr %s/bare.exr --leave-out shine", dir, dir);
    assert_int_equal(rc, 2);
    assert_non_null(strstr(err, "'shine' is not a term"));
}

static int setup(void **state)
{
    (void)state;
    snprintf(dir, sizeof dir, "/tmp/test_diff_terms.XXXXXX");
    return mkdtemp(dir) ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    return system(cmd) == 0 ? 0 : -1;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_leave_out_compares_the_shared_terms),
        cmocka_unit_test(test_refusals),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
