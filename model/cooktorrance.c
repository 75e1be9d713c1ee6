#include "cooktorrance.h"

#include <math.h>

#include "formula.h"
#include "fresnel.h"
#include "microfacet.h"

static double cooktorrance_cap(double x)
{
    if (x > COOKTORRANCE_MAX)
        return COOKTORRANCE_MAX;
    if (x < -COOKTORRANCE_MAX)
        return -COOKTORRANCE_MAX;
    return x;
}

/* Fresnel per channel for the cosine c (V.H for the lobe, N.V for the reflection). */
static dvec3 cooktorrance_fresnel(const ct_params *p, double c, const material *mat)
{
    if (p->f == F_ONE)
        return dv3(1.0, 1.0, 1.0);
    if (p->f == F_EXACT && mat) {
        if (mat->conductor)
            return dv3(fresnel_conductor(c, mat->eta.x, mat->k.x), fresnel_conductor(c, mat->eta.y, mat->k.y),
                       fresnel_conductor(c, mat->eta.z, mat->k.z));
        /* A cosine of exactly 0 stays on the outside: the ray arrives from outside. */
        double f = fresnel_dielectric(c, mat->ior);
        return dv3(f, f, f);
    }
    return dv3_from(fresnel_schlick_rgb(p->f0, (float)c));
}

static double cooktorrance_g(const ct_params *p, double n_h, double n_v, double n_l, double v_h)
{
    switch (p->g) {
    case G_SMITH_WALTER: return microfacet_smith_g_walter((float)n_v, (float)n_l, p->m);
    case G_SMITH_EXACT: return microfacet_smith_g_exact(n_v, n_l, p->m);
    case G_VCAVITY:
    default: return microfacet_vcavity_g((float)n_h, (float)n_v, (float)n_l, (float)v_h);
    }
}

vec3 cooktorrance_specular(const ct_params *p, vec3 n, vec3 v, vec3 l, const material *mat)
{
    /* Unit vectors in double: a tiny (even denormal) float vector normalises without 1/len
     * overflowing, a zero vector stays zero and then fails guard 1. */
    dvec3 nd = dv3_norm(dv3_from(n));
    dvec3 vd = dv3_norm(dv3_from(v));
    dvec3 ld = dv3_norm(dv3_from(l));
    double n_l = dv3_dot(nd, ld);
    double n_v = dv3_dot(nd, vd);
    if (isnan(n_l) || isnan(n_v))
        return v3s(NAN);
    /* 1. hemisphere */
    if (n_l <= 0.0 || n_v <= 0.0)
        return v3s(0.0f);
    /* 2. zero cosines */
    n_l = formula_cos_floor_d(n_l);
    n_v = formula_cos_floor_d(n_v);
    /* 3. zero-length half vector */
    dvec3 hs = dv3_add(ld, vd);
    double hl = dv3_len(hs);
    if (hl < FORMULA_HALF_MIN)
        return v3s(0.0f);
    /* 4. normalise, then the terms */
    dvec3 h = dv3_scale(hs, formula_half_scale_d(hl));
    double n_h = dv3_dot(nd, h);
    double v_h = dv3_dot(vd, h);
    if (v_h < 0.0)
        v_h = 0.0; /* V.H = |L+V|/2 >= 0 exactly; only rounding can dip below */
    if (v_h > 1.0)
        v_h = 1.0;
    double d = microfacet_beckmann_d(n_h, p->m, p->norm);
    double g = cooktorrance_g(p, n_h, n_v, n_l, v_h);
    dvec3 f = cooktorrance_fresnel(p, v_h, mat);
    /* ks F D G / (k N.V): N.V >= 1e-6 and D <= 1e12, so this is finite before the cap. */
    double common = formula_ct_lobe_d(d, g, formula_ct_k_d(p->norm != CT_CT1982), n_v);
    dvec3 r = dv3_scale(dv3_mul(dv3_from(p->ks), f), common);
    return v3((float)cooktorrance_cap(r.x), (float)cooktorrance_cap(r.y), (float)cooktorrance_cap(r.z));
}

vec3 cooktorrance_reflection_weight(const ct_params *p, float n_v, const material *mat)
{
    if (isnan(n_v))
        return v3s(NAN);
    double c = n_v < 0.0f ? 0.0 : (n_v > 1.0f ? 1.0 : (double)n_v);
    dvec3 f = cooktorrance_fresnel(p, c, mat);
    return v3((float)cooktorrance_cap(f.x), (float)cooktorrance_cap(f.y), (float)cooktorrance_cap(f.z));
}
