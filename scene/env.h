/* env.h - environment radiance: a constant, an equirectangular image or a Direct3D cube map,
 * with bilinear lookup.
 *
 * Usage:
 *   env_map e = {.kind = ENV_IMAGE, .width = W, .height = H, .rgb = pixels, .scale = v3s(1)};
 *   env_map c = {.kind = ENV_CUBE, .width = N, .height = N, .rgb = faces, .scale = v3s(1)};
 *   vec3 L = env_lookup(&e, dir);     dir: any non-zero canonical direction (normalised inside)
 *   env_texel_check chk;
 *   if (env_check(&e, &chk) != RC_OK) ...  chk.n_nonfinite, chk.n_negative, chk.first_nonfinite.x ...
 * Orientation (docs/conventions.md, verified against POV-Ray and Cycles): direction (x, y, z) maps to
 * u = 0.5 + atan2(z, x)/(2 pi) (to the right) and v = 0.5 + asin(y)/pi (up; image row 0 is the
 * top); texel centres at (i + 0.5)/W, bilinear, wrapping in u and clamping in v.
 * rgb is interleaved R, G, B floats, row 0 at the top; the map does not own it.
 * Cube maps (ENV_CUBE): six square N x N faces one after the other in rgb, in D3DCUBEMAP_FACES
 * order (+X, -X, +Y, -Y, +Z, -Z), each row 0 at the top (texture v = 0). Our canonical frame is
 * right-handed with +Y up, Direct3D's left-handed with +Y up: a canonical direction (x, y, z) is
 * the D3D direction (X, Y, Z) = (x, y, -z) (the usual right- to left-handed change, which
 * D3DXMatrixLookAtRH vs LH also makes), so the +Z face is what a camera looking down canonical -z
 * sees, +x to its right. The face is the D3D major axis (largest |X|, |Y|, |Z|; ties go to X,
 * then Y), and on it, from the D3DCUBEMAP_FACES table (sc, tc, ma):
 *   +X: -Z, -Y, X   -X: +Z, -Y, X   +Y: +X, +Z, Y   -Y: +X, -Z, Y   +Z: +X, -Y, Z   -Z: -X, -Y, Z
 * s = (sc/|ma| + 1)/2 to the right, t = (tc/|ma| + 1)/2 down; texel centres at (i + 0.5)/N;
 * bilinear within the face, clamped at its edge (D3DTADDRESS_CLAMP, D3D9 without seamless cube
 * filtering): the last half texel of a face repeats its edge texel, so radiance jumps at the
 * seams between faces. That seam is part of the approximation being judged, not smoothed away.
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
    int face;          /* cube face (D3DCUBEMAP_FACES order, y within it); -1 for other maps */
    float value;
} env_texel;

typedef struct {
    long n_nonfinite;          /* texel values that are NaN or +-Inf */
    long n_negative;           /* finite values below 0 */
    env_texel first_nonfinite; /* in row-major, then R, G, B order */
    env_texel first_negative;
} env_texel_check;

/* Counts the non-finite and negative values of an ENV_IMAGE or ENV_CUBE map's texels into out. Returns
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
/* The sun of an environment image moved into a directional light (env_extract_sun). */
typedef struct {
    vec3 direction;     /* unit, from the scene toward the sun */
    vec3 irradiance;    /* E [W/m^2] at normal incidence, the image scale applied */
    double solid_angle; /* of the texels it took [sr] */
    int n_texels;
    float peak; /* the brightest texel's luminance (scale applied) */
    vec3 fill;  /* the radiance left in its texels (unscaled): the mean of the texels around it */
} env_sun;

/* Finds the sun of an equirectangular image (interleaved RGB, row 0 at the top, the map's
 * orientation) and moves it into a directional light, as engines split an HDR sky: the sun is
 * the 8-connected region (wrapping in u) of texels whose luminance (Rec. 709, times scale) is
 * above lum_min, grown from the brightest texel. Each of its texels keeps the mean of the
 * texels bordering the region (per channel, never more than its own value); what it gives up,
 * sum of (L - fill) dOmega over the region with each texel's exact solid angle
 * (2 pi / W)(sin lat_top - sin lat_bottom), is the light's irradiance at normal incidence, and
 * its direction is the luminance-weighted mean of the texel centres' directions. So the texel
 * sums of remainder + sun equal the image's: energy is conserved; the sun becomes a point on
 * the sky (a surface facing it receives sum L dOmega, not sum L cos dOmega: 1 - cos of the
 * region's radius, 3e-4 for 1.4 degrees). rgb is changed in place. RC_ERR_RANGE when no texel
 * is above lum_min (nothing written), RC_ERR_NOMEM. */
rc_status env_extract_sun(float *rgb, int width, int height, vec3 scale, float lum_min, env_sun *out);

/* The image coordinates (in texels, x right, y down from the top edge) of a direction. */
void env_direction_to_texel(const env_map *e, vec3 dir, float *tx, float *ty);

/* The face names of a cube map in D3DCUBEMAP_FACES order: "+X", "-X", "+Y", "-Y", "+Z", "-Z". */
extern const char *const env_cube_face_names[6];
/* The same faces as scene-file keys (environment.cube): "px", "nx", "py", "ny", "pz", "nz". */
extern const char *const env_cube_face_keys[6];
/* The face (D3DCUBEMAP_FACES order) and face coordinates s (right), t (down), both in [0, 1],
 * of a canonical direction: the one formula both lookups use. A zero or non-finite direction
 * gives a face and s, t inside [0, 1] (meaningless but never out of bounds). */
int env_cube_coords(vec3 dir, float *s, float *t);
/* The canonical unit direction through face coordinates (s, t) of a face: env_cube_coords'
 * inverse (for generators and tests). */
vec3 env_cube_direction(int face, float s, float t);
/* An ENV_CUBE map resampled as an equirectangular image (width x height, interleaved RGB, row 0
 * at the top, the ENV_IMAGE orientation above): each texel is the cube lookup in the direction
 * of the texel's centre, without the scale. An exact conversion at the texel centres; a renderer
 * that interpolates it bilinearly departs from the cube lookup between them (most at the seams),
 * by less the larger the image (docs/cubemaps.md measures it). */
void env_cube_to_equirect(const env_map *cube, int width, int height, float *rgb);

#endif
