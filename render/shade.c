#include "shade.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

#include "cooktorrance.h"
#include "d3d.h"
#include "d3d9client.h"
#include "formula.h"
#include "smath.h"
#include "user_load.h"

void shade_context_make(const scene *s, const env_map *env, shade_context *c)
{
    c->s = s;
    c->env = env;
    c->eye = s->camera.eye;
    c->e_inf = v3_norm(v3_sub(s->camera.eye, s->camera.target));
    c->tex = NULL;
}

/* The plan's textures from the context's set, by the material's index in the scene. */
void shade_plan_textures(const shade_context *c, const material *m, shade_plan *p)
{
    p->textured = 0;
    long mi = m - c->s->materials;
    for (int k = 0; k < MAT_TEX_SLOTS; k++) {
        p->tex[k] = NULL;
        if (c->tex != NULL && mi >= 0 && mi < c->s->n_materials && c->tex->map[mi][k].width > 0) {
            p->tex[k] = &c->tex->map[mi][k];
            p->textured = 1;
        }
    }
}

/* The lane-independent part of shade_texture_apply: one sample's terms times its texels. */
static inline void shade_texture_mul(const shade_plan *p, const float *dif, const float *spec, shade_terms *t)
{
    if (dif != NULL) {
        vec3 c = v3(dif[0], dif[1], dif[2]);
        t->diffuse = v3_mul(t->diffuse, c);
        t->emission = v3_mul(t->emission, c);
        if (p->mat->model == MODEL_D3D9CLIENT) {
            /* eq. (7) again with the texture's alpha (d_a as texel_alpha says): |R_tot| from the
             * reflection term it made. */
            float rn = d3d9client_colour_norm(t->reflection, p->mat->d9.norm);
            t->alpha = formula_d3d9_alpha_f(d3d9client_diffuse_alpha(&p->mat->d9, dif[3]), rn);
        } else {
            t->alpha *= dif[3];
        }
    }
    if (spec != NULL)
        t->specular = v3_mul(t->specular, v3(spec[0], spec[1], spec[2]));
}

void shade_texture_apply(const shade_plan *p, float u, float v, shade_terms *t)
{
    float dif[4], spec[4];
    if (p->tex[MAT_TEX_DIFFUSE] != NULL)
        texture_sample(p->tex[MAT_TEX_DIFFUSE], u, v, dif);
    if (p->tex[MAT_TEX_SPECULAR] != NULL)
        texture_sample(p->tex[MAT_TEX_SPECULAR], u, v, spec);
    shade_texture_mul(p, p->tex[MAT_TEX_DIFFUSE] ? dif : NULL, p->tex[MAT_TEX_SPECULAR] ? spec : NULL, t);
}

void shade_texture_apply_n(const shade_plan *p, const shade_batch_in *in, shade_batch_out *out)
{
    /* Texels gathered for the batch first (texture_sample_n), then applied lane by lane. */
    float dif[4][SHADE_BATCH], spec[4][SHADE_BATCH];
    const int n = in->n;
    const texture *td = p->tex[MAT_TEX_DIFFUSE], *ts = p->tex[MAT_TEX_SPECULAR];
    if (td != NULL)
        texture_sample_n(td, n, in->tu, in->tv, dif[0], dif[1], dif[2], dif[3]);
    if (ts != NULL)
        texture_sample_n(ts, n, in->tu, in->tv, spec[0], spec[1], spec[2], spec[3]);
    for (int i = 0; i < n; i++) {
        shade_terms t;
        float d[4] = {1, 1, 1, 1}, s[4] = {1, 1, 1, 1};
        for (int k = 0; k < 4; k++) {
            d[k] = td ? dif[k][i] : 1.0f;
            s[k] = ts ? spec[k][i] : 1.0f;
        }
        shade_batch_get_terms(out, i, &t);
        shade_texture_mul(p, td ? d : NULL, ts ? s : NULL, &t);
        shade_batch_set_terms(out, i, &t);
    }
}

