/* frame.h - a rasterizer frame's files: its environment image in, its layers out.
 *
 * Usage:
 *   env_map e; float *pixels = NULL;
 *   if (frame_env_load(&scn, &e, &pixels, err, sizeof err) != RC_OK) ...;
 *   ... env_lookup(&e, dir), render_scene(&scn, &msh, &e, ...) ...
 *   free(pixels);                       the caller owns the interleaved RGB pixels
 *   frame_write("out.exr", &scn, &msh, &img, err, sizeof err);
 *   texture_set ts; frame_textures_load(&scn, &ts, err, sizeof err); ... texture_set_free(&ts);
 * Images by extension: linear EXR (exr.c), DDS (image_oiio.h: a cube map for
 * environment.cube_dds, a 2D image elsewhere; 8-bit colour sRGB-decoded as PNG/JPEG are, BC6H
 * linear), else PNG/JPEG (scene/texture.c).
 * An environment image must have R, G and B channels and finite texels >= 0 (RC_ERR_RANGE
 * otherwise, naming the first bad texel and the counts); errors name the file and the scene.
 * On error nothing is allocated (*pixels is NULL).
 *   frame_env_split_sun(&scn, pixels, &e, &sun, err, sizeof err);   environment.sun_threshold
 *   frame_inputs_load(&scn, &e, &pixels, &ts, err, sizeof err);  the three above, in their order
 * frame_write stores every layer the render produced as 32-bit float, with the scene's name
 * and hash, the renderer (reflcheck-raster; frame_write_as names another), the render time, k,
 * the triangle and shaded-sample counts in the header; and the model's "crease" layer: each
 * pixel's share of samples where Cycles' shading-normal rules depart (harness/crease.h), which
 * compare reads as a mask. frame_write_as (another renderer's image) writes no crease layer.
 */
#ifndef REFLCHECK_FRAME_H
#define REFLCHECK_FRAME_H

#include <stddef.h>
#include "env.h"
#include "mesh.h"
#include "render.h"
#include "status.h"
#include "texture.h"

rc_status frame_env_load(const scene *s, env_map *e, float **pixels, char *err, size_t errlen);
/* Every material texture of the scene into ts (zeroed first): PNG/JPEG through scene/texture.c,
 * linear EXR (R, G, B, optional A) through exr.c, DDS through image_oiio.h; texels must be finite
 * and >= 0. On error
 * nothing stays allocated; free with texture_set_free. */
rc_status frame_textures_load(const scene *s, texture_set *ts, char *err, size_t errlen);
/* The scene's sun extraction (environment.sun_threshold > 0 on an image; else nothing): moves
 * the sun out of pixels (frame_env_load's) into a sun light appended to s->lights, as every
 * renderer must receive it (scene/env.h env_extract_sun); *sun (may be NULL) describes it.
 * RC_ERR_RANGE with one line naming the scene, key and fix when no texel is above the
 * threshold or the lights are full. */
rc_status frame_env_split_sun(scene *s, float *pixels, const env_map *e, env_sun *sun, char *err, size_t errlen);
/* 1 when the scene asks for its sky's sun as a light (environment.sun_threshold > 0 on an
 * image): what frame_env_split_sun then does, and jobs.c writes the split sky for. */
int frame_sun_split(const scene *s);
/* The inputs every frame of the scene needs, in the one order they must come: the environment
 * (frame_env_load), the material textures (frame_textures_load), then the environment's sun split
 * into a light (frame_env_split_sun). The first error stops; the caller frees *env_pixels (set
 * even on error once the environment loaded) and ts (texture_set_free). */
rc_status frame_inputs_load(scene *s, env_map *e, float **env_pixels, texture_set *ts, char *err, size_t errlen);
/* The number of lights every renderer receives for the scene as its file gives it: its own,
 * plus the sun frame_env_split_sun appends. Light masks (the physics manifest's
 * diffuse_lights, specular_lights) are read against this count, on the scene file's side
 * (compare) as on the renderer's (the job record). */
int frame_light_count(const scene *s);
/* Writes the environment's pixels (interleaved RGB) as a 32-bit float RGB EXR, for renderers
 * that read the image from a file (the split environment). */
rc_status frame_env_write(const char *path, const env_map *e, char *err, size_t errlen);
/* Writes a cube map's exact conversion (scene/env.h env_cube_to_equirect; its size is
 * FRAME_CUBE_EQUIRECT_PER_FACE in frame.c, which the cache key covers) as a 32-bit float RGB EXR,
 * for renderers that read an equirectangular image from a file. */
rc_status frame_env_cube_write(const char *path, const env_map *cube, char *err, size_t errlen);
/* The scene-file key a cube map's face comes from, for messages: "environment.cube.px" (six
 * files), "environment.cube_cross" or "environment.cube_dds" (one file holds all six). */
void frame_env_cube_key(const scene *s, int face, char *key, size_t len);
/* 1 when a path the scene names is a DDS file (its extension, any case), read through
 * image_oiio.h. */
int frame_is_dds(const char *path);
rc_status frame_write(const char *path, const scene *s, const mesh *m, const render_image *img, char *err,
                      size_t errlen);
/* frame_write naming another in-process renderer in the header ("reflcheck-exact"). */
rc_status frame_write_as(const char *path, const scene *s, const mesh *m, const render_image *img, const char *renderer,
                         char *err, size_t errlen);

#endif
