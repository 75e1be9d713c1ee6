/* Direct3D fixed-function factors: attenuation and spot falloff at hand-worked points,
 * Blinn-Phong with local and infinite viewer, half-vector guards, and a sweep of extreme
 * arguments that must stay finite. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include "check.h"

#include <float.h>
#include <math.h>

#include "d3d.h"

/* Written out here rather than through scene.c, so the test depends on d3d.c alone. */
static light point_light(float a0, float a1, float a2, float range)
{
    light l = {0};
    l.kind = LIGHT_POINT;
    l.position = v3(1.0f, 4.0f, -2.0f);
    l.direction = v3(0.0f, -1.0f, 0.0f);
    l.intensity = v3s(1.0f);
    l.a0 = a0;
    l.a1 = a1;
    l.a2 = a2;
    l.range = range;
    l.falloff = 1.0f;
    return l;
}

static void test_attenuation(void **state)
{
    (void)state;
    light l = point_light(0.0f, 0.0f, 1.0f, INFINITY);
    close_rel(d3d_attenuation(&l, 2.0f), 0.25, 1e-7); /* 1/d^2 */
    close_rel(d3d_attenuation(&l, 0.1f), 100.0, 1e-6);
    l = point_light(1.0f, 0.5f, 0.25f, 5.0f);
    close_rel(d3d_attenuation(&l, 2.0f), 1.0 / 3.0, 1e-7);  /* 1/(1 + 1 + 1) */
    close_rel(d3d_attenuation(&l, 5.0f), 1.0 / 9.75, 1e-7); /* at range: 1/(1 + 2.5 + 6.25) */
    assert_true(d3d_attenuation(&l, 5.0001f) == 0.0f);      /* beyond range */
    l = point_light(2.0f, 0.0f, 0.0f, INFINITY);
    close_rel(d3d_attenuation(&l, 1e30f), 0.5, 1e-7);    /* constant only */
    close_rel(d3d_attenuation(&l, INFINITY), 0.5, 1e-7); /* 0 * Inf not formed */
    l.kind = LIGHT_SUN;
    assert_true(d3d_attenuation(&l, 123.0f) == 1.0f);
    /* a0 = a1 = a2 = 0 and d = 0 with 1/d^2: the documented cap, not Inf */
    l = point_light(0.0f, 0.0f, 0.0f, INFINITY);
    close_rel(d3d_attenuation(&l, 3.0f), 1.0 / D3D_ATTEN_DENOM_MIN, 1e-6);
    l = point_light(0.0f, 0.0f, 1.0f, INFINITY);
    close_rel(d3d_attenuation(&l, 0.0f), 1.0 / D3D_ATTEN_DENOM_MIN, 1e-6);
    l = point_light(-1.0f, 0.0f, 0.0f, INFINITY);
    close_rel(d3d_attenuation(&l, 1.0f), 1.0 / D3D_ATTEN_DENOM_MIN, 1e-6);
}

static light spot(spot_profile profile, float falloff)
{
    light l = point_light(0.0f, 0.0f, 1.0f, INFINITY);
    l.kind = LIGHT_SPOT;
    l.inner = (float)deg(40); /* full angles: half angles 20 and 30 deg */
    l.outer = (float)deg(60);
    l.falloff = falloff;
    l.profile = profile;
    l.direction = v3(0.0f, -2.0f, 0.0f); /* not unit on purpose */
    return l;
}

static vec3 off_axis(double a) { return v3((float)sin(deg(a)), (float)-cos(deg(a)), 0.0f); }

/* cos 20 = 0.9396926, cos 30 = 0.8660254, rho = cos 25 = 0.9063078:
 * t = 0.0402824/0.0736672 = 0.5468156; t^2 = 0.2990073;
 * smooth: rho t^2 (3 - 2t) = 0.9063078 * 0.2990073 * 1.9063688 = 0.5166119 */
