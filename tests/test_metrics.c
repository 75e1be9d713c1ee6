/* test_metrics.c - metrics on hand-worked tiny images, masks, SSIM, the noise-aware z-test,
 * and a cross-check against OpenImageIO's idiff run on EXR files written by exr.c.
 * Expected numbers come from the formulas worked by hand (shown beside each) and, for
 * normal quantiles, from Python's statistics.NormalDist (Wichura's AS241, a different
 * algorithm from ours). */
#define _POSIX_C_SOURCE 200809L
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "exr.h"
#include "metrics.h"

#define REL(a, b, tol) assert_true(fabs((a) - (b)) <= (tol)*fabs(b))

/* ---- 3x2 hand-worked fixture ----
 * Reference (row-major, row 0 on top); every value exact in binary so differences are exact.
 *   R: 0.125 0.25  0.375 | 0.5   0.625 1.2
 *   G: 0.0625 0.125 0.375 | 0.5  0.25  0.75
 *   B: 0.875 0.75  0.625 | 0.5   0.375 0.25
 * Test = reference with G at (x 1, y 1) raised by 0.5 (0.25 -> 0.75). */
static float hr[6] = {0.125f, 0.25f, 0.375f, 0.5f, 0.625f, 1.2f};
static float hg[6] = {0.0625f, 0.125f, 0.375f, 0.5f, 0.25f, 0.75f};
static float hb[6] = {0.875f, 0.75f, 0.625f, 0.5f, 0.375f, 0.25f};
static float tr[6], tg[6], tb[6];

static void hand_images(metrics_image *ref, metrics_image *tst)
{
    memcpy(tr, hr, sizeof tr);
    memcpy(tg, hg, sizeof tg);
    memcpy(tb, hb, sizeof tb);
    tg[4] = 0.75f;
    *ref = (metrics_image){3, 2, {hr, hg, hb}};
    *tst = (metrics_image){3, 2, {tr, tg, tb}};
}

static void test_hand_3x2(void **state)
{
    (void)state;
    metrics_image ref, tst;
    hand_images(&ref, &tst);
    metrics_options opt = {0};
    opt.threshold = 0.1;
    metrics_result r;
    char err[256];
    assert_int_equal(metrics_compare(&ref, &tst, NULL, &opt, &r, err, sizeof err), RC_OK);
    assert_int_equal(r.n_pixels, 6);
    assert_int_equal(r.n_nonfinite, 0);
    REL(r.mae, 0.5 / 18.0, 1e-12);                        /* one error of 0.5 over 18 values */
    REL(r.rmse, sqrt(0.25 / 18.0), 1e-12);                /* 0.11785113019775792 */
    REL(r.rel_mse, 0.25 / (0.0625 + 0.01) / 18.0, 1e-12); /* r = 0.25 there: 0.19157088122605365 */
    REL(r.rel_rms, sqrt(0.25 / (0.0625 + 0.01) / 18.0), 1e-12);
    REL(r.peak, 1.2f, 0.0);                 /* idiff: max(1, largest |value|) = 1.2 */
    REL(r.psnr, 20.156950230411418, 1e-12); /* 20 log10(1.2 / 0.117851...) */
    assert_float_equal(r.max_abs, 0.5, 0.0);
    assert_int_equal(r.max_x, 1);
    assert_int_equal(r.max_y, 1);
    assert_int_equal(r.max_c, 1);
    assert_float_equal(r.max_ref, 0.25, 0.0);
    assert_float_equal(r.max_test, 0.75, 0.0);
    assert_float_equal(r.mae_ch[0], 0.0, 0.0);
    REL(r.mae_ch[1], 0.5 / 6.0, 1e-12);
    REL(r.rmse_ch[1], sqrt(0.25 / 6.0), 1e-12);
    assert_float_equal(r.max_abs_ch[1], 0.5, 0.0);
    assert_float_equal(r.max_abs_ch[2], 0.0, 0.0);
    assert_int_equal(r.n_over, 1);
    REL(r.share_over, 1.0 / 6.0, 1e-12);
    assert_true(r.ssim < 1.0 && r.ssim > 0.0);
    assert_float_equal(r.ssim_ch[0], 1.0, 1e-12); /* R and B untouched */
    assert_float_equal(r.ssim_ch[2], 1.0, 1e-12);
    assert_true(r.ssim_ch[1] < 1.0);

    /* Another epsilon changes only the relative error: 0.25 / (0.0625 + 1) / 18. */
    opt.rel_eps = 1.0;
    assert_int_equal(metrics_compare(&ref, &tst, NULL, &opt, &r, err, sizeof err), RC_OK);
    REL(r.rel_mse, 0.013071895424836602, 1e-12);
    /* A fixed peak of 1: 20 log10(1 / 0.117851...) = 10 log10(72). */
    opt.psnr_peak = 1.0;
    assert_int_equal(metrics_compare(&ref, &tst, NULL, &opt, &r, err, sizeof err), RC_OK);
    REL(r.psnr, 10.0 * log10(72.0), 1e-12);
}

