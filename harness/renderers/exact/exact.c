#include "exact.h"

#include <math.h>
#include <stdio.h>

#include "frame.h"
#include "fresnel.h"
#include "render.h"

/* R_s and R_p of a smooth dielectric for cos_i in [0, 1]; total internal reflection gives 1. */
static void exact_fresnel_sp(double cos_i, double eta, double *rs2, double *rp2)
{
    double sin_i = sqrt((1.0 - cos_i) * (1.0 + cos_i)), sin_t = sin_i / eta;
    if (eta <= 0.0 || sin_t >= 1.0) {
        *rs2 = *rp2 = 1.0;
        return;
    }
    double cos_t = sqrt((1.0 - sin_t) * (1.0 + sin_t));
    double rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t), rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    *rs2 = rs * rs;
    *rp2 = rp * rp;
}

static double exact_clamp01(double c) { return c < 0.0 ? 0.0 : (c > 1.0 ? 1.0 : c); }

double exact_thin_sheet_reflectance(double cos_i, double eta)
{
    double rs2, rp2;
    exact_fresnel_sp(exact_clamp01(cos_i), eta, &rs2, &rp2);
    return 0.5 * (2.0 * rs2 / (1.0 + rs2) + 2.0 * rp2 / (1.0 + rp2));
}

double exact_thin_sheet_reflectance_unpolarised(double cos_i, double eta)
{
    double f = fresnel_dielectric(exact_clamp01(cos_i), eta);
    return 2.0 * f / (1.0 + f);
}

/* A thin sheet's sample: the environment along the mirror direction as its colour, R_sheet as
 * its alpha (exact.h); the blend makes R_sheet phi + (1 - R_sheet) behind. */
static void exact_thin_shade(const shade_context *c, const shade_plan *p, vec3 x, vec3 n, vec3 v, shade_terms *out)
{
    const physics *ph = p->params;
    dvec3 xd = dv3_from(x), nd = dv3_norm(dv3_from(n));
    dvec3 vd = dv3_norm(dv3_sub(dv3_from(c->eye), xd));
    double n_v = dv3_dot(nd, vd);
    (void)v; /* formed again in double, as the physical model does */
    *out = (shade_terms){.alpha = 0.0f};
    if (ph->env_specular && c->env != NULL && c->env->kind != ENV_NONE)
        out->reflection = env_lookup(c->env, v3_from_d(dv3_sub(dv3_scale(nd, 2.0 * n_v), vd)));
    out->alpha = (float)exact_thin_sheet_reflectance(n_v, p->mat->ior);
}

/* Whether the physical model can render s's objects under ph: why names what it cannot. */
static rc_status exact_plans(const scene *s, const env_map *env, const texture_set *tex, const physics *ph,
                             shade_plan *plans, char *why, size_t whylen)
{
    shade_context c;
    shade_context_make(s, env, &c);
    c.tex = tex; /* a diffuse texture multiplies the albedo (render/physical.h) */
    char one[400];
    for (int i = 0; i < s->n_objects; i++)
        if (physical_plan_make(&c, &s->materials[s->objects[i].material], ph, &plans[i], one, sizeof one) != RC_OK) {
            snprintf(why, whylen, "exact cannot represent this scene: objects[%d]: %s", i, one);
            return RC_ERR_RANGE;
        } else if (plans[i].mat->thin) {
            if (ph->fresnel_reflection != PHYS_FRESNEL_EXACT) {
                snprintf(why, whylen,
                         "exact cannot represent this scene: objects[%d]: a thin sheet reflects with the exact "
                         "Fresnel of each face; set physics fresnel_reflection: exact",
                         i);
                return RC_ERR_RANGE;
            }
            plans[i].fn = exact_thin_shade;
            plans[i].path = "physical-thin-sheet";
            plans[i].terms = SHADE_TERM_REFLECTION;
        }
    return RC_OK;
}

int exact_supersample(int k)
{
    /* Samples sit at i + (s + 0.5)/K: one of the rasterizer's k x k equals one of ours when
     * (2s + 1) k = (2t + 1) K, impossible when K holds a higher power of two than k. K = 16, the
     * renderer's largest, does for every k < 16 and puts at least 16x16 samples in a pixel. */
    return k < EXACT_SUPERSAMPLE ? EXACT_SUPERSAMPLE : k;
}

rc_status exact_physics(const scene *s, physics *rendered, char *err, size_t errlen)
{
    /* The plans look at the environment's kind only. */
    env_map env = {.kind = s->env.kind};
    shade_plan plans[SCENE_MAX_OBJECTS];
    *rendered = s->physics;
    return exact_plans(s, &env, NULL, &s->physics, plans, err, errlen);
}

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
    for (int mi = 0; mi < j->s->n_materials; mi++)
        if (mesh_material_vertex_coloured(j->s, j->m, mi)) {
            renderer_fail(r, RUNNER_MISSING,
                          "exact cannot represent this scene: materials[%d] '%s': D3D vertex colours "
                          "(d3d.colour_vertex) are not part of the physics manifest; set colour_vertex false",
                          mi, j->s->materials[mi].name);
            return;
        }
    shade_plan plans[SCENE_MAX_OBJECTS];
    char why[500];
    if (exact_plans(j->s, j->env, j->tex, phys, plans, why, sizeof why) != RC_OK) {
        renderer_fail(r, RUNNER_MISSING, "%s", why);
        return;
    }
    render_image img = {0};
    char err[1024];
    unsigned char thin[SCENE_MAX_OBJECTS];
    for (int i = 0; i < j->s->n_objects; i++)
        thin[i] = (unsigned char)(j->s->materials[j->s->objects[i].material].thin != 0);
    render_options ro = {.threads = j->threads, .plans = plans, .textures = j->tex, .blend = thin};
    if (eo == NULL || !eo->point)
        ro.supersample = exact_supersample(j->s->supersample);
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

void exact_point_render_job(const renderer_job *j, renderer_result *r)
{
    const exact_options *eo = j->options;
    exact_options o = eo != NULL ? *eo : (exact_options){0};
    o.point = 1;
    renderer_job pj = *j;
    pj.options = &o;
    exact_render_job(&pj, r);
}
