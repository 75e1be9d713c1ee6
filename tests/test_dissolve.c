/* D3D9Client Dissolve (source 000, docs/dissolve.md): the noise texels against values worked out
 * by hand (the published lowbias32 hash, in Python), the offset at texel centres and between
 * them, the off switch and strength scaling, the noise's mean and variance (which the
 * validate's roughness m = strength / sqrt(54) rests on), every formula instance and the SIMD
 * lanes against the scalar model, bit-identical renders for 1, 2 and 3 threads, the scene
 * file's refusals, and the twin refusals. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "cli_exec.h"
#include "d3d9client.h"
#include "formula.h"
#include "frame.h"
#include "mesh.h"
#include "render.h"
#include "scene_file.h"
#include "shade.h"

#define SCENE "scenes/d3d9_dissolve.yaml"

/* lowbias32 of i + 256 (j + 256 ch), top 24 bits / 2^24, computed in Python: exact binary
 * fractions, so the comparison is exact. */
static void test_texels_by_hand(void **state)
{
    (void)state;
    assert_true(formula_dissolve_texel(0, 0, 0) == 0.0f); /* the hash of 0 is 0 */
    assert_true(formula_dissolve_texel(1, 0, 0) == 0.40834903717041016f);
    assert_true(formula_dissolve_texel(3, 5, 0) == 0.10102009773254395f);
    assert_true(formula_dissolve_texel(4, 5, 0) == 0.6509618163108826f);
    assert_true(formula_dissolve_texel(3, 6, 0) == 0.5199966430664062f);
    assert_true(formula_dissolve_texel(4, 6, 0) == 0.06777602434158325f);
    assert_true(formula_dissolve_texel(3, 5, 1) == 0.9244070649147034f);
    assert_true(formula_dissolve_texel(3, 5, 2) == 0.562632143497467f);
    assert_true(formula_dissolve_texel(255, 255, 2) == 0.011332035064697266f);
}

/* Scale 2: x = 512 u - 1/2 texels. u = 3.5/512, v = 5.5/512 is texel (3, 5)'s centre, so the
 * offset is (T - 1/2) strength of that texel alone: strength 0.2 gives (0.10102 - 0.5) 0.2 =
 * -0.0797960, (0.92441 - 0.5) 0.2 = 0.0848814, (0.56263 - 0.5) 0.2 = 0.0125264. Halfway to
 * column 4 (u = 4/512): the two texels' mean. At (x, y) = (3.25, 5.75) the weights are
 * 0.75 x 0.25 on (3, 5), 0.25 x 0.25 on (4, 5), 0.75 x 0.75 on (3, 6), 0.25 x 0.75 on (4, 6). */
static void test_offset_by_hand(void **state)
{
    (void)state;
    const float s = 2.0f, k = 0.2f;
    const struct {
        float u, v;
        double want[3];
    } pt[] = {
        {3.5f / 512, 5.5f / 512, {-0.07979598045349122, 0.08488141298294068, 0.012526428699493409}},
        {4.0f / 512, 5.5f / 512, {-0.02480180859565735, 0.015602254867553712, 0.05574760437011719}},
        {3.75f / 512, 6.25f / 512, {-0.027033500373363495, 0.028597189486026766, 0.03456104248762131}},
    };
    for (size_t i = 0; i < sizeof pt / sizeof *pt; i++)
        for (uint32_t c = 0; c < 3; c++) {
            close_rel(formula_dissolve_offset_f(pt[i].u, pt[i].v, s, k, c), pt[i].want[c], 2e-6);
            close_rel(formula_dissolve_offset_v(pt[i].u, pt[i].v, s, k, c), pt[i].want[c], 2e-6);
            /* 0.2f is not 0.2: the double and long double instances carry its float value. */
            close_rel(formula_dissolve_offset_d(pt[i].u, pt[i].v, s, (double)k, c), pt[i].want[c] * (double)k / 0.2,
                      1e-12);
            close_rel((double)formula_dissolve_offset_l(pt[i].u, pt[i].v, s, (long double)k, c),
                      pt[i].want[c] * (double)k / 0.2, 1e-12);
        }
    /* The model adapter: R, G, B -> x, y, z. */
    d3d9client_params p = {.dissolve_scale = s, .dissolve_strength = k};
    vec3 o = d3d9client_dissolve_offset(&p, pt[0].u, pt[0].v);
    close_rel(o.x, pt[0].want[0], 2e-6);
    close_rel(o.y, pt[0].want[1], 2e-6);
    close_rel(o.z, pt[0].want[2], 2e-6);
}

