/* cycles.c - the Cycles job file, the blender command line, and the collected EXR. */
/* realpath */
#define _XOPEN_SOURCE 700

#include "cycles.h"
#include "cycles_samples.h"
#include "cycles_worker.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cJSON.h>

#include "formula.h"
#include "d3d.h"
#include "d3d9client.h"
#include "exr.h"
#include "fileio.h"
#include "jsonio.h"
#include "runner.h"
#include "../registry.h"

/* Blender's side of the translation, a file of the source tree (renderer_data_path). */
#define CYCLES_SCRIPT "harness/renderers/cycles/cycles_render.py"

/* ------------------------------------------------------------------ JSON writing */

/* The job is a cJSON document written through core/jsonio. Numbers keep 9 significant
 * digits: every float round-trips (Blender stores float32), and the file stays as short as
 * the text of "%.9g". */
#define CYCLES_JSON_DIGITS 9

typedef struct {
    int bad; /* a non-finite number was asked for: JSON cannot hold it */
    const char *bad_key;
    int nomem; /* an allocation or an attachment failed */
} jw;

static cJSON *jw_num(jw *w, const char *key, double x)
{
    if (!isfinite(x)) {
        if (!w->bad)
            w->bad_key = key;
        w->bad = 1;
        x = 0.0;
    }
    return jsonio_number(x, CYCLES_JSON_DIGITS);
}

/* item under name in obj; any failure (obj or item NULL) is remembered and item freed. */
static void jw_put(jw *w, cJSON *obj, const char *name, cJSON *item)
{
    if (!jsonio_add(obj, name, item))
        w->nomem = 1;
}

static void jw_push(jw *w, cJSON *arr, cJSON *item)
{
    if (arr == NULL || item == NULL || !cJSON_AddItemToArray(arr, item)) {
        cJSON_Delete(item);
        w->nomem = 1;
    }
}

/* A new object or array under name in parent (pushed when name is NULL); NULL on failure, which
 * the later additions into it then record. */
static cJSON *jw_add_new(jw *w, cJSON *parent, const char *name, cJSON *item)
{
    cJSON *keep = item;
    if (name != NULL)
        jw_put(w, parent, name, item);
    else
        jw_push(w, parent, item);
    return w->nomem ? NULL : keep;
}

static cJSON *jw_obj(jw *w, cJSON *parent, const char *name)
{
    return jw_add_new(w, parent, name, cJSON_CreateObject());
}

static cJSON *jw_arr(jw *w, cJSON *parent, const char *name)
{
    return jw_add_new(w, parent, name, cJSON_CreateArray());
}

static void jw_put_num(jw *w, cJSON *obj, const char *name, const char *key, double x)
{
    jw_put(w, obj, name, jw_num(w, key, x));
}

static void jw_put_str(jw *w, cJSON *obj, const char *name, const char *s)
{
    jw_put(w, obj, name, cJSON_CreateString(s));
}

static void jw_put_int(jw *w, cJSON *obj, const char *name, long x)
{
    jw_put(w, obj, name, cJSON_CreateNumber((double)x));
}

static void jw_put_bool(jw *w, cJSON *obj, const char *name, int b) { jw_put(w, obj, name, cJSON_CreateBool(b)); }

static void jw_push_num(jw *w, cJSON *arr, const char *key, double x) { jw_push(w, arr, jw_num(w, key, x)); }

/* [x, y, z] under name. */
static void jw_put_vec(jw *w, cJSON *obj, const char *name, const char *key, vec3 v)
{
    cJSON *a = jw_arr(w, obj, name);
    jw_push_num(w, a, key, v.x);
    jw_push_num(w, a, key, v.y);
    jw_push_num(w, a, key, v.z);
}

/* The vectors v[order[0..n-1]] as one flat list x, y, z, x, y, z, ... under name. */
static void jw_put_flat(jw *w, cJSON *obj, const char *name, const char *key, const vec3 *v, const int *order, int n)
{
    cJSON *a = jw_arr(w, obj, name);
    for (int i = 0; i < n && !w->nomem; i++) {
        vec3 p = v[order[i]];
        jw_push_num(w, a, key, p.x);
        jw_push_num(w, a, key, p.y);
        jw_push_num(w, a, key, p.z);
    }
}

/* ------------------------------------------------------------------ translation checks */

static int cycles_finite3(vec3 a) { return isfinite(a.x) && isfinite(a.y) && isfinite(a.z); }

typedef struct {
    const scene *s;
    const mesh *m;
    const cycles_options *o;
    int twin;             /* the model's terms; else (validate, agree) the scene's physics */
    char missing[8][160]; /* terms left out under options.partial */
    int n_missing;
    unsigned missing_terms; /* their RENDERER_TERM_* bits */
    char *err;
    size_t errlen;
} cycles_ctx;

/* Something Cycles cannot reproduce: an error, or, when it is a whole term (term, a
 * RENDERER_TERM_* bit) and options.partial is set, a note in the job and in options.left_out.
 * Leaving out part of a term (ambient inside diffuse, Gouraud, clamping) would compare
 * unlike images, so that is always an error. */
static rc_status cycles_cannot(cycles_ctx *c, unsigned term, const char *what, const char *fix)
{
    if (!c->o->partial || term == 0) {
        /* Only a whole term can be left out, and only by a twin (jobs.c sets partial for twins):
         * say so where it applies, never where no partial twin could lift the refusal. */
        status_message(c->err, c->errlen, "%s: %s; %s%s", c->s->path, what, fix,
                       term != 0 ? " (a twin leaves this term out and compares the rest)" : "");
        return RC_ERR_RANGE;
    }
    if (c->n_missing < (int)(sizeof c->missing / sizeof c->missing[0]))
        snprintf(c->missing[c->n_missing++], sizeof c->missing[0], "%s", what);
    if (c->o->left_out != NULL)
        renderer_leave_out(c->o->left_out, term, what);
    c->missing_terms |= term;
    return RC_OK;
}

/* Largest distance from p to any mesh vertex: decides whether a light's range cuts the geometry. */
static double cycles_max_dist(const mesh *m, vec3 p)
{
    double d = 0.0;
    for (int i = 0; i < m->n_verts; i++)
        d = fmax(d, dv3_len(dv3_sub(dv3_from(m->pos[i]), dv3_from(p))));
    return d;
}

static rc_status cycles_check_light(cycles_ctx *c, int i)
{
    const light *l = &c->s->lights[i];
    if (!cycles_finite3(l->intensity) || l->intensity.x < 0.0f || l->intensity.y < 0.0f || l->intensity.z < 0.0f) {
        status_message(c->err, c->errlen, "%s: lights[%d]: intensity must be finite and >= 0", c->s->path, i);
        return RC_ERR_RANGE;
    }
    if (l->kind == LIGHT_SUN)
        return RC_OK;
    if (l->a0 != 0.0f || l->a1 != 0.0f || !(l->a2 > 0.0f)) {
        status_message(c->err, c->errlen,
                       "%s: lights[%d]: Cycles lights fall off as 1/d^2 only (a0 = %g, a1 = %g, a2 = %g); "
                       "set a0 = a1 = 0 and a2 > 0 for a Cycles comparison",
                       c->s->path, i, (double)l->a0, (double)l->a1, (double)l->a2);
        return RC_ERR_RANGE;
    }
    if (isfinite(l->range) && (double)l->range < cycles_max_dist(c->m, l->position)) {
        status_message(c->err, c->errlen,
                       "%s: lights[%d]: range %g cuts through the geometry and Cycles lights have no range; "
                       "raise the range beyond %g or remove it",
                       c->s->path, i, (double)l->range, cycles_max_dist(c->m, l->position));
        return RC_ERR_RANGE;
    }
    if (l->kind == LIGHT_SPOT) {
        if (l->profile != SPOT_SMOOTH) {
            status_message(c->err, c->errlen,
                           "%s: lights[%d]: the D3D spot power law has no Cycles equivalent; use profile smooth",
                           c->s->path, i);
            return RC_ERR_RANGE;
        }
        if (!(l->outer > 0.0f && l->outer <= (float)FORMULA_PI_D && l->inner >= 0.0f && l->inner <= l->outer)) {
            status_message(c->err, c->errlen,
                           "%s: lights[%d]: spot cones need 0 <= inner <= outer <= 180 degrees, outer > 0", c->s->path,
                           i);
            return RC_ERR_RANGE;
        }
    }
    return RC_OK;
}

/* ------------------------------------------------------------------ job sections */

