/* test_fit.c - reflcheck fit: synthetic fits that must recover known parameters (the model
 * rendered with them is the reference, the fit starts elsewhere), the error measures against
 * values worked out from the images by hand, the free parameters and their bounds per model,
 * and the command line: its errors, a failing reference renderer, and one real fit of a small
 * canonical scene against POV-Ray whose as-authored NRMSE must be compare.json's. */
/* realpath (XSI): the test writes a scene whose environment path must be absolute. */
#define _XOPEN_SOURCE 700
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>

#include "check.h"
#include "cli_exec.h"

#include <cJSON.h>

#include "exr.h"
#include "fileio.h"
#include "fit.h"
#include "frame.h"
#include "mesh.h"
#include "render.h"
#include "scene_file.h"

/* A scene, its mesh and environment, from text. */
typedef struct {
    scene *s;
    mesh m;
    env_map env;
    float *env_px;
} world;

static void world_load(world *w, const char *text)
{
    char err[1024];
    w->s = malloc(sizeof *w->s);
    assert_non_null(w->s);
    memset(&w->m, 0, sizeof w->m);
    w->env_px = NULL;
    if (scene_file_parse(text, strlen(text), "fit.yaml", w->s, err, sizeof err) != RC_OK)
        fail_msg("%s", err);
    assert_int_equal(mesh_build(w->s, &w->m, err, sizeof err), RC_OK);
    assert_int_equal(frame_env_load(w->s, &w->env, &w->env_px, err, sizeof err), RC_OK);
}

static void world_free(world *w)
{
    mesh_free(&w->m);
    free(w->env_px);
    free(w->s);
}

/* The render of w's scene with p[0..n-1] set to values: the synthetic reference. */
static void render_with(const world *w, const fit_param *p, int n, const double *values, render_image *img)
{
    scene *t = malloc(sizeof *t);
    assert_non_null(t);
    *t = *w->s;
    fit_apply(t, p, n, values);
    char err[1024];
    render_options o = {.threads = 2, .aovs = RENDER_AOV_NONE};
    assert_int_equal(render_scene(t, &w->m, &w->env, &o, img, err, sizeof err), RC_OK);
    free(t);
}

static metrics_image planes(const render_image *img)
{
    metrics_image r = {img->width, img->height, {img->chan[RENDER_R], img->chan[RENDER_G], img->chan[RENDER_B]}};
    return r;
}

/* A D3D9Client sphere in a two-tone environment (constant sky; the reflection's strength is
 * R(N.V) times it, so p and r0 shape the image). */
static const char glass_text[] =
    "image: {width: 64, height: 48, supersample: 1}\n"
    "camera: {eye: [0, 0.3, 3.2], target: [0, 0, 0], hfov: 45}\n"
    "environment: {constant: [0.8, 0.9, 1.0]}\n"
    "materials:\n"
    "  glass: {albedo: [0, 0, 0], ior: 1.5, roughness: 0, model: d3d9client, "
    "d3d9client: {p: 3.5}}\n"
    "  unused: {albedo: [0.5, 0.5, 0.5], model: cook_torrance}\n"
    "objects:\n"
    "  - {shape: sphere, center: [0, 0, 0], radius: 1, tessellation: 48, material: glass}\n";

/* The brief's case: the model with p = 2.7 is the reference, the fit starts at 3.5 (authored)
 * and must come back to 2.7; with r0 free as well it must find both. */
static void test_recovers_d3d9client_p(void **state)
{
    (void)state;
    world w;
    world_load(&w, glass_text);
    fit_param p[FIT_MAX_PARAMS];
    int n = fit_default_params(w.s, FIT_BOUNDS_SEED, p, FIT_MAX_PARAMS);
    assert_int_equal(n, 2); /* p, r0 of glass; the unused material is left out */
    assert_int_equal(p[0].kind, FIT_D9_P);
    assert_int_equal(p[1].kind, FIT_D9_R0);
    close_rel(p[0].authored, 3.5, 1e-7);

    /* p alone */
    double truth[2] = {2.7, p[1].authored};
    render_image ref;
    render_with(&w, p, 2, truth, &ref);
    metrics_image rm = planes(&ref);
    fit_result r;
    char err[1024];
    fit_options o = {.threads = 2};
    assert_int_equal(fit_run(w.s, &w.m, &w.env, &rm, p, 1, &o, &r, err, sizeof err), RC_OK);
    assert_true(fabs(p[0].value - 2.7) < 0.01);
    assert_false(p[0].at_bound);
    assert_true(r.authored.nrmse > 0.05);
    assert_true(r.best.nrmse < 1e-3 * r.authored.nrmse);
    assert_true(r.evaluations >= 2 && r.evaluations <= FIT_DEFAULT_EVALS);
    assert_int_equal(strncmp(r.stop, "converged", 9), 0);
    render_image_free(&ref);

    /* p and r0 (m = 1 - r0 follows) */
    assert_true(p[1].tied);
    double truth2[2] = {2.7, 0.12};
    render_with(&w, p, 2, truth2, &ref);
    rm = planes(&ref);
    assert_int_equal(fit_run(w.s, &w.m, &w.env, &rm, p, 2, &o, &r, err, sizeof err), RC_OK);
    assert_true(fabs(p[0].value - 2.7) < 0.02);
    assert_true(fabs(p[1].value - 0.12) < 0.002);
    assert_true(r.best.nrmse < 1e-2 * r.authored.nrmse);
    render_image_free(&ref);
    world_free(&w);
}

/* Wide bounds reach a p the source range cannot: truth p = 5 (Schlick's exponent), where the seed
 * fit stops at its bound 3.5 and says so. */
