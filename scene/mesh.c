/* mesh.c - tessellation of scene objects and the OBJ/PLY readers (scene/mesh.h).
 *
 * Shapes are built in object space in double precision, then rotated (Euler X, then Y, then Z)
 * and translated by the object's center. Debian 12 ships no C library for OBJ or PLY
 * (tinyobjloader is C++, rply is not packaged), so both readers are here: small, bounds-checked,
 * and reading the whole file into memory first (a regular file of at most FILEIO_MESH_MAX_BYTES,
 * checked before reading: core/fileio.h).
 *
 * Sphere: UV sphere, `tessellation` segments around Y, tessellation/2 rings, single pole vertices.
 * Quad: two triangles in the object's XZ plane, normal +Y, size.x by size.z.
 * Box: inner box (size/2 - radius) grown by `radius`: 6 flat faces, 12 quarter-cylinder edges of
 *   `tessellation` segments, 8 octant corners with the same segments along each boundary arc;
 *   radius 0 gives a sharp box with face normals.
 * Torus: ring of radius `major` around Y in the XZ plane, tube radius `radius`;
 *   `tessellation` segments around the ring, max(3, tessellation/2) around the tube.
 * Generated triangles get their winding from the shape's outward vertex normals.
 * On failure mesh_add_object leaves the mesh as it was; mesh_build frees it.
 */
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "d3d.h"
#include "fileio.h"
#include "formula.h"
#include "mesh.h"
#include "mesh_assimp.h"

typedef struct {
    double r[3][3];
    dvec3 t;
    dvec3 s, inv_s; /* the object's scale and its reciprocal (normals: the inverse transpose) */
} mesh_xform;

static mesh_xform mesh_make_xform(const object *o)
{
    double cx = cos(o->rotate.x), sx = sin(o->rotate.x);
    double cy = cos(o->rotate.y), sy = sin(o->rotate.y);
    double cz = cos(o->rotate.z), sz = sin(o->rotate.z);
    /* R = Rz * Ry * Rx: X is applied first. */
    mesh_xform x = {{{cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx},
                     {sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx},
                     {-sy, cy * sx, cy * cx}},
                    dv3_from(o->center),
                    dv3_from(o->scale),
                    dv3(1.0 / (double)o->scale.x, 1.0 / (double)o->scale.y, 1.0 / (double)o->scale.z)};
    return x;
}

static dvec3 mesh_rotate(const mesh_xform *x, dvec3 v)
{
    return dv3(x->r[0][0] * v.x + x->r[0][1] * v.y + x->r[0][2] * v.z,
               x->r[1][0] * v.x + x->r[1][1] * v.y + x->r[1][2] * v.z,
               x->r[2][0] * v.x + x->r[2][1] * v.y + x->r[2][2] * v.z);
}

static rc_status mesh_reserve(mesh *m, size_t add_verts, size_t add_tris)
{
    size_t nv = (size_t)m->n_verts + add_verts, nt = (size_t)m->n_tris + add_tris;
    /* Indices are uint32 and counts int: stay below both. */
    if (nv > (size_t)INT_MAX || nt > (size_t)INT_MAX / 3)
        return RC_ERR_NOMEM;
    if (nv > (size_t)m->cap_verts) {
        size_t cap = m->cap_verts ? (size_t)m->cap_verts : 256;
        while (cap < nv)
            cap = cap * 2 > (size_t)INT_MAX ? (size_t)INT_MAX : cap * 2;
        vec3 *p = realloc(m->pos, cap * sizeof *p);
        if (!p)
            return RC_ERR_NOMEM;
        m->pos = p;
        vec3 *n = realloc(m->nrm, cap * sizeof *n);
        if (!n)
            return RC_ERR_NOMEM;
        m->nrm = n;
        float *uv = realloc(m->uv, cap * 2 * sizeof *uv);
        if (!uv)
            return RC_ERR_NOMEM;
        m->uv = uv;
        if (m->col1 != NULL) {
            vec3 *c1 = realloc(m->col1, cap * sizeof *c1);
            if (!c1)
                return RC_ERR_NOMEM;
            m->col1 = c1;
            vec3 *c2 = realloc(m->col2, cap * sizeof *c2);
            if (!c2)
                return RC_ERR_NOMEM;
            m->col2 = c2;
        }
        m->cap_verts = (int)cap;
    }
    if (nt > (size_t)m->cap_tris) {
        size_t cap = m->cap_tris ? (size_t)m->cap_tris : 256;
        while (cap < nt)
            cap = cap * 2 > (size_t)INT_MAX / 3 ? (size_t)INT_MAX / 3 : cap * 2;
        uint32_t *i = realloc(m->idx, cap * 3 * sizeof *i);
        if (!i)
            return RC_ERR_NOMEM;
        m->idx = i;
        int *o = realloc(m->tri_object, cap * sizeof *o);
        if (!o)
            return RC_ERR_NOMEM;
        m->tri_object = o;
        m->cap_tris = (int)cap;
    }
    return RC_OK;
}

/* Shape builder: object-space vertices go through the transform as they are added. */
typedef struct {
    mesh *m;
    mesh_xform x;
    int object;
    int textured; /* the object's material has a texture: a mesh file must give UVs */
    vec3 c1, c2;  /* the colours of the next vertex (where the mesh holds colours) */
} mesh_builder;

/* Turns the colour arrays on: zero for the vertices so far, and grown with the others. */
static rc_status mesh_colours_on(mesh *m)
{
    if (m->col1 != NULL)
        return RC_OK;
    size_t cap = m->cap_verts > 0 ? (size_t)m->cap_verts : 1;
    m->col1 = calloc(cap, sizeof *m->col1);
    m->col2 = calloc(cap, sizeof *m->col2);
    if (!m->col1 || !m->col2) {
        free(m->col1);
        free(m->col2);
        m->col1 = m->col2 = NULL;
        return RC_ERR_NOMEM;
    }
    return RC_OK;
}

static uint32_t mesh_vert(mesh_builder *b, dvec3 p, dvec3 n)
{
    mesh *m = b->m;
    /* Scale, then rotate, then translate; a normal goes through the inverse transpose of the
     * linear part, (R S)^-T = R S^-1, and is renormalised. */
    m->pos[m->n_verts] = v3_from_d(dv3_add(mesh_rotate(&b->x, dv3_mul(p, b->x.s)), b->x.t));
    m->nrm[m->n_verts] = v3_from_d(dv3_norm(mesh_rotate(&b->x, dv3_mul(n, b->x.inv_s))));
    m->uv[2 * (size_t)m->n_verts] = m->uv[2 * (size_t)m->n_verts + 1] = 0.0f;
    if (m->col1 != NULL) {
        m->col1[m->n_verts] = b->c1;
        m->col2[m->n_verts] = b->c2;
    }
    return (uint32_t)m->n_verts++;
}

/* Sets the texture coordinates of vertex i. */
static uint32_t mesh_uv(mesh_builder *b, uint32_t i, double u, double v)
{
    b->m->uv[2 * (size_t)i] = (float)u;
    b->m->uv[2 * (size_t)i + 1] = (float)v;
    return i;
}

static double mesh_tri_area2(const mesh *m, uint32_t a, uint32_t b, uint32_t c, dvec3 *cross)
{
    dvec3 pa = dv3_from(m->pos[a]);
    *cross = dv3_cross(dv3_sub(dv3_from(m->pos[b]), pa), dv3_sub(dv3_from(m->pos[c]), pa));
    return dv3_len(*cross);
}

static void mesh_tri(mesh *m, uint32_t a, uint32_t b, uint32_t c, int obj)
{
    uint32_t *t = &m->idx[3 * (size_t)m->n_tris];
    t[0] = a;
    t[1] = b;
    t[2] = c;
    m->tri_object[m->n_tris++] = obj;
}

/* A generated triangle, wound CCW around the outward direction its vertex normals give.
 * Returns 0 for a zero-area triangle (the caller reports it). */
static int mesh_tri_out(mesh_builder *b, uint32_t v0, uint32_t v1, uint32_t v2)
{
    mesh *m = b->m;
    dvec3 cr;
    if (mesh_tri_area2(m, v0, v1, v2, &cr) == 0.0)
        return 0;
    dvec3 n = dv3_add(dv3_add(dv3_from(m->nrm[v0]), dv3_from(m->nrm[v1])), dv3_from(m->nrm[v2]));
    if (dv3_dot(cr, n) < 0.0)
        mesh_tri(m, v0, v2, v1, b->object);
    else
        mesh_tri(m, v0, v1, v2, b->object);
    return 1;
}

/* Two triangles of the quad a-b-c-d (in order around it). */
static int mesh_quad_out(mesh_builder *b, uint32_t a, uint32_t bb, uint32_t c, uint32_t d)
{
    return mesh_tri_out(b, a, bb, c) && mesh_tri_out(b, a, c, d);
}

