#include "compare.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cJSON.h>

#include "crease.h"
#include "exr.h"
#include "fileio.h"
#include "frame.h"
#include "jsonio.h"
#include "jobs.h"
#include "renderers/registry.h"
#include "d3d9client.h"
#include "metrics.h"
#include "scene_file.h"

static const char *const compare_aovs[3] = {"diffuse", "specular", "reflection"};
#define COMPARE_ANGLE_BINS 10

/* One side of a comparison: its record and image. */
typedef struct {
    int renderer; /* a row of the renderer table */
    comparison_role role;
    cJSON *record;
    exr_image img;
    int have_img;
    char path[1024];
} compare_side;

static cJSON *compare_read_json(const char *path)
{
    char *text = fileio_read_all(path, NULL);
    cJSON *j = text != NULL ? cJSON_Parse(text) : NULL;
    free(text);
    return j;
}

static const char *compare_json_str(const cJSON *o, const char *key)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
    return cJSON_IsString(v) ? v->valuestring : "";
}

/* What a side's job left: an image to compare, a job the vocabulary calls skipped (renderer
 * not installed, or it cannot represent the scene), or an error (no record, any other
 * status, an image that cannot be read). */
typedef enum { COMPARE_SIDE_OK = 0, COMPARE_SIDE_SKIPPED, COMPARE_SIDE_ERROR } compare_side_state;

/* Loads a side; the reason goes to buf unless the side is ok. */
static compare_side_state compare_load_side(const char *run, const char *scene_name, compare_side *s, char *buf,
                                            size_t len)
{
    char rec[1024];
    const char *rname = registry_name(s->renderer), *role = job_role_names[s->role];
    job_output_path(run, scene_name, s->renderer, s->role, "json", rec, sizeof rec);
    job_output_path(run, scene_name, s->renderer, s->role, "exr", s->path, sizeof s->path);
    s->record = compare_read_json(rec);
    if (s->record == NULL) {
        snprintf(buf, len,
                 "%s %s: no job record %s (missing or not JSON); render it with: reflcheck run SCENE "
                 "--renderer %s --role %s",
                 rname, role, rec, rname, role);
        return COMPARE_SIDE_ERROR;
    }
    const char *status = compare_json_str(s->record, "status");
    if (strcmp(status, "skipped") == 0) {
        snprintf(buf, len, "%s %s skipped: %s", rname, role, compare_json_str(s->record, "message"));
        return COMPARE_SIDE_SKIPPED;
    }
    if (strcmp(status, "ok") != 0) {
        snprintf(buf, len, "%s %s job %s: %s", rname, role, status[0] ? status : "has no status",
                 compare_json_str(s->record, "message"));
        return COMPARE_SIDE_ERROR;
    }
    char e[512];
    if (exr_read(s->path, &s->img, e, sizeof e) != RC_OK) {
        snprintf(buf, len, "%s %s job ok but its image cannot be read: %s", rname, role, e);
        return COMPARE_SIDE_ERROR;
    }
    s->have_img = 1;
    if (!exr_image_channel(&s->img, "R") || !exr_image_channel(&s->img, "G") || !exr_image_channel(&s->img, "B")) {
        snprintf(buf, len, "%s %s: %s has no R, G, B channels", rname, role, s->path);
        return COMPARE_SIDE_ERROR;
    }
    return COMPARE_SIDE_OK;
}

static void compare_side_free(compare_side *s)
{
    cJSON_Delete(s->record);
    s->record = NULL;
    if (s->have_img)
        exr_image_free(&s->img);
    s->have_img = 0;
}

static metrics_image compare_planes(const exr_image *img, const char *layer)
{
    metrics_image m = {img->width, img->height, {NULL, NULL, NULL}};
    const char *c = "RGB";
    for (int i = 0; i < 3; i++) {
        char name[64];
        if (layer[0])
            snprintf(name, sizeof name, "%s.%c", layer, c[i]);
        else
            snprintf(name, sizeof name, "%c", c[i]);
        m.c[i] = exr_image_channel(img, name);
    }
    return m;
}

static cJSON *compare_metrics_json(const metrics_result *r)
{
    cJSON *o = cJSON_CreateObject();
    cJSON_AddNumberToObject(o, "n_pixels", (double)r->n_pixels);
    cJSON_AddNumberToObject(o, "n_nonfinite", (double)r->n_nonfinite);
    cJSON_AddNumberToObject(o, "mae", r->mae);
    cJSON_AddNumberToObject(o, "rmse", r->rmse);
    cJSON_AddNumberToObject(o, "rel_mse", r->rel_mse);
    cJSON_AddNumberToObject(o, "rel_rms", r->rel_rms);
    /* JSON has no infinity: identical images report psnr as null. */
    if (isfinite(r->psnr))
        cJSON_AddNumberToObject(o, "psnr", r->psnr);
    else
        cJSON_AddNullToObject(o, "psnr");
    cJSON_AddNumberToObject(o, "max_abs", r->max_abs);
    cJSON_AddNumberToObject(o, "max_x", r->max_x);
    cJSON_AddNumberToObject(o, "max_y", r->max_y);
    cJSON_AddNumberToObject(o, "max_c", r->max_c);
    cJSON_AddNumberToObject(o, "max_ref", r->max_ref);
    cJSON_AddNumberToObject(o, "max_test", r->max_test);
    cJSON_AddNumberToObject(o, "share_over", r->share_over);
    cJSON_AddNumberToObject(o, "ssim", r->ssim);
    return o;
}

/* Metrics over a mask, or NULL when the mask selects nothing. */
static cJSON *compare_region(const metrics_image *ref, const metrics_image *test, const unsigned char *mask)
{
    metrics_options mo = {.rel_eps = COMPARE_REL_EPS, .threshold = 1e-3};
    metrics_result r;
    char e[256];
    if (metrics_compare(ref, test, mask, &mo, &r, e, sizeof e) != RC_OK || r.n_pixels == 0)
        return NULL;
    /* RMSE over the reference's mean: a relative error that dark pixels cannot blow up,
     * the headline for validate comparisons where the reference is near 0 in places. */
    double sum = 0.0;
    long n = 0;
    size_t np = (size_t)ref->width * (size_t)ref->height;
    for (size_t i = 0; i < np; i++) {
        if (mask != NULL && !mask[i])
            continue;
        double v = fabs((double)ref->c[0][i]) + fabs((double)ref->c[1][i]) + fabs((double)ref->c[2][i]);
        if (isfinite(v)) {
            sum += v / 3.0;
            n++;
        }
    }
    cJSON *o = compare_metrics_json(&r);
    cJSON_AddNumberToObject(o, "nrmse", n > 0 && sum > 0.0 ? r.rmse / (sum / (double)n) : 0.0);
    cJSON_AddNumberToObject(o, "nrmse_mean_n", (double)n);
    /* How the figure spreads over the pixels (metrics_robust): a headline a handful of pixels
     * carries shows as a large worst1_share and an nrmse_trim1 far below nrmse. */
    metrics_robust_options ro = {.rel_eps = COMPARE_REL_EPS, .trim = 0.01};
    metrics_robust_result rb;
    if (metrics_robust(ref, test, mask, &ro, &rb, e, sizeof e) == RC_OK) {
        cJSON_AddNumberToObject(o, "rel_median", rb.rel_median);
        cJSON_AddNumberToObject(o, "rel_p95", rb.rel_p95);
        cJSON_AddNumberToObject(o, "nrmse_trim1", rb.nrmse_trim);
        cJSON_AddNumberToObject(o, "worst1_share", rb.worst_share);
        cJSON_AddNumberToObject(o, "trim1_n", (double)rb.n_trimmed);
    }
    return o;
}

/* Mean of (R + G + B) / 3 over the mask. */
static double compare_mean(const metrics_image *m, const unsigned char *mask)
{
    double sum = 0.0;
    long n = 0;
    size_t np = (size_t)m->width * (size_t)m->height;
    for (size_t i = 0; i < np; i++) {
        double v = ((double)m->c[0][i] + (double)m->c[1][i] + (double)m->c[2][i]) / 3.0;
        if (mask[i] && isfinite(v)) {
            sum += v;
            n++;
        }
    }
    return n > 0 ? sum / (double)n : 0.0;
}

/* One term (the sum of `layers`, each "name" of a .R/.G/.B triple) of one image into out (3
 * planes of np). Returns 0 when the image has none of the layers. */
static int compare_term_planes(const exr_image *img, const char *const *layers, int n_layers, float *out[3])
{
    size_t np = (size_t)img->width * (size_t)img->height;
    int found = 0;
    for (int c = 0; c < 3; c++)
        memset(out[c], 0, np * sizeof(float));
    for (int l = 0; l < n_layers; l++) {
        metrics_image m = compare_planes(img, layers[l]);
        if (!m.c[0] || !m.c[1] || !m.c[2])
            continue;
        found = 1;
        for (int c = 0; c < 3; c++)
            for (size_t i = 0; i < np; i++)
                out[c][i] += m.c[c][i];
    }
    return found;
}

typedef struct {
    const char *name;
    const char *layers[2];
    int n;
    unsigned bits; /* RENDERER_TERM_* it holds */
} compare_term;

/* The terms compare_terms and the angle bins split the error into: a twin splits its light
 * as the model does; a physical reference files its glossy closures its own way (Cycles puts
 * lamps and environment under specular), so validate and agree take glossy = specular +
 * reflection. */
static const compare_term compare_twin_terms[3] = {{"diffuse", {"diffuse"}, 1, RENDERER_TERM_DIFFUSE},
                                                   {"specular", {"specular"}, 1, RENDERER_TERM_SPECULAR},
                                                   {"reflection", {"reflection"}, 1, RENDERER_TERM_REFLECTION}};
static const compare_term compare_phys_terms[2] = {
    {"diffuse", {"diffuse"}, 1, RENDERER_TERM_DIFFUSE},
    {"glossy", {"specular", "reflection"}, 2, RENDERER_TERM_SPECULAR | RENDERER_TERM_REFLECTION}};

/* The float floor under a bias: a path tracer's pixel is a float sum of a few hundred float
 * samples (2^-24 each), good to about 1e-5 of the image's level; an offset below that is
 * rounding, whatever the sampling noise says (a term of float dust against a variance of 1e-24
 * would otherwise read as z = 500). */
#define COMPARE_BIAS_FLOAT_FLOOR 1e-5

typedef struct {
    double z, rel; /* the channel with the largest |z|: mean offset over its standard error, and over the ref's mean */
} compare_bias_value;

/* A bias a per-pixel z-test cannot see: a small offset spread over every pixel. Per channel,
 * the mean difference over the kept pixels, d = mean(test - ref), against its standard error
 * from both sides' per-pixel variances plus the float floor, se = sqrt(sum var_i + n f^2) / n
 * with f = COMPARE_BIAS_FLOAT_FLOOR x scale (pixels independent: a box filter of width 1 shares
 * no sample between pixels). Returns 0 when no pixel is kept. */
static int compare_bias_core(const float *const tp[3], const float *const rp[3], const float *const rv[3],
                             const float *const tv[3], const unsigned char *keep, size_t np, double scale,
                             compare_bias_value *out)
{
    int any = 0;
    double f = COMPARE_BIAS_FLOAT_FLOOR * scale;
    *out = (compare_bias_value){0.0, 0.0};
    for (int c = 0; c < 3; c++) {
        double d = 0.0, v = 0.0, ref = 0.0;
        long n = 0;
        for (size_t i = 0; i < np; i++) {
            double di = (double)tp[c][i] - (double)rp[c][i];
            double vi = (double)rv[c][i] + (tv != NULL ? (double)tv[c][i] : 0.0);
            if (!keep[i] || !isfinite(di) || !isfinite(vi))
                continue;
            d += di;
            v += vi + f * f;
            ref += rp[c][i];
            n++;
        }
        if (n == 0)
            continue;
        /* Both sides exactly equal and no variance at all: no offset to test. */
        double zc = v > 0.0 ? d / sqrt(v) : 0.0;
        if (!any || fabs(zc) > fabs(out->z))
            *out = (compare_bias_value){zc, ref != 0.0 ? d / ref : 0.0};
        any = 1;
    }
    return any;
}

