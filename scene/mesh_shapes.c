/* mesh_shapes.c - tessellation of the generated shapes: sphere, quad, box, torus (scene/mesh.h,
 * scenes/FORMAT.md). Vertices are given in object space; mesh_vert (mesh.c) transforms them.
 *
 * Sphere: UV sphere, `tessellation` segments around Y, tessellation/2 rings, single pole vertices.
 * Quad: two triangles in the object's XZ plane, normal +Y, size.x by size.z.
 * Box: inner box (size/2 - radius) grown by `radius`: 6 flat faces, 12 quarter-cylinder edges of
 *   `tessellation` segments, 8 octant corners with the same segments along each boundary arc;
 *   radius 0 gives a sharp box with face normals.
 * Torus: ring of radius `major` around Y in the XZ plane, tube radius `radius`;
 *   `tessellation` segments around the ring, max(3, tessellation/2) around the tube.
 * Generated triangles get their winding from the shape's outward vertex normals.
 */
#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "formula.h"
#include "mesh.h"
#include "mesh_internal.h"

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

/* Upper bounds of vertices and triangles a generated shape adds (reserved up front). */
void mesh_counts(const object *o, size_t *nv, size_t *nt)
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

int mesh_shape(mesh_builder *b, const object *o)
{
    switch (o->shape) {
    case SHAPE_SPHERE: return mesh_sphere(b, o);
    case SHAPE_QUAD: return mesh_quad(b, o);
    case SHAPE_BOX: return mesh_box(b, o);
    default: return mesh_torus(b, o);
    }
}
