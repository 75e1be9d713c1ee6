#include "jobs.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <inttypes.h>
#include <limits.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <cJSON.h>

#include "frame.h"
#include "image_oiio.h"
#include "exr.h"
#include "fileio.h"
#include "jsonio.h"
#include "mesh.h"
#include "renderers/registry.h"
#include "scene_file.h"

const char *const job_role_names[3] = {"twin", "validate", "agree"};

int job_role_from_name(const char *name)
{
    for (int i = 0; i < 3; i++)
        if (strcmp(name, job_role_names[i]) == 0)
            return i;
    return -1;
}

void job_apply_variant(scene *s, job_variant v)
{
    if (v != JOB_SMALL)
        return;
    int w = s->small.width, h = s->small.height;
    if (w <= 0) {
        w = s->width < 96 ? s->width : 96;
        h = h > 0 ? h : (int)((long)s->height * w / s->width);
    } else if (h <= 0)
        h = (int)((long)s->height * w / s->width);
    s->width = w;
    s->height = h > 0 ? h : 1;
    s->supersample = s->small.supersample > 0 ? s->small.supersample : (s->supersample < 2 ? s->supersample : 2);
    s->samples = s->small.samples > 0 ? s->small.samples : (s->samples < 32 ? s->samples : 32);
    s->small.active = 1;
}

void job_output_path(const char *out_dir, const char *scene_name, int renderer, comparison_role role, const char *ext,
                     char *buf, size_t len)
{
    snprintf(buf, len, "%s/%s/%s-%s.%s", out_dir, scene_name, registry_name(renderer), job_role_names[role], ext);
}

int job_mkdirs(const char *path)
{
    char tmp[1024];
    /* A cut path would make another folder. */
    if ((size_t)snprintf(tmp, sizeof tmp, "%s", path) >= sizeof tmp) {
        errno = ENAMETOOLONG;
        return -1;
    }
    for (char *p = tmp + 1; *p; p++) {
        if (*p != '/')
            continue;
        *p = '\0';
        if (mkdir(tmp, 0755) != 0 && errno != EEXIST)
            return -1;
        *p = '/';
    }
    return (mkdir(tmp, 0755) != 0 && errno != EEXIST) ? -1 : 0;
}

void job_apply_overrides(scene *s, const job_spec *j)
{
    if (j->supersample > 0)
        s->supersample = j->supersample;
    if (j->samples > 0)
        s->samples = j->samples;
    for (int i = 0; i < s->n_objects && j->tessellation > 0; i++)
        s->objects[i].tessellation = j->tessellation;
    for (int i = 0; i < s->n_materials && j->per_vertex; i++)
        s->materials[i].d3d.per_vertex = 1;
}

/* Twin role: the rasterizer switches Cook-Torrance to what Cycles' Glossy Beckmann computes
 * (separable Smith G in Walter's form, F = 1), on our side and in the job we hand Cycles. */
static void job_twin_switches(scene *s)
{
    for (int i = 0; i < s->n_materials; i++) {
        if (s->materials[i].model != MODEL_COOK_TORRANCE)
            continue;
        /* With its environment term CM * Fr on, a material keeps its Fresnel: one F serves the
         * lobe and Fr, and the twin checks the mirror lookup times Schlick F(N.V). A twin
         * renderer that cannot reproduce the lobe's V-cavity G and Schlick F leaves the lobe out
         * (Cycles must anyway: harness/renderers/cycles/cycles.c). */
        if (s->materials[i].ct.reflection && s->env.kind != ENV_NONE)
            continue;
        s->materials[i].ct.g = G_SMITH_WALTER;
        s->materials[i].ct.f = F_ONE;
    }
}

/* The cache key is FNV-1a 64 streamed over labelled fields (label, length, bytes), so two
 * fields can never run into each other and every byte of every input counts. */
#define JOB_FNV_BASIS 0xcbf29ce484222325ull
#define JOB_FNV_PRIME 0x100000001b3ull

static uint64_t job_fnv(uint64_t h, const void *bytes, size_t n)
{
    const unsigned char *p = bytes;
    for (size_t i = 0; i < n; i++) {
        h ^= p[i];
        h *= JOB_FNV_PRIME;
    }
    return h;
}

static uint64_t job_key_field(uint64_t h, const char *label, const void *bytes, size_t n)
{
    uint64_t len = n;
    h = job_fnv(h, label, strlen(label) + 1);
    h = job_fnv(h, &len, sizeof len);
    return job_fnv(h, bytes, n);
}

/* Hashes a file's bytes into *h. Regular files only, opened without blocking (a FIFO would
 * wait for a writer forever) and read up to the size fstat gave (a device never ends). */
static rc_status job_key_file(uint64_t *h, const char *label, const char *path, char *err, size_t errlen)
{
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    struct stat st;
    if (fd < 0 || fstat(fd, &st) != 0) {
        snprintf(err, errlen, "%s: %s: cannot read it for the cache key: %s; give a readable file", path, label,
                 strerror(errno));
        if (fd >= 0)
            close(fd);
        return RC_ERR_IO;
    }
    if (!S_ISREG(st.st_mode)) {
        close(fd);
        snprintf(err, errlen, "%s: %s: not a regular file (a device, FIFO or folder); give a file", path, label);
        return RC_ERR_IO;
    }
    uint64_t size = (uint64_t)st.st_size, done = 0;
    *h = job_key_field(*h, label, &size, sizeof size);
    unsigned char buf[65536];
    while (done < size) {
        size_t want = size - done < sizeof buf ? (size_t)(size - done) : sizeof buf;
        ssize_t n = read(fd, buf, want);
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0) {
            snprintf(err, errlen, "%s: %s: %s while hashing it for the cache key; rerun once it is no longer changing",
                     path, label, n < 0 ? strerror(errno) : "shorter than its size");
            close(fd);
            return RC_ERR_IO;
        }
        *h = job_fnv(*h, buf, (size_t)n);
        done += (uint64_t)n;
    }
    close(fd);
    return RC_OK;
}

/* 1 when the scene reads a DDS file (cube map, face or texture). */
static int job_uses_dds(const scene *s)
{
    int any = s->env.kind == ENV_CUBE && frame_is_dds(s->env.path);
    for (int f = 0; s->env.kind == ENV_CUBE && f < 6; f++)
        any |= frame_is_dds(s->env.cube[f]);
    for (int i = 0; i < s->n_materials; i++)
        for (int k = 0; k < MAT_TEX_SLOTS; k++)
            any |= frame_is_dds(s->materials[i].texture[k]);
    return any;
}

/* Every file the scene references, in a fixed order. A new kind of referenced file (a
 * texture) is one more job_key_file call here. */
