/* test_cycles.c - the Cycles translation against independent closed forms, with the real
 * blender (docs/conventions.md settings). Each render is tiny (<= 64 x 48, 2 seeds x 32 spp).
 * Expected values are computed here in double from first principles: our own camera ray
 * through sub-pixel positions (box average over the pixel), ray-plane intersection, Lambert,
 * Beckmann D and Smith-Walter G written out again, not taken from the model library.
 * Tolerance per pixel: 4 sigma of the Cycles noise (variance of the mean from two seeds,
 * pooled over the pixels compared) plus 2e-4 relative (float32 accumulation, custom-normal
 * quantisation ~2.4e-4 rad, compositor float maths).
 */
#define _XOPEN_SOURCE 700

#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <ftw.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmocka.h>

#include <cJSON.h>

#include "check.h"

#include "renderers/cycles/cycles.h"
#include "renderers/registry.h"
#include "exr.h"
#include "mesh.h"
#include "raster.h"
#include "render.h"
#include "runner.h"
#include "scene.h"

#define PI 3.14159265358979323846

static char g_dir[256];
static const char *g_script;

static int group_setup(void **state)
{
    (void)state;
    snprintf(g_dir, sizeof g_dir, "/tmp/test_cycles_XXXXXX");
    if (mkdtemp(g_dir) == NULL)
        return -1;
    static const char *candidates[] = {"harness/renderers/cycles/cycles_render.py",
                                       "../harness/renderers/cycles/cycles_render.py"};
    for (size_t i = 0; i < sizeof candidates / sizeof candidates[0]; i++)
        if (access(candidates[i], R_OK) == 0)
            g_script = candidates[i];
    if (g_script == NULL) {
        fprintf(stderr,
                "test_cycles: harness/renderers/cycles/cycles_render.py not found; run from the repository root\n");
        return -1;
    }
    return 0;
}

static int remove_entry(const char *path, const struct stat *sb, int flag, struct FTW *ftw)
{
    (void)sb;
    (void)flag;
    (void)ftw;
    return remove(path);
}

/* Keeps the renders and logs for inspection when REFLCHECK_KEEP_TMP is set. */
static int group_teardown(void **state)
{
    (void)state;
    if (getenv("REFLCHECK_KEEP_TMP") != NULL) {
        printf("# test_cycles: renders kept in %s\n", g_dir);
        return 0;
    }
    return nftw(g_dir, remove_entry, 16, FTW_DEPTH | FTW_PHYS) == 0 ? 0 : -1;
}

/* ------------------------------------------------------------------ fixtures */

typedef struct {
    vec3 pos[16], nrm[16];
    uint32_t idx[48];
    int tri_object[16];
} fixture_mesh;

/* A planar quad p0 + s*e1 + t*e2 (s, t in [0, 1]) with normal n, as two triangles of object o,
 * wound counter-clockwise seen from n. */
static void add_quad(mesh *m, fixture_mesh *f, vec3 p0, vec3 e1, vec3 e2, int o)
{
    vec3 n = v3_norm(v3_cross(e1, e2));
    int b = m->n_verts;
    vec3 p[4] = {p0, v3_add(p0, e1), v3_add(v3_add(p0, e1), e2), v3_add(p0, e2)};
    for (int i = 0; i < 4; i++) {
        f->pos[b + i] = p[i];
        f->nrm[b + i] = n;
    }
    uint32_t t[6] = {0, 1, 2, 0, 2, 3};
    for (int i = 0; i < 6; i++)
        f->idx[3 * m->n_tris + i] = (uint32_t)b + t[i];
    f->tri_object[m->n_tris] = o;
    f->tri_object[m->n_tris + 1] = o;
    m->n_verts += 4;
    m->n_tris += 2;
    m->pos = f->pos;
    m->nrm = f->nrm;
    m->idx = f->idx;
    m->tri_object = f->tri_object;
}

static void base_scene(scene *s, int w, int h)
{
    scene_init(s);
    snprintf(s->path, sizeof s->path, "test_cycles fixture");
    s->width = w;
    s->height = h;
    s->samples = 32;
    s->n_objects = 1;
    s->objects[0].material = 0;
    s->n_materials = 1;
}

/* The floor quad y = 0, x in [-1.5, 1.3], z in [-1.2, 1.4] (asymmetric), normal +Y. */
static void floor_mesh(mesh *m, fixture_mesh *f)
{
    memset(m, 0, sizeof *m);
    add_quad(m, f, v3(-1.5f, 0.0f, 1.4f), v3(2.8f, 0.0f, 0.0f), v3(0.0f, 0.0f, -2.6f), 0);
}

/* The same floor through the project's mesh_build (SHAPE_QUAD: XZ plane, normal +Y). */
static void floor_scene_mesh(scene *s, mesh *m)
{
    char err[256];
    s->objects[0].shape = SHAPE_QUAD;
    s->objects[0].center = v3(-0.1f, 0.0f, 0.1f);
    s->objects[0].size = v3(2.8f, 1.0f, 2.6f);
    memset(m, 0, sizeof *m);
    if (mesh_build(s, m, err, sizeof err) != RC_OK)
        fail_msg("mesh_build: %s", err);
    assert_int_equal(m->n_tris, 2);
}

/* ------------------------------------------------------------------ rendering */

typedef struct {
    exr_image img;
    int w, h;
    const float *ch[32];
} result;

static double now_wall;

/* Renders through the renderer table's entry, the one production (harness/jobs.c) runs:
 * job, blender, collect. Returns the entry's result; out names the image. */
static renderer_result render_entry(const scene *s, const mesh *m, const cycles_options *o, const char *tag, char *out,
                                    size_t outlen)
{
    char dir[512], log[512];
    snprintf(dir, sizeof dir, "%s/%s-work", g_dir, tag);
    mkdir(dir, 0755);
    snprintf(out, outlen, "%s/%s.exr", g_dir, tag);
    snprintf(log, sizeof log, "%s/%s.log", g_dir, tag);
    renderer_job j = {
        .s = s, .m = m, .role = o->role, .dir = dir, .exr = out, .log = log, .timeout = 3600.0, .options = o};
    renderer_result res = {0};
    registry_row(registry_find("cycles"))->render(&j, &res);
    return res;
}

static void render_ok(const scene *s, const mesh *m, const cycles_options *o, const char *tag, result *r)
{
    char out[512], err[512];
    renderer_result res = render_entry(s, m, o, tag, out, sizeof out);
    if (res.status != RUNNER_OK)
        fail_msg("cycles entry: %s", res.message);
    now_wall = res.wall_s;
    if (exr_read(out, &r->img, err, sizeof err) != RC_OK)
        fail_msg("exr_read: %s", err);
    r->w = r->img.width;
    r->h = r->img.height;
}

static void render(const scene *s, const mesh *m, const char *tag, result *r)
{
    cycles_options o = {.role = ROLE_TWIN, .n_seeds = 2, .seed = 11, .threads = 2, .script = g_script};
    render_ok(s, m, &o, tag, r);
    r->w = r->img.width;
    r->h = r->img.height;
    printf("# %s: blender wall %.2f s (scene build %s s, render %s s for 2 seeds x %d spp, %dx%d)\n", tag, now_wall,
           exr_image_attr(&r->img, "reflcheck.cycles_build_s"), exr_image_attr(&r->img, "reflcheck.cycles_render_s"),
           s->samples, r->w, r->h);
}

static const float *chan(const result *r, const char *name)
{
    const float *p = exr_image_channel(&r->img, name);
    if (p == NULL)
        fail_msg("channel %s missing from the Cycles EXR", name);
    return p;
}

/* Independent pinhole camera (double): the ray through screen point (sx, sy) in pixels. */
typedef struct {
    dvec3 eye, f, r, u;
    double tx, ty;
    int w, h;
} cam;

static void cam_make(const scene *s, int w, int h, cam *c)
{
    c->eye = dv3_from(s->camera.eye);
    c->f = dv3_norm(dv3_sub(dv3_from(s->camera.target), c->eye));
    c->r = dv3_norm(dv3_cross(c->f, dv3_from(s->camera.up)));
    c->u = dv3_cross(c->r, c->f);
    c->tx = tan(0.5 * s->camera.hfov);
    c->ty = c->tx * h / w;
    c->w = w;
    c->h = h;
}

