/* env.h - environment radiance: a constant, or an equirectangular image with bilinear lookup.
 *
 * Usage:
 *   env_map e = {.kind = ENV_IMAGE, .width = W, .height = H, .rgb = pixels, .scale = v3s(1)};
 *   vec3 L = env_lookup(&e, dir);     dir: any non-zero canonical direction (normalised inside)
 * Orientation (CONVENTIONS.md, verified against POV-Ray and Cycles): direction (x, y, z) maps to
 * u = 0.5 + atan2(z, x)/(2 pi) (to the right) and v = 0.5 + asin(y)/pi (up; image row 0 is the
 * top); texel centres at (i + 0.5)/W, bilinear, wrapping in u and clamping in v.
 * rgb is interleaved R, G, B floats, row 0 at the top; the map does not own it.
 * ENV_NONE gives zero radiance; a zero direction gives zero radiance.
 */
#ifndef REFLCHECK_ENV_H
#define REFLCHECK_ENV_H

#include "scene.h"

typedef struct {
    env_kind kind;
    vec3 constant;       /* ENV_CONSTANT radiance */
    vec3 scale;          /* ENV_IMAGE multiplier */
    int width, height;
    const float *rgb;
} env_map;

vec3 env_lookup(const env_map *e, vec3 dir);
/* env_lookup for n directions at once, structure of arrays (dx[i], dy[i], dz[i] -> r[i],
 * g[i], b[i]); vectorised through smath_atan2, so the result differs from env_lookup's by
 * under 1e-6 of a texel step (tests/test_shade_batch.c). Directions need not be unit (lengths
 * 1e-15 to 1e15: beyond, squares leave float's range, as in env_lookup); a zero one gives 0. */
void env_lookup_n(const env_map *e, int n, const float *dx, const float *dy, const float *dz,
                  float *r, float *g, float *b);
/* The image coordinates (in texels, x right, y down from the top edge) of a direction. */
void env_direction_to_texel(const env_map *e, vec3 dir, float *tx, float *ty);

#endif
