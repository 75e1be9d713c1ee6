/* test_d3d_features - the D3D fixed-function features no reference renderer twins, checked in
 * a rendered pixel against the D3D formulas worked out by hand (docs/features.md): a0 + a1 d +
 * a2 d^2 with the range cut-off, the power-law spot (profile d3d) with falloff 2, distance-
 * attenuated light ambient with the global ambient and the emissive colour, clamping on and
 * off, Gouraud beside per pixel, the infinite viewer beside the local one, and every
 * vertex-colour source (colour1 and colour2 for the diffuse, specular, ambient and emissive
 * colours).
 *
 * Usage: make BUILD=x check T=d3d_features
 *
 * Every scene is a 2 x 2 quad in the XZ plane (normal +Y) seen from straight above; the centre
 * pixel's single sample is the quad's centre, the origin, where N = V = (0, 1, 0). D3D's light
 * colour is E/pi (render/shade.c), E = I / (a0 + a1 d + a2 d^2). */
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
#include "scene_file.h"
#include "render_text.h"
#include "tmpdir.h"

#define PI_TEXT   "3.14159265358979"
#define TEST_PI_D 3.14159265358979323846

static const char head[] = "image: {width: 3, height: 3, supersample: 1}\n"
                           "camera: {eye: [0, 2, 0], target: [0, 0, 0], up: [0, 0, -1], hfov: 20}\n";

/* Pixel (col, 1)'s R, G, B of head + body. */
static void row_pixel(const char *body, int col, float rgb[3])
{
    char text[4096];
    snprintf(text, sizeof text, "%s%s", head, body);
    render_text_pixel(text, "/tmp/features.yaml", col, 1, rgb);
}

/* The centre pixel's R, G, B of head + body. */
static void centre_pixel(const char *body, float rgb[3]) { row_pixel(body, 1, rgb); }

static void expect3(const float rgb[3], double r, double g, double b)
{
    const double e[3] = {r, g, b};
    for (int k = 0; k < 3; k++) {
        /* Float shading of values of order 1: a few ulp (6e-8 relative each); 1e-5 leaves room. */
        if (!(fabs(rgb[k] - e[k]) <= 1e-5 * fabs(e[k]) + 1e-7))
            fail_msg("channel %d: %.9g, expected %.9g", k, (double)rgb[k], e[k]);
    }
}

/* d = 2: a0 + a1 d + a2 d^2 = 0.5 + 0.5 + 0.5 = 1.5, so E/pi = 1/1.5 and 0.6 Vd gives 0.4; a range
 * below d cuts the light off entirely, one above it changes nothing. */
static void test_attenuation_range(void **state)
{
    (void)state;
    static const char fmt[] = "lights:\n  - {type: point, position: [0, 2, 0], intensity: [" PI_TEXT ", " PI_TEXT
                              ", " PI_TEXT "], attenuation: [0.5, 0.25, 0.125]%s}\n"
                              "materials:\n  m: {model: d3d, d3d: {diffuse: [0.6, 0.6, 0.6]}}\n"
                              "objects:\n  - {shape: quad, size: [2, 2], material: m}\n";
    char body[1024];
    float rgb[3];
    snprintf(body, sizeof body, fmt, "");
    centre_pixel(body, rgb);
    expect3(rgb, 0.4, 0.4, 0.4);
    snprintf(body, sizeof body, fmt, ", range: 2.1");
    centre_pixel(body, rgb);
    expect3(rgb, 0.4, 0.4, 0.4);
    snprintf(body, sizeof body, fmt, ", range: 1.9");
    centre_pixel(body, rgb);
    expect3(rgb, 0.0, 0.0, 0.0);
}

/* The spot's axis 20 degrees off the direction to the point; cone halves 15 and 30 degrees:
 * D3D's ((cos 20 - cos 30) / (cos 15 - cos 30))^falloff, E/pi = 1/4 at d = 2, Vd 0.8. */
static void test_spot_power_law(void **state)
{
    (void)state;
    const double a = 20.0 * TEST_PI_D / 180.0;
    const double x = (cos(a) - cos(TEST_PI_D / 6.0)) / (cos(TEST_PI_D / 12.0) - cos(TEST_PI_D / 6.0));
    static const char fmt[] = "lights:\n  - {type: spot, position: [0, 2, 0], direction: [%.17g, %.17g, 0], "
                              "intensity: [" PI_TEXT ", " PI_TEXT ", " PI_TEXT "], inner: 30, outer: 60, "
                              "falloff: %s, profile: d3d}\n"
                              "materials:\n  m: {model: d3d, d3d: {diffuse: [0.8, 0.8, 0.8]}}\n"
                              "objects:\n  - {shape: quad, size: [2, 2], material: m}\n";
    char body[1024];
    float rgb[3];
    snprintf(body, sizeof body, fmt, sin(a), -cos(a), "2");
    centre_pixel(body, rgb);
    expect3(rgb, 0.2 * x * x, 0.2 * x * x, 0.2 * x * x);
    snprintf(body, sizeof body, fmt, sin(a), -cos(a), "1");
    centre_pixel(body, rgb);
    expect3(rgb, 0.2 * x, 0.2 * x, 0.2 * x);
}

