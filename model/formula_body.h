/* formula_body.h - the body of formula.h, compiled once per instance: formula.h includes it
 * four times, each after defining FORMULA_T (the type), FORMULA_FN (the name's suffix: _f, _d,
 * _v, _l), FORMULA_C (a literal's suffix), FORMULA_INLINE and the maths functions. Never include
 * it yourself: include formula.h. A name such as formula_schlick_d is FN(formula_schlick) here;
 * .ctags.d/formula.ctags teaches universal-ctags the four names of each, so `ctags -R` leads
 * formula_schlick_d to its line below. No include guard: it is meant to be read four times. */
#ifndef FORMULA_T
#error "formula_body.h is formula.h's body: include formula.h"
#endif

#define FT FORMULA_T
#define FN FORMULA_FN
#define FC FORMULA_C

/* ---- helpers ---------------------------------------------------------------------------- */

/* x clamped to [0, 1]; a NaN passes (every comparison with it is false). */
FORMULA_INLINE FT FN(formula_clamp01)(FT x) { return x < 0 ? 0 : (x > 1 ? 1 : x); }

/* x saturated to the float range +-FLT_MAX (the models' outputs are floats: a sum formed in a
 * wider type must not become Inf when narrowed); a NaN passes. */
FORMULA_INLINE FT FN(formula_sat)(FT x) { return x > FLT_MAX ? FLT_MAX : (x < -FLT_MAX ? -FLT_MAX : x); }

/* 1 - c with c clamped to [0, 1]: the base of the Fresnel powers (1) and (4.9). */
FORMULA_INLINE FT FN(formula_one_minus_cos)(FT cos_theta) { return 1 - FN(formula_clamp01)(cos_theta); }

/* ---- Fresnel (docs/models.md §2, §3) ------------------------------------------------------- */

/* (2) D3D9Client and (4.9) F0: R0 = ((1 - n)/(1 + n))^2 for a relative index n. 1 - n is exact
 * near n = 1 (Sterbenz), so R0 keeps full relative precision as n -> 1. n <= 0 (not an index)
 * and n = +Inf give 1, the limits n -> 0+ and n -> Inf. */
FORMULA_INLINE FT FN(formula_r0)(FT n)
{
    FT r = (1 - n) / (1 + n);
    return (n <= 0 || isinf(n)) ? 1 : r * r;
}

/* (4.9) Schlick's weight (1 - c)^5, c clamped to [0, 1]. */
FORMULA_INLINE FT FN(formula_schlick_weight)(FT cos_theta)
{
    FT x = FN(formula_one_minus_cos)(cos_theta), x2 = x * x;
    return x2 * x2 * x;
}

/* (4.9) Schlick: F = F0 + (1 - F0)(1 - c)^5; c is V.H for the lobe, N.V for the environment. */
FORMULA_INLINE FT FN(formula_schlick)(FT f0, FT cos_theta)
{
    return f0 + (1 - f0) * FN(formula_schlick_weight)(cos_theta);
}

#ifdef FORMULA_HYPOT
/* The exact references (docs/models.md §4), double and long double only: no SIMD lane needs them. */

/* Exact unpolarised Fresnel reflectance of a smooth dielectric, (Rs + Rp)/2, for cos_i in
 * [0, 1] and a relative index eta > 0 seen from the side the ray arrives on (the caller swaps
 * the media for a ray from inside). Total internal reflection (and exact grazing) gives 1.
 * sin_t from sin_i/eta rather than sin_i^2/eta^2, so a tiny eta cannot make 0/0. */
FORMULA_INLINE FT FN(formula_fresnel_dielectric)(FT cos_i, FT eta)
{
    FT sin_i = FORMULA_SQRT((1 - cos_i) * (1 + cos_i));
    FT sin_t = sin_i / eta;
    if (sin_t >= 1)
        return 1;
    FT cos_t = FORMULA_SQRT((1 - sin_t) * (1 + sin_t));
    /* Both denominators are > 0 here: cos_t > 0 because sin_t < 1, and eta > 0. */
    FT rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    FT rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    return FC(0.5) * (rs * rs + rp * rp);
}

/* Exact unpolarised Fresnel reflectance of a conductor with complex index eta + i k, c = |cos_i|
 * in [0, 1], eta and k >= 0: the standard real form of |r_s|^2 and |r_p|^2 (as in PBRT),
 * t0 = eta^2 - k^2 - sin^2, a^2 + b^2 = |t0 + 2 i eta k|, a = Re sqrt(t0 + 2 i eta k). */
