#include "jobs.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <inttypes.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <cJSON.h>

#include "cycles.h"
#include "frame.h"
#include "exr.h"
#include "fileio.h"
#include "mesh.h"
#include "povray.h"
#include "render.h"
#include "scene_file.h"

const char *const job_renderer_names[RENDERER_COUNT] = {"raster", "povray", "cycles"};
const char *const job_role_names[3] = {"twin", "validate", "agree"};

int job_renderer_from_name(const char *name)
{
    for (int i = 0; i < RENDERER_COUNT; i++)
        if (strcmp(name, job_renderer_names[i]) == 0)
            return i;
    return -1;
}

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
}

void job_output_path(const char *out_dir, const char *scene_name, renderer_id r, comparison_role role,
                     const char *ext, char *buf, size_t len)
{
    snprintf(buf, len, "%s/%s/%s-%s.%s", out_dir, scene_name, job_renderer_names[r], job_role_names[role], ext);
}

static int job_mkdirs(const char *path)
{
    char tmp[1024];
    snprintf(tmp, sizeof tmp, "%s", path);
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

/* Every file the scene references, in a fixed order. A new kind of referenced file (a
 * texture) is one more job_key_file call here. */
static rc_status job_key_inputs(const scene *s, uint64_t *h, char *err, size_t errlen)
{
    rc_status st = RC_OK;
    if (s->env.kind == ENV_IMAGE)
        st = job_key_file(h, "environment.image", s->env.path, err, errlen);
    for (int i = 0; st == RC_OK && i < s->n_objects; i++)
        if (s->objects[i].shape == SHAPE_MESH)
            st = job_key_file(h, "objects.path", s->objects[i].path, err, errlen);
    return st;
}

/* The code a render depends on. A reference render depends on the scene pipeline and its
 * translator only, so a change to our shading does not re-render POV-Ray or Cycles; those
 * sources are hashed when the run starts in the source tree. Elsewhere (or for our own
 * rasterizer) the whole reflcheck binary stands in for them. */
static void job_key_code(renderer_id r, uint64_t *key)
{
    static const char *const common[] = {"harness/jobs.c",  "harness/scene_file.c", "model/scene.c", "model/scene.h",
                                         "model/mesh.c",    "model/mesh.h",         "model/vec.h",   "harness/exr.c"};
    static const char *const povray[] = {"harness/povray.c", "harness/povray.h"};
    static const char *const cycles[] = {"harness/cycles.c", "harness/cycles.h", "harness/cycles_render.py"};
    const char *const *own = r == RENDERER_POVRAY ? povray : cycles;
    size_t n_own = r == RENDERER_POVRAY ? sizeof povray / sizeof povray[0] : sizeof cycles / sizeof cycles[0];
    int have = r != RENDERER_RASTER;
    for (size_t i = 0; have && i < sizeof common / sizeof common[0]; i++)
        have = access(common[i], R_OK) == 0;
    for (size_t i = 0; have && i < n_own; i++)
        have = access(own[i], R_OK) == 0;
    char err[1024];
    uint64_t h = *key;
    rc_status st = RC_OK;
    for (size_t i = 0; have && st == RC_OK && i < sizeof common / sizeof common[0]; i++)
        st = job_key_file(&h, common[i], common[i], err, sizeof err);
    for (size_t i = 0; have && st == RC_OK && i < n_own; i++)
        st = job_key_file(&h, own[i], own[i], err, sizeof err);
    if (!have || st != RC_OK) {
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
    static const char *const programs[RENDERER_COUNT] = {NULL, "povray", "blender"};
    uint64_t h = JOB_FNV_BASIS;
    rc_status st = job_key_file(&h, "scene", j->scene_path, err, errlen);
    if (st == RC_OK)
        st = job_key_inputs(s, &h, err, errlen);
    if (st != RC_OK)
        return st;
    char settings[512];
    int seeds = j->renderer == RENDERER_CYCLES ? (j->seeds > 0 ? j->seeds : 2) : 0;
    snprintf(settings, sizeof settings, "%s|%s|%s|%dx%d|k%d|spp%d|seeds%d@%d|tess%d|pv%d",
             job_renderer_names[j->renderer], job_role_names[j->role], j->variant == JOB_SMALL ? "small" : "full",
             s->width, s->height, s->supersample, s->samples, seeds, j->seed, j->tessellation, j->per_vertex);
    h = job_key_field(h, "options", settings, strlen(settings));
    job_key_program(programs[j->renderer], version, &h);
    job_key_code(j->renderer, &h);
    *key = h;
    return RC_OK;
}

typedef struct {
    const job_spec *j;
    scene *s;
    mesh *m;
    char dir[1024];       /* where the work happens (cache entry or output folder) */
    char exr[1100], log[1100];
    char version[256];
    char command[2048];
    double timeout;
    const char *shown_log; /* the log messages point to: the copy in OUT, which stays */
    env_map env;          /* loaded and checked once, before any renderer runs */
} job_ctx;

__attribute__((format(printf, 3, 4))) static void job_fail(job_record *r, runner_status st, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    r->status = st;
    vsnprintf(r->message, sizeof r->message, fmt, ap);
    va_end(ap);
}

static void job_raster(job_ctx *c, job_record *r)
{
    render_image img = {0};
    char err[1024];
    render_options ro = {.threads = c->j->threads};
    snprintf(c->command, sizeof c->command, "reflcheck render (in process)");
    rc_status st = render_scene(c->s, c->m, &c->env, &ro, &img, err, sizeof err);
    if (st != RC_OK) {
        /* Our side out of memory is an error; anything else the rasterizer refuses fails the job. */
        job_fail(r, st == RC_ERR_NOMEM ? RUNNER_ERROR : RUNNER_FAILED, "%s", err);
        return;
    }
    st = frame_write(c->exr, c->s, c->m, &img, err, sizeof err);
    r->wall_s = img.seconds;
    r->cpu_s = img.seconds;
    render_image_free(&img);
    if (st != RC_OK)
        job_fail(r, RUNNER_ERROR, "%s", err);
}

/* A renderer that did not end well: the record's status, and a message that says which kind
 * of skip it is when the program is not there. */
static void job_fail_run(job_record *r, const runner_result *rr, const char *program, const char *package,
                         const char *what, const char *log)
{
    if (rr->status == RUNNER_MISSING)
        job_fail(r, RUNNER_MISSING, "%s is not installed; install it with: apt-get install %s", program, package);
    else if (rr->status == RUNNER_ERROR)
        job_fail(r, RUNNER_ERROR, "%s could not be run (log file, fork or wait failed%s); see %s", program, what, log);
    else if (rr->exec_errno != 0)
        job_fail(r, RUNNER_FAILED, "%s failed to start (%s%s); see %s", program, strerror(rr->exec_errno), what, log);
    else if (rr->status == RUNNER_CRASHED)
        job_fail(r, RUNNER_CRASHED, "%s crashed (signal %d%s); see %s", program, rr->signal, what, log);
    else if (rr->status == RUNNER_TIMEOUT)
        job_fail(r, RUNNER_TIMEOUT, "%s timeout (killed after %.1f s%s); see %s", program, rr->wall_s, what, log);
    else
        job_fail(r, RUNNER_FAILED, "%s failed (exit status %d%s); see %s", program, rr->exit_code, what, log);
}

/* The variance of each k x k block's mean (unbiased sample variance / k^2), as the rasterizer
 * writes it: how far a pixel's k*k samples may be from its box integral. */
static void job_block_variance(const float *src, int kw, int k, int w, int h, float *var)
{
    double n = (double)k * k;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double s = 0.0, sq = 0.0;
            for (int t = 0; t < k; t++)
                for (int u = 0; u < k; u++) {
                    double v = src[(size_t)(y * k + t) * (size_t)kw + (size_t)(x * k + u)];
                    s += v;
                    sq += v * v;
                }
            double vv = k > 1 ? (sq - s * s / n) / (n * (n - 1.0)) : 0.0;
            var[(size_t)y * (size_t)w + (size_t)x] = (float)(vv > 0.0 ? vv : 0.0);
        }
}

/* One POV-Ray pass at k times the size, box-filtered into planes (w*h each, caller frees),
 * and, if var is not NULL, the block variances. Returns 0, or -1 with the record's status and
 * message set. */
static int job_povray_pass(job_ctx *c, job_record *r, const povray_options *o, const char *tag, float *planes[3],
                           float *var[3])
{
    char sdl[1100], raw[1100], err[1024];
    snprintf(sdl, sizeof sdl, "%s/%s.pov", c->dir, tag);
    snprintf(raw, sizeof raw, "%s/%s-raw.exr", c->dir, tag);
    rc_status st = povray_write_scene(c->s, c->m, o, sdl, err, sizeof err);
    povray_argv cmd;
    if (st == RC_OK)
        st = povray_command(o, sdl, raw, c->s->width, c->s->height, c->s->supersample, &cmd, err, sizeof err);
    if (st != RC_OK) {
        if (st == RC_ERR_RANGE)
            job_fail(r, RUNNER_MISSING, "povray cannot represent this scene: %s", err);
        else
            job_fail(r, RUNNER_ERROR, "cannot write the POV-Ray job: %s", err);
        return -1;
    }
    if (!o->coverage)
        povray_command_string(&cmd, c->command, sizeof c->command);
    runner_result rr;
    unlink(raw);
    runner_exec((const char *const *)cmd.argv, c->timeout, c->log, &rr);
    r->wall_s += rr.wall_s;
    r->cpu_s += rr.cpu_s;
    if (rr.status != RUNNER_OK) {
        char what[64];
        snprintf(what, sizeof what, ", %s pass", tag);
        job_fail_run(r, &rr, "povray", "povray", what, c->shown_log);
        return -1;
    }
    exr_image img;
    if (exr_read(raw, &img, err, sizeof err) != RC_OK) {
        job_fail(r, RUNNER_FAILED, "povray wrote an unreadable image: %s", err);
        return -1;
    }
    int k = c->s->supersample, w = c->s->width, h = c->s->height;
    const char *names[3] = {"R", "G", "B"};
    int ok = img.width == k * w && img.height == k * h;
    for (int i = 0; ok && i < 3; i++) {
        const float *src = exr_image_channel(&img, names[i]);
        planes[i] = malloc((size_t)w * (size_t)h * sizeof(float));
        ok = src != NULL && planes[i] != NULL && povray_box_downsample(src, img.width, img.height, k, planes[i]) == RC_OK;
        double scale = o->output_scale > 0 ? o->output_scale : 1.0;
        for (size_t p = 0; ok && p < (size_t)w * (size_t)h; p++)
            planes[i][p] = (float)(planes[i][p] / scale);
        if (ok && var != NULL) {
            var[i] = malloc((size_t)w * (size_t)h * sizeof(float));
            ok = var[i] != NULL;
            if (ok) {
                job_block_variance(src, img.width, k, w, h, var[i]);
                for (size_t p = 0; p < (size_t)w * (size_t)h; p++)
                    var[i][p] = (float)(var[i][p] / (scale * scale));
            }
        }
    }
    exr_image_free(&img);
    if (!ok) {
        job_fail(r, RUNNER_FAILED, "povray image %s is not the size asked for, or lacks R, G, B", raw);
        return -1;
    }
    return 0;
}

static void job_povray(job_ctx *c, job_record *r)
{
    povray_options o = {.role = c->j->role, .threads = c->j->threads};
    povray_options geo = {.role = c->j->role, .threads = c->j->threads, .coverage = 1};
    float *rgb[3] = {NULL, NULL, NULL}, *cov[3] = {NULL, NULL, NULL}, *var[3] = {NULL, NULL, NULL};
    if (job_povray_pass(c, r, &o, "scene", rgb, var) == 0 && job_povray_pass(c, r, &geo, "coverage", cov, NULL) == 0) {
        /* Coverage pass: R is the covered share, G/R the object index + 1 (box-filtered). */
        size_t np = (size_t)c->s->width * (size_t)c->s->height;
        for (size_t p = 0; p < np; p++)
            cov[1][p] = cov[0][p] > 0.5f ? floorf(cov[1][p] / cov[0][p] + 0.5f) - 1.0f : -1.0f;
        exr_channel ch[8] = {{"R", rgb[0]},          {"G", rgb[1]},        {"B", rgb[2]},
                             {"coverage", cov[0]},   {"object", cov[1]},   {"var.R", var[0]},
                             {"var.G", var[1]},      {"var.B", var[2]}};
        exr_attr at[] = {{"reflcheck.renderer", c->version}};
        char err[1024];
        if (exr_write(c->exr, c->s->width, c->s->height, ch, 8, at, 1, err, sizeof err) != RC_OK)
            job_fail(r, RUNNER_ERROR, "%s", err);
    }
    for (int i = 0; i < 3; i++) {
        free(rgb[i]);
        free(cov[i]);
        free(var[i]);
    }
}

/* 1 if every seed image Blender wrote reads as an EXR. */
static int job_cycles_raw_readable(const cycles_options *o, const char *exr)
{
    for (int i = 0; i < o->n_seeds; i++) {
        char path[1200], err[512];
        exr_image img;
        if (cycles_raw_path(exr, i, path, sizeof path) != RC_OK || exr_read(path, &img, err, sizeof err) != RC_OK)
            return 0;
        exr_image_free(&img);
    }
    return 1;
}

static void job_cycles(job_ctx *c, job_record *r)
{
    char job[1100], err[1024];
    snprintf(job, sizeof job, "%s/job.json", c->dir);
    cycles_options o = {.role = c->j->role, .n_seeds = c->j->seeds > 0 ? c->j->seeds : 2,
                        .seed = (unsigned)c->j->seed, .threads = c->j->threads, .partial = 1};
    rc_status st = cycles_write_job(c->s, c->m, &o, job, err, sizeof err);
    cycles_argv a;
    if (st == RC_OK)
        st = cycles_command(&o, job, c->exr, &a, err, sizeof err);
    if (st != RC_OK) {
        if (st == RC_ERR_RANGE)
            job_fail(r, RUNNER_MISSING, "cycles cannot represent this scene: %s", err);
        else
            job_fail(r, RUNNER_ERROR, "cannot write the Cycles job: %s", err);
        return;
    }
    size_t used = 0;
    for (int i = 0; i < a.argc && used < sizeof c->command; i++)
        used += (size_t)snprintf(c->command + used, sizeof c->command - used, "%s%s", i ? " " : "", a.argv[i]);
    runner_result rr;
    runner_exec(a.argv, c->timeout, c->log, &rr);
    r->wall_s = rr.wall_s;
    r->cpu_s = rr.cpu_s;
    if (rr.status != RUNNER_OK) {
        job_fail_run(r, &rr, "blender", "blender", "", c->shown_log);
        return;
    }
    st = cycles_collect(&o, c->exr, err, sizeof err);
    if (st != RC_OK) {
        /* Blender's images unreadable fail the job; readable ones that we could not merge and
         * write (disk full) are our error. */
        runner_status why = st == RC_ERR_NOMEM ? RUNNER_ERROR : RUNNER_FAILED;
        if (st == RC_ERR_IO && job_cycles_raw_readable(&o, c->exr))
            why = RUNNER_ERROR;
        job_fail(r, why, "%s: %s", why == RUNNER_ERROR ? "cannot write the Cycles image" : "cycles output unreadable",
                 err);
    }
}

/* Writes a cJSON document to path through a temporary file and a rename. */
static rc_status job_write_json(cJSON *doc, const char *path, char *err, size_t errlen)
{
    char *text = cJSON_Print(doc);
    if (text == NULL) {
        snprintf(err, errlen, "%s: out of memory for the job record", path);
        return RC_ERR_NOMEM;
    }
    size_t n = strlen(text);
    char *line = realloc(text, n + 2);
    if (line == NULL) {
        cJSON_free(text);
        snprintf(err, errlen, "%s: out of memory for the job record", path);
        return RC_ERR_NOMEM;
    }
    memcpy(line + n, "\n", 2);
    rc_status st = fileio_write_atomic(path, line, err, errlen);
    free(line);
    return st;
}

static rc_status job_write_record(const job_ctx *c, const job_record *r, const char *path, uint64_t key,
                                  char *err, size_t errlen)
{
    const scene *s = c->s;
    char hash[32], keyhex[32];
    snprintf(hash, sizeof hash, "%016" PRIx64, s->hash);
    snprintf(keyhex, sizeof keyhex, "%016" PRIx64, key);
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "scene", s->name);
    cJSON_AddStringToObject(o, "scene_path", c->j->scene_path);
    cJSON_AddStringToObject(o, "scene_hash", hash);
    cJSON_AddStringToObject(o, "renderer", job_renderer_names[c->j->renderer]);
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
    cJSON_AddNumberToObject(o, "samples", c->j->renderer == RENDERER_CYCLES ? s->samples : 0);
    cJSON_AddNumberToObject(o, "seeds", c->j->renderer == RENDERER_CYCLES ? (c->j->seeds > 0 ? c->j->seeds : 2) : 0);
    cJSON_AddNumberToObject(o, "seed", c->j->renderer == RENDERER_CYCLES ? c->j->seed : 0);
    cJSON_AddNumberToObject(o, "tessellation", s->n_objects > 0 ? s->objects[0].tessellation : 0);
    cJSON_AddBoolToObject(o, "per_vertex", c->j->per_vertex);
    cJSON_AddStringToObject(o, "tag", c->j->tag ? c->j->tag : "");
    cJSON_AddStringToObject(o, "key", keyhex);
    cJSON_AddStringToObject(o, "exr", r->exr);
    cJSON_AddStringToObject(o, "log", r->log);
    cJSON_AddNumberToObject(o, "finished_unix", (double)time(NULL));
    rc_status st = job_write_json(o, path, err, errlen);
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

/* A published entry: its marker (wall and CPU seconds of the render) and image. */
static int job_entry_complete(const char *entry, job_record *rec)
{
    char done[1100], exr[1100];
    snprintf(done, sizeof done, "%s/ok", entry);
    snprintf(exr, sizeof exr, "%s/out.exr", entry);
    if (access(exr, R_OK) != 0)
        return 0;
    FILE *f = fopen(done, "r");
    if (f == NULL)
        return 0;
    int ok = fscanf(f, "%lf %lf", &rec->wall_s, &rec->cpu_s) == 2;
    fclose(f);
    return ok;
}

static void job_render(job_ctx *c, job_record *rec)
{
    switch (c->j->renderer) {
    case RENDERER_RASTER: job_raster(c, rec); break;
    case RENDERER_POVRAY: job_povray(c, rec); break;
    default: job_cycles(c, rec); break;
    }
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
    if (job_entry_complete(entry, rec)) {
        rec->cached = 1;
        snprintf(c->command, sizeof c->command, "(cached %s)", keyhex);
        return;
    }
    rec->wall_s = rec->cpu_s = 0.0;
    job_remove_tree(entry, 0); /* an entry without its marker or image is not a result */
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
}

rc_status job_run(const job_spec *j, job_record *rec, char *err, size_t errlen)
{
    memset(rec, 0, sizeof *rec);
    scene *s = malloc(sizeof *s);
    mesh m = {0};
    if (s == NULL) {
        snprintf(err, errlen, "%s: out of memory for the scene", j->scene_path);
        return RC_ERR_NOMEM;
    }
    job_ctx c = {.j = j, .s = s, .m = &m};
    float *env_pixels = NULL;
    uint64_t key = 0;
    rc_status st = scene_file_load(j->scene_path, s, err, errlen);
    if (st == RC_OK) {
        job_apply_variant(s, j->variant);
        job_apply_overrides(s, j);
        char why[900];
        st = mesh_build(s, &m, why, sizeof why);
        if (st != RC_OK)
            snprintf(err, errlen, "%s: objects: %s", j->scene_path, why);
    }
    /* The environment is checked here for every renderer, so POV-Ray and Cycles never get one
     * the rasterizer would refuse. */
    if (st == RC_OK)
        st = frame_env_load(s, &c.env, &env_pixels, err, errlen);
    if (st == RC_OK && j->role == ROLE_TWIN)
        job_twin_switches(s);

    c.timeout = j->timeout_s > 0 ? j->timeout_s : (s->timeout > 0 ? s->timeout : 600.0);
    static const char *const programs[RENDERER_COUNT] = {NULL, "povray", "blender"};
    if (st == RC_OK) {
        if (j->renderer == RENDERER_RASTER)
            snprintf(c.version, sizeof c.version, "reflcheck-raster");
        else if (!runner_version(programs[j->renderer], c.version, sizeof c.version))
            snprintf(rec->message, sizeof rec->message, "%s is not installed; install it with: apt-get install %s",
                     programs[j->renderer], programs[j->renderer]);
        if (rec->message[0] != '\0')
            rec->status = RUNNER_MISSING;
        st = job_key(j, s, c.version, &key, err, errlen);
    }
    if (st != RC_OK) {
        /* Nothing written: the scene, a file it references or an option is bad. */
        rec->bad_input = st != RC_ERR_NOMEM;
        rec->status = RUNNER_ERROR;
        free(env_pixels);
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
    if (job_mkdirs(dest_dir) != 0) {
        snprintf(err, errlen, "%s: cannot create the output folder: %s; check --out and its space", dest_dir,
                 strerror(errno));
        rec->status = RUNNER_ERROR;
        free(env_pixels);
        mesh_free(&m);
        free(s);
        return RC_ERR_IO;
    }

    c.shown_log = dest_log;
    int lock_fd = -1;
    char work[1100] = "";
    if (rec->status == RUNNER_OK && j->cache_dir != NULL)
        job_cached(&c, rec, keyhex, &lock_fd, work, sizeof work);
    else if (rec->status == RUNNER_OK) {
        /* Without a cache the job still locks itself (in OUT), so that the work folders a
         * killed run left can be told from a running one's and removed. */
        char prefix[64], lockname[80];
        snprintf(prefix, sizeof prefix, "tmp-%s-%s", job_renderer_names[j->renderer], job_role_names[j->role]);
        snprintf(lockname, sizeof lockname, ".%s.lock", prefix);
        lock_fd = job_lock(dest_dir, lockname);
        if (lock_fd >= 0)
            job_clean_own(dest_dir, prefix);
        if (lock_fd < 0 || job_make_work(&c, dest_dir, prefix) != 0)
            job_fail(rec, RUNNER_ERROR, "%s: cannot create a work folder: %s; check --out and its space", dest_dir,
                     strerror(errno));
        else {
            snprintf(work, sizeof work, "%s", c.dir);
            job_render(&c, rec);
        }
    }
    if (rec->status == RUNNER_OK && fileio_copy(c.exr, dest_exr) != 0)
        job_fail(rec, RUNNER_ERROR, "cannot copy %s to %s: %s; check the output folder and its space", c.exr,
                 dest_exr, strerror(errno));
    /* This job's log or none: an older run's must not pass for this one's. */
    unlink(dest_log);
    if (c.log[0] != '\0' && access(c.log, R_OK) == 0)
        fileio_copy(c.log, dest_log);
    if (work[0] != '\0')
        job_remove_tree(work, 0);
    if (lock_fd >= 0)
        close(lock_fd);
    snprintf(rec->exr, sizeof rec->exr, "%s", rec->status == RUNNER_OK ? dest_exr : "");
    snprintf(rec->log, sizeof rec->log, "%s", access(dest_log, R_OK) == 0 ? dest_log : "");
    snprintf(rec->record, sizeof rec->record, "%s", dest_json);
    st = job_write_record(&c, rec, dest_json, key, err, errlen);
    free(env_pixels);
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