/* keep = mask without the 1 % of its pixels (nearest rank, floor) of largest |test - ref|
 * summed over R, G, B: the robust bias, which one sub-pixel feature (a reflected sun that k x k
 * point samples and a pixel integral weigh differently) cannot carry, while an offset spread
 * over every pixel still shows in full. Returns 0 when out of memory. */
static int compare_bias_trim(const float *const tp[3], const float *const rp[3], const unsigned char *mask, size_t np,
                             unsigned char *keep)
{
    memcpy(keep, mask, np);
    metrics_ranked *rank = malloc(np * sizeof *rank);
    if (rank == NULL)
        return 0;
    size_t n = 0;
    for (size_t i = 0; i < np; i++) {
        if (!mask[i])
            continue;
        double e =
            fabs((double)tp[0][i] - rp[0][i]) + fabs((double)tp[1][i] - rp[1][i]) + fabs((double)tp[2][i] - rp[2][i]);
        /* A non-finite pixel is the worst (its comparison fails the value gate anyway). */
        rank[n++] = (metrics_ranked){isnan(e) ? INFINITY : e, i};
    }
    metrics_rank_sort_desc(rank, n);
    for (size_t k = 0; k < n / 100; k++)
        keep[rank[k].index] = 0;
    free(rank);
    return 1;
}

/* Both bias figures (all surface pixels, and without the worst 1 %) into o as PREFIX_z,
 * PREFIX_rel, PREFIX_z_trim1, PREFIX_rel_trim1; nothing without a pixel. */
static void compare_bias_put(const float *const tp[3], const float *const rp[3], const float *const rv[3],
                             const float *const tv[3], const unsigned char *mask, size_t np, double scale, cJSON *o)
{
    unsigned char *keep = malloc(np);
    compare_bias_value all, trim;
    if (keep != NULL && compare_bias_core(tp, rp, rv, tv, mask, np, scale, &all)) {
        if (compare_bias_trim(tp, rp, mask, np, keep) && compare_bias_core(tp, rp, rv, tv, keep, np, scale, &trim)) {
            cJSON_AddNumberToObject(o, "bias_z", all.z);
            cJSON_AddNumberToObject(o, "bias_rel", all.rel);
            cJSON_AddNumberToObject(o, "bias_z_trim1", trim.z);
            cJSON_AddNumberToObject(o, "bias_rel_trim1", trim.rel);
        }
    }
    free(keep);
}

/* A term's bias from its var.<layer> planes, layers of one sample taken as independent (an
 * upper bound on the variance where they correlate); nothing when the reference has no such
 * planes (a deterministic renderer). */
static void compare_term_bias(const exr_image *t, const exr_image *r, const compare_term *term, float *tp[3],
                              float *rp[3], const unsigned char *mask, double scale, cJSON *m)
{
    size_t np = (size_t)t->width * (size_t)t->height;
    float *vb = malloc(6 * np * sizeof(float));
    if (vb == NULL)
        return;
    float *rv[3] = {vb, vb + np, vb + 2 * np}, *tv[3] = {vb + 3 * np, vb + 4 * np, vb + 5 * np};
    char names[2][64];
    const char *vl[2];
    for (int l = 0; l < term->n; l++) {
        snprintf(names[l], sizeof names[l], "var.%s", term->layers[l]);
        vl[l] = names[l];
    }
    if (compare_term_planes(r, vl, term->n, rv)) {
        int test_var = compare_term_planes(t, vl, term->n, tv);
        const float *tc[3] = {tp[0], tp[1], tp[2]}, *rc[3] = {rp[0], rp[1], rp[2]};
        const float *rvc[3] = {rv[0], rv[1], rv[2]}, *tvc[3] = {tv[0], tv[1], tv[2]};
        compare_bias_put(tc, rc, rvc, test_var ? tvc : NULL, mask, np, scale, m);
    }
    free(vb);
}

/* The worst of o's members by |KEY|: its name and that member, or NULL. */
static const cJSON *compare_bias_worst(const cJSON *group, const char *key, const cJSON *worst)
{
    const cJSON *t;
    cJSON_ArrayForEach(t, group)
    {
        const cJSON *z = cJSON_GetObjectItemCaseSensitive(t, key);
        if (cJSON_IsNumber(z) &&
            (worst == NULL ||
             fabs(z->valuedouble) > fabs(cJSON_GetNumberValue(cJSON_GetObjectItemCaseSensitive(worst, key)))))
            worst = t;
    }
    return worst;
}

/* compare.json's "bias": the image's (R, G, B with var.R/G/B, as "image") and each term's mean
 * departure from the reference in standard errors; z_max / term / rel the largest |bias_z|,
 * z_trim1_max / term_trim1 / rel_trim1 the largest |bias_z_trim1|. Absent where the reference
 * has no variance layers. */
static void compare_bias_summary(const metrics_image *tm, const metrics_image *rm, const exr_image *t,
                                 const exr_image *r, cJSON *terms, const unsigned char *mask, cJSON *cmp)
{
    metrics_image rv = compare_planes(r, "var"), tv = compare_planes(t, "var");
    size_t np = (size_t)r->width * (size_t)r->height;
    cJSON *image = cJSON_CreateObject();
    if (rv.c[0] && rv.c[1] && rv.c[2])
        compare_bias_put(tm->c, rm->c, rv.c, tv.c[0] && tv.c[1] && tv.c[2] ? tv.c : NULL, mask, np,
                         compare_mean(rm, mask), image);
    cJSON *all = cJSON_CreateObject();
    cJSON_AddItemToObject(all, "image", image);
    const cJSON *w = compare_bias_worst(terms, "bias_z", compare_bias_worst(all, "bias_z", NULL));
    const cJSON *wt = compare_bias_worst(terms, "bias_z_trim1", compare_bias_worst(all, "bias_z_trim1", NULL));
    if (w != NULL && wt != NULL) {
        cJSON *b = cJSON_AddObjectToObject(cmp, "bias");
        cJSON_AddNumberToObject(b, "z_max", fabs(cJSON_GetNumberValue(cJSON_GetObjectItemCaseSensitive(w, "bias_z"))));
        cJSON_AddStringToObject(b, "term", w->string);
        cJSON_AddNumberToObject(b, "rel", cJSON_GetNumberValue(cJSON_GetObjectItemCaseSensitive(w, "bias_rel")));
        cJSON_AddNumberToObject(b, "z_trim1_max",
                                fabs(cJSON_GetNumberValue(cJSON_GetObjectItemCaseSensitive(wt, "bias_z_trim1"))));
        cJSON_AddStringToObject(b, "term_trim1", wt->string);
        cJSON_AddNumberToObject(b, "rel_trim1",
                                cJSON_GetNumberValue(cJSON_GetObjectItemCaseSensitive(wt, "bias_rel_trim1")));
    }
    cJSON_Delete(all);
}

/* Error by term on the surface, from the layers both sides have: each term's mean on both
 * sides and its RMSE over the whole reference image's mean (so the terms' figures share one
 * scale with the image's nrmse). A twin splits its light as the model does: diffuse, specular,
 * reflection. A physical reference files its glossy closures its own way (Cycles puts lamps
 * and environment under specular), so validate and agree compare diffuse and glossy =
 * specular + reflection. */
static cJSON *compare_terms(const exr_image *t, const exr_image *r, const metrics_image *rfull, unsigned left_out,
                            int twin, const unsigned char *mask)
{
    const compare_term *terms = twin ? compare_twin_terms : compare_phys_terms;
    int n_terms = twin ? 3 : 2;
    cJSON *o = cJSON_CreateObject();
    size_t np = (size_t)t->width * (size_t)t->height;
    float *buf = malloc(6 * np * sizeof(float));
    double scale = compare_mean(rfull, mask);
    for (int k = 0; buf != NULL && k < n_terms; k++) {
        if (left_out & terms[k].bits)
            continue;
        float *tp[3] = {buf, buf + np, buf + 2 * np}, *rp[3] = {buf + 3 * np, buf + 4 * np, buf + 5 * np};
        if (!compare_term_planes(t, terms[k].layers, terms[k].n, tp) ||
            !compare_term_planes(r, terms[k].layers, terms[k].n, rp))
            continue;
        metrics_image tm = {t->width, t->height, {tp[0], tp[1], tp[2]}};
        metrics_image rm = {t->width, t->height, {rp[0], rp[1], rp[2]}};
        double se = 0.0;
        long cnt = 0;
        for (size_t i = 0; i < np; i++) {
            if (!mask[i])
                continue;
            double e = 0.0;
            for (int c = 0; c < 3; c++) {
                double d = (double)tp[c][i] - (double)rp[c][i];
                e += d * d;
            }
            if (isfinite(e)) {
                se += e;
                cnt++;
            }
        }
        cJSON *m = cJSON_AddObjectToObject(o, terms[k].name);
        cJSON_AddNumberToObject(m, "test_mean", compare_mean(&tm, mask));
        cJSON_AddNumberToObject(m, "ref_mean", compare_mean(&rm, mask));
        cJSON_AddNumberToObject(m, "nrmse", cnt > 0 && scale > 0.0 ? sqrt(se / (3.0 * (double)cnt)) / scale : 0.0);
        cJSON_AddNumberToObject(m, "n_pixels", (double)cnt);
        compare_term_bias(t, r, &terms[k], tp, rp, mask, scale, m);
    }
    free(buf);
    return o;
}

/* What the angle bins split the surface's error by: the images compared (a partial twin's
 * already without its left-out terms), each term's planes on both sides (compare_terms' split:
 * a twin's diffuse, specular, reflection, a physical reference's diffuse and glossy; NULL where
 * a side lacks the term or it was left out), the object layer and the scene's materials. */
typedef struct {
    const metrics_image *ref, *test;
    const unsigned char *mask; /* the surface */
    const float *object;       /* the object layer, or NULL */
    const scene *s;
    int n_terms;
    const compare_term *terms;
    float *tp[3][3], *rp[3][3]; /* per term, R G B; NULL when not compared */
    double total_se;            /* squared error of the image over the surface (R + G + B) */
    double total_term_se;       /* the terms' squared errors summed over the surface */
} compare_bin_ctx;

/* One bin's running sums. */
typedef struct {
    long n, bad;
    double se_rel, sum_rel, se;
    double term_se[3];
    double mat_se[SCENE_MAX_MATERIALS];
    long mat_n[SCENE_MAX_MATERIALS];
} compare_bin_acc;

/* Squared error summed over R, G, B of pixel i between two plane triples; NaN if not finite. */
static double compare_px_se(const float *const t[3], const float *const r[3], size_t i)
{
    double e = 0.0;
    for (int c = 0; c < 3; c++) {
        double d = (double)t[c][i] - (double)r[c][i];
        e += d * d;
    }
    return e;
}

/* The material index of pixel i (its centre sample's object's), or -1. */
static int compare_px_material(const compare_bin_ctx *x, size_t i)
{
    if (x->object == NULL)
        return -1;
    int ob = (int)x->object[i];
    return ob >= 0 && ob < x->s->n_objects ? x->s->objects[ob].material : -1;
}

/* Pixel i (finite on both sides) into bin a: relative and absolute error, per term, per material. */
static void compare_bin_add(const compare_bin_ctx *x, size_t i, compare_bin_acc *a)
{
    const metrics_image *ref = x->ref, *test = x->test;
    for (int c = 0; c < 3; c++) {
        double d = (double)test->c[c][i] - (double)ref->c[c][i];
        a->se_rel += d * d / ((double)ref->c[c][i] * ref->c[c][i] + COMPARE_REL_EPS);
        a->sum_rel += fabs(d) / (fabs((double)ref->c[c][i]) + sqrt(COMPARE_REL_EPS));
    }
    double e = compare_px_se((const float *const *)test->c, (const float *const *)ref->c, i);
    a->se += e;
    for (int k = 0; k < x->n_terms; k++) {
        if (x->tp[k][0] == NULL)
            continue;
        double te = compare_px_se((const float *const *)x->tp[k], (const float *const *)x->rp[k], i);
        a->term_se[k] += isfinite(te) ? te : 0.0;
    }
    int m = compare_px_material(x, i);
    if (m >= 0) {
        a->mat_se[m] += e;
        a->mat_n[m]++;
    }
    a->n++;
}

