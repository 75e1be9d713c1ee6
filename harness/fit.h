/* fit.h - the best an approximation can do: its free parameters fitted to a reference image.
 *
 * Usage:
 *   fit_param p[FIT_MAX_PARAMS];
 *   int n = fit_default_params(&scn, FIT_BOUNDS_SEED, p, FIT_MAX_PARAMS);   free parameters, as authored
 *   fit_options o = {0};              zero = screen + 4 BOBYQA runs, 400 renders, x tolerance 1e-4
 *   fit_result r;
 *   fit_run(&scn, &msh, &env, &ref, p, n, &o, &r, err, sizeof err);
 *   r.authored.nrmse, r.best.nrmse, p[i].value, r.evaluations, r.seconds ...
 *
 * The scene is rendered by our rasterizer (render/render.h) at the reference's size with the
 * scene's supersampling, exactly as the validate job renders it; each evaluation changes the
 * parameters of a private copy of the scene and renders again, into the same layers
 * (render_options.reuse_image), shading the authored render's kept frame again instead of
 * rasterizing it (render_options.keep: only materials change). A point rendered before (every
 * bit of its scaled x the same: each BOBYQA run starts by evaluating its start, mostly a
 * screened point) takes its value from that
 * render, and the best point's render is kept for its robust figures; the result is the same to
 * the bit as rendering every evaluation afresh (o.fresh = 1). The objective is the least-squares
 * error over surface pixels: interior pixels of the model's own coverage and object layers
 * (harness/metrics.h, metrics_classify), the region compare.json calls "surface", over R, G, B.
 * It is reported as NRMSE (RMSE over the mean reference, as compare.c computes it), so
 * minimising it is least squares. Beside it, for the authored and the best point, the spread
 * figures compare.json gives a validate (harness/metrics.h, metrics_robust, worst 1 %): the
 * median per-pixel relative error, sqrt(mean over R, G, B of (t - r)^2 / (r^2 +
 * COMPARE_REL_EPS)), the NRMSE without the worst 1 % of pixels, and their share of the squared
 * error.
 *
 * The search has two stages, on parameters scaled to [0, 1] over their bounds (log-scaled for
 * powers and roughness, which act multiplicatively). Global: a screen of FIT_SCREEN_PER_PARAM
 * points per parameter from the Halton sequence (deterministic: no seed), at most a third of
 * the budget. Local: NLopt's bounded derivative-free BOBYQA (Powell 2009) from o.starts starts,
 * the authored point first, then the best screened points FIT_START_APART from each other, each
 * run with an even share of the budget left; a run stops when a step changes every scaled
 * parameter by less than o.xtol or at its share, or when it comes within FIT_SAME_END of where an
 * earlier run ended (the same basin, the same end). A local search from the authored point alone
 * (o.starts = 1, the fit before the screen) stops in the first basin it meets: d3d9_glass wide
 * against POV-Ray stopped at NRMSE 0.396 with the better basin at 0.10. The best point seen is
 * kept, so best.nrmse is never above authored.nrmse, and the result records every run (start,
 * end, NRMSE, renders, stop).
 * Uncertainty per parameter: the change that raises the best NRMSE by FIT_UNCERTAINTY_TOL of
 * itself, from the objective's curvature along the parameter at the best point (2 probes each).
 * The curvature, not the spread among starts, because starts that reach the same basin end at
 * the same point whatever the objective's flatness; the spread among starts within the same
 * tolerance is reported beside it and shows a second basin as good as the best.
 * Free parameters per model (fit_default_params; materials no object uses are left out), with
 * their FIT_BOUNDS_SEED ranges (FIT_BOUNDS_WIDE in brackets):
 *   D3D9Client: p in the source's typical range [2.5, 3.5] ([1, 10]), and r0 in [0.05, 0.25]
 *     ([0, 1]) with m = 1 - r0 as the D3D9Client material editor sets it (r0 alone when the
 *     scene authors its own m);
 *   Direct3D Blinn-Phong (a material with a specular colour): Vs, the largest channel of the
 *     specular colour (hue kept), in [0, 1] ([0, 2]), and the power P in [1, 256] ([1, 1e4]);
 *   Cook-Torrance: the Beckmann m per material in [0.01, 1] ([0.001, 1]); it shapes the light
 *     lobe only: the environment term CM.Fr does not depend on m.
 *   A user's model (model/user_model.h): every parameter it declares, within its declared bounds
 *     and scale, under both bound sets.
 * Each range is widened to hold the authored value, so the as-authored point is feasible.
 * fit_run returns RC_OK with the result, RC_ERR_RANGE for a reference of another size, no
 * parameters or no surface pixels, RC_ERR_NOMEM, or the renderer's error; err says which.
 */
#ifndef REFLCHECK_FIT_H
#define REFLCHECK_FIT_H

#include <stddef.h>

#include "env.h"
#include "mesh.h"
#include "metrics.h"
#include "scene.h"
#include "status.h"
#include "texture.h"

#define FIT_MAX_PARAMS      16
/* The budget, screen and local runs together: a 1-3 parameter BOBYQA run converges in 20-80
 * renders; 400 pays for a 24-36 point screen and 4 such runs with room, and caps a full-size
 * d3d9_glass fit (0.1 s a render on 2 cores) at about 40 s. */
#define FIT_DEFAULT_EVALS   400
/* 1e-4 of a parameter's range: far below what moves the error (p by 1e-4, m by 0.1 % on the
 * log scale), so the fit stops on convergence, not on the budget. */
