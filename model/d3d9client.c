#include "d3d9client.h"

#include <float.h>
#include <math.h>

#include "fresnel.h"

static float d3d9client_sat(double x)
{
    if (x > FLT_MAX) return FLT_MAX;
    if (x < -FLT_MAX) return -FLT_MAX;
    return (float)x;
}

float d3d9_colour_norm(vec3 c, colour_norm norm)
{
    double r = c.x, g = c.y, b = c.z;
    if (isnan(r) || isnan(g) || isnan(b)) return NAN;   /* fmaxf below would drop a NaN */
    switch (norm) {
    case NORM_MEAN: return d3d9client_sat((r + g + b) / 3.0);
    case NORM_LUMINANCE: return d3d9client_sat(0.2126 * r + 0.7152 * g + 0.0722 * b);
    case NORM_EUCLID: return d3d9client_sat(sqrt(r * r + g * g + b * b));
    case NORM_MAX:
    default: return v3_max_comp(c);
    }
}

void d3d9client_combine(const d3d9client_params *p, vec3 diffuse_rgb, float diffuse_alpha,
                        vec3 env_radiance_phi, float n_v, float n_sun, d3d9_result *out)
{
    double R = fresnel_d3d9(p->r0, p->m, p->p, n_v);
    dvec3 lambda = dv3_from(p->reflect);
    dvec3 s = dv3_from(p->fresnel_colour);
    /* (5): lambda (1 - R) + s R, times phi. */
    dvec3 k = dv3_add(dv3_scale(lambda, 1.0 - R), dv3_scale(s, R));
    dvec3 r_tot = dv3_mul(k, dv3_from(env_radiance_phi));
    vec3 r_tot_f = v3(d3d9client_sat(r_tot.x), d3d9client_sat(r_tot.y), d3d9client_sat(r_tot.z));
    double w = 1.0 - (double)d3d9_colour_norm(p->reflect, p->norm);
    double dw = w;
    /* (8): the sun-lit diffuse loses what the coat's Fresnel reflects at the sun angle. */
    if (p->sun_angle) dw *= 1.0 - (double)fresnel_d3d9(p->r0, p->m, p->p, n_sun);
    dvec3 c = dv3_add(dv3_scale(dv3_from(diffuse_rgb), dw), r_tot);
    out->rgb = v3(d3d9client_sat(c.x), d3d9client_sat(c.y), d3d9client_sat(c.z));
    out->r_tot = r_tot_f;
    out->fresnel_R = (float)R;
    out->diffuse_weight = d3d9client_sat(w);
    /* (7); fmax would hide a NaN, so compare explicitly. */
    float rn = d3d9_colour_norm(r_tot_f, p->norm);
    out->alpha = (isnan(diffuse_alpha) || isnan(rn)) ? NAN : (diffuse_alpha > rn ? diffuse_alpha : rn);
}