/* Va (Ia + La / d^2) + Vd E/pi + Ve: the light's ambient fades with its attenuation (d = 2). */
static void test_ambient_emissive(void **state)
{
    (void)state;
    static const char body[] =
        "ambient: [0.1, 0.2, 0.3]\n"
        "lights:\n  - {type: point, position: [0, 2, 0], intensity: [" PI_TEXT ", " PI_TEXT ", " PI_TEXT
        "], ambient: [0.4, 0.4, 0.4]}\n"
        "materials:\n  m: {model: d3d, d3d: {diffuse: [0.2, 0.4, 0.8], ambient: [0.5, 0.5, 0.5], emissive: [0.01, "
        "0.02, 0.03]}}\n"
        "objects:\n  - {shape: quad, size: [2, 2], material: m}\n";
    float rgb[3];
    centre_pixel(body, rgb);
    expect3(rgb, 0.5 * (0.1 + 0.1) + 0.2 / 4 + 0.01, 0.5 * (0.2 + 0.1) + 0.4 / 4 + 0.02,
            0.5 * (0.3 + 0.1) + 0.8 / 4 + 0.03);
}

/* E/pi = 1 at d = 1 and N.H = 1: Dv = Ve + Vd = (2.7, 0.9, 1.2), Sv = 3. Clamped, D3D saturates
 * Dv (emissive first) and Sv to 1 each. */
static void test_clamp(void **state)
{
    (void)state;
    static const char fmt[] =
        "lights:\n  - {type: point, position: [0, 1, 0], intensity: [" PI_TEXT ", " PI_TEXT ", " PI_TEXT "]}\n"
        "materials:\n  m: {model: d3d, d3d: {diffuse: [2, 0.2, 0.5], emissive: [0.7, 0.7, 0.7], "
        "specular: [3, 3, 3], power: 1, clamp: %s}}\n"
        "objects:\n  - {shape: quad, size: [2, 2], material: m}\n";
    char body[1024];
    float rgb[3];
    snprintf(body, sizeof body, fmt, "false");
    centre_pixel(body, rgb);
    expect3(rgb, 5.7, 3.9, 4.2);
    snprintf(body, sizeof body, fmt, "true");
    centre_pixel(body, rgb);
    expect3(rgb, 2.0, 1.9, 2.0);
}

/* Per pixel at the centre: E/pi = 1, N.L = 1. Gouraud: every corner (+-1, 0, +-1) has d^2 = 3 and
 * N.L = 1/sqrt 3, so the blend is 1 / (3 sqrt 3) everywhere. */
static void test_gouraud(void **state)
{
    (void)state;
    static const char fmt[] =
        "lights:\n  - {type: point, position: [0, 1, 0], intensity: [" PI_TEXT ", " PI_TEXT ", " PI_TEXT "]}\n"
        "materials:\n  m: {model: d3d, d3d: {diffuse: [1, 1, 1], per_vertex: %s}}\n"
        "objects:\n  - {shape: quad, size: [2, 2], material: m}\n";
    char body[1024];
    float rgb[3];
    snprintf(body, sizeof body, fmt, "false");
    centre_pixel(body, rgb);
    expect3(rgb, 1.0, 1.0, 1.0);
    const double g = 1.0 / (3.0 * sqrt(3.0));
    snprintf(body, sizeof body, fmt, "true");
    centre_pixel(body, rgb);
    expect3(rgb, g, g, g);
}

/* D3D's H = norm(L + V) with V the direction to the eye (local viewer) or the fixed eye-to-
 * target direction (0, 1, 0) (infinite viewer), at pixel (0, 1): its centre ray, nx = -2/3
 * of tan 10 deg, meets the quad at |x| = (2/3) tan(10 deg) 2 (the light on the axis makes the
 * side irrelevant). Vd = 0, Vs = 1, P = 20, E/pi = 1/(1 + x^2). */
