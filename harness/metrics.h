/* metrics.h - per-pixel error metrics between a reference and a test linear float RGB image.
 *
 * Usage:
 *   metrics_image ref = {w, h, {r0, g0, b0}}, tst = {w, h, {r1, g1, b1}};   planar, row 0 at the top
 *   metrics_result res;
 *   metrics_compare(&ref, &tst, mask, NULL, &res, err, sizeof err);    mask NULL = every pixel
 *
 *   unsigned char *cls = malloc(w * h), *m = malloc(w * h);
 *   metrics_classify(w, h, alpha, object_id, cls);                     background / interior / edge
 *   metrics_mask_from_class(w, h, cls, METRICS_PX_INTERIOR, object_id, 3.0f, m);   object 3 only
 *   metrics_compare(&ref, &tst, m, NULL, &res, err, sizeof err);
 *
 *   metrics_robust(&ref, &tst, m, NULL, &rob, err, sizeof err);       median, p95, trimmed NRMSE, worst 1 %
 *
 *   metrics_seed_stats(seeds, k, mean, var, err, sizeof err);   reference mean, variance of the mean
 *   metrics_ztest(&mean, &var, &tst, NULL, mask, NULL, &z, err, sizeof err);
 *
 *   metrics_value_scan sc;
 *   metrics_scan_values(plane, w * h, &sc);     NaN/Inf and negative values of one plane, the first of each
 *
 * Units: whatever the images hold (linear radiance); every metric is over R, G, B only.
 * Masks are w*h bytes, 0 = pixel excluded, anything else = included. The caller owns every
 * array; nothing here allocates memory that outlives a call. Options structs may be NULL,
 * and a zero field means the default stated beside it.
 * Return: RC_OK, or RC_ERR_RANGE (size mismatch, NULL plane, bad option) with a one-line
 * message in err naming the argument and the fix; RC_ERR_NOMEM when scratch memory fails.
 * A pixel where either image holds a NaN or Inf in any channel is left out of every sum and
 * counted in n_nonfinite (idiff instead scores such values as matching or as an infinite max):
 * report n_pixels beside every metric, and gate on metrics_scan_values over the whole image,
 * so a mostly-NaN image cannot pass on its few finite pixels.
 */
#ifndef REFLCHECK_METRICS_H
#define REFLCHECK_METRICS_H

#include <stddef.h>
#include "status.h"

typedef struct {
    int width, height;
    const float *c[3]; /* R, G, B planes of width*height floats */
} metrics_image;

enum { METRICS_SSIM_GAUSS11 = 0, METRICS_SSIM_BOX8 = 1 };

typedef struct {
    double threshold;  /* share_over counts pixels with any |t - r| > threshold; 0 -> 1e-6 (idiff -fail default) */
    double rel_eps;    /* relative MSE denominator r^2 + rel_eps; 0 -> 1e-2 */
    double psnr_peak;  /* 0 -> idiff convention: max(1, largest |value| in either image) */
    int ssim_window;   /* METRICS_SSIM_GAUSS11 (sigma 1.5, Wang et al. 2004) or METRICS_SSIM_BOX8 */
    double ssim_range; /* dynamic range L in C1 = (0.01 L)^2, C2 = (0.03 L)^2; 0 -> 1.0 */
} metrics_options;

typedef struct {
    long n_pixels;    /* pixels included by the mask and finite */
    long n_nonfinite; /* included pixels left out because a value was NaN or Inf */
    double mae, rmse; /* over all included values of R, G, B */
    double rel_mse, rel_rms;
    double psnr, peak;        /* psnr in dB, +inf when rmse == 0; peak as used */
    double max_abs;           /* largest |t - r|; first in row-major, then R, G, B order */
    int max_x, max_y, max_c;  /* its pixel and channel (0 R, 1 G, 2 B); -1 if no pixel */
    double max_ref, max_test; /* the two values there */
    long n_over;              /* pixels with any channel |t - r| > threshold */
    double share_over;        /* n_over / n_pixels */
    double ssim;              /* mean SSIM of Rec.709 luminance over included pixels */
    double mae_ch[3], rmse_ch[3], rel_mse_ch[3], max_abs_ch[3], ssim_ch[3];
} metrics_result;