/* share = part / whole, 0 when there is nothing to share (identical images). */
static double compare_share(double part, double whole) { return whole > 0.0 ? part / whole : 0.0; }

/* One bin's JSON: its range, counts, relative errors, its share of the surface's squared error
 * and that error split by term and by material. */
static cJSON *compare_bin_json(const compare_bin_ctx *x, const compare_bin_acc *a, int b)
{
    cJSON *o = cJSON_CreateObject();
    cJSON_AddNumberToObject(o, "lo", (double)b / COMPARE_ANGLE_BINS);
    cJSON_AddNumberToObject(o, "hi", (double)(b + 1) / COMPARE_ANGLE_BINS);
    cJSON_AddNumberToObject(o, "n", (double)a->n);
    cJSON_AddNumberToObject(o, "n_nonfinite", (double)a->bad);
    /* A bin of only non-finite pixels measured nothing: NaN, which cJSON writes as null. */
    double n3 = 3.0 * (double)a->n;
    cJSON_AddNumberToObject(o, "rel_rms", a->n > 0 ? sqrt(a->se_rel / n3) : NAN);
    cJSON_AddNumberToObject(o, "mean_rel", a->n > 0 ? a->sum_rel / n3 : NAN);
    cJSON_AddNumberToObject(o, "rmse", a->n > 0 ? sqrt(a->se / n3) : NAN);
    cJSON_AddNumberToObject(o, "share", compare_share(a->se, x->total_se));
    cJSON *terms = cJSON_AddObjectToObject(o, "terms");
    for (int k = 0; k < x->n_terms; k++) {
        if (x->tp[k][0] == NULL)
            continue;
        cJSON *t = cJSON_AddObjectToObject(terms, x->terms[k].name);
        cJSON_AddNumberToObject(t, "rmse", a->n > 0 ? sqrt(a->term_se[k] / n3) : NAN);
        cJSON_AddNumberToObject(t, "share", compare_share(a->term_se[k], x->total_term_se));
    }
    cJSON *mats = cJSON_AddObjectToObject(o, "materials");
    for (int m = 0; x->object != NULL && m < x->s->n_materials; m++) {
        if (a->mat_n[m] == 0 || cJSON_GetObjectItemCaseSensitive(mats, x->s->materials[m].name) != NULL)
            continue;
        cJSON *t = cJSON_AddObjectToObject(mats, x->s->materials[m].name);
        cJSON_AddNumberToObject(t, "n", (double)a->mat_n[m]);
        cJSON_AddNumberToObject(t, "rmse", sqrt(a->mat_se[m] / (3.0 * (double)a->mat_n[m])));
        cJSON_AddNumberToObject(t, "share", compare_share(a->mat_se[m], x->total_se));
    }
    return o;
}

/* Per bin of an angle channel (N.V, N.H or N.L, 10 bins of 0.1 over (0, 1]; pixels at or
 * below 0 are in no bin) over the surface: relative RMS error, and the bin's share of the
 * surface's squared error, split by term and by material (compare_bin_json). */
static cJSON *compare_angle_bins(const compare_bin_ctx *x, const float *angle)
{
    cJSON *arr = cJSON_CreateArray();
    compare_bin_acc *acc = calloc(COMPARE_ANGLE_BINS, sizeof *acc);
    if (angle == NULL || acc == NULL) {
        free(acc);
        return arr;
    }
    size_t np = (size_t)x->ref->width * (size_t)x->ref->height;
    for (size_t i = 0; i < np; i++) {
        if (!x->mask[i] || !(angle[i] > 0.0f))
            continue;
        int b = (int)(angle[i] * COMPARE_ANGLE_BINS);
        b = b >= COMPARE_ANGLE_BINS ? COMPARE_ANGLE_BINS - 1 : b;
        /* Counted apart, as metrics_compare does, so a bin says how many pixels it measured. */
        if (!isfinite(compare_px_se((const float *const *)x->test->c, (const float *const *)x->ref->c, i))) {
            acc[b].bad++;
            continue;
        }
        compare_bin_add(x, i, &acc[b]);
    }
    for (int b = 0; b < COMPARE_ANGLE_BINS; b++)
        if (acc[b].n != 0 || acc[b].bad != 0)
            cJSON_AddItemToArray(arr, compare_bin_json(x, &acc[b], b));
    free(acc);
    return arr;
}

/* The angle bins' context: each term's planes of both sides and the surface totals every
 * share is taken of. Returns 0, or -1 out of memory; compare_bin_free frees either way. */
static int compare_bin_setup(compare_bin_ctx *x, const exr_image *t, const exr_image *r, unsigned left_out, int twin)
{
    size_t np = (size_t)t->width * (size_t)t->height;
    x->terms = twin ? compare_twin_terms : compare_phys_terms;
    x->n_terms = twin ? 3 : 2;
    for (int k = 0; k < x->n_terms; k++) {
        float *buf = malloc(6 * np * sizeof(float));
        if (buf == NULL)
            return -1;
        for (int c = 0; c < 3; c++) {
            x->tp[k][c] = buf + (size_t)c * np;
            x->rp[k][c] = buf + (size_t)(3 + c) * np;
        }
        if ((left_out & x->terms[k].bits) || !compare_term_planes(t, x->terms[k].layers, x->terms[k].n, x->tp[k]) ||
            !compare_term_planes(r, x->terms[k].layers, x->terms[k].n, x->rp[k])) {
            free(buf);
            memset(x->tp[k], 0, sizeof x->tp[k]);
            memset(x->rp[k], 0, sizeof x->rp[k]);
        }
    }
    for (size_t i = 0; i < np; i++) {
        double e =
            x->mask[i] ? compare_px_se((const float *const *)x->test->c, (const float *const *)x->ref->c, i) : NAN;
        if (!isfinite(e))
            continue;
        x->total_se += e;
        for (int k = 0; k < x->n_terms; k++) {
            double te =
                x->tp[k][0] ? compare_px_se((const float *const *)x->tp[k], (const float *const *)x->rp[k], i) : NAN;
            x->total_term_se += isfinite(te) ? te : 0.0;
        }
    }
    return 0;
}

static void compare_bin_free(compare_bin_ctx *x)
{
    for (int k = 0; k < 3; k++)
        free(x->tp[k][0]);
}

/* compare.json's angle_bins (N.V), angle_bins_ndoth and angle_bins_ndotl, from the raster
 * geometry's layers (geo; no bins without it). */
static void compare_angle_bins_put(const scene *s, const comparison *c, const exr_image *geo, const exr_image *t,
                                   const exr_image *r, const metrics_image *tm, const metrics_image *rm,
                                   unsigned left_out, const unsigned char *mask, cJSON *o)
{
    static const char *const keys[3] = {"angle_bins", "angle_bins_ndoth", "angle_bins_ndotl"};
    static const char *const layers[3] = {"ndotv", "ndoth", "ndotl"};
    compare_bin_ctx x = {.ref = rm, .test = tm, .mask = mask, .s = s};
    x.object = geo ? exr_image_channel(geo, "object") : NULL;
    int ok = compare_bin_setup(&x, t, r, left_out, c->role == ROLE_TWIN) == 0;
    for (int a = 0; a < 3; a++)
        cJSON_AddItemToObject(o, keys[a],
                              ok ? compare_angle_bins(&x, geo ? exr_image_channel(geo, layers[a]) : NULL)
                                 : cJSON_CreateArray());
    compare_bin_free(&x);
}

/* The variance of a Cycles mean from a few seeds has few degrees of freedom; pooling it over
 * the 3x3 neighbourhood (same mask) multiplies them by up to 9, so the normal quantiles of
 * the z-test are not fooled by a lucky low estimate. Noise varies smoothly across a surface. */
static void compare_pool_variance(const metrics_image *var, const unsigned char *mask, float *out[3])
{
    int w = var->width, h = var->height;
    for (int c = 0; c < 3; c++)
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                double s = 0.0;
                int n = 0;
                for (int dy = -1; dy <= 1; dy++)
                    for (int dx = -1; dx <= 1; dx++) {
                        int xx = x + dx, yy = y + dy;
                        if (xx < 0 || yy < 0 || xx >= w || yy >= h || !mask[yy * w + xx])
                            continue;
                        s += var->c[c][yy * w + xx];
                        n++;
                    }
                out[c][y * w + x] = n > 0 ? (float)(s / n) : var->c[c][y * w + x];
            }
}

static cJSON *compare_noise(const exr_image *ref, const metrics_image *refm, const exr_image *test,
                            const metrics_image *testm, const unsigned char *mask)
{
    metrics_image rv = compare_planes(ref, "var");
    if (rv.c[0] == NULL || rv.c[1] == NULL || rv.c[2] == NULL)
        return NULL;
    size_t np = (size_t)ref->width * (size_t)ref->height;
    float *pool[6];
    for (int i = 0; i < 6; i++)
        pool[i] = malloc(np * sizeof(float));
    cJSON *o = NULL;
    if (pool[0] && pool[1] && pool[2] && pool[3] && pool[4] && pool[5]) {
        compare_pool_variance(&rv, mask, pool);
        metrics_image pv = {ref->width, ref->height, {pool[0], pool[1], pool[2]}};
        metrics_image tv = compare_planes(test, "var"), *tvp = NULL;
        metrics_image tpv = {ref->width, ref->height, {pool[3], pool[4], pool[5]}};
        if (tv.c[0] && tv.c[1] && tv.c[2]) {
            compare_pool_variance(&tv, mask, &pool[3]);
            tvp = &tpv;
        }
        double var_sum = 0.0, ref_sq = 0.0;
        long n = 0;
        for (size_t i = 0; i < np; i++) {
            if (!mask[i])
                continue;
            for (int c = 0; c < 3; c++) {
                var_sum += rv.c[c][i];
                ref_sq += (double)refm->c[c][i] * refm->c[c][i];
            }
            n++;
        }
        metrics_ztest_options zo = {.alpha = 0.01, .correction = METRICS_HOLM};
        metrics_ztest_result z;
        char e[256];
        o = cJSON_CreateObject();
        cJSON_AddNumberToObject(o, "ref_rel_rms", n > 0 && ref_sq > 0 ? sqrt(var_sum / ref_sq) : 0.0);
        if (metrics_ztest(refm, &pv, testm, tvp, mask, &zo, &z, e, sizeof e) == RC_OK) {
            cJSON *zj = cJSON_AddObjectToObject(o, "ztest");
            cJSON_AddNumberToObject(zj, "n_tests", (double)z.n_tests);
            cJSON_AddNumberToObject(zj, "n_nonfinite", (double)z.n_nonfinite);
            cJSON_AddNumberToObject(zj, "n_fail", (double)z.n_fail);
            cJSON_AddNumberToObject(zj, "n_fail_pixels", (double)z.n_fail_pixels);
            cJSON_AddNumberToObject(zj, "z_crit", z.z_crit);
            cJSON_AddNumberToObject(zj, "max_abs_z", z.max_abs_z);
            cJSON_AddNumberToObject(zj, "share_fail_pixels", n > 0 ? (double)z.n_fail_pixels / (double)n : 0.0);
            cJSON_AddStringToObject(zj, "correction", "holm, alpha 0.01, variance pooled 3x3");
        }
    }
    for (int i = 0; i < 6; i++)
        free(pool[i]);
    return o;
}

