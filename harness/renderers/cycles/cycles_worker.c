/* cycles_worker.c - a Cycles job's Blender step through a worker (cycles_worker.h). */
#include "cycles_worker.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

#include <cJSON.h>

static double cycles_worker_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* path made absolute against our working folder: the worker's may differ. */
static int cycles_worker_abs(const char *path, char *buf, size_t len)
{
    char cwd[PATH_MAX];
    if (path[0] == '/')
        return (size_t)snprintf(buf, len, "%s", path) < len ? 0 : -1;
    if (getcwd(cwd, sizeof cwd) == NULL)
        return -1;
    return (size_t)snprintf(buf, len, "%s/%s", cwd, path) < len ? 0 : -1;
}

/* Reads one line (up to '\n') into buf before the deadline. 1 a line, 0 end of stream or an
 * error, -1 the deadline passed. */
static int cycles_worker_line(int fd, char *buf, size_t len, double deadline)
{
    size_t n = 0;
    while (n + 1 < len) {
        double left = deadline - cycles_worker_now();
        if (left <= 0)
            return -1;
        struct pollfd p = {.fd = fd, .events = POLLIN};
        /* At most a second per wait: the deadline is checked between waits. */
        int ms = left > 1.0 ? 1000 : (int)(left * 1000.0) + 1;
        int k = poll(&p, 1, ms);
        if (k < 0 && errno == EINTR)
            continue;
        if (k < 0)
            return 0;
        if (k == 0)
            continue;
        ssize_t got = read(fd, buf + n, 1);
        if (got < 0 && errno == EINTR)
            continue;
        if (got <= 0)
            return 0;
        if (buf[n] == '\n') {
            buf[n] = '\0';
            return 1;
        }
        n++;
    }
    return 0;
}

static double cycles_worker_number(const cJSON *o, const char *key)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
    return cJSON_IsNumber(v) ? v->valuedouble : 0.0;
}

int cycles_worker_run(const char *socket_path, const char *job_json, const char *out_exr, int threads, double timeout_s,
                      const char *log, runner_result *rr)
{
    if (socket_path == NULL || socket_path[0] == '\0')
        return 0;
    struct sockaddr_un addr;
    memset(&addr, 0, sizeof addr);
    addr.sun_family = AF_UNIX;
    if (strlen(socket_path) >= sizeof addr.sun_path)
        return 0;
    memcpy(addr.sun_path, socket_path, strlen(socket_path) + 1);
    char job[PATH_MAX], out[PATH_MAX], lg[PATH_MAX];
    if (cycles_worker_abs(job_json, job, sizeof job) != 0 || cycles_worker_abs(out_exr, out, sizeof out) != 0 ||
        cycles_worker_abs(log, lg, sizeof lg) != 0)
        return 0;
    int fd = socket(AF_UNIX, SOCK_STREAM, 0);
    if (fd < 0)
        return 0;
    fcntl(fd, F_SETFD, FD_CLOEXEC);
    if (connect(fd, (const struct sockaddr *)&addr, sizeof addr) != 0) {
        close(fd);
        return 0;
    }
    cJSON *req = cJSON_CreateObject();
    cJSON_AddStringToObject(req, "job", job);
    cJSON_AddStringToObject(req, "out", out);
    cJSON_AddStringToObject(req, "log", lg);
    cJSON_AddNumberToObject(req, "threads", threads);
    char *text = cJSON_PrintUnformatted(req);
    cJSON_Delete(req);
    size_t len = text ? strlen(text) : 0;
    int sent =
        text != NULL && send(fd, text, len, MSG_NOSIGNAL) == (ssize_t)len && send(fd, "\n", 1, MSG_NOSIGNAL) == 1;
    free(text);
    if (!sent) {
        close(fd);
        return 0;
    }
    memset(rr, 0, sizeof *rr);
    double timeout = timeout_s > 0 ? timeout_s : 600.0;
    char line[1024];
    /* Waiting for a free worker is bounded by the job's own time limit too. */
    int got = cycles_worker_line(fd, line, sizeof line, cycles_worker_now() + timeout);
    if (got == 1 && strstr(line, "\"started\"") == NULL) {
        /* The worker refused the request: ours is malformed, which is our error. */
        close(fd);
        rr->status = RUNNER_ERROR;
        return 1;
    }
    double t0 = cycles_worker_now();
    if (got == 1)
        got = cycles_worker_line(fd, line, sizeof line, t0 + timeout);
    rr->wall_s = cycles_worker_now() - t0;
    /* Hanging up is how a render is stopped: the worker ends itself when we go. */
    close(fd);
    if (got == -1) {
        rr->status = RUNNER_TIMEOUT;
        return 1;
    }
    cJSON *reply = got == 1 ? cJSON_Parse(line) : NULL;
    if (reply == NULL) {
        /* The worker died with the job (Blender crashed, or was killed). */
        rr->status = RUNNER_CRASHED;
        return 1;
    }
    int status = (int)cycles_worker_number(reply, "status");
    rr->cpu_s = cycles_worker_number(reply, "cpu_s");
    if (cJSON_GetObjectItemCaseSensitive(reply, "wall_s") != NULL)
        rr->wall_s = cycles_worker_number(reply, "wall_s");
    cJSON_Delete(reply);
    rr->exit_code = status;
    rr->status = status == 0 ? RUNNER_OK : RUNNER_FAILED;
    return 1;
}
