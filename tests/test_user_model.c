/* test_user_model.c - a user's shading model (model/user_model.h, scene/user_load.h): the
 * loader's one-line errors (missing file, missing symbol, another ABI, bad bounds, no eval, NaN
 * found by the probe), the scene file's (a parameter out of bounds, an unknown one, model user
 * without its object and the reverse), the shipped GGX example (examples/ggx/ggx.c) against
 * values worked out by hand, the rasterizer's shading path through it, and fit's parameters.
 * The shared objects are built by the Makefile into USER_MODELS_DIR (the build folder). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "check.h"

#include "fit.h"
#include "scene_file.h"
#include "shade.h"
#include "stability.h"
#include "user_load.h"

#ifndef USER_MODELS_DIR
#define USER_MODELS_DIR "build"
#endif
#define GGX_SO     USER_MODELS_DIR "/examples/ggx/ggx.so"
#define FIXTURE(n) USER_MODELS_DIR "/tests/user_models/" n ".so"

/* A message is one line that names the file and, where given, contains the words expected. */
static void expect_message(const char *err, const char *file, const char *a, const char *b)
{
    if (strchr(err, '\n') != NULL)
        fail_msg("message spans lines: %s", err);
    if (strstr(err, file) == NULL || (a && strstr(err, a) == NULL) || (b && strstr(err, b) == NULL))
        fail_msg("message '%s' lacks '%s', '%s' or '%s'", err, file, a ? a : "", b ? b : "");
}

static void test_load_ggx(void **state)
{
    (void)state;
    const reflcheck_user_model *m;
    char err[1024] = "";
    assert_int_equal(user_model_load(GGX_SO, &m, err, sizeof err), RC_OK);
    assert_string_equal(m->name, "ggx");
    assert_int_equal(m->n_params, 2);
    int r = user_model_param_index(m, "roughness"), f = user_model_param_index(m, "f0");
    assert_true(r >= 0 && f >= 0);
    assert_int_equal(user_model_param_index(m, "nope"), -1);
    assert_true(m->params[r].log_scale && m->params[r].lo > 0.0);
    /* The same file twice: the same description (dlopen counts references). */
    const reflcheck_user_model *again;
    assert_int_equal(user_model_load(GGX_SO, &again, err, sizeof err), RC_OK);
    assert_ptr_equal(m, again);
    double v[REFLCHECK_USER_PARAMS_MAX];
    user_model_defaults(m, v);
    assert_int_equal(user_model_probe(m, GGX_SO, v, err, sizeof err), RC_OK);
}

static void test_load_errors(void **state)
{
    (void)state;
    const reflcheck_user_model *m = (const reflcheck_user_model *)1;
    char err[1024];
    assert_int_equal(user_model_load(FIXTURE("missing"), &m, err, sizeof err), RC_ERR_IO);
    assert_null(m);
    expect_message(err, "missing.so", "cannot load", "cc -shared");
    assert_int_equal(user_model_load(FIXTURE("no_entry"), &m, err, sizeof err), RC_ERR_PARSE);
    expect_message(err, "no_entry.so", REFLCHECK_USER_ENTRY, "export");
    assert_int_equal(user_model_load(FIXTURE("abi_2"), &m, err, sizeof err), RC_ERR_RANGE);
    expect_message(err, "abi_2.so", "ABI 2", "rebuild");
    assert_int_equal(user_model_load(FIXTURE("bad_bounds"), &m, err, sizeof err), RC_ERR_PARSE);
    expect_message(err, "bad_bounds.so", "'gain'", "default 2");
    assert_int_equal(user_model_load(FIXTURE("null_eval"), &m, err, sizeof err), RC_ERR_PARSE);
    expect_message(err, "null_eval.so", "no eval function", NULL);
    /* A name without '/' is never searched for on the library path: ./name only. */
    assert_int_equal(user_model_load("libm.so.6", &m, err, sizeof err), RC_ERR_IO);
}

