/* test_cycles_samples.c - a Cycles job's samples from its gates' noise (cycles_samples.h).
 * Expected values are worked out by hand in the comments; the noise image is written here with
 * known variances, 3 x 2 pixels, one of them uncovered.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cmocka.h>

#include "check.h"

#include "renderers/cycles/cycles_samples.h"
#include "renderers/registry.h"
#include "exr.h"
#include "scene.h"

static void add_gate(comparison *c, const char *metric, double fail)
{
    threshold *t = &c->thresholds[c->n_thresholds++];
    memset(t, 0, sizeof *t);
    snprintf(t->metric, sizeof t->metric, "%s", metric);
    t->warn = fail / 2.0;
    t->fail = fail;
}

/* Comparisons: model/cycles twin (z-test alone), model/cycles validate nrmse 0.9 and
 * glossy.nrmse 0.3 (full size: 0.15) and a z-test, povray/cycles agree rel_rms 0.06 and ssim
 * (not an RMS metric), model/povray twin rel_rms 0.0003 (not Cycles: ignored). */
static void fixture(scene *s, int cyc, int model, int pov)
{
    scene_init(s);
    snprintf(s->path, sizeof s->path, "fixture.yaml");
    s->samples_line = 4;
    comparison *c = s->comparisons;
    c[0] = (comparison){.test = model, .reference = cyc, .role = ROLE_TWIN};
    add_gate(&c[0], "z_fail_share", 0.002);
    c[1] = (comparison){.test = model, .reference = cyc, .role = ROLE_VALIDATE};
    add_gate(&c[1], "nrmse", 0.9);
    add_gate(&c[1], "glossy.nrmse", 0.3);
    c[1].thresholds[1].at[1].set = c[1].thresholds[1].at[1].fail_set = 1;
    c[1].thresholds[1].at[1].fail = 0.15;
    add_gate(&c[1], "z_fail_share", 0.01);
    c[2] = (comparison){.test = pov, .reference = cyc, .role = ROLE_AGREE};
    add_gate(&c[2], "rel_rms", 0.06);
    add_gate(&c[2], "ssim", 0.99);
    c[3] = (comparison){.test = model, .reference = pov, .role = ROLE_TWIN};
    add_gate(&c[3], "rel_rms", 0.0003);
    s->n_comparisons = 4;
}

static void test_need_of_roles(void **state)
{
    (void)state;
    int cyc = registry_find("cycles"), pov = registry_find("povray"), model = registry_find("raster");
    assert_true(cyc >= 0 && pov >= 0 && model >= 0);
    scene s;
    fixture(&s, cyc, model, pov);
    cycles_noise_need need;
    /* validate serves validate and agree: RMS min(0.9, 0.3, 0.06) / 3 = 0.02, from the agree's
     * rel_rms; its z-test takes b from its own comparison's smallest RMS fail, 0.3 (small) */
    cycles_noise_need_of(&s, cyc, ROLE_VALIDATE, 0, &need);
    assert_false(need.refuse);
    close_rel(need.target, 0.02, 1e-12);
    assert_non_null(strstr(need.gate, "comparisons[2] povray/agree rel_rms fail 0.06"));
    close_rel(need.bias, 0.3, 1e-12);
    assert_non_null(strstr(need.zgate, "comparisons[1] raster/validate z_fail_share bias 0.3 (its RMS fail)"));
    /* full size: glossy.nrmse's own full block, 0.15, is the z-test's b */
    cycles_noise_need_of(&s, cyc, ROLE_VALIDATE, 1, &need);
    close_rel(need.bias, 0.15, 1e-12);
    /* twin serves the twin alone: a z-test with no RMS gate and no stated bias is refused,
     * naming the scene line and the fix */
    cycles_noise_need_of(&s, cyc, ROLE_TWIN, 0, &need);
    assert_true(need.refuse);
    assert_non_null(strstr(need.why, "fixture.yaml:4: image.samples auto: comparisons[0] raster/twin z_fail_share is "
                                     "a z-test with no bias size; write image.samples: {auto: true, bias: B"));
    /* stated: the scene's bias is its b, and no RMS target */
    s.samples_bias = 0.05;
    cycles_noise_need_of(&s, cyc, ROLE_TWIN, 0, &need);
    assert_false(need.refuse);
    close_rel(need.bias, 0.05, 1e-12);
    assert_true(need.target == 0.0);
    assert_non_null(strstr(need.zgate, "(image.samples bias)"));
    /* and the stated bias wins over a comparison's RMS fail: the validate's z-test takes 0.05 */
    cycles_noise_need_of(&s, cyc, ROLE_VALIDATE, 0, &need);
    close_rel(need.bias, 0.05, 1e-12);
    assert_non_null(strstr(need.zgate, "comparisons[1] raster/validate z_fail_share bias 0.05 (image.samples bias)"));
    /* a bias gate in standard errors cannot be decided, stated bias or not */
    add_gate(&s.comparisons[0], "bias.z_trim1_max", 5.0);
    cycles_noise_need_of(&s, cyc, ROLE_TWIN, 0, &need);
    assert_true(need.refuse);
    assert_non_null(strstr(need.why, "comparisons[0] raster/twin bias.z_trim1_max counts standard errors"));
    /* an nrmse_trim1 gate asks its own target, of the trimmed noise: 0.03 / 3 = 0.01, naming it;
     * the whole noise's target stays the rel_rms's 0.02 */
    add_gate(&s.comparisons[2], "nrmse_trim1", 0.03);
    cycles_noise_need_of(&s, cyc, ROLE_VALIDATE, 0, &need);
    close_rel(need.target_trim1, 0.01, 1e-12);
    close_rel(need.target, 0.02, 1e-12);
    assert_non_null(strstr(need.gate_trim1, "comparisons[2] povray/agree nrmse_trim1 fail 0.03"));
    /* without the agree, the validate's glossy.nrmse 0.3 / 3 = 0.1 sets the RMS target */
    s.n_comparisons = 2;
    cycles_noise_need_of(&s, cyc, ROLE_VALIDATE, 0, &need);
    close_rel(need.target, 0.1, 1e-12);
    /* a background gate asks nothing of the surface's noise */
    s.comparisons[1].n_thresholds = 0;
    add_gate(&s.comparisons[1], "background.rel_rms", 0.0012);
    cycles_noise_need_of(&s, cyc, ROLE_VALIDATE, 0, &need);
    assert_true(need.target == 0.0 && need.target_trim1 == 0.0);
    /* a render no comparison gates by an RMS metric or a z-test asks nothing */
    s.comparisons[1].n_thresholds = 0;
    cycles_noise_need_of(&s, cyc, ROLE_VALIDATE, 0, &need);
    assert_true(need.target == 0.0 && need.bias == 0.0 && !need.refuse);
}

