/* shade_batch.c - shade.c's D3D, D3D9Client and Cook-Torrance paths over structure-of-arrays
 * batches.
 *
 * Each kernel runs the light loop outside and the lanes inside, so a lane loop has no branch
 * that depends on the light or the material (those are chosen before it starts) and compiles
 * to straight SIMD code: one sample per lane, selects for the per-sample conditions that
 * shade.c writes as `if`/`continue`, smath for pow, log, exp and atan2. Every formula is
 * formula.h's lane instance (suffix _v), the very code the scalar models run in double (_d) and
 * the stability check in long double (_l), with the scalar models' order of guards; what
 * differs is float where the scalar path sums in double, and smath's approximations, which is
 * why lanes match shade_eval within the bounds shade.h states rather than bit for bit
 * (tests/test_shade_batch.c measures them).
 *
 * A lane outside the float-safe range of the point-light distance (the scalar path switches
 * to double there) marks the batch, and the whole batch is redone by shade_batch_scalar;
 * grazing or non-unit Cook-Torrance lanes are redone one by one. */
#include "shade.h"

#include <float.h>
#include <math.h>
#include <stdint.h>

#include "cooktorrance.h"
#include "d3d9client.h"
#include "formula.h"
#include "fresnel.h"
#include "microfacet.h"
#include "smath.h"

/* The lane loops must be inlined into each SMATH_CLONES kernel to be compiled for its ISA,
 * and their constant arguments must reach them to remove the branches they select. */
#if defined(__GNUC__)
#define SB_INLINE static inline __attribute__((always_inline))
#else
#define SB_INLINE static inline
#endif
/* The float-safe band of a squared light distance (shade_light_incident's own band). */
#define SB_D2_MIN 1e-30f
#define SB_D2_MAX 1e30f

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

/* Lane i from shade_eval. */
static void sb_scalar_lane(const shade_context *c, const shade_plan *p, const shade_batch_in *in, shade_batch_out *out,
                           int i)
{
    shade_terms t;
    vec3 x = shade_lane_get(&in->x, i), n = shade_lane_get(&in->nrm, i), v = shade_lane_get(&in->v, i);
    if (p->fn_uv != NULL)
        p->fn_uv(c, p, x, n, v, in->tu[i], in->tv[i], &t);
    else
        p->fn(c, p, x, n, v, &t);
    shade_batch_set_terms(out, i, &t);
}

void shade_batch_scalar(const shade_context *c, const shade_plan *p, const shade_batch_in *in, shade_batch_out *out)
{
    for (int i = 0; i < in->n; i++)
        sb_scalar_lane(c, p, in, out, i);
}

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

/* The mirror directions plus Dissolve's offsets, the effect on or (a constant) off: off, the
 * offset is formula_dissolve_offset's 0, still added (a -0 component becomes +0, as in shade.c). */
SB_INLINE void sb_dissolved_dirs(const d3d9client_params *d9, const shade_batch_in *restrict in,
                                 shade_vec3_n *restrict dir, const int on)
{
    const int n = in->n;
    const float sc = d9->dissolve_scale, k = d9->dissolve_strength;
#pragma omp simd
    for (int i = 0; i < n; i++) {
        const float u = in->tu[i], v = in->tv[i];
        vec3 off = on ? v3(formula_dissolve_offset_on_v(u, v, sc, k, 0), formula_dissolve_offset_on_v(u, v, sc, k, 1),
                           formula_dissolve_offset_on_v(u, v, sc, k, 2))
                      : v3s(0.0f);
        shade_lane_set(dir, i, v3_add(v3_reflect(shade_lane_get(&in->v, i), shade_lane_get(&in->nrm, i)), off));
    }
}

/* phi along the mirror direction plus Dissolve's offset at each lane's (tu, tv): shade.c's
 * shade_d3d9client_impl, formula_dissolve_offset per channel (d3d9client_dissolve_offset),
 * its on/off test made once per batch. */
