/* Cube-map environments (scene/env.h ENV_CUBE): the Direct3D face selection and face coordinates
 * against values worked out by hand from the D3DCUBEMAP_FACES table (canonical z is D3D -Z), the
 * orientation of every face on a 2 x 2 fixture whose texels all differ, bilinear at texel
 * centres, between them and clamped at a face edge (the seam: no blending across faces), the
 * SIMD lanes against the scalar lookup, the equirectangular conversion, texel checks, and the
 * scene-file and loader paths: six faces, a 4 x 3 cross, the refusals with their messages, and
 * the cache key covering the face files. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "cli_exec.h"
#include "env.h"
#include "exr.h"
#include "frame.h"
#include "jobs.h"
#include "renderers/registry.h"
#include "scene_file.h"
#include "tmpdir.h"

/* The fixture: N = 2, texel (x, y) of face f has R = 100 f + 10 y + x + 1, G = 2 R, B = R + 0.5. */
#define FN 2
static float fixture[6 * FN * FN * 3];

static float fixture_r(int face, int x, int y)
{
    return (float)(100 * face + 10 * y + x + 1);
}

static env_map fixture_map(void)
{
    for (int f = 0; f < 6; f++)
        for (int y = 0; y < FN; y++)
            for (int x = 0; x < FN; x++) {
                float *p = fixture + 3 * ((f * FN + y) * FN + x);
                p[0] = fixture_r(f, x, y);
                p[1] = 2.0f * p[0];
                p[2] = p[0] + 0.5f;
            }
    return (env_map){.kind = ENV_CUBE, .width = FN, .height = FN, .rgb = fixture, .scale = v3s(1.0f)};
}

static void test_face_selection(void **state)
{
    (void)state;
    /* Canonical direction, face, s, t: worked out from the table with (X, Y, Z) = (x, y, -z). */
    static const struct {
        float x, y, z;
        int face;
        float s, t;
    } c[] = {
        {1, 0, 0, 0, 0.5f, 0.5f},
        {-1, 0, 0, 1, 0.5f, 0.5f},
        {0, 1, 0, 2, 0.5f, 0.5f},
        {0, -1, 0, 3, 0.5f, 0.5f},
        {0, 0, -1, 4, 0.5f, 0.5f}, /* canonical -z is D3D +Z */
        {0, 0, 1, 5, 0.5f, 0.5f},
        /* +X: sc = -Z = 0.2, tc = -Y = -0.3, ma = 0.8 */
        {0.8f, 0.3f, 0.2f, 0, 0.625f, 0.3125f},
        /* -X: sc = +Z = -0.2, tc = -Y */
        {-0.8f, 0.3f, 0.2f, 1, 0.375f, 0.3125f},
        /* +Y: sc = X = 0.3, tc = +Z = -0.2 */
        {0.3f, 0.8f, 0.2f, 2, 0.6875f, 0.375f},
        /* -Y: sc = X, tc = -Z = 0.2 */
        {0.3f, -0.8f, 0.2f, 3, 0.6875f, 0.625f},
        /* +Z (z = -0.8): sc = X, tc = -Y = -0.2 */
        {0.3f, 0.2f, -0.8f, 4, 0.6875f, 0.375f},
        /* -Z (z = 0.8): sc = -X = -0.3, tc = -Y */
        {0.3f, 0.2f, 0.8f, 5, 0.3125f, 0.375f},
        /* Near the diagonals: the largest component wins by 1e-3. */
        {1.0f, 0.999f, 0.0f, 0, 0.5f, 0.0005f},
        {0.999f, 1.0f, 0.0f, 2, 0.9995f, 0.5f},
        {0.0f, -0.999f, -1.0f, 4, 0.5f, 0.9995f},
        {-0.999f, 0.5f, 1.0f, 5, 0.9995f, 0.25f},
        /* Length does not matter: a long and a short copy of the +X case. */
        {8e6f, 3e6f, 2e6f, 0, 0.625f, 0.3125f},
        {8e-6f, 3e-6f, 2e-6f, 0, 0.625f, 0.3125f},
    };
    for (size_t i = 0; i < sizeof c / sizeof c[0]; i++) {
        float s, t;
        int f = env_cube_coords(v3(c[i].x, c[i].y, c[i].z), &s, &t);
        if (f != c[i].face || fabsf(s - c[i].s) > 1e-6f || fabsf(t - c[i].t) > 1e-6f)
            fail_msg("case %zu: face %d s %g t %g, want face %d s %g t %g", i, f, (double)s, (double)t, c[i].face,
                     (double)c[i].s, (double)c[i].t);
        /* The inverse lands on the same direction. */
        vec3 d = env_cube_direction(f, s, t), u = v3_norm(v3(c[i].x, c[i].y, c[i].z));
        assert_true(fabsf(d.x - u.x) < 1e-5f && fabsf(d.y - u.y) < 1e-5f && fabsf(d.z - u.z) < 1e-5f);
    }
    /* Ties go to X, then Y (the header's rule); a zero or NaN direction stays in range. */
    float s, t;
    assert_int_equal(env_cube_coords(v3(1, 1, 1), &s, &t), 0);
    assert_int_equal(env_cube_coords(v3(0, 1, -1), &s, &t), 2);
    env_cube_coords(v3(0, 0, 0), &s, &t);
    assert_true(s >= 0 && s <= 1 && t >= 0 && t <= 1);
    env_cube_coords(v3(NAN, 0, 1), &s, &t);
    assert_true(s >= 0 && s <= 1 && t >= 0 && t <= 1);
}

