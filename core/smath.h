/* smath.h - float log, exp, pow and atan2 written so that a compiler can vectorise them.
 *
 * Usage (inside a `#pragma omp simd` loop over structure-of-arrays lanes):
 *   float y = smath_pow(x, p);          x in [0, 1], p >= 0 (Blinn, Fresnel powers)
 *   float a = smath_atan2(y, x);        any finite y, x; signed zeros as C's atan2
 *   float w = smath_pow_whole(x, 3);    whole n in [0, 15], exact to 5 roundings
 * No branches, no libm calls, no lookup tables: each function is straight-line arithmetic,
 * integer bit tricks and selects, so one SIMD lane evaluates one sample. Accuracy against
 * glibc, measured by tests/test_smath.c (exhaustive or worst-case searches): log within 2.3e-7
 * relative, exp within 1.2e-7 relative (subnormal results within 0.84 of their ulp), atan2
 * within 3.2e-7 rad, pow within 1.7e-5 relative for p up to 1e4 wherever the result exceeds
 * 1e-30 (there |p ln x| reaches 69, and the float rounding of that exponent alone costs up to
 * 3.8e-6; log's own error times 69 makes the rest), 4e-6 for p up to 1. Arguments outside the
 * stated domains are the caller's business (the shading kernels guard them and fall back to
 * the scalar models).
 *
 * SMATH_CLONES marks a kernel for runtime dispatch to AVX-512, AVX2 or baseline code (GCC's
 * target_clones, x86-64 Linux). ISO C mode does not contract a*b+c into an FMA and no kernel
 * reduces floats across lanes, so every clone performs the same IEEE operations per sample;
 * only one clone runs on a given machine, so that is argued, not tested.
 */
#ifndef REFLCHECK_SMATH_H
#define REFLCHECK_SMATH_H

#include <float.h>
#include <stdint.h>
#include <string.h>

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define SMATH_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define SMATH_CLONES
#endif

/* Every function must be inlined into the lane loop that calls it: a call would stop the
 * loop from vectorising, and GCC's size heuristics alone do not always inline them. */
#if defined(__GNUC__)
#define SMATH_INLINE static inline __attribute__((always_inline))
#else
#define SMATH_INLINE static inline
#endif

/* pi to 36 digits: the project's one spelling of it (formula.h rounds it once per precision). */
#define SMATH_PI_DIGITS     3.14159265358979323846264338327950288
/* A literal's float, long double form: SMATH_SUFFIX(SMATH_PI_DIGITS, f) is the literal with f. */
#define SMATH_SUFFIX_(x, s) x##s
#define SMATH_SUFFIX(x, s)  SMATH_SUFFIX_(x, s)
#define SMATH_PI            SMATH_SUFFIX(SMATH_PI_DIGITS, f)
#define SMATH_PI_2          1.57079632679489661923f
/* ln 2 split so that n * SMATH_LN2_HI is exact for |n| < 2^15 (Cody and Waite). */
#define SMATH_LN2_HI        0.693359375f
#define SMATH_LN2_LO        (-2.12194440e-4f)
#define SMATH_LOG2E         1.44269504088896340736f

SMATH_INLINE int32_t smath_bits(float f)
{
    int32_t i;
    memcpy(&i, &f, sizeof i);
    return i;
}
SMATH_INLINE float smath_float(int32_t i)
{
    float f;
    memcpy(&f, &i, sizeof f);
    return f;
}

/* Natural log of a positive finite x. */
SMATH_INLINE float smath_log(float x)
{
    /* Subnormals carry no implicit bit: scale them into the normal range first. */
    int tiny = x < FLT_MIN;
    x = tiny ? x * 8388608.0f : x;
    int32_t b = smath_bits(x);
    int32_t e = ((b >> 23) & 0xff) - 127 - (tiny ? 23 : 0);
    float m = smath_float((b & 0x007fffff) | 0x3f800000);
    /* m in [sqrt(1/2), sqrt(2)) keeps t = (m - 1)/(m + 1) within +-0.1716, where the atanh
     * series below is exact to 7e-10 with five terms. */
    int big = m > 1.41421356f;
    m = big ? 0.5f * m : m;
    e += big;
    float t = (m - 1.0f) / (m + 1.0f), t2 = t * t;
    float s = t * (2.0f + t2 * (0.666666667f + t2 * (0.4f + t2 * (0.285714286f + t2 * 0.222222222f))));
    float ef = (float)e;
    return ef * SMATH_LN2_HI + (s + ef * SMATH_LN2_LO);
}