rc_status metrics_compare(const metrics_image *ref, const metrics_image *test, const unsigned char *mask,
                          const metrics_options *opt, metrics_result *out, char *err, size_t errlen);

/* A pixel's figure and its index; metrics_rank_sort_desc orders them largest first, ties by
 * index, so "the worst k pixels" is one deterministic set wherever it is taken. */
typedef struct {
    double key;
    size_t index;
} metrics_ranked;
void metrics_rank_sort_desc(metrics_ranked *r, size_t n);

/* ---- robust error: how a figure is spread over the pixels ---- */
typedef struct {
    double rel_eps; /* per-pixel relative error denominator r^2 + rel_eps; 0 -> 1e-2 (as metrics_compare) */
    double trim;    /* share of pixels trimmed as the worst, in (0, 1); 0 -> 0.01 */
} metrics_robust_options;

typedef struct {
    long n_pixels;      /* included finite pixels N */
    long n_trimmed;     /* k = min(ceil(trim N), N - 1) worst pixels by squared error */
    double nrmse;       /* sqrt(sum e / 3N) / mean_ref: e = sum over R, G, B of (t - r)^2 per pixel,
                           mean_ref = mean over pixels of (|R| + |G| + |B|) / 3 of the reference */
    double nrmse_trim;  /* the same over the N - k pixels left after the k worst (their own mean_ref) */
    double worst_share; /* share of sum e held by the k worst pixels, in [0, 1]; 0 when sum e = 0 */
    double rel_median;  /* per-pixel relative error q = sqrt(sum_c (t - r)^2 / (r^2 + rel_eps) / 3): */
    double rel_p95;     /* nearest-rank percentiles, the value of rank ceil(p N) in ascending order */
} metrics_robust_result;

/* Robust, spread-aware figures of the included finite pixels (NaN/Inf pixels left out, as in
 * metrics_compare): a headline NRMSE that a handful of pixels carries shows as a large
 * worst_share and an nrmse_trim far below nrmse. N = 0 gives every figure 0. Ties among equal
 * errors are broken by pixel index, so the trimmed set is deterministic. */
rc_status metrics_robust(const metrics_image *ref, const metrics_image *test, const unsigned char *mask,
                         const metrics_robust_options *opt, metrics_robust_result *out, char *err, size_t errlen);

/* Per-pixel SSIM of one plane pair (w*h each) into map (w*h; 0 where mask excludes the pixel).
 * Windows are truncated at the image border and at excluded pixels, with the remaining
 * weights renormalised, so an excluded region never leaks into the score. *mean gets the
 * mean over included pixels (may be NULL). */
rc_status metrics_ssim_map(int width, int height, const float *ref, const float *test, const unsigned char *mask,
                           const metrics_options *opt, float *map, double *mean, char *err, size_t errlen);

/* Rec.709 luminance Y = 0.2126 R + 0.7152 G + 0.0722 B of one pixel. */
double metrics_luminance(double r, double g, double b);

/* ---- masks ---- */
/* METRICS_PX_CREASE: interior pixels compare takes out of the surface when the reference shades
 * creases by other rules (harness/crease.h); metrics_classify never sets it. */
enum { METRICS_PX_BACKGROUND = 0, METRICS_PX_INTERIOR = 1, METRICS_PX_EDGE = 2, METRICS_PX_CREASE = 3 };