/* Either parameter 0 turns the effect off; strength scales it; u, v repeat with period
 * 1/scale; every offset lies within +-strength/2; a NaN coordinate still gives a finite one. */
static void test_off_scale_wrap(void **state)
{
    (void)state;
    for (uint32_t c = 0; c < 3; c++) {
        assert_true(formula_dissolve_offset_f(0.3f, 0.7f, 0.0f, 0.2f, c) == 0.0f);
        assert_true(formula_dissolve_offset_f(0.3f, 0.7f, 1.5f, 0.0f, c) == 0.0f);
        assert_true(formula_dissolve_offset_d(0.3, 0.7, 0.0, 0.2, c) == 0.0);
        /* 0.2f is exactly 2 x 0.1f, so the offsets double exactly. */
        float a = formula_dissolve_offset_f(0.3f, 0.7f, 1.5f, 0.1f, c);
        float b = formula_dissolve_offset_f(0.3f, 0.7f, 1.5f, 0.2f, c);
        assert_true(a != 0.0f && b == 2.0f * a);
        /* Period 1/scale = 0.5 at scale 2, both ways; the coordinates are exact binary fractions. */
        float w = formula_dissolve_offset_f(0.3125f, 0.6875f, 2.0f, 0.2f, c);
        assert_true(formula_dissolve_offset_f(0.3125f + 0.5f, 0.6875f - 1.5f, 2.0f, 0.2f, c) == w);
        assert_true(formula_dissolve_offset_f(0.3125f - 3.0f, 0.6875f + 2.0f, 2.0f, 0.2f, c) == w);
        assert_true(isfinite(formula_dissolve_offset_f(NAN, INFINITY, 2.0f, 0.2f, c)));
        assert_true(isfinite(formula_dissolve_offset_f(1e30f, -1e30f, 12.0f, 0.2f, c)));
    }
    srand(7);
    for (int i = 0; i < 20000; i++) {
        float u = (float)rand() / RAND_MAX * 8.0f - 4.0f, v = (float)rand() / RAND_MAX * 8.0f - 4.0f;
        for (uint32_t c = 0; c < 3; c++)
            assert_true(fabsf(formula_dissolve_offset_f(u, v, 3.0f, 0.2f, c)) <= 0.1f);
    }
}

/* The noise t over random points: mean 1/2, variance (1/12)(2/3)^2 = 1/27 = 0.0370 (a bilinear
 * mix of four independent uniform texels, the squared weights' mean (2/3)^2 over a texel), and
 * channels uncorrelated: the isotropic spread sqrt(1/27) strength per axis from which the
 * scene's validate roughness is derived. 2e5 points: the standard error of the mean is 4e-4,
 * of the variance about 1e-4. */
static void test_noise_statistics(void **state)
{
    (void)state;
    const int n = 200000;
    double sum[3] = {0}, sq[3] = {0}, cross = 0.0;
    srand(11);
    for (int i = 0; i < n; i++) {
        float u = (float)rand() / RAND_MAX, v = (float)rand() / RAND_MAX;
        double t[3];
        for (uint32_t c = 0; c < 3; c++) {
            t[c] = formula_dissolve_offset_d(u, v, 1.0, 1.0, c); /* t - 1/2 */
            sum[c] += t[c];
            sq[c] += t[c] * t[c];
        }
        cross += t[0] * t[1];
    }
    for (int c = 0; c < 3; c++) {
        double mean = sum[c] / n, var = sq[c] / n - mean * mean;
        assert_true(fabs(mean) < 2.5e-3);
        close_rel(var, 1.0 / 27.0, 0.03);
    }
    double corr = (cross / n - sum[0] / n * sum[1] / n) * 27.0;
    assert_true(fabs(corr) < 0.02);
}

typedef struct {
    scene *s;
    mesh m;
    env_map env;
    float *px;
    texture_set ts;
} fixture;

static void fixture_load(fixture *f)
{
    char err[1024];
    f->s = calloc(1, sizeof *f->s);
    assert_non_null(f->s);
    if (scene_file_load(SCENE, f->s, err, sizeof err) != RC_OK)
        fail_msg("%s", err);
    memset(&f->m, 0, sizeof f->m);
    if (mesh_build(f->s, &f->m, err, sizeof err) != RC_OK || frame_env_load(f->s, &f->env, &f->px, err, sizeof err) ||
        frame_textures_load(f->s, &f->ts, err, sizeof err))
        fail_msg("%s", err);
}