static void cycles_write_light(jw *w, cJSON *lights, const light *l)
{
    /* Cycles takes a scalar power times a colour; the colour carries the RGB ratio. */
    float mx = v3_max_comp(l->intensity);
    vec3 col = mx > 0.0f ? v3_scale(l->intensity, 1.0f / mx) : v3s(1.0f);
    /* 1/(a2 d^2) is pure inverse square with intensity I/a2. */
    double inv_a2 = l->kind == LIGHT_SUN ? 1.0 : 1.0 / (double)l->a2;
    cJSON *o = jw_obj(w, lights, NULL);
    if (l->kind == LIGHT_SUN) {
        /* Sun strength is irradiance at normal incidence. */
        jw_put_str(w, o, "type", "SUN");
        jw_put_num(w, o, "energy", "lights.energy", mx);
    } else {
        /* Point energy P [W] radiates P / (4 pi) W/sr; spots keep the point's intensity. */
        jw_put_str(w, o, "type", l->kind == LIGHT_SPOT ? "SPOT" : "POINT");
        jw_put_num(w, o, "energy", "lights.energy", 4.0 * FORMULA_PI_D * (double)mx * inv_a2);
        jw_put_vec(w, o, "position", "lights.position", l->position);
    }
    jw_put_vec(w, o, "color", "lights.color", col);
    if (l->kind != LIGHT_POINT)
        jw_put_vec(w, o, "direction", "lights.direction", v3_norm(l->direction));
    if (l->kind == LIGHT_SPOT) {
        /* Cycles: cos * smoothstep from cos(size/2) over (1 - cos(size/2)) * blend, which is
         * POV-Ray's radius/falloff pair with half angles inner/2, outer/2 (docs/conventions.md). */
        double cf = cos(0.5 * (double)l->outer), cr = cos(0.5 * (double)l->inner);
        jw_put_num(w, o, "spot_size", "lights.spot_size", l->outer);
        jw_put_num(w, o, "spot_blend", "lights.spot_blend", cf < 1.0 ? (cr - cf) / (1.0 - cf) : 0.0);
    }
}

/* {"kind": "conductor", "eta", "k"} or {"kind": "dielectric", "ior"} under name. */
static void cycles_write_fresnel_of(jw *w, cJSON *parent, const char *name, const material *mat)
{
    cJSON *f = jw_obj(w, parent, name);
    if (mat->conductor) {
        jw_put_str(w, f, "kind", "conductor");
        jw_put_vec(w, f, "eta", "materials.eta", mat->eta);
        jw_put_vec(w, f, "k", "materials.k", mat->k);
    } else {
        jw_put_str(w, f, "kind", "dielectric");
        jw_put_num(w, f, "ior", "materials.ior", mat->ior);
    }
}

/* The material's physical normal-incidence reflectance: dielectric ((n-1)/(n+1))^2, conductor
 * ((eta-1)^2 + k^2)/((eta+1)^2 + k^2) per channel. */
static vec3 cycles_f0(const material *mat)
{
    if (!mat->conductor) {
        float r = (mat->ior - 1.0f) / (mat->ior + 1.0f);
        return v3s(r * r);
    }
    float e[3] = {mat->eta.x, mat->eta.y, mat->eta.z}, k[3] = {mat->k.x, mat->k.y, mat->k.z}, f[3];
    for (int c = 0; c < 3; c++)
        f[c] = ((e[c] - 1.0f) * (e[c] - 1.0f) + k[c] * k[c]) / ((e[c] + 1.0f) * (e[c] + 1.0f) + k[c] * k[c]);
    return v3(f[0], f[1], f[2]);
}

rc_status cycles_physics(const scene *s, physics *out, char *err, size_t errlen)
{
    const physics *want = &s->physics;
    int any_rough = 0;
    for (int mi = 0; mi < s->n_materials; mi++) {
        const material *mat = &s->materials[mi];
        if (!scene_material_used(s, mi))
            continue;
        if (mat->thin && want->fresnel_reflection != PHYS_FRESNEL_EXACT) {
            status_message(err, errlen,
                           "%s: materials[%d] '%s': a thin sheet (a Glass BSDF slab) reflects with the exact "
                           "Fresnel of each face; set physics fresnel_reflection: exact",
                           s->path, mi, mat->name);
            return RC_ERR_RANGE;
        }
        if (!(mat->roughness >= 0.0f && mat->roughness <= 1.0f)) {
            status_message(err, errlen,
                           "%s: materials[%d] '%s': roughness %g outside [0, 1]; Cycles clamps Beckmann alpha "
                           "to 1, so use a roughness in [0, 1]",
                           s->path, mi, mat->name, (double)mat->roughness);
            return RC_ERR_RANGE;
        }
        any_rough |= mat->lobe && mat->roughness > 0.0f;
    }
    unsigned all = s->n_lights >= 32 ? ~0u : (1u << s->n_lights) - 1u;
    /* A mirror's highlight of a point or sun light is a delta (zero in the image): only a rough
     * lobe is lit by the lamps. */
    int lamps_on_lobe = any_rough && (want->specular_lights & all) != 0;
    int env_on_lobe = want->env_specular && s->env.kind != ENV_NONE;
    *out = *want;
    if (lamps_on_lobe && env_on_lobe && want->fresnel_specular != want->fresnel_reflection) {
        status_message(err, errlen,
                       "%s: physics: fresnel_specular %s and fresnel_reflection %s: one Cycles Glossy closure "
                       "reflects the lamps and the environment; give both one form",
                       s->path, physics_fresnel_names[want->fresnel_specular],
                       physics_fresnel_names[want->fresnel_reflection]);
        return RC_ERR_RANGE;
    }
    if (!any_rough)
        return RC_OK; /* on a mirror F(N.V) is F(V.H): every form is rendered as asked */
    /* The Glossy BSDF's colour tints the whole Beckmann lobe: Fresnel of N.V, not per
     * microfacet. So exact becomes nv (a bias, measured against the exact reference), and a
     * per-microfacet Schlick has no form at all. */
    if ((lamps_on_lobe && want->fresnel_specular == PHYS_FRESNEL_SCHLICK) ||
        (env_on_lobe && want->fresnel_reflection == PHYS_FRESNEL_SCHLICK)) {
        status_message(err, errlen,
                       "%s: physics: Schlick per microfacet on a rough lobe: Blender 3.4's Glossy BSDF has no "
                       "per-microfacet Fresnel; use fresnel one, or nv (a bias), or the exact reference",
                       s->path);
        return RC_ERR_RANGE;
    }
    if (lamps_on_lobe && want->fresnel_specular == PHYS_FRESNEL_EXACT)
        out->fresnel_specular = PHYS_FRESNEL_NV;
    if (env_on_lobe && want->fresnel_reflection == PHYS_FRESNEL_EXACT)
        out->fresnel_reflection = PHYS_FRESNEL_NV;
    return RC_OK;
}

typedef struct {
    int mirror; /* a SHARP glossy closure that must see the environment */
    int glossy; /* a Beckmann closure lit by the lamps */
} cycles_usage;

/* Textures (scene/texture.h): an Image Texture node, Linear interpolation, repeat, on the mesh's
 * UVs, reading our decoded texels as linear float (renderer_write_textures), multiplies the
 * diffuse and emission colours (diffuse map) or the glossy colour (specular map), as the
 * rasterizer multiplies those terms. */
static rc_status cycles_write_textures(cycles_ctx *c, jw *w, cJSON *o, int mi)
{
    const material *mat = &c->s->materials[mi];
    static const char *const slot[MAT_TEX_SLOTS] = {"diffuse", "specular"};
    static const char *const closure[MAT_TEX_SLOTS] = {"diffuse", "glossy"};
    for (int k = 0; k < MAT_TEX_SLOTS; k++) {
        if (mat->texture[k][0] == '\0')
            continue;
        if (c->o->texture_dir == NULL || c->m->uv == NULL) {
            status_message(c->err, c->errlen,
                           "%s: materials[%d] '%s': textured, but no texture folder (cycles_options.texture_dir) or "
                           "mesh UVs were given; render it through cycles_render_job",
                           c->s->path, mi, mat->name);
            return RC_ERR_RANGE;
        }
        if (k == MAT_TEX_SPECULAR && !c->twin) {
            status_message(c->err, c->errlen,
                           "%s: materials[%d] '%s': texture.specular scales an approximation's specular term and has "
                           "no place in the physics; validate without it",
                           c->s->path, mi, mat->name);
            return RC_ERR_RANGE;
        }
        char path[1200];
        snprintf(path, sizeof path, "%s/tex%d_%s.exr", c->o->texture_dir, mi, slot[k]);
        cJSON *target = cJSON_GetObjectItemCaseSensitive(o, closure[k]);
        if (target != NULL)
            jw_put_str(w, target, "texture", path);
        if (k == MAT_TEX_DIFFUSE && cJSON_GetObjectItemCaseSensitive(o, "emission") != NULL)
            jw_put_str(w, o, "emission_texture", path);
    }
    return RC_OK;
}

/* Whether material mi's twin takes its diffuse colour from the vertices (a colour attribute,
 * interpolated across each face as the rasterizer interpolates it per pixel): model d3d,
 * colour_vertex, diffuse_source colour1 and no other source from the vertex. */
static int cycles_vertex_diffuse(const scene *s, const mesh *m, int mi, int twin)
{
    const material *mat = &s->materials[mi];
    if (!twin || !mesh_material_vertex_coloured(s, m, mi) || mat->d3d.diffuse_source != COLOUR_SOURCE_COLOUR1)
        return 0;
    unsigned have = 0;
    for (int i = 0; i < s->n_objects && i < SCENE_MAX_OBJECTS; i++)
        if (s->objects[i].material == mi)
            have |= m->colours[i];
    d3d_params rest = mat->d3d;
    rest.diffuse_source = COLOUR_SOURCE_MATERIAL;
    return !d3d_uses_vertex_colours(&rest, have);
}

/* A validate's material: the scene's physics (cycles_physics has checked it is renderable), a
 * dielectric coating over Lambert, or a bare conductor. Roughness 0 is a mirror (SHARP). */
