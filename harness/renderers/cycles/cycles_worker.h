/* cycles_worker.h - the Blender step of a Cycles job, handed to a running Blender worker.
 *
 * Usage (cycles_render_job does this; the pool is harness/renderers/cycles/worker_pool.py):
 *   runner_result rr;
 *   if (!cycles_worker_run(getenv(CYCLES_WORKER_ENV), "w/job.json", "w/out.exr", 1, 600.0,
 *                          "w/render.log", &rr))
 *       runner_exec(blender argv, 600.0, "w/render.log", &rr);    no worker: Blender as usual
 * A worker (worker.py, one Blender process that renders job after job) answers on a Unix
 * socket whose path the environment variable REFLCHECK_CYCLES_WORKER holds. The job runs there
 * as cycles_render.py runs it in a fresh Blender: the same files beside out.exr, the same log,
 * failure as exit status 1. rr is filled like runner_exec fills it: RUNNER_OK, RUNNER_FAILED
 * (exit_code 1), RUNNER_CRASHED (the worker died), RUNNER_TIMEOUT (no answer within timeout_s
 * of the worker taking the job: we hang up and the worker ends itself); wall and CPU seconds
 * are the worker's for this job alone, without Blender's start-up or the wait for a free worker.
 * Returns 0 with nothing done when socket_path is NULL or empty or nothing listens there.
 */
#ifndef REFLCHECK_CYCLES_WORKER_H
#define REFLCHECK_CYCLES_WORKER_H

#include "runner.h"

#define CYCLES_WORKER_ENV "REFLCHECK_CYCLES_WORKER"

int cycles_worker_run(const char *socket_path, const char *job_json, const char *out_exr, int threads, double timeout_s,
                      const char *log, runner_result *rr);

#endif
