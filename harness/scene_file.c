/* scene_file.c - YAML scene files (scenes/FORMAT.md) to a scene, with strict validation.
 *
 * Two passes over the text: libyaml's event parser first, only to refuse deep nesting (libyaml's
 * scanner is quadratic in nesting depth: 40k '[' take seconds, 1M take minutes), then the document
 * API, whose nodes carry line/column marks for the messages. Every map is read against a fixed key
 * list, so unknown and duplicate keys are errors, and the walk is bounded by the schema (aliases
 * cannot make it loop or explode).
 */
#include <ctype.h>
#include <errno.h>
#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <yaml.h>

#include "fileio.h"
#include "texture.h"
#include "formula.h"
#include "mesh.h"
#include "mesh_assimp.h"
#include "scene_file.h"
#include "user_load.h"

/* Deeper than any scene needs (the format nests 4 levels), small enough to keep libyaml linear. */
#define SF_MAX_DEPTH 32
#define SF_PATHLEN   256

typedef struct {
    yaml_document_t *doc;
    const char *file;
    /* The name the file's base name gives, when it fails scene_name_check: then the file must
     * give `name:` (why says what is wrong with the derived one). */
    const char *default_bad;
    char default_why[160];
    char dir[SCENE_PATH_MAX];
    char *err;
    size_t errlen;
} sf_ctx;

typedef struct {
    yaml_node_t *k, *v;
} sf_kv;

#if defined(__GNUC__)
#define SF_PRINTF(f, a) __attribute__((format(printf, f, a)))
#else
#define SF_PRINTF(f, a)
#endif

uint64_t scene_file_hash(const void *bytes, size_t len)
{
    const unsigned char *p = bytes;
    uint64_t h = 14695981039346656037ull;
    for (size_t i = 0; i < len; i++) {
        h ^= p[i];
        h *= 1099511628211ull;
    }
    return h;
}

SF_PRINTF(5, 0)
static void sf_vmsg(sf_ctx *c, unsigned long line, unsigned long col, const char *path, const char *fmt, va_list ap)
{
    char msg[512];
    if (!c->err || c->errlen == 0)
        return;
    vsnprintf(msg, sizeof msg, fmt, ap);
    snprintf(c->err, c->errlen, "%s:%lu:%lu: %s: %s", c->file, line, col, path, msg);
}

SF_PRINTF(5, 6)
static rc_status sf_fail(sf_ctx *c, rc_status rc, const yaml_node_t *n, const char *path, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    sf_vmsg(c, n ? (unsigned long)n->start_mark.line + 1 : 1, n ? (unsigned long)n->start_mark.column + 1 : 1, path,
            fmt, ap);
    va_end(ap);
    return rc;
}

SF_PRINTF(5, 6)
static rc_status sf_fail_at(sf_ctx *c, rc_status rc, yaml_mark_t m, const char *path, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    sf_vmsg(c, (unsigned long)m.line + 1, (unsigned long)m.column + 1, path, fmt, ap);
    va_end(ap);
    return rc;
}

/* Appends src to out (SF_PATHLEN bytes, holding `used`), truncating; returns the new length. */
static size_t sf_append(char *out, size_t used, const char *src)
{
    while (*src && used + 1 < SF_PATHLEN)
        out[used++] = *src++;
    out[used] = '\0';
    return used;
}

/* Key paths for messages: "materials.white.d3d.power"; a path that long is truncated. */
static void sf_child(char *out, const char *path, const char *key)
{
    size_t used = sf_append(out, 0, path);
    if (path[0])
        used = sf_append(out, used, ".");
    sf_append(out, used, key);
}

static void sf_index(char *out, const char *path, int i)
{
    char idx[16];
    snprintf(idx, sizeof idx, "[%d]", i);
    sf_append(out, sf_append(out, 0, path), idx);
}

static const char *sf_kind(const yaml_node_t *n)
{
    switch (n->type) {
    case YAML_SEQUENCE_NODE: return "a list";
    case YAML_MAPPING_NODE: return "a map";
    default: return "a single value";
    }
}

/* The scalar's text, or NULL for a non-scalar or a scalar holding a NUL byte (an escape). */
static const char *sf_text(const yaml_node_t *n)
{
    if (n->type != YAML_SCALAR_NODE)
        return NULL;
    const char *s = (const char *)n->data.scalar.value;
    if (strlen(s) != n->data.scalar.length)
        return NULL;
    return s;
}

/* YAML 1.1 and 1.2 alike: a quoted scalar is a string, never a boolean or a number, so
 * `clamp: "true"` or `power: "8"` is a type error, not a value. */
static int sf_quoted(const yaml_node_t *n)
{
    return n->type == YAML_SCALAR_NODE && n->data.scalar.style != YAML_PLAIN_SCALAR_STYLE;
}

/* A short printable copy of user text for messages. */
static void sf_quote(char *out, size_t outlen, const char *s)
{
    size_t j = 0;
    for (size_t i = 0; s[i] && j + 4 < outlen; i++)
        out[j++] = isprint((unsigned char)s[i]) ? s[i] : '?';
    if (s[0] && strlen(s) >= outlen - 4 && j + 3 < outlen) {
        out[j++] = '.';
        out[j++] = '.';
    }
    out[j] = '\0';
}

static void sf_join(char *out, size_t outlen, const char *const *names, int n)
{
    size_t used = 0;
    out[0] = '\0';
    for (int i = 0; i < n && used + 1 < outlen; i++) {
        int w = snprintf(out + used, outlen - used, "%s%s", i ? ", " : "", names[i]);
        if (w < 0)
            break;
        used += (size_t)w;
    }
}

/* Reads a map whose keys must come from `keys`; found[i] gets key i's key and value nodes. */
static rc_status sf_map(sf_ctx *c, yaml_node_t *n, const char *path, const char *const *keys, int nkeys, sf_kv *found)
{
    char allowed[400], child[SF_PATHLEN], q[48];
    sf_join(allowed, sizeof allowed, keys, nkeys);
    memset(found, 0, sizeof(sf_kv) * (size_t)nkeys);
    if (n->type != YAML_MAPPING_NODE)
        return sf_fail(c, RC_ERR_PARSE, n, path[0] ? path : "(top level)",
                       "expected a map {key: value, ...}, got %s; allowed keys: %s", sf_kind(n), allowed);
    for (yaml_node_pair_t *p = n->data.mapping.pairs.start; p < n->data.mapping.pairs.top; p++) {
        yaml_node_t *k = yaml_document_get_node(c->doc, p->key);
        yaml_node_t *v = yaml_document_get_node(c->doc, p->value);
        const char *kt = k ? sf_text(k) : NULL;
        if (!k || !v || !kt)
            return sf_fail(c, RC_ERR_PARSE, k, path[0] ? path : "(top level)",
                           "a key is not a plain word; allowed keys: %s", allowed);
        int idx = -1;
        for (int i = 0; i < nkeys; i++)
            if (strcmp(kt, keys[i]) == 0)
                idx = i;
        sf_quote(q, sizeof q, kt);
        sf_child(child, path, q);
        if (idx < 0)
            return sf_fail(c, RC_ERR_PARSE, k, child, "unknown key; allowed: %s", allowed);
        if (found[idx].k)
            return sf_fail(c, RC_ERR_PARSE, k, child, "duplicate key (first at line %lu); allowed: each key once",
                           (unsigned long)found[idx].k->start_mark.line + 1);
        found[idx].k = k;
        found[idx].v = v;
    }
    return RC_OK;
}

static rc_status sf_need(sf_ctx *c, yaml_node_t *map, const char *path, const sf_kv *f, const char *key)
{
    char child[SF_PATHLEN];
    if (f->v)
        return RC_OK;
    sf_child(child, path, key);
    return sf_fail(c, RC_ERR_PARSE, map, child,
                   "missing required key in the map at this line; "
                   "allowed: add %s: ...",
                   key);
}

/* A key given where it does not apply (e.g. `radius` on a quad). */
static rc_status sf_forbid(sf_ctx *c, const char *path, const sf_kv *f, const char *key, const char *what,
                           const char *allowed)
{
    char child[SF_PATHLEN];
    if (!f->k)
        return RC_OK;
    sf_child(child, path, key);
    return sf_fail(c, RC_ERR_PARSE, f->k, child, "not used by %s; allowed: %s", what, allowed);
}

enum { SF_LO_OPEN = 1, SF_HI_OPEN = 2, SF_ALLOW_INF = 4 };

static int sf_parse_double(const char *s, double *out)
{
    static const char *const inf[] = {".inf", ".Inf", ".INF", "+.inf", "+.Inf", "+.INF"};
    static const char *const ninf[] = {"-.inf", "-.Inf", "-.INF"};
    static const char *const nan[] = {".nan", ".NaN", ".NAN"};
    for (size_t i = 0; i < sizeof inf / sizeof *inf; i++)
        if (strcmp(s, inf[i]) == 0)
            return *out = INFINITY, 1;
    for (size_t i = 0; i < sizeof ninf / sizeof *ninf; i++)
        if (strcmp(s, ninf[i]) == 0)
            return *out = -INFINITY, 1;
    for (size_t i = 0; i < sizeof nan / sizeof *nan; i++)
        if (strcmp(s, nan[i]) == 0)
            return *out = NAN, 1;
    if (!s[0] || isspace((unsigned char)s[0]))
        return 0;
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (end == s || *end)
        return 0;
    *out = v;
    return 1;
}

static rc_status sf_number(sf_ctx *c, yaml_node_t *n, const char *path, double lo, double hi, int flags,
                           const char *allowed, double *out)
{
    const char *s = sf_text(n);
    double v;
    if (s && sf_quoted(n))
        return sf_fail(c, RC_ERR_PARSE, n, path,
                       "expected a number, got quoted text (a string in YAML); allowed: %s, without quotes", allowed);
    if (!s || !sf_parse_double(s, &v))
        return sf_fail(c, RC_ERR_PARSE, n, path, "expected a number, got %s; allowed: %s", s ? "text" : sf_kind(n),
                       allowed);
    if (isnan(v))
        return sf_fail(c, RC_ERR_RANGE, n, path, "NaN is not a value; allowed: %s", allowed);
    if (isinf(v) && !(flags & SF_ALLOW_INF))
        return sf_fail(c, RC_ERR_RANGE, n, path, "%s is not finite; allowed: %s", s, allowed);
    if (v < lo || v > hi || ((flags & SF_LO_OPEN) && v == lo) || ((flags & SF_HI_OPEN) && v == hi))
        return sf_fail(c, RC_ERR_RANGE, n, path, "%s is out of range; allowed: %s", s, allowed);
    *out = v;
    return RC_OK;
}

static rc_status sf_float(sf_ctx *c, yaml_node_t *n, const char *path, double lo, double hi, int flags,
                          const char *allowed, float *out)
{
    double v;
    rc_status rc = sf_number(c, n, path, lo, hi, flags, allowed, &v);
    if (rc)
        return rc;
    if (isfinite(v) && fabs(v) > FLT_MAX)
        return sf_fail(c, RC_ERR_RANGE, n, path, "too large for single precision; allowed: %s", allowed);
    *out = (float)v;
    return RC_OK;
}

/* Degrees in the file, radians in the struct. */
static rc_status sf_angle(sf_ctx *c, yaml_node_t *n, const char *path, double lo, double hi, int flags,
                          const char *allowed, float *out)
{
    double v;
    rc_status rc = sf_number(c, n, path, lo, hi, flags, allowed, &v);
    if (rc)
        return rc;
    *out = (float)(v * FORMULA_PI_D / 180.0);
    return RC_OK;
}

static rc_status sf_int(sf_ctx *c, yaml_node_t *n, const char *path, long lo, long hi, int *out)
{
    const char *s = sf_text(n);
    char *end;
    if (!s || !s[0] || isspace((unsigned char)s[0]))
        return sf_fail(c, RC_ERR_PARSE, n, path, "expected a whole number, got %s; allowed: %ld..%ld",
                       s ? "empty text" : sf_kind(n), lo, hi);
    if (sf_quoted(n))
        return sf_fail(c, RC_ERR_PARSE, n, path,
                       "expected a whole number, got quoted text (a string in YAML); allowed: %ld..%ld, without "
                       "quotes",
                       lo, hi);
    errno = 0;
    long v = strtol(s, &end, 10);
    if (*end) {
        double d;
        if (sf_parse_double(s, &d))
            return sf_fail(c, RC_ERR_PARSE, n, path, "expected a whole number, got %s; allowed: %ld..%ld", s, lo, hi);
        return sf_fail(c, RC_ERR_PARSE, n, path, "expected a whole number, got text; allowed: %ld..%ld", lo, hi);
    }
    if (errno == ERANGE || v < lo || v > hi)
        return sf_fail(c, RC_ERR_RANGE, n, path, "%s is out of range; allowed: %ld..%ld", s, lo, hi);
    *out = (int)v;
    return RC_OK;
}

static rc_status sf_bool(sf_ctx *c, yaml_node_t *n, const char *path, int *out)
{
    static const char *const yes[] = {"true", "True", "TRUE", "yes", "Yes", "on", "On"};
    static const char *const no[] = {"false", "False", "FALSE", "no", "No", "off", "Off"};
    const char *s = sf_text(n);
    if (s && sf_quoted(n))
        return sf_fail(c, RC_ERR_PARSE, n, path,
                       "expected true or false, got quoted text (a string in YAML); allowed: true, false, without "
                       "quotes");
    for (size_t i = 0; s && i < sizeof yes / sizeof *yes; i++) {
        if (strcmp(s, yes[i]) == 0)
            return *out = 1, RC_OK;
        if (strcmp(s, no[i]) == 0)
            return *out = 0, RC_OK;
    }
    return sf_fail(c, RC_ERR_PARSE, n, path, "expected true or false, got %s; allowed: true, false",
                   s ? "other text" : sf_kind(n));
}

static rc_status sf_enum(sf_ctx *c, yaml_node_t *n, const char *path, const char *const *names, int count, int *out)
{
    char allowed[200], q[48];
    const char *s = sf_text(n);
    for (int i = 0; s && i < count; i++)
        if (strcmp(s, names[i]) == 0)
            return *out = i, RC_OK;
    sf_join(allowed, sizeof allowed, names, count);
    if (!s)
        return sf_fail(c, RC_ERR_PARSE, n, path, "expected a word, got %s; allowed: %s", sf_kind(n), allowed);
    sf_quote(q, sizeof q, s);
    return sf_fail(c, RC_ERR_PARSE, n, path, "unknown value '%s'; allowed: %s", q, allowed);
}

