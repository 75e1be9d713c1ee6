/* test_exact.c - the exact reference renderer and its physical model, against closed forms
 * computed here by other formulas than model/formula.h's:
 *   - the Beckmann lobe at one (N, V, L) by hand: D from tan and cos, Smith G1 through the
 *     Lambda form 1/(1 + Lambda), the dielectric Fresnel in Walter et al.'s g-form, the
 *     conductor Fresnel with complex arithmetic (Snell's law in <complex.h>);
 *   - energy: a dielectric's R + T = 1 with T from the transmission amplitudes; the lobe's
 *     furnace (its directional albedo by quadrature over the hemisphere: <= 1 with F = 1, and
 *     near F(0) with the exact Fresnel at a small roughness);
 *   - whole renders through the registry entry: a Lambert plane under a sun (rho E cos / pi in
 *     every covered pixel), a mirror conductor in a constant environment (L F(N.V) at the
 *     centre), and the refusals (twin, a rough lobe under an environment).
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <cjson/cJSON.h>
#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "compare.h"
#include "jobs.h"
#include "exr.h"
#include "frame.h"
#include "mesh.h"
#include "physical.h"
#include "render.h"
#include "renderers/exact/exact.h"
#include "renderers/registry.h"
#include "scene_file.h"

/* ---- second formulas ------------------------------------------------------------------ */

/* Dielectric Fresnel, Walter et al. 2007 eq. 22: g = sqrt(n^2 - 1 + c^2). */
static double ref_fresnel_dielectric(double c, double n)
{
    double g2 = n * n - 1.0 + c * c;
    if (g2 < 0.0)
        return 1.0;
    double g = sqrt(g2);
    double a = (g - c) / (g + c), b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0);
    return 0.5 * a * a * (1.0 + b * b);
}

/* Conductor Fresnel from the complex amplitudes: cos_t = sqrt(1 - sin^2 / n^2), n = eta + ik. */
static double ref_fresnel_conductor(double c, double eta, double k)
{
    double complex n = eta + k * I;
    double s2 = 1.0 - c * c;
    double complex ct = csqrt(1.0 - s2 / (n * n));
    double complex rs = (c - n * ct) / (c + n * ct);
    double complex rp = (n * c - ct) / (n * c + ct);
    return 0.5 * (creal(rs * conj(rs)) + creal(rp * conj(rp)));
}

/* Smith G1 for Beckmann through Lambda: a = 1/(m tan), Lambda = (erf(a) - 1)/2 + exp(-a^2)/(2 a sqrt(pi)). */
static double ref_g1(double c, double m)
{
    double a = c / (m * sqrt(1.0 - c * c));
    double lambda = 0.5 * (erf(a) - 1.0) + exp(-a * a) / (2.0 * a * sqrt(TEST_PI));
    return 1.0 / (1.0 + lambda);
}

static double ref_beckmann(double n_h, double m)
{
    double t2 = (1.0 - n_h * n_h) / (n_h * n_h);
    return exp(-t2 / (m * m)) / (TEST_PI * m * m * pow(n_h, 4));
}

static dvec3 unit(double x, double y, double z) { return dv3_norm(dv3(x, y, z)); }

/* ---- the lobe and the Fresnel ------------------------------------------------------------ */

