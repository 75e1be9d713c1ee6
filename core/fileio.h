/* fileio.h - bounded reads of a user's input files, crash-safe writes of outputs.
 *
 * Usage:
 *   int fd; long long size;
 *   fileio_open_input("m.obj", FILEIO_MESH_MAX_BYTES, "an OBJ or PLY mesh", &fd, &size, err, sizeof err);
 *       regular files only, at most max bytes, checked before a byte is read; close(fd) after
 *   size_t limit; fileio_memory_limit(&limit, err, sizeof err);   what a render or image may allocate
 *   fileio_same_file("out.exr", "scene.yaml")                   1: the same file (device and inode)
 *   char target[FILEIO_PATH_MAX], tmp[FILEIO_PATH_MAX]; int fd;
 *   fileio_output_target("out.exr", target, sizeof target, err, sizeof err);  refuses devices etc.
 *   fileio_temp_open(target, tmp, sizeof tmp, &fd, err, sizeof err);  ... write(fd) ...
 *   fileio_temp_finish(fd, tmp, target, failed, err, sizeof err);     rename, or unlink the temp
 *   fileio_write_atomic("run/x/compare.json", text, err, sizeof err);  temp file, then rename
 *   char *text = fileio_read_all("record.json", &len);   NUL-terminated; free(); regular files
 *                                                         of at most FILEIO_READ_ALL_MAX_BYTES
 *   fileio_read_input("t.png", max, "a texture", &bytes, &len, err, sizeof err);   the same, any
 *                                                         limit, with the reason in err
 *   fileio_copy("cache/k/out.exr", "run/x/raster-twin.exr");           temp file, then rename
 * Inputs: a FIFO, a device, a directory or a socket is refused with its kind named (it is
 * opened O_NONBLOCK, so a FIFO without a writer never blocks), and so is a file over the
 * limit. Status RC_ERR_IO: cannot open (missing, no permission); RC_ERR_RANGE: not a regular
 * file, or too large (bad input: exit 2).
 * Outputs: written to a temporary name in the destination's folder (through a symlink: the
 * folder of the file it points to) and renamed over it only when complete, so a reader never
 * sees a half-written file, and a failed or killed write leaves the old file (or none) in
 * place. A destination that exists and is not a regular file (e.g. /dev/full, a FIFO, a
 * directory) is refused with RC_ERR_RANGE; a write error is RC_ERR_IO. fileio_read_all
 * returns NULL, fileio_copy -1 on error.
 * Memory: REFLCHECK_MEMORY_LIMIT (bytes, or with a K, M, G or T suffix, binary) overrides the
 * default of half the physical memory.
 * It sits in the model library, the bottom layer: the mesh reader and the renderer's memory
 * estimate use it as the harness does.
 */
#ifndef REFLCHECK_FILEIO_H
#define REFLCHECK_FILEIO_H

#include <errno.h>
#include <fcntl.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include "status.h"

/* Room for a scene-relative path (SCENE_PATH_MAX) plus a temporary suffix. */
#define FILEIO_PATH_MAX 4200

/* A mesh is read whole into memory before parsing (scene/mesh.c): 10^7 triangles take about
 * 600 MB as OBJ text and 250 MB as binary PLY, far beyond any real-time scene, so 1 GiB keeps
 * every reasonable mesh and stops /dev/zero-like or runaway files before the first byte. */
#define FILEIO_MESH_MAX_BYTES ((long long)1 << 30)

/* fileio_read_all reads the harness's own JSON (job records, compare results): kilobytes, or a
 * few MB with embedded image planes; 256 MiB keeps all of them and stops a runaway file. */
#define FILEIO_READ_ALL_MAX_BYTES ((long long)256 << 20)

/* When the physical memory cannot be asked (sysconf fails), assume a small 8 GiB machine. */
#define FILEIO_MEMORY_FALLBACK ((size_t)8 << 30)

/* The kind of a non-regular file, for messages ("a FIFO", "a directory", ...). */
const char *fileio_kind(mode_t m);
rc_status fileio_open_input(const char *path, long long max_bytes, const char *what, int *fd_out, long long *size_out,
                            char *err, size_t errlen);
rc_status fileio_memory_limit(size_t *bytes, char *err, size_t errlen);
/* The check every image reader makes after the header and before allocating for the pixels:
 * RC_ERR_PARSE when the header's w x h needs at least min_bytes bytes of coded data (worked out
 * from the format's largest compression ratio) and the file has fewer (file_bytes): it cannot be
 * a complete file; RC_ERR_RANGE when the reader's allocations (alloc bytes) exceed the memory
 * limit. format names the format in messages ("PNG", "JPEG", ...). */
rc_status fileio_image_budget(const char *path, const char *format, long long w, long long h, double min_bytes,
                              long long file_bytes, double alloc, char *err, size_t errlen);

int fileio_same_file(const char *a, const char *b);
rc_status fileio_output_target(const char *path, char *target, size_t len, char *err, size_t errlen);
rc_status fileio_temp_open(const char *target, char *tmp, size_t tmplen, int *fd, char *err, size_t errlen);
rc_status fileio_temp_finish(int fd, const char *tmp, const char *target, int failed, char *err, size_t errlen);

rc_status fileio_write_atomic(const char *path, const char *text, char *err, size_t errlen);
/* The whole of an input file, opened as fileio_open_input does (what names it in messages), into
 * a malloc'd buffer of *len bytes with a NUL after them; free(*out). */
rc_status fileio_read_input(const char *path, long long max_bytes, const char *what, unsigned char **out, size_t *len,
                            char *err, size_t errlen);
char *fileio_read_all(const char *path, size_t *len);
int fileio_copy(const char *from, const char *to);

#endif
