#include "env.h"

#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "formula.h"
#include "smath.h"

void env_direction_to_texel(const env_map *e, vec3 dir, float *tx, float *ty)
{
    vec3 d = v3_norm(dir);
    /* asinf is only defined on [-1, 1]; rounding in v3_norm can leave y a few ulp outside. */
    float y = fminf(fmaxf(d.y, -1.0f), 1.0f);
    float u = 0.5f + atan2f(d.z, d.x) / (2.0f * FORMULA_PI_F);
    float v = 0.5f + asinf(y) / FORMULA_PI_F;
    *tx = u * (float)e->width;
    *ty = (1.0f - v) * (float)e->height;
}

rc_status env_check(const env_map *e, env_texel_check *out)
{
    const env_texel none = {-1, -1, -1, -1, 0.0f};
    *out = (env_texel_check){0, 0, none, none};
    if (e == NULL || (e->kind != ENV_IMAGE && e->kind != ENV_CUBE) || e->rgb == NULL || e->width <= 0 || e->height <= 0)
        return RC_OK;
    /* A cube's faces lie one below the other: row y of the whole is row y % N of face y / N. */
    int faces = e->kind == ENV_CUBE ? 6 : 1;
    for (int y = 0; y < faces * e->height; y++)
        for (int x = 0; x < e->width; x++)
            for (int c = 0; c < 3; c++) {
                float v = e->rgb[3 * ((size_t)y * (size_t)e->width + (size_t)x) + (size_t)c];
                int face = e->kind == ENV_CUBE ? y / e->height : -1, row = y % e->height;
                if (!isfinite(v)) {
                    if (out->n_nonfinite++ == 0)
                        out->first_nonfinite = (env_texel){x, row, c, face, v};
                } else if (v < 0.0f && out->n_negative++ == 0) {
                    out->first_negative = (env_texel){x, row, c, face, v};
                }
            }
    return out->n_nonfinite > 0 || out->n_negative > 0 ? RC_ERR_RANGE : RC_OK;
}

const char *const env_cube_face_names[6] = {"+X", "-X", "+Y", "-Y", "+Z", "-Z"};
const char *const env_cube_face_keys[6] = {"px", "nx", "py", "ny", "pz", "nz"};

/* v clamped to [0, 1], a NaN to 0, so that every index stays inside the face whatever the
 * input: the values of fminf(fmaxf(v, 0), 1) but in compares and selects, which GCC 12
 * vectorises (fminf and fmaxf, whose NaN rules x86's min and max do not follow, kept the cube
 * lane loop scalar). A -0 may come out where fmaxf gives +0: the callers' s * N - 0.5 is -0.5
 * either way. */
static inline float env_unit_clamp(float v)
{
    v = v > 0.0f ? v : 0.0f;
    return v < 1.0f ? v : 1.0f;
}

/* The D3D face selection and face coordinates (env.h's table), written with selects only so
 * that env_lookup_n's lane loop if-converts it; (x, y, z) canonical, not necessarily unit. */
static inline int env_cube_face_st(float x, float y, float z, float *s, float *t)
{
    float dz = -z; /* D3D's left-handed Z */
    float ax = fabsf(x), ay = fabsf(y), az = fabsf(dz);
    int is_x = (ax >= ay) & (ax >= az), is_y = !is_x & (ay >= az);
    int face = is_x ? (x > 0.0f ? 0 : 1) : is_y ? (y > 0.0f ? 2 : 3) : (dz > 0.0f ? 4 : 5);
    float ma = is_x ? ax : is_y ? ay : az;
    float sc = face == 0 ? -dz : face == 1 ? dz : face == 5 ? -x : x;
    float tc = face == 2 ? dz : face == 3 ? -dz : -y;
    /* A zero direction has no major axis: any in-range answer will do (the callers zero it). */
    float inv = ma > 0.0f ? 0.5f / ma : 0.0f;
    *s = env_unit_clamp(sc * inv + 0.5f);
    *t = env_unit_clamp(tc * inv + 0.5f);
    return face;
}

int env_cube_coords(vec3 dir, float *s, float *t) { return env_cube_face_st(dir.x, dir.y, dir.z, s, t); }

