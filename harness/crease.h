/* crease.h - the samples where Cycles' shading-normal rules depart from the model's.
 *
 * Usage:
 *   float *share = malloc((size_t)w * (size_t)h * sizeof *share);
 *   crease_share(&scn, &msh, w, h, k, threads, share, err, sizeof err);   per pixel, in [0, 1]
 *   int d = crease_departs(n, ng, v, l, n_lights);                          one sample
 *
 * The model shades with the interpolated vertex normal N alone, turned toward the viewer. Cycles
 * (3.4, intern/cycles/kernel) also reads the triangle's own normal Ng, and three of its rules
 * change a sample whose N and Ng disagree, which happens along the creases of a low-poly mesh
 * whose vertex normals are smoothed across them:
 *   1. a back face flips N and Ng together, so an N that leans away from the viewer while Ng
 *      faces it stays away (the model turns it round);
 *   2. ensure_valid_reflection bends N toward Ng, for every BSDF, when the mirror direction
 *      R = 2 (N.V) N - V has R.Ng below min(0.9 Ng.V, 0.01);
 *   3. a light below the triangle (L.Ng < 0) is a transmission direction, which a reflective
 *      BSDF does not answer, though L.N > 0 lights the sample in the model.
 * crease_departs says whether any rule applies to one sample (unit n, ng, v and light
 * directions l, all pointing away from the surface; ng of either orientation). crease_share
 * rasterizes the mesh at the render's samples (model/raster.h, model/render.h's camera) and
 * writes each pixel's share of covered samples that depart (0 where none is covered), so
 * compare can leave those pixels out of a comparison with Cycles and report them
 * (harness/compare.c, renderer_row.crease_rules). The lights are the scene's (point and spot
 * from their position, sun from its direction), all of them. Returns RC_OK, RC_ERR_NOMEM, or
 * RC_ERR_RANGE with one line in err.
 */
#ifndef REFLCHECK_CREASE_H
#define REFLCHECK_CREASE_H

#include <stddef.h>
#include "mesh.h"
#include "scene.h"
#include "status.h"
#include "vec.h"

int crease_departs(vec3 n, vec3 ng, vec3 v, const vec3 *l, int n_lights);
rc_status crease_share(const scene *s, const mesh *m, int width, int height, int k, int threads, float *share,
                       char *err, size_t errlen);
/* The one rule compare and fit share: each METRICS_PX_INTERIOR pixel of cls (harness/metrics.h)
 * whose share is above 0 becomes METRICS_PX_CREASE. Returns the pixels moved; *interior (may be
 * NULL) gets the interior pixels there were. */
long crease_classify(unsigned char *cls, const float *share, size_t np, long *interior);

#endif
