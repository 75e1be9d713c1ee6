/* mesh_ply.c - the PLY reader (ascii and binary_little_endian): the header's elements and
 * properties, then the vertex (x y z, nx ny nz, texture coordinates, colours) and face
 * (vertex_indices) elements into a polygon soup (mesh_internal.h); other elements are read past.
 * Debian 12 ships no C library for PLY (rply is not packaged), so the reader is here: small and
 * bounds-checked, on the whole file read into memory (mesh.c).
 */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mesh_internal.h"
#include "status.h"

typedef enum { PLY_I8, PLY_U8, PLY_I16, PLY_U16, PLY_I32, PLY_U32, PLY_F32, PLY_F64, PLY_BAD } ply_type;

#define PLY_MAX_ELEMENTS 16
#define PLY_MAX_PROPS    32

typedef struct {
    char name[40];
    ply_type type;
    int is_list;
    ply_type count_type;
} ply_prop;

typedef struct {
    char name[40];
    long count;
    int n_props;
    ply_prop props[PLY_MAX_PROPS];
} ply_element;

static ply_type ply_type_of(const char *s)
{
    static const char *const names[][2] = {{"char", "int8"},     {"uchar", "uint8"},   {"short", "int16"},
                                           {"ushort", "uint16"}, {"int", "int32"},     {"uint", "uint32"},
                                           {"float", "float32"}, {"double", "float64"}};
    for (int i = 0; i < 8; i++)
        if (strcmp(s, names[i][0]) == 0 || strcmp(s, names[i][1]) == 0)
            return (ply_type)i;
    return PLY_BAD;
}

static size_t ply_size(ply_type t)
{
    static const size_t sz[] = {1, 1, 2, 2, 4, 4, 4, 8};
    return sz[t];
}

typedef struct {
    const unsigned char *p, *end;
    int binary;
    int line;     /* ascii: the line of the last token read (the data start after end_header) */
    char tok[64]; /* ascii: the last token as written, for messages */
} ply_reader;

/* What ply_read found: a value, the end of the data (or a token that is not a number), or, in
 * an ascii file, a number its integer type cannot hold (binary integers always fit). */
typedef enum { PLY_VALUE_OK = 0, PLY_VALUE_END, PLY_VALUE_NOT_WHOLE, PLY_VALUE_RANGE } ply_value;

static const char *const ply_type_names[] = {"char", "uchar", "short", "ushort", "int", "uint", "float", "double"};
/* Each integer type's range; the doubles hold them exactly (|v| <= 2^32). */
static const double ply_type_lo[] = {-128, 0, -32768, 0, -2147483648.0, 0};
static const double ply_type_hi[] = {127, 255, 32767, 65535, 2147483647.0, 4294967295.0};

static ply_value ply_read_binary(ply_reader *r, ply_type t, double *out)
{
    size_t n = ply_size(t);
    if ((size_t)(r->end - r->p) < n)
        return PLY_VALUE_END;
    uint64_t u = 0;
    for (size_t i = 0; i < n; i++)
        u |= (uint64_t)r->p[i] << (8 * i);
    r->p += n;
    switch (t) {
    case PLY_I8: *out = (int8_t)u; break;
    case PLY_U8: *out = (uint8_t)u; break;
    case PLY_I16: *out = (int16_t)u; break;
    case PLY_U16: *out = (uint16_t)u; break;
    case PLY_I32: *out = (int32_t)u; break;
    case PLY_U32: *out = (uint32_t)u; break;
    case PLY_F32: {
        uint32_t w = (uint32_t)u;
        float f;
        memcpy(&f, &w, sizeof f);
        *out = f;
        break;
    }
    default: {
        double d;
        memcpy(&d, &u, sizeof d);
        *out = d;
    }
    }
    return PLY_VALUE_OK;
}

/* One value as double. An ascii value of an integer type must be a whole number within the
 * type's range: a uchar colour of 300 or -5 is refused, not read as 300/255 or wrapped. */
