#include "fit.h"
#include "user_model.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <nlopt.h>

#include "compare.h"
#include "crease.h"
#include "render.h"

typedef struct {
    double lo, hi;
    int log_scale; /* powers and roughness act multiplicatively */
} fit_range;

/* Seed ranges: source 000 (docs/models.md, D3D9Client eq. 3), "A typical range for the power parameter is 2.5 to 3.5
 * ... the offset R_0 ... 0.05 to 0.25", the multiplier set to 1 - offset. Direct3D colours are fractions of the light,
 * and a Blinn power beyond 256 is a glint at our sizes (a lobe about 7 degrees wide). Beckmann m below 0.01 is a lobe
 * narrower than a pixel here; 1 is the roughest surface source 004 describes. Wide ranges, to see where the best value
 * lies when a seed range holds it at a bound: p up to 10 (Schlick's own exponent is 5), any r0, Vs up to 2 (an
 * over-bright highlight), P up to 1e4 and m down to 0.001 (the stiff scenes' values). */
static const fit_range fit_ranges[2][5] = {
    [FIT_BOUNDS_SEED] = {[FIT_D9_P] = {2.5, 3.5, 0},
                         [FIT_D9_R0] = {0.05, 0.25, 0},
                         [FIT_D3D_VS] = {0.0, 1.0, 0},
                         [FIT_D3D_POWER] = {1.0, 256.0, 1},
                         [FIT_CT_M] = {0.01, 1.0, 1}},
    [FIT_BOUNDS_WIDE] = {[FIT_D9_P] = {1.0, 10.0, 0},
                         [FIT_D9_R0] = {0.0, 1.0, 0},
                         [FIT_D3D_VS] = {0.0, 2.0, 0},
                         [FIT_D3D_POWER] = {1.0, 1e4, 1},
                         [FIT_CT_M] = {0.001, 1.0, 1}},
};

/* Global stage: Halton points per free parameter. 12 per parameter puts about 3.5 points along
 * each axis of a 2-parameter box per basin of a tenth of the range, enough to land one start
 * in the basin the authored point misses (d3d9_glass, p = 4.7 against p = 3.6). */
#define FIT_SCREEN_PER_PARAM 12
/* Screen storage: points times parameters, scaled coordinates. */
#define FIT_MAX_SCREEN       256
/* Two starts closer than this in every scaled coordinate would descend the same basin: a
 * start's first BOBYQA step is 0.1 of the range. */
#define FIT_START_APART      0.15
/* The curvature probes' step: 1 % of the scaled range, small beside a basin (0.1) but large
 * enough that the NRMSE change (about curv h^2 / 2, 1e-4 of f0 at typical curvatures) stands well
 * above float rounding in the renders (1e-7 relative). */
#define FIT_CURVATURE_STEP   0.01
/* A local run's first step: a tenth of each range, large enough to see past a pixel's worth of
 * highlight. */
#define FIT_LOCAL_STEP       0.1
/* A local run within this (scaled, every coordinate) of an earlier run's end, and within
 * FIT_UNCERTAINTY_TOL of its NRMSE, has joined its basin: 5 % of a first step (0.1), 50 times
 * xtol, so a run only passing by is not stopped. */
#define FIT_SAME_END         0.005

/* A fitted value this close (in the scaled range) to a bound is reported as held by it. */
#define FIT_AT_BOUND 1e-3

const char *fit_param_name(fit_param_kind k)
{
    switch (k) {
    case FIT_D9_P: return "p";
    case FIT_D9_R0: return "r0";
    case FIT_D3D_VS: return "Vs";
    case FIT_D3D_POWER: return "P";
    case FIT_CT_M: return "m";
    case FIT_USER: return "user";
    }
    return "?";
}

const char *fit_param_label(const scene *s, const fit_param *p)
{
    if (p->kind == FIT_USER)
        return s->materials[p->material].user.model->params[p->user_index].name;
    return fit_param_name(p->kind);
}

/* A user model's parameters: its own bounds and scale (the authored value is within them: the
 * scene parser refuses one outside). */