/* A list of exactly `count` numbers, each checked like sf_float. */
static rc_status sf_floats(sf_ctx *c, yaml_node_t *n, const char *path, int count, double lo, double hi, int flags,
                           const char *allowed, float *out)
{
    char child[SF_PATHLEN];
    if (n->type != YAML_SEQUENCE_NODE || n->data.sequence.items.top - n->data.sequence.items.start != count)
        return sf_fail(c, RC_ERR_PARSE, n, path, "expected a list of %d numbers, got %s; allowed: %s", count,
                       n->type == YAML_SEQUENCE_NODE ? "a list of another length" : sf_kind(n), allowed);
    for (int i = 0; i < count; i++) {
        yaml_node_t *e = yaml_document_get_node(c->doc, n->data.sequence.items.start[i]);
        sf_index(child, path, i);
        if (!e)
            return sf_fail(c, RC_ERR_PARSE, n, child, "missing list item; allowed: %s", allowed);
        rc_status rc = sf_float(c, e, child, lo, hi, flags, allowed, &out[i]);
        if (rc)
            return rc;
    }
    return RC_OK;
}

static rc_status sf_vec3(sf_ctx *c, yaml_node_t *n, const char *path, double lo, const char *allowed, vec3 *out)
{
    float f[3];
    rc_status rc = sf_floats(c, n, path, 3, lo, INFINITY, 0, allowed, f);
    if (rc == RC_OK)
        *out = v3(f[0], f[1], f[2]);
    return rc;
}

static rc_status sf_point(sf_ctx *c, yaml_node_t *n, const char *path, vec3 *out)
{
    return sf_vec3(c, n, path, -INFINITY, "[x, y, z], 3 finite numbers [m]", out);
}

static rc_status sf_colour(sf_ctx *c, yaml_node_t *n, const char *path, vec3 *out)
{
    return sf_vec3(c, n, path, 0.0, "[r, g, b], 3 finite numbers >= 0", out);
}

static rc_status sf_unit01(sf_ctx *c, yaml_node_t *n, const char *path, vec3 *out)
{
    float f[3];
    rc_status rc = sf_floats(c, n, path, 3, 0.0, 1.0, 0, "[r, g, b], 3 numbers in [0, 1]", f);
    if (rc == RC_OK)
        *out = v3(f[0], f[1], f[2]);
    return rc;
}

/* A direction, stored unit length. */
static rc_status sf_direction(sf_ctx *c, yaml_node_t *n, const char *path, vec3 *out)
{
    vec3 d;
    rc_status rc = sf_point(c, n, path, &d);
    if (rc)
        return rc;
    dvec3 dd = dv3_from(d);
    if (dv3_len(dd) == 0.0)
        return sf_fail(c, RC_ERR_RANGE, n, path, "zero-length direction; allowed: [x, y, z] with a nonzero length");
    *out = v3_from_d(dv3_norm(dd));
    return RC_OK;
}

static int sf_name_char(int ch) { return isalnum(ch) || ch == '_' || ch == '-' || ch == '.'; }

static rc_status sf_name(sf_ctx *c, yaml_node_t *n, const char *path, char *out, size_t outlen)
{
    const char *s = sf_text(n);
    if (!s)
        return sf_fail(c, RC_ERR_PARSE, n, path, "expected a name, got %s; allowed: letters, digits, _ - .",
                       sf_kind(n));
    size_t len = strlen(s);
    if (len == 0 || len >= outlen)
        return sf_fail(c, RC_ERR_RANGE, n, path, "name length %zu; allowed: 1..%zu characters", len, outlen - 1);
    for (size_t i = 0; i < len; i++)
        if (!sf_name_char((unsigned char)s[i]))
            return sf_fail(c, RC_ERR_RANGE, n, path,
                           "character %zu is not allowed in a name; allowed: letters, digits, _ - .", i + 1);
    memcpy(out, s, len + 1);
    return RC_OK;
}

/* A scene's name: it becomes file and folder names of a run, so model/scene.h checks it. */
static rc_status sf_scene_name(sf_ctx *c, yaml_node_t *n, char *out)
{
    char why[200], q[48];
    const char *s = sf_text(n);
    if (!s)
        return sf_fail(c, RC_ERR_PARSE, n, "name", "expected a name, got %s; allowed: %s",
                       n->type == YAML_SCALAR_NODE ? "text holding a NUL byte" : sf_kind(n), SCENE_NAME_RULE);
    if (!scene_name_check(s, why, sizeof why)) {
        sf_quote(q, sizeof q, s);
        return sf_fail(c, RC_ERR_RANGE, n, "name", "'%s': %s; allowed: %s", q, why, SCENE_NAME_RULE);
    }
    snprintf(out, SCENE_NAME_MAX, "%s", s);
    return RC_OK;
}

static int sf_ends_with(const char *s, const char *suffix)
{
    size_t a = strlen(s), b = strlen(suffix);
    if (a < b)
        return 0;
    for (size_t i = 0; i < b; i++)
        if (tolower((unsigned char)s[a - b + i]) != suffix[i])
            return 0;
    return 1;
}

/* A file path relative to the scene file's directory; the file must be a readable regular
 * file of at most max_bytes now (checked without reading it, so a FIFO cannot block). */
static rc_status sf_file(sf_ctx *c, yaml_node_t *n, const char *path, const char *const *exts, int nexts,
                         const char *what, long long max_bytes, char *out)
{
    char q[80], allowed[80];
    const char *s = sf_text(n);
    sf_join(allowed, sizeof allowed, exts, nexts);
    if (!s || !s[0])
        return sf_fail(c, RC_ERR_PARSE, n, path, "expected a file path, got %s; allowed: %s (%s)",
                       s ? "empty text" : sf_kind(n), what, allowed);
    int ok = 0;
    for (int i = 0; i < nexts; i++)
        ok |= sf_ends_with(s, exts[i]);
    sf_quote(q, sizeof q, s);
    if (!ok)
        return sf_fail(c, RC_ERR_RANGE, n, path, "'%s' has an unsupported extension; allowed: %s (%s)", q, what,
                       allowed);
    size_t need = (s[0] == '/' ? 0 : strlen(c->dir)) + strlen(s) + 1;
    if (need > SCENE_PATH_MAX)
        return sf_fail(c, RC_ERR_RANGE, n, path, "path is %zu bytes long; allowed: at most %d", need,
                       SCENE_PATH_MAX - 1);
    snprintf(out, SCENE_PATH_MAX, "%s%s", s[0] == '/' ? "" : c->dir, s);
    int fd;
    char why[SCENE_PATH_MAX + 300], kind[120];
    snprintf(kind, sizeof kind, "a %s", what);
    rc_status rc = fileio_open_input(out, max_bytes, kind, &fd, NULL, why, sizeof why);
    if (rc != RC_OK)
        return sf_fail(c, rc, n, path, "%s; allowed: a regular file, path relative to the scene file", why);
    close(fd);
    return RC_OK;
}

/* --- sections ------------------------------------------------------------------------------ */

static rc_status sf_threshold_text(sf_ctx *c, yaml_node_t *v, const char *path, char *out, size_t outlen);

/* image.samples: a whole number; `auto` (stored as 0): Cycles then takes the samples the noise
 * target of the scene's gates asks for (cycles_samples.h); or {auto: true, bias: b, why: text},
 * auto with the smallest per-pixel error its z-test gates must catch stated (a fraction of the
 * surface's mean radiance, (0, 1]). The small variant follows auto unless image.small.samples
 * gives a number. */
static rc_status sf_samples(sf_ctx *c, yaml_node_t *n, const char *path, scene *s)
{
    static const char *const keys[] = {"auto", "bias", "why"};
    const char *t = sf_text(n);
    s->samples_line = (int)n->start_mark.line + 1;
    if (t != NULL && strcmp(t, "auto") == 0 && !sf_quoted(n)) {
        s->samples = 0;
        return RC_OK;
    }
    if (n->type == YAML_MAPPING_NODE) {
        char sub[SF_PATHLEN], why[200];
        sf_kv f[3];
        int on = 0;
        rc_status rc;
        if ((rc = sf_map(c, n, path, keys, 3, f)) || (rc = sf_need(c, n, path, &f[0], "auto")) ||
            (rc = sf_need(c, n, path, &f[1], "bias")) || (rc = sf_need(c, n, path, &f[2], "why")))
            return rc;
        sf_child(sub, path, "auto");
        if ((rc = sf_bool(c, f[0].v, sub, &on)))
            return rc;
        if (!on)
            return sf_fail(c, RC_ERR_RANGE, f[0].v, sub, "false; allowed: true, or give image.samples a number");
        sf_child(sub, path, "bias");
        if ((rc = sf_number(c, f[1].v, sub, 0.0, 1.0, SF_LO_OPEN, "a fraction of the surface's mean radiance in (0, 1]",
                            &s->samples_bias)))
            return rc;
        sf_child(sub, path, "why");
        if ((rc = sf_threshold_text(c, f[2].v, sub, why, sizeof why)))
            return rc;
        s->samples = 0;
        return RC_OK;
    }
    rc_status rc = sf_int(c, n, path, 1, 1 << 20, &s->samples);
    if (rc != RC_OK)
        snprintf(c->err + strlen(c->err), c->errlen - strlen(c->err), "%s",
                 strlen(c->err) + 96 < c->errlen ? ", or auto, or {auto: true, bias: b, why: text}" : "");
    return rc;
}

static rc_status sf_image(sf_ctx *c, yaml_node_t *n, scene *s)
{
    static const char *const keys[] = {"width", "height", "supersample", "samples", "small", "timeout"};
    sf_kv f[6];
    rc_status rc;
    if ((rc = sf_map(c, n, "image", keys, 6, f)))
        return rc;
    if ((rc = sf_need(c, n, "image", &f[0], "width")) || (rc = sf_need(c, n, "image", &f[1], "height")))
        return rc;
    if ((rc = sf_int(c, f[0].v, "image.width", 1, 16384, &s->width)) ||
        (rc = sf_int(c, f[1].v, "image.height", 1, 16384, &s->height)))
        return rc;
    if (f[2].v && (rc = sf_int(c, f[2].v, "image.supersample", 1, 16, &s->supersample)))
        return rc;
    if (f[3].v && (rc = sf_samples(c, f[3].v, "image.samples", s)))
        return rc;
    if (f[5].v && (rc = sf_float(c, f[5].v, "image.timeout", 1.0, 1e6, 0, "seconds from 1 to 1e6", &s->timeout)))
        return rc;
    if (f[4].v) {
        /* The small variant `make test` renders; absent keys are derived (jobs.h). */
        sf_kv g[4];
        if ((rc = sf_map(c, f[4].v, "image.small", keys, 4, g)))
            return rc;
        if ((g[0].v && (rc = sf_int(c, g[0].v, "image.small.width", 4, 16384, &s->small.width))) ||
            (g[1].v && (rc = sf_int(c, g[1].v, "image.small.height", 4, 16384, &s->small.height))) ||
            (g[2].v && (rc = sf_int(c, g[2].v, "image.small.supersample", 1, 16, &s->small.supersample))) ||
            (g[3].v && (rc = sf_int(c, g[3].v, "image.small.samples", 1, 1 << 20, &s->small.samples))))
            return rc;
    }
    return RC_OK;
}

/* The smallest field of view single precision resolves. The rasterizer (like Cycles and EEVEE)
 * projects in float: a coordinate of magnitude R is held to R 2^-24 and a ray direction's
 * components (at most 1) to 2^-24, while neighbouring samples at distance z from the eye lie
 * 2 z tan(hfov/2) / N apart (N samples across: width times supersample, of the full size or
 * the small variant, whichever is larger). Keeping that rounding within half a sample needs
 * tan(hfov/2) >= 2^-24 N max(1, R/z), R the larger distance of eye and target from the
 * origin, z the view distance. Below it, edges land whole samples off (measured: a quad edge
 * at 3/4 of a 1024-sample row, R/z = 1, lands 2 samples off at 1e-4 degrees against a bound of
 * 7e-3), rays of neighbouring pixels become one float, and near 1e-30 degrees the projection
 * overflows (half the image black) while POV-Ray calls the camera unrepresentable. */
static rc_status sf_hfov_resolved(sf_ctx *c, yaml_node_t *n, const scene *s, double z)
{
    double across = fmax((double)s->width * s->supersample, (double)s->small.width * s->small.supersample);
    double r = fmax(dv3_len(dv3_from(s->camera.eye)), dv3_len(dv3_from(s->camera.target)));
    double tan_min = ldexp(1.0, -24) * across * fmax(1.0, r / z);
    double min_deg = 2.0 * atan(tan_min) * 180.0 / FORMULA_PI_D;
    if (tan(0.5 * (double)s->camera.hfov) >= tan_min)
        return RC_OK;
    return sf_fail(c, RC_ERR_RANGE, n, "camera.hfov",
                   "%s degrees is below %.6g, the smallest field of view single precision resolves for %.0f samples "
                   "across with the eye and target up to %.3g from the origin at distance %.3g; allowed: degrees in "
                   "[%.6g, 180), or fewer samples across, or eye and target nearer the origin",
                   sf_text(n), min_deg, across, r, z, min_deg);
}

static rc_status sf_camera(sf_ctx *c, yaml_node_t *n, scene *s)
{
    static const char *const keys[] = {"eye", "target", "up", "hfov"};
    sf_kv f[4];
    rc_status rc;
    if ((rc = sf_map(c, n, "camera", keys, 4, f)))
        return rc;
    if ((rc = sf_need(c, n, "camera", &f[0], "eye")) || (rc = sf_need(c, n, "camera", &f[1], "target")) ||
        (rc = sf_need(c, n, "camera", &f[3], "hfov")))
        return rc;
    if ((rc = sf_point(c, f[0].v, "camera.eye", &s->camera.eye)) ||
        (rc = sf_point(c, f[1].v, "camera.target", &s->camera.target)))
        return rc;
    if (f[2].v && (rc = sf_direction(c, f[2].v, "camera.up", &s->camera.up)))
        return rc;
    if ((rc = sf_angle(c, f[3].v, "camera.hfov", 0.0, 180.0, SF_LO_OPEN | SF_HI_OPEN, "degrees in (0, 180)",
                       &s->camera.hfov)))
        return rc;
    dvec3 view = dv3_sub(dv3_from(s->camera.target), dv3_from(s->camera.eye));
    if (dv3_len(view) == 0.0)
        return sf_fail(c, RC_ERR_RANGE, f[1].v, "camera.target",
                       "equals camera.eye; allowed: a target point different from the eye");
    if ((rc = sf_hfov_resolved(c, f[3].v, s, dv3_len(view))))
        return rc;
    /* Below sin(angle) = 1e-3 between up and the view axis, the normalised right vector
     * cross(view, up) carries float rounding of order 1e-4 relative: refuse it. */
    if (dv3_len(dv3_cross(dv3_norm(view), dv3_from(s->camera.up))) < 1e-3)
        return sf_fail(c, RC_ERR_RANGE, f[2].v ? f[2].v : n, "camera.up",
                       "parallel to the view direction target - eye; allowed: an up vector at an "
                       "angle to the view direction");
    return RC_OK;
}