static void fixture_free(fixture *f)
{
    texture_set_free(&f->ts);
    free(f->px);
    mesh_free(&f->m);
    free(f->s);
}

/* Lanes against shade_eval_uv on points of the scene's sphere seen from its camera, at random
 * texture coordinates: the same formula instance arithmetic (formula_dissolve_offset _v and _f)
 * and environment lookups that agree to 1e-6 of a texel step, so the terms agree closely.
 * Dissolve must change the reflection (against the plain plan) on nearly every lane. */
static void test_lanes_match_scalar(void **state)
{
    (void)state;
    fixture f;
    fixture_load(&f);
    shade_context c;
    shade_context_make(f.s, &f.env, &c);
    shade_plan bare;
    shade_plan_make(&c, &f.s->materials[0], &bare); /* no textures in the context: no dissolve */
    assert_string_equal(bare.path, "d3d9client");
    assert_null(bare.fn_uv);
    c.tex = &f.ts;
    shade_plan p;
    shade_plan_make(&c, &f.s->materials[0], &p);
    assert_string_equal(p.path, "d3d9client-dissolve");
    assert_true(p.batch == shade_batch_d3d9client_dissolve);

    vec3 eye = f.s->camera.eye;
    static shade_batch_in in;
    static shade_batch_out out;
    int changed = 0, total = 0;
    srand(5);
    for (int b = 0; b < 8; b++) {
        in.n = SHADE_BATCH;
        for (int i = 0; i < SHADE_BATCH; i++) {
            /* A point on the half of the sphere (centre 0, radius 0.8) facing the camera. */
            vec3 d;
            do {
                d = v3((float)rand() / RAND_MAX * 2 - 1, (float)rand() / RAND_MAX * 2 - 1,
                       (float)rand() / RAND_MAX * 2 - 1);
            } while (v3_dot(d, d) < 0.01f || v3_dot(d, d) > 1.0f);
            vec3 n = v3_norm(d);
            if (v3_dot(n, v3_norm(eye)) < 0.05f)
                n = v3_norm(v3_add(n, v3_scale(v3_norm(eye), 1.2f)));
            vec3 x = v3_scale(n, 0.8f);
            shade_batch_set_input(&in, i, x, n, v3_norm(v3_sub(eye, x)));
            in.tu[i] = (float)rand() / RAND_MAX;
            in.tv[i] = (float)rand() / RAND_MAX;
        }
        shade_eval_n(&c, &p, &in, &out);
        for (int i = 0; i < SHADE_BATCH; i++) {
            shade_terms t, lane, plain;
            vec3 x = shade_lane_get(&in.x, i), n = shade_lane_get(&in.nrm, i), v = shade_lane_get(&in.v, i);
            shade_eval_uv(&c, &p, x, n, v, in.tu[i], in.tv[i], &t);
            shade_batch_get_terms(&out, i, &lane);
            const float *a = &t.reflection.x, *l = &lane.reflection.x;
            for (int k = 0; k < 3; k++) {
                if (!(fabsf(a[k] - l[k]) <= 2e-4f * fabsf(a[k]) + 1e-6f))
                    fail_msg("lane %d channel %d: scalar %.9g, lanes %.9g", i, k, (double)a[k], (double)l[k]);
            }
            close_rel(lane.diffuse.x, t.diffuse.x, 1e-5);
            close_rel(lane.alpha, t.alpha, 1e-4);
            shade_eval_uv(&c, &bare, x, n, v, in.tu[i], in.tv[i], &plain);
            changed += fabsf(plain.reflection.y - t.reflection.y) > 1e-6f * fabsf(t.reflection.y);
            total++;
        }
    }
    assert_true(changed > total * 9 / 10);
    fixture_free(&f);
}

/* Renders at 1, 2 and 3 threads (and another tile size) are bit-identical, and the dissolve
 * reaches the image: off, the reflection layer differs. */
