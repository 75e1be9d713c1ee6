/* exact.h - the deterministic exact reference: the scene's physics through our own pipeline,
 * a renderer of the table (registry.h).
 *
 * Usage:
 *   renderer_job j = {.s = &scn, .m = &msh, .env = &env, .role = ROLE_VALIDATE, .exr = "out.exr"};
 *   renderer_result r = {0};
 *   exact_render_job(&j, &r);          r.status RUNNER_OK, or RUNNER_MISSING with what it cannot
 *   exact_options o = {.physics = scn.physics, .set = 1};  o.physics.fresnel_specular = PHYS_FRESNEL_NV;
 *   j.options = &o;                    tests: another physics than the scene's manifest
 * It renders the scene's physics manifest (scene.physics): every material is replaced by the
 * physical BRDF (model/physical.h) and rendered by the
 * rasterizer (model/render.h) with the scene's k x k box-filtered samples, in double precision
 * per sample: noise-free, no variance but that of the k x k samples inside each pixel (the
 * var.* layers, as the rasterizer writes them). Geometry and interpolation are float, shading
 * double. A twin has no meaning for a physical reference (it is refused, RUNNER_MISSING); so
 * are scenes whose physics needs an integral (a rough lobe under an environment, an
 * environment image on the diffuse): the message says which material and why.
 */
#ifndef REFLCHECK_EXACT_H
#define REFLCHECK_EXACT_H

#include "../renderer.h"
#include "physical.h"

typedef struct {
    physics physics; /* used when set */
    int set;         /* 0 = the scene's manifest (scene.physics) */
} exact_options;

void exact_render_job(const renderer_job *j, renderer_result *r);
/* The physics exact renders for s (renderer.h renderer_physics_fn): s->physics itself, or
 * RC_ERR_RANGE with what it cannot (shadows, inter-reflection, bounces > 1, a rough lobe
 * reflecting the environment, an environment image on the diffuse). */
rc_status exact_physics(const scene *s, physics *rendered, char *err, size_t errlen);

#endif
