/* mesh_soup.c - the polygon soup every mesh file becomes (mesh_internal.h): the appends the
 * readers fill it with, and its emission into the mesh: fan triangulation, the repairs renderers
 * make (a zero-area triangle left out, a zero or non-finite file normal recomputed from the faces,
 * both counted per object), vertices shared per (position, normal, texture coordinate), and the
 * texture-coordinate check. libassimp's import is turned into a soup here too, so every format
 * goes through the same emission.
 */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "mesh.h"
#include "mesh_assimp.h"
#include "mesh_internal.h"
#include "status.h"

void mesh_soup_free(mesh_soup *s)
{
    free(s->pos);
    free(s->nrm);
    free(s->tex);
    free(s->ct);
    free(s->cv);
    free(s->cn);
    free(s->face_start);
    free(s->face_line);
    free(s->col);
}

/* Grows *p (elem bytes each, capacity *cap) to hold need elements. */
static int mesh_grow(void **p, int *cap, int need, size_t elem)
{
    if (need <= *cap)
        return 1;
    if (need > INT_MAX / 2)
        return 0;
    int c = *cap ? *cap : 64;
    while (c < need)
        c *= 2;
    void *q = realloc(*p, (size_t)c * elem);
    if (!q)
        return 0;
    *p = q;
    *cap = c;
    return 1;
}

/* Sets position s->n_pos - 1's colours (bits 1: c[0..2] is colour1, 2: c[3..5] colour2). */
int mesh_soup_colour(mesh_soup *s, const double c[6], int bits)
{
    int had = s->cap_col;
    if (!mesh_grow((void **)&s->col, &s->cap_col, s->n_pos, 6 * sizeof(double)))
        return 0;
    if (s->cap_col > had)
        memset(&s->col[6 * (size_t)had], 0, (size_t)(s->cap_col - had) * 6 * sizeof(double));
    memcpy(&s->col[6 * (size_t)(s->n_pos - 1)], c, 6 * sizeof(double));
    s->col_bits |= bits;
    s->col_given++;
    return 1;
}

int mesh_soup_pos(mesh_soup *s, const double v[3])
{
    if (!mesh_grow((void **)&s->pos, &s->cap_pos, s->n_pos + 1, 3 * sizeof(double)))
        return 0;
    memcpy(&s->pos[3 * (size_t)s->n_pos++], v, 3 * sizeof(double));
    return 1;
}

int mesh_soup_nrm(mesh_soup *s, const double v[3])
{
    if (!mesh_grow((void **)&s->nrm, &s->cap_nrm, s->n_nrm + 1, 3 * sizeof(double)))
        return 0;
    memcpy(&s->nrm[3 * (size_t)s->n_nrm++], v, 3 * sizeof(double));
    return 1;
}

int mesh_soup_tex(mesh_soup *s, const double v[2])
{
    if (!mesh_grow((void **)&s->tex, &s->cap_tex, s->n_tex + 1, 2 * sizeof(double)))
        return 0;
    memcpy(&s->tex[2 * (size_t)s->n_tex++], v, 2 * sizeof(double));
    return 1;
}

int mesh_soup_corner(mesh_soup *s, int v, int n)
{
    int cap = s->cap_corner;
    if (!mesh_grow((void **)&s->cv, &cap, s->n_corner + 1, sizeof(int)))
        return 0;
    cap = s->cap_corner;
    if (!mesh_grow((void **)&s->cn, &cap, s->n_corner + 1, sizeof(int)))
        return 0;
    cap = s->cap_corner;
    if (!mesh_grow((void **)&s->ct, &cap, s->n_corner + 1, sizeof(int)))
        return 0;
    s->ct[s->n_corner] = -1;
    s->cap_corner = cap;
    s->cv[s->n_corner] = v;
    s->cn[s->n_corner++] = n;
    return 1;
}

/* Closes the face whose corners were added since the last call. */
int mesh_soup_face(mesh_soup *s, int line)
{
    int cap = s->cap_face;
    if (!mesh_grow((void **)&s->face_start, &cap, s->n_face + 2, sizeof(int)))
        return 0;
    cap = s->cap_face;
    if (!mesh_grow((void **)&s->face_line, &cap, s->n_face + 2, sizeof(int)))
        return 0;
    s->cap_face = cap;
    if (s->n_face == 0)
        s->face_start[0] = 0;
    s->face_line[s->n_face] = line;
    s->face_start[++s->n_face] = s->n_corner;
    return 1;
}

