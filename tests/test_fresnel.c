/* Fresnel: Schlick and D3D9Client equations (1)-(3) at hand-worked points, the exact
 * dielectric against Fresnel's sine/tangent amplitude form, the conductor against complex
 * arithmetic, and a sweep of extreme arguments that must stay finite. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include "check.h"

#include <complex.h>
#include <float.h>
#include <math.h>

#include "fresnel.h"

/* (2): R0 = ((1 - n)/(1 + n))^2. 1.5: (-0.5/2.5)^2 = 0.04; 2: (1/3)^2 = 0.111111;
 * 1.33: (0.33/2.33)^2 = 0.1416309^2 = 0.0200593. */
static void test_r0_from_ior(void **state)
{
    (void)state;
    close_rel(fresnel_r0_from_ior(1.5f), 0.04, 1e-6);
    close_rel(fresnel_r0_from_ior(2.0f), 1.0 / 9.0, 1e-6);
    close_rel(fresnel_r0_from_ior(1.33f), 0.0200593122, 1e-6);
    /* symmetric in n -> 1/n: (1 - 1/n)/(1 + 1/n) = (n - 1)/(n + 1) */
    close_rel(fresnel_r0_from_ior(1.0f / 1.5f), 0.04, 1e-6);
    /* n -> 1: R0 ~ ((n-1)/2)^2; n = 1 + 2^-20: (2^-21 / (1 + 2^-21))^2 keeps full precision */
    close_rel(fresnel_r0_from_ior(1.0f + 0x1p-20f), pow(0x1p-21 / (1.0 + 0x1p-21), 2.0), 1e-6);
    assert_true(fresnel_r0_from_ior(1.0f) == 0.0f);
    assert_true(fresnel_r0_from_ior(0.0f) == 1.0f);
    assert_true(fresnel_r0_from_ior(-1.0f) == 1.0f);
    assert_true(fresnel_r0_from_ior(INFINITY) == 1.0f);
    close_rel(fresnel_r0_from_ior(FLT_MAX), 1.0, 1e-6);
}

/* (4.9): F0 + (1 - F0)(1 - c)^5. c = 0.5: 0.04 + 0.96/32 = 0.07; 0.5 + 0.5/32 = 0.515625;
 * 0.9 + 0.1/32 = 0.903125. */
static void test_schlick(void **state)
{
    (void)state;
    close_rel(fresnel_schlick(0.04f, 1.0f), 0.04, 1e-6);
    close_rel(fresnel_schlick(0.04f, 0.0f), 1.0, 1e-6);
    close_rel(fresnel_schlick(0.04f, 0.5f), 0.07, 1e-6);
    /* clamped cosine: below 0 acts as 0, above 1 as 1 */
    close_rel(fresnel_schlick(0.04f, -0.3f), 1.0, 1e-6);
    close_rel(fresnel_schlick(0.04f, 1.7f), 0.04, 1e-6);
    vec3 f = fresnel_schlick_rgb(v3(0.04f, 0.5f, 0.9f), 0.5f);
    close_rel(f.x, 0.07, 1e-6);
    close_rel(f.y, 0.515625, 1e-6);
    close_rel(f.z, 0.903125, 1e-6);
    assert_true(isnan(fresnel_schlick(0.04f, NAN)));
}

/* (1)/(3): R0 + m (1 - c)^p. The source's checks: c = 1 (0 deg) gives R0, c = 0 (90 deg)
 * gives R0 + m. Interior: 0.05 + 0.5 * 0.4^2 = 0.13; 0.2 + 0.8 * 0.25^2.5 = 0.2 + 0.8/32
 * = 0.225. */
static void test_d3d9(void **state)
{
    (void)state;
    close_rel(fresnel_d3d9(0.1f, 0.9f, 3.0f, 1.0f), 0.1, 1e-6);
    close_rel(fresnel_d3d9(0.1f, 0.9f, 3.0f, 0.0f), 1.0, 1e-6);
    close_rel(fresnel_d3d9(0.05f, 0.7f, 2.5f, 0.0f), 0.75, 1e-6);
    close_rel(fresnel_d3d9(0.05f, 0.5f, 2.0f, 0.6f), 0.13, 1e-6);
    close_rel(fresnel_d3d9(0.2f, 0.8f, 2.5f, 0.75f), 0.225, 1e-6);
    /* with m = 1 - R0 and p = 5 it is Schlick */
    close_rel(fresnel_d3d9(0.04f, 0.96f, 5.0f, 0.3f), fresnel_schlick(0.04f, 0.3f), 1e-6);
    /* Fresnel disabled by R0 = m = 0 */
    assert_true(fresnel_d3d9(0.0f, 0.0f, 3.0f, 0.3f) == 0.0f);
    /* p = 0: x^0 = 1 everywhere, including c = 1; negative p acts as 0 */
    close_rel(fresnel_d3d9(0.1f, 0.5f, 0.0f, 1.0f), 0.6, 1e-6);
    close_rel(fresnel_d3d9(0.1f, 0.5f, -2.0f, 1.0f), 0.6, 1e-6);
    /* negative N.V (back side) clamps to 0 -> the grazing value */
    close_rel(fresnel_d3d9(0.1f, 0.9f, 3.0f, -0.5f), 1.0, 1e-6);
}