static void test_masks_and_nonfinite(void **state)
{
    (void)state;
    metrics_image ref, tst;
    hand_images(&ref, &tst);
    metrics_result r;
    char err[256];
    unsigned char m[6] = {1, 1, 1, 1, 0, 1}; /* drop the differing pixel */
    assert_int_equal(metrics_compare(&ref, &tst, m, NULL, &r, err, sizeof err), RC_OK);
    assert_int_equal(r.n_pixels, 5);
    assert_float_equal(r.mae, 0.0, 0.0);
    assert_float_equal(r.max_abs, 0.0, 0.0);
    assert_true(isinf(r.psnr) && r.psnr > 0);
    assert_int_equal(r.n_over, 0);
    assert_float_equal(r.ssim, 1.0, 1e-12);

    unsigned char m2[6] = {0, 1, 1, 1, 1, 1}; /* drop pixel 0: 0.5 over 15 values */
    assert_int_equal(metrics_compare(&ref, &tst, m2, NULL, &r, err, sizeof err), RC_OK);
    assert_int_equal(r.n_pixels, 5);
    REL(r.mae, 0.5 / 15.0, 1e-12);

    tr[5] = NAN; /* a NaN in the test drops that pixel and is counted */
    assert_int_equal(metrics_compare(&ref, &tst, NULL, NULL, &r, err, sizeof err), RC_OK);
    assert_int_equal(r.n_nonfinite, 1);
    assert_int_equal(r.n_pixels, 5);
    REL(r.mae, 0.5 / 15.0, 1e-12);
    assert_true(isfinite(r.ssim));

    /* Tie: a second error of 0.5 earlier in scan order (x 0, y 1, B: 0.5 -> 1.0) wins. */
    hand_images(&ref, &tst);
    tb[3] = 1.0f;
    assert_int_equal(metrics_compare(&ref, &tst, NULL, NULL, &r, err, sizeof err), RC_OK);
    assert_int_equal(r.max_x, 0);
    assert_int_equal(r.max_y, 1);
    assert_int_equal(r.max_c, 2);
    REL(r.rmse, sqrt(0.5 / 18.0), 1e-12);

    /* Argument errors. */
    metrics_image small = {2, 2, {hr, hg, hb}};
    assert_int_equal(metrics_compare(&ref, &small, NULL, NULL, &r, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "2x2"));
    metrics_image hole = {3, 2, {hr, NULL, hb}};
    assert_int_equal(metrics_compare(&ref, &hole, NULL, NULL, &r, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "channel G"));
}

static void test_ssim(void **state)
{
    (void)state;
    enum { S = 16, SN = S * S };
    static float a[SN], b[SN], map[SN];
    char err[256];
    double mean;
    /* Constant grey images a = 0.5, b = 0.25: sigma terms vanish, so
     * SSIM = (2ab + C1) / (a^2 + b^2 + C1) with C1 = 1e-4: 0.8000639795265515. */
    for (int i = 0; i < SN; i++) {
        a[i] = 0.5f;
        b[i] = 0.25f;
    }
    metrics_image ia = {S, S, {a, a, a}}, ib = {S, S, {b, b, b}};
    metrics_result r;
    assert_int_equal(metrics_compare(&ia, &ib, NULL, NULL, &r, err, sizeof err), RC_OK);
    REL(r.ssim, 0.8000639795265515, 1e-9);
    REL(r.ssim_ch[1], 0.8000639795265515, 1e-9);
    metrics_options opt = {0};
    opt.ssim_range = 2.0; /* C1 = (0.01 * 2)^2 = 4e-4 */
    assert_int_equal(metrics_compare(&ia, &ib, NULL, &opt, &r, err, sizeof err), RC_OK);
    REL(r.ssim, 0.8002556727388942, 1e-9);

    /* Checkerboard 0.5 +- 0.1 against constant 0.5, 8x8 box window: wherever the window is
     * inside the image it holds 32 of each, so mu equal, sigma_x^2 = 0.01, sigma_xy = 0 and
     * SSIM = C2 / (0.01 + C2) = 0.08256880733944955 (C2 = 9e-4). */
    for (int y = 0; y < S; y++)
        for (int x = 0; x < S; x++) {
            a[y * S + x] = ((x + y) & 1) ? 0.6f : 0.4f;
            b[y * S + x] = 0.5f;
        }
    opt = (metrics_options){0};
    opt.ssim_window = METRICS_SSIM_BOX8;
    assert_int_equal(metrics_ssim_map(S, S, a, b, NULL, &opt, map, &mean, err, sizeof err), RC_OK);
    for (int y = 3; y <= S - 5; y++)
        for (int x = 3; x <= S - 5; x++)
            REL(map[y * S + x], 0.08256880733944955, 1e-5);
    /* Identical structured images score 1 everywhere, border windows included. */
    assert_int_equal(metrics_ssim_map(S, S, a, a, NULL, NULL, map, &mean, err, sizeof err), RC_OK);
    assert_float_equal(mean, 1.0, 1e-12);
    /* Excluded pixels do not enter any window: a garbage half outside the mask leaves the
     * score of the identical kept half at 1. */
    static unsigned char m[SN];
    for (int i = 0; i < SN; i++) {
        m[i] = (unsigned char)((i % S) < S / 2);
        b[i] = m[i] ? a[i] : 100.0f;
    }
    assert_int_equal(metrics_ssim_map(S, S, a, b, m, NULL, map, &mean, err, sizeof err), RC_OK);
    assert_float_equal(mean, 1.0, 1e-12);
    assert_float_equal(map[S - 1], 0.0, 0.0);
    opt.ssim_window = 7;
    assert_int_equal(metrics_ssim_map(S, S, a, b, NULL, &opt, map, &mean, err, sizeof err), RC_ERR_RANGE);
    REL(metrics_luminance(1, 0, 0) + metrics_luminance(0, 1, 0) + metrics_luminance(0, 0, 1), 1.0, 1e-15);
}

