#include "d3d.h"

#include <math.h>

float d3d_attenuation(const light *l, float d)
{
    if (l->kind == LIGHT_SUN) return 1.0f;
    if (isnan(d)) return NAN;
    if (d > l->range) return 0.0f;
    double dd = d;
    /* A zero coefficient adds nothing even at d = Inf (0 * Inf would be NaN). */
    double den = l->a0;
    if (l->a1 != 0.0f) den += (double)l->a1 * dd;
    if (l->a2 != 0.0f) den += (double)l->a2 * dd * dd;
    if (isnan(den)) return NAN;
    if (den < D3D_ATTEN_DENOM_MIN) den = D3D_ATTEN_DENOM_MIN;
    return (float)(1.0 / den);
}

/* Unit vectors in double, so a tiny (even denormal) float vector normalises without 1/len
 * overflowing; a zero vector stays zero. */
static vec3 d3d_norm(vec3 a)
{
    return v3_from_d(dv3_norm(dv3_from(a)));
}

float d3d_spot(const light *l, vec3 light_to_point_unit)
{
    if (l->kind != LIGHT_SPOT) return 1.0f;
    double rho = dv3_dot(dv3_from(d3d_norm(l->direction)), dv3_from(light_to_point_unit));
    if (isnan(rho)) return NAN;
    double cos_in = cos(0.5 * (double)l->inner);
    double cos_out = cos(0.5 * (double)l->outer);
    if (l->profile == SPOT_SMOOTH) {
        /* Order as Cycles: outside the outer cone 0, inside the inner cone rho; when the
         * cones coincide (cos_in <= cos_out) the edge is hard and no division happens. */
        if (rho <= 0.0 || rho <= cos_out) return 0.0f;
        if (rho >= cos_in) return (float)rho;
        double t = (rho - cos_out) / (cos_in - cos_out);   /* cos_in > rho > cos_out here */
        return (float)(rho * t * t * (3.0 - 2.0 * t));
    }
    if (rho > cos_in) return 1.0f;
    if (rho <= cos_out) return 0.0f;
    /* Reached only with cos_out < rho <= cos_in, so the denominator is positive and the
     * ratio lies in (0, 1]. */
    double t = (rho - cos_out) / (cos_in - cos_out);
    double e = l->falloff < 0.0f ? 0.0 : (double)l->falloff;
    return (float)pow(t, e);
}

float d3d_lambert(float n_l)
{
    return n_l <= 0.0f ? 0.0f : (n_l > 1.0f ? 1.0f : n_l);
}

float d3d_blinn(float n_h, float power)
{
    if (isnan(n_h) || isnan(power)) return NAN;
    if (n_h <= 0.0f) return 0.0f;
    float x = n_h > 1.0f ? 1.0f : n_h;
    /* powf is within 1 ulp of the exact power (glibc); double pow rounded to float gave
     * the correctly rounded value at three times the cost. */
    return powf(x, power < 0.0f ? 0.0f : power);
}

/* Below this |L + V| the half vector's direction is float rounding noise (see d3d.h). */
#define D3D_HALF_MIN 1e-6

vec3 d3d_half_vector(vec3 l, vec3 v_local, vec3 e_infinite, int local_viewer)
{
    vec3 v = local_viewer ? v_local : e_infinite;
    float ll = v3_dot(l, l), vv = v3_dot(v, v);
    /* Unit-length-ish inputs (the shading loop's) stay in float; anything whose squared
     * length could under- or overflow takes the double path. */
    if (ll > 1e-20f && ll < 1e20f && vv > 1e-20f && vv < 1e20f) {
        vec3 s = v3_add(v3_scale(l, 1.0f / sqrtf(ll)), v3_scale(v, 1.0f / sqrtf(vv)));
        float len = v3_len(s);
        if (isnan(len)) return v3s(NAN);
        if (len < (float)D3D_HALF_MIN) return v3s(0.0f);
        return v3_scale(s, 1.0f / len);
    }
    dvec3 ld = dv3_norm(dv3_from(l));
    dvec3 vd = dv3_norm(dv3_from(v));
    dvec3 s = dv3_add(ld, vd);
    double len = dv3_len(s);
    if (isnan(len)) return v3s(NAN);
    if (len < D3D_HALF_MIN) return v3s(0.0f);
    return v3_from_d(dv3_scale(s, 1.0 / len));
}