/* Image files the scene names for textures and cube-map faces: PNG or JPEG (sRGB, through
 * scene/texture.c), linear OpenEXR, or a 2D DDS (scene/image_oiio.h; 8-bit colour as sRGB). */
static const char *const sf_image_exts[] = {".png", ".jpg", ".jpeg", ".exr", ".dds"};
#define SF_N_IMAGE_EXTS ((int)(sizeof sf_image_exts / sizeof sf_image_exts[0]))
/* A cross takes every image but a DDS, the table's last: one DDS file under the environment is a
 * cube map (cube_dds), which harness/frame.c tells from a cross by its extension. */
#define SF_N_CROSS_EXTS (SF_N_IMAGE_EXTS - 1)

/* cube: {px: file, nx: ..., py, ny, pz, nz}: the six faces of a cube map (scene/env.h), each
 * PNG/JPEG (sRGB) or linear EXR; all six required. */
static rc_status sf_cube(sf_ctx *c, yaml_node_t *n, scene *s)
{
    const char *const *keys = env_cube_face_keys; /* scene/env.h, D3DCUBEMAP_FACES order */
    sf_kv f[6];
    char child[SF_PATHLEN];
    rc_status rc;
    if ((rc = sf_map(c, n, "environment.cube", keys, 6, f)))
        return rc;
    for (int k = 0; k < 6; k++) {
        if ((rc = sf_need(c, n, "environment.cube", &f[k], keys[k])))
            return rc;
        sf_child(child, "environment.cube", keys[k]);
        if ((rc = sf_file(c, f[k].v, child, sf_image_exts, SF_N_IMAGE_EXTS, "cube-map face image", TEXTURE_MAX_BYTES,
                          s->env.cube[k])))
            return rc;
    }
    return RC_OK;
}

static rc_status sf_environment(sf_ctx *c, yaml_node_t *n, scene *s)
{
    static const char *const keys[] = {"constant", "image", "scale", "sun_threshold", "cube", "cube_cross", "cube_dds"};
    static const char *const exts[] = {".exr"}, *const dds[] = {".dds"};
    sf_kv f[7];
    rc_status rc;
    if ((rc = sf_map(c, n, "environment", keys, 7, f)))
        return rc;
    if (!!f[0].v + !!f[1].v + !!f[4].v + !!f[5].v + !!f[6].v != 1)
        return sf_fail(c, RC_ERR_PARSE, n, "environment",
                       "give exactly one of 'constant', 'image', 'cube', 'cube_cross' and 'cube_dds'; allowed: "
                       "{constant: [r, g, b]}, {image: file.exr, scale: s}, {cube: {px: f, nx: f, py: f, ny: f, pz: "
                       "f, nz: f}, scale: s}, {cube_cross: file, scale: s}, {cube_dds: file.dds, scale: s}, or omit "
                       "environment for none");
    if (f[0].v) {
        if ((rc = sf_forbid(c, "environment", &f[2], "scale", "a constant environment", "constant: [r, g, b] alone")) ||
            (rc = sf_forbid(c, "environment", &f[3], "sun_threshold", "a constant environment",
                            "constant: [r, g, b] alone")))
            return rc;
        s->env.kind = ENV_CONSTANT;
        return sf_colour(c, f[0].v, "environment.constant", &s->env.radiance);
    }
    s->env.kind = f[1].v ? ENV_IMAGE : ENV_CUBE;
    s->env.radiance = v3s(1.0f);
    if (f[1].v && (rc = sf_file(c, f[1].v, "environment.image", exts, 1, "equirectangular linear OpenEXR image",
                                LLONG_MAX, s->env.path)))
        return rc;
    if (f[4].v && (rc = sf_cube(c, f[4].v, s)))
        return rc;
    if (f[5].v && (rc = sf_file(c, f[5].v, "environment.cube_cross", sf_image_exts, SF_N_CROSS_EXTS,
                                "horizontal 4 x 3 cube-map cross image", TEXTURE_MAX_BYTES, s->env.path)))
        return rc;
    /* One DDS cube map (harness/frame.c tells it from a cross by its extension). */
    if (f[6].v &&
        (rc = sf_file(c, f[6].v, "environment.cube_dds", dds, 1, "DDS cube map", TEXTURE_MAX_BYTES, s->env.path)))
        return rc;
    /* The sun split finds a region of an equirectangular image; a cube map has none to give. */
    if (s->env.kind == ENV_CUBE && (rc = sf_forbid(c, "environment", &f[3], "sun_threshold", "a cube map",
                                                   "an equirectangular image: {image: file.exr, sun_threshold: t}")))
        return rc;
    if (f[2].v) {
        if (f[2].v->type == YAML_SEQUENCE_NODE)
            return sf_colour(c, f[2].v, "environment.scale", &s->env.radiance);
        float k;
        if ((rc = sf_float(c, f[2].v, "environment.scale", 0.0, INFINITY, 0, "a finite number >= 0 or [r, g, b]", &k)))
            return rc;
        s->env.radiance = v3s(k);
    }
    if (f[3].v) {
        if ((rc =
                 sf_float(c, f[3].v, "environment.sun_threshold", 0.0, INFINITY, 0,
                          "a finite luminance > 0 [W/m^2/sr] above the sky's, below the sun's", &s->env.sun_threshold)))
            return rc;
        if (!(s->env.sun_threshold > 0.0f))
            return sf_fail(c, RC_ERR_RANGE, f[3].v, "environment.sun_threshold",
                           "0 is not a threshold; allowed: a finite luminance > 0, or omit sun_threshold for no split");
    }
    return RC_OK;
}

enum {
    LK_TYPE,
    LK_POSITION,
    LK_DIRECTION,
    LK_INTENSITY,
    LK_IRRADIANCE,
    LK_AMBIENT,
    LK_ATTENUATION,
    LK_RANGE,
    LK_INNER,
    LK_OUTER,
    LK_FALLOFF,
    LK_PROFILE,
    LK_COUNT
};

static const char *const sf_light_keys[LK_COUNT] = {"type",       "position", "direction",   "intensity",
                                                    "irradiance", "ambient",  "attenuation", "range",
                                                    "inner",      "outer",    "falloff",     "profile"};
static const char *const sf_light_types[] = {"point", "sun", "spot"};

/* A light's type, and the keys that type accepts and requires. */
static rc_status sf_light_type(sf_ctx *c, yaml_node_t *n, const char *path, sf_kv *f, light *l)
{
    static const int point_ok[] = {LK_TYPE, LK_POSITION, LK_INTENSITY, LK_AMBIENT, LK_ATTENUATION, LK_RANGE, -1};
    static const int sun_ok[] = {LK_TYPE, LK_DIRECTION, LK_IRRADIANCE, LK_AMBIENT, -1};
    static const int spot_ok[] = {LK_TYPE,  LK_POSITION, LK_DIRECTION, LK_INTENSITY, LK_AMBIENT, LK_ATTENUATION,
                                  LK_RANGE, LK_INNER,    LK_OUTER,     LK_FALLOFF,   LK_PROFILE, -1};
    static const int point_req[] = {LK_POSITION, LK_INTENSITY, -1};
    static const int sun_req[] = {LK_DIRECTION, LK_IRRADIANCE, -1};
    static const int spot_req[] = {LK_POSITION, LK_DIRECTION, LK_INTENSITY, LK_INNER, LK_OUTER, -1};
    static const int *const ok_of[] = {point_ok, sun_ok, spot_ok};
    static const int *const req_of[] = {point_req, sun_req, spot_req};
    char child[SF_PATHLEN], allowed[300];
    rc_status rc;
    int type;

    if ((rc = sf_map(c, n, path, sf_light_keys, LK_COUNT, f)))
        return rc;
    if ((rc = sf_need(c, n, path, &f[LK_TYPE], "type")))
        return rc;
    sf_child(child, path, "type");
    if ((rc = sf_enum(c, f[LK_TYPE].v, child, sf_light_types, 3, &type)))
        return rc;
    light_init(l);
    l->kind = (light_kind)type;

    const char *names[LK_COUNT];
    int nn = 0;
    for (const int *k = ok_of[type]; *k >= 0; k++)
        names[nn++] = sf_light_keys[*k];
    sf_join(allowed, sizeof allowed, names, nn);
    for (int i = 0; i < LK_COUNT; i++) {
        int ok = 0;
        for (const int *k = ok_of[type]; *k >= 0; k++)
            ok |= *k == i;
        if (!ok) {
            char what[32];
            snprintf(what, sizeof what, "a %s light", sf_light_types[type]);
            if ((rc = sf_forbid(c, path, &f[i], sf_light_keys[i], what, allowed)))
                return rc;
        }
    }
    for (const int *k = req_of[type]; *k >= 0; k++)
        if ((rc = sf_need(c, n, path, &f[*k], sf_light_keys[*k])))
            return rc;
    return RC_OK;
}

#define SF_CHILD(key) (sf_child(child, path, (key)), child)

/* A spot light's cone: inner and outer angles, falloff and profile. */
static rc_status sf_light_spot(sf_ctx *c, const char *path, const sf_kv *f, light *l)
{
    static const char *const profiles[] = {"d3d", "smooth"};
    char child[SF_PATHLEN];
    rc_status rc;
    if ((rc = sf_angle(c, f[LK_INNER].v, SF_CHILD("inner"), 0.0, 180.0, SF_HI_OPEN,
                       "full cone angle in degrees, 0 <= inner <= outer < 180", &l->inner)) ||
        (rc = sf_angle(c, f[LK_OUTER].v, SF_CHILD("outer"), 0.0, 180.0, SF_LO_OPEN | SF_HI_OPEN,
                       "full cone angle in degrees, 0 < outer < 180", &l->outer)))
        return rc;
    if (l->inner > l->outer)
        return sf_fail(c, RC_ERR_RANGE, f[LK_INNER].v, SF_CHILD("inner"),
                       "inner cone is wider than outer; allowed: inner <= outer");
    if (f[LK_FALLOFF].v && (rc = sf_float(c, f[LK_FALLOFF].v, SF_CHILD("falloff"), 0.0, INFINITY, 0,
                                          "a finite exponent >= 0", &l->falloff)))
        return rc;
    if (f[LK_PROFILE].v) {
        int p;
        if ((rc = sf_enum(c, f[LK_PROFILE].v, SF_CHILD("profile"), profiles, 2, &p)))
            return rc;
        l->profile = p ? SPOT_SMOOTH : SPOT_D3D;
    }
    return RC_OK;
}

static rc_status sf_light(sf_ctx *c, yaml_node_t *n, const char *path, light *l)
{
    sf_kv f[LK_COUNT];
    char child[SF_PATHLEN];
    rc_status rc;
    if ((rc = sf_light_type(c, n, path, f, l)))
        return rc;
    if (f[LK_POSITION].v && (rc = sf_point(c, f[LK_POSITION].v, SF_CHILD("position"), &l->position)))
        return rc;
    if (f[LK_DIRECTION].v && (rc = sf_direction(c, f[LK_DIRECTION].v, SF_CHILD("direction"), &l->direction)))
        return rc;
    if (f[LK_INTENSITY].v && (rc = sf_colour(c, f[LK_INTENSITY].v, SF_CHILD("intensity"), &l->intensity)))
        return rc;
    if (f[LK_IRRADIANCE].v && (rc = sf_colour(c, f[LK_IRRADIANCE].v, SF_CHILD("irradiance"), &l->intensity)))
        return rc;
    if (f[LK_AMBIENT].v && (rc = sf_colour(c, f[LK_AMBIENT].v, SF_CHILD("ambient"), &l->ambient)))
        return rc;
    if (f[LK_ATTENUATION].v) {
        float a[3];
        if ((rc = sf_floats(c, f[LK_ATTENUATION].v, SF_CHILD("attenuation"), 3, 0.0, INFINITY, 0,
                            "[a0, a1, a2], finite numbers >= 0, not all 0", a)))
            return rc;
        if (a[0] == 0.0f && a[1] == 0.0f && a[2] == 0.0f)
            return sf_fail(c, RC_ERR_RANGE, f[LK_ATTENUATION].v, child,
                           "a0 = a1 = a2 = 0 divides by zero; allowed: [a0, a1, a2] >= 0, not all 0 "
                           "(physical 1/d^2 is [0, 0, 1])");
        l->a0 = a[0];
        l->a1 = a[1];
        l->a2 = a[2];
    }
    if (f[LK_RANGE].v && (rc = sf_float(c, f[LK_RANGE].v, SF_CHILD("range"), 0.0, INFINITY, SF_LO_OPEN | SF_ALLOW_INF,
                                        "a number > 0 or .inf [m]", &l->range)))
        return rc;
    if (l->kind == LIGHT_SPOT)
        return sf_light_spot(c, path, f, l);
    return RC_OK;
}
#undef SF_CHILD

/* The head every list section shares: a YAML sequence of at most max items (the scene's fixed
 * arrays). name is the section ("lights"), first_key the key its items start with ("type"). */
static rc_status sf_list(sf_ctx *c, yaml_node_t *n, const char *name, const char *first_key, long max, long *count)
{
    if (n->type != YAML_SEQUENCE_NODE)
        return sf_fail(c, RC_ERR_PARSE, n, name, "expected a list (- {%s: ...} items), got %s; allowed: a list of %s",
                       first_key, sf_kind(n), name);
    *count = n->data.sequence.items.top - n->data.sequence.items.start;
    if (*count > max)
        return sf_fail(c, RC_ERR_RANGE, n, name, "%ld %s; allowed: at most %ld", *count, name, max);
    return RC_OK;
}

static rc_status sf_lights(sf_ctx *c, yaml_node_t *n, scene *s)
{
    char child[SF_PATHLEN];
    long count;
    rc_status lrc = sf_list(c, n, "lights", "type", SCENE_MAX_LIGHTS, &count);
    if (lrc)
        return lrc;
    for (int i = 0; i < count; i++) {
        yaml_node_t *e = yaml_document_get_node(c->doc, n->data.sequence.items.start[i]);
        sf_index(child, "lights", i);
        rc_status rc = e ? sf_light(c, e, child, &s->lights[i])
                         : sf_fail(c, RC_ERR_PARSE, n, child, "missing item; allowed: a light map");
        if (rc)
            return rc;
    }
    s->n_lights = (int)count;
    return RC_OK;
}

enum {
    MK_ALBEDO,
    MK_IOR,
    MK_CONDUCTOR,
    MK_ROUGHNESS,
    MK_MODEL,
    MK_D3D,
    MK_D9,
    MK_CT,
    MK_TEXTURE,
    MK_ASSET,
    MK_THIN,
    MK_USER,
    MK_DISTRIBUTION,
    MK_COUNT
};

