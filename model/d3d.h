/* d3d.h - Direct3D fixed-function lighting factors (docs/models.md §1), one light at a time.
 *
 * Usage:
 *   float a  = d3d_attenuation(&light, d) * d3d_spot(&light, v3_norm(v3_sub(x, light.position)));
 *   float rd = d3d_lambert(v3_dot(n, l));
 *   vec3  h  = d3d_half_vector(l, v3_norm(v3_sub(eye, x)), e_inf, mat->d3d.local_viewer);
 *   float rs = d3d_blinn(v3_dot(n, h), mat->d3d.power);
 * The caller sums Dv = Ia Va + Ve + sum A (Rd Vd Ld + Va La) and Sv = sum A Rs Vs Ls.
 * The formulas are formula.h's (formula_attenuation, formula_spot_d3d, formula_spot_smooth,
 * formula_d3d_lambert, formula_blinn, formula_half_scale), shared with the SIMD lanes and the
 * stability reference; these functions read the light and add the scalar path's guards.
 * All factors are dimensionless and contain no 1/pi. Pure functions; a NaN argument
 * propagates, every finite argument gives a finite result.
 */
#ifndef REFLCHECK_D3D_H
#define REFLCHECK_D3D_H

#include "formula.h"
#include "scene.h"

/* The attenuation denominator never goes below this, so A <= 1e12 (formula.h says why). */
#define D3D_ATTEN_DENOM_MIN FORMULA_ATTEN_DENOM_MIN

/* 1/(a0 + a1 d + a2 d^2), computed in double (d^2 of a finite float cannot overflow there);
 * 0 for d > range; 1 for LIGHT_SUN. The denominator is clamped to D3D_ATTEN_DENOM_MIN, so
 * a0 = a1 = a2 = 0 gives 1e12, never Inf or NaN. */
float d3d_attenuation(const light *l, float d);

/* Spot factor for the unit direction from the light to the shaded point (1 for point and
 * sun lights). rho = dot(norm(l->direction), dir); inner/outer are full cone angles.
 * SPOT_D3D: 1 if rho > cos(inner/2), 0 if rho <= cos(outer/2), else
 *   ((rho - cos(outer/2)) / (cos(inner/2) - cos(outer/2)))^falloff; falloff < 0 is treated
 *   as 0 (a negative power is unbounded near the outer edge).
 * SPOT_SMOOTH: rho * smoothstep(t), t = the same ratio clamped to [0, 1], 0 for rho <= 0:
 *   POV-Ray's spotlight with tightness 1 and Cycles' spot_attenuation (the extra cos). */
float d3d_spot(const light *l, vec3 light_to_point_unit);

/* Rd = (N.L)+ clamped to [0, 1]. */
float d3d_lambert(float n_l);

/* Rs = ((N.H)+)^P, N.H clamped to [0, 1]. N.H <= 0 gives 0 for every P (no highlight from a
 * half vector below the surface, and d3d_half_vector's degenerate zero vector lands here).
 * P = 0 gives 1 for N.H > 0 (x^0 = 1, the P -> 0+ limit); "power 0 means specular off" is
 * a scene-level rule, not this function's. P < 0 (bad input) is treated as 0. */
float d3d_blinn(float n_h, float power);

/* D3D half vector H = norm(L + V): V = norm(v_local) (unit vector to the camera) when
 * local_viewer, else e_infinite (D3D's (0,0,-1) in view space, i.e. the unit vector from the
 * scene toward the camera along the view axis). L and V are normalised here. Returns the zero
 * vector (components +-0) when |L + V| < FORMULA_HALF_MIN (1e-6): L is then opposite V, H has
 * no defined direction and the light gives no highlight (d3d_blinn(+-0, P) = 0). */
vec3 d3d_half_vector(vec3 l, vec3 v_local, vec3 e_infinite, int local_viewer);

/* The material colours D3D lights a vertex with (D3DRS_COLORVERTEX and the four
 * D3DRS_*MATERIALSOURCE states): d with Va, Vd, Vs, Ve replaced by the vertex's colour1 or colour2
 * where d->colour_vertex is set and its source selects one the vertex has (have: bit 1 colour1,
 * bit 2 colour2); a missing colour keeps the material's. */
void d3d_vertex_colours(const d3d_params *d, unsigned have, vec3 colour1, vec3 colour2, d3d_params *out);
/* Whether those states make any of the four colours come from the vertex, given have. */
int d3d_uses_vertex_colours(const d3d_params *d, unsigned have);

#endif
