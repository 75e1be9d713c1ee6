#include "crease.h"

#include <math.h>
#include <stdint.h>
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
    const raster_vertex *rv;     /* the rasterizer's own inputs, for the ties */
    const unsigned char *open;   /* per triangle: bit i when the edge opposite vertex i is open */
    double half_w, half_h, band; /* W k / 2, H k / 2 in samples; the tie band */
} crease_job;

double crease_tie_band(const scene *s, int width, int k)
{
    return 8.0 * ldexp(1.0, -24) * 0.5 * (double)width * (double)k / tan(0.5 * (double)s->camera.hfov);
}

/* Vertex v on screen, in samples (raster.h's mapping, in double from the same float inputs). */
static void crease_screen(const crease_job *j, uint32_t v, double *x, double *y)
{
    const raster_vertex *r = &j->rv[v];
    *x = ((double)r->x / r->w + 1.0) * j->half_w;
    *y = (1.0 - (double)r->y / r->w) * j->half_h;
}

typedef struct {
    uint32_t a, b; /* vertex indices, a < b */
    int32_t tri;
    int edge; /* opposite vertex */
} crease_edge;

static int crease_edge_cmp(const void *pa, const void *pb)
{
    const crease_edge *x = pa, *y = pb;
    if (x->a != y->a)
        return x->a < y->a ? -1 : 1;
    if (x->b != y->b)
        return x->b < y->b ? -1 : 1;
    return (x->tri > y->tri) - (x->tri < y->tri);
}

/* The side of the screen line a-b that vertex c is on: the sign of the cross product. */
static int crease_side(const crease_job *j, uint32_t a, uint32_t b, uint32_t c)
{
    double ax, ay, bx, by, cx, cy;
    crease_screen(j, a, &ax, &ay);
    crease_screen(j, b, &bx, &by);
    crease_screen(j, c, &cx, &cy);
    double d = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
    return (d > 0) - (d < 0);
}

/* open[t] bit i: the edge of triangle t opposite vertex i is open (crease.h, CREASE_TIE): no
 * other triangle shares it by index from the other side on screen. A triangle with a vertex
 * behind the eye (w <= 0) is clipped and never tested for ties. */
static int crease_open_edges(const crease_job *j, unsigned char *open)
{
    const mesh *m = j->m;
    crease_edge *e = malloc((size_t)(m->n_tris > 0 ? m->n_tris : 1) * 3 * sizeof *e);
    if (e == NULL)
        return 0;
    for (int t = 0; t < m->n_tris; t++) {
        open[t] = 0;
        for (int i = 0; i < 3; i++) {
            uint32_t a = m->idx[3 * (size_t)t + (i + 1) % 3], b = m->idx[3 * (size_t)t + (i + 2) % 3];
            e[3 * (size_t)t + i] = (crease_edge){a < b ? a : b, a < b ? b : a, t, i};
        }
    }
    size_t n = 3 * (size_t)m->n_tris;
    qsort(e, n, sizeof *e, crease_edge_cmp);
    for (size_t g = 0; g < n;) {
        size_t h = g + 1;
        while (h < n && e[h].a == e[g].a && e[h].b == e[g].b)
            h++;
        int closed = 0;
        if (h - g == 2) {
            uint32_t c0 = m->idx[3 * (size_t)e[g].tri + e[g].edge],
                     c1 = m->idx[3 * (size_t)e[g + 1].tri + e[g + 1].edge];
            closed = crease_side(j, e[g].a, e[g].b, c0) * crease_side(j, e[g].a, e[g].b, c1) < 0;
        }
        for (size_t q = g; q < h && !closed; q++)
            open[e[q].tri] |= (unsigned char)(1u << e[q].edge);
        g = h;
    }
    free(e);
    return 1;
}