vec3 env_cube_direction(int face, float s, float t)
{
    float sc = 2.0f * s - 1.0f, tc = 2.0f * t - 1.0f;
    /* The table read backwards, in D3D (X, Y, Z) with |ma| = 1. */
    vec3 d;
    switch (face) {
    case 0: d = v3(1.0f, -tc, -sc); break;
    case 1: d = v3(-1.0f, -tc, sc); break;
    case 2: d = v3(sc, 1.0f, tc); break;
    case 3: d = v3(sc, -1.0f, -tc); break;
    case 4: d = v3(sc, -tc, 1.0f); break;
    default: d = v3(-sc, -tc, -1.0f); break;
    }
    d.z = -d.z; /* back to canonical */
    return v3_norm(d);
}

/* by (bx t00 + ax t01) + ay (bx t10 + ax t11): the bilinear sum of four texel values, weights
 * ax, ay and their complements bx, by. Every lookup's sums (the cube's, the image's lane by
 * lane and four lanes at a time) call this one function, so all make the same roundings in the
 * same order. */
SMATH_INLINE float env_bilerp(float t00, float t01, float t10, float t11, float ax, float ay, float bx, float by)
{
    return by * (bx * t00 + ax * t01) + ay * (bx * t10 + ax * t11);
}

/* One lookup's four texels (float offsets into rgb) and bilinear weights. */
typedef struct {
    int o00, o01, o10, o11;
    float ax, ay;
} env_tap;

/* The cube's taps for one direction: the face and (s, t) of env_cube_face_st, then the four
 * nearest texel centres of that face, indices clamped to it. env_cube_sample and
 * env_cube_taps (the lane loop) both call it. Returned by value: a local array written
 * through a pointer in the lane loop kept it scalar (GCC 12 saw scatter stores). */
SMATH_INLINE env_tap env_cube_tap(int n, float x, float y, float z)
{
    env_tap p;
    float s, t;
    int face = env_cube_face_st(x, y, z, &s, &t);
    float fx = s * (float)n - 0.5f, fy = t * (float)n - 0.5f;
    /* fx, fy >= -0.5: truncating fx + 1 is floor(fx) + 1 without a libm floorf. */
    int x0 = (int)(fx + 1.0f) - 1, y0 = (int)(fy + 1.0f) - 1;
    p.ax = fx - (float)x0;
    p.ay = fy - (float)y0;
    int x1 = x0 + 1, y1 = y0 + 1;
    x0 = x0 < 0 ? 0 : (x0 >= n ? n - 1 : x0);
    x1 = x1 < 0 ? 0 : (x1 >= n ? n - 1 : x1);
    y0 = y0 < 0 ? 0 : (y0 >= n ? n - 1 : y0);
    y1 = y1 < 0 ? 0 : (y1 >= n ? n - 1 : y1);
    int base = face * n;
    p.o00 = 3 * ((base + y0) * n + x0);
    p.o01 = 3 * ((base + y0) * n + x1);
    p.o10 = 3 * ((base + y1) * n + x0);
    p.o11 = 3 * ((base + y1) * n + x1);
    return p;
}

/* One cube lookup (unscaled): env_cube_tap, then the bilinear sum per channel. */
static void env_cube_sample(const float *restrict rgb, int n, float x, float y, float z, float *r, float *g, float *b)
{
    const env_tap p = env_cube_tap(n, x, y, z);
    const float *p00 = rgb + p.o00, *p01 = rgb + p.o01, *p10 = rgb + p.o10, *p11 = rgb + p.o11;
    const float bx = 1.0f - p.ax, by = 1.0f - p.ay;
    *r = env_bilerp(p00[0], p01[0], p10[0], p11[0], p.ax, p.ay, bx, by);
    *g = env_bilerp(p00[1], p01[1], p10[1], p11[1], p.ax, p.ay, bx, by);
    *b = env_bilerp(p00[2], p01[2], p10[2], p11[2], p.ax, p.ay, bx, by);
}

