#include "d3d9client.h"

#include <float.h>
#include <math.h>

#include "formula.h"
#include "fresnel.h"

/* The float result of a sum formed in double, saturated to +-FLT_MAX. */
static float d3d9client_sat(double x) { return (float)formula_sat_d(x); }

d3d9client_norm_weights d3d9client_norm_weights_of(colour_norm norm)
{
    d3d9client_norm_weights w = {0.0, 0.0, 0.0, 0.0, 0.0};
    switch (norm) {
    case NORM_MEAN: w.w_r = w.w_g = w.w_b = 1.0 / 3.0; break;
    case NORM_LUMINANCE:
        w.w_r = 0.2126;
        w.w_g = 0.7152;
        w.w_b = 0.0722;
        break;
    case NORM_EUCLID: w.w_euclid = 1.0; break;
    case NORM_MAX:
    default: w.w_max = 1.0; break;
    }
    return w;
}

double d3d9client_colour_norm_d(vec3 c, colour_norm norm)
{
    d3d9client_norm_weights w = d3d9client_norm_weights_of(norm);
    return formula_colour_norm_d(c.x, c.y, c.z, w.w_max, w.w_r, w.w_g, w.w_b, w.w_euclid);
}

float d3d9client_colour_norm(vec3 c, colour_norm norm)
{
    if (isnan(c.x) || isnan(c.y) || isnan(c.z))
        return NAN; /* a max by selects would drop a NaN */
    return d3d9client_sat(d3d9client_colour_norm_d(c, norm));
}

void d3d9client_combine(const d3d9client_params *p, vec3 diffuse_rgb, float diffuse_alpha, vec3 env_radiance_phi,
                        float n_v, float n_sun, d3d9client_result *out)
{
    double R = fresnel_d3d9(p->r0, p->m, p->p, n_v);
    vec3 l = p->reflect, s = p->fresnel_colour, phi = env_radiance_phi;
    /* (5) */
    dvec3 r_tot = dv3(formula_d3d9_r_tot_d(l.x, s.x, R, phi.x), formula_d3d9_r_tot_d(l.y, s.y, R, phi.y),
                      formula_d3d9_r_tot_d(l.z, s.z, R, phi.z));
    vec3 r_tot_f = v3(d3d9client_sat(r_tot.x), d3d9client_sat(r_tot.y), d3d9client_sat(r_tot.z));
    /* (6), and (8): the sun-lit diffuse loses what the coat's Fresnel reflects at the sun angle. */
    double w = formula_d3d9_diffuse_weight_d(d3d9client_colour_norm(p->reflect, p->norm));
    float r_sun = p->sun_angle ? fresnel_d3d9(p->r0, p->m, p->p, n_sun) : 0.0f;
    double dw = p->sun_angle ? w * formula_d3d9_sun_factor_d(r_sun) : w;
    out->rgb = v3(d3d9client_sat(formula_d3d9_colour_d(diffuse_rgb.x, dw, r_tot.x)),
                  d3d9client_sat(formula_d3d9_colour_d(diffuse_rgb.y, dw, r_tot.y)),
                  d3d9client_sat(formula_d3d9_colour_d(diffuse_rgb.z, dw, r_tot.z)));
    out->r_tot = r_tot_f;
    out->fresnel_R = (float)R;
    out->diffuse_weight = d3d9client_sat(w);
    out->diffuse_scale = p->sun_angle ? out->diffuse_weight * formula_d3d9_sun_factor_f(r_sun) : out->diffuse_weight;
    /* (7), with an explicit NaN test: the select would pick the other operand. */
    float rn = d3d9client_colour_norm(r_tot_f, p->norm);
    out->alpha = (isnan(diffuse_alpha) || isnan(rn)) ? NAN : formula_d3d9_alpha_f(diffuse_alpha, rn);
}

float d3d9client_diffuse_alpha(const d3d9client_params *p, float texel_a)
{
    switch (p->texel_alpha) {
    case TEXEL_ALPHA_MATERIAL: return p->alpha;
    case TEXEL_ALPHA_TEXEL: return texel_a;
    case TEXEL_ALPHA_MULTIPLY:
    default: return p->alpha * texel_a;
    }
}

int d3d9client_dissolve_on(const material *m)
{
    return m->model == MODEL_D3D9CLIENT && m->d9.dissolve_scale > 0.0f && m->d9.dissolve_strength > 0.0f &&
           m->texture[MAT_TEX_DIFFUSE][0] != '\0';
}

vec3 d3d9client_dissolve_offset(const d3d9client_params *p, float u, float v)
{
    const float s = p->dissolve_scale, k = p->dissolve_strength;
    return v3(formula_dissolve_offset_f(u, v, s, k, 0), formula_dissolve_offset_f(u, v, s, k, 1),
              formula_dissolve_offset_f(u, v, s, k, 2));
}