static rc_status sf_d3d(sf_ctx *c, yaml_node_t *n, const char *path, d3d_params *d, int *diffuse_given,
                        yaml_node_t *state_node[3])
{
    static const char *const keys[] = {
        "ambient",        "diffuse",        "specular",        "emissive",          "power",
        "local_viewer",   "per_vertex",     "clamp",           "normalize_normals", "colour_vertex",
        "ambient_source", "diffuse_source", "specular_source", "emissive_source",   "two_sided"};
    static const char *const sources[] = {"material", "colour1", "colour2"};
    sf_kv f[15];
    char child[SF_PATHLEN];
    rc_status rc;
    if ((rc = sf_map(c, n, path, keys, 15, f)))
        return rc;
    state_node[0] = f[8].v;
    state_node[1] = f[9].v;
    state_node[2] = f[14].v;
    if (f[14].v) {
        sf_child(child, path, keys[14]);
        if ((rc = sf_bool(c, f[14].v, child, &d->two_sided)))
            return rc;
    }
    if (f[9].v) {
        sf_child(child, path, keys[9]);
        if ((rc = sf_bool(c, f[9].v, child, &d->colour_vertex)))
            return rc;
    }
    colour_source *src[4] = {&d->ambient_source, &d->diffuse_source, &d->specular_source, &d->emissive_source};
    for (int i = 0; i < 4; i++) {
        int e = 0;
        sf_child(child, path, keys[10 + i]);
        if (f[10 + i].v && (rc = sf_enum(c, f[10 + i].v, child, sources, 3, &e)))
            return rc;
        if (f[10 + i].v)
            *src[i] = (colour_source)e;
    }
    vec3 *col[4] = {&d->ambient, &d->diffuse, &d->specular, &d->emissive};
    for (int i = 0; i < 4; i++) {
        sf_child(child, path, keys[i]);
        if (f[i].v && (rc = sf_colour(c, f[i].v, child, col[i])))
            return rc;
    }
    *diffuse_given = f[1].v != NULL;
    sf_child(child, path, "power");
    if (f[4].v && (rc = sf_float(c, f[4].v, child, 0.0, INFINITY, 0, "a finite exponent >= 0", &d->power)))
        return rc;
    int *flag[4] = {&d->local_viewer, &d->per_vertex, &d->clamp, &d->normalize_normals};
    for (int i = 0; i < 4; i++) {
        sf_child(child, path, keys[5 + i]);
        if (f[5 + i].v && (rc = sf_bool(c, f[5 + i].v, child, flag[i])))
            return rc;
    }
    return RC_OK;
}

/* d3d9client.dissolve: [scale, strength] within D3D9Client's material editor clamps (scale 0 to
 * 12, strength 0 to 0.2; "typical" 0.2 to 3 and 0.01 to 0.1). The strength bound also keeps the
 * offset, at most strength sqrt(3)/2 long, shorter than the unit mirror direction it is added
 * to, so the dissolved direction is never zero. */
static rc_status sf_dissolve(sf_ctx *c, yaml_node_t *n, const char *path, d3d9client_params *d)
{
    static const char allowed[] = "[scale, strength], scale in [0, 12] and strength in [0, 0.2] (D3D9Client's "
                                  "material editor ranges; either 0 turns dissolve off)";
    float f[2];
    rc_status rc = sf_floats(c, n, path, 2, 0.0, 12.0, 0, allowed, f);
    if (rc)
        return rc;
    if (f[1] > 0.2f) {
        char child[SF_PATHLEN];
        sf_index(child, path, 1);
        return sf_fail(c, RC_ERR_RANGE, yaml_document_get_node(c->doc, n->data.sequence.items.start[1]), child,
                       "%g is out of range; allowed: %s", f[1], allowed);
    }
    d->dissolve_scale = f[0];
    d->dissolve_strength = f[1];
    return RC_OK;
}

static rc_status sf_d9(sf_ctx *c, yaml_node_t *n, const char *path, d3d9client_params *d, int *r0_given, int *m_given,
                       yaml_node_t **dissolve_node)
{
    static const char *const keys[] = {"p",         "r0",    "m",        "reflect",     "fresnel_colour", "norm",
                                       "sun_angle", "alpha", "dissolve", "texel_alpha", "blend"};
    static const char *const norms[] = {"max", "mean", "luminance", "euclid"};
    static const char *const texel_modes[] = {"multiply", "material", "texel"};
    sf_kv f[11];
    char child[SF_PATHLEN];
    rc_status rc;
    int e;
    if ((rc = sf_map(c, n, path, keys, 11, f)))
        return rc;
#define SF_CHILD(key) (sf_child(child, path, (key)), child)
    if (f[9].v) {
        if ((rc = sf_enum(c, f[9].v, SF_CHILD("texel_alpha"), texel_modes, 3, &e)))
            return rc;
        d->texel_alpha = (texel_alpha_mode)e;
    }
    if (f[10].v && (rc = sf_bool(c, f[10].v, SF_CHILD("blend"), &d->blend)))
        return rc;
    if (f[0].v && (rc = sf_float(c, f[0].v, SF_CHILD("p"), 0.0, INFINITY, 0, "a finite power >= 0", &d->p)))
        return rc;
    if (f[1].v && (rc = sf_float(c, f[1].v, SF_CHILD("r0"), 0.0, 1.0, 0, "R0 in [0, 1]", &d->r0)))
        return rc;
    if (f[2].v && (rc = sf_float(c, f[2].v, SF_CHILD("m"), 0.0, INFINITY, 0, "a finite multiplier >= 0", &d->m)))
        return rc;
    if (f[3].v && (rc = sf_colour(c, f[3].v, SF_CHILD("reflect"), &d->reflect)))
        return rc;
    if (f[4].v && (rc = sf_colour(c, f[4].v, SF_CHILD("fresnel_colour"), &d->fresnel_colour)))
        return rc;
    if (f[5].v) {
        if ((rc = sf_enum(c, f[5].v, SF_CHILD("norm"), norms, 4, &e)))
            return rc;
        d->norm = (colour_norm)e;
    }
    if (f[6].v && (rc = sf_bool(c, f[6].v, SF_CHILD("sun_angle"), &d->sun_angle)))
        return rc;
    if (f[7].v && (rc = sf_float(c, f[7].v, SF_CHILD("alpha"), 0.0, 1.0, 0, "an alpha in [0, 1]", &d->alpha)))
        return rc;
    if (f[8].v && (rc = sf_dissolve(c, f[8].v, SF_CHILD("dissolve"), d)))
        return rc;
#undef SF_CHILD
    *dissolve_node = f[8].v;
    *r0_given = f[1].v != NULL;
    *m_given = f[2].v != NULL;
    return RC_OK;
}

static rc_status sf_ct(sf_ctx *c, yaml_node_t *n, const char *path, ct_params *d, int *m_given, int *f0_given)
{
    static const char *const keys[] = {"m", "f0", "ks", "normalisation", "g", "f", "reflection"};
    static const char *const norms[] = {"walter", "ct1982"};
    static const char *const gs[] = {"vcavity", "smith_walter", "smith_exact"};
    static const char *const fs[] = {"schlick", "one", "exact"};
    sf_kv f[7];
    char child[SF_PATHLEN];
    rc_status rc;
    int e;
    if ((rc = sf_map(c, n, path, keys, 7, f)))
        return rc;
#define SF_CHILD(key) (sf_child(child, path, (key)), child)
    if (f[0].v &&
        (rc = sf_float(c, f[0].v, SF_CHILD("m"), 0.0, INFINITY, 0, "a finite Beckmann roughness >= 0", &d->m)))
        return rc;
    if (f[1].v && (rc = sf_unit01(c, f[1].v, SF_CHILD("f0"), &d->f0)))
        return rc;
    if (f[2].v && (rc = sf_colour(c, f[2].v, SF_CHILD("ks"), &d->ks)))
        return rc;
    if (f[3].v) {
        if ((rc = sf_enum(c, f[3].v, SF_CHILD("normalisation"), norms, 2, &e)))
            return rc;
        d->norm = (ct_normalisation)e;
    }
    if (f[4].v) {
        if ((rc = sf_enum(c, f[4].v, SF_CHILD("g"), gs, 3, &e)))
            return rc;
        d->g = (ct_geometry)e;
    }
    if (f[5].v) {
        if ((rc = sf_enum(c, f[5].v, SF_CHILD("f"), fs, 3, &e)))
            return rc;
        d->f = (ct_fresnel)e;
    }
    if (f[6].v && (rc = sf_bool(c, f[6].v, SF_CHILD("reflection"), &d->reflection)))
        return rc;
#undef SF_CHILD
    *m_given = f[0].v != NULL;
    *f0_given = f[1].v != NULL;
    return RC_OK;
}

/* Fresnel reflectance at normal incidence: dielectric n in air, or conductor n + ik. */
static float sf_f0(double eta, double k)
{
    return (float)(((eta - 1) * (eta - 1) + k * k) / ((eta + 1) * (eta + 1) + k * k));
}

/* texture: {diffuse: file, specular: file}: PNG/JPEG (sRGB) or linear EXR images, each optional
 * (scene/texture.h; the slots' meaning is scene.h's material_texture_slot). */
static rc_status sf_texture(sf_ctx *c, yaml_node_t *n, const char *path, material *m)
{
    static const char *const keys[MAT_TEX_SLOTS] = {"diffuse", "specular"};
    sf_kv f[MAT_TEX_SLOTS];
    char child[SF_PATHLEN];
    rc_status rc;
    if ((rc = sf_map(c, n, path, keys, MAT_TEX_SLOTS, f)))
        return rc;
    for (int k = 0; k < MAT_TEX_SLOTS; k++) {
        sf_child(child, path, keys[k]);
        if (f[k].v && (rc = sf_file(c, f[k].v, child, sf_image_exts, SF_N_IMAGE_EXTS, "texture image",
                                    TEXTURE_MAX_BYTES, m->texture[k])))
            return rc;
    }
    return RC_OK;
}

/* An extension in lower case, as sf_file compares them (".DAE" -> ".dae"); cut to len. */
static void sf_lower_ext(const char *ext, char *out, size_t len)
{
    size_t i = 0;
    for (; ext[i] && i + 1 < len; i++)
        out[i] = (char)tolower((unsigned char)ext[i]);
    out[i] = '\0';
}

/* An asset's material name: exporters write spaces and punctuation ("Material #25"), so any
 * text without control characters. */
static rc_status sf_asset_name(sf_ctx *c, yaml_node_t *n, const char *path, char *out, size_t outlen)
{
    const char *s = sf_text(n);
    if (!s)
        return sf_fail(c, RC_ERR_PARSE, n, path, "expected an asset's material name, got %s; allowed: text",
                       sf_kind(n));
    size_t len = strlen(s);
    if (len == 0 || len >= outlen)
        return sf_fail(c, RC_ERR_RANGE, n, path, "name length %zu; allowed: 1..%zu bytes", len, outlen - 1);
    for (size_t i = 0; i < len; i++)
        if ((unsigned char)s[i] < 0x20 || s[i] == 0x7f)
            return sf_fail(c, RC_ERR_RANGE, n, path,
                           "byte %zu is a control character; allowed: the material name as the asset writes it", i + 1);
    memcpy(out, s, len + 1);
    return RC_OK;
}

/* An imported asset's material (asset: {path: FILE, material: NAME}), mapped by the rule of
 * scene/mesh_assimp.h (scenes/FORMAT.md, "Imported assets"). */
static rc_status sf_asset(sf_ctx *c, yaml_node_t *n, const char *path, material *m, int *f0_given)
{
    static const char *const keys[] = {"path", "material", "texture"};
    sf_kv f[3];
    int use_texture = 1;
    char child[SF_PATHLEN], file[SCENE_PATH_MAX], name[SCENE_NAME_MAX], why[SCENE_PATH_MAX + 600];
    rc_status rc;
    if ((rc = sf_map(c, n, path, keys, 3, f)) || (rc = sf_need(c, n, path, &f[0], "path")) ||
        (rc = sf_need(c, n, path, &f[1], "material")))
        return rc;
    sf_child(child, path, "path");
    const char *text = sf_text(f[0].v), *dot = text ? strrchr(text, '.') : NULL;
    char low[16];
    sf_lower_ext(dot && mesh_assimp_supported(text) ? dot : ".gltf", low, sizeof low);
    const char *ext[1] = {low};
    if ((rc = sf_file(c, f[0].v, child, ext, 1, "an asset libassimp reads", FILEIO_MESH_MAX_BYTES, file)))
        return rc;
    sf_child(child, path, "material");
    if ((rc = sf_asset_name(c, f[1].v, child, name, sizeof name)))
        return rc;
    if (f[2].v && (sf_child(child, path, "texture"), rc = sf_bool(c, f[2].v, child, &use_texture)))
        return rc;
    sf_child(child, path, "material");
    mesh_assimp_material a;
    if ((rc = mesh_assimp_material_load(file, name, &a, why, sizeof why)))
        return sf_fail(c, rc, f[1].v, child, "%s", why);
    if (!use_texture)
        a.texture[0] = '\0';
    if (a.texture[0]) {
        int ok = 0, fd;
        for (int i = 0; i < SF_N_IMAGE_EXTS; i++)
            ok |= sf_ends_with(a.texture, sf_image_exts[i]);
        if (!ok)
            return sf_fail(c, RC_ERR_RANGE, f[1].v, child,
                           "the asset's texture %s is not an image reflcheck reads; allowed: convert it to PNG or "
                           "JPEG and name it in texture: {diffuse: FILE}, with asset: {texture: false}",
                           a.texture);
        if ((rc = fileio_open_input(a.texture, TEXTURE_MAX_BYTES, "a texture image", &fd, NULL, why, sizeof why)))
            return sf_fail(c, rc, f[1].v, child, "the asset's texture: %s", why);
        close(fd);
    }
    *f0_given |= mesh_assimp_material_apply(&a, m);
    return RC_OK;
}

/* user: {path: FILE.so, params: {name: value, ...}}: the shared object is loaded here (code
 * execution by design: only a path the scene names), its parameters checked against the bounds
 * it declares, and the model probed at the scene's values (scene/user_load.h). */