/* Direct 2-D evaluation of Wang et al.'s SSIM at one pixel, Gaussian sigma 1.5 over 11x11,
 * truncated at the border, two-pass moments: an independent check of the separable code. */
static double ssim_direct(int w, int h, const float *x, const float *y, int px, int py)
{
    double ws = 0, mx = 0, my = 0, sxx = 0, syy = 0, sxy = 0;
    for (int pass = 0; pass < 2; pass++) {
        for (int j = py - 5; j <= py + 5; j++)
            for (int i = px - 5; i <= px + 5; i++) {
                if (i < 0 || j < 0 || i >= w || j >= h)
                    continue;
                double g = exp(-((i - px) * (i - px) + (j - py) * (j - py)) / 4.5); /* 2 sigma^2 */
                double a = x[j * w + i], b = y[j * w + i];
                if (pass == 0) {
                    ws += g;
                    mx += g * a;
                    my += g * b;
                } else {
                    sxx += g * (a - mx) * (a - mx);
                    syy += g * (b - my) * (b - my);
                    sxy += g * (a - mx) * (b - my);
                }
            }
        if (pass == 0) {
            mx /= ws;
            my /= ws;
        }
    }
    sxx /= ws;
    syy /= ws;
    sxy /= ws;
    const double c1 = 1e-4, c2 = 9e-4;
    return ((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx * mx + my * my + c1) * (sxx + syy + c2));
}

static void test_ssim_gauss_direct(void **state)
{
    (void)state;
    enum { GW = 13, GH = 9, GN = GW * GH };
    float x[GN], y[GN], map[GN];
    uint32_t s = 77u;
    for (int i = 0; i < GN; i++) {
        s = s * 1664525u + 1013904223u;
        x[i] = 2.0f * (float)(s >> 8) / 16777216.0f;
        s = s * 1664525u + 1013904223u;
        y[i] = 0.7f * x[i] + 0.5f * (float)(s >> 8) / 16777216.0f;
    }
    double mean;
    char err[256];
    assert_int_equal(metrics_ssim_map(GW, GH, x, y, NULL, NULL, map, &mean, err, sizeof err), RC_OK);
    const int pts[][2] = {{6, 4}, {0, 0}, {12, 8}, {3, 7}, {10, 1}};
    for (size_t k = 0; k < sizeof pts / sizeof pts[0]; k++) {
        double want = ssim_direct(GW, GH, x, y, pts[k][0], pts[k][1]);
        if (!(fabs(map[pts[k][1] * GW + pts[k][0]] - want) <= 1e-6 * fabs(want)))
            fail_msg("SSIM at (%d, %d): %.9g, direct %.9g", pts[k][0], pts[k][1], map[pts[k][1] * GW + pts[k][0]],
                     want);
    }
}

