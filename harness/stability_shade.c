/* stability_shade.c - the whole-shader stability sweeps (stability_sweep.h): shade_eval and
 * the SIMD batch kernel on one lane against the long double model, with unit and with
 * unnormalised (scaled mesh) normals.
 */
#include <stdlib.h>

#include "env.h"
#include "mesh.h"
#include "shade.h"
#include "stability_sweep.h"

/* shade_eval_n on a batch of one lane: the batch kernel's answer for one input. */
static void shade_eval_one_lane(const shade_context *ctx, const shade_plan *plan, vec3 x, vec3 n, vec3 v,
                                shade_terms *t)
{
    shade_batch_in in;
    shade_batch_out out;
    in.n = 1;
    shade_batch_set_input(&in, 0, x, n, v);
    shade_eval_n(ctx, plan, &in, &out);
    shade_batch_get_terms(&out, 0, t);
}

static void shade_material(int model, material *m)
{
    material_init(m);
    m->albedo = v3(0.8f, 0.6f, 0.3f);
    m->d3d.diffuse = m->albedo;
    m->d3d.specular = v3(0.9f, 0.7f, 0.5f);
    m->d3d.ambient = v3(0.2f, 0.1f, 0.05f);
    m->d3d.emissive = v3(0.01f, 0.02f, 0.03f);
    m->d3d.power = 32.0f;
    switch (model) {
    case 0: m->model = MODEL_D3D; break;
    case 1:
        m->model = MODEL_D3D9CLIENT;
        m->d9.reflect = v3(0.9f, 0.6f, 0.2f);
        m->d9.sun_angle = 1;
        break;
    default:
        m->model = MODEL_COOK_TORRANCE;
        m->ct.norm = model == 2 ? CT_WALTER : CT_CT1982;
        m->ct.g = model == 2 ? G_SMITH_EXACT : G_VCAVITY;
        m->ct.f = model == 2 ? F_EXACT : F_SCHLICK;
        m->ct.m = 0.2f;
        break;
    }
}

/* One sample of the shade sweeps: the shading point, normal, view, the direction and distance
 * to the (single) light, and the constant environment. */
typedef struct {
    vec3 x, nn, v, ldir, env_c;
    double dist;
} shade_sample;

/* The scene every shade sample starts from: one material of the given model, one light. */
static void shade_scene_base(scene *sc, int model)
{
    scene_init(sc);
    sc->camera.eye = v3(0.3f, 1.7f, 4.1f);
    sc->global_ambient = v3(0.05f, 0.04f, 0.03f);
    shade_material(model, &sc->materials[0]);
    sc->n_materials = 1;
    sc->n_lights = 1;
    sc->lights[0].intensity = v3(10.0f, 8.0f, 6.0f);
    sc->lights[0].ambient = v3(0.1f, 0.1f, 0.1f);
}

/* Sample i of case `mode` (the cases of stab_sweep_shade): draws the geometry, then pushes the
 * swept parameter to its extreme, then places the light. The draws' order is the random
 * stream's: keep it. */