static rc_status job_key_inputs(const scene *s, uint64_t *h, char *err, size_t errlen)
{
    rc_status st = RC_OK;
    if (s->env.kind == ENV_IMAGE)
        st = job_key_file(h, "environment.image", s->env.path, err, errlen);
    char key[64];
    if (s->env.kind == ENV_CUBE && s->env.cube[0][0] == '\0') {
        frame_env_cube_key(s, 0, key, sizeof key);
        st = job_key_file(h, key, s->env.path, err, errlen);
    }
    for (int f = 0; st == RC_OK && s->env.kind == ENV_CUBE && f < 6; f++)
        if (s->env.cube[f][0] != '\0')
            st = job_key_file(h, "environment.cube", s->env.cube[f], err, errlen);
    for (int i = 0; st == RC_OK && i < s->n_objects; i++)
        if (s->objects[i].shape == SHAPE_MESH)
            st = job_key_file(h, "objects.path", s->objects[i].path, err, errlen);
    for (int i = 0; st == RC_OK && i < s->n_materials; i++)
        for (int k = 0; st == RC_OK && k < MAT_TEX_SLOTS; k++)
            if (s->materials[i].texture[k][0] != '\0')
                st = job_key_file(h, "materials.texture", s->materials[i].texture[k], err, errlen);
    /* A user's model is code the sources do not hold: its shared object's bytes. */
    for (int i = 0; st == RC_OK && i < s->n_materials; i++)
        if (s->materials[i].model == MODEL_USER)
            st = job_key_file(h, "materials.user.path", s->materials[i].user.path, err, errlen);
    /* A DDS is decoded by the OpenImageIO loaded at run time, which the sources do not name. */
    if (st == RC_OK && job_uses_dds(s)) {
        const char *v = image_oiio_version();
        *h = job_key_field(*h, "openimageio", v, strlen(v));
    }
    return st;
}

/* Where the build wrote each renderer's key sources (Makefile, harness/renderers/key_sources.py). */
#ifndef REFLCHECK_KEY_SOURCES
#define REFLCHECK_KEY_SOURCES "key-sources"
#endif

/* Hashes every file of BUILD/key-sources/<name>.list (paths in the source tree, found through
 * renderer_data_path). RC_OK, or an error when the list or a file it names cannot be read. */
static rc_status job_key_list(const char *name, uint64_t *h, char *err, size_t errlen)
{
    const char *dir = getenv("REFLCHECK_KEY_SOURCES");
    char list[PATH_MAX], line[PATH_MAX], path[PATH_MAX];
    snprintf(list, sizeof list, "%s/%s.list", dir != NULL && dir[0] != '\0' ? dir : REFLCHECK_KEY_SOURCES, name);
    FILE *f = fopen(list, "r");
    if (f == NULL) {
        snprintf(err, errlen, "%s: %s", list, strerror(errno));
        return RC_ERR_IO;
    }
    rc_status st = RC_OK;
    int n = 0;
    while (st == RC_OK && fgets(line, sizeof line, f) != NULL) {
        line[strcspn(line, "\n")] = '\0';
        if (line[0] == '\0')
            continue;
        renderer_data_path(line, path, sizeof path);
        st = job_key_file(h, line, path, err, errlen);
        n++;
    }
    fclose(f);
    if (st == RC_OK && n == 0) {
        snprintf(err, errlen, "%s: empty", list);
        st = RC_ERR_IO;
    }
    return st;
}

/* The code a render depends on. A reference render depends on the scene pipeline and its
 * translator only: the files the build says their objects are made of and call
 * (harness/renderers/key_sources.py, never a hand-written list), hashed as they are in the
 * source tree, so a change to a translator or to a header it includes re-renders it. An
 * in-process renderer (our rasterizer), or one whose list or files are gone (an installed
 * program without its tree), has the whole reflcheck binary stand in for them. */
static void job_key_code(const renderer_row *row, uint64_t *key)
{
    char err[1024];
    uint64_t h = *key;
    if (row->program == NULL || job_key_list(row->name, &h, err, sizeof err) != RC_OK) {
        h = *key;
        /* Unreadable, the key still differs from any source-tree key: no false hit. */
        if (job_key_file(&h, "binary", "/proc/self/exe", err, sizeof err) != RC_OK)
            h = job_key_field(h, "binary", "unknown", 7);
    }
    *key = h;
}

/* The renderer as installed: its version line, and the executable's path, size and change
 * time, so a rebuilt or reinstalled renderer with the same version line is a new key. */
static void job_key_program(const char *program, const char *version, uint64_t *key)
{
    char path[4352];
    struct stat st;
    *key = job_key_field(*key, "version", version, strlen(version));
    if (program == NULL || !runner_which(program, path, sizeof path) || stat(path, &st) != 0)
        return;
    long long id[3] = {(long long)st.st_size, (long long)st.st_mtime, (long long)st.st_ctime};
    *key = job_key_field(*key, "program", path, strlen(path));
    *key = job_key_field(*key, "program.stat", id, sizeof id);
}

/* Everything that can change the image: the scene's bytes, the files it references, the
 * code and renderer, and the job's options after the variant and overrides are applied.
 * Threads and the timeout are not in it: every renderer's output is the same for any thread
 * count (our rasterizer bit for bit, POV-Ray without antialiasing jitter, Cycles per seed),
 * and a job that times out is never cached. The tag only names the outputs. */
static rc_status job_key(const job_spec *j, const scene *s, const char *version, uint64_t *key, char *err,
                         size_t errlen)
{
    const renderer_row *row = registry_row(j->renderer);
    uint64_t h = JOB_FNV_BASIS;
    rc_status st = job_key_file(&h, "scene", j->scene_path, err, errlen);
    if (st == RC_OK)
        st = job_key_inputs(s, &h, err, errlen);
    if (st != RC_OK)
        return st;
    char settings[512];
    int seeds = row->stochastic ? (j->seeds > 0 ? j->seeds : 2) : 0;
    snprintf(settings, sizeof settings, "%s|%s|%s|%dx%d|k%d|spp%d|seeds%d@%d|tess%d|pv%d", row->name,
             job_role_names[j->role], j->variant == JOB_SMALL ? "small" : "full", s->width, s->height, s->supersample,
             s->samples, seeds, j->seed, j->tessellation, j->per_vertex);
    h = job_key_field(h, "options", settings, strlen(settings));
    job_key_program(row->program, version, &h);
    job_key_code(row, &h);
    *key = h;
    return RC_OK;
}

typedef struct {
    const job_spec *j;
    scene *s;
    mesh *m;
    char dir[1024]; /* where the work happens (cache entry or output folder) */
    char exr[1100], log[1100];
    char version[256];
    char command[2048];
    double timeout;
    const char *shown_log; /* the log messages point to: the copy in OUT, which stays */
    env_map env;           /* loaded and checked once, before any renderer runs */
    texture_set tex;       /* the materials' textures, likewise */
    renderer_result res;   /* the render entry's result: left-out terms for the record */
} job_ctx;

