/* test_exact_sun.c - the sun extraction of HDR environments (environment.sun_threshold), on a
 * synthetic sky whose sun is known: a uniform sky with a 2 x 2 texel sun.
 * Expected values are formed here another way: each texel's solid angle by a fine midpoint
 * rule over cos(latitude), its centre direction checked against the lookup's own mapping
 * (env_direction_to_texel), and energy as texel sums before and after.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "env.h"
#include "exr.h"
#include "frame.h"
#include "mesh.h"
#include "scene_file.h"

#define W 64
#define H 32

static const float sky[3] = {0.5f, 0.6f, 0.7f}, sun[3] = {2000.0f, 1800.0f, 1500.0f};
static const int sun_x[4] = {40, 41, 40, 41}, sun_y[4] = {10, 10, 11, 11};

static float *make_sky(void)
{
    float *p = malloc(sizeof(float) * 3 * W * H);
    assert_non_null(p);
    for (int i = 0; i < W * H; i++)
        memcpy(p + 3 * i, sky, sizeof sky);
    for (int k = 0; k < 4; k++)
        memcpy(p + 3 * (sun_y[k] * W + sun_x[k]), sun, sizeof sun);
    return p;
}

/* Solid angle of row y's texels: the integral of cos(lat) dlat dphi, by 2000 midpoint steps. */
static double texel_omega(int y)
{
    double top = TEST_PI * (0.5 - (double)y / H), bot = TEST_PI * (0.5 - (double)(y + 1) / H), s = 0.0;
    for (int i = 0; i < 2000; i++)
        s += cos(bot + (top - bot) * (i + 0.5) / 2000);
    return s * (top - bot) / 2000 * (2.0 * TEST_PI / W);
}

static dvec3 texel_dir(int x, int y)
{
    double lat = TEST_PI * (0.5 - (y + 0.5) / H), phi = 2.0 * TEST_PI * ((x + 0.5) / W - 0.5);
    return dv3(cos(lat) * cos(phi), sin(lat), cos(lat) * sin(phi));
}

static void texel_sum(const float *p, double out[3])
{
    out[0] = out[1] = out[2] = 0.0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            for (int c = 0; c < 3; c++)
                out[c] += p[3 * (y * W + x) + c] * texel_omega(y);
}

static void test_known_sun(void **state)
{
    (void)state;
    float *p = make_sky();
    double before[3], after[3];
    texel_sum(p, before);
    env_sun s;
    assert_int_equal(env_extract_sun(p, W, H, v3s(1.0f), 100.0f, &s), RC_OK);
    assert_int_equal(s.n_texels, 4);
    dvec3 dir = dv3(0, 0, 0);
    double omega = 0.0, e[3] = {0, 0, 0};
    env_map em = {.kind = ENV_IMAGE, .width = W, .height = H, .rgb = p, .scale = v3s(1.0f)};
    for (int k = 0; k < 4; k++) {
        double w = texel_omega(sun_y[k]);
        omega += w;
        dir = dv3_add(dir, dv3_scale(texel_dir(sun_x[k], sun_y[k]), w));
        for (int c = 0; c < 3; c++)
            e[c] += (sun[c] - sky[c]) * w;
        /* The test's texel centres are the lookup's: the mapping lands on (x + 0.5, y + 0.5). */
        float tx, ty;
        env_direction_to_texel(&em, v3_from_d(texel_dir(sun_x[k], sun_y[k])), &tx, &ty);
        close_rel(tx, sun_x[k] + 0.5, 1e-5);
        close_rel(ty, sun_y[k] + 0.5, 1e-5);
        /* What is left is the sky around the sun. */
        for (int c = 0; c < 3; c++)
            assert_true(p[3 * (sun_y[k] * W + sun_x[k]) + c] == sky[c]);
    }
    dir = dv3_norm(dir);
    close_rel(s.solid_angle, omega, 1e-6);
    close_rel(s.irradiance.x, e[0], 1e-6);
    close_rel(s.irradiance.y, e[1], 1e-6);
    close_rel(s.irradiance.z, e[2], 1e-6);
    /* The direction is stored as float: its length differs from 1 by up to ~1e-7. */
    assert_true(dv3_dot(dv3_from(s.direction), dir) > 1.0 - 1e-6);
    close_rel(s.fill.y, sky[1], 1e-7);
    /* Energy: the remainder's texel sum plus the sun's irradiance is the image's. */
    texel_sum(p, after);
    close_rel(after[0] + s.irradiance.x, before[0], 1e-6);
    close_rel(after[2] + s.irradiance.z, before[2], 1e-6);
    free(p);

    /* The image scale applies to the threshold and the irradiance alike. */
    p = make_sky();
    assert_int_equal(env_extract_sun(p, W, H, v3s(2.0f), 100.0f, &s), RC_OK);
    close_rel(s.irradiance.x, 2.0 * e[0], 1e-6);
    free(p);
    /* No texel above the threshold: refused, the image untouched. */
    p = make_sky();
    assert_int_equal(env_extract_sun(p, W, H, v3s(1.0f), 5000.0f, &s), RC_ERR_RANGE);
    assert_true(p[3 * (10 * W + 40)] == sun[0]);
    free(p);
}