static void test_probe_finds_nan(void **state)
{
    (void)state;
    const reflcheck_user_model *m;
    char err[1024];
    assert_int_equal(user_model_load(FIXTURE("nan"), &m, err, sizeof err), RC_OK);
    double v[1] = {1.0};
    assert_int_equal(user_model_probe(m, FIXTURE("nan"), v, err, sizeof err), RC_ERR_RANGE);
    expect_message(err, "nan.so", "NaN", "gain=1");
    assert_int_equal(user_model_check_value(m, "x.so", 0, 2.5, err, sizeof err), RC_ERR_RANGE);
    expect_message(err, "x.so", "'gain' = 2.5", "[0, 2]");
    assert_int_equal(user_model_check_value(m, "x.so", 0, 2.0, err, sizeof err), RC_OK);
}

/* A scene of one GGX sphere; user_text is the material's user line. */
static rc_status parse_with(const char *model, const char *user_text, scene *s, char *err, size_t errlen)
{
    char text[2048];
    snprintf(text, sizeof text,
             "name: t\nimage: {width: 16, height: 8}\ncamera: {eye: [0, 0, 3], target: [0, 0, 0], hfov: 40}\n"
             "lights:\n  - {type: sun, direction: [0, -1, 0], irradiance: [2, 2, 2]}\n"
             "materials:\n  m:\n    albedo: [0.5, 0.25, 0.1]\n    model: %s\n%s"
             "objects:\n  - {shape: sphere, center: [0, 0, 0], radius: 1, material: m}\n",
             model, user_text);
    return scene_file_parse(text, strlen(text), "t.yaml", s, err, errlen);
}

static void test_scene_errors(void **state)
{
    (void)state;
    static scene s;
    char err[2048];
    assert_int_equal(
        parse_with("user", "    user: {path: " GGX_SO ", params: {roughness: 0.5, f0: 0.2}}\n", &s, err, sizeof err),
        RC_OK);
    assert_int_equal(s.materials[0].model, MODEL_USER);
    close_rel(s.materials[0].user.params[1], 0.2, 0);
    /* Out of its declared bounds [0.03, 1]: the scene's line, the parameter and the bounds. */
    assert_int_equal(
        parse_with("user", "    user: {path: " GGX_SO ", params: {roughness: 1.5}}\n", &s, err, sizeof err),
        RC_ERR_RANGE);
    expect_message(err, "t.yaml:10:", "'roughness' = 1.5", "[0.03, 1]");
    assert_int_equal(parse_with("user", "    user: {path: " GGX_SO ", params: {rough: 0.5}}\n", &s, err, sizeof err),
                     RC_ERR_PARSE);
    expect_message(err, "t.yaml", "unknown key", "roughness, f0");
    assert_int_equal(parse_with("user", "", &s, err, sizeof err), RC_ERR_PARSE);
    expect_message(err, "t.yaml", "model user needs", "user: {path:");
    assert_int_equal(parse_with("d3d", "    user: {path: " GGX_SO "}\n", &s, err, sizeof err), RC_ERR_PARSE);
    expect_message(err, "t.yaml", "model user only", NULL);
    assert_int_equal(parse_with("user", "    user: {path: " FIXTURE("abi_2") "}\n", &s, err, sizeof err), RC_ERR_RANGE);
    expect_message(err, "t.yaml:10:", "abi_2.so", "ABI 2");
    assert_int_equal(parse_with("user", "    user: {path: " FIXTURE("nan") "}\n", &s, err, sizeof err), RC_ERR_RANGE);
    expect_message(err, "nan.so", "NaN", "fix the model");
    assert_int_equal(parse_with("user", "    user: {path: nowhere/x.so}\n", &s, err, sizeof err), RC_ERR_IO);
    expect_message(err, "x.so", NULL, NULL);
}

/* The GGX example at one configuration: N = +Z, V and L given. */
static reflcheck_user_output ggx_at(double roughness, double f0, dvec3 v, dvec3 l)
{
    const reflcheck_user_model *m;
    char err[1024];
    assert_int_equal(user_model_load(GGX_SO, &m, err, sizeof err), RC_OK);
    double p[2];
    p[user_model_param_index(m, "roughness")] = roughness;
    p[user_model_param_index(m, "f0")] = f0;
    reflcheck_user_output o;
    assert_int_equal(user_model_eval(m, p, dv3(0, 0, 1), dv3_norm(v), dv3_norm(l), dv3(0.5, 0.25, 0.1), &o), 1);
    return o;
}

