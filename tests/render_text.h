/* render_text.h - render a scene given as YAML text through our rasterizer and read one pixel,
 * for unit tests that work a pixel's value out by hand from the model's formulas.
 *
 * Usage:
 *   #include "render_text.h"          after <cmocka.h>; needs frame.h, mesh.h, render.h, scene_file.h
 *   float rgb[3];
 *   render_text_pixel(yaml, "x.yaml", 1, 1, rgb);     R, G, B of pixel (x 1, y 1), one thread
 * name is only what messages call the text. A scene that does not parse fails the test with the
 * parser's message; everything the render allocated is freed before it returns.
 */
#ifndef REFLCHECK_TESTS_RENDER_TEXT_H
#define REFLCHECK_TESTS_RENDER_TEXT_H

#include <stdlib.h>
#include <string.h>

#include "frame.h"
#include "mesh.h"
#include "render.h"
#include "scene_file.h"

static void render_text_pixel(const char *text, const char *name, int x, int y, float rgb[3])
{
    char err[1024];
    scene *s = malloc(sizeof *s);
    assert_non_null(s);
    mesh m = {0};
    env_map env;
    float *px = NULL;
    if (scene_file_parse(text, strlen(text), name, s, err, sizeof err) != RC_OK)
        fail_msg("%s", err);
    assert_int_equal(mesh_build(s, &m, err, sizeof err), RC_OK);
    assert_int_equal(frame_env_load(s, &env, &px, err, sizeof err), RC_OK);
    render_image img;
    render_options o = {.threads = 1};
    assert_int_equal(render_scene(s, &m, &env, &o, &img, err, sizeof err), RC_OK);
    const size_t c = (size_t)y * (size_t)img.width + (size_t)x;
    for (int k = 0; k < 3; k++)
        rgb[k] = img.chan[RENDER_R + k][c];
    render_image_free(&img);
    free(px);
    mesh_free(&m);
    free(s);
}

#endif