static void shade_case(sweep *s, scene *sc, int mode, int i, shade_sample *p)
{
    int n = s->n;
    material *m = &sc->materials[0];
    light *l = &sc->lights[0];
    p->env_c = v3(0.5f, 0.6f, 0.7f);
    p->x = v3((float)stab_rng_range(&s->r, -1, 1), (float)stab_rng_range(&s->r, -1, 1),
              (float)stab_rng_range(&s->r, -1, 1));
    p->nn = v3(0, 1, 0);
    double ph = stab_rng_range(&s->r, 0.0, 2.0 * (double)REF_PI);
    p->v = stab_rng_dir_upper(&s->r, 0.0, 1.0);
    p->ldir = stab_rng_dir_upper(&s->r, 0.0, 1.0);
    p->dist = stab_rng_log(&s->r, 0.1, 10.0);
    switch (mode) {
    case 0: p->v = stab_dir_at(stab_lsp(i, n, 1.4e-45, 0.1), ph); break;
    case 1: p->ldir = stab_dir_at(stab_lsp(i, n, 1.4e-45, 0.1), ph); break;
    case 2: p->ldir = stab_rng_dir_upper(&s->r, -1.0, 0.0); break;
    case 3:
        p->dist = stab_lsp(i, n, 1e-30, 1e-3);
        p->x = v3s(0.0f);
        break;
    case 4:
        p->dist = stab_lsp(i, n, 1e3, 1e30);
        p->x = v3s(0.0f);
        break;
    case 5: l->a0 = l->a1 = l->a2 = 0.0f; break;
    case 6:
        l->intensity = v3_scale(l->intensity, (float)stab_lsp(i, n, 1.0, 1e5));
        p->env_c = v3_scale(p->env_c, (float)stab_lsp(n - 1 - i, n, 1.0, 1.4e6));
        break;
    case 7: p->nn = i % 2 ? v3s(0.0f) : v3(0.0f, (float)stab_lsp(i, n, 1.4e-45, 1e-38), 0.0f); break;
    case 8:
        m->ct.m = (float)stab_lsp(i, n, 1e-6, 1e-2);
        m->d3d.power = (float)(i % 2 ? stab_lsp(i, n, 1e-6, 0.1) : stab_lsp(i, n, 1e4, 1e7));
        m->d9.p = m->d3d.power;
        /* light near V's mirror direction, so the narrow lobes are hit */
        p->ldir = v3_reflect(p->v, v3_norm(v3_add(p->nn, v3((float)stab_rng_range(&s->r, -0.01, 0.01), 0.0f,
                                                            (float)stab_rng_range(&s->r, -0.01, 0.01)))));
        break;
    default:
        l->kind = (light_kind)(i % 3);
        l->direction = stab_rng_dir_upper(&s->r, -1.0, -0.2);
        l->inner = (float)stab_rng_range(&s->r, 0.3, 1.5);
        l->outer = l->inner + (float)stab_rng_range(&s->r, 0.05, 0.5);
        l->profile = (spot_profile)(i % 2);
        l->a0 = (float)stab_rng_u(&s->r);
        l->a1 = (float)stab_rng_u(&s->r);
        p->ldir = stab_rng_dir_upper(&s->r, -0.2, 1.0);
        break;
    }
    l->position = v3_add(p->x, v3_scale(p->ldir, (float)p->dist));
    if (l->kind == LIGHT_SPOT)
        l->direction = v3_norm(v3_add(v3_neg(p->ldir), v3((float)stab_rng_range(&s->r, -0.3, 0.3), 0.0f, 0.0f)));
    if (l->kind == LIGHT_SUN)
        l->direction = v3_neg(p->ldir);
}

/* Adds one evaluation's terms (t) against the reference's (e) to row r. */
static void shade_add_terms(stability_row *r, const shade_terms *t, const ref_terms *e, const scene *sc,
                            const shade_sample *p)
{
    static const char *tname[4] = {"diffuse", "specular", "reflection", "emission"};
    const material *m = &sc->materials[0];
    const light *l = &sc->lights[0];
    const vec3 nn = p->nn, v = p->v;
    const ld3 ev[4] = {e->diffuse, e->specular, e->reflection, e->emission};
    const vec3 gv[4] = {t->diffuse, t->specular, t->reflection, t->emission};
    for (int j = 0; j < 4; j++) {
        const float g3[3] = {gv[j].x, gv[j].y, gv[j].z};
        const ld w3[3] = {ev[j].x, ev[j].y, ev[j].z};
        for (int c = 0; c < 3; c++)
            ADD(r, g3[c], w3[c], "%s.%c N.V=%.6g N.L=%.6g d=%.6g I=%.3g env=%.3g m=%.3g P=%.3g", tname[j], "rgb"[c],
                v3_dot(nn, v), v3_dot(nn, p->ldir), p -> dist, l -> intensity.x, p->env_c.x, m->ct.m, m->d3d.power);
    }
    ADD(r, t->alpha, e->alpha, "alpha N.V=%.6g", v3_dot(nn, v));
}

/* One sample: shade_eval (into row) and, where brow is not NULL, the batch kernel on one lane
 * (into brow), both against the long double model. */
static void shade_compare(const scene *sc, const shade_sample *p, stability_row *row, stability_row *brow)
{
    const material *m = &sc->materials[0];
    env_map env = {.kind = ENV_CONSTANT, .constant = p->env_c, .scale = v3s(1.0f)};
    shade_context ctx;
    shade_context_make(sc, &env, &ctx);
    shade_plan plan;
    shade_plan_make(&ctx, m, &plan);
    shade_terms t[2];
    shade_eval(&ctx, &plan, p->x, p->nn, p->v, &t[0]);
    if (brow != NULL)
        shade_eval_one_lane(&ctx, &plan, p->x, p->nn, p->v, &t[1]);
    ref_terms e;
    stab_ref_shade(sc, p->env_c, m, p->x, p->nn, p->v, &e);
    shade_add_terms(row, &t[0], &e, sc, p);
    if (brow != NULL)
        shade_add_terms(brow, &t[1], &e, sc, p);
}

