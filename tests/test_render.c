/* test_render.c - render_scene's stage profile: it changes no output bit, and its stage times
 * are each >= 0 and together within the workers' share of the frame's wall time. The resolve:
 * a k x k supersampled frame against the same frame rendered k times larger with one sample
 * per pixel (the very same sample positions), box-averaged here; and the same output for any
 * thread count, tile size and AOV choice. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "check.h"

#include "frame.h"
#include "mesh.h"
#include "render.h"
#include "scene_file.h"

/* A Blinn sphere on a Lambert quad under a point light, with sky showing above the horizon,
 * so every stage (background included) has work. */
static const char scene_text[] =
    "image: {width: 48, height: 32, supersample: 2}\n"
    "camera: {eye: [0, 1.2, 4], target: [0, 0.3, 0], hfov: 50}\n"
    "environment: {constant: [0.2, 0.3, 0.5]}\n"
    "lights:\n  - {type: point, position: [1, 3, 2], intensity: [30, 30, 30]}\n"
    "materials:\n"
    "  floor: {albedo: [0.6, 0.5, 0.4], model: d3d}\n"
    "  ball: {albedo: [0.3, 0.4, 0.7], model: d3d, d3d: {specular: [0.5, 0.5, 0.5], power: 30}}\n"
    "objects:\n"
    "  - {shape: quad, center: [0, 0, 0], size: [3, 3], material: floor}\n"
    "  - {shape: sphere, center: [0.2, 0.5, 0], radius: 0.5, material: ball}\n";

static void test_profile_changes_nothing(void **state)
{
    (void)state;
    scene *s = malloc(sizeof *s);
    assert_non_null(s);
    char err[1024];
    mesh m = {0};
    assert_int_equal(scene_file_parse(scene_text, sizeof scene_text - 1, "profile.yaml", s, err, sizeof err), RC_OK);
    assert_int_equal(mesh_build(s, &m, err, sizeof err), RC_OK);
    env_map env;
    float *px = NULL;
    assert_int_equal(frame_env_load(s, &env, &px, err, sizeof err), RC_OK);

    render_image plain, timed;
    render_profile prof;
    render_options o = {.threads = 2};
    assert_int_equal(render_scene(s, &m, &env, &o, &plain, err, sizeof err), RC_OK);
    o.profile = &prof;
    assert_int_equal(render_scene(s, &m, &env, &o, &timed, err, sizeof err), RC_OK);
    for (int c = 0; c < RENDER_CHANNELS; c++) {
        if (plain.chan[c] == NULL) {
            assert_null(timed.chan[c]);
            continue;
        }
        assert_memory_equal(plain.chan[c], timed.chan[c], (size_t)plain.width * (size_t)plain.height * sizeof(float));
    }
    assert_int_equal(prof.threads, 2);
    double sum = 0.0;
    for (int k = 0; k < RENDER_STAGE_COUNT; k++) {
        assert_true(prof.seconds[k] >= 0.0);
        sum += prof.seconds[k];
    }
    /* Work that happened: shading, interpolation, resolve and the sky all ran. */
    assert_true(prof.seconds[RENDER_STAGE_SHADE] > 0.0);
    assert_true(prof.seconds[RENDER_STAGE_INTERPOLATE] > 0.0);
    assert_true(prof.seconds[RENDER_STAGE_RESOLVE] > 0.0);
    assert_true(prof.seconds[RENDER_STAGE_BACKGROUND] > 0.0);
    /* The stages lie inside the draw, which lies inside the frame: at most threads x wall. */
    assert_true(prof.wall > 0.0);
    assert_true(sum <= prof.threads * prof.wall);
    render_image_free(&plain);
    render_image_free(&timed);
    free(px);
    mesh_free(&m);
    free(s);
}

/* The scene above with a Gouraud floor (per-vertex terms, blended per sample). */
static void resolve_scene(scene *s, mesh *m, env_map *env, float **px)
{
    char err[1024];
    assert_int_equal(scene_file_parse(scene_text, sizeof scene_text - 1, "resolve.yaml", s, err, sizeof err), RC_OK);
    assert_string_equal(s->materials[0].name, "floor");
    s->materials[0].d3d.per_vertex = 1;
    memset(m, 0, sizeof *m);
    assert_int_equal(mesh_build(s, m, err, sizeof err), RC_OK);
    assert_int_equal(frame_env_load(s, env, px, err, sizeof err), RC_OK);
}

