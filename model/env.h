/* env.h - environment radiance: a constant, or an equirectangular image with bilinear lookup.
 *
 * Usage:
 *   env_map e = {.kind = ENV_IMAGE, .width = W, .height = H, .rgb = pixels, .scale = v3s(1)};
 *   vec3 L = env_lookup(&e, dir);     dir: any non-zero canonical direction (normalised inside)
 *   env_texel_check chk;
 *   if (env_check(&e, &chk) != RC_OK) ...  chk.n_nonfinite, chk.n_negative, chk.first_nonfinite.x ...
 * Orientation (CONVENTIONS.md, verified against POV-Ray and Cycles): direction (x, y, z) maps to
 * u = 0.5 + atan2(z, x)/(2 pi) (to the right) and v = 0.5 + asin(y)/pi (up; image row 0 is the
 * top); texel centres at (i + 0.5)/W, bilinear, wrapping in u and clamping in v.
 * rgb is interleaved R, G, B floats, row 0 at the top; the map does not own it.
 * ENV_NONE gives zero radiance; a zero direction gives zero radiance.
 * Radiance is finite and >= 0: a NaN, Inf or negative texel would spread through the bilinear
 * lookup into every pixel that reflects it, so images are checked once with env_check before
 * rendering (harness/frame.c refuses them); the lookups themselves do not test texels.
 */
#ifndef REFLCHECK_ENV_H
#define REFLCHECK_ENV_H

#include "scene.h"
#include "status.h"

typedef struct {
    env_kind kind;
    vec3 constant; /* ENV_CONSTANT radiance */
    vec3 scale;    /* ENV_IMAGE multiplier */
    int width, height;
    const float *rgb;
} env_map;

typedef struct {
    int x, y, channel; /* texel column, row (0 at the top), channel (0 R, 1 G, 2 B); -1 if none */
    float value;
} env_texel;

typedef struct {
    long n_nonfinite;          /* texel values that are NaN or +-Inf */
    long n_negative;           /* finite values below 0 */
    env_texel first_nonfinite; /* in row-major, then R, G, B order */
    env_texel first_negative;
} env_texel_check;

/* Counts the non-finite and negative values of an ENV_IMAGE map's texels into out. Returns
 * RC_OK when there are none (and for ENV_NONE and ENV_CONSTANT, whose radiance the scene
 * parser has checked), RC_ERR_RANGE otherwise. */
rc_status env_check(const env_map *e, env_texel_check *out);

vec3 env_lookup(const env_map *e, vec3 dir);
/* env_lookup for n directions at once, structure of arrays (dx[i], dy[i], dz[i] -> r[i],
 * g[i], b[i]); vectorised through smath_atan2, so the result differs from env_lookup's by
 * under 1e-6 of a texel step (tests/test_shade_batch.c). Directions need not be unit (lengths
 * 1e-15 to 1e15: beyond, squares leave float's range, as in env_lookup); a zero one gives 0. */
void env_lookup_n(const env_map *e, int n, const float *dx, const float *dy, const float *dz, float *r, float *g,
                  float *b);
/* The image coordinates (in texels, x right, y down from the top edge) of a direction. */
void env_direction_to_texel(const env_map *e, vec3 dir, float *tx, float *ty);

#endif