/* The scene path: the key parses, the split appends a sun light every renderer then sees, and the
 * split image written for file-reading renderers reads back as the remainder. */
static void test_scene_split(void **state)
{
    (void)state;
    char dir[] = "/tmp/reflcheck-sun-XXXXXX", path[300], split[300], err[1024], text[1024];
    assert_non_null(mkdtemp(dir));
    snprintf(path, sizeof path, "%s/sky.exr", dir);
    float *p = make_sky();
    env_map src = {.kind = ENV_IMAGE, .width = W, .height = H, .rgb = p, .scale = v3s(1.0f)};
    assert_int_equal(frame_env_write(path, &src, err, sizeof err), RC_OK);
    snprintf(text, sizeof text,
             "image: {width: 16, height: 8}\ncamera: {eye: [0, 0, 3], target: [0, 0, 0], hfov: 40}\n"
             "environment: {image: %s, scale: 1, sun_threshold: 100}\n"
             "lights:\n  - {type: point, position: [0, 2, 2], intensity: [1, 1, 1]}\n"
             "materials:\n  m: {model: d3d}\nobjects:\n  - {shape: sphere, radius: 1, material: m}\n",
             path);
    scene *s = malloc(sizeof *s);
    assert_non_null(s);
    if (scene_file_parse(text, strlen(text), "sun.yaml", s, err, sizeof err) != RC_OK)
        fail_msg("%s", err);
    close_rel(s->env.sun_threshold, 100.0, 0.0);
    env_map e;
    float *px = NULL;
    assert_int_equal(frame_env_load(s, &e, &px, err, sizeof err), RC_OK);
    env_sun sn;
    assert_int_equal(frame_env_split_sun(s, px, &e, &sn, err, sizeof err), RC_OK);
    assert_int_equal(s->n_lights, 2);
    assert_int_equal(s->lights[1].kind, LIGHT_SUN);
    close_rel(s->lights[1].intensity.y, sn.irradiance.y, 0.0);
    assert_true(v3_dot(s->lights[1].direction, sn.direction) < -0.999999f);
    snprintf(split, sizeof split, "%s/split.exr", dir);
    assert_int_equal(frame_env_write(split, &e, err, sizeof err), RC_OK);
    exr_image img;
    assert_int_equal(exr_read(split, &img, err, sizeof err), RC_OK);
    assert_true(exr_image_channel(&img, "G")[10 * W + 40] == sky[1]);
    exr_image_free(&img);
    free(px);

    /* A threshold above the brightest texel is bad input, named. */
    s->env.sun_threshold = 1e6f;
    s->n_lights = 1;
    assert_int_equal(frame_env_load(s, &e, &px, err, sizeof err), RC_OK);
    assert_int_equal(frame_env_split_sun(s, px, &e, NULL, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "environment.sun_threshold"));
    assert_int_equal(s->n_lights, 1);
    free(px);

    /* In the file, 0 and a constant environment are refused. */
    snprintf(text, sizeof text,
             "image: {width: 16, height: 8}\ncamera: {eye: [0, 0, 3], target: [0, 0, 0], hfov: 40}\n"
             "environment: {constant: [1, 1, 1], sun_threshold: 10}\n");
    assert_int_not_equal(scene_file_parse(text, strlen(text), "sun.yaml", s, err, sizeof err), RC_OK);
    assert_non_null(strstr(err, "sun_threshold"));
    snprintf(text, sizeof text,
             "image: {width: 16, height: 8}\ncamera: {eye: [0, 0, 3], target: [0, 0, 0], hfov: 40}\n"
             "environment: {image: %s, sun_threshold: 0}\n",
             path);
    assert_int_equal(scene_file_parse(text, strlen(text), "sun.yaml", s, err, sizeof err), RC_ERR_RANGE);
    free(s);
    free(p);
    unlink(path);
    unlink(split);
    rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_known_sun),
        cmocka_unit_test(test_scene_split),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