/* Looks a threshold's metric up in a comparison's JSON. */
static int compare_metric_value(const cJSON *cmp, const char *metric, double *v)
{
    const cJSON *x = NULL;
    char head[64];
    const char *dot = strchr(metric, '.');
    if (strcmp(metric, "z_fail_share") == 0) {
        x = cJSON_GetObjectItemCaseSensitive(
            cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(cmp, "noise"), "ztest"),
            "share_fail_pixels");
    } else if (strcmp(metric, "noise_rel_rms") == 0) {
        x = cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(cmp, "noise"), "ref_rel_rms");
    } else if (strcmp(metric, "coverage_agreement") == 0 || strcmp(metric, "test_nonfinite") == 0 ||
               strcmp(metric, "ref_nonfinite") == 0 || strcmp(metric, "test_negative") == 0 ||
               strcmp(metric, "ref_negative") == 0) {
        x = cJSON_GetObjectItemCaseSensitive(cmp, metric);
    } else if (dot != NULL && (size_t)(dot - metric) < sizeof head) {
        memcpy(head, metric, (size_t)(dot - metric));
        head[dot - metric] = '\0';
        const cJSON *grp = cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(cmp, "regions"), head);
        if (grp == NULL)
            grp = cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(cmp, "aovs"), head);
        if (grp == NULL)
            grp = cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(cmp, "terms"), head);
        if (grp == NULL && strcmp(head, "bias") == 0)
            grp = cJSON_GetObjectItemCaseSensitive(cmp, "bias");
        x = cJSON_GetObjectItemCaseSensitive(grp, dot + 1);
    } else {
        x = cJSON_GetObjectItemCaseSensitive(
            cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(cmp, "regions"), "surface"), metric);
    }
    if (!cJSON_IsNumber(x))
        return 0;
    *v = x->valuedouble;
    return 1;
}

static int compare_higher_is_better(const char *metric)
{
    const char *base = strrchr(metric, '.');
    base = base ? base + 1 : metric;
    return strcmp(base, "psnr") == 0 || strcmp(base, "ssim") == 0 || strcmp(base, "coverage_agreement") == 0;
}

/* Whether a threshold judges accuracy (how far the images are apart), or only guards the
 * inputs: that the values are finite and of the right sign, that the silhouettes agree, that a
 * region set apart stays small. A comparison with guards alone has no accuracy gate: its
 * verdict is "not_gated", never "pass", whatever its figures. */
static int compare_is_accuracy(const char *metric)
{
    static const char *const guards[] = {"test_nonfinite", "ref_nonfinite",      "test_negative",
                                         "ref_negative",   "coverage_agreement", "crease.share_of_surface"};
    for (size_t i = 0; i < sizeof guards / sizeof guards[0]; i++)
        if (strcmp(metric, guards[i]) == 0)
            return 0;
    return 1;
}

/* Whether a comparison's renders are the full size (1) or the small variant (0), from the
 * job records' variant: it picks each threshold's gate (scene-file small: and full:). A record
 * without the field (written before it existed) counts as the full size, the only size runs
 * rendered then. */
static int compare_full_size(const compare_side *t, const compare_side *r)
{
    const char *v = compare_json_str(t->record, "variant");
    if (v[0] == '\0')
        v = compare_json_str(r->record, "variant");
    return strcmp(v, "small") != 0;
}

/* The gate a threshold applied at this size, and the figure it was sized on, into its entry. */
static void compare_gate_json(const threshold_gate *g, int full, cJSON *o)
{
    static const char *const sizes[] = {"", "small", "full"};
    cJSON_AddStringToObject(o, "size", full ? "full" : "small");
    cJSON_AddStringToObject(o, "levels", g->own ? (full ? "full" : "small") : "shared");
    cJSON_AddStringToObject(o, "loose", g->loose);
    if (g->sized_size != SIZED_NONE) {
        cJSON *z = cJSON_AddObjectToObject(o, "sized");
        cJSON_AddNumberToObject(z, "figure", g->sized_figure);
        cJSON_AddStringToObject(z, "size", sizes[g->sized_size]);
        cJSON_AddStringToObject(z, "run", g->sized_run);
    }
}

static const char *compare_judge(const scene *s, const comparison *c, int full, cJSON *cmp, const char *id,
                                 compare_summary *sum)
{
    cJSON *arr = cJSON_AddArrayToObject(cmp, "thresholds");
    int worst = 0; /* 0 pass, 1 warn, 2 fail */
    int accuracy = 0;
    for (int i = 0; i < c->n_thresholds; i++) {
        const threshold *t = &c->thresholds[i];
        threshold_gate g;
        threshold_gate_at(t, full, &g);
        accuracy += compare_is_accuracy(t->metric);
        cJSON *o = cJSON_CreateObject();
        cJSON_AddStringToObject(o, "metric", t->metric);
        cJSON_AddNumberToObject(o, "warn", g.warn);
        cJSON_AddNumberToObject(o, "fail", g.fail);
        cJSON_AddStringToObject(o, "why", t->why);
        compare_gate_json(&g, full, o);
        double v;
        const char *verdict;
        /* A NaN compares false with both limits and would pass: it fails like a missing value. */
        if (!compare_metric_value(cmp, t->metric, &v) || isnan(v)) {
            verdict = "fail";
            cJSON_AddNullToObject(o, "value");
            worst = 2;
            if (sum->first_failure[0] == '\0')
                snprintf(sum->first_failure, sizeof sum->first_failure,
                         "%s: %s: metric %s was not measured or is NaN (threshold %g); scene key "
                         "comparisons[%d].thresholds.%s",
                         s->name, id, t->metric, g.fail, (int)(c - s->comparisons), t->metric);
        } else {
            int hib = compare_higher_is_better(t->metric);
            int fail = hib ? v < g.fail : v > g.fail;
            int warn = hib ? v < g.warn : v > g.warn;
            verdict = fail ? "fail" : warn ? "warn" : "pass";
            cJSON_AddNumberToObject(o, "value", v);
            if (fail && worst < 2) {
                worst = 2;
            } else if (warn && worst < 1)
                worst = 1;
            if (fail && sum->first_failure[0] == '\0')
                snprintf(sum->first_failure, sizeof sum->first_failure,
                         "%s: %s: %s = %.4g %s fail threshold %.4g at %s size (%s); scene key "
                         "comparisons[%d].thresholds.%s%s",
                         s->name, id, t->metric, v, hib ? "<" : ">", g.fail, full ? "full" : "small", t->why,
                         (int)(c - s->comparisons), t->metric, g.own ? (full ? ".full" : ".small") : "");
        }
        cJSON_AddStringToObject(o, "verdict", verdict);
        cJSON_AddItemToArray(arr, o);
    }
    return worst == 2 ? "fail" : worst == 1 ? "warn" : accuracy == 0 ? "not_gated" : "pass";
}

static const char compare_b64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

/* Appends base64 of n floats (little-endian IEEE, as JS Float32Array reads on x86/ARM). */
static void compare_append_b64(FILE *f, const float *v, size_t n)
{
    const unsigned char *p = (const unsigned char *)v;
    size_t len = n * sizeof(float);
    for (size_t i = 0; i < len; i += 3) {
        unsigned a = p[i], b = i + 1 < len ? p[i + 1] : 0, c = i + 2 < len ? p[i + 2] : 0;
        unsigned t = (a << 16) | (b << 8) | c;
        fputc(compare_b64[(t >> 18) & 63], f);
        fputc(compare_b64[(t >> 12) & 63], f);
        fputc(i + 1 < len ? compare_b64[(t >> 6) & 63] : '=', f);
        fputc(i + 2 < len ? compare_b64[t & 63] : '=', f);
    }
}

/* A JSON string that is also safe inside a script file: a scene named after a file such as
 * `<!--<script>.yaml` must not open an HTML comment (which script files honour) or end a
 * script element, and a quote or backslash must not end the string. */
static void compare_put_js_string(FILE *f, const char *text)
{
    fputc('"', f);
    for (const unsigned char *p = (const unsigned char *)text; *p; p++) {
        if (*p == '"' || *p == '\\')
            fprintf(f, "\\%c", *p);
        else if (*p < 0x20 || *p == '<' || *p == '>' || *p == '&')
            fprintf(f, "\\u%04x", *p);
        else if (p[0] == 0xe2 && p[1] == 0x80 && (p[2] == 0xa8 || p[2] == 0xa9)) {
            /* U+2028 and U+2029 end a line in older JavaScript. */
            fprintf(f, "\\u%04x", p[2] == 0xa8 ? 0x2028 : 0x2029);
            p += 2;
        } else
            fputc(*p, f);
    }
    fputc('"', f);
}

/* view.js: every render of this scene as interleaved RGB floats, plus coverage and N.V. */
static rc_status compare_write_view(const scene *s, const char *run, char *err, size_t errlen)
{
    char path[1024], target[FILEIO_PATH_MAX], tmp[FILEIO_PATH_MAX];
    snprintf(path, sizeof path, "%s/%s/view.js", run, s->name);
    int fd = -1;
    rc_status st = fileio_output_target(path, target, sizeof target, err, errlen);
    if (st == RC_OK)
        st = fileio_temp_open(target, tmp, sizeof tmp, &fd, err, errlen);
    if (st != RC_OK)
        return st;
    FILE *f = fdopen(fd, "w");
    if (f == NULL) {
        snprintf(err, errlen, "%s: cannot write: %s", path, strerror(errno));
        return fileio_temp_finish(fd, tmp, target, 1, err, errlen);
    }
    fputs("window.REFLCHECK_VIEW = {\"scene\": ", f);
    compare_put_js_string(f, s->name);
    fputs(", \"images\": {", f);
    int first = 1, w = 0, h = 0;
    float *buf = NULL;
    exr_image raster = {0};
    int have_raster = 0;
    for (int r = 0; r < registry_count(); r++)
        for (int role = ROLE_TWIN; role <= ROLE_AGREE; role++) {
            char exr[1024], e[256];
            job_output_path(run, s->name, r, (comparison_role)role, "exr", exr, sizeof exr);
            exr_image img;
            if (access(exr, R_OK) != 0 || exr_read(exr, &img, e, sizeof e) != RC_OK)
                continue;
            metrics_image m = compare_planes(&img, "");
            if (m.c[0] && m.c[1] && m.c[2] && (first || (img.width == w && img.height == h))) {
                w = img.width;
                h = img.height;
                size_t np = (size_t)w * (size_t)h;
                float *nb = realloc(buf, 3 * np * sizeof(float));
                if (nb != NULL) {
                    buf = nb;
                    for (size_t i = 0; i < np; i++)
                        for (int c = 0; c < 3; c++)
                            buf[3 * i + (size_t)c] = m.c[c][i];
                    fprintf(f, "%s\"%s-%s\": \"", first ? "" : ", ", registry_name(r), job_role_names[role]);
                    compare_append_b64(f, buf, 3 * np);
                    fputc('"', f);
                    first = 0;
                }
            }
            if (r == registry_model() && !have_raster && img.width == w && img.height == h) {
                raster = img;
                have_raster = 1;
            } else
                exr_image_free(&img);
        }
    fprintf(f, "}, \"width\": %d, \"height\": %d", w, h);
    const char *extra[3] = {"coverage", "ndotv", "object"};
    for (int i = 0; i < 3 && have_raster; i++) {
        const float *ch = exr_image_channel(&raster, extra[i]);
        if (ch == NULL)
            continue;
        fprintf(f, ", \"%s\": \"", extra[i]);
        compare_append_b64(f, ch, (size_t)w * (size_t)h);
        fputc('"', f);
    }
    fputs("};\n", f);
    if (have_raster)
        exr_image_free(&raster);
    free(buf);
    /* fclose closed the descriptor: fileio_temp_finish renames the temporary, or removes it. */
    int failed = fclose(f) != 0;
    if (failed)
        snprintf(err, errlen, "%s: cannot write: %s", path, strerror(errno));
    return fileio_temp_finish(-1, tmp, target, failed, err, errlen);
}

/* Non-finite and negative values of one image over the layers a comparison reads. */
typedef struct {
    long channels, values, nonfinite, negative;
    int negative_allowed; /* radiance may be < 0: the scene's own parameters allow it */
    long negative_gated;  /* negatives that fail: radiance unless allowed, variance always */
    char first_nonfinite[128], first_negative[128];
} compare_values;

enum { COMPARE_CH_RADIANCE, COMPARE_CH_VARIANCE, COMPARE_CH_GEOMETRY };

/* 1 when every material can only reflect radiance >= 0. Colours, lights and the environment
 * are >= 0 (the scene parser and frame_env_load check), so only the D3D9Client weights can go
 * below 0: the diffuse weight 1 - |lambda| when |lambda| > 1, and 1 - R in eq. 5 and 8 when
 * R = r0 + m (1 - N.V)^p exceeds 1, which needs r0 + m > 1. The default m = 1 - r0 is
 * rounded to float, so the sum may sit a few float ulps (6e-8 each) above 1: an excess below
 * 1e-6 is that rounding, not a parameter choice, and is not taken as a promise broken. */
