#include "microfacet.h"

#include <float.h>
#include <math.h>

#define MICROFACET_PI 3.14159265358979323846

float microfacet_beckmann_d(double cos_h, float m, ct_normalisation norm)
{
    if (isnan(cos_h) || isnan(m)) return NAN;
    if (cos_h <= 0.0) return 0.0f;
    double c = cos_h > 1.0 ? 1.0 : cos_h;
    if (m <= 0.0f) return c >= 1.0 ? MICROFACET_D_MAX : 0.0f;
    double md = m;
    /* Below 1e-150, c^2 would underflow; tan^2/m^2 > 1e300/FLT_MAX^2 = 8e222 there, so D is 0
     * for every float m. */
    if (c < 1e-150) return 0.0f;
    double c2 = c * c;
    double tan2 = (1.0 - c) * (1.0 + c) / c2;
    /* log D = -tan^2/m^2 - log(pi) - 2 log m - 4 log c; each term is finite in double for
     * every positive finite float c and m, and the sum's exp underflows to 0 or is capped. */
    double log_d = -tan2 / (md * md) - 2.0 * log(md) - 2.0 * log(c2);
    if (norm != CT_CT1982) log_d -= log(MICROFACET_PI);
    if (log_d >= log((double)MICROFACET_D_MAX)) return MICROFACET_D_MAX;
    return (float)exp(log_d);
}

float microfacet_vcavity_g(float n_h, float n_v, float n_l, float v_h)
{
    if (isnan(n_h) || isnan(n_v) || isnan(n_l) || isnan(v_h)) return NAN;
    if (n_h <= 0.0f || n_v <= 0.0f || n_l <= 0.0f) return 0.0f;
    double vh = v_h;
    double g = 1.0;
    /* Compare before dividing: a ratio is taken only when it is below g <= 1, which
     * implies vh > 0, so neither 0/0 nor x/0 can happen. */
    double tv = 2.0 * (double)n_h * (double)n_v;
    double tl = 2.0 * (double)n_h * (double)n_l;
    if (tv < g * vh) g = tv / vh;
    if (tl < g * vh) g = tl / vh;
    return (float)g;
}

/* m tan(theta) in double: 0 * Inf cannot occur because tan is finite for cos > 0 in
 * double (cos >= 4.9e-324 gives tan <= 2e323), and m * tan overflowing to Inf is fine. */
static double microfacet_m_tan(double c, double m)
{
    return m * (sqrt((1.0 - c) * (1.0 + c)) / c);
}

float microfacet_smith_g1_walter(float cos_theta, float m)
{
    if (isnan(cos_theta) || isnan(m)) return NAN;
    if (cos_theta <= 0.0f) return 0.0f;
    if (cos_theta >= 1.0f || m <= 0.0f) return 1.0f;
    double inv_a = microfacet_m_tan(cos_theta, m);
    /* 0.625 = 1/1.6, Cycles' branch point. */
    if (inv_a < 0.625) return 1.0f;
    double a = 1.0 / inv_a;   /* inv_a >= 0.625: a in [0, 1.6] */
    return (float)(((2.181 * a + 3.535) * a) / ((2.577 * a + 2.276) * a + 1.0));
}

double microfacet_smith_g1_exact(double cos_theta, double m)
{
    if (isnan(cos_theta) || isnan(m)) return NAN;
    if (cos_theta <= 0.0) return 0.0;
    if (cos_theta >= 1.0 || m <= 0.0) return 1.0;
    double x = microfacet_m_tan(cos_theta, m);
    if (x <= 0.0) return 1.0;
    if (isinf(x)) return 0.0;
    double a = 1.0 / x;
    /* For a > 26, exp(-a^2) underflows to 0 and erf(a) rounds to 1: G1 = 1 exactly.
     * For tiny a, exp(-a^2)/(a sqrt(pi)) is large but finite (a >= 1/DBL_MAX), so G1 -> 0. */
    double lambda_term = exp(-a * a) / (a * sqrt(MICROFACET_PI));
    return 2.0 / (1.0 + erf(a) + lambda_term);
}

float microfacet_smith_g_walter(float n_v, float n_l, float m)
{
    return microfacet_smith_g1_walter(n_v, m) * microfacet_smith_g1_walter(n_l, m);
}

double microfacet_smith_g_exact(double n_v, double n_l, double m)
{
    return microfacet_smith_g1_exact(n_v, m) * microfacet_smith_g1_exact(n_l, m);
}

double microfacet_lambert_brdf(double albedo)
{
    return albedo / MICROFACET_PI;
}
