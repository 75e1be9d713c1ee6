/* test_render.c - render_scene's stage profile: it changes no output bit, and its stage times
 * are each >= 0 and together within the workers' share of the frame's wall time. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

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

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_profile_changes_nothing),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