static void test_wide_bounds_reach_beyond_the_seed(void **state)
{
    (void)state;
    world w;
    world_load(&w, glass_text);
    fit_param p[FIT_MAX_PARAMS];
    int n = fit_default_params(w.s, FIT_BOUNDS_WIDE, p, FIT_MAX_PARAMS);
    assert_int_equal(n, 2);
    close_rel(p[0].lo, 1.0, 1e-9);
    close_rel(p[0].hi, 10.0, 1e-9);
    double truth[2] = {5.0, p[1].authored};
    render_image ref;
    render_with(&w, p, n, truth, &ref);
    metrics_image rm = planes(&ref);
    fit_result r;
    char err[1024];
    fit_options o = {.threads = 2};
    assert_int_equal(fit_run(w.s, &w.m, &w.env, &rm, p, 1, &o, &r, err, sizeof err), RC_OK);
    assert_true(fabs(p[0].value - 5.0) < 0.02);
    assert_false(p[0].at_bound);
    n = fit_default_params(w.s, FIT_BOUNDS_SEED, p, FIT_MAX_PARAMS);
    assert_int_equal(fit_run(w.s, &w.m, &w.env, &rm, p, 1, &o, &r, err, sizeof err), RC_OK);
    close_rel(p[0].value, 3.5, 1e-6);
    assert_true(p[0].at_bound);
    render_image_free(&ref);
    world_free(&w);
}

/* Blinn-Phong: Vs = 0.3 and P = 25 from an authored 0.5 and 40; the specular colour's hue is
 * kept (a tinted Vs scales as a whole). */
static void test_recovers_blinn_phong(void **state)
{
    (void)state;
    world w;
    world_load(&w, "image: {width: 64, height: 48, supersample: 1}\n"
                   "camera: {eye: [0, 0.4, 3.2], target: [0, 0, 0], hfov: 45}\n"
                   "lights:\n  - {type: point, position: [1.6, 2.2, 2.4], intensity: [12, 12, 12]}\n"
                   "materials:\n"
                   "  plastic: {albedo: [0.6, 0.15, 0.1], model: d3d, d3d: {specular: [0.5, 0.4, 0.5], power: 40}}\n"
                   "objects:\n"
                   "  - {shape: sphere, center: [0, 0, 0], radius: 1, tessellation: 48, material: plastic}\n");
    fit_param p[FIT_MAX_PARAMS];
    int n = fit_default_params(w.s, FIT_BOUNDS_SEED, p, FIT_MAX_PARAMS);
    assert_int_equal(n, 2);
    assert_int_equal(p[0].kind, FIT_D3D_VS);
    assert_int_equal(p[1].kind, FIT_D3D_POWER);
    assert_true(p[1].log_scale);
    double truth[2] = {0.3, 25.0};
    render_image ref;
    render_with(&w, p, n, truth, &ref);
    metrics_image rm = planes(&ref);
    fit_result r;
    char err[1024];
    fit_options o = {.threads = 2};
    assert_int_equal(fit_run(w.s, &w.m, &w.env, &rm, p, n, &o, &r, err, sizeof err), RC_OK);
    close_rel(p[0].value, 0.3, 0.01);
    close_rel(p[1].value, 25.0, 0.01);
    /* the hue: Vs = 0.3 is the largest channel of (0.5, 0.4, 0.5) scaled, so G = 0.24 */
    scene *t = malloc(sizeof *t);
    *t = *w.s;
    double v[2] = {p[0].value, p[1].value};
    fit_apply(t, p, n, v);
    close_rel(t->materials[0].d3d.specular.y, 0.8 * p[0].value, 1e-6);
    free(t);
    render_image_free(&ref);
    world_free(&w);
}

/* Cook-Torrance: one m per material, two spheres fitted together. */
static void test_recovers_ct_m_per_material(void **state)
{
    (void)state;
    world w;
    world_load(&w, "image: {width: 80, height: 40, supersample: 1}\n"
                   "camera: {eye: [0, 0.5, 3.5], target: [0, 0, 0], hfov: 50}\n"
                   "lights:\n  - {type: point, position: [-1.5, 3.0, 2.5], intensity: [30, 30, 30]}\n"
                   "  - {type: sun, direction: [0.5, -1.0, -0.6], irradiance: [2, 2, 2]}\n"
                   "materials:\n"
                   "  a: {albedo: [0, 0, 0], conductor: {eta: [1.66, 0.88, 0.52], k: [9.22, 6.27, 4.84]}, "
                   "roughness: 0.3, model: cook_torrance, cook_torrance: {reflection: false}}\n"
                   "  b: {albedo: [0, 0, 0], conductor: {eta: [1.66, 0.88, 0.52], k: [9.22, 6.27, 4.84]}, "
                   "roughness: 0.3, model: cook_torrance, cook_torrance: {reflection: false}}\n"
                   "objects:\n"
                   "  - {shape: sphere, center: [-0.8, 0, 0], radius: 0.6, tessellation: 48, material: a}\n"
                   "  - {shape: sphere, center: [0.8, 0, 0], radius: 0.6, tessellation: 48, material: b}\n");
    fit_param p[FIT_MAX_PARAMS];
    int n = fit_default_params(w.s, FIT_BOUNDS_SEED, p, FIT_MAX_PARAMS);
    assert_int_equal(n, 2);
    assert_int_equal(p[0].material, 0);
    assert_int_equal(p[1].material, 1);
    double truth[2] = {0.2, 0.45};
    render_image ref;
    render_with(&w, p, n, truth, &ref);
    metrics_image rm = planes(&ref);
    fit_result r;
    char err[1024];
    fit_options o = {.threads = 2};
    assert_int_equal(fit_run(w.s, &w.m, &w.env, &rm, p, n, &o, &r, err, sizeof err), RC_OK);
    close_rel(p[0].value, 0.2, 0.01);
    close_rel(p[1].value, 0.45, 0.01);
    render_image_free(&ref);
    world_free(&w);
}