static void test_lobe_by_hand(void **state)
{
    (void)state;
    material mat;
    material_init(&mat);
    mat.roughness = 0.3f;
    mat.ior = 1.5f;
    dvec3 n = dv3(0, 0, 1), v = unit(0.3, 0.1, 0.8), l = unit(-0.4, 0.2, 0.7);
    dvec3 h = dv3_norm(dv3_add(v, l));
    double n_v = dv3_dot(n, v), n_l = dv3_dot(n, l), n_h = dv3_dot(n, h), v_h = dv3_dot(v, h);
    double m = 0.3f; /* the float roughness the material holds */
    double common = ref_beckmann(n_h, m) * ref_g1(n_v, m) * ref_g1(n_l, m) / (4.0 * n_v);
    dvec3 got = physical_lobe(&mat, PHYS_FRESNEL_EXACT, n, v, l);
    /* Double arithmetic on both sides, different orders: a few ulps of erf/exp. */
    close_rel(got.x, common * ref_fresnel_dielectric(v_h, 1.5f), 1e-12);
    close_rel(physical_lobe(&mat, PHYS_FRESNEL_NV, n, v, l).y, common * ref_fresnel_dielectric(n_v, 1.5f), 1e-12);
    close_rel(physical_lobe(&mat, PHYS_FRESNEL_ONE, n, v, l).z, common, 1e-12);
    double f0 = (0.5 / 2.5) * (0.5 / 2.5);
    close_rel(physical_lobe(&mat, PHYS_FRESNEL_SCHLICK, n, v, l).x, common * (f0 + (1 - f0) * pow(1 - v_h, 5)), 1e-12);

    /* Aluminium: per channel, the complex-amplitude Fresnel of V.H. */
    mat.conductor = 1;
    mat.eta = v3(1.66f, 0.88f, 0.52f);
    mat.k = v3(9.22f, 6.27f, 4.84f);
    got = physical_lobe(&mat, PHYS_FRESNEL_EXACT, n, v, l);
    close_rel(got.x, common * ref_fresnel_conductor(v_h, 1.66f, 9.22f), 1e-12);
    close_rel(got.y, common * ref_fresnel_conductor(v_h, 0.88f, 6.27f), 1e-12);
    close_rel(got.z, common * ref_fresnel_conductor(v_h, 0.52f, 4.84f), 1e-12);

    /* Below the horizon on either side: nothing. */
    assert_true(physical_lobe(&mat, PHYS_FRESNEL_EXACT, n, v, unit(0.5, 0, -0.1)).x == 0.0);
    assert_true(physical_lobe(&mat, PHYS_FRESNEL_EXACT, n, unit(0.5, 0, -0.1), l).x == 0.0);
}

static void test_fresnel_second_formula_and_energy(void **state)
{
    (void)state;
    material d;
    material_init(&d);
    d.ior = 1.5f;
    for (int i = 0; i <= 100; i++) {
        double c = i / 100.0;
        double r = physical_fresnel_exact(&d, c).x;
        if (c > 0.0)
            close_rel(r, ref_fresnel_dielectric(c, 1.5f), 1e-12);
        /* R + T = 1: T_s,p = (n cos_t / cos_i) t^2 with t_s = 2 ci/(ci + n ct), t_p = 2 ci/(n ci + ct). */
        if (c > 0.0) {
            double n = 1.5f, ct = sqrt(1.0 - (1.0 - c * c) / (n * n));
            double ts = 2.0 * c / (c + n * ct), tp = 2.0 * c / (n * c + ct);
            double t = 0.5 * (n * ct / c) * (ts * ts + tp * tp);
            close_rel(r + t, 1.0, 1e-13);
        }
    }
    material a = d;
    a.conductor = 1;
    a.eta = v3(0.166f, 0.424f, 1.468f); /* gold */
    a.k = v3(3.15f, 2.36f, 1.80f);
    for (int i = 0; i <= 100; i++) {
        double c = i / 100.0;
        dvec3 r = physical_fresnel_exact(&a, c);
        if (c > 0.0) {
            close_rel(r.x, ref_fresnel_conductor(c, 0.166f, 3.15f), 1e-12);
            close_rel(r.z, ref_fresnel_conductor(c, 1.468f, 1.80f), 1e-12);
        }
        assert_true(r.x > 0.0 && r.x <= 1.0);
    }
}

/* The lobe's directional albedo: integral of f cos over the light's hemisphere, by the midpoint
 * rule in (cos theta, phi). */