SB_INLINE void sb_env_dissolved(const shade_context *c, const d3d9client_params *d9, const shade_batch_in *restrict in,
                                shade_vec3_n *restrict phi)
{
    shade_vec3_n dir;
    if (d9->dissolve_scale > 0.0f && d9->dissolve_strength > 0.0f)
        sb_dissolved_dirs(d9, in, &dir, 1);
    else
        sb_dissolved_dirs(d9, in, &dir, 0);
    env_lookup_n(c->env, in->n, dir.x, dir.y, dir.z, phi->x, phi->y, phi->z);
}

/* What a light's lane loop reads, fixed before the loop (d3d_spot's normalised axis and cone
 * cosines, which d3d.c recomputes per call). */
typedef struct {
    vec3 to_sun; /* sun: unit direction to the light */
    vec3 axis;   /* spot: unit direction the light travels */
    float cos_in, cos_out, falloff;
    float cone; /* cos_in - cos_out, 1 where the cones coincide (no division then) */
} sb_light;

static sb_light sb_light_compute(const light *l)
{
    sb_light b = {v3s(0.0f), v3s(0.0f), 0.0f, 0.0f, 0.0f, 1.0f};
    b.to_sun = v3_neg(v3_norm(l->direction));
    b.axis = v3_from_d(dv3_norm(dv3_from(l->direction)));
    b.cos_in = (float)cos(0.5 * (double)l->inner);
    b.cos_out = (float)cos(0.5 * (double)l->outer);
    b.falloff = l->falloff;
    b.cone = formula_spot_cone_f(b.cos_in, b.cos_out);
    return b;
}

/* sb_light_compute depends on the light's direction, cone angles and falloff alone; a batch of
 * 64 lanes recomputed its two double cosines per light (2 % of a frame), so the last few
 * lights' results are kept per thread and reused while those fields are unchanged (compared
 * by value, so an edited or reused light struct is never served a stale entry). */
#define SB_LIGHT_CACHE 4
typedef struct {
    vec3 direction;
    float inner, outer, falloff;
    sb_light b;
    int used;
} sb_light_entry;

/* Bit equality (a NaN equals itself, -0 differs from +0): the entry is reused only where
 * sb_light_compute would see the very same input bits. */
static int sb_same_bits(float a, float b)
{
    union {
        float f;
        uint32_t u;
    } x = {a}, y = {b};
    return x.u == y.u;
}

static int sb_light_same(const sb_light_entry *e, const light *l)
{
    return e->used && sb_same_bits(e->direction.x, l->direction.x) && sb_same_bits(e->direction.y, l->direction.y) &&
           sb_same_bits(e->direction.z, l->direction.z) && sb_same_bits(e->inner, l->inner) &&
           sb_same_bits(e->outer, l->outer) && sb_same_bits(e->falloff, l->falloff);
}

static sb_light sb_light_make(const light *l)
{
    static _Thread_local sb_light_entry cache[SB_LIGHT_CACHE];
    static _Thread_local int next;
    for (int i = 0; i < SB_LIGHT_CACHE; i++)
        if (sb_light_same(&cache[i], l))
            return cache[i].b;
    sb_light_entry *e = &cache[next];
    next = (next + 1) % SB_LIGHT_CACHE;
    *e = (sb_light_entry){l->direction, l->inner, l->outer, l->falloff, sb_light_compute(l), 1};
    return e->b;
}

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
    int safe = (d2 > SB_D2_MIN) & (d2 < SB_D2_MAX);
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

static int sb_kind(const light *l)
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
    return sb_any(bad, n);
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
static vec3 sb_d3d_emission(const d3d_params *d) { return d->clamp ? sb_min(d->emissive, v3s(1.0f)) : d->emissive; }

/* shade.c's shade_d3d_impl over a batch: sb_d3d_lit, then no reflection and alpha 1. */
SB_INLINE int sb_d3d(const shade_context *c, const material *m, const shade_batch_in *restrict in,
                     shade_batch_out *restrict out, const int specular, const int ambient)
{
    const int bad = sb_d3d_lit(c, m, in, out, specular, ambient), n = in->n;
    const vec3 emission = sb_d3d_emission(&m->d3d);
#pragma omp simd
    for (int i = 0; i < n; i++) {
        shade_lane_set(&out->reflection, i, v3s(0.0f));
        shade_lane_set(&out->emission, i, emission);
        out->alpha[i] = 1.0f;
    }
    return bad;
}