static dvec3 cam_ray(const cam *c, double sx, double sy)
{
    double nx = 2.0 * sx / c->w - 1.0, ny = 1.0 - 2.0 * sy / c->h;
    dvec3 d = dv3_add(c->f, dv3_add(dv3_scale(c->r, nx * c->tx), dv3_scale(c->u, ny * c->ty)));
    return dv3_norm(d);
}

/* Radiance leaving floor point x (y = 0, normal +Y) toward the eye; 0 for a miss. */
typedef double (*radiance_fn)(const void *ctx, dvec3 x, dvec3 v);

/* Box average over pixel (i, j) with an 8 x 8 grid; *covered = 1 if every sub-sample hits the floor. */
static double expected_pixel(const cam *c, int i, int j, radiance_fn fn, const void *ctx, int *covered)
{
    const int k = 8;
    double sum = 0.0;
    *covered = 1;
    for (int t = 0; t < k; t++)
        for (int s = 0; s < k; s++) {
            dvec3 d = cam_ray(c, i + (s + 0.5) / k, j + (t + 0.5) / k);
            if (d.y >= 0.0) {
                *covered = 0;
                continue;
            }
            double tt = -c->eye.y / d.y;
            dvec3 x = dv3_add(c->eye, dv3_scale(d, tt));
            if (x.x < -1.5 || x.x > 1.3 || x.z < -1.2 || x.z > 1.4) {
                *covered = 0;
                continue;
            }
            sum += fn(ctx, x, dv3_scale(d, -1.0));
        }
    return sum / (k * k);
}

typedef struct {
    double n, sum_abs_z, max_z, sum_rel, max_rel;
} agreement;

static void agree_add(agreement *a, double obs, double exp, double sigma)
{
    double z = sigma > 0.0 ? fabs(obs - exp) / sigma : (obs == exp ? 0.0 : INFINITY);
    double rel = fabs(obs - exp) / fmax(fabs(exp), 1e-12);
    a->n++;
    a->sum_abs_z += z;
    a->max_z = fmax(a->max_z, z);
    a->sum_rel += rel;
    a->max_rel = fmax(a->max_rel, rel);
}

static void agree_print(const char *what, const agreement *a)
{
    printf("# %s: %d pixels, mean |z| %.2f, max |z| %.2f, mean rel %.2e, max rel %.2e\n", what, (int)a->n,
           a->sum_abs_z / a->n, a->max_z, a->sum_rel / a->n, a->max_rel);
}

/* Compares one channel (scale * fn) over every fully covered pixel; returns the pixel count. */
static int compare_floor_channel(const result *r, const cam *c, const char *name, float scale, radiance_fn fn,
                                 const void *ctx, const char *what, double min_value)
{
    agreement a = {0};
    int n_checked = 0;
    char vname[80];
    snprintf(vname, sizeof vname, "var.%s", name);
    const float *v = chan(r, name), *var = chan(r, vname), *cov = chan(r, "coverage");
    /* Two seeds give one degree of freedom per pixel: pool the relative variance (noise scales
     * with the signal) over the covered pixels of a 5 x 5 neighbourhood, where the noise level
     * is nearly the same; never go below the pixel's own estimate. */
    for (int j = 0; j < r->h; j++)
        for (int i = 0; i < r->w; i++) {
            int covered;
            int p = j * r->w + i;
            /* Edge pixels: our 8 x 8 grid can miss a sliver that Cycles' samples hit. */
            if (cov[p] < 1.0f)
                continue;
            double e = scale * expected_pixel(c, i, j, fn, ctx, &covered);
            if (!covered || isnan(e) || e < min_value)
                continue;
            double pool = 0.0;
            int np = 0;
            for (int b = j - 2; b <= j + 2; b++)
                for (int ii = i - 2; ii <= i + 2; ii++) {
                    if (ii < 0 || b < 0 || ii >= r->w || b >= r->h)
                        continue;
                    int q = b * r->w + ii;
                    if (cov[q] >= 1.0f && fabsf(v[q]) > 0.0f) {
                        pool += var[q] / ((double)v[q] * v[q]);
                        np++;
                    }
                }
            pool = np ? pool / np : 0.0;
            double sigma = sqrt(fmax(var[p], pool * e * e));
            double tol = 4.0 * sigma + 2e-4 * fabs(e);
            agree_add(&a, v[p], e, sqrt(sigma * sigma + (1e-4 * e) * (1e-4 * e)));
            if (fabs(v[p] - e) > tol)
                fail_msg("%s: pixel (%d, %d) %s = %.6g, expected %.6g (sigma %.3g)", what, i, j, name, v[p], e, sigma);
            n_checked++;
        }
    agree_print(what, &a);
    return n_checked;
}

static int compare_floor(const result *r, const cam *c, const char *layer, const float rgb_scale[3], radiance_fn fn,
                         const void *ctx, const char *what, double min_value)
{
    static const char comp[3] = {'R', 'G', 'B'};
    int n = 0;
    for (int ch = 0; ch < 3; ch++) {
        char name[64], w[96];
        snprintf(name, sizeof name, "%s.%c", layer, comp[ch]);
        snprintf(w, sizeof w, "%s %c", what, comp[ch]);
        n += compare_floor_channel(r, c, name, rgb_scale[ch], fn, ctx, w, min_value);
    }
    return n;
}

/* ------------------------------------------------------------------ 1: sun on a Lambert quad */

typedef struct {
    dvec3 to_light;
    double e;
    double albedo;
} sun_ctx;

static double sun_lambert(const void *ctx, dvec3 x, dvec3 v)
{
    (void)x;
    (void)v;
    const sun_ctx *s = ctx;
    return s->albedo * s->e / PI * fmax(s->to_light.y, 0.0);
}

/* ------------------------------------------------------------------ point samples of a twin */

typedef struct {
    int w, k;
    float *cov;
} cov_ctx;

static void cov_tile(void *user, const raster_tile *t)
{
    cov_ctx *c = user;
    for (int py = 0; py < t->h; py++)
        for (int px = 0; px < t->w; px++) {
            int n = 0;
            for (int sy = 0; sy < t->k; sy++)
                for (int sx = 0; sx < t->k; sx++)
                    n += t->samples[(size_t)(py * t->k + sy) * (size_t)(t->w * t->k) + (size_t)(px * t->k + sx)].tri >=
                         0;
            c->cov[(t->y0 + py) * c->w + t->x0 + px] = (float)n / (float)(t->k * t->k);
        }
}

/* A twin with k = 2 samples the model's 2 x 2 positions: Cycles' coverage is then a multiple of
 * 1/4 in every pixel and equals the rasterizer's, sample for sample, along the floor's slanted
 * edges. Control: the pixel integral (supersample 1, a box filter over the pixel) gives edge
 * pixels between those steps. Blender ignores a box filter's width, so a narrow box would not
 * do: the control with a 0.01 box fails the same way (measured; cycles_render.py uses a
 * Gaussian). */
