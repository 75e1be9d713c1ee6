/* formula.h: the float (_f), lane (_v), double (_d) and long double (_l) instances of every
 * formula agree on asymmetric inputs within tolerances derived below, and a few formulas give the
 * values worked out by hand.
 *
 * Tolerances. Inputs are floats, so every instance sees the same numbers and the long double
 * instance is the reference (its own error, 2^-64 per operation, is 2^-40 of a float ulp). A
 * formula of k roundings with no cancellation (the inputs below keep 1 - c and rho - cos_out away
 * from it) is within k u of the exact value, u = 2^-24 in float (6e-8) and 2^-53 in double
 * (1.1e-16); each check states its k, with a factor for what amplifies it:
 *  - smath_pow (the lanes' pow) is within 4e-6 relative for p <= 1 and 1.7e-5 for p up to 1e4
 *    (smath.h, measured by test_smath.c); powf and pow are within 1 ulp (glibc);
 *  - Beckmann: D = exp(log_d) turns an absolute error e of log_d into a relative error e of D;
 *    log_d's terms are at most L = 60 in magnitude here, each with a few roundings, so
 *    e <= 8 L u, plus exp's own error (smath_exp 1.2e-7, expf/exp/expl 1 ulp) and smath_log's
 *    2.3e-7 relative, times 2 (the 2 ln cos^2 term).
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <cmocka.h>

#include "check.h"

#include <float.h>
#include <math.h>

#include "formula.h"

#define U_F              0x1p-24
#define U_D              0x1p-53
#define SMATH_POW_REL_P1 4e-6   /* smath_pow, p <= 1 (smath.h) */
#define SMATH_POW_REL    1.7e-5 /* smath_pow, p up to 1e4 (smath.h) */
#define SAMPLES          20000

/* A small LCG: asymmetric, reproducible inputs without libc's rand. */
static uint64_t lcg_state = 0x9E3779B97F4A7C15ull;
static float rnd(double lo, double hi)
{
    lcg_state = lcg_state * 6364136223846793005ull + 1442695040888963407ull;
    double u = (double)(lcg_state >> 11) * 0x1p-53;
    return (float)(lo + (hi - lo) * u);
}

/* |got - ref| <= rel |ref| + abs_floor; the floor only where a formula subtracts (stated). */
static void agree(const char *what, int i, long double got, long double ref, double rel, double abs_floor)
{
    long double err = fabsl(got - ref);
    if (!(err <= (long double)rel * fabsl(ref) + (long double)abs_floor))
        fail_msg("%s sample %d: got %.17Lg, reference %.17Lg, error %.3Lg > %.3g rel + %.3g", what, i, got, ref, err,
                 rel, abs_floor);
}

/* The constants each instance rounds from one literal, and the lane's literal ln(1e12f). */
static void test_constants(void **state)
{
    (void)state;
    assert_true((float)FORMULA_PI_D == FORMULA_PI_F);
    assert_true((double)FORMULA_PI_L == FORMULA_PI_D);
    assert_true(FORMULA_INV_PI_F == (float)(1.0 / FORMULA_PI_D));
    assert_true(27.6310211f == logf(FORMULA_D_MAX));
    assert_true((float)log((double)FORMULA_D_MAX) == 27.6310211f);
    /* The thresholds are double literals; the float instances use them rounded once. */
    assert_true((float)FORMULA_HALF_MIN == 1e-6f);
    assert_true((float)FORMULA_COS_MIN == 1e-6f);
    assert_true((float)FORMULA_ATTEN_DENOM_MIN == 1e-12f);
}

