/* libFuzzer target: assets through libassimp (scene/mesh_assimp.h), in this process. Each input
 * is written to an in-memory file (memfd, read as /proc/self/fd/N, as fuzz_texture does); with no
 * extension libassimp picks the format from the content, so one target covers every importer's
 * format detection and our walk of its result. libassimp is the system library, not
 * instrumented: coverage counts mesh_assimp.c and fileio.c, and ASan sees our reads of its
 * arrays. A crash inside libassimp stops this fuzzer; in reflcheck itself it is a one-line error,
 * because mesh_assimp_load imports in a child process (findings: docs/assets.md). */
#define _GNU_SOURCE
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#include "mesh_assimp.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static int fuzz_fd = -1;
static char fuzz_path[64];

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    fuzz_fd = memfd_create("fuzz_assimp", 0);
    if (fuzz_fd < 0) {
        perror("fuzz_assimp: memfd_create");
        abort();
    }
    snprintf(fuzz_path, sizeof fuzz_path, "/proc/self/fd/%d", fuzz_fd);
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (ftruncate(fuzz_fd, 0) != 0 || (size && pwrite(fuzz_fd, data, size, 0) != (ssize_t)size))
        abort(); /* the harness itself failed, not the reader */
    char err[1024] = "";
    mesh_assimp_soup g;
    if (mesh_assimp_import(fuzz_path, "", &g, err, sizeof err) == RC_OK) {
        /* Every index is in range and every vertex is read (ASan sees short arrays). */
        double sum = 0.0;
        for (int t = 0; t < 3 * g.n_tris; t++) {
            if (g.idx[t] < 0 || g.idx[t] >= g.n_verts)
                abort();
            sum += g.pos[3 * g.idx[t]] + g.uv[2 * g.idx[t]] + g.has_uv[g.idx[t]];
        }
        if (sum == 1e300)
            puts("");
        mesh_assimp_soup_free(&g);
    } else if (!err[0] || strchr(err, '\n')) {
        abort(); /* a refusal must leave a one-line message */
    }
    mesh_assimp_material a;
    if (mesh_assimp_material_import(fuzz_path, "", &a, err, sizeof err) != RC_OK && (!err[0] || strchr(err, '\n')))
        abort();
    return 0;
}
