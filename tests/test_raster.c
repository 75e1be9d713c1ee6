/* test_raster.c - coverage, fill rule, sample positions, perspective, clipping, depth,
 * sub-sample precision at a contour and thread invariance of render/raster.c. Expected values
 * come from hand-worked pixel sets or from analytic ray-plane intersection, never from the
 * rasterizer itself. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#include "raster.h"
#include "vec.h"

/* A full-frame copy of the samples, filled tile by tile from the callback. */
typedef struct {
    int sw, sh; /* sample grid size */
    raster_sample *s;
    int *tile_hits; /* per pixel: how many tiles claimed it */
    int *thread;    /* per pixel: the worker that delivered its tile */
    int w, h;
    int planes_only; /* drawn with raster_options.planes_only: the tiles must carry no structures */
} frame;

static void frame_init(frame *f, int w, int h, int k)
{
    f->w = w;
    f->planes_only = 0;
    f->h = h;
    f->sw = w * k;
    f->sh = h * k;
    f->s = calloc((size_t)f->sw * f->sh, sizeof *f->s);
    f->tile_hits = calloc((size_t)w * h, sizeof *f->tile_hits);
    assert_non_null(f->s);
    f->thread = calloc((size_t)w * h, sizeof *f->thread);
    assert_non_null(f->tile_hits);
    assert_non_null(f->thread);
}

static void frame_free(frame *f)
{
    free(f->s);
    free(f->tile_hits);
    free(f->thread);
}

/* The tile into the frame from its planes; where it also carries the structures (planes_only
 * 0), each of them must equal its planes' entries. */
static void frame_tile(void *user, const raster_tile *t)
{
    frame *f = user;
    int k = t->k;
    for (int j = 0; j < t->h * k; j++)
        for (int i = 0; i < t->w * k; i++) {
            const size_t o = (size_t)j * (size_t)(t->w * k) + (size_t)i;
            raster_sample *d = &f->s[(size_t)(t->y0 * k + j) * f->sw + t->x0 * k + i];
            *d = (raster_sample){t->tri[o], t->b1[o], t->b2[o]};
            if (f->planes_only)
                assert_null(t->samples);
            else
                assert_memory_equal(&t->samples[o], d, sizeof *d);
        }
    /* tiles are disjoint, so this unlocked update only races if the rasterizer is wrong */
    for (int j = 0; j < t->h; j++)
        for (int i = 0; i < t->w; i++) {
            f->tile_hits[(t->y0 + j) * f->w + t->x0 + i]++;
            f->thread[(t->y0 + j) * f->w + t->x0 + i] = t->thread;
        }
}

static const raster_sample *frame_at(const frame *f, int sx, int sy) { return &f->s[(size_t)sy * f->sw + sx]; }

/* Clip-space vertex (w = 1) at pixel position (px, py) of a w x h image, from the
 * header's mapping: pixel = (x + 1)/2 W, row = (1 - y)/2 H. */
static raster_vertex px_vertex(double px, double py, int w, int h)
{
    raster_vertex v = {(float)(2.0 * px / w - 1.0), (float)(1.0 - 2.0 * py / h), 1.0f};
    return v;
}

static void draw(const raster_vertex *v, int nv, const uint32_t *idx, int nt, raster_options o, frame *f)
{
    assert_int_equal(raster_draw(v, nv, idx, nt, &o, frame_tile, f), RC_OK);
    for (int i = 0; i < f->w * f->h; i++)
        assert_int_equal(f->tile_hits[i], 1);
}

/* Adds 1 to cov[] for every sample each triangle covers when drawn on its own. */
static void coverage_per_triangle(const raster_vertex *v, int nv, const uint32_t *idx, int nt, raster_options o,
                                  int *cov)
{
    for (int t = 0; t < nt; t++) {
        frame f;
        frame_init(&f, o.width, o.height, o.supersample);
        draw(v, nv, idx + 3 * t, 1, o, &f);
        for (int i = 0; i < f.sw * f.sh; i++) {
            if (f.s[i].tri >= 0) {
                assert_int_equal(f.s[i].tri, 0);
                cov[i]++;
            }
        }
        frame_free(&f);
    }
}

