/* raster.c - tiled, multi-threaded rasterizer with exact integer coverage (see raster.h).
 *
 * Pipeline: triangles are binned to tiles in two passes (count, then fill) over
 * contiguous chunks of triangle indices, so every tile's list is in index order
 * whatever the chunking. Workers then take tiles from an atomic counter and redo the
 * per-triangle setup (clip, project, snap) for each binned triangle: this keeps the
 * memory at the bins plus one tile buffer per worker.
 *
 * Fixed point: screen coordinates are stored in units of 1/(S k) pixel, so sample
 * (sx, sy) of the (W k) x (H k) sample grid sits at the integers (S sx + S/2,
 * S sy + S/2). S is the finest power of two up to 2^18 that keeps the guard band (one
 * image width beyond each side) within +-2^29, and at least 512: 2^18 for images up to
 * 1024 samples across, 2^15 at 8192. Coordinates are kept within +-2^29 by the guard band,
 * so edge functions (products of two differences below 2^30) fit easily in int64.
 * Why fine: a sample that lies within half a fixed unit of an edge can land on its other
 * side, and at an occluding contour inside a mesh that sample sees the surface behind where
 * a ray tracer sees the one in front (measured at 1/512: WusonOBJ from behind, one sample
 * 7.8e-4 samples inside a contour, a pixel 5 % off against POV-Ray). 2^-18 sample is about
 * the float clip-space input's own rounding (2^-24 of W k / 2 samples at the image's side)
 * at 128 samples across, and finer beyond, so the rounding left is mostly the input's.
 *
 * Attributes do not come from the clipped vertices: for the original triangle with
 * clip-space columns V0, V1, V2, the rows of M^-1 = (V1xV2, V2xV0, V0xV1)/det give
 * F_i(u, v) = row_i . (u, v, 1) = b_i / w at normalised device point (u, v), so
 * 1/w = sum F_i and b_i = F_i / sum F_i for the original triangle, whatever clipping
 * did to it.
 */
#define _POSIX_C_SOURCE 200809L

#include "raster.h"
#include "smath.h"
#include "vec.h"

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define RASTER_STEP_MIN         512       /* fixed units per sample: the coarsest grid allowed */
#define RASTER_STEP_MAX         (1 << 18) /* ... and the finest (see the header comment) */
#define RASTER_FIX_LIMIT        (1 << 29) /* |fixed coordinate| bound kept by the guard band */
#define RASTER_MAX_POLY         16        /* 3 vertices + one per clip plane (5), + slack */
#define RASTER_MAX_THREADS      1024
#define RASTER_MAX_TILE_SAMPLES 4096      /* tile * k bound: keeps a worker buffer <= 320 MB */
#define RASTER_MAX_CHUNK_CELLS  (1 << 22) /* bound on chunks * tiles bookkeeping */

typedef struct {
    int32_t x, y;
} raster_fix;

typedef struct {
    const raster_vertex *v;
    const uint32_t *idx;
    int n_tris;
    int width, height, k, tile;
    int tiles_x, tiles_y, n_tiles;
    double near, gx, gy;
    double half_w_fix, half_h_fix; /* 0.5 * W (or H) * fixed units per pixel */
    int64_t step, half;            /* fixed units between neighbouring samples, and half that */
    int step_shift;                /* log2(step): step is a power of two */
    int n_chunks, chunk_len;
    uint32_t *counts;   /* [chunk][tile] bin entries */
    size_t *offsets;    /* [chunk][tile] write position during the fill */
    size_t *tile_start; /* [tile + 1] */
    uint32_t *bins;
    uint16_t (*rects)[4]; /* [triangle] tile range from the count pass; x0 > x1 = none */
    raster_tile_fn fn;
    void *user;
    int n_threads;
    int phase;
    atomic_int next;
    int planes_only;
    raster_sample **tile_samples; /* [thread], the planes interleaved for the callback */
    void **tile_planes;           /* [thread], tri then b1 then b2 planes of the tile */
    double **tile_depth;          /* [thread], 1/w of the current winner */
    double **tile_uv;             /* [thread], u per sample column then v per row */
} raster_ctx;

enum { RASTER_PHASE_COUNT, RASTER_PHASE_FILL, RASTER_PHASE_TILES };

static int64_t raster_floor_div(int64_t a, int64_t b)
{
    int64_t q = a / b;
    return (a % b != 0 && a < 0) ? q - 1 : q;
}

/* Round to nearest (ties to even) without a libm call: adding 1.5 * 2^52 leaves no
 * fraction bits for |x| < 2^51, far above the 2^29 fixed-point bound. */
static double raster_round(double x)
{
    const double magic = 6755399441055744.0;
    return (x + magic) - magic;
}