/* Values worked out by hand (each comment shows the arithmetic). */
static void test_hand_values(void **state)
{
    (void)state;
    /* (2): ((1 - 1.5)/(1 + 1.5))^2 = (-0.2)^2 = 0.04 */
    close_rel(formula_r0_l(1.5L), 0.04, 1e-18);
    /* (4.9): 0.04 + 0.96 (1 - 0.5)^5 = 0.04 + 0.96/32 = 0.07 */
    close_rel(formula_schlick_d(0.04, 0.5), 0.07, 4 * U_D);
    /* (3): 0.1 + 0.9 * 0.5^3 = 0.2125 */
    close_rel(formula_d3d9_fresnel_d(0.1, 0.9, pow(formula_one_minus_cos_d(0.5), 3.0)), 0.2125, 4 * U_D);
    /* (4.12) at N = H: 1/(pi m^2), m = 0.5: 4/pi = 1.2732395447351628 */
    close_rel(formula_beckmann_d_d(0.0, 1.0, 4.0, formula_beckmann_log_norm_d(0.5, 1)), 1.2732395447351628, 1e-14);
    /* (4.12) at 45 degrees, m = 1: exp(-1)/(pi * 1 * cos^4) = 0.36787944 / (pi / 4) = 0.46839865 */
    close_rel(formula_beckmann_d_d(0.5, 0.5, 1.0, formula_beckmann_log_norm_d(1.0, 1)), 0.46839865219455334, 1e-14);
    /* ct1982: the same without pi: exp(-1) / 0.25 = 1.4715177646857693 */
    close_rel(formula_beckmann_d_d(0.5, 0.5, 1.0, formula_beckmann_log_norm_d(1.0, 0)), 1.4715177646857693, 1e-14);
    /* (4.10)/(4.11): 2 0.9 0.5 / 0.95 = 0.947368..., 2 0.9 0.8 / 0.95 = 1.5158 -> 0.94736842 */
    close_rel(formula_vcavity_g_d(0.9, 0.5, 0.8, 0.95), 0.9 / 0.95, 4 * U_D);
    assert_true(formula_vcavity_g_d(0.9, 0.5, 0.8, 0.6) == 1.0);  /* both ratios above 1 */
    assert_true(formula_vcavity_g_d(0.9, -0.1, 0.8, 0.6) == 0.0); /* masked */
    /* Walter G1, c = 0.5, m = 0.5: a = 1/(0.5 tan 60deg) = 1.1547005, a^2 = 4/3;
     * (3.535 a + 2.181 a^2) / (1 + 2.276 a + 2.577 a^2) = 6.9898663 / 7.0641 = 0.98949165 */
    close_rel(formula_smith_g1_walter_d(0.5, 0.5), 0.9894916495056011, 1e-14);
    /* Exact G1 at the same point: 2 / (1 + erf(a) + exp(-a^2)/(a sqrt pi)) = 0.98700909 */
    close_rel(formula_smith_g1_exact_d(0.5, 0.5), 0.9870090905029527, 1e-14);
    /* Attenuation: 1/(1 + 0.5 2 + 0.25 4) = 1/3; beyond the range 0 */
    close_rel(formula_attenuation_d(1.0, 0.5, 0.25, 2.0, 4.0, 10.0), 1.0 / 3.0, 2 * U_D);
    assert_true(formula_attenuation_d(1.0, 0.5, 0.25, 20.0, 400.0, 10.0) == 0.0);
    /* a0 = a1 = a2 = 0: the floored denominator, 1e12; d = Inf with a zero a1 adds nothing */
    close_rel(formula_attenuation_d(0.0, 0.0, 0.0, 1.0, 1.0, 10.0), 1e12, 2 * U_D);
    close_rel(formula_attenuation_d(2.0, 0.0, 0.0, INFINITY, INFINITY, INFINITY), 0.5, 0.0);
    /* D3D spot: cos_in 0.9, cos_out 0.7, rho 0.8: t = 0.1/0.2 = 0.5, t^2 = 0.25 */
    close_rel(formula_spot_d3d_d(0.8, 0.9, 0.7, formula_spot_cone_d(0.9, 0.7), 2.0), 0.25, 8 * U_D);
    /* smooth: 0.8 * 0.5^2 * (3 - 1) = 0.4 */
    close_rel(formula_spot_smooth_d(0.8, 0.9, 0.7, formula_spot_cone_d(0.9, 0.7)), 0.4, 8 * U_D);
    /* Lambert and Blinn: 0.5^3 = 0.125; below the surface 0 */
    assert_true(formula_d3d_lambert_f(1.5f) == 1.0f && formula_d3d_lambert_f(-0.5f) == 0.0f);
    close_rel(formula_blinn_f(0.5f, 3.0f), 0.125, 2 * U_F);
    assert_true(formula_blinn_v(-0.5f, 3.0f) == 0.0f && formula_blinn_v(0.5f, 0.0f) == 1.0f);
    /* Cook-Torrance lobe: 2 * 0.5 / (4 * 0.25) = 1; ct1982's k = pi */
    close_rel(formula_ct_lobe_d(2.0, 0.5, formula_ct_k_d(1), 0.25), 1.0, 2 * U_D);
    close_rel(formula_ct_k_l(0), 3.14159265358979323846, 1e-18);
    /* (5): (0.5 (1 - 0.2) + 1 * 0.2) * 2 = 1.2; (6): 0.5 * 0.25 + 1.2 = 1.325; (7) */
    close_rel(formula_d3d9_r_tot_d(0.5, 1.0, 0.2, 2.0), 1.2, 4 * U_D);
    close_rel(formula_d3d9_colour_d(0.5, formula_d3d9_diffuse_weight_d(0.75), 1.2), 1.325, 4 * U_D);
    assert_true(formula_d3d9_alpha_d(0.3, 1.2) == 1.2 && formula_d3d9_alpha_d(0.3, 0.1) == 0.3);
    /* |(0.3, 0.6, 0.9)|: max 0.9, mean 0.6, Rec. 709 0.55788, euclid sqrt(1.26) = 1.1224972 */
    close_rel(formula_colour_norm_d(0.3, 0.6, 0.9, 1, 0, 0, 0, 0), 0.9, 0.0);
    close_rel(formula_colour_norm_d(0.3, 0.6, 0.9, 0, 1.0 / 3, 1.0 / 3, 1.0 / 3, 0), 0.6, 4 * U_D);
    close_rel(formula_colour_norm_d(0.3, 0.6, 0.9, 0, 0.2126, 0.7152, 0.0722, 0), 0.55788, 4 * U_D);
    close_rel(formula_colour_norm_d(0.3, 0.6, 0.9, 0, 0, 0, 0, 1), 1.1224972160321824, 8 * U_D);
    /* Exact Fresnel at normal incidence: ((1 - 1.5)/(1 + 1.5))^2 = 0.04 for the dielectric and
     * for the conductor with k = 0; a perfect conductor (k -> Inf) reflects everything. */
    close_rel(formula_fresnel_dielectric_d(1.0, 1.5), 0.04, 8 * U_D);
    close_rel(formula_fresnel_conductor_d(1.0, 1.5, 0.0), 0.04, 8 * U_D);
    close_rel(formula_fresnel_conductor_l(1.0L, 0.0L, 1e6L), 1.0, 1e-11);
    /* Total internal reflection: from inside glass (eta = 1/1.5) beyond 41.8 degrees */
    assert_true(formula_fresnel_dielectric_d(cos(deg(60.0)), 1.0 / 1.5) == 1.0);
    /* Lambert BRDF: 1/pi */
    close_rel(formula_lambert_brdf_d(1.0), 0.31830988618379067, 2 * U_D);
}