/* Square [0.25, 6.25)^2 in pixels with k = 2: samples sit at 0.25 + 0.5 m, so the four
 * sides and the diagonal pass exactly through samples. Top-left: left and top sides
 * are in, right and bottom out, so exactly sample indices 0..11 on each axis. */
static void check_square_coverage(const int *cov, int sw, int sh)
{
    for (int sy = 0; sy < sh; sy++)
        for (int sx = 0; sx < sw; sx++) {
            int want = (sx <= 11 && sy <= 11) ? 1 : 0;
            if (cov[sy * sw + sx] != want)
                fail_msg("sample (%d,%d): covered %d times, want %d", sx, sy, cov[sy * sw + sx], want);
        }
}

static void test_shared_edge_quad(void **state)
{
    (void)state;
    const int w = 8, h = 8;
    raster_options o = {.width = w, .height = h, .supersample = 2, .threads = 2, .tile = 4};
    raster_vertex v[4] = {px_vertex(0.25, 0.25, w, h), px_vertex(6.25, 0.25, w, h), px_vertex(6.25, 6.25, w, h),
                          px_vertex(0.25, 6.25, w, h)};
    /* main diagonal 0-2; first triangle clockwise on screen, second anticlockwise */
    uint32_t idx_a[6] = {0, 1, 2, 0, 3, 2};
    /* other diagonal 1-3, which also passes through samples */
    uint32_t idx_b[6] = {1, 3, 0, 3, 1, 2};
    int cov[16 * 16];
    memset(cov, 0, sizeof cov);
    coverage_per_triangle(v, 4, idx_a, 2, o, cov);
    check_square_coverage(cov, 16, 16);
    memset(cov, 0, sizeof cov);
    coverage_per_triangle(v, 4, idx_b, 2, o, cov);
    check_square_coverage(cov, 16, 16);

    /* together: every sample of the square is covered by the triangle that owns it */
    frame f;
    frame_init(&f, w, h, 2);
    draw(v, 4, idx_a, 2, o, &f);
    for (int sy = 0; sy < 16; sy++)
        for (int sx = 0; sx < 16; sx++) {
            int tri = frame_at(&f, sx, sy)->tri;
            if (sx > 11 || sy > 11)
                assert_int_equal(tri, -1);
            /* below the diagonal (larger y) belongs to triangle 1 (0, 3, 2) */
            else if (sy > sx)
                assert_int_equal(tri, 1);
            else if (sy < sx)
                assert_int_equal(tri, 0);
            else
                assert_true(tri == 0 || tri == 1);
        }
    frame_free(&f);
}

static void test_fan(void **state)
{
    (void)state;
    const int w = 8, h = 8;
    raster_options o = {.width = w, .height = h, .supersample = 2, .threads = 3, .tile = 2};
    /* off-centre hub on a sample, eight rim vertices on the square's boundary */
    raster_vertex v[9] = {px_vertex(3.25, 2.75, w, h), px_vertex(0.25, 0.25, w, h), px_vertex(3.25, 0.25, w, h),
                          px_vertex(6.25, 0.25, w, h), px_vertex(6.25, 3.25, w, h), px_vertex(6.25, 6.25, w, h),
                          px_vertex(3.25, 6.25, w, h), px_vertex(0.25, 6.25, w, h), px_vertex(0.25, 3.25, w, h)};
    uint32_t idx[24];
    for (int i = 0; i < 8; i++) {
        uint32_t a = 1 + i, b = 1 + (i + 1) % 8;
        /* mixed windings */
        idx[3 * i] = 0;
        idx[3 * i + 1] = (i % 3 == 0) ? b : a;
        idx[3 * i + 2] = (i % 3 == 0) ? a : b;
    }
    int cov[16 * 16];
    memset(cov, 0, sizeof cov);
    coverage_per_triangle(v, 9, idx, 8, o, cov);
    check_square_coverage(cov, 16, 16);
    /* the hub itself is the sample (6, 5) */
    assert_int_equal(cov[5 * 16 + 6], 1);
}

