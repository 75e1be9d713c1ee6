/* povray.c - POV-Ray 3.7 SDL writer, command line, runner and box filter (see povray.h).
 *
 * The SDL facts used here (finish defaults are not zero, fade law, spot profile, camera
 * handedness, sky_sphere orientation, half-float EXR) are those of docs/conventions.md;
 * tests/test_povray.c renders each one and checks it against an independent formula.
 */
#define _POSIX_C_SOURCE 200809L
#include "povray.h"

#include <errno.h>
#include <fcntl.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "d3d.h"
#include "d3d9client.h"
#include "formula.h"
#include "exr.h"
#include "frame.h"
#include "runner.h"

/* ---- resolved options ---------------------------------------------------------------- */

typedef struct {
    int validate; /* physical material instead of the model twin */
    unsigned term;
    int k;
    int max_trace_level;
    double fade_ratio;
    double scale;
} povray_resolved;

static rc_status povray_resolve(const scene *s, const povray_options *o, povray_resolved *r, const char *where,
                                char *err, size_t errlen)
{
    povray_options zero = {0};
    if (!o)
        o = &zero;
    r->validate = o->role == ROLE_VALIDATE || o->role == ROLE_AGREE;
    r->term = o->term ? o->term : POVRAY_TERM_ALL;
    r->k = o->supersample > 0 ? o->supersample : (s && s->supersample > 0 ? s->supersample : 1);
    r->max_trace_level = o->max_trace_level > 0 ? o->max_trace_level : 2;
    r->fade_ratio = o->fade_ratio > 0.0 ? o->fade_ratio : 1e-3;
    r->scale = o->output_scale > 0.0 ? o->output_scale : 1.0;
    if ((r->term & ~(unsigned)POVRAY_TERM_ALL) || o->supersample < 0 || o->threads < 0 || o->max_trace_level < 0 ||
        !(o->fade_ratio >= 0.0 && o->fade_ratio < 1.0) || !(o->output_scale >= 0.0 && isfinite(o->output_scale))) {
        status_message(err, errlen,
                       "%s: povray_options: term must be a POVRAY_TERM_* mask, supersample/threads/"
                       "max_trace_level >= 0, fade_ratio in [0, 1), output_scale finite >= 0",
                       where);
        return RC_ERR_RANGE;
    }
    return RC_OK;
}

/* ---- geometry helpers ------------------------------------------------------------------ */

/* Distance from p to triangle abc (closest point by Voronoi regions, Ericson 5.1.5). */
static double povray_point_tri_dist(dvec3 p, dvec3 a, dvec3 b, dvec3 c)
{
    dvec3 ab = dv3_sub(b, a), ac = dv3_sub(c, a), ap = dv3_sub(p, a);
    double d1 = dv3_dot(ab, ap), d2 = dv3_dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0)
        return dv3_len(ap);
    dvec3 bp = dv3_sub(p, b);
    double d3 = dv3_dot(ab, bp), d4 = dv3_dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3)
        return dv3_len(bp);
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        double v = d1 / (d1 - d3);
        return dv3_len(dv3_sub(p, dv3_add(a, dv3_scale(ab, v))));
    }
    dvec3 cp = dv3_sub(p, c);
    double d5 = dv3_dot(ab, cp), d6 = dv3_dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6)
        return dv3_len(cp);
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        double w = d2 / (d2 - d6);
        return dv3_len(dv3_sub(p, dv3_add(a, dv3_scale(ac, w))));
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return dv3_len(dv3_sub(p, dv3_add(b, dv3_scale(dv3_sub(c, b), w))));
    }
    double denom = 1.0 / (va + vb + vc);
    double v = vb * denom, w = vc * denom;
    dvec3 q = dv3_add(a, dv3_add(dv3_scale(ab, v), dv3_scale(ac, w)));
    return dv3_len(dv3_sub(p, q));
}

/* Nearest and farthest distance from p to the mesh (the farthest is at a vertex, since the
 * distance is convex over each triangle). */
static void povray_mesh_dist(const mesh *m, vec3 p, double *dmin, double *dmax)
{
    dvec3 q = dv3_from(p);
    double lo = INFINITY, hi = 0.0;
    for (int t = 0; t < m->n_tris; t++) {
        dvec3 a = dv3_from(m->pos[m->idx[3 * t]]);
        dvec3 b = dv3_from(m->pos[m->idx[3 * t + 1]]);
        dvec3 c = dv3_from(m->pos[m->idx[3 * t + 2]]);
        double d = povray_point_tri_dist(q, a, b, c);
        if (d < lo)
            lo = d;
    }
    for (int v = 0; v < m->n_verts; v++) {
        double d = dv3_len(dv3_sub(dv3_from(m->pos[v]), q));
        if (d > hi)
            hi = d;
    }
    *dmin = lo;
    *dmax = hi;
}

static void povray_mesh_bounds(const mesh *m, dvec3 *centre, double *radius)
{
    dvec3 lo = dv3(INFINITY, INFINITY, INFINITY), hi = dv3(-INFINITY, -INFINITY, -INFINITY);
    for (int v = 0; v < m->n_verts; v++) {
        dvec3 p = dv3_from(m->pos[v]);
        lo = dv3(fmin(lo.x, p.x), fmin(lo.y, p.y), fmin(lo.z, p.z));
        hi = dv3(fmax(hi.x, p.x), fmax(hi.y, p.y), fmax(hi.z, p.z));
    }
    if (m->n_verts == 0) {
        *centre = dv3(0, 0, 0);
        *radius = 1.0;
        return;
    }
    *centre = dv3_scale(dv3_add(lo, hi), 0.5);
    *radius = 0.5 * dv3_len(dv3_sub(hi, lo));
}

static int povray_finite3(vec3 v) { return isfinite(v.x) && isfinite(v.y) && isfinite(v.z); }

/* ---- lights ---------------------------------------------------------------------------- */

/* How one light is written: colour, fade law, and the distance-independent part of its
 * attenuation when there is one (for the D3D ambient term Va*La*A). */
typedef struct {
    int skip;             /* the whole mesh lies beyond the light's range */
    dvec3 colour;         /* POV-Ray light colour */
    double fade_distance; /* 0 = no fade */
    int fade_power;
    int constant_atten; /* A does not depend on the distance */
    double atten;       /* that constant A */
} povray_light;

static rc_status povray_light_convert(const scene *s, const mesh *m, int i, const povray_resolved *r, povray_light *pl,
                                      char *err, size_t errlen)
{
    const light *l = &s->lights[i];
    memset(pl, 0, sizeof *pl);
    int needs_dir = l->kind == LIGHT_SUN || l->kind == LIGHT_SPOT;
    /* POV-Ray's falloff is a half angle, which must stay below 90 degrees. */
    if (!povray_finite3(l->intensity) || !povray_finite3(l->position) || !povray_finite3(l->direction) ||
        (needs_dir && v3_len(l->direction) == 0.0f) ||
        (l->kind == LIGHT_SPOT && !(l->inner >= 0.0f && l->inner <= l->outer && (double)l->outer < FORMULA_PI_D))) {
        status_message(err, errlen,
                       "%s: lights[%d]: intensity/position/direction must be finite, a sun or spot "
                       "direction non-zero, and a spot's 0 <= inner <= outer < 180 degrees",
                       s->path, i);
        return RC_ERR_RANGE;
    }
    dvec3 c = dv3_scale(dv3_from(l->intensity), r->scale / FORMULA_PI_D);
    if (l->kind == LIGHT_SUN) {
        pl->colour = c;
        pl->constant_atten = 1;
        pl->atten = 1.0;
        return RC_OK;
    }
    if (l->kind == LIGHT_SPOT && l->profile != SPOT_SMOOTH) {
        status_message(err, errlen,
                       "%s: lights[%d]: a spot with profile d3d (power law) has no POV-Ray equivalent; "
                       "use profile smooth",
                       s->path, i);
        return RC_ERR_RANGE;
    }
    double dmin, dmax;
    povray_mesh_dist(m, l->position, &dmin, &dmax);
    if (isfinite(l->range)) {
        if (dmin > l->range) {
            pl->skip = 1;
            return RC_OK;
        }
        if (dmax > l->range) {
            status_message(err, errlen,
                           "%s: lights[%d]: range %g m cuts through the geometry (%g..%g m away) and "
                           "POV-Ray has no light range; set range to infinity or beyond %g m",
                           s->path, i, (double)l->range, dmin, dmax, dmax);
            return RC_ERR_RANGE;
        }
    }
    double a0 = l->a0, a1 = l->a1, a2 = l->a2;
    /* The nearest geometry sets the fade distance when a0 = 0: (D/d)^2 <= fade_ratio^2. */
    double dfade = r->fade_ratio * (dmin > 0.0 ? dmin : 1.0);
    if (a0 < 0.0 || a1 < 0.0 || a2 < 0.0 || !(a0 + a1 + a2 > 0.0)) {
        status_message(err, errlen, "%s: lights[%d]: attenuation a0, a1, a2 must be >= 0 and not all 0", s->path, i);
        return RC_ERR_RANGE;
    }
    if (a1 == 0.0 && a2 > 0.0) {
        /* 2/(1 + (d/D)^2) = 2 D^2/(D^2 + d^2): with D^2 = a0/a2 it is 2 a0/(a0 + a2 d^2). */
        pl->fade_power = 2;
        pl->fade_distance = a0 > 0.0 ? sqrt(a0 / a2) : dfade;
        pl->colour = dv3_scale(c, 1.0 / (2.0 * a2 * pl->fade_distance * pl->fade_distance));
    } else if (a2 == 0.0 && a1 > 0.0) {
        /* 2/(1 + d/D) = 2 D/(D + d): with D = a0/a1 it is 2 a0/(a0 + a1 d). */
        pl->fade_power = 1;
        pl->fade_distance = a0 > 0.0 ? a0 / a1 : dfade;
        pl->colour = dv3_scale(c, 1.0 / (2.0 * a1 * pl->fade_distance));
    } else if (a1 == 0.0 && a2 == 0.0) {
        pl->colour = dv3_scale(c, 1.0 / a0);
        pl->constant_atten = 1;
        pl->atten = 1.0 / a0;
    } else {
        status_message(err, errlen,
                       "%s: lights[%d]: attenuation with both a1 and a2 non-zero has no POV-Ray "
                       "fade law; set a1 = 0 or a2 = 0",
                       s->path, i);
        return RC_ERR_RANGE;
    }
    return RC_OK;
}