static void test_classify(void **state)
{
    (void)state;
    /* 10x7: a full block x 1..6, y 1..5, object 1 in x 1..3 and 2 in x 4..6, and a
     * half-covered pixel (7, 3) of object 2. Expected classes worked by hand from the 3x3
     * rule (B background, I interior, E edge): */
    static const char *want[7] = {
        "EEEEEEEEBB", "EEEEEEEEBB", "EEIEEIEEEB", "EEIEEIEEEB", "EEIEEIEEEB", "EEEEEEEEBB", "EEEEEEEEBB",
    };
    enum { CW = 10, CH = 7 };
    float cov[CW * CH] = {0}, id[CW * CH] = {0};
    for (int y = 1; y <= 5; y++)
        for (int x = 1; x <= 6; x++) {
            cov[y * CW + x] = x == 6 ? 0.99999994f : 1.0f; /* one ulp short still counts as full */
            id[y * CW + x] = x <= 3 ? 1.0f : 2.0f;
        }
    cov[3 * CW + 7] = 0.5f;
    id[3 * CW + 7] = 2.0f;
    unsigned char cls[CW * CH], m[CW * CH];
    metrics_classify(CW, CH, cov, id, cls);
    for (int y = 0; y < CH; y++)
        for (int x = 0; x < CW; x++) {
            int e = want[y][x] == 'B'   ? METRICS_PX_BACKGROUND
                    : want[y][x] == 'I' ? METRICS_PX_INTERIOR
                                        : METRICS_PX_EDGE;
            if (cls[y * CW + x] != e)
                fail_msg("pixel (%d, %d): class %d, want %c", x, y, cls[y * CW + x], want[y][x]);
        }
    assert_int_equal(metrics_mask_from_class(CW, CH, cls, METRICS_PX_INTERIOR, NULL, 0, m), 6);
    assert_int_equal(metrics_mask_from_class(CW, CH, cls, METRICS_PX_BACKGROUND, NULL, 0, m), 11);
    assert_int_equal(metrics_mask_from_class(CW, CH, cls, METRICS_PX_EDGE, NULL, 0, m), 53);
    assert_int_equal(metrics_mask_from_class(CW, CH, cls, METRICS_PX_INTERIOR, id, 2.0f, m), 3);
    assert_int_equal(m[3 * CW + 5], 1);
    assert_int_equal(m[3 * CW + 2], 0);
    assert_int_equal(metrics_mask_from_class(CW, CH, cls, -1, id, 1.0f, m), 15);

    /* Without coverage only id boundaries count: columns 3 and 4 (where 1 meets 2) and the
     * 0 / 1, 2 / 0 boundaries; column 9 touches only ids 0 and stays interior. */
    metrics_classify(CW, CH, NULL, id, cls);
    assert_int_equal(cls[3 * CW + 9], METRICS_PX_INTERIOR);
    assert_int_equal(cls[3 * CW + 3], METRICS_PX_EDGE);
    assert_int_equal(cls[3 * CW + 2], METRICS_PX_INTERIOR);
}

/* ---- statistics ---- */

static double phi(double x) { return 0.5 * erfc(-x / sqrt(2.0)); }

static void test_norm_quantile(void **state)
{
    (void)state;
    REL(metrics_norm_quantile(0.975), 1.9599639845400536, 1e-14);
    REL(metrics_norm_quantile(0.995), 2.5758293035489, 1e-14);
    REL(metrics_norm_quantile(1e-10), -6.361340902404056, 1e-14);
    assert_float_equal(metrics_norm_quantile(0.5), 0.0, 1e-16);
    const double ps[] = {1e-300, 1e-100, 1e-20, 1e-5, 0.02425, 0.024250001, 0.3, 0.5 - 1e-9, 0.7, 0.999999};
    for (size_t i = 0; i < sizeof ps / sizeof ps[0]; i++) {
        double x = metrics_norm_quantile(ps[i]);
        REL(phi(x), ps[i], 1e-13);
        /* Symmetry: for q >= 0.5, 1 - q is exact, so Phi^-1(q) = -Phi^-1(1 - q) exactly. */
        double q = 1.0 - ps[i];
        if (q < 1.0)
            REL(metrics_norm_quantile(q), -metrics_norm_quantile(1.0 - q), 1e-15);
    }
    assert_true(isinf(metrics_norm_quantile(0.0)) && metrics_norm_quantile(0.0) < 0);
    assert_true(isnan(metrics_norm_quantile(1.5)));
}

enum { ZW = 4, ZH = 3, ZN = ZW * ZH };
static float z_mean[ZN], z_vr[ZN], z_vt[ZN], z_t[3][ZN];

static void z_setup(metrics_image *mean, metrics_image *vr, metrics_image *tst, metrics_image *vt)
{
    /* Reference mean 0, var 0.6e-4 + test var 0.4e-4: sigma 0.01 for every value. */
    for (int i = 0; i < ZN; i++) {
        z_mean[i] = 0.0f;
        z_vr[i] = 0.6e-4f;
        z_vt[i] = 0.4e-4f;
        z_t[0][i] = z_t[1][i] = z_t[2][i] = 0.0f;
    }
    *mean = (metrics_image){ZW, ZH, {z_mean, z_mean, z_mean}};
    *vr = (metrics_image){ZW, ZH, {z_vr, z_vr, z_vr}};
    *vt = (metrics_image){ZW, ZH, {z_vt, z_vt, z_vt}};
    *tst = (metrics_image){ZW, ZH, {z_t[0], z_t[1], z_t[2]}};
}