static void test_point_samples(void **state)
{
    (void)state;
    scene s;
    mesh m;
    base_scene(&s, 24, 16);
    floor_scene_mesh(&s, &m);
    s.supersample = 2;
    s.samples = 8;
    s.camera.eye = v3(0.9f, 2.2f, 3.1f);
    s.camera.target = v3(-0.2f, 0.0f, 0.1f);
    s.camera.hfov = (float)(62.0 * PI / 180.0);
    s.materials[0].d3d.diffuse = v3(0.5f, 0.5f, 0.5f);
    s.n_lights = 1;
    s.lights[0].kind = LIGHT_SUN;
    s.lights[0].direction = v3_norm(v3(0.35f, -1.0f, 0.2f));
    s.lights[0].intensity = v3s(3.0f);
    render_camera rc;
    render_camera_make(&s, s.width, s.height, &rc);
    raster_vertex rv[4];
    for (int i = 0; i < m.n_verts; i++)
        rv[i] = render_camera_clip(&rc, m.pos[i]);
    float want[24 * 16];
    cov_ctx cc = {s.width, 2, want};
    raster_options ro = {.width = s.width, .height = s.height, .supersample = 2, .threads = 1};
    assert_int_equal(raster_draw(rv, m.n_verts, m.idx, m.n_tris, &ro, cov_tile, &cc), RC_OK);
    for (int pass = 0; pass < 2; pass++) {
        cycles_options o = {
            .role = ROLE_TWIN, .n_seeds = 2, .seed = 5, .threads = 2, .script = g_script, .supersample = pass};
        result r;
        render_ok(&s, &m, &o, pass == 0 ? "points" : "integral", &r);
        assert_int_equal(r.w, s.width);
        const float *cov = chan(&r, "coverage");
        int partial = 0, off_grid = 0, differ = 0;
        for (int p = 0; p < r.w * r.h; p++) {
            partial += want[p] > 0.0f && want[p] < 1.0f;
            /* 1e-4: float sums of four 0/1 sub-pixel means over two seeds are exact to ~1e-7 */
            off_grid += fabsf(4.0f * cov[p] - roundf(4.0f * cov[p])) > 1e-4f;
            differ += fabsf(cov[p] - want[p]) > 1e-4f;
        }
        printf("# %s: %d edge pixels (rasterizer), %d off the 1/4 steps, %d differ from the rasterizer\n",
               pass == 0 ? "k x k points" : "pixel integral", partial, off_grid, differ);
        assert_true(partial >= 10);
        if (pass == 0) {
            assert_int_equal(off_grid, 0);
            assert_int_equal(differ, 0);
        } else
            assert_true(off_grid >= partial / 2);
        exr_image_free(&r.img);
    }
    mesh_free(&m);
}

static void test_sun_lambert(void **state)
{
    (void)state;
    scene s;
    mesh m;
    base_scene(&s, 48, 40);
    floor_scene_mesh(&s, &m);
    s.camera.eye = v3(0.4f, 2.6f, 2.2f);
    s.camera.target = v3(-0.1f, 0.0f, 0.1f);
    s.camera.hfov = (float)(70.0 * PI / 180.0);
    s.materials[0].d3d.diffuse = v3(0.5f, 0.5f, 0.5f);
    s.n_lights = 1;
    s.lights[0].kind = LIGHT_SUN;
    s.lights[0].direction = v3_norm(v3(0.35f, -1.0f, 0.2f));
    s.lights[0].intensity = v3s(3.0f);
    result r;
    render(&s, &m, "sun", &r);
    cam c;
    cam_make(&s, r.w, r.h, &c);
    dvec3 dir = dv3_norm(dv3(0.35, -1.0, 0.2));
    sun_ctx sc = {dv3_scale(dir, -1.0), 3.0, 0.5};
    const float one[3] = {1, 1, 1};
    int n = compare_floor(&r, &c, "diffuse", one, sun_lambert, &sc, "sun Lambert diffuse", 0.0);
    assert_true(n > 3 * 200);
    /* Mean over the floor: a sun on a flat Lambert quad is nearly noise-free. */
    const float *d = chan(&r, "diffuse.G"), *cov = chan(&r, "coverage"), *R = chan(&r, "R");
    const float *spec = chan(&r, "specular.G"), *refl = chan(&r, "reflection.G");
    double sum = 0.0;
    int np = 0;
    for (int p = 0; p < r.w * r.h; p++)
        if (cov[p] >= 1.0f) {
            sum += d[p];
            np++;
            /* R = diffuse where fully covered (no other term, no environment). */
            assert_float_equal(R[p], chan(&r, "diffuse.R")[p], 1e-5 * R[p] + 1e-7);
            assert_float_equal(spec[p], 0.0, 1e-7);
            assert_float_equal(refl[p], 0.0, 1e-7);
        }
    double want = 0.5 * 3.0 / PI * sc.to_light.y;
    printf("# sun Lambert: mean %.7f over %d pixels, expected %.7f, rel %.2e\n", sum / np, np, want,
           fabs(sum / np - want) / want);
    assert_true(fabs(sum / np - want) < 2e-4 * want);
    exr_image_free(&r.img);
    mesh_free(&m);
}

/* ------------------------------------------------------------------ 2: point light, Lambert */

typedef struct {
    dvec3 p;
    double i, albedo;
} point_ctx;

static double point_lambert(const void *ctx, dvec3 x, dvec3 v)
{
    (void)v;
    const point_ctx *pc = ctx;
    dvec3 d = dv3_sub(pc->p, x);
    double d2 = dv3_dot(d, d);
    double cos_l = d.y / sqrt(d2);
    return pc->albedo * pc->i / PI * fmax(cos_l, 0.0) / d2;
}

static void test_point_lambert(void **state)
{
    (void)state;
    scene s;
    mesh m;
    base_scene(&s, 40, 32);
    floor_scene_mesh(&s, &m);
    s.camera.eye = v3(-0.3f, 2.4f, 2.4f);
    s.camera.target = v3(0.1f, 0.0f, 0.0f);
    s.camera.hfov = (float)(65.0 * PI / 180.0);
    s.materials[0].d3d.diffuse = v3(0.7f, 0.5f, 0.3f);
    s.n_lights = 1;
    s.lights[0].kind = LIGHT_POINT;
    s.lights[0].position = v3(0.3f, 1.1f, -0.25f);
    /* RGB ratios differ from the albedo's so that a channel swap shows. */
    s.lights[0].intensity = v3(2.0f, 1.0f, 3.0f);
    result r;
    render(&s, &m, "point", &r);
    cam c;
    cam_make(&s, r.w, r.h, &c);
    point_ctx pc = {dv3(0.3, 1.1, -0.25), 1.0, 1.0};
    const float scale[3] = {0.7f * 2.0f, 0.5f * 1.0f, 0.3f * 3.0f};
    int n = compare_floor(&r, &c, "diffuse", scale, point_lambert, &pc, "point Lambert diffuse", 0.0);
    assert_true(n > 3 * 150);
    exr_image_free(&r.img);
    mesh_free(&m);
}

/* ------------------------------------------------------------------ 3: Beckmann twin */

typedef struct {
    dvec3 p;
    double i, m;
} beck_ctx;

/* Walter et al. 2007 rational approximation of the Beckmann Smith G1 (the form Cycles uses). */
static double g1_walter(double cos_t, double m)
{
    double tan_t = sqrt(fmax(1.0 - cos_t * cos_t, 0.0)) / cos_t;
    if (tan_t == 0.0)
        return 1.0;
    double a = 1.0 / (m * tan_t);
    return a < 1.6 ? (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a) : 1.0;
}

static double beckmann_spec(const void *ctx, dvec3 x, dvec3 v)
{
    const beck_ctx *b = ctx;
    dvec3 dl = dv3_sub(b->p, x);
    double d2 = dv3_dot(dl, dl);
    dvec3 l = dv3_scale(dl, 1.0 / sqrt(d2));
    double nl = l.y, nv = v.y;
    if (nl <= 0.0 || nv <= 0.0)
        return 0.0;
    dvec3 h = dv3_norm(dv3_add(l, v));
    double c = h.y, c2 = c * c, m2 = b->m * b->m;
    double tan2 = (1.0 - c2) / c2;
    double dd = exp(-tan2 / m2) / (PI * m2 * c2 * c2);
    double g = g1_walter(nl, b->m) * g1_walter(nv, b->m);
    /* F = 1; f = D G / (4 NL NV); radiance = f * (I / d^2) * NL. */
    return dd * g / (4.0 * nl * nv) * b->i / d2 * nl;
}