FORMULA_INLINE FT FN(formula_fresnel_conductor)(FT c, FT eta, FT k)
{
    FT c2 = c * c;
    FT s2 = (1 - c) * (1 + c);
    FT t0 = eta * eta - k * k - s2;
    FT a2pb2 = FORMULA_HYPOT(t0, 2 * eta * k);
    FT h = FC(0.5) * (a2pb2 + t0);
    FT a = FORMULA_SQRT(h > 0 ? h : 0);
    FT t1 = a2pb2 + c2;
    FT t2 = 2 * c * a;
    /* t1 + t2 = 0 only at exact grazing with eta = 1, k = 0: the grazing limit is 1. */
    FT rs = t1 + t2 > 0 ? (t1 - t2) / (t1 + t2) : 1;
    FT t3 = c2 * a2pb2 + s2 * s2;
    FT t4 = t2 * s2;
    /* t3 + t4 = 0 only at normal incidence with eta = k = 0, where p equals s. */
    FT rp = t3 + t4 > 0 ? rs * (t3 - t4) / (t3 + t4) : rs;
    return FC(0.5) * (rs + rp);
}
#endif

/* The exponent of (1)/(3): p, with p < 0 (bad input) taken as 0, because (1 - c)^p would be
 * unbounded at normal incidence. */
FORMULA_INLINE FT FN(formula_d3d9_power)(FT p) { return p < 0 ? 0 : p; }

/* (1)/(3) D3D9Client: R = R0 + m (1 - cos)^p, with x_p = (1 - cos)^p, the power of
 * formula_one_minus_cos(cos) to formula_d3d9_power(p) as the instance evaluates it. (1) is
 * m = 1 - R0. */
FORMULA_INLINE FT FN(formula_d3d9_fresnel)(FT r0, FT m, FT x_p) { return r0 + m * x_p; }

/* ---- Direct3D fixed function (docs/models.md §1, source 003) ---------------------------------- */

/* Light attenuation over distance: A = 1/(a0 + a1 d + a2 d^2), 0 for d > range. d2 is d^2 as the
 * caller has it (the lanes' squared distance, or d*d). A zero coefficient adds nothing even at
 * d = Inf (0 * Inf would be NaN). The denominator is raised to FORMULA_ATTEN_DENOM_MIN, so
 * a0 = a1 = a2 = 0 gives 1e12, never Inf. */
FORMULA_INLINE FT FN(formula_attenuation)(FT a0, FT a1, FT a2, FT d, FT d2, FT range)
{
    FT den = a0 + (a1 != 0 ? a1 * d : 0) + (a2 != 0 ? a2 * d2 : 0);
    den = den < (FT)FORMULA_ATTEN_DENOM_MIN ? (FT)FORMULA_ATTEN_DENOM_MIN : den;
    return d > range ? 0 : 1 / den;
}

/* The spot's cone width cos(inner/2) - cos(outer/2), the falloff's denominator; 1 when the cones
 * coincide or cross (the edge is then hard and no ratio is taken). */
FORMULA_INLINE FT FN(formula_spot_cone)(FT cos_in, FT cos_out) { return cos_in > cos_out ? cos_in - cos_out : 1; }

/* Spotlight falloff model, rho = cos of the angle between the spot axis and the light-to-point
 * direction: 1 if rho > cos(inner/2), 0 if rho <= cos(outer/2), else
 * ((rho - cos_out) / (cos_in - cos_out))^falloff; falloff < 0 (bad input) is taken as 0 (a
 * negative power is unbounded at the outer edge). cone = formula_spot_cone(cos_in, cos_out). */
FORMULA_INLINE FT FN(formula_spot_d3d)(FT rho, FT cos_in, FT cos_out, FT cone, FT falloff)
{
    FT t = FN(formula_clamp01)((rho - cos_out) / cone);
    return rho > cos_in ? 1 : (rho <= cos_out ? 0 : FORMULA_POW(t, falloff < 0 ? 0 : falloff));
}

/* The smooth spot (POV-Ray's spotlight with tightness 1, Cycles' spot_attenuation): 0 outside
 * the outer cone or for rho <= 0, rho inside the inner cone, else rho smoothstep(t). */