static int64_t raster_ceil_div(int64_t a, int64_t b) { return -raster_floor_div(-a, b); }

/* floor(a / step) and ceil(a / step) as shifts: a 64-bit divide costs tens of cycles and every
 * triangle's box takes four in the count pass and four more per tile. step is a power of two
 * and >> of a negative int64 is arithmetic (floor) with GCC and Clang, so the results are the
 * divisions' to the bit. */
static int64_t raster_floor_step(const raster_ctx *c, int64_t a) { return a >> c->step_shift; }

static int64_t raster_ceil_step(const raster_ctx *c, int64_t a) { return -((-a) >> c->step_shift); }

/* Signed distance-like value of clip-space point p (x, y, w stored as x, y, z) to plane i;
 * >= 0 is inside. */
static double raster_plane_dist(const raster_ctx *c, dvec3 p, int plane)
{
    switch (plane) {
    case 0: return p.z - c->near;
    case 1: return c->gx * p.z - p.x;
    case 2: return c->gx * p.z + p.x;
    case 3: return c->gy * p.z - p.y;
    default: return c->gy * p.z + p.y;
    }
}

/* Intersection computed from the inside end always, so the two triangles sharing an
 * edge get bit-identical clipped vertices and their coverage stays watertight. */
static dvec3 raster_intersect(dvec3 in, double d_in, dvec3 out, double d_out)
{
    double t = d_in / (d_in - d_out);
    return dv3_add(in, dv3_scale(dv3_sub(out, in), t));
}

static int raster_clip_plane(const raster_ctx *c, const dvec3 *in, int n, dvec3 *out, int plane)
{
    int m = 0;
    for (int i = 0; i < n; i++) {
        /* Exact clipping of a triangle adds one vertex per plane; rounding could in
         * principle make a near-degenerate polygon non-convex, so bound the output
         * (the caller then drops the sliver). */
        if (m + 2 > RASTER_MAX_POLY)
            return 0;
        dvec3 a = in[i], b = in[(i + 1) % n];
        double da = raster_plane_dist(c, a, plane), db = raster_plane_dist(c, b, plane);
        if (da >= 0)
            out[m++] = a;
        if ((da >= 0) != (db >= 0))
            out[m++] = da >= 0 ? raster_intersect(a, da, b, db) : raster_intersect(b, db, a, da);
    }
    return m;
}

static bool raster_load_tri(const raster_ctx *c, uint32_t t, dvec3 p[3])
{
    for (int i = 0; i < 3; i++) {
        const raster_vertex *rv = &c->v[c->idx[3 * (size_t)t + i]];
        if (!isfinite(rv->x) || !isfinite(rv->y) || !isfinite(rv->w))
            return false;
        p[i] = dv3(rv->x, rv->y, rv->w);
    }
    return true;
}

/* Clip triangle t, project and snap it. Returns the polygon's vertex count (0 when
 * nothing is left) and its orientation from the unsnapped positions in *orient. */
static int raster_polygon(const raster_ctx *c, uint32_t t, raster_fix *fix, int *orient)
{
    dvec3 a[RASTER_MAX_POLY], b[RASTER_MAX_POLY];
    if (!raster_load_tri(c, t, a))
        return 0;
    int n = 3;
    bool inside = true;
    for (int i = 0; i < 3; i++) {
        /* the same comparisons as raster_plane_dist(...) >= 0 for the five planes */
        double gw = c->gx * a[i].z, hw = c->gy * a[i].z;
        inside = inside && a[i].z >= c->near && a[i].x <= gw && -a[i].x <= gw && a[i].y <= hw && -a[i].y <= hw;
    }
    dvec3 *poly = a;
    if (!inside) {
        dvec3 *src = a, *dst = b;
        for (int pl = 0; pl < 5 && n >= 3; pl++) {
            n = raster_clip_plane(c, src, n, dst, pl);
            dvec3 *tmp = src;
            src = dst;
            dst = tmp;
        }
        poly = src;
        if (n < 3)
            return 0;
    }
    double fx[RASTER_MAX_POLY], fy[RASTER_MAX_POLY];
    const double lim = RASTER_FIX_LIMIT;
    for (int i = 0; i < n; i++) {
        /* Clipping leaves every point inside the guard band up to rounding; the clamp
         * only absorbs that rounding so the integer bound always holds. */
        double x = (poly[i].x / poly[i].z + 1.0) * c->half_w_fix;
        double y = (1.0 - poly[i].y / poly[i].z) * c->half_h_fix;
        fx[i] = x < -lim ? -lim : x > lim ? lim : x;
        fy[i] = y < -lim ? -lim : y > lim ? lim : y;
        fix[i].x = (int32_t)raster_round(fx[i]);
        fix[i].y = (int32_t)raster_round(fy[i]);
    }
    double area = 0;
    for (int i = 1; i + 1 < n; i++)
        area += (fx[i] - fx[0]) * (fy[i + 1] - fy[0]) - (fy[i] - fy[0]) * (fx[i + 1] - fx[0]);
    if (!(area != 0))
        return 0;
    *orient = area > 0 ? 1 : -1;
    return n;
}