SMATH_CLONES
void shade_batch_d3d_diffuse(const shade_context *c, const shade_plan *p, const shade_batch_in *in,
                             shade_batch_out *out)
{
    if (sb_d3d(c, p->mat, in, out, 0, 0))
        shade_batch_scalar(c, p, in, out);
}

SMATH_CLONES
void shade_batch_d3d_full(const shade_context *c, const shade_plan *p, const shade_batch_in *in, shade_batch_out *out)
{
    if (sb_d3d(c, p->mat, in, out, 1, 1))
        shade_batch_scalar(c, p, in, out);
}

/* (1)/(3) per lane: formula_d3d9_fresnel with the instance's power of 1 - cos: a whole p up to
 * 8 (a constant `whole` at each call) by multiplication, as fresnel.c, else smath_pow. */
SB_INLINE float sb_fresnel(const d3d9client_params *d9, float p, const int whole, float cos_theta)
{
    float x = formula_one_minus_cos_v(cos_theta);
    float xe = whole ? smath_pow_whole(x, (int)p) : smath_pow(x, p);
    return formula_sat_v(formula_d3d9_fresnel_v(d9->r0, d9->m, xe));
}

/* What the D3D9Client's last pass reads, fixed per batch. */
typedef struct {
    float fp;                             /* the Fresnel power, formula_d3d9_power(p) */
    vec3 lambda, s;                       /* the metallic and the Fresnel colour */
    float w;                              /* (6)'s diffuse weight 1 - |lambda|, saturated */
    float w_max, w_r, w_g, w_b, w_euclid; /* the colour norm's weights in float */
    float d_alpha;
    vec3 emission;
} sb_d9_consts;

static sb_d9_consts sb_d9_consts_of(const material *m)
{
    const d3d9client_params *d9 = &m->d9;
    /* The norm's weights in float, fixed before the loop (a switch on the norm inside it would
     * not vectorise). */
    const d3d9client_norm_weights nw = d3d9client_norm_weights_of(d9->norm);
    sb_d9_consts k = {
        .fp = fresnel_d3d9_power(d9->p),
        .lambda = d9->reflect,
        .s = d9->fresnel_colour,
        .w = formula_sat_v(formula_d3d9_diffuse_weight_f(d3d9client_colour_norm(d9->reflect, d9->norm))),
        .w_max = (float)nw.w_max,
        .w_r = (float)nw.w_r,
        .w_g = (float)nw.w_g,
        .w_b = (float)nw.w_b,
        .w_euclid = (float)nw.w_euclid,
        .d_alpha = d9->alpha,
        .emission = sb_d3d_emission(&m->d3d),
    };
    return k;
}

/* Equations (3)-(8) on the D3D terms already in out, in one lane loop: (8)'s factor
 * 1 - F(N.L_sun) (the main light's direction from geometry alone, scene_main_light: it counts
 * even where the light gives nothing; 1 without a main light, has_sun 0), R at N.V, R_tot, the
 * weighted diffuse, the alpha, and the emission. One pass instead of a sun-factor pass, a
 * combine pass and sb_d3d's fill, whose reflection and alpha this pass overwrote: the same
 * operations per lane. Returns non-zero when the main light's d^2 left the float-safe band. */
