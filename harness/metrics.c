/* metrics.c - image error metrics, masks and a noise-aware per-pixel test (see metrics.h). */
#include "metrics.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Default relative-MSE epsilon: the value used with relMSE in the denoising literature
 * (Rousselle, Knaus and Zwicker 2011 and later work). It keeps near-black reference pixels
 * from dominating the mean: below r ~ 0.1 the error is judged in absolute terms. */
#define METRICS_REL_EPS   1e-2
/* idiff's default -fail/-warn threshold, so share_over matches its "pixels over" line. */
#define METRICS_THRESHOLD 1e-6
/* Wang, Bovik, Sheikh and Simoncelli 2004, "Image quality assessment: from error visibility
 * to structural similarity", IEEE TIP 13(4): K1 = 0.01, K2 = 0.03, Gaussian sigma 1.5 over
 * 11x11. L = 1 treats 1.0 as reference white; for HDR data the constants only keep the
 * ratios finite in flat dark regions, and bright regions (values >> L) dominate regardless. */
#define SSIM_K1           0.01
#define SSIM_K2           0.03
#define SSIM_SIGMA        1.5
/* Default z-test variance floor: sigma = 1e-5 absolute, about 100 float ulps at 1.0, so a
 * pixel whose seeds agree exactly (variance 0) tolerates float rounding but nothing more. */
#define ZTEST_VAR_FLOOR   1e-10
#define ZTEST_ALPHA       0.01

static int check_image(const metrics_image *im, const char *what, int w, int h, char *err, size_t errlen)
{
    if (!im) {
        status_message(err, errlen, "metrics: %s image is NULL; pass a metrics_image", what);
        return 0;
    }
    if (im->width <= 0 || im->height <= 0 || (w > 0 && (im->width != w || im->height != h))) {
        status_message(err, errlen, "metrics: %s image is %dx%d but %dx%d was expected; compare images of one size",
                       what, im->width, im->height, w, h);
        return 0;
    }
    for (int c = 0; c < 3; c++)
        if (!im->c[c]) {
            status_message(err, errlen, "metrics: %s image channel %c is NULL; fill all of R, G, B", what, "RGB"[c]);
            return 0;
        }
    return 1;
}

double metrics_luminance(double r, double g, double b) { return 0.2126 * r + 0.7152 * g + 0.0722 * b; }

/* ---------------------------------------------------------------- SSIM */

static double ssim_const(const metrics_options *opt, double k)
{
    double L = opt && opt->ssim_range > 0 ? opt->ssim_range : 1.0;
    return (k * L) * (k * L);
}

/* One separable pass of the window over a plane: out = rows then columns of k[lo..hi],
 * taps outside the image dropped (the mask-weight plane renormalises them later). */
static void window_pass(int w, int h, const double *in, double *tmp, double *out, const double *k, int lo, int hi)
{
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double s = 0;
            for (int d = lo; d <= hi; d++)
                if (x + d >= 0 && x + d < w)
                    s += k[d - lo] * in[(size_t)y * (size_t)w + (size_t)(x + d)];
            tmp[(size_t)y * (size_t)w + (size_t)x] = s;
        }
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double s = 0;
            for (int d = lo; d <= hi; d++)
                if (y + d >= 0 && y + d < h)
                    s += k[d - lo] * tmp[(size_t)(y + d) * (size_t)w + (size_t)x];
            out[(size_t)y * (size_t)w + (size_t)x] = s;
        }
}

