/* Environment lookup: orientation (docs/conventions.md) and bilinear filtering with texel
 * centres at +0.5, on a small asymmetric image whose texels are all different; texels checked
 * on load (env_check, and through the CLI: render and check refuse NaN, Inf and negative
 * texels naming the first one). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>
#include <sys/stat.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli_exec.h"
#include "env.h"
#include "exr.h"
#include "formula.h"
#include "smath.h"

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

/* env_check: every texel value, counted; the first non-finite and the first negative one in
 * row-major, then R, G, B order, with its column, row and channel. */
static void test_check_texels(void **state)
{
    (void)state;
    env_map e = make_env();
    env_texel_check chk;
    assert_int_equal(env_check(&e, &chk), RC_OK);
    assert_int_equal(chk.n_nonfinite + chk.n_negative, 0);
    assert_int_equal(chk.first_nonfinite.x, -1);

    img[3 * (2 * W + 5) + 1] = NAN;      /* (x 5, y 2) G */
    img[3 * (3 * W + 7) + 2] = INFINITY; /* (x 7, y 3) B */
    img[3 * (1 * W + 6) + 0] = -0.5f;    /* (x 6, y 1) R */
    img[3 * (3 * W + 0) + 0] = -1e-30f;  /* (x 0, y 3) R: tiny, still negative */
    img[3 * (0 * W + 2) + 1] = -0.0f;    /* (x 2, y 0) G: -0 is not negative */
    assert_int_equal(env_check(&e, &chk), RC_ERR_RANGE);
    assert_int_equal(chk.n_nonfinite, 2);
    assert_int_equal(chk.n_negative, 2);
    assert_int_equal(chk.first_nonfinite.x, 5);
    assert_int_equal(chk.first_nonfinite.y, 2);
    assert_int_equal(chk.first_nonfinite.channel, 1);
    assert_true(isnan(chk.first_nonfinite.value));
    assert_int_equal(chk.first_negative.x, 6);
    assert_int_equal(chk.first_negative.y, 1);
    assert_int_equal(chk.first_negative.channel, 0);
    assert_float_equal(chk.first_negative.value, -0.5f, 0.0);

    /* Only images hold texels: constant and none are the parser's business. */
    env_map c = {.kind = ENV_CONSTANT, .constant = {1, 1, 1}};
    assert_int_equal(env_check(&c, &chk), RC_OK);
    env_map n = {.kind = ENV_NONE};
    assert_int_equal(env_check(&n, &chk), RC_OK);
}

/* An environment image for a scene: 8x4 texels of 0.25, one of them (bad_x, bad_y, bad_c)
 * set to bad_value unless bad_x < 0. */
static void put_env(const char *path, float bad_value, int bad_x, int bad_y, int bad_c)
{
    static float ch[3][8 * 4];
    for (int c = 0; c < 3; c++)
        for (int i = 0; i < 32; i++)
            ch[c][i] = 0.25f;
    if (bad_x >= 0)
        ch[bad_c][bad_y * 8 + bad_x] = bad_value;
    exr_channel e[3] = {{"R", ch[0]}, {"G", ch[1]}, {"B", ch[2]}};
    char err[512];
    assert_int_equal(exr_write(path, 8, 4, e, 3, NULL, 0, err, sizeof err), RC_OK);
}

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    assert_int_equal(fclose(f), 0);
}

/* A scene whose mirror-like sphere reflects env.exr beside it; its folder in dir. */
static void env_scene(char *dir, size_t dirlen, char *scn, size_t scnlen)
{
    snprintf(dir, dirlen, "/tmp/reflcheck-env-%ld", (long)getpid());
    snprintf(scn, scnlen, "%s/env.yaml", dir);
    char cmd[300];
    snprintf(cmd, sizeof cmd, "mkdir -p %s", dir);
    assert_int_equal(system(cmd), 0);
    write_text(scn, "image: {width: 8, height: 4}\ncamera: {eye: [0, 0, 4], target: [0, 0, 0], hfov: 40}\n"
                    "environment: {image: env.exr}\n"
                    "materials:\n  m: {model: d3d9client, d3d9client: {reflect: [1, 1, 1]}}\n"
                    "objects:\n  - {shape: sphere, radius: 1, material: m}\n");
}

static void env_scene_remove(const char *dir)
{
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    assert_int_equal(system(cmd), 0);
}

/* render refuses an environment with a NaN, Inf or negative texel (it used to put NaN into
 * the image), exit 2, naming the scene, the file, the first texel and the counts. */