static int mesh_sphere(mesh_builder *b, const object *o)
{
    int seg = o->tessellation, rings = seg / 2;
    double r = o->radius;
    /* u = 1 - phi/2pi (phi from +X toward +Z, so the image reads unmirrored from outside),
     * v = 1 - theta/pi; the seam column (j = seg, u = 0) and each pole triangle's own pole
     * vertex (at the mid u of its triangle) carry the texture coordinates a shared vertex
     * cannot. */
    uint32_t top = (uint32_t)b->m->n_verts;
    for (int j = 0; j < seg; j++)
        mesh_uv(b, mesh_vert(b, dv3(0, r, 0), dv3(0, 1, 0)), 1.0 - (j + 0.5) / seg, 1.0);
    uint32_t first = (uint32_t)b->m->n_verts;
    for (int i = 1; i < rings; i++) {
        double th = FORMULA_PI_D * i / rings;
        for (int j = 0; j <= seg; j++) {
            double ph = 2.0 * FORMULA_PI_D * (j % seg) / seg;
            dvec3 n = dv3(sin(th) * cos(ph), cos(th), sin(th) * sin(ph));
            mesh_uv(b, mesh_vert(b, dv3_scale(n, r), n), 1.0 - (double)j / seg, 1.0 - (double)i / rings);
        }
    }
    uint32_t bottom = (uint32_t)b->m->n_verts;
    for (int j = 0; j < seg; j++)
        mesh_uv(b, mesh_vert(b, dv3(0, -r, 0), dv3(0, -1, 0)), 1.0 - (j + 0.5) / seg, 0.0);
#define RING(i, j) (first + (uint32_t)(((i)-1) * (seg + 1) + (j)))
    for (int j = 0; j < seg; j++) {
        if (!mesh_tri_out(b, top + (uint32_t)j, RING(1, j + 1), RING(1, j)))
            return 0;
        for (int i = 1; i + 1 < rings; i++)
            if (!mesh_quad_out(b, RING(i, j), RING(i, j + 1), RING(i + 1, j + 1), RING(i + 1, j)))
                return 0;
        if (!mesh_tri_out(b, RING(rings - 1, j), RING(rings - 1, j + 1), bottom + (uint32_t)j))
            return 0;
    }
#undef RING
    return 1;
}

static int mesh_quad(mesh_builder *b, const object *o)
{
    double hx = 0.5 * o->size.x, hz = 0.5 * o->size.z;
    dvec3 up = dv3(0, 1, 0);
    /* u along +X, v along -Z: seen from above with -Z up the screen, the image reads unmirrored. */
    uint32_t a = mesh_uv(b, mesh_vert(b, dv3(-hx, 0, -hz), up), 0, 1);
    uint32_t bb = mesh_uv(b, mesh_vert(b, dv3(-hx, 0, hz), up), 0, 0);
    uint32_t c = mesh_uv(b, mesh_vert(b, dv3(hx, 0, hz), up), 1, 0);
    uint32_t d = mesh_uv(b, mesh_vert(b, dv3(hx, 0, -hz), up), 1, 1);
    return mesh_quad_out(b, a, bb, c, d);
}

static dvec3 mesh_axis(int a, double s) { return dv3(a == 0 ? s : 0.0, a == 1 ? s : 0.0, a == 2 ? s : 0.0); }

/* A box vertex with its texture coordinates: the face of the normal's largest component maps
 * the whole image, u along the face's first in-plane axis p and v along the second q of the
 * right-handed (p, q, a) (flipped in u on the face toward -a), so every face reads unmirrored
 * from outside. The rounding takes the coordinates its normal's face gives (clamped to the
 * face), so a rounded edge changes face at 45 degrees. */
static uint32_t mesh_box_vert(mesh_builder *b, const object *o, dvec3 pos, dvec3 n)
{
    double an[3] = {fabs(n.x), fabs(n.y), fabs(n.z)}, pc[3] = {pos.x, pos.y, pos.z}, nc[3] = {n.x, n.y, n.z};
    double sz[3] = {o->size.x, o->size.y, o->size.z};
    int a = an[0] >= an[1] && an[0] >= an[2] ? 0 : (an[1] >= an[2] ? 1 : 2);
    int p = (a + 1) % 3, q = (a + 2) % 3;
    double u = (nc[a] < 0.0 ? -pc[p] : pc[p]) / sz[p] + 0.5, v = pc[q] / sz[q] + 0.5;
    return mesh_uv(b, mesh_vert(b, pos, n), fmin(fmax(u, 0.0), 1.0), fmin(fmax(v, 0.0), 1.0));
}

static int mesh_box(mesh_builder *b, const object *o)
{
    double r = o->radius;
    double h[3] = {0.5 * o->size.x - r, 0.5 * o->size.y - r, 0.5 * o->size.z - r};
    int seg = o->tessellation;
    for (int a = 0; a < 3; a++)
        if (h[a] < 0.0)
            h[a] = 0.0; /* radius == half size up to rounding: that axis is all curve */

    /* Faces: normal along axis a, spanning the inner extents of axes p and q. */
    for (int a = 0; a < 3; a++) {
        int p = (a + 1) % 3, q = (a + 2) % 3;
        if (h[p] == 0.0 || h[q] == 0.0)
            continue;
        for (int s = -1; s <= 1; s += 2) {
            dvec3 n = mesh_axis(a, s), c = mesh_axis(a, s * (h[a] + r));
            uint32_t v[4];
            for (int k = 0; k < 4; k++) {
                double sp = (k == 0 || k == 3) ? -1.0 : 1.0, sq = (k < 2) ? -1.0 : 1.0;
                dvec3 pos = dv3_add(c, dv3_add(mesh_axis(p, sp * h[p]), mesh_axis(q, sq * h[q])));
                v[k] = mesh_box_vert(b, o, pos, n);
            }
            if (!mesh_quad_out(b, v[0], v[1], v[2], v[3]))
                return 0;
        }
    }
    if (r == 0.0)
        return 1;

    /* Edges: quarter cylinders along axis a, around the inner edge at signs (sp, sq). */
    for (int a = 0; a < 3; a++) {
        int p = (a + 1) % 3, q = (a + 2) % 3;
        if (h[a] == 0.0)
            continue;
        for (int sp = -1; sp <= 1; sp += 2)
            for (int sq = -1; sq <= 1; sq += 2) {
                dvec3 c = dv3_add(mesh_axis(p, sp * h[p]), mesh_axis(q, sq * h[q]));
                uint32_t start = (uint32_t)b->m->n_verts;
                for (int k = 0; k <= seg; k++) {
                    double al = 0.5 * FORMULA_PI_D * k / seg;
                    dvec3 n = dv3_add(mesh_axis(p, sp * cos(al)), mesh_axis(q, sq * sin(al)));
                    dvec3 rim = dv3_add(c, dv3_scale(n, r));
                    mesh_box_vert(b, o, dv3_add(rim, mesh_axis(a, -h[a])), n);
                    mesh_box_vert(b, o, dv3_add(rim, mesh_axis(a, h[a])), n);
                }
                for (int k = 0; k < seg; k++) {
                    uint32_t v = start + 2u * (uint32_t)k;
                    if (!mesh_quad_out(b, v, v + 1, v + 3, v + 2))
                        return 0;
                }
            }
    }

    /* Corners: octant patches, row k (polar angle k/seg * 90 deg from the Y pole) has k + 1
     * vertices, so each boundary arc has seg + 1 vertices like the edges it meets. */
    for (int sx = -1; sx <= 1; sx += 2)
        for (int sy = -1; sy <= 1; sy += 2)
            for (int sz = -1; sz <= 1; sz += 2) {
                dvec3 c = dv3(sx * h[0], sy * h[1], sz * h[2]);
                uint32_t start = (uint32_t)b->m->n_verts;
                for (int k = 0; k <= seg; k++) {
                    double th = 0.5 * FORMULA_PI_D * k / seg;
                    for (int j = 0; j <= k; j++) {
                        double ph = k ? 0.5 * FORMULA_PI_D * j / k : 0.0;
                        dvec3 n = dv3(sx * sin(th) * cos(ph), sy * cos(th), sz * sin(th) * sin(ph));
                        mesh_box_vert(b, o, dv3_add(c, dv3_scale(n, r)), n);
                    }
                }
#define ROW(k) (start + (uint32_t)((k) * ((k) + 1) / 2))
                for (int k = 0; k < seg; k++) {
                    for (int j = 0; j <= k; j++)
                        if (!mesh_tri_out(b, ROW(k) + (uint32_t)j, ROW(k + 1) + (uint32_t)j,
                                          ROW(k + 1) + (uint32_t)j + 1))
                            return 0;
                    for (int j = 0; j < k; j++)
                        if (!mesh_tri_out(b, ROW(k) + (uint32_t)j, ROW(k + 1) + (uint32_t)j + 1,
                                          ROW(k) + (uint32_t)j + 1))
                            return 0;
                }
#undef ROW
            }
    return 1;
}

