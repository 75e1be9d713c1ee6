/* The shading loop: each model's terms at a point against values worked out here in double
 * from the equations of docs/models.md, and the specialised paths against the general one. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include "shade.h"

#define PI 3.14159265358979323846

static double rel(double a, double b) { return fabs(a - b) / fmax(fabs(b), 1e-30); }

static void base_scene(scene *s)
{
    scene_init(s);
    s->camera.eye = v3(0.0f, 1.0f, -1.0f);
    s->camera.target = v3(0.0f, 0.0f, 0.0f);
    s->n_materials = 1;
    material_init(&s->materials[0]);
    s->materials[0].d9.alpha = 1.0f;
}

/* Lambert under a sun: Vd * E/pi * cos, per channel (asymmetric colours catch swaps). */
static void test_d3d_sun_lambert(void **state)
{
    (void)state;
    scene s;
    base_scene(&s);
    s.n_lights = 1;
    light_init(&s.lights[0]);
    s.lights[0].kind = LIGHT_SUN;
    s.lights[0].direction = v3(-0.6f, -0.8f, 0.0f);
    s.lights[0].intensity = v3(3.0f, 2.0f, 1.0f);
    s.materials[0].d3d.diffuse = v3(0.5f, 0.25f, 0.75f);
    env_map env = {.kind = ENV_NONE};
    shade_context c;
    shade_context_make(&s, &env, &c);
    shade_plan p;
    shade_plan_make(&c, &s.materials[0], &p);
    assert_string_equal(p.path, "d3d-diffuse");
    shade_terms t;
    vec3 x = v3(0.1f, 0.0f, 0.2f);
    shade_eval(&c, &p, x, v3(0, 1, 0), v3_norm(v3_sub(s.camera.eye, x)), &t);
    assert_true(rel(t.diffuse.x, 0.5 * 3.0 / PI * 0.8) < 1e-6);
    assert_true(rel(t.diffuse.y, 0.25 * 2.0 / PI * 0.8) < 1e-6);
    assert_true(rel(t.diffuse.z, 0.75 * 1.0 / PI * 0.8) < 1e-6);
    assert_true(t.specular.x == 0.0f && t.reflection.x == 0.0f);
}

/* Point light with D3D attenuation and Blinn-Phong, local and infinite viewer. */
static void test_d3d_point_blinn(void **state)
{
    (void)state;
    scene s;
    base_scene(&s);
    s.n_lights = 1;
    light_init(&s.lights[0]);
    s.lights[0].position = v3(0.0f, 2.0f, 1.0f);
    s.lights[0].intensity = v3(10.0f, 10.0f, 10.0f);
    s.lights[0].a0 = 0.5f; /* A = 1/(0.5 + d^2) */
    material *m = &s.materials[0];
    m->d3d.diffuse = v3(0.2f, 0.4f, 0.6f);
    m->d3d.specular = v3(0.5f, 0.5f, 0.5f);
    m->d3d.power = 20.0f;
    env_map env = {.kind = ENV_NONE};
    shade_context c;
    shade_context_make(&s, &env, &c);
    shade_plan p;
    shade_plan_make(&c, m, &p);
    assert_string_equal(p.path, "d3d-full");

    /* At x = (0.5, 0, 0): to light (-0.5, 2, 1), d^2 = 5.25; A = 1/5.75. */
    double lx = -0.5, ly = 2, lz = 1, d = sqrt(5.25);
    lx /= d;
    ly /= d;
    lz /= d;
    double colour = 10.0 / 5.75 / PI;
    double vx = -0.5, vy = 1, vz = -1, vl = sqrt(2.25);
    vx /= vl;
    vy /= vl;
    vz /= vl;
    double hx = lx + vx, hy = ly + vy, hz = lz + vz, hl = sqrt(hx * hx + hy * hy + hz * hz);
    double spec_local = 0.5 * colour * pow(hy / hl, 20.0);
    /* Infinite viewer: E = norm(eye - target) = (0, 1, -1)/sqrt 2. */
    double ex = 0, ey = 1 / sqrt(2.0), ez = -1 / sqrt(2.0);
    double gx = lx + ex, gy = ly + ey, gz = lz + ez, gl = sqrt(gx * gx + gy * gy + gz * gz);
    double spec_inf = 0.5 * colour * pow(gy / gl, 20.0);

    shade_terms t;
    vec3 x = v3(0.5f, 0.0f, 0.0f);
    vec3 v = v3_norm(v3_sub(s.camera.eye, x));
    shade_eval(&c, &p, x, v3(0, 1, 0), v, &t);
    assert_true(rel(t.diffuse.y, 0.4 * colour * ly) < 1e-5);
    assert_true(rel(t.specular.x, spec_local) < 1e-4);
    m->d3d.local_viewer = 0;
    shade_eval(&c, &p, x, v3(0, 1, 0), v, &t);
    assert_true(rel(t.specular.x, spec_inf) < 1e-4);
    assert_true(fabs(spec_inf - spec_local) > 1e-3 * spec_local); /* the fixture tells them apart */

    /* A light below the surface gives nothing, not even a highlight. */
    s.lights[0].position = v3(0.0f, -2.0f, 1.0f);
    shade_eval(&c, &p, x, v3(0, 1, 0), v, &t);
    assert_true(t.diffuse.x == 0.0f && t.specular.x == 0.0f);
}

