/* eevee.c - EEVEE jobs: Cycles' job file, the xvfb-run blender command line, the collected EXR. */
#define _XOPEN_SOURCE 700

#include "eevee.h"

#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cJSON.h>

#include "../cycles/cycles.h"
#include "../cycles/cycles_worker.h"
#include "d3d9client.h"
#include "exr.h"
#include "fileio.h"
#include "runner.h"

#define EEVEE_INSTALL            "apt-get install xvfb xauth"
/* worker_pool.py's EEVEE workers: their socket, and the llvmpipe threads they draw with. */
#define EEVEE_WORKER_ENV         "REFLCHECK_EEVEE_WORKER"
#define EEVEE_WORKER_THREADS_ENV "REFLCHECK_EEVEE_WORKER_THREADS"
/* TAA samples at most: EEVEE's error is its approximation's, flat in the sample count
 * (d3d_blinn_phong: 0.0827 at 1, 0.0824 at 16), while a full-size frame of 128 samples took
 * 400 s on llvmpipe, near the 600 s job limit. */
#define EEVEE_TAA_MAX            32

/* Twin: EEVEE computes what our model computes only for Lambert under lamps. 1 and a message
 * naming what it cannot twin, else 0. */
static int eevee_twin_refused(const scene *s, char *why, size_t len)
{
    if (s->env.kind != ENV_NONE && v3_nonzero(s->env.radiance)) {
        snprintf(why, len,
                 "%s: environment: EEVEE lights every diffuse surface with the world (its probe), which our "
                 "model does not; compare EEVEE in validate or agree",
                 s->path);
        return 1;
    }
    for (int i = 0; i < s->n_lights; i++)
        if (s->lights[i].kind == LIGHT_SPOT) {
            snprintf(why, len,
                     "%s: lights[%d]: EEVEE's spot cone is the smoothstep alone, without the cos(angle) factor "
                     "of Cycles' and our smooth profile (measured +3 %% mean); compare EEVEE in validate or agree",
                     s->path, i);
            return 1;
        }
    for (int mi = 0; mi < s->n_materials; mi++) {
        const material *m = &s->materials[mi];
        if (!scene_material_used(s, mi))
            continue;
        if (mesh_material_unnormalised(s, mi)) {
            snprintf(why, len,
                     "%s: materials[%d] '%s': d3d.normalize_normals false on a scaled object (D3D's unnormalised "
                     "normals); EEVEE normalises every normal; compare EEVEE in validate or agree",
                     s->path, mi, m->name);
            return 1;
        }
        if (d3d9client_dissolve_on(m)) {
            snprintf(why, len,
                     "%s: materials[%d] '%s': d3d9client.dissolve (source 000's noise on the reflected direction) has "
                     "no EEVEE twin: no renderer reproduces that noise; compare EEVEE in validate or agree",
                     s->path, mi, m->name);
            return 1;
        }
        if (m->model == MODEL_USER) {
            snprintf(why, len,
                     "%s: materials[%d] '%s': model user (%s) has no EEVEE twin: a twin needs a translator of the "
                     "user's model, which none was given; compare EEVEE in validate or agree",
                     s->path, mi, m->name, m->user.path);
            return 1;
        }
        if (m->model == MODEL_COOK_TORRANCE && (v3_nonzero(m->ct.ks) || m->ct.reflection)) {
            snprintf(why, len,
                     "%s: materials[%d] '%s': EEVEE's glossy lobe is GGX with split-sum and LTC lights, not a "
                     "twin of Beckmann; compare EEVEE in validate or agree",
                     s->path, mi, m->name);
            return 1;
        }
    }
    return 0;
}

/* Validate and agree render the scene's physics manifest: 1 and a message naming what EEVEE
 * cannot render of it, else 0. Lamps per closure it can (light diffuse/specular factors). */
static int eevee_physics_refused(const scene *s, char *why, size_t len)
{
    const physics *ph = &s->physics;
    if (ph->shadows || ph->interreflection || ph->bounces > 1) {
        snprintf(why, len,
                 "%s: physics: shadows, interreflection or bounces above 1; EEVEE renders none of them here "
                 "(the real-time setting): set physics.shadows and physics.interreflection false and "
                 "physics.bounces 1, or leave eevee out of this scene's validate and agree comparisons",
                 s->path);
        return 1;
    }
    if (ph->env_diffuse || s->env.kind == ENV_NONE || !v3_nonzero(s->env.radiance))
        return 0;
    for (int mi = 0; mi < s->n_materials; mi++) {
        const material *m = &s->materials[mi];
        if (scene_material_used(s, mi) && !m->conductor && v3_nonzero(m->albedo)) {
            snprintf(why, len,
                     "%s: physics: env_diffuse false, but EEVEE lights every Lambert term with the world (its "
                     "probe) and materials[%d] '%s' has one; set env_diffuse true to compare EEVEE",
                     s->path, mi, m->name);
            return 1;
        }
    }
    return 0;
}