static ply_value ply_read(ply_reader *r, ply_type t, double *out)
{
    if (r->binary)
        return ply_read_binary(r, t, out);
    while (r->p < r->end && (*r->p == ' ' || *r->p == '\t' || *r->p == '\n' || *r->p == '\r'))
        r->line += *r->p++ == '\n';
    if (r->p >= r->end)
        return PLY_VALUE_END;
    size_t n = 0;
    while (r->p < r->end && *r->p != ' ' && *r->p != '\t' && *r->p != '\n' && *r->p != '\r') {
        if (n + 1 >= sizeof r->tok)
            return PLY_VALUE_END;
        r->tok[n++] = (char)*r->p++;
    }
    r->tok[n] = '\0';
    char *e;
    *out = strtod(r->tok, &e);
    if (*e != '\0')
        return PLY_VALUE_END;
    if (t >= PLY_F32)
        return PLY_VALUE_OK;
    if (*out != floor(*out))
        return PLY_VALUE_NOT_WHOLE; /* also NaN and Inf */
    return *out >= ply_type_lo[t] && *out <= ply_type_hi[t] ? PLY_VALUE_OK : PLY_VALUE_RANGE;
}

/* The message for a value ply_read refused: in an ascii file with its line and the token as
 * written; what names the element, its index and the property. */
static rc_status ply_value_error(const ply_reader *r, ply_value v, ply_type t, const char *label, const char *what,
                                 char *err, size_t errlen)
{
    if (v == PLY_VALUE_END) {
        status_message(err, errlen,
                       "%s: PLY data ends early or holds a malformed number (%s); fix: a complete file matching its "
                       "header",
                       label, what);
        return RC_ERR_PARSE;
    }
    char range[64];
    snprintf(range, sizeof range, "%.0f..%.0f", ply_type_lo[t], ply_type_hi[t]);
    if (v == PLY_VALUE_NOT_WHOLE)
        status_message(err, errlen, "%s:%d: %s: '%s' is not a whole number, but its type is %s; fix: an integer in %s",
                       label, r->line, what, r->tok, ply_type_names[t], range);
    else
        status_message(err, errlen,
                       "%s:%d: %s: '%s' is outside the range of its type %s; fix: a value in %s, or declare the "
                       "property with a wider type",
                       label, r->line, what, r->tok, ply_type_names[t], range);
    return RC_ERR_RANGE;
}

static int ply_keyword(const char *w)
{
    static const char *const k[] = {"comment", "obj_info", "format", "element", "property", "end_header"};
    for (size_t i = 0; i < sizeof k / sizeof *k; i++)
        if (strcmp(w, k[i]) == 0)
            return 1;
    return 0;
}

static int ply_has_element(const ply_element *el, int n, const char *name)
{
    for (int i = 0; i < n; i++)
        if (strcmp(el[i].name, name) == 0)
            return 1;
    return 0;
}

/* The vertex element's colour properties: red green blue (or diffuse_red ...) as colour1,
 * specular_red ... as colour2, each only as a set of three. Integer colours are scaled by their type's
 * largest value (uchar 255, ushort 65535), float ones taken as linear RGB. */
static rc_status ply_colour_props(const ply_element *x, const char *label, int ic[6], double scale[6], int *bits,
                                  char *err, size_t errlen)
{
    static const char *const names[3][6] = {{"red", "green", "blue", "", "", ""},
                                            {"diffuse_red", "diffuse_green", "diffuse_blue", "", "", ""},
                                            {"", "", "", "specular_red", "specular_green", "specular_blue"}};
    for (int c = 0; c < 6; c++)
        ic[c] = -1;
    *bits = 0;
    for (int k = 0; k < x->n_props; k++) {
        const ply_prop *pr = &x->props[k];
        for (int v = 0; v < 3; v++)
            for (int c = 0; c < 6; c++) {
                if (pr->is_list || !names[v][c][0] || strcmp(pr->name, names[v][c]) != 0)
                    continue;
                if (pr->type != PLY_U8 && pr->type != PLY_U16 && pr->type != PLY_F32 && pr->type != PLY_F64) {
                    status_message(err, errlen,
                                   "%s: vertex colour property %s has a signed or 32-bit integer type; fix: uchar, "
                                   "ushort, float or double",
                                   label, pr->name);
                    return RC_ERR_PARSE;
                }
                ic[c] = k;
                scale[c] = pr->type == PLY_U8 ? 1.0 / 255.0 : pr->type == PLY_U16 ? 1.0 / 65535.0 : 1.0;
            }
    }
    for (int g = 0; g < 2; g++) {
        int n = (ic[3 * g] >= 0) + (ic[3 * g + 1] >= 0) + (ic[3 * g + 2] >= 0);
        /* An incomplete set (a lone `red`) is another property of the file's, not a colour. */
        if (n == 3)
            *bits |= 1 << g;
        else
            ic[3 * g] = ic[3 * g + 1] = ic[3 * g + 2] = -1;
    }
    return RC_OK;
}

