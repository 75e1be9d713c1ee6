/* cycles_samples.c - a Cycles job's samples from its gates' noise (cycles_samples.h). */
#include "cycles_samples.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "exr.h"
#include "metrics.h"
#include "scene_file.h"
#include "status.h"
#include "../registry.h"

/* The metric's own name, without its region ("glossy.nrmse" -> "nrmse"). */
static const char *cycles_metric_base(const char *metric)
{
    const char *dot = strrchr(metric, '.');
    return dot != NULL ? dot + 1 : metric;
}

/* An RMS-error gate the surface's noise speaks for: not one of the background, the environment
 * seen by camera rays, a texture lookup per sample position whose only noise is the pixel's
 * sub-sample spread (cube_mirror's twin: background.rel_rms fail 0.0012 asked 4096 spp of the
 * surface's closure noise, which that region does not have). */
static int cycles_rms_metric(const char *metric)
{
    const char *m = cycles_metric_base(metric);
    if (strncmp(metric, "background.", 11) == 0)
        return 0;
    return strcmp(m, "nrmse") == 0 || strcmp(m, "nrmse_trim1") == 0 || strcmp(m, "rel_rms") == 0;
}

/* A per-pixel z-test of any region ("z_fail_share", "crease.z_fail_share"). */
static int cycles_ztest_metric(const char *metric) { return strcmp(cycles_metric_base(metric), "z_fail_share") == 0; }

/* A bias in standard errors ("bias.z_max", "bias.z_trim1_max"). */
static int cycles_bias_metric(const char *metric) { return strncmp(metric, "bias.z_", 7) == 0; }

/* A twin render serves the twin comparisons; the validate render serves validate and agree. */
static int cycles_serves(const comparison *c, int row, comparison_role role)
{
    if (c->reference != row && c->test != row)
        return 0;
    return role == ROLE_TWIN ? c->role == ROLE_TWIN : c->role != ROLE_TWIN;
}

/* "comparisons[2] povray/agree": the comparison as the scene lists it, from this render's side. */
static void cycles_cmp_name(const comparison *c, int i, int row, char *out, size_t len)
{
    static const char *const roles[] = {"twin", "validate", "agree"};
    const char *other = registry_name(c->reference == row ? c->test : c->reference);
    snprintf(out, len, "comparisons[%d] %s/%s", i, other ? other : "?", roles[c->role]);
}

/* The comparison's smallest RMS-gate fail at the size, 0 = none. */
static double cycles_rms_fail(const comparison *c, int full)
{
    double best = 0.0;
    for (int k = 0; k < c->n_thresholds; k++) {
        threshold_gate g;
        threshold_gate_at(&c->thresholds[k], full, &g);
        if (cycles_rms_metric(c->thresholds[k].metric) && g.fail > 0.0 && (best == 0.0 || g.fail < best))
            best = g.fail;
    }
    return best;
}

/* One z-test gate: its b is the scene's stated bias, else the comparison's smallest RMS fail; the
 * smallest b over the gates wins. Neither: refused, naming the scene line and the fix. */
static void cycles_need_ztest(const scene *s, const comparison *c, const char *name, const char *metric, int full,
                              cycles_noise_need *out)
{
    double rms = s->samples_bias > 0.0 ? 0.0 : cycles_rms_fail(c, full), b = rms > 0.0 ? rms : s->samples_bias;
    if (!(b > 0.0)) {
        if (!out->refuse)
            snprintf(out->why, sizeof out->why,
                     "%s:%d: image.samples auto: %s %s is a z-test with no bias size; write image.samples: "
                     "{auto: true, bias: B, why: \"...\"} or a number",
                     s->path, s->samples_line, name, metric);
        out->refuse = 1;
        return;
    }
    if (out->bias == 0.0 || b < out->bias) {
        out->bias = b;
        snprintf(out->zgate, sizeof out->zgate, "%s %s bias %g (%s)", name, metric, b,
                 rms > 0.0 ? "its RMS fail" : "image.samples bias");
    }
}

/* An RMS gate's target, fail / 3, against the trimmed noise for nrmse_trim1 (of any region), the
 * whole noise otherwise; each kind keeps its smallest and names its gate. */