static void test_ztest(void **state)
{
    (void)state;
    metrics_image mean, vr, tst, vt;
    metrics_ztest_options opt = {0};
    metrics_ztest_result r;
    char err[256];
    opt.var_floor = -1; /* none */
    /* m = 36 values, alpha 0.01: Bonferroni per-value level 0.01/36, two-sided,
     * z_crit = 3.635188198352098. */
    const double zc = 3.635188198352098;
    z_setup(&mean, &vr, &tst, &vt);
    z_t[0][0] = (float)(0.01 * 1.01 * zc);       /* (0,0) R: just over  -> fails */
    z_t[2][ZN - 1] = (float)(-0.01 * 0.99 * zc); /* (3,2) B: just under -> passes */
    assert_int_equal(metrics_ztest(&mean, &vr, &tst, &vt, NULL, &opt, &r, err, sizeof err), RC_OK);
    assert_int_equal(r.n_tests, 36);
    REL(r.z_crit, zc, 1e-12);
    assert_int_equal(r.n_fail, 1);
    assert_int_equal(r.n_fail_pixels, 1);
    REL(r.max_abs_z, 1.01 * zc, 1e-5);
    assert_int_equal(r.max_x, 0);
    assert_int_equal(r.max_y, 0);
    assert_int_equal(r.max_c, 0);
    /* Without the test variance sigma drops to sqrt(0.6e-4): both now fail. */
    assert_int_equal(metrics_ztest(&mean, &vr, &tst, NULL, NULL, &opt, &r, err, sizeof err), RC_OK);
    assert_int_equal(r.n_fail, 2);
    /* A floor of 3e-4 doubles sigma: nothing fails. */
    opt.var_floor = 3e-4;
    assert_int_equal(metrics_ztest(&mean, &vr, &tst, &vt, NULL, &opt, &r, err, sizeof err), RC_OK);
    assert_int_equal(r.n_fail, 0);
    opt.var_floor = -1;
    /* Masking out (0,0) leaves 33 tests and no failure. */
    unsigned char m[ZN];
    for (int i = 0; i < ZN; i++)
        m[i] = i != 0;
    assert_int_equal(metrics_ztest(&mean, &vr, &tst, &vt, m, &opt, &r, err, sizeof err), RC_OK);
    assert_int_equal(r.n_tests, 33);
    assert_int_equal(r.n_fail, 0);

    /* Holm versus Bonferroni: one value far out (10 sigma), one with p = alpha/35.5
     * (z = 3.631581066489111): between alpha/36 (Bonferroni) and alpha/35 (Holm's 2nd step). */
    z_setup(&mean, &vr, &tst, &vt);
    z_t[1][5] = 0.1f;
    z_t[0][7] = (float)(0.01 * 3.631581066489111);
    assert_int_equal(metrics_ztest(&mean, &vr, &tst, &vt, NULL, &opt, &r, err, sizeof err), RC_OK);
    assert_int_equal(r.n_fail, 1);
    opt.correction = METRICS_HOLM;
    assert_int_equal(metrics_ztest(&mean, &vr, &tst, &vt, NULL, &opt, &r, err, sizeof err), RC_OK);
    assert_int_equal(r.n_fail, 2);
    assert_int_equal(r.n_fail_pixels, 2);
    /* Sidak: level 1 - 0.99^(1/36) = 2.7913702993845123e-4, z_crit 3.6339296245524224; a value
     * at z = 3.6345581918066565 (p halfway between the Bonferroni and Sidak levels) fails
     * only under Sidak. */
    z_setup(&mean, &vr, &tst, &vt);
    z_t[2][3] = (float)(0.01 * 3.6345581918066565);
    opt.correction = METRICS_BONFERRONI;
    assert_int_equal(metrics_ztest(&mean, &vr, &tst, &vt, NULL, &opt, &r, err, sizeof err), RC_OK);
    assert_int_equal(r.n_fail, 0);
    opt.correction = METRICS_SIDAK;
    assert_int_equal(metrics_ztest(&mean, &vr, &tst, &vt, NULL, &opt, &r, err, sizeof err), RC_OK);
    assert_int_equal(r.n_fail, 1);
    REL(r.z_crit, 3.6339296245524224, 1e-12);
    /* A negative variance makes the pixel untestable, counted apart. */
    z_vr[2] = -1.0f;
    assert_int_equal(metrics_ztest(&mean, &vr, &tst, &vt, NULL, &opt, &r, err, sizeof err), RC_OK);
    assert_int_equal(r.n_nonfinite, 1);
    assert_int_equal(r.n_tests, 33);
    opt.alpha = 2.0;
    assert_int_equal(metrics_ztest(&mean, &vr, &tst, &vt, NULL, &opt, &r, err, sizeof err), RC_ERR_RANGE);
}