static rc_status cycles_material_physical(cycles_ctx *c, jw *w, cJSON *o, int mi, int used, cycles_usage *u)
{
    const scene *s = c->s;
    const material *mat = &s->materials[mi];
    const physics *ph = &s->physics;
    if (mat->thin) {
        /* A glass slab (cycles_render.py: the pane and its copy CYCLES_THIN_THICKNESS behind,
         * faces reversed) with a sharp Glass BSDF: two faces, every internal reflection. */
        jw_put_num(w, jw_obj(w, o, "glass"), "ior", "materials.ior", mat->ior);
        u->mirror |= used; /* its reflection must see the environment */
        return RC_OK;
    }
    if (!mat->conductor) {
        cJSON *dif = jw_obj(w, o, "diffuse");
        jw_put_vec(w, dif, "color", "materials.albedo", mat->albedo);
        if (ph->diffuse_weight == PHYS_DIFFUSE_ONE_MINUS_F)
            jw_put_num(w, dif, "fresnel_ior", "materials.ior", mat->ior);
    }
    cJSON *gl = jw_obj(w, o, "glossy");
    jw_put_num(w, gl, "roughness", "materials.roughness", sqrt(fmax((double)mat->roughness, 0.0)));
    /* Glossy's GGX: alpha = Roughness^2 as for Beckmann, separable Smith G with the exact GGX
     * G1 (svm/closure.h, closure/bsdf_microfacet.h), the physics of model/physical.h. */
    if (mat->distribution == DIST_GGX)
        jw_put_str(w, gl, "distribution", "ggx");
    /* A material without a lobe (material.lobe 0) reflects nothing: a black glossy. */
    jw_put_vec(w, gl, "color", "materials.glossy_color", v3s(mat->lobe ? 1.0f : 0.0f));
    /* One closure reflects lamps and environment: a rough lobe takes the lamps' form
     * (cycles_physics refuses two forms on one lobe), a mirror the environment's. */
    physics_fresnel form = mat->roughness > 0.0f ? ph->fresnel_specular : ph->fresnel_reflection;
    if (form == PHYS_FRESNEL_ONE) {
        jw_put_str(w, jw_obj(w, gl, "fresnel"), "kind", "one");
    } else if (form == PHYS_FRESNEL_SCHLICK) {
        cJSON *f = jw_obj(w, gl, "fresnel");
        jw_put_str(w, f, "kind", "schlick");
        jw_put_vec(w, f, "f0", "materials.f0", cycles_f0(mat));
    } else {
        cycles_write_fresnel_of(w, gl, "fresnel", mat);
    }
    if (v3_nonzero(mat->d3d.emissive))
        jw_put_vec(w, o, "emission", "materials.emissive", mat->d3d.emissive);
    u->glossy |= used;
    return used ? cycles_write_textures(c, w, o, mi) : RC_OK;
}

/* A used D3D or D3D9Client material's features a Cycles twin has no closure for: a whole term
 * left out under options.partial (cycles_cannot), else an error. */
static rc_status cycles_twin_d3d_refusals(cycles_ctx *c, int mi)
{
    const scene *s = c->s;
    const material *mat = &s->materials[mi];
    const d3d_params *d = &mat->d3d;
    char what[160];
    rc_status rc;
    int amb_light = 0;
    for (int i = 0; i < s->n_lights; i++)
        amb_light |= v3_nonzero(s->lights[i].ambient);
    if (v3_nonzero(d->specular)) {
        snprintf(what, sizeof what, "materials[%d] '%s': Cycles has no Blinn-Phong lobe (d3d specular)", mi, mat->name);
        if ((rc = cycles_cannot(c, RENDERER_TERM_SPECULAR, what, "set the d3d specular colour to 0")) != RC_OK)
            return rc;
    }
    if (v3_nonzero(d->ambient) && (amb_light || v3_nonzero(s->global_ambient))) {
        snprintf(what, sizeof what, "materials[%d] '%s': D3D ambient Va*(Ia + La) has no Cycles equivalent", mi,
                 mat->name);
        if ((rc = cycles_cannot(c, 0, what, "set the material ambient to 0")) != RC_OK)
            return rc;
    }
    if (d->per_vertex) {
        snprintf(what, sizeof what, "materials[%d] '%s': Gouraud (per-vertex) shading", mi, mat->name);
        if ((rc = cycles_cannot(c, 0, what, "shade per pixel")) != RC_OK)
            return rc;
    }
    if (d->clamp) {
        snprintf(what, sizeof what, "materials[%d] '%s': D3D clamping to [0, 1]", mi, mat->name);
        if ((rc = cycles_cannot(c, 0, what, "turn clamp off")) != RC_OK)
            return rc;
    }
    /* What no renderer twins: only a validate can judge it. */
    const char *only_validate =
        mesh_material_unnormalised(s, mi)
            ? "d3d.normalize_normals false on a scaled object (Cycles normalises every normal)"
        : d3d9client_dissolve_on(mat)
            ? "d3d9client.dissolve (source 000's noise on the reflected direction; no renderer reproduces it)"
        : mat->model == MODEL_D3D9CLIENT && mat->d9.blend && mat->texture[MAT_TEX_DIFFUSE][0] != '\0'
            ? "d3d9client.blend on a textured material (eq. 7's texel alpha is not translated)"
            : NULL;
    if (only_validate != NULL) {
        snprintf(what, sizeof what, "materials[%d] '%s': %s", mi, mat->name, only_validate);
        if ((rc = cycles_cannot(c, 0, what, "judge it with role validate")) != RC_OK)
            return rc;
    }
    return RC_OK;
}

/* The D3D9Client twin: eq. (6)'s weighted diffuse, eq. (8)'s sun angle, eq. (5)'s mirror under
 * an environment and eq. (7)'s blend. */
static rc_status cycles_twin_d3d9client(cycles_ctx *c, jw *w, cJSON *o, int mi, int used, cycles_usage *u)
{
    const scene *s = c->s;
    const material *mat = &s->materials[mi];
    const d3d9client_params *p = &mat->d9;
    char what[160];
    rc_status rc;
    /* eq. (6): the lit diffuse d times 1 - |lambda| (a constant, formed here as the rasterizer does). */
    float weight = 1.0f - d3d9client_colour_norm(p->reflect, p->norm);
    cJSON *dif = jw_obj(w, o, "diffuse");
    jw_put_vec(w, dif, "color", "materials.d3d.diffuse", v3_scale(mat->d3d.diffuse, weight));
    if (p->sun_angle) {
        const light *ml = scene_main_light(s);
        if (ml != NULL && ml->kind != LIGHT_SUN && used) {
            snprintf(what, sizeof what,
                     "materials[%d] '%s': eq. (8) with a point or spot main light (position-dependent)", mi, mat->name);
            if ((rc = cycles_cannot(c, 0, what, "make the first light a sun or turn sun_angle off")) != RC_OK)
                return rc;
        } else if (ml != NULL) {
            cJSON *sa = jw_obj(w, dif, "sun_angle");
            jw_put_vec(w, sa, "to_sun", "lights.direction", v3_neg(v3_norm(ml->direction)));
            jw_put_num(w, sa, "r0", "materials.d9.r0", p->r0);
            jw_put_num(w, sa, "m", "materials.d9.m", p->m);
            jw_put_num(w, sa, "p", "materials.d9.p", p->p);
        }
    }
    if (s->env.kind != ENV_NONE) {
        cJSON *mir = jw_obj(w, o, "mirror");
        jw_put_str(w, mir, "kind", "d3d9client");
        jw_put_vec(w, mir, "lambda", "materials.d9.reflect", p->reflect);
        jw_put_vec(w, mir, "s", "materials.d9.fresnel_colour", p->fresnel_colour);
        jw_put_num(w, mir, "r0", "materials.d9.r0", p->r0);
        jw_put_num(w, mir, "m", "materials.d9.m", p->m);
        jw_put_num(w, mir, "p", "materials.d9.p", p->p);
        u->mirror |= used;
    }
    if (p->blend) {
        /* Eq. (7)'s blend: cycles_render.py forms a = max(d_a, |R_tot|) clamped to [0, 1] from
         * the mirror's colour and the environment along the mirror direction, and mixes a
         * Transparent BSDF in with weight 1 - a. */
        d3d9client_norm_weights nw = d3d9client_norm_weights_of(p->norm);
        cJSON *bl = jw_obj(w, o, "blend");
        jw_put_num(w, bl, "d_a", "materials.d9.alpha", p->alpha);
        const double wv[5] = {nw.w_max, nw.w_r, nw.w_g, nw.w_b, nw.w_euclid};
        static const char *const wk[5] = {"w_max", "w_r", "w_g", "w_b", "w_euclid"};
        for (int k = 0; k < 5; k++)
            jw_put_num(w, bl, wk[k], "materials.d9.norm", wv[k]);
    }
    return RC_OK;
}

/* The Cook-Torrance twin: Lambert, a Beckmann lobe when Cycles' matches the model's, and the
 * mirror term CM * Fr under an environment. */