static void cycles_need_rms(const char *name, const char *metric, double fail, cycles_noise_need *out)
{
    int trim = strcmp(cycles_metric_base(metric), "nrmse_trim1") == 0;
    double target = fail / CYCLES_NOISE_MARGIN, *slot = trim ? &out->target_trim1 : &out->target;
    if (*slot != 0.0 && target >= *slot)
        return;
    *slot = target;
    snprintf(trim ? out->gate_trim1 : out->gate, sizeof out->gate, "%s %s fail %g", name, metric, fail);
}

void cycles_noise_need_of(const scene *s, int row, comparison_role role, int full, cycles_noise_need *out)
{
    memset(out, 0, sizeof *out);
    for (int i = 0; i < s->n_comparisons; i++) {
        const comparison *c = &s->comparisons[i];
        if (!cycles_serves(c, row, role))
            continue;
        char name[64];
        cycles_cmp_name(c, i, row, name, sizeof name);
        for (int k = 0; k < c->n_thresholds; k++) {
            const threshold *t = &c->thresholds[k];
            threshold_gate g;
            threshold_gate_at(t, full, &g);
            if (cycles_bias_metric(t->metric)) {
                if (!out->refuse)
                    snprintf(out->why, sizeof out->why,
                             "%s:%d: image.samples auto: %s %s counts standard errors, which grow as "
                             "sqrt(samples) for a real bias, so its level holds at one count; give image.samples "
                             "a number",
                             s->path, s->samples_line, name, t->metric);
                out->refuse = 1;
            } else if (cycles_ztest_metric(t->metric)) {
                cycles_need_ztest(s, c, name, t->metric, full, out);
            } else if (cycles_rms_metric(t->metric) && g.fail > 0.0) {
                cycles_need_rms(name, t->metric, g.fail, out);
            }
        }
    }
}

double cycles_ztest_span(long n_values)
{
    double m = n_values > 1 ? (double)n_values : 1.0;
    return -metrics_norm_quantile(0.5 * CYCLES_ZTEST_ALPHA / m) - metrics_norm_quantile(CYCLES_ZTEST_BETA);
}

double cycles_ztest_target(const cycles_noise_need *need, long n_values)
{
    return need->bias > 0.0 ? need->bias / cycles_ztest_span(n_values) : 0.0;
}

int cycles_samples_for(double noise, int n_pilot, double target)
{
    if (!(target > 0.0) || !(noise > target))
        return n_pilot;
    double n = ceil(n_pilot * (noise / target) * (noise / target));
    return n > CYCLES_MAX_SPP ? CYCLES_MAX_SPP : (int)n;
}

int cycles_pilot_samples(int positions)
{
    int p = 2 * (positions > 1 ? positions : 1);
    return p > CYCLES_PILOT_SPP ? p : CYCLES_PILOT_SPP;
}

/* The count as Cycles renders it best: per position, a power of two (PMJ's strata are whole
 * there); at most CYCLES_MAX_SPP unless one per position is already more. */
static int cycles_samples_round(int n, int positions)
{
    int k = positions > 1 ? positions : 1, per = 1;
    while (per < (n + k - 1) / k && per * k < CYCLES_MAX_SPP)
        per *= 2;
    return per * k;
}

int cycles_samples_step(int current, int wanted)
{
    return wanted < CYCLES_STEP * current ? wanted : CYCLES_STEP * current;
}

int cycles_samples_need(const cycles_noise *pilot, int n_pilot, int positions, const cycles_noise_need *need)
{
    int a = cycles_samples_for(pilot->nrmse, n_pilot, need->target);
    int t = cycles_samples_for(pilot->trim1, n_pilot, need->target_trim1);
    int b = cycles_samples_for(pilot->pixel_q, n_pilot, cycles_ztest_target(need, pilot->n_values));
    a = a > t ? a : t;
    a = a > b ? a : b;
    return a > n_pilot ? cycles_samples_round(a, positions) : n_pilot;
}

