/* exr.h - linear float OpenEXR images through the OpenEXR C API (OpenEXRCore).
 *
 * Usage:
 *   exr_channel ch[] = {{"R", r}, {"G", g}, {"B", b}, {"diffuse.R", dr}, ...};
 *   exr_attr at[] = {{"reflcheck.scene_hash", "9f..."}, {"reflcheck.render_ms", "12.5"}};
 *   exr_write("out.exr", w, h, ch, n, at, 2, err, sizeof err);   32-bit float, ZIP, every core
 *   exr_write_options o = {.threads = 1, .zip_level = 6};         one thread, zlib level 6
 *   exr_write_opt("out.exr", w, h, ch, n, at, 2, &o, err, sizeof err);
 *   exr_image img; exr_read("in.exr", &img, err, sizeof err);    every channel as float
 *   const float *r = exr_image_channel(&img, "R");               NULL if absent
 *   exr_image_free(&img);
 * Pixels are row-major, row 0 at the top, one float array (w*h) per channel.
 * Half and uint channels are converted to float on read. The image owns its arrays.
 * Errors name the file and what is wrong (missing file, not an EXR, truncated, ...).
 * exr_write writes a temporary file beside path (beside its target for a symlink) and renames
 * it over path only when complete: on any failure (full disk, ulimit -f: RC_ERR_IO) an existing
 * file is left byte for byte and the temporary removed. A path that exists and is not a regular
 * file (/dev/full, a FIFO, a directory) is refused with RC_ERR_RANGE before anything is written.
 * exr_read reads regular files only (a device, FIFO or directory: RC_ERR_RANGE, at once, never
 * blocking) and refuses a header whose float planes (width x height x channels x 4 bytes)
 * exceed the memory limit (core/fileio.h: half the physical memory or REFLCHECK_MEMORY_LIMIT),
 * or whose data window needs more samples than the file can hold (its offset table, 8 bytes a
 * chunk, and the compression's largest ratio: exr.c's exr_max_ratio), before allocating.
 */
#ifndef REFLCHECK_EXR_H
#define REFLCHECK_EXR_H

#include <stddef.h>
#include "status.h"

typedef struct {
    const char *name;
    const float *data;
} exr_channel;
typedef struct {
    const char *name;
    const char *value;
} exr_attr;

#define EXR_NAME_MAX 64
typedef struct {
    int width, height, n_channels;
    char (*names)[EXR_NAME_MAX];
    float **data;
    int n_attrs; /* string attributes only */
    char (*attr_names)[EXR_NAME_MAX];
    char (*attr_values)[256];
} exr_image;

/* How exr_write_opt writes; zero = exr_write's defaults. The bytes of the file do not depend on
 * threads. */
typedef struct {
    int threads;   /* compression threads; 0 = one per online core */
    int zip_level; /* zlib level 1..9 of the ZIP chunks; 0 = 1, the fastest (exr.c's EXR_ZIP_LEVEL) */
} exr_write_options;

rc_status exr_write(const char *path, int width, int height, const exr_channel *ch, int n_channels,
                    const exr_attr *attrs, int n_attrs, char *err, size_t errlen);
rc_status exr_write_opt(const char *path, int width, int height, const exr_channel *ch, int n_channels,
                        const exr_attr *attrs, int n_attrs, const exr_write_options *opt, char *err, size_t errlen);
rc_status exr_read(const char *path, exr_image *img, char *err, size_t errlen);
const float *exr_image_channel(const exr_image *img, const char *name);
const char *exr_image_attr(const exr_image *img, const char *name);
void exr_image_free(exr_image *img);

#endif
