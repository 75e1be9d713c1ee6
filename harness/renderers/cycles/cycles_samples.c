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

static int cycles_rms_metric(const char *metric)
{
    const char *m = cycles_metric_base(metric);
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

/* One z-test gate: its b from the comparison's RMS gate, else the scene's stated bias; the
 * smallest b over the gates wins. Neither: refused, naming the scene line and the fix. */
static void cycles_need_ztest(const scene *s, const comparison *c, const char *name, const char *metric, int full,
                              cycles_noise_need *out)
{
    double rms = cycles_rms_fail(c, full), b = rms > 0.0 ? rms : s->samples_bias;
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
                double target = g.fail / CYCLES_NOISE_MARGIN;
                if (out->target == 0.0 || target < out->target) {
                    out->target = target;
                    snprintf(out->gate, sizeof out->gate, "%s %s fail %g", name, t->metric, g.fail);
                }
            }
        }
    }
}

double cycles_ztest_span(long n_values)
{
    double m = n_values > 1 ? (double)n_values : 1.0;
    return -metrics_norm_quantile(0.5 * CYCLES_ZTEST_ALPHA / m) - metrics_norm_quantile(CYCLES_ZTEST_BETA);
}

double cycles_noise_target(const cycles_noise_need *need, long n_values)
{
    double t = need->target;
    if (need->bias > 0.0) {
        double z = need->bias / cycles_ztest_span(n_values);
        if (t == 0.0 || z < t)
            t = z;
    }
    return t;
}

int cycles_samples_for(double noise, int n_pilot, double target)
{
    if (!(target > 0.0) || !(noise > target))
        return n_pilot;
    double n = ceil(n_pilot * (noise / target) * (noise / target));
    return n > CYCLES_MAX_SPP ? CYCLES_MAX_SPP : (int)n;
}

rc_status cycles_exr_noise(const char *exr_path, cycles_noise *out, char *err, size_t errlen)
{
    exr_image img;
    rc_status st = exr_read(exr_path, &img, err, errlen);
    if (st != RC_OK)
        return st;
    const float *v[3], *x[3];
    int ok = 1;
    for (int c = 0; c < 3; c++) {
        char name[8] = "var.R";
        name[4] = "RGB"[c];
        v[c] = exr_image_channel(&img, name);
        x[c] = exr_image_channel(&img, name + 4);
        ok &= v[c] != NULL && x[c] != NULL;
    }
    /* The surface as the metrics take it: interior pixels, not an edge's (whose variance is its
     * coverage's, judged apart in the edges region), nor a boundary between two objects. */
    size_t np = (size_t)img.width * (size_t)img.height;
    unsigned char *cls = ok ? malloc(np) : NULL;
    if (cls != NULL)
        metrics_classify(img.width, img.height, exr_image_channel(&img, "coverage"), exr_image_channel(&img, "object"),
                         cls);
    double sv = 0.0, sx = 0.0;
    long n = 0;
    for (size_t p = 0; cls != NULL && p < np; p++) {
        if (cls[p] != METRICS_PX_INTERIOR)
            continue;
        for (int c = 0; c < 3; c++) {
            sv += v[c][p];
            sx += x[c][p];
        }
        n += 3;
    }
    free(cls);
    exr_image_free(&img);
    if (!ok || n == 0 || !(sx > 0.0)) { /* a failed malloc reads as no interior pixel */
        status_message(err, errlen, "%s: %s; render two seeds or more of a scene with a lit surface", exr_path,
                       !ok ? "no var.R/G/B channels" : "no interior pixel of non-zero mean");
        return RC_ERR_RANGE;
    }
    out->nrmse = sqrt(sv / (double)n) / (sx / (double)n);
    out->n_values = n;
    return RC_OK;
}