static void test_beckmann_twin(void **state)
{
    (void)state;
    scene s;
    mesh m;
    fixture_mesh f;
    base_scene(&s, 48, 36);
    floor_mesh(&m, &f);
    s.camera.eye = v3(0.0f, 1.6f, 2.6f);
    s.camera.target = v3(0.0f, 0.0f, -0.2f);
    s.camera.hfov = (float)(60.0 * PI / 180.0);
    material *mt = &s.materials[0];
    mt->model = MODEL_COOK_TORRANCE;
    mt->albedo = v3s(0.0f);
    mt->ct.m = 0.3f;
    mt->ct.ks = v3(0.9f, 0.6f, 0.3f);
    mt->ct.g = G_SMITH_WALTER;
    mt->ct.f = F_ONE;
    mt->ct.norm = CT_WALTER;
    s.n_lights = 1;
    s.lights[0].kind = LIGHT_POINT;
    s.lights[0].position = v3(0.2f, 1.3f, -1.0f);
    s.lights[0].intensity = v3s(1.5f);
    result r;
    render(&s, &m, "beckmann", &r);
    cam c;
    cam_make(&s, r.w, r.h, &c);
    beck_ctx bc = {dv3(0.2, 1.3, -1.0), 1.5, 0.3};
    const float ks[3] = {0.9f, 0.6f, 0.3f};
    /* Compared where the lobe is at least 2 % of its peak order of magnitude, not in its far tail. */
    int n = compare_floor(&r, &c, "specular", ks, beckmann_spec, &bc, "Beckmann twin specular", 1e-3);
    assert_true(n > 3 * 100);
    /* The lobe must actually be there: a peak well above the tail threshold. */
    const float *sp = chan(&r, "specular.R");
    float peak = 0.0f;
    for (int p = 0; p < r.w * r.h; p++)
        peak = fmaxf(peak, sp[p]);
    printf("# Beckmann twin: peak specular.R %.4f\n", peak);
    assert_true(peak > 0.1f);
    exr_image_free(&r.img);
}

/* ------------------------------------------------------------------ 4: camera and frame */

static void test_camera_frame(void **state)
{
    (void)state;
    scene s;
    mesh m;
    fixture_mesh f;
    base_scene(&s, 64, 40);
    memset(&m, 0, sizeof m);
    /* A 0.4 x 0.2 rectangle right of and above the view axis, parallel to the image plane,
     * so its coverage centroid is exactly the projection of its centre (0.7, 0.4, 0). */
    add_quad(&m, &f, v3(0.5f, 0.3f, 0.0f), v3(0.4f, 0.0f, 0.0f), v3(0.0f, 0.2f, 0.0f), 0);
    s.camera.eye = v3(0.0f, 0.0f, 5.0f);
    s.camera.target = v3(0.0f, 0.0f, 0.0f);
    s.camera.hfov = (float)(40.0 * PI / 180.0);
    s.materials[0].d3d.diffuse = v3s(0.0f);
    s.materials[0].d3d.emissive = v3(1.0f, 0.5f, 0.25f);
    s.n_lights = 0;
    result r;
    render(&s, &m, "frame", &r);
    const float *cov = chan(&r, "coverage"), *obj = chan(&r, "object"), *em = chan(&r, "emission.G");
    double sx = 0.0, sy = 0.0, sa = 0.0;
    for (int j = 0; j < r.h; j++)
        for (int i = 0; i < r.w; i++) {
            double a = cov[j * r.w + i];
            sx += a * (i + 0.5);
            sy += a * (j + 0.5);
            sa += a;
        }
    /* Prediction: x_ndc = X / (Z tan(hfov/2)), y_ndc = Y / (Z tan(hfov/2) H/W). */
    double t = tan(20.0 * PI / 180.0), z = 5.0;
    double px = (0.7 / (z * t) + 1.0) / 2.0 * r.w;
    double py = (1.0 - 0.4 / (z * t * r.h / r.w)) / 2.0 * r.h;
    double area = (0.4 / (z * t) * r.w / 2.0) * (0.2 / (z * t * r.h / r.w) * r.h / 2.0);
    printf("# frame: centroid (%.3f, %.3f) predicted (%.3f, %.3f); area %.2f px^2 predicted %.2f\n", sx / sa, sy / sa,
           px, py, sa, area);
    assert_true(px > r.w / 2.0 && py < r.h / 2.0); /* the fixture itself is right and up */
    assert_float_equal(sx / sa, px, 0.15);
    assert_float_equal(sy / sa, py, 0.15);
    assert_float_equal(sa, area, 0.03 * area);
    int ci = (int)px, cj = (int)py;
    assert_float_equal(obj[cj * r.w + ci], 0.0, 0.0);
    assert_float_equal(obj[0], -1.0, 0.0);
    assert_float_equal(obj[(r.h - 1) * r.w + r.w - 1], -1.0, 0.0);
    /* Emission G = 0.5 * coverage inside; the mirror image position (left/down) is empty. */
    assert_float_equal(em[cj * r.w + ci], 0.5, 1e-5);
    assert_float_equal(cov[cj * r.w + (r.w - 1 - ci)], 0.0, 0.0);
    assert_float_equal(cov[(r.h - 1 - cj) * r.w + ci], 0.0, 0.0);
    exr_image_free(&r.img);
}

/* ------------------------------------------------------------------ 5: constant background */

static void test_background_constant(void **state)
{
    (void)state;
    scene s;
    mesh m;
    fixture_mesh f;
    base_scene(&s, 32, 24);
    memset(&m, 0, sizeof m);
    add_quad(&m, &f, v3(-0.3f, -0.2f, 0.0f), v3(0.5f, 0.0f, 0.0f), v3(0.0f, 0.3f, 0.0f), 0);
    s.env.kind = ENV_CONSTANT;
    s.env.radiance = v3(0.2f, 0.35f, 0.5f);
    s.materials[0].d3d.diffuse = v3s(0.6f);
    s.n_lights = 0;
    result r;
    render(&s, &m, "background", &r);
    const float *ch[3] = {chan(&r, "R"), chan(&r, "G"), chan(&r, "B")};
    const float *bg = chan(&r, "background.B"), *cov = chan(&r, "coverage"), *dif = chan(&r, "diffuse.G");
    const float want[3] = {0.2f, 0.35f, 0.5f};
    int empty = 0;
    for (int p = 0; p < r.w * r.h; p++) {
        /* The twin keeps the environment out of diffuse lighting: the quad stays black. */
        assert_float_equal(dif[p], 0.0, 1e-7);
        if (cov[p] > 0.0f)
            continue;
        empty++;
        for (int c = 0; c < 3; c++)
            assert_float_equal(ch[c][p], want[c], 1e-6);
        assert_float_equal(bg[p], 0.5, 1e-6);
    }
    assert_true(empty > r.w * r.h / 2);
    printf("# background: %d empty pixels equal L to 1e-6\n", empty);
    exr_image_free(&r.img);
}

/* ------------------------------------------------------------------ blend (twin) */

/* D3D9Client eq. (7)'s blend (d3d9client.blend) as the twin renders it: a Mix of a Transparent
 * BSDF and the surface, factor a = max(d_a, |R_tot|). A pane at z = 0.5 over an emissive quad at
 * z = 0, both filling the frame, in a constant environment L = (0.5, 1, 2); the pane has
 * p = 0, m = 0 (R = R0 = 0.2 at every angle), no diffuse, d_a = 0.1, so c = R0 L = (0.1, 0.2, 0.4),
 * a = 0.4 and every pixel is 0.4 c + 0.6 E, E = (0.2, 0.4, 0.6): (0.16, 0.32, 0.52), by hand as in
 * tests/test_blend.c. The image mean is compared, within 4 standard errors of the pixels' spread
 * plus 2e-4 relative. */
