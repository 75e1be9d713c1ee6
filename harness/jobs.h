/* jobs.h - one render job: a scene in one renderer and role, cached, timed, recorded.
 *
 * Usage:
 *   job_spec j = {.scene_path = "scenes/x.yaml", .renderer = RENDERER_POVRAY, .role = ROLE_TWIN,
 *                 .variant = JOB_SMALL, .out_dir = "reports/runs/r1", .cache_dir = "reports/cache"};
 *   job_record r;
 *   job_run(&j, &r, err, sizeof err);
 * Results land in OUT/<scene>/<renderer>-<role>.exr with a record .json (status, wall and CPU
 * time, renderer version, command, cache key) and the renderer's .log. The work is keyed by a
 * hash of (scene bytes, environment image, renderer, version, role, size, samples, and the code
 * the render depends on: translator and scene-pipeline sources for POV-Ray and Cycles, the
 * reflcheck binary for our rasterizer), so an unchanged job is copied from the cache.
 * A renderer that is missing, fails, crashes, times out or writes an unreadable image is a
 * record with that status, not an error: job_run returns RC_OK after writing the record.
 * Only bad input (scene file, options) and I/O on our own files return an error.
 * Files are written under a temporary name and renamed, so a killed run leaves no half file.
 */
#ifndef REFLCHECK_JOBS_H
#define REFLCHECK_JOBS_H

#include <stddef.h>
#include "runner.h"
#include "scene.h"
#include "status.h"

typedef enum { JOB_FULL = 0, JOB_SMALL = 1 } job_variant;

typedef struct {
    const char *scene_path;
    renderer_id renderer;
    comparison_role role;     /* raster: ROLE_TWIN switches Cook-Torrance to Smith G, F = 1 */
    job_variant variant;
    const char *out_dir;
    const char *cache_dir;    /* NULL = no cache */
    double timeout_s;         /* 0 = the scene's timeout */
    int threads;              /* 0 = all cores */
    int seeds;                /* Cycles seeds, 0 = 2 */
    int seed;                 /* Cycles first seed, default 0: sweeps use seeds disjoint from
                                 their reference's */
    /* Quality overrides for error-against-time sweeps (0 = the scene's or variant's). With any
     * set, outputs are named <renderer>-<role>-<tag> so sweeps do not overwrite each other. */
    int supersample, samples, tessellation, per_vertex;
    const char *tag;
} job_spec;

typedef struct {
    runner_status status;
    char message[512];
    char exr[1024], record[1024], log[1024];
    double wall_s, cpu_s;
    int cached;
} job_record;

extern const char *const job_renderer_names[RENDERER_COUNT];
extern const char *const job_role_names[3];

int job_renderer_from_name(const char *name);   /* -1 if unknown */
int job_role_from_name(const char *name);       /* -1 if unknown */
/* Applies the variant's image size and samples to s. */
void job_apply_variant(scene *s, job_variant v);
/* The files of a job: OUT/<scene>/<renderer>-<role>.<ext>. */
void job_output_path(const char *out_dir, const char *scene_name, renderer_id r, comparison_role role,
                     const char *ext, char *buf, size_t len);
/* Applies a spec's quality overrides to s (tessellation of every object, per-vertex shading
 * of every D3D material, supersample, samples). */
void job_apply_overrides(scene *s, const job_spec *j);
rc_status job_run(const job_spec *j, job_record *rec, char *err, size_t errlen);

#endif
