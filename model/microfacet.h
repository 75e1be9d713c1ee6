/* microfacet.h - Beckmann microfacet distribution and masking-shadowing terms.
 *
 * Usage:
 *   float d = microfacet_beckmann_d(n_h, m, CT_WALTER);            (4.12), per steradian of H
 *   float g = microfacet_vcavity_g(n_h, n_v, n_l, v_h);            (4.10)/(4.11)
 *   float s = microfacet_smith_g_walter(n_v, n_l, m);              Smith, as Cycles evaluates it
 *   double e = microfacet_smith_g_exact(n_v, n_l, m);              Smith, exact erf form
 * The formulas are formula.h's (formula_beckmann_d, formula_vcavity_g, formula_smith_g1_*),
 * shared with the SIMD lanes and the stability reference; these functions add the scalar
 * model's guards (NaN, delta limit, underflow) and evaluate them in double.
 * Arguments are cosines of unit directions pointing away from the surface; m is the
 * Beckmann roughness (RMS slope; Cycles' alpha). Pure functions, no cosine factor beyond
 * what each formula states. Every finite argument gives a finite, non-negative result
 * for m >= 0; a NaN argument propagates.
 */
#ifndef REFLCHECK_MICROFACET_H
#define REFLCHECK_MICROFACET_H

#include "formula.h"
#include "scene.h"

/* D never exceeds this (formula.h says why). */
#define MICROFACET_D_MAX FORMULA_D_MAX

/* (4.12) Beckmann. walter: exp(-tan^2/m^2) / (pi m^2 cos^4); ct1982: the same without pi.
 * cos_h <= 0 gives 0, cos_h > 1 is treated as 1. Evaluated in double in log space, so
 * exp underflow and 1/m^2 overflow cannot meet (m -> 0, m -> Inf, cos_h -> 0 are finite);
 * the result is capped at MICROFACET_D_MAX. m <= 0 is the delta limit: D_MAX at
 * cos_h = 1, else 0. Walter's D satisfies the integral of D(h) (N.H) over the hemisphere = 1.
 * cos_h is a double: near the peak of a sharp lobe tan^2 comes from 1 - cos_h, which cancels,
 * and a float cos_h's rounding (6e-8) over m^2 would move D by up to 5% at m = 0.001. */
float microfacet_beckmann_d(double cos_h, float m, ct_normalisation norm);

/* (4.10)/(4.11) V-cavity: min(1, 2 NH NV / VH, 2 NH NL / VH). A cosine <= 0 gives 0 (the
 * term is masked or shadowed), V.H <= 0 with positive cosines gives 1 (the VH -> 0+ limit);
 * no division happens unless the ratio is below 1, so VH -> 0 is safe. */
float microfacet_vcavity_g(float n_h, float n_v, float n_l, float v_h);

/* Smith G1 for Beckmann with Walter et al. 2007's rational approximation, exactly as
 * Cycles 3.4 (bsdf_beckmann_G1): a = 1/(m tan theta); 1 for a >= 1.6, else
 * (3.535 a + 2.181 a^2) / (1 + 2.276 a + 2.577 a^2). cos <= 0 gives 0, cos >= 1 gives 1. */
float microfacet_smith_g1_walter(float cos_theta, float m);

/* Exact Smith G1 for Beckmann: 2 / (1 + erf(a) + exp(-a^2) / (a sqrt(pi))), a = 1/(m tan).
 * cos <= 0 gives 0, cos >= 1 or m <= 0 gives 1. */
double microfacet_smith_g1_exact(double cos_theta, double m);

/* Separable Smith: G1(N.V) G1(N.L). */
float microfacet_smith_g_walter(float n_v, float n_l, float m);
double microfacet_smith_g_exact(double n_v, double n_l, double m);

/* GGX / Trowbridge-Reitz (Walter et al. 2007, eq. 33), of slope width alpha:
 * alpha^2 / (pi (alpha^2 cos^2 + sin^2)^2), the form 1/(pi alpha^2) at the peak; sin2_h and
 * cos2_h of N to H given apart (sin^2 from a cross product: 1 - cos^2 cancels at a sharp peak).
 * alpha <= 0 is the delta limit (MICROFACET_D_MAX at sin2_h = 0, else 0); capped at D_MAX. */
double microfacet_ggx_d(double sin2_h, double cos2_h, double alpha);
/* Smith G1 for GGX, exact (Walter et al. 2007, eq. 34): 2 / (1 + sqrt(1 + alpha^2 tan^2)), as
 * Cycles 3.4 evaluates it (bsdf_microfacet_ggx_eval_reflect). cos <= 0 gives 0, cos >= 1 gives 1. */
double microfacet_ggx_g1(double cos_theta, double alpha);
/* Separable Smith for GGX: G1(N.V) G1(N.L), Cycles 3.4's form (not the height-correlated one). */
double microfacet_ggx_g(double n_v, double n_l, double alpha);

/* Lambert BRDF with 1/pi, the radiometric reference: albedo / pi (no cosine). */
double microfacet_lambert_brdf(double albedo);

#endif