rc_status metrics_ssim_map(int width, int height, const float *ref, const float *test, const unsigned char *mask,
                           const metrics_options *opt, float *map, double *mean, char *err, size_t errlen)
{
    if (width <= 0 || height <= 0 || !ref || !test) {
        status_message(err, errlen, "metrics_ssim_map: need positive size and two planes (got %dx%d)", width, height);
        return RC_ERR_RANGE;
    }
    if (opt && opt->ssim_window != METRICS_SSIM_BOX8 && opt->ssim_window != METRICS_SSIM_GAUSS11) {
        status_message(err, errlen, "metrics: ssim_window %d unknown; use METRICS_SSIM_GAUSS11 or METRICS_SSIM_BOX8",
                       opt->ssim_window);
        return RC_ERR_RANGE;
    }
    int box = opt && opt->ssim_window == METRICS_SSIM_BOX8;
    /* Box: the 8x8 window of Wang et al.'s first experiment, offsets -3..4 (even size has no
     * centre pixel). Gaussian: 11x11, offsets -5..5. Both are separable, and so is the
     * window times the mask, which makes the masked moments five filtered planes. */
    int lo = box ? -3 : -5, hi = box ? 4 : 5;
    double k[11];
    for (int i = lo; i <= hi; i++)
        k[i - lo] = box ? 1.0 : exp(-(double)(i * i) / (2.0 * SSIM_SIGMA * SSIM_SIGMA));
    const double c1 = ssim_const(opt, SSIM_K1), c2 = ssim_const(opt, SSIM_K2);

    const size_t np = (size_t)width * (size_t)height;
    enum { PW, PX, PY, PXX, PYY, PXY, NPL };
    double *buf = malloc(np * (NPL + 2) * sizeof *buf);
    if (!buf) {
        status_message(err, errlen, "metrics_ssim_map: out of memory for a %dx%d image", width, height);
        return RC_ERR_NOMEM;
    }
    double *in = buf + NPL * np, *tmp = in + np;
    for (int pl = 0; pl < NPL; pl++) {
        for (size_t p = 0; p < np; p++) {
            double m = !mask || mask[p] ? 1.0 : 0.0;
            /* Zero the value where excluded so a NaN there cannot reach a sum. */
            double x = m != 0 ? ref[p] : 0.0, y = m != 0 ? test[p] : 0.0;
            switch (pl) {
            case PW: in[p] = m; break;
            case PX: in[p] = x; break;
            case PY: in[p] = y; break;
            case PXX: in[p] = x * x; break;
            case PYY: in[p] = y * y; break;
            default: in[p] = x * y; break;
            }
        }
        window_pass(width, height, in, tmp, buf + (size_t)pl * np, k, lo, hi);
    }
    double sum = 0.0;
    long n = 0;
    for (size_t p = 0; p < np; p++) {
        if (mask && !mask[p]) {
            if (map)
                map[p] = 0.0f;
            continue;
        }
        /* Moments in double: E[x^2] - E[x]^2 keeps ~1e-16 relative, ample for the variances
         * of HDR data (a 1e-4 variance at x = 100 keeps 8 digits). */
        double wsum = buf[PW * np + p];
        double mx = buf[PX * np + p] / wsum, my = buf[PY * np + p] / wsum;
        double sxx = fmax(buf[PXX * np + p] / wsum - mx * mx, 0.0);
        double syy = fmax(buf[PYY * np + p] / wsum - my * my, 0.0);
        double sxy = buf[PXY * np + p] / wsum - mx * my;
        double s = ((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx * mx + my * my + c1) * (sxx + syy + c2));
        if (map)
            map[p] = (float)s;
        sum += s;
        n++;
    }
    free(buf);
    if (mean)
        *mean = n > 0 ? sum / (double)n : NAN;
    return RC_OK;
}

/* ---------------------------------------------------------------- compare */

static int pixel_finite(const metrics_image *a, const metrics_image *b, size_t p)
{
    for (int c = 0; c < 3; c++)
        if (!isfinite(a->c[c][p]) || !isfinite(b->c[c][p]))
            return 0;
    return 1;
}

/* The per-channel sums of one comparison, accumulated in scan order. */
typedef struct {
    double sabs[3], ssq[3], srel[3];
    double peak;
} metrics_sums;

/* Step 1 of a comparison: the sums, the largest difference and the pixels used (USE), with
 * their luminances (YR, YT) for SSIM. */
