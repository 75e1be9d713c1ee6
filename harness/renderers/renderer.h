/* renderer.h - what one renderer implements: a single render entry, scene in, EXR out.
 *
 * Usage (a renderer's folder, harness/renderers/NAME/):
 *   void NAME_render(const renderer_job *j, renderer_result *r);
 *     writes j->exr (linear float: R, G, B, and what layers it has) and fills r: status and
 *     message (renderer_fail, renderer_fail_run), wall and CPU seconds, the command line, and
 *     in a twin the terms it left out (renderer_leave_out) when j->partial allows it.
 *   Production (harness/jobs.c) and the renderer's unit tests call the same entry through
 *   the table in registry.h; tests may pass the translator's own options in j->options.
 *
 * Paths (one rule for every renderer): a renderer is never handed a path of the user's on its
 * command line or in its scene language. Files it reads are staged in j->dir under fixed ASCII
 * names (renderer_stage: a symlink to the file's absolute path; renderer_write_textures), and
 * POV-Ray runs in j->dir (runner_exec_in) with only those names; Blender reads its paths from
 * the job's JSON (any bytes survive) and takes only absolute paths, after `--`, on its command
 * line. The project's own files (the scripts Blender runs) come from renderer_data_path, so
 * the program works from any folder. Command lines shown to people are quoted for POSIX sh
 * (renderer_command_string).
 *
 * Terms are the rasterizer's AOV layers (diffuse, specular, reflection, emission); their sum
 * is the image. A reference that cannot reproduce a whole term of a twin may leave it out:
 * its image is then the sum of the terms it did render, and the comparison removes the same
 * terms from the other side (harness/compare.c).
 */
#ifndef REFLCHECK_RENDERER_H
#define REFLCHECK_RENDERER_H

#include <stddef.h>

#include "env.h"
#include "mesh.h"
#include "runner.h"
#include "scene.h"
#include "texture.h"

enum {
    RENDERER_TERM_DIFFUSE = 1,
    RENDERER_TERM_SPECULAR = 2,
    RENDERER_TERM_REFLECTION = 4,
    RENDERER_TERM_EMISSION = 8,
    RENDERER_TERM_ALL = 15
};
#define RENDERER_N_TERMS 4

typedef struct {
    const scene *s;
    const mesh *m;          /* the scene's mesh (mesh_build) */
    const env_map *env;     /* the environment, loaded and checked */
    const texture_set *tex; /* the materials' textures, loaded and checked; NULL = none */
    comparison_role role;
    int threads;           /* 0 = all cores */
    int seeds;             /* stochastic renderers: seeds averaged, 0 = 2 */
    int seed;              /* first seed */
    double timeout;        /* seconds before the renderer is killed; 0 = 600 */
    int partial;           /* twin: terms it cannot reproduce may be left out (r->left_out) */
    const char *dir;       /* a private work folder that exists */
    const char *exr;       /* the image to write */
    const char *log;       /* the renderer's console output */
    const char *shown_log; /* the log messages name; NULL = log */
    const char *version;   /* the version line, stored in the image */
    const void *options;   /* the translator's own options struct, NULL = derived from the above */
} renderer_job;

typedef struct {
    runner_status status; /* RUNNER_OK, or why not (RUNNER_MISSING: cannot represent the scene) */
    char message[512];
    double wall_s, cpu_s;
    char command[2048];
    unsigned left_out;               /* RENDERER_TERM_* bits left out of the image */
    char why[RENDERER_N_TERMS][200]; /* per left-out term (bit index), the reason */
} renderer_result;

typedef void (*renderer_render_fn)(const renderer_job *j, renderer_result *r);

/* A reference's physics (model/scene.h, `physics`): what its validate render of s computes,
 * read back from the settings its translator would write, into *rendered. RC_ERR_RANGE with
 * one line in err when it cannot render the scene physically at all (e.g. POV-Ray and a
 * conductor). The render entry refuses a validate whose rendered physics differs from
 * s->physics (renderer_physics_check), so two references of one scene never compute two. */
typedef rc_status (*renderer_physics_fn)(const scene *s, physics *rendered, char *err, size_t errlen);

/* RC_OK when fn renders exactly s->physics, else RC_ERR_RANGE and why ("renders env_diffuse 0,
 * the scene wants 1; ...") in err. fn NULL (the model) is RC_OK. */
rc_status renderer_physics_check(renderer_physics_fn fn, const scene *s, char *err, size_t errlen);

/* The name of term bit i (0..3): diffuse, specular, reflection, emission. */
const char *renderer_term_name(int i);
/* The bit of a term name, 0 if unknown. */
unsigned renderer_term_from_name(const char *name);
/* Sets the result's status and a formatted message. */
void renderer_fail(renderer_result *r, runner_status st, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
/* A renderer process that did not end well: status and a message naming the kind of end,
 * `what` appended inside the parentheses, the first error line of the log (`marker` picks
 * it: a line holding it; NULL = none) and the shown log. */
void renderer_fail_run(renderer_result *r, const runner_result *rr, const char *program, const char *package,
                       const char *what, const char *log, const char *marker, const char *shown_log);
/* Writes every texture of j->tex into j->dir as tex<material>_<slot>.exr (slots diffuse,
 * specular): linear float R, G, B (no alpha), our decoded texels, so that a reference filters exactly
 * what the rasterizer samples. RC_OK, or an error with one line in err. */
rc_status renderer_write_textures(const renderer_job *j, char *err, size_t errlen);
/* Records term bit `term` as left out, with its reason (the first reason is kept). */
void renderer_leave_out(renderer_result *r, unsigned term, const char *why);

/* The absolute path of the project's own file rel ("harness/renderers/cycles/cycles_render.py")
 * into out: under $REFLCHECK_DATA_DIR if set, else the source tree the program was built from
 * (Makefile, -DREFLCHECK_DATA_DIR). 1 if that file is readable, else 0 (out still names it). */
int renderer_data_path(const char *rel, char *out, size_t len);
/* Stages src in j->dir as `name` (letters, digits and ._-+, no leading '-'): a symlink to src's
 * absolute path, so a renderer running in j->dir reads it by that name whatever src's bytes
 * (spaces, quotes, non-ASCII, a leading '-'). RC_OK, or an error with one line in err. */
rc_status renderer_stage(const renderer_job *j, const char *src, const char *name, char *err, size_t errlen);
/* argv as one line for the record, each word quoted for POSIX sh where it needs it. */
void renderer_command_string(const char *const argv[], char *buf, size_t buflen);

#endif