static double lobe_albedo(const material *mat, physics_fresnel f, dvec3 v)
{
    const int nt = 2000, np = 400;
    double sum = 0.0;
    for (int i = 0; i < nt; i++) {
        double ct = (i + 0.5) / nt, st = sqrt(1.0 - ct * ct);
        for (int j = 0; j < np; j++) {
            double ph = 2.0 * TEST_PI * (j + 0.5) / np;
            /* physical_lobe includes N.L: the albedo is its plain integral over solid angle. */
            sum += physical_lobe(mat, f, dv3(0, 0, 1), v, dv3(st * cos(ph), st * sin(ph), ct)).x;
        }
    }
    return sum * (1.0 / nt) * (2.0 * TEST_PI / np);
}

static void test_furnace(void **state)
{
    (void)state;
    material mat;
    material_init(&mat);
    mat.ior = 1.5f;
    /* F = 1: Smith masking only loses energy; at normal view and m = 0.1 it loses under 1 %
     * (the quadrature resolves the lobe: 2000 steps in cos over a lobe of width ~ m^2). */
    mat.roughness = 0.1f;
    double a = lobe_albedo(&mat, PHYS_FRESNEL_ONE, dv3(0, 0, 1));
    assert_true(a <= 1.0 + 1e-3);
    assert_true(a > 0.99);
    /* At grazing view the masking loses more, and never gains. */
    mat.roughness = 0.5f;
    double g = lobe_albedo(&mat, PHYS_FRESNEL_ONE, unit(0.95, 0, 0.3122));
    assert_true(g < 1.0 && g > 0.5);
    /* Exact Fresnel at normal view and a narrow lobe: F(V.H) stays near F(0) = 0.04. */
    mat.roughness = 0.1f;
    double e = lobe_albedo(&mat, PHYS_FRESNEL_EXACT, dv3(0, 0, 1));
    close_rel(e, a * ref_fresnel_dielectric(1.0, 1.5f), 2e-3);
}

/* ---- whole renders ---------------------------------------------------------------------- */

typedef struct {
    scene *s;
    mesh m;
    env_map env;
    float *px;
} fixture;

static void fixture_load(fixture *f, const char *text)
{
    char err[1024];
    f->s = malloc(sizeof *f->s);
    assert_non_null(f->s);
    memset(&f->m, 0, sizeof f->m);
    f->px = NULL;
    if (scene_file_parse(text, strlen(text), "exact.yaml", f->s, err, sizeof err) != RC_OK)
        fail_msg("%s", err);
    assert_int_equal(mesh_build(f->s, &f->m, err, sizeof err), RC_OK);
    assert_int_equal(frame_env_load(f->s, &f->env, &f->px, err, sizeof err), RC_OK);
}

static void fixture_free(fixture *f)
{
    free(f->px);
    mesh_free(&f->m);
    free(f->s);
}

static char tmpdir[] = "/tmp/reflcheck-exact-XXXXXX";

/* The checks below that want one value per sample position (a pixel's centre sample, k = 1 or 2
 * samples all equal) render the point-sampled variant; test_pixel_integral checks the default. */
static const exact_options point = {.point = 1};

static void render_exact(fixture *f, comparison_role role, const exact_options *o, renderer_result *r, exr_image *img)
{
    char exr[512], err[512];
    snprintf(exr, sizeof exr, "%s/out.exr", tmpdir);
    unlink(exr);
    renderer_job j = {.s = f->s,
                      .m = &f->m,
                      .env = &f->env,
                      .role = role,
                      .threads = 2,
                      .dir = tmpdir,
                      .exr = exr,
                      .log = "/dev/null",
                      .options = o};
    memset(r, 0, sizeof *r);
    registry_row(registry_find("exact"))->render(&j, r);
    if (img != NULL && r->status == RUNNER_OK && exr_read(exr, img, err, sizeof err) != RC_OK)
        fail_msg("%s", err);
}