int shade_light_incident(const light *l, vec3 x, vec3 *to_light, vec3 *e_perp, float *atten)
{
    if (l->kind == LIGHT_SUN) {
        *to_light = v3_neg(v3_norm(l->direction));
        *e_perp = l->intensity;
        *atten = 1.0f;
        return 1;
    }
    vec3 d = v3_sub(l->position, x);
    float d2 = v3_dot(d, d);
    float fd;
    *to_light = v3s(0.0f);
    *e_perp = v3s(0.0f);
    *atten = 0.0f;
    /* Outside the float band (shade.h) the distance is taken in double. */
    if (d2 > SHADE_D2_MIN && d2 < SHADE_D2_MAX) {
        fd = sqrtf(d2);
        *to_light = v3_scale(d, 1.0f / fd);
    } else {
        dvec3 dd = dv3_sub(dv3_from(l->position), dv3_from(x));
        double dist = dv3_len(dd);
        /* A light exactly at the shaded point has no direction; it lights nothing there. */
        if (!(dist > 0.0))
            return 0;
        *to_light = v3_from_d(dv3_scale(dd, 1.0 / dist));
        fd = dist < 3e38 ? (float)dist : 3e38f;
    }
    *atten = d3d_attenuation(l, fd) * d3d_spot(l, v3_neg(*to_light));
    *e_perp = v3_scale(l->intensity, *atten);
    return *atten > 0.0f;
}

/* Direct3D fixed function (docs/models.md §1). The flags are compile-time constants in each
 * wrapper below, so every specialised path is its own branch-free loop body. */
static inline void shade_d3d_impl(const shade_context *c, const material *m, vec3 x, vec3 n, vec3 v, shade_terms *out,
                                  const int specular, const int ambient)
{
    const d3d_params *d = &m->d3d;
    vec3 diffuse = ambient ? v3_mul(d->ambient, c->s->global_ambient) : v3s(0.0f);
    vec3 spec = v3s(0.0f);
    for (int i = 0; i < c->s->n_lights; i++) {
        const light *l = &c->s->lights[i];
        vec3 to_l, e_perp;
        float atten;
        if (!shade_light_incident(l, x, &to_l, &e_perp, &atten))
            continue;
        if (ambient)
            diffuse = v3_add(diffuse, v3_scale(v3_mul(d->ambient, l->ambient), atten));
        float n_l = v3_dot(n, to_l);
        /* D3D lights nothing, not even the highlight, from behind the surface. */
        if (n_l <= 0.0f)
            continue;
        /* The D3D model has no 1/pi: its light colour is E/pi (docs/conventions.md#direct3d-light-colours). */
        vec3 colour = v3_scale(e_perp, FORMULA_INV_PI_F);
        diffuse = v3_add(diffuse, v3_scale(v3_mul(d->diffuse, colour), d3d_lambert(n_l)));
        if (specular) {
            vec3 h = d3d_half_vector(to_l, v, c->e_inf, d->local_viewer);
            spec = v3_add(spec, v3_scale(v3_mul(d->specular, colour), d3d_blinn(v3_dot(n, h), d->power)));
        }
    }
    vec3 emission = d->emissive;
    if (d->clamp) {
        /* D3D saturates Dv (which holds the emissive colour) and Sv to [0, 1] separately. */
        emission = v3(fminf(emission.x, 1.0f), fminf(emission.y, 1.0f), fminf(emission.z, 1.0f));
        vec3 room = v3_sub(v3s(1.0f), emission);
        diffuse = v3(fminf(diffuse.x, room.x), fminf(diffuse.y, room.y), fminf(diffuse.z, room.z));
        spec = v3(fminf(spec.x, 1.0f), fminf(spec.y, 1.0f), fminf(spec.z, 1.0f));
    }
    out->diffuse = diffuse;
    out->specular = spec;
    out->reflection = v3s(0.0f);
    out->emission = emission;
    out->alpha = 1.0f;
}

void shade_d3d_diffuse(const shade_context *c, const shade_plan *p, vec3 x, vec3 n, vec3 v, shade_terms *out)
{
    shade_d3d_impl(c, p->mat, x, n, v, out, 0, 0);
}

void shade_d3d_full(const shade_context *c, const shade_plan *p, vec3 x, vec3 n, vec3 v, shade_terms *out)
{
    shade_d3d_impl(c, p->mat, x, n, v, out, 1, 1);
}

/* dissolve: the texture coordinates (tu, tv) offset the mirror direction (source 000's Dissolve,
 * d3d9client_dissolve_offset); env_lookup takes the sum as it is, unnormalised, as a cube-map
 * lookup does. The Fresnel R keeps the unperturbed N.V: the effect moves only where phi is read. */