static void test_orientation(void **state)
{
    (void)state;
    env_map e = fixture_map();
    /* One texel centre per face, its direction worked out by hand from the table (texel centres
     * at s, t = 0.25 and 0.75, so sc, tc = -0.5 and 0.5). */
    static const struct {
        float x, y, z;
        int face, tx, ty;
    } c[] = {
        {1, 0.5f, 0.5f, 0, 1, 0},     /* sc = -Z = 0.5, tc = -Y = -0.5 */
        {-1, -0.5f, 0.5f, 1, 0, 1},   /* sc = Z = -0.5, tc = -Y = 0.5 */
        {0.5f, 1, -0.5f, 2, 1, 1},    /* sc = X = 0.5, tc = Z = 0.5 */
        {-0.5f, -1, -0.5f, 3, 0, 0},  /* sc = X = -0.5, tc = -Z = -0.5 */
        {-0.5f, -0.5f, -1, 4, 0, 1},  /* sc = X = -0.5, tc = -Y = 0.5 */
        {-0.5f, 0.5f, 1, 5, 1, 0},    /* sc = -X = 0.5, tc = -Y = -0.5 */
    };
    for (size_t i = 0; i < sizeof c / sizeof c[0]; i++) {
        vec3 l = env_lookup(&e, v3(c[i].x, c[i].y, c[i].z));
        float want = fixture_r(c[i].face, c[i].tx, c[i].ty);
        if (fabsf(l.x - want) > 1e-4f || fabsf(l.y - 2 * want) > 1e-4f || fabsf(l.z - (want + 0.5f)) > 1e-4f)
            fail_msg("case %zu: got (%g, %g, %g), want R %g", i, (double)l.x, (double)l.y, (double)l.z, (double)want);
    }
}

static void test_bilinear_and_seam(void **state)
{
    (void)state;
    env_map e = fixture_map();
    /* +Z face (401, 402 / 411, 412): halfway between the top texels (s = 0.5, t = 0.25). */
    close_rel(env_lookup(&e, v3(0, 0.5f, -1)).x, 401.5, 1e-6);
    /* Face centre: the mean of its four texels. */
    close_rel(env_lookup(&e, v3(0, 0, -1)).x, (401 + 402 + 411 + 412) / 4.0, 1e-6);
    /* A quarter of the way from centre (0.25) to centre (0.75) in s: s = 0.375, sc = -0.25. */
    close_rel(env_lookup(&e, v3(-0.25f, 0.5f, -1)).x, 401.25, 1e-6);
    /* Beyond the last texel centre (s = 0.9 > 0.75): clamped to the edge texel, 402 exactly. */
    close_rel(env_lookup(&e, v3(0.8f, 0.5f, -1)).x, 402.0, 1e-6);
    /* Across the +Z / +X seam (D3D Z = X): on +Z just before it the edge texel 402, on +X just
     * after it s = 0.0005, the +X edge texel (0, 0) = 1: a jump, no blending between faces. */
    close_rel(env_lookup(&e, v3(0.999f, 0.5f, -1)).x, 402.0, 1e-6);
    close_rel(env_lookup(&e, v3(1, 0.5f, -0.999f)).x, 1.0, 1e-6);
    /* The scale multiplies, per channel; a zero direction gives zero. */
    e.scale = v3(2.0f, 0.5f, 1.0f);
    vec3 l = env_lookup(&e, v3(1, 0.5f, 0.5f));
    close_rel(l.x, 4.0, 1e-6);
    close_rel(l.y, 2.0, 1e-6);
    close_rel(l.z, 2.5, 1e-6);
    assert_true(env_lookup(&e, v3(0, 0, 0)).x == 0.0f);
}