static int mesh_torus(mesh_builder *b, const object *o)
{
    int nu = o->tessellation, nv = o->tessellation / 2 < 3 ? 3 : o->tessellation / 2;
    double big = o->major, r = o->radius;
    uint32_t start = (uint32_t)b->m->n_verts;
    /* u = 1 - (angle around the ring)/2pi as the sphere's, v = (angle around the tube)/2pi from
     * the outer equator, upward; the seam row and column (u = 0, v = 1) have their own vertices. */
    for (int i = 0; i <= nu; i++) {
        double u = 2.0 * FORMULA_PI_D * (i % nu) / nu;
        dvec3 radial = dv3(cos(u), 0, sin(u));
        for (int j = 0; j <= nv; j++) {
            double v = 2.0 * FORMULA_PI_D * (j % nv) / nv;
            dvec3 n = dv3_add(dv3_scale(radial, cos(v)), dv3(0, sin(v), 0));
            mesh_uv(b, mesh_vert(b, dv3_add(dv3_scale(radial, big), dv3_scale(n, r)), n), 1.0 - (double)i / nu,
                    (double)j / nv);
        }
    }
#define TV(i, j) (start + (uint32_t)((i) * (nv + 1) + (j)))
    for (int i = 0; i < nu; i++)
        for (int j = 0; j < nv; j++)
            if (!mesh_quad_out(b, TV(i, j), TV(i + 1, j), TV(i + 1, j + 1), TV(i, j + 1)))
                return 0;
#undef TV
    return 1;
}

/* --- OBJ and PLY ------------------------------------------------------------------------- */

/* A polygon soup as read from a file, before triangulation. */
typedef struct {
    double *pos; /* 3 per position */
    double *nrm; /* 3 per file normal */
    int n_pos, cap_pos, n_nrm, cap_nrm;
    double *tex; /* 2 per file texture coordinate (OBJ vt; PLY: one per position) */
    int n_tex, cap_tex;
    int *ct;            /* per face corner: texture coordinate index or -1 */
    const char *usemtl; /* OBJ: only faces after `usemtl` with this name; NULL or "" = all */
    int *cv, *cn;       /* per face corner: position index, normal index or -1 */
    int n_corner, cap_corner;
    int *face_start; /* n_face + 1 entries into the corner arrays */
    int *face_line;  /* OBJ line or PLY face number, for messages */
    int n_face, cap_face;
    /* Vertex colours, 6 per position (colour1 rgb, colour2 rgb), allocated at the first colour
     * read (earlier positions get zeros); col_bits: 1 colour1, 2 colour2; col_given: positions
     * that carried a colour. */
    double *col;
    int cap_col, col_bits, col_given;
} mesh_soup;

static void mesh_soup_free(mesh_soup *s)
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
static int mesh_soup_colour(mesh_soup *s, const double c[6], int bits)
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

static int mesh_soup_pos(mesh_soup *s, const double v[3])
{
    if (!mesh_grow((void **)&s->pos, &s->cap_pos, s->n_pos + 1, 3 * sizeof(double)))
        return 0;
    memcpy(&s->pos[3 * (size_t)s->n_pos++], v, 3 * sizeof(double));
    return 1;
}

static int mesh_soup_nrm(mesh_soup *s, const double v[3])
{
    if (!mesh_grow((void **)&s->nrm, &s->cap_nrm, s->n_nrm + 1, 3 * sizeof(double)))
        return 0;
    memcpy(&s->nrm[3 * (size_t)s->n_nrm++], v, 3 * sizeof(double));
    return 1;
}

static int mesh_soup_tex(mesh_soup *s, const double v[2])
{
    if (!mesh_grow((void **)&s->tex, &s->cap_tex, s->n_tex + 1, 2 * sizeof(double)))
        return 0;
    memcpy(&s->tex[2 * (size_t)s->n_tex++], v, 2 * sizeof(double));
    return 1;
}

static int mesh_soup_corner(mesh_soup *s, int v, int n)
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
static int mesh_soup_face(mesh_soup *s, int line)
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

/* Reads the whole mesh file; only a regular file of at most FILEIO_MESH_MAX_BYTES is read, so
 * /dev/zero, a FIFO or a runaway file is refused before the first byte (message in err). */
static rc_status mesh_read_file(const char *path, char **out, size_t *len, char *err, size_t errlen)
{
    int fd;
    long long size = 0;
    rc_status rc = fileio_open_input(path, FILEIO_MESH_MAX_BYTES, "an OBJ or PLY mesh file", &fd, &size, err, errlen);
    if (rc != RC_OK)
        return rc;
    char *buf = malloc((size_t)size + 1);
    if (!buf) {
        close(fd);
        status_message(err, errlen, "%s: out of memory for %lld bytes; fix: a smaller mesh", path, size);
        return RC_ERR_NOMEM;
    }
    /* Read at most the size fstat gave: a file that grows meanwhile is cut there, never
     * read without bound. */
    size_t n = 0;
    while (n < (size_t)size) {
        ssize_t r = read(fd, buf + n, (size_t)size - n);
        if (r < 0 && errno == EINTR)
            continue;
        if (r < 0) {
            status_message(err, errlen, "%s: read error (%s); fix: check the file", path, strerror(errno));
            free(buf);
            close(fd);
            return RC_ERR_IO;
        }
        if (r == 0)
            break;
        n += (size_t)r;
    }
    close(fd);
    buf[n] = '\0';
    *out = buf;
    *len = n;
    return RC_OK;
}

/* OBJ index: 1-based, or negative relative to the count so far. -1 on error. */
static int mesh_obj_index(long i, int count)
{
    if (i > 0 && i <= count)
        return (int)(i - 1);
    if (i < 0 && i >= -(long)count) /* not -i <= count: -LONG_MIN overflows */
        return (int)(count + i);
    return -1;
}

static int mesh_parse_doubles(char **cur, double *v, int max)
{
    int n = 0;
    for (;;) {
        char *s = *cur, *end;
        while (*s == ' ' || *s == '\t')
            s++;
        if (!*s)
            break;
        if (n == max)
            return -1;
        errno = 0;
        v[n] = strtod(s, &end);
        if (end == s || (*end && *end != ' ' && *end != '\t'))
            return -1;
        n++;
        *cur = end;
    }
    return n;
}

/* A zero or non-finite file normal becomes (0, 0, 0): the mark mesh_soup_emit replaces by the
 * normal computed from the faces (mesh_soup_normal_bad). */
static void mesh_normal_screen(double v[3])
{
    double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (!isfinite(l) || l == 0.0)
        v[0] = v[1] = v[2] = 0.0;
}

/* The message for a 'v' line that is not 'v x y z [w | r g b]': names the first token that is
 * not a number, or says how many numbers there are. */
static void mesh_obj_bad_vertex(const char *text, const char *label, int line, char *err, size_t errlen)
{
    const char *q = text;
    while (*q == ' ' || *q == '\t')
        q++;
    q++; /* the 'v' */
    int count = 0;
    for (;;) {
        while (*q == ' ' || *q == '\t')
            q++;
        if (!*q)
            break;
        const char *e = q;
        while (*e && *e != ' ' && *e != '\t')
            e++;
        char tok[40];
        size_t n = (size_t)(e - q) < sizeof tok - 1 ? (size_t)(e - q) : sizeof tok - 1;
        memcpy(tok, q, n);
        tok[n] = '\0';
        char *end;
        strtod(tok, &end);
        if (end == tok || *end) {
            status_message(err, errlen, "%s:%d: bad vertex: '%s' is not a number; fix: write 'v x y z' with 3 numbers",
                           label, line, tok);
            return;
        }
        count++;
        q = e;
    }
    status_message(err, errlen, "%s:%d: bad vertex: %d numbers; fix: write 'v x y z' (optionally w, or r g b)", label,
                   line, count);
}

/* A byte-order mark: UTF-8's is skipped (the text after it is plain OBJ); UTF-16 and UTF-32
 * text is refused by name. Returns the bytes to skip, or -1 (message in err). */
static int mesh_obj_bom(const char *buf, size_t len, const char *label, char *err, size_t errlen)
{
    const unsigned char *u = (const unsigned char *)buf;
    if (len >= 3 && u[0] == 0xEF && u[1] == 0xBB && u[2] == 0xBF)
        return 3;
    if (len >= 2 && ((u[0] == 0xFE && u[1] == 0xFF) || (u[0] == 0xFF && u[1] == 0xFE))) {
        status_message(err, errlen,
                       "%s:1: UTF-16 or UTF-32 text (byte-order mark %02X %02X) is not supported; fix: save "
                       "the OBJ as UTF-8 or ASCII",
                       label, u[0], u[1]);
        return -1;
    }
    return 0;
}

/* `v x y z r g b`: a colour1 (linear RGB as written: OBJ does not say, and the files in use write
 * 0..1). Every vertex or none: a file that starts colouring halfway is refused at its end. */