void stab_sweep_shade(sweep *s)
{
    static const char *mname[4] = {"shade_eval[d3d]", "shade_eval[d3d9client]", "shade_eval[ct walter smith F-exact]",
                                   "shade_eval[ct ct1982 vcavity schlick]"};
    /* The SIMD batch kernels the shading loop runs (shade_batch_*.c), on the same inputs; the
     * exact Smith G and Fresnel have none (shade_batch_ct_supported). */
    static const char *bname[4] = {"shade_eval_n[d3d]", "shade_eval_n[d3d9client]", NULL,
                                   "shade_eval_n[ct ct1982 vcavity schlick]"};
    static const char *cname[] = {
        "grazing view (N.V denormal..0.1)", "grazing light (N.L->0)",          "N.L < 0",
        "light distance->0 (1e-30..1e-3)",  "light distance->inf (1e3..1e30)", "a0=a1=a2=0",
        "HDR intensity, env 1e6",           "zero-length / denormal normal",   "m->0 or P->0 / P>=1e4",
        "random lights (point/sun/spot)",
    };
    scene *sc = malloc(sizeof *sc);
    if (!sc)
        abort();
    for (int model = 0; model < 4; model++) {
        for (size_t k = 0; k < sizeof cname / sizeof cname[0]; k++) {
            stability_row *row = stab_row_begin(s, mname[model], cname[k], STABILITY_ROUNDING, 24);
            stability_row *brow =
                bname[model] != NULL ? stab_row_begin(s, bname[model], cname[k], STABILITY_ROUNDING, 24) : NULL;
            for (int i = 0; i < s->n; i++) {
                shade_sample p;
                shade_scene_base(sc, model);
                shade_case(s, sc, (int)k, i, &p);
                shade_compare(sc, &p, row, brow);
            }
            stab_row_end(row);
            if (brow != NULL)
                stab_row_end(brow);
        }
    }
    free(sc);
}

/* D3DRS_NORMALIZENORMALS off under scale (source 003), the stiff case of scaled meshes: an object
 * scaled by 10 (D3D's normal a tenth long: N.L and N.H shrink) and by 0.1 (ten times long: both
 * pass 1 and D3D's clamp to [0, 1] must hold them). Each scale also varies per axis by up to
 * 2x and the rotation is random, so the length 1/|S R^T n| (mesh_normal_length_of, float) is
 * checked against its long double value, and the D3D shading (scalar and SIMD lane) on that
 * float normal against the long double model on the same input. */