static void test_render_lambert_sun(void **state)
{
    (void)state;
    /* A plane seen from above under a sun at 60 degrees from the normal: every covered pixel is
     * rho E cos(60) / pi, whatever the sample positions. */
    fixture f;
    fixture_load(&f, "image: {width: 24, height: 16, supersample: 2}\n"
                     "camera: {eye: [0, 3, 0.01], target: [0, 0, 0], hfov: 40}\n"
                     "lights:\n  - {type: sun, direction: [0.8660254037844386, -0.5, 0], irradiance: [2, 3, 4]}\n"
                     "materials:\n  m: {albedo: [0.5, 0.25, 0.75], roughness: 0, model: d3d9client}\n"
                     "objects:\n  - {shape: quad, size: [20, 20], material: m}\n");
    renderer_result r;
    exr_image img = {0};
    render_exact(&f, ROLE_VALIDATE, &point, &r, &img);
    assert_int_equal(r.status, RUNNER_OK);
    const float *R = exr_image_channel(&img, "R"), *G = exr_image_channel(&img, "G"), *B = exr_image_channel(&img, "B");
    assert_non_null(R);
    /* E cos as the float sun direction gives it; the sums are double, the output float. */
    double cosl = 0.5f / sqrt(0.8660254037844386f * 0.8660254037844386f + 0.25);
    for (int i = 0; i < img.width * img.height; i++) {
        close_rel(R[i], 0.5f * 2.0 * cosl / TEST_PI, 1e-6);
        close_rel(G[i], 0.25f * 3.0 * cosl / TEST_PI, 1e-6);
        close_rel(B[i], 0.75f * 4.0 * cosl / TEST_PI, 1e-6);
    }
    exr_image_free(&img);
    fixture_free(&f);
}

static void test_render_point_and_mirror(void **state)
{
    (void)state;
    /* A gold mirror sphere in a constant environment: the centre pixel looks straight at it, so
     * reflection = L F_gold(1); a point light adds nothing to a mirror (its delta lobe). */
    fixture f;
    fixture_load(&f, "image: {width: 33, height: 33, supersample: 1}\n"
                     "camera: {eye: [0, 0, 5], target: [0, 0, 0], hfov: 30}\n"
                     "environment: {constant: [1.5, 1.0, 0.5]}\n"
                     "lights:\n  - {type: point, position: [0, 0, 4], intensity: [100, 100, 100]}\n"
                     "materials:\n  gold: {conductor: {eta: [0.166, 0.424, 1.468], k: [3.15, 2.36, 1.80]},\n"
                     "    roughness: 0, model: d3d9client}\n"
                     "objects:\n  - {shape: sphere, radius: 1, tessellation: 64, material: gold}\n");
    renderer_result r;
    exr_image img = {0};
    render_exact(&f, ROLE_VALIDATE, &point, &r, &img);
    assert_int_equal(r.status, RUNNER_OK);
    int c = 16 * 33 + 16;
    /* The centre sample's normal is the tessellated sphere's at its pole: N.V = 1 to float. */
    close_rel(exr_image_channel(&img, "reflection.R")[c], 1.5 * ref_fresnel_conductor(1.0, 0.166f, 3.15f), 1e-5);
    close_rel(exr_image_channel(&img, "reflection.B")[c], 0.5 * ref_fresnel_conductor(1.0, 1.468f, 1.80f), 1e-5);
    assert_true(exr_image_channel(&img, "specular.R")[c] == 0.0f);
    assert_true(exr_image_channel(&img, "diffuse.R")[c] == 0.0f);
    exr_image_free(&img);
    fixture_free(&f);

    /* A rough dielectric under a point light straight above the view axis: the centre pixel is
     * rho I/(pi d^2) + the lobe at N = V = L (D(0) G1(1)^2 F(1) / 4 = F0 / (4 pi m^2)) I/d^2. */
    fixture_load(&f, "image: {width: 33, height: 33, supersample: 1}\n"
                     "camera: {eye: [0, 0, 5], target: [0, 0, 0], hfov: 30}\n"
                     "lights:\n  - {type: point, position: [0, 0, 3], intensity: [8, 8, 8]}\n"
                     "materials:\n  p: {albedo: [0.2, 0.4, 0.6], ior: 1.5, roughness: 0.25, model: d3d}\n"
                     "objects:\n  - {shape: sphere, radius: 1, tessellation: 64, material: p}\n");
    render_exact(&f, ROLE_VALIDATE, &point, &r, &img);
    assert_int_equal(r.status, RUNNER_OK);
    double e = 8.0 / 4.0; /* I / d^2 at distance 2 */
    close_rel(exr_image_channel(&img, "diffuse.G")[c], 0.4f * e / TEST_PI, 1e-5);
    double m = 0.25f;
    close_rel(exr_image_channel(&img, "specular.G")[c], 0.04 / (4.0 * TEST_PI * m * m) * e, 1e-4);
    exr_image_free(&img);
    fixture_free(&f);
}