static void test_render_refuses_bad_texels(void **state)
{
    (void)state;
    char dir[200], scn[300], env[300], out[300], err[2048];
    env_scene(dir, sizeof dir, scn, sizeof scn);
    snprintf(env, sizeof env, "%s/env.exr", dir);
    snprintf(out, sizeof out, "%s/out.exr", dir);
    put_env(env, 0.0f, -1, 0, 0);
    assert_int_equal(cli_exec(err, sizeof err, "render %s -o %s", scn, out), 0);

    put_env(env, NAN, 3, 1, 1);
    assert_int_equal(cli_exec(err, sizeof err, "render %s -o %s", scn, out), 2);
    assert_non_null(strstr(err, "env.yaml: environment.image: "));
    assert_non_null(strstr(err, "env.exr: 1 non-finite and 0 negative texel values, the first at texel (x 3, y 1) "
                                "channel G = nan; "));
    assert_non_null(strstr(err, "oiiotool"));

    put_env(env, -INFINITY, 7, 3, 2);
    assert_int_equal(cli_exec(err, sizeof err, "render %s -o %s", scn, out), 2);
    assert_non_null(strstr(err, "(x 7, y 3) channel B = -inf"));

    put_env(env, -0.5f, 0, 2, 0);
    assert_int_equal(cli_exec(err, sizeof err, "render %s -o %s", scn, out), 2);
    assert_non_null(
        strstr(err, "0 non-finite and 1 negative texel values, the first at texel (x 0, y 2) channel R = -0.5"));
    /* A corrupt or missing environment image is bad input for render as for check (exit 2). */
    write_text(env, "this is not an EXR file\n");
    assert_int_equal(cli_exec(err, sizeof err, "render %s -o %s", scn, out), 2);
    assert_non_null(strstr(err, "env.yaml: environment.image: "));
    assert_int_equal(unlink(env), 0);
    assert_int_equal(cli_exec(err, sizeof err, "render %s -o %s", scn, out), 2);
    /* A whole header with its pixel data cut off fails while decoding (an I/O status inside). */
    put_env(env, 0.0f, -1, 0, 0);
    struct stat st;
    assert_int_equal(stat(env, &st), 0);
    assert_int_equal(truncate(env, st.st_size - 40), 0);
    assert_int_equal(cli_exec(err, sizeof err, "render %s -o %s", scn, out), 2);
    assert_int_equal(cli_exec(err, sizeof err, "check %s", scn), 2);
    env_scene_remove(dir);
}

/* check loads what render loads: a scene whose environment render refuses (bad texels, a
 * corrupt image) fails check too, with exit 2, and a good one passes without rendering. */
static void test_check_loads_environment(void **state)
{
    (void)state;
    char dir[200], scn[300], env[300], err[2048];
    env_scene(dir, sizeof dir, scn, sizeof scn);
    snprintf(env, sizeof env, "%s/env.exr", dir);
    put_env(env, 0.0f, -1, 0, 0);
    assert_int_equal(cli_exec(err, sizeof err, "check %s", scn), 0);

    put_env(env, NAN, 3, 1, 1);
    assert_int_equal(cli_exec(err, sizeof err, "check %s", scn), 2);
    assert_non_null(strstr(err, "env.exr: 1 non-finite and 0 negative texel values, the first at texel (x 3, y 1) "
                                "channel G = nan; "));
    put_env(env, -0.5f, 0, 2, 0);
    assert_int_equal(cli_exec(err, sizeof err, "check %s", scn), 2);
    assert_non_null(strstr(err, "(x 0, y 2) channel R = -0.5"));

    write_text(env, "this is not an EXR file\n");
    assert_int_equal(cli_exec(err, sizeof err, "check %s", scn), 2);
    assert_non_null(strstr(err, "env.yaml: environment.image: "));
    /* render refuses a frame beyond the memory limit before allocating; check says so too. */
    put_env(env, 0.0f, -1, 0, 0);
    setenv("REFLCHECK_MEMORY_LIMIT", "1K", 1);
    assert_int_equal(cli_exec(err, sizeof err, "check %s", scn), 2);
    assert_non_null(strstr(err, "env.yaml: image: a 8x4 render at supersample 1 needs about "));
    assert_non_null(strstr(err, "REFLCHECK_MEMORY_LIMIT"));
    unsetenv("REFLCHECK_MEMORY_LIMIT");
    assert_int_equal(cli_exec(err, sizeof err, "check %s", scn), 0);
    /* The rest of check's exit statuses: a missing scene, and a command line, are bad input. */
    assert_int_equal(cli_exec(err, sizeof err, "check %s/missing.yaml", dir), 2);
    assert_int_equal(cli_exec(err, sizeof err, "check %s %s", scn, scn), 2);
    env_scene_remove(dir);
}

/* env_lookup_n's lane formula written out per lane, as the kernel stated it in one lane loop
 * (two smath_atan2, truncating floor, wrap in u, clamp in v, bilinear sum times the scale): the
 * reference its chunked two-pass form (four lanes' texels read as 16-byte loads and
 * transposed) must equal bit for bit. */
