/* test_blend - D3D's SRCALPHA/INVSRCALPHA blend of a D3D9Client pane (d3d9client.blend,
 * render/render.h) over what lies behind it, worked out by hand.
 *
 * Usage: make BUILD=x check T=blend
 *
 * The scene, seen from above (eye at y = 5, looking down -Y): a pane quad at y = 1 over an
 * emissive D3D quad at y = 0 that covers only the middle column, under a constant environment
 * L. The pane is a D3D9Client material with p = 0 and m = 0, so R = R0 at every angle; it has no
 * diffuse (black albedo, no lights) and lambda = 0, so eq. (6) gives c = R_tot = R0 L and eq. (7)
 * c_a = max(d_a, |R0 L|), |.| the largest component. The blend gives
 *   out = c a + behind (1 - a),  A = a a + A_behind (1 - a),  a = c_a clamped to [0, 1],
 * behind the emissive colour E (A_behind 1, the D3D model's alpha) in the middle column and the
 * environment L (A_behind 0) beside it. With R0 = 0.2, L = (0.5, 1, 2), d_a = 0.1:
 *   c = (0.1, 0.2, 0.4), a = 0.4; middle: 0.4 c + 0.6 E, E = (0.2, 0.4, 0.6) -> (0.16, 0.32, 0.52),
 *   A = 0.16 + 0.6 = 0.76; beside: 0.4 c + 0.6 L = (0.34, 0.68, 1.36), A = 0.16.
 * With L = (10, 1, 1): c = (2, 0.2, 0.2), c_a = 2 clamps to a = 1: out = c, the pane opaque (without
 * the clamp it would be 2c - E = (3.8, 0, -0.2)). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "check.h"
#include "frame.h"
#include "mesh.h"
#include "render.h"
#include "renderers/povray/povray.h"
#include "scene_file.h"

static const char scene_fmt[] = "image: {width: 3, height: 3, supersample: 1}\n"
                                "camera: {eye: [0, 5, 0], target: [0, 0, 0], up: [0, 0, -1], hfov: 20}\n"
                                "environment: {constant: [%g, %g, %g]}\n"
                                "materials:\n"
                                "  pane: {albedo: [0, 0, 0], model: d3d9client,\n"
                                "         d3d9client: {p: 0, r0: 0.2, m: 0, alpha: 0.1, blend: %s}}\n"
                                "  back: {albedo: [0, 0, 0], model: d3d, d3d: {emissive: [0.2, 0.4, 0.6]}}\n"
                                "objects:\n"
                                "  - {shape: quad, size: [1, 2], material: back}\n"
                                "  - {shape: quad, size: [2, 2], center: [0, %g, 0], material: pane}\n";

/* R, G, B, A of pixel (x, 1) of the scene with environment L, blend on or off and the pane at
 * height y. */
static void pixel(const double L[3], const char *blend, double y, int x, float rgba[4])
{
    char text[2048], err[1024];
    snprintf(text, sizeof text, scene_fmt, L[0], L[1], L[2], blend, y);
    scene *s = malloc(sizeof *s);
    assert_non_null(s);
    mesh m = {0};
    env_map env;
    float *px = NULL;
    if (scene_file_parse(text, strlen(text), "blend.yaml", s, err, sizeof err) != RC_OK)
        fail_msg("%s", err);
    assert_int_equal(mesh_build(s, &m, err, sizeof err), RC_OK);
    assert_int_equal(frame_env_load(s, &env, &px, err, sizeof err), RC_OK);
    render_image img;
    render_options o = {.threads = 1};
    assert_int_equal(render_scene(s, &m, &env, &o, &img, err, sizeof err), RC_OK);
    const size_t c = (size_t)img.width + (size_t)x;
    for (int k = 0; k < 4; k++)
        rgba[k] = img.chan[RENDER_R + k][c];
    render_image_free(&img);
    free(px);
    mesh_free(&m);
    free(s);
}

/* Float products and sums of values near 1: a few ulp; 1e-6 relative leaves room. */
static void expect(const float got[4], double r, double g, double b, double a)
{
    close_rel(got[0], r, 1e-6);
    close_rel(got[1], g, 1e-6);
    close_rel(got[2], b, 1e-6);
    close_rel(got[3], a, 1e-6);
}

static const double dim[3] = {0.5, 1.0, 2.0};