static void test_render_manifest(void **state)
{
    (void)state;
    /* The manifest's switches on a plane seen from above: only the sun (light 1) reaches the
     * diffuse, the constant environment lights it too (rho L), and then the coating weight
     * 1 - F(N.V) of n = 1.5, from the centre sample's N.V (k = 1: the pixel's only sample). */
    fixture f;
    fixture_load(&f, "image: {width: 16, height: 12, supersample: 1}\n"
                     "camera: {eye: [0, 3, 0.01], target: [0, 0, 0], hfov: 40}\n"
                     "environment: {constant: [0.5, 0.5, 0.5]}\n"
                     "physics: {diffuse_lights: [1], env_diffuse: true, env_specular: false}\n"
                     "lights:\n  - {type: point, position: [0, 1, 0], intensity: [50, 50, 50]}\n"
                     "  - {type: sun, direction: [0, -1, 0], irradiance: [2, 2, 2]}\n"
                     "materials:\n  m: {albedo: [0.5, 0.5, 0.5], ior: 1.5, roughness: 0.2, model: d3d}\n"
                     "objects:\n  - {shape: quad, size: [20, 20], material: m}\n");
    renderer_result r;
    exr_image img = {0};
    render_exact(&f, ROLE_VALIDATE, &point, &r, &img);
    assert_int_equal(r.status, RUNNER_OK);
    const float *d = exr_image_channel(&img, "diffuse.G"), *nv = exr_image_channel(&img, "ndotv");
    for (int i = 0; i < img.width * img.height; i++)
        close_rel(d[i], 0.5f * (2.0 / TEST_PI + 0.5), 1e-6);
    exact_options o = {.physics = f.s->physics, .set = 1, .point = 1};
    o.physics.diffuse_weight = PHYS_DIFFUSE_ONE_MINUS_F;
    exr_image_free(&img);
    render_exact(&f, ROLE_VALIDATE, &o, &r, &img);
    assert_int_equal(r.status, RUNNER_OK);
    d = exr_image_channel(&img, "diffuse.G");
    nv = exr_image_channel(&img, "ndotv");
    for (int i = 0; i < img.width * img.height; i++)
        /* N.V of the image is float; F moves by 1e-8 per 1e-7 of N.V near normal incidence. */
        close_rel(d[i], 0.5f * (2.0 / TEST_PI + 0.5) * (1.0 - ref_fresnel_dielectric(nv[i], 1.5f)), 1e-6);
    /* The point light (light 0) still lights the lobe: specular_lights is all. */
    assert_true(exr_image_channel(&img, "specular.G")[6 * 16 + 8] > 0.0f);
    o.physics.specular_lights = 0;
    exr_image_free(&img);
    render_exact(&f, ROLE_VALIDATE, &o, &r, &img);
    assert_true(exr_image_channel(&img, "specular.G")[6 * 16 + 8] == 0.0f);
    exr_image_free(&img);
    o.physics.shadows = 1;
    render_exact(&f, ROLE_VALIDATE, &o, &r, NULL);
    assert_int_equal(r.status, RUNNER_MISSING);
    assert_non_null(strstr(r.message, "shadows"));
    fixture_free(&f);
}

