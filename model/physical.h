/* physical.h - the physical BRDF as a material model of the shading loop: what the exact
 * reference renderer (harness/renderers/exact/) shades in place of every scene model.
 *
 * Usage:
 *   physical_options o = {0};                           zero = the defaults below
 *   shade_context c;  shade_context_make(&scn, &env, &c);
 *   shade_plan p;
 *   if (physical_plan_make(&c, &scn.materials[i], &o, &p, why, sizeof why) != RC_OK) ...   why: what it cannot
 *   render_options ro = {.plans = plans};               one plan per object (model/render.h)
 * Per sample, in double precision on the scalar path (shade_eval; the batch form calls it lane
 * by lane), from the material's physical intent (albedo, ior or conductor eta + ik, roughness m):
 *   diffuse   Lambert albedo/pi (a conductor has none unless conductor_diffuse), times the
 *             diffuse rule's weight, lit by every point, spot and sun light (E N.L), and with
 *             env_diffuse by a constant environment (albedo L: its unoccluded cosine-weighted
 *             irradiance is pi L);
 *   specular  m > 0: F D G / (4 N.V) times E, Beckmann D (walter normalisation), the separable
 *             Smith G with the exact Beckmann G1 (erf), F per lobe_fresnel (default: the exact
 *             dielectric or conductor Fresnel of V.H, per microfacet); m = 0 is a mirror, whose
 *             delta lobe gives a point, spot or sun light zero measure: nothing;
 *   reflection m = 0: the environment along reflect(-V, N) times the exact Fresnel of N.V;
 *   emission  the material's emissive colour.
 * No shadows and no inter-reflection, as every reference of the project. Geometry, the
 * interpolated normal and the environment lookup are float (the rasterizer's); the viewer and
 * light directions, distances, spot profile, D, G, F and the sums are double; terms are
 * returned as float (saturated to the float range), averaged over the k x k samples in float.
 * What needs an integral (a rough lobe lit by an environment; an environment image on the
 * diffuse) is refused by physical_plan_make with RC_ERR_RANGE and the reason in why.
 */
#ifndef REFLCHECK_PHYSICAL_H
#define REFLCHECK_PHYSICAL_H

#include <stddef.h>

#include "shade.h"
#include "status.h"

/* The Fresnel factor of a rough lobe. */
typedef enum {
    PHYSICAL_FRESNEL_VH = 0, /* exact F(V.H) per microfacet: the physics */
    PHYSICAL_FRESNEL_NV,     /* exact F(N.V) tinting the whole lobe (what Cycles' validate setup does) */
    PHYSICAL_FRESNEL_ONE     /* F = 1 (Cycles' Glossy BSDF without a Fresnel node) */
} physical_fresnel;

/* The weight of the Lambert term. */
typedef enum {
    PHYSICAL_DIFFUSE_PLAIN = 0,     /* albedo/pi, not under the coating */
    PHYSICAL_DIFFUSE_ONE_MINUS_F_NV /* albedo/pi (1 - F_dielectric(N.V)) */
} physical_diffuse;

typedef struct {
    physical_fresnel lobe_fresnel;
    physical_diffuse diffuse;
    int conductor_diffuse; /* 1: a conductor keeps its albedo as a Lambert term; 0 (default): none */
    int env_diffuse;       /* 1: the environment lights the diffuse too; 0 (default): only the lights */
} physical_options;

/* The physical model's plan for material m: p->fn is the double-precision path, p->batch runs
 * it lane by lane, p->params points at o (which must outlive the plan). RC_ERR_RANGE, with
 * why naming the material and what would need an integral, for a rough lobe (m > 0) under
 * an environment, or (env_diffuse) an environment image lighting a non-zero diffuse. */
rc_status physical_plan_make(const shade_context *c, const material *m, const physical_options *o, shade_plan *p,
                             char *why, size_t whylen);

/* Incident light in double: the unit direction from x to the light and the irradiance it gives
 * at normal incidence there (I A spot / d^2 is folded into A for point and spot: D3D's
 * attenuation 1/(a0 + a1 d + a2 d^2), the spot profile). Returns 0 when it gives nothing. */
int physical_light_incident(const light *l, dvec3 x, dvec3 *to_light, dvec3 *e_perp);

/* The rough lobe, one channel set, for unit n, v, l: F D G / (4 N.V) (INCLUDES N.L), with F per
 * o->lobe_fresnel for material mat. 0 when N.L or N.V <= 0 or m <= 0. */
dvec3 physical_lobe(const material *mat, const physical_options *o, dvec3 n, dvec3 v, dvec3 l);

/* The exact Fresnel reflectance of mat at cosine c, per channel. */
dvec3 physical_fresnel_exact(const material *mat, double c);

#endif