/* A zero or non-finite file normal becomes (0, 0, 0): the mark mesh_soup_emit replaces by the
 * normal computed from the faces (mesh_soup_normal_bad). */
void mesh_normal_screen(double v[3])
{
    double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (!isfinite(l) || l == 0.0)
        v[0] = v[1] = v[2] = 0.0;
}

/* A file normal that is zero or not finite (stored as zero by the readers): its vertex gets the
 * normal computed from its faces instead, as renderers do. */
static int mesh_soup_normal_bad(const mesh_soup *s, int ni)
{
    const double *nn = &s->nrm[3 * (size_t)ni];
    return nn[0] == 0.0 && nn[1] == 0.0 && nn[2] == 0.0;
}

/* Fan triangle k of face f: its three corners. */
static void mesh_soup_fan(const mesh_soup *s, int f, int k, int c[3])
{
    c[0] = s->face_start[f];
    c[1] = k;
    c[2] = k + 1;
}

static dvec3 mesh_soup_cross(const mesh_soup *s, const int c[3])
{
    dvec3 pv[3];
    for (int q = 0; q < 3; q++) {
        const double *pp = &s->pos[3 * (size_t)s->cv[c[q]]];
        pv[q] = dv3(pp[0], pp[1], pp[2]);
    }
    return dv3_cross(dv3_sub(pv[1], pv[0]), dv3_sub(pv[2], pv[0]));
}

/* Output vertices shared per (position, file normal or computed, texture coordinate): an
 * open-addressing table. */
typedef struct {
    size_t cap;
    int64_t *key; /* position and normal */
    int *tex;     /* texture coordinate index, -1 for none */
    uint32_t *val;
} mesh_vtable;

/* The output vertex of corner i, made on first use; RC_ERR_RANGE when it needs a computed normal
 * and its faces' normals cancel. */
static rc_status mesh_soup_vertex(const mesh_soup *s, mesh_builder *b, mesh_vtable *t, const dvec3 *acc, int i,
                                  const char *label, int is_obj, uint32_t *out, char *err, size_t errlen)
{
    int vi = s->cv[i], ni = s->cn[i], ti = s->ct[i];
    int bad = ni >= 0 && mesh_soup_normal_bad(s, ni);
    if (bad)
        ni = -1;
    int64_t key = (int64_t)vi * ((int64_t)s->n_nrm + 1) + (ni + 1);
    uint64_t mix = (uint64_t)key * 0x9E3779B97F4A7C15ull ^ (uint64_t)(uint32_t)(ti + 1) * 0xC2B2AE3D27D4EB4Full;
    size_t h = (size_t)(mix >> 20) & (t->cap - 1);
    while (t->key[h] != -1 && !(t->key[h] == key && t->tex[h] == ti))
        h = (h + 1) & (t->cap - 1);
    if (t->key[h] == -1) {
        const double *pp = &s->pos[3 * (size_t)vi];
        if (s->col_bits) {
            const double *c = &s->col[6 * (size_t)vi];
            b->c1 = v3((float)c[0], (float)c[1], (float)c[2]);
            b->c2 = v3((float)c[3], (float)c[4], (float)c[5]);
        }
        dvec3 n;
        if (ni >= 0) {
            const double *nn = &s->nrm[3 * (size_t)ni];
            n = dv3_norm(dv3(nn[0], nn[1], nn[2]));
        } else {
            n = acc[vi];
            if (dv3_len(n) == 0.0) {
                status_message(err, errlen,
                               "%s: vertex %d: its triangles' normals cancel, so no "
                               "normal can be computed; fix: give normals or remove back-to-back "
                               "faces",
                               label, vi + is_obj);
                return RC_ERR_RANGE;
            }
            n = dv3_norm(n);
        }
        t->key[h] = key;
        t->tex[h] = ti;
        t->val[h] = mesh_vert(b, dv3(pp[0], pp[1], pp[2]), n);
        if (ti >= 0)
            mesh_uv(b, t->val[h], s->tex[2 * (size_t)ti], s->tex[2 * (size_t)ti + 1]);
        if (bad)
            b->m->recomputed[b->object]++;
    }
    *out = t->val[h];
    return RC_OK;
}