static void test_infinite_viewer(void **state)
{
    (void)state;
    static const char fmt[] =
        "lights:\n  - {type: point, position: [0, 1, 0], intensity: [" PI_TEXT ", " PI_TEXT ", " PI_TEXT "]}\n"
        "materials:\n  m: {model: d3d, d3d: {diffuse: [0, 0, 0], specular: [1, 1, 1], power: 20, "
        "local_viewer: %s}}\n"
        "objects:\n  - {shape: quad, size: [2, 2], material: m}\n";
    const double x = 2.0 / 3.0 * tan(10.0 * TEST_PI_D / 180.0) * 2.0;
    const double dl = sqrt(1.0 + x * x), dv = sqrt(4.0 + x * x);
    const double lx = x / dl, ly = 1.0 / dl; /* to the light and the eye, both along +x from the point */
    double hx = lx + x / dv, hy = ly + 2.0 / dv;
    const double local = pow(hy / sqrt(hx * hx + hy * hy), 20.0) / (1.0 + x * x);
    hx = lx;
    hy = ly + 1.0;
    const double inf = pow(hy / sqrt(hx * hx + hy * hy), 20.0) / (1.0 + x * x);
    char body[1024];
    float rgb[3];
    snprintf(body, sizeof body, fmt, "true");
    row_pixel(body, 0, rgb);
    /* 20th power: N.H's float error (1e-7) grows 20-fold; 1e-4 relative leaves room. */
    for (int k = 0; k < 3; k++)
        if (!(fabs(rgb[k] - local) <= 1e-4 * local))
            fail_msg("local viewer, channel %d: %.9g, expected %.9g", k, (double)rgb[k], local);
    snprintf(body, sizeof body, fmt, "false");
    row_pixel(body, 0, rgb);
    for (int k = 0; k < 3; k++)
        if (!(fabs(rgb[k] - inf) <= 1e-4 * inf))
            fail_msg("infinite viewer, channel %d: %.9g, expected %.9g (local %.9g)", k, (double)rgb[k], inf, local);
}

/* A PLY quad whose every vertex has colour1 = (255, 51, 102)/255 and colour2 = (0, 255, 153)/255.
 * E/pi = 1, N.H = 1, power 1, Ia = 0.1: the pixel is diffuse + specular + 0.1 ambient + emissive,
 * each from the colour its source names. */
static void test_colour_sources(void **state)
{
    (void)state;
    char ply[512];
    snprintf(ply, sizeof ply, "%s/quad.ply", tmpdir);
    FILE *fp = fopen(ply, "w");
    assert_non_null(fp);
    fputs("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
          "property float nx\nproperty float ny\nproperty float nz\nproperty uchar red\nproperty uchar green\n"
          "property uchar blue\nproperty uchar specular_red\nproperty uchar specular_green\n"
          "property uchar specular_blue\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n",
          fp);
    const int xz[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
    for (int v = 0; v < 4; v++)
        fprintf(fp, "%d 0 %d 0 1 0 255 51 102 0 255 153\n", xz[v][0], xz[v][1]);
    fputs("3 0 2 1\n3 0 3 2\n", fp); /* counter-clockwise seen from +Y */
    assert_int_equal(fclose(fp), 0);
    const double c1[3] = {1.0, 0.2, 0.4}, c2[3] = {0.0, 1.0, 0.6};
    static const char fmt[] =
        "ambient: [0.1, 0.1, 0.1]\n"
        "lights:\n  - {type: point, position: [0, 1, 0], intensity: [" PI_TEXT ", " PI_TEXT ", " PI_TEXT "]}\n"
        "materials:\n  m: {model: d3d, d3d: {diffuse: [0.3, 0.3, 0.3], specular: [0.3, 0.3, 0.3], "
        "ambient: [0.3, 0.3, 0.3], emissive: [0.3, 0.3, 0.3], power: 1, colour_vertex: true, "
        "diffuse_source: %s, specular_source: %s, ambient_source: %s, emissive_source: %s}}\n"
        "objects:\n  - {shape: mesh, path: %s, material: m}\n";
    char body[2048];
    float rgb[3];
    snprintf(body, sizeof body, fmt, "colour2", "colour1", "colour1", "colour2", ply);
    centre_pixel(body, rgb);
    expect3(rgb, 2 * c2[0] + 1.1 * c1[0], 2 * c2[1] + 1.1 * c1[1], 2 * c2[2] + 1.1 * c1[2]);
    snprintf(body, sizeof body, fmt, "colour1", "colour2", "colour2", "colour1", ply);
    centre_pixel(body, rgb);
    expect3(rgb, 2 * c1[0] + 1.1 * c2[0], 2 * c1[1] + 1.1 * c2[1], 2 * c1[2] + 1.1 * c2[2]);
    /* material: the material's own 0.3 in all four, (1 + 1 + 0.1 + 1) x 0.3. */
    snprintf(body, sizeof body, fmt, "material", "material", "material", "material", ply);
    centre_pixel(body, rgb);
    expect3(rgb, 0.93, 0.93, 0.93);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_attenuation_range), cmocka_unit_test(test_spot_power_law),
        cmocka_unit_test(test_ambient_emissive),  cmocka_unit_test(test_clamp),
        cmocka_unit_test(test_gouraud),           cmocka_unit_test(test_colour_sources),
        cmocka_unit_test(test_infinite_viewer),
    };
    return cmocka_run_group_tests(tests, tmpdir_setup, tmpdir_teardown);
}