SB_INLINE int sb_d9_last(const d3d9client_params *d9, const sb_d9_consts *k, const light *sun,
                         const shade_batch_in *restrict in, const shade_vec3_n *restrict phi,
                         shade_batch_out *restrict out, const int has_sun, const int kind, const int whole)
{
    const sb_light b = has_sun ? sb_light_make(sun) : (sb_light){0};
    const float fp = k->fp, w = k->w, d_alpha = k->d_alpha;
    const float w_max = k->w_max, w_r = k->w_r, w_g = k->w_g, w_b = k->w_b, w_euclid = k->w_euclid;
    const vec3 lambda = k->lambda, s = k->s, emission = k->emission;
    const int n = in->n;
    int bad[SHADE_BATCH];
#pragma omp simd
    for (int i = 0; i < n; i++) {
        const vec3 nn = shade_lane_get(&in->nrm, i);
        float sun_f = 1.0f;
        bad[i] = 0;
        if (has_sun) {
            sb_incidence inc = sb_incident(sun, &b, shade_lane_get(&in->x, i), kind);
            bad[i] = inc.bad;
            sun_f = formula_d3d9_sun_factor_v(sb_fresnel(d9, fp, whole, v3_dot(nn, inc.to_l)));
        }
        float R = sb_fresnel(d9, fp, whole, v3_dot(nn, shade_lane_get(&in->v, i)));
        vec3 ph = shade_lane_get(phi, i);
        vec3 r_tot = v3(formula_sat_v(formula_d3d9_r_tot_v(lambda.x, s.x, R, ph.x)),
                        formula_sat_v(formula_d3d9_r_tot_v(lambda.y, s.y, R, ph.y)),
                        formula_sat_v(formula_d3d9_r_tot_v(lambda.z, s.z, R, ph.z)));
        shade_lane_set(&out->diffuse, i, v3_scale(shade_lane_get(&out->diffuse, i), w * sun_f));
        shade_lane_set(&out->reflection, i, r_tot);
        shade_lane_set(&out->emission, i, emission);
        float rn = formula_colour_norm_v(r_tot.x, r_tot.y, r_tot.z, w_max, w_r, w_g, w_b, w_euclid);
        out->alpha[i] = formula_d3d9_alpha_v(d_alpha, rn);
    }
    return sb_any(bad, n);
}

/* shade.c's shade_d3d9client (docs/models.md §2, eqs. 3-8) over a batch; dissolve a constant. */
SB_INLINE void sb_d3d9client(const shade_context *c, const shade_plan *p, const shade_batch_in *in,
                             shade_batch_out *out, const int dissolve)
{
    const d3d9client_params *d9 = &p->mat->d9;
    if (sb_d3d_lit(c, p->mat, in, out, 1, 1)) {
        shade_batch_scalar(c, p, in, out);
        return;
    }
    shade_vec3_n phi;
    if (dissolve)
        sb_env_dissolved(c, d9, in, &phi);
    else
        sb_env_reflected(c, in, &phi);

    const sb_d9_consts k = sb_d9_consts_of(p->mat);
    const int whole = k.fp == floorf(k.fp) && k.fp <= 8.0f;
    const light *sun = d9->sun_angle ? scene_main_light(c->s) : NULL;
    int bad = 0;
    if (sun == NULL && whole)
        bad = sb_d9_last(d9, &k, NULL, in, &phi, out, 0, SB_SUN, 1);
    else if (sun == NULL)
        bad = sb_d9_last(d9, &k, NULL, in, &phi, out, 0, SB_SUN, 0);
    else if (whole)
        SB_WITH_KIND(sun, bad = sb_d9_last(d9, &k, sun, in, &phi, out, 1, K, 1));
    else
        SB_WITH_KIND(sun, bad = sb_d9_last(d9, &k, sun, in, &phi, out, 1, K, 0));
    if (bad)
        shade_batch_scalar(c, p, in, out);
}

SMATH_CLONES
void shade_batch_d3d9client(const shade_context *c, const shade_plan *p, const shade_batch_in *in, shade_batch_out *out)
{
    sb_d3d9client(c, p, in, out, 0);
}

SMATH_CLONES
void shade_batch_d3d9client_dissolve(const shade_context *c, const shade_plan *p, const shade_batch_in *in,
                                     shade_batch_out *out)
{
    sb_d3d9client(c, p, in, out, 1);
}

/* ---- Cook-Torrance (docs/models.md §3): cooktorrance.c's lobe and reflection weight in float ---- */

/* Roughness below this goes through the scalar path: m^2 would leave float's normal range in
 * the Beckmann exponent, where cooktorrance.c works in double. */
#define SB_CT_M_MIN    1e-6f
/* Lanes the kernel hands back to shade_eval. Below N.V = 0.01 the lobe's 1/N.V turns the float
 * dot product's ~1e-7 absolute error into more than 1e-5 relative (cooktorrance.c forms N.V in
 * double); such grazing lanes are a thin band at silhouettes. A normal whose squared length
 * is off 1 by more than 1e-5 is one cooktorrance.c would renormalise in double. */
