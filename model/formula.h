/* formula.h - every source equation once, as pure inline functions on plain numbers.
 *
 * Usage:
 *   #include "formula.h"
 *   double f = formula_schlick_d(0.04, v_h);                    (4.9), the scalar model
 *   float  g = formula_vcavity_g_v(n_h, n_v, n_l, v_h);          (4.10)/(4.11), one SIMD lane
 *   long double d = formula_beckmann_d_l(s2, c2, inv_m2, norm);  (4.12), the stability reference
 *   float o = formula_dissolve_offset_v(u, v, scale, strength, 0);  source 000's Dissolve, x axis
 * One body (formula_body.h) is compiled once per instance, each with its type and
 * its maths library; the suffix names the instance:
 *   _f  float, libm (powf)          the scalar models' float factors (Lambert, Blinn)
 *   _d  double, libm                the scalar models, which form their sums in double
 *   _v  float, smath.h, always      the SIMD lanes (render/shade_batch_*.c): smath's pow, log and exp
 *       inlined                     vectorise where libm's would stop the loop
 *   _l  long double, libm           harness/stability_ref.c's reference (64-bit significand on x86-64)
 * So the scalar path, the lanes and the high-precision check run the same code: a formula changed
 * here changes all three, and tests/test_formula.c compares the instances.
 *
 * Convention: every direction points away from the surface (N normal, L to the light, V to the
 * viewer, H = norm(L + V)); a cosine is the dot product of two unit vectors. Each function says
 * whether its value includes the cosine (N.L) of the light; none includes 1/pi unless its name
 * says so. Functions are pure (no state, no scene structs) and return by value. Guards are
 * selects (?:) so that a lane loop if-converts them; a NaN argument propagates unless a comment
 * says otherwise; argument ranges are the callers' (the scene parser rejects bad input, the
 * model files keep their documented finite answers for it). Where a formula needs a power whose
 * evaluation an instance chooses (whole powers by multiplication, smath_pow), it takes the
 * power's value as an argument.
 * The constants (pi, 1/pi, the caps and thresholds) are defined once below.
 */
#ifndef REFLCHECK_FORMULA_H
#define REFLCHECK_FORMULA_H

#include <float.h>
#include <math.h>
#include <stdint.h>

#include "smath.h"

/* pi (smath.h's digits) and 1/pi to 36 digits: every instance's constant is the literal rounded
 * once. */
#define FORMULA_PI_DIGITS     SMATH_PI_DIGITS
#define FORMULA_INV_PI_DIGITS 0.318309886183790671537767526745028724
#define FORMULA_PI_F          SMATH_PI
#define FORMULA_INV_PI_F      SMATH_SUFFIX(FORMULA_INV_PI_DIGITS, f)
#define FORMULA_PI_D          SMATH_PI_DIGITS
#define FORMULA_PI_L          SMATH_SUFFIX(SMATH_PI_DIGITS, L)

/* Beckmann D never exceeds this. 1/(pi m^2) reaches it at m = 5.6e-7, a lobe far narrower than
 * any pixel resolves. With the other caps (the lobe's FORMULA_CT_MAX, the attenuation's
 * 1/FORMULA_ATTEN_DENOM_MIN) a shading sum of 8 lights of radiance 1e6 stays below ~1e31, well
 * inside float (3.4e38). */
#define FORMULA_D_MAX            1e12f
/* The Cook-Torrance lobe's cap, by the same headroom argument. */
#define FORMULA_CT_MAX           1e12f
/* The attenuation denominator never goes below this, so A <= 1e12: reached only for
 * a0 = a1 = a2 = 0 (rejected by the scene parser) or a light closer than 1e-6 m with a2 = 1, a
 * singularity no pixel footprint resolves. */
#define FORMULA_ATTEN_DENOM_MIN  1e-12
/* Below this |L + V| (unit L, V) the half vector's direction is float rounding noise (~1e-7 per
 * component of a unit vector): L is opposite V, H has no direction, and for any N either N.L or
 * N.V is <= 0 up to that rounding, so the light gives no highlight. */
#define FORMULA_HALF_MIN         1e-6
/* Cook-Torrance's zero-cosine guard: N.V and N.L are raised to this before use. Below it a unit
 * vector's cosine is float rounding noise, and the lobe F D G / (k N.V) has a finite limit there
 * that the clamp approaches. */