static void test_lanes_match_scalar(void **state)
{
    (void)state;
    /* A larger, smooth-free map: 8 x 8 faces of pseudo-random texels. */
    enum { N = 8, M = 1000 };
    static float rgb[6 * N * N * 3];
    unsigned seed = 12345u;
    for (size_t i = 0; i < sizeof rgb / sizeof rgb[0]; i++) {
        seed = seed * 1664525u + 1013904223u;
        rgb[i] = (float)(seed >> 8) / 16777216.0f * 10.0f;
    }
    env_map e = {.kind = ENV_CUBE, .width = N, .height = N, .rgb = rgb, .scale = v3(1.0f, 2.0f, 0.5f)};
    static float dx[M], dy[M], dz[M], r[M], g[M], b[M];
    for (int i = 0; i < M; i++) {
        float v[3];
        for (int k = 0; k < 3; k++) {
            seed = seed * 1664525u + 1013904223u;
            v[k] = (float)(seed >> 8) / 8388608.0f - 1.0f;
        }
        /* Every 50th lane is zero, every 7th lies near a seam (|x| = |z|). */
        dx[i] = i % 50 == 0 ? 0.0f : v[0];
        dy[i] = i % 50 == 0 ? 0.0f : v[1];
        dz[i] = i % 50 == 0 ? 0.0f : (i % 7 == 0 ? -v[0] * 1.0001f : v[2]);
    }
    env_lookup_n(&e, M, dx, dy, dz, r, g, b);
    for (int i = 0; i < M; i++) {
        vec3 l = env_lookup(&e, v3(dx[i], dy[i], dz[i]));
        if (fabsf(l.x - r[i]) > 1e-5f * fmaxf(1.0f, l.x) || fabsf(l.y - g[i]) > 1e-5f * fmaxf(1.0f, l.y) ||
            fabsf(l.z - b[i]) > 1e-5f * fmaxf(1.0f, l.z))
            fail_msg("lane %d (%g, %g, %g): scalar (%g, %g, %g), lanes (%g, %g, %g)", i, (double)dx[i], (double)dy[i],
                     (double)dz[i], (double)l.x, (double)l.y, (double)l.z, (double)r[i], (double)g[i], (double)b[i]);
    }
    assert_true(r[0] == 0.0f && g[50] == 0.0f);
}

static void test_equirect_and_check(void **state)
{
    (void)state;
    env_map e = fixture_map();
    float eq[4 * 2 * 3];
    env_cube_to_equirect(&e, 4, 2, eq);
    /* Texel (0, 0) of a 4 x 2 image: u = 0.125, v = 0.75, so longitude -135 and latitude 45
     * degrees: (-0.5, 0.7071, -0.5), D3D (-0.5, 0.7071, 0.5), face +Y with s = 0.146, t = 0.854:
     * clamped to texel (0, 1) of +Y, 211. */
    close_rel(eq[0], 211.0, 1e-6);
    /* Texel (2, 1): u = 0.625 (longitude 45), latitude -45: (0.5, -0.7071, 0.5), D3D
     * (0.5, -0.7071, -0.5), face -Y, sc = X/|Y| = 0.7071, tc = -Z/|Y| = 0.7071: s = t = 0.854,
     * texel (1, 1) of -Y, 312. */
    close_rel(eq[3 * (1 * 4 + 2)], 312.0, 1e-6);

    env_texel_check chk;
    assert_int_equal(env_check(&e, &chk), RC_OK);
    fixture[3 * ((3 * FN + 1) * FN + 0) + 2] = NAN; /* face -Y, x 0, y 1, B */
    fixture[3 * ((4 * FN + 0) * FN + 1) + 0] = -1.0f;
    assert_int_equal(env_check(&e, &chk), RC_ERR_RANGE);
    assert_int_equal(chk.n_nonfinite, 1);
    assert_int_equal(chk.n_negative, 1);
    assert_int_equal(chk.first_nonfinite.face, 3);
    assert_int_equal(chk.first_nonfinite.x, 0);
    assert_int_equal(chk.first_nonfinite.y, 1);
    assert_int_equal(chk.first_nonfinite.channel, 2);
    assert_int_equal(chk.first_negative.face, 4);
    assert_int_equal(chk.first_negative.x, 1);
}

