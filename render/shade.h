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
 * shade_eval_n is the shading loop's form: the same models over a structure-of-arrays batch,
 * one SIMD lane per sample (shade_batch_*.c), with smath's pow and atan2 in place of libm's and
 * float where the scalar path sums in double. Lanes agree with shade_eval to 1.3e-5 relative
 * for Blinn powers up to 40 (1.2e-3 over tests/test_shade_batch.c's 1024 lanes at a power of 1e4,
 * 2.4e-3 over 4096: the power multiplies the 2-ulp N.H difference of the scalar path's
 * renormalised half vector), and near a soft spot edge to
 * 5e-7 of the term's largest value (tests/test_shade_batch.c). Lanes outside the
 * kernels' safe range (a point light within 1e-15 m or beyond 1e15 m) and materials without a
 * kernel (see shade_batch_ct_supported) go through shade_eval lane by lane.
 */
#ifndef REFLCHECK_SHADE_H
#define REFLCHECK_SHADE_H

#include "env.h"
#include "scene.h"
#include "texture.h"

typedef struct {
    vec3 diffuse, specular, reflection, emission;
    float alpha;
} shade_terms;

typedef struct {
    const scene *s;
    const env_map *env;
    vec3 eye;
    vec3 e_inf;             /* unit vector from the target toward the eye: D3D's infinite viewer */
    const texture_set *tex; /* the materials' textures; NULL (shade_context_make's default) = none */
} shade_context;

enum { SHADE_TERM_DIFFUSE = 1, SHADE_TERM_SPECULAR = 2, SHADE_TERM_REFLECTION = 4, SHADE_TERM_EMISSION = 8 };

/* Samples per batch: enough lanes to amortise each flush's fixed cost (the per-light set-up,
 * every lane loop's entry and exit, the render queue's interpolation and scatter calls), few
 * enough that a batch's inputs and outputs (22 floats a lane, 22.5 KiB) stay in a 32 KiB L1
 * cache. Measured on the bench frame (10^4 triangles, one thread, CPU ms): 64 lanes 385-389,
 * 128 370-373, 256 357-362, 512 364-370 (docs/render_time.md). At most 256: render.c's queue
 * keeps a lane's index in a uint8_t (render_queue.centre). */
#define SHADE_BATCH 256
_Static_assert(SHADE_BATCH <= 256 && SHADE_BATCH % 16 == 0,
               "SHADE_BATCH: at most 256 (render.c's uint8_t lane index), a multiple of 16 (AVX-512 floats)");
typedef struct {
    float x[SHADE_BATCH], y[SHADE_BATCH], z[SHADE_BATCH];
} shade_vec3_n;
typedef struct {
    int n;                                  /* lanes in use, 0..SHADE_BATCH */
    shade_vec3_n x, nrm, v;                 /* as shade_eval's x, n, v */
    float tu[SHADE_BATCH], tv[SHADE_BATCH]; /* texture coordinates, read only for textured plans */
} shade_batch_in;
typedef struct {
    shade_vec3_n diffuse, specular, reflection, emission;
    float alpha[SHADE_BATCH];
} shade_batch_out;

/* Lane i of a batch: one vector, one sample's input, one sample's terms. */
static inline vec3 shade_lane_get(const shade_vec3_n *a, int i) { return v3(a->x[i], a->y[i], a->z[i]); }
static inline void shade_lane_set(shade_vec3_n *a, int i, vec3 v)
{
    a->x[i] = v.x;
    a->y[i] = v.y;
    a->z[i] = v.z;
}
static inline void shade_batch_set_input(shade_batch_in *in, int i, vec3 x, vec3 n, vec3 v)
{
    shade_lane_set(&in->x, i, x);
    shade_lane_set(&in->nrm, i, n);
    shade_lane_set(&in->v, i, v);
}
static inline void shade_batch_get_terms(const shade_batch_out *o, int i, shade_terms *t)
{
    t->diffuse = shade_lane_get(&o->diffuse, i);
    t->specular = shade_lane_get(&o->specular, i);
    t->reflection = shade_lane_get(&o->reflection, i);
    t->emission = shade_lane_get(&o->emission, i);
    t->alpha = o->alpha[i];
}
static inline void shade_batch_set_terms(shade_batch_out *o, int i, const shade_terms *t)
{
    shade_lane_set(&o->diffuse, i, t->diffuse);
    shade_lane_set(&o->specular, i, t->specular);
    shade_lane_set(&o->reflection, i, t->reflection);
    shade_lane_set(&o->emission, i, t->emission);
    o->alpha[i] = t->alpha;
}