/* Range of tiles touched by triangle t's bounding box; false when it misses the image. */
static bool raster_tile_range(const raster_ctx *c, uint32_t t, int r[4])
{
    raster_fix p[RASTER_MAX_POLY];
    int orient;
    int n = raster_polygon(c, t, p, &orient);
    if (n == 0)
        return false;
    int64_t x0 = p[0].x, x1 = p[0].x, y0 = p[0].y, y1 = p[0].y;
    for (int i = 1; i < n; i++) {
        if (p[i].x < x0)
            x0 = p[i].x;
        if (p[i].x > x1)
            x1 = p[i].x;
        if (p[i].y < y0)
            y0 = p[i].y;
        if (p[i].y > y1)
            y1 = p[i].y;
    }
    int64_t sx0 = raster_ceil_step(c, x0 - c->half);
    int64_t sx1 = raster_floor_step(c, x1 - c->half);
    int64_t sy0 = raster_ceil_step(c, y0 - c->half);
    int64_t sy1 = raster_floor_step(c, y1 - c->half);
    int64_t nsx = (int64_t)c->width * c->k, nsy = (int64_t)c->height * c->k;
    if (sx0 < 0)
        sx0 = 0;
    if (sy0 < 0)
        sy0 = 0;
    if (sx1 > nsx - 1)
        sx1 = nsx - 1;
    if (sy1 > nsy - 1)
        sy1 = nsy - 1;
    if (sx0 > sx1 || sy0 > sy1)
        return false;
    /* 0 <= sample index < 2^31 (the image's sample grid), so a 32-bit divide, cheaper than
     * a 64-bit one, gives the same quotient. */
    int ts = c->tile * c->k;
    r[0] = (int)sx0 / ts;
    r[1] = (int)sy0 / ts;
    r[2] = (int)sx1 / ts;
    r[3] = (int)sy1 / ts;
    return true;
}

typedef struct {
    bool ready, ok;
    dvec3 f1, f2, sum; /* F_1, F_2 and sum F_i as (u, v, 1) coefficient rows */
} raster_attr;

static void raster_attr_setup(const raster_ctx *c, uint32_t t, raster_attr *at)
{
    dvec3 p[3];
    at->ready = true;
    at->ok = false;
    if (!raster_load_tri(c, t, p))
        return;
    dvec3 r0 = dv3_cross(p[1], p[2]), r1 = dv3_cross(p[2], p[0]), r2 = dv3_cross(p[0], p[1]);
    double det = dv3_dot(p[0], r0);
    /* det = 0: the triangle's plane contains the eye, it is seen edge-on. */
    if (!(det != 0) || !isfinite(det))
        return;
    double inv = 1.0 / det;
    at->f1 = dv3_scale(r1, inv);
    at->f2 = dv3_scale(r2, inv);
    at->sum = dv3_scale(dv3_add(r0, dv3_add(r1, r2)), inv);
    at->ok = true;
}

typedef struct {
    int sx0, sy0, sx1, sy1; /* inclusive sample rectangle of the tile */
    int stride;
    int32_t *tri; /* the winners' planes, stride apart per row */
    float *b1, *b2;
    double *depth;
    const double *u, *v; /* NDC u per column, v per row */
} raster_target;

static int64_t raster_edge(raster_fix a, raster_fix b, int64_t px, int64_t py)
{
    return ((int64_t)b.x - a.x) * (py - a.y) - ((int64_t)b.y - a.y) * (px - a.x);
}

/* The sample rows and columns a sub-triangle's box covers, clipped to the target; 0 when none. */
static int raster_subtri_box(const raster_ctx *c, const raster_target *tg, const raster_fix *const q[3], int64_t box[4])
{
    int32_t x0 = q[0]->x, x1 = q[0]->x, y0 = q[0]->y, y1 = q[0]->y;
    for (int i = 1; i < 3; i++) {
        if (q[i]->x < x0)
            x0 = q[i]->x;
        if (q[i]->x > x1)
            x1 = q[i]->x;
        if (q[i]->y < y0)
            y0 = q[i]->y;
        if (q[i]->y > y1)
            y1 = q[i]->y;
    }
    int64_t sx0 = raster_ceil_step(c, (int64_t)x0 - c->half);
    int64_t sx1 = raster_floor_step(c, (int64_t)x1 - c->half);
    int64_t sy0 = raster_ceil_step(c, (int64_t)y0 - c->half);
    int64_t sy1 = raster_floor_step(c, (int64_t)y1 - c->half);
    if (sx0 < tg->sx0)
        sx0 = tg->sx0;
    if (sy0 < tg->sy0)
        sy0 = tg->sy0;
    if (sx1 > tg->sx1)
        sx1 = tg->sx1;
    if (sy1 > tg->sy1)
        sy1 = tg->sy1;
    box[0] = sx0;
    box[1] = sy0;
    box[2] = sx1;
    box[3] = sy1;
    return sx0 <= sx1 && sy0 <= sy1;
}

