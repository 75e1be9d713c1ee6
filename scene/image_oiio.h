/* image_oiio.h - DDS files (a 2D image or a cube map) through OpenImageIO's C++ API, for C.
 *
 * Usage:
 *   image_dds d;
 *   if (image_dds_read("sky.dds", IMAGE_DDS_CUBE, TEXTURE_MAX_BYTES, TEXTURE_MAX_SIDE, &d, err,
 *                      sizeof err) != RC_OK) ...;            err names the file and the fix
 *   for (int f = 0; f < d.faces; f++) {
 *       face f: d.width x d.height texels at offset f * d.width * d.height * 4 of
 *       d.rgba8 (d.linear == 0: 8-bit colour as stored, sRGB-encoded for a colour map) or
 *       d.rgbaf (d.linear == 1: float data, BC6H, linear)
 *   }
 *   image_dds_free(&d);
 *   image_oiio_version()                                      "2.4.7" (for cache keys)
 * Texels are interleaved R, G, B, A (A 255 or 1 where the file has none), row 0 at the top of
 * each face, faces in the file's order, which is D3DCUBEMAP_FACES' (+X, -X, +Y, -Y, +Z, -Z), each
 * face as Direct3D addresses it (texel (0, 0) at u = v = 0): exactly scene/env.h's layout.
 * OpenImageIO 2.4 shows a cube map as one 1 x 6 strip of tiles, a tile per face, with
 * textureformat "CubeFace Environment" and dds:CubeMapSides naming the faces present; a cube
 * here needs all six and square faces. The file is opened with core/fileio.h's checks (regular
 * file, at most max_bytes) and read whole into memory; a header whose faces need more bytes than
 * the file has (at BC1's 8 bytes a 4x4 block, the most compact) or more memory than the limit is
 * refused before allocating (fileio_image_budget), and OpenImageIO's DDS reader decodes it
 * from there. Formats OpenImageIO 2.4.7 decodes (docs/cubemaps.md, measured): legacy headers
 * with uncompressed RGB/RGBA masks, DXT1..DXT5, ATI1/ATI2 (BC4/BC5); DX10 headers with BC4, BC5,
 * BC6H and BC7_UNORM only. Colour needs three or four channels (BC4, BC5, luminance are refused).
 * Status: RC_ERR_IO (cannot open), RC_ERR_RANGE (not a regular file, too large, not the kind
 * asked for, faces not square), RC_ERR_PARSE (not a DDS, a format OpenImageIO does not read,
 * truncated or corrupt data), RC_ERR_NOMEM. On error nothing stays allocated.
 */
#ifndef REFLCHECK_IMAGE_OIIO_H
#define REFLCHECK_IMAGE_OIIO_H

#include <stddef.h>
#include "status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum { IMAGE_DDS_2D, IMAGE_DDS_CUBE } image_dds_kind;

typedef struct {
    int width, height;    /* one face of a cube, or the 2D image */
    int faces;            /* 6 for a cube map, 1 for a 2D image */
    int linear;           /* 1: float data in rgbaf; 0: 8-bit data in rgba8 */
    unsigned char *rgba8; /* faces x height x width x 4, or NULL */
    float *rgbaf;         /* faces x height x width x 4, or NULL */
    char format[16];      /* the encoding OpenImageIO reports: "DXT1", "BC7", ... or "uncompressed" */
} image_dds;

rc_status image_dds_read(const char *path, image_dds_kind kind, long long max_bytes, int max_side, image_dds *out,
                         char *err, size_t errlen);
void image_dds_free(image_dds *d);
const char *image_oiio_version(void);

#ifdef __cplusplus
}
#endif

#endif