static void images_equal(const render_image *a, const render_image *b)
{
    for (int c = 0; c < RENDER_CHANNELS; c++) {
        if (a->chan[c] == NULL || b->chan[c] == NULL) {
            assert_true(a->chan[c] == b->chan[c]);
            continue;
        }
        assert_memory_equal(a->chan[c], b->chan[c], (size_t)a->width * (size_t)a->height * sizeof(float));
    }
}

/* reuse_image: a frame rendered into an earlier frame's layers equals a fresh one, layer for
 * layer; the layers of the same size are the very arrays reused (no new allocation); a new
 * size or fewer AOVs give the fresh frame's layers, and the sanitizer run sees no leak. */
static void test_reuse_image(void **state)
{
    (void)state;
    scene *s = malloc(sizeof *s);
    assert_non_null(s);
    char err[1024];
    mesh m;
    env_map env;
    float *px = NULL;
    resolve_scene(s, &m, &env, &px);
    render_options fresh = {.threads = 2}, reuse = {.threads = 2, .reuse_image = 1};
    render_image a, b, c;
    memset(&b, 0, sizeof b);
    assert_int_equal(render_scene(s, &m, &env, &fresh, &a, err, sizeof err), RC_OK);
    assert_int_equal(render_scene(s, &m, &env, &reuse, &b, err, sizeof err), RC_OK); /* from zeroed */
    images_equal(&a, &b);
    const float *first_r = b.chan[RENDER_R];
    assert_int_equal(render_scene(s, &m, &env, &reuse, &b, err, sizeof err), RC_OK);
    assert_ptr_equal(b.chan[RENDER_R], first_r);
    images_equal(&a, &b);

    /* Another size: the old layers go, the new frame is the fresh one of that size. */
    fresh.width = reuse.width = 40;
    fresh.height = reuse.height = 24;
    assert_int_equal(render_scene(s, &m, &env, &fresh, &c, err, sizeof err), RC_OK);
    assert_int_equal(render_scene(s, &m, &env, &reuse, &b, err, sizeof err), RC_OK);
    assert_int_equal(b.width, 40);
    images_equal(&c, &b);
    /* Reused layers are not cleared first: the resolve must write every pixel of every layer,
     * partial tiles (40 x 24 is not a multiple of the 16-pixel tile) included. NaN everywhere
     * beforehand shows any pixel it missed. */
    for (int k = 0; k < RENDER_CHANNELS; k++)
        for (size_t i = 0; b.chan[k] != NULL && i < (size_t)b.width * (size_t)b.height; i++)
            b.chan[k][i] = NAN;
    assert_int_equal(render_scene(s, &m, &env, &reuse, &b, err, sizeof err), RC_OK);
    images_equal(&c, &b);
    render_image_free(&c);

    /* Beauty only: the term layers reused before are freed, not left behind. */
    fresh.aovs = reuse.aovs = RENDER_AOV_NONE;
    assert_int_equal(render_scene(s, &m, &env, &fresh, &c, err, sizeof err), RC_OK);
    assert_int_equal(render_scene(s, &m, &env, &reuse, &b, err, sizeof err), RC_OK);
    assert_null(b.chan[RENDER_DIFFUSE_R]);
    images_equal(&c, &b);

    /* An error leaves the reused image empty (its layers freed). */
    reuse.supersample = 99;
    assert_int_equal(render_scene(s, &m, &env, &reuse, &b, err, sizeof err), RC_ERR_RANGE);
    for (int k = 0; k < RENDER_CHANNELS; k++)
        assert_null(b.chan[k]);
    render_image_free(&a);
    render_image_free(&c);
    free(px);
    mesh_free(&m);
    free(s);
}