static int covered(const frame *f, double px, double py)
{
    int k = f->sw / f->w;
    int sx = (int)lround(px * k - 0.5), sy = (int)lround(py * k - 0.5);
    return frame_at(f, sx, sy)->tri >= 0;
}

static void test_top_left(void **state)
{
    (void)state;
    const int w = 8, h = 8;
    raster_options o = {.width = w, .height = h, .supersample = 2, .threads = 1};
    frame f;
    /* legs on the top and left, hypotenuse x + y = 4.5 is a right edge */
    raster_vertex a[3] = {px_vertex(0.25, 0.25, w, h), px_vertex(4.25, 0.25, w, h), px_vertex(0.25, 4.25, w, h)};
    uint32_t idx[3] = {0, 1, 2};
    frame_init(&f, w, h, 2);
    draw(a, 3, idx, 1, o, &f);
    assert_true(covered(&f, 0.25, 0.25));  /* top-left corner */
    assert_true(covered(&f, 2.25, 0.25));  /* on the top edge */
    assert_true(covered(&f, 0.25, 2.25));  /* on the left edge */
    assert_true(covered(&f, 1.75, 2.25));  /* inside, next to the hypotenuse */
    assert_false(covered(&f, 2.25, 2.25)); /* on the hypotenuse (a right edge) */
    assert_false(covered(&f, 4.25, 0.25)); /* end of the top edge on the right edge */
    assert_false(covered(&f, 0.25, 4.25)); /* end of the left edge on the bottom */
    int n = 0;
    for (int i = 0; i < f.sw * f.sh; i++)
        n += f.s[i].tri >= 0;
    /* samples (m, n) with m, n >= 0 and m + n <= 7 (m + n = 8 is the hypotenuse) */
    assert_int_equal(n, 36);
    frame_free(&f);

    /* mirrored: legs on the right and bottom are out, hypotenuse is now a left edge */
    raster_vertex b[3] = {px_vertex(4.25, 4.25, w, h), px_vertex(0.25, 4.25, w, h), px_vertex(4.25, 0.25, w, h)};
    frame_init(&f, w, h, 2);
    draw(b, 3, idx, 1, o, &f);
    assert_true(covered(&f, 2.25, 2.25));
    assert_true(covered(&f, 3.75, 3.75));
    assert_false(covered(&f, 4.25, 2.25));
    assert_false(covered(&f, 2.25, 4.25));
    assert_false(covered(&f, 4.25, 4.25));
    n = 0;
    for (int i = 0; i < f.sw * f.sh; i++)
        n += f.s[i].tri >= 0;
    /* m + n >= 8 with m, n <= 7: 1 + 2 + ... + 7 = 28 */
    assert_int_equal(n, 28);
    frame_free(&f);
}

static void test_asymmetric_pixels(void **state)
{
    (void)state;
    /* 16 x 8 image, triangle (2,1) (10,1) (2,5) in pixels written out by hand in clip
     * space (x = X/8 - 1, y = 1 - Y/4), so a flip of x, y or row order changes the set. */
    raster_vertex v[3] = {{-0.75f, 0.75f, 1.0f}, {0.25f, 0.75f, 1.0f}, {-0.75f, -0.25f, 1.0f}};
    uint32_t idx[3] = {0, 1, 2};
    /* centres (i + .5, j + .5) with i >= 2, j >= 1, i + 2j <= 10 */
    static const int last_i[8] = {-1, 8, 6, 4, 2, -1, -1, -1};
    raster_options o = {.width = 16, .height = 8, .threads = 2, .tile = 8};
    frame f;
    frame_init(&f, 16, 8, 1);
    draw(v, 3, idx, 1, o, &f);
    for (int j = 0; j < 8; j++)
        for (int i = 0; i < 16; i++) {
            const raster_sample *s = frame_at(&f, i, j);
            bool want = last_i[j] >= 0 && i >= 2 && i <= last_i[j];
            if ((s->tri == 0) != want)
                fail_msg("pixel (%d,%d): tri %d", i, j, s->tri);
            if (want) {
                /* affine (w = 1): P = v0 + b1 (8, 0) + b2 (0, 4); 1e-6 covers the float
                 * output and the float clip coordinates (exact here) */
                assert_float_equal(s->b1, (i + 0.5 - 2.0) / 8.0, 1e-6);
                assert_float_equal(s->b2, (j + 0.5 - 1.0) / 4.0, 1e-6);
            }
        }
    frame_free(&f);
}