#define SB_CT_NV_MIN   0.01f
#define SB_CT_UNIT_TOL 1e-5f

int shade_batch_ct_supported(const ct_params *ct)
{
    return ct->g != G_SMITH_EXACT && ct->f != F_EXACT && ct->m >= SB_CT_M_MIN;
}

/* (4.9) Schlick per channel, c clamped to [0, 1]; or 1 (F_ONE). */
SB_INLINE vec3 sb_ct_fresnel(vec3 f0, float c, const int f_one)
{
    if (f_one)
        return v3s(1.0f);
    return v3(formula_schlick_v(f0.x, c), formula_schlick_v(f0.y, c), formula_schlick_v(f0.z, c));
}

/* The lobe ks F D G / (k N.V) for unit n, v, l, with cooktorrance_specular's guards in their
 * order: hemisphere, zero cosines, zero-length half vector, then normalise. log_d0 is
 * -2 ln m (- ln pi for Walter's normalisation), fixed per material. */
SB_INLINE vec3 sb_ct_lobe(const ct_params *ct, float log_d0, float inv_m2, float k_norm, vec3 n, vec3 v, vec3 l,
                          const int smith, const int f_one)
{
    float n_l = v3_dot(n, l), n_v = v3_dot(n, v);
    int front = (n_l > 0.0f) & (n_v > 0.0f);
    n_l = formula_cos_floor_v(n_l);
    n_v = formula_cos_floor_v(n_v);
    vec3 hs = v3_add(l, v);
    float hl = v3_len(hs);
    front &= hl >= (float)FORMULA_HALF_MIN;
    vec3 h = v3_scale(hs, formula_half_scale_v(hl));
    float n_h = v3_dot(n, h), v_h = v3_dot(v, h);
    v_h = v_h < 0.0f ? 0.0f : (v_h > 1.0f ? 1.0f : v_h);
    /* (4.12), sin^2 from |N x H|^2, not 1 - cos^2: near the peak of a sharp lobe 1 - cos cancels,
     * and its rounding (6e-8) over m^2 would move log D by 0.12 at m = 0.001; the cross product
     * keeps sin^2's relative precision, so the kernel is the more accurate of the two paths there. */
    float c = n_h > 1.0f ? 1.0f : n_h, c2 = c * c;
    vec3 nxh = v3_cross(n, h);
    float s2 = v3_dot(nxh, nxh);
    float d = formula_beckmann_d_v(s2 > 1.0f ? 1.0f : s2, c2 > 0.0f ? c2 : FLT_MIN, inv_m2, log_d0);
    d = n_h > 0.0f ? d : 0.0f;
    float g = smith ? formula_smith_g1_walter_v(n_v, ct->m) * formula_smith_g1_walter_v(n_l, ct->m)
                    : formula_vcavity_g_v(n_h, n_v, n_l, v_h);
    vec3 f = sb_ct_fresnel(sb_v3_load(&ct->f0), v_h, f_one);
    float common = front ? formula_ct_lobe_v(d, g, k_norm, n_v) : 0.0f;
    vec3 r = v3_mul(v3_mul(sb_v3_load(&ct->ks), f), v3s(common));
    return sb_min(r, v3s(FORMULA_CT_MAX));
}