#define COMPARE_R_SUM_TOL 1e-6
static int compare_scene_nonnegative(const scene *s)
{
    for (int i = 0; i < s->n_materials; i++) {
        const material *m = &s->materials[i];
        if (m->model == MODEL_D3D9CLIENT && (!(d3d9client_colour_norm(m->d9.reflect, m->d9.norm) <= 1.0f) ||
                                             (double)m->d9.r0 + (double)m->d9.m > 1.0 + COMPARE_R_SUM_TOL))
            return 0;
    }
    return 1;
}

/* Our rasterizer and a twin reference compute the scene's model, so they may go below 0
 * where the model does; a physical reference (validate, agree) never reflects negative light. */
static int compare_negative_allowed(int scene_nonnegative, int renderer, comparison_role role)
{
    const renderer_row *row = registry_row(renderer);
    return !scene_nonnegative && ((row != NULL && row->is_model) || role == ROLE_TWIN);
}

static void compare_scan_channel(const exr_image *img, const char *name, int kind, compare_values *v)
{
    const float *p = exr_image_channel(img, name);
    if (p == NULL)
        return;
    metrics_value_scan sc;
    metrics_scan_values(p, (size_t)img->width * (size_t)img->height, &sc);
    v->channels++;
    v->values += sc.n_values;
    v->nonfinite += sc.n_nonfinite;
    if (sc.n_nonfinite > 0 && v->first_nonfinite[0] == '\0')
        snprintf(v->first_nonfinite, sizeof v->first_nonfinite, "%s at (x %ld, y %ld) = %g", name,
                 sc.first_nonfinite % img->width, sc.first_nonfinite / img->width, (double)sc.nonfinite_value);
    /* Geometry may be negative: object is -1 on the background, N.L < 0 faces away from a light. */
    if (kind == COMPARE_CH_GEOMETRY)
        return;
    v->negative += sc.n_negative;
    if (kind == COMPARE_CH_RADIANCE && v->negative_allowed)
        return;
    v->negative_gated += sc.n_negative;
    if (sc.n_negative > 0 && v->first_negative[0] == '\0')
        snprintf(v->first_negative, sizeof v->first_negative, "%s at (x %ld, y %ld) = %g", name,
                 sc.first_negative % img->width, sc.first_negative / img->width, (double)sc.negative_value);
}

/* Radiance (R, G, B; in a twin also the term layers), variance and geometry layers, where
 * present; geometry_only for the raster image that only lends its masks. */
static void compare_scan_image(const exr_image *img, int twin, int geometry_only, compare_values *v)
{
    static const char *const geometry[5] = {"coverage", "object", "ndotv", "ndotl", "ndoth"};
    char name[64];
    for (int c = 0; c < 3 && !geometry_only; c++) {
        snprintf(name, sizeof name, "%c", "RGB"[c]);
        compare_scan_channel(img, name, COMPARE_CH_RADIANCE, v);
        for (int a = 0; a < 3 && twin; a++) {
            snprintf(name, sizeof name, "%s.%c", compare_aovs[a], "RGB"[c]);
            compare_scan_channel(img, name, COMPARE_CH_RADIANCE, v);
        }
        snprintf(name, sizeof name, "var.%c", "RGB"[c]);
        compare_scan_channel(img, name, COMPARE_CH_VARIANCE, v);
    }
    for (int g = 0; g < 5; g++)
        compare_scan_channel(img, geometry[g], COMPARE_CH_GEOMETRY, v);
}

/* Adds a side's counts to values[side] and, when they fail the gate, a clause to gate. */
static void compare_values_report(const compare_values *v, const char *side, const char *renderer, cJSON *values,
                                  char *gate, size_t len)
{
    cJSON *o = cJSON_AddObjectToObject(values, side);
    cJSON_AddNumberToObject(o, "channels", (double)v->channels);
    cJSON_AddNumberToObject(o, "values", (double)v->values);
    cJSON_AddNumberToObject(o, "nonfinite", (double)v->nonfinite);
    cJSON_AddNumberToObject(o, "negative", (double)v->negative);
    cJSON_AddBoolToObject(o, "negative_allowed", v->negative_allowed);
    if (v->first_nonfinite[0])
        cJSON_AddStringToObject(o, "first_nonfinite", v->first_nonfinite);
    if (v->first_negative[0])
        cJSON_AddStringToObject(o, "first_negative", v->first_negative);
    if (v->nonfinite == 0 && v->negative_gated == 0)
        return;
    size_t used = strlen(gate);
    char nf[200] = "", ng[200] = "";
    if (v->nonfinite > 0)
        snprintf(nf, sizeof nf, "%ld non-finite (first %s)", v->nonfinite, v->first_nonfinite);
    if (v->negative_gated > 0)
        snprintf(ng, sizeof ng, "%ld negative (first %s)", v->negative_gated, v->first_negative);
    snprintf(gate + used, len - used, "%s%s %s: %s%s%s of %ld values; its output must be finite and >= 0",
             used ? "; " : "", side, renderer, nf, nf[0] && ng[0] ? " and " : "", ng, v->values);
}

/* A partial twin (harness/renderers/renderer.h): the terms left out by either side, why, and
 * each side's image without them (R, G, B minus the side's own layers of those terms). */
typedef struct {
    unsigned left_out;               /* RENDERER_TERM_* bits */
    char why[RENDERER_N_TERMS][240]; /* "<renderer>: <reason>" */
    float *planes[2][3];             /* [test, ref][channel], NULL = the image's own */
    char reason[1200];
} compare_partial;

/* The terms a side's record says it left out, with their reasons. */
static void compare_partial_read(const compare_side *s, compare_partial *p)
{
    const cJSON *arr = cJSON_GetObjectItemCaseSensitive(s->record, "terms_left_out");
    const cJSON *g;
    cJSON_ArrayForEach(g, arr)
    {
        unsigned bit = renderer_term_from_name(compare_json_str(g, "term"));
        for (int t = 0; t < RENDERER_N_TERMS; t++)
            if (bit == (1u << t) && !(p->left_out & bit)) {
                p->left_out |= bit;
                snprintf(p->why[t], sizeof p->why[t], "%s: %s", registry_name(s->renderer),
                         compare_json_str(g, "reason"));
            }
    }
}

static unsigned compare_side_left_out(const compare_side *s)
{
    compare_partial own = {0};
    compare_partial_read(s, &own);
    return own.left_out;
}

/* Reads both records and builds the images without the left-out terms. Returns 0, or -1 with
 * the reason when a side lacks the layer of a term it must give up. */
static int compare_partial_setup(const compare_side *t, const compare_side *r, compare_partial *p, char *reason,
                                 size_t len)
{
    compare_partial_read(t, p);
    compare_partial_read(r, p);
    if (p->left_out == 0)
        return 0;
    const compare_side *sides[2] = {t, r};
    size_t np = (size_t)t->img.width * (size_t)t->img.height;
    for (int sd = 0; sd < 2; sd++) {
        unsigned drop = p->left_out & ~compare_side_left_out(sides[sd]);
        if (drop == 0)
            continue;
        metrics_image full = compare_planes(&sides[sd]->img, "");
        for (int ch = 0; ch < 3; ch++) {
            p->planes[sd][ch] = malloc(np * sizeof(float));
            if (p->planes[sd][ch] == NULL) {
                snprintf(reason, len, "out of memory for a partial twin's image");
                return -1;
            }
            memcpy(p->planes[sd][ch], full.c[ch], np * sizeof(float));
        }
        for (int term = 0; term < RENDERER_N_TERMS; term++) {
            if (!(drop & (1u << term)))
                continue;
            metrics_image layer = compare_planes(&sides[sd]->img, renderer_term_name(term));
            if (!layer.c[0] || !layer.c[1] || !layer.c[2]) {
                snprintf(reason, len, "partial twin: %s left out %s, but %s has no %s layer to leave out too",
                         p->why[term], renderer_term_name(term), sides[sd]->path, renderer_term_name(term));
                return -1;
            }
            for (int ch = 0; ch < 3; ch++)
                for (size_t i = 0; i < np; i++)
                    p->planes[sd][ch][i] -= layer.c[ch][i];
        }
    }
    return 0;
}

static void compare_partial_apply(const compare_partial *p, metrics_image *tm, metrics_image *rm)
{
    metrics_image *m[2] = {tm, rm};
    for (int sd = 0; sd < 2; sd++)
        for (int ch = 0; ch < 3; ch++)
            if (p->planes[sd][ch] != NULL)
                m[sd]->c[ch] = p->planes[sd][ch];
}

/* terms_compared and terms_left_out, and the reason a passing partial twin states. */
static void compare_partial_json(compare_partial *p, cJSON *o)
{
    cJSON *cmp = cJSON_AddArrayToObject(o, "terms_compared");
    cJSON *left = cJSON_AddArrayToObject(o, "terms_left_out");
    char done[200] = "", gone[900] = "";
    for (int t = 0; t < RENDERER_N_TERMS; t++) {
        char *buf = (p->left_out & (1u << t)) ? gone : done;
        size_t cap = (p->left_out & (1u << t)) ? sizeof gone : sizeof done, used = strlen(buf);
        if (!(p->left_out & (1u << t))) {
            cJSON_AddItemToArray(cmp, cJSON_CreateString(renderer_term_name(t)));
            snprintf(buf + used, cap - used, "%s%s", used ? ", " : "", renderer_term_name(t));
            continue;
        }
        cJSON *g = cJSON_CreateObject();
        cJSON_AddStringToObject(g, "term", renderer_term_name(t));
        cJSON_AddStringToObject(g, "reason", p->why[t]);
        cJSON_AddItemToArray(left, g);
        snprintf(buf + used, cap - used, "%s%s (%s)", used ? "; " : "", renderer_term_name(t), p->why[t]);
    }
    if (p->left_out != 0)
        snprintf(p->reason, sizeof p->reason, "partial twin: compared %s; left out %s", done, gone);
}

static void compare_partial_free(compare_partial *p)
{
    for (int sd = 0; sd < 2; sd++)
        for (int ch = 0; ch < 3; ch++)
            free(p->planes[sd][ch]);
}

/* The crease region's size beside the surface figures it was taken from, so whoever reads a
 * Cycles figure reads how much was set apart with it. */
static void compare_crease_beside(const cJSON *cmp, cJSON *regions)
{
    const cJSON *cr = cJSON_GetObjectItemCaseSensitive(cmp, "crease");
    cJSON *surf = cJSON_GetObjectItemCaseSensitive(regions, "surface");
    const cJSON *px = cJSON_GetObjectItemCaseSensitive(cr, "pixels");
    const cJSON *share = cJSON_GetObjectItemCaseSensitive(cr, "share_of_surface");
    if (surf == NULL || !cJSON_IsNumber(px) || !cJSON_IsNumber(share))
        return;
    cJSON_AddNumberToObject(surf, "crease_pixels", px->valuedouble);
    cJSON_AddNumberToObject(surf, "crease_share", share->valuedouble);
    /* And in the crease region, for a threshold "crease.share_of_surface". */
    cJSON *creg = cJSON_GetObjectItemCaseSensitive(regions, "crease");
    if (creg == NULL)
        creg = cJSON_AddObjectToObject(regions, "crease");
    cJSON_AddNumberToObject(creg, "share_of_surface", share->valuedouble);
}

/* The crease region's own z-test (the surface's, on the crease mask), so a threshold can gate
 * "crease.z_fail_share" like any region's; nothing where the reference has no variance layers. */
static void compare_crease_noise(const exr_image *ref, const metrics_image *refm, const exr_image *test,
                                 const metrics_image *testm, const unsigned char *mask, cJSON *region)
{
    cJSON *noise = compare_noise(ref, refm, test, testm, mask);
    if (noise == NULL)
        return;
    const cJSON *share =
        cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(noise, "ztest"), "share_fail_pixels");
    if (cJSON_IsNumber(share))
        cJSON_AddNumberToObject(region, "z_fail_share", share->valuedouble);
    cJSON_AddItemToObject(region, "noise", noise);
}