/* ---- materials ------------------------------------------------------------------------- */

typedef struct {
    dvec3 pigment;
    double diffuse;
    /* d3d.two_sided false: the back face (seen against its normal) has its own texture, lit
     * only through the surface (POV-Ray's diffuse Front, Back with Front 0). */
    int one_sided;
    dvec3 emission; /* POV-Ray's emission, which it multiplies by the pigment */
    double specular, roughness;
    int reflection; /* 0 none, 1 { min, max falloff p }, 2 { 0, 1 fresnel on } */
    dvec3 rmin, rmax;
    double falloff, ior;
    char texture[1200]; /* the diffuse texture's EXR, "" = the pigment colour */
} povray_finish;

static double povray_comp(dvec3 v, int c) { return c == 0 ? v.x : (c == 1 ? v.y : v.z); }

static int povray_is_zero(vec3 v) { return v.x == 0.0f && v.y == 0.0f && v.z == 0.0f; }

/* The model features a POV-Ray twin cannot express, checked in this order: RC_ERR_RANGE
 * naming the first one the material uses. */
static rc_status povray_twin_refusal(const scene *s, int mi, const povray_resolved *r, char *err, size_t errlen)
{
    const material *mat = &s->materials[mi];
    const d3d_params *d = &mat->d3d;
    const char *name = mat->name[0] ? mat->name : "(unnamed)";
    if (mat->model == MODEL_USER) {
        status_message(err, errlen,
                       "%s: materials[%d] '%s': model user (%s) has no POV-Ray twin: a twin needs a translator of "
                       "the user's model, which none was given; use role validate",
                       s->path, mi, name, mat->user.path);
        return RC_ERR_RANGE;
    }
    if (mat->model == MODEL_COOK_TORRANCE) {
        status_message(err, errlen,
                       "%s: materials[%d] '%s': model cook_torrance has no POV-Ray twin (no Beckmann "
                       "lobe); compare it against cycles, or use role validate",
                       s->path, mi, name);
        return RC_ERR_RANGE;
    }
    if (d->per_vertex || d->clamp) {
        status_message(err, errlen,
                       "%s: materials[%d] '%s': d3d.per_vertex and d3d.clamp have no POV-Ray twin; "
                       "set both to false for a twin comparison",
                       s->path, mi, name);
        return RC_ERR_RANGE;
    }
    if (mesh_material_unnormalised(s, mi)) {
        status_message(err, errlen,
                       "%s: materials[%d] '%s': d3d.normalize_normals false on a scaled object (D3D's "
                       "unnormalised normals) has no POV-Ray twin: POV-Ray normalises every normal; judge it "
                       "with role validate",
                       s->path, mi, name);
        return RC_ERR_RANGE;
    }
    int d9 = mat->model == MODEL_D3D9CLIENT;
    if (d3d9client_dissolve_on(mat)) {
        status_message(err, errlen,
                       "%s: materials[%d] '%s': d3d9client.dissolve (source 000's noise on the reflected "
                       "direction) has no POV-Ray twin: no renderer reproduces that noise; judge it with "
                       "role validate",
                       s->path, mi, name);
        return RC_ERR_RANGE;
    }
    if (d9 && mat->d9.blend) {
        status_message(err, errlen,
                       "%s: materials[%d] '%s': d3d9client.blend (eq. 7's alpha blend) has no POV-Ray twin: a "
                       "pigment's transmit cannot depend on the reflected environment; judge it with role validate",
                       s->path, mi, name);
        return RC_ERR_RANGE;
    }
    if (d9 && mat->d9.sun_angle) {
        status_message(err, errlen,
                       "%s: materials[%d] '%s': d3d9client.sun_angle (eq. 8) has no POV-Ray twin; "
                       "set it to false",
                       s->path, mi, name);
        return RC_ERR_RANGE;
    }
    if (!d->two_sided && (r->term & POVRAY_TERM_SPECULAR) && d->power > 0.0f && !povray_is_zero(d->specular)) {
        status_message(err, errlen,
                       "%s: materials[%d] '%s': d3d.two_sided false with a d3d.specular highlight has no POV-Ray "
                       "twin: D3D lights a back face's highlight from the far side, POV-Ray only its diffuse; "
                       "set d3d.specular to 0 or two_sided to true",
                       s->path, mi, name);
        return RC_ERR_RANGE;
    }
    return RC_OK;
}

/* The constant part: D3D ambient Va*(Ia + sum La*A) (diffuse term, scaled by keep = 1 - |lambda|
 * like all of d) and Ve. POV-Ray has it only as emission, times the pigment: f->emission is
 * that constant over f->pigment. */
static rc_status povray_twin_emission(const scene *s, int mi, const povray_light *lights, const povray_resolved *r,
                                      double keep, povray_finish *f, char *err, size_t errlen)
{
    const material *mat = &s->materials[mi];
    const d3d_params *d = &mat->d3d;
    const char *name = mat->name[0] ? mat->name : "(unnamed)";
    dvec3 amb = dv3_from(s->global_ambient);
    for (int i = 0; i < s->n_lights; i++) {
        if (povray_is_zero(s->lights[i].ambient) || povray_is_zero(d->ambient) || lights[i].skip)
            continue;
        if (!lights[i].constant_atten) {
            status_message(err, errlen,
                           "%s: materials[%d] '%s' with lights[%d]: the D3D ambient term Va*La*A(d) "
                           "varies with distance and POV-Ray cannot express it; set the light's ambient "
                           "or the material's d3d.ambient to 0",
                           s->path, mi, name, i);
            return RC_ERR_RANGE;
        }
        amb = dv3_add(amb, dv3_scale(dv3_from(s->lights[i].ambient), lights[i].atten));
    }
    dvec3 konst = dv3(0, 0, 0);
    if (r->term & POVRAY_TERM_DIFFUSE)
        konst = dv3_scale(dv3_mul(dv3_from(d->ambient), amb), keep * r->scale);
    if (r->term & POVRAY_TERM_EMISSION)
        konst = dv3_add(konst, dv3_scale(dv3_from(d->emissive), r->scale));
    double e[3];
    for (int c = 0; c < 3; c++) {
        double p = povray_comp(f->pigment, c), k = povray_comp(konst, c);
        if (k == 0.0)
            e[c] = 0.0;
        else if (p != 0.0)
            e[c] = k / p;
        else {
            status_message(err, errlen,
                           "%s: materials[%d] '%s': emissive/ambient colour on channel %d where the "
                           "POV-Ray pigment (d3d.diffuse%s) is 0; POV-Ray multiplies emission by the "
                           "pigment, so give that channel a non-zero diffuse",
                           s->path, mi, name, c, mat->model == MODEL_D3D9CLIENT ? " * (1 - |reflect|)" : "");
            return RC_ERR_RANGE;
        }
    }
    f->emission = dv3(e[0], e[1], e[2]);
    return RC_OK;
}