static rc_status cycles_twin_cook_torrance(cycles_ctx *c, jw *w, cJSON *o, int mi, int used, cycles_usage *u)
{
    const scene *s = c->s;
    const material *mat = &s->materials[mi];
    const ct_params *p = &mat->ct;
    char what[160];
    rc_status rc;
    jw_put_vec(w, jw_obj(w, o, "diffuse"), "color", "materials.albedo", mat->albedo);
    int lobe = v3_nonzero(p->ks), env_term = p->reflection && s->env.kind != ENV_NONE;
    if (lobe && used && env_term) {
        /* The mirror below needs the world visible to glossy rays, and then the Beckmann lobe
         * would reflect the environment too (Cycles 3.4 has no light linking); a scene
         * without an environment (ct_toaster) is the lobe's twin. */
        snprintf(what, sizeof what,
                 "materials[%d] '%s': its Beckmann lobe would reflect the environment its mirror term needs", mi,
                 mat->name);
        if ((rc = cycles_cannot(c, RENDERER_TERM_SPECULAR, what,
                                "switch the reflection off (cook_torrance reflection: false)")) != RC_OK)
            return rc;
        lobe = 0;
    }
    if (lobe && used && (p->g != G_SMITH_WALTER || p->f != F_ONE || p->norm != CT_WALTER)) {
        snprintf(what, sizeof what,
                 "materials[%d] '%s': Cycles' Beckmann lobe is walter-normalised, Smith-Walter G, F = 1", mi,
                 mat->name);
        if ((rc = cycles_cannot(c, RENDERER_TERM_SPECULAR, what, "set ct g smith_walter, f one, norm walter")) != RC_OK)
            return rc;
        lobe = 0;
    }
    if (lobe && used && !(p->m > 0.0f && p->m <= 1.0f)) {
        status_message(c->err, c->errlen,
                       "%s: materials[%d] '%s': ct m %g outside (0, 1]; Cycles clamps Beckmann alpha to 1, "
                       "so use m in (0, 1]",
                       s->path, mi, mat->name, (double)p->m);
        return RC_ERR_RANGE;
    }
    if (lobe) {
        /* Cycles: alpha = Roughness^2 and alpha is Beckmann's m. */
        cJSON *gl = jw_obj(w, o, "glossy");
        jw_put_num(w, gl, "roughness", "materials.ct.m", sqrt((double)p->m));
        jw_put_vec(w, gl, "color", "materials.ct.ks", p->ks);
        u->glossy |= used;
    }
    if (env_term) {
        /* CM * Fr: a Glossy Sharp closure sees env(reflect(-V, N)) through the path tracer,
         * coloured by Fr(N.V) as cooktorrance_reflection_weight picks it (Schlick as
         * authored: the twin switches keep F for such a material). */
        if (p->f == F_ONE) {
            jw_put_str(w, jw_obj(w, o, "mirror"), "kind", "one");
        } else if (p->f == F_EXACT) {
            cycles_write_fresnel_of(w, o, "mirror", mat);
        } else {
            cJSON *f = jw_obj(w, o, "mirror");
            jw_put_str(w, f, "kind", "schlick");
            jw_put_vec(w, f, "f0", "materials.ct.f0", p->f0);
        }
        u->mirror |= used;
    }
    return RC_OK;
}

static rc_status cycles_write_material(cycles_ctx *c, jw *w, cJSON *materials, int mi, cycles_usage *u)
{
    const scene *s = c->s;
    const material *mat = &s->materials[mi];
    int used = scene_material_used(s, mi);
    cJSON *o = jw_obj(w, materials, NULL);
    rc_status rc = RC_OK;

    jw_put_str(w, o, "name", mat->name);
    if (!c->twin)
        return cycles_material_physical(c, w, o, mi, used, u);

    /* Twin: the rasterizer's own terms (harness/CONTRACT.md). */
    const d3d_params *d = &mat->d3d;
    if (used && (mat->model == MODEL_D3D || mat->model == MODEL_D3D9CLIENT) &&
        (rc = cycles_twin_d3d_refusals(c, mi)) != RC_OK)
        return rc;
    if (used && mat->model == MODEL_USER) {
        status_message(c->err, c->errlen,
                       "%s: materials[%d] '%s': model user (%s) has no Cycles twin: a twin needs a translator of "
                       "the user's model, which none was given; judge it with role validate",
                       s->path, mi, mat->name, mat->user.path);
        return RC_ERR_RANGE;
    }
    switch (mat->model) {
    case MODEL_USER: break;
    case MODEL_D3D: {
        cJSON *dif = jw_obj(w, o, "diffuse");
        jw_put_vec(w, dif, "color", "materials.d3d.diffuse", d->diffuse);
        if (cycles_vertex_diffuse(s, c->m, mi, c->twin))
            jw_put_bool(w, dif, "vertex_colour", 1);
        /* d3d.two_sided false: a back face lit through the surface (cycles_render.py). */
        if (!d->two_sided && c->twin)
            jw_put_bool(w, dif, "one_sided", 1);
        break;
    }
    case MODEL_D3D9CLIENT: rc = cycles_twin_d3d9client(c, w, o, mi, used, u); break;
    case MODEL_COOK_TORRANCE: rc = cycles_twin_cook_torrance(c, w, o, mi, used, u); break;
    }
    if (rc != RC_OK)
        return rc;
    if (v3_nonzero(d->emissive))
        jw_put_vec(w, o, "emission", "materials.d3d.emissive", d->emissive);
    return used ? cycles_write_textures(c, w, o, mi) : RC_OK;
}

/* A thin sheet's thickness in the validate render, in metres: the sideways shift of a ray through
 * it, at most about this much, is far below a pixel at canonical scene sizes (metres across). */
#define CYCLES_THIN_THICKNESS 0.002

static void cycles_write_objects(jw *w, cJSON *objects, const scene *s, const mesh *m, int *remap, int twin)
{
    for (int oi = 0; oi < s->n_objects && !w->nomem; oi++) {
        int n_tris = 0, n_verts = 0;
        for (int t = 0; t < m->n_tris; t++) {
            if (m->tri_object[t] != oi)
                continue;
            n_tris++;
            for (int k = 0; k < 3; k++) {
                uint32_t v = m->idx[3 * t + k];
                if (remap[v] < 0)
                    remap[v] = n_verts++;
            }
        }
        if (n_tris == 0)
            continue;
        /* Object-local vertex order: the order of first use, so the list can be written in one pass. */
        int *order = remap + m->n_verts;
        for (int v = 0; v < m->n_verts; v++)
            if (remap[v] >= 0)
                order[remap[v]] = v;
        cJSON *o = jw_obj(w, objects, NULL);
        char name[32];
        snprintf(name, sizeof name, "object_%d", oi);
        jw_put_str(w, o, "name", name);
        jw_put_int(w, o, "material", s->objects[oi].material);
        jw_put_int(w, o, "pass_index", oi + 1);
        if (!twin && s->materials[s->objects[oi].material].thin)
            jw_put_num(w, o, "thin", "objects.thin", CYCLES_THIN_THICKNESS);
        jw_put_flat(w, o, "verts", "mesh.pos", m->pos, order, n_verts);
        jw_put_flat(w, o, "normals", "mesh.nrm", m->nrm, order, n_verts);
        const material *mat = &s->materials[s->objects[oi].material];
        if (cycles_vertex_diffuse(s, m, s->objects[oi].material, twin)) {
            /* An object without colour1 keeps the material's diffuse colour (model/d3d.h). */
            cJSON *col = jw_arr(w, o, "colours");
            for (int i = 0; i < n_verts && !w->nomem; i++) {
                vec3 cv = (m->colours[oi] & 1u) ? m->col1[order[i]] : mat->d3d.diffuse;
                jw_push_num(w, col, "mesh.col1", cv.x);
                jw_push_num(w, col, "mesh.col1", cv.y);
                jw_push_num(w, col, "mesh.col1", cv.z);
            }
        }
        int textured = 0;
        for (int k = 0; k < MAT_TEX_SLOTS; k++)
            textured |= mat->texture[k][0] != '\0';
        if (textured && m->uv != NULL) {
            cJSON *uv = jw_arr(w, o, "uvs");
            for (int i = 0; i < n_verts && !w->nomem; i++) {
                jw_push_num(w, uv, "mesh.uv", m->uv[2 * order[i]]);
                jw_push_num(w, uv, "mesh.uv", m->uv[2 * order[i] + 1]);
            }
        }
        cJSON *tris = jw_arr(w, o, "tris");
        for (int t = 0; t < m->n_tris && !w->nomem; t++) {
            if (m->tri_object[t] != oi)
                continue;
            for (int k = 0; k < 3; k++)
                jw_push(w, tris, cJSON_CreateNumber(remap[m->idx[3 * t + k]]));
        }
        for (int i = 0; i < n_verts; i++)
            remap[order[i]] = -1;
    }
}

/* The image the job asks for: options over the scene, k x k sub-pixels per pixel. */
typedef struct {
    int ss; /* supersample k, at least 1 */
    int width, height;
    int samples; /* per sub-pixel */
    int n_seeds;
} cycles_job_size;