_Static_assert(USER_PARAMS_MAX == REFLCHECK_USER_PARAMS_MAX, "scene.h holds every parameter a model may declare");
static rc_status sf_user(sf_ctx *c, yaml_node_t *n, const char *path, user_params *u)
{
    static const char *const keys[] = {"path", "params"};
    static const char *const exts[] = {".so"};
    sf_kv f[2], pf[USER_PARAMS_MAX];
    char child[SF_PATHLEN], sub[SF_PATHLEN], why[SCENE_PATH_MAX + 600];
    rc_status rc;
    if ((rc = sf_map(c, n, path, keys, 2, f)) || (rc = sf_need(c, n, path, &f[0], "path")))
        return rc;
    sf_child(child, path, "path");
    if ((rc = sf_file(c, f[0].v, child, exts, 1, "a user model's shared object", FILEIO_MESH_MAX_BYTES, u->path)))
        return rc;
    const reflcheck_user_model *um;
    if ((rc = user_model_load(u->path, &um, why, sizeof why)))
        return sf_fail(c, rc, f[0].v, child, "%s", why);
    u->model = um;
    user_model_defaults(um, u->params);
    sf_child(child, path, "params");
    if (f[1].v) {
        const char *names[USER_PARAMS_MAX];
        for (int i = 0; i < um->n_params; i++)
            names[i] = um->params[i].name;
        if ((rc = sf_map(c, f[1].v, child, names, um->n_params, pf)))
            return rc;
        for (int i = 0; i < um->n_params; i++) {
            if (!pf[i].v)
                continue;
            sf_child(sub, child, names[i]);
            if ((rc = sf_number(c, pf[i].v, sub, -INFINITY, INFINITY, 0, "a finite number", &u->params[i])))
                return rc;
            if ((rc = user_model_check_value(um, u->path, i, u->params[i], why, sizeof why)))
                return sf_fail(c, rc, pf[i].v, sub, "%s", why);
        }
    }
    if ((rc = user_model_probe(um, u->path, u->params, why, sizeof why)))
        return sf_fail(c, rc, f[1].v ? f[1].v : n, child, "%s", why);
    return RC_OK;
}

/* What a material's file gave, so the derived defaults fill only what it left out. */
typedef struct {
    int diffuse, r0, d9m, ctm, f0;
    yaml_node_t *dissolve; /* the d3d9client dissolve key, checked after the whole material */
} sf_mat_given;

#define SF_CHILD(key) (sf_child(child, path, (key)), child)

/* A conductor's complex index: conductor: {eta: [r, g, b], k: [r, g, b]}. */
static rc_status sf_material_conductor(sf_ctx *c, yaml_node_t *n, const char *path, material *m)
{
    static const char *const ckeys[] = {"eta", "k"};
    sf_kv cf[2];
    char sub[SF_PATHLEN];
    rc_status rc;
    if ((rc = sf_map(c, n, path, ckeys, 2, cf)) || (rc = sf_need(c, n, path, &cf[0], "eta")) ||
        (rc = sf_need(c, n, path, &cf[1], "k")))
        return rc;
    float eta[3], k[3];
    sf_child(sub, path, "eta");
    if ((rc = sf_floats(c, cf[0].v, sub, 3, 0.0, INFINITY, SF_LO_OPEN, "[r, g, b], 3 finite numbers > 0", eta)))
        return rc;
    sf_child(sub, path, "k");
    if ((rc = sf_floats(c, cf[1].v, sub, 3, 0.0, INFINITY, 0, "[r, g, b], 3 finite numbers >= 0", k)))
        return rc;
    m->conductor = 1;
    m->eta = v3(eta[0], eta[1], eta[2]);
    m->k = v3(k[0], k[1], k[2]);
    return RC_OK;
}

/* The material's physics: asset, albedo, index or conductor, roughness, thin, model,
 * distribution and a user model's object. */
static rc_status sf_material_physics(sf_ctx *c, yaml_node_t *n, const char *path, const sf_kv *f, material *m,
                                     sf_mat_given *g)
{
    static const char *const models[] = {"d3d", "d3d9client", "cook_torrance", "user"};
    static const char *const dists[] = {"beckmann", "ggx"};
    char child[SF_PATHLEN];
    rc_status rc;
    int e;
    /* First, so that every other key of the material replaces what the asset states. */
    if (f[MK_ASSET].v && (rc = sf_asset(c, f[MK_ASSET].v, SF_CHILD("asset"), m, &g->f0)))
        return rc;
    if (f[MK_ALBEDO].v && (rc = sf_colour(c, f[MK_ALBEDO].v, SF_CHILD("albedo"), &m->albedo)))
        return rc;
    if (f[MK_IOR].v && f[MK_CONDUCTOR].v)
        return sf_fail(c, RC_ERR_PARSE, f[MK_CONDUCTOR].k, SF_CHILD("conductor"),
                       "both ior and conductor given; allowed: one of ior: n (dielectric) or "
                       "conductor: {eta: [..], k: [..]}");
    if (f[MK_IOR].v && (rc = sf_float(c, f[MK_IOR].v, SF_CHILD("ior"), 0.0, INFINITY, SF_LO_OPEN,
                                      "a finite refractive index > 0", &m->ior)))
        return rc;
    if (f[MK_CONDUCTOR].v && (rc = sf_material_conductor(c, f[MK_CONDUCTOR].v, SF_CHILD("conductor"), m)))
        return rc;
    if (f[MK_ROUGHNESS].v && (rc = sf_float(c, f[MK_ROUGHNESS].v, SF_CHILD("roughness"), 0.0, INFINITY, 0,
                                            "a finite Beckmann roughness >= 0", &m->roughness)))
        return rc;
    if (f[MK_THIN].v && (rc = sf_bool(c, f[MK_THIN].v, SF_CHILD("thin"), &m->thin)))
        return rc;
    if (f[MK_MODEL].v) {
        if ((rc = sf_enum(c, f[MK_MODEL].v, SF_CHILD("model"), models, 4, &e)))
            return rc;
        m->model = (model_kind)e;
    }
    if (f[MK_DISTRIBUTION].v) {
        if ((rc = sf_enum(c, f[MK_DISTRIBUTION].v, SF_CHILD("distribution"), dists, 2, &e)))
            return rc;
        m->distribution = (microfacet_distribution)e;
    }
    if ((m->model == MODEL_USER) != (f[MK_USER].v != NULL))
        return sf_fail(c, RC_ERR_PARSE, f[MK_USER].v ? f[MK_USER].k : n, SF_CHILD("user"),
                       m->model == MODEL_USER ? "model user needs its shared object; allowed: add user: {path: "
                                                "FILE.so, params: {...}} (docs/user_models.md)"
                                              : "user applies to model user only; allowed: model: user, or no user");
    if (f[MK_USER].v && (rc = sf_user(c, f[MK_USER].v, SF_CHILD("user"), &m->user)))
        return rc;
    return RC_OK;
}

/* The models' own sections (d3d, d3d9client, cook_torrance) and the texture. */
static rc_status sf_material_sections(sf_ctx *c, const char *path, const sf_kv *f, material *m, sf_mat_given *g)
{
    char child[SF_PATHLEN], sub[SF_PATHLEN];
    rc_status rc;
    yaml_node_t *state_node[3] = {NULL, NULL, NULL};
    if (f[MK_D3D].v && (rc = sf_d3d(c, f[MK_D3D].v, SF_CHILD("d3d"), &m->d3d, &g->diffuse, state_node)))
        return rc;
    /* D3DRS_NORMALIZENORMALS and D3DRS_COLORVERTEX are fixed-function state: the D3D9Client and
     * Cook-Torrance models are shaders, which take the normal and colours they are given. */
    if ((!m->d3d.normalize_normals || m->d3d.colour_vertex) && m->model != MODEL_D3D) {
        int norm = !m->d3d.normalize_normals;
        sf_child(sub, path, "d3d");
        sf_child(child, sub, norm ? "normalize_normals" : "colour_vertex");
        return sf_fail(c, RC_ERR_RANGE, state_node[norm ? 0 : 1], child,
                       "%s applies to the fixed-function model d3d only (%s); allowed: %s, or model: d3d",
                       norm ? "false" : "true", norm ? "D3DRS_NORMALIZENORMALS" : "D3DRS_COLORVERTEX",
                       norm ? "true" : "false");
    }
    /* One-sided lighting: the shaders' N.V < 0 has no meaning in their formulas (Cook-Torrance
     * divides by it), so only the fixed function lights a normal facing away. */
    if (!m->d3d.two_sided && m->model != MODEL_D3D) {
        sf_child(sub, path, "d3d");
        sf_child(child, sub, "two_sided");
        return sf_fail(c, RC_ERR_RANGE, state_node[2], child,
                       "false applies to the fixed-function model d3d only (the normal as given, "
                       "D3DCULL_NONE); allowed: true, or model: d3d");
    }
    if (f[MK_D9].v && (rc = sf_d9(c, f[MK_D9].v, SF_CHILD("d3d9client"), &m->d9, &g->r0, &g->d9m, &g->dissolve)))
        return rc;
    if (f[MK_CT].v && (rc = sf_ct(c, f[MK_CT].v, SF_CHILD("cook_torrance"), &m->ct, &g->ctm, &g->f0)))
        return rc;
    if (f[MK_TEXTURE].v && (rc = sf_texture(c, f[MK_TEXTURE].v, SF_CHILD("texture"), m)))
        return rc;
    return RC_OK;
}
#undef SF_CHILD

/* The checks across keys, after the whole material, so key order does not matter. */
static rc_status sf_material_combos(sf_ctx *c, const char *path, const sf_kv *f, const material *m,
                                    const sf_mat_given *g)
{
    char child[SF_PATHLEN], sub[SF_PATHLEN];
    /* Source 000: Dissolve "can be only applied to non-normal mapped surface that has a texture" (it
     * reads the texture coordinates); a D3D9Client shader effect. */
    if (g->dissolve != NULL && m->d9.dissolve_scale > 0.0f && m->d9.dissolve_strength > 0.0f &&
        (m->model != MODEL_D3D9CLIENT || m->texture[MAT_TEX_DIFFUSE][0] == '\0')) {
        sf_child(sub, path, "d3d9client");
        sf_child(child, sub, "dissolve");
        return sf_fail(c, RC_ERR_RANGE, g->dissolve, child,
                       m->model != MODEL_D3D9CLIENT
                           ? "dissolve applies to model d3d9client only (a D3D9Client shader effect); allowed: "
                             "model: d3d9client, or no dissolve"
                           : "dissolve needs a textured surface (source 000: it applies only to a surface that has "
                             "a texture, whose coordinates it reads); allowed: texture: {diffuse: file}, or no "
                             "dissolve");
    }

    /* A thin sheet is a smooth dielectric pane (its closed form, docs/physics.md); blending is
     * the D3D9Client's eq. (7) at work, so only that model's alpha means a coverage. */
    if (m->thin && (m->conductor || m->roughness != 0.0f))
        return sf_fail(c, RC_ERR_RANGE, f[MK_THIN].v, (sf_child(child, path, "thin"), child),
                       "a thin sheet is a smooth dielectric pane; allowed: thin: true with ior (no conductor) "
                       "and roughness: 0, or thin: false");
    if (m->d9.blend && m->model != MODEL_D3D9CLIENT) {
        sf_child(sub, path, "d3d9client");
        sf_child(child, sub, "blend");
        return sf_fail(c, RC_ERR_RANGE, f[MK_D9].v, child,
                       "blend applies to model d3d9client only (its alpha is eq. 7); allowed: model: d3d9client, "
                       "or blend: false");
    }
    return RC_OK;
}

/* Derived defaults, after the whole material, so key order in the file does not matter. */
static void sf_material_defaults(const sf_kv *f, const sf_mat_given *g, material *m)
{
    if (!g->diffuse)
        m->d3d.diffuse = m->albedo;
    if (!g->r0)
        m->d9.r0 = sf_f0(m->ior, 0.0);
    if (!g->d9m)
        m->d9.m = 1.0f - m->d9.r0;
    if (!g->ctm)
        m->ct.m = m->roughness;
    /* A d3d material without a specular colour shows no highlight: its physics gets no lobe
     * either, unless the file writes a roughness (then the user asked for one). */
    if (m->model == MODEL_D3D && !f[MK_ROUGHNESS].v && m->d3d.specular.x == 0.0f && m->d3d.specular.y == 0.0f &&
        m->d3d.specular.z == 0.0f)
        m->lobe = 0;
    if (!g->f0)
        m->ct.f0 = m->conductor ? v3(sf_f0(m->eta.x, m->k.x), sf_f0(m->eta.y, m->k.y), sf_f0(m->eta.z, m->k.z))
                                : v3s(sf_f0(m->ior, 0.0));
}

static rc_status sf_material(sf_ctx *c, yaml_node_t *n, const char *path, material *m)
{
    static const char *const keys[MK_COUNT] = {"albedo", "ior",        "conductor",     "roughness", "model",
                                               "d3d",    "d3d9client", "cook_torrance", "texture",   "asset",
                                               "thin",   "user",       "distribution"};
    sf_kv f[MK_COUNT];
    sf_mat_given g = {0};
    rc_status rc;
    if ((rc = sf_map(c, n, path, keys, MK_COUNT, f)) || (rc = sf_material_physics(c, n, path, f, m, &g)) ||
        (rc = sf_material_sections(c, path, f, m, &g)) || (rc = sf_material_combos(c, path, f, m, &g)))
        return rc;
    sf_material_defaults(f, &g, m);
    return RC_OK;
}

static rc_status sf_materials(sf_ctx *c, yaml_node_t *n, scene *s)
{
    char child[SF_PATHLEN];
    if (n->type != YAML_MAPPING_NODE)
        return sf_fail(c, RC_ERR_PARSE, n, "materials",
                       "expected a map of name: {material}, got %s; allowed: materials: {white: "
                       "{albedo: [..]}, ...}",
                       sf_kind(n));
    long count = n->data.mapping.pairs.top - n->data.mapping.pairs.start;
    if (count > SCENE_MAX_MATERIALS)
        return sf_fail(c, RC_ERR_RANGE, n, "materials", "%ld materials; allowed: at most %d", count,
                       SCENE_MAX_MATERIALS);
    for (int i = 0; i < count; i++) {
        yaml_node_pair_t *p = &n->data.mapping.pairs.start[i];
        yaml_node_t *k = yaml_document_get_node(c->doc, p->key);
        yaml_node_t *v = yaml_document_get_node(c->doc, p->value);
        material *m = &s->materials[i];
        rc_status rc;
        if (!k || !v)
            return sf_fail(c, RC_ERR_PARSE, n, "materials", "incomplete entry; allowed: name: {...}");
        material_init(m);
        if ((rc = sf_name(c, k, "materials", m->name, sizeof m->name)))
            return rc;
        sf_child(child, "materials", m->name);
        for (int j = 0; j < i; j++)
            if (strcmp(s->materials[j].name, m->name) == 0)
                return sf_fail(c, RC_ERR_PARSE, k, child, "duplicate material name; allowed: each name once");
        if ((rc = sf_material(c, v, child, m)))
            return rc;
    }
    s->n_materials = (int)count;
    return RC_OK;
}

enum {
    OK_SHAPE,
    OK_CENTER,
    OK_ROTATE,
    OK_SCALE,
    OK_RADIUS,
    OK_MAJOR,
    OK_SIZE,
    OK_TESS,
    OK_PATH,
    OK_MATERIAL,
    OK_USEMTL,
    OK_COUNT
};