static void lane_reference(const env_map *e, float x, float y, float z, float out[3])
{
    const int w = e->width, h = e->height;
    int zero = (x == 0.0f) & (y == 0.0f) & (z == 0.0f);
    float u = 0.5f + smath_atan2(z, x) * (0.5f / FORMULA_PI_F);
    float v = 0.5f + smath_atan2(y, sqrtf(x * x + z * z)) * (1.0f / FORMULA_PI_F);
    float fx = u * (float)w - 0.5f, fy = (1.0f - v) * (float)h - 0.5f;
    int x0 = (int)(fx + 1.0f) - 1, y0 = (int)(fy + 1.0f) - 1;
    float ax = fx - (float)x0, ay = fy - (float)y0;
    x0 = x0 < 0 ? x0 + w : (x0 >= w ? x0 - w : x0);
    x0 = (x0 >= 0 && x0 < w) ? x0 : 0;
    int x1 = x0 + 1 >= w ? 0 : x0 + 1, y1 = y0 + 1;
    y0 = y0 < 0 ? 0 : (y0 >= h ? h - 1 : y0);
    y1 = y1 < 0 ? 0 : (y1 >= h ? h - 1 : y1);
    const float *p00 = e->rgb + 3 * (y0 * w + x0), *p01 = e->rgb + 3 * (y0 * w + x1);
    const float *p10 = e->rgb + 3 * (y1 * w + x0), *p11 = e->rgb + 3 * (y1 * w + x1);
    const float k[3] = {e->scale.x, e->scale.y, e->scale.z};
    float bx = 1.0f - ax, by = 1.0f - ay;
    for (int c = 0; c < 3; c++) {
        float s = by * (bx * p00[c] + ax * p01[c]) + ay * (bx * p10[c] + ax * p11[c]);
        out[c] = s * (zero ? 0.0f : k[c]);
    }
}

/* 67 lanes (a full chunk of 64 and three left over) on the 8 x 4 image, its texels exactly
 * the 96 floats of a heap block (so a read past the end is visible to valgrind or ASan), with
 * a lane in the first and one in the second chunk whose texels include the image's last one
 * (bottom row, right column: no 16-byte load there), a zero direction, the poles and random
 * directions; every channel must equal lane_reference's bits. */
static void test_lookup_n_bits(void **state)
{
    (void)state;
    enum { N = 67 };
    env_map e = make_env();
    float *tight = malloc(sizeof img);
    assert_non_null(tight);
    memcpy(tight, img, sizeof img);
    e.rgb = tight;
    e.scale = v3(0.5f, 2.0f, 3.0f);
    float dx[N], dy[N], dz[N], r[N], g[N], b[N];
    unsigned seed = 12345u;
    for (int i = 0; i < N; i++) {
        float d[3];
        for (int c = 0; c < 3; c++) {
            seed = seed * 1664525u + 1013904223u;
            d[c] = (float)(seed >> 8) / 8388608.0f - 1.0f;
        }
        dx[i] = d[0], dy[i] = d[1], dz[i] = d[2];
    }
    /* Down and just short of u = 1: x0 = W - 1 (x1 wraps to 0), y0 = y1 = H - 1. */
    dx[5] = -1.0f, dy[5] = -8.0f, dz[5] = 0.01f;
    dx[65] = -1.0f, dy[65] = -8.0f, dz[65] = 0.02f;
    dx[6] = dy[6] = dz[6] = 0.0f;
    dx[7] = 0.0f, dy[7] = 1.0f, dz[7] = 0.0f;
    dx[8] = 0.0f, dy[8] = -1.0f, dz[8] = 0.0f;
    float tx, ty;
    env_direction_to_texel(&e, v3(dx[5], dy[5], dz[5]), &tx, &ty);
    assert_true(tx > (float)W - 0.5f && ty > (float)H - 0.5f);
    env_lookup_n(&e, N, dx, dy, dz, r, g, b);
    for (int i = 0; i < N; i++) {
        float want[3], got[3] = {r[i], g[i], b[i]};
        lane_reference(&e, dx[i], dy[i], dz[i], want);
        if (memcmp(want, got, sizeof want) != 0)
            fail_msg("lane %d (%g, %g, %g): got (%a, %a, %a), want (%a, %a, %a)", i, (double)dx[i], (double)dy[i],
                     (double)dz[i], (double)got[0], (double)got[1], (double)got[2], (double)want[0], (double)want[1],
                     (double)want[2]);
    }
    free(tight);
}

