#include "d3d.h"

#include <math.h>

#include "formula.h"

float d3d_attenuation(const light *l, float d)
{
    if (l->kind == LIGHT_SUN)
        return 1.0f;
    if (isnan(d))
        return NAN;
    /* In double: d^2 of a finite float cannot overflow there. */
    double dd = d;
    return (float)formula_attenuation_d(l->a0, l->a1, l->a2, dd, dd * dd, l->range);
}

/* Unit vectors in double, so a tiny (even denormal) float vector normalises without 1/len
 * overflowing; a zero vector stays zero. */
static vec3 d3d_norm(vec3 a) { return v3_from_d(dv3_norm(dv3_from(a))); }

float d3d_spot(const light *l, vec3 light_to_point_unit)
{
    if (l->kind != LIGHT_SPOT)
        return 1.0f;
    double rho = dv3_dot(dv3_from(d3d_norm(l->direction)), dv3_from(light_to_point_unit));
    if (isnan(rho))
        return NAN;
    double cos_in = cos(0.5 * (double)l->inner);
    double cos_out = cos(0.5 * (double)l->outer);
    double cone = formula_spot_cone_d(cos_in, cos_out);
    if (l->profile == SPOT_SMOOTH)
        return (float)formula_spot_smooth_d(rho, cos_in, cos_out, cone);
    return (float)formula_spot_d3d_d(rho, cos_in, cos_out, cone, l->falloff);
}

float d3d_lambert(float n_l) { return formula_d3d_lambert_f(n_l); }

float d3d_blinn(float n_h, float power)
{
    if (isnan(n_h) || isnan(power))
        return NAN;
    /* powf is within 1 ulp of the exact power (glibc); double pow rounded to float gave
     * the correctly rounded value at three times the cost. */
    return formula_blinn_f(n_h, power);
}

vec3 d3d_half_vector(vec3 l, vec3 v_local, vec3 e_infinite, int local_viewer)
{
    vec3 v = local_viewer ? v_local : e_infinite;
    float ll = v3_dot(l, l), vv = v3_dot(v, v);
    /* Unit-length-ish inputs (the shading loop's) stay in float; anything whose squared
     * length could under- or overflow takes the double path. */
    if (ll > 1e-20f && ll < 1e20f && vv > 1e-20f && vv < 1e20f) {
        vec3 s = v3_add(v3_scale(l, 1.0f / sqrtf(ll)), v3_scale(v, 1.0f / sqrtf(vv)));
        float len = v3_len(s);
        if (isnan(len))
            return v3s(NAN);
        return v3_scale(s, formula_half_scale_f(len));
    }
    dvec3 ld = dv3_norm(dv3_from(l));
    dvec3 vd = dv3_norm(dv3_from(v));
    dvec3 s = dv3_add(ld, vd);
    double len = dv3_len(s);
    if (isnan(len))
        return v3s(NAN);
    return v3_from_d(dv3_scale(s, formula_half_scale_d(len)));
}

static int d3d_source_takes(colour_source src, unsigned have)
{
    return (src == COLOUR_SOURCE_COLOUR1 && (have & 1u)) || (src == COLOUR_SOURCE_COLOUR2 && (have & 2u));
}

int d3d_uses_vertex_colours(const d3d_params *d, unsigned have)
{
    return d->colour_vertex &&
           (d3d_source_takes(d->ambient_source, have) || d3d_source_takes(d->diffuse_source, have) ||
            d3d_source_takes(d->specular_source, have) || d3d_source_takes(d->emissive_source, have));
}

static vec3 d3d_pick(colour_source src, unsigned have, vec3 own, vec3 colour1, vec3 colour2)
{
    if (!d3d_source_takes(src, have))
        return own;
    return src == COLOUR_SOURCE_COLOUR1 ? colour1 : colour2;
}

void d3d_vertex_colours(const d3d_params *d, unsigned have, vec3 colour1, vec3 colour2, d3d_params *out)
{
    *out = *d;
    if (!d->colour_vertex)
        return;
    out->ambient = d3d_pick(d->ambient_source, have, d->ambient, colour1, colour2);
    out->diffuse = d3d_pick(d->diffuse_source, have, d->diffuse, colour1, colour2);
    out->specular = d3d_pick(d->specular_source, have, d->specular, colour1, colour2);
    out->emissive = d3d_pick(d->emissive_source, have, d->emissive, colour1, colour2);
}