__attribute__((format(printf, 3, 4))) static void job_fail(job_record *r, runner_status st, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    r->status = st;
    vsnprintf(r->message, sizeof r->message, fmt, ap);
    va_end(ap);
}

/* The Slurm id of the job (docs/slurm.md): the spec's, else the environment's: an array task
 * as ARRAY_TASK (what scontrol and sacct take), a step as JOB.STEP, else JOB. 0 outside Slurm. */
static int job_slurm_id(const job_spec *j, char *buf, size_t len)
{
    if (j->slurm_job != NULL) {
        snprintf(buf, len, "%s", j->slurm_job);
        return buf[0] != '\0';
    }
    const char *job = getenv("SLURM_JOB_ID"), *array = getenv("SLURM_ARRAY_JOB_ID"),
               *task = getenv("SLURM_ARRAY_TASK_ID"), *step = getenv("SLURM_STEP_ID");
    if (job == NULL || job[0] == '\0')
        return 0;
    if (array != NULL && task != NULL && array[0] != '\0' && task[0] != '\0')
        snprintf(buf, len, "%s_%s", array, task);
    else
        snprintf(buf, len, "%s", job);
    /* The batch script itself is no step of ours: only srun steps (0, 1, ...) are named. */
    if (step != NULL && step[0] >= '0' && step[0] <= '9') {
        size_t n = strlen(buf);
        snprintf(buf + n, len - n, ".%s", step);
    }
    return 1;
}

/* A stochastic render's samples and the noise it reached, from its log's last
 * "reflcheck-samples:" line (harness/renderers/cycles/cycles_samples.h): "samples" becomes the
 * count rendered (image.samples auto picks it) and "noise" says the noise NRMSE reached and the
 * target its RMS gates set (0: none), the per-value noise quantile reached (pixel_q) and the
 * target its z-tests set (z_target, 0: none), the gates, and the renderer's passes from the
 * last "reflcheck-passes:" line. Lines from before the z-test rule have no pixel_q, logs from
 * before the passes line no passes. Returns the samples, or `samples` without a line. */
static int job_samples_from_log(const char *log, int samples, cJSON *o)
{
    FILE *f = log[0] != '\0' ? fopen(log, "r") : NULL;
    if (f == NULL)
        return samples;
    char line[1024], last[1024] = "";
    int passes = 0;
    while (fgets(line, sizeof line, f) != NULL)
        if (strncmp(line, "reflcheck-samples: ", 19) == 0)
            snprintf(last, sizeof last, "%s", line);
        else if (strncmp(line, "reflcheck-passes: ", 18) == 0)
            passes = atoi(line + 18);
    fclose(f);
    int n = 0, pilot = 0, at = 0, with_z = 1;
    double noise = 0.0, target = 0.0, pilot_noise = 0.0, pilot_q = 0.0, pixel_q = 0.0, z_target = 0.0;
    if (sscanf(last,
               "reflcheck-samples: samples %d noise %lf target %lf pilot %d pilot_noise %lf pilot_pixel_q %lf "
               "pixel_q %lf ztarget %lf gate %n",
               &n, &noise, &target, &pilot, &pilot_noise, &pilot_q, &pixel_q, &z_target, &at) < 8 ||
        at == 0) {
        with_z = 0;
        at = 0;
        if (sscanf(last, "reflcheck-samples: samples %d noise %lf target %lf pilot %d pilot_noise %lf gate %n", &n,
                   &noise, &target, &pilot, &pilot_noise, &at) < 5)
            at = 0;
    }
    if (at == 0 || n < 1)
        return samples;
    last[strcspn(last, "\n")] = '\0';
    cJSON *x = cJSON_AddObjectToObject(o, "noise");
    cJSON_AddNumberToObject(x, "nrmse", noise);
    cJSON_AddNumberToObject(x, "target", target);
    if (with_z) {
        cJSON_AddNumberToObject(x, "pixel_q", pixel_q);
        cJSON_AddNumberToObject(x, "z_target", z_target);
    }
    cJSON_AddBoolToObject(x, "reached", (target <= 0.0 || noise <= target) && (z_target <= 0.0 || pixel_q <= z_target));
    cJSON_AddStringToObject(x, "gate", last + at);
    cJSON_AddStringToObject(x, "samples_from", pilot > 0 ? "auto" : "image.samples");
    if (passes > 0)
        cJSON_AddNumberToObject(x, "passes", passes);
    if (pilot > 0) {
        cJSON_AddNumberToObject(x, "pilot_samples", pilot);
        cJSON_AddNumberToObject(x, "pilot_nrmse", pilot_noise);
        if (with_z)
            cJSON_AddNumberToObject(x, "pilot_pixel_q", pilot_q);
    }
    return n;
}

