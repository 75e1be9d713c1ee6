/* test_eevee.c - the EEVEE renderer through its table entry, as production runs it, with the
 * real blender under xvfb-run: Lambert under a sun against the closed form albedo E cos / pi
 * (worked out here, not by the model library), the refusals of its twin role, and the skip
 * when no display can be had, the passes EEVEE is asked to draw. Three renders, 32 x 24 pixels,
 * 4 TAA samples.
 */
#define _XOPEN_SOURCE 700

#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <ftw.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmocka.h>

#include "renderers/eevee/eevee.h"
#include "renderers/registry.h"
#include "exr.h"
#include "mesh.h"
#include "scene.h"

#define PI 3.14159265358979323846

static char g_dir[256];

static int group_setup(void **state)
{
    (void)state;
    snprintf(g_dir, sizeof g_dir, "/tmp/test_eevee_XXXXXX");
    if (mkdtemp(g_dir) == NULL)
        return -1;
    if (access("harness/renderers/eevee/eevee_render.py", R_OK) != 0) {
        fprintf(stderr,
                "test_eevee: harness/renderers/eevee/eevee_render.py not found; run from the repository root\n");
        return -1;
    }
    return 0;
}

static int remove_entry(const char *path, const struct stat *sb, int flag, struct FTW *ftw)
{
    (void)sb;
    (void)flag;
    (void)ftw;
    return remove(path);
}

static int group_teardown(void **state)
{
    (void)state;
    if (getenv("REFLCHECK_KEEP_TMP") != NULL) {
        printf("# test_eevee: renders kept in %s\n", g_dir);
        return 0;
    }
    return nftw(g_dir, remove_entry, 16, FTW_DEPTH | FTW_PHYS) == 0 ? 0 : -1;
}

/* A Lambert floor quad (y = 0, 2.8 x 2.6 m) seen from above, under one sun. */
static void floor_scene(scene *s, mesh *m)
{
    char err[256];
    scene_init(s);
    snprintf(s->path, sizeof s->path, "test_eevee fixture");
    s->width = 32;
    s->height = 24;
    s->samples = 4;
    s->n_objects = 1;
    s->objects[0].material = 0;
    s->objects[0].shape = SHAPE_QUAD;
    s->objects[0].center = v3(-0.1f, 0.0f, 0.1f);
    s->objects[0].size = v3(2.8f, 1.0f, 2.6f);
    s->n_materials = 1;
    s->materials[0].d3d.diffuse = v3(0.5f, 0.4f, 0.3f);
    s->camera.eye = v3(0.4f, 2.6f, 2.2f);
    s->camera.target = v3(-0.1f, 0.0f, 0.1f);
    s->camera.hfov = (float)(70.0 * PI / 180.0);
    s->n_lights = 1;
    s->lights[0].kind = LIGHT_SUN;
    s->lights[0].direction = v3_norm(v3(0.35f, -1.0f, 0.2f));
    s->lights[0].intensity = v3s(3.0f);
    memset(m, 0, sizeof *m);
    if (mesh_build(s, m, err, sizeof err) != RC_OK)
        fail_msg("mesh_build: %s", err);
}

static void run_job(const scene *s, const mesh *m, comparison_role role, const eevee_options *o, const char *tag,
                    char *exr, size_t len, renderer_result *r)
{
    char dir[300], log[320];
    snprintf(dir, sizeof dir, "%s/%s", g_dir, tag);
    assert_int_equal(mkdir(dir, 0755), 0);
    snprintf(exr, len, "%s/out.exr", dir);
    snprintf(log, sizeof log, "%s/out.log", dir);
    renderer_job j = {.s = s, .m = m, .role = role, .dir = dir, .exr = exr, .log = log, .options = o};
    memset(r, 0, sizeof *r);
    int row = registry_find("eevee");
    assert_true(row >= 0);
    registry_row(row)->render(&j, r);
}