static void test_render_deterministic(void **state)
{
    (void)state;
    fixture f;
    fixture_load(&f);
    char err[1024];
    render_options o = {.threads = 1, .supersample = 2, .width = 64, .height = 40, .textures = &f.ts};
    render_image ref, img;
    assert_int_equal(render_scene(f.s, &f.m, &f.env, &o, &ref, err, sizeof err), RC_OK);
    static const int threads[] = {2, 3}, tiles[] = {0, 7};
    for (int i = 0; i < 2; i++) {
        o.threads = threads[i];
        o.tile = tiles[i];
        assert_int_equal(render_scene(f.s, &f.m, &f.env, &o, &img, err, sizeof err), RC_OK);
        for (int ch = 0; ch < RENDER_CHANNELS; ch++) {
            assert_true((ref.chan[ch] == NULL) == (img.chan[ch] == NULL));
            if (ref.chan[ch] != NULL)
                assert_memory_equal(ref.chan[ch], img.chan[ch], (size_t)ref.width * (size_t)ref.height * sizeof(float));
        }
        render_image_free(&img);
    }
    f.s->materials[0].d9.dissolve_strength = 0.0f;
    o.threads = 2;
    assert_int_equal(render_scene(f.s, &f.m, &f.env, &o, &img, err, sizeof err), RC_OK);
    size_t npx = (size_t)ref.width * (size_t)ref.height, differ = 0, surface = 0;
    for (size_t i = 0; i < npx; i++) {
        surface += ref.chan[RENDER_COVERAGE][i] > 0.0f;
        differ += ref.chan[RENDER_REFLECTION_G][i] != img.chan[RENDER_REFLECTION_G][i];
    }
    assert_true(surface > 100 && differ > surface / 2);
    render_image_free(&img);
    render_image_free(&ref);
    fixture_free(&f);
}

/* The committed texture's absolute path (the scene text is parsed as if from elsewhere). */
static void uvgrid_path(char *out, size_t len)
{
    char cwd[PATH_MAX];
    assert_non_null(getcwd(cwd, sizeof cwd));
    snprintf(out, len, "%s/scenes/assets/uvgrid.png", cwd);
}

static void expect_error(const char *mat_yaml, rc_status want, const char *needle)
{
    char tex[PATH_MAX], text[2048], err[1024] = "";
    uvgrid_path(tex, sizeof tex);
    snprintf(text, sizeof text,
             "image: {width: 8, height: 8}\ncamera: {eye: [0, 0, 3], target: [0, 0, 0], hfov: 40}\n"
             "materials:\n  a: %s\nobjects:\n  - {shape: sphere, radius: 1, material: a}\n",
             mat_yaml);
    char *t = strstr(text, "TEX");
    if (t != NULL) {
        char rest[2048];
        snprintf(rest, sizeof rest, "%s", t + 3);
        snprintf(t, sizeof text - (size_t)(t - text), "%s%s", tex, rest);
    }
    scene *s = calloc(1, sizeof *s);
    assert_non_null(s);
    rc_status rc = scene_file_parse(text, strlen(text), "mem.yaml", s, err, sizeof err);
    if (rc != want || (needle != NULL && strstr(err, needle) == NULL))
        fail_msg("%s: rc %d (want %d): %s", mat_yaml, rc, want, err);
    if (want == RC_OK && strstr(mat_yaml, "[1.5, 0.05]") != NULL) {
        assert_true(s->materials[0].d9.dissolve_scale == 1.5f);
        assert_true(s->materials[0].d9.dissolve_strength == 0.05f);
    }
    free(s);
}