static rc_status job_write_record(const job_ctx *c, const job_record *r, const char *path, uint64_t key, char *err,
                                  size_t errlen)
{
    const scene *s = c->s;
    char hash[32], keyhex[32];
    snprintf(hash, sizeof hash, "%016" PRIx64, s->hash);
    snprintf(keyhex, sizeof keyhex, "%016" PRIx64, key);
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "scene", s->name);
    cJSON_AddStringToObject(o, "scene_path", c->j->scene_path);
    cJSON_AddStringToObject(o, "scene_hash", hash);
    const renderer_row *row = registry_row(c->j->renderer);
    cJSON_AddStringToObject(o, "renderer", row->name);
    cJSON_AddStringToObject(o, "role", job_role_names[c->j->role]);
    cJSON_AddStringToObject(o, "variant", c->j->variant == JOB_SMALL ? "small" : "full");
    cJSON_AddStringToObject(o, "status", runner_status_name(r->status));
    cJSON_AddStringToObject(o, "message", r->message);
    cJSON_AddStringToObject(o, "version", c->version);
    cJSON_AddStringToObject(o, "command", c->command);
    cJSON_AddNumberToObject(o, "wall_s", r->wall_s);
    cJSON_AddNumberToObject(o, "cpu_s", r->cpu_s);
    cJSON_AddBoolToObject(o, "cached", r->cached);
    cJSON_AddNumberToObject(o, "width", s->width);
    cJSON_AddNumberToObject(o, "height", s->height);
    cJSON_AddNumberToObject(o, "supersample", s->supersample);
    cJSON_AddNumberToObject(o, "samples", row->stochastic ? job_samples_from_log(r->log, s->samples, o) : 0);
    cJSON_AddNumberToObject(o, "seeds", row->stochastic ? (c->j->seeds > 0 ? c->j->seeds : 2) : 0);
    cJSON_AddNumberToObject(o, "seed", row->stochastic ? c->j->seed : 0);
    cJSON_AddNumberToObject(o, "tessellation", s->n_objects > 0 ? s->objects[0].tessellation : 0);
    cJSON_AddBoolToObject(o, "per_vertex", c->j->per_vertex);
    /* What the mesh readers repaired: the figures were measured on this mesh, not the file's. */
    int dropped, recomputed;
    mesh_repair_totals(c->m, &dropped, &recomputed);
    cJSON *mo = cJSON_AddObjectToObject(o, "mesh");
    cJSON_AddNumberToObject(mo, "triangles", c->m->n_tris);
    cJSON_AddNumberToObject(mo, "degenerate_dropped", dropped);
    cJSON_AddNumberToObject(mo, "normals_recomputed", recomputed);
    cJSON_AddStringToObject(o, "tag", c->j->tag ? c->j->tag : "");
    cJSON_AddStringToObject(o, "key", keyhex);
    cJSON_AddStringToObject(o, "exr", r->exr);
    cJSON_AddStringToObject(o, "log", r->log);
    /* A physical reference: the physics it renders, read back from its translator
     * (renderer.h), which compare.c holds against the scene's and the other reference's. */
    if (c->j->role != ROLE_TWIN && row->physics != NULL) {
        physics got;
        char text[400], why[600];
        if (row->physics(s, &got, why, sizeof why) == RC_OK)
            cJSON_AddStringToObject(o, "physics", physics_describe(&got, s->n_lights, text, sizeof text));
    }
    /* A partial twin: the terms the renderer left out of its image, and why. */
    cJSON *gaps = cJSON_AddArrayToObject(o, "terms_left_out");
    for (int t = 0; r->status == RUNNER_OK && t < RENDERER_N_TERMS; t++) {
        if (!(c->res.left_out & (1u << t)))
            continue;
        cJSON *g = cJSON_CreateObject();
        cJSON_AddStringToObject(g, "term", renderer_term_name(t));
        cJSON_AddStringToObject(g, "reason", c->res.why[t]);
        cJSON_AddItemToArray(gaps, g);
    }
    char slurm[128];
    if (job_slurm_id(c->j, slurm, sizeof slurm)) {
        cJSON *sl = cJSON_AddObjectToObject(o, "slurm");
        const char *node = getenv("SLURMD_NODENAME");
        cJSON_AddStringToObject(sl, "job_id", slurm);
        /* A record written for a job Slurm ended is not written on that job's node. */
        cJSON_AddStringToObject(sl, "node", c->j->slurm_job == NULL && node != NULL ? node : "");
    } else
        cJSON_AddNullToObject(o, "slurm");
    cJSON_AddNumberToObject(o, "finished_unix", (double)time(NULL));
    rc_status st = jsonio_write_file(o, path, err, errlen);
    cJSON_Delete(o);
    return st;
}

/* Removes a work folder and what is in it. Our work folders are flat; the depth limit only
 * stops a pathological tree (symbolic links are removed, never followed). */
static void job_remove_tree(const char *path, int depth)
{
    struct stat st;
    if (lstat(path, &st) != 0)
        return;
    if (!S_ISDIR(st.st_mode) || depth > 8) {
        unlink(path);
        return;
    }
    DIR *d = opendir(path);
    struct dirent *e;
    while (d != NULL && (e = readdir(d)) != NULL) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0)
            continue;
        char sub[2048];
        /* A cut path could name another file: leave such an entry alone. */
        if ((size_t)snprintf(sub, sizeof sub, "%s/%s", path, e->d_name) < sizeof sub)
            job_remove_tree(sub, depth + 1);
    }
    if (d != NULL)
        closedir(d);
    rmdir(path);
}

static int job_lock_fd(const char *dir, const char *name)
{
    char path[1100];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    return open(path, O_RDWR | O_CREAT | O_CLOEXEC, 0644);
}

/* Takes a job's lock: an exclusive flock on DIR/NAME, waited for. The kernel drops it when
 * we exit or are killed, and it is close-on-exec so no renderer inherits it. Returns the
 * descriptor, or -1 with errno set. */
static int job_lock(const char *dir, const char *name)
{
    int fd = job_lock_fd(dir, name);
    if (fd < 0)
        return -1;
    while (flock(fd, LOCK_EX) != 0) {
        if (errno != EINTR) {
            int e = errno;
            close(fd);
            errno = e;
            return -1;
        }
    }
    return fd;
}

/* 1 if name is PREFIX-XXXXXX, a work folder job_make_work named. */
static int job_is_work(const char *name, const char *prefix)
{
    size_t n = strlen(prefix);
    return strncmp(name, prefix, n) == 0 && name[n] == '-' && strlen(name) == n + 7;
}

/* Under the lock that work folders PREFIX-XXXXXX are made under, those left in dir by a
 * killed run (nobody else can be making one) are removed. */
static void job_clean_own(const char *dir, const char *prefix)
{
    DIR *d = opendir(dir);
    struct dirent *e;
    while (d != NULL && (e = readdir(d)) != NULL) {
        char sub[2048];
        if (job_is_work(e->d_name, prefix) && (size_t)snprintf(sub, sizeof sub, "%s/%s", dir, e->d_name) < sizeof sub)
            job_remove_tree(sub, 0);
    }
    if (d != NULL)
        closedir(d);
}

/* Removes work folders killed runs left in the cache: ours (we hold its lock) and any other
 * whose key's lock is free, so nobody is rendering it. Never waits for a lock. */
static void job_clean_stale(const char *cache_dir, const char *own_keyhex)
{
    char own[32];
    snprintf(own, sizeof own, "tmp-%s", own_keyhex);
    job_clean_own(cache_dir, own);
    DIR *d = opendir(cache_dir);
    struct dirent *e;
    while (d != NULL && (e = readdir(d)) != NULL) {
        /* tmp-<16 hex digits>-XXXXXX, as job_cached names them */
        char prefix[32], lockname[32], sub[2048];
        snprintf(prefix, sizeof prefix, "%.20s", e->d_name);
        if (strncmp(prefix, "tmp-", 4) != 0 || !job_is_work(e->d_name, prefix) || strcmp(prefix, own) == 0 ||
            (size_t)snprintf(sub, sizeof sub, "%s/%s", cache_dir, e->d_name) >= sizeof sub)
            continue;
        snprintf(lockname, sizeof lockname, "%s.lock", prefix + 4);
        int fd = job_lock_fd(cache_dir, lockname);
        if (fd >= 0 && flock(fd, LOCK_EX | LOCK_NB) == 0)
            job_remove_tree(sub, 0);
        if (fd >= 0)
            close(fd);
    }
    if (d != NULL)
        closedir(d);
}

/* A published entry: its marker (wall and CPU seconds of the render, then one line per term
 * the renderer left out: bit index and reason) and image. */