static void metrics_accumulate(const metrics_image *ref, const metrics_image *test, const unsigned char *mask,
                               double thr, double eps, unsigned char *use, float *yr, float *yt, metrics_sums *sm,
                               metrics_result *out)
{
    const int w = ref->width, h = ref->height;
    double *sabs = sm->sabs, *ssq = sm->ssq, *srel = sm->srel;
    double peak = 1.0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            size_t p = (size_t)y * (size_t)w + (size_t)x;
            use[p] = 0;
            yr[p] = yt[p] = 0.0f;
            if (mask && !mask[p])
                continue;
            if (!pixel_finite(ref, test, p)) {
                out->n_nonfinite++;
                continue;
            }
            use[p] = 1;
            out->n_pixels++;
            int over = 0;
            for (int c = 0; c < 3; c++) {
                double r = ref->c[c][p], t = test->c[c][p];
                double d = t - r, a = fabs(d);
                sabs[c] += a;
                ssq[c] += d * d;
                srel[c] += d * d / (r * r + eps);
                peak = fmax(peak, fmax(fabs(r), fabs(t)));
                if (a > out->max_abs_ch[c])
                    out->max_abs_ch[c] = a;
                /* Strictly greater keeps the first maximum in scan order, as idiff reports it. */
                if (a > out->max_abs || out->max_c < 0) {
                    out->max_abs = a;
                    out->max_x = x;
                    out->max_y = y;
                    out->max_c = c;
                    out->max_ref = r;
                    out->max_test = t;
                }
                if (a > thr)
                    over = 1;
            }
            out->n_over += over;
            yr[p] = (float)metrics_luminance(ref->c[0][p], ref->c[1][p], ref->c[2][p]);
            yt[p] = (float)metrics_luminance(test->c[0][p], test->c[1][p], test->c[2][p]);
        }
    sm->peak = peak;
}

/* Step 2: the means, PSNR and SSIM from the sums. */
static rc_status metrics_summarise(const metrics_image *ref, const metrics_image *test, const unsigned char *use,
                                   const float *yr, const float *yt, const metrics_options *opt, const metrics_sums *sm,
                                   metrics_result *out, char *err, size_t errlen)
{
    const int w = ref->width, h = ref->height;
    const double *sabs = sm->sabs, *ssq = sm->ssq, *srel = sm->srel;
    double peak = sm->peak;
    rc_status st = RC_OK;
    if (out->n_pixels > 0) {
        double n = (double)out->n_pixels;
        double tabs = 0, tsq = 0, trel = 0;
        for (int c = 0; c < 3; c++) {
            out->mae_ch[c] = sabs[c] / n;
            out->rmse_ch[c] = sqrt(ssq[c] / n);
            out->rel_mse_ch[c] = srel[c] / n;
            tabs += sabs[c];
            tsq += ssq[c];
            trel += srel[c];
        }
        out->mae = tabs / (3 * n);
        out->rmse = sqrt(tsq / (3 * n));
        out->rel_mse = trel / (3 * n);
        out->rel_rms = sqrt(out->rel_mse);
        out->peak = opt && opt->psnr_peak > 0 ? opt->psnr_peak : peak;
        out->psnr = out->rmse > 0 ? 20.0 * log10(out->peak / out->rmse) : INFINITY;
        out->share_over = (double)out->n_over / n;
        st = metrics_ssim_map(w, h, yr, yt, use, opt, NULL, &out->ssim, err, errlen);
        for (int c = 0; st == RC_OK && c < 3; c++)
            st = metrics_ssim_map(w, h, ref->c[c], test->c[c], use, opt, NULL, &out->ssim_ch[c], err, errlen);
    } else {
        out->mae = out->rmse = out->rel_mse = out->rel_rms = out->psnr = out->ssim = NAN;
        out->peak = opt && opt->psnr_peak > 0 ? opt->psnr_peak : 1.0;
        for (int c = 0; c < 3; c++)
            out->mae_ch[c] = out->rmse_ch[c] = out->rel_mse_ch[c] = out->ssim_ch[c] = NAN;
    }
    return st;
}