/* Every instance against the long double one. */
static void test_instances_agree(void **state)
{
    (void)state;
    for (int i = 0; i < SAMPLES; i++) {
        /* (2) from n in [1.05, 4]: 1 - n exact (Sterbenz, n <= 2) or one rounding, then 1 + n,
         * the quotient and the square (twice the quotient's error): k = 6. */
        float n = rnd(1.05, 4.0);
        agree("r0 _d", i, formula_r0_d(n), formula_r0_l(n), 6 * U_D, 0);
        /* (4.9): c in [0.02, 0.98], f0 in [0.01, 0.9]: weight 4 roundings after the exact or
         * 1-rounding 1 - c (5 u relative per factor of x^5 -> 5 u), then 3 more: k = 12. */
        float c = rnd(0.02, 0.98), f0 = rnd(0.01, 0.9);
        long double sl = formula_schlick_l(f0, c);
        agree("schlick _f", i, formula_schlick_f(f0, c), sl, 12 * U_F, 0);
        agree("schlick _v", i, formula_schlick_v(f0, c), sl, 12 * U_F, 0);
        agree("schlick _d", i, formula_schlick_d(f0, c), sl, 12 * U_D, 0);
        /* (3) with the instance's pow: p in [0.5, 8]; x^p inherits p times x's relative error
         * (<= 8 u), plus the pow's own: smath 1.7e-5, libm 1 ulp; then 2 roundings. */
        float r0 = rnd(0.0, 0.25), m = rnd(0.1, 1.0), p = rnd(0.5, 8.0);
        long double rl = formula_d3d9_fresnel_l(r0, m, powl(formula_one_minus_cos_l(c), p));
        agree("d3d9 _v", i, formula_d3d9_fresnel_v(r0, m, smath_pow(formula_one_minus_cos_v(c), p)), rl,
              SMATH_POW_REL + 12 * U_F, 0);
        agree("d3d9 _f", i, formula_d3d9_fresnel_f(r0, m, powf(formula_one_minus_cos_f(c), p)), rl, 12 * U_F, 0);
        agree("d3d9 _d", i, formula_d3d9_fresnel_d(r0, m, pow(formula_one_minus_cos_d(c), p)), rl, 12 * U_D, 0);

        /* (4.12): cos_h in [0.55, 1] and m in [0.2, 1] keep tan^2 <= 2.31 and tan^2/m^2 <= 58, so
         * |log_d| <= L = 60 and D stays far from the cap and from underflow: e = 8 L u. */
        float ch = rnd(0.55, 1.0), mm = rnd(0.2, 1.0);
        float s2 = (1.0f - ch) * (1.0f + ch), c2 = ch * ch;
        int walter = i & 1;
        long double dl =
            formula_beckmann_d_l(s2, c2, 1.0L / ((long double)mm * mm), formula_beckmann_log_norm_l(mm, walter));
        agree("beckmann _v", i,
              formula_beckmann_d_v(s2, c2, 1.0f / (mm * mm), (float)formula_beckmann_log_norm_d(mm, walter)), dl,
              8 * 60 * U_F + 1.2e-7 + 2 * 2.3e-7, 0);
        agree("beckmann _f", i, formula_beckmann_d_f(s2, c2, 1.0f / (mm * mm), formula_beckmann_log_norm_f(mm, walter)),
              dl, 8 * 60 * U_F + 2 * U_F, 0);
        agree("beckmann _d", i,
              formula_beckmann_d_d(s2, c2, 1.0 / ((double)mm * mm), formula_beckmann_log_norm_d(mm, walter)), dl,
              8 * 60 * U_D + 2 * U_D, 0);

        /* (4.10)/(4.11): products and one reciprocal, k = 4 (a select picks 1 exactly). */
        float nh = rnd(0.01, 1.0), nv = rnd(0.01, 1.0), nl = rnd(0.01, 1.0), vh = rnd(0.01, 1.0);
        long double gl = formula_vcavity_g_l(nh, nv, nl, vh);
        agree("vcavity _v", i, formula_vcavity_g_v(nh, nv, nl, vh), gl, 4 * U_F, 0);
        agree("vcavity _d", i, formula_vcavity_g_d(nh, nv, nl, vh), gl, 4 * U_D, 0);

        /* Walter G1: c in [0.05, 0.98]; sqrt((1 - c)(1 + c)) 3 roundings (+ 1 - c), /c, m*, 1/:
         * a within 6 u; the rational has positive terms: 9 more. k = 16; near the branch point
         * 0.625 an instance may pick the other side: the rational there is 0.99977, within
         * 2.3e-4 of 1 (absolute floor). */
        float cg = rnd(0.05, 0.98), mg = rnd(0.05, 1.5);
        long double wl = formula_smith_g1_walter_l(cg, mg);
        agree("walter _v", i, formula_smith_g1_walter_v(cg, mg), wl, 16 * U_F, 2.3e-4);
        agree("walter _d", i, formula_smith_g1_walter_d(cg, mg), wl, 16 * U_D, 2.3e-4);
        agree("exact G1 _d", i, formula_smith_g1_exact_d(cg, mg), formula_smith_g1_exact_l(cg, mg), 64 * U_D, 0);

        /* Attenuation: sums of positive terms and one reciprocal, k = 6. */
        float a0 = rnd(0.0, 2.0), a1 = rnd(0.0, 1.0), a2 = rnd(0.0, 1.0), d = rnd(0.1, 50.0);
        float d2 = d * d;
        long double al = formula_attenuation_l(a0, a1, a2, d, d2, 40.0f);
        agree("attenuation _v", i, formula_attenuation_v(a0, a1, a2, d, d2, 40.0f), al, 6 * U_F, 0);
        agree("attenuation _d", i, formula_attenuation_d(a0, a1, a2, d, d2, 40.0f), al, 6 * U_D, 0);

        /* Spots: cos_out in [0.5, 0.8], cos_in 0.05..0.15 above; rho anywhere near. t carries
         * rho - cos_out's rounding relative to itself: keep rho at least 0.01 from cos_out
         * (|t| error <= 2 u (cos_in - cos_out)/0.01 <= 30 u), times falloff (<= 4) for the power. */
        float co = rnd(0.5, 0.8), ci = co + rnd(0.05, 0.15), rho = rnd(0.4, 0.999), fo = rnd(0.0, 4.0);
        if (fabsf(rho - co) >= 0.01f) {
            float cone = formula_spot_cone_f(ci, co);
            long double conel = formula_spot_cone_l(ci, co);
            long double spl = formula_spot_d3d_l(rho, ci, co, conel, fo);
            agree("spot d3d _v", i, formula_spot_d3d_v(rho, ci, co, cone, fo), spl, SMATH_POW_REL + 4 * 34 * U_F, 0);
            agree("spot d3d _d", i, formula_spot_d3d_d(rho, ci, co, formula_spot_cone_d(ci, co), fo), spl, 4 * 34 * U_D,
                  0);
            long double sml = formula_spot_smooth_l(rho, ci, co, conel);
            agree("spot smooth _v", i, formula_spot_smooth_v(rho, ci, co, cone), sml, 3 * 34 * U_F, 0);
            agree("spot smooth _d", i, formula_spot_smooth_d(rho, ci, co, formula_spot_cone_d(ci, co)), sml,
                  3 * 34 * U_D, 0);
        }

        /* Blinn: x^P with x in [0.02, 1] exact input: the pow's own error (P up to 1e4). */
        float nhb = rnd(0.02, 1.0), pw = rnd(0.0, 100.0);
        long double bl = formula_blinn_l(nhb, pw);
        agree("blinn _v", i, formula_blinn_v(nhb, pw), bl, SMATH_POW_REL, 1e-37);
        agree("blinn _f", i, formula_blinn_f(nhb, pw), bl, 2 * U_F, 1e-37);
        agree("d3d lambert _f", i, formula_d3d_lambert_f(nhb), formula_d3d_lambert_l(nhb), 0, 0);

        /* D3D9Client (4)-(7): positive terms, k = 4 for R_tot, 2 for the colour; the norms: max
         * exact, weighted sums k = 5, euclid (scaled) k = 8. */
        float lam = rnd(0.0, 1.0), sc = rnd(0.5, 1.0), R = rnd(0.0, 1.0), phi = rnd(0.0, 1e3);
        long double rtl = formula_d3d9_r_tot_l(lam, sc, R, phi);
        agree("r_tot _v", i, formula_d3d9_r_tot_v(lam, sc, R, phi), rtl, 5 * U_F, 0);
        agree("r_tot _d", i, formula_d3d9_r_tot_d(lam, sc, R, phi), rtl, 5 * U_D, 0);
        float cr = rnd(0.0, 2.0), cgr = rnd(0.0, 2.0), cb = rnd(0.0, 2.0);
        static const float w[4][5] = {{1, 0, 0, 0, 0},
                                      {0, 1.0f / 3.0f, 1.0f / 3.0f, 1.0f / 3.0f, 0},
                                      {0, 0.2126f, 0.7152f, 0.0722f, 0},
                                      {0, 0, 0, 0, 1}};
        for (int k = 0; k < 4; k++) {
            long double nl_ = formula_colour_norm_l(cr, cgr, cb, w[k][0], w[k][1], w[k][2], w[k][3], w[k][4]);
            agree("colour norm _v", i, formula_colour_norm_v(cr, cgr, cb, w[k][0], w[k][1], w[k][2], w[k][3], w[k][4]),
                  nl_, 8 * U_F, 0);
            agree("colour norm _d", i, formula_colour_norm_d(cr, cgr, cb, w[k][0], w[k][1], w[k][2], w[k][3], w[k][4]),
                  nl_, 8 * U_D, 0);
        }
        /* Exact Fresnel, double against long double: about 12 roundings, and rs, rp subtract
         * (cos_i - eta cos_t vanishes at Brewster's angle), so an absolute floor of 12 u on
         * reflectances <= 1 covers the cancellation: rel 64 u, abs 12 u. */
        float ce = rnd(0.05, 1.0), eta = rnd(1.1, 3.0), ke = rnd(0.0, 5.0);
        agree("dielectric _d", i, formula_fresnel_dielectric_d(ce, eta), formula_fresnel_dielectric_l(ce, eta),
              64 * U_D, 12 * U_D);
        agree("conductor _d", i, formula_fresnel_conductor_d(ce, eta, ke), formula_fresnel_conductor_l(ce, eta, ke),
              64 * U_D, 12 * U_D);
        /* The lobe: 3 roundings. */
        float dd = rnd(0.0, 100.0), gg = rnd(0.0, 1.0), nvv = rnd(1e-6, 1.0);
        long double ll = formula_ct_lobe_l(dd, gg, formula_ct_k_l(walter), nvv);
        agree("ct lobe _v", i, formula_ct_lobe_v(dd, gg, formula_ct_k_v(walter), nvv), ll, 4 * U_F, 0);
        agree("ct lobe _d", i, formula_ct_lobe_d(dd, gg, formula_ct_k_d(walter), nvv), ll, 4 * U_D, 0);
    }
}