static int job_entry_complete(const char *entry, job_record *rec, renderer_result *res)
{
    char done[1100], exr[1100];
    snprintf(done, sizeof done, "%s/ok", entry);
    snprintf(exr, sizeof exr, "%s/out.exr", entry);
    if (access(exr, R_OK) != 0)
        return 0;
    FILE *f = fopen(done, "r");
    if (f == NULL)
        return 0;
    int ok = fscanf(f, "%lf %lf\n", &rec->wall_s, &rec->cpu_s) == 2;
    char line[300];
    memset(res, 0, sizeof *res);
    while (ok && fgets(line, sizeof line, f) != NULL) {
        char *end;
        long t = strtol(line, &end, 10);
        if (end == line || *end != ' ' || t < 0 || t >= RENDERER_N_TERMS)
            continue;
        end[1 + strcspn(end + 1, "\n")] = '\0';
        renderer_leave_out(res, 1u << t, end + 1);
    }
    fclose(f);
    return ok;
}

/* 1 when the entry's image (c->exr) reads whole at the scene's size: an entry damaged after it
 * was published (a truncated file, a full disk, a hand edit) must not be served again. The
 * read is the whole check: EXR has no checksum of its own, and a record of the bytes would not
 * cover an entry from before it was kept. Else 0 and why in one line. */
static int job_entry_image_ok(const job_ctx *c, char *why, size_t whylen)
{
    exr_image img;
    char err[600];
    if (exr_read(c->exr, &img, err, sizeof err) != RC_OK) {
        snprintf(why, whylen, "%s", err);
        return 0;
    }
    int ok = img.width == c->s->width && img.height == c->s->height;
    if (!ok)
        snprintf(why, whylen, "its image is %d x %d, the job %d x %d", img.width, img.height, c->s->width,
                 c->s->height);
    exr_image_free(&img);
    return ok;
}

/* 1 when path holds a published conversion: its size is the one its writer kept in
 * path.bytes. A conversion damaged after it was published (truncated, emptied) is written
 * again; the rename that publishes it means a killed writer never leaves a half file. */
static int job_env_cube_kept(const char *path)
{
    char sizes[1100];
    snprintf(sizes, sizeof sizes, "%s.bytes", path);
    char *text = fileio_read_all(sizes, NULL);
    struct stat st;
    int ok = text != NULL && stat(path, &st) == 0 && strtoll(text, NULL, 10) == (long long)st.st_size;
    free(text);
    return ok;
}

rc_status job_env_cube_file(const char *cache_dir, int renderer, const env_map *cube, char *path, size_t len, char *err,
                            size_t errlen)
{
    /* The key: the faces as loaded (whatever files and decoder gave them) and the code that
     * converts and writes them, the renderer's key sources (job_key_code: scene/env.c,
     * harness/frame.c, scene/exr.c are in them), so a rebuild that leaves them alone keeps the
     * ~100 MB file instead of writing another beside it. */
    uint64_t h = JOB_FNV_BASIS;
    int dims[2] = {cube->width, cube->height};
    h = job_key_field(h, "cube.size", dims, sizeof dims);
    h = job_key_field(h, "cube.texels", cube->rgb,
                      (size_t)6 * (size_t)cube->width * (size_t)cube->height * 3 * sizeof *cube->rgb);
    job_key_code(registry_row(renderer), &h);
    rc_status st = RC_OK;
    char dir[1100], name[64], tmp[1200];
    /* REFLCHECK_ENV_CACHE: one folder for the conversions of several caches (the nightly's
     * renders and its sweep keep separate job caches but convert the same cubes). */
    const char *shared = getenv("REFLCHECK_ENV_CACHE");
    if (shared != NULL && shared[0] != '\0')
        snprintf(dir, sizeof dir, "%s", shared);
    else
        snprintf(dir, sizeof dir, "%s/env", cache_dir);
    snprintf(name, sizeof name, "cube-%016" PRIx64, h);
    if ((size_t)snprintf(path, len, "%s/%s.exr", dir, name) >= len) {
        snprintf(err, errlen, "%s: the folder's path is too long for the environment files; use a shorter one", dir);
        return RC_ERR_RANGE;
    }
    char lockname[80];
    snprintf(lockname, sizeof lockname, "%s.lock", name);
    int fd = st == RC_OK && job_mkdirs(dir) == 0 ? job_lock(dir, lockname) : -1;
    if (st == RC_OK && fd < 0) {
        snprintf(err, errlen, "%s: cannot create or lock it: %s; check the cache folder and its space", dir,
                 strerror(errno));
        st = RC_ERR_IO;
    }
    if (st != RC_OK || job_env_cube_kept(path)) {
        if (fd >= 0)
            close(fd);
        return st;
    }
    /* Under the lock: written once, then published by rename after its size. */
    snprintf(tmp, sizeof tmp, "%s/%s.tmp.exr", dir, name);
    st = frame_env_cube_write(tmp, cube, err, errlen);
    struct stat fst;
    if (st == RC_OK && stat(tmp, &fst) == 0) {
        char sizes[1100], bytes[32];
        snprintf(sizes, sizeof sizes, "%s.bytes", path);
        snprintf(bytes, sizeof bytes, "%lld\n", (long long)fst.st_size);
        st = fileio_write_atomic(sizes, bytes, err, errlen);
        if (st == RC_OK && rename(tmp, path) != 0) {
            snprintf(err, errlen, "%s: cannot publish it: %s; check the cache folder and its space", path,
                     strerror(errno));
            st = RC_ERR_IO;
        }
    } else if (st == RC_OK) {
        snprintf(err, errlen, "%s: gone after it was written: %s; check the cache folder", tmp, strerror(errno));
        st = RC_ERR_IO;
    }
    if (st != RC_OK)
        unlink(tmp);
    close(fd);
    return st;
}

/* The cube map's equirectangular conversion for a renderer that reads it from a file, into
 * path: the cache's copy (job_env_cube_file) with a cache, else a file in the work folder,
 * which *remove asks the caller to delete after the render. */
static rc_status job_env_cube(job_ctx *c, char *path, size_t len, int *remove, char *why, size_t whylen)
{
    *remove = 0;
    if (c->j->cache_dir != NULL)
        return job_env_cube_file(c->j->cache_dir, c->j->renderer, &c->env, path, len, why, whylen);
    *remove = 1;
    snprintf(path, len, "%s/environment-cube.exr", c->dir);
    return frame_env_cube_write(path, &c->env, why, whylen);
}