static inline void shade_d3d9client_impl(const shade_context *c, const shade_plan *p, vec3 x, vec3 n, vec3 v, float tu,
                                         float tv, shade_terms *out, const int dissolve)
{
    const material *m = p->mat;
    shade_d3d_impl(c, m, x, n, v, out, 1, 1);
    vec3 dir = v3_reflect(v, n);
    if (dissolve)
        dir = v3_add(dir, d3d9client_dissolve_offset(&m->d9, tu, tv));
    vec3 phi = env_lookup(c->env, dir);
    /* Equation (8) takes the sun's angle sigma from geometry alone: a main light that gives
     * nothing here (outside its cone or range) still has a direction. */
    float n_sun = 0.0f;
    const light *sun = m->d9.sun_angle ? scene_main_light(c->s) : NULL;
    if (sun != NULL) {
        vec3 to_l, e_perp;
        float atten;
        shade_light_incident(sun, x, &to_l, &e_perp, &atten);
        n_sun = v3_dot(n, to_l);
    }
    d3d9client_result r;
    d3d9client_combine(&m->d9, out->diffuse, m->d9.alpha, phi, v3_dot(n, v), n_sun, &r);
    /* The diffuse layer from its own factors, not rgb - R_tot: that difference cancels to 0
     * when an HDR environment makes R_tot much larger than d. */
    out->diffuse = v3_scale(out->diffuse, r.diffuse_scale);
    out->reflection = r.r_tot;
    out->alpha = r.alpha;
}

void shade_d3d9client(const shade_context *c, const shade_plan *p, vec3 x, vec3 n, vec3 v, shade_terms *out)
{
    shade_d3d9client_impl(c, p, x, n, v, 0.0f, 0.0f, out, 0);
}

void shade_d3d9client_dissolve(const shade_context *c, const shade_plan *p, vec3 x, vec3 n, vec3 v, float tu, float tv,
                               shade_terms *out)
{
    shade_d3d9client_impl(c, p, x, n, v, tu, tv, out, 1);
}

static inline void shade_ct_impl(const shade_context *c, const material *m, vec3 x, vec3 n, vec3 v, shade_terms *out,
                                 const int reflection)
{
    vec3 diffuse = v3s(0.0f), spec = v3s(0.0f);
    vec3 kd = v3_scale(m->albedo, FORMULA_INV_PI_F);
    for (int i = 0; i < c->s->n_lights; i++) {
        vec3 to_l, e_perp;
        float atten;
        if (!shade_light_incident(&c->s->lights[i], x, &to_l, &e_perp, &atten))
            continue;
        float n_l = v3_dot(n, to_l);
        if (n_l <= 0.0f)
            continue;
        diffuse = v3_add(diffuse, v3_scale(v3_mul(kd, e_perp), n_l));
        spec = v3_add(spec, v3_mul(cooktorrance_specular(&m->ct, n, v, to_l, m), e_perp));
    }
    out->diffuse = diffuse;
    out->specular = spec;
    out->reflection = reflection ? v3_mul(env_lookup(c->env, v3_reflect(v, n)),
                                          cooktorrance_reflection_weight(&m->ct, v3_dot(n, v), m))
                                 : v3s(0.0f);
    out->emission = m->d3d.emissive;
    out->alpha = 1.0f;
}

void shade_ct_lights(const shade_context *c, const shade_plan *p, vec3 x, vec3 n, vec3 v, shade_terms *out)
{
    shade_ct_impl(c, p->mat, x, n, v, out, 0);
}

void shade_ct_full(const shade_context *c, const shade_plan *p, vec3 x, vec3 n, vec3 v, shade_terms *out)
{
    shade_ct_impl(c, p->mat, x, n, v, out, 1);
}

/* A user's model (model/user_model.h): its BRDF f per light, times E N.L, in double as the
 * interface passes it; shade_batch_user below is its batch form, to the bit. Lights only: no
 * environment term; the material's emissive colour as for every model. */
void shade_user(const shade_context *c, const shade_plan *p, vec3 x, vec3 n, vec3 v, shade_terms *out)
{
    const material *m = p->mat;
    dvec3 diffuse = dv3(0, 0, 0), spec = dv3(0, 0, 0);
    dvec3 nd = dv3_norm(dv3_from(n)), vd = dv3_norm(dv3_from(v));
    for (int i = 0; i < c->s->n_lights; i++) {
        vec3 to_l, e_perp;
        float atten;
        if (!shade_light_incident(&c->s->lights[i], x, &to_l, &e_perp, &atten))
            continue;
        reflcheck_user_output o;
        dvec3 ld = dv3_norm(dv3_from(to_l));
        if (!user_model_eval(m->user.model, m->user.params, nd, vd, ld, dv3_from(m->albedo), &o))
            continue;
        dvec3 e = dv3_scale(dv3_from(e_perp), dv3_dot(nd, ld));
        diffuse = dv3_add(diffuse, dv3_mul(dv3(o.diffuse[0], o.diffuse[1], o.diffuse[2]), e));
        spec = dv3_add(spec, dv3_mul(dv3(o.specular[0], o.specular[1], o.specular[2]), e));
    }
    out->diffuse = v3_from_d(diffuse);
    out->specular = v3_from_d(spec);
    out->reflection = v3s(0.0f);
    out->emission = m->d3d.emissive;
    out->alpha = 1.0f;
}