static void fit_add_user(fit_param *p, int max, int *n, int mat, const material *mt)
{
    const reflcheck_user_model *um = mt->user.model;
    for (int i = 0; um != NULL && i < um->n_params && *n < max; i++) {
        fit_param *q = &p[(*n)++];
        memset(q, 0, sizeof *q);
        q->kind = FIT_USER;
        q->material = mat;
        q->user_index = i;
        q->lo = um->params[i].lo;
        q->hi = um->params[i].hi;
        q->log_scale = um->params[i].log_scale;
        q->authored = q->value = mt->user.params[i];
    }
}

static void fit_add(fit_param *p, int max, int *n, fit_bounds b, fit_param_kind kind, int mat, double authored)
{
    if (*n >= max)
        return;
    const fit_range *r = &fit_ranges[b == FIT_BOUNDS_WIDE][kind];
    fit_param *q = &p[(*n)++];
    memset(q, 0, sizeof *q);
    q->kind = kind;
    q->material = mat;
    q->lo = fmin(r->lo, authored);
    q->hi = fmax(r->hi, authored);
    q->log_scale = r->log_scale;
    q->authored = authored;
    q->value = authored;
}

int fit_default_params(const scene *s, fit_bounds b, fit_param *p, int max)
{
    int n = 0;
    for (int i = 0; i < s->n_materials; i++) {
        int used = 0;
        for (int o = 0; o < s->n_objects; o++)
            used |= s->objects[o].material == i;
        if (!used)
            continue;
        const material *mt = &s->materials[i];
        switch (mt->model) {
        case MODEL_D3D9CLIENT:
            fit_add(p, max, &n, b, FIT_D9_P, i, mt->d9.p);
            fit_add(p, max, &n, b, FIT_D9_R0, i, mt->d9.r0);
            /* float rounding of 1 - r0 as the scene file computed it */
            if (n > 0 && p[n - 1].kind == FIT_D9_R0)
                p[n - 1].tied = fabsf(mt->d9.m - (1.0f - mt->d9.r0)) < 1e-6f;
            break;
        case MODEL_D3D: {
            float vs = v3_max_comp(mt->d3d.specular);
            if (vs <= 0.0f)
                break;
            fit_add(p, max, &n, b, FIT_D3D_VS, i, vs);
            if (n > 0 && p[n - 1].kind == FIT_D3D_VS)
                p[n - 1].colour = mt->d3d.specular;
            /* P = 0 is a flat highlight, no lobe: nothing for a power to shape on a log scale. */
            if (mt->d3d.power > 0.0f)
                fit_add(p, max, &n, b, FIT_D3D_POWER, i, mt->d3d.power);
            break;
        }
        case MODEL_COOK_TORRANCE:
            if (mt->ct.m > 0.0f)
                fit_add(p, max, &n, b, FIT_CT_M, i, mt->ct.m);
            break;
        case MODEL_USER: fit_add_user(p, max, &n, i, mt); break;
        }
    }
    return n;
}

void fit_apply(scene *s, const fit_param *p, int n, const double *values)
{
    for (int i = 0; i < n; i++) {
        material *mt = &s->materials[p[i].material];
        float v = (float)values[i];
        switch (p[i].kind) {
        case FIT_D9_P: mt->d9.p = v; break;
        case FIT_D9_R0:
            mt->d9.r0 = v;
            if (p[i].tied)
                mt->d9.m = 1.0f - v;
            break;
        case FIT_D3D_VS: {
            float c = v3_max_comp(p[i].colour);
            mt->d3d.specular = c > 0.0f ? v3_scale(p[i].colour, v / c) : v3s(v);
            break;
        }
        case FIT_D3D_POWER: mt->d3d.power = v; break;
        case FIT_CT_M: mt->ct.m = v; break;
        case FIT_USER: mt->user.params[p[i].user_index] = values[i]; break;
        }
    }
}

static double fit_unscale(const fit_param *p, double x)
{
    if (p->log_scale)
        return exp(log(p->lo) + x * (log(p->hi) - log(p->lo)));
    return p->lo + x * (p->hi - p->lo);
}

static double fit_scale(const fit_param *p, double v)
{
    double x = p->log_scale ? (log(v) - log(p->lo)) / (log(p->hi) - log(p->lo)) : (v - p->lo) / (p->hi - p->lo);
    return x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x);
}

