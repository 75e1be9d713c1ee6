#include "diff_terms.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "exr.h"
#include "renderers/renderer.h"

rc_status diff_terms_parse(const char *list, unsigned *bits, char *err, size_t errlen)
{
    char buf[128];
    *bits = 0;
    if (strlen(list) >= sizeof buf || list[0] == '\0') {
        snprintf(err, errlen,
                 "--leave-out '%s': expected a comma-separated list of diffuse, specular, reflection, emission", list);
        return RC_ERR_PARSE;
    }
    snprintf(buf, sizeof buf, "%s", list);
    char *save = NULL;
    for (char *w = strtok_r(buf, ",", &save); w != NULL; w = strtok_r(NULL, ",", &save)) {
        unsigned b = renderer_term_from_name(w);
        if (b == 0) {
            snprintf(err, errlen,
                     "--leave-out '%s': '%s' is not a term; allowed: diffuse, specular, reflection, emission", list, w);
            return RC_ERR_PARSE;
        }
        *bits |= b;
    }
    /* Leaving every term out leaves nothing to compare. */
    if (*bits == RENDERER_TERM_ALL) {
        snprintf(err, errlen, "--leave-out '%s': every term; allowed: at most three of the four", list);
        return RC_ERR_PARSE;
    }
    return RC_OK;
}

/* The writable plane of channel name, NULL if absent. */
static float *diff_terms_plane(const exr_image *img, const char *name)
{
    for (int c = 0; c < img->n_channels; c++)
        if (strcmp(img->names[c], name) == 0)
            return img->data[c];
    return NULL;
}

rc_status diff_terms_strip(const char *in, unsigned bits, const char *out, char *err, size_t errlen)
{
    exr_image img;
    rc_status st = exr_read(in, &img, err, errlen);
    if (st != RC_OK)
        return st;
    size_t np = (size_t)img.width * (size_t)img.height;
    static const char rgb[3] = {'R', 'G', 'B'};
    for (int t = 0; t < RENDERER_N_TERMS && st == RC_OK; t++) {
        if (!(bits & (1u << t)))
            continue;
        for (int c = 0; c < 3; c++) {
            char name[64], base[2] = {rgb[c], '\0'};
            snprintf(name, sizeof name, "%s.%c", renderer_term_name(t), rgb[c]);
            const float *layer = exr_image_channel(&img, name);
            float *total = diff_terms_plane(&img, base);
            if (layer == NULL || total == NULL) {
                snprintf(err, errlen, "%s: no %s channel to leave %s out of; give an image with its term layers", in,
                         layer == NULL ? name : base, renderer_term_name(t));
                st = RC_ERR_RANGE;
                break;
            }
            for (size_t i = 0; i < np; i++)
                total[i] -= layer[i];
        }
    }
    exr_channel *ch = st == RC_OK ? malloc((size_t)img.n_channels * sizeof *ch) : NULL;
    if (st == RC_OK && ch == NULL) {
        snprintf(err, errlen, "out of memory for %d channels of %s", img.n_channels, in);
        st = RC_ERR_NOMEM;
    }
    if (st == RC_OK) {
        for (int i = 0; i < img.n_channels; i++)
            ch[i] = (exr_channel){img.names[i], img.data[i]};
        st = exr_write(out, img.width, img.height, ch, img.n_channels, NULL, 0, err, errlen);
    }
    free(ch);
    exr_image_free(&img);
    return st;
}

rc_status diff_terms_pair(const char *test, const char *ref, unsigned bits, char *dir, size_t dirlen, char *err,
                          size_t errlen)
{
    const char *tmp = getenv("TMPDIR");
    char path[300];
    snprintf(dir, dirlen, "%s/reflcheck-diff-XXXXXX", tmp != NULL && tmp[0] != '\0' ? tmp : "/tmp");
    if (mkdtemp(dir) == NULL) {
        snprintf(err, errlen,
                 "%s: cannot make a folder for the images without their left-out terms; set TMPDIR to a "
                 "writable folder",
                 dir);
        dir[0] = '\0';
        return RC_ERR_IO;
    }
    snprintf(path, sizeof path, "%s/test.exr", dir);
    rc_status st = diff_terms_strip(test, bits, path, err, errlen);
    snprintf(path, sizeof path, "%s/ref.exr", dir);
    if (st == RC_OK)
        st = diff_terms_strip(ref, bits, path, err, errlen);
    return st;
}

void diff_terms_cleanup(const char *dir)
{
    char path[300];
    if (dir[0] == '\0')
        return;
    snprintf(path, sizeof path, "%s/test.exr", dir);
    unlink(path);
    snprintf(path, sizeof path, "%s/ref.exr", dir);
    unlink(path);
    rmdir(dir);
}

void diff_terms_names(char *msg, size_t len, const char *dir, const char *test, const char *ref)
{
    char from[2][300], out[2048];
    const char *to[2] = {test, ref};
    snprintf(from[0], sizeof from[0], "%s/test.exr", dir);
    snprintf(from[1], sizeof from[1], "%s/ref.exr", dir);
    size_t used = 0;
    const char *p = msg;
    while (*p != '\0' && used + 1 < sizeof out) {
        int k = strncmp(p, from[0], strlen(from[0])) == 0 ? 0 : (strncmp(p, from[1], strlen(from[1])) == 0 ? 1 : -1);
        if (dir[0] != '\0' && k >= 0) {
            used += (size_t)snprintf(out + used, sizeof out - used, "%s", to[k]);
            p += strlen(from[k]);
        } else {
            out[used++] = *p++;
        }
    }
    out[used < sizeof out ? used : sizeof out - 1] = '\0';
    snprintf(msg, len, "%s", out);
}