/* Pixel (i, j) of a k x k frame is the box average of pixels (k i + s, k j + t) of the frame k
 * times larger at one sample per pixel: the rasterizer puts both frames' samples at the same
 * fixed-point positions and the constant sky needs no ray, so the per-sample values are the
 * same and only the sums are formed here again (in double). Tolerance 1e-6 relative: float
 * sums of k * k terms in whatever order the resolve uses. Coverage and the centre sample's object,
 * N.V and N.L are exact. */
static void resolve_box_average_k(const int k)
{
    scene *s = malloc(sizeof *s);
    assert_non_null(s);
    mesh m;
    env_map env;
    float *px = NULL;
    char err[1024];
    resolve_scene(s, &m, &env, &px);
    const int w = 48, h = 32;
    render_image img, big;
    render_options o = {.threads = 2, .supersample = k, .width = w, .height = h};
    assert_int_equal(render_scene(s, &m, &env, &o, &img, err, sizeof err), RC_OK);
    render_options ob = {.threads = 2, .supersample = 1, .width = k * w, .height = k * h};
    assert_int_equal(render_scene(s, &m, &env, &ob, &big, err, sizeof err), RC_OK);
    int partial = 0, gouraud = 0, sky = 0;
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++) {
            const size_t p = (size_t)j * w + (size_t)i;
            double sum[RENDER_CHANNELS] = {0}, sq[3] = {0};
            for (int t = 0; t < k; t++)
                for (int u = 0; u < k; u++) {
                    const size_t q = (size_t)(k * j + t) * (size_t)(k * w) + (size_t)(k * i + u);
                    for (int c = 0; c < RENDER_CHANNELS; c++)
                        if (big.chan[c] != NULL)
                            sum[c] += big.chan[c][q];
                    for (int c = 0; c < 3; c++)
                        sq[c] += (double)big.chan[RENDER_R + c][q] * big.chan[RENDER_R + c][q];
                }
            const double n = k * k;
            static const int averaged[] = {RENDER_R,          RENDER_G,          RENDER_B,          RENDER_A,
                                           RENDER_DIFFUSE_R,  RENDER_DIFFUSE_G,  RENDER_DIFFUSE_B,  RENDER_SPECULAR_R,
                                           RENDER_SPECULAR_G, RENDER_SPECULAR_B, RENDER_EMISSION_R, RENDER_COVERAGE};
            for (size_t a = 0; a < sizeof averaged / sizeof averaged[0]; a++) {
                const int c = averaged[a];
                if (fabs(sum[c] / n) < 1e-30)
                    assert_true(fabs(img.chan[c][p]) < 1e-30);
                else
                    close_rel(img.chan[c][p], sum[c] / n, 1e-6);
            }
            /* The unbiased variance of the 9 sample values, over 9; float cancellation in the
             * resolve's one-pass form bounds the agreement by the squares' size. */
            for (int c = 0; c < 3; c++) {
                double var = (sq[c] - sum[c] * sum[c] / n) / (n * (n - 1.0));
                assert_true(fabs(img.chan[RENDER_VAR_R + c][p] - fmax(var, 0.0)) <= 1e-6 * sq[c] / n + 1e-12);
            }
            const size_t centre = (size_t)(k * j + k / 2) * (size_t)(k * w) + (size_t)(k * i + k / 2);
            assert_true(img.chan[RENDER_OBJECT][p] == big.chan[RENDER_OBJECT][centre]);
            assert_true(img.chan[RENDER_NDOTV][p] == big.chan[RENDER_NDOTV][centre]);
            assert_true(img.chan[RENDER_NDOTL][p] == big.chan[RENDER_NDOTL][centre]);
            partial += img.chan[RENDER_COVERAGE][p] > 0.0f && img.chan[RENDER_COVERAGE][p] < 1.0f;
            gouraud += img.chan[RENDER_OBJECT][p] == 0.0f;
            sky += img.chan[RENDER_COVERAGE][p] == 0.0f;
        }
    /* The frame has edges (mixed pixels), Gouraud pixels and open sky. */
    assert_true(partial > 20 && gouraud > 100 && sky > 100);
    render_image_free(&img);
    render_image_free(&big);
    free(px);
    mesh_free(&m);
    free(s);
}