void stab_sweep_unnormalised(sweep *s)
{
    static const struct {
        const char *name;
        double scale;
    } sc_case[] = {{"normalize_normals false, scale 10", 10.0}, {"normalize_normals false, scale 0.1", 0.1}};
    static const char *tname[4] = {"diffuse", "specular", "reflection", "emission"};
    int n = s->n;
    scene *sc = malloc(sizeof *sc);
    if (!sc)
        abort();
    for (size_t k = 0; k < sizeof sc_case / sizeof *sc_case; k++) {
        stability_row *lrow = stab_row_begin(s, "mesh_normal_length_of", sc_case[k].name, STABILITY_ROUNDING, 24);
        stability_row *row = stab_row_begin(s, "shade_eval[d3d]", sc_case[k].name, STABILITY_ROUNDING, 24);
        stability_row *brow = stab_row_begin(s, "shade_eval_n[d3d]", sc_case[k].name, STABILITY_ROUNDING, 24);
        for (int i = 0; i < n; i++) {
            scene_init(sc);
            sc->camera.eye = v3(0.3f, 1.7f, 4.1f);
            sc->global_ambient = v3(0.05f, 0.04f, 0.03f);
            material *m = &sc->materials[0];
            shade_material(0, m);
            m->d3d.normalize_normals = 0;
            m->d3d.power = (float)stab_rng_log(&s->r, 1.0, 1e4);
            sc->n_materials = 1;
            object *o = &sc->objects[0];
            o->scale = v3((float)(sc_case[k].scale * stab_rng_log(&s->r, 0.5, 2.0)),
                          (float)(sc_case[k].scale * stab_rng_log(&s->r, 0.5, 2.0)),
                          (float)(sc_case[k].scale * stab_rng_log(&s->r, 0.5, 2.0)));
            o->rotate = v3((float)stab_rng_range(&s->r, -3.2, 3.2), (float)stab_rng_range(&s->r, -3.2, 3.2),
                           (float)stab_rng_range(&s->r, -3.2, 3.2));
            sc->n_objects = 1;
            sc->n_lights = 1;
            light *l = &sc->lights[0];
            l->kind = (light_kind)(i % 3);
            l->intensity = v3(10.0f, 8.0f, 6.0f);
            l->ambient = v3(0.1f, 0.1f, 0.1f);
            vec3 x = v3((float)stab_rng_range(&s->r, -1, 1), (float)stab_rng_range(&s->r, -1, 1),
                        (float)stab_rng_range(&s->r, -1, 1));
            /* A unit world normal in any direction, the viewer on its side (as the shading loop
             * turns it), the light anywhere around. */
            vec3 ax = stab_rng_dir_upper(&s->r, -1.0, 1.0), v = stab_rng_dir_upper(&s->r, -1.0, 1.0);
            if (v3_dot(ax, v) < 0.0f)
                v = v3_neg(v);
            vec3 ldir = stab_rng_dir_upper(&s->r, -1.0, 1.0);
            l->position = v3_add(x, v3_scale(ldir, (float)stab_rng_log(&s->r, 0.1, 10.0)));
            l->direction = v3_neg(ldir);
            l->inner = 1.0f;
            l->outer = 2.0f;

            mesh_normal_length nl;
            mesh_normal_length_make(o, &nl);
            float len = mesh_normal_length_of(&nl, ax);
            /* Long double: 1/|S R^T n| with R from the same Euler angles (Rz Ry Rx). */
            ld cx = cosl(o->rotate.x), sx = sinl(o->rotate.x), cy = cosl(o->rotate.y), sy = sinl(o->rotate.y);
            ld cz = cosl(o->rotate.z), sz = sinl(o->rotate.z);
            ld r[3][3] = {{cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx},
                          {sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx},
                          {-sy, cy * sx, cy * cx}};
            ld3 a = l3_from(ax);
            ld rt[3] = {r[0][0] * a.x + r[1][0] * a.y + r[2][0] * a.z, r[0][1] * a.x + r[1][1] * a.y + r[2][1] * a.z,
                        r[0][2] * a.x + r[1][2] * a.y + r[2][2] * a.z};
            ld3 srt = l3(o->scale.x * rt[0], o->scale.y * rt[1], o->scale.z * rt[2]);
            ADD(lrow, len, 1 / l3_len(srt), "scale=(%.4g,%.4g,%.4g)", o->scale.x, o->scale.y, o->scale.z);

            vec3 nn = v3_scale(ax, len);
            shade_context ctx;
            shade_context_make(sc, NULL, &ctx);
            shade_plan plan;
            shade_plan_make(&ctx, m, &plan);
            shade_terms t[2];
            shade_eval(&ctx, &plan, x, nn, v, &t[0]);
            shade_eval_one_lane(&ctx, &plan, x, nn, v, &t[1]);
            ref_terms e;
            stab_ref_shade(sc, v3s(0.0f), m, x, nn, v, &e);
            const ld3 ev[4] = {e.diffuse, e.specular, e.reflection, e.emission};
            for (int b = 0; b < 2; b++) {
                stability_row *rw = b ? brow : row;
                const vec3 gv[4] = {t[b].diffuse, t[b].specular, t[b].reflection, t[b].emission};
                for (int j = 0; j < 4; j++) {
                    const float g3[3] = {gv[j].x, gv[j].y, gv[j].z};
                    const ld w3[3] = {ev[j].x, ev[j].y, ev[j].z};
                    for (int c = 0; c < 3; c++)
                        ADD(rw, g3[c], w3[c], "%s.%c |N|=%.6g N.L=%.6g P=%.6g light %d", tname[j], "rgb"[c], v3_len(nn),
                            v3_dot(nn, ldir), m -> d3d.power, (int)l->kind);
                }
            }
        }
        stab_row_end(lrow);
        stab_row_end(row);
        stab_row_end(brow);
    }
    free(sc);
}