/* Ray through sample (sx, sy): direction (u, v, 1) in the test's view space, where
 * clip = (X, Y, depth) with a 90-degree frustum. */
static dvec3 sample_dir(int sx, int sy, int sw, int sh)
{
    return dv3(2.0 * (sx + 0.5) / sw - 1.0, 1.0 - 2.0 * (sy + 0.5) / sh, 1.0);
}

/* Analytic hit of the ray t * dir with triangle p: t and barycentrics (b1, b2). */
static bool ray_tri(dvec3 dir, const dvec3 p[3], double *t, double *b1, double *b2)
{
    dvec3 e1 = dv3_sub(p[1], p[0]), e2 = dv3_sub(p[2], p[0]);
    dvec3 n = dv3_cross(e1, e2);
    double dn = dv3_dot(n, dir);
    if (dn == 0)
        return false;
    *t = dv3_dot(n, p[0]) / dn;
    dvec3 q = dv3_sub(dv3_scale(dir, *t), p[0]);
    /* solve q = b1 e1 + b2 e2 by projecting on n x e2 and e1 x n */
    double nn = dv3_dot(n, n);
    *b1 = dv3_dot(q, dv3_cross(e2, n)) / nn;
    *b2 = dv3_dot(q, dv3_cross(n, e1)) / nn;
    return true;
}

static raster_vertex view_vertex(dvec3 p)
{
    raster_vertex v = {(float)p.x, (float)p.y, (float)p.z};
    return v;
}

static void test_perspective(void **state)
{
    (void)state;
    /* a quad receding from depth 1.5 to 6, off-centre; values exact in float */
    dvec3 p[4] = {dv3(-1.0, -0.5, 1.5), dv3(1.25, -0.5, 1.5), dv3(1.25, 0.375, 6.0), dv3(-1.0, 0.375, 6.0)};
    raster_vertex v[4];
    for (int i = 0; i < 4; i++)
        v[i] = view_vertex(p[i]);
    uint32_t idx[6] = {0, 1, 2, 0, 2, 3};
    const int w = 40, h = 24, k = 2;
    raster_options o = {.width = w, .height = h, .supersample = k, .threads = 2, .tile = 16};
    frame f;
    frame_init(&f, w, h, k);
    draw(v, 4, idx, 2, o, &f);
    int n = 0;
    for (int sy = 0; sy < f.sh; sy++)
        for (int sx = 0; sx < f.sw; sx++) {
            const raster_sample *s = frame_at(&f, sx, sy);
            if (s->tri < 0)
                continue;
            n++;
            const uint32_t *ti = idx + 3 * s->tri;
            dvec3 q[3] = {p[ti[0]], p[ti[1]], p[ti[2]]};
            double b0 = 1.0 - s->b1 - s->b2;
            /* world position from the rasterizer's weights */
            dvec3 pos = dv3_add(dv3_scale(q[0], b0), dv3_add(dv3_scale(q[1], s->b1), dv3_scale(q[2], s->b2)));
            double t, a1, a2;
            dvec3 dir = sample_dir(sx, sy, f.sw, f.sh);
            assert_true(ray_tri(dir, q, &t, &a1, &a2));
            /* the true hit, from the plane alone; samples a snapping step outside the
             * triangle get clamped weights, so compare those only loosely */
            bool interior = a1 > 1e-4 && a2 > 1e-4 && 1 - a1 - a2 > 1e-4;
            double tol = interior ? 1e-5 : 1e-3;
            if (fabs(pos.z - t) > tol * t)
                fail_msg("sample (%d,%d): depth %.9g, analytic %.9g", sx, sy, pos.z, t);
            if (fabs(pos.x - dir.x * t) > tol * t)
                fail_msg("sample (%d,%d): x %.9g, analytic %.9g", sx, sy, pos.x, dir.x * t);
        }
    /* the quad's screen area, by the shoelace formula on its projected corners
     * (-2/3,-1/3) (5/6,-1/3) (5/24,1/16) (-1/6,1/16), is 0.37109 of the 4 NDC units */
    assert_float_equal(n / (double)(f.sw * f.sh), 0.37109375 / 4, 0.005);
    frame_free(&f);
}