/* `scale: k` or `scale: [sx, sy, sz]`: each factor, once stored as float, must pass
 * mesh_scale_ok, the check scene/mesh.c makes again for scenes built in code. */
static rc_status sf_scale_factor(sf_ctx *c, yaml_node_t *n, const char *path, float *out)
{
    static const char allowed[] = "a number or [sx, sy, sz], each in [1e-06, 1e+06] (no mirroring)";
    double v;
    rc_status rc = sf_number(c, n, path, -INFINITY, INFINITY, 0, allowed, &v);
    if (rc)
        return rc;
    if (!mesh_scale_ok((float)v))
        return sf_fail(c, RC_ERR_RANGE, n, path, "%s is out of range; allowed: %s", sf_text(n), allowed);
    *out = (float)v;
    return RC_OK;
}

static rc_status sf_object_scale(sf_ctx *c, yaml_node_t *n, const char *path, vec3 *out)
{
    char child[SF_PATHLEN];
    float k[3];
    if (n->type != YAML_SEQUENCE_NODE) {
        rc_status rc = sf_scale_factor(c, n, path, &k[0]);
        if (rc == RC_OK)
            *out = v3s(k[0]);
        return rc;
    }
    if (n->data.sequence.items.top - n->data.sequence.items.start != 3)
        return sf_fail(c, RC_ERR_PARSE, n, path,
                       "expected a list of 3 numbers, got a list of another length; allowed: a number or [sx, sy, "
                       "sz], each in [1e-06, 1e+06] (no mirroring)");
    for (int i = 0; i < 3; i++) {
        yaml_node_t *e = yaml_document_get_node(c->doc, n->data.sequence.items.start[i]);
        sf_index(child, path, i);
        rc_status rc = e ? sf_scale_factor(c, e, child, &k[i])
                         : sf_fail(c, RC_ERR_PARSE, n, child, "missing list item; allowed: 3 numbers");
        if (rc)
            return rc;
    }
    *out = v3(k[0], k[1], k[2]);
    return RC_OK;
}

static const char *const sf_object_keys[OK_COUNT] = {"shape", "center",       "rotate", "scale",    "radius", "major",
                                                     "size",  "tessellation", "path",   "material", "usemtl"};
static const char *const sf_object_shapes[] = {"sphere", "quad", "box", "torus", "mesh"};
/* Per shape: 0 = not allowed, 1 = optional, 2 = required. */
static const unsigned char sf_object_use[5][OK_COUNT] = {
    /*          shape center rotate scale radius major size tess path material usemtl */
    /* sphere */ {2, 1, 1, 1, 2, 0, 0, 1, 0, 2, 0},
    /* quad   */ {2, 1, 1, 1, 0, 0, 2, 0, 0, 2, 0},
    /* box    */ {2, 1, 1, 1, 1, 0, 2, 1, 0, 2, 0},
    /* torus  */ {2, 1, 1, 1, 2, 2, 0, 1, 0, 2, 0},
    /* mesh   */ {2, 1, 1, 1, 0, 0, 0, 0, 2, 2, 1},
};

/* An object's shape, and the keys that shape allows and needs. */
static rc_status sf_object_shape(sf_ctx *c, yaml_node_t *n, const char *path, sf_kv *f, object *o)
{
    char child[SF_PATHLEN], allowed[200], what[32];
    rc_status rc;
    int shape;

    if ((rc = sf_map(c, n, path, sf_object_keys, OK_COUNT, f)) || (rc = sf_need(c, n, path, &f[OK_SHAPE], "shape")))
        return rc;
    sf_child(child, path, "shape");
    if ((rc = sf_enum(c, f[OK_SHAPE].v, child, sf_object_shapes, 5, &shape)))
        return rc;
    object_init(o);
    o->shape = (shape_kind)shape;
    if (shape == SHAPE_BOX)
        o->radius = 0.0f;

    const char *names[OK_COUNT];
    int nn = 0;
    for (int i = 0; i < OK_COUNT; i++)
        if (sf_object_use[shape][i])
            names[nn++] = sf_object_keys[i];
    sf_join(allowed, sizeof allowed, names, nn);
    snprintf(what, sizeof what, "a %s", sf_object_shapes[shape]);
    for (int i = 0; i < OK_COUNT; i++) {
        if (!sf_object_use[shape][i] && (rc = sf_forbid(c, path, &f[i], sf_object_keys[i], what, allowed)))
            return rc;
        if (sf_object_use[shape][i] == 2 && (rc = sf_need(c, n, path, &f[i], sf_object_keys[i])))
            return rc;
    }
    return RC_OK;
}

#define SF_CHILD(key) (sf_child(child, path, (key)), child)

/* An object's placement and dimensions, each checked against its shape. */
static rc_status sf_object_dims(sf_ctx *c, const char *path, const sf_kv *f, object *o)
{
    /* Tessellation limits: a sphere needs 2 rings (segments/2), a torus tube 3 segments. */
    static const int tess_lo[5] = {4, 0, 1, 3, 0}, tess_hi[5] = {1024, 0, 256, 1024, 0};
    char child[SF_PATHLEN];
    rc_status rc;
    int shape = (int)o->shape;
    if (f[OK_CENTER].v && (rc = sf_point(c, f[OK_CENTER].v, SF_CHILD("center"), &o->center)))
        return rc;
    if (f[OK_ROTATE].v) {
        float r[3];
        if ((rc = sf_floats(c, f[OK_ROTATE].v, SF_CHILD("rotate"), 3, -INFINITY, INFINITY, 0,
                            "[x, y, z] Euler angles in degrees, applied X then Y then Z", r)))
            return rc;
        o->rotate = v3_scale(v3(r[0], r[1], r[2]), (float)(FORMULA_PI_D / 180.0));
    }
    if (f[OK_SCALE].v && (rc = sf_object_scale(c, f[OK_SCALE].v, SF_CHILD("scale"), &o->scale)))
        return rc;
    if (f[OK_MAJOR].v && (rc = sf_float(c, f[OK_MAJOR].v, SF_CHILD("major"), 0.0, INFINITY, SF_LO_OPEN,
                                        "a finite ring radius > 0 [m]", &o->major)))
        return rc;
    if (f[OK_RADIUS].v) {
        int box = shape == SHAPE_BOX;
        if ((rc = sf_float(c, f[OK_RADIUS].v, SF_CHILD("radius"), 0.0, INFINITY, box ? 0 : SF_LO_OPEN,
                           box ? "an edge rounding >= 0 [m]" : "a finite radius > 0 [m]", &o->radius)))
            return rc;
    }
    if (f[OK_SIZE].v) {
        float sz[3];
        int quad = shape == SHAPE_QUAD;
        if ((rc = sf_floats(c, f[OK_SIZE].v, SF_CHILD("size"), quad ? 2 : 3, 0.0, INFINITY, SF_LO_OPEN,
                            quad ? "[x, z] extents > 0 [m]" : "[x, y, z] full extents > 0 [m]", sz)))
            return rc;
        o->size = quad ? v3(sz[0], 0.0f, sz[1]) : v3(sz[0], sz[1], sz[2]);
    }
    if (f[OK_TESS].v &&
        (rc = sf_int(c, f[OK_TESS].v, SF_CHILD("tessellation"), tess_lo[shape], tess_hi[shape], &o->tessellation)))
        return rc;
    if (shape == SHAPE_BOX) {
        float half = 0.5f * fminf(o->size.x, fminf(o->size.y, o->size.z));
        if (o->radius > half)
            return sf_fail(c, RC_ERR_RANGE, f[OK_RADIUS].v, SF_CHILD("radius"),
                           "rounding exceeds half the smallest size; allowed: 0 <= radius <= %g", half);
    }
    if (shape == SHAPE_TORUS && o->radius > o->major)
        return sf_fail(c, RC_ERR_RANGE, f[OK_RADIUS].v, SF_CHILD("radius"),
                       "tube radius exceeds the ring radius (self-intersecting); allowed: radius <= "
                       "major = %g",
                       o->major);
    return RC_OK;
}

/* A mesh object's file and the OBJ material (or asset mesh) it selects. */
static rc_status sf_object_mesh(sf_ctx *c, const char *path, const sf_kv *f, object *o)
{
    static const char *const mesh_exts[] = {".obj", ".ply"};
    char child[SF_PATHLEN];
    rc_status rc;
    /* Besides OBJ and PLY, any extension libassimp reads (scene/mesh_assimp.h). */
    const char *mp = f[OK_PATH].v ? sf_text(f[OK_PATH].v) : NULL, *dot = mp ? strrchr(mp, '.') : NULL;
    int imported = dot && !sf_ends_with(mp, ".obj") && !sf_ends_with(mp, ".ply") && mesh_assimp_supported(mp);
    char low[16];
    const char *lowp = low;
    sf_lower_ext(dot ? dot : "", low, sizeof low);
    if (f[OK_PATH].v &&
        (rc = sf_file(c, f[OK_PATH].v, SF_CHILD("path"), imported ? &lowp : mesh_exts, imported ? 1 : 2,
                      imported ? "an asset libassimp reads" : "triangle mesh", FILEIO_MESH_MAX_BYTES, o->path)))
        return rc;
    if (f[OK_USEMTL].v && imported) {
        /* An asset's meshes of one material (its name as the asset writes it). */
        if ((rc = sf_asset_name(c, f[OK_USEMTL].v, SF_CHILD("usemtl"), o->usemtl, sizeof o->usemtl)))
            return rc;
    } else if (f[OK_USEMTL].v) {
        if ((rc = sf_name(c, f[OK_USEMTL].v, SF_CHILD("usemtl"), o->usemtl, sizeof o->usemtl)))
            return rc;
        if (!sf_ends_with(o->path, ".obj"))
            return sf_fail(c, RC_ERR_PARSE, f[OK_USEMTL].v, child,
                           "usemtl selects faces of an OBJ file, and this mesh is a PLY; allowed: usemtl with an "
                           ".obj path");
    }
    return RC_OK;
}

/* The object's material, by name among the scene's materials. */
static rc_status sf_object_material(sf_ctx *c, const char *path, const sf_kv *f, const scene *s, object *o)
{
    char child[SF_PATHLEN];
    const char *mt = sf_text(f[OK_MATERIAL].v);
    int mi = -1;
    for (int i = 0; mt && i < s->n_materials; i++)
        if (strcmp(mt, s->materials[i].name) == 0)
            mi = i;
    if (mi < 0) {
        char q[48], known[300];
        const char *mn[SCENE_MAX_MATERIALS];
        for (int i = 0; i < s->n_materials; i++)
            mn[i] = s->materials[i].name;
        sf_join(known, sizeof known, mn, s->n_materials);
        sf_quote(q, sizeof q, mt ? mt : "");
        return sf_fail(c, mt ? RC_ERR_RANGE : RC_ERR_PARSE, f[OK_MATERIAL].v, SF_CHILD("material"),
                       "unknown material '%s'; allowed: %s", q,
                       s->n_materials ? known : "(none defined: add a materials: section)");
    }
    o->material = mi;
    return RC_OK;
}
#undef SF_CHILD

static rc_status sf_object(sf_ctx *c, yaml_node_t *n, const char *path, const scene *s, object *o)
{
    sf_kv f[OK_COUNT];
    rc_status rc;
    if ((rc = sf_object_shape(c, n, path, f, o)) || (rc = sf_object_dims(c, path, f, o)) ||
        (rc = sf_object_mesh(c, path, f, o)))
        return rc;
    return sf_object_material(c, path, f, s, o);
}

static rc_status sf_objects(sf_ctx *c, yaml_node_t *n, scene *s)
{
    char child[SF_PATHLEN];
    long count;
    rc_status lrc = sf_list(c, n, "objects", "shape", SCENE_MAX_OBJECTS, &count);
    if (lrc)
        return lrc;
    for (int i = 0; i < count; i++) {
        yaml_node_t *e = yaml_document_get_node(c->doc, n->data.sequence.items.start[i]);
        sf_index(child, "objects", i);
        rc_status rc = e ? sf_object(c, e, child, s, &s->objects[i])
                         : sf_fail(c, RC_ERR_PARSE, n, child, "missing item; allowed: an object map");
        if (rc)
            return rc;
    }
    s->n_objects = (int)count;
    return RC_OK;
}

/* Metric names may be dotted paths into the comparison result, e.g. background.rel_rms. */
static int sf_metric_char(int ch) { return islower(ch) || isdigit(ch) || ch == '_' || ch == '.'; }

/* A threshold's sentence (why, loose): quoted text that fits its field. */
static rc_status sf_threshold_text(sf_ctx *c, yaml_node_t *v, const char *path, char *out, size_t outlen)
{
    const char *text = sf_text(v);
    if (!text || !text[0])
        return sf_fail(c, RC_ERR_PARSE, v, path, "expected text, got %s; allowed: a quoted sentence",
                       text ? "nothing" : sf_kind(v));
    if (strlen(text) >= outlen)
        return sf_fail(c, RC_ERR_RANGE, v, path, "text too long; allowed: at most %zu characters", outlen - 1);
    strcpy(out, text);
    return RC_OK;
}

/* sized: {figure: x, size: small|full, run: id}: the figure the gate was set on, all three. */
static rc_status sf_threshold_sized(sf_ctx *c, yaml_node_t *v, const char *path, threshold *t)
{
    static const char *const keys[] = {"figure", "size", "run"};
    static const char *const sizes[] = {"small", "full"};
    char sub[SF_PATHLEN];
    sf_kv f[3];
    int size = 0;
    rc_status rc;
    if ((rc = sf_map(c, v, path, keys, 3, f)) || (rc = sf_need(c, v, path, &f[0], "figure")) ||
        (rc = sf_need(c, v, path, &f[1], "size")) || (rc = sf_need(c, v, path, &f[2], "run")))
        return rc;
    sf_child(sub, path, "figure");
    if ((rc = sf_number(c, f[0].v, sub, -INFINITY, INFINITY, 0, "the measured figure, a finite number",
                        &t->sized_figure)))
        return rc;
    sf_child(sub, path, "size");
    if ((rc = sf_enum(c, f[1].v, sub, sizes, 2, &size)))
        return rc;
    t->sized_size = size == 0 ? SIZED_SMALL : SIZED_FULL;
    sf_child(sub, path, "run");
    return sf_threshold_text(c, f[2].v, sub, t->sized_run, sizeof t->sized_run);
}

/* small: or full: {warn, fail, loose, sized: {figure, run}}: the gate at one image size, each
 * key optional (what it leaves out is the threshold's own); its sized figure was measured at
 * that size, so the block's sized: names no size. */