static rc_status cycles_size(const scene *s, const cycles_options *o, cycles_job_size *z, char *err, size_t errlen)
{
    z->ss = o->supersample > 1 ? o->supersample : 1;
    z->width = (o->width > 0 ? o->width : s->width) * z->ss;
    z->height = (o->height > 0 ? o->height : s->height) * z->ss;
    int samples = o->samples > 0 ? o->samples : s->samples;
    z->n_seeds = o->n_seeds > 0 ? o->n_seeds : 1;
    /* k x k sub-pixels share the pixel's samples: the same count per pixel, rounded up. */
    z->samples = (samples + z->ss * z->ss - 1) / (z->ss * z->ss);
    /* Blender refuses images smaller than 4 pixels (docs/conventions.md). */
    if (o->supersample < 0 || o->supersample > 16) {
        status_message(err, errlen, "%s: supersample %d: Cycles samples k x k positions for k in 1..16", s->path,
                       o->supersample);
        return RC_ERR_RANGE;
    }
    if (z->width < 4 || z->height < 4 || z->width > 65536 || z->height > 65536) {
        status_message(err, errlen, "%s: image %d x %d: Cycles needs 4 to 65536 pixels per side; change width/height",
                       s->path, z->width, z->height);
        return RC_ERR_RANGE;
    }
    if (z->samples < 1 || z->n_seeds > 64) {
        status_message(err, errlen, "%s: samples %d, seeds %d: need samples >= 1 and at most 64 seeds", s->path,
                       z->samples, z->n_seeds);
        return RC_ERR_RANGE;
    }
    return RC_OK;
}

/* The mesh must be this scene's (mesh_build): arrays present, every index in range, and
 * vertex colours only where the role can render them. */
static rc_status cycles_check_mesh(const cycles_ctx *c)
{
    const scene *s = c->s;
    const mesh *m = c->m;
    if (m->n_tris > 0 && (m->tri_object == NULL || m->idx == NULL || m->pos == NULL || m->nrm == NULL)) {
        status_message(c->err, c->errlen, "%s: mesh arrays missing; build the mesh with mesh_build", s->path);
        return RC_ERR_RANGE;
    }
    for (int t = 0; t < m->n_tris; t++) {
        if (m->tri_object[t] < 0 || m->tri_object[t] >= s->n_objects) {
            status_message(c->err, c->errlen, "%s: mesh triangle %d names object %d of %d; rebuild the mesh", s->path,
                           t, m->tri_object[t], s->n_objects);
            return RC_ERR_RANGE;
        }
        for (int k = 0; k < 3; k++)
            if (m->idx[3 * t + k] >= (uint32_t)m->n_verts) {
                status_message(c->err, c->errlen, "%s: mesh triangle %d has vertex %u of %d; rebuild the mesh", s->path,
                               t, m->idx[3 * t + k], m->n_verts);
                return RC_ERR_RANGE;
            }
    }
    for (int mi = 0; mi < s->n_materials; mi++)
        if (mesh_material_vertex_coloured(s, m, mi) && !cycles_vertex_diffuse(s, m, mi, c->twin)) {
            status_message(c->err, c->errlen, "%s: materials[%d] '%s': D3D vertex colours (d3d.colour_vertex): %s; %s",
                           s->path, mi, s->materials[mi].name,
                           c->twin ? "Cycles' twin takes the diffuse colour alone from the vertex (diffuse_source "
                                     "colour1)"
                                   : "a validate renders the physics, which has no vertex colours",
                           c->twin ? "select the material for the others" : "set colour_vertex false");
            return RC_ERR_RANGE;
        }
    return RC_OK;
}

/* Every light Cycles can render, the physics a validate asks for, and no D3D light ambient La
 * on a used material's Va in a twin. */
static rc_status cycles_check_lights(cycles_ctx *c)
{
    const scene *s = c->s;
    rc_status rc;
    for (int i = 0; i < s->n_lights; i++)
        if ((rc = cycles_check_light(c, i)) != RC_OK)
            return rc;
    if (!c->twin && (rc = renderer_physics_check(cycles_physics, s, c->err, c->errlen)) != RC_OK)
        return rc;
    if (c->twin) {
        char what[160];
        for (int i = 0; i < s->n_lights; i++) {
            int any_va = 0;
            for (int mi = 0; mi < s->n_materials; mi++)
                any_va |= scene_material_used(s, mi) && s->materials[mi].model != MODEL_COOK_TORRANCE &&
                          v3_nonzero(s->materials[mi].d3d.ambient);
            if (v3_nonzero(s->lights[i].ambient) && any_va) {
                snprintf(what, sizeof what, "lights[%d]: D3D light ambient La", i);
                if ((rc = cycles_cannot(c, 0, what, "set the light ambient to 0")) != RC_OK)
                    return rc;
            }
        }
    }
    return RC_OK;
}

/* The environment image's absolute path for Blender (env_path, PATH_MAX bytes; "" without an
 * image); a cube map is refused: Blender takes its equirectangular conversion. */
static rc_status cycles_env_path(const scene *s, char *env_path, char *err, size_t errlen)
{
    env_path[0] = '\0';
    if (s->env.kind == ENV_CUBE) {
        status_message(err, errlen,
                       "%s: environment: a cube map reaches Blender as its equirectangular conversion, which "
                       "`reflcheck run` writes (harness/jobs.c); render the scene through it",
                       s->path);
        return RC_ERR_RANGE;
    }
    if (s->env.kind == ENV_IMAGE) {
        /* Blender resolves relative paths against its own idea of the .blend directory. */
        if (realpath(s->env.path, env_path) == NULL) {
            status_message(err, errlen, "%s: environment '%s': %s; check the path (relative to the working directory)",
                           s->path, s->env.path, strerror(errno));
            return RC_ERR_IO;
        }
    }
    return RC_OK;
}

/* The job's identity and image: format, scene, role, size, samples, filter and seeds. */
static void cycles_write_header(jw *w, cJSON *doc, const cycles_ctx *c, const cycles_job_size *z)
{
    const scene *s = c->s;
    jw_put_str(w, doc, "format", "reflcheck-cycles-job");
    jw_put_int(w, doc, "version", 1);
    jw_put_str(w, doc, "scene", s->name);
    jw_put_str(w, doc, "scene_path", s->path);
    char hash[24];
    snprintf(hash, sizeof hash, "%016llx", (unsigned long long)s->hash);
    jw_put_str(w, doc, "scene_hash", hash);
    jw_put_str(w, doc, "role", c->twin ? "twin" : "validate");
    jw_put_int(w, doc, "width", z->width);
    jw_put_int(w, doc, "height", z->height);
    jw_put_int(w, doc, "samples", z->samples);
    /* A point per sub-pixel: Blender's narrowest filter (0.01 sub-pixel, a Gaussian: it ignores
     * a box's width) spreads the samples over 1 % of the 1/k spacing of the positions. */
    jw_put_num(w, doc, "filter_width", "filter_width", z->ss > 1 ? 0.01 : 1.0);
    jw_put_int(w, doc, "supersample", z->ss);
    cJSON *seeds = jw_arr(w, doc, "seeds");
    for (int i = 0; i < z->n_seeds; i++)
        jw_push(w, seeds, cJSON_CreateNumber(c->o->seed + (unsigned)i));
}

static void cycles_write_camera(jw *w, cJSON *doc, const scene *s, const mesh *m)
{
    /* Camera rays start at clip_start: keep it far below any scene distance. */
    double far = cycles_max_dist(m, s->camera.eye);
    cJSON *cam = jw_obj(w, doc, "camera");
    jw_put_vec(w, cam, "eye", "camera.eye", s->camera.eye);
    jw_put_vec(w, cam, "target", "camera.target", s->camera.target);
    jw_put_vec(w, cam, "up", "camera.up", s->camera.up);
    jw_put_num(w, cam, "hfov", "camera.hfov", s->camera.hfov);
    jw_put_num(w, cam, "clip_start", "camera.clip_start", fmax(1e-6, 1e-5 * far));
    jw_put_num(w, cam, "clip_end", "camera.clip_end", fmax(1.0, 4.0 * far));
}

/* The physics (validate): which closures each lamp lights, shadows, inter-reflection and
 * bounces. A twin computes the model: every lamp on every closure, nothing else. */
static void cycles_write_physics(jw *w, cJSON *doc, const scene *s, int twin)
{
    const physics *ph = &s->physics;
    cJSON *phj = jw_obj(w, doc, "physics");
    cJSON *lv = jw_arr(w, phj, "light_visibility");
    for (int i = 0; i < s->n_lights; i++) {
        cJSON *e = jw_obj(w, lv, NULL);
        jw_put_bool(w, e, "diffuse", twin || (ph->diffuse_lights & (1u << i)) != 0);
        jw_put_bool(w, e, "glossy", twin || (ph->specular_lights & (1u << i)) != 0);
    }
    jw_put_bool(w, phj, "shadows", !twin && ph->shadows);
    jw_put_bool(w, phj, "interreflection", !twin && ph->interreflection);
    jw_put_int(w, phj, "bounces", twin ? 1 : ph->bounces);
}

/* An image's "map_resolution" (options.env_detail, when set): the width of the world's importance
 * map cycles_render.py builds, where the image's own width would over-resolve its detail. */
static void cycles_write_environment(jw *w, cJSON *doc, const scene *s, const char *env_path, int detail)
{
    cJSON *env = jw_obj(w, doc, "environment");
    switch (s->env.kind) {
    case ENV_NONE: jw_put_str(w, env, "type", "none"); break;
    case ENV_CONSTANT:
        jw_put_str(w, env, "type", "constant");
        jw_put_vec(w, env, "radiance", "environment.radiance", s->env.radiance);
        break;
    case ENV_CUBE: /* refused by cycles_env_path */
    case ENV_IMAGE:
        jw_put_str(w, env, "type", "image");
        jw_put_str(w, env, "path", env_path);
        jw_put_vec(w, env, "scale", "environment.radiance", s->env.radiance);
        if (detail > 0)
            jw_put_int(w, env, "map_resolution", detail);
        break;
    }
}