static rc_status mesh_obj_colour(mesh_soup *s, const double *v, int n, const char *label, int line, char *err,
                                 size_t errlen)
{
    if (n != 6)
        return RC_OK;
    for (int c = 3; c < 6; c++)
        if (!(isfinite(v[c]) && v[c] >= 0.0 && v[c] <= 1e30)) {
            status_message(err, errlen,
                           "%s:%d: vertex colour %g is not a finite value >= 0; fix: 'v x y z r g b' with "
                           "r g b >= 0",
                           label, line, v[c]);
            return RC_ERR_RANGE;
        }
    double c[6] = {v[3], v[4], v[5], 0, 0, 0};
    return mesh_soup_colour(s, c, 1) ? RC_OK : RC_ERR_NOMEM;
}

static rc_status mesh_obj_parse(char *buf, size_t len, const char *label, mesh_soup *s, char *err, size_t errlen)
{
    int line = 0;
    int take = s->usemtl == NULL || s->usemtl[0] == '\0'; /* faces are kept (usemtl filter) */
    char *p = buf, *endbuf = buf + len;
    int skip = mesh_obj_bom(buf, len, label, err, errlen);
    if (skip < 0)
        return RC_ERR_PARSE;
    p += skip;
    while (p < endbuf) {
        char *nl = memchr(p, '\n', (size_t)(endbuf - p));
        char *le = nl ? nl : endbuf;
        line++;
        if (memchr(p, '\0', (size_t)(le - p))) {
            status_message(err, errlen, "%s:%d: NUL byte: not a text OBJ file; fix: export as Wavefront OBJ", label,
                           line);
            return RC_ERR_PARSE;
        }
        *le = '\0';
        char *hash = strchr(p, '#');
        if (hash)
            *hash = '\0';
        for (char *q = p; *q; q++)
            if (*q == '\r')
                *q = ' ';
        char *cur = p;
        while (*cur == ' ' || *cur == '\t')
            cur++;
        char *kw = cur;
        while (*cur && *cur != ' ' && *cur != '\t')
            cur++;
        size_t kwlen = (size_t)(cur - kw);
        double v[8];
        if (kwlen == 1 && kw[0] == 'v') {
            int n = mesh_parse_doubles(&cur, v, 7);
            if (n < 3) {
                mesh_obj_bad_vertex(p, label, line, err, errlen);
                return RC_ERR_PARSE;
            }
            if (!isfinite(v[0]) || !isfinite(v[1]) || !isfinite(v[2]) || fabs(v[0]) > 1e30 || fabs(v[1]) > 1e30 ||
                fabs(v[2]) > 1e30) {
                status_message(err, errlen,
                               "%s:%d: vertex coordinate not finite or beyond 1e30; fix: "
                               "finite coordinates",
                               label, line);
                return RC_ERR_RANGE;
            }
            if (!mesh_soup_pos(s, v))
                return RC_ERR_NOMEM;
            rc_status crc = mesh_obj_colour(s, v, n, label, line, err, errlen);
            if (crc != RC_OK)
                return crc;
        } else if (kwlen == 2 && kw[0] == 'v' && kw[1] == 'n') {
            int n = mesh_parse_doubles(&cur, v, 3);
            if (n != 3) {
                status_message(err, errlen, "%s:%d: bad normal; fix: write 'vn x y z' with 3 numbers", label, line);
                return RC_ERR_PARSE;
            }
            mesh_normal_screen(v);
            if (!mesh_soup_nrm(s, v))
                return RC_ERR_NOMEM;
        } else if (kwlen == 2 && kw[0] == 'v' && kw[1] == 't') {
            /* u [v [w]]: a missing v is 0 (the OBJ default); w has no meaning for 2D images. */
            int n = mesh_parse_doubles(&cur, v, 3);
            if (n < 1 || !isfinite(v[0]) || (n > 1 && !isfinite(v[1]))) {
                status_message(err, errlen, "%s:%d: bad texture coordinate; fix: write 'vt u v' with finite numbers",
                               label, line);
                return RC_ERR_PARSE;
            }
            if (n < 2)
                v[1] = 0.0;
            if (!mesh_soup_tex(s, v))
                return RC_ERR_NOMEM;
        } else if (kwlen == 6 && strncmp(kw, "usemtl", 6) == 0) {
            if (s->usemtl != NULL && s->usemtl[0] != '\0') {
                while (*cur == ' ' || *cur == '\t')
                    cur++;
                char *e = cur + strlen(cur);
                while (e > cur && (e[-1] == ' ' || e[-1] == '\t'))
                    *--e = '\0';
                take = strcmp(cur, s->usemtl) == 0;
            }
        } else if (kwlen == 1 && kw[0] == 'f' && !take) {
            /* a face of another material (usemtl filter): not this object's */
        } else if (kwlen == 1 && kw[0] == 'f') {
            int corners = 0;
            for (;;) {
                while (*cur == ' ' || *cur == '\t')
                    cur++;
                if (!*cur)
                    break;
                /* strtol saturates an index beyond long at LONG_MAX or LONG_MIN, out of range
                 * either way; messages quote the corner as written, not the saturated value. */
                char *e, *corner = cur;
                long vi = strtol(cur, &e, 10), ni = 0, ti = 0;
                int ok = e != cur;
                if (ok && *e == '/') {
                    cur = e + 1;
                    if (*cur != '/') {
                        ti = strtol(cur, &e, 10);
                        ok = e != cur;
                    } else {
                        e = cur;
                    }
                    if (ok && *e == '/') {
                        cur = e + 1;
                        ni = strtol(cur, &e, 10);
                        ok = e != cur;
                    }
                }
                if (!ok || (*e && *e != ' ' && *e != '\t')) {
                    status_message(err, errlen, "%s:%d: bad face corner; fix: use v, v/vt, v/vt/vn or v//vn", label,
                                   line);
                    return RC_ERR_PARSE;
                }
                cur = e;
                int cn = (int)(e - corner < 60 ? e - corner : 60);
                int pv = mesh_obj_index(vi, s->n_pos), pn = -1;
                if (pv < 0) {
                    status_message(err, errlen,
                                   "%s:%d: corner '%.*s': vertex index out of range (%d vertices so far); "
                                   "fix: indices 1..%d or negative",
                                   label, line, cn, corner, s->n_pos, s->n_pos);
                    return RC_ERR_RANGE;
                }
                if (ni != 0 && (pn = mesh_obj_index(ni, s->n_nrm)) < 0) {
                    status_message(err, errlen,
                                   "%s:%d: corner '%.*s': normal index out of range (%d normals so far); "
                                   "fix: indices 1..%d or negative",
                                   label, line, cn, corner, s->n_nrm, s->n_nrm);
                    return RC_ERR_RANGE;
                }
                int pt = -1;
                if (ti != 0 && (pt = mesh_obj_index(ti, s->n_tex)) < 0) {
                    status_message(err, errlen,
                                   "%s:%d: corner '%.*s': texture coordinate index out of range (%d so far); "
                                   "fix: indices 1..%d or negative",
                                   label, line, cn, corner, s->n_tex, s->n_tex);
                    return RC_ERR_RANGE;
                }
                if (!mesh_soup_corner(s, pv, pn))
                    return RC_ERR_NOMEM;
                s->ct[s->n_corner - 1] = pt;
                corners++;
            }
            if (corners < 3) {
                status_message(err, errlen, "%s:%d: face with %d corners; fix: at least 3", label, line, corners);
                return RC_ERR_PARSE;
            }
            if (!mesh_soup_face(s, line))
                return RC_ERR_NOMEM;
        }
        /* Everything else (o, g, s, mtllib, l, ...) carries nothing we shade with. */
        p = le + 1;
    }
    if (s->col_given > 0 && s->col_given < s->n_pos) {
        status_message(err, errlen,
                       "%s: %d of %d vertices carry a colour ('v x y z r g b'); fix: a colour on every vertex "
                       "or on none",
                       label, s->col_given, s->n_pos);
        return RC_ERR_PARSE;
    }
    return RC_OK;
}

/* --- PLY --------------------------------------------------------------------------------- */

typedef enum { PLY_I8, PLY_U8, PLY_I16, PLY_U16, PLY_I32, PLY_U32, PLY_F32, PLY_F64, PLY_BAD } ply_type;

#define PLY_MAX_ELEMENTS 16
#define PLY_MAX_PROPS    32

typedef struct {
    char name[40];
    ply_type type;
    int is_list;
    ply_type count_type;
} ply_prop;

typedef struct {
    char name[40];
    long count;
    int n_props;
    ply_prop props[PLY_MAX_PROPS];
} ply_element;

static ply_type ply_type_of(const char *s)
{
    static const char *const names[][2] = {{"char", "int8"},     {"uchar", "uint8"},   {"short", "int16"},
                                           {"ushort", "uint16"}, {"int", "int32"},     {"uint", "uint32"},
                                           {"float", "float32"}, {"double", "float64"}};
    for (int i = 0; i < 8; i++)
        if (strcmp(s, names[i][0]) == 0 || strcmp(s, names[i][1]) == 0)
            return (ply_type)i;
    return PLY_BAD;
}

