#include "microfacet.h"

#include <float.h>
#include <math.h>

#include "formula.h"

float microfacet_beckmann_d(double cos_h, float m, ct_normalisation norm)
{
    if (isnan(cos_h) || isnan(m))
        return NAN;
    if (cos_h <= 0.0)
        return 0.0f;
    double c = cos_h > 1.0 ? 1.0 : cos_h;
    if (m <= 0.0f)
        return c >= 1.0 ? MICROFACET_D_MAX : 0.0f;
    double md = m;
    /* Below 1e-150, c^2 would underflow; tan^2/m^2 > 1e300/FLT_MAX^2 = 8e222 there, so D is 0
     * for every float m. */
    if (c < 1e-150)
        return 0.0f;
    /* In double: every term of log D is finite for every positive finite float c and m, and
     * sin^2 = (1 - c)(1 + c) keeps its precision near the peak (cos_h is a double, see the
     * header). */
    return (float)formula_beckmann_d_d((1.0 - c) * (1.0 + c), c * c, 1.0 / (md * md),
                                       formula_beckmann_log_norm_d(md, norm != CT_CT1982));
}

float microfacet_vcavity_g(float n_h, float n_v, float n_l, float v_h)
{
    if (isnan(n_h) || isnan(n_v) || isnan(n_l) || isnan(v_h))
        return NAN;
    return (float)formula_vcavity_g_d(n_h, n_v, n_l, v_h);
}

float microfacet_smith_g1_walter(float cos_theta, float m)
{
    if (isnan(cos_theta) || isnan(m))
        return NAN;
    return (float)formula_smith_g1_walter_d(cos_theta, m);
}

double microfacet_smith_g1_exact(double cos_theta, double m)
{
    if (isnan(cos_theta) || isnan(m))
        return NAN;
    return formula_smith_g1_exact_d(cos_theta, m);
}

float microfacet_smith_g_walter(float n_v, float n_l, float m)
{
    return microfacet_smith_g1_walter(n_v, m) * microfacet_smith_g1_walter(n_l, m);
}

double microfacet_smith_g_exact(double n_v, double n_l, double m)
{
    return microfacet_smith_g1_exact(n_v, m) * microfacet_smith_g1_exact(n_l, m);
}

double microfacet_ggx_d(double sin2_h, double cos2_h, double alpha)
{
    double a2 = alpha * alpha;
    if (!(alpha > 0.0))
        return sin2_h > 0.0 ? 0.0 : MICROFACET_D_MAX;
    double t = a2 * cos2_h + sin2_h;
    /* t > 0 unless cos and sin are both 0 (not a direction): D's limit there is the cap. */
    double d = t > 0.0 ? a2 / (FORMULA_PI_D * t * t) : (double)MICROFACET_D_MAX;
    return d < MICROFACET_D_MAX ? d : MICROFACET_D_MAX;
}

double microfacet_ggx_g1(double cos_theta, double alpha)
{
    if (!(cos_theta > 0.0))
        return 0.0;
    if (cos_theta >= 1.0)
        return 1.0;
    double c2 = cos_theta * cos_theta;
    return 2.0 / (1.0 + sqrt(1.0 + alpha * alpha * (1.0 - c2) / c2));
}

double microfacet_ggx_g(double n_v, double n_l, double alpha)
{
    return microfacet_ggx_g1(n_v, alpha) * microfacet_ggx_g1(n_l, alpha);
}

double microfacet_lambert_brdf(double albedo) { return formula_lambert_brdf_d(albedo); }