static rc_status sf_threshold_size(sf_ctx *c, yaml_node_t *v, const char *path, int full, threshold *t)
{
    static const char *const keys[] = {"warn", "fail", "loose", "sized"};
    static const char *const sized_keys[] = {"figure", "run"};
    char sub[SF_PATHLEN], sub2[SF_PATHLEN];
    sf_kv f[4], z[2];
    rc_status rc;
    if ((rc = sf_map(c, v, path, keys, 4, f)))
        return rc;
    if (!f[0].v && !f[1].v && !f[2].v && !f[3].v)
        return sf_fail(c, RC_ERR_PARSE, v, path, "empty block; allowed: one or more of warn, fail, loose, sized");
    t->at[full].set = 1;
    sf_child(sub, path, "warn");
    if (f[0].v && (rc = sf_number(c, f[0].v, sub, -INFINITY, INFINITY, 0, "a finite number", &t->at[full].warn)))
        return rc;
    sf_child(sub, path, "fail");
    if (f[1].v && (rc = sf_number(c, f[1].v, sub, -INFINITY, INFINITY, 0, "a finite number", &t->at[full].fail)))
        return rc;
    t->at[full].warn_set = f[0].v != NULL;
    t->at[full].fail_set = f[1].v != NULL;
    sf_child(sub, path, "loose");
    if (f[2].v && (rc = sf_threshold_text(c, f[2].v, sub, t->at[full].loose, sizeof t->at[full].loose)))
        return rc;
    if (!f[3].v)
        return RC_OK;
    sf_child(sub, path, "sized");
    if ((rc = sf_map(c, f[3].v, sub, sized_keys, 2, z)) || (rc = sf_need(c, f[3].v, sub, &z[0], "figure")) ||
        (rc = sf_need(c, f[3].v, sub, &z[1], "run")))
        return rc;
    sf_child(sub2, sub, "figure");
    if ((rc = sf_number(c, z[0].v, sub2, -INFINITY, INFINITY, 0, "the measured figure, a finite number",
                        &t->at[full].sized_figure)))
        return rc;
    t->at[full].sized = 1;
    sf_child(sub2, sub, "run");
    return sf_threshold_text(c, z[1].v, sub2, t->at[full].sized_run, sizeof t->at[full].sized_run);
}

void threshold_gate_at(const threshold *t, int full, threshold_gate *out)
{
    int k = full ? 1 : 0;
    out->own = t->at[k].set;
    out->warn = t->at[k].warn_set ? t->at[k].warn : t->warn;
    out->fail = t->at[k].fail_set ? t->at[k].fail : t->fail;
    out->loose = t->at[k].loose[0] ? t->at[k].loose : t->loose;
    if (t->at[k].sized) {
        out->sized_size = full ? SIZED_FULL : SIZED_SMALL;
        out->sized_figure = t->at[k].sized_figure;
        out->sized_run = t->at[k].sized_run;
    } else {
        out->sized_size = t->sized_size;
        out->sized_figure = t->sized_figure;
        out->sized_run = t->sized_run;
    }
}

/* One metric's {warn, fail, why, loose, sized, small, full}. */
static rc_status sf_threshold(sf_ctx *c, yaml_node_t *v, const char *path, threshold *t)
{
    static const char *const keys[] = {"warn", "fail", "why", "loose", "sized", "small", "full"};
    char sub[SF_PATHLEN];
    sf_kv f[7];
    rc_status rc;
    if ((rc = sf_map(c, v, path, keys, 7, f)) || (rc = sf_need(c, v, path, &f[0], "warn")) ||
        (rc = sf_need(c, v, path, &f[1], "fail")))
        return rc;
    for (int k = 0; k < 2; k++) {
        sf_child(sub, path, keys[5 + k]);
        if (f[5 + k].v && (rc = sf_threshold_size(c, f[5 + k].v, sub, k, t)))
            return rc;
    }
    sf_child(sub, path, "warn");
    if ((rc = sf_number(c, f[0].v, sub, -INFINITY, INFINITY, 0, "a finite number", &t->warn)))
        return rc;
    sf_child(sub, path, "fail");
    if ((rc = sf_number(c, f[1].v, sub, -INFINITY, INFINITY, 0, "a finite number", &t->fail)))
        return rc;
    sf_child(sub, path, "why");
    if (f[2].v && (rc = sf_threshold_text(c, f[2].v, sub, t->why, sizeof t->why)))
        return rc;
    sf_child(sub, path, "loose");
    if (f[3].v && (rc = sf_threshold_text(c, f[3].v, sub, t->loose, sizeof t->loose)))
        return rc;
    sf_child(sub, path, "sized");
    return f[4].v ? sf_threshold_sized(c, f[4].v, sub, t) : RC_OK;
}

static rc_status sf_thresholds(sf_ctx *c, yaml_node_t *n, const char *path, comparison *cmp)
{
    char child[SF_PATHLEN];
    rc_status rc;
    if (n->type != YAML_MAPPING_NODE)
        return sf_fail(c, RC_ERR_PARSE, n, path,
                       "expected a map metric: {warn: x, fail: y, why: text}, got %s; allowed: "
                       "rel_rms: {warn: 5e-4, fail: 1e-3}",
                       sf_kind(n));
    long count = n->data.mapping.pairs.top - n->data.mapping.pairs.start;
    if (count > METRIC_MAX)
        return sf_fail(c, RC_ERR_RANGE, n, path, "%ld metrics; allowed: at most %d", count, METRIC_MAX);
    for (int i = 0; i < count; i++) {
        yaml_node_pair_t *p = &n->data.mapping.pairs.start[i];
        yaml_node_t *k = yaml_document_get_node(c->doc, p->key);
        yaml_node_t *v = yaml_document_get_node(c->doc, p->value);
        threshold *t = &cmp->thresholds[i];
        const char *name = k ? sf_text(k) : NULL;
        memset(t, 0, sizeof *t);
        if (!v || !name || !name[0] || strlen(name) >= sizeof t->metric)
            return sf_fail(c, RC_ERR_PARSE, k ? k : n, path,
                           "metric name missing or too long; allowed: a lower_snake_case name of at "
                           "most %zu characters",
                           sizeof t->metric - 1);
        for (const char *q = name; *q; q++)
            if (!sf_metric_char((unsigned char)*q))
                return sf_fail(c, RC_ERR_PARSE, k, path,
                               "metric name has a character outside a-z 0-9 _ .; allowed: e.g. "
                               "rel_rms, psnr, background.rel_rms");
        strcpy(t->metric, name);
        sf_child(child, path, name);
        for (int j = 0; j < i; j++)
            if (strcmp(cmp->thresholds[j].metric, name) == 0)
                return sf_fail(c, RC_ERR_PARSE, k, child, "duplicate metric; allowed: each once");
        if ((rc = sf_threshold(c, v, child, t)))
            return rc;
    }
    cmp->n_thresholds = (int)count;
    return RC_OK;
}

/* A renderer name: one of the table's (harness/renderers/registry.h). */
static rc_status sf_renderer(sf_ctx *c, yaml_node_t *n, const char *path, int *out)
{
    const char *names[16];
    int count = registry_count() < 16 ? registry_count() : 16;
    for (int i = 0; i < count; i++)
        names[i] = registry_name(i);
    return sf_enum(c, n, path, names, count, out);
}

static rc_status sf_comparisons(sf_ctx *c, yaml_node_t *n, scene *s)
{
    static const char *const keys[] = {"test", "reference", "role", "thresholds"};
    static const char *const roles[] = {"twin", "validate", "agree"};
    char path[SF_PATHLEN], child[SF_PATHLEN];
    long count;
    rc_status lrc = sf_list(c, n, "comparisons", "reference", SCENE_MAX_COMPARISONS, &count);
    if (lrc)
        return lrc;
    for (int i = 0; i < count; i++) {
        yaml_node_t *e = yaml_document_get_node(c->doc, n->data.sequence.items.start[i]);
        comparison *cmp = &s->comparisons[i];
        sf_kv f[4];
        rc_status rc;
        int v;
        sf_index(path, "comparisons", i);
        if (!e)
            return sf_fail(c, RC_ERR_PARSE, n, path, "missing item; allowed: a comparison map");
        if ((rc = sf_map(c, e, path, keys, 4, f)) || (rc = sf_need(c, e, path, &f[1], "reference")))
            return rc;
        cmp->test = registry_model();
        cmp->role = ROLE_TWIN;
        cmp->n_thresholds = 0;
        sf_child(child, path, "test");
        if (f[0].v) {
            if ((rc = sf_renderer(c, f[0].v, child, &v)))
                return rc;
            cmp->test = v;
        }
        sf_child(child, path, "reference");
        if ((rc = sf_renderer(c, f[1].v, child, &v)))
            return rc;
        cmp->reference = v;
        if (cmp->reference == cmp->test)
            return sf_fail(c, RC_ERR_RANGE, f[1].v, child, "reference equals test; allowed: two different renderers");
        sf_child(child, path, "role");
        if (f[2].v) {
            if ((rc = sf_enum(c, f[2].v, child, roles, 3, &v)))
                return rc;
            cmp->role = (comparison_role)v;
        }
        /* An agree measures one reference's physics by another: an approximation (a row with no
         * physics, like the model or EEVEE) on either side would make it a second validate. */
        for (int side = 0; cmp->role == ROLE_AGREE && side < 2; side++) {
            const renderer_row *row = registry_row(side ? cmp->reference : cmp->test);
            if (row != NULL && row->physics == NULL) {
                sf_child(child, path, side ? "reference" : "test");
                return sf_fail(c, RC_ERR_RANGE, f[side].v ? f[side].v : e, child,
                               "%s is an approximation, not a physical reference; allowed: an agree between two "
                               "physical references, or role validate (against a reference) or twin",
                               row->name);
            }
        }
        sf_child(child, path, "thresholds");
        if (f[3].v && (rc = sf_thresholds(c, f[3].v, child, cmp)))
            return rc;
    }
    s->n_comparisons = (int)count;
    return RC_OK;
}

/* A physics field's value as physics_describe writes it, in the scene file's YAML: booleans for
 * 0/1 flags, a light list "0+2" as [0, 2]. */
static void sf_physics_yaml(const char *key, const char *v, char *out, size_t len)
{
    static const char *const flags[] = {"env_diffuse", "env_specular", "shadows", "interreflection"};
    for (size_t i = 0; i < sizeof flags / sizeof flags[0]; i++)
        if (strcmp(key, flags[i]) == 0) {
            snprintf(out, len, "%s", strcmp(v, "0") != 0 ? "true" : "false");
            return;
        }
    if (!isdigit((unsigned char)v[0])) {
        snprintf(out, len, "%s", v);
        return;
    }
    size_t used = (size_t)snprintf(out, len, "%s", strstr(key, "_lights") ? "[" : "");
    for (const char *p = v; *p != '\0' && used + 3 < len; p++) {
        if (*p == '+') {
            out[used++] = ',';
            out[used++] = ' ';
        } else {
            out[used++] = *p;
        }
        out[used] = '\0';
    }
    if (strstr(key, "_lights") && used + 1 < len)
        snprintf(out + used, len - used, "]");
}

/* "key: value, ..." of the fields where rendered departs from want, in YAML; returns how many. */
static int sf_physics_fix(const physics *want, const physics *rendered, int n_lights, char *out, size_t len)
{
    char a[400], b[400], val[64];
    physics_describe(want, n_lights, a, sizeof a);
    physics_describe(rendered, n_lights, b, sizeof b);
    char *sa = NULL, *sb = NULL;
    size_t used = 0;
    int n = 0;
    out[0] = '\0';
    for (char *wa = strtok_r(a, " ", &sa), *wb = strtok_r(b, " ", &sb); wa != NULL && wb != NULL;
         wa = strtok_r(NULL, " ", &sa), wb = strtok_r(NULL, " ", &sb)) {
        char *eq = strchr(wb, '=');
        if (strcmp(wa, wb) == 0 || eq == NULL)
            continue;
        *eq = '\0';
        sf_physics_yaml(wb, eq + 1, val, sizeof val);
        if (used < len)
            used += (size_t)snprintf(out + used, len - used, "%s%s: %s", n ? ", " : "", wb, val);
        n++;
    }
    return n;
}

rc_status scene_file_physics_check(const scene *s, char *err, size_t errlen)
{
    static const char *const roles[] = {"twin", "validate", "agree"};
    for (int i = 0; i < s->n_comparisons; i++) {
        const comparison *c = &s->comparisons[i];
        for (int side = 0; c->role != ROLE_TWIN && side < 2; side++) {
            const renderer_row *row = registry_row(side ? c->reference : c->test);
            if (row == NULL || row->physics == NULL)
                continue;
            physics got;
            char why[700], diff[700], fix[300];
            const char *place = side ? "reference" : "test";
            rc_status st = row->physics(s, &got, why, sizeof why);
            if (st != RC_OK) {
                snprintf(err, errlen, "%s (comparisons[%d].%s: %s, role %s)", why, i, place, row->name, roles[c->role]);
                return st;
            }
            if (physics_diff(&s->physics, &got, s->n_lights, diff, sizeof diff) == 0)
                continue;
            sf_physics_fix(&s->physics, &got, s->n_lights, fix, sizeof fix);
            snprintf(err, errlen,
                     "%s: comparisons[%d].%s: %s cannot render the scene's physics (%s); allowed: set physics: {%s}, "
                     "or name another reference",
                     s->path, i, place, row->name, diff, fix);
            return RC_ERR_RANGE;
        }
    }
    return RC_OK;
}

/* A light mask: `all`, `none`, or a list of light indices (each < the number of lights). */
static rc_status sf_light_mask(sf_ctx *c, yaml_node_t *n, const char *path, const scene *s, unsigned *out)
{
    char allowed[96], child[SF_PATHLEN];
    snprintf(allowed, sizeof allowed, "all, none, or a list of light indices 0..%d", s->n_lights - 1);
    if (n->type == YAML_SCALAR_NODE) {
        static const char *const words[] = {"all", "none"};
        int w;
        rc_status rc = sf_enum(c, n, path, words, 2, &w);
        if (rc)
            return rc;
        *out = w == 0 ? PHYSICS_ALL_LIGHTS : 0u;
        return RC_OK;
    }
    if (n->type != YAML_SEQUENCE_NODE)
        return sf_fail(c, RC_ERR_PARSE, n, path, "expected a word or a list, got %s; allowed: %s", sf_kind(n), allowed);
    unsigned mask = 0;
    int i = 0;
    for (yaml_node_item_t *it = n->data.sequence.items.start; it < n->data.sequence.items.top; it++, i++) {
        yaml_node_t *e = yaml_document_get_node(c->doc, *it);
        int li;
        sf_index(child, path, i);
        if (!e)
            return sf_fail(c, RC_ERR_PARSE, n, child, "missing item; allowed: %s", allowed);
        if (s->n_lights == 0)
            return sf_fail(c, RC_ERR_RANGE, e, child, "the scene has no lights; allowed: all or none");
        rc_status rc = sf_int(c, e, child, 0, s->n_lights - 1, &li);
        if (rc)
            return rc;
        if (mask & (1u << li))
            return sf_fail(c, RC_ERR_PARSE, e, child, "light %d listed twice; allowed: each index once", li);
        mask |= 1u << li;
    }
    *out = mask;
    return RC_OK;
}