/* One row's covered samples, an interval [*lo, *hi] from sx0 (each edge function is linear
 * along the row): found exactly from the three edge values at sx0, e + step x >= 0, instead
 * of testing every sample of the bounding box. */
static void raster_row_span(const int64_t e_row[3], const int64_t step_x[3], int64_t *lo, int64_t *hi)
{
    for (int i = 0; i < 3 && *lo <= *hi; i++) {
        const int64_t e = e_row[i], st = step_x[i];
        if (st > 0 && e < 0) {
            int64_t m = raster_ceil_div(-e, st);
            *lo = m > *lo ? m : *lo;
        } else if (st < 0) {
            int64_t m = e < 0 ? -1 : raster_floor_div(e, -st);
            *hi = m < *hi ? m : *hi;
        } else if (st == 0 && e < 0) {
            *hi = -1;
        }
    }
}

/* Rows at least this long go through raster_row_fill_wide: below it the lane loops' setup
 * costs more than the scalar loop (at 10^6 triangles most rows are one or two samples). */
#define RASTER_WIDE_MIN  8
/* The lanes raster_row_fill_wide computes before storing, on the stack. */
#define RASTER_ROW_CHUNK 64

/* A sample's weights b1, b2 from its column's u and inverse depth w, clamped to [0, 1]. */
SMATH_INLINE void raster_sample_weights(const raster_attr *at, double u, double w, double f1_row, double f2_row,
                                        double *b1, double *b2)
{
    const double r = 1.0 / w;
    const double c1 = (at->f1.x * u + f1_row) * r, c2 = (at->f2.x * u + f2_row) * r;
    *b1 = c1 < 0.0 ? 0.0 : c1 > 1.0 ? 1.0 : c1;
    *b2 = c2 < 0.0 ? 0.0 : c2 > 1.0 ? 1.0 : c2;
}

/* A covered sample stored at place i of the row: snapping may admit samples up to one fixed
 * unit outside the true triangle, so weights summing past 1 are scaled back onto it. */
static inline void raster_sample_store(const raster_target *tg, size_t i, uint32_t t, double iw, double b1, double b2)
{
    if (b1 + b2 > 1.0) {
        double s = 1.0 / (b1 + b2);
        b1 *= s;
        b2 *= s;
    }
    tg->depth[i] = iw;
    tg->tri[i] = (int32_t)t;
    tg->b1[i] = (float)b1;
    tg->b2[i] = (float)b2;
}

/* The depth test and barycentrics of one row's covered samples [from, to] (target columns).
 * Strictly greater: on an exact tie the earlier (lower) index stays. */
static void raster_row_fill(const raster_target *tg, const raster_attr *at, uint32_t t, int64_t sy, int64_t from,
                            int64_t to)
{
    const size_t row = (size_t)(sy - tg->sy0) * tg->stride;
    const double v = tg->v[sy - tg->sy0];
    const double iw_row = at->sum.y * v + at->sum.z, f1_row = at->f1.y * v + at->f1.z, f2_row = at->f2.y * v + at->f2.z;
    for (int64_t sx = from; sx <= to; sx++) {
        const double u = tg->u[sx], iw = at->sum.x * u + iw_row;
        if (iw > tg->depth[row + (size_t)sx]) {
            double b1, b2;
            raster_sample_weights(at, u, iw, f1_row, f2_row, &b1, &b2);
            raster_sample_store(tg, row + (size_t)sx, t, iw, b1, b2);
        }
    }
}

/* raster_row_fill for a long row: the depths and clamped weights of RASTER_ROW_CHUNK samples at
 * a time as one lane loop (the division four or eight at a time), then the depth test and the
 * stores sample by sample; the rare renormalisation stays there, so a lane loop pays one division
 * a sample, not two. Same operations per stored sample as raster_row_fill. */