/* k = 3 takes the general queueing; k = 4 the 4 x 4 pixel's vector paths (render.c's
 * render_pixel_uniform, render_queue_whole, render_queue_background), whose samples must land in
 * the same slots with the same weights as the big frame's. */
static void test_resolve_box_average(void **state)
{
    (void)state;
    resolve_box_average_k(3);
    resolve_box_average_k(4);
}

/* A per-pixel Blinn quad lit from close by, filling most of the view: its 4 x 4 pixels lie
 * wholly inside a triangle and take render_queue_whole's vector stores, and every sample's
 * value depends on its own weights (a swapped or shifted weight row moves 70 % of the pixels
 * by more than 1e-6), so the frame must be the box average of the frame 4 times larger at one
 * sample per pixel (render_queue_samples' scalar path) as in resolve_box_average_k. */
static const char quad_text[] = "image: {width: 40, height: 28, supersample: 4}\n"
                                "camera: {eye: [0.1, 1.5, 1.2], target: [0, 0, 0], hfov: 60}\n"
                                "environment: {constant: [0.2, 0.3, 0.5]}\n"
                                "lights:\n  - {type: point, position: [0.3, 0.4, 0.2], intensity: [3, 3, 3]}\n"
                                "materials:\n"
                                "  floor: {albedo: [0.6, 0.5, 0.4], model: d3d, d3d: {specular: [0.5, 0.5, 0.5], "
                                "power: 20}}\n"
                                "objects:\n  - {shape: quad, center: [0, 0, 0], size: [2, 2], material: floor}\n";

static void test_queue_4x4_box_average(void **state)
{
    (void)state;
    scene *s = malloc(sizeof *s);
    assert_non_null(s);
    char err[1024];
    mesh m = {0};
    assert_int_equal(scene_file_parse(quad_text, sizeof quad_text - 1, "quad.yaml", s, err, sizeof err), RC_OK);
    assert_int_equal(mesh_build(s, &m, err, sizeof err), RC_OK);
    env_map env;
    float *px = NULL;
    assert_int_equal(frame_env_load(s, &env, &px, err, sizeof err), RC_OK);
    const int k = 4, w = 40, h = 28;
    render_image img, big;
    render_options o = {.threads = 2, .supersample = k, .width = w, .height = h};
    assert_int_equal(render_scene(s, &m, &env, &o, &img, err, sizeof err), RC_OK);
    render_options ob = {.threads = 2, .supersample = 1, .width = k * w, .height = k * h};
    assert_int_equal(render_scene(s, &m, &env, &ob, &big, err, sizeof err), RC_OK);
    int whole = 0;
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++) {
            const size_t p = (size_t)j * w + (size_t)i;
            for (int c = RENDER_R; c <= RENDER_B; c++) {
                double sum = 0.0;
                for (int t = 0; t < k; t++)
                    for (int u = 0; u < k; u++)
                        sum += big.chan[c][(size_t)(k * j + t) * (size_t)(k * w) + (size_t)(k * i + u)];
                close_rel(img.chan[c][p], sum / (k * k), 1e-6);
            }
            /* The angle channels come from the sample nearest the centre: each sample in its own
             * slot, not just in its own pixel. */
            const size_t centre = (size_t)(k * j + k / 2) * (size_t)(k * w) + (size_t)(k * i + k / 2);
            assert_true(img.chan[RENDER_NDOTV][p] == big.chan[RENDER_NDOTV][centre]);
            assert_true(img.chan[RENDER_NDOTL][p] == big.chan[RENDER_NDOTL][centre]);
            whole += img.chan[RENDER_COVERAGE][p] == 1.0f;
        }
    /* Most pixels are covered whole (nearly all of them by one of the two triangles). */
    assert_true(whole > w * h / 2);
    render_image_free(&img);
    render_image_free(&big);
    free(px);
    mesh_free(&m);
    free(s);
}

/* One output whatever the thread count and tile size (spans of a tile, whole tiles, and spans
 * of part of a tile row when a tile row holds more samples than a span), and the same beauty
 * with or without the AOV layers. */
