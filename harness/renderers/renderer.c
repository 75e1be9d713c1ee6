#include "renderer.h"

#include <errno.h>
#include <limits.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "exr.h"

/* stdlib.h declares realpath only under XSI; the project builds at the POSIX level. */
char *realpath(const char *restrict path, char *restrict resolved);

static const char *const renderer_terms[RENDERER_N_TERMS] = {"diffuse", "specular", "reflection", "emission"};

const char *renderer_term_name(int i) { return i >= 0 && i < RENDERER_N_TERMS ? renderer_terms[i] : ""; }

unsigned renderer_term_from_name(const char *name)
{
    for (int i = 0; i < RENDERER_N_TERMS; i++)
        if (strcmp(name, renderer_terms[i]) == 0)
            return 1u << i;
    return 0;
}

void renderer_fail(renderer_result *r, runner_status st, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    r->status = st;
    vsnprintf(r->message, sizeof r->message, fmt, ap);
    va_end(ap);
}

void renderer_leave_out(renderer_result *r, unsigned term, const char *why)
{
    for (int i = 0; i < RENDERER_N_TERMS; i++)
        if ((term & (1u << i)) && !(r->left_out & (1u << i))) {
            r->left_out |= 1u << i;
            snprintf(r->why[i], sizeof r->why[i], "%s", why);
        }
}

/* The first line of the log holding marker, for a one-line message; "" if none. */
static void renderer_log_line(const char *log, const char *marker, char *line, size_t n)
{
    line[0] = '\0';
    FILE *fp = log != NULL && marker != NULL ? fopen(log, "r") : NULL;
    if (fp == NULL)
        return;
    char buf[512];
    while (fgets(buf, sizeof buf, fp) != NULL)
        if (strstr(buf, marker) != NULL) {
            buf[strcspn(buf, "\r\n")] = '\0';
            snprintf(line, n, "%s", buf);
            break;
        }
    fclose(fp);
}

void renderer_fail_run(renderer_result *r, const runner_result *rr, const char *program, const char *package,
                       const char *what, const char *log, const char *marker, const char *shown_log)
{
    char line[240], tail[260] = "";
    renderer_log_line(log, marker, line, sizeof line);
    if (line[0])
        snprintf(tail, sizeof tail, ": %s", line);
    if (shown_log == NULL)
        shown_log = log;
    if (rr->status == RUNNER_MISSING)
        renderer_fail(r, RUNNER_MISSING, "%s is not installed; install it with: apt-get install %s", program, package);
    else if (rr->status == RUNNER_ERROR)
        renderer_fail(r, RUNNER_ERROR, "%s could not be run (log file, fork or wait failed%s); see %s", program, what,
                      shown_log);
    else if (rr->exec_errno != 0)
        renderer_fail(r, RUNNER_FAILED, "%s failed to start (%s%s); see %s", program, strerror(rr->exec_errno), what,
                      shown_log);
    else if (rr->status == RUNNER_CRASHED)
        renderer_fail(r, RUNNER_CRASHED, "%s crashed (signal %d%s)%s; see %s", program, rr->signal, what, tail,
                      shown_log);
    else if (rr->status == RUNNER_TIMEOUT)
        renderer_fail(r, RUNNER_TIMEOUT, "%s timeout (killed after %.1f s%s); see %s", program, rr->wall_s, what,
                      shown_log);
    else
        renderer_fail(r, RUNNER_FAILED, "%s failed (exit status %d%s)%s; see %s", program, rr->exit_code, what, tail,
                      shown_log);
}

rc_status renderer_physics_check(renderer_physics_fn fn, const scene *s, char *err, size_t errlen)
{
    physics got;
    char diff[700];
    if (fn == NULL)
        return RC_OK;
    rc_status st = fn(s, &got, err, errlen);
    if (st != RC_OK)
        return st;
    if (physics_diff(&s->physics, &got, s->n_lights, diff, sizeof diff) == 0)
        return RC_OK;
    status_message(err, errlen, "%s: physics: %s; change the scene's physics or compare another reference", s->path,
                   diff);
    return RC_ERR_RANGE;
}