SMATH_CLONES
static void raster_row_fill_wide(const raster_target *tg, const raster_attr *at, uint32_t t, int64_t sy, int64_t from,
                                 int64_t to)
{
    const size_t row = (size_t)(sy - tg->sy0) * tg->stride;
    const double v = tg->v[sy - tg->sy0];
    const double iw_row = at->sum.y * v + at->sum.z, f1_row = at->f1.y * v + at->f1.z, f2_row = at->f2.y * v + at->f2.z;
    const double *restrict u = tg->u;
    for (int64_t c0 = from; c0 <= to; c0 += RASTER_ROW_CHUNK) {
        const int m = to - c0 + 1 < RASTER_ROW_CHUNK ? (int)(to - c0 + 1) : RASTER_ROW_CHUNK;
        double iw[RASTER_ROW_CHUNK], b1[RASTER_ROW_CHUNK], b2[RASTER_ROW_CHUNK];
#pragma omp simd
        for (int i = 0; i < m; i++) {
            iw[i] = at->sum.x * u[c0 + i] + iw_row;
            raster_sample_weights(at, u[c0 + i], iw[i], f1_row, f2_row, &b1[i], &b2[i]);
        }
        const size_t r0 = row + (size_t)c0;
        for (int i = 0; i < m; i++)
            if (iw[i] > tg->depth[r0 + (size_t)i])
                raster_sample_store(tg, r0 + (size_t)i, t, iw[i], b1[i], b2[i]);
    }
}

static void raster_subtri(const raster_ctx *c, const raster_target *tg, raster_fix p0, raster_fix p1, raster_fix p2,
                          int orient, uint32_t t, raster_attr *at)
{
    int64_t area = raster_edge(p0, p1, p2.x, p2.y);
    /* A sub-triangle that snapping turned over (or flattened) is a sliver: drop it. */
    if (area == 0 || (area > 0) != (orient > 0))
        return;
    if (area < 0) {
        raster_fix tmp = p1;
        p1 = p2;
        p2 = tmp;
    }
    const raster_fix *q[3] = {&p0, &p1, &p2};
    int64_t box[4];
    if (!raster_subtri_box(c, tg, q, box))
        return;
    const int64_t sx0 = box[0], sy0 = box[1], sx1 = box[2], sy1 = box[3];

    /* Edge i is opposite vertex i; inside is e >= 0. Top-left rule (y down, this
     * orientation): a top edge runs in +x with dy = 0, a left edge has dy < 0. Other
     * edges get a bias of -1 so a sample exactly on them (e = 0) fails the test. */
    const raster_fix *ea[3] = {&p1, &p2, &p0}, *eb[3] = {&p2, &p0, &p1};
    int64_t e_row[3], step_x[3], step_y[3];
    int64_t px = sx0 * c->step + c->half, py = sy0 * c->step + c->half;
    for (int i = 0; i < 3; i++) {
        int64_t dx = (int64_t)eb[i]->x - ea[i]->x, dy = (int64_t)eb[i]->y - ea[i]->y;
        bool top_left = dy < 0 || (dy == 0 && dx > 0);
        e_row[i] = raster_edge(*ea[i], *eb[i], px, py) - (top_left ? 0 : 1);
        step_x[i] = -dy * c->step;
        step_y[i] = dx * c->step;
    }
    if (!at->ready)
        raster_attr_setup(c, t, at);
    if (!at->ok)
        return;
    for (int64_t sy = sy0; sy <= sy1; sy++) {
        int64_t lo = 0, hi = sx1 - sx0;
        raster_row_span(e_row, step_x, &lo, &hi);
        for (int i = 0; i < 3; i++)
            e_row[i] += step_y[i];
        if (lo > hi)
            continue;
        if (hi - lo + 1 >= RASTER_WIDE_MIN)
            raster_row_fill_wide(tg, at, t, sy, sx0 - tg->sx0 + lo, sx0 - tg->sx0 + hi);
        else
            raster_row_fill(tg, at, t, sy, sx0 - tg->sx0 + lo, sx0 - tg->sx0 + hi);
    }
}

/* A tile's triangles are scattered through the index and vertex arrays (a triangle
 * soup has no locality), so the loads are the bottleneck: fetch the indices 16
 * entries ahead and the vertices 8 ahead. */
static void raster_prefetch(const raster_ctx *c, size_t e, size_t e_end)
{
#if defined(__GNUC__) || defined(__clang__)
    if (e + 16 < e_end)
        __builtin_prefetch(&c->idx[3 * (size_t)c->bins[e + 16]]);
    if (e + 8 < e_end) {
        const uint32_t *ix = &c->idx[3 * (size_t)c->bins[e + 8]];
        for (int i = 0; i < 3; i++)
            __builtin_prefetch(&c->v[ix[i]]);
    }
#else
    (void)c;
    (void)e;
    (void)e_end;
#endif
}