typedef struct {
    scene *s;
    const mesh *m;
    const env_map *env;
    const metrics_image *ref;
    const fit_param *p;
    int n;
    render_options ro;
    unsigned char *mask; /* surface pixels, from the first render */
    double *values;      /* scratch: parameter values */
    double best_f;
    double *best_x;
    fit_error best;
    int evaluations;
    int budget;                                  /* evaluations allowed in all, the authored one included */
    nlopt_opt run;                               /* the local run going on, NULL in the screen */
    double ends[FIT_MAX_STARTS][FIT_MAX_PARAMS]; /* where the earlier local runs ended (scaled) */
    double end_f[FIT_MAX_STARTS];                /* and their NRMSE */
    int n_ends;
    int joined;                          /* the current run reached an earlier end */
    double run_f, run_x[FIT_MAX_PARAMS]; /* the current run's best: what a stopped run returns */
    rc_status failed;
    char *err;
    size_t errlen;
    /* The frame's layers, kept between evaluations (render_options.reuse_image): img takes each
     * render, best_img holds the render of best_x once an evaluation has beaten the authored point
     * (a pointer swap, no copy), so the best point's robust figures need no render again. */
    render_image img, best_img;
    int best_rendered;
    int fresh; /* fit_options.fresh: every evaluation renders into fresh layers */
    /* The authored render kept (render_options.keep): an evaluation changes material parameters
     * only, so later renders shade the kept frame again instead of rasterizing it; NULL fresh. */
    render_keep *keep;
    /* Every point fit_value rendered (scaled x, bit for bit) and its objective: NLopt starts each
     * BOBYQA run by evaluating its start, which the screen (or an earlier run) often rendered. */
    double (*seen_x)[FIT_MAX_PARAMS];
    double *seen_f;
    int n_seen, max_seen;
    int renders; /* render_scene calls, the authored and the best point's included */
} fit_ctx;

/* NRMSE of a render against the reference over the mask (every evaluation); with robust set,
 * also the spread figures compare.json gives a validate (metrics_robust, worst 1 %), so a
 * fit's median, trimmed NRMSE and worst share are the comparison's own definitions. */
static rc_status fit_measure(const fit_ctx *c, const render_image *img, int robust, fit_error *e)
{
    size_t np = (size_t)c->ref->width * (size_t)c->ref->height;
    double sse = 0.0, ref_sum = 0.0;
    long n = 0;
    for (size_t i = 0; i < np; i++) {
        if (!c->mask[i])
            continue;
        double t[3], r[3];
        int finite = 1;
        for (int ch = 0; ch < 3; ch++) {
            t[ch] = img->chan[RENDER_R + ch][i];
            r[ch] = c->ref->c[ch][i];
            finite &= isfinite(t[ch]) && isfinite(r[ch]);
        }
        if (!finite)
            continue;
        for (int ch = 0; ch < 3; ch++) {
            double d = t[ch] - r[ch];
            sse += d * d;
            ref_sum += fabs(r[ch]) / 3.0;
        }
        n++;
    }
    e->n_pixels = n;
    e->nrmse = n > 0 && ref_sum > 0.0 ? sqrt(sse / (3.0 * (double)n)) / (ref_sum / (double)n) : NAN;
    e->median_rel = e->nrmse_trim1 = e->worst1_share = NAN;
    if (!robust || n == 0)
        return RC_OK;
    metrics_image test = {img->width, img->height, {img->chan[RENDER_R], img->chan[RENDER_G], img->chan[RENDER_B]}};
    metrics_robust_options ro = {.rel_eps = COMPARE_REL_EPS, .trim = 0.01};
    metrics_robust_result rb;
    rc_status st = metrics_robust(c->ref, &test, c->mask, &ro, &rb, c->err, c->errlen);
    if (st == RC_OK) {
        e->median_rel = rb.rel_median;
        e->nrmse_trim1 = rb.nrmse_trim;
        e->worst1_share = rb.worst_share;
    }
    return st;
}

/* The objective at x if fit_value rendered that very point before (every bit of x the same:
 * the render is deterministic, so the value is too); 0 when it did not. */
static int fit_seen(const fit_ctx *c, const double *x, double *f)
{
    for (int i = 0; i < c->n_seen; i++)
        if (memcmp(c->seen_x[i], x, (size_t)c->n * sizeof *x) == 0) {
            *f = c->seen_f[i];
            return 1;
        }
    return 0;
}