static size_t ply_size(ply_type t)
{
    static const size_t sz[] = {1, 1, 2, 2, 4, 4, 4, 8};
    return sz[t];
}

typedef struct {
    const unsigned char *p, *end;
    int binary;
    int line;     /* ascii: the line of the last token read (the data start after end_header) */
    char tok[64]; /* ascii: the last token as written, for messages */
} ply_reader;

/* What ply_read found: a value, the end of the data (or a token that is not a number), or, in
 * an ascii file, a number its integer type cannot hold (binary integers always fit). */
typedef enum { PLY_VALUE_OK = 0, PLY_VALUE_END, PLY_VALUE_NOT_WHOLE, PLY_VALUE_RANGE } ply_value;

static const char *const ply_type_names[] = {"char", "uchar", "short", "ushort", "int", "uint", "float", "double"};
/* Each integer type's range; the doubles hold them exactly (|v| <= 2^32). */
static const double ply_type_lo[] = {-128, 0, -32768, 0, -2147483648.0, 0};
static const double ply_type_hi[] = {127, 255, 32767, 65535, 2147483647.0, 4294967295.0};

static ply_value ply_read_binary(ply_reader *r, ply_type t, double *out)
{
    size_t n = ply_size(t);
    if ((size_t)(r->end - r->p) < n)
        return PLY_VALUE_END;
    uint64_t u = 0;
    for (size_t i = 0; i < n; i++)
        u |= (uint64_t)r->p[i] << (8 * i);
    r->p += n;
    switch (t) {
    case PLY_I8: *out = (int8_t)u; break;
    case PLY_U8: *out = (uint8_t)u; break;
    case PLY_I16: *out = (int16_t)u; break;
    case PLY_U16: *out = (uint16_t)u; break;
    case PLY_I32: *out = (int32_t)u; break;
    case PLY_U32: *out = (uint32_t)u; break;
    case PLY_F32: {
        uint32_t w = (uint32_t)u;
        float f;
        memcpy(&f, &w, sizeof f);
        *out = f;
        break;
    }
    default: {
        double d;
        memcpy(&d, &u, sizeof d);
        *out = d;
    }
    }
    return PLY_VALUE_OK;
}

/* One value as double. An ascii value of an integer type must be a whole number within the
 * type's range: a uchar colour of 300 or -5 is refused, not read as 300/255 or wrapped. */
static ply_value ply_read(ply_reader *r, ply_type t, double *out)
{
    if (r->binary)
        return ply_read_binary(r, t, out);
    while (r->p < r->end && (*r->p == ' ' || *r->p == '\t' || *r->p == '\n' || *r->p == '\r'))
        r->line += *r->p++ == '\n';
    if (r->p >= r->end)
        return PLY_VALUE_END;
    size_t n = 0;
    while (r->p < r->end && *r->p != ' ' && *r->p != '\t' && *r->p != '\n' && *r->p != '\r') {
        if (n + 1 >= sizeof r->tok)
            return PLY_VALUE_END;
        r->tok[n++] = (char)*r->p++;
    }
    r->tok[n] = '\0';
    char *e;
    *out = strtod(r->tok, &e);
    if (*e != '\0')
        return PLY_VALUE_END;
    if (t >= PLY_F32)
        return PLY_VALUE_OK;
    if (*out != floor(*out))
        return PLY_VALUE_NOT_WHOLE; /* also NaN and Inf */
    return *out >= ply_type_lo[t] && *out <= ply_type_hi[t] ? PLY_VALUE_OK : PLY_VALUE_RANGE;
}

/* The message for a value ply_read refused: in an ascii file with its line and the token as
 * written; what names the element, its index and the property. */
static rc_status ply_value_error(const ply_reader *r, ply_value v, ply_type t, const char *label, const char *what,
                                 char *err, size_t errlen)
{
    if (v == PLY_VALUE_END) {
        status_message(err, errlen,
                       "%s: PLY data ends early or holds a malformed number (%s); fix: a complete file matching its "
                       "header",
                       label, what);
        return RC_ERR_PARSE;
    }
    char range[64];
    snprintf(range, sizeof range, "%.0f..%.0f", ply_type_lo[t], ply_type_hi[t]);
    if (v == PLY_VALUE_NOT_WHOLE)
        status_message(err, errlen, "%s:%d: %s: '%s' is not a whole number, but its type is %s; fix: an integer in %s",
                       label, r->line, what, r->tok, ply_type_names[t], range);
    else
        status_message(err, errlen,
                       "%s:%d: %s: '%s' is outside the range of its type %s; fix: a value in %s, or declare the "
                       "property with a wider type",
                       label, r->line, what, r->tok, ply_type_names[t], range);
    return RC_ERR_RANGE;
}

static int ply_keyword(const char *w)
{
    static const char *const k[] = {"comment", "obj_info", "format", "element", "property", "end_header"};
    for (size_t i = 0; i < sizeof k / sizeof *k; i++)
        if (strcmp(w, k[i]) == 0)
            return 1;
    return 0;
}

static int ply_has_element(const ply_element *el, int n, const char *name)
{
    for (int i = 0; i < n; i++)
        if (strcmp(el[i].name, name) == 0)
            return 1;
    return 0;
}

/* The vertex element's colour properties: red green blue (or diffuse_red ...) as colour1,
 * specular_red ... as colour2, each only as a set of three. Integer colours are scaled by their type's
 * largest value (uchar 255, ushort 65535), float ones taken as linear RGB. */
static rc_status ply_colour_props(const ply_element *x, const char *label, int ic[6], double scale[6], int *bits,
                                  char *err, size_t errlen)
{
    static const char *const names[3][6] = {{"red", "green", "blue", "", "", ""},
                                            {"diffuse_red", "diffuse_green", "diffuse_blue", "", "", ""},
                                            {"", "", "", "specular_red", "specular_green", "specular_blue"}};
    for (int c = 0; c < 6; c++)
        ic[c] = -1;
    *bits = 0;
    for (int k = 0; k < x->n_props; k++) {
        const ply_prop *pr = &x->props[k];
        for (int v = 0; v < 3; v++)
            for (int c = 0; c < 6; c++) {
                if (pr->is_list || !names[v][c][0] || strcmp(pr->name, names[v][c]) != 0)
                    continue;
                if (pr->type != PLY_U8 && pr->type != PLY_U16 && pr->type != PLY_F32 && pr->type != PLY_F64) {
                    status_message(err, errlen,
                                   "%s: vertex colour property %s has a signed or 32-bit integer type; fix: uchar, "
                                   "ushort, float or double",
                                   label, pr->name);
                    return RC_ERR_PARSE;
                }
                ic[c] = k;
                scale[c] = pr->type == PLY_U8 ? 1.0 / 255.0 : pr->type == PLY_U16 ? 1.0 / 65535.0 : 1.0;
            }
    }
    for (int g = 0; g < 2; g++) {
        int n = (ic[3 * g] >= 0) + (ic[3 * g + 1] >= 0) + (ic[3 * g + 2] >= 0);
        /* An incomplete set (a lone `red`) is another property of the file's, not a colour. */
        if (n == 3)
            *bits |= 1 << g;
        else
            ic[3 * g] = ic[3 * g + 1] = ic[3 * g + 2] = -1;
    }
    return RC_OK;
}