rc_status eevee_raw_path(const char *out_exr_path, char *buf, size_t len)
{
    size_t n = strlen(out_exr_path);
    if (n >= 4 && (strcmp(out_exr_path + n - 4, ".exr") == 0 || strcmp(out_exr_path + n - 4, ".EXR") == 0))
        n -= 4;
    int k = snprintf(buf, len, "%.*s.eevee.exr", (int)n, out_exr_path);
    return k < 0 || (size_t)k >= len ? RC_ERR_RANGE : RC_OK;
}

static void eevee_timing_path(const char *out_exr_path, char *buf, size_t len)
{
    size_t n = strlen(out_exr_path);
    if (n >= 4 && (strcmp(out_exr_path + n - 4, ".exr") == 0 || strcmp(out_exr_path + n - 4, ".EXR") == 0))
        n -= 4;
    snprintf(buf, len, "%.*s.timing.json", (int)n, out_exr_path);
}

/* Cycles' layers but the object index, which eevee_render.py does not write. */
#define EEVEE_LAYOUT_N (CYCLES_LAYOUT_N - 1)

rc_status eevee_collect(const char *out_exr_path, int keep_raw, char *err, size_t errlen)
{
    char raw[PATH_MAX], tpath[PATH_MAX];
    if (eevee_raw_path(out_exr_path, raw, sizeof raw) != RC_OK) {
        status_message(err, errlen, "%s: path too long", out_exr_path);
        return RC_ERR_RANGE;
    }
    exr_image img;
    rc_status rc = exr_read(raw, &img, err, errlen);
    if (rc != RC_OK)
        return rc;
    exr_channel ch[EEVEE_LAYOUT_N];
    char names[EEVEE_LAYOUT_N][32], rname[64];
    for (int k = 0; k < EEVEE_LAYOUT_N && rc == RC_OK; k++) {
        const char *aov = cycles_layout[k].aov;
        char c = cycles_layout[k].c;
        cycles_channel_name(aov, c, rname, sizeof rname);
        ch[k].data = exr_image_channel(&img, rname);
        if (ch[k].data == NULL) {
            status_message(err, errlen, "%s: channel %s missing; the file is not from eevee_render.py", raw, rname);
            rc = RC_ERR_PARSE;
        }
        cycles_layer_name(k, names[k], sizeof names[k]);
        ch[k].name = names[k];
    }
    if (rc == RC_OK) {
        char build[32] = "", render[32] = "", samples[32] = "";
        eevee_timing_path(out_exr_path, tpath, sizeof tpath);
        char *text = fileio_read_all(tpath, NULL);
        cJSON *timing = text != NULL ? cJSON_Parse(text) : NULL;
        const cJSON *v;
        if (cJSON_IsNumber(v = cJSON_GetObjectItemCaseSensitive(timing, "build_s")))
            snprintf(build, sizeof build, "%.3f", v->valuedouble);
        if (cJSON_IsNumber(v = cJSON_GetObjectItemCaseSensitive(timing, "render_s")))
            snprintf(render, sizeof render, "%.3f", v->valuedouble);
        if (cJSON_IsNumber(v = cJSON_GetObjectItemCaseSensitive(timing, "samples")))
            snprintf(samples, sizeof samples, "%d", v->valueint);
        cJSON_Delete(timing);
        free(text);
        exr_attr at[] = {{"reflcheck.renderer", "eevee"},
                         {"reflcheck.eevee_taa_samples", samples},
                         {"reflcheck.eevee_build_s", build},
                         {"reflcheck.eevee_render_s", render}};
        rc = exr_write(out_exr_path, img.width, img.height, ch, EEVEE_LAYOUT_N, at, 4, err, errlen);
    }
    exr_image_free(&img);
    if (rc == RC_OK && !keep_raw) {
        remove(raw);
        eevee_timing_path(out_exr_path, tpath, sizeof tpath);
        remove(tpath);
    }
    return rc;
}

/* The first line of the log that starts with prefix, into buf ("" if none). */
static void eevee_log_line(const char *log, const char *prefix, char *buf, size_t len)
{
    buf[0] = '\0';
    FILE *f = fopen(log, "r");
    char line[512];
    while (f != NULL && fgets(line, sizeof line, f) != NULL)
        if (strncmp(line, prefix, strlen(prefix)) == 0) {
            line[strcspn(line, "\r\n")] = '\0';
            snprintf(buf, len, "%s", line);
            break;
        }
    if (f != NULL)
        fclose(f);
}

