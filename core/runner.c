#include "runner.h"

#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/time.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

/* wait4 is BSD/GNU, not POSIX; declared here to keep the project's POSIX feature level. */
pid_t wait4(pid_t pid, int *status, int options, struct rusage *rusage);

static double runner_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int runner_which(const char *program, char *out, size_t outlen)
{
    if (outlen > 0)
        out[0] = '\0';
    if (strchr(program, '/') != NULL) {
        if (access(program, X_OK) != 0)
            return 0;
        snprintf(out, outlen, "%s", program);
        return 1;
    }
    const char *path = getenv("PATH");
    if (path == NULL)
        return 0;
    char dir[4096];
    while (*path) {
        size_t n = strcspn(path, ":");
        if (n > 0 && n < sizeof dir - 1) {
            char full[4352];
            memcpy(dir, path, n);
            dir[n] = '\0';
            snprintf(full, sizeof full, "%s/%s", dir, program);
            struct stat st;
            if (stat(full, &st) == 0 && S_ISREG(st.st_mode) && access(full, X_OK) == 0) {
                snprintf(out, outlen, "%s", full);
                return 1;
            }
        }
        path += n + (path[n] == ':');
    }
    return 0;
}

int runner_available(const char *program)
{
    char full[4352];
    return runner_which(program, full, sizeof full);
}

const char *runner_status_name(runner_status s)
{
    switch (s) {
    case RUNNER_OK: return "ok";
    case RUNNER_MISSING: return "skipped";
    case RUNNER_FAILED: return "failed";
    case RUNNER_CRASHED: return "crashed";
    case RUNNER_TIMEOUT: return "timeout";
    case RUNNER_ERROR: return "error";
    }
    return "error";
}

/* The process group of the renderer runner_exec is waiting for (0: none). A signal handler
 * reads it, hence sig_atomic_t (a pid_t fits: both are int on Linux). */
static volatile sig_atomic_t runner_group;

/* The grace a renderer gets after SIGTERM before its group gets SIGKILL, in 10 ms steps: the
 * same 2 s a timeout gives, enough for Blender to remove its temporary files. */
#define RUNNER_GRACE_STEPS 200

/* Ends the running renderer's whole group, then lets the signal end us as it would have
 * without the handler. Only async-signal-safe calls (kill, waitpid, nanosleep, sigaction,
 * raise). */
static void runner_on_signal(int sig)
{
    pid_t g = (pid_t)runner_group;
    if (g > 0) {
        kill(-g, SIGTERM);
        for (int i = 0; i < RUNNER_GRACE_STEPS; i++) {
            struct timespec nap = {0, 10 * 1000 * 1000};
            nanosleep(&nap, NULL);
            int st;
            waitpid(g, &st, WNOHANG); /* a zombie leader would keep the group alive */
            if (kill(-g, 0) != 0)
                break;
        }
        kill(-g, SIGKILL);
    }
    struct sigaction dfl;
    memset(&dfl, 0, sizeof dfl);
    dfl.sa_handler = SIG_DFL;
    sigemptyset(&dfl.sa_mask);
    sigaction(sig, &dfl, NULL);
    raise(sig); /* pending until the handler returns, then the default action ends us */
}

/* The signals that end a run from outside (Ctrl-C, kill, a closed terminal) and that the
 * renderer, in its own process group, would not get. */
static const int runner_forwarded[] = {SIGINT, SIGTERM, SIGHUP};
#define RUNNER_N_FORWARDED (sizeof runner_forwarded / sizeof runner_forwarded[0])

static void runner_forward_signals(struct sigaction old[RUNNER_N_FORWARDED])
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = runner_on_signal;
    sigemptyset(&sa.sa_mask);
    for (size_t i = 0; i < RUNNER_N_FORWARDED; i++)
        sigaddset(&sa.sa_mask, runner_forwarded[i]);
    for (size_t i = 0; i < RUNNER_N_FORWARDED; i++) {
        sigaction(runner_forwarded[i], NULL, &old[i]);
        /* An ignored signal (nohup's SIGHUP) stays ignored: it would not have ended us. */
        if (old[i].sa_handler != SIG_IGN)
            sigaction(runner_forwarded[i], &sa, NULL);
    }
}