/* An RGB EXR of w x h whose R is v0 + x + 10 y (G, B constant). */
static void write_exr(const char *name, int w, int h, float v0)
{
    char path[300], err[512];
    snprintf(path, sizeof path, "%s/%s", tmpdir, name);
    float *r = malloc(sizeof(float) * (size_t)(w * h)), *gb = malloc(sizeof(float) * (size_t)(w * h));
    for (int i = 0; i < w * h; i++) {
        r[i] = v0 + (float)(i % w) + 10.0f * (float)(i / w);
        gb[i] = 0.25f;
    }
    exr_channel ch[3] = {{"R", r}, {"G", gb}, {"B", gb}};
    assert_int_equal(exr_write(path, w, h, ch, 3, NULL, 0, err, sizeof err), RC_OK);
    free(r);
    free(gb);
}

static const char *const scene_head = "image: {width: 8, height: 8}\n"
                                      "camera: {eye: [0, 0, 3], target: [0, 0, 0], hfov: 40}\n"
                                      "materials:\n  a: {model: d3d9client, d3d9client: {reflect: [1, 1, 1]}}\n"
                                      "objects:\n  - {shape: sphere, radius: 1, material: a}\n";

/* Loads tmpdir/s.yaml with the given environment line and its cube; returns the status of the
 * first step that fails, the message in err. */
static rc_status load_env(const char *env_line, scene *s, env_map *e, float **px, char *err, size_t errlen)
{
    char path[300];
    snprintf(path, sizeof path, "%s/s.yaml", tmpdir);
    FILE *f = fopen(path, "w");
    fprintf(f, "%senvironment: %s\n", scene_head, env_line);
    fclose(f);
    *px = NULL;
    rc_status st = scene_file_load(path, s, err, errlen);
    return st != RC_OK ? st : frame_env_load(s, e, px, err, errlen);
}

#define SIX "{px: px.exr, nx: nx.exr, py: py.exr, ny: ny.exr, pz: pz.exr, nz: nz.exr}"

static void test_scene_faces_and_cross(void **state)
{
    (void)state;
    static const char *const key[6] = {"px", "nx", "py", "ny", "pz", "nz"};
    char name[32], err[2048];
    for (int f = 0; f < 6; f++) {
        snprintf(name, sizeof name, "%s.exr", key[f]);
        write_exr(name, 2, 2, 100.0f * (float)f);
    }
    scene *s = malloc(sizeof *s);
    env_map e;
    float *px;
    assert_int_equal(load_env("{cube: " SIX ", scale: 2}", s, &e, &px, err, sizeof err), RC_OK);
    assert_int_equal(e.kind, ENV_CUBE);
    assert_int_equal(e.width, 2);
    /* Face -Y (3), texel (1, 0): 300 + 1; the +X face's texel (1, 0) seen from (1, 0.5, 0.5): 1. */
    close_rel(e.rgb[3 * ((3 * 2 + 0) * 2 + 1)], 301.0, 0);
    close_rel(env_lookup(&e, v3(1, 0.5f, 0.5f)).x, 2.0, 1e-6);
    free(px);

    /* The 4 x 3 cross: face f at its cell, each texel R = 100 f + x + 10 y + 1 inside it. */
    int n = 2, w = 4 * n, h = 3 * n;
    static const int cell[6][2] = {{2, 1}, {0, 1}, {1, 0}, {1, 2}, {1, 1}, {3, 1}};
    float r[8 * 6], gb[8 * 6];
    for (int i = 0; i < w * h; i++)
        r[i] = -7.0f, gb[i] = 0.5f; /* the empty cells' texels are never read */
    for (int f = 0; f < 6; f++)
        for (int y = 0; y < n; y++)
            for (int x = 0; x < n; x++)
                r[(cell[f][1] * n + y) * w + cell[f][0] * n + x] = fixture_r(f, x, y);
    char path[300];
    snprintf(path, sizeof path, "%s/cross.exr", tmpdir);
    exr_channel ch[3] = {{"R", r}, {"G", gb}, {"B", gb}};
    assert_int_equal(exr_write(path, w, h, ch, 3, NULL, 0, err, sizeof err), RC_OK);
    assert_int_equal(load_env("{cube_cross: cross.exr}", s, &e, &px, err, sizeof err), RC_OK);
    env_map fx = fixture_map();
    for (int i = 0; i < 6 * n * n; i++)
        close_rel(e.rgb[3 * i], fx.rgb[3 * i], 0);
    free(px);

    /* The cache key covers the faces: a cached raster run, then one face changed. */
    char scn[300], out[300], rec[400], cache[300];
    snprintf(scn, sizeof scn, "%s/s.yaml", tmpdir);
    snprintf(out, sizeof out, "%s/run", tmpdir);
    snprintf(cache, sizeof cache, "%s/cache", tmpdir);
    FILE *f = fopen(scn, "w");
    fprintf(f, "name: cubekey\n%senvironment: {cube: " SIX "}\n", scene_head);
    fclose(f);
    job_output_path(out, "cubekey", registry_find("raster"), ROLE_TWIN, "json", rec, sizeof rec);
    const char *want[3] = {"false", "true", "false"};
    for (int run = 0; run < 3; run++) {
        if (run == 2)
            write_exr("nz.exr", 2, 2, 7.0f);
        assert_int_equal(cli_exec(err, sizeof err, "run %s --renderer raster --role twin --out %s --cache %s", scn,
                                  out, cache),
                         0);
        FILE *j = fopen(rec, "r");
        assert_non_null(j);
        char buf[8192];
        size_t len = fread(buf, 1, sizeof buf - 1, j);
        buf[len] = '\0';
        fclose(j);
        const char *v = strstr(buf, "\"cached\":");
        assert_non_null(v);
        v += strlen("\"cached\":");
        v += strspn(v, " \t");
        if (strncmp(v, want[run], strlen(want[run])) != 0)
            fail_msg("run %d: the record %s has not \"cached\": %s", run, rec, want[run]);
    }
    free(s);
}

