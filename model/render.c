#include "render.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "raster.h"
#include "shade.h"

const char *const render_channel_names[RENDER_CHANNELS] = {
    "R", "G", "B", "A",
    "diffuse.R", "diffuse.G", "diffuse.B",
    "specular.R", "specular.G", "specular.B",
    "reflection.R", "reflection.G", "reflection.B",
    "emission.R", "emission.G", "emission.B",
    "coverage", "object", "ndotv", "ndotl",
    "var.R", "var.G", "var.B",
};

void render_camera_make(const scene *s, int width, int height, render_camera *c)
{
    c->eye = s->camera.eye;
    c->forward = v3_norm(v3_sub(s->camera.target, s->camera.eye));
    c->right = v3_norm(v3_cross(c->forward, s->camera.up));
    c->up = v3_cross(c->right, c->forward);
    c->tan_half_x = tanf(0.5f * s->camera.hfov);
    c->tan_half_y = c->tan_half_x * (float)height / (float)width;
    c->width = width;
    c->height = height;
}

vec3 render_camera_ray(const render_camera *c, float sx, float sy)
{
    float nx = 2.0f * sx / (float)c->width - 1.0f;
    float ny = 1.0f - 2.0f * sy / (float)c->height;
    vec3 d = v3_madd(c->forward, c->right, nx * c->tan_half_x);
    return v3_norm(v3_madd(d, c->up, ny * c->tan_half_y));
}

static raster_vertex render_project(const render_camera *c, vec3 p)
{
    vec3 d = v3_sub(p, c->eye);
    raster_vertex r = {v3_dot(d, c->right) / c->tan_half_x, v3_dot(d, c->up) / c->tan_half_y,
                       v3_dot(d, c->forward)};
    return r;
}

typedef struct {
    const scene *s;
    const mesh *m;
    const render_camera *cam;
    shade_context sc;
    const shade_plan *plans;       /* one per object */
    const shade_terms *vertex_terms; /* Gouraud: per vertex, NULL where per-pixel */
    const unsigned char *per_vertex; /* per object */
    render_image *out;
    long long *shaded;             /* per worker */
} render_job;

static vec3 render_terms_sum(const shade_terms *t)
{
    return v3_add(v3_add(t->diffuse, t->specular), v3_add(t->reflection, t->emission));
}

/* Shades one sample; for the centre sample (angles != NULL) angles[0], angles[1] get N.V and
 * N.L (first light) for the angle channels. */
static void render_shade_hit(const render_job *j, const raster_sample *rs, shade_terms *t, float *angles)
{
    const mesh *m = j->m;
    const uint32_t *tri = m->idx + 3 * (size_t)rs->tri;
    int obj = m->tri_object[rs->tri];
    float b0 = 1.0f - rs->b1 - rs->b2;

    if (j->per_vertex[obj]) {
        const shade_terms *a = &j->vertex_terms[tri[0]], *b = &j->vertex_terms[tri[1]], *c = &j->vertex_terms[tri[2]];
#define RENDER_BLEND(f) v3_add(v3_add(v3_scale(a->f, b0), v3_scale(b->f, rs->b1)), v3_scale(c->f, rs->b2))
        t->diffuse = RENDER_BLEND(diffuse);
        t->specular = RENDER_BLEND(specular);
        t->reflection = RENDER_BLEND(reflection);
        t->emission = RENDER_BLEND(emission);
#undef RENDER_BLEND
        t->alpha = a->alpha * b0 + b->alpha * rs->b1 + c->alpha * rs->b2;
        /* Gouraud shading has no per-sample normal; the angle channels stay 0 there. */
        if (angles != NULL)
            angles[0] = angles[1] = 0.0f;
        return;
    }

    vec3 p0 = m->pos[tri[0]], p1 = m->pos[tri[1]], p2 = m->pos[tri[2]];
    vec3 x = v3_add(v3_add(v3_scale(p0, b0), v3_scale(p1, rs->b1)), v3_scale(p2, rs->b2));
    vec3 n = v3_add(v3_add(v3_scale(m->nrm[tri[0]], b0), v3_scale(m->nrm[tri[1]], rs->b1)),
                    v3_scale(m->nrm[tri[2]], rs->b2));
    /* Opposite vertex normals can cancel; the face normal is the only direction left. */
    if (v3_dot(n, n) < 1e-12f)
        n = v3_cross(v3_sub(p1, p0), v3_sub(p2, p0));
    n = v3_norm(n);
    vec3 v = v3_norm(v3_sub(j->cam->eye, x));
    /* Two-sided, as POV-Ray and Cycles shade: the normal faces the viewer. */
    if (v3_dot(n, v) < 0.0f)
        n = v3_neg(n);
    if (angles != NULL) {
        angles[0] = v3_dot(n, v);
        angles[1] = 0.0f;
        if (j->s->n_lights > 0) {
            vec3 to_l, e_perp;
            float atten;
            shade_light_incident(&j->s->lights[0], x, &to_l, &e_perp, &atten);
            angles[1] = v3_dot(n, to_l);
        }
    }
    shade_eval(&j->sc, &j->plans[obj], x, n, v, t);
}

