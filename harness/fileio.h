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
 * fileio_open_input and fileio_memory_limit are static inline: the model library (mesh.c,
 * render.c) is linked after the harness one and the fuzz targets link single sources, so they
 * must not depend on fileio.c.
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

/* A mesh is read whole into memory before parsing (model/mesh.c): 10^7 triangles take about
 * 600 MB as OBJ text and 250 MB as binary PLY, far beyond any real-time scene, so 1 GiB keeps
 * every reasonable mesh and stops /dev/zero-like or runaway files before the first byte. */
#define FILEIO_MESH_MAX_BYTES ((long long)1 << 30)

/* fileio_read_all reads the harness's own JSON (job records, compare results): kilobytes, or a
 * few MB with embedded image planes; 256 MiB keeps all of them and stops a runaway file. */
#define FILEIO_READ_ALL_MAX_BYTES ((long long)256 << 20)

/* When the physical memory cannot be asked (sysconf fails), assume a small 8 GiB machine. */
#define FILEIO_MEMORY_FALLBACK ((size_t)8 << 30)

static inline const char *fileio_kind(mode_t m)
{
    if (S_ISDIR(m)) return "a directory";
    if (S_ISFIFO(m)) return "a FIFO";
    if (S_ISCHR(m)) return "a character device";
    if (S_ISBLK(m)) return "a block device";
    if (S_ISSOCK(m)) return "a socket";
    return "not a regular file";
}

static inline rc_status fileio_open_input(const char *path, long long max_bytes, const char *what, int *fd_out,
                                          long long *size_out, char *err, size_t errlen)
{
    *fd_out = -1;
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
    if (fd < 0) {
        status_message(err, errlen, "%s: cannot open (%s); give a path to %s", path, strerror(errno), what);
        return RC_ERR_IO;
    }
    struct stat st;
    if (fstat(fd, &st) != 0) {
        status_message(err, errlen, "%s: cannot stat (%s); give a path to %s", path, strerror(errno), what);
        close(fd);
        return RC_ERR_IO;
    }
    if (!S_ISREG(st.st_mode)) {
        status_message(err, errlen, "%s: not a regular file (%s); give a path to %s", path, fileio_kind(st.st_mode),
                       what);
        close(fd);
        return RC_ERR_RANGE;
    }
    if ((long long)st.st_size > max_bytes) {
        status_message(err, errlen, "%s: %lld bytes is over the limit of %lld bytes; give %s of at most that size",
                       path, (long long)st.st_size, max_bytes, what);
        close(fd);
        return RC_ERR_RANGE;
    }
    /* Reads of a regular file never block; clear the flag so they behave as ordinary reads. */
    int fl = fcntl(fd, F_GETFL);
    if (fl != -1)
        fcntl(fd, F_SETFL, fl & ~O_NONBLOCK);
    *fd_out = fd;
    if (size_out != NULL)
        *size_out = (long long)st.st_size;
    return RC_OK;
}

static inline rc_status fileio_memory_limit(size_t *bytes, char *err, size_t errlen)
{
    const char *v = getenv("REFLCHECK_MEMORY_LIMIT");
    if (v != NULL && v[0] != '\0') {
        char *end;
        errno = 0;
        unsigned long long n = strtoull(v, &end, 10);
        int shift = 0;
        switch (*end) {
        case 'k': case 'K': shift = 10; end++; break;
        case 'm': case 'M': shift = 20; end++; break;
        case 'g': case 'G': shift = 30; end++; break;
        case 't': case 'T': shift = 40; end++; break;
        default: break;
        }
        if (errno != 0 || end == v || *end != '\0' || v[0] == '-' || n == 0 || n > (SIZE_MAX >> shift)) {
            status_message(err, errlen, "REFLCHECK_MEMORY_LIMIT='%s': expected a positive number of bytes with an "
                           "optional K, M, G or T suffix, e.g. 8G; fix or unset it", v);
            return RC_ERR_RANGE;
        }
        *bytes = (size_t)n << shift;
        return RC_OK;
    }
    long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
    /* Half the machine: the other half stays for the system, the page cache and the second
     * job the nightly runs beside this one (make -j2). */
    if (pages <= 0 || page <= 0)
        *bytes = FILEIO_MEMORY_FALLBACK;
    else
        *bytes = (size_t)pages / 2 * (size_t)page;
    return RC_OK;
}

int fileio_same_file(const char *a, const char *b);
rc_status fileio_output_target(const char *path, char *target, size_t len, char *err, size_t errlen);
rc_status fileio_temp_open(const char *target, char *tmp, size_t tmplen, int *fd, char *err, size_t errlen);
rc_status fileio_temp_finish(int fd, const char *tmp, const char *target, int failed, char *err, size_t errlen);

rc_status fileio_write_atomic(const char *path, const char *text, char *err, size_t errlen);
char *fileio_read_all(const char *path, size_t *len);
int fileio_copy(const char *from, const char *to);
/* The temporary name used for path (path + ".tmp" + pid), for writers that stream. */
void fileio_temp_name(const char *path, char *buf, size_t len);

#endif
