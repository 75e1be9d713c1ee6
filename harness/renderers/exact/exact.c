#include "exact.h"

#include <stdio.h>

#include "frame.h"
#include "render.h"

void exact_render_job(const renderer_job *j, renderer_result *r)
{
    const exact_options *eo = j->options;
    const physics *phys = eo != NULL && eo->set ? &eo->physics : &j->s->physics;
    snprintf(r->command, sizeof r->command, "reflcheck exact reference (in process)");
    if (j->role == ROLE_TWIN) {
        renderer_fail(r, RUNNER_MISSING,
                      "exact cannot represent a twin: it renders the physics, a reference for validate and agree; "
                      "compare it with role validate");
        return;
    }
    shade_context c;
    shade_context_make(j->s, j->env, &c);
    c.tex = j->tex;
    shade_plan plans[SCENE_MAX_OBJECTS];
    char why[400];
    for (int i = 0; i < j->s->n_objects; i++)
        if (physical_plan_make(&c, &j->s->materials[j->s->objects[i].material], phys, &plans[i], why, sizeof why) !=
            RC_OK) {
            renderer_fail(r, RUNNER_MISSING, "exact cannot represent this scene: objects[%d]: %s", i, why);
            return;
        }
    render_image img = {0};
    char err[1024];
    render_options ro = {.threads = j->threads, .plans = plans, .textures = j->tex};
    rc_status st = render_scene(j->s, j->m, j->env, &ro, &img, err, sizeof err);
    if (st != RC_OK) {
        renderer_fail(r, st == RC_ERR_NOMEM ? RUNNER_ERROR : RUNNER_FAILED, "%s", err);
        return;
    }
    st = frame_write_as(j->exr, j->s, j->m, &img, "reflcheck-exact", err, sizeof err);
    r->wall_s = img.seconds;
    r->cpu_s = img.seconds;
    render_image_free(&img);
    if (st != RC_OK)
        renderer_fail(r, RUNNER_ERROR, "%s", err);
}
