/* mesh_assimp.h - meshes and materials of any format Open Asset Import Library reads (glTF 2.0,
 * FBX, COLLADA, DirectX .x, 3DS, .blend, ...), for scene/mesh.c and harness/scene_file.c.
 *
 * Usage:
 *   mesh_assimp_soup g = {0};
 *   if (mesh_assimp_load("a.gltf", "", &g, err, sizeof err) != RC_OK) ...;   "" = all meshes,
 *   ... g.pos[3*v], g.nrm[3*v] (NaN: none in the file), g.uv[2*v] (g.has_uv[v]), g.idx[3*t] ...
 *   mesh_assimp_soup_free(&g);
 *   mesh_assimp_material mat;
 *   if (mesh_assimp_material_load("a.x", "Mat1", &mat, err, sizeof err) != RC_OK) ...;
 * The import runs in a child process (fork): libassimp is a large C++ parser we do not build, and
 * a crash inside it (seen on malformed files) must not end the run. The child writes the result
 * through a pipe; a child killed by a signal is a one-line error naming the file and the signal.
 * mesh_assimp_import and mesh_assimp_material_import are the same work in this process (the
 * fuzzer and the tests call them; nothing else should).
 * Geometry: node transforms are applied (aiProcess_PreTransformVertices), polygons triangulated,
 * points and lines left out; coordinates are the asset's own (glTF: metres, +Y up). A material
 * name selects the meshes that use that material (the scene's `usemtl`).
 */
#ifndef REFLCHECK_MESH_ASSIMP_H
#define REFLCHECK_MESH_ASSIMP_H

#include <stddef.h>
#include "scene.h"
#include "status.h"

typedef struct {
    int n_verts, n_tris;
    double *pos;           /* 3 per vertex */
    double *nrm;           /* 3 per vertex; NaN where the file has no normal */
    double *uv;            /* 2 per vertex (u right, v up) */
    unsigned char *has_uv; /* per vertex: 1 when its mesh has texture coordinates */
    int *idx;              /* 3 per triangle */
} mesh_assimp_soup;

/* An asset material, as the file states it (has_* say which keys the file has). */
typedef struct {
    char name[SCENE_NAME_MAX];
    int pbr;   /* glTF metallic-roughness keys present */
    vec3 base; /* $clr.base (glTF baseColorFactor) */
    float metallic, roughness;
    vec3 diffuse, specular, emissive, ambient; /* $clr.* (.x, 3DS, COLLADA, FBX) */
    float power;                               /* $mat.shininess (D3D Power) */
    int has_base, has_diffuse, has_specular, has_emissive, has_ambient, has_power;
    char texture[SCENE_PATH_MAX]; /* base colour or diffuse texture, resolved next to the asset; "" = none */
} mesh_assimp_material;

/* Whether libassimp reads files with this path's extension. */
int mesh_assimp_supported(const char *path);

rc_status mesh_assimp_load(const char *path, const char *material_name, mesh_assimp_soup *out, char *err,
                           size_t errlen);
rc_status mesh_assimp_import(const char *path, const char *material_name, mesh_assimp_soup *out, char *err,
                             size_t errlen);
void mesh_assimp_soup_free(mesh_assimp_soup *g);

rc_status mesh_assimp_material_load(const char *path, const char *material_name, mesh_assimp_material *out, char *err,
                                    size_t errlen);
rc_status mesh_assimp_material_import(const char *path, const char *material_name, mesh_assimp_material *out, char *err,
                                      size_t errlen);

/* The stated rule (scenes/FORMAT.md, "Imported assets") mapping an asset material onto a scene
 * material, whatever its model (each model reads its own fields); fields the asset does not state keep their value.
 * Returns 1 when it set the Cook-Torrance F0 (the scene file then derives no F0 from the ior). */
int mesh_assimp_material_apply(const mesh_assimp_material *a, material *m);

#endif