/* What EEVEE cannot render at all: no xvfb-run, a twin or physics it has no translation for,
 * D3D vertex colours. 1 with r failed, else 0. */
static int eevee_refused(const renderer_job *j, const char *xvfb, renderer_result *r)
{
    char where[PATH_MAX], why[600];
    if (!runner_which(xvfb, where, sizeof where)) {
        renderer_fail(r, RUNNER_MISSING, "%s is not installed: EEVEE needs a display; install it with: %s", xvfb,
                      EEVEE_INSTALL);
        return 1;
    }
    if (j->role == ROLE_TWIN && eevee_twin_refused(j->s, why, sizeof why)) {
        renderer_fail(r, RUNNER_MISSING, "eevee cannot twin this scene: %s", why);
        return 1;
    }
    for (int mi = 0; mi < j->s->n_materials; mi++)
        if (mesh_material_vertex_coloured(j->s, j->m, mi)) {
            /* cycles_write_job would send the colour attribute; eevee_render.py does not read it. */
            renderer_fail(r, RUNNER_MISSING,
                          "eevee cannot represent this scene: materials[%d] '%s': D3D vertex colours "
                          "(d3d.colour_vertex) are not translated to EEVEE; set colour_vertex false",
                          mi, j->s->materials[mi].name);
            return 1;
        }
    if (j->role != ROLE_TWIN && eevee_physics_refused(j->s, why, sizeof why)) {
        renderer_fail(r, RUNNER_MISSING, "eevee cannot render this scene's physics: %s", why);
        return 1;
    }
    return 0;
}

/* The scene as Cycles' job file (job, in j->dir): 1 written, else 0 with r failed. */
static int eevee_write_job(const renderer_job *j, const eevee_options *o, const char *job, renderer_result *r)
{
    char err[1024];
    /* Agree: EEVEE renders the physical material, as against Cycles; the other side (our
     * model) is the second approximation of it. image.samples auto (0) sizes Cycles' noise;
     * EEVEE's TAA is no noise, so it takes its most. */
    cycles_options co = {.role = j->role == ROLE_TWIN ? ROLE_TWIN : ROLE_VALIDATE,
                         .samples =
                             o->samples > 0
                                 ? o->samples
                                 : (j->s->samples > 0 && j->s->samples < EEVEE_TAA_MAX ? j->s->samples : EEVEE_TAA_MAX),
                         .n_seeds = 1,
                         .width = o->width,
                         .height = o->height,
                         .partial = j->partial,
                         .left_out = r};
    rc_status st = cycles_write_job(j->s, j->m, &co, job, err, sizeof err);
    if (st != RC_OK) {
        r->left_out = 0;
        if (st == RC_ERR_RANGE)
            renderer_fail(r, RUNNER_MISSING, "eevee cannot represent this scene: %s", err);
        else
            renderer_fail(r, RUNNER_ERROR, "cannot write the EEVEE job: %s", err);
        return 0;
    }
    return 1;
}

/* The command line and the strings it points into. */
typedef struct {
    const char *argv[24];
    int job_arg; /* argv[job_arg] is the job file */
    char display[32], threads[48], script[PATH_MAX];
} eevee_argv;

/* xvfb-run [env LP_NUM_THREADS=n] blender -b ... -P eevee_render.py -- JOB OUT: 1 built, else
 * 0 with r failed (the script missing). */
static int eevee_command(const renderer_job *j, const eevee_options *o, const char *xvfb, const char *job,
                         eevee_argv *a, renderer_result *r)
{
    /* xvfb-run -a searches upwards from -n for a free display: starting from a number of our
     * own keeps two jobs started at once (make -j2) from racing for the same one. */
    snprintf(a->display, sizeof a->display, "%d", 100 + (int)(getpid() % 800));
    int n = 0;
    a->argv[n++] = xvfb;
    a->argv[n++] = "-a";
    a->argv[n++] = "-n";
    a->argv[n++] = a->display;
    a->argv[n++] = "-s";
    a->argv[n++] = "-screen 0 640x480x24";
    if (j->threads > 0) {
        /* llvmpipe draws with LP_NUM_THREADS threads, unset one per core (0 would mean none). */
        snprintf(a->threads, sizeof a->threads, "LP_NUM_THREADS=%d", j->threads);
        a->argv[n++] = "env";
        a->argv[n++] = a->threads;
    }
    a->argv[n++] = o->blender ? o->blender : "blender";
    a->argv[n++] = "-b";
    a->argv[n++] = "--factory-startup";
    /* without this a Python exception still exits 0 */
    a->argv[n++] = "--python-exit-code";
    a->argv[n++] = "1";
    a->argv[n++] = "-P";
    if (o->script == NULL &&
        !renderer_data_path("harness/renderers/eevee/eevee_render.py", a->script, sizeof a->script)) {
        renderer_fail(r, RUNNER_ERROR, "eevee: %s is missing; set REFLCHECK_DATA_DIR to the reflcheck source tree",
                      a->script);
        return 0;
    }
    a->argv[n++] = o->script ? o->script : a->script;
    a->argv[n++] = "--";
    a->job_arg = n;
    a->argv[n++] = job;
    a->argv[n++] = j->exr;
    a->argv[n] = NULL;
    return 1;
}