/* --- the header ------------------------------------------------------------------------- */

/* One header line as words: at most 6 of at most 39 characters; long_word says the line had
 * more or longer ones (which only a comment or obj_info may have). */
typedef struct {
    char w[6][40];
    int nw, long_word;
} ply_words;

/* The header as read: its elements, the data's format (-1 until a format line) and where the
 * data start. */
typedef struct {
    ply_element el[PLY_MAX_ELEMENTS];
    int n_el, binary, line;
    const char *data;
} ply_header;

/* Header line `line` at *p into words; *p moves past it. */
static rc_status ply_header_words(const char **p, const char *end, int line, ply_words *out, const char *label,
                                  char *err, size_t errlen)
{
    char text[256];
    const char *nl = memchr(*p, '\n', (size_t)(end - *p));
    if (!nl) {
        status_message(err, errlen, "%s:%d: PLY header has no end_header line; fix: a complete PLY file", label, line);
        return RC_ERR_PARSE;
    }
    size_t n = (size_t)(nl - *p);
    if (n >= sizeof text || memchr(*p, '\0', n)) {
        status_message(err, errlen, "%s:%d: PLY header line too long or holding a NUL byte; fix: a valid PLY header",
                       label, line);
        return RC_ERR_PARSE;
    }
    memcpy(text, *p, n);
    text[n] = '\0';
    if (n && text[n - 1] == '\r')
        text[n - 1] = '\0';
    *p = nl + 1;
    out->nw = out->long_word = 0;
    for (char *tk = strtok(text, " \t"); tk; tk = strtok(NULL, " \t")) {
        if (out->nw == 6 || strlen(tk) >= sizeof out->w[0]) {
            out->long_word = 1;
            break;
        }
        strcpy(out->w[out->nw++], tk);
    }
    return RC_OK;
}

/* `format ascii 1.0` or `format binary_little_endian 1.0`. */
static rc_status ply_header_format(ply_header *h, const ply_words *wd, const char *label, char *err, size_t errlen)
{
    if (strcmp(wd->w[1], "ascii") == 0) {
        h->binary = 0;
    } else if (strcmp(wd->w[1], "binary_little_endian") == 0) {
        h->binary = 1;
    } else {
        status_message(err, errlen, "%s:%d: PLY format '%s' not supported; fix: ascii or binary_little_endian", label,
                       h->line, wd->w[1]);
        return RC_ERR_PARSE;
    }
    return RC_OK;
}

/* `element name count`: a count no larger than the file's bytes (each item takes at least one). */
static rc_status ply_header_element(ply_header *h, const ply_words *wd, size_t len, const char *label, char *err,
                                    size_t errlen)
{
    char *e;
    long count = strtol(wd->w[2], &e, 10);
    if (*e || count < 0 || (size_t)count > len || h->n_el == PLY_MAX_ELEMENTS) {
        status_message(err, errlen,
                       "%s:%d: bad element line (count %s, %d elements so far); fix: "
                       "'element name count' with a count the file can hold, at most %d elements",
                       label, h->line, wd->w[2], h->n_el, PLY_MAX_ELEMENTS);
        return RC_ERR_PARSE;
    }
    ply_element *x = &h->el[h->n_el++];
    memset(x, 0, sizeof *x);
    snprintf(x->name, sizeof x->name, "%s", wd->w[1]);
    x->count = count;
    return RC_OK;
}

/* "property <type> <name>" or "property list <count type> <item type> <name>", of the last
 * element (the caller checked there is one with room). */