/* Whether the soup can give triangles: some faces (after the usemtl filter), and texture
 * coordinates when the material has a texture. *ntri: its fan triangles. */
static rc_status mesh_soup_check(const mesh_soup *s, const mesh_builder *b, const char *label, size_t *ntri, char *err,
                                 size_t errlen)
{
    *ntri = 0;
    for (int f = 0; f < s->n_face; f++)
        *ntri += (size_t)(s->face_start[f + 1] - s->face_start[f] - 2);
    if (*ntri == 0 && s->usemtl != NULL && s->usemtl[0] != '\0') {
        status_message(err, errlen, "%s: no face after `usemtl %s`; fix: a material name from the file's usemtl lines",
                       label, s->usemtl);
        return RC_ERR_RANGE;
    }
    if (*ntri == 0) {
        status_message(err, errlen,
                       "%s: no faces (points and lines are not drawn); fix: a mesh with at least one "
                       "triangle or polygon",
                       label);
        return RC_ERR_RANGE;
    }
    if (b->textured && s->n_tex == 0) {
        status_message(err, errlen,
                       "%s: has no texture coordinates (OBJ vt, PLY u v or s t) and its material has a texture; "
                       "fix: a mesh with UVs, or a material without texture",
                       label);
        return RC_ERR_RANGE;
    }
    return RC_OK;
}

/* An empty vertex table with room for every corner at half load. */
static rc_status mesh_vtable_make(mesh_vtable *t, int n_corner)
{
    *t = (mesh_vtable){16, NULL, NULL, NULL};
    while (t->cap < 2 * (size_t)n_corner)
        t->cap *= 2;
    t->key = malloc(t->cap * sizeof *t->key);
    t->tex = malloc(t->cap * sizeof *t->tex);
    t->val = malloc(t->cap * sizeof *t->val);
    if (!t->key || !t->tex || !t->val)
        return RC_ERR_NOMEM;
    for (size_t i = 0; i < t->cap; i++)
        t->key[i] = -1;
    return RC_OK;
}

/* Each position's area-weighted normal sum over the triangles of nonzero area (in double) into
 * acc; returns how many such triangles there are. */
static size_t mesh_soup_accumulate(const mesh_soup *s, dvec3 *acc)
{
    size_t kept = 0;
    for (int f = 0; f < s->n_face; f++)
        for (int k = s->face_start[f] + 1; k + 1 < s->face_start[f + 1]; k++) {
            int c[3];
            mesh_soup_fan(s, f, k, c);
            dvec3 cr = mesh_soup_cross(s, c);
            if (dv3_len(cr) == 0.0)
                continue;
            kept++;
            /* |cross| is twice the area: summing it weights normals by area. */
            for (int q = 0; q < 3; q++)
                acc[s->cv[c[q]]] = dv3_add(acc[s->cv[c[q]]], cr);
        }
    return kept;
}

/* The fan triangles into the mesh, each zero-area one (in double, or once stored as float)
 * counted in *dropped instead. */
static rc_status mesh_soup_triangles(const mesh_soup *s, mesh_builder *b, mesh_vtable *t, const dvec3 *acc,
                                     const char *label, int is_obj, size_t *dropped, char *err, size_t errlen)
{
    rc_status rc = RC_OK;
    for (int f = 0; f < s->n_face && rc == RC_OK; f++)
        for (int k = s->face_start[f] + 1; k + 1 < s->face_start[f + 1] && rc == RC_OK; k++) {
            int c[3];
            uint32_t v[3];
            mesh_soup_fan(s, f, k, c);
            if (dv3_len(mesh_soup_cross(s, c)) == 0.0) {
                (*dropped)++;
                continue;
            }
            for (int q = 0; q < 3 && rc == RC_OK; q++)
                rc = mesh_soup_vertex(s, b, t, acc, c[q], label, is_obj, &v[q], err, errlen);
            if (rc != RC_OK)
                break;
            dvec3 cr;
            /* Nonzero in the file's precision can still collapse once stored as float. */
            if (mesh_tri_area2(b->m, v[0], v[1], v[2], &cr) == 0.0) {
                (*dropped)++;
                continue;
            }
            mesh_tri(b->m, v[0], v[1], v[2], b->object);
        }
    return rc;
}

