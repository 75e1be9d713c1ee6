/* d3d9client.h - D3D9Client Fresnel + metallic reflection (docs/models.md §2, seed
 * equations (1)-(8)), evaluated for one surface point.
 *
 * Usage:
 *   d3d9client_result r;
 *   d3d9client_combine(&mat->d9, lit_diffuse_rgb, diffuse_alpha, env(reflect(-V, N)),
 *                      n_v, n_sun, &r);          r.rgb is the pixel colour (6) or (8)
 * diffuse_rgb is the lit diffuse colour d (section 1's Dv, or texture x lighting);
 * env_radiance_phi is phi, the radiance arriving along the mirror direction. Outputs are
 * radiance-like colours in the inputs' units; nothing is clamped (HDR), so a negative
 * diffuse weight (euclid norm of a bright lambda) shows in the result instead of hiding.
 * The equations are formula.h's (formula_d3d9_fresnel, formula_d3d9_r_tot,
 * formula_d3d9_diffuse_weight, formula_d3d9_sun_factor, formula_d3d9_colour, formula_d3d9_alpha,
 * formula_colour_norm), shared with the SIMD lanes and the stability reference.
 * Pure functions; every finite argument gives a finite result (sums are formed in double
 * and saturated to +-FLT_MAX); a NaN argument propagates.
 * Blend (p->blend, D3D's SRCALPHA/INVSRCALPHA; render/render.h composites):
 *   out = c_rgb * a + behind * (1 - a),  a = render_blend_alpha(r.alpha): c_a clamped to [0, 1]
 * Dissolve (source 000, our reading: docs/dissolve.md):
 *   if (d3d9client_dissolve_on(mat))
 *       dir = v3_add(reflect(-V, N), d3d9client_dissolve_offset(&mat->d9, u, v));   then phi = env(dir)
 */
#ifndef REFLCHECK_D3D9CLIENT_H
#define REFLCHECK_D3D9CLIENT_H

#include "formula.h"
#include "scene.h"

/* |c| for a colour: NORM_MAX largest component, NORM_MEAN (R+G+B)/3, NORM_LUMINANCE
 * 0.2126 R + 0.7152 G + 0.0722 B (Rec. 709), NORM_EUCLID sqrt(R^2+G^2+B^2) (sqrt 3 for
 * white: 1 - |lambda| < 0). Unknown values behave as NORM_MAX. As formula.h's
 * formula_colour_norm weights it: w_max max(c) + w . c + w_euclid |c|_2, one weight non-zero. */
typedef struct {
    double w_max, w_r, w_g, w_b, w_euclid;
} d3d9client_norm_weights;
d3d9client_norm_weights d3d9client_norm_weights_of(colour_norm norm);
/* |c| in double, unsaturated (the POV-Ray translator's 1 - |lambda|). */
double d3d9client_colour_norm_d(vec3 c, colour_norm norm);
/* |c| saturated to +-FLT_MAX. */
float d3d9client_colour_norm(vec3 c, colour_norm norm);

typedef struct {
    vec3 rgb;             /* (6), or (8) when p->sun_angle */
    float alpha;          /* (7) max(d_a, |R_tot|) */
    vec3 r_tot;           /* (5) (lambda (1 - R) + s R) phi */
    float fresnel_R;      /* (3) R0 + m (1 - (N.V)+)^p */
    float diffuse_weight; /* 1 - |lambda|, reported unclamped: < 0 flags a norm (euclid)
                             that makes bright metals subtract diffuse light */
    float diffuse_scale;  /* what multiplies d in rgb, in float as the shading loop applies
                             it: diffuse_weight, times (8)'s 1 - R(sigma) when p->sun_angle */
} d3d9client_result;

/* Equations (3)-(8). n_v = N.V (clamped to [0, 1] inside (3)); n_sun = cos sigma = N.L of
 * the main light, read only when p->sun_angle (clamped the same way in (8)). */
void d3d9client_combine(const d3d9client_params *p, vec3 diffuse_rgb, float diffuse_alpha, vec3 env_radiance_phi,
                        float n_v, float n_sun, d3d9client_result *out);

/* d_a of eq. (7) on a textured material whose diffuse texel has alpha texel_a, as p->texel_alpha
 * says: d_a x texel_a (multiply, the default), d_a (material) or texel_a (texel). */
float d3d9client_diffuse_alpha(const d3d9client_params *p, float texel_a);

/* Whether a material's reflection is dissolved: model d3d9client, scale and strength both > 0
 * (either 0 turns the effect off, source 000), and a diffuse texture, the source's condition (the
 * scene file refuses dissolve on an untextured material, so this is only a guard). */
int d3d9client_dissolve_on(const material *m);
/* Dissolve's offset to the mirror direction at texture coordinates (u, v):
 * formula_dissolve_offset per channel (R -> x, G -> y, B -> z), each in +-strength/2. */
vec3 d3d9client_dissolve_offset(const d3d9client_params *p, float u, float v);

#endif
