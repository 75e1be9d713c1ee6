/* mesh.h - triangle meshes: the one tessellation every renderer receives.
 *
 * Usage:
 *   mesh m = {0};
 *   if (mesh_build(&scn, &m, err, sizeof err) != RC_OK) ...;   all objects, world space
 *   ... m.pos[m.idx[3*t + c]], m.nrm[...], m.uv[2*i], m.uv[2*i + 1], m.tri_object[t] ...
 *   mesh_free(&m);
 * Triangles wind counter-clockwise seen from the side their normals point to.
 * Normals are unit per-vertex shading normals (smooth where the shape is smooth,
 * duplicated vertices along creases). The mesh owns its arrays.
 * Texture coordinates (u right, v up, scene/texture.h) are per vertex: generated for the shapes
 * (scenes/FORMAT.md says how), read from OBJ `vt` and PLY `u v`, `s t` or `texture_u texture_v`;
 * (0, 0) where a file has none. A seam (the sphere's and torus's u = 0 = 1, the poles) has its
 * own vertices, with the same position and normal, on each side.
 * Mesh files are read only when they are regular files of at most FILEIO_MESH_MAX_BYTES (1 GiB,
 * core/fileio.h), checked before reading: a device, FIFO or directory, or a larger file, is
 * RC_ERR_RANGE with its kind or size in the message.
 * The readers are lenient where renderers are: a zero-area triangle in a file is left out and a
 * zero or non-finite file normal is replaced by the area-weighted normal of the vertex's faces;
 * both are counted per object (m.dropped, m.recomputed; mesh_repair_note says it in one line).
 * Malformed files are still refused with a one-line error naming file, line and fix.
 */
#ifndef REFLCHECK_MESH_H
#define REFLCHECK_MESH_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include "scene.h"
#include "status.h"

typedef struct {
    int n_verts, n_tris;
    int cap_verts, cap_tris;
    vec3 *pos;
    vec3 *nrm;
    float *uv;       /* 2 per vertex; NULL in meshes built by hand without UVs */
    uint32_t *idx;   /* 3 per triangle */
    int *tri_object; /* index into scene.objects, per triangle */
    /* Per object, what the file readers repaired: zero-area triangles left out (in the file's
     * double precision or once stored as float), and vertices whose zero or non-finite file
     * normal was recomputed from the faces. */
    int dropped[SCENE_MAX_OBJECTS], recomputed[SCENE_MAX_OBJECTS];
    /* Vertex colours from the files, linear RGB: colour1 (OBJ `v x y z r g b`, PLY red green
     * blue or diffuse_*) and colour2 (PLY specular_*), the D3D vertex's diffuse and specular
     * colours. NULL until an object brings one; colours[o] says which object o has (bit 1:
     * colour1, bit 2: colour2); vertices of other objects hold 0. */
    vec3 *col1, *col2;
    unsigned char colours[SCENE_MAX_OBJECTS];
} mesh;

/* Object scale limits per axis. A bound on scene scale, not a precision limit: a million either
 * way takes a metre-sized mesh from micrometre detail to a thousand kilometres; zero, negative
 * (a mirror, which would flip the winding), NaN and Inf are refused. */
#define MESH_SCALE_MIN 1e-6
#define MESH_SCALE_MAX 1e6
/* The one check of a scale factor, for the scene file (with its line) and for scenes built in
 * code alike. The factor is stored as a float, so it is compared with the floats nearest the
 * bounds: (float)1e-6 is 9.99999997e-7, below the double 1e-6, and a file's `scale: 1e-6`
 * stored as float must not fall outside the range it was checked against. */
static inline int mesh_scale_ok(float k) { return k >= (float)MESH_SCALE_MIN && k <= (float)MESH_SCALE_MAX; }

/* D3DRS_NORMALIZENORMALS off (material d3d.normalize_normals = 0): Direct3D transforms an
 * object's unit normal n_o by the inverse transpose of the world matrix, (R S)^-T = R S^-1, and
 * uses it unnormalised. The mesh holds the unit world normal n, the direction of R S^-1 n_o;
 * the length D3D's normal has there is 1/|S R^T n|. Usage:
 *   mesh_normal_length L; mesh_normal_length_make(&obj, &L);
 *   vec3 n_d3d = v3_scale(n, mesh_normal_length_of(&L, n));
 * An unscaled object gives exactly 1. */
typedef struct {
    float a[3][3]; /* S R^T */
    int unit;      /* scale (1, 1, 1): the length is 1 */
} mesh_normal_length;
void mesh_normal_length_make(const object *o, mesh_normal_length *out);
/* Whether material mi's D3D lighting sees normals that are not unit: model d3d with
 * normalize_normals off on an object whose scale is not (1, 1, 1). No reference renderer
 * represents that (they all normalise); the translators refuse it for a twin. */
int mesh_material_unnormalised(const scene *s, int mi);
/* Whether material mi takes colours from the vertices of an object of m (model d3d,
 * d3d.colour_vertex, a source selecting a colour that object's file carries). */
int mesh_material_vertex_coloured(const scene *s, const mesh *m, int mi);
static inline float mesh_normal_length_of(const mesh_normal_length *l, vec3 n)
{
    if (l->unit)
        return 1.0f;
    float x = l->a[0][0] * n.x + l->a[0][1] * n.y + l->a[0][2] * n.z;
    float y = l->a[1][0] * n.x + l->a[1][1] * n.y + l->a[1][2] * n.z;
    float z = l->a[2][0] * n.x + l->a[2][1] * n.y + l->a[2][2] * n.z;
    /* |S R^T n| >= MESH_SCALE_MIN for a unit n: no division by zero. */
    return 1.0f / sqrtf(x * x + y * y + z * z);
}

rc_status mesh_build(const scene *s, mesh *out, char *err, size_t errlen);
/* One object, appended to out, in world space. */
rc_status mesh_add_object(const scene *s, int object_index, mesh *out, char *err, size_t errlen);
void mesh_free(mesh *m);
/* Totals of m.dropped and m.recomputed over the objects. */
void mesh_repair_totals(const mesh *m, int *dropped, int *recomputed);
/* One line naming each object the readers repaired, e.g. "objects[0] (a.obj): 2 zero-area
 * triangles left out, 1 normal recomputed from the faces"; returns 0 (and "") when none was. */
int mesh_repair_note(const scene *s, const mesh *m, char *buf, size_t len);

#endif
