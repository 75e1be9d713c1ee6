/* texture.h - material textures: linear RGBA images sampled at surface UVs.
 *
 * Usage:
 *   texture t = {0};
 *   if (texture_load("skin.png", &t, err, sizeof err) != RC_OK) ...;   PNG or JPEG (sRGB, 8 bit)
 *   float c[4]; texture_sample(&t, u, v, c);        linear R, G, B and alpha at (u, v)
 *   texture_free(&t);
 *   texture_set ts = {0};  ts.map[material][MAT_TEX_DIFFUSE] = t;   what a render reads
 * Texels are linear floats, interleaved R, G, B, A, row 0 at the top of the image. PNG and JPEG
 * files are sRGB-encoded: colour channels are decoded with the IEC 61966-2-1 curve
 * (texture_srgb_to_linear), alpha is linear (a / 255). A PNG is reduced to 8-bit sRGB first
 * (libpng's simplified API): a gAMA or sRGB chunk is honoured (an iCCP profile is not applied);
 * without one, 16-bit samples are sRGB like 8-bit ones (PNG_IMAGE_FLAG_16BIT_sRGB; libpng's
 * default takes them as linear), so the 8- and 16-bit saves of an image give the same texels.
 * Images the harness reads come in through texture_from_planes (linear EXR), texture_from_srgb8
 * (8-bit sRGB RGBA, e.g. DDS colour: the same decode as PNG and JPEG) and texture_from_rgba
 * (linear float RGBA, e.g. DDS BC6H) (harness/frame.c).
 * Sampling, the same in every renderer (scenes/FORMAT.md): u to the right, v up (v = 0 is the
 * bottom row, as OBJ, PLY, POV-Ray's uv_mapping and Blender's UVs have it); texel (i, j) has its
 * centre at ((i + 0.5)/w, 1 - (j + 0.5)/h); bilinear between the four nearest centres; wrap mode
 * repeat in both directions (u and u + 1 are the same point).
 * Files are read only when they are regular files of at most TEXTURE_MAX_BYTES, and images of at
 * most TEXTURE_MAX_SIDE pixels a side within the memory limit (core/fileio.h); a bad file is
 * RC_ERR_IO (unreadable), RC_ERR_PARSE (not a PNG/JPEG, corrupt) or RC_ERR_RANGE (too large, not
 * a regular file), with a one-line message naming it and the fix. Before a pixel is allocated the
 * header's size is checked against the file (fileio_image_budget: a PNG's rows cannot inflate
 * more than deflate's 1032:1, a Huffman JPEG's first scan takes a bit a block at least) and the
 * memory limit; a JPEG that libjpeg finds data missing in (a cut file, a bad Huffman code: it
 * would fill grey) is RC_ERR_PARSE, and so are CMYK/YCCK and arithmetic-coded JPEGs.
 */
#ifndef REFLCHECK_TEXTURE_H
#define REFLCHECK_TEXTURE_H

#include <stddef.h>
#include "scene.h"
#include "status.h"

/* Compressed images of real-time content are kilobytes to a few MB; 256 MiB keeps any of them
 * and stops a runaway file before the first byte. */
#define TEXTURE_MAX_BYTES ((long long)256 << 20)
/* D3D11's largest 2D texture is 16384 texels a side. */
#define TEXTURE_MAX_SIDE  16384

typedef struct {
    int width, height;
    float *rgba; /* 4 floats per texel, linear, row 0 at the top; owned (texture_free) */
} texture;

/* The textures of a scene's materials, by material index and slot; width 0 = none. */
typedef struct {
    texture map[SCENE_MAX_MATERIALS][MAT_TEX_SLOTS];
} texture_set;

/* IEC 61966-2-1 sRGB decoding of an encoded value in [0, 1]. */
float texture_srgb_to_linear(float c);

rc_status texture_load(const char *path, texture *t, char *err, size_t errlen);
/* A copy of w x h linear RGBA floats (row 0 at the top); alpha may be NULL (then 1). */
rc_status texture_from_planes(int w, int h, const float *r, const float *g, const float *b, const float *a, texture *t,
                              char *err, size_t errlen);
/* w x h interleaved 8-bit sRGB RGBA decoded as PNG/JPEG texels are (colour through
 * texture_srgb_to_linear, alpha a / 255). */
rc_status texture_from_srgb8(int w, int h, const unsigned char *rgba, texture *t, char *err, size_t errlen);
/* A copy of w x h interleaved linear RGBA floats (row 0 at the top). */
rc_status texture_from_rgba(int w, int h, const float *rgba, texture *t, char *err, size_t errlen);
void texture_free(texture *t);
void texture_set_free(texture_set *ts);

/* Bilinear, repeat-wrapped RGBA at (u, v); a texture of width 0 gives (1, 1, 1, 1). Non-finite
 * u or v gives the texel at 0. */
void texture_sample(const texture *t, float u, float v, float out[4]);
/* texture_sample for n points at once, structure of arrays; the same arithmetic, lane by lane. */
void texture_sample_n(const texture *t, int n, const float *u, const float *v, float *r, float *g, float *b, float *a);

#endif