/* The socket of a running EEVEE worker (worker_pool.py --eevee-threads) to hand the job to, or
 * NULL: none runs, the job names its own Blender or script, or it asks for other threads than
 * the workers' llvmpipe draws with (their LP_NUM_THREADS is fixed when they start). */
static const char *eevee_worker(const renderer_job *j, const eevee_options *o)
{
    const char *sock = getenv(EEVEE_WORKER_ENV);
    const char *threads = getenv(EEVEE_WORKER_THREADS_ENV);
    if (sock == NULL || sock[0] == '\0' || threads == NULL || o->blender != NULL || o->script != NULL)
        return NULL;
    char *end;
    long n = strtol(threads, &end, 10);
    return *end == '\0' && n > 0 && n == j->threads ? sock : NULL;
}

/* Runs the command and collects Blender's image into j->exr; r holds the outcome. 1 when
 * Blender wrote its image (collected or not), 0 when it did not: the job then stays for a look. */
static int eevee_run(const renderer_job *j, const eevee_options *o, const eevee_argv *a, renderer_result *r)
{
    char err[1024];
    renderer_command_string(a->argv, r->command, sizeof r->command);
    runner_result rr;
    const char *worker = eevee_worker(j, o);
    if (cycles_worker_run(worker, a->argv[a->job_arg], j->exr, j->threads, j->timeout, j->log, &rr)) {
        char via[2100];
        snprintf(via, sizeof via, "(blender worker %s) %s", worker, r->command);
        snprintf(r->command, sizeof r->command, "%s", via);
    } else
        runner_exec(a->argv, j->timeout > 0 ? j->timeout : 600.0, j->log, &rr);
    r->wall_s = rr.wall_s;
    r->cpu_s = rr.cpu_s;
    if (rr.status != RUNNER_OK) {
        char line[300];
        eevee_log_line(j->log, "xvfb-run: error", line, sizeof line);
        if (line[0] != '\0' && rr.status == RUNNER_FAILED) {
            renderer_fail(r, RUNNER_MISSING, "no display for EEVEE (%s); install Xvfb with: %s", line, EEVEE_INSTALL);
            return 0;
        }
        renderer_fail_run(r, &rr, "blender", "blender", " under xvfb-run", j->log, "error:", j->shown_log);
        return 0;
    }
    char raw[PATH_MAX];
    if (eevee_raw_path(j->exr, raw, sizeof raw) != RC_OK || access(raw, R_OK) != 0) {
        renderer_fail(r, RUNNER_FAILED, "blender under xvfb-run wrote no image %s; see %s", raw,
                      j->shown_log ? j->shown_log : j->log);
        return 0;
    }
    rc_status st = eevee_collect(j->exr, o->keep_raw, err, sizeof err);
    if (st != RC_OK)
        renderer_fail(r, st == RC_ERR_NOMEM || st == RC_ERR_IO ? RUNNER_ERROR : RUNNER_FAILED, "%s: %s",
                      st == RC_ERR_IO ? "cannot write the EEVEE image" : "eevee output unreadable", err);
    return 1;
}

void eevee_render_job(const renderer_job *j, renderer_result *r)
{
    eevee_options o = {0};
    if (j->options != NULL)
        o = *(const eevee_options *)j->options;
    const char *xvfb = o.xvfb_run ? o.xvfb_run : "xvfb-run";
    char job[1100];
    if (eevee_refused(j, xvfb, r))
        return;
    snprintf(job, sizeof job, "%s/job.json", j->dir);
    if (!eevee_write_job(j, &o, job, r))
        return;
    eevee_argv a;
    if (!eevee_command(j, &o, xvfb, job, &a, r))
        return;
    if (eevee_run(j, &o, &a, r) && !o.keep_raw)
        remove(job);
}
