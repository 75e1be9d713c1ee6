/* envfile.h - a scene's environment made ready for lookup (the EXR read through harness/exr.h).
 *
 * Usage:
 *   env_map e; float *pixels = NULL;
 *   if (envfile_load(&scn, &e, &pixels, err, sizeof err) != RC_OK) ...;
 *   ... env_lookup(&e, dir) ...
 *   free(pixels);                       the caller owns the interleaved RGB pixels
 * An image must have R, G and B channels; errors name the file and the scene.
 */
#ifndef REFLCHECK_ENVFILE_H
#define REFLCHECK_ENVFILE_H

#include <stddef.h>
#include "env.h"
#include "status.h"

rc_status envfile_load(const scene *s, env_map *e, float **pixels, char *err, size_t errlen);

#endif