#define FIT_DEFAULT_XTOL    1e-4
/* Local runs: the authored point and the 3 best screened points apart from it and each other. */
#define FIT_DEFAULT_STARTS  4
#define FIT_MAX_STARTS      8
/* The uncertainty of a parameter: the change that raises the best NRMSE by 1 % of itself, an
 * amount below which two fits' NRMSE figures do not differ in any threshold we gate. */
#define FIT_UNCERTAINTY_TOL 0.01

/* FIT_USER: a parameter of a user's model (model/user_model.h), with the bounds and scale the
 * model declares (the same under both bound sets: the model's author knows its range). */
typedef enum { FIT_D9_P, FIT_D9_R0, FIT_D3D_VS, FIT_D3D_POWER, FIT_CT_M, FIT_USER } fit_param_kind;
typedef enum { FIT_BOUNDS_SEED = 0, FIT_BOUNDS_WIDE = 1 } fit_bounds;

typedef struct {
    fit_param_kind kind;
    int material;                /* index into scene.materials */
    double lo, hi;               /* bounds */
    int log_scale;               /* scaled as log(value) between log(lo) and log(hi) */
    double authored;             /* the scene's value: the start */
    double value;                /* fitted (fit_run) */
    int at_bound;                /* the fitted value is within 1e-3 of the range of a bound */
    int tied;                    /* FIT_D9_R0: m = 1 - r0 follows r0 */
    vec3 colour;                 /* FIT_D3D_VS: the authored specular colour, whose hue is kept */
    int user_index;              /* FIT_USER: the parameter's index in the model's params */
    double uncertainty;          /* fit_run: the change raising the NRMSE by FIT_UNCERTAINTY_TOL of itself,
                                    from the objective's curvature; NAN where it does not curve up or
                                    the value is held by a bound */
    double spread_lo, spread_hi; /* fit_run: the range of the value among starts ending within
                                    FIT_UNCERTAINTY_TOL of the best NRMSE (the best included) */
} fit_param;

typedef struct {
    int max_evals;               /* renders in all, screen and local runs; 0 = FIT_DEFAULT_EVALS */
    int starts;                  /* local runs; 0 = FIT_DEFAULT_STARTS, 1 = local only, no screen */
    double xtol;                 /* per parameter, in the scaled [0, 1] range; 0 = 1e-4 */
    int threads;                 /* render threads, 0 = all cores */
    const texture_set *textures; /* the materials' textures (harness/frame.h), NULL = none */
    int crease_rules;            /* 1: the reference shades creases by its own rules (renderer_row):
                                    the crease pixels leave the mask, as compare leaves them out */
    int fresh;                   /* 1: every evaluation renders, into fresh layers (no point's value
                                    taken from an earlier render of it, no layers kept): the same
                                    result with more renders, to check the default against */
} fit_options;

typedef struct {
    double nrmse;        /* RMSE over the mean reference, surface pixels, R, G, B */
    double median_rel;   /* median per-pixel relative error */
    double nrmse_trim1;  /* NRMSE without the worst 1 % of pixels */
    double worst1_share; /* share of the squared error the worst 1 % hold */
    long n_pixels;       /* surface pixels used (finite in both images) */
} fit_error;

/* One local run of the fit: where it started and ended (parameter values), its NRMSE there. */
typedef struct {
    double start[FIT_MAX_PARAMS], end[FIT_MAX_PARAMS];
    double nrmse;
    int evaluations;
    const char *stop;
} fit_start;

typedef struct {
    fit_error authored, best;
    int evaluations;    /* objective values the optimiser asked for, the authored one included (the
                           best point's figures and the curvature probes are not counted) */
    int renders;        /* frames rendered in all: evaluations less those of a point rendered before,
                           plus the best point's when it was not kept, plus the probes (fit.h top) */
    int reshaded;       /* of those, frames shaded again from the authored render's kept frame
                           (render/render.h, render_options.keep) instead of rasterized; 0 with fresh */
    double seconds;     /* wall time of the fit, renders included */
    double cpu_seconds; /* CPU time of the fitting process over the same span, all its threads */
    int width, height, supersample;
    const char *stop;  /* why the optimiser stopped, in words: the budget, else the best run's stop */
    int screen_points; /* global stage: Halton points rendered (counted in evaluations) */
    int n_starts, best_start;
    fit_start starts[FIT_MAX_STARTS];
    int uncertainty_evaluations; /* curvature probes: 2 per parameter, not in evaluations */
} fit_result;

/* The parameter's name as the fit record writes it: "p", "r0", "Vs", "P", "m". */
const char *fit_param_name(fit_param_kind k);
/* The name as the fit record writes it: fit_param_name's, or a user model's own parameter name. */
const char *fit_param_label(const scene *s, const fit_param *p);
/* Fills p with the scene's free parameters (see above), at most max; returns how many. */
int fit_default_params(const scene *s, fit_bounds b, fit_param *p, int max);
/* Writes values into a scene's materials (m = 1 - r0 follows r0 where fit_default_params tied
 * them). */
void fit_apply(scene *s, const fit_param *p, int n, const double *values);
/* Fits p[0..n-1] (value and at_bound filled) so the render of s approaches ref (R, G, B planes
 * of the reference image; ref->width, ref->height set the render size). */
rc_status fit_run(const scene *s, const mesh *m, const env_map *env, const metrics_image *ref, fit_param *p, int n,
                  const fit_options *o, fit_result *out, char *err, size_t errlen);

#endif
