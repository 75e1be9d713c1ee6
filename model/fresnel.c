#include "fresnel.h"

#include <float.h>
#include <math.h>

#include "formula.h"

/* Clamp to [lo, hi] without hiding a NaN (comparisons with NaN are false). */
static double fresnel_clampd(double x, double lo, double hi) { return x < lo ? lo : (x > hi ? hi : x); }

float fresnel_r0_from_ior(float n)
{
    /* In double: 1 + n and the square cannot overflow for n near FLT_MAX. */
    return (float)formula_r0_d(n);
}

float fresnel_schlick(float f0, float cos_theta) { return (float)formula_sat_d(formula_schlick_d(f0, cos_theta)); }

vec3 fresnel_schlick_rgb(vec3 f0, float cos_theta)
{
    return v3(fresnel_schlick(f0.x, cos_theta), fresnel_schlick(f0.y, cos_theta), fresnel_schlick(f0.z, cos_theta));
}

float fresnel_d3d9(float r0, float m, float p, float cos_theta)
{
    double e = formula_d3d9_power_d(p);
    double x = formula_one_minus_cos_d(cos_theta), xe;
    /* Small whole powers (the source's p = 2..5 and Schlick's 5) by repeated multiplication:
     * at most 7 double roundings, far below float resolution, and no libm pow per pixel. */
    if (e == floor(e) && e <= 8.0) {
        xe = 1.0;
        for (int i = 0; i < (int)e; i++)
            xe *= x;
    } else
        xe = pow(x, e);
    /* x^e with x in [0, 1] and e >= 0 lies in [0, 1]: no overflow here. */
    return (float)formula_sat_d(formula_d3d9_fresnel_d(r0, m, xe));
}

/* Beyond this ratio eta^2 (or 1/eta^2) leaves the double range, while the reflectance
 * already equals its limit 1 to double precision ((1 - 2/(1 + 1e150))^2 rounds to 1). */
#define FRESNEL_ETA_LIMIT 1e150

double fresnel_dielectric(double cos_i, double eta)
{
    if (!(eta > 0.0))
        return isnan(eta) ? eta : 1.0;
    eta = fresnel_clampd(eta, 1.0 / FRESNEL_ETA_LIMIT, FRESNEL_ETA_LIMIT);
    if (cos_i < 0.0) {
        cos_i = -cos_i;
        eta = 1.0 / eta;
    }
    cos_i = fresnel_clampd(cos_i, 0.0, 1.0);
    return formula_fresnel_dielectric_d(cos_i, eta);
}

double fresnel_conductor(double cos_i, double eta, double k)
{
    if (isnan(cos_i) || isnan(eta) || isnan(k))
        return NAN;
    double c = fresnel_clampd(fabs(cos_i), 0.0, 1.0);
    eta = fresnel_clampd(fabs(eta), 0.0, FRESNEL_ETA_LIMIT);
    k = fresnel_clampd(fabs(k), 0.0, FRESNEL_ETA_LIMIT);
    /* Overflow-free for eta, k <= 1e150 since every square stays below 1e300. */
    return formula_fresnel_conductor_d(c, eta, k);
}