/* Against a renderer with crease rules (registry.h), the interior pixels where the model's crease
 * layer has one of that renderer's rule bits (harness/crease.h) leave the surface for the crease
 * region, and the comparison says how many, per rule, and why; an image without the layer (an
 * older run) changes nothing and says so. A crease region above COMPARE_CREASE_MAX_SHARE of the
 * surface fails the comparison (gate gets the clause) unless the scene states its own limit as
 * the threshold "crease.share_of_surface": the surface figures would then judge too little of
 * the object to stand for it. */
static void compare_crease(const comparison *c, const exr_image *geo, unsigned char *cls, size_t np, cJSON *o,
                           char *gate, size_t gatelen)
{
    const renderer_row *t = registry_row(c->test), *r = registry_row(c->reference);
    const renderer_row *rules = r != NULL && r->crease_rules ? r : (t != NULL && t->crease_rules ? t : NULL);
    if (rules == NULL)
        return;
    cJSON *j = cJSON_AddObjectToObject(o, "crease");
    const float *layer = geo != NULL ? exr_image_channel(geo, "crease") : NULL;
    if (layer == NULL) {
        cJSON_AddStringToObject(j, "note",
                                "the model image has no crease layer (rendered before it existed): "
                                "no pixel left out; re-render the model to get it");
        return;
    }
    long interior = 0, per_rule[CREASE_RULE_COUNT];
    long moved = crease_classify_rules(cls, layer, np, (unsigned)rules->crease_rules, &interior, per_rule);
    char why[300];
    snprintf(why, sizeof why,
             "%s shades creases by its own rules (harness/crease.h): pixels with a sample where one departs are the "
             "crease region, not the surface",
             rules->title);
    cJSON_AddStringToObject(j, "rule", why);
    cJSON_AddNumberToObject(j, "pixels", (double)moved);
    double share = interior > 0 ? (double)moved / (double)interior : 0.0;
    cJSON_AddNumberToObject(j, "share_of_surface", share);
    cJSON_AddNumberToObject(j, "max_share", COMPARE_CREASE_MAX_SHARE);
    cJSON *pr = cJSON_AddObjectToObject(j, "per_rule");
    for (int b = 0; b < CREASE_RULE_COUNT; b++)
        if ((unsigned)rules->crease_rules & (1u << b))
            cJSON_AddNumberToObject(pr, crease_rule_names[b], (double)per_rule[b]);
    /* A scene that states its own limit ("crease.share_of_surface", with its reason) is judged
     * by it among the thresholds instead. */
    int stated = 0;
    for (int i = 0; i < c->n_thresholds; i++)
        stated |= strcmp(c->thresholds[i].metric, "crease.share_of_surface") == 0;
    if (!stated && share > COMPARE_CREASE_MAX_SHARE) {
        size_t used = strlen(gate);
        snprintf(gate + used, gatelen - used,
                 "%screase region %ld of %ld surface pixels (%.3g) exceeds %.3g: %s's crease rules set apart too "
                 "much of the object; use a finer tessellation or vertex normals closer to the faces",
                 used ? "; " : "", moved, interior, share, COMPARE_CREASE_MAX_SHARE, rules->name);
    }
}

/* A twin samples the model's own positions (POV-Ray at k times the size; Cycles at k times the
 * size with a 0.01 sub-pixel filter), so at an open edge (a silhouette, crack, fold or split hard
 * edge) a sample closer to it than the float inputs resolve can land on either side: the interior
 * pixels with such a sample (the crease layer's CREASE_TIE, harness/crease.h) join the edges.
 * Measured: real_spider small, one sample 5e-6 samples from a crack between unwelded parts, seen
 * through by the rasterizer, not by POV-Ray (rel_rms 5.8e-3). Reported as the region "ties" (its
 * pixels, share_of_surface, band); above COMPARE_TIE_MAX_SHARE of the surface the comparison fails
 * unless the scene states "ties.share_of_surface": a band that wide would hide real differences. */
#define COMPARE_TIE_MAX_SHARE 0.005
static void compare_ties(const comparison *c, const scene *s, const exr_image *geo, unsigned char *cls, size_t np,
                         cJSON *regions, char *gate, size_t gatelen)
{
    const float *layer = geo != NULL ? exr_image_channel(geo, "crease") : NULL;
    if (c->role != ROLE_TWIN || layer == NULL || geo->width <= 0)
        return;
    long interior = 0, moved = crease_classify_ties(cls, layer, np, &interior);
    const char *k = exr_image_attr(geo, "reflcheck.supersample");
    double share = interior > 0 ? (double)moved / (double)interior : 0.0;
    cJSON *m = cJSON_AddObjectToObject(regions, "ties");
    cJSON_AddNumberToObject(m, "pixels", (double)moved);
    cJSON_AddNumberToObject(m, "share_of_surface", share);
    cJSON_AddNumberToObject(m, "max_share", COMPARE_TIE_MAX_SHARE);
    if (k != NULL)
        cJSON_AddNumberToObject(m, "band_samples", crease_tie_band(s, geo->width, atoi(k)));
    cJSON_AddStringToObject(m, "rule",
                            "pixels with a sample nearer an open edge than the float inputs resolve (harness/crease.h "
                            "CREASE_TIE): which side it falls on is rounding; set apart with the edges");
    int stated = 0;
    for (int i = 0; i < c->n_thresholds; i++)
        stated |= strcmp(c->thresholds[i].metric, "ties.share_of_surface") == 0;
    if (!stated && share > COMPARE_TIE_MAX_SHARE) {
        size_t used = strlen(gate);
        snprintf(gate + used, gatelen - used,
                 "%stie region %ld of %ld surface pixels (%.3g) exceeds %.3g: state ties.share_of_surface with its "
                 "reason, or weld the mesh's cracks",
                 used ? "; " : "", moved, interior, share, COMPARE_TIE_MAX_SHARE);
    }
}

/* A twin against a path tracer (a stochastic reference) computes our model, so its mean over
 * the surface may depart only by its noise: without the worst 1 % of pixels (a reflected sun's
 * sub-pixel disc, which k x k point samples and a pixel integral weigh differently), no term's
 * mean is further than COMPARE_TWIN_BIAS_Z standard errors from the reference's (two-sided
 * p = 5.7e-7 per channel: under 1e-5 over the 12 channels of 4 terms) by more than
 * COMPARE_TWIN_BIAS_REL of its level. The second bound is the twins' precision floor (their
 * rel_rms gates fail at 1e-3, over POV-Ray's half-float step of 4.9e-4): at full size a Cycles
 * twin's standard error is small enough that offsets of 2e-4 to 4e-4 read as z = 12 to 15
 * (ct_cube, ct_env, d3d9_glass), differences no twin figure resolves. The gate gets the clause
 * unless the scene states its own "bias.z_trim1_max" threshold, with its reason. */
#define COMPARE_TWIN_BIAS_Z   5.0
#define COMPARE_TWIN_BIAS_REL 1e-3

static void compare_bias_gate(const comparison *c, cJSON *o, char *gate, size_t gatelen)
{
    const renderer_row *r = registry_row(c->reference);
    cJSON *b = cJSON_GetObjectItemCaseSensitive(o, "bias");
    if (c->role != ROLE_TWIN || r == NULL || !r->stochastic || b == NULL)
        return;
    /* A twin with no accuracy gate (the stiff scenes judge finiteness only) stays not_gated:
     * its bias is reported beside its other figures, not judged. */
    int accuracy = 0;
    for (int i = 0; i < c->n_thresholds; i++)
        accuracy += compare_is_accuracy(c->thresholds[i].metric);
    if (accuracy == 0)
        return;
    cJSON_AddNumberToObject(b, "max_z", COMPARE_TWIN_BIAS_Z);
    for (int i = 0; i < c->n_thresholds; i++)
        if (strcmp(c->thresholds[i].metric, "bias.z_trim1_max") == 0)
            return;
    double z = cJSON_GetNumberValue(cJSON_GetObjectItemCaseSensitive(b, "z_trim1_max"));
    double rel = cJSON_GetNumberValue(cJSON_GetObjectItemCaseSensitive(b, "rel_trim1"));
    cJSON_AddNumberToObject(b, "max_rel", COMPARE_TWIN_BIAS_REL);
    if (z > COMPARE_TWIN_BIAS_Z && fabs(rel) > COMPARE_TWIN_BIAS_REL) {
        size_t used = strlen(gate);
        snprintf(gate + used, gatelen - used,
                 "%sbias: the %s term's mean is %.3g standard errors (%+.3g relative) from %s's, over %.3g and "
                 "%.3g: an offset over the whole surface that no per-pixel test sees; find it, or state "
                 "bias.z_trim1_max with its reason",
                 used ? "; " : "", cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(b, "term_trim1")), z, rel,
                 r->name, COMPARE_TWIN_BIAS_Z, COMPARE_TWIN_BIAS_REL);
    }
}

/* A twin renders the same triangles from the same camera, so its silhouettes agree with ours
 * to the sample pattern: a pixel whose covered share moves by half a pixel or more is a
 * silhouette moved, and a twin with more than 1 % of such pixels does not see the same image
 * (a camera the reference cannot represent, a mesh it read otherwise), whatever its surface
 * figures say. Judged unless the scene states its own coverage_agreement threshold. */
#define COMPARE_TWIN_COVERAGE 0.99

static void compare_coverage_gate(const comparison *c, double agreement, char *gate, size_t gatelen)
{
    if (c->role != ROLE_TWIN)
        return;
    for (int i = 0; i < c->n_thresholds; i++)
        if (strcmp(c->thresholds[i].metric, "coverage_agreement") == 0)
            return;
    if (agreement < COMPARE_TWIN_COVERAGE) {
        size_t used = strlen(gate);
        snprintf(gate + used, gatelen - used,
                 "%scoverage: %.3g of the pixels agree with the reference's coverage, under %.3g: the two images "
                 "do not show the same silhouettes; check the camera and the mesh",
                 used ? "; " : "", agreement, COMPARE_TWIN_COVERAGE);
    }
}

/* A validate figure stands beside the agrees that measure its reference by a second reference
 * ("agrees": their ids), or says plainly that it has none ("agree_none"): the physics then rests
 * on that reference's translator alone, declared, not measured. */
static void compare_agrees_put(const scene *s, const comparison *c, cJSON *o)
{
    cJSON *ids = cJSON_AddArrayToObject(o, "agrees");
    for (int i = 0; i < s->n_comparisons; i++) {
        const comparison *a = &s->comparisons[i];
        if (a->role != ROLE_AGREE || (a->test != c->reference && a->reference != c->reference))
            continue;
        char id[128];
        snprintf(id, sizeof id, "%s-vs-%s-%s", registry_name(a->test), registry_name(a->reference),
                 job_role_names[a->role]);
        cJSON_AddItemToArray(ids, cJSON_CreateString(id));
    }
    if (cJSON_GetArraySize(ids) == 0) {
        char text[200];
        snprintf(text, sizeof text,
                 "%s alone renders this physics here: no agree measures it against a second reference",
                 registry_name(c->reference));
        cJSON_AddStringToObject(o, "agree_none", text);
    }
}

/* The kind of each material the scene's objects use ("material_kinds": {name: kind}): its model,
 * dielectric or conductor, or "without specular" (material.lobe 0). Figures of one kind under
 * two physics are not comparable; the report names the difference beside both. */
static void compare_kinds_put(const scene *s, cJSON *o)
{
    static const char *const models[] = {"d3d", "d3d9client", "cook_torrance", "user"};
    cJSON *kinds = cJSON_AddObjectToObject(o, "material_kinds");
    for (int i = 0; i < s->n_objects; i++) {
        const material *m = &s->materials[s->objects[i].material];
        char kind[64];
        snprintf(kind, sizeof kind, "%s %s", (unsigned)m->model < 4 ? models[m->model] : "?",
                 !m->lobe ? "without specular" : (m->conductor ? "conductor" : "dielectric"));
        if (cJSON_GetObjectItemCaseSensitive(kinds, m->name) == NULL)
            cJSON_AddStringToObject(kinds, m->name, kind);
    }
}