/* The error measures, by hand: against a reference twice the model's render, every pixel's
 * relative error is |t - 2t| / 2t = 1/2 (the 1e-8 floor is far below these radiances), so the
 * median is 0.5, and NRMSE = sqrt(mean t^2) / mean(2t) over the surface pixels, which the test
 * sums itself from the render and the mask it classifies, as it sorts out the worst 1 % for the
 * trimmed NRMSE and their share. A budget of 4 renders stops there. */
static void test_measures_by_hand_and_budget(void **state)
{
    (void)state;
    world w;
    world_load(&w, glass_text);
    fit_param p[FIT_MAX_PARAMS];
    int n = fit_default_params(w.s, FIT_BOUNDS_SEED, p, FIT_MAX_PARAMS);
    render_image ref;
    double authored[2] = {p[0].authored, p[1].authored};
    render_with(&w, p, n, authored, &ref);
    size_t np = (size_t)ref.width * (size_t)ref.height;
    for (int ch = 0; ch < 3; ch++)
        for (size_t i = 0; i < np; i++)
            ref.chan[RENDER_R + ch][i] *= 2.0f;
    unsigned char *cls = malloc(np), *mask = malloc(np);
    metrics_classify(ref.width, ref.height, ref.chan[RENDER_COVERAGE], ref.chan[RENDER_OBJECT], cls);
    long n_mask = metrics_mask_from_class(ref.width, ref.height, cls, METRICS_PX_INTERIOR, NULL, 0.0f, mask);
    double sq = 0.0, sum = 0.0;
    for (size_t i = 0; i < np; i++)
        for (int ch = 0; mask[i] && ch < 3; ch++) {
            double t = 0.5 * ref.chan[RENDER_R + ch][i];
            sq += t * t;
            sum += 2.0 * t;
        }
    double want = sqrt(sq / (3.0 * (double)n_mask)) / (sum / (3.0 * (double)n_mask));
    /* The worst 1 %: k = ceil(0.01 N) pixels of largest e = sum over R, G, B of t^2; their share
     * of sum e, and the NRMSE of the others over their own mean reference. */
    double *e = malloc((size_t)n_mask * sizeof *e), *rs = malloc((size_t)n_mask * sizeof *rs);
    long k = (long)ceil(0.01 * (double)n_mask), j = 0;
    for (size_t i = 0; i < np; i++) {
        if (!mask[i])
            continue;
        e[j] = rs[j] = 0.0;
        for (int ch = 0; ch < 3; ch++) {
            double t = 0.5 * ref.chan[RENDER_R + ch][i];
            e[j] += t * t;
            rs[j] += 2.0 * t;
        }
        j++;
    }
    for (long a = 0; a < k; a++) /* selection of the k largest to the front */
        for (long b = a + 1; b < n_mask; b++)
            if (e[b] > e[a]) {
                double te = e[a], tr = rs[a];
                e[a] = e[b], rs[a] = rs[b];
                e[b] = te, rs[b] = tr;
            }
    double top = 0.0, rest = 0.0, rest_ref = 0.0;
    for (long a = 0; a < n_mask; a++) {
        if (a < k)
            top += e[a];
        else
            rest += e[a], rest_ref += rs[a] / 3.0;
    }
    double want_share = top / (top + rest);
    double want_trim = sqrt(rest / (3.0 * (double)(n_mask - k))) / (rest_ref / (double)(n_mask - k));
    free(e);
    free(rs);
    metrics_image rm = planes(&ref);
    fit_result r;
    char err[1024];
    fit_options o = {.threads = 2, .max_evals = 4};
    assert_int_equal(fit_run(w.s, &w.m, &w.env, &rm, p, n, &o, &r, err, sizeof err), RC_OK);
    assert_int_equal(r.authored.n_pixels, n_mask);
    close_rel(r.authored.nrmse, want, 1e-6);
    close_rel(r.authored.median_rel, 0.5, 1e-5);
    close_rel(r.authored.worst1_share, want_share, 1e-6);
    close_rel(r.authored.nrmse_trim1, want_trim, 1e-6);
    assert_true(r.authored.nrmse_trim1 < r.authored.nrmse);
    assert_int_equal(r.evaluations, 4);
    assert_string_equal(r.stop, "evaluation budget used");
    assert_true(r.best.nrmse <= r.authored.nrmse);
    free(cls);
    free(mask);
    render_image_free(&ref);
    world_free(&w);
}

/* Two fits' results the same to the bit: figures, parameters, counts, stops and every local run. */
static void same_fit(const fit_result *a, const fit_result *b, const fit_param *pa, const fit_param *pb, int n)
{
    assert_memory_equal(&a->authored, &b->authored, sizeof a->authored);
    assert_memory_equal(&a->best, &b->best, sizeof a->best);
    assert_int_equal(a->evaluations, b->evaluations);
    assert_int_equal(a->screen_points, b->screen_points);
    assert_int_equal(a->n_starts, b->n_starts);
    assert_int_equal(a->best_start, b->best_start);
    assert_int_equal(a->uncertainty_evaluations, b->uncertainty_evaluations);
    assert_string_equal(a->stop, b->stop);
    for (int s = 0; s < a->n_starts; s++) {
        assert_memory_equal(a->starts[s].start, b->starts[s].start, (size_t)n * sizeof(double));
        assert_memory_equal(a->starts[s].end, b->starts[s].end, (size_t)n * sizeof(double));
        assert_memory_equal(&a->starts[s].nrmse, &b->starts[s].nrmse, sizeof(double));
        assert_int_equal(a->starts[s].evaluations, b->starts[s].evaluations);
        assert_string_equal(a->starts[s].stop, b->starts[s].stop);
    }
    for (int i = 0; i < n; i++) {
        assert_memory_equal(&pa[i].value, &pb[i].value, sizeof(double));
        assert_memory_equal(&pa[i].uncertainty, &pb[i].uncertainty, sizeof(double));
        assert_memory_equal(&pa[i].spread_lo, &pb[i].spread_lo, sizeof(double));
        assert_memory_equal(&pa[i].spread_hi, &pb[i].spread_hi, sizeof(double));
        assert_int_equal(pa[i].at_bound, pb[i].at_bound);
    }
}