/* The Blinn-Phong highlight as POV-Ray's specular (a scalar, roughness 1 / power). */
static rc_status povray_twin_specular(const scene *s, int mi, const povray_resolved *r, povray_finish *f, char *err,
                                      size_t errlen)
{
    const material *mat = &s->materials[mi];
    const d3d_params *d = &mat->d3d;
    const char *name = mat->name[0] ? mat->name : "(unnamed)";
    f->specular = 0.0;
    f->roughness = 1.0;
    if ((r->term & POVRAY_TERM_SPECULAR) && d->power > 0.0f && !povray_is_zero(d->specular)) {
        if (!(d->specular.x == d->specular.y && d->specular.y == d->specular.z)) {
            status_message(err, errlen,
                           "%s: materials[%d] '%s': d3d.specular (%g, %g, %g) is not grey, and POV-Ray's "
                           "specular is a scalar times the light colour: this scene cannot be twinned; "
                           "use a grey specular",
                           s->path, mi, name, (double)d->specular.x, (double)d->specular.y, (double)d->specular.z);
            return RC_ERR_RANGE;
        }
        if (!d->local_viewer) {
            status_message(err, errlen,
                           "%s: materials[%d] '%s': d3d.local_viewer false (infinite viewer) has no "
                           "POV-Ray twin; set it to true",
                           s->path, mi, name);
            return RC_ERR_RANGE;
        }
        f->specular = d->specular.x;
        f->roughness = 1.0 / d->power;
    }
    return RC_OK;
}

/* The D3D9Client environment reflection as POV-Ray's variable reflection. */
static void povray_twin_reflection(const material *mat, const povray_resolved *r, povray_finish *f)
{
    f->reflection = 0;
    if (mat->model == MODEL_D3D9CLIENT && (r->term & POVRAY_TERM_REFLECTION)) {
        /* eq. 5: lambda + (s - lambda) R, R = R0 + m (1 - cos)^p, is POV-Ray's
         * Rmin + (Rmax - Rmin)(1 - cos)^falloff with these end points. */
        dvec3 lam = dv3_from(mat->d9.reflect), sc = dv3_from(mat->d9.fresnel_colour);
        dvec3 span = dv3_sub(sc, lam);
        f->rmin = dv3_add(lam, dv3_scale(span, mat->d9.r0));
        f->rmax = dv3_add(lam, dv3_scale(span, (double)mat->d9.r0 + mat->d9.m));
        f->falloff = mat->d9.p;
        if (dv3_dot(f->rmin, f->rmin) > 0.0 || dv3_dot(f->rmax, f->rmax) > 0.0)
            f->reflection = 1;
    }
}

static rc_status povray_material_twin(const scene *s, int mi, const povray_light *lights, const povray_resolved *r,
                                      povray_finish *f, char *err, size_t errlen)
{
    rc_status st = povray_twin_refusal(s, mi, r, err, errlen);
    if (st != RC_OK)
        return st;
    const material *mat = &s->materials[mi];
    const d3d_params *d = &mat->d3d;
    double keep = mat->model == MODEL_D3D9CLIENT
                      ? formula_d3d9_diffuse_weight_d(d3d9client_colour_norm_d(mat->d9.reflect, mat->d9.norm))
                      : 1.0;
    f->pigment = dv3_scale(dv3_from(d->diffuse), keep);
    f->diffuse = (r->term & POVRAY_TERM_DIFFUSE) ? 1.0 : 0.0;
    f->one_sided = !d->two_sided;
    if ((st = povray_twin_emission(s, mi, lights, r, keep, f, err, errlen)) != RC_OK)
        return st;
    if ((st = povray_twin_specular(s, mi, r, f, err, errlen)) != RC_OK)
        return st;
    povray_twin_reflection(mat, r, f);
    return RC_OK;
}

/* The conductor refusal, shared by the material writer and povray_physics. */
static rc_status povray_conductor_refusal(const scene *s, int mi, char *err, size_t errlen)
{
    const material *mat = &s->materials[mi];
    status_message(err, errlen,
                   "%s: materials[%d] '%s': a conductor needs the complex Fresnel equations, which "
                   "POV-Ray does not have (its `metallic` is an empirical curve); validate it "
                   "against cycles or the exact reference instead",
                   s->path, mi, mat->name[0] ? mat->name : "(unnamed)");
    return RC_ERR_RANGE;
}

rc_status povray_physics(const scene *s, physics *out, char *err, size_t errlen)
{
    const physics *want = &s->physics;
    int any_rough = 0, any_diffuse = 0;
    for (int mi = 0; mi < s->n_materials; mi++) {
        if (!scene_material_used(s, mi))
            continue;
        const material *mat = &s->materials[mi];
        if (mat->conductor)
            return povray_conductor_refusal(s, mi, err, errlen);
        if (mat->thin) {
            status_message(err, errlen,
                           "%s: materials[%d] '%s': thin (a thin glass sheet, both faces and their internal "
                           "reflections) is not translated for POV-Ray; compare it with the exact reference",
                           s->path, mi, mat->name);
            return RC_ERR_RANGE;
        }
        any_rough |= mat->lobe && mat->roughness > 0.0f;
        any_diffuse |= !povray_is_zero(mat->albedo);
    }
    unsigned all = s->n_lights >= 32 ? ~0u : (1u << s->n_lights) - 1u;
    int has_env = s->env.kind != ENV_NONE;
    *out = *want;
    /* `diffuse 1` takes every light, `diffuse 0` none: no mask in between. */
    if (any_diffuse)
        out->diffuse_lights = (want->diffuse_lights & all) ? PHYSICS_ALL_LIGHTS : 0u;
    /* No Beckmann lobe (`specular` is Phong-like): a rough lobe gets no highlight. A mirror's
     * highlight of a point or sun light is a delta, zero in every image, so any mask holds. */
    if (any_rough)
        out->specular_lights = 0u;
    /* `reflection` is a mirror: a rough lobe reflects no environment rather than a sharp one. */
    if (any_rough && has_env)
        out->env_specular = 0;
    /* No radiosity: the environment never lights the diffuse, nor does another object. */
    if (any_diffuse && has_env)
        out->env_diffuse = 0;
    out->interreflection = 0;
    out->bounces = 1;
    /* The diffuse is not weighted by what the reflection takes (checked: `fresnel on` over a
     * black sky leaves a lit plane's diffuse unchanged). */
    if (any_diffuse)
        out->diffuse_weight = PHYS_DIFFUSE_PLAIN;
    /* On a mirror every Fresnel form is rendered as asked (`fresnel on` is the exact F(N.V),
     * which is F(V.H) there; Schlick through falloff 5; F = 1 as reflection 1); on a rough lobe
     * the lobes are gone (above), so their Fresnel form is moot. Shadows as asked. */
    return RC_OK;
}

static rc_status povray_material_physical(const scene *s, int mi, const povray_resolved *r, povray_finish *f, char *err,
                                          size_t errlen)
{
    const material *mat = &s->materials[mi];
    const physics *ph = &s->physics;
    unsigned all = s->n_lights >= 32 ? ~0u : (1u << s->n_lights) - 1u;
    if (mat->conductor)
        return povray_conductor_refusal(s, mi, err, errlen);
    f->pigment = dv3_from(mat->albedo);
    f->diffuse = (r->term & POVRAY_TERM_DIFFUSE) && (ph->diffuse_lights & all) ? 1.0 : 0.0;
    f->one_sided = 0; /* the physics lights both sides (FORMAT.md, two_sided) */
    f->emission = dv3(0, 0, 0);
    /* A smooth dielectric's highlight from a point or sun light is a delta lobe: nothing to
     * render with `specular`, so it is left out (povray_physics says so for a rough lobe). */
    f->specular = 0.0;
    f->roughness = 1.0;
    f->reflection = 0;
    f->rmin = dv3(0, 0, 0);
    f->rmax = dv3(1, 1, 1);
    f->falloff = 1.0;
    f->ior = mat->ior;
    if (!(r->term & POVRAY_TERM_REFLECTION) || !ph->env_specular || !mat->lobe || mat->roughness > 0.0f)
        return RC_OK;
    switch (ph->fresnel_reflection) {
    case PHYS_FRESNEL_EXACT:
    case PHYS_FRESNEL_NV: f->reflection = 2; break;
    case PHYS_FRESNEL_ONE:
        f->reflection = 1;
        f->rmin = dv3(1, 1, 1);
        break;
    case PHYS_FRESNEL_SCHLICK: {
        /* POV-Ray's Rmin + (Rmax - Rmin)(1 - cos)^falloff is Schlick's form exactly. */
        double f0 = ((double)mat->ior - 1.0) / ((double)mat->ior + 1.0);
        f->reflection = 1;
        f->rmin = dv3(f0 * f0, f0 * f0, f0 * f0);
        f->falloff = 5.0;
        break;
    }
    }
    if (f->reflection == 2 && !(mat->ior >= 1.0f && isfinite(mat->ior))) {
        status_message(err, errlen,
                       "%s: materials[%d]: ior %g must be finite and >= 1 for POV-Ray's "
                       "fresnel reflection",
                       s->path, mi, (double)mat->ior);
        return RC_ERR_RANGE;
    }
    return RC_OK;
}

/* ---- SDL writing ----------------------------------------------------------------------- */

static void povray_put_vec(FILE *fp, dvec3 v) { fprintf(fp, "<%.9g, %.9g, %.9g>", v.x, v.y, v.z); }