typedef struct shade_plan shade_plan;
typedef void (*shade_fn)(const shade_context *c, const shade_plan *p, vec3 x, vec3 n, vec3 v, shade_terms *out);
/* A path that also reads the sample's texture coordinates (tu, tv) inside the model. */
typedef void (*shade_uv_fn)(const shade_context *c, const shade_plan *p, vec3 x, vec3 n, vec3 v, float tu, float tv,
                            shade_terms *out);
typedef void (*shade_batch_fn)(const shade_context *c, const shade_plan *p, const shade_batch_in *in,
                               shade_batch_out *out);
struct shade_plan {
    const material *mat;
    unsigned terms; /* SHADE_TERM_* this material can make non-zero here */
    shade_fn fn;
    /* Set for a path whose model reads (u, v) itself (the D3D9Client Dissolve of a textured
     * material): shade_eval_uv and the batch's scalar lanes call it in place of fn, and fn then
     * shades without what (u, v) adds. NULL otherwise. */
    shade_uv_fn fn_uv;
    shade_batch_fn batch; /* the same path over a batch */
    const char *path;     /* the specialised path's name, for reports and benchmarks */
    const void *params;   /* a model adapter's own parameters (render/physical.h); NULL for the
                             scene's models, which read everything from mat */
    /* The material's textures (c->tex), NULL per slot where none; any non-NULL makes the plan
     * textured: shade_eval_uv and shade_eval_n then multiply the terms by the texels. */
    const texture *tex[MAT_TEX_SLOTS];
    int textured;
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

/* Textures (scene/texture.h, scene.h's slots) enter after the model, because every model is
 * linear in what they scale: the diffuse texel's colour multiplies the diffuse and emission
 * terms (D3D's texture stage MODULATE of Dv; Cook-Torrance's albedo; the D3D9Client's lit d of
 * eq. 6, whose weight 1 - |lambda| does not depend on d), its alpha the material alpha (D3D:
 * alpha = texel alpha; D3D9Client eq. 7: max(d_a * texel alpha, |R_tot|)), and the specular
 * texel multiplies the specular term (D3D Vs, Cook-Torrance ks). Exact, not an approximation:
 * tests/test_texture.c compares with materials whose colours are the texel's. */
void shade_texture_apply(const shade_plan *p, float u, float v, shade_terms *t);
/* Sets p->tex and p->textured from c->tex for material m (shade_plan_make does it; a model
 * adapter making its own plans, render/physical.c, calls it too). */
void shade_plan_textures(const shade_context *c, const material *m, shade_plan *p);
void shade_texture_apply_n(const shade_plan *p, const shade_batch_in *in, shade_batch_out *out);

/* shade_eval at texture coordinates (u, v): the same for an untextured plan. */
static inline void shade_eval_uv(const shade_context *c, const shade_plan *p, vec3 x, vec3 n, vec3 v, float tu,
                                 float tv, shade_terms *out)
{
    if (p->fn_uv != NULL)
        p->fn_uv(c, p, x, n, v, tu, tv, out);
    else
        p->fn(c, p, x, n, v, out);
    if (p->textured)
        shade_texture_apply(p, tu, tv, out);
}

static inline void shade_eval_n(const shade_context *c, const shade_plan *p, const shade_batch_in *in,
                                shade_batch_out *out)
{
    p->batch(c, p, in, out);
    if (p->textured)
        shade_texture_apply_n(p, in, out);
}

/* The scalar kernels (shade.c), one per specialised path, that shade_plan_make
 * (shade_plan.c) installs as p->fn (p->fn_uv for Dissolve). */
void shade_d3d_diffuse(const shade_context *c, const shade_plan *p, vec3 x, vec3 n, vec3 v, shade_terms *out);
void shade_d3d_full(const shade_context *c, const shade_plan *p, vec3 x, vec3 n, vec3 v, shade_terms *out);
void shade_d3d9client(const shade_context *c, const shade_plan *p, vec3 x, vec3 n, vec3 v, shade_terms *out);
void shade_d3d9client_dissolve(const shade_context *c, const shade_plan *p, vec3 x, vec3 n, vec3 v, float tu, float tv,
                               shade_terms *out);
void shade_ct_lights(const shade_context *c, const shade_plan *p, vec3 x, vec3 n, vec3 v, shade_terms *out);
void shade_ct_full(const shade_context *c, const shade_plan *p, vec3 x, vec3 n, vec3 v, shade_terms *out);
void shade_user(const shade_context *c, const shade_plan *p, vec3 x, vec3 n, vec3 v, shade_terms *out);
/* The batch kernels (shade_batch_*.c), one per specialised path, that shade_plan_make installs;
 * shade_batch_scalar is shade_eval lane by lane (models without a kernel, unsafe lanes). */
void shade_batch_scalar(const shade_context *c, const shade_plan *p, const shade_batch_in *in, shade_batch_out *out);
/* shade_user over a batch, bit for bit (shade.c). */
void shade_batch_user(const shade_context *c, const shade_plan *p, const shade_batch_in *in, shade_batch_out *out);
void shade_batch_d3d_diffuse(const shade_context *c, const shade_plan *p, const shade_batch_in *in,
                             shade_batch_out *out);
void shade_batch_d3d_full(const shade_context *c, const shade_plan *p, const shade_batch_in *in, shade_batch_out *out);
void shade_batch_d3d9client(const shade_context *c, const shade_plan *p, const shade_batch_in *in,
                            shade_batch_out *out);
/* The same with Dissolve: each lane's mirror direction offset at its (tu, tv). */
void shade_batch_d3d9client_dissolve(const shade_context *c, const shade_plan *p, const shade_batch_in *in,
                                     shade_batch_out *out);
void shade_batch_ct_lights(const shade_context *c, const shade_plan *p, const shade_batch_in *in, shade_batch_out *out);
void shade_batch_ct_env(const shade_context *c, const shade_plan *p, const shade_batch_in *in, shade_batch_out *out);
/* Whether the Cook-Torrance kernels cover a material: Beckmann D, V-cavity or Walter's Smith G,
 * Schlick or unit Fresnel, m >= 1e-6. The exact Smith G (erf) and exact Fresnel (complex
 * index) stay on shade_eval, lane by lane. */
int shade_batch_ct_supported(const ct_params *ct);

/* The band of a light's squared distance d^2 within which every path takes the distance in
 * float: below about 1e-19 m d^2 underflows and above 1.8e19 m it overflows, and the light
 * would vanish at either end, so outside it the scalar path takes the distance in double and a
 * lane loop hands the sample to that path (or flags it). */
#define SHADE_D2_MIN 1e-30f
#define SHADE_D2_MAX 1e30f

/* Incident light i at x: unit direction to the light and the irradiance it would give at
 * normal incidence (I*A*spot for point/spot, E for a sun). Returns 0 when it gives nothing. */
int shade_light_incident(const light *l, vec3 x, vec3 *to_light, vec3 *e_perp, float *atten);

#endif