rc_status renderer_write_textures(const renderer_job *j, char *err, size_t errlen)
{
    static const char *const slot[MAT_TEX_SLOTS] = {"diffuse", "specular"};
    for (int mi = 0; j->tex != NULL && mi < j->s->n_materials; mi++)
        for (int k = 0; k < MAT_TEX_SLOTS; k++) {
            const texture *t = &j->tex->map[mi][k];
            if (t->width <= 0)
                continue;
            size_t n = (size_t)t->width * (size_t)t->height;
            float *pl = malloc(4 * n * sizeof *pl);
            if (pl == NULL) {
                snprintf(err, errlen, "out of memory for a %d x %d texture", t->width, t->height);
                return RC_ERR_NOMEM;
            }
            for (size_t i = 0; i < n; i++)
                for (int c = 0; c < 4; c++)
                    pl[(size_t)c * n + i] = t->rgba[4 * i + (size_t)c];
            char path[1200];
            snprintf(path, sizeof path, "%s/tex%d_%s.exr", j->dir, mi, slot[k]);
            /* No alpha channel: POV-Ray would make the surface transparent and Blender reads an
             * EXR's alpha as premultiplied; the texture's alpha enters only our A layer. */
            exr_channel ch[3] = {{"R", pl}, {"G", pl + n}, {"B", pl + 2 * n}};
            rc_status st = exr_write(path, t->width, t->height, ch, 3, NULL, 0, err, errlen);
            free(pl);
            if (st != RC_OK)
                return st;
        }
    return RC_OK;
}

/* The source tree the program was built from (Makefile: -DREFLCHECK_DATA_DIR); a build without
 * it finds its files from the working folder, as before. */
#ifndef REFLCHECK_DATA_DIR
#define REFLCHECK_DATA_DIR "."
#endif

int renderer_data_path(const char *rel, char *out, size_t len)
{
    const char *dir = getenv("REFLCHECK_DATA_DIR");
    if (dir == NULL || dir[0] == '\0')
        dir = REFLCHECK_DATA_DIR;
    int n = snprintf(out, len, "%s/%s", dir, rel);
    return n > 0 && (size_t)n < len && access(out, R_OK) == 0;
}

/* A name a renderer can take whole, on its command line or in its scene language: letters,
 * digits and "._-+", not starting with '-' (an option), and not "." or "..". */
static int renderer_safe_name(const char *name)
{
    static const char ok[] = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789._-+";
    return name[0] != '\0' && name[0] != '-' && strspn(name, ok) == strlen(name) && strcmp(name, ".") != 0 &&
           strcmp(name, "..") != 0;
}

rc_status renderer_stage(const renderer_job *j, const char *src, const char *name, char *err, size_t errlen)
{
    char target[PATH_MAX], link[PATH_MAX + 64];
    if (!renderer_safe_name(name)) {
        snprintf(err, errlen, "renderer_stage: '%s' is not a safe name; use letters, digits and ._-+ only", name);
        return RC_ERR_RANGE;
    }
    if (realpath(src, target) == NULL) {
        snprintf(err, errlen, "%s: cannot resolve it to stage it for the renderer: %s; give a readable file", src,
                 strerror(errno));
        return RC_ERR_IO;
    }
    if ((size_t)snprintf(link, sizeof link, "%s/%s", j->dir, name) >= sizeof link) {
        snprintf(err, errlen, "%s: the work folder's path is too long; use a shorter --cache or --out", j->dir);
        return RC_ERR_RANGE;
    }
    unlink(link);
    if (symlink(target, link) != 0) {
        snprintf(err, errlen, "%s: cannot stage %s there: %s; check the work folder and its space", link, src,
                 strerror(errno));
        return RC_ERR_IO;
    }
    return RC_OK;
}

void renderer_command_string(const char *const argv[], char *buf, size_t buflen)
{
    if (buflen == 0)
        return;
    size_t used = 0;
    buf[0] = '\0';
    for (int i = 0; argv[i] != NULL && used < buflen; i++) {
        const char *a = argv[i];
        int plain = a[0] != '\0' && strspn(a, "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                              "0123456789+-_./=:,@%") == strlen(a);
        if (i > 0 && used + 1 < buflen)
            buf[used++] = ' ';
        if (plain) {
            int w = snprintf(buf + used, buflen - used, "%s", a);
            used += w > 0 ? (size_t)w : 0;
        } else {
            /* POSIX sh single quotes: everything literal but the quote itself, written '\''. */
            if (used + 1 < buflen)
                buf[used++] = '\'';
            for (; *a && used + 5 < buflen; a++) {
                if (*a == '\'') {
                    memcpy(buf + used, "'\\''", 4);
                    used += 4;
                } else
                    buf[used++] = *a;
            }
            if (used + 1 < buflen)
                buf[used++] = '\'';
        }
        if (used >= buflen)
            used = buflen - 1;
        buf[used] = '\0';
    }
}