static rc_status mesh_ply_parse(const char *buf, size_t len, const char *label, mesh_soup *s, char *err, size_t errlen)
{
    ply_element el[PLY_MAX_ELEMENTS];
    int n_el = 0, binary = -1, line = 0;
    const char *p = buf, *end = buf + len;
    char text[256];

    for (;;) {
        const char *nl = memchr(p, '\n', (size_t)(end - p));
        line++;
        if (!nl) {
            status_message(err, errlen,
                           "%s:%d: PLY header has no end_header line; fix: a complete PLY "
                           "file",
                           label, line);
            return RC_ERR_PARSE;
        }
        size_t n = (size_t)(nl - p);
        if (n >= sizeof text || memchr(p, '\0', n)) {
            status_message(err, errlen,
                           "%s:%d: PLY header line too long or holding a NUL byte; fix: a "
                           "valid PLY header",
                           label, line);
            return RC_ERR_PARSE;
        }
        memcpy(text, p, n);
        text[n] = '\0';
        if (n && text[n - 1] == '\r')
            text[n - 1] = '\0';
        p = nl + 1;
        char w[6][40];
        int nw = 0, long_word = 0;
        for (char *tk = strtok(text, " \t"); tk; tk = strtok(NULL, " \t")) {
            if (nw == 6 || strlen(tk) >= sizeof w[0]) {
                long_word = 1;
                break;
            }
            strcpy(w[nw++], tk);
        }
        if (nw > 0 && line > 1 && !ply_keyword(w[0])) {
            status_message(err, errlen,
                           "%s:%d: '%s' is not a PLY header keyword (malformed header; a comment needs "
                           "'comment'); fix: format, element, property, comment, obj_info, end_header",
                           label, line, w[0]);
            return RC_ERR_PARSE;
        }
        if (long_word && !(nw > 0 && (strcmp(w[0], "comment") == 0 || strcmp(w[0], "obj_info") == 0))) {
            status_message(err, errlen,
                           "%s:%d: PLY header line has too many or too long words; fix: a "
                           "valid PLY header",
                           label, line);
            return RC_ERR_PARSE;
        }
        if (line == 1) {
            if (nw != 1 || strcmp(w[0], "ply") != 0) {
                status_message(err, errlen,
                               "%s:1: not a PLY file (first line must be 'ply'); fix: export "
                               "as PLY",
                               label);
                return RC_ERR_PARSE;
            }
            continue;
        }
        if (nw == 0 || strcmp(w[0], "comment") == 0 || strcmp(w[0], "obj_info") == 0)
            continue;
        if (strcmp(w[0], "end_header") == 0)
            break;
        if (strcmp(w[0], "format") == 0 && nw == 3) {
            if (strcmp(w[1], "ascii") == 0)
                binary = 0;
            else if (strcmp(w[1], "binary_little_endian") == 0)
                binary = 1;
            else {
                status_message(err, errlen,
                               "%s:%d: PLY format '%s' not supported; fix: ascii or "
                               "binary_little_endian",
                               label, line, w[1]);
                return RC_ERR_PARSE;
            }
        } else if (strcmp(w[0], "element") == 0 && nw == 3) {
            char *e;
            long count = strtol(w[2], &e, 10);
            if (*e || count < 0 || (size_t)count > len || n_el == PLY_MAX_ELEMENTS) {
                status_message(err, errlen,
                               "%s:%d: bad element line (count %s, %d elements so far); fix: "
                               "'element name count' with a count the file can hold, at most %d elements",
                               label, line, w[2], n_el, PLY_MAX_ELEMENTS);
                return RC_ERR_PARSE;
            }
            ply_element *x = &el[n_el++];
            memset(x, 0, sizeof *x);
            snprintf(x->name, sizeof x->name, "%s", w[1]);
            x->count = count;
        } else if (strcmp(w[0], "property") == 0 && n_el > 0 && el[n_el - 1].n_props < PLY_MAX_PROPS &&
                   (nw == 3 || (nw == 5 && strcmp(w[1], "list") == 0))) {
            /* "property <type> <name>" or "property list <count type> <item type> <name>" */
            ply_element *x = &el[n_el - 1];
            ply_prop *pr = &x->props[x->n_props++];
            memset(pr, 0, sizeof *pr);
            pr->is_list = nw == 5;
            pr->type = ply_type_of(w[nw - 2]);
            pr->count_type = pr->is_list ? ply_type_of(w[2]) : PLY_U8;
            snprintf(pr->name, sizeof pr->name, "%s", w[nw - 1]);
            if (pr->type == PLY_BAD || pr->count_type == PLY_BAD ||
                (pr->is_list && (pr->count_type == PLY_F32 || pr->count_type == PLY_F64))) {
                status_message(err, errlen,
                               "%s:%d: unknown PLY property type; fix: char uchar short ushort "
                               "int uint float double (or int8 ... float64), integer list counts",
                               label, line);
                return RC_ERR_PARSE;
            }
        } else {
            status_message(err, errlen,
                           "%s:%d: unexpected PLY header line '%s'; fix: format, element, "
                           "property, comment, end_header",
                           label, line, w[0]);
            return RC_ERR_PARSE;
        }
    }
    if (binary < 0) {
        status_message(err, errlen, "%s: PLY header has no format line; fix: 'format ascii 1.0'", label);
        return RC_ERR_PARSE;
    }
    if (!ply_has_element(el, n_el, "face")) {
        status_message(err, errlen,
                       "%s: PLY has no face element (a point cloud, or faces declared inside another "
                       "element); fix: vertex and face elements",
                       label);
        return RC_ERR_PARSE;
    }

    ply_reader r = {(const unsigned char *)p, (const unsigned char *)end, binary, line + 1, ""};
    int have_vertex = 0, have_face = 0, ply_uv = 0;
    for (int e = 0; e < n_el; e++) {
        ply_element *x = &el[e];
        int is_vertex = strcmp(x->name, "vertex") == 0, is_face = strcmp(x->name, "face") == 0;
        int ix[6] = {-1, -1, -1, -1, -1, -1}, iface = -1, ic[6], cbits = 0;
        double cscale[6];
        static const char *const vn[6] = {"x", "y", "z", "nx", "ny", "nz"};
        if (x->n_props == 0 && x->count > 0) {
            status_message(err, errlen, "%s: element '%s' has no properties; fix: a valid PLY header", label, x->name);
            return RC_ERR_PARSE;
        }
        /* Texture coordinates: the names the PLY writers use (Blender s t, others u v or
         * texture_u texture_v). */
        static const char *const uvn[3][2] = {{"u", "v"}, {"s", "t"}, {"texture_u", "texture_v"}};
        int iuv[2] = {-1, -1};
        for (int k = 0; k < x->n_props; k++) {
            for (int c = 0; c < 6; c++)
                if (!x->props[k].is_list && strcmp(x->props[k].name, vn[c]) == 0)
                    ix[c] = k;
            for (int q = 0; q < 3; q++)
                for (int c = 0; c < 2; c++)
                    if (!x->props[k].is_list && strcmp(x->props[k].name, uvn[q][c]) == 0)
                        iuv[c] = k;
            if (x->props[k].is_list &&
                (strcmp(x->props[k].name, "vertex_indices") == 0 || strcmp(x->props[k].name, "vertex_index") == 0))
                iface = k;
        }
        if (is_vertex) {
            if (have_vertex || ix[0] < 0 || ix[1] < 0 || ix[2] < 0) {
                status_message(err, errlen, "%s: vertex element %s; fix: one vertex element with x, y, z", label,
                               have_vertex ? "given twice" : "lacks x, y or z");
                return RC_ERR_PARSE;
            }
            int nn = (ix[3] >= 0) + (ix[4] >= 0) + (ix[5] >= 0);
            if (nn != 0 && nn != 3) {
                status_message(err, errlen, "%s: vertex has only some of nx, ny, nz; fix: all three or none", label);
                return RC_ERR_PARSE;
            }
            have_vertex = 1 + (nn == 3);
            if ((iuv[0] >= 0) != (iuv[1] >= 0)) {
                status_message(err, errlen,
                               "%s: vertex has only one texture coordinate; fix: both of u v (or s t, "
                               "texture_u texture_v) or neither",
                               label);
                return RC_ERR_PARSE;
            }
            ply_uv = iuv[0] >= 0;
            rc_status crc = ply_colour_props(x, label, ic, cscale, &cbits, err, errlen);
            if (crc != RC_OK)
                return crc;
        }
        if (is_face) {
            if (!have_vertex || have_face || iface < 0) {
                status_message(err, errlen,
                               "%s: face element %s; fix: vertex element first, then one "
                               "face element with a vertex_indices list",
                               label,
                               !have_vertex ? "before the vertex element"
                               : have_face  ? "given twice"
                                            : "lacks vertex_indices");
                return RC_ERR_PARSE;
            }
            have_face = 1;
        }
        for (long i = 0; i < x->count; i++) {
            double vals[6] = {0, 0, 0, 0, 0, 0}, uvv[2] = {0, 0}, cv[6] = {0, 0, 0, 0, 0, 0};
            for (int k = 0; k < x->n_props; k++) {
                ply_prop *pr = &x->props[k];
                double d;
                char what[120];
                ply_value pv;
                snprintf(what, sizeof what, "%s %ld, property %s", x->name, i, pr->name);
                if (!pr->is_list) {
                    if ((pv = ply_read(&r, pr->type, &d)) != PLY_VALUE_OK)
                        return ply_value_error(&r, pv, pr->type, label, what, err, errlen);
                    for (int c = 0; c < 6; c++) {
                        if (ix[c] == k)
                            vals[c] = d;
                        if (is_vertex && cbits && ic[c] == k)
                            cv[c] = d * cscale[c];
                    }
                    for (int c = 0; c < 2; c++)
                        if (is_vertex && iuv[c] == k)
                            uvv[c] = d;
                    continue;
                }
                double cnt;
                if ((pv = ply_read(&r, pr->count_type, &cnt)) != PLY_VALUE_OK) {
                    snprintf(what, sizeof what, "%s %ld, list length of %s", x->name, i, pr->name);
                    return ply_value_error(&r, pv, pr->count_type, label, what, err, errlen);
                }
                if (!(cnt >= 0 && cnt <= 65535 && cnt == floor(cnt))) {
                    status_message(err, errlen, "%s: %s %ld: list length %.17g; fix: 0..65535", label, x->name, i, cnt);
                    return RC_ERR_PARSE;
                }
                if (is_face && k == iface && cnt < 3) {
                    status_message(err, errlen, "%s: face %ld has %g corners; fix: at least 3", label, i, cnt);
                    return RC_ERR_PARSE;
                }
                for (int j = 0; j < (int)cnt; j++) {
                    if ((pv = ply_read(&r, pr->type, &d)) != PLY_VALUE_OK)
                        return ply_value_error(&r, pv, pr->type, label, what, err, errlen);
                    if (is_face && k == iface) {
                        if (!(d >= 0 && d < s->n_pos && d == floor(d))) {
                            status_message(err, errlen,
                                           "%s: face %ld: vertex index %.17g out of range; fix: "
                                           "0..%d",
                                           label, i, d, s->n_pos - 1);
                            return RC_ERR_RANGE;
                        }
                        int vi = (int)d;
                        if (!mesh_soup_corner(s, vi, have_vertex == 2 ? vi : -1))
                            return RC_ERR_NOMEM;
                        s->ct[s->n_corner - 1] = ply_uv ? vi : -1;
                    }
                }
            }
            if (is_vertex) {
                for (int c = 0; c < 3; c++)
                    if (!isfinite(vals[c]) || fabs(vals[c]) > 1e30) {
                        status_message(err, errlen,
                                       "%s: vertex %ld: %s not finite or beyond 1e30; fix: "
                                       "finite values",
                                       label, i, vn[c]);
                        return RC_ERR_RANGE;
                    }
                if (!mesh_soup_pos(s, vals))
                    return RC_ERR_NOMEM;
                if (ply_uv) {
                    if (!isfinite(uvv[0]) || !isfinite(uvv[1])) {
                        status_message(err, errlen, "%s: vertex %ld: texture coordinate not finite; fix: finite values",
                                       label, i);
                        return RC_ERR_RANGE;
                    }
                    if (!mesh_soup_tex(s, uvv))
                        return RC_ERR_NOMEM;
                }
                if (cbits) {
                    for (int c = 0; c < 6; c++)
                        if (!(isfinite(cv[c]) && cv[c] >= 0.0 && cv[c] <= 1e30)) {
                            status_message(err, errlen,
                                           "%s: vertex %ld: colour %g is not a finite value >= 0; fix: colours "
                                           ">= 0",
                                           label, i, cv[c]);
                            return RC_ERR_RANGE;
                        }
                    if (!mesh_soup_colour(s, cv, cbits))
                        return RC_ERR_NOMEM;
                }
                if (have_vertex == 2) {
                    mesh_normal_screen(vals + 3);
                    if (!mesh_soup_nrm(s, vals + 3))
                        return RC_ERR_NOMEM;
                }
            }
            if (is_face && !mesh_soup_face(s, (int)(i < INT_MAX ? i : INT_MAX)))
                return RC_ERR_NOMEM;
        }
    }
    if (!have_vertex || !have_face) {
        status_message(err, errlen, "%s: PLY has no %s element; fix: vertex and face elements", label,
                       have_vertex ? "face" : "vertex");
        return RC_ERR_PARSE;
    }
    return RC_OK;
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

/* Triangulates the soup (fans), computes missing normals (area-weighted), appends to the mesh.
 * Vertices are shared per (position, normal, texture coordinate). Zero-area triangles (in double, or once the
 * positions are stored as float) are left out and counted, as every renderer skips them; only a
 * mesh left with none is refused. */
static rc_status mesh_soup_emit(const mesh_soup *s, mesh_builder *b, const char *label, int is_obj, char *err,
                                size_t errlen)
{
    mesh *m = b->m;
    size_t ntri = 0, kept = 0, dropped = 0;
    for (int f = 0; f < s->n_face; f++)
        ntri += (size_t)(s->face_start[f + 1] - s->face_start[f] - 2);
    if (ntri == 0 && s->usemtl != NULL && s->usemtl[0] != '\0') {
        status_message(err, errlen, "%s: no face after `usemtl %s`; fix: a material name from the file's usemtl lines",
                       label, s->usemtl);
        return RC_ERR_RANGE;
    }
    if (ntri == 0) {
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
    dvec3 *acc = calloc((size_t)s->n_pos, sizeof *acc);
    mesh_vtable t = {16, NULL, NULL, NULL};
    while (t.cap < 2 * (size_t)s->n_corner)
        t.cap *= 2;
    t.key = malloc(t.cap * sizeof *t.key);
    t.tex = malloc(t.cap * sizeof *t.tex);
    t.val = malloc(t.cap * sizeof *t.val);
    rc_status rc = RC_OK;
    if (!acc || !t.key || !t.tex || !t.val) {
        rc = RC_ERR_NOMEM;
        goto done;
    }
    for (size_t i = 0; i < t.cap; i++)
        t.key[i] = -1;

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
    if (kept == 0) {
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
    for (int f = 0; f < s->n_face && rc == RC_OK; f++)
        for (int k = s->face_start[f] + 1; k + 1 < s->face_start[f + 1] && rc == RC_OK; k++) {
            int c[3];
            uint32_t v[3];
            mesh_soup_fan(s, f, k, c);
            if (dv3_len(mesh_soup_cross(s, c)) == 0.0) {
                dropped++;
                continue;
            }
            for (int q = 0; q < 3 && rc == RC_OK; q++)
                rc = mesh_soup_vertex(s, b, &t, acc, c[q], label, is_obj, &v[q], err, errlen);
            if (rc != RC_OK)
                break;
            dvec3 cr;
            /* Nonzero in the file's precision can still collapse once stored as float. */
            if (mesh_tri_area2(m, v[0], v[1], v[2], &cr) == 0.0) {
                dropped++;
                continue;
            }
            mesh_tri(m, v[0], v[1], v[2], b->object);
        }
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
static rc_status mesh_soup_from_assimp(mesh_assimp_soup *g, mesh_soup *s)
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

static rc_status mesh_file(mesh_builder *b, const object *o, int index, char *err, size_t errlen)
{
    char label[SCENE_PATH_MAX + 32];
    char *buf = NULL;
    size_t len = 0;
    mesh_soup s;
    memset(&s, 0, sizeof s);
    s.usemtl = o->usemtl;
    snprintf(label, sizeof label, "%s", o->path);
    size_t pl = strlen(o->path);
    int is_obj = pl >= 4 && (strcmp(o->path + pl - 4, ".obj") == 0 || strcmp(o->path + pl - 4, ".OBJ") == 0);
    int is_ply = pl >= 4 && (strcmp(o->path + pl - 4, ".ply") == 0 || strcmp(o->path + pl - 4, ".PLY") == 0);
    char why[SCENE_PATH_MAX + 600];
    rc_status rc;
    if (!is_obj && !is_ply) {
        /* Every other format through libassimp, in a child process (scene/mesh_assimp.h). */
        if (!mesh_assimp_supported(o->path)) {
            status_message(err, errlen,
                           "%s: objects[%d]: unknown mesh format; fix: a .obj or .ply file, or a format "
                           "libassimp reads (.gltf, .glb, .fbx, .dae, .x, .3ds, ...)",
                           o->path, index);
            return RC_ERR_PARSE;
        }
        mesh_assimp_soup g;
        rc = mesh_assimp_load(o->path, o->usemtl, &g, why, sizeof why);
        if (rc != RC_OK) {
            status_message(err, errlen, "objects[%d]: cannot import mesh: %s", index, why);
            return rc;
        }
        rc = mesh_soup_from_assimp(&g, &s);
        mesh_assimp_soup_free(&g);
    } else {
        rc = mesh_read_file(o->path, &buf, &len, why, sizeof why);
        if (rc != RC_OK) {
            status_message(err, errlen, "objects[%d]: cannot read mesh: %s", index, why);
            return rc;
        }
        rc = is_obj ? mesh_obj_parse(buf, len, label, &s, err, errlen)
                    : mesh_ply_parse(buf, len, label, &s, err, errlen);
    }
    if (rc == RC_OK)
        rc = mesh_soup_emit(&s, b, label, is_obj, err, errlen);
    if (rc == RC_ERR_NOMEM)
        status_message(err, errlen, "%s: objects[%d]: out of memory reading the mesh; fix: a smaller mesh", o->path,
                       index);
    mesh_soup_free(&s);
    free(buf);
    return rc;
}

/* Upper bounds of vertices and triangles a generated shape adds (reserved up front). */
static void mesh_counts(const object *o, size_t *nv, size_t *nt)
{
    size_t s = (size_t)o->tessellation;
    switch (o->shape) {
    case SHAPE_SPHERE:
        *nv = 2 * s + (s + 1) * (s / 2);
        *nt = 2 * s * (s / 2);
        break;
    case SHAPE_QUAD:
        *nv = 4;
        *nt = 2;
        break;
    case SHAPE_BOX:
        *nv = 24 + 12 * 2 * (s + 1) + 8 * (s + 1) * (s + 2) / 2;
        *nt = 12 + 24 * s + 8 * s * s;
        break;
    case SHAPE_TORUS:
        *nv = (s + 1) * ((s / 2 < 3 ? 3 : s / 2) + 1);
        *nt = 2 * s * (s / 2 < 3 ? 3 : s / 2);
        break;
    default: *nv = *nt = 0;
    }
}

static const char *mesh_shape_name(shape_kind k)
{
    static const char *const n[] = {"sphere", "quad", "box", "torus", "mesh"};
    return (unsigned)k < 5 ? n[k] : "?";
}

/* Geometry the scene file already validates; checked again for scenes built in code. */
static int mesh_valid(const object *o, char *why, size_t whylen)
{
    const float big = 1e30f; /* coordinates beyond this overflow float products in the shaders */
    float sz = fminf(o->size.x, fminf(o->size.y, o->size.z));
    if (!(fabsf(o->center.x) < big && fabsf(o->center.y) < big && fabsf(o->center.z) < big) ||
        !(isfinite(o->rotate.x) && isfinite(o->rotate.y) && isfinite(o->rotate.z)))
        return snprintf(why, whylen, "center and rotate must be finite"), 0;
    if (!(mesh_scale_ok(o->scale.x) && mesh_scale_ok(o->scale.y) && mesh_scale_ok(o->scale.z)))
        return snprintf(why, whylen, "scale must be in [%g, %g] per axis", MESH_SCALE_MIN, MESH_SCALE_MAX), 0;
    switch (o->shape) {
    case SHAPE_SPHERE:
        if (!(o->radius > 0 && o->radius < big) || o->tessellation < 4 || o->tessellation > 1024)
            return snprintf(why, whylen, "needs radius > 0 and tessellation 4..1024"), 0;
        break;
    case SHAPE_QUAD:
        if (!(o->size.x > 0 && o->size.z > 0 && o->size.x < big && o->size.z < big))
            return snprintf(why, whylen, "needs size x, z > 0"), 0;
        break;
    case SHAPE_BOX:
        if (!(sz > 0 && fmaxf(o->size.x, fmaxf(o->size.y, o->size.z)) < big) ||
            !(o->radius >= 0 && o->radius <= 0.5f * sz) || o->tessellation < 1 || o->tessellation > 256)
            return snprintf(why, whylen, "needs size > 0, 0 <= radius <= min(size)/2, tessellation 1..256"), 0;
        break;
    case SHAPE_TORUS:
        if (!(o->major > 0 && o->major < big && o->radius > 0 && o->radius <= o->major) || o->tessellation < 3 ||
            o->tessellation > 1024)
            return snprintf(why, whylen, "needs 0 < radius <= major and tessellation 3..1024"), 0;
        break;
    case SHAPE_MESH:
        if (!o->path[0])
            return snprintf(why, whylen, "needs a path"), 0;
        break;
    default: return snprintf(why, whylen, "unknown shape"), 0;
    }
    return 1;
}

rc_status mesh_add_object(const scene *s, int object_index, mesh *out, char *err, size_t errlen)
{
    if (!s || !out || object_index < 0 || object_index >= s->n_objects) {
        status_message(err, errlen, "%s: objects[%d]: no such object; fix: an index below %d", s ? s->path : "(scene)",
                       object_index, s ? s->n_objects : 0);
        return RC_ERR_RANGE;
    }
    const object *o = &s->objects[object_index];
    char why[128];
    if (!mesh_valid(o, why, sizeof why)) {
        status_message(err, errlen, "%s: objects[%d] (%s): %s", s->path, object_index, mesh_shape_name(o->shape), why);
        return RC_ERR_RANGE;
    }
    int nv0 = out->n_verts, nt0 = out->n_tris;
    mesh_builder b = {.m = out, .x = mesh_make_xform(o), .object = object_index};
    for (int k = 0; k < MAT_TEX_SLOTS && o->material >= 0 && o->material < s->n_materials; k++)
        b.textured |= s->materials[o->material].texture[k][0] != '\0';
    rc_status rc;
    if (o->shape == SHAPE_MESH) {
        rc = mesh_file(&b, o, object_index, err, errlen);
    } else {
        size_t nv, nt;
        mesh_counts(o, &nv, &nt);
        rc = mesh_reserve(out, nv, nt);
        if (rc != RC_OK) {
            status_message(err, errlen, "%s: objects[%d] (%s): out of memory; fix: lower tessellation", s->path,
                           object_index, mesh_shape_name(o->shape));
        } else {
            int ok = 0;
            switch (o->shape) {
            case SHAPE_SPHERE: ok = mesh_sphere(&b, o); break;
            case SHAPE_QUAD: ok = mesh_quad(&b, o); break;
            case SHAPE_BOX: ok = mesh_box(&b, o); break;
            default: ok = mesh_torus(&b, o); break;
            }
            if (!ok) {
                status_message(err, errlen,
                               "%s: objects[%d] (%s): a triangle has zero area in float "
                               "precision; fix: a larger size or lower tessellation",
                               s->path, object_index, mesh_shape_name(o->shape));
                rc = RC_ERR_RANGE;
            }
        }
    }
    if (rc != RC_OK) {
        out->n_verts = nv0;
        out->n_tris = nt0;
        out->dropped[object_index] = 0;
        out->recomputed[object_index] = 0;
        out->colours[object_index] = 0;
    }
    return rc;
}

rc_status mesh_build(const scene *s, mesh *out, char *err, size_t errlen)
{
    out->n_verts = 0;
    out->n_tris = 0;
    memset(out->dropped, 0, sizeof out->dropped);
    memset(out->recomputed, 0, sizeof out->recomputed);
    memset(out->colours, 0, sizeof out->colours);
    for (int i = 0; i < s->n_objects; i++) {
        rc_status rc = mesh_add_object(s, i, out, err, errlen);
        if (rc != RC_OK) {
            mesh_free(out);
            return rc;
        }
    }
    return RC_OK;
}

void mesh_free(mesh *m)
{
    free(m->pos);
    free(m->nrm);
    free(m->uv);
    free(m->idx);
    free(m->tri_object);
    free(m->col1);
    free(m->col2);
    memset(m, 0, sizeof *m);
}

void mesh_repair_totals(const mesh *m, int *dropped, int *recomputed)
{
    *dropped = *recomputed = 0;
    for (int i = 0; i < SCENE_MAX_OBJECTS; i++) {
        *dropped += m->dropped[i];
        *recomputed += m->recomputed[i];
    }
}

int mesh_repair_note(const scene *s, const mesh *m, char *buf, size_t len)
{
    size_t used = 0;
    int n = 0;
    if (len > 0)
        buf[0] = '\0';
    for (int i = 0; i < s->n_objects && i < SCENE_MAX_OBJECTS; i++) {
        int d = m->dropped[i], r = m->recomputed[i];
        if (d == 0 && r == 0)
            continue;
        char one[SCENE_PATH_MAX + 160], part[2][80] = {"", ""};
        if (d > 0)
            snprintf(part[0], sizeof part[0], "%d zero-area triangle%s left out", d, d == 1 ? "" : "s");
        if (r > 0)
            snprintf(part[1], sizeof part[1], "%d zero or non-finite normal%s recomputed from the faces", r,
                     r == 1 ? "" : "s");
        int w = snprintf(one, sizeof one, "%sobjects[%d] (%s): %s%s%s", n ? "; " : "", i, s->objects[i].path, part[0],
                         d > 0 && r > 0 ? ", " : "", part[1]);
        if (w > 0 && used + (size_t)w < len) {
            memcpy(buf + used, one, (size_t)w + 1);
            used += (size_t)w;
        }
        n++;
    }
    return n;
}

void mesh_normal_length_make(const object *o, mesh_normal_length *out)
{
    mesh_xform x = mesh_make_xform(o);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            out->a[i][j] = (float)((i == 0 ? x.s.x : i == 1 ? x.s.y : x.s.z) * x.r[j][i]);
    out->unit = o->scale.x == 1.0f && o->scale.y == 1.0f && o->scale.z == 1.0f;
}

int mesh_material_unnormalised(const scene *s, int mi)
{
    const material *m = &s->materials[mi];
    if (m->model != MODEL_D3D || m->d3d.normalize_normals)
        return 0;
    for (int i = 0; i < s->n_objects; i++) {
        const object *o = &s->objects[i];
        if (o->material == mi && !(o->scale.x == 1.0f && o->scale.y == 1.0f && o->scale.z == 1.0f))
            return 1;
    }
    return 0;
}

int mesh_material_vertex_coloured(const scene *s, const mesh *m, int mi)
{
    const material *mat = &s->materials[mi];
    if (mat->model != MODEL_D3D)
        return 0;
    for (int i = 0; i < s->n_objects && i < SCENE_MAX_OBJECTS; i++)
        if (s->objects[i].material == mi && d3d_uses_vertex_colours(&mat->d3d, m->colours[i]))
            return 1;
    return 0;
}