/* e^y for finite y, subnormal results included; below -104 (under half the smallest
 * subnormal) it returns 0, above ln FLT_MAX FLT_MAX. */
#define SMATH_LN_FLT_MAX 88.72283935546875f
SMATH_INLINE float smath_exp(float y)
{
    int under = y<-104.0f, over = y> SMATH_LN_FLT_MAX;
    y = under ? -104.0f : (over ? SMATH_LN_FLT_MAX : y);
    /* Adding and subtracting 1.5 * 2^23 rounds to the nearest integer without a libm call. */
    float nf = (y * SMATH_LOG2E + 12582912.0f) - 12582912.0f;
    float r = (y - nf * SMATH_LN2_HI) - nf * SMATH_LN2_LO;
    /* Minimax on |r| <= ln2/2: relative error 1.9e-9 before float rounding. */
    float p = 1.000000001f +
              r * (1.000000036f +
                   r * (0.4999999208f +
                        r * (0.1666642020f + r * (0.04166822580f + r * (0.008374813388f + r * 0.001383682195f)))));
    /* 2^n as two normal powers of two (n in [-150, 128] does not fit one float exponent), so
     * that results between FLT_MIN and the smallest subnormal round once, at the end. */
    int32_t n = (int32_t)nf, h = n / 2;
    float v = p * smath_float((h + 127) << 23) * smath_float((n - h + 127) << 23);
    /* At ln FLT_MAX itself the polynomial's rounding can carry v past FLT_MAX. */
    return under ? 0.0f : ((over | (v > FLT_MAX)) ? FLT_MAX : v);
}

/* x^p for x in [0, 1] and p >= 0, with 0^0 = 1 (the limit from above) and 0^p = 0. */
SMATH_INLINE float smath_pow(float x, float p)
{
    float v = smath_exp(p * smath_log(x > 0.0f ? x : 1.0f));
    return x > 0.0f ? v : (p == 0.0f ? 1.0f : 0.0f);
}

/* x^n for a whole n in [0, 15] by at most 5 multiplications (binary powers), 0^0 = 1: the small
 * whole powers of the seeds (Fresnel p = 2..5) without smath_pow's log and exp. */
SMATH_INLINE float smath_pow_whole(float x, int n)
{
    float x2 = x * x, x4 = x2 * x2;
    return ((n & 1) ? x : 1.0f) * ((n & 2) ? x2 : 1.0f) * ((n & 4) ? x4 : 1.0f) * ((n & 8) ? x4 * x4 : 1.0f);
}

/* atan2(y, x) in [-pi, pi], with C's signed zeros: the quadrant comes from the sign bits, so
 * atan2(+-0, -0) = +-pi and atan2(-0, x < 0) = -pi (the environment's u seam depends on it). */
SMATH_INLINE float smath_atan2(float y, float x)
{
    int x_neg = smath_bits(x) < 0, y_neg = smath_bits(y) < 0;
    float ax = smath_float(smath_bits(x) & 0x7fffffff), ay = smath_float(smath_bits(y) & 0x7fffffff);
    float hi = ax > ay ? ax : ay, lo = ax > ay ? ay : ax;
    float a = hi > 0.0f ? lo / hi : 0.0f, t = a * a;
    /* atan(a) = a P(a^2) on [0, 1]; minimax, 3.7e-8 rad before float rounding. */
    float r =
        a *
        (0.9999993356f +
         t * (-0.3332986070f +
              t * (0.1994656454f +
                   t * (-0.1390862345f +
                        t * (0.09642180306f + t * (-0.05591207542f + t * (0.02186277073f + t * -0.004054511950f)))))));
    r = ay > ax ? SMATH_PI_2 - r : r;
    r = x_neg ? SMATH_PI - r : r;
    return y_neg ? -r : r;
}

#endif