enum {
    PK_DIFFUSE_LIGHTS,
    PK_SPECULAR_LIGHTS,
    PK_ENV_DIFFUSE,
    PK_ENV_SPECULAR,
    PK_BOUNCES,
    PK_SHADOWS,
    PK_INTERREFLECTION,
    PK_FRESNEL_SPECULAR,
    PK_FRESNEL_REFLECTION,
    PK_DIFFUSE_WEIGHT,
    PK_COUNT
};

/* After the lights: a light mask names light indices. */
static rc_status sf_physics(sf_ctx *c, yaml_node_t *n, scene *s)
{
    static const char *const keys[PK_COUNT] = {
        "diffuse_lights", "specular_lights", "env_diffuse",      "env_specular",       "bounces",
        "shadows",        "interreflection", "fresnel_specular", "fresnel_reflection", "diffuse_weight"};
    physics *p = &s->physics;
    sf_kv f[PK_COUNT];
    char child[SF_PATHLEN];
    rc_status rc;
    int v;
    if ((rc = sf_map(c, n, "physics", keys, PK_COUNT, f)))
        return rc;
    if (f[PK_DIFFUSE_LIGHTS].v &&
        (rc = sf_light_mask(c, f[PK_DIFFUSE_LIGHTS].v, "physics.diffuse_lights", s, &p->diffuse_lights)))
        return rc;
    if (f[PK_SPECULAR_LIGHTS].v &&
        (rc = sf_light_mask(c, f[PK_SPECULAR_LIGHTS].v, "physics.specular_lights", s, &p->specular_lights)))
        return rc;
    if (f[PK_ENV_DIFFUSE].v && (rc = sf_bool(c, f[PK_ENV_DIFFUSE].v, "physics.env_diffuse", &p->env_diffuse)))
        return rc;
    if (f[PK_ENV_SPECULAR].v && (rc = sf_bool(c, f[PK_ENV_SPECULAR].v, "physics.env_specular", &p->env_specular)))
        return rc;
    if (f[PK_BOUNCES].v && (rc = sf_int(c, f[PK_BOUNCES].v, "physics.bounces", 1, 64, &p->bounces)))
        return rc;
    if (f[PK_SHADOWS].v && (rc = sf_bool(c, f[PK_SHADOWS].v, "physics.shadows", &p->shadows)))
        return rc;
    if (f[PK_INTERREFLECTION].v &&
        (rc = sf_bool(c, f[PK_INTERREFLECTION].v, "physics.interreflection", &p->interreflection)))
        return rc;
    if (f[PK_FRESNEL_SPECULAR].v) {
        if ((rc = sf_enum(c, f[PK_FRESNEL_SPECULAR].v, "physics.fresnel_specular", physics_fresnel_names, 4, &v)))
            return rc;
        p->fresnel_specular = (physics_fresnel)v;
    }
    if (f[PK_FRESNEL_REFLECTION].v) {
        if ((rc = sf_enum(c, f[PK_FRESNEL_REFLECTION].v, "physics.fresnel_reflection", physics_fresnel_names, 4, &v)))
            return rc;
        p->fresnel_reflection = (physics_fresnel)v;
    }
    if (f[PK_DIFFUSE_WEIGHT].v) {
        if ((rc = sf_enum(c, f[PK_DIFFUSE_WEIGHT].v, "physics.diffuse_weight", physics_diffuse_weight_names, 2, &v)))
            return rc;
        p->diffuse_weight = (physics_diffuse_weight)v;
    }
    /* Without inter-reflection a second scattering event has nothing to hit. */
    if (p->bounces > 1 && !p->interreflection) {
        sf_child(child, "physics", "bounces");
        return sf_fail(c, RC_ERR_RANGE, f[PK_BOUNCES].v, child,
                       "%d bounces without inter-reflection reach nothing; allowed: 1, or set "
                       "interreflection: true",
                       p->bounces);
    }
    return RC_OK;
}

enum {
    TK_NAME,
    TK_IMAGE,
    TK_CAMERA,
    TK_AMBIENT,
    TK_ENV,
    TK_LIGHTS,
    TK_MATERIALS,
    TK_OBJECTS,
    TK_COMPARISONS,
    TK_PHYSICS,
    TK_COUNT
};

static rc_status sf_top(sf_ctx *c, yaml_node_t *root, scene *s)
{
    static const char *const keys[TK_COUNT] = {"name",   "image",     "camera",  "ambient",     "environment",
                                               "lights", "materials", "objects", "comparisons", "physics"};
    sf_kv f[TK_COUNT];
    rc_status rc;
    if ((rc = sf_map(c, root, "", keys, TK_COUNT, f)) || (rc = sf_need(c, root, "", &f[TK_IMAGE], "image")) ||
        (rc = sf_need(c, root, "", &f[TK_CAMERA], "camera")))
        return rc;
    if (f[TK_NAME].v && (rc = sf_scene_name(c, f[TK_NAME].v, s->name)))
        return rc;
    if (!f[TK_NAME].v && c->default_bad)
        return sf_fail(c, RC_ERR_RANGE, root, "name",
                       "no name: key, and the file name gives '%s', which is not a name (%s); allowed: add "
                       "name: with %s",
                       c->default_bad, c->default_why, SCENE_NAME_RULE);
    if ((rc = sf_image(c, f[TK_IMAGE].v, s)) || (rc = sf_camera(c, f[TK_CAMERA].v, s)))
        return rc;
    if (f[TK_AMBIENT].v && (rc = sf_colour(c, f[TK_AMBIENT].v, "ambient", &s->global_ambient)))
        return rc;
    if (f[TK_ENV].v && (rc = sf_environment(c, f[TK_ENV].v, s)))
        return rc;
    if (f[TK_LIGHTS].v && (rc = sf_lights(c, f[TK_LIGHTS].v, s)))
        return rc;
    if (f[TK_PHYSICS].v && (rc = sf_physics(c, f[TK_PHYSICS].v, s)))
        return rc;
    /* Materials before objects, whatever the order in the file: objects refer to them by name. */
    if (f[TK_MATERIALS].v && (rc = sf_materials(c, f[TK_MATERIALS].v, s)))
        return rc;
    if (f[TK_OBJECTS].v && (rc = sf_objects(c, f[TK_OBJECTS].v, s)))
        return rc;
    if (f[TK_COMPARISONS].v && (rc = sf_comparisons(c, f[TK_COMPARISONS].v, s)))
        return rc;
    return RC_OK;
}

static rc_status sf_yaml_error(sf_ctx *c, const yaml_parser_t *p)
{
    const char *problem = p->problem ? p->problem : "malformed YAML";
    if (p->error == YAML_MEMORY_ERROR)
        return sf_fail(c, RC_ERR_NOMEM, NULL, "(yaml)", "out of memory; allowed: a smaller file");
    if (p->error == YAML_READER_ERROR)
        return sf_fail_at(c, RC_ERR_PARSE, p->problem_mark, "(yaml)",
                          "%s at byte %zu; allowed: UTF-8 text without control characters", problem, p->problem_offset);
    return sf_fail_at(c, RC_ERR_PARSE, p->problem_mark, "(yaml)",
                      "%s%s%s; allowed: valid YAML (check indentation, brackets, quotes, and that "
                      "lists use '- ' or [a, b])",
                      problem, p->context ? " " : "", p->context ? p->context : "");
}

/* Pass 1: refuse nesting deeper than SF_MAX_DEPTH before libyaml's quadratic scanner sees it. */
static rc_status sf_depth_check(sf_ctx *c, const char *text, size_t len)
{
    yaml_parser_t p;
    yaml_event_t e;
    int depth = 0;
    rc_status rc = RC_OK;
    if (!yaml_parser_initialize(&p))
        return sf_fail(c, RC_ERR_NOMEM, NULL, "(yaml)", "out of memory; allowed: a smaller file");
    yaml_parser_set_input_string(&p, (const unsigned char *)text, len);
    for (;;) {
        if (!yaml_parser_parse(&p, &e)) {
            rc = sf_yaml_error(c, &p);
            break;
        }
        yaml_event_type_t t = e.type;
        yaml_mark_t m = e.start_mark;
        yaml_event_delete(&e);
        if (t == YAML_SEQUENCE_START_EVENT || t == YAML_MAPPING_START_EVENT)
            depth++;
        else if (t == YAML_SEQUENCE_END_EVENT || t == YAML_MAPPING_END_EVENT)
            depth--;
        if (depth > SF_MAX_DEPTH) {
            rc = sf_fail_at(c, RC_ERR_PARSE, m, "(yaml)",
                            "nesting deeper than %d levels; allowed: the scene format's 4 levels", SF_MAX_DEPTH);
            break;
        }
        if (t == YAML_STREAM_END_EVENT)
            break;
    }
    yaml_parser_delete(&p);
    return rc;
}

rc_status scene_file_parse(const char *text, size_t len, const char *path_for_messages, scene *out, char *err,
                           size_t errlen)
{
    sf_ctx c;
    memset(&c, 0, sizeof c);
    c.file = path_for_messages ? path_for_messages : "<string>";
    c.err = err;
    c.errlen = errlen;
    if (err && errlen)
        err[0] = '\0';
    if (!text && len)
        return sf_fail(&c, RC_ERR_IO, NULL, "(file)", "no text given; allowed: a buffer");
    if (len > SCENE_FILE_MAX_BYTES)
        return sf_fail(&c, RC_ERR_RANGE, NULL, "(file)",
                       "file is %zu bytes; allowed: at most %u bytes (scene files are hand-written)", len,
                       SCENE_FILE_MAX_BYTES);
    if (path_for_messages && strlen(path_for_messages) >= SCENE_PATH_MAX)
        return sf_fail(&c, RC_ERR_RANGE, NULL, "(file)", "scene file path too long; allowed: at most %d bytes",
                       SCENE_PATH_MAX - 1);
    if (path_for_messages) {
        const char *slash = strrchr(path_for_messages, '/');
        if (slash)
            snprintf(c.dir, sizeof c.dir, "%.*s", (int)(slash - path_for_messages + 1), path_for_messages);
    }

    rc_status rc = sf_depth_check(&c, text ? text : "", len);
    if (rc)
        return rc;

    scene *s = malloc(sizeof *s);
    yaml_parser_t p;
    yaml_document_t doc, extra;
    if (!s)
        return sf_fail(&c, RC_ERR_NOMEM, NULL, "(file)", "out of memory; allowed: -");
    if (!yaml_parser_initialize(&p)) {
        free(s);
        return sf_fail(&c, RC_ERR_NOMEM, NULL, "(yaml)", "out of memory; allowed: -");
    }
    yaml_parser_set_input_string(&p, (const unsigned char *)(text ? text : ""), len);
    if (!yaml_parser_load(&p, &doc)) {
        rc = sf_yaml_error(&c, &p);
        yaml_parser_delete(&p);
        free(s);
        return rc;
    }
    c.doc = &doc;
    scene_init(s);
    s->hash = scene_file_hash(text ? text : "", len);
    if (path_for_messages)
        snprintf(s->path, sizeof s->path, "%s", path_for_messages);
    char derived[SCENE_NAME_MAX];
    if (path_for_messages) {
        /* Default name: the file's base name up to its first '.', sanitised (model/scene.h) and
         * then checked like a `name:`. The name becomes folder names, make targets and page
         * names, so a file called `x;id>y.yaml` or `<!--<script>.yaml` must not carry its
         * characters into them, and `.yaml` (no name) or `plots.yaml` (a folder the report
         * writes) must not give a name at all without a `name:` key; two files that map to one name are refused where
         * names must be unique (plan, compare). */
        const char *base = strrchr(c.file, '/');
        base = base ? base + 1 : c.file;
        scene_name_sanitise(base, strcspn(base, "."), derived);
        if (scene_name_check(derived, c.default_why, sizeof c.default_why))
            snprintf(s->name, sizeof s->name, "%s", derived);
        else
            c.default_bad = derived;
    }

    yaml_node_t *root = yaml_document_get_root_node(&doc);
    if (!root)
        rc = sf_fail(&c, RC_ERR_PARSE, NULL, "(top level)",
                     "empty scene file; allowed: a map with at least image: and camera:");
    else
        rc = sf_top(&c, root, s);
    yaml_document_delete(&doc);
    if (rc == RC_OK) {
        if (!yaml_parser_load(&p, &extra)) {
            rc = sf_yaml_error(&c, &p);
        } else {
            yaml_node_t *r2 = yaml_document_get_root_node(&extra);
            if (r2)
                rc = sf_fail(&c, RC_ERR_PARSE, r2, "(file)",
                             "a second YAML document ('---'); allowed: one document per file");
            yaml_document_delete(&extra);
        }
    }
    yaml_parser_delete(&p);
    if (rc == RC_OK)
        *out = *s;
    free(s);
    return rc;
}

rc_status scene_file_load(const char *path, scene *out, char *err, size_t errlen)
{
    sf_ctx c;
    memset(&c, 0, sizeof c);
    c.file = path ? path : "(null)";
    c.err = err;
    c.errlen = errlen;
    if (!path)
        return sf_fail(&c, RC_ERR_IO, NULL, "(file)", "no path given; allowed: a scene file path");
    /* A regular file of at most the limit, checked before reading: /dev/zero, a FIFO or a
     * directory is refused by kind, never read or waited on. */
    int fd;
    long long size = 0;
    char why[SCENE_PATH_MAX + 200];
    rc_status orc = fileio_open_input(path, SCENE_FILE_MAX_BYTES, "a YAML scene file", &fd, &size, why, sizeof why);
    if (orc != RC_OK)
        return sf_fail(&c, orc, NULL, "(file)", "%s; allowed: a hand-written scene file (regular, at most %u bytes)",
                       why, SCENE_FILE_MAX_BYTES);
    char *buf = malloc((size_t)size + 1);
    if (!buf) {
        close(fd);
        return sf_fail(&c, RC_ERR_NOMEM, NULL, "(file)", "out of memory; allowed: -");
    }
    /* At most the size fstat gave: a file growing meanwhile is cut there, never read without end. */
    size_t len = 0;
    while (len < (size_t)size) {
        ssize_t r = read(fd, buf + len, (size_t)size - len);
        if (r < 0 && errno == EINTR)
            continue;
        if (r < 0) {
            int e = errno;
            close(fd);
            free(buf);
            return sf_fail(&c, RC_ERR_IO, NULL, "(file)", "read error (%s); allowed: a readable file", strerror(e));
        }
        if (r == 0)
            break;
        len += (size_t)r;
    }
    close(fd);
    rc_status rc = scene_file_parse(buf, len, path, out, err, errlen);
    free(buf);
    return rc;
}