/* The default fit keeps its frame's layers between evaluations, takes a point's value from its
 * earlier render and the best point's figures from its kept render; fresh renders every one into
 * new layers, as the fit did before; the default shades the authored render's kept frame again
 * (render_options.keep), fresh rasterizes every frame. Both must give the same result to the bit, the default with
 * fewer renders: each BOBYQA run starts by evaluating its start, which the screen or the authored
 * render has already measured. The reference is no render of the model (a left-to-right ramp of
 * 0.8 to 1.2 times one, p = 2.9, r0 = 0.16 at 2 x 2 samples), so the fit ends at no exact zero
 * and its runs start apart. */
static void test_reused_layers_same_result(void **state)
{
    (void)state;
    world w;
    world_load(&w, glass_text);
    w.s->supersample = 2;
    fit_param p[FIT_MAX_PARAMS], q[FIT_MAX_PARAMS];
    int n = fit_default_params(w.s, FIT_BOUNDS_WIDE, p, FIT_MAX_PARAMS);
    assert_int_equal(n, 2);
    memcpy(q, p, sizeof p);
    double truth[2] = {2.9, 0.16};
    render_image ref;
    render_with(&w, p, n, truth, &ref);
    for (int y = 0; y < ref.height; y++)
        for (int x = 0; x < ref.width; x++)
            for (int ch = 0; ch < 3; ch++)
                ref.chan[RENDER_R + ch][y * ref.width + x] *= 0.8f + 0.4f * (float)x / (float)(ref.width - 1);
    metrics_image rm = planes(&ref);
    fit_result r, rf;
    char err[1024];
    fit_options o = {.threads = 2}, of = {.threads = 2, .fresh = 1};
    assert_int_equal(fit_run(w.s, &w.m, &w.env, &rm, p, n, &o, &r, err, sizeof err), RC_OK);
    assert_int_equal(fit_run(w.s, &w.m, &w.env, &rm, q, n, &of, &rf, err, sizeof err), RC_OK);
    same_fit(&r, &rf, p, q, n);
    assert_true(r.n_starts >= 2);
    assert_true(r.best.nrmse > 0.0 && r.best.nrmse < r.authored.nrmse);
    /* fresh: every evaluation, the best point once more and 2 probes a parameter */
    assert_int_equal(rf.renders, rf.evaluations + 1 + 2 * n);
    /* At least the best point's figures and the second run's start from renders made: that start
     * (4.375, 0.222) lies more than a first step (0.1 scaled) from every bound, where BOBYQA
     * evaluates its start as given (a start nearer a bound it moves first). */
    assert_true(r.starts[1].start[0] > 1.0 + 0.1 * 9.0 && r.starts[1].start[0] < 10.0 - 0.1 * 9.0);
    assert_true(r.renders <= rf.renders - 2);
    /* Every render after the authored one shades its kept frame again; fresh rasterizes all. */
    assert_int_equal(r.reshaded, r.renders - 1);
    assert_int_equal(rf.reshaded, 0);
    render_image_free(&ref);
    world_free(&w);
}

/* Bounds hold the authored value (r0 = 0.04 for n = 1.5 lies below the source's 0.05); a scene
 * that authors its own m fits r0 alone; a wrongly sized reference and no parameter refuse. */
static void test_bounds_and_refusals(void **state)
{
    (void)state;
    world w;
    world_load(&w, glass_text);
    fit_param p[FIT_MAX_PARAMS];
    fit_default_params(w.s, FIT_BOUNDS_SEED, p, FIT_MAX_PARAMS);
    close_rel(p[0].lo, 2.5, 1e-9);
    close_rel(p[0].hi, 3.5, 1e-9);
    close_rel(p[1].lo, 0.04, 1e-6);
    close_rel(p[1].hi, 0.25, 1e-9);
    w.s->materials[0].d9.m = 0.5f;
    fit_default_params(w.s, FIT_BOUNDS_SEED, p, FIT_MAX_PARAMS);
    assert_false(p[1].tied);
    w.s->materials[0].d9.p = 6.0f;
    fit_default_params(w.s, FIT_BOUNDS_SEED, p, FIT_MAX_PARAMS);
    close_rel(p[0].hi, 6.0, 1e-9);

    float plane[12] = {0};
    metrics_image small = {4, 3, {plane, plane, plane}};
    fit_result r;
    char err[1024];
    assert_int_equal(fit_run(w.s, &w.m, &w.env, &small, p, 1, NULL, &r, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "4x3"));
    assert_int_equal(fit_run(w.s, &w.m, &w.env, &small, p, 0, NULL, &r, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "free parameters"));
    world_free(&w);
}

static char tmp_dir[128];

static int setup(void **state)
{
    (void)state;
    snprintf(tmp_dir, sizeof tmp_dir, "/tmp/reflcheck-fit-%ld", (long)getpid());
    mkdir(tmp_dir, 0755);
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp_dir);
    return system(cmd) == 0 ? 0 : -1;
}

static cJSON *read_json(const char *path)
{
    char *text = fileio_read_all(path, NULL);
    if (text == NULL)
        fail_msg("cannot read %s", path);
    cJSON *j = cJSON_Parse(text);
    free(text);
    assert_non_null(j);
    return j;
}