/* The table row's render entry, the same one the renderers' tests call. */
static void job_render(job_ctx *c, job_record *rec)
{
    /* A renderer that reads the environment from its file gets the split one (frame_env_split_sun),
     * written into its work folder. The cache key covers the original image, the threshold (the
     * scene file) and the code that splits it (scene/env.c, harness/frame.c). */
    char split[1100] = "";
    int remove = 0;
    if (registry_row(c->j->renderer)->program != NULL && frame_sun_split(c->s)) {
        char why[600];
        remove = 1;
        snprintf(split, sizeof split, "%s/environment-split.exr", c->dir);
        if (frame_env_write(split, &c->env, why, sizeof why) != RC_OK) {
            job_fail(rec, RUNNER_ERROR, "the split environment: %s; check the work folder and its space", why);
            return;
        }
        snprintf(c->s->env.path, sizeof c->s->env.path, "%s", split);
    }
    /* A renderer that reads the environment from its file gets a cube map as its equirectangular
     * conversion (frame_env_cube_write), unless its row says it looks the cube up itself, as the
     * in-process ones do. The key covers the faces and the converting code (scene/env.c,
     * harness/frame.c). With a cache, every job of the same faces shares one conversion. */
    const renderer_row *row = registry_row(c->j->renderer);
    if (row->program != NULL && !row->cube_maps && c->s->env.kind == ENV_CUBE) {
        char why[600];
        if (job_env_cube(c, split, sizeof split, &remove, why, sizeof why) != RC_OK) {
            job_fail(rec, RUNNER_ERROR, "the cube map's conversion: %s; check the work folder and its space", why);
            return;
        }
        c->s->env.kind = ENV_IMAGE;
        snprintf(c->s->env.path, sizeof c->s->env.path, "%s", split);
    }
    renderer_job rj = {.s = c->s,
                       .m = c->m,
                       .env = &c->env,
                       .tex = &c->tex,
                       .role = c->j->role,
                       .threads = c->j->threads,
                       .seeds = c->j->seeds,
                       .seed = c->j->seed,
                       .timeout = c->timeout,
                       .partial = c->j->role == ROLE_TWIN,
                       .dir = c->dir,
                       .exr = c->exr,
                       .log = c->log,
                       .shown_log = c->shown_log,
                       .version = c->version};
    memset(&c->res, 0, sizeof c->res);
    registry_row(c->j->renderer)->render(&rj, &c->res);
    /* The split sky or a work folder's converted cube served the render; a cache entry keeps
     * only the render. */
    if (remove)
        unlink(split);
    rec->status = c->res.status;
    snprintf(rec->message, sizeof rec->message, "%s", c->res.message);
    rec->wall_s = c->res.wall_s;
    rec->cpu_s = c->res.cpu_s;
    snprintf(c->command, sizeof c->command, "%s", c->res.command);
}

/* Renders into a private work folder c->dir (created here) under parent. */
static int job_make_work(job_ctx *c, const char *parent, const char *prefix)
{
    snprintf(c->dir, sizeof c->dir, "%s/%s-XXXXXX", parent, prefix);
    if (mkdtemp(c->dir) == NULL)
        return -1;
    snprintf(c->exr, sizeof c->exr, "%s/out.exr", c->dir);
    snprintf(c->log, sizeof c->log, "%s/render.log", c->dir);
    return 0;
}

/* The cached way: under the entry's lock, use the published entry or render into a private
 * folder and publish it by rename; the second of two runs waits and then uses the first's
 * result. On return c->exr and c->log name the image and log to copy; *work is the folder to
 * remove afterwards ("" if none). The lock is held until *lock_fd is closed. */
static void job_cached(job_ctx *c, job_record *rec, const char *keyhex, int *lock_fd, char *work, size_t worklen)
{
    const char *cache = c->j->cache_dir;
    char entry[1100];
    snprintf(entry, sizeof entry, "%s/%s", cache, keyhex);
    work[0] = '\0';
    char lockname[40];
    snprintf(lockname, sizeof lockname, "%s.lock", keyhex);
    if (job_mkdirs(cache) != 0 || (*lock_fd = job_lock(cache, lockname)) < 0) {
        job_fail(rec, RUNNER_ERROR, "%s: cannot create or lock the cache: %s; check the folder and its space", cache,
                 strerror(errno));
        return;
    }
    job_clean_stale(cache, keyhex);
    snprintf(c->exr, sizeof c->exr, "%s/out.exr", entry);
    snprintf(c->log, sizeof c->log, "%s/render.log", entry);
    char damaged[700] = "";
    if (job_entry_complete(entry, rec, &c->res)) {
        if (job_entry_image_ok(c, damaged, sizeof damaged)) {
            rec->cached = 1;
            snprintf(c->command, sizeof c->command, "(cached %s)", keyhex);
            return;
        }
        fprintf(stderr, "reflcheck: note: %s: %s; rendering it again\n", entry, damaged);
    }
    rec->wall_s = rec->cpu_s = 0.0;
    job_remove_tree(entry, 0); /* an entry without its marker or a whole image is not a result */
    char prefix[64];
    snprintf(prefix, sizeof prefix, "tmp-%s", keyhex);
    if (job_make_work(c, cache, prefix) != 0) {
        job_fail(rec, RUNNER_ERROR, "%s: cannot create a work folder in the cache: %s", cache, strerror(errno));
        return;
    }
    snprintf(work, worklen, "%s", c->dir);
    job_render(c, rec);
    if (rec->status != RUNNER_OK)
        return;
    char done[1200];
    snprintf(done, sizeof done, "%s/ok", c->dir);
    FILE *f = fopen(done, "w");
    int ok = f != NULL && fprintf(f, "%.6f %.6f\n", rec->wall_s, rec->cpu_s) > 0;
    for (int t = 0; ok && t < RENDERER_N_TERMS; t++)
        if (c->res.left_out & (1u << t))
            ok = fprintf(f, "%d %s\n", t, c->res.why[t]) > 0;
    if (f != NULL)
        ok &= fclose(f) == 0;
    if (!ok || rename(c->dir, entry) != 0) {
        job_fail(rec, RUNNER_ERROR, "%s: cannot publish the cache entry: %s; check the folder and its space", entry,
                 strerror(errno));
        return;
    }
    work[0] = '\0';
    snprintf(c->exr, sizeof c->exr, "%s/out.exr", entry);
    snprintf(c->log, sizeof c->log, "%s/render.log", entry);
    if (damaged[0] != '\0')
        snprintf(rec->message, sizeof rec->message, "rendered again: the cache entry %s was damaged (%s)", keyhex,
                 damaged);
}

/* The renderer's version line into c->version. Only a program that is not there is "not
 * installed" (skipped); one that is there but fails its --version is a broken install, and its
 * job fails with the reason instead of passing for a skip. */
/* A renderer's version line belongs to its executable: with a cache it is kept in
 * CACHE/versions/<FNV-1a of the path, size, inode and change times>, so jobs over a cache ask
 * an install once (Blender's --version costs 0.3 s of CPU, most of a cached job). Fills path
 * (empty: no cache, or the program not found) and returns 1 when the kept line was read. */