static void test_resolve_invariance(void **state)
{
    (void)state;
    scene *s = malloc(sizeof *s);
    assert_non_null(s);
    mesh m;
    env_map env;
    float *px = NULL;
    char err[1024];
    resolve_scene(s, &m, &env, &px);
    render_image ref, img;
    render_options o = {.threads = 1, .supersample = 3, .width = 300, .height = 200};
    assert_int_equal(render_scene(s, &m, &env, &o, &ref, err, sizeof err), RC_OK);
    static const int threads[] = {2, 3, 1, 2}, tiles[] = {0, 5, 300, 97};
    for (int i = 0; i < 4; i++) {
        o.threads = threads[i];
        o.tile = tiles[i];
        assert_int_equal(render_scene(s, &m, &env, &o, &img, err, sizeof err), RC_OK);
        images_equal(&ref, &img);
        render_image_free(&img);
    }
    o.aovs = RENDER_AOV_NONE;
    o.tile = 0;
    assert_int_equal(render_scene(s, &m, &env, &o, &img, err, sizeof err), RC_OK);
    assert_null(img.chan[RENDER_DIFFUSE_R]);
    for (int c = 0; c < RENDER_CHANNELS; c++)
        if (img.chan[c] != NULL)
            assert_memory_equal(img.chan[c], ref.chan[c], (size_t)img.width * (size_t)img.height * sizeof(float));
    render_image_free(&img);
    render_image_free(&ref);
    free(px);
    mesh_free(&m);
    free(s);
}

/* The angle channels against the geometry, worked out here in double: a floor (normal +Y, the
 * plane y = 0) seen from above, one light, and at every pixel the floor covers wholly, the
 * centre sample's point from the camera ray through it (sample (k/2, k/2), at
 * ((k/2 + 0.5)/k) of the pixel) meeting the plane; N.V, N.L, N.H are the y components of the
 * unit V, L and H there. Three lights: a point light, a sun, and a point light so far off
 * that its squared distance leaves float's range (the double path of shade_light_incident).
 * The tolerance covers the float interpolation of the hit point over a 4 m quad (about 1e-6
 * relative) and the cosines' float roundings, a hundred times over; a channel taken from the
 * wrong light, vector or lane is off by far more. */
static void angles_case(const char *light_yaml, dvec3 light_pos, dvec3 sun_dir, int sun)
{
    char text[1024], err[1024];
    snprintf(text, sizeof text,
             "image: {width: 40, height: 30, supersample: 3}\n"
             "camera: {eye: [0.3, 2.5, 2.2], target: [0, 0, -0.2], hfov: 50}\n"
             "environment: {constant: [0.2, 0.3, 0.5]}\n"
             "lights:\n  - %s\n"
             "materials:\n  floor: {albedo: [0.6, 0.5, 0.4], model: d3d, d3d: {specular: [0.5, 0.5, 0.5], power: 20}}\n"
             "objects:\n  - {shape: quad, center: [0, 0, 0], size: [4, 4], material: floor}\n",
             light_yaml);
    scene *s = malloc(sizeof *s);
    assert_non_null(s);
    assert_int_equal(scene_file_parse(text, strlen(text), "angles.yaml", s, err, sizeof err), RC_OK);
    mesh m;
    memset(&m, 0, sizeof m);
    assert_int_equal(mesh_build(s, &m, err, sizeof err), RC_OK);
    env_map env;
    float *px = NULL;
    assert_int_equal(frame_env_load(s, &env, &px, err, sizeof err), RC_OK);
    const int w = 40, h = 30, k = 3;
    render_options o = {.threads = 2, .supersample = k, .width = w, .height = h};
    render_image img;
    assert_int_equal(render_scene(s, &m, &env, &o, &img, err, sizeof err), RC_OK);
    render_camera cam;
    render_camera_make(s, w, h, &cam);
    const float off = ((float)(k / 2) + 0.5f) / (float)k;
    int checked = 0;
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++) {
            const size_t p = (size_t)j * w + (size_t)i;
            if (img.chan[RENDER_COVERAGE][p] != 1.0f)
                continue;
            const vec3 r = render_camera_ray(&cam, (float)i + off, (float)j + off);
            const dvec3 eye = dv3_from(cam.eye), dir = dv3_from(r);
            const dvec3 x = dv3_add(eye, dv3_scale(dir, -eye.y / dir.y));
            const dvec3 v = dv3_norm(dv3_sub(eye, x));
            const dvec3 l = sun ? dv3_norm(dv3_scale(sun_dir, -1.0)) : dv3_norm(dv3_sub(light_pos, x));
            const dvec3 hv = dv3_norm(dv3_add(l, v));
            assert_true(fabs(img.chan[RENDER_NDOTV][p] - v.y) < 1e-4);
            assert_true(fabs(img.chan[RENDER_NDOTL][p] - l.y) < 1e-4);
            assert_true(fabs(img.chan[RENDER_NDOTH][p] - hv.y) < 1e-4);
            checked++;
        }
    /* Most of the frame is floor. */
    assert_true(checked > w * h / 2);
    render_image_free(&img);
    free(px);
    mesh_free(&m);
    free(s);
}

