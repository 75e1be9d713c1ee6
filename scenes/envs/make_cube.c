/* make_cube.c - resamples an equirectangular image into the six 64 x 64 faces of a Direct3D cube
 * map: scenes/envs/city_cube_{px,nx,py,ny,pz,nz}.exr from city.exr (scenes/cube_mirror.yaml) and
 * courtyard_cube_*.exr from courtyard.exr (scenes/ct_cube.yaml).
 *
 * Build and run from the repository root after `make` (scenes/envs/make_cube.sh does both):
 *   cc -std=c11 -O2 -Imodel -Iharness scenes/envs/make_cube.c build/libreflcheck_harness.a \
 *      build/libreflcheck_model.a $(pkg-config --libs OpenEXR) -lm -o build/make_cube
 *   build/make_cube scenes/envs/city.exr scenes/envs/city_cube     (and courtyard likewise)
 * Each face texel is the mean of 8 x 8 bilinear lookups of the equirectangular image (env.h's
 * orientation) in the directions of a regular grid over the texel (env_cube_direction, the
 * cube's own orientation): a box filter, since a 64-texel face spans 90 degrees (1.4 degrees a
 * texel at its centre) and the source has 0.35 degrees a texel. The faces are a real sky seen
 * through the cube's geometry, not a fixture whose values matter one by one.
 */
#include <stdio.h>
#include <stdlib.h>

#include "env.h"
#include "exr.h"

#define FACE 64
#define SUB  8

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: make_cube IN.exr OUT_PREFIX (writes OUT_PREFIX_px.exr ... _nz.exr)\n");
        return 2;
    }
    char err[1024];
    exr_image img;
    if (exr_read(argv[1], &img, err, sizeof err) != RC_OK) {
        fprintf(stderr, "make_cube: %s\n", err);
        return 1;
    }
    const float *ch[3] = {exr_image_channel(&img, "R"), exr_image_channel(&img, "G"), exr_image_channel(&img, "B")};
    if (ch[0] == NULL || ch[1] == NULL || ch[2] == NULL) {
        fprintf(stderr, "make_cube: %s has no R, G, B channels\n", argv[1]);
        return 1;
    }
    size_t n = (size_t)img.width * (size_t)img.height;
    float *rgb = malloc(3 * n * sizeof *rgb), *face[3];
    for (int c = 0; c < 3; c++)
        face[c] = malloc(FACE * FACE * sizeof(float));
    if (rgb == NULL || face[0] == NULL || face[1] == NULL || face[2] == NULL) {
        fprintf(stderr, "make_cube: out of memory\n");
        return 1;
    }
    for (size_t i = 0; i < n; i++)
        for (int c = 0; c < 3; c++)
            rgb[3 * i + (size_t)c] = ch[c][i];
    env_map src = {.kind = ENV_IMAGE, .width = img.width, .height = img.height, .rgb = rgb, .scale = v3s(1.0f)};
    static const char *const key[6] = {"px", "nx", "py", "ny", "pz", "nz"};
    for (int f = 0; f < 6; f++) {
        for (int y = 0; y < FACE; y++)
            for (int x = 0; x < FACE; x++) {
                double sum[3] = {0, 0, 0};
                for (int j = 0; j < SUB; j++)
                    for (int i = 0; i < SUB; i++) {
                        float s = (x + (i + 0.5f) / SUB) / FACE, t = (y + (j + 0.5f) / SUB) / FACE;
                        vec3 l = env_lookup(&src, env_cube_direction(f, s, t));
                        sum[0] += l.x, sum[1] += l.y, sum[2] += l.z;
                    }
                for (int c = 0; c < 3; c++)
                    face[c][y * FACE + x] = (float)(sum[c] / (SUB * SUB));
            }
        char path[1024];
        snprintf(path, sizeof path, "%s_%s.exr", argv[2], key[f]);
        exr_channel out[3] = {{"R", face[0]}, {"G", face[1]}, {"B", face[2]}};
        if (exr_write(path, FACE, FACE, out, 3, NULL, 0, err, sizeof err) != RC_OK) {
            fprintf(stderr, "make_cube: %s\n", err);
            return 1;
        }
    }
    exr_image_free(&img);
    free(rgb);
    for (int c = 0; c < 3; c++)
        free(face[c]);
    return 0;
}