/* 1. Lambert under a sun: every fully covered floor pixel is albedo * E * cos / pi. */
static void test_sun_lambert(void **state)
{
    (void)state;
    scene s;
    mesh m;
    floor_scene(&s, &m);
    char exr[400];
    renderer_result r;
    run_job(&s, &m, ROLE_TWIN, NULL, "sun", exr, sizeof exr, &r);
    if (r.status != RUNNER_OK)
        fail_msg("eevee: %s", r.message);
    exr_image img;
    char err[512];
    if (exr_read(exr, &img, err, sizeof err) != RC_OK)
        fail_msg("%s", err);
    assert_int_equal(img.width, 32);
    assert_int_equal(img.height, 24);
    double cos_l = 1.0 / sqrt(0.35 * 0.35 + 1.0 + 0.2 * 0.2);
    const double albedo[3] = {0.5, 0.4, 0.3};
    const char *names[3] = {"R", "G", "B"}, *dnames[3] = {"diffuse.R", "diffuse.G", "diffuse.B"};
    const float *cov = exr_image_channel(&img, "coverage");
    assert_non_null(cov);
    assert_non_null(exr_image_channel(&img, "specular.R"));
    assert_non_null(exr_image_channel(&img, "reflection.R"));
    assert_non_null(exr_image_channel(&img, "background.R"));
    for (int c = 0; c < 3; c++) {
        const float *full = exr_image_channel(&img, names[c]), *d = exr_image_channel(&img, dnames[c]);
        assert_non_null(full);
        assert_non_null(d);
        double want = albedo[c] * 3.0 * cos_l / PI, worst = 0.0, worst_pass = 0.0;
        int n = 0;
        for (int p = 0; p < img.width * img.height; p++) {
            if (cov[p] < 1.0f)
                continue;
            n++;
            worst = fmax(worst, fabs(full[p] - want) / want);
            /* Nothing but the diffuse term lights a Lambert floor without an environment. */
            worst_pass = fmax(worst_pass, fabs(full[p] - d[p]) / want);
        }
        printf("# eevee sun Lambert %s: %d pixels, expected %.6f, worst relative error %.2e, diffuse pass %.2e\n",
               names[c], n, want, worst, worst_pass);
        assert_true(n > 200);
        /* Measured 5.1e-4 (float shading on llvmpipe, the sun a disc of radius 0.001); 1e-3 leaves
         * room for another Mesa and still catches any unit error (the smallest, 1/pi, is 68 %). */
        assert_true(worst < 1e-3);
        /* EEVEE keeps its light and colour passes in half float (a relative step of 9.8e-4 each):
         * their product is within 2e-3 (measured 1.7e-3). */
        assert_true(worst_pass < 4e-3);
    }
    exr_image_free(&img);
    mesh_free(&m);
}

/* 2. Twin only where EEVEE computes our model: spots, glossy lobes and lit worlds are refused
 *    (skipped, with the reason), before anything runs. */
static void test_twin_refusals(void **state)
{
    (void)state;
    scene s;
    mesh m;
    char exr[400];
    renderer_result r;

    floor_scene(&s, &m);
    s.lights[0].kind = LIGHT_SPOT;
    s.lights[0].position = v3(0.0f, 2.0f, 0.0f);
    s.lights[0].outer = 1.0f;
    run_job(&s, &m, ROLE_TWIN, NULL, "spot", exr, sizeof exr, &r);
    assert_int_equal(r.status, RUNNER_MISSING);
    assert_non_null(strstr(r.message, "spot cone"));
    mesh_free(&m);

    floor_scene(&s, &m);
    s.materials[0].model = MODEL_COOK_TORRANCE;
    s.materials[0].ct.ks = v3s(1.0f);
    run_job(&s, &m, ROLE_TWIN, NULL, "ct", exr, sizeof exr, &r);
    assert_int_equal(r.status, RUNNER_MISSING);
    assert_non_null(strstr(r.message, "GGX"));
    mesh_free(&m);

    floor_scene(&s, &m);
    s.env.kind = ENV_CONSTANT;
    s.env.radiance = v3s(0.1f);
    run_job(&s, &m, ROLE_TWIN, NULL, "world", exr, sizeof exr, &r);
    assert_int_equal(r.status, RUNNER_MISSING);
    assert_non_null(strstr(r.message, "world"));
    assert_int_not_equal(access(exr, F_OK), 0);
    mesh_free(&m);

    /* Validate renders the physics manifest: a world that must not light the Lambert term
     * (env_diffuse false, the default) is beyond EEVEE, whose probe lights every diffuse. */
    floor_scene(&s, &m);
    s.physics.fresnel_specular = PHYS_FRESNEL_NV;
    s.env.kind = ENV_CONSTANT;
    s.env.radiance = v3s(0.1f);
    run_job(&s, &m, ROLE_VALIDATE, NULL, "envdiffuse", exr, sizeof exr, &r);
    assert_int_equal(r.status, RUNNER_MISSING);
    assert_non_null(strstr(r.message, "env_diffuse"));
    mesh_free(&m);
}