static void test_angle_channels(void **state)
{
    (void)state;
    angles_case("{type: point, position: [1, 3, 2], intensity: [30, 30, 30]}", dv3(1, 3, 2), dv3(0, 0, 0), 0);
    angles_case("{type: sun, direction: [-0.4, -1, -0.3], irradiance: [1, 1, 1]}", dv3(0, 0, 0), dv3(-0.4, -1, -0.3),
                1);
    angles_case("{type: point, position: [1e16, 3e16, 2e16], intensity: [30, 30, 30]}", dv3(1e16, 3e16, 2e16),
                dv3(0, 0, 0), 0);
}

/* A kept frame: a textured Cook-Torrance floor, a D3D9Client ball and a blended D3D9Client
 * pane (eq. 7: its alpha max(d_a, |R_tot|) follows r0) over the ball and the sky, under a point
 * light; 37 x 23 pixels at 3 x 3 samples, so that tiles are partial and the frame is not
 * symmetric. */
static const char keep_text[] =
    "image: {width: 37, height: 23, supersample: 3}\n"
    "camera: {eye: [0.3, 1.1, 4], target: [0, 0.4, 0], hfov: 55}\n"
    "environment: {constant: [0.2, 0.3, 0.5]}\n"
    "lights:\n  - {type: point, position: [1, 3, 2], intensity: [30, 25, 20]}\n"
    "materials:\n"
    "  floor: {albedo: [0.6, 0.5, 0.4], roughness: 0.3, model: cook_torrance}\n"
    "  ball: {albedo: [0.3, 0.4, 0.7], model: d3d9client, d3d9client: {p: 3, r0: 0.04, reflect: [0.6, 0.6, "
    "0.62]}}\n"
    "  pane: {albedo: [0, 0, 0], ior: 1.5, roughness: 0, thin: true, model: d3d9client, d3d9client: {p: 3, "
    "alpha: 0, blend: true}}\n"
    "objects:\n"
    "  - {shape: quad, center: [0, 0, 0], size: [3, 3], material: floor}\n"
    "  - {shape: sphere, center: [0.2, 0.5, 0], radius: 0.5, material: ball}\n"
    "  - {shape: quad, center: [-0.3, 0.9, 1.0], size: [1.0, 1.5], rotate: [70, 20, 0], material: pane}\n";

/* A 3 x 2 texture of distinct texels: each floor sample's texel shows in its colour. */
static float keep_texels[3 * 2 * 4] = {0.9f, 0.2f, 0.1f, 1, 0.1f, 0.8f, 0.3f, 1, 0.2f, 0.3f, 0.9f, 1,
                                       0.7f, 0.7f, 0.2f, 1, 0.4f, 0.1f, 0.6f, 1, 1.0f, 1.0f, 1.0f, 1};