static void test_spot(void **state)
{
    (void)state;
    light l = spot(SPOT_D3D, 1.0f);
    close_rel(d3d_spot(&l, off_axis(25)), 0.5468155971, 1e-5);
    l.falloff = 2.0f;
    close_rel(d3d_spot(&l, off_axis(25)), 0.2990072972, 1e-5);
    assert_true(d3d_spot(&l, off_axis(10)) == 1.0f);
    assert_true(d3d_spot(&l, off_axis(35)) == 0.0f);
    assert_true(d3d_spot(&l, off_axis(150)) == 0.0f);
    l.falloff = 0.0f;
    assert_true(d3d_spot(&l, off_axis(25)) == 1.0f);
    l.falloff = -3.0f; /* bad input acts as 0 */
    assert_true(d3d_spot(&l, off_axis(29.999)) == 1.0f);

    l = spot(SPOT_SMOOTH, 1.0f);
    close_rel(d3d_spot(&l, off_axis(25)), 0.5166119191, 1e-5);
    close_rel(d3d_spot(&l, off_axis(10)), cos(deg(10)), 1e-6); /* inside: the extra cos */
    assert_true(d3d_spot(&l, off_axis(35)) == 0.0f);
    /* continuous at both edges */
    close_rel(d3d_spot(&l, off_axis(19.999)), cos(deg(20)), 1e-4);
    assert_true(d3d_spot(&l, off_axis(29.999)) < 1e-6f);
    /* coinciding cones: a hard edge, no division */
    l.inner = l.outer;
    close_rel(d3d_spot(&l, off_axis(29)), cos(deg(29)), 1e-6);
    assert_true(d3d_spot(&l, off_axis(31)) == 0.0f);

    light p = point_light(0.0f, 0.0f, 1.0f, INFINITY);
    assert_true(d3d_spot(&p, off_axis(80)) == 1.0f);
}

static void test_lambert_blinn(void **state)
{
    (void)state;
    close_rel(d3d_lambert(0.3f), 0.3, 1e-7);
    assert_true(d3d_lambert(-0.2f) == 0.0f);
    assert_true(d3d_lambert(1.5f) == 1.0f);
    close_rel(d3d_blinn(0.9f, 10.0f), 0.3486784401, 1e-6); /* 0.9^10 */
    /* 0.9999^1e4 = exp(1e4 ln 0.9999) = exp(-1.000050003) = 0.3678610 */
    close_rel(d3d_blinn(0.9999f, 1e4f), 0.3678610464, 5e-4); /* 0.9999f = 0.99989998: 2.0e-4 lower */
    assert_true(d3d_blinn(0.5f, 0.0f) == 1.0f);
    assert_true(d3d_blinn(0.0f, 0.0f) == 0.0f);
    assert_true(d3d_blinn(-0.5f, 20.0f) == 0.0f);
    assert_true(d3d_blinn(0.5f, -1.0f) == 1.0f);
    assert_true(d3d_blinn(0.5f, 1e30f) == 0.0f);
}

/* Camera C = (0, 0, 5), point X = (2, 0, 0), light direction L = (0, 1, 0), N = (0, 0.6, 0.8).
 * local:    V = (-2, 0, 5)/sqrt 29; |L + V|^2 = 2 (L.V = 0);
 *           H = (-0.2626129, 0.7071068, 0.6565322), N.H = 0.9494898, ^20 = 0.3546550
 * infinite: E = (0, 0, 1), H = (0, 1, 1)/sqrt 2, N.H = 1.4/sqrt 2 = 0.9899495, ^20 = 0.8170728 */
