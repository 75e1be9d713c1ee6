/* D3D9Client model: source equations (3)-(8) at a hand-worked point, the colour-norm options
 * (including euclid's negative diffuse weight, which must show), the POV-Ray reflection
 * form as a second formula, and a sweep of extreme arguments that must stay finite. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include "check.h"

#include <float.h>
#include <math.h>

#include "d3d9client.h"

static void close_v3(vec3 got, double x, double y, double z, double rel)
{
    close_rel(got.x, x, rel);
    close_rel(got.y, y, rel);
    close_rel(got.z, z, rel);
}

/* lambda = (0.9, 0.6, 0.3): max 0.9; mean 0.6; luminance 0.2126*0.9 + 0.7152*0.6 +
 * 0.0722*0.3 = 0.19134 + 0.42912 + 0.02166 = 0.64212; euclid sqrt(1.26) = 1.1224972. */
static void test_colour_norm(void **state)
{
    (void)state;
    vec3 c = v3(0.9f, 0.6f, 0.3f);
    close_rel(d3d9client_colour_norm(c, NORM_MAX), 0.9, 1e-7);
    close_rel(d3d9client_colour_norm(c, NORM_MEAN), 0.6, 1e-7);
    close_rel(d3d9client_colour_norm(c, NORM_LUMINANCE), 0.64212, 1e-6);
    close_rel(d3d9client_colour_norm(c, NORM_EUCLID), 1.1224972160, 1e-6);
    /* max is the only one with |lambda| <= 1 for every lambda in [0,1]^3 and = the largest */
    close_rel(d3d9client_colour_norm(v3(0.2f, 0.7f, 0.1f), NORM_MAX), 0.7, 1e-7);
    close_rel(d3d9client_colour_norm(v3s(1.0f), NORM_EUCLID), sqrt(3.0), 1e-7);
    close_rel(d3d9client_colour_norm(v3s(1.0f), NORM_LUMINANCE), 1.0, 1e-6); /* weights sum to 1 */
    assert_true(isnan(d3d9client_colour_norm(v3(0.1f, NAN, 0.2f), NORM_MAX)));
}

static d3d9client_params params(void)
{
    d3d9client_params p = {0};
    p.p = 3.0f;
    p.r0 = 0.04f;
    p.m = 0.96f;
    p.reflect = v3(0.9f, 0.6f, 0.3f);
    p.fresnel_colour = v3s(1.0f);
    p.norm = NORM_MAX;
    return p;
}

/* R0 = 0.04, m = 0.96, p = 3, N.V = 0.5: (3) R = 0.04 + 0.96 * 0.125 = 0.16.
 * (5) lambda (1 - R) + s R = (0.756, 0.504, 0.252) + 0.16 = (0.916, 0.664, 0.412);
 *     phi = (2, 1, 0.5) -> R_tot = (1.832, 0.664, 0.206).
 * (6) d = (0.2, 0.3, 0.4), 1 - |lambda| = 0.1 -> c = (1.852, 0.694, 0.246).
 * (7) alpha = max(0.5, 1.832) = 1.832.
 * (8) N.L = 0.8: 1 - 0.04 - 0.96 * 0.2^3 = 0.95232 -> c = d * 0.095232 + R_tot
 *     = (1.8510464, 0.6925696, 0.2440928). */
static void test_combine_point(void **state)
{
    (void)state;
    d3d9client_params p = params();
    vec3 d = v3(0.2f, 0.3f, 0.4f), phi = v3(2.0f, 1.0f, 0.5f);
    d3d9client_result r;
    d3d9client_combine(&p, d, 0.5f, phi, 0.5f, 0.8f, &r);
    close_rel(r.fresnel_R, 0.16, 1e-6);
    close_v3(r.r_tot, 1.832, 0.664, 0.206, 1e-6);
    close_v3(r.rgb, 1.852, 0.694, 0.246, 1e-6);
    close_rel(r.alpha, 1.832, 1e-6);
    close_rel(r.diffuse_weight, 0.1, 1e-6);
    p.sun_angle = 1;
    d3d9client_combine(&p, d, 0.5f, phi, 0.5f, 0.8f, &r);
    close_v3(r.rgb, 1.8510464, 0.6925696, 0.2440928, 1e-6);
    /* the alpha keeps the diffuse alpha when the reflection is dim */
    d3d9client_combine(&p, d, 0.5f, v3s(0.1f), 0.5f, 0.8f, &r);
    close_rel(r.alpha, 0.5, 1e-7);
}