/* Class per pixel into cls (w*h). A pixel is covered when coverage > 0 (coverage NULL: all
 * covered). It is an EDGE when its coverage is partial (not within 1e-6 of 0 or 1), or when
 * any pixel in its 3x3 neighbourhood differs in covered-ness or, both covered, in object id
 * (exact float compare: box-filtered ids at a boundary are fractional and so differ;
 * object_id NULL: ids ignored). Otherwise INTERIOR if covered, BACKGROUND if not. */
void metrics_classify(int width, int height, const float *coverage, const float *object_id, unsigned char *cls);

/* mask[i] = 1 where cls[i] == want (want < 0: any class) and, if object_id is not NULL,
 * object_id[i] == id; else 0. Returns the number of pixels selected. */
long metrics_mask_from_class(int width, int height, const unsigned char *cls, int want, const float *object_id,
                             float id, unsigned char *mask);

/* ---- noise-aware per-pixel test ---- */
enum { METRICS_BONFERRONI = 0, METRICS_HOLM = 1, METRICS_SIDAK = 2 };

typedef struct {
    double alpha;     /* family-wise error rate; 0 -> 0.01 (Mitsuba 3's render tests) */
    double var_floor; /* absolute variance added to every value; 0 -> 1e-10, < 0 -> none */
    double rel_floor; /* sigma_floor = rel_floor * |r| added in quadrature; 0 -> none */
    int correction;   /* METRICS_BONFERRONI, METRICS_HOLM or METRICS_SIDAK */
} metrics_ztest_options;

typedef struct {
    long n_tests;       /* values tested: included finite pixels times 3 channels */
    long n_fail;        /* values whose null hypothesis (same mean) is rejected */
    long n_fail_pixels; /* pixels with at least one rejected channel */
    long n_nonfinite;   /* included pixels skipped for a NaN/Inf or a non-positive variance */
    double z_crit;      /* |z| threshold of the per-value level (Bonferroni/Sidak; the first Holm step) */
    double max_abs_z;
    int max_x, max_y, max_c;
    double min_p; /* smallest two-sided p-value */
} metrics_ztest_result;

/* z = (t - r) / sqrt(var_ref + var_test + var_floor + (rel_floor r)^2) per channel, with
 * two-sided p = erfc(|z| / sqrt 2) under a normal model, judged at the family-wise alpha over
 * all tested values. var_ref is the variance of the reference mean (see metrics_seed_stats);
 * var_test may be NULL for a deterministic test image. With few seeds the variance estimate
 * has k - 1 degrees of freedom and normal quantiles understate its tails: use many seeds or a
 * floor. */
rc_status metrics_ztest(const metrics_image *ref_mean, const metrics_image *ref_var, const metrics_image *test,
                        const metrics_image *test_var, const unsigned char *mask, const metrics_ztest_options *opt,
                        metrics_ztest_result *out, char *err, size_t errlen);

/* Mean and variance of the mean (unbiased sample variance / k) over k >= 2 renders with
 * different seeds, into caller planes mean[3] and var[3] (w*h floats each). */
rc_status metrics_seed_stats(const metrics_image *seeds, int k, float *const mean[3], float *const var[3], char *err,
                             size_t errlen);

/* ---- value integrity ---- */
typedef struct {
    long n_values;        /* values scanned */
    long n_nonfinite;     /* NaN, +Inf or -Inf */
    long n_negative;      /* finite and < 0 (-0.0 is not negative) */
    long first_nonfinite; /* index of the first such value, -1 if none */
    long first_negative;
    float nonfinite_value; /* the value there (0 if none) */
    float negative_value;
} metrics_value_scan;

/* Counts the non-finite and negative values among v[0..n-1] into out (overwritten). */
void metrics_scan_values(const float *v, size_t n, metrics_value_scan *out);

/* Standard normal quantile: x with Phi(x) = p, for 0 < p < 1 (returns -inf/+inf at 0/1, NaN
 * outside). Accurate to about 1e-15 relative, also for p near 1e-300. */
double metrics_norm_quantile(double p);

#endif