#define FORMULA_COS_MIN          1e-6
/* Walter et al. 2007's rational Smith G1 is 1 for a = 1/(m tan) >= 1.6, i.e. m tan <= 1/1.6. */
#define FORMULA_WALTER_INV_A_MAX 0.625

/* Dissolve (source 000): the side of the square noise texture, in texels; a power of two so that
 * the repeat wrap is a mask. The source's "particle" is one texel, 1/(256 scale) of the UV square:
 * at the typical scales 0.2 to 3 about a pixel on an object a few hundred pixels across, so the
 * noise reads as noise, which pixel averaging turns into blur. */
#define FORMULA_DISSOLVE_SIZE      256
/* Texel coordinates are taken modulo the side only within +-2^30 texels: beyond, a float has no
 * fraction left and the noise has no pattern to keep; the coordinate is then taken as 0 (as a
 * NaN is), so the integer conversion below is always defined. */
#define FORMULA_DISSOLVE_COORD_MAX 1073741824.0

/* Dissolve's noise texel (i, j) of channel ch (0 R, 1 G, 2 B), i and j in [0, SIZE): the
 * integer hash "lowbias32" (C. Wellons, 2018) of the texel's index, its top 24 bits scaled to
 * [0, 1). The same exact value in every instance (24 bits fit float's significand), so the
 * scalar path, the lanes and long double read one texture; no table, so lanes compute texels
 * instead of gathering them. */
static inline float formula_dissolve_texel(uint32_t i, uint32_t j, uint32_t ch)
{
    uint32_t x = i + (uint32_t)FORMULA_DISSOLVE_SIZE * (j + (uint32_t)FORMULA_DISSOLVE_SIZE * ch);
    x ^= x >> 16;
    x *= 0x7feb352du;
    x ^= x >> 15;
    x *= 0x846ca68bu;
    x ^= x >> 16;
    return (float)(x >> 8) * 0x1p-24f;
}

/* The instances. FORMULA_C gives a literal the instance's type (2.5 -> 2.5f, 2.5, 2.5L). */
#define FORMULA_CAT(a, b) SMATH_SUFFIX(a, b)

#define FORMULA_T        float
#define FORMULA_FN(name) name##_f
#define FORMULA_C(x)     FORMULA_CAT(x, f)
#define FORMULA_INLINE   static inline
#define FORMULA_POW      powf
#define FORMULA_LOG      logf
#define FORMULA_EXP      expf
#define FORMULA_SQRT     sqrtf
#define FORMULA_FLOOR    floorf
#define FORMULA_LN_D_MAX logf(FORMULA_D_MAX)
#include "formula_body.h"

#define FORMULA_T        double
#define FORMULA_FN(name) name##_d
#define FORMULA_C(x)     x
#define FORMULA_INLINE   static inline
#define FORMULA_POW      pow
#define FORMULA_LOG      log
#define FORMULA_EXP      exp
#define FORMULA_SQRT     sqrt
#define FORMULA_FLOOR    floor
#define FORMULA_ERF      erf
#define FORMULA_HYPOT    hypot
/* ln of the float cap as a double: D is compared with the very value the float result is capped
 * to (1e12f = 999999995904). */
#define FORMULA_LN_D_MAX log((double)FORMULA_D_MAX)
#include "formula_body.h"

#define FORMULA_T        float
#define FORMULA_FN(name) name##_v
#define FORMULA_C(x)     FORMULA_CAT(x, f)
#define FORMULA_INLINE   SMATH_INLINE
#define FORMULA_POW      smath_pow
#define FORMULA_LOG      smath_log
#define FORMULA_EXP      smath_exp
#define FORMULA_SQRT     sqrtf
#define FORMULA_FLOOR    floorf
/* ln 1e12f rounded to float, a literal so that no lane evaluates it (tests/test_formula.c checks
 * it against logf). */
#define FORMULA_LN_D_MAX 27.6310211f
#include "formula_body.h"

#define FORMULA_T        long double
#define FORMULA_FN(name) name##_l
#define FORMULA_C(x)     FORMULA_CAT(x, L)
#define FORMULA_INLINE   static inline
#define FORMULA_POW      powl
#define FORMULA_LOG      logl
#define FORMULA_EXP      expl
#define FORMULA_SQRT     sqrtl
#define FORMULA_FLOOR    floorl
#define FORMULA_ERF      erfl
#define FORMULA_HYPOT    hypotl
#define FORMULA_LN_D_MAX logl((long double)FORMULA_D_MAX)
#include "formula_body.h"

#endif /* REFLCHECK_FORMULA_H */
