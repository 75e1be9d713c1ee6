/* eevee.h - a reflcheck scene rendered by Blender 3.4 EEVEE (a real-time engine: the
 * approximation judged), headless under Xvfb, and the render entry of the renderer table.
 *
 * Usage:
 *   eevee_options o = {.samples = 16};                          zero = defaults (below)
 *   renderer_job j = {.s = &scn, .m = &msh, .role = ROLE_VALIDATE, .dir = "work",
 *                     .exr = "out.exr", .log = "out.log", .options = &o};
 *   renderer_result r = {0};
 *   eevee_render_job(&j, &r);           job.json, xvfb-run blender, collect: what production runs
 * Under worker_pool.py --eevee-threads T (REFLCHECK_EEVEE_WORKER set), a job of T threads hands
 * its Blender step to a running Blender under the pool's Xvfb instead (eevee_worker.py): the
 * same image, bit for bit (tests/eevee_worker.sh), without Blender's and Xvfb's start-up.
 *
 * The scene translation is Cycles' (cycles_write_job and cycles_render.py): EEVEE renders the
 * same Blender scene as Cycles and only the engine differs (eevee_render.py sets it up).
 *   validate, agree: the material's physical intent (Cycles' validate recipe) in both roles:
 *             against Cycles it measures EEVEE's own approximation error, against the raster
 *             two approximations of one material side by side.
 *   twin:     Cycles' twin recipe, only where EEVEE computes the same thing as our model:
 *             Lambert (Diffuse BSDF) under point, spot and sun lights with no environment; the
 *             calibration. A glossy lobe (EEVEE: GGX, split-sum), a mirror or an environment
 *             (EEVEE: pre-filtered probes) is refused, RUNNER_MISSING, naming the material.
 * EEVEE draws one frame of TAA samples (the scene's samples, at most 32: its error does not
 * move with them); it is deterministic, so seeds do not reach the image and there are no
 * var.* layers.
 *
 * Out: j->exr, 32-bit float: R G B A, diffuse.RGB, specular.RGB, reflection.RGB,
 * emission.RGB, background.RGB, coverage (no object layer: EEVEE has no index pass; masks
 * come from the rasterizer). With no xvfb-run on PATH, or an Xvfb that cannot start, the job
 * is RUNNER_MISSING with the install command (the comparison is skipped, as for a missing
 * renderer).
 */
#ifndef REFLCHECK_EEVEE_H
#define REFLCHECK_EEVEE_H

#include <stddef.h>

#include "../renderer.h"
#include "mesh.h"
#include "scene.h"
#include "status.h"

typedef struct {
    int samples;          /* TAA render samples; 0 = the scene's samples, at most 32 */
    int width, height;    /* 0 = the scene's */
    int keep_raw;         /* nonzero: keep OUT.eevee.exr, OUT.timing.json and the job */
    const char *blender;  /* NULL = "blender" on PATH */
    const char *xvfb_run; /* NULL = "xvfb-run" on PATH */
    const char *script;   /* NULL = "harness/renderers/eevee/eevee_render.py" */
} eevee_options;

/* The raw file eevee_render.py writes: OUT without ".exr" + ".eevee.exr". */
rc_status eevee_raw_path(const char *out_exr_path, char *buf, size_t len);

/* Reads the raw file, writes out_exr_path with reflcheck's channel names and the timing. */
rc_status eevee_collect(const char *out_exr_path, int keep_raw, char *err, size_t errlen);

/* The render entry (renderer.h). */
void eevee_render_job(const renderer_job *j, renderer_result *r);

#endif