/* Quantiles from Python's statistics.NormalDist().inv_cdf, a second implementation: z_beta =
 * Phi^-1(0.9) = 1.2815516; m = 1: Phi^-1(1 - 0.005) = 2.5758293, span 3.8573809; m = 3000:
 * Phi^-1(1 - 0.01 / 6000) = 4.6491329, span 5.9306845. */
static void test_ztest_span(void **state)
{
    (void)state;
    close_rel(cycles_ztest_span(1), 3.8573808690935, 1e-9);
    close_rel(cycles_ztest_span(0), 3.8573808690935, 1e-9); /* fewer than one value counts as one */
    close_rel(cycles_ztest_span(3000), 5.9306844995521, 1e-9);
    /* b 0.1 over 3000 values: 0.1 / 5.9306845 = 0.0168615; no z-test: 0 */
    cycles_noise_need need = {.bias = 0.1, .target = 0.02};
    close_rel(cycles_ztest_target(&need, 3000), 0.016861460090745, 1e-9);
    need.bias = 0.0;
    assert_true(cycles_ztest_target(&need, 3000) == 0.0);
}

static void test_samples_for(void **state)
{
    (void)state;
    /* pilot 16 spp at noise 0.05, target 0.02: 16 (0.05 / 0.02)^2 = 100 */
    assert_int_equal(cycles_samples_for(0.05, 16, 0.02), 100);
    /* 0.0501: 16 * 6.275025 = 100.4 -> 101 (rounded up: the target is a bound) */
    assert_int_equal(cycles_samples_for(0.0501, 16, 0.02), 101);
    /* a z-test's target, b 0.1 over 3000 values: 16 (0.2 / 0.0168615)^2 = 2251.07 -> 2252 */
    assert_int_equal(cycles_samples_for(0.2, 16, 0.016861460090745), 2252);
    /* already quiet enough, or nothing asked: the pilot is the render */
    assert_int_equal(cycles_samples_for(0.019, 16, 0.02), 16);
    assert_int_equal(cycles_samples_for(5.0, 16, 0.0), 16);
    /* capped: 16 (1 / 0.02)^2 = 40000 > CYCLES_MAX_SPP */
    assert_int_equal(cycles_samples_for(1.0, 16, 0.02), CYCLES_MAX_SPP);
}

/* Each noise against its own target, the largest count wins, rounded up to a power of two per
 * position. Pilot 16 spp: nrmse 0.05, pixel_q 0.2 over 3000 values; RMS target 0.02 -> 100
 * (above) -> 128; z-test b 0.1 -> 2252 (above) -> 4096. */