static void test_over_object(void **state)
{
    (void)state;
    float p[4];
    pixel(dim, "true", 1.0, 1, p);
    expect(p, 0.16, 0.32, 0.52, 0.76);
}

static void test_over_background(void **state)
{
    (void)state;
    float p[4];
    pixel(dim, "true", 1.0, 0, p);
    expect(p, 0.34, 0.68, 1.36, 0.16);
}

/* Without blend the pane hides the object: its colour c and A = c_a (eq. 7 written, not used). */
static void test_opaque(void **state)
{
    (void)state;
    float p[4];
    pixel(dim, "false", 1.0, 1, p);
    expect(p, 0.1, 0.2, 0.4, 0.4);
}

static void test_hdr_alpha_clamped(void **state)
{
    (void)state;
    const double bright[3] = {10.0, 1.0, 1.0};
    float p[4];
    pixel(bright, "true", 1.0, 1, p);
    expect(p, 2.0, 0.2, 0.2, 1.0);
}

/* The pane below the object (y = -1): the depth test hides it where the object is, and shows it
 * over the background beside it. */
static void test_depth(void **state)
{
    (void)state;
    float p[4];
    pixel(dim, "true", -1.0, 1, p);
    expect(p, 0.2, 0.4, 0.6, 1.0);
    pixel(dim, "true", -1.0, 0, p);
    expect(p, 0.34, 0.68, 1.36, 0.16);
}

static void test_render_blend_alpha(void **state)
{
    (void)state;
    assert_true(render_blend_alpha(-0.5f) == 0.0f);
    assert_true(render_blend_alpha(0.25f) == 0.25f);
    assert_true(render_blend_alpha(3.0f) == 1.0f);
    assert_true(isnan(render_blend_alpha(NAN)));
}

/* blend on another model is refused with the key named. */
static void test_key_refused(void **state)
{
    (void)state;
    static const char text[] = "image: {width: 3, height: 3, supersample: 1}\n"
                               "camera: {eye: [0, 0, 5], target: [0, 0, 0], hfov: 20}\n"
                               "materials:\n  m: {model: d3d, d3d9client: {blend: true}}\n"
                               "objects:\n  - {shape: sphere, radius: 1, material: m}\n";
    scene *s = malloc(sizeof *s);
    assert_non_null(s);
    char err[1024];
    assert_int_not_equal(scene_file_parse(text, strlen(text), "k.yaml", s, err, sizeof err), RC_OK);
    assert_non_null(strstr(err, "blend"));
    free(s);
}

/* POV-Ray renders neither the blend (twin) nor the thin sheet (validate): refused with the key
 * named, never drawn opaque (Cycles renders both: tests/test_cycles.c). */
static void test_references_refuse(void **state)
{
    (void)state;
    static const char text[] = "image: {width: 3, height: 3, supersample: 1}\n"
                               "camera: {eye: [0, 0, 5], target: [0, 0, 0], hfov: 20}\n"
                               "environment: {constant: [1, 1, 1]}\n"
                               "materials:\n  g: {albedo: [0, 0, 0], roughness: 0, thin: true, model: d3d9client,\n"
                               "    d3d9client: {blend: true}}\n"
                               "objects:\n  - {shape: quad, size: [2, 2], rotate: [90, 0, 0], material: g}\n";
    scene *s = malloc(sizeof *s);
    assert_non_null(s);
    char err[1024];
    assert_int_equal(scene_file_parse(text, strlen(text), "r.yaml", s, err, sizeof err), RC_OK);
    physics ph;
    assert_int_equal(povray_physics(s, &ph, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "thin"));
    mesh m = {0};
    assert_int_equal(mesh_build(s, &m, err, sizeof err), RC_OK);
    povray_options twin = {.role = ROLE_TWIN};
    assert_int_equal(povray_write_scene(s, &m, &twin, "/tmp/reflcheck-blend-never.pov", err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "blend"));
    mesh_free(&m);
    free(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_over_object), cmocka_unit_test(test_over_background),
        cmocka_unit_test(test_opaque),      cmocka_unit_test(test_hdr_alpha_clamped),
        cmocka_unit_test(test_depth),       cmocka_unit_test(test_render_blend_alpha),
        cmocka_unit_test(test_key_refused), cmocka_unit_test(test_references_refuse),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