static int job_version_kept(job_ctx *c, const char *program, char *path, size_t pathlen)
{
    char exe[4352];
    struct stat st;
    path[0] = '\0';
    if (c->j->cache_dir == NULL || !runner_which(program, exe, sizeof exe) || stat(exe, &st) != 0)
        return 0;
    long long id[4] = {(long long)st.st_size, (long long)st.st_ino, (long long)st.st_mtime, (long long)st.st_ctime};
    uint64_t h = job_key_field(JOB_FNV_BASIS, "program", exe, strlen(exe));
    h = job_key_field(h, "program.stat", id, sizeof id);
    snprintf(path, pathlen, "%s/versions/%016" PRIx64, c->j->cache_dir, h);
    char *text = fileio_read_all(path, NULL);
    if (text == NULL)
        return 0;
    text[strcspn(text, "\n")] = '\0';
    int ok = text[0] != '\0' && strlen(text) < sizeof c->version;
    if (ok)
        snprintf(c->version, sizeof c->version, "%s", text);
    free(text);
    return ok;
}

/* Keeps the version line for the next job (a private file renamed into place: a reader never
 * sees half a line). Failing to keep it costs only the next job a probe. */
static void job_version_keep(const char *path, const char *version)
{
    char dir[1100], tmp[1200];
    snprintf(dir, sizeof dir, "%s", path);
    char *slash = strrchr(dir, '/');
    if (slash == NULL)
        return;
    *slash = '\0';
    snprintf(tmp, sizeof tmp, "%s.tmp.%ld", path, (long)getpid());
    FILE *f = job_mkdirs(dir) == 0 ? fopen(tmp, "w") : NULL;
    if (f == NULL)
        return;
    int ok = fprintf(f, "%s\n", version) > 0;
    ok &= fclose(f) == 0;
    if (!ok || rename(tmp, path) != 0)
        remove(tmp);
}

static void job_probe_version(const renderer_row *row, job_ctx *c, job_record *rec)
{
    char why[400], kept[1100];
    if (job_version_kept(c, row->program, kept, sizeof kept))
        return;
    runner_status vs = runner_version(row->program, c->version, sizeof c->version, why, sizeof why);
    if (vs == RUNNER_OK && kept[0] != '\0')
        job_version_keep(kept, c->version);
    if (vs == RUNNER_MISSING)
        job_fail(rec, RUNNER_MISSING, "%s is not installed; install it with: apt-get install %s", row->program,
                 row->package);
    else if (vs != RUNNER_OK)
        job_fail(rec, vs, "%s; reinstall it with: apt-get install --reinstall %s", why, row->package);
}

/* The longest --out (with --tag) and --cache a job takes: its paths are built in 1024-byte
 * buffers, and below a folder of this length the longest names it adds (the scene name of up to
 * SCENE_NAME_MAX - 1 bytes, "tmp-<16 hex>-XXXXXX", "<renderer>-<role>.json") still fit, so no
 * path is ever cut (a cut path names another file). */
#define JOB_DIR_MAX 800

static rc_status job_check_dirs(const job_spec *j, char *err, size_t errlen)
{
    size_t out = strlen(j->out_dir) + (j->tag != NULL ? strlen(j->tag) + 1 : 0);
    size_t cache = j->cache_dir != NULL ? strlen(j->cache_dir) : 0;
    if (out <= JOB_DIR_MAX && cache <= JOB_DIR_MAX)
        return RC_OK;
    snprintf(err, errlen, "%s: %s of %zu bytes is longer than the %d a job takes; use a shorter folder", j->scene_path,
             out > JOB_DIR_MAX ? (j->tag != NULL ? "--out with --tag" : "--out") : "--cache",
             out > JOB_DIR_MAX ? out : cache, JOB_DIR_MAX);
    return RC_ERR_RANGE;
}

/* Step 1 of a job: the scene as this job renders it (variant, overrides, mesh, environment,
 * twin switches), the renderer's row and version, and the cache key. */
static rc_status job_prepare(job_ctx *c, job_record *rec, float **env_pixels, const renderer_row **row, uint64_t *key,
                             char *err, size_t errlen)
{
    const job_spec *j = c->j;
    scene *s = c->s;
    rc_status st = scene_file_load(j->scene_path, s, err, errlen);
    if (st == RC_OK) {
        job_apply_variant(s, j->variant);
        job_apply_overrides(s, j);
        char why[900];
        st = mesh_build(s, c->m, why, sizeof why);
        if (st != RC_OK)
            snprintf(err, errlen, "%s: objects: %s", j->scene_path, why);
        else if (mesh_repair_note(s, c->m, why, sizeof why))
            fprintf(stderr, "reflcheck: note: %s: %s\n", j->scene_path, why);
    }
    /* The environment is checked here for every renderer, so POV-Ray and Cycles never get one
     * the rasterizer would refuse. */
    if (st == RC_OK)
        st = frame_inputs_load(s, &c->env, env_pixels, &c->tex, err, errlen);
    if (st == RC_OK && j->role == ROLE_TWIN)
        job_twin_switches(s);

    c->timeout = j->timeout_s > 0 ? j->timeout_s : (s->timeout > 0 ? s->timeout : 600.0);
    *row = registry_row(j->renderer);
    if (st == RC_OK && *row == NULL) {
        snprintf(err, errlen, "renderer %d: not a row of the renderer table", j->renderer);
        st = RC_ERR_RANGE;
    }
    if (st == RC_OK) {
        if ((*row)->program == NULL)
            snprintf(c->version, sizeof c->version, "%s", (*row)->version ? (*row)->version : (*row)->name);
        else
            job_probe_version(*row, c, rec);
        st = job_key(j, s, c->version, key, err, errlen);
    }
    return st;
}

/* Step 2: the job's result, from the scheduler's record, the cache, or a render in a locked
 * work folder under DEST_DIR (WORK names that folder for removal). */
static void job_execute(job_ctx *c, job_record *rec, const renderer_row *row, const char *dest_dir, const char *keyhex,
                        int *lock_fd, char *work, size_t worklen)
{
    const job_spec *j = c->j;
    if (j->record_only) {
        /* The scheduler's verdict: its output file is the only log the job left. */
        job_fail(rec, j->record_status, "%s", j->record_message ? j->record_message : "");
        snprintf(c->command, sizeof c->command, "(record written for the scheduler)");
        if (j->record_log != NULL)
            snprintf(c->log, sizeof c->log, "%s", j->record_log);
    } else if (rec->status == RUNNER_OK && j->cache_dir != NULL)
        job_cached(c, rec, keyhex, lock_fd, work, worklen);
    else if (rec->status == RUNNER_OK) {
        /* Without a cache the job still locks itself (in OUT), so that the work folders a
         * killed run left can be told from a running one's and removed. */
        char prefix[64], lockname[80];
        snprintf(prefix, sizeof prefix, "tmp-%s-%s", row->name, job_role_names[j->role]);
        snprintf(lockname, sizeof lockname, ".%s.lock", prefix);
        *lock_fd = job_lock(dest_dir, lockname);
        if (*lock_fd >= 0)
            job_clean_own(dest_dir, prefix);
        if (*lock_fd < 0 || job_make_work(c, dest_dir, prefix) != 0)
            job_fail(rec, RUNNER_ERROR, "%s: cannot create a work folder: %s; check --out and its space", dest_dir,
                     strerror(errno));
        else {
            snprintf(work, worklen, "%s", c->dir);
            job_render(c, rec);
        }
    }
}