/* NRMSE of test against ref over ref's surface (compare_images, as `reflcheck diff`). */
static double surface_nrmse(const char *test, const char *ref)
{
    char *buf = NULL, err[1024];
    size_t len = 0;
    int failed = 0;
    FILE *mem = open_memstream(&buf, &len);
    assert_non_null(mem);
    if (compare_images(test, ref, NULL, mem, &failed, err, sizeof err) != RC_OK)
        fail_msg("compare_images: %s", err);
    fclose(mem);
    assert_int_equal(failed, 0);
    cJSON *o = cJSON_Parse(buf);
    const cJSON *n = cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(o, "surface"), "nrmse");
    assert_true(cJSON_IsNumber(n));
    double v = cJSON_GetNumberValue(n);
    cJSON_Delete(o);
    free(buf);
    return v;
}

/* The bias of the F(N.V) tint the canonical rough-lobe scenes ask of their references (what
 * Cycles 3.4 can render) against the per-microfacet F(V.H), noise-free: both exact, small size,
 * the same samples, so the difference is the Fresnel form alone. Printed for the README. */
static void test_bias_of_nv_tint(void **state)
{
    (void)state;
    static const char *const scenes[] = {"scenes/d3d_blinn_phong.yaml", "scenes/ct_toaster.yaml",
                                         "scenes/stiff_blinn.yaml", "scenes/stiff_ct.yaml"};
    for (size_t i = 0; i < sizeof scenes / sizeof scenes[0]; i++) {
        char err[1024], tint[600], vh[600];
        fixture f = {.s = malloc(sizeof(scene))};
        assert_non_null(f.s);
        if (scene_file_load(scenes[i], f.s, err, sizeof err) != RC_OK)
            fail_msg("%s", err);
        assert_int_equal(f.s->physics.fresnel_specular, PHYS_FRESNEL_NV);
        job_apply_variant(f.s, JOB_SMALL);
        assert_int_equal(mesh_build(f.s, &f.m, err, sizeof err), RC_OK);
        assert_int_equal(frame_env_load(f.s, &f.env, &f.px, err, sizeof err), RC_OK);
        renderer_result r;
        render_exact(&f, ROLE_VALIDATE, NULL, &r, NULL);
        assert_int_equal(r.status, RUNNER_OK);
        snprintf(tint, sizeof tint, "%s/tint.exr", tmpdir);
        snprintf(vh, sizeof vh, "%s/out.exr", tmpdir);
        assert_int_equal(rename(vh, tint), 0);
        exact_options o = {.physics = f.s->physics, .set = 1};
        o.physics.fresnel_specular = PHYS_FRESNEL_EXACT;
        render_exact(&f, ROLE_VALIDATE, &o, &r, NULL);
        assert_int_equal(r.status, RUNNER_OK);
        double bias = surface_nrmse(tint, vh);
        printf("# %s: bias of the F(N.V) tint against F(V.H), noise-free NRMSE %.4f (small)\n", scenes[i], bias);
        /* A real, finite difference: the tint is not the physics, nor far from it on these lobes. */
        assert_true(bias > 0.0 && bias < 0.5);
        unlink(tint);
        fixture_free(&f);
    }
}

/* exact is a pixel integral: 16 x 16 samples per pixel, none at one of the rasterizer's k x k
 * positions, so a pixel is its box average to (k/16)^2 of the rasterizer's error where the
 * radiance varies inside it. Worked out independently: which positions coincide, by brute force
 * over the fractions; and each pixel's box average of a Lambert floor under a near point light,
 * rho I h / (pi d^3), by a 64 x 64 midpoint sum of the closed form over the pixel. */
