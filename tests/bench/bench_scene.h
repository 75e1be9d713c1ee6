/* bench_scene.h - the benchmark's canonical scene, shared by bench_raster and bench_llvmpipe.
 *
 * Usage:
 *   scene s; char err[512];
 *   bench_scene_load("tests/bench/bench_scene.yaml", BENCH_SCENE_REFLECT, &s, err, sizeof err);
 *   mesh m; bench_mesh_make(&s, 100000, &m, err, sizeof err);   mesh_build, about that many triangles
 *   ... render ...;  mesh_free(&m);
 * The scene file: a tessellated unit sphere on a floor quad, one point light and one sun, an
 * equirectangular environment, the D3D9Client model on both objects (per-pixel Blinn-Phong plus
 * Schlick-style Fresnel environment reflection). BENCH_SCENE_DIFFUSE turns both materials into
 * plain D3D Lambert (no specular, no environment term) for the specialisation measurement.
 * bench_mesh_make sets the sphere's (object 0) tessellation to sqrt(target) segments, so the
 * mesh has that many triangles plus the floor's two. Both return RC_OK or the loader's status.
 *   bench_scene_variant("tests/bench/bench_scene.yaml", 1000000, "/tmp/x/cli.yaml", err, sizeof err);
 *                                      the same scene as a file for `reflcheck render`
 */
#ifndef REFLCHECK_BENCH_SCENE_H
#define REFLCHECK_BENCH_SCENE_H

#include <stddef.h>
#include "env.h"
#include "mesh.h"
#include "scene.h"
#include "status.h"

typedef enum { BENCH_SCENE_REFLECT, BENCH_SCENE_DIFFUSE } bench_scene_kind;

rc_status bench_scene_load(const char *path, bench_scene_kind kind, scene *s, char *err, size_t errlen);
rc_status bench_mesh_make(scene *s, int target_tris, mesh *m, char *err, size_t errlen);
/* The sphere's segments bench_mesh_make uses for a target triangle count. */
int bench_tessellation(int target_tris);
/* The scene file at path copied to out with the sphere tessellated as bench_mesh_make does and
 * its relative image paths made absolute: the same frame for `reflcheck render`. */
rc_status bench_scene_variant(const char *path, int target_tris, const char *out, char *err, size_t errlen);
/* Everything a benchmark frame needs: bench_scene_load, the environment (frame_env_load; the
 * caller frees *env_px) and bench_mesh_make. On failure nothing stays allocated. */
rc_status bench_frame_load(const char *path, bench_scene_kind kind, int target_tris, scene *s, env_map *env,
                           float **env_px, mesh *m, char *err, size_t errlen);

/* Wall clock in seconds (CLOCK_MONOTONIC). */
double bench_now(void);

#endif