static void test_near_clip(void **state)
{
    (void)state;
    /* vertex 0 behind the camera, the others in front; near plane at depth 0.5 */
    dvec3 p[3] = {dv3(-0.5, -0.25, -2.0), dv3(1.5, -0.25, 3.0), dv3(-0.75, 1.0, 4.0)};
    raster_vertex v[3];
    for (int i = 0; i < 3; i++)
        v[i] = view_vertex(p[i]);
    uint32_t idx[3] = {0, 1, 2};
    const int w = 48, h = 32, k = 2;
    const double near = 0.5;
    raster_options o = {.width = w, .height = h, .supersample = k, .threads = 3, .tile = 8, .near = (float)near};
    frame f;
    frame_init(&f, w, h, k);
    draw(v, 3, idx, 1, o, &f);
    int n_in = 0, n_checked = 0;
    for (int sy = 0; sy < f.sh; sy++)
        for (int sx = 0; sx < f.sw; sx++) {
            const raster_sample *s = frame_at(&f, sx, sy);
            dvec3 dir = sample_dir(sx, sy, f.sw, f.sh);
            double t, a1, a2;
            assert_true(ray_tri(dir, p, &t, &a1, &a2));
            double a0 = 1 - a1 - a2;
            double m = fmin(a0, fmin(a1, a2));
            /* clear-cut cases only: 1e-3 keeps away from the snapped edges (1/1024 px) */
            bool in = m > 1e-3 && t > near * (1 + 1e-3);
            bool out = m < -1e-3 || t < near * (1 - 1e-3);
            if (s->tri >= 0) {
                double b0 = 1.0 - s->b1 - s->b2;
                double depth = b0 * p[0].z + s->b1 * p[1].z + s->b2 * p[2].z;
                /* 1e-3: edge samples admitted by snapping, clamped onto the triangle */
                assert_true(depth > near * (1 - 1e-3));
            }
            if (in) {
                n_in++;
                if (s->tri != 0)
                    fail_msg("sample (%d,%d) should be covered", sx, sy);
                /* weights are float; 1e-5 is far above float rounding yet catches any
                 * screen-space (non-perspective) interpolation */
                assert_float_equal(s->b1, a1, 1e-5);
                assert_float_equal(s->b2, a2, 1e-5);
                n_checked++;
            } else if (out && s->tri != -1) {
                fail_msg("sample (%d,%d) should be empty (t = %g, min b = %g)", sx, sy, t, m);
            }
        }
    assert_true(n_in > 100);
    assert_int_equal(n_checked, n_in);
    frame_free(&f);
}