static void povray_put_fvec(FILE *fp, vec3 v)
{
    fprintf(fp, "<%.9g, %.9g, %.9g>", (double)v.x, (double)v.y, (double)v.z);
}

/* A textured material: the pigment becomes the texture (texel colour), and the material colour
 * the finish's diffuse, which must then be grey; emission and ambient, which POV-Ray multiplies
 * by the pigment, stay as the unscaled colour, since our texture multiplies those terms too. */
static rc_status povray_material_texture(const scene *s, int mi, const povray_options *o, const mesh *m,
                                         povray_finish *f, char *err, size_t errlen)
{
    const material *mat = &s->materials[mi];
    const char *name = mat->name[0] ? mat->name : "(unnamed)";
    f->texture[0] = '\0';
    if (mat->texture[MAT_TEX_SPECULAR][0] != '\0') {
        status_message(err, errlen,
                       "%s: materials[%d] '%s': texture.specular has no POV-Ray form (its specular is one "
                       "number per finish); compare it against cycles",
                       s->path, mi, name);
        return RC_ERR_RANGE;
    }
    if (mat->texture[MAT_TEX_DIFFUSE][0] == '\0')
        return RC_OK;
    if (o == NULL || o->texture_dir == NULL || m->uv == NULL) {
        status_message(err, errlen,
                       "%s: materials[%d] '%s': textured, but no texture folder (povray_options.texture_dir) or "
                       "mesh UVs were given; render it through povray_render_job",
                       s->path, mi, name);
        return RC_ERR_RANGE;
    }
    dvec3 p = f->pigment;
    if (!(p.x == p.y && p.y == p.z)) {
        status_message(err, errlen,
                       "%s: materials[%d] '%s': a texture times the non-grey colour (%g, %g, %g) has no POV-Ray "
                       "form (the image is the pigment, the colour a scalar diffuse); use a grey diffuse colour",
                       s->path, mi, name, p.x, p.y, p.z);
        return RC_ERR_RANGE;
    }
    f->emission = dv3_mul(f->emission, f->pigment);
    f->diffuse *= p.x;
    f->pigment = dv3(1, 1, 1);
    snprintf(f->texture, sizeof f->texture, "%s/tex%d_diffuse.exr", o->texture_dir, mi);
    return RC_OK;
}

/* kw is "texture", or "interior_texture" for a mesh2's other side; back 1: the finish of a
 * one-sided material's back face, lit only through the surface. */
static void povray_write_finish_as(FILE *fp, const povray_finish *f, const char *kw, int back)
{
    if (f->texture[0] != '\0') {
        /* interpolate 2: bilinear; repeat is image_map's default (no `once`). */
        fprintf(fp, "    %s {\n      uv_mapping pigment { image_map { exr \"%s\" interpolate 2 } }", kw, f->texture);
    } else {
        fprintf(fp, "    %s {\n      pigment { color rgb ", kw);
        povray_put_vec(fp, f->pigment);
        fprintf(fp, " }");
    }
    fprintf(fp, "\n      finish {\n        ambient 0\n        emission rgb ");
    povray_put_vec(fp, f->emission);
    fprintf(fp, "\n        diffuse %.9g", back ? 0.0 : f->diffuse);
    /* diffuse Front, Back: Back lights the side away from the light with the same cosine. */
    if (back)
        fprintf(fp, ", %.9g", f->diffuse);
    fprintf(fp, "\n        brilliance 1\n        crand 0\n");
    fprintf(fp, "        specular %.9g\n        roughness %.9g\n        phong 0\n        metallic 0\n", f->specular,
            f->roughness);
    if (f->reflection == 1) {
        fprintf(fp, "        reflection { color rgb ");
        povray_put_vec(fp, f->rmin);
        fprintf(fp, ", color rgb ");
        povray_put_vec(fp, f->rmax);
        fprintf(fp, " falloff %.9g exponent 1 metallic 0 }\n", f->falloff);
    } else if (f->reflection == 2) {
        fprintf(fp, "        reflection { 0, 1 fresnel on exponent 1 metallic 0 }\n");
    } else {
        fprintf(fp, "        reflection 0\n");
    }
    fprintf(fp, "      }\n    }\n");
    if (f->reflection == 2)
        fprintf(fp, "    interior { ior %.9g }\n", f->ior);
}

static void povray_write_finish(FILE *fp, const povray_finish *f)
{
    if (!f->one_sided) {
        povray_write_finish_as(fp, f, "texture", 0);
        return;
    }
    /* POV-Ray gives a mesh2 face's interior_texture to the side its winding's normal points to
     * (counter-clockwise seen from there, as mesh.c winds toward the normal), `texture` to the
     * other: the normal side is lit as usual, the back face only by lights beyond it. Either
     * side's normal is turned toward the ray, so Back's cosine is the given normal's N.L. */
    povray_write_finish_as(fp, f, "texture", 1);
    povray_write_finish_as(fp, f, "interior_texture", 0);
}

/* D3D vertex colours POV-Ray can twin: the diffuse colour from colour1 (a mesh2 texture_list of
 * one pigment per vertex, interpolated across each face), nothing else from the vertex. */
static rc_status povray_vertex_colour_check(const scene *s, const mesh *m, int mi, const povray_resolved *r, char *err,
                                            size_t errlen)
{
    const material *mat = &s->materials[mi];
    unsigned have = 0;
    for (int i = 0; i < s->n_objects && i < SCENE_MAX_OBJECTS; i++)
        if (s->objects[i].material == mi)
            have |= m->colours[i];
    d3d_params rest = mat->d3d;
    rest.diffuse_source = COLOUR_SOURCE_MATERIAL;
    const char *why = r->validate ? "a validate renders the physics, which has no vertex colours"
                      : mat->d3d.diffuse_source != COLOUR_SOURCE_COLOUR1 || d3d_uses_vertex_colours(&rest, have)
                          ? "POV-Ray's twin takes the diffuse colour alone from the vertex (diffuse_source colour1)"
                          : NULL;
    if (why == NULL)
        return RC_OK;
    status_message(err, errlen, "%s: materials[%d] '%s': D3D vertex colours (d3d.colour_vertex): %s; %s", s->path, mi,
                   mat->name, why, r->validate ? "set colour_vertex false" : "select the material for the others");
    return RC_ERR_RANGE;
}

/* A Direct3D cube map as a sky_sphere pigment (scene/env.h), written from the D3DCUBEMAP_FACES
 * table itself rather than through our lookup, so the twin checks the table: POV-Ray's canonical
 * frame is ours, D3D Z = -z. Per face, (s, t) is clamped to the texel-centre range
 * [0.5/N, 1 - 0.5/N] and looked up with image_map interpolate 2 (bilinear, texel centres as ours,
 * docs/textures.md), v = 1 - t: bilinear clamped at the face edge, as D3D9 samples a cube. A
 * function pattern gives one scalar, so each channel is its own pattern over the channel's
 * maximum (times 1.01, keeping the value below 1, where patterns wrap) through a colour map,
 * and the three are averaged (hence the 3). */
static void povray_put_cube_sky(FILE *fp, const povray_options *o)
{
    for (int f = 0; f < 6; f++)
        fprintf(fp, "#declare CubeF%d = function { pigment { image_map { exr \"%s/cube%d.exr\" interpolate 2 } } }\n",
                f, o->cube_dir, f);
    fprintf(fp, "#declare CubeC = function(a) { min(max(a, %.17g), %.17g) }\n", 0.5 / o->cube_size,
            1.0 - 0.5 / o->cube_size);
    /* Face f at face coordinates (s, t), channel c (.red, .green, .blue). */
    static const char *const chan[3] = {"red", "green", "blue"};
    for (int c = 0; c < 3; c++) {
        for (int f = 0; f < 6; f++)
            fprintf(fp, "#declare CubeL%d%d = function(fs, ft) { CubeF%d(CubeC(fs), 1 - CubeC(ft), 0).%s }\n", f, c, f,
                    chan[c]);
        /* x, y, z canonical with ax, ay, az their magnitudes. The table (sc, tc, ma) in D3D
         * (X, Y, Z) = (x, y, -z): +X (-Z, -Y, X), -X (Z, -Y, X), +Y (X, Z, Y), -Y (X, -Z, Y),
         * +Z (X, -Y, Z), -Z (-X, -Y, Z); ties go to X, then Y, as in env.h; select(a, b, c) is
         * b where a < 0. */
        fprintf(fp,
                "#declare CubeA%d = function(x, y, z, ax, ay, az) {\n"
                "  select(min(ax - ay, ax - az),\n"
                "    select(ay - az,\n"
                "      select(z, CubeL4%d((x/az + 1)/2, (-y/az + 1)/2), CubeL5%d((-x/az + 1)/2, (-y/az + 1)/2)),\n"
                "      select(y, CubeL3%d((x/ay + 1)/2, (z/ay + 1)/2), CubeL2%d((x/ay + 1)/2, (-z/ay + 1)/2))),\n"
                "    select(x, CubeL1%d((-z/ax + 1)/2, (-y/ax + 1)/2), CubeL0%d((z/ax + 1)/2, (-y/ax + 1)/2)))\n"
                "}\n",
                c, c, c, c, c, c, c);
    }
    fprintf(fp, "sky_sphere {\n  pigment { average pigment_map {\n");
    for (int c = 0; c < 3; c++) {
        double m = o->cube_max[c] > 0.0f ? 1.01 * o->cube_max[c] : 1.0;
        fprintf(fp,
                "    [1 function { CubeA%d(x, y, z, abs(x), abs(y), abs(z)) / %.17g } "
                "color_map { [0 rgb 0] [1 rgb <%.17g, %.17g, %.17g>] }]\n",
                c, m, c == 0 ? 3.0 * m : 0.0, c == 1 ? 3.0 * m : 0.0, c == 2 ? 3.0 * m : 0.0);
    }
    fprintf(fp, "  } }\n");
}