/* One comparison's working state, shared by the stages of compare_one below: both sides as
 * loaded, the raster geometry that classifies pixels, and the words of a gate or an error. */
typedef struct {
    const scene *s;
    const comparison *c;
    comparison_role rr; /* agree compares the two validate renders themselves, never a third setup */
    char id[128];
    char reason[1200];
    compare_side t, r, mask_src;
    compare_partial part;
    const exr_image *geo;
    metrics_image tm, rm;
    size_t np;
    unsigned char *cls, *mask[4];
    char gate[900];
    char crease_gate[1000];
} compare_work;

/* Stage 1: the comparison's names. */
static cJSON *compare_header(compare_work *wk)
{
    const comparison *c = wk->c;
    wk->rr = c->role == ROLE_AGREE ? ROLE_VALIDATE : c->role;
    snprintf(wk->id, sizeof wk->id, "%s-vs-%s-%s", registry_name(c->test), registry_name(c->reference),
             job_role_names[c->role]);
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "id", wk->id);
    cJSON_AddStringToObject(o, "test", registry_name(c->test));
    cJSON_AddStringToObject(o, "reference", registry_name(c->reference));
    cJSON_AddStringToObject(o, "role", job_role_names[c->role]);
    return o;
}

/* Stage 2: load both sides; NULL when they can be compared, else "error" or "skipped" with
 * the reason in wk->reason. */
static const char *compare_load_both(compare_work *wk, const char *run)
{
    const scene *s = wk->s;
    char why_t[600] = "", why_r[600] = "";
    compare_side_state ts = compare_load_side(run, s->name, &wk->t, why_t, sizeof why_t);
    compare_side_state rs = compare_load_side(run, s->name, &wk->r, why_r, sizeof why_r);
    if (ts == COMPARE_SIDE_ERROR || rs == COMPARE_SIDE_ERROR) {
        snprintf(wk->reason, sizeof wk->reason, "%s%s%s", ts == COMPARE_SIDE_ERROR ? why_t : "",
                 ts == COMPARE_SIDE_ERROR && rs == COMPARE_SIDE_ERROR ? "; " : "",
                 rs == COMPARE_SIDE_ERROR ? why_r : "");
        return "error";
    }
    if (ts == COMPARE_SIDE_SKIPPED || rs == COMPARE_SIDE_SKIPPED) {
        snprintf(wk->reason, sizeof wk->reason, "%s%s%s", why_t, why_t[0] && why_r[0] ? "; " : "", why_r);
        return "skipped";
    }
    if (wk->t.img.width != wk->r.img.width || wk->t.img.height != wk->r.img.height) {
        snprintf(wk->reason, sizeof wk->reason, "image sizes differ: %s is %dx%d, %s is %dx%d", wk->t.path,
                 wk->t.img.width, wk->t.img.height, wk->r.path, wk->r.img.width, wk->r.img.height);
        return "error";
    }
    return NULL;
}

/* Stage 3: a validate's references must render the scene's one physics: a record that says
 * otherwise (a translator drifted, or an old run) is an error, never a figure. */
static const char *compare_physics_check(compare_work *wk, const char *state, cJSON *o)
{
    const scene *s = wk->s;
    char want_physics[400];
    physics_describe(&s->physics, frame_light_count(s), want_physics, sizeof want_physics);
    if (wk->rr == ROLE_VALIDATE)
        cJSON_AddStringToObject(o, "physics", want_physics);
    if (wk->c->role == ROLE_VALIDATE) {
        compare_agrees_put(s, wk->c, o);
        compare_kinds_put(s, o);
    }
    const compare_side *both[2] = {&wk->t, &wk->r};
    for (int sd = 0; sd < 2 && state == NULL && wk->rr == ROLE_VALIDATE; sd++) {
        const renderer_row *row = registry_row(both[sd]->renderer);
        if (row == NULL || row->physics == NULL)
            continue;
        const char *got = compare_json_str(both[sd]->record, "physics");
        if (strcmp(got, want_physics) != 0) {
            state = "error";
            snprintf(wk->reason, sizeof wk->reason,
                     "%s validate rendered physics '%s', the scene's is '%s'; every validate reference must "
                     "render the scene's physics: re-render it",
                     row->name, got[0] ? got : "(not recorded)", want_physics);
        }
    }
    return state;
}

/* Stage 4: a partial twin (the terms either side left out are removed from the other, its own
 * layers, so both images hold the same sum of terms) and the raster geometry that classifies
 * pixels: the raster side itself, else the raster's render of the same size. */
static const char *compare_setup(compare_work *wk, const char *run, const char *state)
{
    const comparison *c = wk->c;
    if (state == NULL && compare_partial_setup(&wk->t, &wk->r, &wk->part, wk->reason, sizeof wk->reason) != 0)
        state = "error";
    if (state == NULL) {
        char tmp[600];
        wk->geo = c->test == registry_model() ? &wk->t.img : (c->reference == registry_model() ? &wk->r.img : NULL);
        if (wk->geo == NULL && compare_load_side(run, wk->s->name, &wk->mask_src, tmp, sizeof tmp) == COMPARE_SIDE_OK &&
            wk->mask_src.img.width == wk->t.img.width && wk->mask_src.img.height == wk->t.img.height)
            wk->geo = &wk->mask_src.img;
    }
    return state;
}

/* A comparison that could not be made: its state and reason, counted in the summary. */
static void compare_put_unmade(compare_work *wk, const char *state, cJSON *o, compare_summary *sum)
{
    /* The renderer's words name the key of the scene it could not take (materials[i].model,
     * lights[i].range, ...); the comparison's own key is what to change when the renderer
     * is missing, or to leave the comparison out. */
    size_t used = strlen(wk->reason);
    snprintf(wk->reason + used, sizeof wk->reason - used, "; scene key comparisons[%d]",
             (int)(wk->c - wk->s->comparisons));
    cJSON_AddStringToObject(o, "status", state);
    cJSON_AddStringToObject(o, "reason", wk->reason);
    if (state[0] == 's') {
        sum->skipped++;
    } else {
        sum->error++;
        if (sum->first_failure[0] == '\0')
            snprintf(sum->first_failure, sizeof sum->first_failure, "%s: %s: error: %s", wk->s->name, wk->id,
                     wk->reason);
    }
}

/* Stage 5: the largest finite value of each side (a half-float EXR overflows to Inf above 65504). */
static void compare_max_put(const compare_work *wk, cJSON *o)
{
    const metrics_image *sides[2] = {&wk->tm, &wk->rm};
    const char *side_names[2] = {"test", "ref"};
    for (int sd = 0; sd < 2; sd++) {
        double vmax = 0.0;
        for (size_t i = 0; i < wk->np; i++)
            for (int ch = 0; ch < 3; ch++) {
                double v = sides[sd]->c[ch][i];
                if (isfinite(v) && v > vmax)
                    vmax = v;
            }
        char key[32];
        snprintf(key, sizeof key, "%s_max", side_names[sd]);
        cJSON_AddNumberToObject(o, key, vmax);
    }
}

/* Stage 6: the value gate: every layer either image holds that the comparison may read, all
 * pixels, whatever the thresholds say. */
static void compare_values_put(compare_work *wk, cJSON *o)
{
    const comparison *c = wk->c;
    int promise = compare_scene_nonnegative(wk->s);
    compare_values vt = {.negative_allowed = compare_negative_allowed(promise, c->test, c->role)};
    compare_values vr = {.negative_allowed = compare_negative_allowed(promise, c->reference, c->role)};
    compare_values vm = {0};
    compare_scan_image(&wk->t.img, c->role == ROLE_TWIN, 0, &vt);
    compare_scan_image(&wk->r.img, c->role == ROLE_TWIN, 0, &vr);
    if (wk->geo == &wk->mask_src.img)
        compare_scan_image(&wk->mask_src.img, 0, 1, &vm);
    cJSON *values = cJSON_AddObjectToObject(o, "values");
    compare_values_report(&vt, "test", registry_name(c->test), values, wk->gate, sizeof wk->gate);
    compare_values_report(&vr, "ref", registry_name(c->reference), values, wk->gate, sizeof wk->gate);
    if (wk->geo == &wk->mask_src.img)
        compare_values_report(&vm, "mask", "raster geometry", values, wk->gate, sizeof wk->gate);
    cJSON_AddNumberToObject(o, "test_nonfinite", (double)vt.nonfinite);
    cJSON_AddNumberToObject(o, "ref_nonfinite", (double)vr.nonfinite);
    cJSON_AddNumberToObject(o, "test_negative", (double)vt.negative);
    cJSON_AddNumberToObject(o, "ref_negative", (double)vr.negative);
}

/* Stage 7a: the pixel classes, the crease and tie clauses, and the figures per region. */
static void compare_regions_put(compare_work *wk, cJSON *o, cJSON *regions)
{
    const char *region_names[4] = {"surface", "edges", "background", "crease"};
    const int region_class[4] = {METRICS_PX_INTERIOR, METRICS_PX_EDGE, METRICS_PX_BACKGROUND, METRICS_PX_CREASE};
    int w = wk->t.img.width, h = wk->t.img.height;
    const exr_image *geo = wk->geo;
    const float *cov = geo ? exr_image_channel(geo, "coverage") : NULL;
    const float *obj = geo ? exr_image_channel(geo, "object") : NULL;
    metrics_classify(w, h, cov, obj, wk->cls);
    compare_crease(wk->c, geo, wk->cls, wk->np, o, wk->crease_gate, sizeof wk->crease_gate);
    compare_ties(wk->c, wk->s, geo, wk->cls, wk->np, regions, wk->crease_gate, sizeof wk->crease_gate);
    for (int i = 0; i < 4; i++) {
        metrics_mask_from_class(w, h, wk->cls, region_class[i], NULL, 0.0f, wk->mask[i]);
        cJSON *m = compare_region(&wk->rm, &wk->tm, wk->mask[i]);
        if (m != NULL && region_class[i] == METRICS_PX_CREASE)
            compare_crease_noise(&wk->r.img, &wk->rm, &wk->t.img, &wk->tm, wk->mask[i], m);
        if (m != NULL)
            cJSON_AddItemToObject(regions, region_names[i], m);
    }
    compare_crease_beside(o, regions);
}

/* Stage 7b: per object (and so per material): surface pixels whose centre sample is that object. */
static void compare_objects_put(const compare_work *wk, cJSON *o)
{
    const scene *s = wk->s;
    const float *obj_layer = wk->geo ? exr_image_channel(wk->geo, "object") : NULL;
    if (obj_layer == NULL || s->n_objects <= 1)
        return;
    int w = wk->t.img.width, h = wk->t.img.height;
    cJSON *objs = cJSON_AddArrayToObject(o, "objects");
    unsigned char *om = malloc(wk->np);
    for (int ob = 0; om != NULL && ob < s->n_objects; ob++) {
        if (metrics_mask_from_class(w, h, wk->cls, METRICS_PX_INTERIOR, obj_layer, (float)ob, om) == 0)
            continue;
        cJSON *m = compare_region(&wk->rm, &wk->tm, om);
        if (m == NULL)
            continue;
        cJSON_AddNumberToObject(m, "object", ob);
        cJSON_AddStringToObject(m, "material", s->materials[s->objects[ob].material].name);
        cJSON_AddItemToArray(objs, m);
    }
    free(om);
}