/* The scene at parameter values rendered into c->img: over its layers, shaded again from the kept
 * first render (render_options.keep: same bits), or fresh ones rasterized anew with
 * fit_options.fresh; every call counted in c->renders. */
static rc_status fit_render(fit_ctx *c, const double *values)
{
    fit_apply(c->s, c->p, c->n, values);
    if (c->fresh)
        render_image_free(&c->img);
    c->renders++;
    return render_scene(c->s, c->m, c->env, &c->ro, &c->img, c->err, c->errlen);
}

/* The objective at scaled x, rendered into c->img and measured (or the value of the same point
 * rendered before; *rendered says which); HUGE_VAL (with c->failed set) when the render fails or
 * nothing is measured. Touches no counter of evaluations: the uncertainty probes use it too. */
static double fit_value(fit_ctx *c, const double *x, int *rendered)
{
    double f;
    *rendered = 0;
    if (!c->fresh && fit_seen(c, x, &f))
        return f;
    for (int i = 0; i < c->n; i++)
        c->values[i] = fit_unscale(&c->p[i], x[i]);
    rc_status st = fit_render(c, c->values);
    if (st != RC_OK) {
        c->failed = st;
        return HUGE_VAL;
    }
    *rendered = 1;
    fit_error e;
    fit_measure(c, &c->img, 0, &e);
    f = isfinite(e.nrmse) ? e.nrmse : HUGE_VAL;
    if (!c->fresh && c->n_seen < c->max_seen) {
        memcpy(c->seen_x[c->n_seen], x, (size_t)c->n * sizeof *x);
        c->seen_f[c->n_seen++] = f;
    }
    return f;
}

static double fit_objective(unsigned n, const double *x, double *grad, void *data)
{
    (void)grad; /* derivative-free */
    fit_ctx *c = data;
    /* Each local run's maxeval keeps within the budget; this guards the screen's loop. */
    if (c->evaluations >= c->budget || c->failed != RC_OK)
        return HUGE_VAL;
    int rendered;
    double f = fit_value(c, x, &rendered);
    if (c->failed != RC_OK)
        return HUGE_VAL;
    c->evaluations++;
    if (f < c->best_f) {
        c->best_f = f;
        memcpy(c->best_x, x, n * sizeof *x);
        /* A value seen before is never below the best (best_f only falls), so a new best was
         * rendered just now: its layers become best_img's, its old ones the next frame's. */
        c->best_rendered = rendered && !c->fresh;
        if (c->best_rendered) {
            render_image t = c->best_img;
            c->best_img = c->img;
            c->img = t;
        }
    }
    if (c->run != NULL && f < c->run_f) {
        c->run_f = f;
        memcpy(c->run_x, x, n * sizeof *x);
    }
    /* A run that comes this close to where an earlier one ended is descending the same basin
     * to the same end: stopping it saves the rest of its renders for the other starts. */
    for (int e = 0; c->run != NULL && e < c->n_ends; e++) {
        double d = 0.0;
        for (unsigned q = 0; q < n; q++)
            d = fmax(d, fabs(x[q] - c->ends[e][q]));
        /* near in place and in value: a run near an end but still well above it (a narrow
         * valley, r0 in d3d9_glass) has not reached it yet */
        if (d < FIT_SAME_END && f <= c->end_f[e] * (1.0 + FIT_UNCERTAINTY_TOL)) {
            c->joined = 1;
            nlopt_force_stop(c->run);
        }
    }
    return f;
}

static const char *fit_stop_text(nlopt_result r)
{
    switch (r) {
    case NLOPT_XTOL_REACHED: return "converged: x tolerance reached";
    case NLOPT_FTOL_REACHED: return "converged: f tolerance reached";
    case NLOPT_STOPVAL_REACHED: return "converged: stop value reached";
    case NLOPT_SUCCESS: return "converged";
    case NLOPT_MAXEVAL_REACHED: return "evaluation budget used";
    case NLOPT_MAXTIME_REACHED: return "time budget used";
    case NLOPT_ROUNDOFF_LIMITED: return "stopped by round-off (best point kept)";
    case NLOPT_FORCED_STOP: return "stopped: a render failed";
    case NLOPT_OUT_OF_MEMORY: return "NLopt out of memory";
    case NLOPT_INVALID_ARGS: return "NLopt refused its arguments";
    default: return "NLopt failed";
    }
}