static void raster_tile_run(raster_ctx *c, int tile, int thread)
{
    int k = c->k;
    int tx = tile % c->tiles_x, ty = tile / c->tiles_x;
    int x0 = tx * c->tile, y0 = ty * c->tile;
    int tw = c->width - x0 < c->tile ? c->width - x0 : c->tile;
    int th = c->height - y0 < c->tile ? c->height - y0 : c->tile;
    raster_target tg;
    tg.sx0 = x0 * k;
    tg.sy0 = y0 * k;
    tg.sx1 = tg.sx0 + tw * k - 1;
    tg.sy1 = tg.sy0 + th * k - 1;
    tg.stride = tw * k;
    const size_t row = (size_t)tw * k, ns = row * (size_t)(th * k);
    tg.tri = c->tile_planes[thread];
    tg.b1 = (float *)(tg.tri + ns);
    tg.b2 = tg.b1 + ns;
    tg.depth = c->tile_depth[thread];
    double *u = c->tile_uv[thread], *v = u + tw * k;
    for (int i = 0; i < tw * k; i++)
        u[i] = (tg.sx0 + i + 0.5) * 2.0 / ((double)k * c->width) - 1.0;
    for (int j = 0; j < th * k; j++)
        v[j] = 1.0 - (tg.sy0 + j + 0.5) * 2.0 / ((double)k * c->height);
    tg.u = u;
    tg.v = v;
    /* Every sample empty: triangle -1 (all one bytes in two's complement), weights and depth
     * 0.0 (all zero bytes). With planes_only the weights of an empty sample are not cleared: a
     * caller of the planes reads b1, b2 only where tri >= 0 (raster.h), and the two planes were
     * 40 % of the bytes cleared per tile (the depth is a double). */
    memset(tg.tri, 0xff, ns * sizeof *tg.tri);
    if (!c->planes_only)
        memset(tg.b1, 0, 2 * ns * sizeof *tg.b1);
    memset(tg.depth, 0, ns * sizeof *tg.depth);
    size_t e_end = c->tile_start[tile + 1];
    for (size_t e = c->tile_start[tile]; e < e_end; e++) {
        uint32_t t = c->bins[e];
        raster_prefetch(c, e, e_end);
        raster_fix p[RASTER_MAX_POLY];
        int orient;
        int n = raster_polygon(c, t, p, &orient);
        raster_attr at = {0};
        for (int i = 1; i + 1 < n; i++)
            raster_subtri(c, &tg, p[0], p[i], p[i + 1], orient, t, &at);
    }
    raster_tile rt = {x0, y0, tw, th, k, thread, NULL, tg.tri, tg.b1, tg.b2};
    if (!c->planes_only) {
        raster_sample *restrict sp = c->tile_samples[thread];
        for (size_t i = 0; i < ns; i++)
            sp[i] = (raster_sample){tg.tri[i], tg.b1[i], tg.b2[i]};
        rt.samples = sp;
    }
    c->fn(c->user, &rt);
}

static void raster_chunk_bounds(const raster_ctx *c, int ch, int *t0, int *t1)
{
    *t0 = ch * c->chunk_len;
    *t1 = *t0 + c->chunk_len < c->n_tris ? *t0 + c->chunk_len : c->n_tris;
}

typedef struct {
    raster_ctx *c;
    int id;
} raster_worker_arg;

static void *raster_worker(void *arg)
{
    raster_worker_arg *w = arg;
    raster_ctx *c = w->c;
    int items = c->phase == RASTER_PHASE_TILES ? c->n_tiles : c->n_chunks;
    for (;;) {
        int it = atomic_fetch_add(&c->next, 1);
        if (it >= items)
            break;
        if (c->phase == RASTER_PHASE_TILES) {
            raster_tile_run(c, it, w->id);
            continue;
        }
        int t0, t1, r[4];
        raster_chunk_bounds(c, it, &t0, &t1);
        size_t base = (size_t)it * c->n_tiles;
        for (int t = t0; t < t1; t++) {
            uint16_t *rc = c->rects[t];
            if (c->phase == RASTER_PHASE_COUNT) {
                if (!raster_tile_range(c, (uint32_t)t, r)) {
                    rc[0] = 1;
                    rc[2] = 0;
                    continue;
                }
                for (int i = 0; i < 4; i++)
                    rc[i] = (uint16_t)r[i];
            }
            for (int y = rc[1]; y <= rc[3]; y++)
                for (int x = rc[0]; x <= rc[2]; x++) {
                    size_t cell = base + (size_t)y * c->tiles_x + x;
                    if (c->phase == RASTER_PHASE_COUNT)
                        c->counts[cell]++;
                    else
                        c->bins[c->offsets[cell]++] = (uint32_t)t;
                }
        }
    }
    return NULL;
}

/* Runs one phase on the pool; work items come from an atomic counter, so threads
 * that could not be started only cost speed. */