/* The command's errors: usage, options, scene files; a scene with nothing to fit; a reference
 * renderer that fails (a fake povray first on PATH) is an error in the record and exit 1. */
static void test_cli_errors(void **state)
{
    (void)state;
    char err[2048];
    assert_int_equal(cli_exec(err, sizeof err, "fit"), 2);
    assert_non_null(strstr(err, "usage: reflcheck fit"));
    assert_int_equal(cli_exec(err, sizeof err, "fit scenes/d3d9_glass.yaml --bogus"), 2);
    assert_non_null(strstr(err, "--bogus"));
    assert_int_equal(cli_exec(err, sizeof err, "fit scenes/d3d9_glass.yaml --max-evals 1"), 2);
    assert_non_null(strstr(err, "--max-evals"));
    assert_int_equal(cli_exec(err, sizeof err, "fit scenes/d3d9_glass.yaml --bounds tight"), 2);
    assert_non_null(strstr(err, "--bounds 'tight'"));
    assert_int_equal(cli_exec(err, sizeof err, "fit %s/none.yaml --out %s", tmp_dir, tmp_dir), 2);
    assert_non_null(strstr(err, "none.yaml"));
    char bad[300];
    snprintf(bad, sizeof bad, "%s/bad.yaml", tmp_dir);
    FILE *f = fopen(bad, "w");
    fputs("name: bad\nimage: {width: -4}\n", f);
    fclose(f);
    assert_int_equal(cli_exec(err, sizeof err, "fit %s --out %s", bad, tmp_dir), 2);
    assert_non_null(strstr(err, "bad.yaml"));
    /* a scene without a validate comparison (a twin only): nothing to fit, no record, exit 0 */
    char twin_only[300];
    snprintf(twin_only, sizeof twin_only, "%s/twin_only.yaml", tmp_dir);
    f = fopen(twin_only, "w");
    fputs("name: twin_only\nimage: {width: 16, height: 12}\ncamera: {eye: [0, 0, 3], target: [0, 0, 0], hfov: 40}\n"
          "materials:\n  m: {albedo: [0.5, 0.5, 0.5], model: d3d}\n"
          "objects:\n  - {shape: sphere, radius: 1, material: m}\n"
          "comparisons:\n  - {reference: povray, role: twin}\n",
          f);
    fclose(f);
    assert_int_equal(cli_exec(err, sizeof err, "fit %s --out %s", twin_only, tmp_dir), 0);
    char rec[300];
    snprintf(rec, sizeof rec, "%s/twin_only/fit.json", tmp_dir);
    assert_int_equal(access(rec, F_OK), -1);

    /* a validate whose model has no free parameter (Lambert only): skipped, recorded in a folder
     * the fit makes itself (no reference job ran) */
    char lam[300];
    snprintf(lam, sizeof lam, "%s/lambert.yaml", tmp_dir);
    f = fopen(lam, "w");
    fputs("name: lambert\nimage: {width: 16, height: 12}\ncamera: {eye: [0, 0, 3], target: [0, 0, 0], hfov: 40}\n"
          "lights:\n  - {type: point, position: [1, 2, 3], intensity: [5, 5, 5]}\n"
          "materials:\n  m: {albedo: [0.5, 0.5, 0.5], model: d3d}\n"
          "objects:\n  - {shape: sphere, radius: 1, material: m}\n"
          "comparisons:\n  - {reference: exact, role: validate}\n",
          f);
    fclose(f);
    assert_int_equal(cli_exec(err, sizeof err, "fit %s --no-cache --out %s/fresh/run", lam, tmp_dir), 0);
    snprintf(rec, sizeof rec, "%s/fresh/run/lambert/fit.json", tmp_dir);
    cJSON *lj = read_json(rec);
    cJSON *l0 = cJSON_GetArrayItem(cJSON_GetObjectItem(lj, "fits"), 0);
    assert_string_equal(cJSON_GetObjectItem(l0, "status")->valuestring, "skipped");
    assert_non_null(strstr(cJSON_GetObjectItem(l0, "reason")->valuestring, "no free parameter"));
    cJSON_Delete(lj);

    char bin[300], path[400];
    snprintf(bin, sizeof bin, "%s/bin", tmp_dir);
    mkdir(bin, 0755);
    snprintf(path, sizeof path, "%s/povray", bin);
    f = fopen(path, "w");
    fputs("#!/bin/sh\ncase \"$1\" in --version) echo 'POV-Ray 3.7.0.10.fake'; exit 0;; esac\n"
          "echo 'fake povray: parse error' >&2; exit 1\n",
          f);
    fclose(f);
    chmod(path, 0755);
    assert_int_equal(sh_exec(err, sizeof err,
                             "PATH='%s':\"$PATH\" %s fit scenes/d3d9_glass.yaml --small --no-cache "
                             "--out %s/failing",
                             bin, cli_bin(), tmp_dir),
                     1);
    assert_non_null(strstr(err, "povray validate job failed"));
    snprintf(rec, sizeof rec, "%s/failing/d3d9_glass/fit.json", tmp_dir);
    cJSON *j = read_json(rec);
    cJSON *fit0 = cJSON_GetArrayItem(cJSON_GetObjectItem(j, "fits"), 0);
    assert_string_equal(cJSON_GetObjectItem(fit0, "status")->valuestring, "error");
    cJSON_Delete(j);
}

/* One real fit: d3d9_glass small against real POV-Ray (exact Fresnel). The as-authored NRMSE
 * must be the validate comparison's surface NRMSE as compare.c computes it from the same
 * images, and the fit must improve on it. */