void env_cube_to_equirect(const env_map *cube, int width, int height, float *rgb)
{
    const double pi = FORMULA_PI_D;
    for (int j = 0; j < height; j++) {
        /* Row j's centre: v = 1 - (j + 0.5)/H, latitude (v - 0.5) pi (env.h). */
        double lat = pi * (0.5 - ((double)j + 0.5) / height);
        for (int i = 0; i < width; i++) {
            double phi = 2.0 * pi * (((double)i + 0.5) / width - 0.5);
            float *p = rgb + 3 * ((size_t)j * (size_t)width + (size_t)i);
            env_cube_sample(cube->rgb, cube->width, (float)(cos(lat) * cos(phi)), (float)sin(lat),
                            (float)(cos(lat) * sin(phi)), &p[0], &p[1], &p[2]);
        }
    }
}

static vec3 env_texel_rgb(const env_map *e, int x, int y)
{
    y = y < 0 ? 0 : (y >= e->height ? e->height - 1 : y);
    const float *p = e->rgb + 3 * ((size_t)y * (size_t)e->width + (size_t)x);
    return v3(p[0], p[1], p[2]);
}

vec3 env_lookup(const env_map *e, vec3 dir)
{
    if (e == NULL || e->kind == ENV_NONE || v3_dot(dir, dir) == 0.0f)
        return v3s(0.0f);
    if (e->kind == ENV_CONSTANT || e->rgb == NULL || e->width <= 0 || e->height <= 0)
        return e->kind == ENV_CONSTANT ? e->constant : v3s(0.0f);
    if (e->kind == ENV_CUBE) {
        vec3 c;
        env_cube_sample(e->rgb, e->width, dir.x, dir.y, dir.z, &c.x, &c.y, &c.z);
        return v3_mul(c, e->scale);
    }

    float tx, ty;
    env_direction_to_texel(e, dir, &tx, &ty);
    /* Texel centres sit at +0.5: shift so that floor() finds the left/upper neighbour. */
    float fx = tx - 0.5f, fy = ty - 0.5f;
    float x0f = floorf(fx), y0f = floorf(fy);
    float ax = fx - x0f, ay = fy - y0f;
    int x0 = (int)x0f, y0 = (int)y0f;
    /* tx lies in [0, W], so x0 is in [-1, W]: wrap with compares instead of a division per texel. */
    x0 = x0 < 0 ? x0 + e->width : (x0 >= e->width ? x0 - e->width : x0);
    int x1 = x0 + 1 >= e->width ? x0 + 1 - e->width : x0 + 1;
    if (x0 < 0 || x0 >= e->width)
        x0 = 0, x1 = e->width > 1 ? 1 : 0;
    vec3 top = v3_lerp(env_texel_rgb(e, x0, y0), env_texel_rgb(e, x1, y0), ax);
    vec3 bottom = v3_lerp(env_texel_rgb(e, x0, y0 + 1), env_texel_rgb(e, x1, y0 + 1), ax);
    return v3_mul(v3_lerp(top, bottom, ay), e->scale);
}

/* env_lookup_n works through its lanes in chunks of this many: the first pass of a chunk
 * (directions to texel offsets, vectorised) leaves its results in arrays this long on the
 * stack, and the second (texel reads and the bilinear sums) reads them back. */
#define ENV_CHUNK 64

/* What the first pass leaves for one lane: the float offsets of its four texels in rgb, its
 * bilinear weights, whether all four texels can be read as 16 bytes (below), and whether the
 * direction was zero. */
typedef struct {
    int o00[ENV_CHUNK], o01[ENV_CHUNK], o10[ENV_CHUNK], o11[ENV_CHUNK];
    float ax[ENV_CHUNK], ay[ENV_CHUNK], bx[ENV_CHUNK], by[ENV_CHUNK];
    int wide[ENV_CHUNK], zero[ENV_CHUNK];
} env_taps;

/* Four floats operated on together: four lanes' values of one channel, or one texel's R, G, B
 * and a fourth float that no result reads. */
typedef float env_v4 __attribute__((vector_size(16)));

SMATH_INLINE env_v4 env_load4(const float *p)
{
    env_v4 v;
    memcpy(&v, p, sizeof v);
    return v;
}

/* Eight floats: eight lanes' values of one channel, or two texels' R, G, B (and the float after
 * each) side by side. */
typedef float env_v8 __attribute__((vector_size(32)));

/* Vector element selection (GCC 12 and clang): indices number a's elements, then b's. */
#define ENV_SHUFFLE __builtin_shufflevector