FORMULA_INLINE FT FN(formula_spot_smooth)(FT rho, FT cos_in, FT cos_out, FT cone)
{
    FT t = (rho - cos_out) / cone;
    return ((rho <= 0) | (rho <= cos_out)) ? 0 : (rho >= cos_in ? rho : rho * t * t * (3 - 2 * t));
}

/* Diffuse reflectance factor Rd = (N.L)+, clamped to [0, 1]: it IS the cosine, no 1/pi (the D3D
 * light colour is E/pi). */
FORMULA_INLINE FT FN(formula_d3d_lambert)(FT n_l) { return n_l <= 0 ? 0 : (n_l > 1 ? 1 : n_l); }

/* Specular reflectance factor Rs = ((N.H)+)^P, N.H clamped to [0, 1]; no N.L inside (the D3D
 * model multiplies none in; the caller lights nothing from behind). N.H <= 0 gives 0 for every P;
 * P = 0 gives 1 for N.H > 0 (x^0 = 1); P < 0 (bad input) is taken as 0. */
FORMULA_INLINE FT FN(formula_blinn)(FT n_h, FT power)
{
    return n_h <= 0 ? 0 : FORMULA_POW(n_h > 1 ? 1 : n_h, power < 0 ? 0 : power);
}

/* The half vector's scale: H = (L + V) / |L + V| for unit L and V, i.e. 1/|L + V|, or 0 when
 * |L + V| < FORMULA_HALF_MIN (the zero-length guard: H is then the zero vector). */
FORMULA_INLINE FT FN(formula_half_scale)(FT len) { return len >= (FT)FORMULA_HALF_MIN ? 1 / len : 0; }

/* ---- Cook-Torrance microfacet terms (docs/models.md §3, source 004) ------------------------- */

/* The zero-cosine guard: a positive cosine raised to FORMULA_COS_MIN. */
FORMULA_INLINE FT FN(formula_cos_floor)(FT c) { return c < (FT)FORMULA_COS_MIN ? (FT)FORMULA_COS_MIN : c; }

/* ln of (4.12)'s normalisation: -2 ln m - ln pi (walter), -2 ln m (ct1982, no pi). */
FORMULA_INLINE FT FN(formula_beckmann_log_norm)(FT m, int walter)
{
    return -2 * FORMULA_LOG(m) - (walter ? FORMULA_LOG(FC(FORMULA_PI_DIGITS)) : 0);
}

/* (4.12) Beckmann D = exp(-tan^2 / m^2) / ([pi] m^2 cos^4), per steradian of H, from sin^2 and
 * cos^2 of the angle between N and H (tan^2 = sin^2 / cos^2: the caller forms sin^2 where it is
 * accurate, (1 - c)(1 + c) or |N x H|^2). inv_m2 = 1/m^2, log_norm = formula_beckmann_log_norm.
 * In log space, so exp's underflow and 1/m^2's overflow never meet; capped at FORMULA_D_MAX. No
 * cosine of the light inside. cos2 > 0 and m > 0 are the caller's. */
FORMULA_INLINE FT FN(formula_beckmann_d)(FT sin2, FT cos2, FT inv_m2, FT log_norm)
{
    FT log_d = -(sin2 / cos2) * inv_m2 + log_norm - 2 * FORMULA_LOG(cos2);
    return log_d >= FORMULA_LN_D_MAX ? (FT)FORMULA_D_MAX : FORMULA_EXP(log_d);
}

/* (4.10)/(4.11) V-cavity masking-shadowing: G = min(1, 2 NH NV / VH, 2 NH NL / VH); 0 when a
 * cosine is <= 0 (masked or shadowed); V.H <= 0 with positive cosines gives 1 (the VH -> 0+
 * limit): a ratio is taken only where it is below the running minimum <= 1, which implies
 * V.H > 0. */
FORMULA_INLINE FT FN(formula_vcavity_g)(FT n_h, FT n_v, FT n_l, FT v_h)
{
    FT tv = 2 * n_h * n_v, tl = 2 * n_h * n_l;
    FT inv_vh = v_h > 0 ? 1 / v_h : 0;
    FT g = 1;
    g = tv < g * v_h ? tv * inv_vh : g;
    g = tl < g * v_h ? tl * inv_vh : g;
    /* One select per cosine: an & of the three comparisons kept GCC 12 from vectorising the lane
     * loop around it. */
    g = n_l > 0 ? g : 0;
    g = n_v > 0 ? g : 0;
    return n_h > 0 ? g : 0;
}

