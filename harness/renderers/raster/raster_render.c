#include "raster_render.h"

#include <stdio.h>

#include "frame.h"
#include "render.h"

void raster_render_job(const renderer_job *j, renderer_result *r)
{
    render_image img = {0};
    char err[1024];
    render_options ro = {.threads = j->threads, .textures = j->tex};
    snprintf(r->command, sizeof r->command, "reflcheck render (in process)");
    rc_status st = render_scene(j->s, j->m, j->env, &ro, &img, err, sizeof err);
    if (st != RC_OK) {
        /* Our side out of memory is an error; anything else the rasterizer refuses fails the job. */
        renderer_fail(r, st == RC_ERR_NOMEM ? RUNNER_ERROR : RUNNER_FAILED, "%s", err);
        return;
    }
    st = frame_write(j->exr, j->s, j->m, &img, err, sizeof err);
    r->wall_s = img.seconds;
    r->cpu_s = img.seconds;
    render_image_free(&img);
    if (st != RC_OK)
        renderer_fail(r, RUNNER_ERROR, "%s", err);
}