/* Two texels (16-byte loads at p and q) as one vector, p's in the low half; out through a
 * pointer (a returned 32-byte vector changes the ABI between the clones, which GCC warns of). */
SMATH_INLINE void env_load4x2(const float *p, const float *q, env_v8 *out)
{
    *out = ENV_SHUFFLE(env_load4(p), env_load4(q), 0, 1, 2, 3, 4, 5, 6, 7);
}

/* One texel of eight lanes (16-byte loads at offsets o[0..7]) transposed into eight-lane R, G
 * and B vectors: lanes 0-3 in the low half and 4-7 in the high one, each half transposed on its
 * own, so every shuffle stays within 16-byte halves (one instruction each with AVX). */
SMATH_INLINE void env_texel_x8(const float *restrict rgb, const int *o, env_v8 *r, env_v8 *g, env_v8 *b)
{
    env_v8 t0, t1, t2, t3;
    env_load4x2(rgb + o[0], rgb + o[4], &t0);
    env_load4x2(rgb + o[1], rgb + o[5], &t1);
    env_load4x2(rgb + o[2], rgb + o[6], &t2);
    env_load4x2(rgb + o[3], rgb + o[7], &t3);
    /* R, G of lanes 0, 1 (then 4, 5) interleaved; B and the unread fourth floats likewise. */
    env_v8 rg01 = ENV_SHUFFLE(t0, t1, 0, 8, 1, 9, 4, 12, 5, 13), rg23 = ENV_SHUFFLE(t2, t3, 0, 8, 1, 9, 4, 12, 5, 13);
    env_v8 b01 = ENV_SHUFFLE(t0, t1, 2, 10, 3, 11, 6, 14, 7, 15), b23 = ENV_SHUFFLE(t2, t3, 2, 10, 3, 11, 6, 14, 7, 15);
    *r = ENV_SHUFFLE(rg01, rg23, 0, 1, 8, 9, 4, 5, 12, 13);
    *g = ENV_SHUFFLE(rg01, rg23, 2, 3, 10, 11, 6, 7, 14, 15);
    *b = ENV_SHUFFLE(b01, b23, 0, 1, 8, 9, 4, 5, 12, 13);
}

/* The second pass for lane i alone: its three channels from scalar loads (unscaled). */
SMATH_INLINE void env_bilinear_lane(const float *restrict rgb, const env_taps *restrict t, int i, float *restrict r,
                                    float *restrict g, float *restrict b)
{
    const float *p00 = rgb + t->o00[i], *p01 = rgb + t->o01[i], *p10 = rgb + t->o10[i], *p11 = rgb + t->o11[i];
    const float ax = t->ax[i], ay = t->ay[i], bx = t->bx[i], by = t->by[i];
    r[i] = env_bilerp(p00[0], p01[0], p10[0], p11[0], ax, ay, bx, by);
    g[i] = env_bilerp(p00[1], p01[1], p10[1], p11[1], ax, ay, bx, by);
    b[i] = env_bilerp(p00[2], p01[2], p10[2], p11[2], ax, ay, bx, by);
}

/* The second pass: the bilinear sums (unscaled) eight lanes at a time, each texel one 16-byte
 * load and the eight lanes' texels transposed into R, G, B vectors, so the sums run across
 * lanes as in a lane loop, in the same operations per channel as env_bilinear_lane. A group
 * with a lane whose texels include the image's last one (a 16-byte load would read past the
 * end) and the lanes after the last whole group go lane by lane. */