static void test_seed_stats(void **state)
{
    (void)state;
    /* One pixel, three seeds {1, 2, 4} in R: mean 7/3, sample variance 7/3, of the mean 7/9.
     * G: two equal seeds and a third: {0.5, 0.5, 2}: mean 1, s^2 = (0.25+0.25+1)/2 = 0.75,
     * of the mean 0.25. B constant: variance 0. */
    float r[3][1] = {{1}, {2}, {4}}, g[3][1] = {{0.5f}, {0.5f}, {2}}, b[3][1] = {{3}, {3}, {3}};
    metrics_image s[3];
    for (int i = 0; i < 3; i++)
        s[i] = (metrics_image){1, 1, {r[i], g[i], b[i]}};
    float mr[1], mg[1], mb[1], vr[1], vg[1], vb[1];
    float *mean[3] = {mr, mg, mb}, *var[3] = {vr, vg, vb};
    char err[256];
    assert_int_equal(metrics_seed_stats(s, 3, mean, var, err, sizeof err), RC_OK);
    REL(mr[0], 7.0 / 3.0, 1e-7);
    REL(vr[0], 7.0 / 9.0, 1e-7);
    REL(mg[0], 1.0, 1e-7);
    REL(vg[0], 0.25, 1e-7);
    assert_float_equal(vb[0], 0.0, 0.0);
    /* Two seeds a, b: variance of the mean is (a - b)^2 / 4. */
    assert_int_equal(metrics_seed_stats(s, 2, mean, var, err, sizeof err), RC_OK);
    REL(vr[0], 0.25, 1e-7);
    assert_int_equal(metrics_seed_stats(s, 1, mean, var, err, sizeof err), RC_ERR_RANGE);
}

/* ---- cross-check against idiff ---- */

typedef struct {
    double mean, rms, psnr, max;
    int mx, my;
    char mc[16];
    long nover;
    int have;
} idiff_out;

static char g_dir[64];

static int run_idiff(const char *a, const char *b, double thr, idiff_out *o)
{
    char cmd[1024], line[512];
    snprintf(cmd, sizeof cmd, "idiff -v -a -fail %g -warn %g '%s' '%s' 2>&1", thr, thr, a, b);
    FILE *p = popen(cmd, "r");
    if (!p)
        return -1;
    memset(o, 0, sizeof *o);
    while (fgets(line, sizeof line, p)) {
        long n;
        double pct, t;
        if (sscanf(line, " Mean error = %lf", &o->mean) == 1)
            o->have |= 1;
        else if (sscanf(line, " RMS error = %lf", &o->rms) == 1)
            o->have |= 2;
        else if (sscanf(line, " Peak SNR = %lf", &o->psnr) == 1)
            o->have |= 4;
        else if (sscanf(line, " Max error = %lf @ (%d, %d, %15[^)])", &o->max, &o->mx, &o->my, o->mc) == 4)
            o->have |= 8;
        else if (sscanf(line, " %ld pixels (%lf%%) over %lf", &n, &pct, &t) == 3) {
            o->nover = n;
            o->have |= 16;
        }
    }
    pclose(p);
    return o->have == 31 ? 0 : -1;
}

/* idiff prints 6 significant digits: allow half a unit in the last one. */
static void expect_printed(double ours, double printed, const char *what)
{
    double tol = printed != 0 ? 0.5 * pow(10.0, floor(log10(fabs(printed))) - 5) : 0.0;
    if (!(fabs(ours - printed) <= tol + 1e-6 * fabs(printed)))
        fail_msg("%s: ours %.10g, idiff %.10g", what, ours, printed);
}

static void write_rgb(const char *path, int w, int h, const float *r, const float *g, const float *b)
{
    exr_channel ch[] = {{"R", r}, {"G", g}, {"B", b}};
    char err[512];
    if (exr_write(path, w, h, ch, 3, NULL, 0, err, sizeof err) != RC_OK)
        fail_msg("%s", err);
}