static void test_depth(void **state)
{
    (void)state;
    const int w = 16, h = 16;
    raster_options o = {.width = w, .height = h, .threads = 2, .tile = 8};
    /* A (depth 2): u >= -0.75, v >= -0.75, u + v <= 0. B (depth 4): v >= -0.5,
     * u <= 0.75, v <= -0.5 + 1.25 (u + 0.25). Clip x = ndc * w keeps the screen shape. */
    double a_ndc[3][2] = {{-0.75, -0.75}, {0.75, -0.75}, {-0.75, 0.75}};
    double b_ndc[3][2] = {{-0.25, -0.5}, {0.75, -0.5}, {0.75, 0.75}};
    raster_vertex v[6];
    for (int i = 0; i < 3; i++) {
        v[i] = (raster_vertex){(float)(a_ndc[i][0] * 2), (float)(a_ndc[i][1] * 2), 2.0f};
        v[3 + i] = (raster_vertex){(float)(b_ndc[i][0] * 4), (float)(b_ndc[i][1] * 4), 4.0f};
    }
    uint32_t ab[6] = {0, 1, 2, 3, 4, 5}, ba[6] = {3, 4, 5, 0, 1, 2};
    /* pixel (8, 9): centre ndc (0.0625, -0.1875) lies inside both triangles */
    frame f;
    frame_init(&f, w, h, 1);
    draw(v, 6, ab, 2, o, &f);
    assert_int_equal(frame_at(&f, 8, 9)->tri, 0);
    frame_free(&f);
    frame_init(&f, w, h, 1);
    draw(v, 6, ba, 2, o, &f);
    assert_int_equal(frame_at(&f, 8, 9)->tri, 1);
    /* inside B only: pixel (12, 7), ndc (0.5625, 0.0625) */
    assert_int_equal(frame_at(&f, 12, 7)->tri, 0);
    frame_free(&f);

    /* exact tie: the same triangle twice, the lower index wins everywhere */
    uint32_t twice[9] = {3, 4, 5, 0, 1, 2, 0, 1, 2};
    frame_init(&f, w, h, 1);
    draw(v, 6, twice, 3, o, &f);
    int n_a = 0;
    for (int i = 0; i < w * h; i++) {
        assert_int_not_equal(f.s[i].tri, 2);
        n_a += f.s[i].tri == 1;
    }
    assert_true(n_a > 20);
    frame_free(&f);
}

/* A contour: a front triangle (w = 1) whose right edge passes d pixels beside the centre of
 * pixel (4, 4) of an 8 x 8 image, over a back triangle (w = 2) that covers the image. The
 * exact geometry says which one the sample sees: the front one for d = +3e-4 (the sample
 * lies 3e-4 pixels inside), the back one for d = -3e-4. A grid of 1/512 pixel snaps both
 * edges onto the sample (4.5 * 512 = 2304 +- 0.15), where the fill rule leaves it out: the
 * sample then sees the surface behind, as WusonOBJ from behind did against POV-Ray. */
static void test_contour_precision(void **state)
{
    (void)state;
    const int w = 8, h = 8;
    raster_options o = {.width = w, .height = h, .threads = 1};
    const double d[2] = {3e-4, -3e-4};
    const int want[2] = {0, 1};
    for (int c = 0; c < 2; c++) {
        double xe = 4.5 + d[c];
        raster_vertex v[6] = {px_vertex(xe, -1.0, w, h),   px_vertex(xe, 9.0, w, h),    px_vertex(-1.0, 4.0, w, h),
                              px_vertex(-2.0, -2.0, w, h), px_vertex(10.0, -2.0, w, h), px_vertex(4.0, 10.0, w, h)};
        for (int i = 3; i < 6; i++) {
            v[i].x *= 2.0f;
            v[i].y *= 2.0f;
            v[i].w = 2.0f;
        }
        uint32_t idx[6] = {0, 1, 2, 3, 4, 5};
        frame f;
        frame_init(&f, w, h, 1);
        draw(v, 6, idx, 2, o, &f);
        if (frame_at(&f, 4, 4)->tri != want[c])
            fail_msg("edge %+g px from the sample: the sample sees triangle %d, want %d", d[c], frame_at(&f, 4, 4)->tri,
                     want[c]);
        /* a sample a whole pixel away on either side is clear-cut whatever the grid */
        assert_int_equal(frame_at(&f, 3, 4)->tri, 0);
        assert_int_equal(frame_at(&f, 5, 4)->tri, 1);
        frame_free(&f);
    }
}