/* (1)/(3): 0 deg gives R0, 90 deg gives R0 + m. */
static void test_fresnel_ends(void **state)
{
    (void)state;
    d3d9client_params p = params();
    p.r0 = 0.1f;
    p.m = 0.7f;
    d3d9client_result r;
    d3d9client_combine(&p, v3s(0.0f), 1.0f, v3s(1.0f), 1.0f, 0.0f, &r);
    close_rel(r.fresnel_R, 0.1, 1e-6);
    d3d9client_combine(&p, v3s(0.0f), 1.0f, v3s(1.0f), 0.0f, 0.0f, &r);
    close_rel(r.fresnel_R, 0.8, 1e-6);
    d3d9client_combine(&p, v3s(0.0f), 1.0f, v3s(1.0f), -0.4f, 0.0f, &r); /* back side clamps */
    close_rel(r.fresnel_R, 0.8, 1e-6);
}

/* Fresnel off (R0 = m = 0) and metal off (lambda = 0): the diffuse colour passes unchanged. */
static void test_disabled(void **state)
{
    (void)state;
    d3d9client_params p = params();
    p.r0 = 0.0f;
    p.m = 0.0f;
    p.reflect = v3s(0.0f);
    d3d9client_result r;
    d3d9client_combine(&p, v3(0.2f, 0.3f, 0.4f), 0.7f, v3(5.0f, 6.0f, 7.0f), 0.3f, 0.2f, &r);
    close_v3(r.rgb, 0.2, 0.3, 0.4, 1e-7);
    assert_true(r.r_tot.x == 0.0f && r.r_tot.y == 0.0f && r.r_tot.z == 0.0f);
    close_rel(r.alpha, 0.7, 1e-7);
}

/* docs/conventions.md#pov-ray: POV-Ray's reflection { Rmin, Rmax falloff p } with Rmin = lambda + (s -
 * lambda) R0, Rmax = lambda + (s - lambda)(R0 + m) gives R_tot/phi = Rmin + (Rmax - Rmin)
 * (1 - c)^p per channel: a second formula for (5). */
static void test_povray_form(void **state)
{
    (void)state;
    d3d9client_params p = params();
    p.r0 = 0.08f;
    p.m = 0.5f;
    p.p = 2.5f;
    p.fresnel_colour = v3(1.0f, 0.9f, 0.7f);
    const float cs[] = {0.0f, 0.1f, 0.45f, 0.8f, 1.0f};
    const float lam[3] = {0.9f, 0.6f, 0.3f}, s[3] = {1.0f, 0.9f, 0.7f};
    for (size_t i = 0; i < 5; i++) {
        d3d9client_result r;
        d3d9client_combine(&p, v3s(0.0f), 0.0f, v3s(1.0f), cs[i], 0.0f, &r);
        const float got[3] = {r.r_tot.x, r.r_tot.y, r.r_tot.z};
        for (int ch = 0; ch < 3; ch++) {
            double rmin = lam[ch] + (s[ch] - lam[ch]) * 0.08;
            double rmax = lam[ch] + (s[ch] - lam[ch]) * 0.58;
            close_rel(got[ch], rmin + (rmax - rmin) * pow(1.0 - cs[i], 2.5), 1e-6);
        }
    }
}

/* euclid of a white lambda is sqrt 3: 1 - |lambda| = -0.7320508 is reported and the diffuse
 * is subtracted, c = d (1 - sqrt 3) + R_tot; luminance and mean keep it at 0. */
