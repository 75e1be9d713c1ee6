#include "bench_scene.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "frame.h"
#include "scene_file.h"

double bench_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

rc_status bench_scene_load(const char *path, bench_scene_kind kind, scene *s, char *err, size_t errlen)
{
    rc_status st = scene_file_load(path, s, err, errlen);
    if (st != RC_OK || kind == BENCH_SCENE_REFLECT)
        return st;
    for (int i = 0; i < s->n_materials; i++) {
        material *m = &s->materials[i];
        m->model = MODEL_D3D;
        m->d3d.specular = v3s(0.0f);
        m->d3d.ambient = v3s(0.0f);
        m->d3d.emissive = v3s(0.0f);
        m->d3d.clamp = 0;
    }
    return RC_OK;
}

rc_status bench_mesh_make(scene *s, int target_tris, mesh *m, char *err, size_t errlen)
{
    /* A UV sphere of s segments has s * (s/2) * 2 = s^2 triangles; mesh.c allows 4..1024. */
    int seg = (int)lround(sqrt((double)(target_tris > 16 ? target_tris : 16)));
    seg += seg & 1;
    s->objects[0].tessellation = seg > 1024 ? 1024 : seg;
    memset(m, 0, sizeof *m);
    return mesh_build(s, m, err, errlen);
}

rc_status bench_frame_load(const char *path, bench_scene_kind kind, int target_tris, scene *s, env_map *env,
                           float **env_px, mesh *m, char *err, size_t errlen)
{
    *env_px = NULL;
    rc_status st = bench_scene_load(path, kind, s, err, errlen);
    if (st == RC_OK)
        st = frame_env_load(s, env, env_px, err, errlen);
    if (st == RC_OK)
        st = bench_mesh_make(s, target_tris, m, err, errlen);
    if (st != RC_OK) {
        free(*env_px);
        *env_px = NULL;
    }
    return st;
}