/* The guards: selects that give the documented value at the edges, in every instance. */
static void test_guards(void **state)
{
    (void)state;
    assert_true(formula_r0_f(0.0f) == 1.0f && formula_r0_d(-1.0) == 1.0 && formula_r0_l(INFINITY) == 1.0L);
    assert_true(formula_half_scale_v(1e-7f) == 0.0f && formula_half_scale_d(2.0) == 0.5);
    assert_true(formula_cos_floor_v(0.0f) == 1e-6f && formula_cos_floor_d(0.5) == 0.5);
    assert_true(formula_d3d9_power_f(-2.0f) == 0.0f && formula_d3d9_power_l(2.5L) == 2.5L);
    assert_true(formula_spot_cone_d(0.5, 0.7) == 1.0);
    /* V.H -> 0 with positive cosines: 1, no division */
    assert_true(formula_vcavity_g_v(0.5f, 0.5f, 0.5f, 0.0f) == 1.0f);
    /* Beckmann's cap */
    assert_true(formula_beckmann_d_v(0.0f, 1.0f, 1e12f, formula_beckmann_log_norm_f(1e-7f, 1)) == FORMULA_D_MAX);
    assert_true(formula_beckmann_d_d(0.0, 1.0, 1e14, formula_beckmann_log_norm_d(1e-7, 1)) == FORMULA_D_MAX);
    /* Walter G1 at the ends */
    assert_true(formula_smith_g1_walter_v(0.0f, 0.5f) == 0.0f && formula_smith_g1_walter_v(1.0f, 0.5f) == 1.0f);
    assert_true(formula_smith_g1_walter_d(0.5, 0.0) == 1.0 && formula_smith_g1_walter_l(0.999L, 0.01L) == 1.0L);
    /* Spot edges */
    assert_true(formula_spot_d3d_v(0.95f, 0.9f, 0.7f, 0.2f, 2.0f) == 1.0f);
    assert_true(formula_spot_d3d_v(0.7f, 0.9f, 0.7f, 0.2f, 2.0f) == 0.0f);
    assert_true(formula_spot_smooth_d(-0.1, 0.9, -0.5, 1.4) == 0.0 &&
                formula_spot_smooth_d(0.95, 0.9, 0.7, 0.2) == 0.95);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_constants),
        cmocka_unit_test(test_hand_values),
        cmocka_unit_test(test_instances_agree),
        cmocka_unit_test(test_guards),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
