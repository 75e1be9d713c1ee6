/* shade_batch_lanes.h - what the batch kernels share; private to render/shade_batch*.c.
 *
 * Usage (a kernel file, say shade_batch_foo.c):
 *   #include "shade_batch_lanes.h"
 *   SB_INLINE int sb_foo_light(...) { const sb_light b = sb_light_make(l); ...
 *       #pragma omp simd  for each lane: sb_incident(l, &b, x, kind) ... }  return sb_any(bad, n);
 *   SMATH_CLONES void shade_batch_foo(c, p, in, out)
 *       { ... SB_WITH_KIND(l, bad |= sb_foo_light(..., K)); ... if (bad) shade_batch_scalar(c, p, in, out); }
 * The kernels are split by model family into shade_batch_d3d.c (D3D), shade_batch_d3d9.c
 * (D3D9Client and Dissolve) and shade_batch_ct.c (Cook-Torrance), so that make compiles them in
 * parallel: each kernel is three SMATH_CLONES clones with every lane loop inlined, and in one
 * file they were one core's 38 s. shade_batch.c holds what is not a lane loop: the scalar
 * fallback and the per-light set-up with its per-thread cache (one cache for all kernels).
 *
 * Everything here that a lane loop calls is SB_INLINE (always_inline): a lane loop must be
 * inlined into each SMATH_CLONES kernel to be compiled for that kernel's ISA, its constant
 * arguments (light kind, specular, ambient) must reach it to remove the branches they select,
 * and a call inside a lane loop would stop it vectorising. Each helper is defined once, here,
 * and inlined into every file that calls it (D3D9Client's pass runs D3D's sb_d3d_lit). */
#ifndef REFLCHECK_SHADE_BATCH_LANES_H
#define REFLCHECK_SHADE_BATCH_LANES_H

#include "shade.h"

#include <float.h>
#include <math.h>

#include "formula.h"
#include "smath.h"

/* Why always_inline: the header comment above. */
#if defined(__GNUC__)
#define SB_INLINE static inline __attribute__((always_inline))
#else
#define SB_INLINE static inline
#endif

static inline vec3 sb_min(vec3 a, vec3 b)
{
    return v3(a.x < b.x ? a.x : b.x, a.y < b.y ? a.y : b.y, a.z < b.z ? a.z : b.z);
}
/* *p read field by field. In a lane loop, a vec3 read whole from a struct (a light's position,
 * a material's f0) is an aggregate copy, which GCC 12 does not vectorise: it kept every
 * Cook-Torrance lane loop scalar. Three float reads of the same fields are the same values. */
SB_INLINE vec3 sb_v3_load(const vec3 *p) { return v3(p->x, p->y, p->z); }

/* Lane flags are gathered in an array and or-ed after the lane loop: an `omp simd reduction`
 * of an int kept GCC 12 from vectorising the float work around it. Here, alone, it vectorises
 * the or (without the pragma GCC 12 -O2 leaves a loop of unknown count scalar). */
SB_INLINE int sb_any(const int *flag, int n)
{
    int any = 0;
#pragma omp simd reduction(| : any)
    for (int i = 0; i < n; i++)
        any |= flag[i];
    return any;
}

/* Lane i from shade_eval (shade_batch.c). */
void sb_scalar_lane(const shade_context *c, const shade_plan *p, const shade_batch_in *in, shade_batch_out *out, int i);

/* phi: the environment's radiance along each lane's mirror direction reflect(V, N).
 * env_lookup_n reads lanes [0, n) of dir, all written by the loop; GCC 12 loses track of that
 * in some of the clones it inlines this into and warns, hence the pragma. */
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
SB_INLINE void sb_env_reflected(const shade_context *c, const shade_batch_in *restrict in, shade_vec3_n *restrict phi)
{
    shade_vec3_n dir;
    const int n = in->n;
#pragma omp simd
    for (int i = 0; i < n; i++)
        shade_lane_set(&dir, i, v3_reflect(shade_lane_get(&in->v, i), shade_lane_get(&in->nrm, i)));
    env_lookup_n(c->env, n, dir.x, dir.y, dir.z, phi->x, phi->y, phi->z);
}
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