int povray_plain_path(const char *path)
{
    static const char ok[] = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789/._-+";
    return path[0] != '\0' && path[0] != '-' && strspn(path, ok) == strlen(path);
}

/* The file names the SDL will hold in strings, each plain (povray_plain_path). */
static rc_status povray_check_paths(const scene *s, const povray_options *o, char *err, size_t errlen)
{
    const char *env = o != NULL && o->env_file != NULL ? o->env_file : s->env.path;
    const char *what[3] = {"environment.image", "povray_options.texture_dir", "povray_options.cube_dir"};
    const char *path[3] = {s->env.kind == ENV_IMAGE ? env : NULL, o != NULL ? o->texture_dir : NULL,
                           o != NULL && s->env.kind == ENV_CUBE ? o->cube_dir : NULL};
    for (int i = 0; i < 3; i++)
        if (path[i] != NULL && !(o != NULL && o->coverage && i == 0) && !povray_plain_path(path[i])) {
            status_message(err, errlen,
                           "%s: %s '%s': POV-Ray cannot take this path in a scene string; render through "
                           "povray_render_job, which stages it under a plain name",
                           s->path, what[i], path[i]);
            return RC_ERR_IO;
        }
    return RC_OK;
}

/* The scene's own consistency before anything is written: the camera, the counts, and every
 * triangle's object and material in range. */
static rc_status povray_check_scene(const scene *s, const mesh *m, char *err, size_t errlen)
{
    /* A perspective angle must stay below 180 degrees (tan(hfov/2) finite). */
    if (s->width <= 0 || s->height <= 0 || !(s->camera.hfov > 0.0f && (double)s->camera.hfov < FORMULA_PI_D) ||
        !povray_finite3(s->camera.eye) || !povray_finite3(s->camera.target) || !povray_finite3(s->camera.up)) {
        status_message(err, errlen,
                       "%s: camera: width/height must be > 0, hfov in (0, 180) degrees, "
                       "eye/target/up finite",
                       s->path);
        return RC_ERR_RANGE;
    }
    if (s->n_lights < 0 || s->n_lights > SCENE_MAX_LIGHTS || s->n_materials < 0 ||
        s->n_materials > SCENE_MAX_MATERIALS || s->n_objects < 0 || s->n_objects > SCENE_MAX_OBJECTS) {
        status_message(err, errlen, "%s: scene counts out of range", s->path);
        return RC_ERR_RANGE;
    }
    for (int t = 0; t < m->n_tris; t++) {
        int ob = m->tri_object[t];
        if (ob < 0 || ob >= s->n_objects || s->objects[ob].material < 0 || s->objects[ob].material >= s->n_materials) {
            status_message(err, errlen,
                           "%s: mesh triangle %d: object %d or its material is out of range; "
                           "build the mesh from this scene",
                           s->path, t, ob);
            return RC_ERR_RANGE;
        }
    }
    return RC_OK;
}

/* Every used material's finish (fin[mi]): the model twin or the physical material, then its
 * texture; vcol[mi] marks a material drawn with D3D vertex colours. Nothing in a coverage pass. */
static rc_status povray_materials(const scene *s, const mesh *m, const povray_options *o, const povray_resolved *r,
                                  const povray_light *lights, const int *vcol, int coverage, povray_finish *fin,
                                  char *err, size_t errlen)
{
    int used[SCENE_MAX_MATERIALS] = {0};
    for (int t = 0; t < m->n_tris; t++)
        used[s->objects[m->tri_object[t]].material] = 1;
    for (int mi = 0; mi < s->n_materials; mi++) {
        if (!used[mi] || coverage)
            continue;
        rc_status st = r->validate ? povray_material_physical(s, mi, r, &fin[mi], err, errlen)
                                   : povray_material_twin(s, mi, lights, r, &fin[mi], err, errlen);
        if (st == RC_OK)
            st = povray_material_texture(s, mi, o, m, &fin[mi], err, errlen);
        if (st != RC_OK)
            return st;
        if (vcol[mi] && (fin[mi].texture[0] != '\0' || fin[mi].emission.x != 0.0 || fin[mi].emission.y != 0.0 ||
                         fin[mi].emission.z != 0.0 || fin[mi].reflection != 0 || fin[mi].one_sided)) {
            status_message(err, errlen,
                           "%s: materials[%d] '%s': D3D vertex colours with a texture, an emissive or ambient "
                           "colour, a reflection or d3d.two_sided false have no POV-Ray twin (its emission is a "
                           "multiple of the pigment; a vertex's texture has one side); use the diffuse source alone",
                           s->path, mi, s->materials[mi].name);
            return RC_ERR_RANGE;
        }
    }
    return RC_OK;
}

/* The file's first lines: what it is, and the global settings. */
static void povray_write_header(FILE *fp, const scene *s, const povray_resolved *r)
{
    fprintf(fp, "// reflcheck scene '%s' for POV-Ray 3.7, role %s, terms 0x%x, output scale %.9g\n", s->name,
            r->validate ? "validate" : "twin", r->term, r->scale);
    if (r->validate) {
        char ph[400];
        fprintf(fp, "// physics: %s\n", physics_describe(&s->physics, s->n_lights, ph, sizeof ph));
    }
    fprintf(fp, "#version 3.7;\n");
    fprintf(fp,
            "global_settings { assumed_gamma 1.0 ambient_light 0 adc_bailout 0 "
            "max_trace_level %d }\n\n",
            r->max_trace_level);
}

static void povray_write_camera(FILE *fp, const scene *s)
{
    /* Right-handed Y-up canonical frame: POV-Ray keeps it with a negative right vector. */
    fprintf(fp, "camera {\n  perspective\n  location ");
    povray_put_fvec(fp, s->camera.eye);
    fprintf(fp, "\n  right -x*%.9g\n  up y\n  sky ", (double)s->width / (double)s->height);
    povray_put_fvec(fp, s->camera.up);
    fprintf(fp, "\n  angle %.9g\n  look_at ", (double)s->camera.hfov * 180.0 / FORMULA_PI_D);
    povray_put_fvec(fp, s->camera.target);
    fprintf(fp, "\n}\n\n");
}

/* The background camera rays and reflections see: black without an environment (or without
 * the reflection term), else a constant, cube-map or image sky. */
static void povray_write_environment(FILE *fp, const scene *s, const povray_options *o, const povray_resolved *r,
                                     int with_env)
{
    if (!with_env) {
        fprintf(fp, "background { color rgb 0 }\n\n");
    } else if (s->env.kind == ENV_CONSTANT) {
        fprintf(fp, "sky_sphere { pigment { color rgb ");
        povray_put_vec(fp, dv3_scale(dv3_from(s->env.radiance), r->scale));
        fprintf(fp, " } }\n\n");
    } else if (s->env.kind == ENV_CUBE) {
        povray_put_cube_sky(fp, o);
        fprintf(fp, "  emission rgb ");
        povray_put_vec(fp, dv3_scale(dv3_from(s->env.radiance), r->scale));
        fprintf(fp, "\n}\n\n");
    } else {
        /* rotate y*180: POV-Ray's map_type 1 otherwise shows the image's -x along +x. */
        fprintf(fp,
                "sky_sphere {\n  pigment { image_map { exr \"%s\" map_type 1 interpolate 2 } "
                "rotate y*180 }\n  emission rgb ",
                o != NULL && o->env_file != NULL ? o->env_file : s->env.path);
        povray_put_vec(fp, dv3_scale(dv3_from(s->env.radiance), r->scale));
        fprintf(fp, "\n}\n\n");
    }
}

