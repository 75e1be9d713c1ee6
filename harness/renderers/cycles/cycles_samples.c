/* cycles_samples.c - a Cycles job's samples from its gates' noise (cycles_samples.h). */
#include "cycles_samples.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "exr.h"
#include "metrics.h"
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

static int cycles_ztest_metric(const char *metric) { return strncmp(cycles_metric_base(metric), "z_", 2) == 0; }

/* A twin render serves the twin comparisons; the validate render serves validate and agree. */
static int cycles_serves(const comparison *c, int row, comparison_role role)
{
    if (c->reference != row && c->test != row)
        return 0;
    return role == ROLE_TWIN ? c->role == ROLE_TWIN : c->role != ROLE_TWIN;
}

void cycles_noise_need_of(const scene *s, int row, comparison_role role, cycles_noise_need *out)
{
    static const char *const roles[] = {"twin", "validate", "agree"};
    memset(out, 0, sizeof *out);
    for (int i = 0; i < s->n_comparisons; i++) {
        const comparison *c = &s->comparisons[i];
        if (!cycles_serves(c, row, role))
            continue;
        for (int k = 0; k < c->n_thresholds; k++) {
            const threshold *t = &c->thresholds[k];
            const char *other = registry_name(c->reference == row ? c->test : c->reference);
            if (cycles_ztest_metric(t->metric) && !out->ztest) {
                out->ztest = 1;
                snprintf(out->gate, sizeof out->gate, "comparisons[%d] %s/%s %s", i, other ? other : "?",
                         roles[c->role], t->metric);
            }
            double target = t->fail / CYCLES_NOISE_MARGIN;
            if (out->ztest || !cycles_rms_metric(t->metric) || !(target > 0.0))
                continue;
            if (out->target == 0.0 || target < out->target) {
                out->target = target;
                snprintf(out->gate, sizeof out->gate, "comparisons[%d] %s/%s %s fail %g", i, other ? other : "?",
                         roles[c->role], t->metric, t->fail);
            }
        }
    }
}

int cycles_samples_for(double noise, int n_pilot, const cycles_noise_need *need)
{
    if (!(need->target > 0.0) || !(noise > need->target))
        return n_pilot;
    double n = ceil(n_pilot * (noise / need->target) * (noise / need->target));
    return n > CYCLES_MAX_SPP ? CYCLES_MAX_SPP : (int)n;
}

rc_status cycles_exr_noise(const char *exr_path, double *noise, char *err, size_t errlen)
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
    *noise = sqrt(sv / (double)n) / (sx / (double)n);
    return RC_OK;
}