static rc_status ply_header_property(ply_header *h, const ply_words *wd, const char *label, char *err, size_t errlen)
{
    int nw = wd->nw;
    ply_element *x = &h->el[h->n_el - 1];
    ply_prop *pr = &x->props[x->n_props++];
    memset(pr, 0, sizeof *pr);
    pr->is_list = nw == 5;
    pr->type = ply_type_of(wd->w[nw - 2]);
    pr->count_type = pr->is_list ? ply_type_of(wd->w[2]) : PLY_U8;
    snprintf(pr->name, sizeof pr->name, "%s", wd->w[nw - 1]);
    if (pr->type == PLY_BAD || pr->count_type == PLY_BAD ||
        (pr->is_list && (pr->count_type == PLY_F32 || pr->count_type == PLY_F64))) {
        status_message(err, errlen,
                       "%s:%d: unknown PLY property type; fix: char uchar short ushort "
                       "int uint float double (or int8 ... float64), integer list counts",
                       label, h->line);
        return RC_ERR_PARSE;
    }
    return RC_OK;
}

/* A format, element or property line (anything else is refused). */
static rc_status ply_header_statement(ply_header *h, const ply_words *wd, size_t len, const char *label, char *err,
                                      size_t errlen)
{
    const char *w0 = wd->w[0];
    int nw = wd->nw;
    if (strcmp(w0, "format") == 0 && nw == 3)
        return ply_header_format(h, wd, label, err, errlen);
    if (strcmp(w0, "element") == 0 && nw == 3)
        return ply_header_element(h, wd, len, label, err, errlen);
    if (strcmp(w0, "property") == 0 && h->n_el > 0 && h->el[h->n_el - 1].n_props < PLY_MAX_PROPS &&
        (nw == 3 || (nw == 5 && strcmp(wd->w[1], "list") == 0)))
        return ply_header_property(h, wd, label, err, errlen);
    status_message(err, errlen,
                   "%s:%d: unexpected PLY header line '%s'; fix: format, element, property, comment, end_header", label,
                   h->line, w0);
    return RC_ERR_PARSE;
}

/* Whether a line of words is one the header skips: empty, a comment or obj_info. */
static int ply_header_note(const ply_words *wd)
{
    return wd->nw == 0 || strcmp(wd->w[0], "comment") == 0 || strcmp(wd->w[0], "obj_info") == 0;
}

/* The header, from the `ply` line to end_header; h->data is where the data start. */
static rc_status ply_header_read(const char *buf, size_t len, const char *label, ply_header *h, char *err,
                                 size_t errlen)
{
    const char *p = buf, *end = buf + len;
    h->n_el = h->line = 0;
    h->binary = -1;
    for (;;) {
        ply_words wd;
        rc_status rc = ply_header_words(&p, end, ++h->line, &wd, label, err, errlen);
        if (rc != RC_OK)
            return rc;
        if (wd.nw > 0 && h->line > 1 && !ply_keyword(wd.w[0])) {
            status_message(err, errlen,
                           "%s:%d: '%s' is not a PLY header keyword (malformed header; a comment needs "
                           "'comment'); fix: format, element, property, comment, obj_info, end_header",
                           label, h->line, wd.w[0]);
            return RC_ERR_PARSE;
        }
        if (wd.long_word && !(wd.nw > 0 && ply_header_note(&wd))) {
            status_message(err, errlen,
                           "%s:%d: PLY header line has too many or too long words; fix: a valid PLY header", label,
                           h->line);
            return RC_ERR_PARSE;
        }
        if (h->line == 1) {
            if (wd.nw != 1 || strcmp(wd.w[0], "ply") != 0) {
                status_message(err, errlen, "%s:1: not a PLY file (first line must be 'ply'); fix: export as PLY",
                               label);
                return RC_ERR_PARSE;
            }
            continue;
        }
        if (ply_header_note(&wd))
            continue;
        if (strcmp(wd.w[0], "end_header") == 0)
            break;
        if ((rc = ply_header_statement(h, &wd, len, label, err, errlen)) != RC_OK)
            return rc;
    }
    h->data = p;
    if (h->binary < 0) {
        status_message(err, errlen, "%s: PLY header has no format line; fix: 'format ascii 1.0'", label);
        return RC_ERR_PARSE;
    }
    if (!ply_has_element(h->el, h->n_el, "face")) {
        status_message(err, errlen,
                       "%s: PLY has no face element (a point cloud, or faces declared inside another "
                       "element); fix: vertex and face elements",
                       label);
        return RC_ERR_PARSE;
    }
    return RC_OK;
}