static void test_pixel_integral(void **state)
{
    (void)state;
    for (int k = 1; k < EXACT_SUPERSAMPLE; k++) {
        int K = exact_supersample(k);
        assert_true(K >= EXACT_SUPERSAMPLE);
        for (int s = 0; s < k; s++)
            for (int t = 0; t < K; t++) /* (s + 0.5)/k == (t + 0.5)/K */
                assert_true((2 * s + 1) * K != (2 * t + 1) * k);
    }
    fixture f;
    fixture_load(&f, "image: {width: 16, height: 12, supersample: 1}\n"
                     "camera: {eye: [0, 3, 0.01], target: [0, 0, 0], hfov: 40}\n"
                     "lights:\n  - {type: point, position: [0.3, 0.6, -0.2], intensity: [5, 5, 5]}\n"
                     "materials:\n  m: {albedo: [0.5, 0.5, 0.5], model: d3d}\n"
                     "objects:\n  - {shape: quad, size: [20, 20], material: m}\n");
    renderer_result r;
    exr_image integral = {0}, pointwise = {0};
    render_exact(&f, ROLE_VALIDATE, NULL, &r, &integral);
    assert_int_equal(r.status, RUNNER_OK);
    render_exact(&f, ROLE_VALIDATE, &point, &r, &pointwise);
    assert_int_equal(r.status, RUNNER_OK);
    render_camera cam;
    render_camera_make(f.s, 16, 12, &cam);
    const double h = 0.6, lx = 0.3, lz = -0.2, rho_i = 0.5f * 5.0f;
    const int n = 64;
    double se_int = 0.0, se_pt = 0.0, sum = 0.0;
    for (int j = 0; j < 12; j++)
        for (int i = 0; i < 16; i++) {
            double box = 0.0;
            for (int b = 0; b < n; b++)
                for (int a = 0; a < n; a++) {
                    vec3 d = render_camera_ray(&cam, (float)(i + (a + 0.5) / n), (float)(j + (b + 0.5) / n));
                    double t = -cam.eye.y / d.y, x = cam.eye.x + t * d.x - lx, z = cam.eye.z + t * d.z - lz;
                    double dist = sqrt(x * x + h * h + z * z);
                    box += rho_i * h / (TEST_PI * dist * dist * dist);
                }
            box /= (double)n * n;
            double vi = exr_image_channel(&integral, "diffuse.G")[j * 16 + i];
            double vp = exr_image_channel(&pointwise, "diffuse.G")[j * 16 + i];
            se_int += (vi - box) * (vi - box);
            se_pt += (vp - box) * (vp - box);
            sum += box;
        }
    double mean = sum / (16.0 * 12.0), nrmse_int = sqrt(se_int / 192.0) / mean, nrmse_pt = sqrt(se_pt / 192.0) / mean;
    printf("# Lambert floor under a near light, box average per pixel: NRMSE %.3g pixel integral (16 x 16), "
           "%.3g point-sampled (k = 1)\n",
           nrmse_int, nrmse_pt);
    /* The midpoint rule's error falls as the square of the sample spacing: 1/256 of the centre
     * sample's; 1e-4 leaves room for the 64 x 64 sum's own error and float shading. */
    assert_true(nrmse_int < 1e-4);
    assert_true(nrmse_pt > 20.0 * nrmse_int);
    exr_image_free(&integral);
    exr_image_free(&pointwise);
    fixture_free(&f);
}

static void test_refusals(void **state)
{
    (void)state;
    fixture f;
    fixture_load(&f, "image: {width: 8, height: 8}\n"
                     "camera: {eye: [0, 0, 5], target: [0, 0, 0], hfov: 30}\n"
                     "environment: {constant: [1, 1, 1]}\n"
                     "materials:\n  p: {roughness: 0.3, model: cook_torrance}\n"
                     "objects:\n  - {shape: sphere, radius: 1, material: p}\n");
    renderer_result r;
    render_exact(&f, ROLE_VALIDATE, NULL, &r, NULL);
    assert_int_equal(r.status, RUNNER_MISSING);
    assert_non_null(strstr(r.message, "rough lobe"));
    render_exact(&f, ROLE_TWIN, NULL, &r, NULL);
    assert_int_equal(r.status, RUNNER_MISSING);
    assert_non_null(strstr(r.message, "twin"));
    fixture_free(&f);
}

/* The thin sheet's reflectance against its series summed term by term, with R_s and R_p from
 * the angle forms (-sin(i - t)/sin(i + t), tan(i - t)/tan(i + t), Snell's law by asin), not the
 * cosine forms exact.c uses; and the unpolarised variant likewise. */