static void test_cli_real_fit(void **state)
{
    (void)state;
    char err[2048];
    int rc = cli_exec(err, sizeof err, "fit scenes/d3d9_glass.yaml --small --no-cache --out %s/real", tmp_dir);
    assert_int_equal(rc, 0);
    assert_int_equal(cli_exec(err, sizeof err,
                              "run scenes/d3d9_glass.yaml --renderer raster --role validate --small --no-cache "
                              "--out %s/real",
                              tmp_dir),
                     0);
    /* the twins are not rendered: compare says error for them (exit 1) and measures the validate */
    cli_exec(err, sizeof err, "compare scenes/d3d9_glass.yaml --run %s/real", tmp_dir);
    char path[300];
    snprintf(path, sizeof path, "%s/real/d3d9_glass/fit.json", tmp_dir);
    cJSON *fit = read_json(path);
    snprintf(path, sizeof path, "%s/real/d3d9_glass/compare.json", tmp_dir);
    cJSON *cmp = read_json(path);
    cJSON *f0 = cJSON_GetArrayItem(cJSON_GetObjectItem(fit, "fits"), 0);
    assert_string_equal(cJSON_GetObjectItem(f0, "status")->valuestring, "ok");
    double authored = cJSON_GetObjectItem(cJSON_GetObjectItem(f0, "authored"), "nrmse")->valuedouble;
    double best = cJSON_GetObjectItem(cJSON_GetObjectItem(f0, "best"), "nrmse")->valuedouble;
    const cJSON *c;
    double surface = -1.0;
    cJSON_ArrayForEach(c, cJSON_GetObjectItem(cmp, "comparisons"))
    {
        if (strcmp(cJSON_GetObjectItem(c, "id")->valuestring, "raster-vs-povray-validate") == 0)
            surface = cJSON_GetObjectItem(cJSON_GetObjectItem(cJSON_GetObjectItem(c, "regions"), "surface"), "nrmse")
                          ->valuedouble;
    }
    close_rel(authored, surface, 1e-9);
    assert_true(best < authored);
    cJSON *p0 = cJSON_GetArrayItem(cJSON_GetObjectItem(f0, "parameters"), 0);
    assert_string_equal(cJSON_GetObjectItem(p0, "name")->valuestring, "p");
    double pf = cJSON_GetObjectItem(p0, "fitted")->valuedouble;
    assert_true(pf >= 2.5 && pf <= 3.5);
    cJSON_Delete(fit);
    cJSON_Delete(cmp);
}

/* The first *.exr in a folder's subfolders (a job cache entry), into out; 0 if none. */
static int find_exr(const char *dir, char *out, size_t len)
{
    char cmd[600];
    snprintf(cmd, sizeof cmd, "ls %s/*/*.exr 2>/dev/null | head -1", dir);
    FILE *f = popen(cmd, "r");
    if (f == NULL)
        return 0;
    int ok = fgets(out, (int)len, f) != NULL;
    pclose(f);
    if (ok)
        out[strcspn(out, "\n")] = '\0';
    return ok && out[0];
}

/* The fit's reference_job of OUT/reuse/fit.json's first fit. */
static cJSON *reference_job(const char *out, cJSON **doc)
{
    char rec[400];
    snprintf(rec, sizeof rec, "%s/reuse/fit.json", out);
    *doc = read_json(rec);
    cJSON *f0 = cJSON_GetArrayItem(cJSON_GetObjectItem(*doc, "fits"), 0);
    cJSON *job = cJSON_GetObjectItem(f0, "reference_job");
    assert_non_null(job);
    return job;
}

/* Issue 26: the fit reads a run's validate image, which the job cache hands back. It used to run
 * the job again as a cache hit and rewrite the run's record (cached, slurm null): the Slurm job
 * that rendered the reference was lost. Now the run's record stays as it was, byte for byte,
 * and the fit's record names it with its Slurm job and node. Control: a fit with no run record
 * runs the job itself (a cache hit, no Slurm id). */
