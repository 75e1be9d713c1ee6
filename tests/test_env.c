/* Environment lookup: orientation (CONVENTIONS.md) and bilinear filtering with texel
 * centres at +0.5, on a small asymmetric image whose texels are all different. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include "env.h"

enum { W = 8, H = 4 };
static float img[W * H * 3];

/* Texel (x, y) holds (x, y, 100 + x + 10 y): channels differ, so a swap shows. */
static env_map make_env(void)
{
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            float *p = img + 3 * (y * W + x);
            p[0] = (float)x;
            p[1] = (float)y;
            p[2] = 100.0f + (float)x + 10.0f * (float)y;
        }
    env_map e = {.kind = ENV_IMAGE, .scale = {1, 1, 1}, .width = W, .height = H, .rgb = img};
    return e;
}

static void test_orientation(void **state)
{
    (void)state;
    env_map e = make_env();
    float tx, ty;
    /* +x: atan2(0, 1) = 0 -> u = 0.5, the horizontal middle; horizon v = 0.5. */
    env_direction_to_texel(&e, v3(1, 0, 0), &tx, &ty);
    assert_float_equal(tx, 4.0f, 1e-5);
    assert_float_equal(ty, 2.0f, 1e-5);
    /* +z: atan2(1, 0) = pi/2 -> u = 0.75. */
    env_direction_to_texel(&e, v3(0, 0, 1), &tx, &ty);
    assert_float_equal(tx, 6.0f, 1e-5);
    /* -z: u = 0.25. */
    env_direction_to_texel(&e, v3(0, 0, -1), &tx, &ty);
    assert_float_equal(tx, 2.0f, 1e-5);
    /* Straight up is the top edge of the image (row 0), down the bottom. */
    env_direction_to_texel(&e, v3(0, 1, 0), &tx, &ty);
    assert_float_equal(ty, 0.0f, 1e-5);
    env_direction_to_texel(&e, v3(0, -1, 0), &tx, &ty);
    assert_float_equal(ty, 4.0f, 1e-5);
}

static void test_bilinear(void **state)
{
    (void)state;
    env_map e = make_env();
    /* Direction at texel coordinate (4.5, 1.5): the centre of texel (4, 1) exactly.
     * u = 4.5/8 -> phi = (u - 0.5) 2 pi = pi/8; v = 1 - 1.5/4 = 0.625 -> lat = 0.125 pi. */
    float phi = 3.14159265f / 8.0f, lat = 0.125f * 3.14159265f;
    vec3 d = v3(cosf(lat) * cosf(phi), sinf(lat), cosf(lat) * sinf(phi));
    vec3 r = env_lookup(&e, d);
    assert_float_equal(r.x, 4.0f, 1e-4);
    assert_float_equal(r.y, 1.0f, 1e-4);
    assert_float_equal(r.z, 114.0f, 1e-3);
    /* Texel coordinate (5.0, 2.25): halfway between columns 4 and 5, a quarter below row 1's
     * centre toward row 2 -> (4.5, 1.75, 100 + 4.5 + 17.5). */
    phi = (5.0f / 8.0f - 0.5f) * 2.0f * 3.14159265f;
    lat = (0.5f - 2.25f / 4.0f) * 3.14159265f;
    d = v3(cosf(lat) * cosf(phi), sinf(lat), cosf(lat) * sinf(phi));
    r = env_lookup(&e, d);
    assert_float_equal(r.x, 4.5f, 1e-4);
    assert_float_equal(r.y, 1.75f, 1e-4);
    assert_float_equal(r.z, 122.0f, 1e-3);
}

static void test_wrap_and_scale(void **state)
{
    (void)state;
    env_map e = make_env();
    e.scale = v3(2, 1, 0.5f);
    /* -x sits on the seam u = 0 = 1: halfway between column 7 and column 0 (x = 3.5). */
    vec3 r = env_lookup(&e, v3(-1, 0, 1e-7f));
    assert_float_equal(r.x, 2.0f * 3.5f, 1e-3);
    /* Row clamping: straight up reads row 0 only (y = 0). */
    r = env_lookup(&e, v3(0, 1, 0));
    assert_float_equal(r.y, 0.0f, 1e-6);
}

static void test_constant_and_none(void **state)
{
    (void)state;
    env_map c = {.kind = ENV_CONSTANT, .constant = {0.25f, 0.5f, 2.0f}};
    vec3 r = env_lookup(&c, v3(0.3f, -0.2f, 0.9f));
    assert_float_equal(r.z, 2.0f, 0.0);
    env_map n = {.kind = ENV_NONE};
    r = env_lookup(&n, v3(1, 0, 0));
    assert_float_equal(r.x + r.y + r.z, 0.0f, 0.0);
    r = env_lookup(&c, v3(0, 0, 0));
    assert_float_equal(r.x, 0.0f, 0.0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_orientation),
        cmocka_unit_test(test_bilinear),
        cmocka_unit_test(test_wrap_and_scale),
        cmocka_unit_test(test_constant_and_none),
    };
    return cmocka_run_group_tests_name("env", tests, NULL, NULL);
}