static void test_blend_twin(void **state)
{
    (void)state;
    scene s;
    mesh m;
    fixture_mesh f;
    base_scene(&s, 32, 24);
    memset(&m, 0, sizeof m);
    add_quad(&m, &f, v3(-3.0f, -3.0f, 0.0f), v3(6.0f, 0.0f, 0.0f), v3(0.0f, 6.0f, 0.0f), 1);
    add_quad(&m, &f, v3(-3.0f, -3.0f, 0.5f), v3(6.0f, 0.0f, 0.0f), v3(0.0f, 6.0f, 0.0f), 0);
    s.n_objects = 2;
    s.objects[0].material = 0;
    s.objects[1].material = 1;
    s.n_materials = 2;
    s.n_lights = 0;
    s.env.kind = ENV_CONSTANT;
    s.env.radiance = v3(0.5f, 1.0f, 2.0f);
    material *pane = &s.materials[0], *back = &s.materials[1];
    pane->model = MODEL_D3D9CLIENT;
    pane->albedo = v3s(0.0f);
    pane->d3d.diffuse = v3s(0.0f);
    pane->d9.p = 0.0f;
    pane->d9.r0 = 0.2f;
    pane->d9.m = 0.0f;
    pane->d9.alpha = 0.1f;
    pane->d9.blend = 1;
    back->d3d.diffuse = v3s(0.0f);
    back->d3d.emissive = v3(0.2f, 0.4f, 0.6f);
    result r;
    render(&s, &m, "blend", &r);
    const char *names[3] = {"R", "G", "B"};
    const double want[3] = {0.16, 0.32, 0.52};
    for (int c = 0; c < 3; c++) {
        const float *x = chan(&r, names[c]);
        double sum = 0.0, sq = 0.0;
        const int n = r.w * r.h;
        for (int p = 0; p < n; p++) {
            sum += x[p];
            sq += (double)x[p] * x[p];
        }
        double mean = sum / n, se = sqrt(fmax(sq / n - mean * mean, 0.0) / n);
        printf("# blend %s: mean %.6f, want %.6f, standard error %.2g\n", names[c], mean, want[c], se);
        assert_true(fabs(mean - want[c]) <= 4.0 * se + 2e-4 * want[c]);
    }
    exr_image_free(&r.img);
}

/* ------------------------------------------------------------------ 6: mirror terms (twin) */

typedef struct {
    dvec3 l;
    double lam[3], sc[3], r0, m, p, f0[3];
    int ch;
} mirror_ctx;

/* Left quad (x < -0.1): D3D9Client reflection (lambda + (s - lambda) R) L; right quad
 * (x > 0.1): Cook-Torrance env(reflect) * Schlick(F0, N.V) with a constant environment L.
 * NAN in the gap between the quads, so those pixels are skipped. */
static double mirror_radiance(const void *ctx, dvec3 x, dvec3 v)
{
    const mirror_ctx *mc = ctx;
    double nv = fmin(fmax(v.y, 0.0), 1.0);
    double l = mc->ch == 0 ? mc->l.x : (mc->ch == 1 ? mc->l.y : mc->l.z);
    if (x.x < -0.1) {
        double r = mc->r0 + mc->m * pow(1.0 - nv, mc->p);
        return (mc->lam[mc->ch] + (mc->sc[mc->ch] - mc->lam[mc->ch]) * r) * l;
    }
    if (x.x > 0.1)
        return (mc->f0[mc->ch] + (1.0 - mc->f0[mc->ch]) * pow(1.0 - nv, 5.0)) * l;
    return NAN;
}

static double mirror_r(const void *ctx, dvec3 x, dvec3 v)
{
    mirror_ctx c = *(const mirror_ctx *)ctx;
    c.ch = 0;
    return mirror_radiance(&c, x, v);
}
static double mirror_g(const void *ctx, dvec3 x, dvec3 v)
{
    mirror_ctx c = *(const mirror_ctx *)ctx;
    c.ch = 1;
    return mirror_radiance(&c, x, v);
}
static double mirror_b(const void *ctx, dvec3 x, dvec3 v)
{
    mirror_ctx c = *(const mirror_ctx *)ctx;
    c.ch = 2;
    return mirror_radiance(&c, x, v);
}

static void test_mirror_terms(void **state)
{
    (void)state;
    scene s;
    mesh m;
    fixture_mesh f;
    base_scene(&s, 48, 32);
    memset(&m, 0, sizeof m);
    add_quad(&m, &f, v3(-1.5f, 0.0f, 1.4f), v3(1.4f, 0.0f, 0.0f), v3(0.0f, 0.0f, -2.6f), 0);
    add_quad(&m, &f, v3(0.1f, 0.0f, 1.4f), v3(1.2f, 0.0f, 0.0f), v3(0.0f, 0.0f, -2.6f), 1);
    s.n_objects = 2;
    s.objects[1].material = 1;
    s.n_materials = 2;
    s.camera.eye = v3(0.2f, 1.2f, 2.6f);
    s.camera.target = v3(-0.1f, 0.0f, 0.0f);
    s.camera.hfov = (float)(70.0 * PI / 180.0);
    s.env.kind = ENV_CONSTANT;
    s.env.radiance = v3(0.8f, 1.0f, 1.3f);
    material *a = &s.materials[0], *b = &s.materials[1];
    a->model = MODEL_D3D9CLIENT;
    /* No diffuse closure beside the mirror: Cycles would pick one closure per bounce, and that
     * selection noise (stratified, far from Gaussian) makes two-seed error bars unreliable.
     * The diffuse weight 1 - |lambda| is checked in the job file test. */
    a->d3d.diffuse = v3s(0.0f);
    a->d9.reflect = v3(0.3f, 0.2f, 0.1f);
    a->d9.fresnel_colour = v3(0.9f, 1.0f, 0.8f);
    a->d9.r0 = 0.1f;
    a->d9.m = 0.7f;
    a->d9.p = 2.5f;
    b->model = MODEL_COOK_TORRANCE;
    b->albedo = v3s(0.0f);
    b->ct.ks = v3s(0.0f); /* no lobe: the mirror and a Beckmann lobe cannot share the glossy passes */
    b->ct.f = F_SCHLICK;
    b->ct.f0 = v3(0.04f, 0.5f, 0.9f);
    s.n_lights = 0;
    result r;
    render(&s, &m, "mirror", &r);
    cam c;
    cam_make(&s, r.w, r.h, &c);
    mirror_ctx mc = {dv3(0.8, 1.0, 1.3), {0.3, 0.2, 0.1}, {0.9, 1.0, 0.8}, 0.1, 0.7, 2.5, {0.04, 0.5, 0.9}, 0};
    const float one[3] = {1, 1, 1};
    radiance_fn fns[3] = {mirror_r, mirror_g, mirror_b};
    static const char *names[3] = {"reflection.R", "reflection.G", "reflection.B"};
    int n = 0;
    for (int ch = 0; ch < 3; ch++) {
        char what[64];
        snprintf(what, sizeof what, "mirror twin %s", names[ch]);
        n += compare_floor_channel(&r, &c, names[ch], one[ch], fns[ch], &mc, what, 0.0);
    }
    assert_true(n > 3 * 400);
    /* No lights: the diffuse and specular layers are empty (the environment lights no diffuse). */
    const float *d = chan(&r, "diffuse.G"), *sp = chan(&r, "specular.G");
    for (int p = 0; p < r.w * r.h; p++) {
        assert_float_equal(d[p], 0.0, 1e-7);
        assert_float_equal(sp[p], 0.0, 1e-7);
    }
    exr_image_free(&r.img);
}

/* ------------------------------------------------------------------ 7: environment image and scale */

static void test_environment_image_scale(void **state)
{
    (void)state;
    /* A uniform 16 x 8 image of (0.25, 0.5, 1): any orientation gives the same radiance, so this
     * checks the image path, the Linear colour space and the per-channel scale only. */
    float px[3][16 * 8];
    for (int i = 0; i < 16 * 8; i++) {
        px[0][i] = 0.25f;
        px[1][i] = 0.5f;
        px[2][i] = 1.0f;
    }
    exr_channel ch[3] = {{"R", px[0]}, {"G", px[1]}, {"B", px[2]}};
    scene s;
    base_scene(&s, 16, 8);
    snprintf(s.env.path, sizeof s.env.path, "%s/uniform.exr", g_dir);
    char err[512];
    assert_int_equal(exr_write(s.env.path, 16, 8, ch, 3, NULL, 0, err, sizeof err), RC_OK);
    s.env.kind = ENV_IMAGE;
    s.env.radiance = v3(2.0f, 3.0f, 0.5f);
    s.n_objects = 0;
    mesh m;
    memset(&m, 0, sizeof m);
    result r;
    render(&s, &m, "envimage", &r);
    const float want[3] = {0.5f, 1.5f, 0.5f};
    const float *c3[3] = {chan(&r, "R"), chan(&r, "G"), chan(&r, "B")};
    for (int p = 0; p < r.w * r.h; p++)
        for (int k = 0; k < 3; k++)
            assert_float_equal(c3[k][p], want[k], 1e-5);
    exr_image_free(&r.img);
}