/* Smith G1 for Beckmann with Walter et al. 2007's rational approximation, as Cycles 3.4
 * (bsdf_beckmann_G1): a = 1/(m tan theta); 1 for a >= 1.6, else
 * (3.535 a + 2.181 a^2) / (1 + 2.276 a + 2.577 a^2). cos <= 0 gives 0, cos >= 1 or m <= 0 gives 1. */
FORMULA_INLINE FT FN(formula_smith_g1_walter)(FT c, FT m)
{
    FT cc = c > 1 ? 1 : c;
    FT inv_a = m * (FORMULA_SQRT((1 - cc) * (1 + cc)) / (c > 0 ? c : 1));
    FT a = inv_a > 0 ? 1 / inv_a : 0;
    FT g = ((FC(2.181) * a + FC(3.535)) * a) / ((FC(2.577) * a + FC(2.276)) * a + 1);
    g = inv_a < (FT)FORMULA_WALTER_INV_A_MAX ? 1 : g;
    return c <= 0 ? 0 : (c >= 1 ? 1 : g);
}

#ifdef FORMULA_ERF
/* Exact Smith G1 for Beckmann: 2 / (1 + erf(a) + exp(-a^2) / (a sqrt(pi))), a = 1/(m tan).
 * cos <= 0 gives 0, cos >= 1 or m <= 0 gives 1. For a > 26 exp(-a^2) underflows and erf(a)
 * rounds to 1 in double: G1 = 1; for tiny a the last term is large but finite. */
FORMULA_INLINE FT FN(formula_smith_g1_exact)(FT c, FT m)
{
    if (c <= 0)
        return 0;
    if (c >= 1 || m <= 0)
        return 1;
    FT x = m * (FORMULA_SQRT((1 - c) * (1 + c)) / c);
    if (x <= 0)
        return 1;
    if (isinf(x))
        return 0;
    FT a = 1 / x;
    return 2 / (1 + FORMULA_ERF(a) + FORMULA_EXP(-a * a) / (a * FORMULA_SQRT(FC(FORMULA_PI_DIGITS))));
}
#endif

/* (4.8)'s k: 4 for Walter's normalisation, pi for Cook and Torrance 1982. */
FORMULA_INLINE FT FN(formula_ct_k)(int walter) { return walter ? 4 : FC(FORMULA_PI_DIGITS); }

/* (4.8) times (N.L): CT_s (N.L) = F D G / (k N.V) without F (the caller's per-channel factor).
 * INCLUDES the cosine of the light (its (N.L) cancels). n_v > 0 (formula_cos_floor). */
FORMULA_INLINE FT FN(formula_ct_lobe)(FT d, FT g, FT k, FT n_v) { return d * g / (k * n_v); }

/* Lambert BRDF with 1/pi, the radiometric reference: albedo / pi, no cosine. */
FORMULA_INLINE FT FN(formula_lambert_brdf)(FT albedo) { return albedo / FC(FORMULA_PI_DIGITS); }

/* ---- D3D9Client reflection (docs/models.md §2, sources 000/001) -------------------------------- */

/* |c| of a colour as weights fixed per norm (formula_norm_weights in the model file):
 * w_max max(c) + w . c + w_euclid |c|_2, one of them non-zero, so a lane loop has no switch.
 * |c|_2 is scaled by the largest magnitude, so squares of HDR values cannot overflow. */
FORMULA_INLINE FT FN(formula_colour_norm)(FT r, FT g, FT b, FT w_max, FT w_r, FT w_g, FT w_b, FT w_euclid)
{
    FT mgb = g > b ? g : b, mx = r > mgb ? r : mgb;
    FT ar = r < 0 ? -r : r, ag = g < 0 ? -g : g, ab = b < 0 ? -b : b;
    FT agb = ag > ab ? ag : ab, a = ar > agb ? ar : agb;
    FT s = a > 0 ? 1 / a : 0;
    FT ur = r * s, ug = g * s, ub = b * s;
    FT euclid = a * FORMULA_SQRT(ur * ur + ug * ug + ub * ub);
    return w_max * mx + (w_r * r + w_g * g + w_b * b) + w_euclid * euclid;
}

/* (4)/(5), one channel: R_tot = (lambda (1 - R) + s R) phi; lambda the metallic colour, s the
 * Fresnel colour, R of (3) at N.V, phi the radiance along the mirror direction. */
FORMULA_INLINE FT FN(formula_d3d9_r_tot)(FT lambda, FT s, FT R, FT phi) { return (lambda * (1 - R) + s * R) * phi; }

