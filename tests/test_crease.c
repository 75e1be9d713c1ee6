/* test_crease.c - where a renderer's shading-normal rules depart from the model's (harness/crease.h).
 *
 * Single samples are worked by hand in the plane of the figure (angles from the geometric
 * normal Ng = +z); the mesh case is a 2 x 2 quad seen from straight above whose vertex normals
 * lean out along x as a ridge's smoothed normals would, N(x) ~ (3x, 1, 0): the mirror direction
 * drops below the quad (valid_reflection) where the lean passes about 45 degrees, |x| > 1/3. A
 * light below the quad's plane is no rule (Cycles lights it by N.L: tests/crease_blender.sh), so
 * a scene with one gives the same layer. Runs from the repository root.
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
#include "metrics.h"
#include "render.h"

#define PI 3.14159265358979323846

static vec3 dir_deg(double deg) { return v3((float)sin(deg * PI / 180.0), 0.0f, (float)cos(deg * PI / 180.0)); }

static void test_flat_and_back_face(void **state)
{
    (void)state;
    vec3 ng = v3(0.0f, 0.0f, 1.0f);
    assert_int_equal(crease_departs(ng, ng, dir_deg(30.0)), 0);
    /* A back face: Cycles flips N with Ng, so a flat back face is no crease. */
    vec3 back = v3_neg(ng);
    assert_int_equal(crease_departs(back, back, dir_deg(30.0)), 0);
}

/* V at 45 degrees. N leaning 10 degrees away: R at -65 degrees, R.Ng = cos 65 = 0.42, kept.
 * N leaning 30 degrees away: R at -105 degrees, below the surface, so Cycles bends N. */
static void test_mirror_below(void **state)
{
    (void)state;
    vec3 ng = v3(0.0f, 0.0f, 1.0f), v = dir_deg(45.0);
    assert_int_equal(crease_departs(dir_deg(-10.0), ng, v), 0);
    assert_int_equal(crease_departs(dir_deg(-30.0), ng, v), CREASE_RULE_VALID_REFLECTION);
}

/* At grazing view the lift Cycles asks for is 0.9 Ng.V, not 0.01: with N = Ng and V at 89.7
 * degrees, R.Ng = Ng.V = 0.0052, which passes 0.9 * 0.0052 but would fail a fixed 0.01. */
static void test_grazing_lift(void **state)
{
    (void)state;
    vec3 ng = v3(0.0f, 0.0f, 1.0f);
    assert_int_equal(crease_departs(ng, ng, dir_deg(89.7)), 0);
}

/* N leaning 61 degrees away from the viewer's side while Ng faces it: the model turns N round;
 * Cycles keeps it (back_face), and its mirror direction then lies below the surface
 * (valid_reflection). V at 30, N at -61: N.V = cos 91 < 0. */
static void test_normal_away(void **state)
{
    (void)state;
    vec3 ng = v3(0.0f, 0.0f, 1.0f);
    assert_int_equal(crease_departs(dir_deg(-61.0), ng, dir_deg(30.0)),
                     CREASE_RULE_BACK_FACE | CREASE_RULE_VALID_REFLECTION);
    /* The same seen from below the triangle (its wound side up): Cycles flips N and Ng toward
     * the viewer, and it is the case above turned over. */
    assert_int_equal(crease_departs(dir_deg(-61.0), ng, v3_neg(dir_deg(30.0))),
                     CREASE_RULE_BACK_FACE | CREASE_RULE_VALID_REFLECTION);
}

/* The rule bits of a layer pick the pixels per renderer: a pixel with only valid_reflection
 * leaves the surface for a renderer with that rule, not for one with only back_face; pixels
 * outside the interior, and values that are no rule bits (an older share layer's fraction, NaN),
 * stay where they are. */
static void test_classify_rules(void **state)
{
    (void)state;
    unsigned char cls[6] = {METRICS_PX_INTERIOR, METRICS_PX_INTERIOR, METRICS_PX_INTERIOR,
                            METRICS_PX_INTERIOR, METRICS_PX_EDGE,     METRICS_PX_INTERIOR};
    const float layer[6] = {0.0f, 2.0f, 3.0f, 0.5f, 3.0f, NAN};
    long interior = 0, per_rule[CREASE_RULE_COUNT];
    unsigned char a[6], b[6];
    memcpy(a, cls, sizeof cls);
    memcpy(b, cls, sizeof cls);
    assert_int_equal(crease_classify_rules(a, layer, 6, CREASE_RULE_VALID_REFLECTION, &interior, per_rule), 2);
    assert_int_equal(interior, 5);
    assert_int_equal(per_rule[0], 0);
    assert_int_equal(per_rule[1], 2);
    assert_int_equal(a[1], METRICS_PX_CREASE);
    assert_int_equal(a[2], METRICS_PX_CREASE);
    assert_int_equal(a[3], METRICS_PX_INTERIOR);
    assert_int_equal(a[4], METRICS_PX_EDGE);
    assert_int_equal(a[5], METRICS_PX_INTERIOR);
    assert_int_equal(crease_classify_rules(b, layer, 6, CREASE_RULE_BACK_FACE, NULL, per_rule), 1);
    assert_int_equal(per_rule[0], 1);
    assert_int_equal(b[1], METRICS_PX_INTERIOR);
    assert_int_equal(b[2], METRICS_PX_CREASE);
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
             * share x); the boundaries lie between pixel centres (|x| = 0.25 or 0.42 near 1/3).
             * The light below the quad changes nothing. */
            int want = fabsf(hx) > 1.0f / 3.0f ? CREASE_RULE_VALID_REFLECTION : 0;
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