/* CREASE_TIE when the sample at (x, y) (samples) lies within the band of an open edge of t. */
static unsigned crease_tie(const crease_job *j, int32_t t, double x, double y)
{
    if (j->open[t] == 0)
        return 0;
    const uint32_t *v = j->m->idx + 3 * (size_t)t;
    double px[3], py[3];
    for (int i = 0; i < 3; i++) {
        if (!(j->rv[v[i]].w > 0.0f))
            return 0;
        crease_screen(j, v[i], &px[i], &py[i]);
    }
    for (int i = 0; i < 3; i++) {
        if (!(j->open[t] & (1u << i)))
            continue;
        double ax = px[(i + 1) % 3], ay = py[(i + 1) % 3], dx = px[(i + 2) % 3] - ax, dy = py[(i + 2) % 3] - ay;
        double len = hypot(dx, dy);
        if (len > 0.0 && fabs(dx * (y - ay) - dy * (x - ax)) < j->band * len)
            return CREASE_TIE;
    }
    return 0;
}

/* CREASE_TIE when tile sample (lx, ly) lies within the band of an open edge of a triangle that
 * covers it or one of its 8 neighbours (clipped at the tile's border): the edge a sample misses
 * by rounding belongs to a triangle its neighbour sees. */
static unsigned crease_tie_near(const crease_job *j, const raster_tile *t, int lx, int ly)
{
    int row = t->w * t->k, rows = t->h * t->k;
    int32_t seen[9];
    int n = 0;
    double x = (double)(t->x0 * t->k + lx) + 0.5, y = (double)(t->y0 * t->k + ly) + 0.5;
    for (int dy = -1; dy <= 1; dy++)
        for (int dx = -1; dx <= 1; dx++) {
            int qx = lx + dx, qy = ly + dy;
            if (qx < 0 || qy < 0 || qx >= row || qy >= rows)
                continue;
            int32_t tri = t->samples[(size_t)qy * (size_t)row + (size_t)qx].tri;
            int dup = tri < 0;
            for (int i = 0; i < n && !dup; i++)
                dup = seen[i] == tri;
            if (dup)
                continue;
            seen[n++] = tri;
            if (crease_tie(j, tri, x, y))
                return CREASE_TIE;
        }
    return 0;
}

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
                    rules |= crease_tie_near(j, t, px * k + sx, py * k + sy);
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
    unsigned char *open = malloc((size_t)(m->n_tris > 0 ? m->n_tris : 1));
    crease_job j = {.m = m,
                    .eye = cam.eye,
                    .width = width,
                    .share = share,
                    .rv = rv,
                    .open = open,
                    .half_w = 0.5 * width * k,
                    .half_h = 0.5 * height * k,
                    .band = crease_tie_band(s, width, k)};
    if (open == NULL || !crease_open_edges(&j, open)) {
        free(open);
        free(rv);
        status_message(err, errlen, "%s: crease_share: out of memory for %d triangles' edges", s->path, m->n_tris);
        return RC_ERR_NOMEM;
    }
    raster_options ro = {.width = width, .height = height, .supersample = k, .threads = threads};
    rc_status st = raster_draw(rv, m->n_verts, m->idx, m->n_tris, &ro, crease_tile, &j);
    free(open);
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
        unsigned bits = f >= 1.0f && f <= (float)CREASE_LAYER_MAX ? (unsigned)f & rules & CREASE_RULES_ALL : 0u;
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

long crease_classify_ties(unsigned char *cls, const float *layer, size_t np, long *interior)
{
    long moved = 0, inside = 0;
    for (size_t i = 0; i < np; i++) {
        if (cls[i] != METRICS_PX_INTERIOR)
            continue;
        inside++;
        float f = layer[i];
        if (f >= 1.0f && f <= (float)CREASE_LAYER_MAX && ((unsigned)f & CREASE_TIE)) {
            cls[i] = METRICS_PX_EDGE;
            moved++;
        }
    }
    if (interior != NULL)
        *interior = inside;
    return moved;
}

long crease_classify(unsigned char *cls, const float *layer, size_t np, long *interior)
{
    return crease_classify_rules(cls, layer, np, CREASE_RULES_ALL, interior, NULL);
}