/* (6)'s diffuse weight 1 - |lambda|, unclamped (a norm that exceeds 1 makes it negative). */
FORMULA_INLINE FT FN(formula_d3d9_diffuse_weight)(FT norm_lambda) { return 1 - norm_lambda; }

/* (8)'s sun factor 1 - R(sigma) = 1 - R0 - m (1 - cos sigma)^p, from R of (3) at cos sigma. */
FORMULA_INLINE FT FN(formula_d3d9_sun_factor)(FT r_sun) { return 1 - r_sun; }

/* (6)/(8), one channel: c = d w + R_tot, w the diffuse weight (times (8)'s sun factor). */
FORMULA_INLINE FT FN(formula_d3d9_colour)(FT d, FT w, FT r_tot) { return d * w + r_tot; }

/* (7) c_a = max(d_a, |R_tot|). */
FORMULA_INLINE FT FN(formula_d3d9_alpha)(FT d_alpha, FT norm_r_tot)
{
    return d_alpha > norm_r_tot ? d_alpha : norm_r_tot;
}

/* ---- D3D9Client Dissolve (source 000; our reading of its shader, docs/dissolve.md) ----------- */

/* One texel coordinate of the noise texture read at t (u or v) times scale: x = t scale SIZE -
 * 1/2 in texels (texel centres at (i + 1/2)/SIZE, as scene/texture.c's), its whole part wrapped
 * to [0, SIZE) (repeat) in *i0, the next texel in *i1, the bilinear weight of *i1 returned. */
FORMULA_INLINE FT FN(formula_dissolve_coord)(FT t, FT scale, uint32_t *i0, uint32_t *i1)
{
    FT x = t * scale * (FT)FORMULA_DISSOLVE_SIZE - FC(0.5);
    x = (x > -(FT)FORMULA_DISSOLVE_COORD_MAX && x < (FT)FORMULA_DISSOLVE_COORD_MAX) ? x : 0;
    FT xf = FORMULA_FLOOR(x);
    int32_t k = (int32_t)xf;
    *i0 = (uint32_t)k & (FORMULA_DISSOLVE_SIZE - 1);
    *i1 = (uint32_t)(k + 1) & (FORMULA_DISSOLVE_SIZE - 1);
    return x - xf;
}

/* Dissolve, one component: the offset added to the mirror direction reflect(-V, N) before the
 * environment lookup, (t - 1/2) strength, t channel ch of the noise texture read bilinearly,
 * wrapping, at (u scale, v scale) (the texel's j counts up in v). If either parameter is 0 the
 * effect is off (the source): the offset is 0 (scale 0 alone would read one constant texel). */
FORMULA_INLINE FT FN(formula_dissolve_offset_on)(FT u, FT v, FT scale, FT strength, uint32_t ch)
{
    uint32_t i0, i1, j0, j1;
    FT a = FN(formula_dissolve_coord)(u, scale, &i0, &i1);
    FT b = FN(formula_dissolve_coord)(v, scale, &j0, &j1);
    FT t = (1 - b) * ((1 - a) * (FT)formula_dissolve_texel(i0, j0, ch) + a * (FT)formula_dissolve_texel(i1, j0, ch)) +
           b * ((1 - a) * (FT)formula_dissolve_texel(i0, j1, ch) + a * (FT)formula_dissolve_texel(i1, j1, ch));
    return (t - FC(0.5)) * strength;
}
/* formula_dissolve_offset_on is the offset where the effect is on (both parameters above 0);
 * a lane loop tests that once, before it: a select on a loop-invariant condition inside it
 * kept GCC 12 from vectorising the loop. */
FORMULA_INLINE FT FN(formula_dissolve_offset)(FT u, FT v, FT scale, FT strength, uint32_t ch)
{
    return (scale > 0 && strength > 0) ? FN(formula_dissolve_offset_on)(u, v, scale, strength, ch) : 0;
}

#undef FT
#undef FN
#undef FC
#undef FORMULA_T
#undef FORMULA_FN
#undef FORMULA_C
#undef FORMULA_INLINE
#undef FORMULA_POW
#undef FORMULA_LOG
#undef FORMULA_EXP
#undef FORMULA_SQRT
#undef FORMULA_FLOOR
#undef FORMULA_ERF
#undef FORMULA_HYPOT
#undef FORMULA_LN_D_MAX
