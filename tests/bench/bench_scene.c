/* realpath (the scene variant's absolute image paths) is an X/Open interface. */
#define _DEFAULT_SOURCE 1

#include "bench_scene.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
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

int bench_tessellation(int target_tris)
{
    /* A UV sphere of s segments has s * (s/2) * 2 = s^2 triangles; mesh.c allows 4..1024. */
    int seg = (int)lround(sqrt((double)(target_tris > 16 ? target_tris : 16)));
    seg += seg & 1;
    return seg > 1024 ? 1024 : seg;
}

rc_status bench_mesh_make(scene *s, int target_tris, mesh *m, char *err, size_t errlen)
{
    s->objects[0].tessellation = bench_tessellation(target_tris);
    memset(m, 0, sizeof *m);
    return mesh_build(s, m, err, errlen);
}

/* Copies text[0, n) into f; 0 when written. */
static int bench_put(FILE *f, const char *text, size_t n) { return fwrite(text, 1, n, f) == n ? 0 : -1; }

rc_status bench_scene_variant(const char *path, int target_tris, const char *out, char *err, size_t errlen)
{
    char dir[PATH_MAX], *text = NULL;
    if (realpath(path, dir) == NULL) {
        snprintf(err, errlen, "%s: %s; give the bench scene's path", path, strerror(errno));
        return RC_ERR_IO;
    }
    *strrchr(dir, '/') = '\0';
    FILE *in = fopen(path, "r");
    long len = -1;
    if (in != NULL && fseek(in, 0, SEEK_END) == 0 && (len = ftell(in)) >= 0 && fseek(in, 0, SEEK_SET) == 0 &&
        (text = malloc((size_t)len + 1)) != NULL && fread(text, 1, (size_t)len, in) == (size_t)len)
        text[len] = '\0';
    else
        len = -1;
    if (in != NULL)
        fclose(in);
    /* One sphere tessellation to set, the file's only "tessellation: " key. */
    const char *tess = len >= 0 ? strstr(text, "tessellation: ") : NULL;
    if (tess == NULL || strstr(tess + 1, "tessellation: ") != NULL) {
        snprintf(err, errlen, "%s: %s; the bench scene needs exactly one 'tessellation: N' (the sphere's)", path,
                 len < 0 ? "cannot read it" : "not exactly one tessellation key");
        free(text);
        return len < 0 ? RC_ERR_IO : RC_ERR_PARSE;
    }
    FILE *f = fopen(out, "w");
    if (f == NULL) {
        snprintf(err, errlen, "%s: %s; give a writable --tmp folder", out, strerror(errno));
        free(text);
        return RC_ERR_IO;
    }
    /* The copy lives elsewhere: each relative image path (a value after "image: " that is not
     * the image block "{" nor absolute) is made absolute against the scene's folder. */
    int bad = 0;
    const char *p = text;
    for (const char *q; !bad && (q = strstr(p, "image: ")) != NULL; p = q) {
        q += strlen("image: ");
        bad = bench_put(f, p, (size_t)(q - p)) != 0;
        if (!bad && *q != '{' && *q != '/')
            bad = fprintf(f, "%s/", dir) < 0;
    }
    const char *num = tess + strlen("tessellation: "), *end = num + strspn(num, "0123456789");
    if (p > num) {
        snprintf(err, errlen, "%s: the tessellation key comes before an image path; keep the sphere after them", path);
        bad = 2;
    }
    if (!bad)
        bad = bench_put(f, p, (size_t)(num - p)) != 0 || fprintf(f, "%d", bench_tessellation(target_tris)) < 0 ||
              bench_put(f, end, strlen(end)) != 0;
    bad |= fclose(f) != 0;
    free(text);
    if (bad == 1)
        snprintf(err, errlen, "%s: write failed; check the space in the --tmp folder", out);
    return bad ? RC_ERR_IO : RC_OK;
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
