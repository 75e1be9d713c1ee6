/* libFuzzer target: the PNG and JPEG texture reader (scene/texture.h). texture_load takes a
 * path, so each input is written to an in-memory file (memfd) and read through /proc/self/fd/N,
 * as fuzz_exr does. The memory limit is set to 256 MiB so that a valid but large image is refused
 * by the reader's own check rather than by libFuzzer's RSS limit (2 GB). libpng and libjpeg are
 * the system libraries, not instrumented: coverage counts texture.c and fileio.c, and ASan still
 * sees their heap use and our buffers. */
#define _GNU_SOURCE
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#include "texture.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static int fuzz_tex_fd = -1;
static char fuzz_tex_path[64];

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    setenv("REFLCHECK_MEMORY_LIMIT", "256M", 1);
    fuzz_tex_fd = memfd_create("fuzz_texture", 0);
    if (fuzz_tex_fd < 0) {
        perror("fuzz_texture: memfd_create");
        abort();
    }
    snprintf(fuzz_tex_path, sizeof fuzz_tex_path, "/proc/self/fd/%d", fuzz_tex_fd);
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (ftruncate(fuzz_tex_fd, 0) != 0 || (size && pwrite(fuzz_tex_fd, data, size, 0) != (ssize_t)size))
        abort(); /* the harness itself failed, not the reader */
    texture t;
    char err[512];
    err[0] = '\0';
    rc_status st = texture_load(fuzz_tex_path, &t, err, sizeof err);
    if (st == RC_OK) {
        /* Every texel read back (ASan sees a short buffer); decoded 8-bit sRGB lies in [0, 1]. */
        size_t n = (size_t)t.width * (size_t)t.height * 4;
        for (size_t i = 0; i < n; i++)
            if (!(t.rgba[i] >= 0.0f && t.rgba[i] <= 1.0f)) {
                fprintf(stderr, "fuzz_texture: texel %zu is %g, outside [0, 1]\n", i, (double)t.rgba[i]);
                abort();
            }
        texture_free(&t);
    } else if (err[0] == '\0' || strchr(err, '\n') != NULL) {
        fprintf(stderr, "fuzz_texture: status %d without a one-line message\n", (int)st);
        abort();
    }
    return 0;
}
