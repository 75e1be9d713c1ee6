/* bench_image.h - the benchmark's scratch image files: raw planar floats, for memcmp and
 * per-pixel differences between processes.
 *
 * Usage:
 *   bench_image_write(path, w, h, n, planes);            0 = ok
 *   bench_image im; bench_image_read(path, &im);         0 = ok; free(im.data) afterwards
 * Format: "RCBENCH1", int32 width, height, channels (native endianness; the files never leave
 * the machine), then channels planes of width*height floats, row 0 at the top.
 */
#ifndef REFLCHECK_BENCH_IMAGE_H
#define REFLCHECK_BENCH_IMAGE_H

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    int32_t width, height, channels;
    float *data;
} bench_image;

static inline int bench_image_write(const char *path, int w, int h, int n, const float *const *planes)
{
    FILE *f = fopen(path, "wb");
    if (!f)
        return -1;
    int32_t hdr[3] = {w, h, n};
    int bad = fwrite("RCBENCH1", 1, 8, f) != 8 || fwrite(hdr, sizeof hdr, 1, f) != 1;
    for (int c = 0; c < n && !bad; c++)
        bad = fwrite(planes[c], sizeof(float), (size_t)w * (size_t)h, f) != (size_t)w * (size_t)h;
    return (fclose(f) != 0 || bad) ? -1 : 0;
}

static inline int bench_image_read(const char *path, bench_image *im)
{
    memset(im, 0, sizeof *im);
    FILE *f = fopen(path, "rb");
    if (!f)
        return -1;
    char magic[8];
    int32_t hdr[3];
    if (fread(magic, 1, 8, f) != 8 || memcmp(magic, "RCBENCH1", 8) != 0 || fread(hdr, sizeof hdr, 1, f) != 1 ||
        hdr[0] <= 0 || hdr[1] <= 0 || hdr[2] <= 0 || hdr[2] > 64) {
        fclose(f);
        return -1;
    }
    size_t n = (size_t)hdr[0] * (size_t)hdr[1] * (size_t)hdr[2];
    im->data = malloc(n * sizeof(float));
    if (!im->data || fread(im->data, sizeof(float), n, f) != n) {
        free(im->data);
        im->data = NULL;
        fclose(f);
        return -1;
    }
    fclose(f);
    im->width = hdr[0];
    im->height = hdr[1];
    im->channels = hdr[2];
    return 0;
}

#endif