/* Stage 7c: the layers, terms, bias, coverage, noise and angle bins over the surface mask. */
static void compare_layers_put(compare_work *wk, cJSON *o)
{
    const comparison *c = wk->c;
    const unsigned char *surface = wk->mask[0];
    /* Layers line up only in twins: a physical reference splits its light differently
     * (Cycles files an environment mirror under glossy, our model under reflection). */
    cJSON *aovs = cJSON_AddObjectToObject(o, "aovs");
    for (int a = 0; a < 3 && c->role == ROLE_TWIN; a++) {
        if (wk->part.left_out & renderer_term_from_name(compare_aovs[a]))
            continue;
        metrics_image ta = compare_planes(&wk->t.img, compare_aovs[a]),
                      ra = compare_planes(&wk->r.img, compare_aovs[a]);
        if (!ta.c[0] || !ta.c[1] || !ta.c[2] || !ra.c[0] || !ra.c[1] || !ra.c[2])
            continue;
        cJSON *m = compare_region(&ra, &ta, surface);
        if (m != NULL)
            cJSON_AddItemToObject(aovs, compare_aovs[a], m);
    }
    cJSON *terms = compare_terms(&wk->t.img, &wk->r.img, &wk->rm, wk->part.left_out, c->role == ROLE_TWIN, surface);
    cJSON_AddItemToObject(o, "terms", terms);
    compare_bias_summary(&wk->tm, &wk->rm, &wk->t.img, &wk->r.img, terms, surface, o);
    compare_bias_gate(c, o, wk->crease_gate, sizeof wk->crease_gate);
    const float *rc = exr_image_channel(&wk->r.img, "coverage"), *tc = exr_image_channel(&wk->t.img, "coverage");
    if (rc != NULL && tc != NULL) {
        long agree = 0;
        /* A pixel disagrees when the covered shares differ by half a pixel or more: a
         * silhouette moved by half a pixel. Smaller differences are the sample pattern
         * (k x k ordered samples against Cycles' jittered ones). */
        for (size_t i = 0; i < wk->np; i++)
            agree += fabsf(rc[i] - tc[i]) < 0.5f;
        cJSON_AddNumberToObject(o, "coverage_agreement", (double)agree / (double)wk->np);
        compare_coverage_gate(c, (double)agree / (double)wk->np, wk->crease_gate, sizeof wk->crease_gate);
    }
    cJSON *noise = compare_noise(&wk->r.img, &wk->rm, &wk->t.img, &wk->tm, surface);
    if (noise != NULL)
        cJSON_AddItemToObject(o, "noise", noise);
    compare_angle_bins_put(wk->s, c, wk->geo, &wk->t.img, &wk->r.img, &wk->tm, &wk->rm, wk->part.left_out, surface, o);
}

/* Stage 8: both sides' render times, then the verdict under the gates and thresholds. */
static void compare_verdict_put(compare_work *wk, cJSON *o, compare_summary *sum)
{
    const scene *s = wk->s;
    cJSON *times = cJSON_AddObjectToObject(o, "times");
    const cJSON *tw = cJSON_GetObjectItemCaseSensitive(wk->t.record, "wall_s");
    const cJSON *rw = cJSON_GetObjectItemCaseSensitive(wk->r.record, "wall_s");
    cJSON_AddNumberToObject(times, "test_wall_s", cJSON_IsNumber(tw) ? tw->valuedouble : 0.0);
    cJSON_AddNumberToObject(times, "reference_wall_s", cJSON_IsNumber(rw) ? rw->valuedouble : 0.0);

    const char *gate = wk->gate, *crease_gate = wk->crease_gate;
    if (gate[0] != '\0' && sum->first_failure[0] == '\0')
        snprintf(sum->first_failure, sizeof sum->first_failure, "%s: %s: values: %s", s->name, wk->id, gate);
    if (crease_gate[0] != '\0' && sum->first_failure[0] == '\0')
        snprintf(sum->first_failure, sizeof sum->first_failure, "%s: %s: %s", s->name, wk->id, crease_gate);
    const char *verdict = compare_judge(s, wk->c, compare_full_size(&wk->t, &wk->r), o, wk->id, sum);
    if (gate[0] != '\0' || crease_gate[0] != '\0') {
        verdict = "fail";
        /* A gate's words say what to look at, or which metric to state with its reason; the key
         * that holds such a statement is the comparison's thresholds. */
        snprintf(wk->reason, sizeof wk->reason, "%s%s%s%s; scene key comparisons[%d].thresholds",
                 gate[0] ? "values: " : "", gate, gate[0] && crease_gate[0] ? "; " : "", crease_gate,
                 (int)(wk->c - s->comparisons));
        cJSON_AddStringToObject(o, "reason", wk->reason);
    }
    if (wk->part.left_out != 0 && gate[0] == '\0' && crease_gate[0] == '\0')
        cJSON_AddStringToObject(o, "reason", wk->part.reason);
    cJSON_AddStringToObject(o, "status", verdict);
    if (strcmp(verdict, "fail") == 0)
        sum->fail++;
    else if (strcmp(verdict, "warn") == 0)
        sum->warn++;
    else if (strcmp(verdict, "not_gated") == 0)
        sum->not_gated++;
    else
        sum->pass++;
}

static void compare_work_free(compare_work *wk)
{
    free(wk->cls);
    for (int i = 0; i < 4; i++)
        free(wk->mask[i]);
    compare_side_free(&wk->t);
    compare_side_free(&wk->r);
    compare_side_free(&wk->mask_src);
    compare_partial_free(&wk->part);
}

/* One comparison, stage by stage: names, both sides loaded and checked, then the figures and
 * gates, then the verdict. */
static cJSON *compare_one(const scene *s, const comparison *c, const char *run, compare_summary *sum)
{
    compare_work wk = {.s = s, .c = c};
    cJSON *o = compare_header(&wk);
    wk.t = (compare_side){.renderer = c->test, .role = wk.rr};
    wk.r = (compare_side){.renderer = c->reference, .role = wk.rr};
    wk.mask_src = (compare_side){.renderer = registry_model(), .role = wk.rr};
    const char *state = compare_load_both(&wk, run);
    state = compare_physics_check(&wk, state, o);
    state = compare_setup(&wk, run, state);
    if (state != NULL) {
        compare_put_unmade(&wk, state, o, sum);
        compare_work_free(&wk);
        return o;
    }
    wk.np = (size_t)wk.t.img.width * (size_t)wk.t.img.height;
    wk.cls = malloc(wk.np);
    for (int i = 0; i < 4; i++)
        wk.mask[i] = malloc(wk.np);
    wk.tm = compare_planes(&wk.t.img, "");
    wk.rm = compare_planes(&wk.r.img, "");
    compare_partial_apply(&wk.part, &wk.tm, &wk.rm);
    compare_partial_json(&wk.part, o);
    compare_max_put(&wk, o);
    compare_values_put(&wk, o);
    /* The built-in gates' clauses: the crease region's share, a twin's bias and coverage. */
    cJSON *regions = cJSON_AddObjectToObject(o, "regions");
    if (wk.cls && wk.mask[0] && wk.mask[1] && wk.mask[2] && wk.mask[3]) {
        compare_regions_put(&wk, o, regions);
        compare_objects_put(&wk, o);
        compare_layers_put(&wk, o);
    }
    compare_verdict_put(&wk, o, sum);
    compare_work_free(&wk);
    return o;
}

rc_status compare_scene(const char *scene_path, const char *run_dir, compare_summary *sum, char *err, size_t errlen)
{
    memset(sum, 0, sizeof *sum);
    scene *s = malloc(sizeof *s);
    if (s == NULL)
        return RC_ERR_NOMEM;
    rc_status st = scene_file_load(scene_path, s, err, errlen);
    if (st != RC_OK) {
        free(s);
        return st;
    }
    cJSON *root = cJSON_CreateObject();
    cJSON_AddStringToObject(root, "scene", s->name);
    cJSON_AddStringToObject(root, "scene_path", scene_path);
    cJSON *arr = cJSON_AddArrayToObject(root, "comparisons");
    for (int i = 0; i < s->n_comparisons; i++)
        cJSON_AddItemToArray(arr, compare_one(s, &s->comparisons[i], run_dir, sum));
    char path[1024];
    snprintf(path, sizeof path, "%s/%s/compare.json", run_dir, s->name);
    st = jsonio_write_file(root, path, err, errlen);
    cJSON_Delete(root);
    if (st == RC_OK)
        st = compare_write_view(s, run_dir, err, errlen);
    free(s);
    return st;
}

rc_status compare_images(const char *test_exr, const char *ref_exr, const char *mask_exr, FILE *out, int *failed,
                         char *err, size_t errlen)
{
    *failed = 0;
    exr_image t, r, g;
    int have_g = 0;
    rc_status st = exr_read(test_exr, &t, err, errlen);
    if (st != RC_OK)
        return st;
    if ((st = exr_read(ref_exr, &r, err, errlen)) != RC_OK) {
        exr_image_free(&t);
        return st;
    }
    if (mask_exr != NULL) {
        if ((st = exr_read(mask_exr, &g, err, errlen)) != RC_OK) {
            exr_image_free(&t);
            exr_image_free(&r);
            return st;
        }
        have_g = 1;
    }
    const exr_image *geo = have_g ? &g : &t;
    metrics_image tm = compare_planes(&t, ""), rm = compare_planes(&r, "");
    if (t.width != r.width || t.height != r.height || geo->width != t.width || geo->height != t.height || !tm.c[0] ||
        !tm.c[1] || !tm.c[2] || !rm.c[0] || !rm.c[1] || !rm.c[2]) {
        snprintf(err, errlen, "%s, %s: images must have the same size and R, G, B channels", test_exr, ref_exr);
        st = RC_ERR_RANGE;
    } else {
        size_t np = (size_t)t.width * (size_t)t.height;
        unsigned char *cls = malloc(np), *mask = malloc(np);
        cJSON *o = cJSON_CreateObject();
        if (cls != NULL && mask != NULL) {
            metrics_classify(t.width, t.height, exr_image_channel(geo, "coverage"), exr_image_channel(geo, "object"),
                             cls);
            metrics_mask_from_class(t.width, t.height, cls, METRICS_PX_INTERIOR, NULL, 0.0f, mask);
            cJSON *m = compare_region(&rm, &tm, mask);
            cJSON_AddItemToObject(o, "surface", m ? m : cJSON_CreateNull());
            metrics_mask_from_class(t.width, t.height, cls, -1, NULL, 0.0f, mask);
            m = compare_region(&rm, &tm, mask);
            cJSON_AddItemToObject(o, "all", m ? m : cJSON_CreateNull());
            metrics_mask_from_class(t.width, t.height, cls, METRICS_PX_INTERIOR, NULL, 0.0f, mask);
            cJSON *noise = compare_noise(&r, &rm, &t, &tm, mask);
            if (noise != NULL)
                cJSON_AddItemToObject(o, "noise", noise);
            /* The same value gate as compare_scene's, for images of a model that promises
             * radiance >= 0 (every model with physical parameters). */
            compare_values vt = {0}, vr = {0}, vg = {0};
            compare_scan_image(&t, 0, 0, &vt);
            compare_scan_image(&r, 0, 0, &vr);
            char gate[900] = "";
            cJSON *values = cJSON_AddObjectToObject(o, "values");
            compare_values_report(&vt, "test", test_exr, values, gate, sizeof gate);
            compare_values_report(&vr, "ref", ref_exr, values, gate, sizeof gate);
            if (have_g) {
                compare_scan_image(&g, 0, 1, &vg);
                compare_values_report(&vg, "mask", mask_exr, values, gate, sizeof gate);
            }
            cJSON_AddStringToObject(o, "status", gate[0] ? "fail" : "pass");
            if (gate[0]) {
                *failed = 1;
                snprintf(err, errlen, "values: %s", gate);
            }
            /* A failed write shows in the stream's error flag, which cli_diff checks. */
            (void)jsonio_print(out, o);
        } else
            st = RC_ERR_NOMEM;
        cJSON_Delete(o);
        free(cls);
        free(mask);
    }
    exr_image_free(&t);
    exr_image_free(&r);
    if (have_g)
        exr_image_free(&g);
    return st;
}

int compare_value_gate(const scene *s, const exr_image *img, int renderer, comparison_role role, const char *side,
                       char *gate, size_t len)
{
    compare_values v = {.negative_allowed = compare_negative_allowed(compare_scene_nonnegative(s), renderer, role)};
    compare_scan_image(img, role == ROLE_TWIN, 0, &v);
    /* compare_values_report writes its counts into a JSON object; here only the clause is wanted */
    cJSON *counts = cJSON_CreateObject();
    gate[0] = '\0';
    compare_values_report(&v, side, registry_name(renderer), counts, gate, len);
    cJSON_Delete(counts);
    return gate[0] != '\0';
}