static void test_euclid_negative_weight(void **state)
{
    (void)state;
    d3d9client_params p = params();
    p.reflect = v3s(1.0f);
    p.norm = NORM_EUCLID;
    d3d9client_result r;
    vec3 d = v3(0.5f, 0.25f, 0.125f);
    d3d9client_combine(&p, d, 1.0f, v3s(1.0f), 1.0f, 0.0f, &r);
    close_rel(r.diffuse_weight, 1.0 - sqrt(3.0), 1e-6);
    /* R = 0.04: lambda (1 - R) + R = 1 -> R_tot = 1; c = 1 + d (1 - sqrt 3) */
    close_v3(r.rgb, 1.0 - 0.5 * 0.7320508076, 1.0 - 0.25 * 0.7320508076, 1.0 - 0.125 * 0.7320508076, 1e-6);
    close_rel(r.alpha, sqrt(3.0), 1e-6); /* (7) |R_tot| with euclid too */
    p.norm = NORM_LUMINANCE;
    d3d9client_combine(&p, d, 1.0f, v3s(1.0f), 1.0f, 0.0f, &r);
    close_rel(r.diffuse_weight + 1.0, 1.0, 1e-6);
}

static const float extremes[] = {
    -FLT_MAX, -1e30f, -1.0f,      -1e-45f, 0.0f, 1e-45f, 1e-30f, 0.04f,
    0.5f,     1.0f,   1.0000001f, 3.0f,    1e4f, 1e6f,   1e30f,  FLT_MAX,
};
#define N_EXTREMES (sizeof extremes / sizeof extremes[0])

static int finite_result(const d3d9client_result *r)
{
    return isfinite(r->rgb.x) && isfinite(r->rgb.y) && isfinite(r->rgb.z) && isfinite(r->alpha) &&
           isfinite(r->r_tot.x) && isfinite(r->r_tot.y) && isfinite(r->r_tot.z) && isfinite(r->fresnel_R) &&
           isfinite(r->diffuse_weight);
}

static void test_extremes_finite(void **state)
{
    (void)state;
    size_t bad = 0, n = 0;
    for (size_t i = 0; i < N_EXTREMES; i++)
        for (size_t j = 0; j < N_EXTREMES; j++)
            for (size_t k = 0; k < N_EXTREMES; k++)
                for (int norm = NORM_MAX; norm <= NORM_EUCLID; norm++) {
                    float a = extremes[i], b = extremes[j], c = extremes[k];
                    d3d9client_params p = params();
                    p.r0 = a;
                    p.m = b;
                    p.p = c;
                    p.reflect = v3(b, a, 0.5f);
                    p.fresnel_colour = v3(c, 1.0f, a);
                    p.norm = (colour_norm)norm;
                    p.sun_angle = (int)(k & 1);
                    d3d9client_result r;
                    d3d9client_combine(&p, v3(a, c, 0.2f), b, v3(c, b, 1e6f), a, b, &r);
                    bad += !finite_result(&r);
                    bad += !isfinite(d3d9client_colour_norm(v3(a, b, c), (colour_norm)norm));
                    n += 2;
                }
    if (bad)
        fail_msg("%zu of %zu evaluations were not finite", bad, n);
}

/* texel_alpha: d_a of eq. (7) on a textured material, material alpha 0.5 and texel alpha 0.25. */
static void test_texel_alpha(void **state)
{
    (void)state;
    d3d9client_params p = {.alpha = 0.5f};
    p.texel_alpha = TEXEL_ALPHA_MULTIPLY;
    assert_true(d3d9client_diffuse_alpha(&p, 0.25f) == 0.125f);
    p.texel_alpha = TEXEL_ALPHA_MATERIAL;
    assert_true(d3d9client_diffuse_alpha(&p, 0.25f) == 0.5f);
    p.texel_alpha = TEXEL_ALPHA_TEXEL;
    assert_true(d3d9client_diffuse_alpha(&p, 0.25f) == 0.25f);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_colour_norm),     cmocka_unit_test(test_combine_point),
        cmocka_unit_test(test_fresnel_ends),    cmocka_unit_test(test_disabled),
        cmocka_unit_test(test_povray_form),     cmocka_unit_test(test_euclid_negative_weight),
        cmocka_unit_test(test_extremes_finite), cmocka_unit_test(test_texel_alpha),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