static void keep_scene(scene *s, mesh *m, env_map *env, float **px, texture_set *ts)
{
    char err[1024];
    assert_int_equal(scene_file_parse(keep_text, sizeof keep_text - 1, "keep.yaml", s, err, sizeof err), RC_OK);
    assert_string_equal(s->materials[0].name, "floor");
    assert_true(s->materials[2].d9.blend);
    snprintf(s->materials[0].texture[MAT_TEX_DIFFUSE], SCENE_PATH_MAX, "texels");
    memset(ts, 0, sizeof *ts);
    ts->map[0][MAT_TEX_DIFFUSE] = (texture){3, 2, keep_texels};
    memset(m, 0, sizeof *m);
    assert_int_equal(mesh_build(s, m, err, sizeof err), RC_OK);
    assert_int_equal(frame_env_load(s, env, px, err, sizeof err), RC_OK);
}

/* New values for every parameter a fit moves here (floor m, ball p and r0, pane r0). */
static void keep_change(scene *s, int step)
{
    s->materials[0].ct.m = 0.3f + 0.11f * (float)step;
    s->materials[1].d9.p = 3.0f + 0.4f * (float)step;
    s->materials[1].d9.r0 = 0.04f + 0.05f * (float)step;
    s->materials[2].d9.r0 = 0.04f + 0.2f * (float)step;
}

/* render_options.keep: a frame shaded again from the kept one after its materials' parameters
 * changed equals, on every layer and bit for bit, the frame rendered afresh at those parameters,
 * on 1 thread and on 2 with another tile size, and across them; and it was shaded again (stats), not rendered in full.
 * The new parameters change the image (else equality would show nothing). */
static void test_keep_reshades(void **state)
{
    (void)state;
    scene *s = malloc(sizeof *s);
    assert_non_null(s);
    char err[1024];
    mesh m;
    env_map env;
    float *px = NULL;
    texture_set ts;
    keep_scene(s, &m, &env, &px, &ts);
    render_image first, again[2], full[2];
    memset(again, 0, sizeof again);
    for (int t = 0; t < 2; t++) {
        render_keep *k = NULL;
        assert_int_equal(render_keep_make(&k), RC_OK);
        /* 2 threads with 8-pixel tiles: the keep follows the rasterizer's tiles. */
        const int tile = t == 1 ? 8 : 0;
        render_options ko = {.threads = t + 1, .tile = tile, .textures = &ts, .keep = k, .reuse_image = 1};
        render_options fo = {.threads = t + 1, .tile = tile, .textures = &ts};
        keep_change(s, 0);
        memset(&first, 0, sizeof first);
        assert_int_equal(render_scene(s, &m, &env, &ko, &first, err, sizeof err), RC_OK);
        for (int step = 1; step <= 2; step++) {
            keep_change(s, step);
            assert_int_equal(render_scene(s, &m, &env, &ko, &again[t], err, sizeof err), RC_OK);
            assert_int_equal(render_scene(s, &m, &env, &fo, &full[t], err, sizeof err), RC_OK);
            images_equal(&full[t], &again[t]);
            assert_int_equal(again[t].shaded_samples, full[t].shaded_samples);
            if (step < 2)
                render_image_free(&full[t]);
        }
        /* The change shows in the beauty, the alpha (the pane's) and the terms. */
        const size_t n = (size_t)first.width * (size_t)first.height * sizeof(float);
        assert_true(memcmp(first.chan[RENDER_R], again[t].chan[RENDER_R], n) != 0);
        assert_true(memcmp(first.chan[RENDER_A], again[t].chan[RENDER_A], n) != 0);
        assert_true(memcmp(first.chan[RENDER_SPECULAR_G], again[t].chan[RENDER_SPECULAR_G], n) != 0);
        render_keep_stats ks;
        render_keep_stats_get(k, &ks);
        assert_int_equal(ks.recorded, 1);
        assert_int_equal(ks.replayed, 2);
        assert_int_equal(ks.full, 0);
        assert_true(ks.bytes > 0.0);
        /* Within its bound (render_memory_estimate counts it): the estimate with the keep exceeds
         * the one without by at least what it holds. */
        double with_keep = 0.0, without = 0.0;
        render_memory_estimate(s, &m, &env, &ko, &with_keep, NULL);
        render_memory_estimate(s, &m, &env, &fo, &without, NULL);
        assert_true(with_keep - without >= ks.bytes);
        render_image_free(&first);
        render_keep_free(k);
    }
    images_equal(&again[0], &again[1]);
    for (int t = 0; t < 2; t++) {
        render_image_free(&again[t]);
        render_image_free(&full[t]);
    }
    free(px);
    mesh_free(&m);
    free(s);
}