rc_status metrics_compare(const metrics_image *ref, const metrics_image *test, const unsigned char *mask,
                          const metrics_options *opt, metrics_result *out, char *err, size_t errlen)
{
    if (!out) {
        status_message(err, errlen, "metrics_compare: result pointer is NULL; pass a metrics_result");
        return RC_ERR_RANGE;
    }
    memset(out, 0, sizeof *out);
    out->max_x = out->max_y = out->max_c = -1;
    if (!check_image(ref, "reference", 0, 0, err, errlen) ||
        !check_image(test, "test", ref->width, ref->height, err, errlen))
        return RC_ERR_RANGE;
    double thr = opt && opt->threshold > 0 ? opt->threshold : METRICS_THRESHOLD;
    double eps = opt && opt->rel_eps > 0 ? opt->rel_eps : METRICS_REL_EPS;
    if (opt && (opt->threshold < 0 || opt->rel_eps < 0 || opt->psnr_peak < 0 || opt->ssim_range < 0)) {
        status_message(err, errlen,
                       "metrics_compare: negative option (threshold %g, rel_eps %g, psnr_peak %g, "
                       "ssim_range %g); use 0 for the default",
                       opt->threshold, opt->rel_eps, opt->psnr_peak, opt->ssim_range);
        return RC_ERR_RANGE;
    }

    const int w = ref->width, h = ref->height;
    const size_t np = (size_t)w * (size_t)h;
    unsigned char *use = malloc(np);
    float *yr = malloc(np * sizeof *yr), *yt = malloc(np * sizeof *yt);
    if (!use || !yr || !yt) {
        free(use);
        free(yr);
        free(yt);
        status_message(err, errlen, "metrics_compare: out of memory for a %dx%d image", w, h);
        return RC_ERR_NOMEM;
    }

    metrics_sums sm = {0};
    metrics_accumulate(ref, test, mask, thr, eps, use, yr, yt, &sm, out);
    rc_status st = metrics_summarise(ref, test, use, yr, yt, opt, &sm, out, err, errlen);
    free(use);
    free(yr);
    free(yt);
    return st;
}

/* ---------------------------------------------------------------- masks */

/* Coverage within 1e-6 of 0 or 1 counts as empty or full: float accumulation of box-filtered
 * samples leaves a full pixel a few ulps (6e-8 each) below 1, while one real sample in 1024
 * changes coverage by 1e-3. */
#define COVER_TOL 1e-6f

static int cover_state(const float *cov, size_t p)
{
    if (!cov)
        return 2;
    float a = cov[p];
    if (!(a > COVER_TOL))
        return 0;
    return a >= 1.0f - COVER_TOL ? 2 : 1;
}

void metrics_classify(int width, int height, const float *coverage, const float *object_id, unsigned char *cls)
{
    if (width <= 0 || height <= 0 || !cls)
        return;
    for (int y = 0; y < height; y++)
        for (int x = 0; x < width; x++) {
            size_t p = (size_t)y * (size_t)width + (size_t)x;
            int sp = cover_state(coverage, p);
            int edge = sp == 1;
            for (int dy = -1; dy <= 1 && !edge; dy++)
                for (int dx = -1; dx <= 1 && !edge; dx++) {
                    int xx = x + dx, yy = y + dy;
                    if (xx < 0 || yy < 0 || xx >= width || yy >= height)
                        continue;
                    size_t q = (size_t)yy * (size_t)width + (size_t)xx;
                    int sq = cover_state(coverage, q);
                    if (sq != sp)
                        edge = 1;
                    else if (sp != 0 && object_id && object_id[q] != object_id[p])
                        edge = 1;
                }
            cls[p] = edge ? METRICS_PX_EDGE : sp ? METRICS_PX_INTERIOR : METRICS_PX_BACKGROUND;
        }
}

long metrics_mask_from_class(int width, int height, const unsigned char *cls, int want, const float *object_id,
                             float id, unsigned char *mask)
{
    if (width <= 0 || height <= 0 || !cls || !mask)
        return 0;
    long n = 0;
    size_t np = (size_t)width * (size_t)height;
    for (size_t p = 0; p < np; p++) {
        int sel = (want < 0 || cls[p] == want) && (!object_id || object_id[p] == id);
        mask[p] = (unsigned char)sel;
        n += sel;
    }
    return n;
}