/* Two quads side by side on y = 0 under quad_case's camera (12 x 12, world x in [-1, 1] across),
 * meeting on the line x = xe through the centres of column 6 (x = 0.0833, 6.5 samples) moved by
 * d samples. Split (the right quad has its own vertices there): the line is an open edge, and a
 * sample nearer than the tie band (8 2^-24 6 / 0.2 = 1.4e-5 samples here) is a tie in every row
 * of column 6. Controls: the same quads welded (shared vertex indices: the edge is closed), and
 * the split ones with the line 1e-3 samples away, 70 bands. */
static void tie_case(double d, int welded, int want_tie)
{
    scene *s = calloc(1, sizeof *s);
    assert_non_null(s);
    scene_init(s);
    snprintf(s->path, sizeof s->path, "test_crease ties");
    const int w = 12;
    s->width = s->height = w;
    s->supersample = 1;
    s->camera.eye = v3(0.0f, 5.0f, 0.0f);
    s->camera.target = v3(0.0f, 0.0f, 0.0f);
    s->camera.up = v3(0.0f, 0.0f, -1.0f);
    s->camera.hfov = (float)(2.0 * atan(1.0 / 5.0));
    assert_true(fabs(crease_tie_band(s, w, 1) - 8.0 * ldexp(1.0, -24) * 6.0 / 0.2) < 1e-9);
    float xe = (float)((6.5 + d) / 6.0 - 1.0);
    vec3 pos[8] = {v3(-1.2f, 0.0f, -1.2f), v3(xe, 0.0f, -1.2f),   v3(xe, 0.0f, 1.2f),   v3(-1.2f, 0.0f, 1.2f),
                   v3(xe, 0.0f, -1.2f),    v3(1.2f, 0.0f, -1.2f), v3(1.2f, 0.0f, 1.2f), v3(xe, 0.0f, 1.2f)};
    vec3 nrm[8];
    for (int i = 0; i < 8; i++)
        nrm[i] = v3(0.0f, 1.0f, 0.0f);
    uint32_t idx[12] = {0, 2, 1, 0, 3, 2, 4, 6, 5, 4, 7, 6};
    if (welded) {
        idx[6] = 1;
        idx[9] = 1;
        idx[10] = 2;
    }
    mesh m = {.n_verts = 8, .n_tris = 4, .pos = pos, .nrm = nrm, .idx = idx};
    float share[12 * 12];
    char err[512];
    assert_int_equal(crease_share(s, &m, w, w, 1, 1, share, err, sizeof err), RC_OK);
    for (int y = 0; y < w; y++)
        for (int x = 0; x < w; x++) {
            float want = want_tie && x == 6 ? (float)CREASE_TIE : 0.0f;
            if (share[y * w + x] != want)
                fail_msg("d %g samples, %s: pixel (%d, %d) has %g, want %g", d, welded ? "welded" : "split", x, y,
                         (double)share[y * w + x], (double)want);
        }
    unsigned char cls[12 * 12];
    memset(cls, METRICS_PX_INTERIOR, sizeof cls);
    long interior = 0;
    assert_int_equal(crease_classify_ties(cls, share, sizeof cls, &interior), want_tie ? w : 0);
    assert_int_equal(interior, w * w);
    free(s);
}

static void test_ties(void **state)
{
    (void)state;
    tie_case(4e-6, 0, 1);
    tie_case(-4e-6, 0, 1);
    tie_case(4e-6, 1, 0);
    tie_case(1e-3, 0, 0);
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
        cmocka_unit_test(test_grazing_lift),       cmocka_unit_test(test_ties),
        cmocka_unit_test(test_normal_away),        cmocka_unit_test(test_classify_rules),
        cmocka_unit_test(test_quad_mirror),        cmocka_unit_test(test_quad_light),
        cmocka_unit_test(test_bad_size),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