static void test_scene_file(void **state)
{
    (void)state;
    expect_error("{model: d3d9client, d3d9client: {dissolve: [1.5, 0.05]}, texture: {diffuse: TEX}}", RC_OK, NULL);
    /* Key order does not matter: the texture after d3d9client is still seen. */
    expect_error("{texture: {diffuse: TEX}, d3d9client: {dissolve: [1.5, 0.05]}, model: d3d9client}", RC_OK, NULL);
    expect_error("{model: d3d9client, d3d9client: {dissolve: [1, 0.3]}, texture: {diffuse: TEX}}", RC_ERR_RANGE,
                 "mem.yaml:4:53:");
    expect_error("{model: d3d9client, d3d9client: {dissolve: [1, 0.3]}, texture: {diffuse: TEX}}", RC_ERR_RANGE,
                 "materials.a.d3d9client.dissolve[1]: 0.3 is out of range; allowed: [scale, strength]");
    expect_error("{model: d3d9client, d3d9client: {dissolve: [13, 0.1]}, texture: {diffuse: TEX}}", RC_ERR_RANGE,
                 "materials.a.d3d9client.dissolve[0]");
    expect_error("{model: d3d9client, d3d9client: {dissolve: [-1, 0.1]}, texture: {diffuse: TEX}}", RC_ERR_RANGE,
                 "dissolve[0]");
    expect_error("{model: d3d9client, d3d9client: {dissolve: [.nan, 0.1]}, texture: {diffuse: TEX}}", RC_ERR_RANGE,
                 "dissolve[0]");
    expect_error("{model: d3d9client, d3d9client: {dissolve: [1]}, texture: {diffuse: TEX}}", RC_ERR_PARSE,
                 "expected a list of 2 numbers");
    expect_error("{model: d3d9client, d3d9client: {dissolve: 1}, texture: {diffuse: TEX}}", RC_ERR_PARSE, "dissolve");
    expect_error("{model: d3d9client, d3d9client: {dissolve: [1, 0.1]}}", RC_ERR_RANGE,
                 "dissolve needs a textured surface (source 000");
    expect_error("{model: d3d, d3d9client: {dissolve: [1, 0.1]}, texture: {diffuse: TEX}}", RC_ERR_RANGE,
                 "dissolve applies to model d3d9client only");
    /* Off (a zero parameter) needs no texture: nothing to apply. */
    expect_error("{model: d3d9client, d3d9client: {dissolve: [0, 0.1]}}", RC_OK, NULL);
}

/* The job record DIR/SCENE/RENDERER-twin.json of a refused twin: skipped, with the reason. */
static void expect_refused(const char *dir, const char *scene_name, const char *renderer, const char *reason)
{
    char path[600], rec[8192];
    snprintf(path, sizeof path, "%s/%s/%s-twin.json", dir, scene_name, renderer);
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    size_t n = fread(rec, 1, sizeof rec - 1, f);
    rec[n] = '\0';
    fclose(f);
    assert_non_null(strstr(rec, "\"status\":\t\"skipped\""));
    if (strstr(rec, reason) == NULL)
        fail_msg("%s: no \"%s\" in %s", path, reason, rec);
}

/* POV-Ray and Cycles refuse a twin of the dissolve scene with the reason (the job is skipped,
 * not compared); EEVEE too, on a scene without the environment it refuses first. */
static void test_twins_refused(void **state)
{
    (void)state;
    char err[4096], dir[] = "/tmp/reflcheck_dissolve_XXXXXX";
    assert_non_null(mkdtemp(dir));
    const char *renderer[] = {"povray", "cycles"};
    for (int i = 0; i < 2; i++) {
        assert_int_equal(
            cli_exec(err, sizeof err, "run %s --renderer %s --role twin --small --out %s", SCENE, renderer[i], dir), 0);
        expect_refused(dir, "d3d9_dissolve", renderer[i],
                       "d3d9client.dissolve (source 000's noise on the reflected direction");
        expect_refused(dir, "d3d9_dissolve", renderer[i], "judge it with role validate");
    }
    char tex[PATH_MAX], scn[600];
    uvgrid_path(tex, sizeof tex);
    snprintf(scn, sizeof scn, "%s/noenv.yaml", dir);
    FILE *f = fopen(scn, "w");
    assert_non_null(f);
    fprintf(f,
            "image: {width: 16, height: 16}\ncamera: {eye: [0, 0, 3], target: [0, 0, 0], hfov: 40}\n"
            "lights:\n  - {type: sun, direction: [0, 0, -1], irradiance: [1, 1, 1]}\n"
            "materials:\n  a: {model: d3d9client, d3d9client: {dissolve: [1, 0.1]}, texture: {diffuse: %s}}\n"
            "objects:\n  - {shape: sphere, radius: 1, material: a}\n",
            tex);
    fclose(f);
    assert_int_equal(cli_exec(err, sizeof err, "run %s --renderer eevee --role twin --out %s", scn, dir), 0);
    expect_refused(dir, "noenv", "eevee",
                   "d3d9client.dissolve (source 000's noise on the reflected direction) has no EEVEE twin");
    char cmd[700];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    assert_int_equal(system(cmd), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_texels_by_hand),     cmocka_unit_test(test_offset_by_hand),
        cmocka_unit_test(test_off_scale_wrap),     cmocka_unit_test(test_noise_statistics),
        cmocka_unit_test(test_lanes_match_scalar), cmocka_unit_test(test_render_deterministic),
        cmocka_unit_test(test_scene_file),         cmocka_unit_test(test_twins_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