static void test_cli_fit_keeps_the_reference_job(void **state)
{
    (void)state;
    char scene_path[300], cache[300], run[300], err[4096];
    snprintf(scene_path, sizeof scene_path, "%s/reuse.yaml", tmp_dir);
    snprintf(cache, sizeof cache, "%s/reusecache", tmp_dir);
    snprintf(run, sizeof run, "%s/reuserun", tmp_dir);
    FILE *f = fopen(scene_path, "w");
    assert_non_null(f);
    fputs("name: reuse\nimage: {width: 24, height: 16, supersample: 1}\n"
          "camera: {eye: [0, 0.3, 3.2], target: [0, 0, 0], hfov: 45}\n"
          "environment: {constant: [0.8, 0.9, 1.0]}\n"
          "materials:\n  glass: {albedo: [0, 0, 0], ior: 1.5, roughness: 0, model: d3d9client, d3d9client: {p: 3}}\n"
          "objects:\n  - {shape: sphere, radius: 1, tessellation: 16, material: glass}\n"
          "comparisons:\n  - {reference: exact, role: validate}\n",
          f);
    fclose(f);
    const char *no_slurm = "env -u SLURM_JOB_ID -u SLURM_ARRAY_JOB_ID -u SLURM_ARRAY_TASK_ID -u SLURM_STEP_ID "
                           "-u SLURMD_NODENAME";
    assert_int_equal(sh_exec(err, sizeof err,
                             "%s SLURM_JOB_ID=4242 SLURM_ARRAY_JOB_ID=4240 SLURM_ARRAY_TASK_ID=2 SLURMD_NODENAME=n2 "
                             "%s run %s --renderer exact --role validate --cache %s --out %s",
                             no_slurm, cli_bin(), scene_path, cache, run),
                     0);
    char record[400];
    snprintf(record, sizeof record, "%s/reuse/exact-validate.json", run);
    size_t n0, n1;
    char *before = fileio_read_all(record, &n0);
    assert_non_null(before);
    assert_int_equal(sh_exec(err, sizeof err, "%s %s fit %s --cache %s --out %s --max-evals 4", no_slurm, cli_bin(),
                             scene_path, cache, run),
                     0);
    char *after = fileio_read_all(record, &n1);
    assert_non_null(after);
    assert_true(n0 == n1 && memcmp(before, after, n0) == 0);
    cJSON *run_rec = cJSON_Parse(before);
    free(before);
    free(after);
    cJSON *doc, *job = reference_job(run, &doc);
    assert_string_equal(cJSON_GetObjectItem(job, "record")->valuestring, record);
    assert_true(cJSON_IsTrue(cJSON_GetObjectItem(job, "reused")));
    assert_true(cJSON_IsFalse(cJSON_GetObjectItem(job, "cached")));
    assert_string_equal(cJSON_GetObjectItem(job, "key")->valuestring, cJSON_GetObjectItem(run_rec, "key")->valuestring);
    cJSON *sl = cJSON_GetObjectItem(job, "slurm");
    assert_string_equal(cJSON_GetObjectItem(sl, "job_id")->valuestring, "4240_2");
    assert_string_equal(cJSON_GetObjectItem(sl, "node")->valuestring, "n2");
    cJSON_Delete(doc);
    cJSON_Delete(run_rec);

    /* Control: no run record in the fit's folder, so the fit runs the job (the cache's image). */
    snprintf(run, sizeof run, "%s/reusefresh", tmp_dir);
    assert_int_equal(sh_exec(err, sizeof err, "%s %s fit %s --cache %s --out %s --max-evals 4", no_slurm, cli_bin(),
                             scene_path, cache, run),
                     0);
    job = reference_job(run, &doc);
    assert_true(cJSON_IsFalse(cJSON_GetObjectItem(job, "reused")));
    assert_true(cJSON_IsTrue(cJSON_GetObjectItem(job, "cached")));
    assert_true(cJSON_IsNull(cJSON_GetObjectItem(job, "slurm")));
    cJSON_Delete(doc);
}

/* Issue 20 item 8: a reference holding one NaN pixel fails compare's value gate, so fit must
 * refuse it by the same rule (compare_value_gate) rather than fit to the finite pixels and
 * report ok. The reference comes through the job cache, where one R value is made NaN. */
static void test_cli_nonfinite_reference(void **state)
{
    (void)state;
    char scene_path[300], cache[300], err[4096];
    snprintf(scene_path, sizeof scene_path, "%s/nanref.yaml", tmp_dir);
    snprintf(cache, sizeof cache, "%s/nancache", tmp_dir);
    FILE *f = fopen(scene_path, "w");
    assert_non_null(f);
    fputs("name: nanref\nimage: {width: 32, height: 24, supersample: 1}\n"
          "camera: {eye: [0, 0.3, 3.2], target: [0, 0, 0], hfov: 45}\n"
          "environment: {constant: [0.8, 0.9, 1.0]}\n"
          "materials:\n  glass: {albedo: [0, 0, 0], ior: 1.5, roughness: 0, model: d3d9client, d3d9client: {p: 3}}\n"
          "objects:\n  - {shape: sphere, radius: 1, tessellation: 24, material: glass}\n"
          "comparisons:\n  - {reference: exact, role: validate}\n",
          f);
    fclose(f);
    assert_int_equal(
        cli_exec(err, sizeof err, "fit %s --cache %s --out %s/nan1 --max-evals 4", scene_path, cache, tmp_dir), 0);
    char exr_path[600];
    assert_true(find_exr(cache, exr_path, sizeof exr_path));
    exr_image img;
    assert_int_equal(exr_read(exr_path, &img, err, sizeof err), RC_OK);
    exr_channel ch[64];
    assert_true(img.n_channels <= 64);
    for (int i = 0; i < img.n_channels; i++) {
        ch[i].name = img.names[i];
        ch[i].data = img.data[i];
        if (strcmp(img.names[i], "R") == 0)
            img.data[i][(size_t)12 * 32 + 16] = NAN; /* the sphere's middle: a surface pixel */
    }
    assert_int_equal(exr_write(exr_path, img.width, img.height, ch, img.n_channels, NULL, 0, err, sizeof err), RC_OK);
    exr_image_free(&img);
    assert_int_equal(
        cli_exec(err, sizeof err, "fit %s --cache %s --out %s/nan2 --max-evals 4", scene_path, cache, tmp_dir), 1);
    assert_non_null(strstr(err, "non-finite"));
    assert_non_null(strstr(err, "nanref.yaml"));
    char rec[400];
    snprintf(rec, sizeof rec, "%s/nan2/nanref/fit.json", tmp_dir);
    cJSON *j = read_json(rec);
    cJSON *f0 = cJSON_GetArrayItem(cJSON_GetObjectItem(j, "fits"), 0);
    assert_string_equal(cJSON_GetObjectItem(f0, "status")->valuestring, "error");
    assert_non_null(strstr(cJSON_GetObjectItem(f0, "reason")->valuestring, "1 non-finite"));
    cJSON_Delete(j);
}

static const cJSON *fit_of(const cJSON *rec, const char *reference)
{
    const cJSON *f;
    cJSON_ArrayForEach(f, cJSON_GetObjectItem(rec, "fits"))
    {
        if (strcmp(cJSON_GetObjectItem(f, "reference")->valuestring, reference) == 0)
            return f;
    }
    fail_msg("no fit against %s", reference);
    return NULL;
}

static double num_at(const cJSON *o, const char *a, const char *b)
{
    const cJSON *x = cJSON_GetObjectItem(o, a);
    if (b != NULL)
        x = cJSON_GetObjectItem(x, b);
    if (!cJSON_IsNumber(x))
        fail_msg("%s%s%s is not a number", a, b ? "." : "", b ? b : "");
    return x->valuedouble;
}

