/* mesh_obj.c - the Wavefront OBJ reader: v (with an optional r g b colour), vn, vt, f and usemtl
 * into a polygon soup (mesh_internal.h); every other statement carries nothing we shade with.
 * Debian 12 ships no C library for OBJ (tinyobjloader is C++), so the reader is here: small and
 * bounds-checked, on the whole file read into memory (mesh.c).
 */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mesh_internal.h"
#include "status.h"

/* OBJ index: 1-based, or negative relative to the count so far. -1 on error. */
static int mesh_obj_index(long i, int count)
{
    if (i > 0 && i <= count)
        return (int)(i - 1);
    if (i < 0 && i >= -(long)count) /* not -i <= count: -LONG_MIN overflows */
        return (int)(count + i);
    return -1;
}

static int mesh_parse_doubles(char **cur, double *v, int max)
{
    int n = 0;
    for (;;) {
        char *s = *cur, *end;
        while (*s == ' ' || *s == '\t')
            s++;
        if (!*s)
            break;
        if (n == max)
            return -1;
        errno = 0;
        v[n] = strtod(s, &end);
        if (end == s || (*end && *end != ' ' && *end != '\t'))
            return -1;
        n++;
        *cur = end;
    }
    return n;
}

/* The message for a 'v' line that is not 'v x y z [w | r g b]': names the first token that is
 * not a number, or says how many numbers there are. */
static void mesh_obj_bad_vertex(const char *text, const char *label, int line, char *err, size_t errlen)
{
    const char *q = text;
    while (*q == ' ' || *q == '\t')
        q++;
    q++; /* the 'v' */
    int count = 0;
    for (;;) {
        while (*q == ' ' || *q == '\t')
            q++;
        if (!*q)
            break;
        const char *e = q;
        while (*e && *e != ' ' && *e != '\t')
            e++;
        char tok[40];
        size_t n = (size_t)(e - q) < sizeof tok - 1 ? (size_t)(e - q) : sizeof tok - 1;
        memcpy(tok, q, n);
        tok[n] = '\0';
        char *end;
        strtod(tok, &end);
        if (end == tok || *end) {
            status_message(err, errlen, "%s:%d: bad vertex: '%s' is not a number; fix: write 'v x y z' with 3 numbers",
                           label, line, tok);
            return;
        }
        count++;
        q = e;
    }
    status_message(err, errlen, "%s:%d: bad vertex: %d numbers; fix: write 'v x y z' (optionally w, or r g b)", label,
                   line, count);
}

/* A byte-order mark: UTF-8's is skipped (the text after it is plain OBJ); UTF-16 and UTF-32
 * text is refused by name. Returns the bytes to skip, or -1 (message in err). */
static int mesh_obj_bom(const char *buf, size_t len, const char *label, char *err, size_t errlen)
{
    const unsigned char *u = (const unsigned char *)buf;
    if (len >= 3 && u[0] == 0xEF && u[1] == 0xBB && u[2] == 0xBF)
        return 3;
    if (len >= 2 && ((u[0] == 0xFE && u[1] == 0xFF) || (u[0] == 0xFF && u[1] == 0xFE))) {
        status_message(err, errlen,
                       "%s:1: UTF-16 or UTF-32 text (byte-order mark %02X %02X) is not supported; fix: save "
                       "the OBJ as UTF-8 or ASCII",
                       label, u[0], u[1]);
        return -1;
    }
    return 0;
}

/* `v x y z r g b`: a colour1 (linear RGB as written: OBJ does not say, and the files in use write
 * 0..1). Every vertex or none: a file that starts colouring halfway is refused at its end. */
static rc_status mesh_obj_colour(mesh_soup *s, const double *v, int n, const char *label, int line, char *err,
                                 size_t errlen)
{
    if (n != 6)
        return RC_OK;
    for (int c = 3; c < 6; c++)
        if (!(isfinite(v[c]) && v[c] >= 0.0 && v[c] <= 1e30)) {
            status_message(err, errlen,
                           "%s:%d: vertex colour %g is not a finite value >= 0; fix: 'v x y z r g b' with "
                           "r g b >= 0",
                           label, line, v[c]);
            return RC_ERR_RANGE;
        }
    double c[6] = {v[3], v[4], v[5], 0, 0, 0};
    return mesh_soup_colour(s, c, 1) ? RC_OK : RC_ERR_NOMEM;
}

/* The reader's place: the soup it fills, the file and line for messages, the usemtl filter. */
typedef struct {
    mesh_soup *s;
    const char *label;
    int line;
    int take; /* faces are kept: no usemtl filter, or the last usemtl named the object's material */
    char *err;
    size_t errlen;
} obj_reader;