static void render_tile(void *user, const raster_tile *tile)
{
    const render_job *j = user;
    render_image *o = j->out;
    const int k = tile->k, stride = tile->w * k;
    const float inv = 1.0f / (float)(k * k);
    long long shaded = 0;

    for (int py = tile->y0; py < tile->y0 + tile->h; py++) {
        for (int px = tile->x0; px < tile->x0 + tile->w; px++) {
            shade_terms sum = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}, {0, 0, 0}, 0.0f};
            vec3 background = v3s(0.0f);
            /* Per-sample beauty, for the variance layers: sum and sum of squares. */
            vec3 b_sum = v3s(0.0f), b_sq = v3s(0.0f);
            int covered = 0, object_id = -1;
            float centre_nv = 0.0f, centre_nl = 0.0f;
            for (int t = 0; t < k; t++) {
                const raster_sample *row = tile->samples + (size_t)((py - tile->y0) * k + t) * (size_t)stride;
                for (int s = 0; s < k; s++) {
                    const raster_sample *rs = &row[(px - tile->x0) * k + s];
                    int centre = (s == k / 2 && t == k / 2);
                    if (rs->tri < 0) {
                        vec3 dir = render_camera_ray(j->cam, (float)px + ((float)s + 0.5f) / (float)k,
                                                     (float)py + ((float)t + 0.5f) / (float)k);
                        vec3 bg = env_lookup(j->sc.env, dir);
                        background = v3_add(background, bg);
                        b_sum = v3_add(b_sum, bg);
                        b_sq = v3_add(b_sq, v3_mul(bg, bg));
                        continue;
                    }
                    shade_terms st;
                    float angles[2];
                    render_shade_hit(j, rs, &st, centre ? angles : NULL);
                    sum.diffuse = v3_add(sum.diffuse, st.diffuse);
                    sum.specular = v3_add(sum.specular, st.specular);
                    sum.reflection = v3_add(sum.reflection, st.reflection);
                    sum.emission = v3_add(sum.emission, st.emission);
                    sum.alpha += st.alpha;
                    vec3 b = render_terms_sum(&st);
                    b_sum = v3_add(b_sum, b);
                    b_sq = v3_add(b_sq, v3_mul(b, b));
                    covered++;
                    if (centre) {
                        object_id = j->m->tri_object[rs->tri];
                        centre_nv = angles[0];
                        centre_nl = angles[1];
                    }
                }
            }
            shaded += covered;
            size_t i = (size_t)py * (size_t)o->width + (size_t)px;
            vec3 beauty = v3_scale(v3_add(render_terms_sum(&sum), background), inv);
            o->chan[RENDER_R][i] = beauty.x;
            o->chan[RENDER_G][i] = beauty.y;
            o->chan[RENDER_B][i] = beauty.z;
            o->chan[RENDER_A][i] = sum.alpha * inv;
            o->chan[RENDER_COVERAGE][i] = (float)covered * inv;
            o->chan[RENDER_OBJECT][i] = (float)object_id;
            o->chan[RENDER_NDOTV][i] = centre_nv;
            o->chan[RENDER_NDOTL][i] = centre_nl;
            /* Unbiased sample variance over n = k*k samples, divided by n; 0 for k = 1.
             * Cancellation can leave a tiny negative: clamp, since a variance is >= 0. */
            float n = (float)(k * k);
            vec3 var = k > 1 ? v3_scale(v3_sub(b_sq, v3_scale(v3_mul(b_sum, b_sum), 1.0f / n)), 1.0f / (n * (n - 1.0f)))
                             : v3s(0.0f);
            o->chan[RENDER_VAR_R][i] = fmaxf(var.x, 0.0f);
            o->chan[RENDER_VAR_G][i] = fmaxf(var.y, 0.0f);
            o->chan[RENDER_VAR_B][i] = fmaxf(var.z, 0.0f);
            const vec3 *aov[4] = {&sum.diffuse, &sum.specular, &sum.reflection, &sum.emission};
            for (int a = 0; a < 4; a++) {
                float **c = &o->chan[RENDER_DIFFUSE_R + 3 * a];
                if (c[0] == NULL)
                    continue;
                c[0][i] = aov[a]->x * inv;
                c[1][i] = aov[a]->y * inv;
                c[2][i] = aov[a]->z * inv;
            }
        }
    }
    j->shaded[tile->thread] += shaded;
}

static double render_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

void render_image_free(render_image *img)
{
    for (int c = 0; c < RENDER_CHANNELS; c++) {
        free(img->chan[c]);
        img->chan[c] = NULL;
    }
}