static void test_idiff_crosscheck(void **state)
{
    (void)state;
    char pa[96], pb[96];
    snprintf(pa, sizeof pa, "%s/a.exr", g_dir);
    snprintf(pb, sizeof pb, "%s/b.exr", g_dir);
    metrics_result r;
    idiff_out o;
    char err[256];

    /* Exact fixture, 4x4: values are multiples of 1/8, the largest 1.25; three errors of
     * exactly 0.5: mean = 1.5/48 = 0.03125, RMS = sqrt(0.75/48) = 0.125,
     * PSNR = 20 log10(1.25 / 0.125) = 20, max 0.5 first at (2, 1, G). Each prints exactly,
     * so agreement must hold to 1e-6 relative. */
    {
        enum { EW = 4, EH = 4, EN = EW * EH };
        float ar[EN], ag[EN], ab[EN], br[EN], bg[EN], bb[EN];
        for (int i = 0; i < EN; i++) {
            ar[i] = 0.125f * (float)(i % 7);
            ag[i] = 0.125f * (float)((3 * i) % 5);
            ab[i] = 0.125f * (float)((5 * i + 1) % 6);
        }
        ar[15] = 1.25f;
        ag[1 * EW + 2] = 0.25f;
        ar[3 * EW + 0] = 0.75f;
        ab[3 * EW + 3] = 0.5f;
        memcpy(br, ar, sizeof br);
        memcpy(bg, ag, sizeof bg);
        memcpy(bb, ab, sizeof bb);
        bg[1 * EW + 2] += 0.5f;
        br[3 * EW + 0] -= 0.5f;
        bb[3 * EW + 3] += 0.5f;
        write_rgb(pa, EW, EH, ar, ag, ab);
        write_rgb(pb, EW, EH, br, bg, bb);
        assert_int_equal(run_idiff(pa, pb, 0.01, &o), 0);
        metrics_image ia = {EW, EH, {ar, ag, ab}}, ib = {EW, EH, {br, bg, bb}};
        metrics_options opt = {0};
        opt.threshold = 0.01;
        assert_int_equal(metrics_compare(&ia, &ib, NULL, &opt, &r, err, sizeof err), RC_OK);
        REL(r.mae, 0.03125, 1e-12);
        REL(r.rmse, 0.125, 1e-12);
        REL(r.psnr, 20.0, 1e-12);
        REL(r.mae, o.mean, 1e-6);
        REL(r.rmse, o.rms, 1e-6);
        REL(r.psnr, o.psnr, 1e-6);
        REL(r.max_abs, o.max, 1e-6);
        assert_int_equal(r.max_x, o.mx);
        assert_int_equal(r.max_y, o.my);
        assert_string_equal(o.mc, "G");
        assert_int_equal(r.max_c, 1);
        assert_int_equal(r.n_over, o.nover);
        assert_int_equal(o.nover, 3);
    }

    /* Irregular fixture, 7x5: LCG values in [-0.5, 2.5), small noise everywhere, one large
     * error; idiff's 6 printed digits bound the agreement. */
    {
        enum { RW = 7, RH = 5, RN = RW * RH };
        float a[3][RN], b[3][RN];
        uint32_t s = 2024u;
        for (int c = 0; c < 3; c++)
            for (int i = 0; i < RN; i++) {
                s = s * 1664525u + 1013904223u;
                a[c][i] = -0.5f + 3.0f * (float)(s >> 8) / 16777216.0f;
                s = s * 1664525u + 1013904223u;
                b[c][i] = a[c][i] + 0.05f * ((float)(s >> 8) / 16777216.0f - 0.5f);
            }
        b[0][3 * RW + 5] = a[0][3 * RW + 5] + 0.7f;
        a[1][9] = b[1][9] = -4.0f; /* the largest |value| is negative: peak 4 */
        write_rgb(pa, RW, RH, a[0], a[1], a[2]);
        write_rgb(pb, RW, RH, b[0], b[1], b[2]);
        assert_int_equal(run_idiff(pa, pb, 0.02, &o), 0);
        metrics_image ia = {RW, RH, {a[0], a[1], a[2]}}, ib = {RW, RH, {b[0], b[1], b[2]}};
        metrics_options opt = {0};
        opt.threshold = 0.02;
        assert_int_equal(metrics_compare(&ia, &ib, NULL, &opt, &r, err, sizeof err), RC_OK);
        expect_printed(r.mae, o.mean, "mean error");
        expect_printed(r.rmse, o.rms, "RMS error");
        expect_printed(r.psnr, o.psnr, "PSNR");
        expect_printed(r.max_abs, o.max, "max error");
        assert_float_equal(r.peak, 4.0, 0.0); /* the HDR peak convention is in play */
        assert_int_equal(r.max_x, 5);
        assert_int_equal(r.max_y, 3);
        assert_int_equal(o.mx, 5);
        assert_int_equal(o.my, 3);
        assert_string_equal(o.mc, "R");
        assert_int_equal(r.n_over, o.nover);
        print_message("idiff irregular: ours rmse %.9g psnr %.9g | idiff %.6g %.6g, %ld over 0.02\n", r.rmse, r.psnr,
                      o.rms, o.psnr, o.nover);
    }
}

/* The value gate's scan: NaN, +Inf, -Inf counted as non-finite, finite values below 0 as
 * negative (-0.0 is not), and the first of each with its value, in index order. */
static void test_scan_values(void **state)
{
    (void)state;
    const float v[10] = {0.5f, -0.0f, 1.0f, -0.25f, NAN, 2.0f, INFINITY, -3.0f, -INFINITY, 0.0f};
    metrics_value_scan sc;
    metrics_scan_values(v, 10, &sc);
    assert_int_equal(sc.n_values, 10);
    assert_int_equal(sc.n_nonfinite, 3);
    assert_int_equal(sc.n_negative, 2);
    assert_int_equal(sc.first_nonfinite, 4);
    assert_true(isnan(sc.nonfinite_value));
    assert_int_equal(sc.first_negative, 3);
    assert_float_equal(sc.negative_value, -0.25f, 0.0);

    metrics_scan_values(v, 3, &sc); /* only the first three: clean */
    assert_int_equal(sc.n_values, 3);
    assert_int_equal(sc.n_nonfinite + sc.n_negative, 0);
    assert_int_equal(sc.first_nonfinite, -1);
    assert_int_equal(sc.first_negative, -1);

    metrics_scan_values(NULL, 5, &sc); /* an absent plane scans nothing */
    assert_int_equal(sc.n_values, 0);
    assert_int_equal(sc.first_nonfinite, -1);
}