SMATH_INLINE void env_bilinear(const float *restrict rgb, const env_taps *restrict t, int n, float *restrict r,
                               float *restrict g, float *restrict b)
{
    int i = 0;
    for (; i + 8 <= n; i += 8) {
        int wide = 1;
        for (int l = 0; l < 8; l++)
            wide &= t->wide[i + l];
        if (!wide) {
            for (int j = i; j < i + 8; j++)
                env_bilinear_lane(rgb, t, j, r, g, b);
            continue;
        }
        env_v8 r00, g00, b00, r01, g01, b01, r10, g10, b10, r11, g11, b11;
        env_texel_x8(rgb, t->o00 + i, &r00, &g00, &b00);
        env_texel_x8(rgb, t->o01 + i, &r01, &g01, &b01);
        env_texel_x8(rgb, t->o10 + i, &r10, &g10, &b10);
        env_texel_x8(rgb, t->o11 + i, &r11, &g11, &b11);
        const float *restrict ax = t->ax + i, *restrict ay = t->ay + i, *restrict bx = t->bx + i,
                              *restrict by = t->by + i;
        /* Eight lanes of a fixed count: one vector per operation. */
#pragma omp simd
        for (int l = 0; l < 8; l++) {
            r[i + l] = env_bilerp(r00[l], r01[l], r10[l], r11[l], ax[l], ay[l], bx[l], by[l]);
            g[i + l] = env_bilerp(g00[l], g01[l], g10[l], g11[l], ax[l], ay[l], bx[l], by[l]);
            b[i + l] = env_bilerp(b00[l], b01[l], b10[l], b11[l], ax[l], ay[l], bx[l], by[l]);
        }
    }
    for (; i < n; i++)
        env_bilinear_lane(rgb, t, i, r, g, b);
}

/* The first pass for an equirectangular image: asin(y) of the unit direction is taken as
 * atan2(y, sqrt(x^2 + z^2)), which needs no normalisation, and every index is kept inside the
 * image by selects, so no lane can read out of bounds whatever its input. */
SMATH_INLINE void env_image_taps(int w, int h, int n_floats, int n, const float *restrict dx, const float *restrict dy,
                                 const float *restrict dz, env_taps *restrict t)
{
    const float fw = (float)w, fh = (float)h;
#pragma omp simd
    for (int i = 0; i < n; i++) {
        float x = dx[i], y = dy[i], z = dz[i];
        t->zero[i] = (x == 0.0f) & (y == 0.0f) & (z == 0.0f);
        float u = 0.5f + smath_atan2(z, x) * (0.5f / FORMULA_PI_F);
        float v = 0.5f + smath_atan2(y, sqrtf(x * x + z * z)) * (1.0f / FORMULA_PI_F);
        float fx = u * fw - 0.5f, fy = (1.0f - v) * fh - 0.5f;
        /* fx, fy >= -0.5: truncating fx + 1 is floor(fx) + 1 without a libm floorf. */
        int x0 = (int)(fx + 1.0f) - 1, y0 = (int)(fy + 1.0f) - 1;
        float ax = fx - (float)x0, ay = fy - (float)y0;
        t->ax[i] = ax;
        t->ay[i] = ay;
        t->bx[i] = 1.0f - ax;
        t->by[i] = 1.0f - ay;
        x0 = x0 < 0 ? x0 + w : (x0 >= w ? x0 - w : x0);
        x0 = ((x0 >= 0) & (x0 < w)) ? x0 : 0;
        int x1 = x0 + 1 >= w ? 0 : x0 + 1;
        int y1 = y0 + 1;
        y0 = y0 < 0 ? 0 : (y0 >= h ? h - 1 : y0);
        y1 = y1 < 0 ? 0 : (y1 >= h ? h - 1 : y1);
        t->o00[i] = 3 * (y0 * w + x0);
        t->o01[i] = 3 * (y0 * w + x1);
        t->o10[i] = 3 * (y1 * w + x0);
        t->o11[i] = 3 * (y1 * w + x1);
        /* Rows y0 <= y1: o10 and o11 are the largest offsets. */
        t->wide[i] = (t->o10[i] + 4 <= n_floats) & (t->o11[i] + 4 <= n_floats);
    }
}

/* The first pass for a cube map of n_floats floats (six faces of w x w texels): env_cube_tap
 * per lane, so that the cube goes through env_bilinear as the image does. Reading the texels
 * in the lane loop itself kept it scalar (twelve gathers a lane, which GCC 12 does not form). */