/* D3D9Client: reflection = (lambda (1 - R) + s R) phi, diffuse = d (1 - |lambda|). */
static void test_d3d9client_terms(void **state)
{
    (void)state;
    scene s;
    base_scene(&s);
    s.n_lights = 1;
    light_init(&s.lights[0]);
    s.lights[0].kind = LIGHT_SUN;
    s.lights[0].direction = v3(0.0f, -1.0f, 0.0f);
    s.lights[0].intensity = v3s(PI);
    material *m = &s.materials[0];
    m->model = MODEL_D3D9CLIENT;
    m->d3d.diffuse = v3(0.6f, 0.5f, 0.4f);
    m->d9.p = 3.0f;
    m->d9.r0 = 0.04f;
    m->d9.m = 0.96f;
    m->d9.reflect = v3(0.5f, 0.3f, 0.1f);
    env_map env = {.kind = ENV_CONSTANT, .constant = {2.0f, 1.0f, 4.0f}};
    shade_context c;
    shade_context_make(&s, &env, &c);
    shade_plan p;
    shade_plan_make(&c, m, &p);
    shade_terms t;
    /* View at 60 degrees from the normal: cos = 0.5, R = 0.04 + 0.96 * 0.125 = 0.16. */
    vec3 v = v3(0.0f, 0.5f, -0.8660254f);
    shade_eval(&c, &p, v3(0, 0, 0), v3(0, 1, 0), v, &t);
    double R = 0.16;
    assert_true(rel(t.reflection.x, (0.5 * (1 - R) + R) * 2.0) < 1e-5);
    assert_true(rel(t.reflection.z, (0.1 * (1 - R) + R) * 4.0) < 1e-5);
    /* sun E = pi straight down: d = Vd * 1, |lambda| (max) = 0.5. */
    assert_true(rel(t.diffuse.x, 0.6 * 0.5) < 1e-5);
    assert_true(rel(t.diffuse.z, 0.4 * 0.5) < 1e-5);
    /* (7): alpha = max(d_a = 1, |R_tot|) with |R_tot| = max component. */
    double rt = fmax(fmax((0.5 * (1 - R) + R) * 2.0, (0.3 * (1 - R) + R) * 1.0), (0.1 * (1 - R) + R) * 4.0);
    assert_true(rel(t.alpha, fmax(1.0, rt)) < 1e-5);
}

/* Cook-Torrance: Lambert diffuse plus F D G/(4 NL NV) E cos and Schlick-weighted environment. */
static void test_cooktorrance_terms(void **state)
{
    (void)state;
    scene s;
    base_scene(&s);
    s.n_lights = 1;
    light_init(&s.lights[0]);
    s.lights[0].kind = LIGHT_SUN;
    s.lights[0].direction = v3_norm(v3(-0.3f, -1.0f, 0.2f));
    s.lights[0].intensity = v3(2.0f, 2.0f, 2.0f);
    material *m = &s.materials[0];
    m->model = MODEL_COOK_TORRANCE;
    m->albedo = v3(0.1f, 0.2f, 0.3f);
    m->ct.m = 0.3f;
    m->ct.f0 = v3(0.9f, 0.6f, 0.3f);
    env_map env = {.kind = ENV_CONSTANT, .constant = {1.0f, 1.0f, 1.0f}};
    shade_context c;
    shade_context_make(&s, &env, &c);
    shade_plan p;
    shade_plan_make(&c, m, &p);
    assert_string_equal(p.path, "cook-torrance-env");
    vec3 n = v3(0, 1, 0), v = v3_norm(v3(0.2f, 0.7f, -0.6f));
    shade_terms t;
    shade_eval(&c, &p, v3(0, 0, 0), n, v, &t);

    double l[3] = {0.3, 1.0, -0.2}, ll = sqrt(0.09 + 1 + 0.04);
    double vv[3] = {0.2, 0.7, -0.6}, vl = sqrt(0.04 + 0.49 + 0.36);
    for (int i = 0; i < 3; i++) {
        l[i] /= ll;
        vv[i] /= vl;
    }
    double h[3] = {l[0] + vv[0], l[1] + vv[1], l[2] + vv[2]};
    double hl = sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    for (int i = 0; i < 3; i++)
        h[i] /= hl;
    double nl = l[1], nv = vv[1], nh = h[1], vh = vv[0] * h[0] + vv[1] * h[1] + vv[2] * h[2];
    double tan2 = (1 - nh * nh) / (nh * nh);
    double D = exp(-tan2 / 0.09) / (PI * 0.09 * nh * nh * nh * nh);
    double G = fmin(1.0, fmin(2 * nh * nv / vh, 2 * nh * nl / vh));
    double F = 0.9 + 0.1 * pow(1 - vh, 5);
    assert_true(rel(t.specular.x, F * D * G / (4 * nl * nv) * 2.0 * nl) < 1e-4);
    assert_true(rel(t.diffuse.y, 0.2 / PI * 2.0 * nl) < 1e-5);
    double fr = 0.3 + 0.7 * pow(1 - nv, 5);
    assert_true(rel(t.reflection.z, fr) < 1e-5);
}

