/* ggx.c - the first user model: the real-time BRDF of Karis 2013, "Real Shading in Unreal
 * Engine 4" (SIGGRAPH course notes), a template for your own (docs/user_models.md).
 *
 *   f = albedo / pi + D F G / (4 N.L N.V)
 *   D = alpha^2 / (pi ((N.H)^2 (alpha^2 - 1) + 1)^2)       Trowbridge-Reitz / GGX, alpha = roughness^2
 *   G = G1(N.L) G1(N.V), G1(c) = c / (c (1 - k) + k)        Smith-Schlick-GGX, k = alpha / 2
 *   F = F0 + (1 - F0) (1 - V.H)^5                           Schlick
 * k = alpha/2 is Karis' fit of Schlick's G to Smith's GGX G; for analytic lights Karis also
 * remaps roughness to (roughness + 1)/2 before squaring (k = (roughness + 1)^2 / 8, Disney's
 * "hotness" reduction), which this model does not: it keeps k = alpha/2 everywhere, so that it
 * approximates the physics and not an artistic choice. F is Schlick's power form, not the
 * spherical-Gaussian exponent Karis evaluates it with.
 *
 * Build: cc -shared -fPIC -O2 -Imodel examples/ggx/ggx.c -o ggx.so (the Makefile builds it into
 * BUILD/examples/ggx/ggx.so).
 */
#include <math.h>

#include "user_model.h"

#define GGX_PI 3.14159265358979323846

enum { P_ROUGHNESS, P_F0 };
static const reflcheck_user_param ggx_params[] = {
    /* roughness 0.03: alpha 9e-4, a highlight far below a pixel; 1: the roughest GGX. */
    [P_ROUGHNESS] = {"roughness", 0.03, 1.0, 0.5, 1},
    /* F0 of a dielectric is about 0.04; 1 a perfect metal. */
    [P_F0] = {"f0", 0.0, 1.0, 0.04, 0},
};

static double ggx_g1(double c, double k) { return c / (c * (1.0 - k) + k); }

static void ggx_eval(const reflcheck_user_input *in, const double *p, reflcheck_user_output *out)
{
    double alpha = p[P_ROUGHNESS] * p[P_ROUGHNESS], a2 = alpha * alpha;
    double t = in->n_h * in->n_h * (a2 - 1.0) + 1.0;
    double d = a2 / (GGX_PI * t * t);
    double g = ggx_g1(in->n_l, alpha / 2.0) * ggx_g1(in->n_v, alpha / 2.0);
    double f = p[P_F0] + (1.0 - p[P_F0]) * pow(1.0 - in->v_h, 5.0);
    double spec = d * f * g / (4.0 * in->n_l * in->n_v);
    for (int c = 0; c < 3; c++) {
        out->diffuse[c] = in->albedo[c] / GGX_PI;
        out->specular[c] = spec;
    }
}

static const reflcheck_user_model ggx_model = {
    REFLCHECK_USER_ABI, "ggx",    "Karis 2013 (UE4): GGX D, Smith-Schlick G k = alpha/2, Schlick F, Lambert", 2,
    ggx_params,         ggx_eval,
};

const reflcheck_user_model *reflcheck_user_model_entry(void);
const reflcheck_user_model *reflcheck_user_model_entry(void) { return &ggx_model; }