SMATH_INLINE void env_cube_taps(int w, int n_floats, int n, const float *restrict dx, const float *restrict dy,
                                const float *restrict dz, env_taps *restrict t)
{
#pragma omp simd
    for (int i = 0; i < n; i++) {
        float x = dx[i], y = dy[i], z = dz[i];
        t->zero[i] = (x == 0.0f) & (y == 0.0f) & (z == 0.0f);
        const env_tap p = env_cube_tap(w, x, y, z);
        t->o00[i] = p.o00;
        t->o01[i] = p.o01;
        t->o10[i] = p.o10;
        t->o11[i] = p.o11;
        t->ax[i] = p.ax;
        t->ay[i] = p.ay;
        t->bx[i] = 1.0f - p.ax;
        t->by[i] = 1.0f - p.ay;
        /* Rows y0 <= y1 within a face: o10 and o11 are the largest offsets. */
        t->wide[i] = (p.o10 + 4 <= n_floats) & (p.o11 + 4 <= n_floats);
    }
}

/* env_lookup_n's chunks for an image or a cube map: the first pass of the map's kind, then
 * env_bilinear, then the scale. cube is a constant at each call, so that each kind has its own
 * loop: with the kind tested in one loop the image lookups of the bench frame took 1.0 % more
 * instructions than before the cube joined them (callgrind, AVX2 clone), with a loop each
 * 0.7 % (how GCC allocates registers around smath_atan2; CPU time did not change). */
SMATH_INLINE void env_lookup_chunks(const env_map *e, int n, const float *restrict dx, const float *restrict dy,
                                    const float *restrict dz, float *restrict r, float *restrict g, float *restrict b,
                                    const int cube)
{
    const int w = e->width, h = e->height;
    const float *restrict rgb = e->rgb;
    const vec3 scale = e->scale;
    const int n_floats = 3 * w * h * (cube ? 6 : 1);
    env_taps t;
    for (int i0 = 0; i0 < n; i0 += ENV_CHUNK) {
        const int m = n - i0 < ENV_CHUNK ? n - i0 : ENV_CHUNK;
        float *restrict cr = r + i0, *restrict cg = g + i0, *restrict cb = b + i0;
        if (cube)
            env_cube_taps(w, n_floats, m, dx + i0, dy + i0, dz + i0, &t);
        else
            env_image_taps(w, h, n_floats, m, dx + i0, dy + i0, dz + i0, &t);
        env_bilinear(rgb, &t, m, cr, cg, cb);
        /* The scale (or 0 for a zero direction) as its own product after the sum, as in
         * env_lookup: the zero select is on the factor, so it cannot hide the texel reads. */
#pragma omp simd
        for (int i = 0; i < m; i++) {
            vec3 k = t.zero[i] ? v3s(0.0f) : scale;
            cr[i] *= k.x;
            cg[i] *= k.y;
            cb[i] *= k.z;
        }
    }
}

/* The same lookup as env_lookup with one lane per direction, in two passes per chunk: the
 * texel offsets and weights vectorised across lanes (no loads), then the texel reads lane by
 * lane, R, G, B together. A lane loop reading the texels itself needs twelve gathers a lane,
 * which GCC emulates with scalar loads and inserts; that was most of this function's time. */
SMATH_CLONES
void env_lookup_n(const env_map *e, int n, const float *restrict dx, const float *restrict dy, const float *restrict dz,
                  float *restrict r, float *restrict g, float *restrict b)
{
    if (e == NULL || e->kind == ENV_NONE || e->kind == ENV_CONSTANT || e->rgb == NULL || e->width <= 0 ||
        e->height <= 0) {
        vec3 c = e != NULL && e->kind == ENV_CONSTANT ? e->constant : v3s(0.0f);
        /* Without the pragma GCC 12 -O2 leaves this loop of unknown count scalar. */
#pragma omp simd
        for (int i = 0; i < n; i++) {
            int zero = (dx[i] == 0.0f) & (dy[i] == 0.0f) & (dz[i] == 0.0f);
            r[i] = zero ? 0.0f : c.x;
            g[i] = zero ? 0.0f : c.y;
            b[i] = zero ? 0.0f : c.z;
        }
        return;
    }
    if (e->kind == ENV_CUBE)
        env_lookup_chunks(e, n, dx, dy, dz, r, g, b, 1);
    else
        env_lookup_chunks(e, n, dx, dy, dz, r, g, b, 0);
}

/* Rec. 709 luminance of a texel, the image scale applied. */
static double env_luminance(const float *p, vec3 scale)
{
    return 0.2126 * p[0] * scale.x + 0.7152 * p[1] * scale.y + 0.0722 * p[2] * scale.z;
}

