#include "runner.h"

#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
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

int runner_available(const char *program)
{
    if (strchr(program, '/') != NULL)
        return access(program, X_OK) == 0;
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
            if (stat(full, &st) == 0 && S_ISREG(st.st_mode) && access(full, X_OK) == 0)
                return 1;
        }
        path += n + (path[n] == ':');
    }
    return 0;
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

runner_status runner_exec(const char *const argv[], double timeout_s, const char *log_path, runner_result *r)
{
    memset(r, 0, sizeof *r);
    if (!runner_available(argv[0]))
        return r->status = RUNNER_MISSING;
    int log = open(log_path ? log_path : "/dev/null", O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (log < 0)
        return r->status = RUNNER_ERROR;

    double t0 = runner_now();
    pid_t pid = fork();
    if (pid < 0) {
        close(log);
        return r->status = RUNNER_ERROR;
    }
    if (pid == 0) {
        setpgid(0, 0);
        dup2(log, STDOUT_FILENO);
        dup2(log, STDERR_FILENO);
        int devnull = open("/dev/null", O_RDONLY);
        if (devnull >= 0)
            dup2(devnull, STDIN_FILENO);
        /* execvp takes char *const[]; the strings are not modified. */
        execvp(argv[0], (char *const *)(uintptr_t)argv);
        fprintf(stderr, "reflcheck: could not start %s: %s\n", argv[0], strerror(errno));
        _exit(127);
    }
    setpgid(pid, pid);
    close(log);

    int status = 0, killed = 0;
    struct rusage ru;
    memset(&ru, 0, sizeof ru);
    double kill_at = 0.0;
    for (;;) {
        pid_t w = wait4(pid, &status, WNOHANG, &ru);
        if (w == pid)
            break;
        if (w < 0 && errno != EINTR) {
            r->status = RUNNER_ERROR;
            return r->status;
        }
        double now = runner_now();
        if (!killed && timeout_s > 0 && now - t0 > timeout_s) {
            kill(-pid, SIGTERM);
            killed = 1;
            kill_at = now + 2.0;
        } else if (killed == 1 && now > kill_at) {
            kill(-pid, SIGKILL);
            killed = 2;
        }
        /* 10 ms polling: negligible against renders that take seconds. */
        struct timespec nap = {0, 10 * 1000 * 1000};
        nanosleep(&nap, NULL);
    }
    r->wall_s = runner_now() - t0;
    r->cpu_s = (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec + (double)ru.ru_stime.tv_sec +
               1e-6 * (double)ru.ru_stime.tv_usec;
    r->max_rss_kb = ru.ru_maxrss;
    if (killed)
        r->status = RUNNER_TIMEOUT;
    else if (WIFSIGNALED(status)) {
        r->signal = WTERMSIG(status);
        r->status = RUNNER_CRASHED;
    } else {
        r->exit_code = WEXITSTATUS(status);
        r->status = r->exit_code == 0 ? RUNNER_OK : (r->exit_code == 127 ? RUNNER_MISSING : RUNNER_FAILED);
    }
    return r->status;
}

int runner_version(const char *program, char *out, size_t outlen)
{
    out[0] = '\0';
    if (!runner_available(program))
        return 0;
    char log[] = "/tmp/reflcheck-version-XXXXXX";
    int fd = mkstemp(log);
    if (fd < 0)
        return 0;
    close(fd);
    const char *argv[] = {program, "--version", NULL};
    runner_result r;
    runner_exec(argv, 60.0, log, &r);
    FILE *f = fopen(log, "r");
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
    unlink(log);
    return out[0] != '\0';
}