/* --- the data ---------------------------------------------------------------------------- */

static const char *const ply_xyz_names[6] = {"x", "y", "z", "nx", "ny", "nz"};

/* What the elements read so far brought: have_vertex 0 (none yet), 1 (positions) or 2 (and
 * normals); uv: the vertices carry texture coordinates. */
typedef struct {
    int have_vertex, have_face, uv;
} ply_state;

/* What an element's properties mean to the soup: the property index of x y z nx ny nz, of u v,
 * of each colour channel (with its scale; cbits as mesh_soup_colour's) and of the face's index
 * list, -1 where absent. */
typedef struct {
    int is_vertex, is_face;
    int ix[6], iuv[2], ic[6], iface, cbits;
    double cscale[6];
} ply_layout;

/* One item's values as read (zero where the element has no such property). */
typedef struct {
    double xyz[6], uv[2], col[6];
} ply_item;

/* The property indices of x's positions, normals, texture coordinates (the names the PLY writers
 * use: Blender s t, others u v or texture_u texture_v) and face index list. */
static void ply_layout_find(const ply_element *x, ply_layout *lay)
{
    static const char *const uvn[3][2] = {{"u", "v"}, {"s", "t"}, {"texture_u", "texture_v"}};
    for (int k = 0; k < x->n_props; k++) {
        const ply_prop *pr = &x->props[k];
        for (int c = 0; c < 6; c++)
            if (!pr->is_list && strcmp(pr->name, ply_xyz_names[c]) == 0)
                lay->ix[c] = k;
        for (int q = 0; q < 3; q++)
            for (int c = 0; c < 2; c++)
                if (!pr->is_list && strcmp(pr->name, uvn[q][c]) == 0)
                    lay->iuv[c] = k;
        if (pr->is_list && (strcmp(pr->name, "vertex_indices") == 0 || strcmp(pr->name, "vertex_index") == 0))
            lay->iface = k;
    }
}

/* The vertex element: once, with x y z, all or none of nx ny nz and of u v, and its colours. */
static rc_status ply_layout_vertex(const ply_element *x, ply_layout *lay, ply_state *st, const char *label, char *err,
                                   size_t errlen)
{
    const int *ix = lay->ix;
    if (st->have_vertex || ix[0] < 0 || ix[1] < 0 || ix[2] < 0) {
        status_message(err, errlen, "%s: vertex element %s; fix: one vertex element with x, y, z", label,
                       st->have_vertex ? "given twice" : "lacks x, y or z");
        return RC_ERR_PARSE;
    }
    int nn = (ix[3] >= 0) + (ix[4] >= 0) + (ix[5] >= 0);
    if (nn != 0 && nn != 3) {
        status_message(err, errlen, "%s: vertex has only some of nx, ny, nz; fix: all three or none", label);
        return RC_ERR_PARSE;
    }
    st->have_vertex = 1 + (nn == 3);
    if ((lay->iuv[0] >= 0) != (lay->iuv[1] >= 0)) {
        status_message(err, errlen,
                       "%s: vertex has only one texture coordinate; fix: both of u v (or s t, "
                       "texture_u texture_v) or neither",
                       label);
        return RC_ERR_PARSE;
    }
    st->uv = lay->iuv[0] >= 0;
    return ply_colour_props(x, label, lay->ic, lay->cscale, &lay->cbits, err, errlen);
}

/* The face element: once, after the vertex element, with a vertex_indices list. */
static rc_status ply_layout_face(ply_layout *lay, ply_state *st, const char *label, char *err, size_t errlen)
{
    if (!st->have_vertex || st->have_face || lay->iface < 0) {
        status_message(err, errlen,
                       "%s: face element %s; fix: vertex element first, then one "
                       "face element with a vertex_indices list",
                       label,
                       !st->have_vertex ? "before the vertex element"
                       : st->have_face  ? "given twice"
                                        : "lacks vertex_indices");
        return RC_ERR_PARSE;
    }
    st->have_face = 1;
    return RC_OK;
}