/* Which rays see the world, the AOV the glossy passes go to, and the terms left out. */
static rc_status cycles_write_world(jw *w, cJSON *doc, const cycles_ctx *c, const cycles_usage *u)
{
    const scene *s = c->s;
    const physics *ph = &s->physics;
    /* Glossy passes hold every glossy closure: they can be routed to one AOV only. A Beckmann
     * lobe also sees the environment whenever a mirror needs the world visible to glossy rays. */
    if (c->twin && u->mirror && u->glossy) {
        status_message(c->err, c->errlen,
                       "%s: a Cycles twin cannot separate a Cook-Torrance lobe (specular) from a D3D9Client mirror "
                       "(reflection) under one environment; put the materials of model cook_torrance and those of "
                       "model d3d9client in separate scenes",
                       s->path);
        return RC_ERR_RANGE;
    }
    int world_diffuse = !c->twin && ph->env_diffuse, world_glossy = c->twin ? u->mirror : ph->env_specular;
    /* Light-sampling the world only helps closures that sample lights: diffuse and Beckmann,
     * not a mirror. Skipping it saves the importance map (~1.7 s for a 1024 x 512 image). */
    int world_sampled = s->env.kind != ENV_NONE && (world_diffuse || (world_glossy && u->glossy));
    cJSON *vis = jw_obj(w, doc, "world_visibility");
    jw_put_bool(w, vis, "diffuse", world_diffuse);
    jw_put_bool(w, vis, "glossy", world_glossy);
    jw_put_bool(w, vis, "light_sampling", world_sampled);
    jw_put_str(w, doc, "glossy_aov", u->mirror ? "reflection" : "specular");
    cJSON *missing = jw_arr(w, doc, "missing");
    for (int i = 0; i < c->n_missing; i++)
        jw_push(w, missing, cJSON_CreateString(c->missing[i]));
    return RC_OK;
}

/* The whole document after the checks: every section in the job's order. */
static rc_status cycles_write_doc(jw *w, cJSON *doc, cycles_ctx *c, const cycles_job_size *z, const char *env_path,
                                  const char *job_json_path)
{
    const scene *s = c->s;
    const mesh *m = c->m;
    rc_status rc;
    cycles_write_header(w, doc, c, z);
    cycles_write_camera(w, doc, s, m);
    cJSON *lights = jw_arr(w, doc, "lights");
    for (int i = 0; i < s->n_lights; i++)
        cycles_write_light(w, lights, &s->lights[i]);
    cycles_write_physics(w, doc, s, c->twin);
    cycles_write_environment(w, doc, s, env_path, c->o->env_detail);
    cJSON *materials = jw_arr(w, doc, "materials");
    cycles_usage u = {0};
    for (int mi = 0; mi < s->n_materials; mi++)
        if ((rc = cycles_write_material(c, w, materials, mi, &u)) != RC_OK)
            return rc;
    if ((rc = cycles_write_world(w, doc, c, &u)) != RC_OK)
        return rc;
    cJSON *objects = jw_arr(w, doc, "objects");
    int *remap = malloc(sizeof(int) * 2 * (size_t)(m->n_verts > 0 ? m->n_verts : 1));
    if (remap == NULL) {
        status_message(c->err, c->errlen, "%s: out of memory for the vertex map", job_json_path);
        return RC_ERR_NOMEM;
    }
    for (int i = 0; i < m->n_verts; i++)
        remap[i] = -1;
    cycles_write_objects(w, objects, s, m, remap, c->twin);
    free(remap);
    return RC_OK;
}

rc_status cycles_write_job(const scene *s, const mesh *m, const cycles_options *o, const char *job_json_path, char *err,
                           size_t errlen)
{
    cycles_options defaults = {0};
    if (o == NULL)
        o = &defaults;
    cycles_ctx c = {.s = s, .m = m, .o = o, .err = err, .errlen = errlen};
    /* agree compares the two validate renders: the same translation. */
    c.twin = o->role == ROLE_TWIN;
    if (o->role != ROLE_TWIN && o->role != ROLE_VALIDATE && o->role != ROLE_AGREE) {
        status_message(err, errlen, "cycles: options.role %d unknown; use twin, validate or agree", (int)o->role);
        return RC_ERR_RANGE;
    }
    cycles_job_size z;
    rc_status rc;
    char env_path[PATH_MAX];
    if ((rc = cycles_size(s, o, &z, err, errlen)) != RC_OK || (rc = cycles_check_mesh(&c)) != RC_OK ||
        (rc = cycles_check_lights(&c)) != RC_OK || (rc = cycles_env_path(s, env_path, err, errlen)) != RC_OK)
        return rc;

    jw w = {0};
    cJSON *doc = cJSON_CreateObject();
    if ((rc = cycles_write_doc(&w, doc, &c, &z, env_path, job_json_path)) != RC_OK) {
        cJSON_Delete(doc);
        return rc;
    }
    if (w.bad) {
        cJSON_Delete(doc);
        status_message(err, errlen, "%s: %s is NaN or infinite; fix the scene value", s->path, w.bad_key);
        return RC_ERR_RANGE;
    }
    if (doc == NULL || w.nomem) {
        cJSON_Delete(doc);
        status_message(err, errlen, "%s: out of memory for the Cycles job", job_json_path);
        return RC_ERR_NOMEM;
    }
    rc = jsonio_write_file(doc, job_json_path, err, errlen);
    cJSON_Delete(doc);
    return rc;
}

/* ------------------------------------------------------------------ running */

static const char *cycles_put(cycles_argv *a, size_t *used, const char *s)
{
    size_t n = strlen(s) + 1;
    if (*used + n > sizeof a->buf || a->argc >= CYCLES_ARGV_MAX)
        return NULL;
    char *p = a->buf + *used;
    memcpy(p, s, n);
    *used += n;
    a->argv[a->argc++] = p;
    a->argv[a->argc] = NULL;
    return p;
}

rc_status cycles_command(const cycles_options *o, const char *job_json_path, const char *out_exr_path, cycles_argv *out,
                         char *err, size_t errlen)
{
    cycles_options defaults = {0};
    if (o == NULL)
        o = &defaults;
    size_t used = 0;
    out->argc = 0;
    out->argv[0] = NULL;
    char threads[32], script[PATH_MAX];
    snprintf(threads, sizeof threads, "%d", o->threads > 0 ? o->threads : 0);
    /* Our script from the tree we were built from (or $REFLCHECK_DATA_DIR), whatever folder we
     * run in. */
    if (o->script == NULL && !renderer_data_path(CYCLES_SCRIPT, script, sizeof script)) {
        status_message(err, errlen, "cycles: %s is missing; set REFLCHECK_DATA_DIR to the reflcheck source tree",
                       script);
        return RC_ERR_IO;
    }
    const char *list[] = {o->blender ? o->blender : "blender", "-b", "--factory-startup",
                          /* without this a Python exception still exits 0 */
                          "--python-exit-code", "1", "-t", threads, "-P", o->script ? o->script : script, "--",
                          job_json_path, out_exr_path};
    for (size_t i = 0; i < sizeof list / sizeof list[0]; i++)
        if (cycles_put(out, &used, list[i]) == NULL) {
            status_message(err, errlen, "cycles: command line too long (%s); use shorter paths", list[i]);
            return RC_ERR_RANGE;
        }
    return RC_OK;
}

static size_t cycles_stem_len(const char *out)
{
    size_t n = strlen(out);
    if (n >= 4 && (strcmp(out + n - 4, ".exr") == 0 || strcmp(out + n - 4, ".EXR") == 0))
        n -= 4;
    return n;
}

rc_status cycles_raw_path(const char *out_exr_path, int seed_index, char *buf, size_t len)
{
    int n = snprintf(buf, len, "%.*s.cyc%d.exr", (int)cycles_stem_len(out_exr_path), out_exr_path, seed_index);
    return n < 0 || (size_t)n >= len ? RC_ERR_RANGE : RC_OK;
}

const char *cycles_channel_name(const char *aov, char c, char *buf, size_t len)
{
    if (aov == NULL || aov[0] == '\0')
        snprintf(buf, len, "%c", c);
    else if (c == 0)
        snprintf(buf, len, "%s.V", aov);
    else
        snprintf(buf, len, "%s.%c", aov, c);
    return buf;
}

const cycles_layer cycles_layout[CYCLES_LAYOUT_N] = {
    {"", 'R'},           {"", 'G'},           {"", 'B'},           {"", 'A'},           {"diffuse", 'R'},
    {"diffuse", 'G'},    {"diffuse", 'B'},    {"specular", 'R'},   {"specular", 'G'},   {"specular", 'B'},
    {"reflection", 'R'}, {"reflection", 'G'}, {"reflection", 'B'}, {"emission", 'R'},   {"emission", 'G'},
    {"emission", 'B'},   {"background", 'R'}, {"background", 'G'}, {"background", 'B'}, {"coverage", 0},
    {"object", 0},
};

const char *cycles_layer_name(int k, char *buf, size_t len)
{
    const char *aov = cycles_layout[k].aov;
    char c = cycles_layout[k].c;
    /* Blender's name but for a one-channel layer, which is its pass alone (no ".V"). */
    if (aov[0] != '\0' && c == 0) {
        snprintf(buf, len, "%s", aov);
        return buf;
    }
    return cycles_channel_name(aov, c, buf, len);
}