static void test_supersample_positions(void **state)
{
    (void)state;
    /* k = 3: samples at i + 1/6, i + 1/2, i + 5/6. Rectangle with its left side at
     * x = 2 + 1/6 (sample column 6), right at 5.5 (column 16), top at 1 + 5/6 (row 5),
     * bottom at 4 + 1/6 (row 12): in are columns 6..15 and rows 5..11. */
    const int w = 8, h = 8, k = 3;
    raster_options o = {.width = w, .height = h, .supersample = k, .threads = 2, .tile = 4};
    double x0 = 2.0 + 1.0 / 6, x1 = 5.5, y0 = 1.0 + 5.0 / 6, y1 = 4.0 + 1.0 / 6;
    raster_vertex v[4] = {px_vertex(x0, y0, w, h), px_vertex(x1, y0, w, h), px_vertex(x1, y1, w, h),
                          px_vertex(x0, y1, w, h)};
    uint32_t idx[6] = {0, 1, 2, 2, 3, 0};
    frame f;
    frame_init(&f, w, h, k);
    draw(v, 4, idx, 2, o, &f);
    for (int sy = 0; sy < f.sh; sy++)
        for (int sx = 0; sx < f.sw; sx++) {
            bool want = sx >= 6 && sx <= 15 && sy >= 5 && sy <= 11;
            if ((frame_at(&f, sx, sy)->tri >= 0) != want)
                fail_msg("sample (%d,%d)", sx, sy);
        }
    frame_free(&f);

    /* the left side moved right by 1e-3 px leaves column 6 out */
    v[0] = px_vertex(x0 + 1e-3, y0, w, h);
    v[3] = px_vertex(x0 + 1e-3, y1, w, h);
    frame_init(&f, w, h, k);
    draw(v, 4, idx, 2, o, &f);
    assert_int_equal(frame_at(&f, 6, 8)->tri, -1);
    assert_true(frame_at(&f, 7, 8)->tri >= 0);
    frame_free(&f);
}

static uint32_t lcg(uint32_t *s)
{
    *s = *s * 1664525u + 1013904223u;
    return *s >> 8;
}

static double lcg_unit(uint32_t *s) { return (double)lcg(s) / (double)(1u << 24); }

static void test_thread_tile_invariance(void **state)
{
    (void)state;
    enum { NT = 400 };
    raster_vertex v[3 * NT];
    uint32_t idx[3 * NT];
    uint32_t seed = 12345;
    for (int t = 0; t < NT; t++) {
        /* mostly small triangles, some large, some crossing the near plane */
        double cx = lcg_unit(&seed) * 2.4 - 1.2, cy = lcg_unit(&seed) * 2.4 - 1.2;
        double size = (t % 17 == 0) ? 1.5 : 0.15;
        for (int i = 0; i < 3; i++) {
            double w = 0.5 + 3 * lcg_unit(&seed);
            if (t % 23 == 0 && i == 0)
                w = -1.0;
            double x = cx + size * (lcg_unit(&seed) - 0.5), y = cy + size * (lcg_unit(&seed) - 0.5);
            v[3 * t + i] = (raster_vertex){(float)(x * w), (float)(y * w), (float)w};
            idx[3 * t + i] = (uint32_t)(3 * t + i);
        }
    }
    const int w = 53, h = 37, k = 3;
    frame ref;
    frame_init(&ref, w, h, k);
    raster_options o = {.width = w, .height = h, .supersample = k, .threads = 1, .tile = 16};
    draw(v, 3 * NT, idx, NT, o, &ref);
    int n_cov = 0;
    for (int i = 0; i < ref.sw * ref.sh; i++)
        n_cov += ref.s[i].tri >= 0;
    assert_true(n_cov > ref.sw * ref.sh / 2);
    static const int threads[3] = {1, 2, 3}, tiles[3] = {8, 16, 32};
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++) {
            frame f;
            frame_init(&f, w, h, k);
            o.threads = threads[a];
            o.tile = tiles[b];
            draw(v, 3 * NT, idx, NT, o, &f);
            for (int i = 0; i < w * h; i++)
                assert_true(f.thread[i] >= 0 && f.thread[i] < raster_thread_count(&o));
            assert_memory_equal(f.s, ref.s, (size_t)f.sw * f.sh * sizeof(raster_sample));
            frame_free(&f);
        }
    /* The planes alone (no structures: frame_tile checks samples is NULL) are the same frame:
     * every sample's triangle, and the weights of every covered one (an empty sample's weights
     * are not cleared then, raster.h). The frame above is covered whole, so this one draws the
     * first NP triangles only, leaving empty samples in tiles drawn after others on their
     * worker, where an earlier tile's weights stay. */
    enum { NP = 40 };
    frame pref;
    frame_init(&pref, w, h, k);
    o.threads = 1;
    o.tile = 8;
    draw(v, 3 * NP, idx, NP, o, &pref);
    int n_empty = 0;
    for (int i = 0; i < pref.sw * pref.sh; i++)
        n_empty += pref.s[i].tri < 0;
    assert_true(n_empty > pref.sw * pref.sh / 10 && n_empty < pref.sw * pref.sh * 9 / 10);
    static const int p_threads[2] = {1, 2};
    for (int a = 0; a < 2; a++) {
        frame p;
        frame_init(&p, w, h, k);
        o.threads = p_threads[a];
        o.planes_only = 1;
        p.planes_only = 1;
        draw(v, 3 * NP, idx, NP, o, &p);
        for (int i = 0; i < p.sw * p.sh; i++) {
            assert_int_equal(p.s[i].tri, pref.s[i].tri);
            if (pref.s[i].tri >= 0) {
                assert_memory_equal(&p.s[i].b1, &pref.s[i].b1, sizeof p.s[i].b1);
                assert_memory_equal(&p.s[i].b2, &pref.s[i].b2, sizeof p.s[i].b2);
            }
        }
        frame_free(&p);
    }
    frame_free(&pref);
    frame_free(&ref);
}

