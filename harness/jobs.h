/* jobs.h - one render job: a scene in one renderer and role, cached, timed, recorded.
 *
 * Usage:
 *   job_spec j = {.scene_path = "scenes/x.yaml", .renderer = registry_find("povray"), .role = ROLE_TWIN,
 *                 .variant = JOB_SMALL, .out_dir = "reports/runs/r1", .cache_dir = "reports/cache"};
 *   job_record r;
 *   rc_status st = job_run(&j, &r, err, sizeof err);
 *   exit status: job_exit_status(st, &r)     0 ok or skipped, 1 anything else, 2 bad input
 * Results land in OUT/<scene>/<renderer>-<role>.exr with a record .json (status, wall and CPU
 * time, renderer version, command, cache key, terms_left_out, slurm: {job_id, node} or null)
 * and the renderer's .log.
 * The job asks the renderer table (harness/renderers/registry.h) for everything about the
 * renderer: its program, package, version and render entry. A twin lets the renderer
 * leave out whole terms it cannot reproduce; the record names them (terms_left_out).
 *
 * Returns RC_OK once the record is written, whatever the renderer did; r.status says what:
 *   ok; skipped (RUNNER_MISSING) only when the renderer is not installed or cannot represent
 *   the scene (the message says which, with the install command); failed (non-zero exit, an
 *   output image that is unreadable or the wrong size); crashed; timeout; error (our side:
 *   a file or folder we could not create or write, a full disk, the cache lock).
 * Returns an error with nothing written when the input is bad (r.bad_input = 1: the scene
 * file, a mesh or environment image it references, unreadable or invalid; the environment is
 * checked here for every renderer) or when the output folder or record cannot be written
 * (r.bad_input = 0).
 *
 * Cache: an entry CACHE/<key>/ is keyed by FNV-1a 64 over the scene file's bytes, the bytes of
 * every file it references (meshes, environment image, a user model's shared object), the options that reach the image
 * (renderer, role, variant, size, k, samples, seeds, seed, tessellation, per-vertex), the
 * renderer's version line and executable (path, size, times), and the code the render depends
 * on (the files of the scene pipeline and the renderer's translator as the build's objects and
 * .d files name them, BUILD/key-sources/<renderer>.list, hashed in the source tree; for an
 * in-process renderer or without the tree, the reflcheck binary), and the terms the
 * renderer left out are kept with the entry. Threads, timeout and tag are not in it. A job takes an exclusive flock on
 * CACHE/<key>.lock while it checks, renders and publishes, renders into a private CACHE/tmp-<key>-XXXXXX and publishes
 * it by rename, so runs sharing a cache render each key once and never see a half entry; a killed run's lock goes with
 * it and its work folder is removed by the next job on that key. Only ok renders are cached. Without a cache the work
 * folder is private too (OUT/<scene>/tmp-<renderer>-<role>-
 * XXXXXX, under a lock OUT/<scene>/.tmp-<renderer>-<role>.lock) and removed afterwards, or by
 * the next run of the job if this one was killed.
 * Files in OUT are written under a temporary name and renamed, so a killed run leaves no half
 * file.
 */
#ifndef REFLCHECK_JOBS_H
#define REFLCHECK_JOBS_H

#include <stddef.h>
#include "env.h"
#include "renderers/registry.h"
#include "runner.h"
#include "scene.h"
#include "status.h"

typedef enum { JOB_FULL = 0, JOB_SMALL = 1 } job_variant;

typedef struct {
    const char *scene_path;
    int renderer;         /* a row of the renderer table (registry_find) */
    comparison_role role; /* raster: ROLE_TWIN switches Cook-Torrance to Smith G, F = 1 */
    job_variant variant;
    const char *out_dir;
    const char *cache_dir; /* NULL = no cache */
    double timeout_s;      /* 0 = the scene's timeout */
    int threads;           /* 0 = all cores */
    int seeds;             /* Cycles seeds, 0 = 2 */
    int seed;              /* Cycles first seed, default 0: sweeps use seeds disjoint from
                              their reference's */
    /* Quality overrides for error-against-time sweeps (0 = the scene's or variant's). With any
     * set, outputs are named <renderer>-<role>-<tag> so sweeps do not overwrite each other. */
    int supersample, samples, tessellation, per_vertex;
    const char *tag;
    /* The batch scheduler's id of this job (Slurm: "JOB", "ARRAY_TASK" or "JOB.STEP"), kept in
     * the record; NULL = from the environment (SLURM_ARRAY_JOB_ID, SLURM_ARRAY_TASK_ID,
     * SLURM_JOB_ID, SLURM_STEP_ID), none when run outside Slurm. */
    const char *slurm_job;
    /* A job that ended without writing its own record (Slurm cancelled it, timed it out or lost
     * its node): record_only writes the record with record_status and record_message and
     * renders nothing; record_log (the scheduler's output file of the job) becomes its log. */
    int record_only;
    runner_status record_status;
    const char *record_message, *record_log;
    /* 1: when OUT already holds this job's record, ok, of the same cache key, with its image,
     * hand that record back (rec.reused = 1) and write nothing: a reader of a run's images (the
     * fit) keeps the record of the job that made them, its Slurm id and times included. */
    int reuse_record;
} job_spec;

typedef struct {
    runner_status status;
    char message[512];
    char exr[1024], record[1024], log[1024];
    double wall_s, cpu_s;
    int cached;
    int reused;    /* the record already in OUT, handed back (job_spec.reuse_record) */
    int bad_input; /* job_run failed on an input the user gave: exit status 2 */
} job_record;

extern const char *const job_role_names[3];

int job_role_from_name(const char *name); /* -1 if unknown */
/* Applies the variant's image size and samples to s. */
void job_apply_variant(scene *s, job_variant v);
/* The files of a job: OUT/<scene>/<renderer>-<role>.<ext>. */
void job_output_path(const char *out_dir, const char *scene_name, int renderer, comparison_role role, const char *ext,
                     char *buf, size_t len);
/* Applies a spec's quality overrides to s (tessellation of every object, per-vertex shading
 * of every D3D material, supersample, samples). */
void job_apply_overrides(scene *s, const job_spec *j);
rc_status job_run(const job_spec *j, job_record *rec, char *err, size_t errlen);
/* A cube map's equirectangular conversion (frame_env_cube_write's bytes) kept in the cache:
 * CACHE/env/cube-<key>.exr, keyed by the faces' texels and the renderer's key sources (the
 * converting and writing code among them), written once under the key's lock and published by
 * rename, so every job of the same faces reads one file instead of converting the cube again
 * (64-texel faces: 4096 x 2048 texels, ~100 MB, ~1.8 CPU-s). A kept file whose size is not the
 * one written (path.bytes) is written again. Its path goes to path (len bytes). The environment
 * variable REFLCHECK_ENV_CACHE, when set, names the folder instead of CACHE/env, so that jobs of
 * several caches share the conversions (the nightly points its renders and its sweep at
 * CACHE/env). renderer: a row of the renderer table (registry_find). */
rc_status job_env_cube_file(const char *cache_dir, int renderer, const env_map *cube, char *path, size_t len, char *err,
                            size_t errlen);
/* mkdir -p: path and every missing parent (0755); 0, or -1 with errno set. */
int job_mkdirs(const char *path);
/* The exit status of `reflcheck run` for job_run's result (README, "The CLI": exit status). */
int job_exit_status(rc_status st, const job_record *rec);

#endif