/* ---------------------------------------------------------------- value integrity */

void metrics_scan_values(const float *v, size_t n, metrics_value_scan *out)
{
    *out = (metrics_value_scan){.first_nonfinite = -1, .first_negative = -1};
    if (v == NULL)
        return;
    out->n_values = (long)n;
    for (size_t i = 0; i < n; i++) {
        if (!isfinite(v[i])) {
            if (out->n_nonfinite++ == 0) {
                out->first_nonfinite = (long)i;
                out->nonfinite_value = v[i];
            }
        } else if (v[i] < 0.0f && out->n_negative++ == 0) {
            out->first_negative = (long)i;
            out->negative_value = v[i];
        }
    }
}

/* ---------------------------------------------------------------- statistics */

/* Acklam's rational approximation of the normal quantile (P. J. Acklam, "An algorithm for
 * computing the inverse normal cumulative distribution function", 2003; relative error
 * < 1.15e-9), refined by one Halley step on Phi(x) = p using the C library's erfc, which
 * brings it to double precision (the step converges cubically). */
double metrics_norm_quantile(double p)
{
    static const double a[6] = {-3.969683028665376e+01, 2.209460984245205e+02,  -2.759285104469687e+02,
                                1.383577518672690e+02,  -3.066479806614716e+01, 2.506628277459239e+00};
    static const double b[5] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                                6.680131188771972e+01, -1.328068155288572e+01};
    static const double c[6] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                                -2.549732539343734e+00, 4.374664141464968e+00,  2.938163982698783e+00};
    static const double d[4] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                                3.754408661907416e+00};
    if (isnan(p) || p < 0.0 || p > 1.0)
        return NAN;
    if (p == 0.0)
        return -INFINITY;
    if (p == 1.0)
        return INFINITY;
    /* Work in the lower half; 1 - p is exact for p >= 0.5 (Sterbenz), so symmetry loses nothing. */
    if (p > 0.5)
        return -metrics_norm_quantile(1.0 - p);
    const double plow = 0.02425;
    double x;
    if (p < plow) {
        double q = sqrt(-2.0 * log(p));
        x = (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
            ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0);
    } else {
        double q = p - 0.5, r = q * q;
        x = (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
            (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1.0);
    }
    double e = 0.5 * erfc(-x / sqrt(2.0)) - p;
    double u = e * 2.5066282746310002 /* sqrt(2 pi) */ * exp(0.5 * x * x);
    return x - u / (1.0 + 0.5 * x * u);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* z and two-sided p of one value, or 0 when the value cannot be tested. */
static int z_of(const metrics_image *rm, const metrics_image *rv, const metrics_image *t, const metrics_image *tv,
                double floor_abs, double floor_rel, size_t p, int c, double *z, double *pv)
{
    double r = rm->c[c][p], x = t->c[c][p], v = rv->c[c][p];
    double vt = tv ? tv->c[c][p] : 0.0;
    double var = v + vt + floor_abs + (floor_rel * r) * (floor_rel * r);
    if (!isfinite(r) || !isfinite(x) || !isfinite(var) || v < 0 || vt < 0 || !(var > 0))
        return 0;
    *z = (x - r) / sqrt(var);
    *pv = erfc(fabs(*z) / sqrt(2.0));
    return 1;
}

/* The inputs of one z-test, shared by its steps. */
typedef struct {
    const metrics_image *rm, *rv, *t, *tv;
    double floor_abs, floor_rel;
} ztest_in;

/* Step 1: which pixels are testable (all three channels), and so m, the number of tests. */
static void ztest_testable(const ztest_in *in, const unsigned char *mask, size_t np, unsigned char *use,
                           metrics_ztest_result *out)
{
    for (size_t p = 0; p < np; p++) {
        double z, pv;
        use[p] = 0;
        if (mask && !mask[p])
            continue;
        int ok = 1;
        for (int c = 0; c < 3 && ok; c++)
            ok = z_of(in->rm, in->rv, in->t, in->tv, in->floor_abs, in->floor_rel, p, c, &z, &pv);
        if (!ok) {
            out->n_nonfinite++;
            continue;
        }
        use[p] = 1;
        out->n_tests += 3;
    }
}

/* Step 2: the p at or below which a value fails, under the multiple-test correction. */
static rc_status ztest_level(const ztest_in *in, const unsigned char *use, size_t np, double alpha, int corr,
                             metrics_ztest_result *out, double *level_out, char *err, size_t errlen)
{
    long m = out->n_tests;
    double level = 0.0; /* a value fails when its p <= level */
    if (m > 0) {
        if (corr == METRICS_SIDAK)
            level = -expm1(log1p(-alpha) / (double)m);
        else
            level = alpha / (double)m;
        out->z_crit = -metrics_norm_quantile(0.5 * level);
        if (corr == METRICS_HOLM) {
            double *ps = malloc((size_t)m * sizeof *ps);
            if (!ps) {
                status_message(err, errlen, "metrics_ztest: out of memory for %ld p-values", m);
                *level_out = level;
                return RC_ERR_NOMEM;
            }
            long k = 0;
            for (size_t p = 0; p < np; p++)
                for (int c = 0; use[p] && c < 3; c++) {
                    double z = 0.0, pv = 1.0;
                    z_of(in->rm, in->rv, in->t, in->tv, in->floor_abs, in->floor_rel, p, c, &z, &pv);
                    ps[k++] = pv;
                }
            qsort(ps, (size_t)m, sizeof *ps, cmp_double);
            /* Step down: reject the i-th smallest while p_(i) <= alpha / (m - i). Tied values
             * share a fate, so the last rejected p is a threshold for all. */
            long i = 0;
            while (i < m && ps[i] <= alpha / (double)(m - i))
                i++;
            level = i > 0 ? ps[i - 1] : -1.0;
            free(ps);
        }
    }
    *level_out = level;
    return RC_OK;
}

/* Step 3: the failing values and pixels, the largest |z| and the smallest p. */
static void ztest_count(const ztest_in *in, const unsigned char *use, int w, int h, double level,
                        metrics_ztest_result *out)
{
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            size_t p = (size_t)y * (size_t)w + (size_t)x;
            if (!use[p])
                continue;
            int failed = 0;
            for (int c = 0; c < 3; c++) {
                double z = 0.0, pv = 1.0;
                z_of(in->rm, in->rv, in->t, in->tv, in->floor_abs, in->floor_rel, p, c, &z, &pv);
                if (fabs(z) > out->max_abs_z || out->max_c < 0) {
                    out->max_abs_z = fabs(z);
                    out->max_x = x;
                    out->max_y = y;
                    out->max_c = c;
                }
                if (pv < out->min_p)
                    out->min_p = pv;
                if (pv <= level) {
                    out->n_fail++;
                    failed = 1;
                }
            }
            out->n_fail_pixels += failed;
        }
}

