/* runner.h - run an external renderer as its own process, with a time limit and a log.
 *
 * Usage:
 *   const char *argv[] = {"povray", "+Iscene.pov", ..., NULL};
 *   runner_result r;
 *   runner_exec(argv, 120.0, "job.log", &r);        returns r.status, never aborts the caller
 *   if (r.status != RUNNER_OK) ... runner_status_name(r.status), r.exit_code, r.signal
 *   runner_where w = {.dir = "work", .err_log = "job.err"};
 *   runner_exec_in(argv, &w, 120.0, "job.log", &r);  the same, run in folder w.dir, stderr apart
 *   runner_version("povray", buf, sizeof buf, why, sizeof why);
 *                                                   RUNNER_OK and the version line; RUNNER_MISSING
 *                                                   only when not on PATH; else why it is broken
 *   runner_which("povray", path, sizeof path);      the executable PATH finds, 1 if found
 * The child gets its own process group, so a timeout kills the renderer and every process
 * it started (SIGTERM, then SIGKILL after 2 s). stdout and stderr go to the log file.
 * wall_s is elapsed time, cpu_s the user + system time of the child and its children.
 * No renderer outlives us: while runner_exec waits, SIGINT, SIGTERM and SIGHUP (unless
 * ignored) are forwarded to the child's group (SIGTERM, 2 s, SIGKILL) before they end us with
 * their usual effect, and the child itself gets SIGKILL when we die any other way, SIGKILL
 * included (PR_SET_PDEATHSIG; processes the renderer started in its group are not covered in
 * that case). After the child exits, what it left running in its group is killed.
 * Statuses: RUNNER_MISSING only when the program is not on PATH (or vanished before exec);
 * exit status 127 from the program itself is RUNNER_FAILED, and an exec that fails for
 * another reason is RUNNER_FAILED with exec_errno set.
 */
#ifndef REFLCHECK_RUNNER_H
#define REFLCHECK_RUNNER_H

#include <stddef.h>

typedef enum {
    RUNNER_OK = 0,
    RUNNER_MISSING, /* the program is not installed (not on PATH) */
    RUNNER_FAILED,  /* exited with a non-zero status */
    RUNNER_CRASHED, /* killed by a signal it did not get from us */
    RUNNER_TIMEOUT, /* exceeded the time limit and was killed */
    RUNNER_ERROR    /* could not start (fork, log file) */
} runner_status;

typedef struct {
    runner_status status;
    int exit_code;
    int signal;
    double wall_s, cpu_s;
    long max_rss_kb;
    int exec_errno; /* why the program could not be started, 0 if it was */
} runner_result;

/* 1 if `program` is an executable on PATH (or a path that is executable). */
int runner_available(const char *program);
/* Writes the path of the executable `program` names (PATH search) to out; 0 if none. */
int runner_which(const char *program, char *out, size_t outlen);
runner_status runner_exec(const char *const argv[], double timeout_s, const char *log_path, runner_result *r);

typedef struct {
    const char *dir;     /* the child's working folder, NULL = ours (a renderer that gets only
                            names relative to its work folder: harness/renderers/renderer.h) */
    const char *err_log; /* the child's stderr apart from log_path, NULL = into log_path */
} runner_where;

/* runner_exec with a working folder and stderr apart; where NULL is runner_exec. A folder the
 * child cannot enter is RUNNER_FAILED with exec_errno set. */
runner_status runner_exec_in(const char *const argv[], const runner_where *where, double timeout_s,
                             const char *log_path, runner_result *r);
const char *runner_status_name(runner_status s);
/* Runs `program --version` and keeps the line that names the version in out. Returns
 * RUNNER_OK; RUNNER_MISSING only when the program is not on PATH or not executable; otherwise
 * the program is there but broken (exits non-zero: RUNNER_FAILED; a signal: RUNNER_CRASHED;
 * no version line: RUNNER_FAILED; ...) and why says so in one line: the exit status or signal
 * and the first line of its stderr. */
runner_status runner_version(const char *program, char *out, size_t outlen, char *why, size_t whylen);

#endif