/* One light_source per converted light (pl); a skipped light leaves a comment. */
static void povray_write_light(FILE *fp, const scene *s, int i, const povray_light *pl, dvec3 bc, double br)
{
    const light *l = &s->lights[i];
    if (pl->skip) {
        fprintf(fp, "// lights[%d]: every surface is beyond its range\n", i);
        return;
    }
    dvec3 dir = dv3_norm(dv3_from(l->direction));
    fprintf(fp, "light_source {\n  ");
    if (l->kind == LIGHT_SUN) {
        /* Outside the geometry's bounding sphere, so that no surface is behind it. */
        dvec3 from = dv3_sub(bc, dv3_scale(dir, 4.0 * br + 10.0));
        povray_put_vec(fp, from);
        fprintf(fp, "\n  color rgb ");
        povray_put_vec(fp, pl->colour);
        fprintf(fp, "\n  parallel\n  point_at ");
        povray_put_vec(fp, dv3_add(from, dir));
        fprintf(fp, "\n");
    } else {
        povray_put_fvec(fp, l->position);
        fprintf(fp, "\n  color rgb ");
        povray_put_vec(fp, pl->colour);
        fprintf(fp, "\n");
        if (l->kind == LIGHT_SPOT) {
            /* POV-Ray's radius/falloff are half angles; tightness 1 = the extra cos. */
            fprintf(fp, "  spotlight\n  radius %.9g\n  falloff %.9g\n  tightness 1\n  point_at ",
                    (double)l->inner * 90.0 / FORMULA_PI_D, (double)l->outer * 90.0 / FORMULA_PI_D);
            povray_put_vec(fp, dv3_add(dv3_from(l->position), dir));
            fprintf(fp, "\n");
        }
        if (pl->fade_power > 0)
            fprintf(fp, "  fade_distance %.9g\n  fade_power %d\n", pl->fade_distance, pl->fade_power);
    }
    fprintf(fp, "}\n\n");
}

/* What povray_write_object needs beside the scene: the pass, the finishes, and two vertex maps
 * (mesh vertex -> the object's, and back) sized to the mesh, reused for every object. */
typedef struct {
    const povray_resolved *r;
    int coverage;
    const povray_finish *fin;
    const int *vcol;
    int *remap;
    int *local;
} povray_object_ctx;

/* Objects[ob]'s vertices in order of first use: remap and local filled, counts returned. */
static void povray_object_vertices(const mesh *m, int ob, int *remap, int *local, int *n_verts, int *n_tris)
{
    int nv = 0, nt = 0;
    for (int v = 0; v < m->n_verts; v++)
        remap[v] = -1;
    for (int t = 0; t < m->n_tris; t++) {
        if (m->tri_object[t] != ob)
            continue;
        nt++;
        for (int c = 0; c < 3; c++) {
            uint32_t v = m->idx[3 * t + c];
            if (remap[v] < 0) {
                remap[v] = nv;
                local[nv++] = (int)v;
            }
        }
    }
    *n_verts = nv;
    *n_tris = nt;
}

/* The mesh2's vertex, normal and (textured) uv vectors. */
static void povray_write_vectors(FILE *fp, const mesh *m, const int *local, int nv, int with_uv)
{
    fprintf(fp, "  vertex_vectors { %d", nv);
    for (int v = 0; v < nv; v++) {
        fprintf(fp, ",\n    ");
        povray_put_fvec(fp, m->pos[local[v]]);
    }
    fprintf(fp, "\n  }\n  normal_vectors { %d", nv);
    for (int v = 0; v < nv; v++) {
        fprintf(fp, ",\n    ");
        povray_put_fvec(fp, m->nrm[local[v]]);
    }
    fprintf(fp, "\n  }\n");
    if (with_uv) {
        /* Without uv_indices POV-Ray indexes uv_vectors with face_indices, as here. */
        fprintf(fp, "  uv_vectors { %d", nv);
        for (int v = 0; v < nv; v++)
            fprintf(fp, ",\n    <%.9g, %.9g>", (double)m->uv[2 * local[v]], (double)m->uv[2 * local[v] + 1]);
        fprintf(fp, "\n  }\n");
    }
}

/* One mesh2 for objects[ob] (nothing when it has no triangles). */
static void povray_write_object(FILE *fp, const scene *s, const mesh *m, int ob, const povray_object_ctx *c)
{
    int nv, nt;
    povray_object_vertices(m, ob, c->remap, c->local, &nv, &nt);
    if (nt == 0)
        return;
    int mi = s->objects[ob].material;
    fprintf(fp, "// objects[%d], material %d\nmesh2 {\n", ob, mi);
    povray_write_vectors(fp, m, c->local, nv, m->uv != NULL && !c->coverage && c->fin[mi].texture[0] != '\0');
    int per_vertex_tex = !c->coverage && c->vcol[mi];
    if (per_vertex_tex) {
        /* D3D's diffuse colour1: one texture per vertex, its pigment the vertex colour; with
         * three texture indices per face POV-Ray interpolates the pigments across it, as
         * the rasterizer interpolates the colour per pixel. */
        povray_finish vf = c->fin[mi];
        fprintf(fp, "  texture_list { %d,\n", nv);
        for (int v = 0; v < nv; v++) {
            vf.pigment = dv3_from(m->col1[c->local[v]]);
            povray_write_finish(fp, &vf);
        }
        fprintf(fp, "  }\n");
    }
    fprintf(fp, "  face_indices { %d", nt);
    for (int t = 0; t < m->n_tris; t++) {
        if (m->tri_object[t] != ob)
            continue;
        int a = c->remap[m->idx[3 * t]], b = c->remap[m->idx[3 * t + 1]], d = c->remap[m->idx[3 * t + 2]];
        fprintf(fp, ",\n    <%d, %d, %d>", a, b, d);
        if (per_vertex_tex)
            fprintf(fp, ", %d, %d, %d", a, b, d);
    }
    fprintf(fp, "\n  }\n");
    if (c->coverage)
        fprintf(fp,
                "  texture {\n    pigment { color rgb <1, %d, 0> }\n    finish { ambient 0 diffuse 0 "
                "specular 0 phong 0 reflection 0 emission 1 }\n  }\n",
                ob + 1);
    else
        povray_write_finish(fp, &c->fin[mi]);
    /* The model has no shadows; a physical reference has them when its physics asks. */
    fprintf(fp, "%s  no_reflection\n}\n\n", c->r->validate && s->physics.shadows ? "" : "  no_shadow\n");
}

/* Everything checked and converted before the file is opened: the lights (lights), the
 * materials' finishes (fin) and which materials take vertex colours (vcol). */
static rc_status povray_prepare(const scene *s, const mesh *m, const povray_options *o, const povray_resolved *r,
                                povray_light *lights, povray_finish *fin, int *vcol, char *err, size_t errlen)
{
    rc_status st = povray_check_scene(s, m, err, errlen);
    if (st != RC_OK)
        return st;
    for (int mi = 0; mi < s->n_materials; mi++)
        if ((vcol[mi] = mesh_material_vertex_coloured(s, m, mi)) &&
            (st = povray_vertex_colour_check(s, m, mi, r, err, errlen)) != RC_OK)
            return st;

    int coverage = o != NULL && o->coverage;
    if (r->validate && !coverage && (st = renderer_physics_check(povray_physics, s, err, errlen)) != RC_OK)
        return st;
    for (int i = 0; i < s->n_lights && !coverage; i++)
        if ((st = povray_light_convert(s, m, i, r, &lights[i], err, errlen)) != RC_OK)
            return st;
    if ((st = povray_materials(s, m, o, r, lights, vcol, coverage, fin, err, errlen)) != RC_OK)
        return st;

    int with_env = s->env.kind != ENV_NONE && (r->term & POVRAY_TERM_REFLECTION) && !coverage;
    if (with_env && s->env.kind == ENV_CUBE && (o->cube_dir == NULL || o->cube_size <= 0)) {
        status_message(err, errlen,
                       "%s: environment: a cube map needs its faces as linear EXR files, which povray_render_job "
                       "writes from the loaded cube (povray_options.cube_dir); render the scene through it",
                       s->path);
        return RC_ERR_RANGE;
    }
    return RC_OK;
}