/* Element x's layout, checked against what the elements before it brought. */
static rc_status ply_layout_of(const ply_element *x, ply_layout *lay, ply_state *st, const char *label, char *err,
                               size_t errlen)
{
    *lay = (ply_layout){.is_vertex = strcmp(x->name, "vertex") == 0,
                        .is_face = strcmp(x->name, "face") == 0,
                        .ix = {-1, -1, -1, -1, -1, -1},
                        .iuv = {-1, -1},
                        .ic = {-1, -1, -1, -1, -1, -1},
                        .iface = -1};
    if (x->n_props == 0 && x->count > 0) {
        status_message(err, errlen, "%s: element '%s' has no properties; fix: a valid PLY header", label, x->name);
        return RC_ERR_PARSE;
    }
    ply_layout_find(x, lay);
    if (lay->is_vertex)
        return ply_layout_vertex(x, lay, st, label, err, errlen);
    if (lay->is_face)
        return ply_layout_face(lay, st, label, err, errlen);
    return RC_OK;
}

/* The message for a value of item i's property pr that ply_read refused (list_length: the list's
 * count, not one of its values). */
static rc_status ply_item_error(const ply_reader *r, ply_value v, const ply_element *x, long i, const ply_prop *pr,
                                int list_length, const char *label, char *err, size_t errlen)
{
    char what[120];
    snprintf(what, sizeof what, list_length ? "%s %ld, list length of %s" : "%s %ld, property %s", x->name, i,
             pr->name);
    return ply_value_error(r, v, list_length ? pr->count_type : pr->type, label, what, err, errlen);
}

/* List property k of item i: its count, then its values; a face's vertex indices become the
 * face's corners. */
static rc_status ply_read_list(ply_reader *r, const ply_element *x, const ply_layout *lay, const ply_state *st, long i,
                               int k, mesh_soup *s, const char *label, char *err, size_t errlen)
{
    const ply_prop *pr = &x->props[k];
    int corners = lay->is_face && k == lay->iface;
    double cnt, d;
    ply_value pv;
    if ((pv = ply_read(r, pr->count_type, &cnt)) != PLY_VALUE_OK)
        return ply_item_error(r, pv, x, i, pr, 1, label, err, errlen);
    if (!(cnt >= 0 && cnt <= 65535 && cnt == floor(cnt))) {
        status_message(err, errlen, "%s: %s %ld: list length %.17g; fix: 0..65535", label, x->name, i, cnt);
        return RC_ERR_PARSE;
    }
    if (corners && cnt < 3) {
        status_message(err, errlen, "%s: face %ld has %g corners; fix: at least 3", label, i, cnt);
        return RC_ERR_PARSE;
    }
    for (int j = 0; j < (int)cnt; j++) {
        if ((pv = ply_read(r, pr->type, &d)) != PLY_VALUE_OK)
            return ply_item_error(r, pv, x, i, pr, 0, label, err, errlen);
        if (!corners)
            continue;
        if (!(d >= 0 && d < s->n_pos && d == floor(d))) {
            status_message(err, errlen, "%s: face %ld: vertex index %.17g out of range; fix: 0..%d", label, i, d,
                           s->n_pos - 1);
            return RC_ERR_RANGE;
        }
        int vi = (int)d;
        if (!mesh_soup_corner(s, vi, st->have_vertex == 2 ? vi : -1))
            return RC_ERR_NOMEM;
        s->ct[s->n_corner - 1] = st->uv ? vi : -1;
    }
    return RC_OK;
}

/* Item i of element x: each property in the header's order, scalars into *it. */
static rc_status ply_read_item(ply_reader *r, const ply_element *x, const ply_layout *lay, const ply_state *st, long i,
                               ply_item *it, mesh_soup *s, const char *label, char *err, size_t errlen)
{
    for (int k = 0; k < x->n_props; k++) {
        const ply_prop *pr = &x->props[k];
        if (pr->is_list) {
            rc_status rc = ply_read_list(r, x, lay, st, i, k, s, label, err, errlen);
            if (rc != RC_OK)
                return rc;
            continue;
        }
        double d;
        ply_value pv = ply_read(r, pr->type, &d);
        if (pv != PLY_VALUE_OK)
            return ply_item_error(r, pv, x, i, pr, 0, label, err, errlen);
        for (int c = 0; c < 6; c++) {
            if (lay->ix[c] == k)
                it->xyz[c] = d;
            if (lay->is_vertex && lay->cbits && lay->ic[c] == k)
                it->col[c] = d * lay->cscale[c];
        }
        for (int c = 0; c < 2; c++)
            if (lay->is_vertex && lay->iuv[c] == k)
                it->uv[c] = d;
    }
    return RC_OK;
}