rc_status metrics_ztest(const metrics_image *ref_mean, const metrics_image *ref_var, const metrics_image *test,
                        const metrics_image *test_var, const unsigned char *mask, const metrics_ztest_options *opt,
                        metrics_ztest_result *out, char *err, size_t errlen)
{
    if (!out) {
        status_message(err, errlen, "metrics_ztest: result pointer is NULL; pass a metrics_ztest_result");
        return RC_ERR_RANGE;
    }
    memset(out, 0, sizeof *out);
    out->max_x = out->max_y = out->max_c = -1;
    out->min_p = 1.0;
    if (!check_image(ref_mean, "reference mean", 0, 0, err, errlen))
        return RC_ERR_RANGE;
    int w = ref_mean->width, h = ref_mean->height;
    if (!check_image(ref_var, "reference variance", w, h, err, errlen) ||
        !check_image(test, "test", w, h, err, errlen) ||
        (test_var && !check_image(test_var, "test variance", w, h, err, errlen)))
        return RC_ERR_RANGE;
    double alpha = opt && opt->alpha > 0 ? opt->alpha : ZTEST_ALPHA;
    double floor_abs = !opt || opt->var_floor == 0 ? ZTEST_VAR_FLOOR : opt->var_floor < 0 ? 0.0 : opt->var_floor;
    double floor_rel = opt ? opt->rel_floor : 0.0;
    int corr = opt ? opt->correction : METRICS_BONFERRONI;
    if (alpha >= 1 || floor_rel < 0 || (corr != METRICS_BONFERRONI && corr != METRICS_HOLM && corr != METRICS_SIDAK)) {
        status_message(err, errlen,
                       "metrics_ztest: bad option (alpha %g must be in (0,1), rel_floor %g >= 0, "
                       "correction %d one of BONFERRONI/HOLM/SIDAK)",
                       alpha, floor_rel, corr);
        return RC_ERR_RANGE;
    }

    size_t np = (size_t)w * (size_t)h;
    unsigned char *use = malloc(np);
    if (!use) {
        status_message(err, errlen, "metrics_ztest: out of memory");
        return RC_ERR_NOMEM;
    }
    ztest_in in = {ref_mean, ref_var, test, test_var, floor_abs, floor_rel};
    ztest_testable(&in, mask, np, use, out);
    double level = 0.0;
    rc_status st = ztest_level(&in, use, np, alpha, corr, out, &level, err, errlen);
    if (st == RC_OK)
        ztest_count(&in, use, w, h, level, out);
    free(use);
    return st;
}