/* ------------------------------------------------------------------ 8: validate role */

typedef struct {
    double ior, albedo, l;
} coat_ctx;

static double fresnel_dielectric_ref(double c, double n)
{
    double g = sqrt(n * n - 1.0 + c * c);
    double a = (g - c) / (g + c), b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0);
    return 0.5 * a * a * (1.0 + b * b);
}

/* Lambert under a constant environment L: irradiance pi L, so radiance albedo (1 - F(N.V)) L. */
static double coat_diffuse(const void *ctx, dvec3 x, dvec3 v)
{
    (void)x;
    const coat_ctx *cc = ctx;
    return cc->albedo * (1.0 - fresnel_dielectric_ref(fmin(fmax(v.y, 0.0), 1.0), cc->ior)) * cc->l;
}

/* Mirror of a constant environment L with exact dielectric Fresnel: F(N.V) L. */
static double fresnel_mirror(const void *ctx, dvec3 x, dvec3 v)
{
    (void)x;
    const coat_ctx *cc = ctx;
    return fresnel_dielectric_ref(fmin(fmax(v.y, 0.0), 1.0), cc->ior) * cc->l;
}

static void test_validate_role(void **state)
{
    (void)state;
    scene s;
    mesh m;
    fixture_mesh f;
    base_scene(&s, 32, 24);
    floor_mesh(&m, &f);
    s.camera.eye = v3(0.4f, 2.6f, 2.2f);
    s.camera.target = v3(-0.1f, 0.0f, 0.1f);
    s.camera.hfov = (float)(70.0 * PI / 180.0);
    s.env.kind = ENV_CONSTANT;
    s.env.radiance = v3s(0.6f);
    s.materials[0].albedo = v3s(0.5f);
    s.materials[0].ior = 1.7f;
    s.materials[0].roughness = 0.2f;
    /* The physics of a coated Lambert under its environment: the world lights the diffuse
     * under 1 - F(N.V), and the rough lobe is tinted by F(N.V), all Cycles can render there. */
    s.physics.env_diffuse = 1;
    s.physics.diffuse_weight = PHYS_DIFFUSE_ONE_MINUS_F;
    s.physics.fresnel_specular = PHYS_FRESNEL_NV;
    s.physics.fresnel_reflection = PHYS_FRESNEL_NV;
    cycles_options o = {
        .role = ROLE_VALIDATE, .n_seeds = 2, .seed = 3, .samples = 64, .threads = 2, .script = g_script};
    result r;
    render_ok(&s, &m, &o, "validate", &r);
    cam c;
    cam_make(&s, r.w, r.h, &c);
    coat_ctx cc = {1.7, 0.5, 0.6};
    int n = compare_floor_channel(&r, &c, "diffuse.G", 1.0f, coat_diffuse, &cc, "validate coated Lambert", 0.0);
    assert_true(n > 150);
    /* The glossy lobe sees the environment: positive, below L (a lobe reflects at most all). */
    const float *g = chan(&r, "specular.G"), *cov = chan(&r, "coverage");
    for (int p = 0; p < r.w * r.h; p++)
        if (cov[p] >= 1.0f)
            assert_true(g[p] > 0.0f && g[p] < 0.6f);
    exr_image_free(&r.img);

    /* A conductor builds the complex-Fresnel node graph and has no diffuse layer. */
    s.materials[0].conductor = 1;
    s.materials[0].eta = v3(0.2f, 0.9f, 1.1f);
    s.materials[0].k = v3(3.9f, 2.4f, 2.2f);
    o.n_seeds = 1;
    o.samples = 4;
    render_ok(&s, &m, &o, "validate", &r);
    const float *dd = chan(&r, "diffuse.R"), *gr = chan(&r, "specular.R"), *gb = chan(&r, "specular.B");
    cov = chan(&r, "coverage");
    for (int p = 0; p < r.img.width * r.img.height; p++) {
        assert_float_equal(dd[p], 0.0, 1e-7);
        /* Gold-like: red reflects more than blue. */
        if (cov[p] >= 1.0f)
            assert_true(gr[p] > gb[p] && isfinite(gr[p]));
    }
    exr_image_free(&r.img);

    /* Agree renders the validate job; on a mirror with the default physics that is what
     * POV-Ray's validate holds: the environment's reflection coloured by the exact dielectric
     * Fresnel of N.V, built from Math nodes. Albedo 0 keeps closure-selection noise out. */
    physics_init(&s.physics);
    s.materials[0].conductor = 0;
    s.materials[0].albedo = v3s(0.0f);
    s.materials[0].roughness = 0.0f;
    o.role = ROLE_AGREE;
    o.n_seeds = 2;
    o.samples = 16;
    render_ok(&s, &m, &o, "validate", &r);
    n = compare_floor_channel(&r, &c, "specular.G", 1.0f, fresnel_mirror, &cc, "agree Fresnel mirror", 0.0);
    assert_true(n > 150);
    exr_image_free(&r.img);
}

/* ------------------------------------------------------------------ job file and errors (no render) */

/* The job file parsed back (cJSON); fails the test when it is not JSON. */
static cJSON *job_parse(const char *path)
{
    FILE *fp = fopen(path, "r");
    if (fp == NULL)
        fail_msg("%s: cannot open the job", path);
    static char buf[1 << 16];
    size_t n = fread(buf, 1, sizeof buf - 1, fp);
    buf[n] = '\0';
    fclose(fp);
    cJSON *doc = cJSON_Parse(buf);
    if (doc == NULL)
        fail_msg("%s: not JSON near '%.40s'", path, cJSON_GetErrorPtr() ? cJSON_GetErrorPtr() : "");
    return doc;
}

/* The item at a path of keys and array indices ("lights", "#1", "energy"), or a failure. */
static const cJSON *job_at(const cJSON *doc, int n, ...)
{
    va_list ap;
    va_start(ap, n);
    const cJSON *v = doc;
    for (int i = 0; i < n; i++) {
        const char *k = va_arg(ap, const char *);
        v = k[0] == '#' ? cJSON_GetArrayItem(v, atoi(k + 1)) : cJSON_GetObjectItemCaseSensitive(v, k);
        if (v == NULL)
            fail_msg("job.json: no '%s' (step %d of the path)", k, i + 1);
    }
    va_end(ap);
    return v;
}

static double job_num(const cJSON *v)
{
    if (!cJSON_IsNumber(v))
        fail_msg("job.json: a number expected");
    return v->valuedouble;
}

/* A three-number array equal to (x, y, z) within rel (the file keeps 9 digits). */
static void job_vec(const cJSON *v, double x, double y, double z, double rel)
{
    assert_true(cJSON_IsArray(v));
    assert_int_equal(cJSON_GetArraySize(v), 3);
    close_rel(job_num(cJSON_GetArrayItem(v, 0)), x, rel);
    close_rel(job_num(cJSON_GetArrayItem(v, 1)), y, rel);
    close_rel(job_num(cJSON_GetArrayItem(v, 2)), z, rel);
}