/* One light's Cook-Torrance terms added to every lane (shade.c's shade_ct_impl loop body). */
SB_INLINE int sb_ct_light(const material *mat, const light *l, const shade_batch_in *restrict in,
                          shade_batch_out *restrict out, const int kind, const int smith, const int f_one)
{
    const ct_params *ct = &mat->ct;
    const sb_light b = sb_light_make(l);
    const vec3 kd = v3_scale(mat->albedo, FORMULA_INV_PI_F);
    const float k_norm = formula_ct_k_f(ct->norm != CT_CT1982);
    const float log_d0 = (float)formula_beckmann_log_norm_d(ct->m, ct->norm != CT_CT1982);
    const float inv_m2 = 1.0f / (ct->m * ct->m);
    const int n = in->n;
    int bad[SHADE_BATCH];
#pragma omp simd
    for (int i = 0; i < n; i++) {
        vec3 nn = shade_lane_get(&in->nrm, i), v = shade_lane_get(&in->v, i);
        sb_incidence inc = sb_incident(l, &b, shade_lane_get(&in->x, i), kind);
        bad[i] = inc.bad;
        vec3 e = v3_scale(sb_v3_load(&l->intensity), inc.atten);
        float n_l = v3_dot(nn, inc.to_l);
        float lit = n_l > 0.0f ? 1.0f : 0.0f;
        shade_lane_set(&out->diffuse, i, v3_add(shade_lane_get(&out->diffuse, i), v3_scale(v3_mul(kd, e), n_l * lit)));
        vec3 s = sb_ct_lobe(ct, log_d0, inv_m2, k_norm, nn, v, inc.to_l, smith, f_one);
        shade_lane_set(&out->specular, i, v3_add(shade_lane_get(&out->specular, i), v3_scale(v3_mul(s, e), lit)));
    }
    return sb_any(bad, n);
}

/* shade.c's shade_ct_impl over a batch; only for materials shade_batch_ct_supported accepts. */
SB_INLINE void sb_ct(const shade_context *c, const shade_plan *p, const shade_batch_in *restrict in,
                     shade_batch_out *restrict out, const int reflection)
{
    const material *mat = p->mat;
    const int n = in->n, smith = mat->ct.g == G_SMITH_WALTER, f_one = mat->ct.f == F_ONE;
    /* A local, as in sb_ct_light: read through mat in the loop, the fill was not vectorised. */
    const vec3 emissive = mat->d3d.emissive;
    int bad = 0;
#pragma omp simd
    for (int i = 0; i < n; i++) {
        shade_lane_set(&out->diffuse, i, v3s(0.0f));
        shade_lane_set(&out->specular, i, v3s(0.0f));
        shade_lane_set(&out->emission, i, emissive);
        shade_lane_set(&out->reflection, i, v3s(0.0f));
        out->alpha[i] = 1.0f;
    }
    for (int li = 0; li < c->s->n_lights; li++) {
        const light *l = &c->s->lights[li];
        if (smith && f_one)
            SB_WITH_KIND(l, bad |= sb_ct_light(mat, l, in, out, K, 1, 1));
        else if (smith)
            SB_WITH_KIND(l, bad |= sb_ct_light(mat, l, in, out, K, 1, 0));
        else if (f_one)
            SB_WITH_KIND(l, bad |= sb_ct_light(mat, l, in, out, K, 0, 1));
        else
            SB_WITH_KIND(l, bad |= sb_ct_light(mat, l, in, out, K, 0, 0));
    }
    if (bad) {
        shade_batch_scalar(c, p, in, out);
        return;
    }
    if (reflection) {
        shade_vec3_n phi;
        sb_env_reflected(c, in, &phi);
        const vec3 f0 = mat->ct.f0;
#pragma omp simd
        for (int i = 0; i < n; i++) {
            /* cooktorrance_reflection_weight: F at N.V, capped. */
            vec3 w = sb_min(sb_ct_fresnel(f0, v3_dot(shade_lane_get(&in->nrm, i), shade_lane_get(&in->v, i)), f_one),
                            v3s(FORMULA_CT_MAX));
            shade_lane_set(&out->reflection, i, v3_mul(shade_lane_get(&phi, i), w));
        }
    }
    for (int i = 0; i < n; i++) {
        vec3 nn = shade_lane_get(&in->nrm, i);
        float n_v = v3_dot(nn, shade_lane_get(&in->v, i)), len2 = v3_dot(nn, nn);
        if (n_v < SB_CT_NV_MIN || fabsf(len2 - 1.0f) > SB_CT_UNIT_TOL)
            sb_scalar_lane(c, p, in, out, i);
    }
}

SMATH_CLONES
void shade_batch_ct_lights(const shade_context *c, const shade_plan *p, const shade_batch_in *in, shade_batch_out *out)
{
    sb_ct(c, p, in, out, 0);
}

SMATH_CLONES
void shade_batch_ct_env(const shade_context *c, const shade_plan *p, const shade_batch_in *in, shade_batch_out *out)
{
    sb_ct(c, p, in, out, 1);
}