/* Robust figures on 7 pixels, worked by hand (rel_eps 1e-12, so q is (t - r)^2 / r^2):
 *   pixel  ref          test         e = sum_c d^2   rel q               |ref| mean
 *   0      1 1 1        1 1 1        0               0                   1
 *   1      2 2 2        2.2 2.2 2.2  0.12            0.1                 2
 *   2      1 1 1        .5 .5 .5     0.75            0.5                 1
 *   3      4 4 4        7 7 7        27              0.75                4
 *   4      1 2 3        1 2 4        1               sqrt(1/27) = 0.192  2
 *   5      1 1 1        NaN 1 1      left out (non-finite)
 *   6      1 1 1        100 100 100  left out (mask)
 * N = 5, sum e = 28.87, mean ref = 10 / 5 = 2: nrmse = sqrt(28.87 / 15) / 2.
 * k = ceil(0.01 * 5) = 1: pixel 3; worst share 27 / 28.87; kept e 1.87 over 4 pixels of
 * mean ref 6 / 4: nrmse_trim = sqrt(1.87 / 12) / 1.5.
 * Sorted q: 0, 0.1, 0.192, 0.5, 0.75: median rank ceil(2.5) = 3 -> sqrt(1/27); p95 rank 5 -> 0.75. */
static void test_robust_hand(void **state)
{
    (void)state;
    float r[3][7] = {{1, 2, 1, 4, 1, 1, 1}, {1, 2, 1, 4, 2, 1, 1}, {1, 2, 1, 4, 3, 1, 1}};
    float t[3][7] = {{1, 2.2f, .5f, 7, 1, NAN, 100}, {1, 2.2f, .5f, 7, 2, 1, 100}, {1, 2.2f, .5f, 7, 4, 1, 100}};
    unsigned char mask[7] = {1, 1, 1, 1, 1, 1, 0};
    metrics_image ref = {7, 1, {r[0], r[1], r[2]}}, tst = {7, 1, {t[0], t[1], t[2]}};
    metrics_robust_options o = {.rel_eps = 1e-12};
    metrics_robust_result res;
    char err[256];
    assert_int_equal(metrics_robust(&ref, &tst, mask, &o, &res, err, sizeof err), RC_OK);
    /* 2.2f and .5f are not exact in float: 1e-6 relative covers their rounding. */
    assert_int_equal(res.n_pixels, 5);
    assert_int_equal(res.n_trimmed, 1);
    assert_float_equal(res.nrmse, sqrt(28.87 / 15.0) / 2.0, 1e-6);
    assert_float_equal(res.nrmse_trim, sqrt(1.87 / 12.0) / 1.5, 1e-6);
    assert_float_equal(res.worst_share, 27.0 / 28.87, 1e-6);
    assert_float_equal(res.rel_median, sqrt(1.0 / 27.0), 1e-6);
    assert_float_equal(res.rel_p95, 0.75, 1e-6);

    /* trim 0.5: k = ceil(2.5) = 3, pixels 3, 4 and 2 (e 27, 1, 0.75); kept 0 and 1: e 0.12
     * over 2 pixels of mean ref 3 / 2. */
    o.trim = 0.5;
    assert_int_equal(metrics_robust(&ref, &tst, mask, &o, &res, err, sizeof err), RC_OK);
    assert_int_equal(res.n_trimmed, 3);
    assert_float_equal(res.worst_share, 28.75 / 28.87, 1e-6);
    assert_float_equal(res.nrmse_trim, sqrt(0.12 / 6.0) / 1.5, 1e-6);

    /* Identical images: every figure 0; one pixel: nothing to trim. */
    assert_int_equal(metrics_robust(&ref, &ref, mask, NULL, &res, err, sizeof err), RC_OK);
    assert_true(res.nrmse == 0.0 && res.worst_share == 0.0 && res.rel_p95 == 0.0 && res.n_trimmed == 1);
    unsigned char one[7] = {0, 0, 0, 1, 0, 0, 0};
    assert_int_equal(metrics_robust(&ref, &tst, one, NULL, &res, err, sizeof err), RC_OK);
    assert_int_equal(res.n_trimmed, 0);
    assert_float_equal(res.nrmse_trim, res.nrmse, 0.0);
    assert_float_equal(res.nrmse, 3.0 / 4.0, 1e-7);

    o.trim = 1.0;
    assert_int_equal(metrics_robust(&ref, &tst, mask, &o, &res, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "trim"));
}

int main(void)
{
    snprintf(g_dir, sizeof g_dir, "/tmp/test_metrics_XXXXXX");
    if (!mkdtemp(g_dir)) {
        perror("mkdtemp");
        return 1;
    }
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_hand_3x2),
        cmocka_unit_test(test_masks_and_nonfinite),
        cmocka_unit_test(test_ssim),
        cmocka_unit_test(test_ssim_gauss_direct),
        cmocka_unit_test(test_classify),
        cmocka_unit_test(test_norm_quantile),
        cmocka_unit_test(test_ztest),
        cmocka_unit_test(test_seed_stats),
        cmocka_unit_test(test_idiff_crosscheck),
        cmocka_unit_test(test_scan_values),
        cmocka_unit_test(test_robust_hand),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_dir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", g_dir);
    return rc;
}
