/* mesh_internal.h - what the pieces of scene/mesh.h share; private to scene/mesh*.c.
 *
 * Usage (a reader of a new mesh format, say mesh_foo.c):
 *   mesh_soup s = {0};                       filled by the reader, one call per item read:
 *   mesh_soup_pos(&s, xyz); mesh_soup_nrm(&s, n); mesh_soup_tex(&s, uv);
 *   mesh_soup_corner(&s, pos_index, nrm_index_or_minus_1); ... mesh_soup_face(&s, line);
 *   rc = mesh_soup_emit(&s, &builder, label, 0, err, errlen);   triangles into the mesh
 *   mesh_soup_free(&s);
 * and a generated shape: mesh_reserve(m, nv, nt), then mesh_vert (object space in, world out),
 * mesh_uv and mesh_tri. The pieces: mesh.c (the type, the appends, build and dispatch),
 * mesh_shapes.c, mesh_obj.c, mesh_ply.c, mesh_soup.c (the soup and its repairs).
 * The mesh_soup_* appends return 1, or 0 when out of memory.
 */
#ifndef REFLCHECK_MESH_INTERNAL_H
#define REFLCHECK_MESH_INTERNAL_H

#include <stddef.h>
#include <stdint.h>
#include "mesh.h"
#include "mesh_assimp.h"
#include "status.h"
#include "vec.h"

typedef struct {
    double r[3][3];
    dvec3 t;
    dvec3 s, inv_s; /* the object's scale and its reciprocal (normals: the inverse transpose) */
} mesh_xform;

/* Shape builder: object-space vertices go through the transform as they are added. */
typedef struct {
    mesh *m;
    mesh_xform x;
    int object;
    int textured; /* the object's material has a texture: a mesh file must give UVs */
    vec3 c1, c2;  /* the colours of the next vertex (where the mesh holds colours) */
} mesh_builder;

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

/* --- the mesh (mesh.c) --- */
/* Room for add_verts more vertices and add_tris more triangles (RC_ERR_NOMEM past int counts). */
rc_status mesh_reserve(mesh *m, size_t add_verts, size_t add_tris);
/* Turns the colour arrays on: zero for the vertices so far, and grown with the others. */
rc_status mesh_colours_on(mesh *m);
/* Appends a vertex given in object space (position p, normal n); returns its index. */
uint32_t mesh_vert(mesh_builder *b, dvec3 p, dvec3 n);
/* Sets the texture coordinates of vertex i; returns i. */
uint32_t mesh_uv(mesh_builder *b, uint32_t i, double u, double v);
/* Twice the area of triangle a b c as stored (float positions); *cross gets its edge cross product. */
double mesh_tri_area2(const mesh *m, uint32_t a, uint32_t b, uint32_t c, dvec3 *cross);
void mesh_tri(mesh *m, uint32_t a, uint32_t b, uint32_t c, int obj);

/* --- the shapes (mesh_shapes.c) --- */
/* Upper bounds of vertices and triangles a generated shape adds (reserved up front). */
void mesh_counts(const object *o, size_t *nv, size_t *nt);
/* Tessellates o (sphere, quad, box or torus) into b; 0 when a triangle has zero area in float. */
int mesh_shape(mesh_builder *b, const object *o);

/* --- the readers (mesh_obj.c, mesh_ply.c): the file's text, whole, into s; label names it in
 * messages. The OBJ reader writes into buf (it cuts lines and comments in place). --- */
rc_status mesh_obj_parse(char *buf, size_t len, const char *label, mesh_soup *s, char *err, size_t errlen);
rc_status mesh_ply_parse(const char *buf, size_t len, const char *label, mesh_soup *s, char *err, size_t errlen);

/* --- the soup (mesh_soup.c) --- */
void mesh_soup_free(mesh_soup *s);
/* Sets position s->n_pos - 1's colours (bits 1: c[0..2] is colour1, 2: c[3..5] colour2). */
int mesh_soup_colour(mesh_soup *s, const double c[6], int bits);
int mesh_soup_pos(mesh_soup *s, const double v[3]);
int mesh_soup_nrm(mesh_soup *s, const double v[3]);
int mesh_soup_tex(mesh_soup *s, const double v[2]);
/* A face corner: position index v and file normal index n (or -1); its texture index is -1
 * until the reader sets s->ct[s->n_corner - 1]. */
int mesh_soup_corner(mesh_soup *s, int v, int n);
/* Closes the face whose corners were added since the last call (line: for messages). */
int mesh_soup_face(mesh_soup *s, int line);
/* A zero or non-finite file normal becomes (0, 0, 0), the mark the emission replaces. */
void mesh_normal_screen(double v[3]);
/* The soup's triangles into b's mesh (is_obj: vertex numbers in messages count from 1). */
rc_status mesh_soup_emit(const mesh_soup *s, mesh_builder *b, const char *label, int is_obj, char *err, size_t errlen);
/* libassimp's import as a soup: g's arrays move into s. */
rc_status mesh_soup_from_assimp(mesh_assimp_soup *g, mesh_soup *s);

#endif