/* A number, or the sum of a list of numbers, under key in the timing JSON the script writes
 * (one entry per seed); NAN if absent. */
static double cycles_timing_value(const cJSON *doc, const char *key)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(doc, key);
    if (cJSON_IsNumber(v))
        return v->valuedouble;
    if (!cJSON_IsArray(v))
        return NAN;
    double sum = 0.0;
    const cJSON *e;
    cJSON_ArrayForEach(e, v) sum += cJSON_IsNumber(e) ? e->valuedouble : NAN;
    return sum;
}

/* The mean of the k x k block of a row-major plane (row length w) whose first sample is first. */
static double cycles_block_mean(const float *plane, int w, size_t first, int k)
{
    double sum = 0.0;
    for (int y = 0; y < k; y++)
        for (int x = 0; x < k; x++)
            sum += plane[first + (size_t)y * (size_t)w + (size_t)x];
    return sum / ((double)k * k);
}

/* The seed images OUT.cyc<i>.exr (img[0..n-1], *loaded of them read) and, in src, each
 * layout channel of each; the first error stops. */
static rc_status cycles_collect_load(const char *out_exr_path, int n, exr_image *img, int *loaded,
                                     const float *src[][CYCLES_LAYOUT_N], char *err, size_t errlen)
{
    char path[PATH_MAX], raw[64];
    rc_status rc = RC_OK;
    for (int i = 0; i < n && rc == RC_OK; i++) {
        if (cycles_raw_path(out_exr_path, i, path, sizeof path) != RC_OK) {
            status_message(err, errlen, "%s: path too long", out_exr_path);
            rc = RC_ERR_RANGE;
            break;
        }
        rc = exr_read(path, &img[i], err, errlen);
        if (rc != RC_OK)
            break;
        (*loaded)++;
        if (img[i].width != img[0].width || img[i].height != img[0].height) {
            status_message(err, errlen, "%s: %d x %d differs from seed 0's %d x %d; render again", path, img[i].width,
                           img[i].height, img[0].width, img[0].height);
            rc = RC_ERR_PARSE;
        }
    }
    for (int i = 0; i < *loaded && rc == RC_OK; i++)
        for (int k = 0; k < CYCLES_LAYOUT_N && rc == RC_OK; k++) {
            cycles_channel_name(cycles_layout[k].aov, cycles_layout[k].c, raw, sizeof raw);
            src[i][k] = exr_image_channel(&img[i], raw);
            if (src[i][k] == NULL) {
                cycles_raw_path(out_exr_path, i, path, sizeof path);
                status_message(err, errlen, "%s: channel %s missing; the file is not from cycles_render.py", path, raw);
                rc = RC_ERR_PARSE;
            }
        }
    return rc;
}

/* One layout channel k reduced to ow x oh pixels: the mean over the seeds of each k x k block
 * (mean) and, with n >= 2 seeds, the variance of that mean (var, else NULL). */
static void cycles_collect_channel(const float *src[][CYCLES_LAYOUT_N], int k, int n, int w_raw, int ss, int ow,
                                   size_t npix, float *mean, float *var)
{
    int is_object = cycles_layout[k].c == 0 && strcmp(cycles_layout[k].aov, "object") == 0;
    for (size_t p = 0; p < npix; p++) {
        size_t first = (p / (size_t)ow) * (size_t)ss * (size_t)w_raw + (p % (size_t)ow) * (size_t)ss;
        if (is_object) {
            /* An index is not averaged: seed 0's first sample names the object. */
            mean[p] = src[0][k][first];
            if (var)
                var[p] = 0.0f;
            continue;
        }
        double v[64], s1 = 0.0;
        for (int i = 0; i < n; i++) {
            v[i] = cycles_block_mean(src[i][k], w_raw, first, ss);
            s1 += v[i];
        }
        double mu = s1 / n, s2 = 0.0;
        for (int i = 0; i < n; i++)
            s2 += (v[i] - mu) * (v[i] - mu);
        mean[p] = (float)mu;
        /* Variance of the mean: sample variance over the seeds (n - 1 dof) / n. */
        if (var)
            var[p] = (float)(s2 / (n - 1) / n);
    }
}

/* out.exr: the reduced channels (data: CYCLES_LAYOUT_N means, then as many variances when
 * n > 1) under reflcheck's names, with the seed count and Blender's timings as attributes. */
static rc_status cycles_collect_write(const char *out_exr_path, const float *src[][CYCLES_LAYOUT_N], int n, int w_raw,
                                      int ss, int ow, int oh, float *data, char *err, size_t errlen)
{
    size_t npix = (size_t)ow * (size_t)oh;
    char names[CYCLES_LAYOUT_N][32], vnames[CYCLES_LAYOUT_N][40];
    exr_channel ch[2 * CYCLES_LAYOUT_N];
    for (int k = 0; k < CYCLES_LAYOUT_N; k++) {
        cycles_layer_name(k, names[k], sizeof names[k]);
        snprintf(vnames[k], sizeof vnames[k], "var.%s", names[k]);
        float *mean = data + (size_t)k * npix;
        float *var = n > 1 ? data + (size_t)(CYCLES_LAYOUT_N + k) * npix : NULL;
        cycles_collect_channel(src, k, n, w_raw, ss, ow, npix, mean, var);
        ch[k].name = names[k];
        ch[k].data = mean;
        if (var) {
            ch[CYCLES_LAYOUT_N + k].name = vnames[k];
            ch[CYCLES_LAYOUT_N + k].data = var;
        }
    }
    char tpath[PATH_MAX], seeds[32], build[32] = "", render[32] = "";
    snprintf(tpath, sizeof tpath, "%.*s.timing.json", (int)cycles_stem_len(out_exr_path), out_exr_path);
    char *text = fileio_read_all(tpath, NULL);
    cJSON *timing = text != NULL ? cJSON_Parse(text) : NULL;
    if (timing != NULL) {
        snprintf(build, sizeof build, "%.3f", cycles_timing_value(timing, "build_s"));
        snprintf(render, sizeof render, "%.3f", cycles_timing_value(timing, "render_s"));
    }
    cJSON_Delete(timing);
    free(text);
    snprintf(seeds, sizeof seeds, "%d", n);
    exr_attr at[] = {{"reflcheck.renderer", "cycles"},
                     {"reflcheck.cycles_seeds", seeds},
                     {"reflcheck.cycles_build_s", build},
                     {"reflcheck.cycles_render_s", render}};
    return exr_write(out_exr_path, ow, oh, ch, n > 1 ? 2 * CYCLES_LAYOUT_N : CYCLES_LAYOUT_N, at, 4, err, errlen);
}

/* Removes the n seed images and the timing file beside out.exr. */
static void cycles_collect_remove_raw(const char *out_exr_path, int n)
{
    char path[PATH_MAX];
    for (int i = 0; i < n; i++)
        if (cycles_raw_path(out_exr_path, i, path, sizeof path) == RC_OK)
            remove(path);
    snprintf(path, sizeof path, "%.*s.timing.json", (int)cycles_stem_len(out_exr_path), out_exr_path);
    remove(path);
}

rc_status cycles_collect(const cycles_options *o, const char *out_exr_path, char *err, size_t errlen)
{
    cycles_options defaults = {0};
    if (o == NULL)
        o = &defaults;
    int n = o->n_seeds > 0 ? o->n_seeds : 1;
    if (n > 64) {
        status_message(err, errlen, "cycles: %d seeds; at most 64", n);
        return RC_ERR_RANGE;
    }
    exr_image img[64];
    memset(img, 0, sizeof img);
    int loaded = 0;
    float *data = NULL;
    const float *src[64][CYCLES_LAYOUT_N];
    rc_status rc = cycles_collect_load(out_exr_path, n, img, &loaded, src, err, errlen);
    int nch = n > 1 ? 2 * CYCLES_LAYOUT_N : CYCLES_LAYOUT_N;
    int ss = o->supersample > 1 ? o->supersample : 1;
    if (rc == RC_OK && (img[0].width % ss != 0 || img[0].height % ss != 0)) {
        status_message(err, errlen, "%s: %d x %d is not a multiple of supersample %d; render again", out_exr_path,
                       img[0].width, img[0].height, ss);
        rc = RC_ERR_PARSE;
    }
    int ow = rc == RC_OK ? img[0].width / ss : 0, oh = rc == RC_OK ? img[0].height / ss : 0;
    size_t npix = (size_t)ow * (size_t)oh;
    if (rc == RC_OK && (data = malloc(sizeof(float) * npix * (size_t)nch)) == NULL) {
        status_message(err, errlen, "%s: out of memory", out_exr_path);
        rc = RC_ERR_NOMEM;
    }
    if (rc == RC_OK)
        rc = cycles_collect_write(out_exr_path, src, n, img[0].width, ss, ow, oh, data, err, errlen);
    free(data);
    for (int i = 0; i < loaded; i++)
        exr_image_free(&img[i]);
    if (rc == RC_OK && !o->keep_raw)
        cycles_collect_remove_raw(out_exr_path, n);
    return rc;
}