static rc_status render_alloc(render_image *out, unsigned aovs, char *err, size_t errlen)
{
    size_t n = (size_t)out->width * (size_t)out->height;
    for (int c = 0; c < RENDER_CHANNELS; c++) {
        int a = c - RENDER_DIFFUSE_R;
        if (a >= 0 && c < RENDER_COVERAGE && !(aovs & (1u << (a / 3))))
            continue;
        out->chan[c] = calloc(n, sizeof(float));
        if (out->chan[c] == NULL) {
            render_image_free(out);
            snprintf(err, errlen, "render: out of memory for a %dx%d image; render smaller", out->width, out->height);
            return RC_ERR_NOMEM;
        }
    }
    return RC_OK;
}

rc_status render_scene(const scene *s, const mesh *m, const env_map *env, const render_options *opt,
                       render_image *out, char *err, size_t errlen)
{
    static const render_options defaults = {0};
    if (opt == NULL)
        opt = &defaults;
    double t0 = render_now();
    memset(out, 0, sizeof *out);
    out->width = opt->width > 0 ? opt->width : s->width;
    out->height = opt->height > 0 ? opt->height : s->height;
    out->supersample = opt->supersample > 0 ? opt->supersample : s->supersample;
    if (out->width <= 0 || out->height <= 0 || out->supersample <= 0 || out->supersample > 16) {
        snprintf(err, errlen, "%s: image %dx%d with supersample %d; width and height must be > 0, supersample 1..16",
                 s->path, out->width, out->height, out->supersample);
        return RC_ERR_RANGE;
    }
    unsigned aovs = opt->aovs == 0 ? RENDER_AOV_ALL : (opt->aovs & RENDER_AOV_ALL);
    rc_status st = render_alloc(out, aovs, err, errlen);
    if (st != RC_OK)
        return st;

    render_camera cam;
    render_camera_make(s, out->width, out->height, &cam);
    render_job j = {.s = s, .m = m, .cam = &cam, .out = out};
    shade_context_make(s, env, &j.sc);

    shade_plan plans[SCENE_MAX_OBJECTS];
    unsigned char per_vertex[SCENE_MAX_OBJECTS] = {0};
    int any_per_vertex = 0;
    for (int i = 0; i < s->n_objects; i++) {
        const material *mat = &s->materials[s->objects[i].material];
        shade_plan_make(&j.sc, mat, &plans[i]);
        per_vertex[i] = (unsigned char)(mat->d3d.per_vertex != 0);
        any_per_vertex |= per_vertex[i];
    }
    j.plans = plans;
    j.per_vertex = per_vertex;

    raster_vertex *rv = malloc((size_t)(m->n_verts > 0 ? m->n_verts : 1) * sizeof *rv);
    shade_terms *vt = any_per_vertex ? malloc((size_t)m->n_verts * sizeof *vt) : NULL;
    raster_options ro = {.width = out->width, .height = out->height, .supersample = out->supersample,
                         .threads = opt->threads, .tile = opt->tile};
    long long *shaded = calloc((size_t)raster_thread_count(&ro), sizeof *shaded);
    if (rv == NULL || (any_per_vertex && vt == NULL) || shaded == NULL) {
        free(rv);
        free(vt);
        free(shaded);
        render_image_free(out);
        snprintf(err, errlen, "render: out of memory for %d vertices", m->n_verts);
        return RC_ERR_NOMEM;
    }
    for (int i = 0; i < m->n_verts; i++)
        rv[i] = render_project(&cam, m->pos[i]);

    if (any_per_vertex) {
        /* Gouraud: D3D evaluates the lighting once per vertex (seed 003); a vertex shared by
         * objects does not exist, as mesh_build never merges objects. */
        for (int t = 0; t < m->n_tris; t++) {
            int obj = m->tri_object[t];
            if (!per_vertex[obj])
                continue;
            for (int c = 0; c < 3; c++) {
                uint32_t vi = m->idx[3 * (size_t)t + (size_t)c];
                vec3 x = m->pos[vi];
                vec3 v = v3_norm(v3_sub(cam.eye, x));
                vec3 n = m->nrm[vi];
                if (v3_dot(n, v) < 0.0f)
                    n = v3_neg(n);
                shade_eval(&j.sc, &plans[obj], x, n, v, &vt[vi]);
            }
        }
    }
    j.vertex_terms = vt;
    j.shaded = shaded;

    st = raster_draw(rv, m->n_verts, m->idx, m->n_tris, &ro, render_tile, &j);
    for (int i = 0; i < raster_thread_count(&ro); i++)
        out->shaded_samples += shaded[i];
    free(rv);
    free(vt);
    free(shaded);
    if (st != RC_OK) {
        render_image_free(out);
        snprintf(err, errlen, "%s: the rasterizer refused the frame (status %d)", s->path, (int)st);
        return st;
    }
    out->seconds = render_now() - t0;
    return RC_OK;
}