rc_status metrics_seed_stats(const metrics_image *seeds, int k, float *const mean[3], float *const var[3], char *err,
                             size_t errlen)
{
    if (!seeds || k < 2 || !mean || !var) {
        status_message(err, errlen, "metrics_seed_stats: need at least 2 seed images (got %d) and output planes", k);
        return RC_ERR_RANGE;
    }
    if (!check_image(&seeds[0], "seed 0", 0, 0, err, errlen))
        return RC_ERR_RANGE;
    for (int i = 1; i < k; i++) {
        char what[32];
        snprintf(what, sizeof what, "seed %d", i);
        if (!check_image(&seeds[i], what, seeds[0].width, seeds[0].height, err, errlen))
            return RC_ERR_RANGE;
    }
    for (int c = 0; c < 3; c++)
        if (!mean[c] || !var[c]) {
            status_message(err, errlen, "metrics_seed_stats: output plane %c is NULL; pass w*h floats", "RGB"[c]);
            return RC_ERR_RANGE;
        }
    size_t np = (size_t)seeds[0].width * (size_t)seeds[0].height;
    for (int c = 0; c < 3; c++)
        for (size_t p = 0; p < np; p++) {
            double s = 0, ss = 0;
            for (int i = 0; i < k; i++)
                s += seeds[i].c[c][p];
            double mu = s / k;
            for (int i = 0; i < k; i++) {
                double d = seeds[i].c[c][p] - mu;
                ss += d * d;
            }
            mean[c][p] = (float)mu;
            var[c][p] = (float)(ss / (double)(k - 1) / (double)k);
        }
    return RC_OK;
}

/* ---------------------------------------------------------------- robust error */

/* The share of pixels metrics_robust trims by default: the "worst 1 %". */
#define METRICS_TRIM 0.01

/* Descending by key, ties ascending by index: the worst first, deterministically. */
static int metrics_rank_desc(const void *a, const void *b)
{
    const metrics_ranked *x = a, *y = b;
    if (x->key != y->key)
        return x->key < y->key ? 1 : -1;
    return x->index < y->index ? -1 : (x->index > y->index);
}

void metrics_rank_sort_desc(metrics_ranked *r, size_t n) { qsort(r, n, sizeof *r, metrics_rank_desc); }

