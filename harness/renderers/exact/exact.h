/* exact.h - the deterministic exact reference: the scene's physics through our own pipeline,
 * a renderer of the table (registry.h).
 *
 * Usage:
 *   renderer_job j = {.s = &scn, .m = &msh, .env = &env, .role = ROLE_VALIDATE, .exr = "out.exr"};
 *   renderer_result r = {0};
 *   exact_render_job(&j, &r);          r.status RUNNER_OK, or RUNNER_MISSING with what it cannot
 *   exact_options o = {.physics = scn.physics, .set = 1};  o.physics.fresnel_specular = PHYS_FRESNEL_NV;
 *   j.options = &o;                    tests: another physics than the scene's manifest
 *   exact_options p = {.point = 1};    the point-sampled variant (below)
 * It renders the scene's physics manifest (scene.physics): every material is replaced by the
 * physical BRDF (render/physical.h) and rendered by the rasterizer (render/render.h), in double
 * precision per sample, as a pixel integral: K x K box-filtered samples (exact_supersample:
 * 16 x 16 for every scene supersample k < 16) at positions none of which is one of the
 * rasterizer's own k x k, so raster-vs-exact holds the rasterizer's sampling error too (of a
 * highlight, a texture, a shading-normal crease smaller than its samples resolve), not only the
 * shading's. Its own integration error is that of K x K samples, (k/K)^2 of the rasterizer's
 * where an edge or a highlight crosses a pixel. With .point = 1 it samples at the rasterizer's
 * own k x k positions instead: the point-sampled variant, which answers the narrower question
 * "how far is the shading alone from the physics, sample for sample" (sampling error cancels).
 * Noise-free either way; the var.* layers hold the spread of the samples inside each pixel, as
 * the rasterizer writes them. Geometry and interpolation are float, shading double. A twin has no meaning for a
 * physical reference (it is refused, RUNNER_MISSING); so are scenes whose physics needs an integral (a rough lobe under
 * an environment, an environment image on the diffuse): the message says which material and why.
 */
#ifndef REFLCHECK_EXACT_H
#define REFLCHECK_EXACT_H

#include "../renderer.h"
#include "physical.h"

typedef struct {
    physics physics; /* used when set */
    int set;         /* 0 = the scene's manifest (scene.physics) */
    int point;       /* 0 = the pixel integral (exact_supersample); 1 = the rasterizer's own samples */
} exact_options;

/* exact's samples per pixel side for a scene of supersample k (K x K, see above). */
#define EXACT_SUPERSAMPLE 16
int exact_supersample(int k);

void exact_render_job(const renderer_job *j, renderer_result *r);
/* The table's `exact_point`: exact_render_job with .point = 1, the rasterizer's own samples. */
void exact_point_render_job(const renderer_job *j, renderer_result *r);
/* The physics exact renders for s (renderer.h renderer_physics_fn): s->physics itself, or
 * RC_ERR_RANGE with what it cannot (shadows, inter-reflection, bounces > 1, a rough lobe
 * reflecting the environment, an environment image on the diffuse). */
rc_status exact_physics(const scene *s, physics *rendered, char *err, size_t errlen);

/* A thin sheet (material.thin, a window pane) is drawn blended (render/render.h) with
 *   alpha = exact_thin_sheet_reflectance(N.V, ior),   colour = the environment along reflect(-V, N)
 * so that the pixel is R_sheet phi + (1 - R_sheet) behind: a lossless sheet transmits what it does
 * not reflect, straight through (the sideways shift of a thin sheet is taken as 0).
 * R_sheet per polarisation x (s, p) sums the light reflected by the front face and, between the
 * faces, every odd number of internal reflections (the inner face reflects R_x too, Stokes):
 *   R_x + T_x^2 R_x (1 + R_x^2 + R_x^4 + ...) = R_x + (1 - R_x)^2 R_x / (1 - R_x^2) = 2 R_x / (1 + R_x)
 * averaged over s and p for unpolarised light; cos_i clamped to [0, 1]. */
double exact_thin_sheet_reflectance(double cos_i, double eta);
/* The same with the unpolarised interface reflectance F = (R_s + R_p)/2 in place of each R_x:
 * 2F/(1 + F), what a path tracer that carries no polarisation computes (Cycles). */
double exact_thin_sheet_reflectance_unpolarised(double cos_i, double eta);

#endif