static void test_bad_options(void **state)
{
    (void)state;
    raster_vertex v[3] = {{0, 0, 1}, {1, 0, 1}, {0, 1, 1}};
    uint32_t idx[3] = {0, 1, 2}, bad_idx[3] = {0, 1, 3};
    frame f;
    frame_init(&f, 4, 4, 1);
    raster_options ok = {.width = 4, .height = 4};
    raster_options o;
#define EXPECT_RANGE(field, value)                                                                                     \
    do {                                                                                                               \
        o = ok;                                                                                                        \
        o.field = value;                                                                                               \
        assert_int_equal(raster_draw(v, 3, idx, 1, &o, frame_tile, &f), RC_ERR_RANGE);                                 \
    } while (0)
    EXPECT_RANGE(width, 0);
    EXPECT_RANGE(width, -3);
    EXPECT_RANGE(height, 0);
    EXPECT_RANGE(supersample, 17);
    EXPECT_RANGE(supersample, -1);
    EXPECT_RANGE(threads, -1);
    EXPECT_RANGE(tile, -2);
    EXPECT_RANGE(near, -1.0f);
    EXPECT_RANGE(near, NAN);
    EXPECT_RANGE(width, 1 << 30);
#undef EXPECT_RANGE
    assert_int_equal(raster_draw(v, 3, bad_idx, 1, &ok, frame_tile, &f), RC_ERR_RANGE);
    assert_int_equal(raster_draw(v, 3, idx, -1, &ok, frame_tile, &f), RC_ERR_RANGE);
    assert_int_equal(raster_draw(v, 3, idx, 1, &ok, NULL, &f), RC_ERR_RANGE);
    assert_int_equal(raster_draw(v, 3, idx, 1, NULL, frame_tile, &f), RC_ERR_RANGE);
    /* the good options still work, and an empty draw hands over every tile */
    assert_int_equal(raster_draw(v, 3, idx, 1, &ok, frame_tile, &f), RC_OK);
    assert_int_equal(raster_draw(v, 3, idx, 0, &ok, frame_tile, &f), RC_OK);
    for (int i = 0; i < 16; i++)
        assert_int_equal(f.tile_hits[i], 2);
    frame_free(&f);

    raster_options t3 = {.width = 4, .height = 4, .threads = 3};
    assert_int_equal(raster_thread_count(&t3), 3);
    raster_options t0 = {.width = 4, .height = 4};
    assert_true(raster_thread_count(&t0) >= 1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_shared_edge_quad),
        cmocka_unit_test(test_fan),
        cmocka_unit_test(test_top_left),
        cmocka_unit_test(test_asymmetric_pixels),
        cmocka_unit_test(test_perspective),
        cmocka_unit_test(test_near_clip),
        cmocka_unit_test(test_depth),
        cmocka_unit_test(test_contour_precision),
        cmocka_unit_test(test_supersample_positions),
        cmocka_unit_test(test_thread_tile_invariance),
        cmocka_unit_test(test_bad_options),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