/* Triangulates the soup (fans), computes missing normals (area-weighted), appends to the mesh.
 * Vertices are shared per (position, normal, texture coordinate). Zero-area triangles (in double, or once the
 * positions are stored as float) are left out and counted, as every renderer skips them; only a
 * mesh left with none is refused. */
rc_status mesh_soup_emit(const mesh_soup *s, mesh_builder *b, const char *label, int is_obj, char *err, size_t errlen)
{
    mesh *m = b->m;
    size_t ntri, kept, dropped = 0;
    rc_status rc = mesh_soup_check(s, b, label, &ntri, err, errlen);
    if (rc != RC_OK)
        return rc;
    dvec3 *acc = calloc((size_t)s->n_pos, sizeof *acc);
    mesh_vtable t;
    rc = mesh_vtable_make(&t, s->n_corner);
    if (rc == RC_OK && !acc)
        rc = RC_ERR_NOMEM;
    if (rc != RC_OK)
        goto done;
    if ((kept = mesh_soup_accumulate(s, acc)) == 0) {
        status_message(err, errlen,
                       "%s: all %zu triangles have zero area (corners coincide or are collinear); fix: "
                       "a mesh with at least one proper face",
                       label, ntri);
        rc = RC_ERR_RANGE;
        goto done;
    }
    if (s->col_bits && (rc = mesh_colours_on(m)) != RC_OK)
        goto done;
    if ((rc = mesh_reserve(m, (size_t)s->n_corner, kept)) != RC_OK)
        goto done;
    m->colours[b->object] = (unsigned char)s->col_bits;
    rc = mesh_soup_triangles(s, b, &t, acc, label, is_obj, &dropped, err, errlen);
    m->dropped[b->object] += (int)dropped;
    if (rc == RC_OK && dropped == ntri) {
        status_message(err, errlen,
                       "%s: all %zu triangles have zero area once stored in single precision (tiny or "
                       "huge coordinates); fix: rescale the mesh",
                       label, ntri);
        rc = RC_ERR_RANGE;
    }
done:
    free(acc);
    free(t.key);
    free(t.tex);
    free(t.val);
    return rc;
}

/* An asset libassimp imported, as a soup: its arrays move into s (one face per triangle, corner =
 * vertex), so the asset goes through the same emit as OBJ and PLY (zero-area triangles, normals,
 * shared vertices, the texture check). Vertices without a file normal get the computed one. */
rc_status mesh_soup_from_assimp(mesh_assimp_soup *g, mesh_soup *s)
{
    size_t nc = 3 * (size_t)g->n_tris;
    s->pos = g->pos;
    s->nrm = g->nrm;
    s->n_pos = s->n_nrm = g->n_verts;
    int any_uv = 0;
    for (int v = 0; v < g->n_verts; v++)
        any_uv |= g->has_uv[v];
    s->tex = g->uv;
    s->n_tex = any_uv ? g->n_verts : 0;
    g->pos = g->nrm = g->uv = NULL;
    s->cv = malloc(nc * sizeof *s->cv);
    s->cn = malloc(nc * sizeof *s->cn);
    s->ct = malloc(nc * sizeof *s->ct);
    s->face_start = malloc((size_t)(g->n_tris + 1) * sizeof *s->face_start);
    s->face_line = malloc((size_t)g->n_tris * sizeof *s->face_line);
    if (!s->cv || !s->cn || !s->ct || !s->face_start || !s->face_line)
        return RC_ERR_NOMEM;
    for (size_t c = 0; c < nc; c++) {
        int v = g->idx[c];
        s->cv[c] = v;
        s->cn[c] = isnan(s->nrm[3 * (size_t)v]) ? -1 : v;
        s->ct[c] = g->has_uv[v] ? v : -1;
    }
    for (int f = 0; f <= g->n_tris; f++)
        s->face_start[f] = 3 * f;
    for (int f = 0; f < g->n_tris; f++)
        s->face_line[f] = f + 1;
    s->n_corner = (int)nc;
    s->n_face = g->n_tris;
    return RC_OK;
}
