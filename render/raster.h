/* raster.h - a tiled, multi-threaded triangle rasterizer that knows nothing of shading.
 *
 * Usage:
 *   raster_vertex v[n];   clip-space x, y and w (w = view depth > 0 in front of the camera)
 *   raster_options o = {.width = W, .height = H, .supersample = k};   zero = default
 *   raster_draw(v, n, idx, n_tris, &o, my_tile_fn, user);
 * Screen mapping: pixel column = (x/w + 1)/2 * W, row = (1 - y/w)/2 * H, row 0 at the top.
 * Sample (s, t) of pixel (i, j) lies at (i + (s + 0.5)/k, j + (t + 0.5)/k): the positions
 * POV-Ray samples when rendered at k times the size.
 * Coverage uses exact integer edge functions with a top-left fill rule, so a sample on an
 * edge shared by two triangles belongs to exactly one. Both windings are drawn.
 * Depth: the nearest (largest 1/w) wins; on an exact tie the lower triangle index wins.
 * Triangles are clipped against the near plane w = near and a guard band.
 * Each tile comes both as raster_sample structures and as planes (tri, b1, b2); a caller that
 * reads the planes only sets planes_only and saves the interleaving pass and the clearing of
 * b1, b2: with planes_only the weights of an empty sample (tri -1) are unspecified bits (what
 * an earlier tile left there), so such a caller uses b1, b2 only where tri >= 0.
 * The callback gets each finished tile once, from any worker thread; tiles are disjoint,
 * so writing the tile's own pixels needs no locking and the result does not depend on
 * the thread count. Returns RC_OK, RC_ERR_NOMEM, or RC_ERR_RANGE for bad options.
 */
#ifndef REFLCHECK_RASTER_H
#define REFLCHECK_RASTER_H

#include <stdint.h>
#include "status.h"

typedef struct {
    float x, y, w;
} raster_vertex;

/* The tile edge in pixels when raster_options.tile is 0. */
#define RASTER_TILE_DEFAULT 16

typedef struct {
    int width, height; /* image size in pixels */
    int supersample;   /* k (k*k samples per pixel), 0 = 1 */
    int threads;       /* 0 = all cores */
    int tile;          /* tile edge in pixels, 0 = RASTER_TILE_DEFAULT */
    float near;        /* near plane in w, 0 = 1e-3 */
    int planes_only;   /* 1: tiles carry the tri, b1, b2 planes only (samples NULL; b1, b2
                          unspecified where tri is -1), 0: both */
} raster_options;

/* One sample: the triangle that covers it (-1 for none) and the perspective-correct
 * barycentric weights of that triangle's vertices 1 and 2 (vertex 0 gets 1 - b1 - b2). */
typedef struct {
    int32_t tri;
    float b1, b2;
} raster_sample;

typedef struct {
    int x0, y0, w, h;             /* pixel rectangle */
    int k;                        /* supersample factor */
    int thread;                   /* worker index, 0..threads-1, for per-thread scratch */
    const raster_sample *samples; /* (h*k) rows of (w*k) samples, row-major, top row first */
    /* The same samples as three planes of the same layout (a lane loop reads them whole). */
    const int32_t *tri;
    const float *b1, *b2;
} raster_tile;

typedef void (*raster_tile_fn)(void *user, const raster_tile *tile);

rc_status raster_draw(const raster_vertex *v, int n_verts, const uint32_t *idx, int n_tris, const raster_options *opt,
                      raster_tile_fn fn, void *user);
/* The worker count raster_draw will use for these options. */
int raster_thread_count(const raster_options *opt);

#endif