/* What a light's lane loop reads, fixed before the loop (d3d_spot's normalised axis and cone
 * cosines, which d3d.c recomputes per call). */
typedef struct {
    vec3 to_sun; /* sun: unit direction to the light */
    vec3 axis;   /* spot: unit direction the light travels */
    float cos_in, cos_out, falloff;
    float cone; /* cos_in - cos_out, 1 where the cones coincide (no division then) */
} sb_light;

/* The set-up of light l, from a per-thread cache of the last few lights (shade_batch.c). */
sb_light sb_light_make(const light *l);

/* shade_light_incident for one lane: unit direction to the light and the attenuation
 * A * spot; bad when d^2 left the float-safe band. kind is a constant at every call, so the
 * light's type is decided before the lane loop, not in it. Returned by value: nothing in a
 * lane loop has its address taken. */
enum { SB_SUN, SB_POINT, SB_SPOT_D3D, SB_SPOT_SMOOTH };
typedef struct {
    vec3 to_l;
    float atten;
    int bad;
} sb_incidence;

SB_INLINE sb_incidence sb_incident(const light *l, const sb_light *b, vec3 x, const int kind)
{
    sb_incidence r = {sb_v3_load(&b->to_sun), 1.0f, 0};
    if (kind == SB_SUN)
        return r;
    vec3 d = v3_sub(sb_v3_load(&l->position), x);
    float d2 = v3_dot(d, d);
    int safe = (d2 > SHADE_D2_MIN) & (d2 < SHADE_D2_MAX);
    r.bad = !safe;
    float inv = 1.0f / sqrtf(safe ? d2 : 1.0f);
    r.to_l = v3_scale(d, inv);
    r.atten = formula_attenuation_v(l->a0, l->a1, l->a2, d2 * inv, d2, l->range);
    if (kind == SB_POINT)
        return r;
    float rho = -v3_dot(sb_v3_load(&b->axis), r.to_l);
    r.atten *= kind == SB_SPOT_SMOOTH ? formula_spot_smooth_v(rho, b->cos_in, b->cos_out, b->cone)
                                      : formula_spot_d3d_v(rho, b->cos_in, b->cos_out, b->cone, b->falloff);
    return r;
}

static inline int sb_kind(const light *l)
{
    if (l->kind == LIGHT_SUN)
        return SB_SUN;
    if (l->kind == LIGHT_POINT)
        return SB_POINT;
    return l->profile == SPOT_SMOOTH ? SB_SPOT_SMOOTH : SB_SPOT_D3D;
}

/* Runs STMT with K a compile-time constant equal to light l's kind, so that each kind gets its
 * own lane loop (sb_incident's `kind` tests fold away). */
#define SB_WITH_KIND(l, STMT)                                                                                          \
    do {                                                                                                               \
        switch (sb_kind(l)) {                                                                                          \
        case SB_SUN: {                                                                                                 \
            enum { K = SB_SUN };                                                                                       \
            STMT;                                                                                                      \
        } break;                                                                                                       \
        case SB_POINT: {                                                                                               \
            enum { K = SB_POINT };                                                                                     \
            STMT;                                                                                                      \
        } break;                                                                                                       \
        case SB_SPOT_D3D: {                                                                                            \
            enum { K = SB_SPOT_D3D };                                                                                  \
            STMT;                                                                                                      \
        } break;                                                                                                       \
        default: {                                                                                                     \
            enum { K = SB_SPOT_SMOOTH };                                                                               \
            STMT;                                                                                                      \
        } break;                                                                                                       \
        }                                                                                                              \
    } while (0)