static void test_half_vector_local_vs_infinite(void **state)
{
    (void)state;
    vec3 eye = v3(0.0f, 0.0f, 5.0f), x = v3(2.0f, 0.0f, 0.0f), n = v3(0.0f, 0.6f, 0.8f);
    vec3 l = v3(0.0f, 3.0f, 0.0f); /* not unit on purpose */
    vec3 hl = d3d_half_vector(l, v3_sub(eye, x), v3(0.0f, 0.0f, 1.0f), 1);
    vec3 hi = d3d_half_vector(l, v3_sub(eye, x), v3(0.0f, 0.0f, 1.0f), 0);
    close_rel(hl.x, -0.2626128657, 1e-6);
    close_rel(hl.y, 0.7071067812, 1e-6);
    close_rel(hl.z, 0.6565321643, 1e-6);
    close_rel(hi.x + 1.0, 1.0, 1e-7);
    close_rel(hi.y, 0.7071067812, 1e-6);
    close_rel(hi.z, 0.7071067812, 1e-6);
    float sl = d3d_blinn(v3_dot(n, hl), 20.0f), si = d3d_blinn(v3_dot(n, hi), 20.0f);
    close_rel(sl, 0.3546549895, 1e-5);
    close_rel(si, 0.8170728069, 1e-5);
    assert_true(si - sl > 0.4f); /* the infinite viewer misplaces this highlight */
}

static void test_half_vector_degenerate(void **state)
{
    (void)state;
    vec3 h = d3d_half_vector(v3(0.0f, 0.0f, 1.0f), v3(0.0f, 0.0f, -1.0f), v3(0, 0, 1), 1);
    assert_true(h.x == 0.0f && h.y == 0.0f && h.z == 0.0f);
    assert_true(d3d_blinn(v3_dot(v3(0, 1, 0), h), 30.0f) == 0.0f);
    /* denormal-length inputs still normalise */
    h = d3d_half_vector(v3(0.0f, 1e-44f, 0.0f), v3(1e-44f, 0.0f, 0.0f), v3(0, 0, 1), 1);
    close_rel(h.x, 0.7071067812, 1e-6);
    close_rel(h.y, 0.7071067812, 1e-6);
}

static const float extremes[] = {
    -FLT_MAX, -1e30f,     -1.0f, -1e-45f,    0.0f, 1e-45f, 1e-38f, 1e-12f, 1e-6f,
    0.3f,     0.9999999f, 1.0f,  1.0000001f, 2.0f, 1e4f,   1e6f,   1e30f,  FLT_MAX,
};
#define N_EXTREMES (sizeof extremes / sizeof extremes[0])

static void test_extremes_finite(void **state)
{
    (void)state;
    size_t bad = 0, n = 0;
    for (size_t i = 0; i < N_EXTREMES; i++) {
        float a = extremes[i];
        bad += !isfinite(d3d_lambert(a));
        n++;
        for (size_t j = 0; j < N_EXTREMES; j++) {
            float b = extremes[j];
            float s = d3d_blinn(a, b);
            bad += !(s >= 0.0f && s <= 1.0f);
            vec3 h = d3d_half_vector(v3(a, b, 0.5f), v3(b, -a, 1e-30f), v3(0, 0, 1), (int)(i & 1));
            bad += !isfinite(h.x) + !isfinite(h.y) + !isfinite(h.z);
            n += 4;
            for (size_t k = 0; k < N_EXTREMES; k++) {
                light l = point_light(a, b, extremes[k], extremes[(i + j) % N_EXTREMES]);
                for (size_t m = 0; m < N_EXTREMES; m++) {
                    bad += !isfinite(d3d_attenuation(&l, fabsf(extremes[m])));
                    n++;
                }
                l.kind = LIGHT_SPOT;
                l.inner = a;
                l.outer = b;
                l.falloff = extremes[k];
                for (int p = 0; p < 2; p++) {
                    l.profile = p ? SPOT_SMOOTH : SPOT_D3D;
                    for (size_t m = 0; m < N_EXTREMES; m++) {
                        l.direction = v3(extremes[m], -1.0f, 0.0f);
                        float sp = d3d_spot(&l, v3_norm(v3(0.3f, -1.0f, 0.2f)));
                        bad += !isfinite(sp);
                        n++;
                    }
                }
            }
        }
    }
    if (bad)
        fail_msg("%zu of %zu evaluations were not finite or out of range", bad, n);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_attenuation),
        cmocka_unit_test(test_spot),
        cmocka_unit_test(test_lambert_blinn),
        cmocka_unit_test(test_half_vector_local_vs_infinite),
        cmocka_unit_test(test_half_vector_degenerate),
        cmocka_unit_test(test_extremes_finite),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