rc_status povray_write_scene(const scene *s, const mesh *m, const povray_options *o, const char *sdl_path, char *err,
                             size_t errlen)
{
    povray_resolved r;
    rc_status st = povray_resolve(s, o, &r, sdl_path, err, errlen);
    if (st != RC_OK)
        return st;
    if ((st = povray_check_paths(s, o, err, errlen)) != RC_OK)
        return st;
    povray_light lights[SCENE_MAX_LIGHTS];
    povray_finish fin[SCENE_MAX_MATERIALS];
    int vcol[SCENE_MAX_MATERIALS] = {0};
    if ((st = povray_prepare(s, m, o, &r, lights, fin, vcol, err, errlen)) != RC_OK)
        return st;
    int coverage = o != NULL && o->coverage;
    int with_env = s->env.kind != ENV_NONE && (r.term & POVRAY_TERM_REFLECTION) && !coverage;

    int *remap = malloc(sizeof *remap * (size_t)(m->n_verts > 0 ? m->n_verts : 1));
    int *local = malloc(sizeof *local * (size_t)(m->n_verts > 0 ? m->n_verts : 1));
    if (!remap || !local) {
        free(remap);
        free(local);
        status_message(err, errlen, "%s: out of memory for the vertex map", sdl_path);
        return RC_ERR_NOMEM;
    }
    FILE *fp = fopen(sdl_path, "w");
    if (!fp) {
        free(remap);
        free(local);
        status_message(err, errlen, "%s: cannot write: %s; check the output directory", sdl_path, strerror(errno));
        return RC_ERR_IO;
    }

    povray_write_header(fp, s, &r);
    povray_write_camera(fp, s);
    povray_write_environment(fp, s, o, &r, with_env);
    dvec3 bc;
    double br;
    povray_mesh_bounds(m, &bc, &br);
    for (int i = 0; i < s->n_lights && !coverage; i++)
        povray_write_light(fp, s, i, &lights[i], bc, br);
    povray_object_ctx ctx = {.r = &r, .coverage = coverage, .fin = fin, .vcol = vcol, .remap = remap, .local = local};
    for (int ob = 0; ob < s->n_objects; ob++)
        povray_write_object(fp, s, m, ob, &ctx);
    free(remap);
    free(local);
    int bad = ferror(fp);
    if (fclose(fp) != 0 || bad) {
        status_message(err, errlen, "%s: write failed (disk full?)", sdl_path);
        return RC_ERR_IO;
    }
    return RC_OK;
}

/* ---- command line and running ---------------------------------------------------------- */

rc_status povray_command(const povray_options *o, const char *sdl_path, const char *exr_out, int width_px,
                         int height_px, int supersample, povray_argv *cmd, char *err, size_t errlen)
{
    povray_options zero = {0};
    if (!o)
        o = &zero;
    int k = supersample > 0 ? supersample : 1;
    if (o->frames < 0 || o->frames > 9) {
        /* One digit: POV-Ray pads the frame number in the file name to the last frame's digits. */
        status_message(err, errlen, "povray_command: frames %d is out of range (0 to 9)", o->frames);
        return RC_ERR_RANGE;
    }
    if (width_px <= 0 || height_px <= 0 || supersample < 0 || o->threads < 0 || width_px > 65536 / k ||
        height_px > 65536 / k) {
        status_message(err, errlen,
                       "povray_command: size %dx%d with supersample %d is out of range "
                       "(positive, k*size <= 65536)",
                       width_px, height_px, supersample);
        return RC_ERR_RANGE;
    }
    size_t n = strlen(exr_out);
    if (n < 4 || strcmp(exr_out + n - 4, ".exr") != 0) {
        status_message(err, errlen,
                       "povray_command: output '%s' must end in .exr (POV-Ray would "
                       "append its own extension)",
                       exr_out);
        return RC_ERR_RANGE;
    }
    const char *bad = !povray_plain_path(sdl_path) ? sdl_path : (!povray_plain_path(exr_out) ? exr_out : NULL);
    if (bad != NULL) {
        status_message(err, errlen,
                       "povray_command: '%s' is not a plain path (letters, digits, /._-+); POV-Ray splits its "
                       "options at spaces and quotes: run it in the folder with plain names",
                       bad);
        return RC_ERR_IO;
    }
    char tmp[POVRAY_ARGV_MAX][64];
    const char *args[POVRAY_ARGV_MAX];
    int argc = 0;
    args[argc++] = o->povray ? o->povray : "povray";
    args[argc++] = "+I"; /* joined with the path below */
    args[argc++] = "+O";
    args[argc++] = "+FE"; /* OpenEXR, half float */
    snprintf(tmp[argc], sizeof tmp[argc], "+W%d", width_px * k);
    args[argc] = tmp[argc];
    argc++;
    snprintf(tmp[argc], sizeof tmp[argc], "+H%d", height_px * k);
    args[argc] = tmp[argc];
    argc++;
    /* No antialiasing (one ray through each pixel centre), no jitter, no alpha channel,
     * no preview window, no verbose/statistics/render console streams, no pause. */
    const char *fixed[] = {"-A", "-J", "-UA", "-D", "-V", "-P", "+Q9", "-GS", "-GR"};
    for (size_t i = 0; i < sizeof fixed / sizeof fixed[0]; i++)
        args[argc++] = fixed[i];
    if (o->threads > 0) {
        snprintf(tmp[argc], sizeof tmp[argc], "+WT%d", o->threads);
        args[argc] = tmp[argc];
        argc++;
    }
    if (o->frames > 1) {
        args[argc++] = "+KFI1";
        snprintf(tmp[argc], sizeof tmp[argc], "+KFF%d", o->frames);
        args[argc] = tmp[argc];
        argc++;
    }
    size_t used = 0;
    for (int i = 0; i < argc; i++) {
        const char *tail = i == 1 ? sdl_path : (i == 2 ? exr_out : "");
        size_t len = strlen(args[i]) + strlen(tail) + 1;
        if (used + len > sizeof cmd->buf) {
            status_message(err, errlen, "povray_command: paths too long (over %d bytes in all)", POVRAY_ARGV_BUF);
            return RC_ERR_NOMEM;
        }
        cmd->argv[i] = cmd->buf + used;
        snprintf(cmd->buf + used, len, "%s%s", args[i], tail);
        used += len;
    }
    cmd->argv[argc] = NULL;
    cmd->argc = argc;
    return RC_OK;
}

void povray_command_string(const povray_argv *cmd, char *buf, size_t buflen)
{
    renderer_command_string((const char *const *)cmd->argv, buf, buflen);
}

/* ---- box filter ------------------------------------------------------------------------ */

rc_status povray_box_downsample(const float *src, int kw, int kh, int k, float *dst)
{
    /* k <= 256 keeps k*k <= 65536 summands per pixel, the bound povray.h states. */
    if (k < 1 || kw < k || kh < k || kw % k != 0 || kh % k != 0 || k > 256)
        return RC_ERR_RANGE;
    int w = kw / k, h = kh / k;
    double inv = 1.0 / ((double)k * k);
    for (int j = 0; j < h; j++) {
        for (int i = 0; i < w; i++) {
            double sum = 0.0;
            for (int t = 0; t < k; t++) {
                const float *row = src + (size_t)(j * k + t) * (size_t)kw + (size_t)i * k;
                for (int u = 0; u < k; u++)
                    sum += row[u];
            }
            dst[(size_t)j * w + i] = (float)(sum * inv);
        }
    }
    return RC_OK;
}

/* ---- the render entry ------------------------------------------------------------------ */

/* The variance of each k x k block's mean (unbiased sample variance / k^2), as the rasterizer
 * writes it: how far a pixel's k*k samples may be from its box integral. */
static void povray_block_variance(const float *src, int kw, int k, int w, int h, float *var)
{
    double n = (double)k * k;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double s = 0.0, sq = 0.0;
            for (int t = 0; t < k; t++)
                for (int u = 0; u < k; u++) {
                    double v = src[(size_t)(y * k + t) * (size_t)kw + (size_t)(x * k + u)];
                    s += v;
                    sq += v * v;
                }
            double vv = k > 1 ? (sq - s * s / n) / (n * (n - 1.0)) : 0.0;
            var[(size_t)y * (size_t)w + (size_t)x] = (float)(vv > 0.0 ? vv : 0.0);
        }
}

/* Reads one pass's image (k times the size) box-filtered into planes (w*h each, caller frees)
 * and, if var is not NULL, the block variances. Returns 0, or -1 with the result's status and
 * message set. */
static int povray_read_pass(const renderer_job *j, renderer_result *r, const povray_options *o, int k, const char *raw,
                            float *planes[3], float *var[3])
{
    const scene *s = j->s;
    char err[1024];
    exr_image img;
    if (exr_read(raw, &img, err, sizeof err) != RC_OK) {
        renderer_fail(r, RUNNER_FAILED, "povray wrote an unreadable image: %s", err);
        return -1;
    }
    int w = s->width, h = s->height;
    const char *names[3] = {"R", "G", "B"};
    int ok = img.width == k * w && img.height == k * h;
    double scale = o->output_scale > 0 ? o->output_scale : 1.0;
    for (int i = 0; ok && i < 3; i++) {
        const float *src = exr_image_channel(&img, names[i]);
        planes[i] = malloc((size_t)w * (size_t)h * sizeof(float));
        ok = src != NULL && planes[i] != NULL &&
             povray_box_downsample(src, img.width, img.height, k, planes[i]) == RC_OK;
        for (size_t p = 0; ok && p < (size_t)w * (size_t)h; p++)
            planes[i][p] = (float)(planes[i][p] / scale);
        if (ok && var != NULL) {
            var[i] = malloc((size_t)w * (size_t)h * sizeof(float));
            ok = var[i] != NULL;
            if (ok) {
                povray_block_variance(src, img.width, k, w, h, var[i]);
                for (size_t p = 0; p < (size_t)w * (size_t)h; p++)
                    var[i][p] = (float)(var[i][p] / (scale * scale));
            }
        }
    }
    exr_image_free(&img);
    if (!ok) {
        renderer_fail(r, RUNNER_FAILED, "povray image %s is not the size asked for, or lacks R, G, B", raw);
        return -1;
    }
    return 0;
}