static int metrics_double_asc(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Nearest rank: the value of rank ceil(p n) (1-based) in ascending order. */
static double metrics_rank_value(const double *sorted, long n, double p)
{
    long rank = (long)ceil(p * (double)n);
    rank = rank < 1 ? 1 : (rank > n ? n : rank);
    return sorted[rank - 1];
}

rc_status metrics_robust(const metrics_image *ref, const metrics_image *test, const unsigned char *mask,
                         const metrics_robust_options *opt, metrics_robust_result *out, char *err, size_t errlen)
{
    if (!out) {
        status_message(err, errlen, "metrics_robust: result pointer is NULL; pass a metrics_robust_result");
        return RC_ERR_RANGE;
    }
    memset(out, 0, sizeof *out);
    if (!check_image(ref, "reference", 0, 0, err, errlen) ||
        !check_image(test, "test", ref->width, ref->height, err, errlen))
        return RC_ERR_RANGE;
    if (opt && (!(opt->rel_eps >= 0.0) || !(opt->trim >= 0.0 && opt->trim < 1.0))) {
        status_message(err, errlen, "metrics_robust: rel_eps %g must be >= 0 and trim %g in [0, 1); 0 = default",
                       opt->rel_eps, opt->trim);
        return RC_ERR_RANGE;
    }
    double eps = opt && opt->rel_eps > 0 ? opt->rel_eps : METRICS_REL_EPS;
    double trim = opt && opt->trim > 0 ? opt->trim : METRICS_TRIM;
    size_t np = (size_t)ref->width * (size_t)ref->height;
    metrics_ranked *rank = malloc(np * sizeof *rank);
    double *rel = malloc(np * sizeof *rel), *refmean = malloc(np * sizeof *refmean);
    if (!rank || !rel || !refmean) {
        free(rank);
        free(rel);
        free(refmean);
        status_message(err, errlen, "metrics_robust: out of memory for %zu pixels", np);
        return RC_ERR_NOMEM;
    }
    long n = 0;
    double sum_e = 0.0, sum_ref = 0.0;
    for (size_t i = 0; i < np; i++) {
        if (mask && !mask[i])
            continue;
        double e = 0.0, q = 0.0, a = 0.0;
        int finite = 1;
        for (int c = 0; c < 3; c++) {
            double r = ref->c[c][i], t = test->c[c][i], d = t - r;
            finite &= isfinite(r) && isfinite(t);
            e += d * d;
            q += d * d / (r * r + eps);
            a += fabs(r);
        }
        if (!finite)
            continue;
        rank[n] = (metrics_ranked){e, i};
        rel[n] = sqrt(q / 3.0);
        refmean[i] = a / 3.0;
        sum_e += e;
        sum_ref += a / 3.0;
        n++;
    }
    out->n_pixels = n;
    if (n > 0) {
        metrics_rank_sort_desc(rank, (size_t)n);
        qsort(rel, (size_t)n, sizeof *rel, metrics_double_asc);
        long k = (long)ceil(trim * (double)n);
        k = k > n - 1 ? n - 1 : k;
        double worst_e = 0.0;
        for (long j = 0; j < k; j++)
            worst_e += rank[j].key;
        /* Kept sums by subtraction would cancel when the worst pixels hold nearly everything. */
        double kept_e = 0.0, kept_ref = 0.0;
        for (long j = k; j < n; j++) {
            kept_e += rank[j].key;
            kept_ref += refmean[rank[j].index];
        }
        out->n_trimmed = k;
        out->nrmse = sum_ref > 0.0 ? sqrt(sum_e / (3.0 * (double)n)) / (sum_ref / (double)n) : 0.0;
        out->nrmse_trim = kept_ref > 0.0 ? sqrt(kept_e / (3.0 * (double)(n - k))) / (kept_ref / (double)(n - k)) : 0.0;
        out->worst_share = sum_e > 0.0 ? worst_e / sum_e : 0.0;
        out->rel_median = metrics_rank_value(rel, n, 0.5);
        out->rel_p95 = metrics_rank_value(rel, n, 0.95);
    }
    free(rank);
    free(rel);
    free(refmean);
    return RC_OK;
}