static void test_refusals(void **state)
{
    (void)state;
    char err[2048];
    scene *s = malloc(sizeof *s);
    env_map e;
    float *px;
    write_exr("sq2.exr", 2, 2, 1.0f);
    write_exr("sq4.exr", 4, 4, 1.0f);
    write_exr("wide.exr", 4, 2, 1.0f);
    static const struct {
        const char *env;
        rc_status st;
        const char *msg[2];
    } c[] = {
        {"{cube: {px: sq2.exr, nx: sq2.exr, py: sq2.exr, ny: sq2.exr, pz: sq2.exr}}",
         RC_ERR_PARSE,
         {"environment.cube.nz", "missing required key"}},
        {"{cube: {px: sq2.exr, nx: sq2.exr, py: wide.exr, ny: sq2.exr, pz: sq2.exr, nz: sq2.exr}}",
         RC_ERR_RANGE,
         {"environment.cube.py: the +Y face", "is 4x2; give square faces"}},
        {"{cube: {px: sq2.exr, nx: sq2.exr, py: sq2.exr, ny: sq2.exr, pz: sq4.exr, nz: sq2.exr}}",
         RC_ERR_RANGE,
         {"environment.cube.pz: the +Z face", "is 4x4 but the +X face"}},
        {"{cube: {px: sq2.exr, nx: sq2.exr, py: sq2.exr, ny: sq2.exr, pz: sq2.exr, nz: nothere.exr}}",
         RC_ERR_IO,
         {"environment.cube.nz", "nothere.exr"}},
        {"{cube_cross: wide.exr}", RC_ERR_RANGE, {"environment.cube_cross", "is 4x2, not a horizontal cross"}},
        {"{cube_cross: sq2.exr, image: sq2.exr}", RC_ERR_PARSE, {"exactly one of", "cube_cross"}},
        {"{cube_cross: sq2.exr, sun_threshold: 5}", RC_ERR_PARSE, {"sun_threshold", "not used by a cube map"}},
        {"{cube: {px: sq2.bmp}}", RC_ERR_RANGE, {"environment.cube.px", "unsupported extension"}},
    };
    for (size_t i = 0; i < sizeof c / sizeof c[0]; i++) {
        px = NULL;
        rc_status st = load_env(c[i].env, s, &e, &px, err, sizeof err);
        if (st != c[i].st || strstr(err, c[i].msg[0]) == NULL || strstr(err, c[i].msg[1]) == NULL)
            fail_msg("case %zu (%s): status %d, message: %s", i, c[i].env, (int)st, err);
        assert_null(px);
    }
    /* A negative texel names the face, its file and the texel. */
    char path[300];
    snprintf(path, sizeof path, "%s/neg.exr", tmpdir);
    float r[4] = {1, 2, 3, -4}, gb[4] = {0, 0, 0, 0};
    exr_channel ch[3] = {{"R", r}, {"G", gb}, {"B", gb}};
    assert_int_equal(exr_write(path, 2, 2, ch, 3, NULL, 0, err, sizeof err), RC_OK);
    assert_int_equal(
        load_env("{cube: {px: sq2.exr, nx: sq2.exr, py: sq2.exr, ny: neg.exr, pz: sq2.exr, nz: sq2.exr}}", s, &e, &px,
                 err, sizeof err),
        RC_ERR_RANGE);
    assert_non_null(strstr(err, "environment.cube.ny"));
    assert_non_null(strstr(err, "neg.exr"));
    assert_non_null(strstr(err, "on the -Y face at texel (x 1, y 1) channel R = -4"));
    free(s);
}