/* A job that could not be written: a scene POV-Ray cannot represent (RC_ERR_RANGE) is missing
 * from this renderer, anything else an error. Returns -1. */
static int povray_job_fail(renderer_result *r, rc_status st, const char *err)
{
    if (st == RC_ERR_RANGE)
        renderer_fail(r, RUNNER_MISSING, "povray cannot represent this scene: %s", err);
    else
        renderer_fail(r, RUNNER_ERROR, "cannot write the POV-Ray job: %s", err);
    return -1;
}

/* Writes scene.pov (o), coverage.pov (geo) and passes.pov, which includes the first in frame 1
 * and the second in frame 2. Returns 0, or -1 with the result's status and message set. */
static int povray_write_passes(const renderer_job *j, renderer_result *r, const povray_options *o,
                               const povray_options *geo)
{
    char path[1100], err[1024];
    const povray_options *opt[2] = {o, geo};
    const char *tag[2] = {"scene", "coverage"};
    for (int i = 0; i < 2; i++) {
        snprintf(path, sizeof path, "%s/%s.pov", j->dir, tag[i]);
        rc_status st = povray_write_scene(j->s, j->m, opt[i], path, err, sizeof err);
        if (st != RC_OK)
            return povray_job_fail(r, st, err);
    }
    snprintf(path, sizeof path, "%s/passes.pov", j->dir);
    FILE *fp = fopen(path, "w");
    int bad = fp == NULL;
    if (fp != NULL) {
        /* #version first, as in every main file: without it POV-Ray 3.7 assumes 3.62's rules. */
        fputs("// reflcheck: frame 1 the scene, frame 2 the geometry pass (povray.h)\n#version 3.7;\n"
              "#if (frame_number = 1)\n#include \"scene.pov\"\n#else\n#include \"coverage.pov\"\n#end\n",
              fp);
        bad = ferror(fp) | (fclose(fp) != 0);
    }
    if (bad) {
        renderer_fail(r, RUNNER_ERROR, "cannot write the POV-Ray job: %s: write failed (disk full?)", path);
        return -1;
    }
    return 0;
}

/* Both passes in one POV-Ray process (povray_render_job's comment says why): the scene, box-
 * filtered into rgb with its block variances in var, and the geometry pass into cov. Returns 0,
 * or -1 with the result's status and message set. */
static int povray_passes(const renderer_job *j, renderer_result *r, const povray_options *o, const povray_options *geo,
                         float *rgb[3], float *var[3], float *cov[3])
{
    const scene *s = j->s;
    char raw[2][1100], err[1024];
    int k = o->supersample > 0 ? o->supersample : (s->supersample > 0 ? s->supersample : 1);
    if (povray_write_passes(j, r, o, geo) != 0)
        return -1;
    povray_options anim = *o;
    anim.frames = 2;
    povray_argv cmd;
    /* POV-Ray runs in the work folder and gets names only (renderer.h, "Paths"); it writes
     * frame f to pass-raw<f>.exr. */
    rc_status st = povray_command(&anim, "passes.pov", "pass-raw.exr", s->width, s->height, k, &cmd, err, sizeof err);
    if (st != RC_OK)
        return povray_job_fail(r, st, err);
    povray_command_string(&cmd, r->command, sizeof r->command);
    for (int f = 0; f < 2; f++) {
        snprintf(raw[f], sizeof raw[f], "%s/pass-raw%d.exr", j->dir, f + 1);
        unlink(raw[f]);
    }
    runner_result rr;
    runner_where where = {.dir = j->dir};
    runner_exec_in((const char *const *)cmd.argv, &where, j->timeout > 0 ? j->timeout : 600.0, j->log, &rr);
    r->wall_s += rr.wall_s;
    r->cpu_s += rr.cpu_s;
    if (rr.status != RUNNER_OK) {
        renderer_fail_run(r, &rr, "povray", "povray", ", scene and coverage passes", j->log, "rror", j->shown_log);
        return -1;
    }
    if (povray_read_pass(j, r, o, k, raw[0], rgb, var) != 0)
        return -1;
    return povray_read_pass(j, r, geo, k, raw[1], cov, NULL);
}

/* A twin POV-Ray cannot write in full may still be written without the Blinn-Phong
 * highlight (coloured Vs, infinite viewer): the only term whose refusals depend on the term
 * mask. Any other refusal stays a refusal. */
static void povray_choose_terms(const renderer_job *j, povray_options *o, renderer_result *r)
{
    if (o->term == 0)
        o->term = POVRAY_TERM_ALL;
    if (!j->partial || j->role != ROLE_TWIN || !(o->term & POVRAY_TERM_SPECULAR))
        return;
    char sdl[1100], err[1024];
    snprintf(sdl, sizeof sdl, "%s/probe.pov", j->dir);
    if (povray_write_scene(j->s, j->m, o, sdl, err, sizeof err) != RC_ERR_RANGE)
        return;
    povray_options less = *o;
    less.term &= ~(unsigned)POVRAY_TERM_SPECULAR;
    char why[1024];
    if (povray_write_scene(j->s, j->m, &less, sdl, why, sizeof why) == RC_OK) {
        *o = less;
        renderer_leave_out(r, RENDERER_TERM_SPECULAR, err);
    }
    unlink(sdl);
}

void povray_render_job(const renderer_job *j, renderer_result *r)
{
    povray_options o = {0};
    if (j->options != NULL)
        o = *(const povray_options *)j->options;
    else
        o.threads = j->threads;
    o.role = j->role;
    if (j->tex != NULL) {
        char err[1024];
        if (renderer_write_textures(j, err, sizeof err) != RC_OK) {
            renderer_fail(r, RUNNER_ERROR, "%s", err);
            return;
        }
        o.texture_dir = ".";
    }
    if (j->s->env.kind == ENV_IMAGE) {
        char err[1024];
        if (renderer_stage(j, j->s->env.path, "environment.exr", err, sizeof err) != RC_OK) {
            renderer_fail(r, RUNNER_ERROR, "%s", err);
            return;
        }
        o.env_file = "environment.exr";
    }
    if (j->env != NULL && j->env->kind == ENV_CUBE && j->env->rgb != NULL) {
        /* The faces as loaded (a cross split, PNG/JPEG decoded): the sky POV-Ray looks up. */
        int n = j->env->width;
        size_t nn = (size_t)n * (size_t)n;
        for (int f = 0; f < 6; f++) {
            char path[1200], err[1024];
            snprintf(path, sizeof path, "%s/cube%d.exr", j->dir, f);
            env_map face = {.kind = ENV_IMAGE, .width = n, .height = n, .rgb = j->env->rgb + (size_t)f * nn * 3};
            if (frame_env_write(path, &face, err, sizeof err) != RC_OK) {
                renderer_fail(r, RUNNER_ERROR, "%s", err);
                return;
            }
        }
        for (size_t i = 0; i < 6 * nn; i++)
            for (int c = 0; c < 3; c++)
                o.cube_max[c] = fmaxf(o.cube_max[c], j->env->rgb[3 * i + (size_t)c]);
        o.cube_dir = ".";
        o.cube_size = n;
    }
    povray_choose_terms(j, &o, r);
    povray_options geo = o;
    geo.coverage = 1;
    float *rgb[3] = {NULL, NULL, NULL}, *cov[3] = {NULL, NULL, NULL}, *var[3] = {NULL, NULL, NULL};
    if (povray_passes(j, r, &o, &geo, rgb, var, cov) == 0) {
        /* Coverage pass: R is the covered share, G/R the object index + 1 (box-filtered). */
        size_t np = (size_t)j->s->width * (size_t)j->s->height;
        for (size_t p = 0; p < np; p++)
            cov[1][p] = cov[0][p] > 0.5f ? floorf(cov[1][p] / cov[0][p] + 0.5f) - 1.0f : -1.0f;
        exr_channel ch[8] = {{"R", rgb[0]},      {"G", rgb[1]},     {"B", rgb[2]},     {"coverage", cov[0]},
                             {"object", cov[1]}, {"var.R", var[0]}, {"var.G", var[1]}, {"var.B", var[2]}};
        exr_attr at[] = {{"reflcheck.renderer", j->version ? j->version : "povray"}};
        char err[1024];
        if (exr_write(j->exr, j->s->width, j->s->height, ch, 8, at, 1, err, sizeof err) != RC_OK)
            renderer_fail(r, RUNNER_ERROR, "%s", err);
    }
    for (int i = 0; i < 3; i++) {
        free(rgb[i]);
        free(cov[i]);
        free(var[i]);
    }
    /* The staged link served the render; a cache entry keeps only the render. */
    if (o.env_file != NULL) {
        char link[1100];
        snprintf(link, sizeof link, "%s/%s", j->dir, o.env_file);
        unlink(link);
    }
}