static void test_samples_need(void **state)
{
    (void)state;
    cycles_noise pilot = {.nrmse = 0.05, .pixel_q = 0.2, .n_values = 3000};
    cycles_noise_need need = {.target = 0.02, .bias = 0.1};
    assert_int_equal(cycles_samples_need(&pilot, 16, 1, &need), 4096);
    need.bias = 0.0; /* no z-test: the RMS gate's 100 -> 128 */
    assert_int_equal(cycles_samples_need(&pilot, 16, 1, &need), 128);
    /* a twin's 3 x 3 positions: 100 / 9 = 11.1 per position -> 16 -> 144 */
    assert_int_equal(cycles_samples_need(&pilot, 18, 9, &need), 144);
    need.bias = 0.1; /* a quiet pixel_q 0.01 <= 0.0168615: the RMS gate's 128 again */
    pilot.pixel_q = 0.01;
    assert_int_equal(cycles_samples_need(&pilot, 16, 1, &need), 128);
    need.target_trim1 = 0.004; /* trim1 0.02 against 0.004: 16 * 25 = 400 -> 512 */
    pilot.trim1 = 0.02;
    assert_int_equal(cycles_samples_need(&pilot, 16, 1, &need), 512);
    need.target_trim1 = 0.0;
    need.target = 0.0; /* and nothing else asks: the pilot */
    assert_int_equal(cycles_samples_need(&pilot, 16, 1, &need), 16);
    /* steps of at most 4 x: 16 -> 64 when 4096 is asked, 64 -> 128 when 128 is */
    assert_int_equal(cycles_samples_step(16, 4096), 64);
    assert_int_equal(cycles_samples_step(64, 128), 128);
    assert_int_equal(cycles_samples_step(18, 144), 72);
    /* the pilot: two per position, at least 16 */
    assert_int_equal(cycles_pilot_samples(1), 16);
    assert_int_equal(cycles_pilot_samples(4), 16);
    assert_int_equal(cycles_pilot_samples(16), 32);
    assert_int_equal(cycles_pilot_samples(9), 18);
}

static void test_exr_noise(void **state)
{
    (void)state;
    /* 6 x 4 pixels, as metrics_classify sees them (border neighbours skipped): column 3 half
     * covered (an edge, and so is column 2 beside it), columns 4-5 uncovered, row 3 another
     * object (rows 2-3 an object boundary). Interior: x 0..1, y 0..1, four pixels; every other
     * pixel holds 500 with variance 50, which would show. Interior R, G, B = 1, 2, 3, var 0.01,
     * but (1, 1): 2, 2, 2, var 0.04 -> values 3 * 6 + 6 = 24 over 12, mean 2; variances
     * 9 * 0.01 + 3 * 0.04 = 0.21, mean 0.0175; noise = sqrt(0.0175) / 2 = 0.0661438. Standard
     * errors: nine 0.1, three 0.2; the 0.9 quantile is the value of rank ceil(10.8) = 11, 0.2,
     * so pixel_q = 0.2 / 2 = 0.1 */
    enum { W = 6, H = 4, N = W * H };
    float r[N], g[N], b[N], v[N], cov[N], obj[N];
    for (int p = 0; p < N; p++) {
        int x = p % W, y = p / W, interior = x <= 1 && y <= 1;
        r[p] = interior ? 1.0f : 500.0f;
        g[p] = interior ? 2.0f : 500.0f;
        b[p] = interior ? 3.0f : 500.0f;
        v[p] = interior ? 0.01f : 50.0f;
        cov[p] = x <= 2 ? 1.0f : x == 3 ? 0.5f : 0.0f;
        obj[p] = y == 3 ? 1.0f : 0.0f;
    }
    r[W + 1] = g[W + 1] = b[W + 1] = 2.0f;
    v[W + 1] = 0.04f;
    exr_channel ch[] = {{"R", r},     {"G", g},     {"B", b},          {"var.R", v},
                        {"var.G", v}, {"var.B", v}, {"coverage", cov}, {"object", obj}};
    char dir[] = "/tmp/test_cycles_samples_XXXXXX", path[64], err[256];
    assert_non_null(mkdtemp(dir));
    snprintf(path, sizeof path, "%s/noise.exr", dir);
    assert_int_equal(exr_write(path, W, H, ch, 8, NULL, 0, err, sizeof err), RC_OK);
    cycles_noise noise = {0};
    assert_int_equal(cycles_exr_noise(path, &noise, err, sizeof err), RC_OK);
    close_rel(noise.nrmse, sqrt(0.0175) / 2.0, 1e-6);
    close_rel(noise.pixel_q, 0.1, 1e-6);
    /* trim1 drops ceil(0.01 * 4) = 1 pixel, the one of largest variance (1, 1): three pixels of
     * values 1, 2, 3 (mean 2) and variances 0.01: sqrt(0.09 / 9) / 2 = 0.05 */
    close_rel(noise.trim1, 0.05, 1e-6);
    assert_int_equal(noise.n_values, 12); /* four interior pixels, three channels */
    /* one seed: no var.* channels -> refused, naming the fix */
    assert_int_equal(exr_write(path, W, H, ch, 3, NULL, 0, err, sizeof err), RC_OK);
    assert_int_equal(cycles_exr_noise(path, &noise, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "no var.R/G/B channels"));
    unlink(path);
    rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_need_of_roles), cmocka_unit_test(test_ztest_span), cmocka_unit_test(test_samples_for),
        cmocka_unit_test(test_samples_need),  cmocka_unit_test(test_exr_noise),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