/* Karis 2013 by hand, f = D F G / (4 N.L N.V), alpha = r^2, k = alpha/2:
 * 1. r 0.5 (alpha 0.25), N = V = L: N.H = 1, D = 1/(pi alpha^2) = 1/(pi 0.0625) = 5.0929582;
 *    G1(1) = 1; F(1) = F0 = 0.04: f = 5.0929582 * 0.04 / 4 = 0.050929582.
 * 2. r 0.5, V and L at 60 degrees on opposite sides: N.H = 1, D as above, V.H = 0.5,
 *    k = 0.125: G1(0.5) = 0.5 / (0.5 * 0.875 + 0.125) = 8/9, G = 64/81;
 *    F = 0.04 + 0.96 * 0.5^5 = 0.07; f = 5.0929582 * 0.07 * (64/81) / (4 * 0.25) = 0.28168460.
 * 3. r 1 (alpha 1: D = 1/pi at every N.H), V = N, L = (0.8, 0, 0.6): H = (0.8, 0, 1.6)/sqrt(3.2),
 *    N.H = V.H = 0.89442719; k = 0.5: G1(0.6) = 0.6/0.8 = 0.75, G1(1) = 1;
 *    F = 0.04 + 0.96 (0.10557281)^5 = 0.04001259; f = 0.04001259 * 0.75 / (pi * 4 * 0.6) = 0.0039801259.
 * Diffuse: albedo / pi per channel, whatever the angles. */
static void test_ggx_hand_points(void **state)
{
    (void)state;
    reflcheck_user_output o = ggx_at(0.5, 0.04, dv3(0, 0, 1), dv3(0, 0, 1));
    for (int c = 0; c < 3; c++)
        close_rel(o.specular[c], 0.050929582, 1e-7);
    close_rel(o.diffuse[0], 0.5 / TEST_PI, 1e-12);
    close_rel(o.diffuse[1], 0.25 / TEST_PI, 1e-12);
    close_rel(o.diffuse[2], 0.1 / TEST_PI, 1e-12);
    double s60 = sqrt(3.0) / 2.0;
    o = ggx_at(0.5, 0.04, dv3(s60, 0, 0.5), dv3(-s60, 0, 0.5));
    close_rel(o.specular[0], 0.28168460, 1e-7);
    o = ggx_at(1.0, 0.04, dv3(0, 0, 1), dv3(0.8, 0, 0.6));
    close_rel(o.specular[1], 0.0039801259, 1e-7);
    /* Behind the surface: eval is not called, the BRDF is 0. */
    const reflcheck_user_model *m;
    char err[256];
    assert_int_equal(user_model_load(GGX_SO, &m, err, sizeof err), RC_OK);
    double p[2] = {0.5, 0.04};
    assert_int_equal(user_model_eval(m, p, dv3(0, 0, 1), dv3(0, 0, 1), dv3(1, 0, -0.1), dv3(1, 1, 1), &o), 0);
    assert_true(o.specular[0] == 0.0 && o.diffuse[0] == 0.0);
}

/* The rasterizer's path (shade.c): a sun of E = 2 straight down on N = V = +Y: diffuse
 * albedo/pi * 2, specular 0.050929582 * 2 (hand point 1), no reflection, path "user". */