/* A cube map through env_lookup_n (the taps vectorised across lanes, then env_bilinear's
 * 16-byte loads) against env_lookup (env_cube_sample: scalar loads), bit for bit: 67 lanes (a
 * chunk of 64 and three more) on six 3 x 3 faces whose texels all differ per channel, exactly
 * the 162 floats of a heap block (a read past the end shows under valgrind or ASan), with the
 * last face's bottom-right texel in a lane of each chunk (no 16-byte load there), a zero
 * direction, a NaN, the six axes, face ties and random directions at scale (0.5, 2, 3). */
static void test_lookup_n_cube_bits(void **state)
{
    (void)state;
    enum { N = 67, F = 3, FLOATS = 6 * F * F * 3 };
    float *rgb = malloc(FLOATS * sizeof *rgb);
    assert_non_null(rgb);
    for (int i = 0; i < FLOATS; i++)
        rgb[i] = (float)(i / 3) + 1000.0f * (float)(i % 3);
    env_map e = {.kind = ENV_CUBE, .width = F, .height = F, .rgb = rgb, .scale = v3(0.5f, 2.0f, 3.0f)};
    float dx[N], dy[N], dz[N], r[N], g[N], b[N];
    unsigned seed = 777u;
    for (int i = 0; i < N; i++) {
        float d[3];
        for (int c = 0; c < 3; c++) {
            seed = seed * 1664525u + 1013904223u;
            d[c] = (float)(seed >> 8) / 8388608.0f - 1.0f;
        }
        dx[i] = d[0], dy[i] = d[1], dz[i] = d[2];
    }
    /* -Z's bottom-right texel (canonical +z major, s = -x/|z| near 1, t = -y/|z| near 1): the
     * image's last one; a lane in each chunk. */
    const float last[3] = {-0.9f, -0.9f, 1.0f};
    for (int c = 0; c < 3; c++) {
        float *d = c == 0 ? dx : (c == 1 ? dy : dz);
        d[3] = last[c];
        d[66] = last[c];
    }
    const float fixed[][3] = {{0, 0, 0}, {NAN, 0, 1}, {1, 0, 0}, {-1, 0, 0}, {0, 1, 0},  {0, -1, 0},
                              {0, 0, 1}, {0, 0, -1},  {1, 1, 0}, {0, 1, 1},  {1, 0, -1}, {1, 1, 1}};
    for (int k = 0; k < (int)(sizeof fixed / sizeof fixed[0]); k++)
        dx[10 + k] = fixed[k][0], dy[10 + k] = fixed[k][1], dz[10 + k] = fixed[k][2];
    float s, t;
    assert_int_equal(env_cube_coords(v3(last[0], last[1], last[2]), &s, &t), 5);
    assert_true(s > 1.0f - 0.5f / F && t > 1.0f - 0.5f / F);
    env_lookup_n(&e, N, dx, dy, dz, r, g, b);
    for (int i = 0; i < N; i++) {
        vec3 l = env_lookup(&e, v3(dx[i], dy[i], dz[i]));
        float want[3] = {l.x, l.y, l.z}, got[3] = {r[i], g[i], b[i]};
        if (memcmp(want, got, sizeof want) != 0)
            fail_msg("cube lane %d (%g, %g, %g): got (%a, %a, %a), want (%a, %a, %a)", i, (double)dx[i], (double)dy[i],
                     (double)dz[i], (double)got[0], (double)got[1], (double)got[2], (double)want[0], (double)want[1],
                     (double)want[2]);
    }
    free(rgb);
}

/* The constant environment's lane loop: the constant, and 0 for a zero direction. */
static void test_lookup_n_constant(void **state)
{
    (void)state;
    enum { N = 19 };
    env_map e = {.kind = ENV_CONSTANT, .constant = v3(0.25f, 2.0f, 7.0f)};
    float dx[N], dy[N], dz[N], r[N], g[N], b[N];
    for (int i = 0; i < N; i++)
        dx[i] = (float)(i % 3), dy[i] = -1.0f * (float)(i % 2), dz[i] = 0.0f;
    env_lookup_n(&e, N, dx, dy, dz, r, g, b);
    for (int i = 0; i < N; i++) {
        int zero = i % 6 == 0;
        assert_true(r[i] == (zero ? 0.0f : 0.25f) && g[i] == (zero ? 0.0f : 2.0f) && b[i] == (zero ? 0.0f : 7.0f));
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_orientation),
        cmocka_unit_test(test_bilinear),
        cmocka_unit_test(test_wrap_and_scale),
        cmocka_unit_test(test_constant_and_none),
        cmocka_unit_test(test_check_texels),
        cmocka_unit_test(test_render_refuses_bad_texels),
        cmocka_unit_test(test_check_loads_environment),
        cmocka_unit_test(test_lookup_n_bits),
        cmocka_unit_test(test_lookup_n_cube_bits),
        cmocka_unit_test(test_lookup_n_constant),
    };
    return cmocka_run_group_tests_name("env", tests, NULL, NULL);
}