/* Step 3: the image and this job's log copied to their places, the work folder removed, and
 * the record written. */
static rc_status job_finish(job_ctx *c, job_record *rec, const char *dest_exr, const char *dest_json,
                            const char *dest_log, const char *work, int lock_fd, uint64_t key, char *err, size_t errlen)
{
    if (rec->status == RUNNER_OK && fileio_copy(c->exr, dest_exr) != 0)
        job_fail(rec, RUNNER_ERROR, "cannot copy %s to %s: %s; check the output folder and its space", c->exr, dest_exr,
                 strerror(errno));
    /* This job's log or none: an older run's must not pass for this one's. */
    unlink(dest_log);
    if (c->log[0] != '\0' && access(c->log, R_OK) == 0)
        fileio_copy(c->log, dest_log);
    if (work[0] != '\0')
        job_remove_tree(work, 0);
    if (lock_fd >= 0)
        close(lock_fd);
    snprintf(rec->exr, sizeof rec->exr, "%s", rec->status == RUNNER_OK ? dest_exr : "");
    snprintf(rec->log, sizeof rec->log, "%s", access(dest_log, R_OK) == 0 ? dest_log : "");
    snprintf(rec->record, sizeof rec->record, "%s", dest_json);
    return job_write_record(c, rec, dest_json, key, err, errlen);
}

/* The record OUT already holds for this job (job_spec.reuse_record): taken when it is ok, of
 * this cache key and its image is there. Returns 1 with rec filled from it, else 0. */
static int job_reuse(const char *json, const char *exr, const char *keyhex, job_record *rec)
{
    char *text = fileio_read_all(json, NULL);
    cJSON *o = text != NULL ? cJSON_Parse(text) : NULL;
    free(text);
    const char *status = cJSON_GetStringValue(cJSON_GetObjectItem(o, "status")),
               *key = cJSON_GetStringValue(cJSON_GetObjectItem(o, "key")),
               *log = cJSON_GetStringValue(cJSON_GetObjectItem(o, "log"));
    int ok = status != NULL && strcmp(status, "ok") == 0 && key != NULL && strcmp(key, keyhex) == 0 &&
             access(exr, R_OK) == 0;
    if (ok) {
        rec->status = RUNNER_OK;
        rec->reused = 1;
        rec->cached = cJSON_IsTrue(cJSON_GetObjectItem(o, "cached"));
        rec->wall_s = cJSON_GetNumberValue(cJSON_GetObjectItem(o, "wall_s"));
        rec->cpu_s = cJSON_GetNumberValue(cJSON_GetObjectItem(o, "cpu_s"));
        snprintf(rec->exr, sizeof rec->exr, "%s", exr);
        snprintf(rec->record, sizeof rec->record, "%s", json);
        snprintf(rec->log, sizeof rec->log, "%s", log != NULL ? log : "");
    }
    cJSON_Delete(o);
    return ok;
}

rc_status job_run(const job_spec *j, job_record *rec, char *err, size_t errlen)
{
    memset(rec, 0, sizeof *rec);
    if (job_check_dirs(j, err, errlen) != RC_OK) {
        rec->bad_input = 1;
        rec->status = RUNNER_ERROR;
        return RC_ERR_RANGE;
    }
    scene *s = malloc(sizeof *s);
    mesh m = {0};
    if (s == NULL) {
        snprintf(err, errlen, "%s: out of memory for the scene", j->scene_path);
        return RC_ERR_NOMEM;
    }
    job_ctx c = {.j = j, .s = s, .m = &m};
    float *env_pixels = NULL;
    uint64_t key = 0;
    const renderer_row *row = NULL;
    rc_status st = job_prepare(&c, rec, &env_pixels, &row, &key, err, errlen);
    if (st != RC_OK) {
        /* Nothing written: the scene, a file it references or an option is bad. */
        rec->bad_input = st != RC_ERR_NOMEM;
        rec->status = RUNNER_ERROR;
        free(env_pixels);
        texture_set_free(&c.tex);
        mesh_free(&m);
        free(s);
        return st;
    }

    char keyhex[32], dest_dir[1024], dest_exr[1024], dest_json[1024], dest_log[1024], stem[160];
    snprintf(keyhex, sizeof keyhex, "%016" PRIx64, key);
    snprintf(dest_dir, sizeof dest_dir, "%s/%s", j->out_dir, s->name);
    snprintf(stem, sizeof stem, "%s%s%s", s->name, j->tag ? "/" : "", j->tag ? j->tag : "");
    job_output_path(j->out_dir, stem, j->renderer, j->role, "exr", dest_exr, sizeof dest_exr);
    job_output_path(j->out_dir, stem, j->renderer, j->role, "json", dest_json, sizeof dest_json);
    job_output_path(j->out_dir, stem, j->renderer, j->role, "log", dest_log, sizeof dest_log);
    if (j->tag)
        snprintf(dest_dir, sizeof dest_dir, "%s/%s/%s", j->out_dir, s->name, j->tag);
    if (j->reuse_record && !j->record_only && job_reuse(dest_json, dest_exr, keyhex, rec)) {
        free(env_pixels);
        texture_set_free(&c.tex);
        mesh_free(&m);
        free(s);
        return RC_OK;
    }
    if (job_mkdirs(dest_dir) != 0) {
        snprintf(err, errlen, "%s: cannot create the output folder: %s; check --out and its space", dest_dir,
                 strerror(errno));
        rec->status = RUNNER_ERROR;
        free(env_pixels);
        texture_set_free(&c.tex);
        mesh_free(&m);
        free(s);
        return RC_ERR_IO;
    }

    c.shown_log = dest_log;
    int lock_fd = -1;
    char work[1100] = "";
    job_execute(&c, rec, row, dest_dir, keyhex, &lock_fd, work, sizeof work);
    st = job_finish(&c, rec, dest_exr, dest_json, dest_log, work, lock_fd, key, err, errlen);
    free(env_pixels);
    texture_set_free(&c.tex);
    mesh_free(&m);
    free(s);
    return st;
}

int job_exit_status(rc_status st, const job_record *rec)
{
    if (st != RC_OK)
        return rec->bad_input ? 2 : 1;
    return rec->status == RUNNER_OK || rec->status == RUNNER_MISSING ? 0 : 1;
}
