/* physical.h - the physical BRDF as a material model of the shading loop: what the exact
 * reference renderer (harness/renderers/exact/) shades in place of every scene model.
 *
 * Usage:
 *   shade_context c;  shade_context_make(&scn, &env, &c);
 *   shade_plan p;
 *   if (physical_plan_make(&c, &scn.materials[i], &scn.physics, &p, why, sizeof why) != RC_OK) ...
 *   render_options ro = {.plans = plans};               one plan per object (render/render.h)
 * It renders the physics manifest (model/scene.h, `physics`) from the material's physical intent
 * (albedo, ior or conductor eta + ik, roughness m), per sample, in double precision on the
 * scalar path (shade_eval; the batch form calls it lane by lane):
 *   diffuse   Lambert albedo/pi (conductors have none) times the manifest's diffuse_weight, lit
 *             by the point, spot and sun lights of diffuse_lights (E N.L) and, with env_diffuse,
 *             by a constant environment (albedo L: its unoccluded cosine-weighted irradiance is
 *             pi L);
 *   specular  m > 0: F D G / (4 N.V) times E for the lights of specular_lights: Beckmann D
 *             (walter normalisation), the separable Smith G with the exact Beckmann G1 (erf);
 *             with the material's distribution ggx, GGX D of alpha = roughness and the separable
 *             Smith G with the exact GGX G1 (Cycles 3.4's Glossy GGX, model/microfacet.h);
 *             F of fresnel_specular (exact: the dielectric or conductor Fresnel of V.H per
 *             microfacet; nv: of N.V for the whole lobe; one; schlick of V.H with F0 the exact
 *             F at normal incidence). m = 0 is a mirror, whose delta lobe gives a point, spot or
 *             sun light zero measure: nothing;
 *   reflection m = 0 with env_specular: the environment along reflect(-V, N) times F of
 *             fresnel_reflection at N.V;
 *   emission  the material's emissive colour.
 * A material with lobe 0 (a d3d material with no specular and no roughness written) has neither
 * specular nor reflection: only its diffuse and emission.
 * No shadows, no inter-reflection, one bounce. Geometry, the interpolated normal and the
 * environment lookup are float (the rasterizer's); the viewer and light directions, distances,
 * spot profile, D, G, F and the sums are double; terms are returned as float (saturated to the
 * float range) and averaged over the k x k samples in float.
 * What needs an integral (a rough lobe reflecting an environment; an environment image on the
 * diffuse) or another light transport (shadows, inter-reflection, bounces > 1) is refused by
 * physical_plan_make with RC_ERR_RANGE and the reason in why; so is a specular texture (it
 * scales an approximation's lobe). A diffuse texture multiplies the albedo.
 */
#ifndef REFLCHECK_PHYSICAL_H
#define REFLCHECK_PHYSICAL_H

#include <stddef.h>

#include "shade.h"
#include "status.h"

/* The physical model's plan for material m under the manifest ph: p->fn is the double-precision
 * path, p->batch runs it lane by lane, p->params points at ph (which must outlive the plan).
 * RC_ERR_RANGE, with why naming the material or manifest key and what it would need, for
 * shadows, inter-reflection or bounces > 1, a rough lobe (m > 0) reflecting an environment, or
 * (env_diffuse) an environment image lighting a non-zero diffuse, or a specular texture map. */
rc_status physical_plan_make(const shade_context *c, const material *m, const physics *ph, shade_plan *p, char *why,
                             size_t whylen);

/* Incident light in double: the unit direction from x to the light and the irradiance it gives
 * at normal incidence there (I A spot / d^2 is folded into A for point and spot: D3D's
 * attenuation 1/(a0 + a1 d + a2 d^2), the spot profile). Returns 0 when it gives nothing. */
int physical_light_incident(const light *l, dvec3 x, dvec3 *to_light, dvec3 *e_perp);

/* The rough lobe per channel for unit n, v, l: F D G / (4 N.V) (INCLUDES N.L), with F of form f
 * for material mat. 0 when N.L or N.V <= 0, m <= 0 or the material has no lobe. */
dvec3 physical_lobe(const material *mat, physics_fresnel f, dvec3 n, dvec3 v, dvec3 l);

/* The Fresnel factor of form f at cosine c (V.H or N.V) per channel. */
dvec3 physical_fresnel(const material *mat, physics_fresnel f, double c);

/* The exact Fresnel reflectance of mat at cosine c, per channel. */
dvec3 physical_fresnel_exact(const material *mat, double c);

#endif