/* 3. No display to be had: skipped with the install command, like a missing renderer; a
 *    blender that fails is a failed job naming its log. */
static void test_no_display_and_failure(void **state)
{
    (void)state;
    scene s;
    mesh m;
    char exr[400];
    renderer_result r;
    floor_scene(&s, &m);
    /* What Cycles' Glossy BSDF (and so EEVEE's translation) renders on a rough lobe. */
    s.physics.fresnel_specular = PHYS_FRESNEL_NV;
    eevee_options o = {.xvfb_run = "/nonexistent/xvfb-run"};
    run_job(&s, &m, ROLE_VALIDATE, &o, "nodisplay", exr, sizeof exr, &r);
    assert_int_equal(r.status, RUNNER_MISSING);
    assert_non_null(strstr(r.message, "apt-get install xvfb xauth"));

    eevee_options bad = {.blender = "/bin/false"};
    run_job(&s, &m, ROLE_VALIDATE, &bad, "fails", exr, sizeof exr, &r);
    if (r.status != RUNNER_FAILED)
        fail_msg("status %d: %s", (int)r.status, r.message);
    assert_non_null(strstr(r.message, "out.log"));
    assert_int_not_equal(access(exr, F_OK), 0);
    mesh_free(&m);
}

/* The whole of a small text file (the job's timing record), or fail. */
static void read_text(const char *path, char *buf, size_t len)
{
    FILE *f = fopen(path, "r");
    if (f == NULL)
        fail_msg("%s: cannot open", path);
    size_t n = fread(buf, 1, len - 1, f);
    buf[n] = '\0';
    fclose(f);
}

/* Over every pixel, the largest |value| of the layer's RGB; over the covered pixels, the worst
 * relative error against want[c] (channels where want[c] > 0). */
static void layer_figures(const char *exr, const char *layer, const double want[3], double *largest, double *worst)
{
    exr_image img;
    char err[512], name[64];
    if (exr_read(exr, &img, err, sizeof err) != RC_OK)
        fail_msg("%s", err);
    const float *cov = exr_image_channel(&img, "coverage");
    assert_non_null(cov);
    *largest = 0.0;
    *worst = 0.0;
    for (int c = 0; c < 3; c++) {
        snprintf(name, sizeof name, "%s.%c", layer, "RGB"[c]);
        const float *e = exr_image_channel(&img, name);
        assert_non_null(e);
        for (int p = 0; p < img.width * img.height; p++) {
            *largest = fmax(*largest, fabs(e[p]));
            if (cov[p] >= 1.0f && want[c] > 0.0)
                *worst = fmax(*worst, fabs(e[p] - want[c]) / want[c]);
        }
    }
    exr_image_free(&img);
}