/* 1 if every seed image Blender wrote reads as an EXR. */
static int cycles_raw_readable(const cycles_options *o, const char *exr)
{
    for (int i = 0; i < (o->n_seeds > 0 ? o->n_seeds : 1); i++) {
        char path[1200], err[512];
        exr_image img;
        if (cycles_raw_path(exr, i, path, sizeof path) != RC_OK || exr_read(path, &img, err, sizeof err) != RC_OK)
            return 0;
        exr_image_free(&img);
    }
    return 1;
}

/* One Blender pass of a job: write job.json for o, render (through a worker when one runs),
 * collect into j->exr. Adds its wall and CPU time to r; 0 when the image is there, else r
 * says why. */
static int cycles_pass(const renderer_job *j, const cycles_options *o, const char *job, renderer_result *r)
{
    char err[1024];
    rc_status st = cycles_write_job(j->s, j->m, o, job, err, sizeof err);
    cycles_argv a;
    if (st == RC_OK)
        st = cycles_command(o, job, j->exr, &a, err, sizeof err);
    if (st != RC_OK) {
        r->left_out = 0;
        if (st == RC_ERR_RANGE)
            renderer_fail(r, RUNNER_MISSING, "cycles cannot represent this scene: %s", err);
        else
            renderer_fail(r, RUNNER_ERROR, "cannot write the Cycles job: %s", err);
        return 1;
    }
    renderer_command_string((const char *const *)a.argv, r->command, sizeof r->command);
    runner_result rr;
    /* A running Blender worker (worker_pool.py) saves Blender's start-up; with none, or with
     * another Blender or script than the worker's, Blender starts for this job. */
    const char *worker = o->blender == NULL && o->script == NULL ? getenv(CYCLES_WORKER_ENV) : NULL;
    if (cycles_worker_run(worker, job, j->exr, o->threads, j->timeout, j->log, &rr)) {
        char via[2100];
        snprintf(via, sizeof via, "(blender worker %s) %s", worker, r->command);
        snprintf(r->command, sizeof r->command, "%s", via);
    } else
        runner_exec(a.argv, j->timeout > 0 ? j->timeout : 600.0, j->log, &rr);
    r->wall_s += rr.wall_s;
    r->cpu_s += rr.cpu_s;
    if (rr.status != RUNNER_OK) {
        renderer_fail_run(r, &rr, "blender", "blender", "", j->log, "error:", j->shown_log);
        return 1;
    }
    st = cycles_collect(o, j->exr, err, sizeof err);
    if (st != RC_OK) {
        /* Blender's images unreadable fail the job; readable ones that we could not merge and
         * write (disk full) are our error. */
        runner_status why = st == RC_ERR_NOMEM ? RUNNER_ERROR : RUNNER_FAILED;
        if (st == RC_ERR_IO && cycles_raw_readable(o, j->exr))
            why = RUNNER_ERROR;
        renderer_fail(r, why, "%s: %s",
                      why == RUNNER_ERROR ? "cannot write the Cycles image" : "cycles output unreadable", err);
        return 1;
    }
    return 0;
}

/* The log's last lines say the samples, the noise reached against the RMS gates' target (nrmse,
 * or trim1 where an nrmse_trim1 gate asks relatively less of it), the per-value noise against
 * the z-test's, and the gates they came from, then the Blender passes the job took (a pilot and
 * each step: tools/cost_table.py prices a Slurm task's Blender start-up per pass); the job
 * record reads them (jobs.c). pilot 0: the samples were a number. */
static void cycles_samples_line(const renderer_job *j, const cycles_options *o, int passes, int pilot,
                                const cycles_noise *pilot_noise, const cycles_noise *reached,
                                const cycles_noise_need *need)
{
    FILE *f = fopen(j->log, "a");
    if (f == NULL)
        return;
    /* The binding RMS kind: the larger noise / target. */
    int trim = need->target_trim1 > 0.0 &&
               (need->target == 0.0 || reached->trim1 / need->target_trim1 > reached->nrmse / need->target);
    const char *rms = trim ? need->gate_trim1 : need->gate;
    char z[64] = "";
    if (need->bias > 0.0)
        snprintf(z, sizeof z, " z_crit+z_beta %.4g over %ld values", cycles_ztest_span(reached->n_values),
                 reached->n_values);
    fprintf(f,
            "reflcheck-samples: samples %d noise %.6g target %.6g pilot %d pilot_noise %.6g pilot_pixel_q %.6g "
            "pixel_q %.6g ztarget %.6g gate %s%s%s%s\n",
            o->samples > 0 ? o->samples : j->s->samples, trim ? reached->trim1 : reached->nrmse,
            trim ? need->target_trim1 : need->target, pilot, trim ? pilot_noise->trim1 : pilot_noise->nrmse,
            pilot_noise->pixel_q, reached->pixel_q, cycles_ztest_target(need, reached->n_values),
            rms[0] != '\0'           ? rms
            : need->zgate[0] != '\0' ? ""
                                     : "none",
            rms[0] != '\0' && need->zgate[0] != '\0' ? "; " : "", need->zgate, z);
    fprintf(f, "reflcheck-passes: %d\n", passes);
    fclose(f);
}

/* image.samples auto (cycles_samples.h): a pilot, then the samples the gates' noise asks for. */
static void cycles_auto_samples(const renderer_job *j, cycles_options *o, const char *job, renderer_result *r,
                                const cycles_noise_need *need)
{
    if (need->refuse) {
        renderer_fail(r, RUNNER_ERROR, "%s", need->why);
        return;
    }
    int positions = o->supersample > 1 ? o->supersample * o->supersample : 1;
    int n_pilot = cycles_pilot_samples(positions);
    o->samples = n_pilot;
    if (o->n_seeds < 2)
        o->n_seeds = 2; /* the noise is the seeds' spread */
    if (cycles_pass(j, o, job, r) != 0)
        return;
    char err[512];
    cycles_noise pilot, reached;
    if (cycles_exr_noise(j->exr, &pilot, err, sizeof err) != RC_OK) {
        renderer_fail(r, RUNNER_FAILED, "image.samples auto: %s", err);
        return;
    }
    reached = pilot;
    int passes = 1;
    /* Steps of at most CYCLES_STEP x, each predicted from the last render's noise (a nearer
     * count predicts better: PMJ's noise falls faster than the rate assumed). */
    for (int n = cycles_samples_need(&pilot, n_pilot, positions, need); n > o->samples;
         n = cycles_samples_need(&reached, o->samples, positions, need)) {
        o->samples = cycles_samples_step(o->samples, n);
        passes++;
        if (cycles_pass(j, o, job, r) != 0)
            return;
        if (cycles_exr_noise(j->exr, &reached, err, sizeof err) != RC_OK) {
            renderer_fail(r, RUNNER_FAILED, "image.samples auto: %s", err);
            return;
        }
    }
    cycles_samples_line(j, o, passes, n_pilot, &pilot, &reached, need);
}

void cycles_render_job(const renderer_job *j, renderer_result *r)
{
    char job[1100], err[1024], texdir[PATH_MAX];
    snprintf(job, sizeof job, "%s/job.json", j->dir);
    cycles_options o = {.n_seeds = j->seeds > 0 ? j->seeds : 2, .seed = (unsigned)j->seed, .threads = j->threads};
    if (j->options != NULL)
        o = *(const cycles_options *)j->options;
    o.role = j->role;
    o.partial = j->partial;
    /* A twin computes the model, whose pixel is the mean of k x k point samples: Cycles samples
     * the same positions (cycles.h). A validate keeps the pixel integral, the physical pixel the
     * approximation's sampling is part of. */
    if (o.role == ROLE_TWIN && o.supersample == 0)
        o.supersample = j->s->supersample;
    /* A cube map reaches Blender as a conversion 16 texels wide per cube texel (harness/frame.c):
     * its detail is the cube's, 4 N around the horizon, and a map that wide costs a 4096-wide
     * one's 1/256th (docs/samples.md, "Where a Cycles job's CPU goes"). */
    if (o.env_detail == 0 && j->env != NULL && j->env->kind == ENV_CUBE)
        o.env_detail = 4 * j->env->width;
    o.left_out = r;
    if (j->tex != NULL) {
        if (renderer_write_textures(j, err, sizeof err) != RC_OK) {
            renderer_fail(r, RUNNER_ERROR, "%s", err);
            return;
        }
        /* Absolute, as every path Blender gets (renderer.h, "Paths"): a worker runs elsewhere. */
        if (realpath(j->dir, texdir) == NULL) {
            renderer_fail(r, RUNNER_ERROR, "%s: cannot resolve the work folder: %s", j->dir, strerror(errno));
            return;
        }
        o.texture_dir = texdir;
    }
    r->wall_s = r->cpu_s = 0.0;
    /* image.samples auto (0) and no --samples: the samples follow from the gates' noise. */
    cycles_noise_need need;
    cycles_noise_need_of(j->s, registry_find("cycles"), o.role, !j->s->small.active, &need);
    if (o.samples == 0 && j->s->samples == 0) {
        cycles_auto_samples(j, &o, job, r, &need);
        return;
    }
    cycles_noise reached;
    char err2[512];
    if (cycles_pass(j, &o, job, r) == 0 && cycles_exr_noise(j->exr, &reached, err2, sizeof err2) == RC_OK)
        cycles_samples_line(j, &o, 1, 0, &(cycles_noise){0}, &reached, &need);
}