/* Fresnel's amplitude form with Snell's law, an independent derivation:
 * rs = -sin(ti - tt)/sin(ti + tt), rp = tan(ti - tt)/tan(ti + tt), R = (rs^2 + rp^2)/2. */
static double fresnel_sine_tangent(double theta_i, double eta)
{
    double theta_t = asin(sin(theta_i) / eta);
    double rs = -sin(theta_i - theta_t) / sin(theta_i + theta_t);
    double rp = tan(theta_i - theta_t) / tan(theta_i + theta_t);
    return 0.5 * (rs * rs + rp * rp);
}

static void test_dielectric_vs_amplitude_form(void **state)
{
    (void)state;
    const double etas[] = {1.5, 1.33, 2.4, 1.0 / 1.5};
    const double angles[] = {5, 10, 30, 40, 45, 60, 80, 89};
    for (size_t e = 0; e < sizeof etas / sizeof etas[0]; e++)
        for (size_t a = 0; a < sizeof angles / sizeof angles[0]; a++) {
            double ti = deg(angles[a]);
            if (sin(ti) / etas[e] >= 1.0)
                continue; /* TIR: tested below */
            close_rel(fresnel_dielectric(cos(ti), etas[e]), fresnel_sine_tangent(ti, etas[e]), 1e-10);
        }
}

static void test_dielectric_points(void **state)
{
    (void)state;
    /* normal incidence: exact equals Schlick's F0 = R0 */
    close_rel(fresnel_dielectric(1.0, 1.5), 0.04, 1e-12);
    close_rel(fresnel_dielectric(1.0, 1.5), fresnel_schlick(fresnel_r0_from_ior(1.5f), 1.0f), 1e-6);
    close_rel(fresnel_dielectric(1.0, 1.33), fresnel_schlick(fresnel_r0_from_ior(1.33f), 1.0f), 1e-6);
    /* 45 deg, eta 1.5: sin_t = 0.4714045, cos_t = 0.8819171; rs = -0.3033898,
     * rp = 0.0920111 -> (0.0920453 + 0.0084660)/2 = 0.0502399 */
    close_rel(fresnel_dielectric(cos(deg(45)), 1.5), 0.0502399110, 1e-8);
    /* Brewster angle tan(theta) = 1.5: rp = 0, rs = cos(2 theta) = (1 - 2.25)/3.25, so
     * R = 0.5 * (1.25/3.25)^2 = 0.0739645 */
    close_rel(fresnel_dielectric(cos(atan(1.5)), 1.5), 0.0739644970, 1e-9);
    /* grazing: 1 */
    close_rel(fresnel_dielectric(0.0, 1.5), 1.0, 1e-12);
    /* inside (cos < 0) equals the swapped media */
    close_rel(fresnel_dielectric(-cos(deg(30)), 1.5), fresnel_dielectric(cos(deg(30)), 1.0 / 1.5), 1e-14);
    /* eta = 1: no interface */
    assert_true(fresnel_dielectric(0.3, 1.0) == 0.0);
}

/* Total internal reflection: from glass (eta 1/1.5), critical angle asin(1/1.5) = 41.81 deg. */
static void test_tir(void **state)
{
    (void)state;
    assert_true(fresnel_dielectric(cos(deg(45)), 1.0 / 1.5) == 1.0);
    assert_true(fresnel_dielectric(-cos(deg(45)), 1.5) == 1.0);
    assert_true(fresnel_dielectric(cos(deg(89)), 1.0 / 1.33) == 1.0);
    /* just inside the critical angle it is below 1 and rising steeply */
    double r = fresnel_dielectric(cos(deg(41.5)), 1.0 / 1.5);
    assert_true(r > 0.3 && r < 1.0);
}

/* Complex arithmetic, the second formula: cos_t = sqrt(1 - sin_i^2/n^2) (principal root),
 * rs = (ci - n ct)/(ci + n ct), rp = (n ci - ct)/(n ci + ct). */