static void runner_restore_signals(const struct sigaction old[RUNNER_N_FORWARDED])
{
    for (size_t i = 0; i < RUNNER_N_FORWARDED; i++)
        sigaction(runner_forwarded[i], &old[i], NULL);
}

/* Kills the group and reaps the leader, for the error paths that stop waiting early. */
static void runner_kill_group(pid_t pid)
{
    kill(-pid, SIGKILL);
    int st;
    while (waitpid(pid, &st, 0) < 0 && errno == EINTR)
        continue;
}

/* In the child: own process group, log as stdout, errlog (or log) as stderr, no stdin, killed
 * when we die, the working folder dir (NULL = ours); then the program, by the full path the
 * parent resolved (a relative argv[0] would not survive the chdir). An exec failure is reported
 * through errfd (close-on-exec, so a successful exec closes it silently). */
__attribute__((noreturn)) static void runner_child(const char *const argv[], const char *full, const char *dir, int log,
                                                   int errlog, int errfd, pid_t parent)
{
    setpgid(0, 0);
    /* SIGKILL with us even if we are killed with SIGKILL ourselves and cannot forward it. */
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    /* We may have died before prctl: then the child was already reparented. */
    if (getppid() != parent)
        _exit(127);
    dup2(log, STDOUT_FILENO);
    dup2(errlog >= 0 ? errlog : log, STDERR_FILENO);
    int devnull = open("/dev/null", O_RDONLY);
    if (devnull >= 0)
        dup2(devnull, STDIN_FILENO);
    int e = 0;
    if (dir != NULL && chdir(dir) != 0)
        e = errno;
    /* execv takes char *const[]; the strings are not modified. */
    if (e == 0) {
        execv(full, (char *const *)(uintptr_t)argv);
        e = errno;
    }
    fprintf(stderr, "reflcheck: could not start %s%s%s: %s\n", argv[0], dir != NULL ? " in " : "", dir ? dir : "",
            strerror(e));
    ssize_t w = write(errfd, &e, sizeof e);
    (void)w;
    _exit(127);
}

/* The program's full path, absolute so that a chdir in the child keeps it; 0 if not found. */
static int runner_resolve(const char *program, char *full, size_t len)
{
    char found[4352];
    if (!runner_which(program, found, sizeof found))
        return 0;
    if (found[0] == '/') {
        snprintf(full, len, "%s", found);
        return 1;
    }
    char cwd[4096];
    if (getcwd(cwd, sizeof cwd) == NULL)
        return 0;
    return (size_t)snprintf(full, len, "%s/%s", cwd, found) < len;
}

runner_status runner_exec(const char *const argv[], double timeout_s, const char *log_path, runner_result *r)
{
    return runner_exec_in(argv, NULL, timeout_s, log_path, r);
}

/* The child's output files and the pipe its exec failure comes back through. */
typedef struct {
    int log, errlog; /* errlog -1: stderr goes with stdout to log */
    int errpipe[2];
} runner_fds;

