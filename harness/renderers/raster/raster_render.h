/* raster_render.h - reflcheck's own rasterizer as a renderer of the table (registry.h).
 *
 * Usage:
 *   renderer_job j = {.s = &scn, .m = &msh, .env = &env, .exr = "out.exr", .threads = 2};
 *   renderer_result r = {0};
 *   raster_render_job(&j, &r);        r.status RUNNER_OK, or why not with r.message
 * Renders in process (render/render.h) and writes every AOV layer (harness/frame.h). Nothing is
 * ever left out: the rasterizer computes the model.
 */
#ifndef REFLCHECK_RASTER_RENDER_H
#define REFLCHECK_RASTER_RENDER_H

#include "../renderer.h"

void raster_render_job(const renderer_job *j, renderer_result *r);

#endif