/* What the keep does not shade again is rendered in full, the same as without it: a Gouraud
 * object (stats.full, a reason); another size is kept anew (recorded twice, never replayed
 * across sizes); a memory limit below the keep's bound renders in full and keeps nothing. */
static void test_keep_falls_back(void **state)
{
    (void)state;
    scene *s = malloc(sizeof *s);
    assert_non_null(s);
    char err[1024];
    mesh m;
    env_map env;
    float *px = NULL;
    resolve_scene(s, &m, &env, &px);
    render_keep *k = NULL;
    assert_int_equal(render_keep_make(&k), RC_OK);
    render_options ko = {.threads = 2, .keep = k}, fo = {.threads = 2};
    render_image a, b;
    assert_int_equal(render_scene(s, &m, &env, &ko, &a, err, sizeof err), RC_OK);
    render_image_free(&a);
    s->materials[1].d3d.power = 12.0f;
    assert_int_equal(render_scene(s, &m, &env, &ko, &a, err, sizeof err), RC_OK);
    assert_int_equal(render_scene(s, &m, &env, &fo, &b, err, sizeof err), RC_OK);
    images_equal(&a, &b);
    render_keep_stats ks;
    render_keep_stats_get(k, &ks);
    assert_int_equal(ks.full, 2);
    assert_int_equal(ks.recorded + ks.replayed, 0);
    assert_non_null(strstr(ks.why, "per vertex"));
    render_image_free(&a);
    render_image_free(&b);

    /* Per sample again: kept; another size is rendered in full and kept in its place. */
    s->materials[0].d3d.per_vertex = 0;
    assert_int_equal(render_scene(s, &m, &env, &ko, &a, err, sizeof err), RC_OK);
    render_image_free(&a);
    ko.width = fo.width = 40;
    s->materials[1].d3d.power = 20.0f;
    assert_int_equal(render_scene(s, &m, &env, &ko, &a, err, sizeof err), RC_OK);
    assert_int_equal(render_scene(s, &m, &env, &fo, &b, err, sizeof err), RC_OK);
    images_equal(&a, &b);
    render_keep_stats_get(k, &ks);
    assert_int_equal(ks.recorded, 2);
    assert_int_equal(ks.replayed, 0);
    render_image_free(&a);
    render_image_free(&b);

    /* A memory limit between the frame's need and its need with the keep. */
    double with_keep = 0.0, without = 0.0;
    render_memory_estimate(s, &m, &env, &ko, &with_keep, NULL);
    render_memory_estimate(s, &m, &env, &fo, &without, NULL);
    assert_true(with_keep > without);
    char limit[64];
    snprintf(limit, sizeof limit, "%.0f", 0.5 * (with_keep + without));
    setenv("REFLCHECK_MEMORY_LIMIT", limit, 1);
    s->materials[1].d3d.power = 25.0f;
    assert_int_equal(render_scene(s, &m, &env, &ko, &a, err, sizeof err), RC_OK);
    unsetenv("REFLCHECK_MEMORY_LIMIT");
    assert_int_equal(render_scene(s, &m, &env, &fo, &b, err, sizeof err), RC_OK);
    images_equal(&a, &b);
    render_keep_stats_get(k, &ks);
    assert_int_equal(ks.replayed, 0);
    assert_int_equal(ks.full, 3);
    assert_true(ks.bytes == 0.0);
    assert_non_null(strstr(ks.why, "memory limit"));
    render_image_free(&a);
    render_image_free(&b);
    render_keep_free(k);
    free(px);
    mesh_free(&m);
    free(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_profile_changes_nothing), cmocka_unit_test(test_resolve_box_average),
        cmocka_unit_test(test_queue_4x4_box_average),   cmocka_unit_test(test_resolve_invariance),
        cmocka_unit_test(test_angle_channels),          cmocka_unit_test(test_reuse_image),
        cmocka_unit_test(test_keep_reshades),           cmocka_unit_test(test_keep_falls_back),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