/* The user model over a batch (shade_plan.c installs it for MODEL_USER): shade_user's arithmetic
 * on every lane, bit for bit (tests/test_shade_batch.c compares them lane by lane), arranged so that
 * the per-sample work around the model's eval is done once per batch pass, not once per call:
 * the double geometry (the unit N, V, L and H and their cosines, user_model_eval's inputs) runs
 * in lane loops the compiler vectorises, and only eval itself is called lane by lane. In a fit of
 * user_ggx that work was 61 % of each evaluation, and the fit now takes 40 % less CPU (docs/fits.md). */
typedef struct {
    double x[SHADE_BATCH], y[SHADE_BATCH], z[SHADE_BATCH];
} shade_user_dv;

static inline dvec3 shade_user_dv_get(const shade_user_dv *a, int i) { return dv3(a->x[i], a->y[i], a->z[i]); }
static inline void shade_user_dv_set(shade_user_dv *a, int i, dvec3 v)
{
    a->x[i] = v.x;
    a->y[i] = v.y;
    a->z[i] = v.z;
}

/* One light's geometry per lane: what user_model_eval derives from (N, V, L) before it calls
 * eval, with its guard (N.L > 0 and N.V > 0) in go[i], and the irradiance factor shade_user
 * multiplies eval's output by (E N.L, N.L before the clamp). The same inline functions in the
 * same order as user_model_eval and shade_user, so each lane's doubles are theirs: ISO C mode
 * contracts no a*b+c and the vector forms of +, *, / and sqrt round as the scalar ones. */
typedef struct {
    shade_user_dv nd, vd, ld, h, e;
    double n_l[SHADE_BATCH], n_v[SHADE_BATCH];
    unsigned char go[SHADE_BATCH];
} shade_user_geom;

SMATH_CLONES
static void shade_user_light_geom(shade_user_geom *g, const shade_vec3_n *to_l, const shade_vec3_n *e_perp,
                                  const unsigned char *lit, int n)
{
    for (int i = 0; i < n; i++) {
        const dvec3 nd = shade_user_dv_get(&g->nd, i), vd = shade_user_dv_get(&g->vd, i);
        const dvec3 ld = dv3_norm(dv3_from(shade_lane_get(to_l, i)));
        const double n_l = dv3_dot(nd, ld), n_v = dv3_dot(nd, vd);
        shade_user_dv_set(&g->ld, i, ld);
        shade_user_dv_set(&g->h, i, user_model_half(nd, vd, ld));
        shade_user_dv_set(&g->e, i, dv3_scale(dv3_from(shade_lane_get(e_perp, i)), n_l));
        g->n_l[i] = n_l;
        g->n_v[i] = n_v;
        g->go[i] = lit[i] && n_l > 0.0 && n_v > 0.0;
    }
}

/* eval's input as user_model_eval makes it (user_model_input), eval called for the lanes the
 * guard lets through; o[i] zero else. */
static void shade_user_light_eval(const reflcheck_user_model *um, const double *params, dvec3 albedo,
                                  const shade_user_geom *g, int n, reflcheck_user_output *o)
{
    memset(o, 0, (size_t)n * sizeof *o);
    reflcheck_user_input in;
    in.albedo[0] = albedo.x;
    in.albedo[1] = albedo.y;
    in.albedo[2] = albedo.z;
    for (int i = 0; i < n; i++) {
        if (!g->go[i])
            continue;
        user_model_input(&in, shade_user_dv_get(&g->nd, i), shade_user_dv_get(&g->vd, i), shade_user_dv_get(&g->ld, i),
                         shade_user_dv_get(&g->h, i), g->n_l[i], g->n_v[i]);
        um->eval(&in, params, &o[i]);
    }
}

/* Sums E N.L times eval's output into the lanes' totals, as shade_user's dv3_add(dv3_mul()). */
SMATH_CLONES
static void shade_user_light_sum(const shade_user_geom *g, const reflcheck_user_output *o, int n,
                                 shade_user_dv *diffuse, shade_user_dv *spec)
{
    for (int i = 0; i < n; i++) {
        if (!g->go[i])
            continue;
        const dvec3 e = shade_user_dv_get(&g->e, i);
        shade_user_dv_set(
            diffuse, i,
            dv3_add(shade_user_dv_get(diffuse, i), dv3_mul(dv3(o[i].diffuse[0], o[i].diffuse[1], o[i].diffuse[2]), e)));
        shade_user_dv_set(
            spec, i,
            dv3_add(shade_user_dv_get(spec, i), dv3_mul(dv3(o[i].specular[0], o[i].specular[1], o[i].specular[2]), e)));
    }
}

