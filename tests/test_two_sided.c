/* test_two_sided - d3d.two_sided (scenes/FORMAT.md): the rasterizer lights a back face with the
 * normal turned toward the viewer (true, the default) or as given (false, D3D's fixed function
 * with D3DCULL_NONE), per pixel and per vertex; the key is refused on the shader models.
 *
 * Usage: make BUILD=x check T=two_sided
 *
 * The expected pixels come from the D3D formula by hand: a quad in the XZ plane (normal +Y) seen
 * from below, a point light of intensity pi W/sr straight above its centre at distance 1.
 * D3D's diffuse is Vd (I/d^2)/pi (N.L)+ (render/shade.c: light colour E/pi). */
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
#include "render_text.h"
#include "scene_file.h"

static const char scene_fmt[] =
    "image: {width: 3, height: 3, supersample: 1}\n"
    "camera: {eye: [0, -2, 0], target: [0, 0, 0], up: [0, 0, -1], hfov: 20}\n"
    "lights:\n  - {type: point, position: [0, 1, 0], intensity: [3.14159265, 3.14159265, 3.14159265]}\n"
    "materials:\n"
    "  m: {model: d3d, d3d: {diffuse: [0.5, 0.25, 0.125]%s}}\n"
    "objects:\n"
    "  - {shape: quad, size: [2, 2], material: m}\n";

/* The centre pixel's R, G, B of the scene with extra d3d keys: pixel (1, 1), whose one sample
 * is the quad's centre. */
static void centre_pixel(const char *extra, float rgb[3])
{
    char text[1024];
    snprintf(text, sizeof text, scene_fmt, extra);
    render_text_pixel(text, "two_sided.yaml", 1, 1, rgb);
}

static void expect(const float rgb[3], double scale)
{
    const double vd[3] = {0.5, 0.25, 0.125};
    for (int k = 0; k < 3; k++)
        /* Float shading of values near 0.5: a few ulp (6e-8 relative each); 1e-5 leaves room. */
        assert_true(fabs(rgb[k] - vd[k] * scale) <= 1e-5 * vd[k] + 1e-9);
}

/* Per pixel at the centre: d = 1, N.L = 1 with the normal as given, -1 turned to the viewer. */
static void test_per_pixel(void **state)
{
    (void)state;
    float rgb[3];
    centre_pixel("", rgb);
    expect(rgb, 0.0);
    centre_pixel(", two_sided: true", rgb);
    expect(rgb, 0.0);
    centre_pixel(", two_sided: false", rgb);
    expect(rgb, 1.0);
}

/* Gouraud: the four corners (+-1, 0, +-1) are all at d^2 = 3 with N.L = 1/sqrt(3), so every
 * vertex, and the blend at the centre, is Vd / (3 sqrt 3) one-sided and 0 two-sided. */
static void test_per_vertex(void **state)
{
    (void)state;
    float rgb[3];
    centre_pixel(", per_vertex: true", rgb);
    expect(rgb, 0.0);
    centre_pixel(", per_vertex: true, two_sided: false", rgb);
    expect(rgb, 1.0 / (3.0 * sqrt(3.0)));
}

/* The shaders take N.V > 0 for granted (Cook-Torrance divides by it): false is refused there
 * with the key's place, and the default is two-sided. */
static void test_key(void **state)
{
    (void)state;
    scene *s = malloc(sizeof *s);
    assert_non_null(s);
    char err[1024];
    static const char ct[] = "image: {width: 3, height: 3}\n"
                             "camera: {eye: [0, -2, 0], target: [0, 0, 0], up: [0, 0, -1], hfov: 20}\n"
                             "materials:\n  m: {model: cook_torrance, d3d: {two_sided: false}}\n"
                             "objects:\n  - {shape: quad, size: [2, 2], material: m}\n";
    assert_int_equal(scene_file_parse(ct, sizeof ct - 1, "ct.yaml", s, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "ct.yaml:4:"));
    assert_non_null(strstr(err, "materials.m.d3d.two_sided"));
    char text[1024];
    snprintf(text, sizeof text, scene_fmt, "");
    assert_int_equal(scene_file_parse(text, strlen(text), "d.yaml", s, err, sizeof err), RC_OK);
    assert_int_equal(s->materials[0].d3d.two_sided, 1);
    free(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_per_pixel),
        cmocka_unit_test(test_per_vertex),
        cmocka_unit_test(test_key),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