/* `v x y z [w | r g b]`; text is the whole line, for the message. */
static rc_status mesh_obj_v(obj_reader *o, const char *text, char *cur)
{
    double v[8];
    int n = mesh_parse_doubles(&cur, v, 7);
    if (n < 3) {
        mesh_obj_bad_vertex(text, o->label, o->line, o->err, o->errlen);
        return RC_ERR_PARSE;
    }
    if (!isfinite(v[0]) || !isfinite(v[1]) || !isfinite(v[2]) || fabs(v[0]) > 1e30 || fabs(v[1]) > 1e30 ||
        fabs(v[2]) > 1e30) {
        status_message(o->err, o->errlen, "%s:%d: vertex coordinate not finite or beyond 1e30; fix: finite coordinates",
                       o->label, o->line);
        return RC_ERR_RANGE;
    }
    if (!mesh_soup_pos(o->s, v))
        return RC_ERR_NOMEM;
    return mesh_obj_colour(o->s, v, n, o->label, o->line, o->err, o->errlen);
}

/* `vn x y z`. */
static rc_status mesh_obj_vn(obj_reader *o, char *cur)
{
    double v[3];
    if (mesh_parse_doubles(&cur, v, 3) != 3) {
        status_message(o->err, o->errlen, "%s:%d: bad normal; fix: write 'vn x y z' with 3 numbers", o->label, o->line);
        return RC_ERR_PARSE;
    }
    mesh_normal_screen(v);
    return mesh_soup_nrm(o->s, v) ? RC_OK : RC_ERR_NOMEM;
}

/* `vt u [v [w]]`: a missing v is 0 (the OBJ default); w has no meaning for 2D images. */
static rc_status mesh_obj_vt(obj_reader *o, char *cur)
{
    double v[3];
    int n = mesh_parse_doubles(&cur, v, 3);
    if (n < 1 || !isfinite(v[0]) || (n > 1 && !isfinite(v[1]))) {
        status_message(o->err, o->errlen, "%s:%d: bad texture coordinate; fix: write 'vt u v' with finite numbers",
                       o->label, o->line);
        return RC_ERR_PARSE;
    }
    if (n < 2)
        v[1] = 0.0;
    return mesh_soup_tex(o->s, v) ? RC_OK : RC_ERR_NOMEM;
}

/* `usemtl name`: the faces after it are kept when name is the object's material (when it has one). */
static void mesh_obj_usemtl(obj_reader *o, char *cur)
{
    const char *want = o->s->usemtl;
    if (want == NULL || want[0] == '\0')
        return;
    while (*cur == ' ' || *cur == '\t')
        cur++;
    char *e = cur + strlen(cur);
    while (e > cur && (e[-1] == ' ' || e[-1] == '\t'))
        *--e = '\0';
    o->take = strcmp(cur, want) == 0;
}

/* One face corner `v`, `v/vt`, `v/vt/vn` or `v//vn` at *cur (moved past it) as soup indices
 * (-1: none). strtol saturates an index beyond long at LONG_MAX or LONG_MIN, out of range either
 * way; messages quote the corner as written, not the saturated value. */
static rc_status mesh_obj_corner(obj_reader *o, char **cur, int *pv, int *pn, int *pt)
{
    const mesh_soup *s = o->s;
    char *e, *corner = *cur;
    long vi = strtol(*cur, &e, 10), ni = 0, ti = 0;
    int ok = e != *cur;
    if (ok && *e == '/') {
        *cur = e + 1;
        if (**cur != '/') {
            ti = strtol(*cur, &e, 10);
            ok = e != *cur;
        } else {
            e = *cur;
        }
        if (ok && *e == '/') {
            *cur = e + 1;
            ni = strtol(*cur, &e, 10);
            ok = e != *cur;
        }
    }
    if (!ok || (*e && *e != ' ' && *e != '\t')) {
        status_message(o->err, o->errlen, "%s:%d: bad face corner; fix: use v, v/vt, v/vt/vn or v//vn", o->label,
                       o->line);
        return RC_ERR_PARSE;
    }
    *cur = e;
    int cn = (int)(e - corner < 60 ? e - corner : 60);
    *pn = *pt = -1;
    if ((*pv = mesh_obj_index(vi, s->n_pos)) < 0) {
        status_message(o->err, o->errlen,
                       "%s:%d: corner '%.*s': vertex index out of range (%d vertices so far); "
                       "fix: indices 1..%d or negative",
                       o->label, o->line, cn, corner, s->n_pos, s->n_pos);
        return RC_ERR_RANGE;
    }
    if (ni != 0 && (*pn = mesh_obj_index(ni, s->n_nrm)) < 0) {
        status_message(o->err, o->errlen,
                       "%s:%d: corner '%.*s': normal index out of range (%d normals so far); "
                       "fix: indices 1..%d or negative",
                       o->label, o->line, cn, corner, s->n_nrm, s->n_nrm);
        return RC_ERR_RANGE;
    }
    if (ti != 0 && (*pt = mesh_obj_index(ti, s->n_tex)) < 0) {
        status_message(o->err, o->errlen,
                       "%s:%d: corner '%.*s': texture coordinate index out of range (%d so far); "
                       "fix: indices 1..%d or negative",
                       o->label, o->line, cn, corner, s->n_tex, s->n_tex);
        return RC_ERR_RANGE;
    }
    return RC_OK;
}