static double conductor_complex(double ci, double eta, double k)
{
    double complex n = eta + k * I;
    double complex ct = csqrt(1.0 - (1.0 - ci * ci) / (n * n));
    double complex rs = (ci - n * ct) / (ci + n * ct);
    double complex rp = (n * ci - ct) / (n * ci + ct);
    double as = cabs(rs), ap = cabs(rp);
    return 0.5 * (as * as + ap * ap);
}

static void test_conductor(void **state)
{
    (void)state;
    /* k = 0 equals the dielectric, also with TIR for eta < 1 */
    const double angles[] = {0, 10, 30, 45, 60, 75, 85, 89.9};
    const double etas[] = {1.5, 2.4, 0.7};
    for (size_t e = 0; e < 3; e++)
        for (size_t a = 0; a < 8; a++) {
            double c = cos(deg(angles[a]));
            close_rel(fresnel_conductor(c, etas[e], 0.0), fresnel_dielectric(c, etas[e]), 1e-12);
        }
    /* gold-ish (0.17, 3.1), aluminium-ish (1.2, 7.0), a lossy dielectric (1.5, 0.3) */
    const double nk[][2] = {{0.17, 3.1}, {1.2, 7.0}, {1.5, 0.3}, {0.05, 4.0}};
    for (size_t i = 0; i < 4; i++)
        for (size_t a = 0; a < 8; a++) {
            double c = cos(deg(angles[a]));
            close_rel(fresnel_conductor(c, nk[i][0], nk[i][1]), conductor_complex(c, nk[i][0], nk[i][1]), 1e-10);
        }
    /* normal incidence: ((eta - 1)^2 + k^2)/((eta + 1)^2 + k^2) = (0.6889 + 9.61)/(1.3689 + 9.61)
     * = 0.9380630 */
    close_rel(fresnel_conductor(1.0, 0.17, 3.1), 0.9380630118, 1e-9);
    close_rel(fresnel_conductor(0.0, 0.17, 3.1), 1.0, 1e-12);
}

static const float extremes[] = {
    -FLT_MAX, -1e30f, -1e6f, -1.0f,      -0.5f, -1e-30f,    -1e-45f, 0.0f, 1e-45f, 1e-38f, 1e-30f, 1e-7f,
    1e-3f,    0.04f,  0.5f,  0.9999999f, 1.0f,  1.0000001f, 1.5f,    2.0f, 1e4f,   1e6f,   1e30f,  FLT_MAX,
};
#define N_EXTREMES (sizeof extremes / sizeof extremes[0])

static void test_extremes_finite(void **state)
{
    (void)state;
    size_t bad = 0, n = 0;
    for (size_t i = 0; i < N_EXTREMES; i++) {
        float a = extremes[i];
        bad += !isfinite(fresnel_r0_from_ior(a));
        n++;
        for (size_t j = 0; j < N_EXTREMES; j++) {
            float b = extremes[j];
            bad += !isfinite(fresnel_schlick(a, b));
            vec3 f = fresnel_schlick_rgb(v3(a, b, 0.5f), b);
            bad += !isfinite(f.x) + !isfinite(f.y) + !isfinite(f.z);
            bad += !isfinite(fresnel_dielectric(a, b));
            n += 5;
            for (size_t k = 0; k < N_EXTREMES; k++) {
                bad += !isfinite(fresnel_conductor(a, b, extremes[k]));
                n++;
                for (size_t l = 0; l < N_EXTREMES; l++) {
                    bad += !isfinite(fresnel_d3d9(a, b, extremes[k], extremes[l]));
                    n++;
                }
            }
        }
    }
    /* the exact references stay reflectances, [0, 1], for every finite input */
    for (size_t i = 0; i < N_EXTREMES; i++)
        for (size_t j = 0; j < N_EXTREMES; j++) {
            double r = fresnel_dielectric(extremes[i], extremes[j]);
            if (!(r >= 0.0 && r <= 1.0))
                bad++;
            for (size_t k = 0; k < N_EXTREMES; k++) {
                double c = fresnel_conductor(extremes[i], extremes[j], extremes[k]);
                if (!(c >= 0.0 && c <= 1.0 + 1e-12))
                    bad++;
            }
        }
    if (bad)
        fail_msg("%zu of %zu evaluations were not finite or out of range", bad, n);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_r0_from_ior),
        cmocka_unit_test(test_schlick),
        cmocka_unit_test(test_d3d9),
        cmocka_unit_test(test_dielectric_vs_amplitude_form),
        cmocka_unit_test(test_dielectric_points),
        cmocka_unit_test(test_tir),
        cmocka_unit_test(test_conductor),
        cmocka_unit_test(test_extremes_finite),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