static int cycles_double_asc(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The images' R, G, B and var.R/G/B; 0 when one is missing. */
static int cycles_noise_planes(const exr_image *img, const float *x[3], const float *v[3])
{
    int ok = 1;
    for (int c = 0; c < 3; c++) {
        char name[8] = "var.R";
        name[4] = "RGB"[c];
        v[c] = exr_image_channel(img, name);
        x[c] = exr_image_channel(img, name + 4);
        ok &= v[c] != NULL && x[c] != NULL;
    }
    return ok;
}

/* Over the n surface pixels (var[i]: the sum of its channels' variances, val[i]: its values'
 * mean) and their 3n values' standard errors sd: nrmse; trim1, the same without the k =
 * ceil(CYCLES_TRIM n) pixels of largest variance, as nrmse_trim1 drops the pixels of largest
 * error; pixel_q, the CYCLES_ZTEST_COVER quantile of sd (the value of rank ceil(q 3n), as the
 * metrics' percentiles), over the mean value. Sorts rank and sd. */
static void cycles_noise_of(metrics_ranked *rank, const double *val, double *sd, long n, cycles_noise *out)
{
    double sv = 0.0, sx = 0.0, kv = 0.0, kx = 0.0;
    metrics_rank_sort_desc(rank, (size_t)n);
    long k = (long)ceil(CYCLES_TRIM * (double)n);
    k = k > n - 1 ? n - 1 : k;
    for (long j = 0; j < n; j++) {
        sv += rank[j].key;
        sx += val[rank[j].index];
        if (j >= k) {
            kv += rank[j].key;
            kx += val[rank[j].index];
        }
    }
    qsort(sd, (size_t)(3 * n), sizeof *sd, cycles_double_asc);
    long q = (long)ceil(CYCLES_ZTEST_COVER * 3.0 * (double)n);
    out->nrmse = sqrt(sv / (3.0 * (double)n)) / (sx / (double)n);
    out->trim1 = kx > 0.0 ? sqrt(kv / (3.0 * (double)(n - k))) / (kx / (double)(n - k)) : out->nrmse;
    out->pixel_q = sd[(q < 1 ? 1 : q) - 1] / (sx / (double)n);
    out->n_values = 3 * n;
}

/* The surface's pixels as cycles_noise_of takes them; returns their count. The surface as the
 * metrics take it: interior pixels, not an edge's (whose variance is its coverage's, judged
 * apart in the edges region), nor a boundary between two objects. */
static long cycles_noise_pixels(const exr_image *img, const unsigned char *cls, const float *const x[3],
                                const float *const v[3], metrics_ranked *rank, double *val, double *sd)
{
    size_t np = (size_t)img->width * (size_t)img->height;
    long n = 0;
    for (size_t p = 0; p < np; p++) {
        if (cls[p] != METRICS_PX_INTERIOR)
            continue;
        double e = 0.0, a = 0.0;
        for (int c = 0; c < 3; c++) {
            e += v[c][p];
            a += x[c][p];
            sd[3 * n + c] = sqrt(fmax(v[c][p], 0.0)); /* a variance is >= 0; the value gate flags one that is not */
        }
        rank[n] = (metrics_ranked){e, (size_t)n};
        val[n++] = a / 3.0;
    }
    return n;
}

rc_status cycles_exr_noise(const char *exr_path, cycles_noise *out, char *err, size_t errlen)
{
    exr_image img;
    rc_status st = exr_read(exr_path, &img, err, errlen);
    if (st != RC_OK)
        return st;
    const float *v[3], *x[3];
    int ok = cycles_noise_planes(&img, x, v);
    size_t np = (size_t)img.width * (size_t)img.height;
    unsigned char *cls = ok ? malloc(np) : NULL;
    metrics_ranked *rank = ok ? malloc(np * sizeof *rank) : NULL;
    double *val = ok ? malloc(np * sizeof *val) : NULL, *sd = ok ? malloc(3 * np * sizeof *sd) : NULL;
    long n = 0;
    double sx = 0.0;
    if (cls != NULL && rank != NULL && val != NULL && sd != NULL) {
        metrics_classify(img.width, img.height, exr_image_channel(&img, "coverage"), exr_image_channel(&img, "object"),
                         cls);
        n = cycles_noise_pixels(&img, cls, (const float *const *)x, (const float *const *)v, rank, val, sd);
        for (long i = 0; i < n; i++)
            sx += val[i];
        if (n > 0 && sx > 0.0)
            cycles_noise_of(rank, val, sd, n, out);
    }
    free(sd);
    free(val);
    free(rank);
    free(cls);
    exr_image_free(&img);
    if (!ok || n == 0 || !(sx > 0.0)) { /* a failed malloc reads as no interior pixel */
        status_message(err, errlen, "%s: %s; render two seeds or more of a scene with a lit surface", exr_path,
                       !ok ? "no var.R/G/B channels" : "no interior pixel of non-zero mean");
        return RC_ERR_RANGE;
    }
    return RC_OK;
}