static double fit_clock(clockid_t id)
{
    struct timespec ts;
    clock_gettime(id, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double fit_now(void) { return fit_clock(CLOCK_MONOTONIC); }

/* The best point's figures, the robust ones included, from its render kept by fit_objective,
 * or rendered at values when the best is still the authored point (whose values may differ
 * from those of its scaled x in the last bit) or the fit renders afresh. */
static rc_status fit_best_measure(fit_ctx *c, const double *values, fit_error *e)
{
    if (c->best_rendered)
        return fit_measure(c, &c->best_img, 1, e);
    rc_status st = fit_render(c, values);
    if (st == RC_OK)
        st = fit_measure(c, &c->img, 1, e);
    return st;
}

/* The surface pixels with a sample where the reference's crease rules depart (harness/crease.h)
 * become METRICS_PX_CREASE in cls, so the mask is compare's surface for that reference. */
static rc_status fit_crease(const scene *s, const mesh *m, int k, int threads, unsigned char *cls, char *err,
                            size_t errlen)
{
    size_t np = (size_t)s->width * (size_t)s->height;
    float *share = malloc(np * sizeof *share);
    if (share == NULL) {
        status_message(err, errlen, "%s: fit: out of memory for the crease layer", s->path);
        return RC_ERR_NOMEM;
    }
    rc_status st = crease_share(s, m, s->width, s->height, k, threads, share, err, errlen);
    if (st == RC_OK)
        crease_classify(cls, share, np, NULL);
    free(share);
    return st;
}

/* Point i (from 1) of the Halton sequence in [0, 1]^n, one prime base per dimension: an even,
 * deterministic spread with no seed to fix, and each prefix is itself evenly spread. */
static void fit_halton(int i, int n, double *x)
{
    static const int primes[FIT_MAX_PARAMS] = {2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53};
    for (int d = 0; d < n; d++) {
        double f = 1.0, r = 0.0;
        for (int k = i; k > 0; k /= primes[d]) {
            f /= primes[d];
            r += f * (k % primes[d]);
        }
        x[d] = r;
    }
}

/* Screen size: FIT_SCREEN_PER_PARAM points per parameter, at most a third of the budget so the
 * local runs keep most of it (and none when one start is asked for: the fit is then local). */
static int fit_screen_size(int n, int budget, int starts)
{
    if (starts <= 1)
        return 0;
    int k = FIT_SCREEN_PER_PARAM * n;
    return k < budget / 3 ? k : budget / 3;
}

/* Starts: the authored point, then the best screened points at least FIT_START_APART (scaled,
 * in some coordinate) from every start already taken, so two starts do not descend the
 * same basin from next door. Returns how many. */
static int fit_pick_starts(int n, const double *x0, const double *pts, const double *fs, int screened, int want,
                           double (*starts)[FIT_MAX_PARAMS])
{
    memcpy(starts[0], x0, (size_t)n * sizeof *x0);
    int k = 1;
    char used[FIT_MAX_SCREEN] = {0};
    while (k < want) {
        int best = -1;
        for (int i = 0; i < screened; i++) {
            if (used[i] || !isfinite(fs[i]) || (best >= 0 && fs[i] >= fs[best]))
                continue;
            int apart = 1;
            for (int j = 0; j < k && apart; j++) {
                double d = 0.0;
                for (int q = 0; q < n; q++)
                    d = fmax(d, fabs(pts[i * n + q] - starts[j][q]));
                apart = d >= FIT_START_APART;
            }
            if (apart)
                best = i;
            else
                used[i] = 1;
        }
        if (best < 0)
            break;
        used[best] = 1;
        memcpy(starts[k++], &pts[best * n], (size_t)n * sizeof *pts);
    }
    return k;
}

/* One local BOBYQA run from x (scaled; the run's end point comes back in x) with maxeval
 * renders at most, its first steps step wide. */
static nlopt_result fit_local(fit_ctx *c, double *x, int maxeval, double xtol, double step, double *f)
{
    double lo[FIT_MAX_PARAMS], hi[FIT_MAX_PARAMS];
    for (int i = 0; i < c->n; i++) {
        lo[i] = 0.0;
        hi[i] = 1.0;
    }
    nlopt_opt h = nlopt_create(NLOPT_LN_BOBYQA, (unsigned)c->n);
    if (h == NULL)
        return NLOPT_OUT_OF_MEMORY;
    nlopt_set_lower_bounds(h, lo);
    nlopt_set_upper_bounds(h, hi);
    nlopt_set_min_objective(h, fit_objective, c);
    nlopt_set_xtol_abs1(h, xtol);
    nlopt_set_maxeval(h, maxeval);
    nlopt_set_initial_step1(h, step);
    c->run = h;
    c->joined = 0;
    c->run_f = HUGE_VAL;
    nlopt_result r = nlopt_optimize(h, x, f);
    c->run = NULL;
    nlopt_destroy(h);
    /* A forced stop hands back the last point tried: the run's record is its best. */
    if (c->run_f < HUGE_VAL) {
        memcpy(x, c->run_x, (size_t)c->n * sizeof *x);
        *f = c->run_f;
    }
    if (c->n_ends < FIT_MAX_STARTS) {
        c->end_f[c->n_ends] = *f;
        memcpy(c->ends[c->n_ends++], x, (size_t)c->n * sizeof *x);
    }
    return r;
}

/* The global stage, then the local one (fit.h): the screen of Halton points, then BOBYQA from
 * each start with an even share of the budget left. x0 is the authored point (scaled), already
 * rendered as evaluation 1. Fills the screen and start records of out and out->stop. */
static rc_status fit_search(fit_ctx *c, const double *x0, int budget, double xtol, int want, fit_result *out)
{
    int n = c->n;
    c->budget = budget;
    want = want < 1 ? 1 : (want > FIT_MAX_STARTS ? FIT_MAX_STARTS : want);
    int screen = fit_screen_size(n, budget, want);
    screen = screen < FIT_MAX_SCREEN / n ? screen : FIT_MAX_SCREEN / n;
    double pts[FIT_MAX_SCREEN], fs[FIT_MAX_SCREEN];
    int screened = 0;
    for (; screened < screen && c->evaluations < budget; screened++) {
        fit_halton(screened + 1, n, &pts[screened * n]);
        fs[screened] = fit_objective((unsigned)n, &pts[screened * n], NULL, c);
        if (c->failed != RC_OK)
            return c->failed;
    }
    out->screen_points = screened;
    double starts[FIT_MAX_STARTS][FIT_MAX_PARAMS];
    int k = fit_pick_starts(n, x0, pts, fs, screened, want, starts);
    nlopt_result best_r = NLOPT_MAXEVAL_REACHED;
    double best_f = HUGE_VAL;
    out->best_start = -1;
    for (int i = 0; i < k; i++) {
        /* Each run to xtol: stopped early (at 1e-2, then the best polished) the runs' ends
         * misranked their basins, and d3d9_glass lost the p = 4.7 one (0.26, 0.31, not 0.10). */
        int left = budget - c->evaluations;
        if (left < 1)
            break;
        fit_start *r = &out->starts[out->n_starts++];
        double x[FIT_MAX_PARAMS], f = HUGE_VAL;
        memcpy(x, starts[i], (size_t)n * sizeof *x);
        int before = c->evaluations;
        nlopt_result nr = fit_local(c, x, left / (k - i) > 0 ? left / (k - i) : 1, xtol, FIT_LOCAL_STEP, &f);
        if (c->failed != RC_OK)
            return c->failed;
        if (nr == NLOPT_OUT_OF_MEMORY) {
            status_message(c->err, c->errlen, "%s: fit: NLopt could not create its optimiser (out of memory)",
                           c->s->path);
            return RC_ERR_NOMEM;
        }
        for (int q = 0; q < n; q++) {
            r->start[q] = fit_unscale(&c->p[q], starts[i][q]);
            r->end[q] = fit_unscale(&c->p[q], x[q]);
        }
        r->nrmse = f;
        r->evaluations = c->evaluations - before;
        r->stop = c->joined ? "stopped: reached an earlier run's end (the same basin)" : fit_stop_text(nr);
        if (f < best_f) {
            best_f = f;
            best_r = nr;
            out->best_start = out->n_starts - 1;
        }
    }
    out->stop = c->evaluations >= budget ? fit_stop_text(NLOPT_MAXEVAL_REACHED) : fit_stop_text(best_r);
    return RC_OK;
}

/* The change of each parameter that raises the NRMSE by FIT_UNCERTAINTY_TOL of itself, from the
 * curvature of the objective along that parameter at the best point (a central second
 * difference, one-sided at a bound): NRMSE is the root of a sum of squares, so near its minimum
 * f = f0 + curv dx^2 / 2 and dx = sqrt(2 tol f0 / curv). NAN where the objective does not curve
 * up (flat) or the value is held by a bound. Also the spread of each parameter
 * among the starts that ended within the same tolerance of the best. */
static rc_status fit_uncertainty(fit_ctx *c, fit_param *pa, const double *xb, double f0, fit_result *out)
{
    const double h = FIT_CURVATURE_STEP;
    for (int i = 0; i < c->n; i++) {
        fit_param *p = &pa[i];
        double x[FIT_MAX_PARAMS], f[2];
        /* offsets of the two probes: either side, or two steps inward from a bound */
        double d[2] = {h, -h};
        if (xb[i] + h > 1.0)
            d[0] = -2.0 * h;
        else if (xb[i] - h < 0.0)
            d[1] = 2.0 * h;
        for (int k = 0; k < 2; k++) {
            memcpy(x, xb, (size_t)c->n * sizeof *x);
            x[i] = xb[i] + d[k];
            int rendered;
            f[k] = fit_value(c, x, &rendered);
            if (c->failed != RC_OK)
                return c->failed;
            out->uncertainty_evaluations++;
        }
        /* the parabola through (0, f0), (d0, f0'), (d1, f1'): its second derivative */
        double curv = 2.0 * ((f[0] - f0) / d[0] - (f[1] - f0) / d[1]) / (d[0] - d[1]);
        /* At a bound the objective still falls towards it: its curvature there bounds nothing. */
        double dx = curv > 0.0 && isfinite(curv) && !p->at_bound ? sqrt(2.0 * FIT_UNCERTAINTY_TOL * f0 / curv) : NAN;
        double v = fit_unscale(p, xb[i]);
        double dvdx = p->log_scale ? v * (log(p->hi) - log(p->lo)) : p->hi - p->lo;
        p->uncertainty = dx * dvdx;
        p->spread_lo = p->spread_hi = v;
        for (int s = 0; s < out->n_starts; s++)
            if (out->starts[s].nrmse <= f0 * (1.0 + FIT_UNCERTAINTY_TOL)) {
                p->spread_lo = fmin(p->spread_lo, out->starts[s].end[i]);
                p->spread_hi = fmax(p->spread_hi, out->starts[s].end[i]);
            }
    }
    return RC_OK;
}

/* Renders the keep shaded again (fit_result.reshaded); 0 without one (fit_options.fresh). */
static int fit_reshaded(const render_keep *k)
{
    render_keep_stats ks = {0};
    if (k != NULL)
        render_keep_stats_get(k, &ks);
    return ks.replayed;
}

/* What fit_run allocated in c: the scene copy, mask, kept layers and the points rendered. */
static void fit_ctx_free(fit_ctx *c)
{
    render_keep_free(c->keep);
    render_image_free(&c->img);
    render_image_free(&c->best_img);
    free(c->seen_x);
    free(c->seen_f);
    free(c->s);
    free(c->mask);
}

rc_status fit_run(const scene *s, const mesh *m, const env_map *env, const metrics_image *ref, fit_param *p, int n,
                  const fit_options *o, fit_result *out, char *err, size_t errlen)
{
    fit_options opt = o != NULL ? *o : (fit_options){0};
    int max_evals = opt.max_evals > 0 ? opt.max_evals : FIT_DEFAULT_EVALS;
    double xtol = opt.xtol > 0.0 ? opt.xtol : FIT_DEFAULT_XTOL;
    memset(out, 0, sizeof *out);
    if (n <= 0 || n > FIT_MAX_PARAMS) {
        status_message(err, errlen, "%s: %d free parameters; a fit needs 1 to %d", s->path, n, FIT_MAX_PARAMS);
        return RC_ERR_RANGE;
    }
    if (ref->width != s->width || ref->height != s->height || !ref->c[0] || !ref->c[1] || !ref->c[2]) {
        status_message(err, errlen,
                       "%s: the reference is %dx%d with%s R, G, B; the scene renders %dx%d: render the "
                       "reference at the scene's size (the same variant)",
                       s->path, ref->width, ref->height, ref->c[0] && ref->c[1] && ref->c[2] ? "" : "out", s->width,
                       s->height);
        return RC_ERR_RANGE;
    }
    double t0 = fit_now(), cpu0 = fit_clock(CLOCK_PROCESS_CPUTIME_ID);
    size_t np = (size_t)s->width * (size_t)s->height;
    fit_ctx c = {
        .m = m,
        .env = env,
        .ref = ref,
        .p = p,
        .n = n,
        .ro = {.threads = opt.threads, .aovs = RENDER_AOV_NONE, .textures = opt.textures, .reuse_image = !opt.fresh},
        .best_f = HUGE_VAL,
        .fresh = opt.fresh,
        .err = err,
        .errlen = errlen};
    c.s = malloc(sizeof *c.s);
    c.mask = malloc(np);
    unsigned char *cls = malloc(np);
    /* every evaluation and probe at most: the budget, 2 probes a parameter */
    c.max_seen = max_evals + 2 * n;
    c.seen_x = malloc((size_t)c.max_seen * sizeof *c.seen_x);
    c.seen_f = malloc((size_t)c.max_seen * sizeof *c.seen_f);
    double x[FIT_MAX_PARAMS], vals[FIT_MAX_PARAMS], best_x[FIT_MAX_PARAMS];
    c.values = vals;
    c.best_x = best_x;
    rc_status st = RC_OK;
    c.ro.keep = !opt.fresh && render_keep_make(&c.keep) == RC_OK ? c.keep : NULL;
    if (c.s == NULL || c.mask == NULL || cls == NULL || c.seen_x == NULL || c.seen_f == NULL ||
        (!opt.fresh && c.ro.keep == NULL)) {
        status_message(err, errlen, "%s: fit: out of memory for a %dx%d frame", s->path, s->width, s->height);
        st = RC_ERR_NOMEM;
    }
    if (st == RC_OK) {
        *c.s = *s;
        for (int i = 0; i < n; i++) {
            vals[i] = p[i].authored;
            x[i] = best_x[i] = fit_scale(&p[i], p[i].authored);
        }
        /* The geometry does not depend on the parameters: the authored render's coverage and
         * object layers give the surface mask for every evaluation. */
        st = fit_render(&c, vals);
    }
    if (st == RC_OK) {
        const render_image *img = &c.img;
        metrics_classify(s->width, s->height, img->chan[RENDER_COVERAGE], img->chan[RENDER_OBJECT], cls);
        if (opt.crease_rules)
            st = fit_crease(c.s, m, img->supersample, opt.threads, cls, err, errlen);
        long n_surface = metrics_mask_from_class(s->width, s->height, cls, METRICS_PX_INTERIOR, NULL, 0.0f, c.mask);
        if (st == RC_OK)
            st = fit_measure(&c, img, 1, &out->authored);
        c.evaluations = 1;
        c.best_f = out->authored.nrmse;
        if (st == RC_OK && (n_surface == 0 || out->authored.n_pixels == 0 || !isfinite(out->authored.nrmse))) {
            status_message(err, errlen,
                           "%s: no surface pixel with finite values in both images and a reference "
                           "mean above 0: nothing to fit",
                           s->path);
            st = RC_ERR_RANGE;
        }
    }
    if (st == RC_OK)
        st = fit_search(&c, x, max_evals, xtol, opt.starts > 0 ? opt.starts : FIT_DEFAULT_STARTS, out);
    if (st == RC_OK) {
        for (int i = 0; i < n; i++) {
            p[i].value = fit_unscale(&p[i], best_x[i]);
            p[i].at_bound = best_x[i] < FIT_AT_BOUND || best_x[i] > 1.0 - FIT_AT_BOUND;
            vals[i] = p[i].value;
        }
        st = fit_best_measure(&c, vals, &out->best);
    }
    if (st == RC_OK)
        st = fit_uncertainty(&c, p, best_x, out->best.nrmse, out);
    out->evaluations = c.evaluations;
    out->renders = c.renders;
    out->reshaded = fit_reshaded(c.keep);
    out->seconds = fit_now() - t0;
    out->cpu_seconds = fit_clock(CLOCK_PROCESS_CPUTIME_ID) - cpu0;
    out->width = s->width;
    out->height = s->height;
    out->supersample = s->supersample;
    fit_ctx_free(&c);
    free(cls);
    return st;
}