/* Issue 21 item 3: the fit finds the best fit, not the first basin. d3d9_glass small, wide
 * bounds: the local search from p = 3 stops at NRMSE 0.303 against both references (p = 3.76),
 * where the basin at p = 4.5 holds 0.087. And a fit against one reference is no worse than the
 * fit against a reference that agrees with it plus their agree distance (the triangle
 * inequality: the best point for one is a candidate for the other), here POV-Ray and
 * noise-free exact_point (at our own sample positions, as POV-Ray), whose distance is measured over
 * the raster's surface by diff. */
static void test_cli_global_fit(void **state)
{
    (void)state;
    char err[4096], path[400], scn[400];
    /* The scene with its exact validate at our own sample positions (exact_point), as POV-Ray
     * samples: against the pixel-integral exact the raster's 4 x 4 sampling of the reflected sun
     * stays in every fit (1.54 at best, small), which no parameter can fit away. */
    snprintf(scn, sizeof scn, "%s/glass.yaml", tmp_dir);
    char *text = NULL;
    size_t len = 0;
    FILE *in = fopen("scenes/d3d9_glass.yaml", "r"), *mem = open_memstream(&text, &len);
    assert_non_null(in);
    assert_non_null(mem);
    char line[1024], envdir[600];
    assert_non_null(realpath("scenes/envs", envdir));
    while (fgets(line, sizeof line, in) != NULL) {
        char *env = strstr(line, "image: envs/");
        if (env != NULL)
            fprintf(mem, "%.*simage: %s/%s", (int)(env - line), line, envdir, env + strlen("image: envs/"));
        else if (strcmp(line, "  - reference: exact\n") == 0)
            fputs("  - reference: exact_point\n", mem);
        else
            fputs(line, mem);
    }
    fclose(in);
    fclose(mem);
    FILE *out_scn = fopen(scn, "w");
    assert_non_null(out_scn);
    fputs(text, out_scn);
    fclose(out_scn);
    assert_non_null(strstr(text, "reference: exact_point"));
    free(text);
    assert_int_equal(cli_exec(err, sizeof err, "fit %s --small --bounds wide --no-cache --out %s/g", scn, tmp_dir), 0);
    snprintf(path, sizeof path, "%s/g/d3d9_glass/fit-wide.json", tmp_dir);
    cJSON *rec = read_json(path);
    const cJSON *fp = fit_of(rec, "povray"), *fe = fit_of(rec, "exact_point");
    double bp = num_at(fp, "best", "nrmse"), be = num_at(fe, "best", "nrmse");
    /* 0.12: the brief's bar for the full-size fit, well under the local optimum's 0.303 */
    assert_true(bp < 0.12);
    assert_true(be < 0.12);
    const cJSON *g = cJSON_GetObjectItem(fp, "global");
    assert_true(num_at(g, "screen_points", NULL) >= 12);
    assert_true(cJSON_GetArraySize(cJSON_GetObjectItem(g, "starts")) >= 2);
    const cJSON *q;
    cJSON_ArrayForEach(q, cJSON_GetObjectItem(fp, "parameters"))
    {
        double u = num_at(q, "uncertainty", NULL);
        assert_true(u > 0.0 && u < num_at(q, "hi", NULL) - num_at(q, "lo", NULL));
        assert_true(num_at(q, "spread_lo", NULL) <= num_at(q, "fitted", NULL));
        assert_true(num_at(q, "spread_hi", NULL) >= num_at(q, "fitted", NULL));
    }

    /* the agree distance: exact against POV-Ray over the raster's surface pixels */
    assert_int_equal(cli_exec(err, sizeof err, "run %s --renderer raster --role validate --small --no-cache --out %s/g",
                              scn, tmp_dir),
                     0);
    char out[400];
    snprintf(out, sizeof out, "%s/g/agree.json", tmp_dir);
    /* the value gate passes on both (exit 0): the images are finite and >= 0 */
    assert_int_equal(sh_exec(err, sizeof err, "%s diff %s %s --mask %s/g/d3d9_glass/raster-validate.exr > %s",
                             cli_bin(), cJSON_GetObjectItem(fe, "reference_exr")->valuestring,
                             cJSON_GetObjectItem(fp, "reference_exr")->valuestring, tmp_dir, out),
                     0);
    cJSON *agree = read_json(out);
    double d = num_at(agree, "surface", "nrmse");
    assert_true(d > 0.0 && d < 0.05);
    /* The NRMSEs are over each reference's own mean, which differ by about d; 2 % of the fit's
     * NRMSE covers that normalisation (d's order, 0.3 %) and the crease pixels POV-Ray's mask
     * leaves out, many times over, while the local optimum (0.303 against 0.087) fails it. */
    assert_true(bp <= (be + d) * 1.02);
    assert_true(be <= (bp + d) * 1.02);
    cJSON_Delete(agree);
    cJSON_Delete(rec);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_recovers_d3d9client_p),
        cmocka_unit_test(test_wide_bounds_reach_beyond_the_seed),
        cmocka_unit_test(test_recovers_blinn_phong),
        cmocka_unit_test(test_recovers_ct_m_per_material),
        cmocka_unit_test(test_measures_by_hand_and_budget),
        cmocka_unit_test(test_reused_layers_same_result),
        cmocka_unit_test(test_bounds_and_refusals),
        cmocka_unit_test(test_cli_errors),
        cmocka_unit_test(test_cli_real_fit),
        cmocka_unit_test(test_cli_nonfinite_reference),
        cmocka_unit_test(test_cli_fit_keeps_the_reference_job),
        cmocka_unit_test(test_cli_global_fit),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