static double sheet_series(double r)
{
    double sum = r, t2 = (1.0 - r) * (1.0 - r), odd = r;
    for (int k = 0; k < 400; k++) { /* R^(2k+1) with R <= 0.6 here: 400 terms reach 1e-80 */
        sum += t2 * odd;
        odd *= r * r;
    }
    return sum;
}

static void test_thin_sheet(void **state)
{
    (void)state;
    const double n = 1.5, angles[] = {0.0, 30.0, 56.30993247402022 /* Brewster, atan 1.5 */, 75.0, 85.0};
    for (size_t a = 0; a < sizeof angles / sizeof angles[0]; a++) {
        double i = deg(angles[a]), t = asin(sin(i) / n), rs, rp;
        if (angles[a] == 0.0) {
            rs = rp = ((n - 1.0) / (n + 1.0)) * ((n - 1.0) / (n + 1.0));
        } else {
            rs = pow(sin(i - t) / sin(i + t), 2.0);
            rp = pow(tan(i - t) / tan(i + t), 2.0);
        }
        close_rel(exact_thin_sheet_reflectance(cos(i), n), 0.5 * (sheet_series(rs) + sheet_series(rp)), 1e-12);
        close_rel(exact_thin_sheet_reflectance_unpolarised(cos(i), n), sheet_series(0.5 * (rs + rp)), 1e-12);
    }
    /* Normal incidence by hand: R = 0.04, 2R/(1 + R) = 1/13. */
    close_rel(exact_thin_sheet_reflectance(1.0, 1.5), 1.0 / 13.0, 1e-14);
}

/* A thin pane in front of an emissive quad under a constant environment L: the centre pixel,
 * seen along the normal, is R_sheet L + (1 - R_sheet) E with R_sheet = 1/13. */
static void test_render_thin_sheet(void **state)
{
    (void)state;
    fixture f;
    fixture_load(&f, "image: {width: 3, height: 3, supersample: 1}\n"
                     "camera: {eye: [0, 0, 5], target: [0, 0, 0], hfov: 20}\n"
                     "environment: {constant: [2, 1, 0.5]}\n"
                     "materials:\n  glass: {albedo: [0, 0, 0], ior: 1.5, roughness: 0, thin: true,\n"
                     "    model: d3d9client, d3d9client: {blend: true}}\n"
                     "  back: {albedo: [0, 0, 0], model: d3d, d3d: {emissive: [0.2, 0.4, 0.6]}}\n"
                     "objects:\n  - {shape: quad, size: [4, 4], rotate: [90, 0, 0], material: back}\n"
                     "  - {shape: quad, size: [4, 4], rotate: [90, 0, 0], center: [0, 0, 1], material: glass}\n");
    renderer_result r;
    exr_image img = {0};
    render_exact(&f, ROLE_VALIDATE, &point, &r, &img);
    assert_int_equal(r.status, RUNNER_OK);
    const int c = 4;
    const double R = 1.0 / 13.0, L[3] = {2, 1, 0.5}, E[3] = {0.2, 0.4, 0.6};
    const char *ch[3] = {"R", "G", "B"};
    for (int k = 0; k < 3; k++)
        close_rel(exr_image_channel(&img, ch[k])[c], R * L[k] + (1.0 - R) * E[k], 1e-6);
    exr_image_free(&img);
    fixture_free(&f);
}

int main(void)
{
    if (mkdtemp(tmpdir) == NULL)
        return 1;
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_lobe_by_hand),
        cmocka_unit_test(test_fresnel_second_formula_and_energy),
        cmocka_unit_test(test_furnace),
        cmocka_unit_test(test_render_lambert_sun),
        cmocka_unit_test(test_render_point_and_mirror),
        cmocka_unit_test(test_render_manifest),
        cmocka_unit_test(test_pixel_integral),
        cmocka_unit_test(test_refusals),
        cmocka_unit_test(test_bias_of_nv_tint),
        cmocka_unit_test(test_thin_sheet),
        cmocka_unit_test(test_render_thin_sheet),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    char p[600];
    snprintf(p, sizeof p, "%s/out.exr", tmpdir);
    unlink(p);
    rmdir(tmpdir);
    return rc;
}
