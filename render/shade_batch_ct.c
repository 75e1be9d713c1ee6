/* shade_batch_ct.c - the Cook-Torrance kernels (docs/models.md §3), direct lights only and
 * with the environment's reflection: cooktorrance.c's lobe and reflection weight in float.
 * shade_batch.c says how the kernels work and when they fall back. */
#include "shade_batch_lanes.h"

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