static void test_job_contents_and_refusals(void **state)
{
    (void)state;
    scene s;
    mesh m;
    fixture_mesh f;
    base_scene(&s, 16, 8);
    floor_mesh(&m, &f);
    s.n_lights = 2;
    s.lights[0].kind = LIGHT_POINT;
    s.lights[0].position = v3(0.0f, 2.0f, 0.0f);
    s.lights[0].intensity = v3(2.0f, 1.0f, 0.5f);
    s.lights[1].kind = LIGHT_SPOT;
    s.lights[1].position = v3(0.0f, 2.0f, 0.0f);
    s.lights[1].intensity = v3s(1.0f);
    s.lights[1].inner = (float)(PI / 3.0); /* 60 deg full: half 30 */
    s.lights[1].outer = (float)(PI / 2.0); /* 90 deg full: half 45 */
    char job[512], err[512];
    snprintf(job, sizeof job, "%s/contents.json", g_dir);
    cycles_options o = {0};
    assert_int_equal(cycles_write_job(&s, &m, &o, job, err, sizeof err), RC_OK);
    cJSON *doc = job_parse(job);
    assert_string_equal(job_at(doc, 1, "format")->valuestring, "reflcheck-cycles-job");
    assert_string_equal(job_at(doc, 1, "role")->valuestring, "twin");
    assert_int_equal((int)job_num(job_at(doc, 1, "width")), 16);
    assert_int_equal(cJSON_GetArraySize(job_at(doc, 1, "lights")), 2);
    /* P = 4 pi max(I) = 8 pi; the colour carries the ratio; 9 digits in the file. */
    close_rel(job_num(job_at(doc, 3, "lights", "#0", "energy")), 8.0 * PI, 1e-8);
    assert_string_equal(job_at(doc, 3, "lights", "#0", "type")->valuestring, "POINT");
    job_vec(job_at(doc, 3, "lights", "#0", "color"), 1.0, 0.5, 0.25, 0.0);
    assert_null(cJSON_GetObjectItemCaseSensitive(job_at(doc, 2, "lights", "#0"), "direction"));
    /* blend = (cos 30 - cos 45) / (1 - cos 45) = 0.5576118... */
    assert_string_equal(job_at(doc, 3, "lights", "#1", "type")->valuestring, "SPOT");
    close_rel(job_num(job_at(doc, 3, "lights", "#1", "spot_blend")), (cos(PI / 6) - cos(PI / 4)) / (1 - cos(PI / 4)),
              1e-8);
    close_rel(job_num(job_at(doc, 3, "lights", "#1", "spot_size")), PI / 2.0, 1e-7);
    const cJSON *tris = job_at(doc, 3, "objects", "#0", "tris");
    assert_int_equal(cJSON_GetArraySize(tris), 6);
    static const int want_tris[6] = {0, 1, 2, 0, 2, 3};
    for (int i = 0; i < 6; i++)
        assert_int_equal((int)job_num(cJSON_GetArrayItem(tris, i)), want_tris[i]);
    assert_int_equal(cJSON_GetArraySize(job_at(doc, 3, "objects", "#0", "verts")), 3 * 4);
    assert_int_equal((int)job_num(job_at(doc, 3, "objects", "#0", "pass_index")), 1);
    cJSON_Delete(doc);
    /* D3D9Client eq. (6): Vd (1 - |lambda|), |lambda| = max component by default: 0.5 (1 - 0.4). */
    s.materials[0].model = MODEL_D3D9CLIENT;
    s.materials[0].d3d.diffuse = v3s(0.5f);
    s.materials[0].d9.reflect = v3(0.1f, 0.4f, 0.2f);
    s.env.kind = ENV_CONSTANT;
    assert_int_equal(cycles_write_job(&s, &m, &o, job, err, sizeof err), RC_OK);
    doc = job_parse(job);
    /* (float) 0.3 written to 9 digits: 0.300000012 */
    job_vec(job_at(doc, 4, "materials", "#0", "diffuse", "color"), 0.3, 0.3, 0.3, 1e-7);
    assert_string_equal(job_at(doc, 4, "materials", "#0", "mirror", "kind")->valuestring, "d3d9client");
    assert_true(cJSON_IsFalse(job_at(doc, 2, "world_visibility", "diffuse")));
    assert_true(cJSON_IsTrue(job_at(doc, 2, "world_visibility", "glossy")));
    assert_true(cJSON_IsFalse(job_at(doc, 2, "world_visibility", "light_sampling")));
    assert_string_equal(job_at(doc, 1, "glossy_aov")->valuestring, "reflection");
    assert_int_equal(cJSON_GetArraySize(job_at(doc, 1, "missing")), 0);
    cJSON_Delete(doc);
    /* ... and a Cook-Torrance lobe beside that mirror cannot be separated: refused. */
    s.n_materials = 2;
    s.n_objects = 2;
    s.objects[1].material = 1;
    f.tri_object[1] = 1;
    s.materials[1].model = MODEL_COOK_TORRANCE;
    s.materials[1].ct.g = G_SMITH_WALTER;
    s.materials[1].ct.f = F_ONE;
    s.materials[1].ct.reflection = 0; /* its own environment term: test_ct_environment_term_job */
    assert_int_equal(cycles_write_job(&s, &m, &o, job, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "separate scenes"));
    s.n_materials = 1;
    s.n_objects = 1;
    f.tri_object[1] = 0;
    s.env.kind = ENV_NONE;
    s.materials[0].model = MODEL_D3D;

    /* Blinn-Phong specular has no Cycles lobe: refused in twin, listed with partial. */
    s.materials[0].d3d.specular = v3s(0.5f);
    s.materials[0].d3d.power = 20.0f;
    assert_int_equal(cycles_write_job(&s, &m, &o, job, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "Blinn-Phong"));
    o.partial = 1;
    assert_int_equal(cycles_write_job(&s, &m, &o, job, err, sizeof err), RC_OK);
    doc = job_parse(job);
    const cJSON *missing = job_at(doc, 1, "missing");
    assert_int_equal(cJSON_GetArraySize(missing), 1);
    assert_non_null(strstr(cJSON_GetArrayItem(missing, 0)->valuestring, "materials[0]"));
    assert_non_null(strstr(cJSON_GetArrayItem(missing, 0)->valuestring, "Blinn-Phong"));
    cJSON_Delete(doc);
    /* Non-inverse-square attenuation is refused in every role. */
    s.lights[0].a0 = 1.0f;
    o.role = ROLE_VALIDATE;
    assert_int_equal(cycles_write_job(&s, &m, &o, job, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "lights[0]"));
    s.lights[0].a0 = 0.0f;
    /* NaN never reaches the JSON. */
    s.lights[0].position.x = NAN;
    assert_int_equal(cycles_write_job(&s, &m, &o, job, err, sizeof err), RC_ERR_RANGE);

    cycles_argv a;
    o.threads = 3;
    assert_int_equal(cycles_command(&o, "j.json", "o.exr", &a, err, sizeof err), RC_OK);
    assert_int_equal(a.argc, 12);
    assert_string_equal(a.argv[0], "blender");
    assert_string_equal(a.argv[1], "-b");
    assert_string_equal(a.argv[5], "-t");
    assert_string_equal(a.argv[6], "3");
    assert_string_equal(a.argv[9], "--");
    assert_string_equal(a.argv[11], "o.exr");
    assert_null(a.argv[12]);
    char buf[64];
    assert_string_equal(cycles_channel_name("", 'R', buf, sizeof buf), "R");
    assert_string_equal(cycles_channel_name("coverage", 0, buf, sizeof buf), "coverage.V");
    /* reflcheck's own names: a one-channel layer is its pass alone, without Blender's ".V". */
    int named = 0;
    for (int k = 0; k < CYCLES_LAYOUT_N; k++) {
        const cycles_layer *l = &cycles_layout[k];
        cycles_layer_name(k, buf, sizeof buf);
        if (l->aov[0] == '\0' && l->c == 'R')
            named += strcmp(buf, "R") == 0;
        else if (strcmp(l->aov, "diffuse") == 0 && l->c == 'G')
            named += strcmp(buf, "diffuse.G") == 0;
        else if (strcmp(l->aov, "coverage") == 0)
            named += strcmp(buf, "coverage") == 0;
    }
    assert_int_equal(named, 3);
    assert_int_equal(cycles_raw_path("d/x.exr", 1, buf, sizeof buf), RC_OK);
    assert_string_equal(buf, "d/x.cyc1.exr");
}

/* Source 004's environment term in a twin: CM * Fr is a Glossy 'SHARP' closure coloured by
 * Schlick(F0, N.V) with the material's F0 (the twin switches keep F for it); the Beckmann lobe
 * beside it would see the environment the mirror needs, so it is refused, or left out and
 * named with partial. */
/* A thin sheet in a validate job: a sharp Glass BSDF of the material's ior and the object marked
 * with the slab's thickness; the exact Fresnel form is required. */
