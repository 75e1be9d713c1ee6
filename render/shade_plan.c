/* shade_plan.c - plan selection: which specialised kernel, scalar (shade.c) and batch
 * (shade_batch_*.c), shades a material, chosen once per material. Apart from both so that the
 * kernels never reach back to the code that picks them (shade.h's usage block). */
#include "shade.h"

#include "d3d9client.h"

void shade_plan_make(const shade_context *c, const material *m, shade_plan *p)
{
    const scene *s = c->s;
    int has_env = c->env != NULL && c->env->kind != ENV_NONE;
    int light_ambient = 0;
    for (int i = 0; i < s->n_lights; i++)
        light_ambient |= v3_nonzero(s->lights[i].ambient);
    p->mat = m;
    p->params = NULL;
    p->fn_uv = NULL;
    shade_plan_textures(c, m, p);
    p->terms = SHADE_TERM_DIFFUSE | (v3_nonzero(m->d3d.emissive) ? SHADE_TERM_EMISSION : 0u);
    switch (m->model) {
    case MODEL_D3D: {
        int spec = v3_nonzero(m->d3d.specular);
        int amb = v3_nonzero(m->d3d.ambient) && (light_ambient || v3_nonzero(s->global_ambient));
        int plain = !spec && !amb && !m->d3d.clamp;
        p->terms |= spec ? SHADE_TERM_SPECULAR : 0u;
        p->fn = plain ? shade_d3d_diffuse : shade_d3d_full;
        p->batch = plain ? shade_batch_d3d_diffuse : shade_batch_d3d_full;
        p->path = plain ? "d3d-diffuse" : "d3d-full";
        break;
    }
    case MODEL_D3D9CLIENT: {
        /* Dissolve reads the diffuse texture's coordinates, which a sample has only when the
         * context holds that texture. */
        int dissolve = has_env && d3d9client_dissolve_on(m) && p->tex[MAT_TEX_DIFFUSE] != NULL;
        p->terms |= SHADE_TERM_SPECULAR | (has_env ? SHADE_TERM_REFLECTION : 0u);
        p->fn = shade_d3d9client;
        p->fn_uv = dissolve ? shade_d3d9client_dissolve : NULL;
        p->batch = dissolve ? shade_batch_d3d9client_dissolve : shade_batch_d3d9client;
        p->path = dissolve ? "d3d9client-dissolve" : "d3d9client";
        break;
    }
    case MODEL_COOK_TORRANCE: {
        int refl = m->ct.reflection && has_env;
        p->terms |= SHADE_TERM_SPECULAR | (refl ? SHADE_TERM_REFLECTION : 0u);
        p->fn = refl ? shade_ct_full : shade_ct_lights;
        p->batch = !shade_batch_ct_supported(&m->ct) ? shade_batch_scalar
                   : refl                            ? shade_batch_ct_env
                                                     : shade_batch_ct_lights;
        p->path = refl ? "cook-torrance-env" : "cook-torrance-lights";
        break;
    }
    case MODEL_USER:
        p->terms |= SHADE_TERM_SPECULAR;
        p->fn = shade_user;
        p->batch = shade_batch_user;
        p->path = "user";
        break;
    }
}

void shade_plan_make_general(const shade_context *c, const material *m, shade_plan *p)
{
    shade_plan_make(c, m, p);
    if (m->model == MODEL_D3D) {
        p->fn = shade_d3d_full;
        p->batch = shade_batch_d3d_full;
        p->path = "d3d-full";
    } else if (m->model == MODEL_COOK_TORRANCE) {
        p->fn = shade_ct_full;
        p->batch = shade_batch_ct_supported(&m->ct) ? shade_batch_ct_env : shade_batch_scalar;
        p->path = "cook-torrance-env";
    }
}
