/* shade.h - the reflection models evaluated at one surface point, term by term.
 *
 * Usage:
 *   shade_context c; shade_context_make(&scn, &env, &c);
 *   shade_plan p;    shade_plan_make(&c, &scn.materials[i], &p);    once per material
 *   shade_terms t;   shade_eval(&c, &p, x, n, v, &t);                 per sample
 * x is the world point, n the unit shading normal (already facing the viewer), v the unit
 * direction to the viewer; all directions point away from the surface. Terms are outgoing
 * radiance (they include every cosine), linear RGB, in the scene's radiometric units, exactly
 * as harness/CONTRACT.md and the README state. The plan picks, once, a specialised function for
 * the terms the material can produce in this scene (no specular, no environment, ... are not
 * computed at all), so the per-sample path has no branches on unused features.
 * Finite input never yields NaN or Inf.
 */
#ifndef REFLCHECK_SHADE_H
#define REFLCHECK_SHADE_H

#include "env.h"
#include "scene.h"

typedef struct { vec3 diffuse, specular, reflection, emission; float alpha; } shade_terms;

typedef struct {
    const scene *s;
    const env_map *env;
    vec3 eye;
    vec3 e_inf;       /* unit vector from the target toward the eye: D3D's infinite viewer */
} shade_context;

enum { SHADE_TERM_DIFFUSE = 1, SHADE_TERM_SPECULAR = 2, SHADE_TERM_REFLECTION = 4, SHADE_TERM_EMISSION = 8 };

typedef struct shade_plan shade_plan;
typedef void (*shade_fn)(const shade_context *c, const shade_plan *p, vec3 x, vec3 n, vec3 v, shade_terms *out);
struct shade_plan {
    const material *mat;
    unsigned terms;       /* SHADE_TERM_* this material can make non-zero here */
    shade_fn fn;
    const char *path;     /* the specialised path's name, for reports and benchmarks */
};

void shade_context_make(const scene *s, const env_map *env, shade_context *c);
void shade_plan_make(const shade_context *c, const material *m, shade_plan *p);
/* The general path: every term computed, whatever the material uses. Same results as the
 * specialised plan; kept for the specialisation benchmark and its equality test. */
void shade_plan_make_general(const shade_context *c, const material *m, shade_plan *p);

static inline void shade_eval(const shade_context *c, const shade_plan *p, vec3 x, vec3 n, vec3 v, shade_terms *out)
{
    p->fn(c, p, x, n, v, out);
}

/* Incident light i at x: unit direction to the light and the irradiance it would give at
 * normal incidence (I*A*spot for point/spot, E for a sun). Returns 0 when it gives nothing. */
int shade_light_incident(const light *l, vec3 x, vec3 *to_light, vec3 *e_perp, float *atten);

#endif