/* The specialised plan gives the same numbers as the general path. */
static void test_specialised_equals_general(void **state)
{
    (void)state;
    scene s;
    base_scene(&s);
    s.n_lights = 2;
    light_init(&s.lights[0]);
    s.lights[0].position = v3(1.0f, 3.0f, 0.5f);
    s.lights[0].intensity = v3(5.0f, 4.0f, 3.0f);
    light_init(&s.lights[1]);
    s.lights[1].kind = LIGHT_SUN;
    s.lights[1].intensity = v3(1.0f, 2.0f, 3.0f);
    env_map env = {.kind = ENV_NONE};
    shade_context c;
    shade_context_make(&s, &env, &c);
    shade_plan fast, general;
    shade_plan_make(&c, &s.materials[0], &fast);
    shade_plan_make_general(&c, &s.materials[0], &general);
    assert_true(fast.fn != general.fn);
    for (int i = 0; i < 50; i++) {
        float a = 0.1f * (float)i;
        vec3 n = v3_norm(v3(sinf(a), 1.0f, cosf(3 * a) * 0.5f));
        vec3 x = v3(0.1f * (float)i, 0.0f, -0.05f * (float)i);
        vec3 v = v3_norm(v3_sub(s.camera.eye, x));
        shade_terms tf, tg;
        shade_eval(&c, &fast, x, n, v, &tf);
        shade_eval(&c, &general, x, n, v, &tg);
        assert_true(tf.diffuse.x == tg.diffuse.x && tf.diffuse.y == tg.diffuse.y && tf.diffuse.z == tg.diffuse.z);
        assert_true(tg.specular.x == 0.0f);
    }
}

/* Stiff cases stay finite: light on the surface, roughness 1e-4, power 1e4, HDR 1e6. */
static void test_extremes_finite(void **state)
{
    (void)state;
    scene s;
    base_scene(&s);
    s.n_lights = 1;
    light_init(&s.lights[0]);
    s.lights[0].position = v3(0.0f, 1e-6f, 0.0f);
    s.lights[0].intensity = v3s(1e6f);
    env_map env = {.kind = ENV_CONSTANT, .constant = {1e6f, 1e6f, 1e6f}};
    shade_context c;
    shade_context_make(&s, &env, &c);
    const model_kind models[3] = {MODEL_D3D, MODEL_D3D9CLIENT, MODEL_COOK_TORRANCE};
    for (int mi = 0; mi < 3; mi++) {
        material *m = &s.materials[0];
        m->model = models[mi];
        m->d3d.specular = v3s(1.0f);
        m->d3d.power = 1e4f;
        m->ct.m = 1e-4f;
        shade_plan p;
        shade_plan_make(&c, m, &p);
        const vec3 xs[3] = {v3(0, 0, 0), v3(1e-7f, 0, 0), v3(0, 1e-6f, 0)};
        for (int xi = 0; xi < 3; xi++) {
            shade_terms t;
            shade_eval(&c, &p, xs[xi], v3(0, 1, 0), v3_norm(v3(0, 1e-7f, -1)), &t);
            float sum = v3_sum(t.diffuse) + v3_sum(t.specular) + v3_sum(t.reflection) + t.alpha;
            assert_true(isfinite(sum));
        }
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_d3d_sun_lambert),
        cmocka_unit_test(test_d3d_point_blinn),
        cmocka_unit_test(test_d3d9client_terms),
        cmocka_unit_test(test_cooktorrance_terms),
        cmocka_unit_test(test_specialised_equals_general),
        cmocka_unit_test(test_extremes_finite),
    };
    return cmocka_run_group_tests_name("shade", tests, NULL, NULL);
}