/* One light's D3D terms added to every lane (shade.c's shade_d3d_impl loop body). */
SB_INLINE int sb_d3d_light(const shade_context *c, const d3d_params *d, const light *l,
                           const shade_batch_in *restrict in, shade_batch_out *restrict out, const int kind,
                           const int specular, const int ambient)
{
    const sb_light b = sb_light_make(l);
    /* The D3D light colour is E/pi (docs/conventions.md#direct3d-light-colours); Vd, Vs, Va folded in once here. */
    const vec3 kd = v3_scale(v3_mul(d->diffuse, l->intensity), FORMULA_INV_PI_F);
    const vec3 ks = v3_scale(v3_mul(d->specular, l->intensity), FORMULA_INV_PI_F);
    const vec3 ka = v3_mul(d->ambient, l->ambient);
    const float power = d->power;
    const vec3 e_inf = c->e_inf;
    const int local = d->local_viewer, n = in->n;
    int bad[SHADE_BATCH];
#pragma omp simd
    for (int i = 0; i < n; i++) {
        vec3 nn = shade_lane_get(&in->nrm, i), v = shade_lane_get(&in->v, i);
        sb_incidence inc = sb_incident(l, &b, shade_lane_get(&in->x, i), kind);
        if (kind != SB_SUN)
            bad[i] = inc.bad;
        float n_l = v3_dot(nn, inc.to_l), atten = inc.atten;
        /* atten >= 0 (a clamped positive denominator times a spot factor in [0, 1]), so where
         * the light gives nothing its products are 0 without a test. D3D lights nothing, not
         * even the highlight, from behind the surface. */
        vec3 dif = shade_lane_get(&out->diffuse, i);
        if (ambient)
            dif = v3_add(dif, v3_scale(ka, atten));
        shade_lane_set(&out->diffuse, i, v3_add(dif, v3_scale(kd, atten * formula_d3d_lambert_v(n_l))));
        if (specular) {
            vec3 h = v3_add(inc.to_l, local ? v : e_inf);
            h = v3_scale(h, formula_half_scale_v(v3_len(h)));
            float rs = n_l > 0.0f ? formula_blinn_v(v3_dot(nn, h), power) : 0.0f;
            shade_lane_set(&out->specular, i, v3_add(shade_lane_get(&out->specular, i), v3_scale(ks, atten * rs)));
        }
    }
    /* A sun has no distance to leave the band: its flags would all be 0, so none are kept. */
    return kind == SB_SUN ? 0 : sb_any(bad, n);
}

/* shade.c's shade_d3d_impl (docs/models.md §1) over a batch, up to the diffuse and specular
 * terms (clamped where D3D clamps them); returns non-zero when a lane was outside the
 * float-safe band. specular and ambient are constants in each caller. The emission, reflection
 * and alpha are left to the caller (sb_d3d_rest, or the D3D9Client's last pass, which writes
 * them with its own reflection and alpha). */
SB_INLINE int sb_d3d_lit(const shade_context *c, const material *m, const shade_batch_in *restrict in,
                         shade_batch_out *restrict out, const int specular, const int ambient)
{
    const d3d_params *d = &m->d3d;
    const scene *s = c->s;
    const int n = in->n;
    const vec3 amb0 = ambient ? v3_mul(d->ambient, s->global_ambient) : v3s(0.0f);
    int bad = 0;

#pragma omp simd
    for (int i = 0; i < n; i++) {
        shade_lane_set(&out->diffuse, i, amb0);
        shade_lane_set(&out->specular, i, v3s(0.0f));
    }
    for (int li = 0; li < s->n_lights; li++) {
        const light *l = &s->lights[li];
        SB_WITH_KIND(l, bad |= sb_d3d_light(c, d, l, in, out, K, specular, ambient));
    }
    /* D3D saturates Dv (which holds the emissive colour) and Sv to [0, 1] separately. */
    if (d->clamp) {
        const vec3 room = v3_sub(v3s(1.0f), sb_min(d->emissive, v3s(1.0f)));
#pragma omp simd
        for (int i = 0; i < n; i++) {
            shade_lane_set(&out->diffuse, i, sb_min(shade_lane_get(&out->diffuse, i), room));
            shade_lane_set(&out->specular, i, sb_min(shade_lane_get(&out->specular, i), v3s(1.0f)));
        }
    }
    return bad;
}

/* The emission sb_d3d_lit's terms go with: the emissive colour, saturated with them. */
static inline vec3 sb_d3d_emission(const d3d_params *d)
{
    return d->clamp ? sb_min(d->emissive, v3s(1.0f)) : d->emissive;
}

#endif
