/* renderer.h - what one renderer implements: a single render entry, scene in, EXR out.
 *
 * Usage (a renderer's folder, harness/renderers/NAME/):
 *   void NAME_render(const renderer_job *j, renderer_result *r);
 *     writes j->exr (linear float: R, G, B, and what layers it has) and fills r: status and
 *     message (renderer_fail, renderer_fail_run), wall and CPU seconds, the command line.
 *   Production (harness/jobs.c) and the renderer's unit tests call the same entry through
 *   the table in registry.h; tests may pass the translator's own options in j->options.
 */
#ifndef REFLCHECK_RENDERER_H
#define REFLCHECK_RENDERER_H

#include <stddef.h>

#include "env.h"
#include "mesh.h"
#include "runner.h"
#include "scene.h"

typedef struct {
    const scene *s;
    const mesh *m;            /* the scene's mesh (mesh_build) */
    const env_map *env;       /* the environment, loaded and checked */
    comparison_role role;
    int threads;              /* 0 = all cores */
    int seeds;                /* stochastic renderers: seeds averaged, 0 = 2 */
    int seed;                 /* first seed */
    double timeout;           /* seconds before the renderer is killed; 0 = 600 */
    int partial;              /* twin: terms it cannot reproduce may be left out */
    const char *dir;          /* a private work folder that exists */
    const char *exr;          /* the image to write */
    const char *log;          /* the renderer's console output */
    const char *shown_log;    /* the log messages name; NULL = log */
    const char *version;      /* the version line, stored in the image */
    const void *options;      /* the translator's own options struct, NULL = derived from the above */
} renderer_job;

typedef struct {
    runner_status status;     /* RUNNER_OK, or why not (RUNNER_MISSING: cannot represent the scene) */
    char message[512];
    double wall_s, cpu_s;
    char command[2048];
} renderer_result;

typedef void (*renderer_render_fn)(const renderer_job *j, renderer_result *r);

/* Sets the result's status and a formatted message. */
void renderer_fail(renderer_result *r, runner_status st, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
/* A renderer process that did not end well: status and a message naming the kind of end,
 * `what` appended inside the parentheses, the first error line of the log (`marker` picks
 * it: a line holding it; NULL = none) and the shown log. */
void renderer_fail_run(renderer_result *r, const runner_result *rr, const char *program, const char *package,
                       const char *what, const char *log, const char *marker, const char *shown_log);
#endif
