/* fresnel.h - Fresnel reflectance: the real-time approximations and the exact references.
 *
 * Usage:
 *   float r0 = fresnel_r0_from_ior(1.5f);                 0.04
 *   float f  = fresnel_schlick(r0, v3_dot(v, h));         Cook-Torrance (4.9)
 *   float R  = fresnel_d3d9(r0, 1.0f - r0, 3.0f, n_v);    D3D9Client (1)/(3)
 *   double e = fresnel_dielectric(cos_i, 1.5);            exact, unpolarised
 *   double c = fresnel_conductor(cos_i, 0.2, 3.0);        exact, complex index eta + i k
 * The approximations' formulas are formula.h's (formula_r0, formula_schlick,
 * formula_d3d9_fresnel), which the SIMD lanes and the stability reference share; these functions
 * add the scalar model's guards and evaluate them in double.
 * float functions model the shader (GPU precision); double functions are the exact
 * references the approximations are judged against. All are pure and return a reflectance
 * (a fraction, not a radiance; no cosine factor). Cosines outside their range are clamped
 * as each function states. A NaN argument propagates to the result, so the harness's NaN
 * counter sees it; every finite argument gives a finite result. Bad input (ior <= 0,
 * negative exponent) is rejected where it enters (scene file, command line); the
 * functions still give the documented finite value for it.
 */
#ifndef REFLCHECK_FRESNEL_H
#define REFLCHECK_FRESNEL_H

#include "formula.h"
#include "vec.h"

/* (2)/(4.9): R0 = ((1 - n)/(1 + n))^2 for a relative index n (n2/n1). n <= 0 (not an index)
 * and n = +Inf give 1, the limits n -> 0+ and n -> Inf. */
float fresnel_r0_from_ior(float n);

/* (4.9) Schlick: F0 + (1 - F0)(1 - c)^5, c clamped to [0, 1]. */
float fresnel_schlick(float f0, float cos_theta);
vec3 fresnel_schlick_rgb(vec3 f0, float cos_theta);

/* (1)/(3) D3D9Client: R0 + m (1 - c)^p, c = (N.V)+ clamped to [0, 1]. p = 0 gives R0 + m
 * for every c (x^0 = 1, also at x = 0, as C's pow). A negative p (bad input) is treated as
 * 0, because (1 - c)^p would be unbounded at c = 1. The sum is formed in double and
 * saturated to +-FLT_MAX, so huge bad R0 and m cannot overflow to Inf. */
float fresnel_d3d9(float r0, float m, float p, float cos_theta);
/* The exponent fresnel_d3d9 applies: p, with p < 0 taken as 0 (a negative power is unbounded at
 * normal incidence). One definition for fresnel_d3d9 and the SIMD kernels (shade_batch_d3d9.c), so a
 * change to the rule reaches every render. */
static inline float fresnel_d3d9_power(float p) { return formula_d3d9_power_f(p); }

/* Exact unpolarised Fresnel reflectance of a smooth dielectric interface, (Rs + Rp)/2.
 * eta = n_t / n_i seen from the side the ray arrives on when cos_i >= 0; cos_i < 0 means
 * the ray arrives from the inside, so the media swap (eta -> 1/eta, cos_i -> -cos_i).
 * |cos_i| is clamped to 1. Total internal reflection (and exact grazing) returns 1.
 * eta <= 0 (not an index) returns 1. */
double fresnel_dielectric(double cos_i, double eta);

/* Exact unpolarised Fresnel reflectance of a conductor with complex index eta + i k
 * (relative to the outside medium), cos_i clamped to [0, 1] (|cos_i| is used: a conductor
 * is not entered). k = 0 and eta > 0 equals fresnel_dielectric(cos_i, eta). Negative eta or
 * k (bad input) are used by magnitude. */
double fresnel_conductor(double cos_i, double eta, double k);

#endif