static void raster_run_phase(raster_ctx *c, int phase)
{
    pthread_t th[RASTER_MAX_THREADS];
    raster_worker_arg args[RASTER_MAX_THREADS];
    bool started[RASTER_MAX_THREADS];
    c->phase = phase;
    atomic_store(&c->next, 0);
    for (int i = 0; i < c->n_threads; i++) {
        args[i].c = c;
        args[i].id = i;
        started[i] = i > 0 && pthread_create(&th[i], NULL, raster_worker, &args[i]) == 0;
    }
    raster_worker(&args[0]);
    for (int i = 1; i < c->n_threads; i++)
        if (started[i])
            pthread_join(th[i], NULL);
}

int raster_thread_count(const raster_options *opt)
{
    if (opt && opt->threads > 0)
        return opt->threads > RASTER_MAX_THREADS ? RASTER_MAX_THREADS : opt->threads;
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    if (n < 1)
        n = 1;
    return n > RASTER_MAX_THREADS ? RASTER_MAX_THREADS : (int)n;
}

static void raster_free(raster_ctx *c)
{
    free(c->counts);
    free(c->offsets);
    free(c->tile_start);
    free(c->bins);
    free(c->rects);
    for (int i = 0; i < c->n_threads; i++) {
        if (c->tile_samples)
            free(c->tile_samples[i]);
        if (c->tile_planes)
            free(c->tile_planes[i]);
        if (c->tile_depth)
            free(c->tile_depth[i]);
        if (c->tile_uv)
            free(c->tile_uv[i]);
    }
    free(c->tile_samples);
    free(c->tile_planes);
    free(c->tile_depth);
    free(c->tile_uv);
}

/* Step 1 of a draw: the arguments, refused whole when any is out of range. */
static rc_status raster_check_args(const raster_vertex *v, int n_verts, const uint32_t *idx, int n_tris,
                                   const raster_options *opt, raster_tile_fn fn)
{
    if (!opt || !fn || n_verts < 0 || n_tris < 0)
        return RC_ERR_RANGE;
    if (n_tris > 0 && (!v || !idx))
        return RC_ERR_RANGE;
    if (opt->width <= 0 || opt->height <= 0)
        return RC_ERR_RANGE;
    if (opt->supersample < 0 || opt->supersample > 16)
        return RC_ERR_RANGE;
    if (opt->threads < 0 || opt->threads > RASTER_MAX_THREADS || opt->tile < 0)
        return RC_ERR_RANGE;
    if (!(opt->near >= 0) || !isfinite(opt->near))
        return RC_ERR_RANGE;
    for (size_t i = 0; i < 3 * (size_t)n_tris; i++)
        if (idx[i] >= (uint32_t)n_verts)
            return RC_ERR_RANGE;
    return RC_OK;
}

/* Step 2: the fixed-point grid, its guard band and the tiles. */
static rc_status raster_setup_grid(raster_ctx *c, const raster_options *opt)
{
    c->width = opt->width;
    c->height = opt->height;
    c->k = opt->supersample ? opt->supersample : 1;
    c->tile = opt->tile ? opt->tile : RASTER_TILE_DEFAULT;
    if ((int64_t)c->tile * c->k > RASTER_MAX_TILE_SAMPLES)
        return RC_ERR_RANGE;
    c->near = opt->near > 0 ? opt->near : 1e-3;
    /* The finest grid whose guard band still reaches 3 (below): step * k * max(W, H) <= 2^28. */
    int64_t across = (int64_t)c->k * (c->width > c->height ? c->width : c->height);
    c->step = RASTER_STEP_MAX;
    while (c->step > RASTER_STEP_MIN && c->step * across > (int64_t)RASTER_FIX_LIMIT / 2)
        c->step /= 2;
    c->half = c->step / 2;
    c->step_shift = 0;
    while (((int64_t)1 << c->step_shift) < c->step)
        c->step_shift++;
    double fix_per_px = (double)c->k * (double)c->step;
    c->gx = 2.0 * RASTER_FIX_LIMIT / (fix_per_px * c->width) - 1.0;
    c->gy = 2.0 * RASTER_FIX_LIMIT / (fix_per_px * c->height) - 1.0;
    /* The guard band must sit well outside the image (3 = at least one image width on
     * each side); a larger image would not fit the fixed-point range. */
    if (c->gx < 3.0 || c->gy < 3.0)
        return RC_ERR_RANGE;
    c->half_w_fix = 0.5 * c->width * fix_per_px;
    c->half_h_fix = 0.5 * c->height * fix_per_px;
    c->tiles_x = (c->width + c->tile - 1) / c->tile;
    c->tiles_y = (c->height + c->tile - 1) / c->tile;
    /* tile ranges are cached as uint16 per axis */
    if (c->tiles_x > UINT16_MAX || c->tiles_y > UINT16_MAX)
        return RC_ERR_RANGE;
    if ((int64_t)c->tiles_x * c->tiles_y > INT32_MAX / 2)
        return RC_ERR_RANGE;
    c->n_tiles = c->tiles_x * c->tiles_y;
    return RC_OK;
}

