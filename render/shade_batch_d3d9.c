/* shade_batch_d3d9.c - the D3D9Client kernels (docs/models.md §2, eqs. 3-8), without and with
 * Dissolve's offsets: shade_batch_lanes.h's D3D lit pass, then the Fresnel, reflection, diffuse
 * weight and alpha in one lane loop. shade_batch.c says how the kernels work and fall back. */
#include "shade_batch_lanes.h"

#include "d3d9client.h"
#include "fresnel.h"

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
        if (has_sun) {
            sb_incidence inc = sb_incident(sun, &b, shade_lane_get(&in->x, i), kind);
            if (kind != SB_SUN)
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
    /* Flags only where a distance was taken (a main light that is not a sun): otherwise they
     * would all be 0, and clearing and or-ing them cost a memset and a pass a batch. */
    return has_sun && kind != SB_SUN ? sb_any(bad, n) : 0;
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