SMATH_CLONES
static void shade_user_unit(const shade_batch_in *in, shade_user_geom *g, shade_user_dv *diffuse, shade_user_dv *spec)
{
    for (int i = 0; i < in->n; i++) {
        shade_user_dv_set(&g->nd, i, dv3_norm(dv3_from(shade_lane_get(&in->nrm, i))));
        shade_user_dv_set(&g->vd, i, dv3_norm(dv3_from(shade_lane_get(&in->v, i))));
        shade_user_dv_set(diffuse, i, dv3(0, 0, 0));
        shade_user_dv_set(spec, i, dv3(0, 0, 0));
    }
}

/* shade_light_incident over the lanes for a point light (its float path, then d3d_attenuation's
 * double formula, d3d_spot being 1 for a point light): the same inline functions in the same
 * order, so each lane's to_l, e_perp and lit are the scalar call's. A lane whose squared distance
 * is outside the scalar path's float range (it takes the distance in double there) is left to
 * shade_light_incident itself: odd[i] set. Returns how many lanes are odd. */
SMATH_CLONES
static int shade_user_point(const light *l, const shade_vec3_n *x, int n, shade_vec3_n *to_l, shade_vec3_n *e_perp,
                            unsigned char *lit, unsigned char *odd)
{
    int n_odd = 0;
    for (int i = 0; i < n; i++) {
        const vec3 d = v3_sub(l->position, shade_lane_get(x, i));
        const float d2 = v3_dot(d, d);
        const int in_range = d2 > SHADE_D2_MIN && d2 < SHADE_D2_MAX;
        const float fd = sqrtf(d2);
        const double dd = fd;
        const float atten = (float)formula_attenuation_d(l->a0, l->a1, l->a2, dd, dd * dd, l->range);
        shade_lane_set(to_l, i, v3_scale(d, 1.0f / fd));
        shade_lane_set(e_perp, i, v3_scale(l->intensity, atten));
        lit[i] = atten > 0.0f;
        odd[i] = !in_range;
        n_odd += !in_range;
    }
    return n_odd;
}

/* One light's incidence on every lane, as shade_user takes it from shade_light_incident. */
static void shade_user_incident(const light *l, const shade_vec3_n *x, int n, shade_vec3_n *to_l, shade_vec3_n *e_perp,
                                unsigned char *lit)
{
    unsigned char odd[SHADE_BATCH];
    int n_odd = n;
    if (l->kind == LIGHT_POINT)
        n_odd = shade_user_point(l, x, n, to_l, e_perp, lit, odd);
    else
        memset(odd, 1, (size_t)n);
    for (int i = 0; n_odd > 0 && i < n; i++) {
        if (!odd[i])
            continue;
        vec3 tl, ep;
        float atten;
        lit[i] = (unsigned char)shade_light_incident(l, shade_lane_get(x, i), &tl, &ep, &atten);
        shade_lane_set(to_l, i, tl);
        shade_lane_set(e_perp, i, ep);
    }
}

void shade_batch_user(const shade_context *c, const shade_plan *p, const shade_batch_in *in, shade_batch_out *out)
{
    const material *m = p->mat;
    const int n = in->n;
    /* About 70 KiB of lanes, on the calling thread's stack (default-sized threads: render_keep_run, raster.c). */
    shade_user_geom g;
    shade_user_dv diffuse, spec;
    shade_vec3_n to_l, e_perp;
    unsigned char lit[SHADE_BATCH];
    reflcheck_user_output o[SHADE_BATCH];
    shade_user_unit(in, &g, &diffuse, &spec);
    for (int l = 0; l < c->s->n_lights; l++) {
        shade_user_incident(&c->s->lights[l], &in->x, n, &to_l, &e_perp, lit);
        shade_user_light_geom(&g, &to_l, &e_perp, lit, n);
        shade_user_light_eval(m->user.model, m->user.params, dv3_from(m->albedo), &g, n, o);
        shade_user_light_sum(&g, o, n, &diffuse, &spec);
    }
    for (int i = 0; i < n; i++) {
        shade_lane_set(&out->diffuse, i, v3_from_d(shade_user_dv_get(&diffuse, i)));
        shade_lane_set(&out->specular, i, v3_from_d(shade_user_dv_get(&spec, i)));
        shade_lane_set(&out->reflection, i, v3s(0.0f));
        shade_lane_set(&out->emission, i, m->d3d.emissive);
        out->alpha[i] = 1.0f;
    }
}
