/* mesh.c - the mesh type: its growth, the vertex and triangle appends every builder shares, and
 * mesh_build / mesh_add_object, which send each object to its shape (mesh_shapes.c) or its file
 * reader (mesh_obj.c, mesh_ply.c, or libassimp through mesh_assimp.c; the soup they fill becomes
 * triangles in mesh_soup.c). Also the per-object repair note and the D3D normal-length and
 * vertex-colour queries (scene/mesh.h).
 *
 * Shapes are built in object space in double precision, then scaled, rotated (Euler X, then Y,
 * then Z) and translated by the object's center as each vertex is added (mesh_vert).
 * On failure mesh_add_object leaves the mesh as it was; mesh_build frees it.
 */
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "d3d.h"
#include "fileio.h"
#include "mesh.h"
#include "mesh_assimp.h"
#include "mesh_internal.h"

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

rc_status mesh_reserve(mesh *m, size_t add_verts, size_t add_tris)
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

/* Turns the colour arrays on: zero for the vertices so far, and grown with the others. */
rc_status mesh_colours_on(mesh *m)
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

uint32_t mesh_vert(mesh_builder *b, dvec3 p, dvec3 n)
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
uint32_t mesh_uv(mesh_builder *b, uint32_t i, double u, double v)
{
    b->m->uv[2 * (size_t)i] = (float)u;
    b->m->uv[2 * (size_t)i + 1] = (float)v;
    return i;
}

double mesh_tri_area2(const mesh *m, uint32_t a, uint32_t b, uint32_t c, dvec3 *cross)
{
    dvec3 pa = dv3_from(m->pos[a]);
    *cross = dv3_cross(dv3_sub(dv3_from(m->pos[b]), pa), dv3_sub(dv3_from(m->pos[c]), pa));
    return dv3_len(*cross);
}

void mesh_tri(mesh *m, uint32_t a, uint32_t b, uint32_t c, int obj)
{
    uint32_t *t = &m->idx[3 * (size_t)m->n_tris];
    t[0] = a;
    t[1] = b;
    t[2] = c;
    m->tri_object[m->n_tris++] = obj;
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
            if (!mesh_shape(&b, o)) {
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
