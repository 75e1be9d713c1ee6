/* libFuzzer target: the OpenEXR reader (scene/exr.h). exr_read takes a path, so each
 * input is written to an in-memory file (memfd) and read back through /proc/self/fd/N: no
 * disk traffic. PATH is cleared at start-up so exr.c's DWA fallback (a posix_spawn of
 * oiiotool) fails at once instead of forking per input; the in-process code, which is what
 * can corrupt memory, is still exercised up to the spawn. OpenEXRCore itself is the system
 * library: not instrumented, so coverage counts exr.c only, but ASan still catches its
 * out-of-bounds accesses to our buffers and its heap errors through the interceptors. */
#define _GNU_SOURCE
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#include "exr.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static int fuzz_exr_fd = -1;
static char fuzz_exr_path[64];

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    setenv("PATH", "/nonexistent", 1);
    fuzz_exr_fd = memfd_create("fuzz_exr", 0);
    if (fuzz_exr_fd < 0) {
        perror("fuzz_exr: memfd_create");
        abort();
    }
    snprintf(fuzz_exr_path, sizeof fuzz_exr_path, "/proc/self/fd/%d", fuzz_exr_fd);
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (ftruncate(fuzz_exr_fd, 0) != 0 || (size && pwrite(fuzz_exr_fd, data, size, 0) != (ssize_t)size))
        abort(); /* the harness itself failed, not the reader */
    exr_image img;
    char err[512];
    err[0] = '\0';
    rc_status st = exr_read(fuzz_exr_path, &img, err, sizeof err);
    if (st == RC_OK) {
        /* Touch every sample, so a short allocation shows up under ASan. */
        volatile float sink = 0.0f;
        size_t n = (size_t)img.width * (size_t)img.height;
        for (int c = 0; c < img.n_channels; c++)
            for (size_t i = 0; i < n; i++)
                sink += img.data[c][i];
        for (int a = 0; a < img.n_attrs; a++)
            sink += (float)strlen(img.attr_values[a]) + (float)strlen(img.attr_names[a]);
        (void)sink;
        exr_image_free(&img);
    } else if (err[0] == '\0') {
        fprintf(stderr, "fuzz_exr: status %d without a message\n", (int)st);
        abort();
    }
    return 0;
}