static void test_shade_path(void **state)
{
    (void)state;
    static scene s;
    char err[2048];
    assert_int_equal(
        parse_with("user", "    user: {path: " GGX_SO ", params: {roughness: 0.5, f0: 0.04}}\n", &s, err, sizeof err),
        RC_OK);
    shade_context c;
    shade_context_make(&s, NULL, &c);
    shade_plan p;
    shade_plan_make(&c, &s.materials[0], &p);
    assert_string_equal(p.path, "user");
    shade_terms t;
    shade_eval(&c, &p, v3(0, 1, 0), v3(0, 1, 0), v3(0, 1, 0), &t);
    close_rel(t.diffuse.x, 2.0 * 0.5 / TEST_PI, 1e-6);
    close_rel(t.diffuse.z, 2.0 * 0.1 / TEST_PI, 1e-6);
    close_rel(t.specular.y, 2.0 * 0.050929582, 1e-6);
    assert_true(t.reflection.x == 0.0f);
    /* The batch form takes it lane by lane: the same terms. */
    shade_batch_in in = {.n = 1};
    shade_batch_out out;
    shade_batch_set_input(&in, 0, v3(0, 1, 0), v3(0, 1, 0), v3(0, 1, 0));
    shade_eval_n(&c, &p, &in, &out);
    assert_true(out.specular.y[0] == t.specular.y && out.diffuse.x[0] == t.diffuse.x);
}

/* fit: the model's own parameters, bounds and scales, named as the model names them. */
static void test_fit_params(void **state)
{
    (void)state;
    static scene s;
    char err[2048];
    assert_int_equal(
        parse_with("user", "    user: {path: " GGX_SO ", params: {roughness: 0.4, f0: 0.1}}\n", &s, err, sizeof err),
        RC_OK);
    fit_param p[FIT_MAX_PARAMS];
    assert_int_equal(fit_default_params(&s, FIT_BOUNDS_SEED, p, FIT_MAX_PARAMS), 2);
    assert_string_equal(fit_param_label(&s, &p[0]), "roughness");
    assert_string_equal(fit_param_label(&s, &p[1]), "f0");
    close_rel(p[0].lo, 0.03, 0);
    close_rel(p[0].hi, 1.0, 0);
    assert_true(p[0].log_scale && !p[1].log_scale);
    close_rel(p[0].authored, 0.4, 0);
    double v[2] = {0.7, 0.3};
    fit_apply(&s, p, 2, v);
    close_rel(s.materials[0].user.params[0], 0.7, 0);
    close_rel(s.materials[0].user.params[1], 0.3, 0);
}

/* The stability sweep of a user model: its rows, finite for the example, its albedo (Karis' G
 * and F = 1 at the smallest roughness reflect just under 1: the quadrature sees the lobe), and
 * the NaN fixture failing the gate. */
static void test_stability_rows(void **state)
{
    (void)state;
    static stability_table t;
    char err[1024];
    stability_options o = {.samples = 64, .albedo_grid = 48};
    assert_int_equal(user_model_load(GGX_SO, &o.user, err, sizeof err), RC_OK);
    assert_int_equal(stability_run(&o, &t), RC_OK);
    int rows = 0;
    for (int i = 0; i < t.n_rows; i++) {
        const stability_row *r = &t.rows[i];
        if (strcmp(r->function, "user[ggx]") != 0)
            continue;
        rows++;
        assert_true(r->nan == 0 && r->inf == 0 && r->negative == 0 && r->samples > 0);
    }
    assert_int_equal(rows, 4);
    const stability_row *al = stability_find(&t, "user[ggx]", "max directional albedo");
    assert_non_null(al);
    assert_true(al->value > 0.9 && al->value <= 1.0);
    assert_int_equal(stability_failures(&t), 0);
    assert_int_equal(user_model_load(FIXTURE("nan"), &o.user, err, sizeof err), RC_OK);
    assert_int_equal(stability_run(&o, &t), RC_OK);
    const stability_row *g = stability_find(&t, "user[fixture]", "grazing");
    assert_non_null(g);
    assert_true(g->nan > 0);
    assert_true(stability_failures(&t) >= 1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_load_ggx),        cmocka_unit_test(test_load_errors),
        cmocka_unit_test(test_probe_finds_nan), cmocka_unit_test(test_scene_errors),
        cmocka_unit_test(test_ggx_hand_points), cmocka_unit_test(test_shade_path),
        cmocka_unit_test(test_fit_params),      cmocka_unit_test(test_stability_rows),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
