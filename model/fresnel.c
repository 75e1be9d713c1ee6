#include "fresnel.h"

#include <float.h>
#include <math.h>

#include "formula.h"

/* Saturate a double to the float range. NaN passes through unchanged. */
static float fresnel_sat(double x)
{
    if (x > FLT_MAX) return FLT_MAX;
    if (x < -FLT_MAX) return -FLT_MAX;
    return (float)x;
}

/* Clamp to [lo, hi] without hiding a NaN (comparisons with NaN are false). */
static double fresnel_clampd(double x, double lo, double hi)
{
    return x < lo ? lo : (x > hi ? hi : x);
}

float fresnel_r0_from_ior(float n)
{
    /* In double: 1 + n and the square cannot overflow for n near FLT_MAX. */
    return (float)formula_r0_d(n);
}

float fresnel_schlick(float f0, float cos_theta)
{
    return fresnel_sat(formula_schlick_d(f0, cos_theta));
}

vec3 fresnel_schlick_rgb(vec3 f0, float cos_theta)
{
    return v3(fresnel_schlick(f0.x, cos_theta), fresnel_schlick(f0.y, cos_theta),
              fresnel_schlick(f0.z, cos_theta));
}

float fresnel_d3d9(float r0, float m, float p, float cos_theta)
{
    double e = formula_d3d9_power_d(p);
    double x = formula_one_minus_cos_d(cos_theta), xe;
    /* Small whole powers (the seed's p = 2..5 and Schlick's 5) by repeated multiplication:
     * at most 7 double roundings, far below float resolution, and no libm pow per pixel. */
    if (e == floor(e) && e <= 8.0) {
        xe = 1.0;
        for (int i = 0; i < (int)e; i++)
            xe *= x;
    } else
        xe = pow(x, e);
    /* x^e with x in [0, 1] and e >= 0 lies in [0, 1]: no overflow here. */
    return fresnel_sat(formula_d3d9_fresnel_d(r0, m, xe));
}

/* Beyond this ratio eta^2 (or 1/eta^2) leaves the double range, while the reflectance
 * already equals its limit 1 to double precision ((1 - 2/(1 + 1e150))^2 rounds to 1). */
#define FRESNEL_ETA_LIMIT 1e150

double fresnel_dielectric(double cos_i, double eta)
{
    if (!(eta > 0.0)) return isnan(eta) ? eta : 1.0;
    eta = fresnel_clampd(eta, 1.0 / FRESNEL_ETA_LIMIT, FRESNEL_ETA_LIMIT);
    if (cos_i < 0.0) {
        cos_i = -cos_i;
        eta = 1.0 / eta;
    }
    cos_i = fresnel_clampd(cos_i, 0.0, 1.0);
    /* sin_t from sin_i/eta rather than sin_i^2/eta^2, so a tiny eta cannot make 0/0. */
    double sin_i = sqrt((1.0 - cos_i) * (1.0 + cos_i));
    double sin_t = sin_i / eta;
    if (sin_t >= 1.0) return 1.0;
    double cos_t = sqrt((1.0 - sin_t) * (1.0 + sin_t));
    /* Both denominators are > 0 here: cos_t > 0 because sin_t < 1, and eta > 0. */
    double rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    double rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    return 0.5 * (rs * rs + rp * rp);
}

double fresnel_conductor(double cos_i, double eta, double k)
{
    if (isnan(cos_i) || isnan(eta) || isnan(k)) return NAN;
    double c = fresnel_clampd(fabs(cos_i), 0.0, 1.0);
    eta = fresnel_clampd(fabs(eta), 0.0, FRESNEL_ETA_LIMIT);
    k = fresnel_clampd(fabs(k), 0.0, FRESNEL_ETA_LIMIT);
    double c2 = c * c;
    double s2 = (1.0 - c) * (1.0 + c);
    /* The standard real form of |r_s|^2 and |r_p|^2 for n = eta + i k (as in PBRT):
     * t0 = eta^2 - k^2 - sin^2, a^2 + b^2 = |t0 + 2 i eta k|, a = Re sqrt(t0 + 2 i eta k).
     * Overflow-free for eta, k <= 1e150 since every square stays below 1e300. */
    double t0 = eta * eta - k * k - s2;
    double a2pb2 = hypot(t0, 2.0 * eta * k);
    double a = sqrt(fmax(0.0, 0.5 * (a2pb2 + t0)));
    double t1 = a2pb2 + c2;
    double t2 = 2.0 * c * a;
    /* t1 + t2 = 0 only at exact grazing with eta = 1, k = 0: the grazing limit is 1. */
    double rs = t1 + t2 > 0.0 ? (t1 - t2) / (t1 + t2) : 1.0;
    double t3 = c2 * a2pb2 + s2 * s2;
    double t4 = t2 * s2;
    /* t3 + t4 = 0 only at normal incidence with eta = k = 0, where p equals s. */
    double rp = t3 + t4 > 0.0 ? rs * (t3 - t4) / (t3 + t4) : rs;
    return 0.5 * (rs + rp);
}