/* Vertex i into the soup: its position, texture coordinates, colours and normal, each checked. */
static rc_status ply_store_vertex(const ply_layout *lay, const ply_state *st, long i, ply_item *it, mesh_soup *s,
                                  const char *label, char *err, size_t errlen)
{
    for (int c = 0; c < 3; c++)
        if (!isfinite(it->xyz[c]) || fabs(it->xyz[c]) > 1e30) {
            status_message(err, errlen, "%s: vertex %ld: %s not finite or beyond 1e30; fix: finite values", label, i,
                           ply_xyz_names[c]);
            return RC_ERR_RANGE;
        }
    if (!mesh_soup_pos(s, it->xyz))
        return RC_ERR_NOMEM;
    if (st->uv) {
        if (!isfinite(it->uv[0]) || !isfinite(it->uv[1])) {
            status_message(err, errlen, "%s: vertex %ld: texture coordinate not finite; fix: finite values", label, i);
            return RC_ERR_RANGE;
        }
        if (!mesh_soup_tex(s, it->uv))
            return RC_ERR_NOMEM;
    }
    if (lay->cbits) {
        for (int c = 0; c < 6; c++)
            if (!(isfinite(it->col[c]) && it->col[c] >= 0.0 && it->col[c] <= 1e30)) {
                status_message(err, errlen, "%s: vertex %ld: colour %g is not a finite value >= 0; fix: colours >= 0",
                               label, i, it->col[c]);
                return RC_ERR_RANGE;
            }
        if (!mesh_soup_colour(s, it->col, lay->cbits))
            return RC_ERR_NOMEM;
    }
    if (st->have_vertex == 2) {
        mesh_normal_screen(it->xyz + 3);
        if (!mesh_soup_nrm(s, it->xyz + 3))
            return RC_ERR_NOMEM;
    }
    return RC_OK;
}

/* Every item of element x: vertices and faces into the soup, other elements read past. */
static rc_status ply_read_element(ply_reader *r, const ply_element *x, const ply_layout *lay, const ply_state *st,
                                  mesh_soup *s, const char *label, char *err, size_t errlen)
{
    for (long i = 0; i < x->count; i++) {
        ply_item it;
        memset(&it, 0, sizeof it);
        rc_status rc = ply_read_item(r, x, lay, st, i, &it, s, label, err, errlen);
        if (rc == RC_OK && lay->is_vertex)
            rc = ply_store_vertex(lay, st, i, &it, s, label, err, errlen);
        if (rc != RC_OK)
            return rc;
        if (lay->is_face && !mesh_soup_face(s, (int)(i < INT_MAX ? i : INT_MAX)))
            return RC_ERR_NOMEM;
    }
    return RC_OK;
}

rc_status mesh_ply_parse(const char *buf, size_t len, const char *label, mesh_soup *s, char *err, size_t errlen)
{
    ply_header h;
    rc_status rc = ply_header_read(buf, len, label, &h, err, errlen);
    if (rc != RC_OK)
        return rc;
    ply_reader r = {(const unsigned char *)h.data, (const unsigned char *)buf + len, h.binary, h.line + 1, ""};
    ply_state st = {0, 0, 0};
    for (int e = 0; e < h.n_el; e++) {
        ply_layout lay;
        if ((rc = ply_layout_of(&h.el[e], &lay, &st, label, err, errlen)) != RC_OK ||
            (rc = ply_read_element(&r, &h.el[e], &lay, &st, s, label, err, errlen)) != RC_OK)
            return rc;
    }
    if (!st.have_vertex || !st.have_face) {
        status_message(err, errlen, "%s: PLY has no %s element; fix: vertex and face elements", label,
                       st.have_vertex ? "face" : "vertex");
        return RC_ERR_PARSE;
    }
    return RC_OK;
}
