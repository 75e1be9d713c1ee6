/* cooktorrance.h - Cook-Torrance metal shader (docs/models.md §3): the specular lobe and
 * the environment reflection weight, per RGB channel.
 *
 * Usage:
 *   vec3 s  = cooktorrance_specular(&mat->ct, n, v, l, mat);   times Ls / d^2 -> radiance
 *   vec3 fr = cooktorrance_reflection_weight(&mat->ct, v3_dot(n, v), mat);  times CM(reflect(-V, N))
 * n, v, l: directions away from the surface (normal, to the viewer, to the light); they are
 * normalised here, so any positive length works; a zero vector gives 0.
 * cooktorrance_specular INCLUDES the cosine: it returns ks CT_s (N.L)+ = ks F D G / (k N.V),
 * with CT_s = F D G / (k (N.L)(N.V)) of (4.8). The diffuse term Kd Ld (N.L)+ / d^2 is the
 * caller's. mat is read only for F_EXACT (dielectric from mat->ior, or the conductor's
 * eta + i k per channel when mat->conductor); NULL there falls back to Schlick with p->f0.
 * The lobe's formulas are formula.h's (formula_ct_lobe, formula_ct_k, formula_cos_floor,
 * formula_half_scale and the microfacet and Fresnel terms), shared with the SIMD lanes and the
 * stability reference; this file orders the guards and evaluates them in double.
 * Pure functions; every finite argument gives a finite result (each channel capped at
 * +-COOKTORRANCE_MAX); a NaN argument propagates.
 */
#ifndef REFLCHECK_COOKTORRANCE_H
#define REFLCHECK_COOKTORRANCE_H

#include "formula.h"
#include "scene.h"

/* Output cap (formula.h's FORMULA_CT_MAX says why). */
#define COOKTORRANCE_MAX FORMULA_CT_MAX

/* Guards, in this order:
 *  1. hemisphere: N.L <= 0 or N.V <= 0 gives 0 (light behind, or surface seen from behind);
 *  2. zero cosines: N.V and N.L are raised to COOKTORRANCE_COS_MIN (1e-6) before any use,
 *     since below that a unit vector's cosine is float rounding noise (~1e-7) and the exact
 *     lobe, F D G / (k N.V), has a finite limit there that the clamp approaches;
 *  3. zero-length half vector: |L + V| < 1e-6 gives 0 (L opposite V: no defined H, and
 *     with guard 1 passed both vectors graze the surface);
 *  4. then H = norm(L + V), N.H, V.H, and F, D, G, k as p selects:
 *     F: F_SCHLICK Schlick(V.H) with p->f0, F_ONE 1, F_EXACT exact Fresnel of V.H (double);
 *     D: Beckmann(N.H, p->m) with p->norm; G: p->g (vcavity, Smith Walter, Smith exact);
 *     k = 4 for CT_WALTER, pi for CT_CT1982. Result times p->ks. */
#define COOKTORRANCE_COS_MIN FORMULA_COS_MIN
vec3 cooktorrance_specular(const ct_params *p, vec3 n, vec3 v, vec3 l, const material *mat);

/* Fr for the environment reflection: Schlick(N.V) with p->f0 (F_SCHLICK), 1 (F_ONE), or the
 * exact Fresnel at N.V (F_EXACT). N.V clamped to [0, 1]. Not multiplied by p->ks (ks scales
 * the specular lobe only). */
vec3 cooktorrance_reflection_weight(const ct_params *p, float n_v, const material *mat);

#endif