/* Renders the job keeping the raw files; its timing record's text into text. */
static void run_kept(const scene *s, const mesh *m, comparison_role role, const char *tag, char *exr, size_t len,
                     char *text, size_t textlen)
{
    eevee_options keep = {.keep_raw = 1};
    renderer_result r;
    char timing[450];
    run_job(s, m, role, &keep, tag, exr, len, &r);
    if (r.status != RUNNER_OK)
        fail_msg("eevee %s: %s", tag, r.message);
    snprintf(timing, sizeof timing, "%.*s.timing.json", (int)(strlen(exr) - 4), exr);
    read_text(timing, text, textlen);
    assert_non_null(strstr(text, "\"passes\""));
    /* No material writes a shader AOV: none is asked. */
    assert_null(strstr(text, "\"aov:"));
}

/* 4. The passes EEVEE is asked to draw (each material pass is one more draw of every material
 *    per TAA sample): none for a term no material has, whose layer is then 0 exactly; an
 *    emitter's emission layer is its colour. */
static void test_passes_asked(void **state)
{
    (void)state;
    scene s;
    mesh m;
    char exr[400], text[4096];
    const double none[3] = {0.0, 0.0, 0.0};
    double largest, worst;

    /* Lambert only: the diffuse passes, no specular nor emission ones. */
    floor_scene(&s, &m);
    run_kept(&s, &m, ROLE_TWIN, "lambert", exr, sizeof exr, text, sizeof text);
    assert_non_null(strstr(text, "\"use_pass_diffuse_direct\""));
    assert_non_null(strstr(text, "\"use_pass_diffuse_color\""));
    assert_null(strstr(text, "\"use_pass_glossy_direct\""));
    assert_null(strstr(text, "\"use_pass_glossy_color\""));
    assert_null(strstr(text, "\"use_pass_emit\""));
    layer_figures(exr, "specular", none, &largest, &worst);
    assert_true(largest == 0.0);
    layer_figures(exr, "emission", none, &largest, &worst);
    assert_true(largest == 0.0);
    mesh_free(&m);

    /* Aluminium (a Cook-Torrance lobe, validate): the specular passes, no diffuse ones. */
    floor_scene(&s, &m);
    s.materials[0].model = MODEL_COOK_TORRANCE;
    s.materials[0].ct.ks = v3s(1.0f);
    s.materials[0].conductor = 1; /* a bare conductor: no Lambert under its lobe */
    s.materials[0].eta = v3(1.66f, 0.88f, 0.52f);
    s.materials[0].k = v3(9.22f, 6.27f, 4.84f);
    s.physics.fresnel_specular = PHYS_FRESNEL_NV;
    run_kept(&s, &m, ROLE_VALIDATE, "metal", exr, sizeof exr, text, sizeof text);
    assert_non_null(strstr(text, "\"use_pass_glossy_direct\""));
    assert_null(strstr(text, "\"use_pass_diffuse_direct\""));
    assert_null(strstr(text, "\"use_pass_diffuse_color\""));
    layer_figures(exr, "diffuse", none, &largest, &worst);
    assert_true(largest == 0.0);
    layer_figures(exr, "specular", none, &largest, &worst);
    assert_true(largest > 0.0);
    mesh_free(&m);

    /* An emitter: the emission pass, its colour in powers of two (exact in half float). */
    floor_scene(&s, &m);
    s.materials[0].d3d.emissive = v3(0.25f, 0.125f, 0.0625f);
    run_kept(&s, &m, ROLE_TWIN, "glow", exr, sizeof exr, text, sizeof text);
    assert_non_null(strstr(text, "\"use_pass_emit\""));
    const double glow[3] = {0.25, 0.125, 0.0625};
    layer_figures(exr, "emission", glow, &largest, &worst);
    printf("# eevee emitter: emission layer worst relative error %.2e\n", worst);
    /* One half-float step (9.8e-4) of room: the colour is exact in EEVEE's passes. */
    assert_true(worst < 1e-3);
    mesh_free(&m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_twin_refusals),
        cmocka_unit_test(test_no_display_and_failure),
        cmocka_unit_test(test_sun_lambert),
        cmocka_unit_test(test_passes_asked),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