/* `f c1 c2 c3 ...`: a polygon of at least 3 corners. */
static rc_status mesh_obj_f(obj_reader *o, char *cur)
{
    mesh_soup *s = o->s;
    int corners = 0;
    for (;;) {
        while (*cur == ' ' || *cur == '\t')
            cur++;
        if (!*cur)
            break;
        int pv, pn, pt;
        rc_status rc = mesh_obj_corner(o, &cur, &pv, &pn, &pt);
        if (rc != RC_OK)
            return rc;
        if (!mesh_soup_corner(s, pv, pn))
            return RC_ERR_NOMEM;
        s->ct[s->n_corner - 1] = pt;
        corners++;
    }
    if (corners < 3) {
        status_message(o->err, o->errlen, "%s:%d: face with %d corners; fix: at least 3", o->label, o->line, corners);
        return RC_ERR_PARSE;
    }
    return mesh_soup_face(s, o->line) ? RC_OK : RC_ERR_NOMEM;
}

/* One line, p up to le (the newline or the end): comment and carriage returns cut, then its
 * statement. Everything but v, vn, vt, usemtl and f (o, g, s, mtllib, l, ...) carries nothing we
 * shade with. */
static rc_status mesh_obj_line(obj_reader *o, char *p, char *le)
{
    if (memchr(p, '\0', (size_t)(le - p))) {
        status_message(o->err, o->errlen, "%s:%d: NUL byte: not a text OBJ file; fix: export as Wavefront OBJ",
                       o->label, o->line);
        return RC_ERR_PARSE;
    }
    *le = '\0';
    char *hash = strchr(p, '#');
    if (hash)
        *hash = '\0';
    for (char *q = p; *q; q++)
        if (*q == '\r')
            *q = ' ';
    char *cur = p;
    while (*cur == ' ' || *cur == '\t')
        cur++;
    char *kw = cur;
    while (*cur && *cur != ' ' && *cur != '\t')
        cur++;
    size_t kwlen = (size_t)(cur - kw);
    if (kwlen == 1 && kw[0] == 'v')
        return mesh_obj_v(o, p, cur);
    if (kwlen == 2 && kw[0] == 'v' && kw[1] == 'n')
        return mesh_obj_vn(o, cur);
    if (kwlen == 2 && kw[0] == 'v' && kw[1] == 't')
        return mesh_obj_vt(o, cur);
    if (kwlen == 6 && strncmp(kw, "usemtl", 6) == 0)
        mesh_obj_usemtl(o, cur);
    else if (kwlen == 1 && kw[0] == 'f' && o->take)
        return mesh_obj_f(o, cur);
    return RC_OK;
}

rc_status mesh_obj_parse(char *buf, size_t len, const char *label, mesh_soup *s, char *err, size_t errlen)
{
    obj_reader o = {s, label, 0, s->usemtl == NULL || s->usemtl[0] == '\0', err, errlen};
    char *p = buf, *endbuf = buf + len;
    int skip = mesh_obj_bom(buf, len, label, err, errlen);
    if (skip < 0)
        return RC_ERR_PARSE;
    p += skip;
    while (p < endbuf) {
        char *nl = memchr(p, '\n', (size_t)(endbuf - p));
        char *le = nl ? nl : endbuf;
        o.line++;
        rc_status rc = mesh_obj_line(&o, p, le);
        if (rc != RC_OK)
            return rc;
        p = le + 1;
    }
    if (s->col_given > 0 && s->col_given < s->n_pos) {
        status_message(err, errlen,
                       "%s: %d of %d vertices carry a colour ('v x y z r g b'); fix: a colour on every vertex "
                       "or on none",
                       label, s->col_given, s->n_pos);
        return RC_ERR_PARSE;
    }
    return RC_OK;
}