static void test_thin_sheet_job(void **state)
{
    (void)state;
    scene s;
    mesh m;
    fixture_mesh f;
    base_scene(&s, 16, 8);
    floor_mesh(&m, &f);
    s.materials[0].thin = 1;
    s.materials[0].roughness = 0.0f;
    s.materials[0].ior = 1.45f;
    char job[512], err[512];
    snprintf(job, sizeof job, "%s/thin.json", g_dir);
    cycles_options o = {.role = ROLE_VALIDATE};
    assert_int_equal(cycles_write_job(&s, &m, &o, job, err, sizeof err), RC_OK);
    cJSON *doc = job_parse(job);
    close_rel(job_num(job_at(doc, 4, "materials", "#0", "glass", "ior")), 1.45, 1e-7);
    assert_null(cJSON_GetObjectItemCaseSensitive(job_at(doc, 2, "materials", "#0"), "diffuse"));
    close_rel(job_num(job_at(doc, 3, "objects", "#0", "thin")), 0.002, 1e-9);
    cJSON_Delete(doc);
    /* The twin is the model: no slab. */
    o.role = ROLE_TWIN;
    assert_int_equal(cycles_write_job(&s, &m, &o, job, err, sizeof err), RC_OK);
    doc = job_parse(job);
    assert_null(cJSON_GetObjectItemCaseSensitive(job_at(doc, 2, "objects", "#0"), "thin"));
    cJSON_Delete(doc);
    s.physics.fresnel_reflection = PHYS_FRESNEL_SCHLICK;
    physics ph;
    assert_int_equal(cycles_physics(&s, &ph, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "thin sheet"));
}

/* The importance map's width in the job: none by default (cycles_render.py takes the image's),
 * options.env_detail when set (cycles_render_job's 4 N for an N x N cube map's conversion). */
static void test_env_map_resolution_job(void **state)
{
    (void)state;
    scene s;
    mesh m;
    fixture_mesh f;
    base_scene(&s, 16, 8);
    floor_mesh(&m, &f);
    float px[4 * 2] = {0.5f, 1.0f, 2.0f, 3.0f, 0.25f, 0.5f, 1.5f, 2.5f};
    exr_channel ch[3] = {{"R", px}, {"G", px}, {"B", px}};
    char job[512], err[512];
    snprintf(s.env.path, sizeof s.env.path, "%s/detail.exr", g_dir);
    assert_int_equal(exr_write(s.env.path, 4, 2, ch, 3, NULL, 0, err, sizeof err), RC_OK);
    s.env.kind = ENV_IMAGE;
    s.env.radiance = v3s(1.0f);
    snprintf(job, sizeof job, "%s/detail.json", g_dir);
    cycles_options o = {0};
    assert_int_equal(cycles_write_job(&s, &m, &o, job, err, sizeof err), RC_OK);
    cJSON *doc = job_parse(job);
    assert_null(cJSON_GetObjectItemCaseSensitive(job_at(doc, 1, "environment"), "map_resolution"));
    cJSON_Delete(doc);
    o.env_detail = 36;
    assert_int_equal(cycles_write_job(&s, &m, &o, job, err, sizeof err), RC_OK);
    doc = job_parse(job);
    assert_int_equal((int)job_num(job_at(doc, 2, "environment", "map_resolution")), 36);
    cJSON_Delete(doc);
}

static void test_ct_environment_term_job(void **state)
{
    (void)state;
    scene s;
    mesh m;
    fixture_mesh f;
    base_scene(&s, 16, 8);
    floor_mesh(&m, &f);
    s.env.kind = ENV_CONSTANT;
    s.env.radiance = v3s(0.5f);
    s.materials[0].model = MODEL_COOK_TORRANCE;
    s.materials[0].albedo = v3s(0.0f);
    s.materials[0].ct.f0 = v3(0.9f, 0.8f, 0.7f);
    s.materials[0].ct.reflection = 1;
    char job[512], err[512];
    snprintf(job, sizeof job, "%s/ct_env.json", g_dir);
    cycles_options o = {0};
    assert_int_equal(cycles_write_job(&s, &m, &o, job, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "would reflect the environment"));
    o.partial = 1;
    assert_int_equal(cycles_write_job(&s, &m, &o, job, err, sizeof err), RC_OK);
    cJSON *doc = job_parse(job);
    assert_string_equal(job_at(doc, 4, "materials", "#0", "mirror", "kind")->valuestring, "schlick");
    job_vec(job_at(doc, 4, "materials", "#0", "mirror", "f0"), 0.9, 0.8, 0.7, 1e-7);
    assert_null(cJSON_GetObjectItemCaseSensitive(job_at(doc, 2, "materials", "#0"), "glossy"));
    assert_true(cJSON_IsTrue(job_at(doc, 2, "world_visibility", "glossy")));
    assert_string_equal(job_at(doc, 1, "glossy_aov")->valuestring, "reflection");
    const cJSON *missing = job_at(doc, 1, "missing");
    assert_int_equal(cJSON_GetArraySize(missing), 1);
    assert_non_null(strstr(cJSON_GetArrayItem(missing, 0)->valuestring, "would reflect the environment"));
    cJSON_Delete(doc);
    /* Without an environment there is no mirror, and the lobe (with Cycles' switches) stays. */
    s.env.kind = ENV_NONE;
    s.materials[0].ct.g = G_SMITH_WALTER;
    s.materials[0].ct.f = F_ONE;
    o.partial = 0;
    assert_int_equal(cycles_write_job(&s, &m, &o, job, err, sizeof err), RC_OK);
    doc = job_parse(job);
    assert_null(cJSON_GetObjectItemCaseSensitive(job_at(doc, 2, "materials", "#0"), "mirror"));
    close_rel(job_num(job_at(doc, 4, "materials", "#0", "glossy", "roughness")), sqrt((double)s.materials[0].ct.m),
              1e-7);
    cJSON_Delete(doc);
}

/* A driver script that fails is a failed job whose message carries the script's error line
 * (the same path production takes). The script here reads the job and refuses it as
 * cycles_render.py refuses a job without samples. */
static void test_script_failure_is_reported(void **state)
{
    (void)state;
    char script[512], out[512];
    snprintf(script, sizeof script, "%s/broken.py", g_dir);
    FILE *fp = fopen(script, "w");
    assert_non_null(fp);
    fputs("import sys\nprint(\"cycles_render.py: error: job: missing key 'samples'\", file=sys.stderr)\n"
          "sys.exit(1)\n",
          fp);
    fclose(fp);
    scene s;
    mesh m;
    base_scene(&s, 8, 8);
    floor_scene_mesh(&s, &m);
    cycles_options o = {.role = ROLE_TWIN, .n_seeds = 1, .samples = 1, .script = script};
    renderer_result r = render_entry(&s, &m, &o, "broken", out, sizeof out);
    assert_int_equal(r.status, RUNNER_FAILED);
    assert_non_null(strstr(r.message, "blender failed (exit status 1)"));
    assert_non_null(strstr(r.message, "missing key 'samples'"));
    mesh_free(&m);
}

int main(void)
{
    if (!runner_available("blender")) {
        fprintf(stderr, "test_cycles: blender is not on PATH; install blender 3.4 (CI installs it)\n");
        return 1;
    }
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_job_contents_and_refusals),
        cmocka_unit_test(test_ct_environment_term_job),
        cmocka_unit_test(test_env_map_resolution_job),
        cmocka_unit_test(test_script_failure_is_reported),
        cmocka_unit_test(test_point_samples),
        cmocka_unit_test(test_sun_lambert),
        cmocka_unit_test(test_point_lambert),
        cmocka_unit_test(test_beckmann_twin),
        cmocka_unit_test(test_camera_frame),
        cmocka_unit_test(test_background_constant),
        cmocka_unit_test(test_mirror_terms),
        cmocka_unit_test(test_blend_twin),
        cmocka_unit_test(test_thin_sheet_job),
        cmocka_unit_test(test_environment_image_scale),
        cmocka_unit_test(test_validate_role),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