/* Step 3: the triangles' chunks (binned in parallel) and every buffer of the draw. */
static rc_status raster_alloc_bins(raster_ctx *c, int n_tris)
{
    int max_chunks = RASTER_MAX_CHUNK_CELLS / c->n_tiles;
    c->n_chunks = 16 * c->n_threads;
    if (c->n_chunks > n_tris / 1024 + 1)
        c->n_chunks = n_tris / 1024 + 1;
    if (c->n_chunks > max_chunks)
        c->n_chunks = max_chunks;
    if (c->n_chunks < 1)
        c->n_chunks = 1;
    c->chunk_len = (n_tris + c->n_chunks - 1) / c->n_chunks;
    if (c->chunk_len < 1)
        c->chunk_len = 1;

    size_t cells = (size_t)c->n_chunks * c->n_tiles;
    c->counts = calloc(cells, sizeof *c->counts);
    c->offsets = malloc(cells * sizeof *c->offsets);
    c->tile_start = malloc(((size_t)c->n_tiles + 1) * sizeof *c->tile_start);
    c->tile_samples = calloc((size_t)c->n_threads, sizeof *c->tile_samples);
    c->tile_planes = calloc((size_t)c->n_threads, sizeof *c->tile_planes);
    c->tile_depth = calloc((size_t)c->n_threads, sizeof *c->tile_depth);
    c->tile_uv = calloc((size_t)c->n_threads, sizeof *c->tile_uv);
    c->rects = malloc(((size_t)n_tris + 1) * sizeof *c->rects);
    if (!c->rects || !c->counts || !c->offsets || !c->tile_start || !c->tile_samples || !c->tile_planes ||
        !c->tile_depth || !c->tile_uv)
        return RC_ERR_NOMEM;
    size_t tsn = (size_t)c->tile * c->k;
    for (int i = 0; i < c->n_threads; i++) {
        /* The structures only when the callback reads them. */
        c->tile_samples[i] = c->planes_only ? NULL : malloc(tsn * tsn * sizeof(raster_sample));
        /* Zeroed once: with planes_only a tile's empty samples keep the bytes an earlier tile
         * left, and in the first tile these are zeros, not uninitialised memory. */
        c->tile_planes[i] = calloc(tsn * tsn, sizeof(int32_t) + 2 * sizeof(float));
        c->tile_depth[i] = malloc(tsn * tsn * sizeof(double));
        c->tile_uv[i] = malloc(2 * tsn * sizeof(double));
        if ((!c->planes_only && !c->tile_samples[i]) || !c->tile_planes[i] || !c->tile_depth[i] || !c->tile_uv[i])
            return RC_ERR_NOMEM;
    }
    return RC_OK;
}

/* Step 4: each tile's and chunk's place in the bins, from the counts; 0 when the bins
 * cannot be allocated. */
static int raster_place_bins(raster_ctx *c)
{
    size_t total = 0;
    for (int t = 0; t < c->n_tiles; t++) {
        c->tile_start[t] = total;
        for (int ch = 0; ch < c->n_chunks; ch++) {
            size_t cell = (size_t)ch * c->n_tiles + t;
            c->offsets[cell] = total;
            total += c->counts[cell];
        }
    }
    c->tile_start[c->n_tiles] = total;
    c->bins = malloc((total ? total : 1) * sizeof *c->bins);
    return c->bins != NULL;
}

rc_status raster_draw(const raster_vertex *v, int n_verts, const uint32_t *idx, int n_tris, const raster_options *opt,
                      raster_tile_fn fn, void *user)
{
    rc_status rc = raster_check_args(v, n_verts, idx, n_tris, opt, fn);
    if (rc != RC_OK)
        return rc;
    raster_ctx c;
    memset(&c, 0, sizeof c);
    c.v = v;
    c.idx = idx;
    c.n_tris = n_tris;
    if ((rc = raster_setup_grid(&c, opt)) != RC_OK)
        return rc;
    c.fn = fn;
    c.user = user;
    c.n_threads = raster_thread_count(opt);
    c.planes_only = opt->planes_only != 0;

    rc = RC_ERR_NOMEM;
    if (raster_alloc_bins(&c, n_tris) == RC_OK) {
        raster_run_phase(&c, RASTER_PHASE_COUNT);
        if (raster_place_bins(&c)) {
            raster_run_phase(&c, RASTER_PHASE_FILL);
            raster_run_phase(&c, RASTER_PHASE_TILES);
            rc = RC_OK;
        }
    }
    raster_free(&c);
    return rc;
}