/* What the references receive: the city cube's conversion as frame_env_cube_write writes it, read
 * back, looked up bilinearly, against the cube lookup over 400 000 directions uniform on the
 * sphere. Prints the luminance relative RMS and the largest relative departure (docs/cubemaps.md
 * quotes them: 3.7e-3 and 0.74); the bound leaves room for the sun, which dominates it. */
static void test_conversion_floor(void **state)
{
    (void)state;
    scene *s = malloc(sizeof *s);
    char err[2048], path[300];
    env_map c;
    float *px = NULL;
    assert_int_equal(scene_file_load("scenes/cube_mirror.yaml", s, err, sizeof err), RC_OK);
    assert_int_equal(frame_env_load(s, &c, &px, err, sizeof err), RC_OK);
    snprintf(path, sizeof path, "%s/conv.exr", tmpdir);
    assert_int_equal(frame_env_cube_write(path, &c, err, sizeof err), RC_OK);
    exr_image img;
    assert_int_equal(exr_read(path, &img, err, sizeof err), RC_OK);
    assert_int_equal(img.width, 64 * c.width);
    assert_int_equal(img.height, 32 * c.width);
    size_t n = (size_t)img.width * (size_t)img.height;
    float *rgb = malloc(3 * n * sizeof *rgb);
    const float *ch[3] = {exr_image_channel(&img, "R"), exr_image_channel(&img, "G"), exr_image_channel(&img, "B")};
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++)
            rgb[3 * i + (size_t)k] = ch[k][i];
    env_map e = {.kind = ENV_IMAGE, .width = img.width, .height = img.height, .rgb = rgb, .scale = v3s(1.0f)};
    unsigned seed = 7u;
    double se = 0.0, sr = 0.0, worst = 0.0;
    for (int i = 0; i < 400000;) {
        float v[3];
        for (int k = 0; k < 3; k++) {
            seed = seed * 1664525u + 1013904223u;
            v[k] = (float)(seed >> 8) / 8388608.0f - 1.0f;
        }
        vec3 d = v3(v[0], v[1], v[2]);
        float l2 = v3_dot(d, d);
        if (l2 > 1.0f || l2 < 1e-6f)
            continue; /* rejection sampling: uniform in the ball, so uniform in direction */
        i++;
        vec3 a = env_lookup(&c, d), b = env_lookup(&e, d);
        double ya = 0.2126 * a.x + 0.7152 * a.y + 0.0722 * a.z, yb = 0.2126 * b.x + 0.7152 * b.y + 0.0722 * b.z;
        se += (ya - yb) * (ya - yb);
        sr += ya * ya;
        worst = fmax(worst, fabs(ya - yb) / fmax(ya, 1e-3));
    }
    double rel = sqrt(se / sr);
    printf("cube conversion %dx%d of city 6 x %d^2: luminance rel RMS %.3g, worst relative %.3g\n", img.width,
           img.height, c.width, rel, worst);
    assert_true(rel < 6e-3);
    exr_image_free(&img);
    free(rgb);
    free(px);
    free(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_face_selection),       cmocka_unit_test(test_orientation),
        cmocka_unit_test(test_bilinear_and_seam),    cmocka_unit_test(test_lanes_match_scalar),
        cmocka_unit_test(test_equirect_and_check),   cmocka_unit_test(test_scene_faces_and_cross),
        cmocka_unit_test(test_refusals),             cmocka_unit_test(test_conversion_floor),
    };
    return cmocka_run_group_tests(tests, tmpdir_setup, tmpdir_teardown);
}
