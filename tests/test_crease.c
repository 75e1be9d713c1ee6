/* test_crease.c - where Cycles' shading-normal rules depart from the model's (harness/crease.h).
 *
 * Single samples are worked by hand in the plane of the figure (angles from the geometric
 * normal Ng = +z); the mesh case is a 2 x 2 quad seen from straight above whose vertex normals
 * lean out along x as a ridge's smoothed normals would, N(x) ~ (3x, 1, 0): the mirror direction
 * drops below the quad (rule 2) where the lean passes about 45 degrees, |x| > 1/3, and a light
 * grazing in from +x just below the quad (rule 3) lights only the half whose N leans toward it.
 * Runs from the repository root.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "crease.h"
#include "render.h"

#define PI 3.14159265358979323846

static vec3 dir_deg(double deg) { return v3((float)sin(deg * PI / 180.0), 0.0f, (float)cos(deg * PI / 180.0)); }

static void test_flat_and_back_face(void **state)
{
    (void)state;
    vec3 ng = v3(0.0f, 0.0f, 1.0f);
    assert_int_equal(crease_departs(ng, ng, dir_deg(30.0), NULL, 0), 0);
    /* A back face: Cycles flips N with Ng, so a flat back face is no crease. */
    vec3 back = v3_neg(ng);
    assert_int_equal(crease_departs(back, back, dir_deg(30.0), NULL, 0), 0);
}

/* V at 45 degrees. N leaning 10 degrees away: R at -65 degrees, R.Ng = cos 65 = 0.42, kept.
 * N leaning 30 degrees away: R at -105 degrees, below the surface, so Cycles bends N. */
static void test_mirror_below(void **state)
{
    (void)state;
    vec3 ng = v3(0.0f, 0.0f, 1.0f), v = dir_deg(45.0);
    assert_int_equal(crease_departs(dir_deg(-10.0), ng, v, NULL, 0), 0);
    assert_int_equal(crease_departs(dir_deg(-30.0), ng, v, NULL, 0), 1);
}

/* At grazing view the lift Cycles asks for is 0.9 Ng.V, not 0.01: with N = Ng and V at 89.7
 * degrees, R.Ng = Ng.V = 0.0052, which passes 0.9 * 0.0052 but would fail a fixed 0.01. */
static void test_grazing_lift(void **state)
{
    (void)state;
    vec3 ng = v3(0.0f, 0.0f, 1.0f);
    assert_int_equal(crease_departs(ng, ng, dir_deg(89.7), NULL, 0), 0);
}

/* N leaning 60 degrees toward the viewer's side while Ng faces it: the model turns N round;
 * Cycles keeps it (rule 1). V at 30, N at -60: N.V = cos 90 - a hair below 0. */
static void test_normal_away(void **state)
{
    (void)state;
    vec3 ng = v3(0.0f, 0.0f, 1.0f);
    assert_int_equal(crease_departs(dir_deg(-61.0), ng, dir_deg(30.0), NULL, 0), 1);
}

/* N at 30 degrees, V straight above (R at 60, kept). A light at 95 degrees is 5 below the
 * surface and 65 from N: the model lights the sample, Cycles does not. At 85 degrees both do. */
static void test_light_below(void **state)
{
    (void)state;
    vec3 ng = v3(0.0f, 0.0f, 1.0f), n = dir_deg(30.0), v = dir_deg(0.0);
    vec3 below = dir_deg(95.0), above = dir_deg(85.0);
    assert_int_equal(crease_departs(n, ng, v, &above, 1), 0);
    assert_int_equal(crease_departs(n, ng, v, &below, 1), 1);
    /* Below the surface and below N's horizon too: both give nothing, no departure. */
    vec3 far_below = dir_deg(-95.0);
    assert_int_equal(crease_departs(n, ng, v, &far_below, 1), 0);
}

/* The quad y = 0, |x|, |z| <= 1, under a camera at (0, 5, 0) whose view just spans it. */
static void quad_case(int with_light)
{
    scene *s = calloc(1, sizeof *s);
    assert_non_null(s);
    scene_init(s);
    snprintf(s->path, sizeof s->path, "test_crease quad");
    const int w = 12;
    s->width = s->height = w;
    s->supersample = 1;
    s->camera.eye = v3(0.0f, 5.0f, 0.0f);
    s->camera.target = v3(0.0f, 0.0f, 0.0f);
    s->camera.up = v3(0.0f, 0.0f, -1.0f);
    s->camera.hfov = (float)(2.0 * atan(1.0 / 5.0));
    if (with_light) {
        s->n_lights = 1;
        s->lights[0].kind = LIGHT_SUN;
        /* Travels toward -x and slightly up: L = (1, -0.1, 0) normalised, below the quad. */
        s->lights[0].direction = v3_norm(v3(-1.0f, 0.1f, 0.0f));
    }
    vec3 pos[4] = {v3(-1.0f, 0.0f, -1.0f), v3(1.0f, 0.0f, -1.0f), v3(1.0f, 0.0f, 1.0f), v3(-1.0f, 0.0f, 1.0f)};
    vec3 nrm[4] = {v3_norm(v3(-3.0f, 1.0f, 0.0f)), v3_norm(v3(3.0f, 1.0f, 0.0f)), v3_norm(v3(3.0f, 1.0f, 0.0f)),
                   v3_norm(v3(-3.0f, 1.0f, 0.0f))};
    uint32_t idx[6] = {0, 2, 1, 0, 3, 2};
    mesh m = {.n_verts = 4, .n_tris = 2, .pos = pos, .nrm = nrm, .idx = idx};
    float share[12 * 12];
    char err[512];
    assert_int_equal(crease_share(s, &m, w, w, 1, 1, share, err, sizeof err), RC_OK);
    render_camera cam;
    render_camera_make(s, w, w, &cam);
    for (int y = 0; y < w; y++)
        for (int x = 0; x < w; x++) {
            vec3 d = render_camera_ray(&cam, (float)x + 0.5f, (float)y + 0.5f);
            float hx = cam.eye.x + d.x * (-cam.eye.y / d.y); /* where the ray meets y = 0 */
            /* The normals lean by atan(3|x|) (bilinear in x only, as both triangles' corners
             * share x); the boundaries lie between pixel centres (|x| = 0.25 or 0.42 near 1/3;
             * the light's N.L = 0 at x = 0.033, between 0 and 0.083). */
            int want = fabsf(hx) > 1.0f / 3.0f || (with_light && hx > 0.0f);
            assert_float_equal(share[y * w + x], (float)want, 0.0f);
        }
    free(s);
}

static void test_quad_mirror(void **state)
{
    (void)state;
    quad_case(0);
}

static void test_quad_light(void **state)
{
    (void)state;
    quad_case(1);
}

static void test_bad_size(void **state)
{
    (void)state;
    scene *s = calloc(1, sizeof *s);
    assert_non_null(s);
    scene_init(s);
    snprintf(s->path, sizeof s->path, "test_crease bad");
    mesh m = {0};
    float share[1];
    char err[512] = "";
    assert_int_equal(crease_share(s, &m, 0, 4, 1, 1, share, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "test_crease bad"));
    free(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_flat_and_back_face), cmocka_unit_test(test_mirror_below),
        cmocka_unit_test(test_grazing_lift),       cmocka_unit_test(test_normal_away),
        cmocka_unit_test(test_light_below),        cmocka_unit_test(test_quad_mirror),
        cmocka_unit_test(test_quad_light),         cmocka_unit_test(test_bad_size),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