rc_status env_extract_sun(float *rgb, int width, int height, vec3 scale, float lum_min, env_sun *out)
{
    memset(out, 0, sizeof *out);
    size_t n = (size_t)width * (size_t)height, peak = 0;
    double best = -1.0;
    for (size_t i = 0; i < n; i++) {
        double y = env_luminance(rgb + 3 * i, scale);
        if (y > best) {
            best = y;
            peak = i;
        }
    }
    if (!(best > lum_min))
        return RC_ERR_RANGE;
    /* 1: in the sun, 2: bordering it. */
    unsigned char *mark = calloc(n, 1);
    size_t *queue = malloc(n * sizeof *queue);
    if (mark == NULL || queue == NULL) {
        free(mark);
        free(queue);
        return RC_ERR_NOMEM;
    }
    size_t head = 0, tail = 0;
    mark[peak] = 1;
    queue[tail++] = peak;
    dvec3 border = dv3(0, 0, 0);
    long n_border = 0;
    while (head < tail) {
        size_t i = queue[head++];
        int x = (int)(i % (size_t)width), y = (int)(i / (size_t)width);
        for (int dy = -1; dy <= 1; dy++)
            for (int dx = -1; dx <= 1; dx++) {
                int yy = y + dy, xx = (x + dx + width) % width;
                if ((dx == 0 && dy == 0) || yy < 0 || yy >= height)
                    continue;
                size_t k = (size_t)yy * (size_t)width + (size_t)xx;
                if (mark[k])
                    continue;
                const float *p = rgb + 3 * k;
                if (env_luminance(p, scale) > lum_min) {
                    mark[k] = 1;
                    queue[tail++] = k;
                } else {
                    mark[k] = 2;
                    border = dv3_add(border, dv3(p[0], p[1], p[2]));
                    n_border++;
                }
            }
    }
    /* A region with no border is the whole image: nothing is left around it. */
    dvec3 fill = n_border > 0 ? dv3_scale(border, 1.0 / (double)n_border) : dv3(0, 0, 0);
    dvec3 e = dv3(0, 0, 0), dir = dv3(0, 0, 0);
    double omega = 0.0;
    const double pi = FORMULA_PI_D, dphi = 2.0 * pi / width;
    for (size_t q = 0; q < tail; q++) {
        size_t i = queue[q];
        int x = (int)(i % (size_t)width), y = (int)(i / (size_t)width);
        /* Row y spans latitudes pi (0.5 - (y + 1)/H) .. pi (0.5 - y/H); u = (x + 0.5)/W is
         * atan2(z, x)/(2 pi) + 0.5 (env.h). */
        double lat_top = pi * (0.5 - (double)y / height), lat_bot = pi * (0.5 - (double)(y + 1) / height);
        double d_omega = dphi * (sin(lat_top) - sin(lat_bot));
        double lat = pi * (0.5 - ((double)y + 0.5) / height), phi = 2.0 * pi * (((double)x + 0.5) / width - 0.5);
        float *p = rgb + 3 * i;
        dvec3 moved = dv3(p[0] - fmin(fill.x, p[0]), p[1] - fmin(fill.y, p[1]), p[2] - fmin(fill.z, p[2]));
        p[0] = (float)fmin(fill.x, p[0]);
        p[1] = (float)fmin(fill.y, p[1]);
        p[2] = (float)fmin(fill.z, p[2]);
        dvec3 scaled = dv3_mul(moved, dv3_from(scale));
        e = dv3_add(e, dv3_scale(scaled, d_omega));
        double w = (0.2126 * scaled.x + 0.7152 * scaled.y + 0.0722 * scaled.z) * d_omega;
        dir = dv3_add(dir, dv3_scale(dv3(cos(lat) * cos(phi), sin(lat), cos(lat) * sin(phi)), w));
        omega += d_omega;
    }
    out->direction = v3_from_d(dv3_norm(dir));
    out->irradiance = v3_from_d(e);
    out->solid_angle = omega;
    out->n_texels = (int)tail;
    out->peak = (float)best;
    out->fill = v3_from_d(fill);
    free(mark);
    free(queue);
    return RC_OK;
}