/* Opens the logs (log_path NULL: /dev/null) and the exec-error pipe; 0, or -1 with none left open. */
static int runner_open_fds(const char *log_path, const char *err_path, runner_fds *f)
{
    f->log = open(log_path ? log_path : "/dev/null", O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (f->log < 0)
        return -1;
    f->errlog = err_path != NULL ? open(err_path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644) : -1;
    if ((err_path != NULL && f->errlog < 0) || pipe(f->errpipe) != 0) {
        close(f->log);
        if (f->errlog >= 0)
            close(f->errlog);
        return -1;
    }
    fcntl(f->errpipe[0], F_SETFD, FD_CLOEXEC);
    fcntl(f->errpipe[1], F_SETFD, FD_CLOEXEC);
    return 0;
}

/* Blocks until the child's exec happened (EOF: 0) or failed (its errno). */
static int runner_exec_errno(int fd)
{
    int exec_errno = 0;
    ssize_t got;
    while ((got = read(fd, &exec_errno, sizeof exec_errno)) < 0 && errno == EINTR)
        continue;
    close(fd);
    return got == (ssize_t)sizeof exec_errno ? exec_errno : 0;
}

/* Waits for the child pid, started at t0, with its resource use; past timeout_s (> 0) its group
 * gets SIGTERM, then SIGKILL 2 s later (*killed 1, 2). -1 when waiting itself fails. */
static int runner_wait(pid_t pid, double t0, double timeout_s, int *status, int *killed, struct rusage *ru)
{
    double kill_at = 0.0;
    *status = *killed = 0;
    memset(ru, 0, sizeof *ru);
    for (;;) {
        pid_t w = wait4(pid, status, WNOHANG, ru);
        if (w == pid)
            return 0;
        if (w < 0 && errno != EINTR)
            return -1;
        double now = runner_now();
        if (!*killed && timeout_s > 0 && now - t0 > timeout_s) {
            kill(-pid, SIGTERM);
            *killed = 1;
            kill_at = now + 2.0;
        } else if (*killed == 1 && now > kill_at) {
            kill(-pid, SIGKILL);
            *killed = 2;
        }
        /* 10 ms polling: negligible against renders that take seconds. */
        struct timespec nap = {0, 10 * 1000 * 1000};
        nanosleep(&nap, NULL);
    }
}

/* The outcome of a child that ended: how, its exit code or signal, its CPU time and memory. */
static void runner_outcome(const char *program, int status, int killed, int exec_errno, const struct rusage *ru,
                           runner_result *r)
{
    r->cpu_s = (double)ru->ru_utime.tv_sec + 1e-6 * (double)ru->ru_utime.tv_usec + (double)ru->ru_stime.tv_sec +
               1e-6 * (double)ru->ru_stime.tv_usec;
    r->max_rss_kb = ru->ru_maxrss;
    r->exec_errno = exec_errno;
    if (exec_errno != 0) {
        /* On PATH a moment ago: gone now is "not installed"; anything else (still there but
         * its interpreter or loader missing, not executable) is an installed program that
         * does not start. */
        r->exit_code = 127;
        r->status = exec_errno == ENOENT && !runner_available(program) ? RUNNER_MISSING : RUNNER_FAILED;
    } else if (killed)
        r->status = RUNNER_TIMEOUT;
    else if (WIFSIGNALED(status)) {
        r->signal = WTERMSIG(status);
        r->status = RUNNER_CRASHED;
    } else {
        r->exit_code = WEXITSTATUS(status);
        /* 127 is the program's own exit status here (an exec failure came through the pipe). */
        r->status = r->exit_code == 0 ? RUNNER_OK : RUNNER_FAILED;
    }
}

runner_status runner_exec_in(const char *const argv[], const runner_where *where, double timeout_s,
                             const char *log_path, runner_result *r)
{
    memset(r, 0, sizeof *r);
    char full[4400];
    if (!runner_resolve(argv[0], full, sizeof full))
        return r->status = RUNNER_MISSING;
    const char *dir = where != NULL ? where->dir : NULL;
    runner_fds f;
    if (runner_open_fds(log_path, where != NULL ? where->err_log : NULL, &f) != 0)
        return r->status = RUNNER_ERROR;

    struct sigaction old[RUNNER_N_FORWARDED];
    runner_forward_signals(old);
    pid_t parent = getpid();
    double t0 = runner_now();
    pid_t pid = fork();
    if (pid == 0)
        runner_child(argv, full, dir, f.log, f.errlog, f.errpipe[1], parent);
    if (pid > 0) {
        setpgid(pid, pid);
        runner_group = pid;
    }
    close(f.log);
    if (f.errlog >= 0)
        close(f.errlog);
    close(f.errpipe[1]);
    if (pid < 0) {
        close(f.errpipe[0]);
        runner_restore_signals(old);
        return r->status = RUNNER_ERROR;
    }
    int exec_errno = runner_exec_errno(f.errpipe[0]);

    int status, killed;
    struct rusage ru;
    if (runner_wait(pid, t0, timeout_s, &status, &killed, &ru) != 0) {
        runner_kill_group(pid);
        runner_group = 0;
        runner_restore_signals(old);
        return r->status = RUNNER_ERROR;
    }
    /* The leader is gone; what it started in its group goes with it. */
    kill(-pid, SIGKILL);
    runner_group = 0;
    runner_restore_signals(old);
    r->wall_s = runner_now() - t0;
    runner_outcome(argv[0], status, killed, exec_errno, &ru, r);
    return r->status;
}

/* The first non-empty line of a file, "" if none. */
static void runner_first_line(const char *path, char *out, size_t outlen)
{
    out[0] = '\0';
    FILE *f = fopen(path, "r");
    char line[512];
    while (f != NULL && out[0] == '\0' && fgets(line, sizeof line, f) != NULL) {
        line[strcspn(line, "\r\n")] = '\0';
        snprintf(out, outlen, "%s", line);
    }
    if (f != NULL)
        fclose(f);
}

/* The line of the --version output that names the program's version, "" if none. */
static void runner_version_line(const char *path, char *out, size_t outlen)
{
    out[0] = '\0';
    FILE *f = fopen(path, "r");
    char line[512];
    while (f != NULL && fgets(line, sizeof line, f) != NULL) {
        /* POV-Ray prints a config warning first; the version line names the program. */
        if (strstr(line, "POV-Ray ") == line || strstr(line, "Blender ") == line) {
            line[strcspn(line, "\r\n")] = '\0';
            snprintf(out, outlen, "%s", line);
            break;
        }
    }
    if (f != NULL)
        fclose(f);
}

runner_status runner_version(const char *program, char *out, size_t outlen, char *why, size_t whylen)
{
    out[0] = '\0';
    why[0] = '\0';
    if (!runner_available(program))
        return RUNNER_MISSING;
    char dir[] = "/tmp/reflcheck-version-XXXXXX", log[64], errlog[64], line[300], first[304];
    if (mkdtemp(dir) == NULL) {
        snprintf(why, whylen, "%s --version: cannot make a folder for its output in /tmp: %s; check /tmp", program,
                 strerror(errno));
        return RUNNER_ERROR;
    }
    snprintf(log, sizeof log, "%s/out", dir);
    snprintf(errlog, sizeof errlog, "%s/err", dir);
    const char *argv[] = {program, "--version", NULL};
    runner_where where = {.err_log = errlog};
    runner_result r;
    /* 60 s: Blender's --version starts its Python, seconds on a loaded machine, never a minute. */
    runner_exec_in(argv, &where, 60.0, log, &r);
    /* POV-Ray prints its banner on stderr, Blender on stdout. */
    runner_version_line(log, out, outlen);
    if (out[0] == '\0')
        runner_version_line(errlog, out, outlen);
    runner_first_line(errlog, line, sizeof line);
    if (line[0] == '\0')
        runner_first_line(log, line, sizeof line);
    /* ": <its first line>", or "" when it printed nothing. */
    snprintf(first, sizeof first, "%s%s", line[0] != '\0' ? ": " : "", line);
    /* A program that is there but does not answer is a broken install, never "not installed":
     * its jobs fail with this reason instead of being skipped. */
    runner_status st = r.status;
    if (st == RUNNER_MISSING)
        snprintf(why, whylen, "%s vanished from PATH during `%s --version`", program, program);
    else if (st == RUNNER_ERROR)
        snprintf(why, whylen, "%s --version could not be run (fork, pipe or its output file in /tmp failed)", program);
    else if (r.exec_errno != 0)
        snprintf(why, whylen, "%s is installed but does not start (%s)%s", program, strerror(r.exec_errno), first);
    else if (st == RUNNER_CRASHED)
        snprintf(why, whylen, "%s --version crashed (signal %d)%s", program, r.signal, first);
    else if (st == RUNNER_TIMEOUT)
        snprintf(why, whylen, "%s --version did not answer in %.0f s", program, r.wall_s);
    else if (st != RUNNER_OK)
        snprintf(why, whylen, "%s --version failed (exit status %d)%s", program, r.exit_code, first);
    else if (out[0] == '\0') {
        snprintf(why, whylen, "%s --version printed no version line (\"POV-Ray ...\" or \"Blender ...\")%s", program,
                 first);
        st = RUNNER_FAILED;
    }
    unlink(log);
    unlink(errlog);
    rmdir(dir);
    return st;
}
