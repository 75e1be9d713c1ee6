#include "crease.h"

#include <stdlib.h>

#include "metrics.h"
#include "raster.h"
#include "render.h"

const char *const crease_rule_names[CREASE_RULE_COUNT] = {"back_face", "valid_reflection"};

unsigned crease_departs(vec3 n, vec3 ng, vec3 v)
{
    /* Cycles' frame: Ng toward the viewer, N flipped with it (the back-face rule keeps N's side). */
    if (v3_dot(ng, v) < 0.0f) {
        ng = v3_neg(ng);
        n = v3_neg(n);
    }
    unsigned rules = 0;
    float nv = v3_dot(n, v), gv = v3_dot(ng, v);
    if (nv < 0.0f)
        rules |= CREASE_RULE_BACK_FACE;
    vec3 r = v3_sub(v3_scale(n, 2.0f * nv), v);
    float lift = 0.9f * gv < 0.01f ? 0.9f * gv : 0.01f; /* Cycles: at least as shallow as the view */
    if (v3_dot(r, ng) < lift)
        rules |= CREASE_RULE_VALID_REFLECTION;
    return rules;
}

typedef struct {
    const mesh *m;
    vec3 eye;
    int width;
    float *share;
} crease_job;

static void crease_tile(void *user, const raster_tile *t)
{
    const crease_job *j = user;
    const mesh *m = j->m;
    int k = t->k, row = t->w * k;
    for (int py = 0; py < t->h; py++)
        for (int px = 0; px < t->w; px++) {
            unsigned rules = 0;
            for (int sy = 0; sy < k; sy++)
                for (int sx = 0; sx < k; sx++) {
                    const raster_sample *rs = &t->samples[(size_t)(py * k + sy) * (size_t)row + (size_t)(px * k + sx)];
                    if (rs->tri < 0)
                        continue;
                    const uint32_t *tri = m->idx + 3 * (size_t)rs->tri;
                    float b0 = 1.0f - rs->b1 - rs->b2;
                    vec3 p0 = m->pos[tri[0]], p1 = m->pos[tri[1]], p2 = m->pos[tri[2]];
                    vec3 x = v3_add(v3_add(v3_scale(p0, b0), v3_scale(p1, rs->b1)), v3_scale(p2, rs->b2));
                    vec3 n = v3_add(v3_add(v3_scale(m->nrm[tri[0]], b0), v3_scale(m->nrm[tri[1]], rs->b1)),
                                    v3_scale(m->nrm[tri[2]], rs->b2));
                    vec3 ng = v3_cross(v3_sub(p1, p0), v3_sub(p2, p0));
                    /* A zero-area triangle has no Ng to disagree with (the mesh reader drops
                     * them); where opposite normals cancel, render.c shades with the face normal. */
                    if (v3_dot(ng, ng) == 0.0f)
                        continue;
                    ng = v3_norm(ng);
                    n = v3_dot(n, n) < 1e-12f ? ng : v3_norm(n);
                    rules |= crease_departs(n, ng, v3_norm(v3_sub(j->eye, x)));
                }
            /* Small integers are exact in a float (and in the EXR's float layer). */
            j->share[(size_t)(t->y0 + py) * (size_t)j->width + (size_t)(t->x0 + px)] = (float)rules;
        }
}

rc_status crease_share(const scene *s, const mesh *m, int width, int height, int k, int threads, float *share,
                       char *err, size_t errlen)
{
    if (width <= 0 || height <= 0 || k <= 0 || share == NULL) {
        status_message(err, errlen, "%s: crease_share: size %dx%d, k %d: give a positive size and k and an output",
                       s->path, width, height, k);
        return RC_ERR_RANGE;
    }
    render_camera cam;
    render_camera_make(s, width, height, &cam);
    raster_vertex *rv = malloc((size_t)(m->n_verts > 0 ? m->n_verts : 1) * sizeof *rv);
    if (rv == NULL) {
        status_message(err, errlen, "%s: crease_share: out of memory for %d vertices", s->path, m->n_verts);
        return RC_ERR_NOMEM;
    }
    for (int i = 0; i < m->n_verts; i++)
        rv[i] = render_camera_clip(&cam, m->pos[i]);
    crease_job j = {.m = m, .eye = cam.eye, .width = width, .share = share};
    raster_options ro = {.width = width, .height = height, .supersample = k, .threads = threads};
    rc_status st = raster_draw(rv, m->n_verts, m->idx, m->n_tris, &ro, crease_tile, &j);
    free(rv);
    if (st != RC_OK)
        status_message(err, errlen, "%s: crease_share: the rasterizer refused %dx%d, k %d (status %d)", s->path, width,
                       height, k, (int)st);
    return st;
}

long crease_classify_rules(unsigned char *cls, const float *layer, size_t np, unsigned rules, long *interior,
                           long *per_rule)
{
    long moved = 0, inside = 0;
    for (int b = 0; per_rule != NULL && b < CREASE_RULE_COUNT; b++)
        per_rule[b] = 0;
    for (size_t i = 0; i < np; i++) {
        if (cls[i] != METRICS_PX_INTERIOR)
            continue;
        inside++;
        /* A layer value outside the rule bits (NaN, negative, a fraction from an older layer)
         * departs by no rule. */
        float f = layer[i];
        unsigned bits = f >= 1.0f && f <= (float)CREASE_RULES_ALL ? (unsigned)f & rules : 0u;
        if (bits == 0)
            continue;
        cls[i] = METRICS_PX_CREASE;
        moved++;
        for (int b = 0; per_rule != NULL && b < CREASE_RULE_COUNT; b++)
            per_rule[b] += (bits >> b) & 1u;
    }
    if (interior != NULL)
        *interior = inside;
    return moved;
}

long crease_classify(unsigned char *cls, const float *layer, size_t np, long *interior)
{
    return crease_classify_rules(cls, layer, np, CREASE_RULES_ALL, interior, NULL);
}
