/* test_povray.c - the POV-Ray translation, checked by rendering with the real povray.
 *
 * Every expected value is computed here from the radiometric formula at the pixel's sample
 * points (an independent pinhole camera and ray-plane intersection), not by the rasterizer.
 * Tolerances: POV-Ray writes half-float EXR, whose relative step is 2^-11 = 4.9e-4, so a
 * rendered value is within 2.5e-4 of the truth by rounding alone; 1e-3 relative leaves room for
 * POV-Ray's float colour arithmetic (~1e-7) and its double ray maths. Set REFLCHECK_KEEP=1 to
 * keep the SDL, EXR and log files in the printed temporary directory.
 */
#define _POSIX_C_SOURCE 200809L
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "exr.h"
#include "renderers/povray/povray.h"
#include "renderers/registry.h"

#define PI       3.14159265358979323846
/* Half-float quantisation (<= 2.4e-4) plus POV-Ray's float arithmetic, with margin. */
#define HALF_TOL 1e-3

static char tmpdir[256];
static double total_seconds;

/* ---- fixtures ---------------------------------------------------------------------- */

static void add_vertex(mesh *m, vec3 p, vec3 n)
{
    if (m->n_verts == m->cap_verts) {
        m->cap_verts = m->cap_verts ? 2 * m->cap_verts : 64;
        m->pos = realloc(m->pos, sizeof *m->pos * (size_t)m->cap_verts);
        m->nrm = realloc(m->nrm, sizeof *m->nrm * (size_t)m->cap_verts);
        assert_non_null(m->pos);
        assert_non_null(m->nrm);
    }
    m->pos[m->n_verts] = p;
    m->nrm[m->n_verts] = n;
    m->n_verts++;
}

static void add_tri(mesh *m, uint32_t a, uint32_t b, uint32_t c, int object_id)
{
    if (m->n_tris == m->cap_tris) {
        m->cap_tris = m->cap_tris ? 2 * m->cap_tris : 64;
        m->idx = realloc(m->idx, sizeof *m->idx * 3 * (size_t)m->cap_tris);
        m->tri_object = realloc(m->tri_object, sizeof *m->tri_object * (size_t)m->cap_tris);
        assert_non_null(m->idx);
        assert_non_null(m->tri_object);
    }
    m->idx[3 * m->n_tris] = a;
    m->idx[3 * m->n_tris + 1] = b;
    m->idx[3 * m->n_tris + 2] = c;
    m->tri_object[m->n_tris] = object_id;
    m->n_tris++;
}

/* A flat quad (two triangles, all four normals = n) with corners c0..c3 in order. */
static void add_quad(mesh *m, const vec3 c[4], vec3 n, int object_id)
{
    uint32_t b = (uint32_t)m->n_verts;
    for (int i = 0; i < 4; i++)
        add_vertex(m, c[i], n);
    add_tri(m, b, b + 1, b + 2, object_id);
    add_tri(m, b, b + 2, b + 3, object_id);
}

/* A square of half-size h centred at o in the plane with unit normal n. */
static void add_plane(mesh *m, vec3 o, vec3 n, float h, int object_id)
{
    vec3 a = fabsf(n.x) < 0.9f ? v3(1, 0, 0) : v3(0, 1, 0);
    vec3 t1 = v3_norm(v3_cross(n, a)), t2 = v3_cross(n, t1);
    vec3 c[4] = {
        v3_add(o, v3_add(v3_scale(t1, -h), v3_scale(t2, -h))),
        v3_add(o, v3_add(v3_scale(t1, h), v3_scale(t2, -h))),
        v3_add(o, v3_add(v3_scale(t1, h), v3_scale(t2, h))),
        v3_add(o, v3_add(v3_scale(t1, -h), v3_scale(t2, h))),
    };
    add_quad(m, c, n, object_id);
}

static void mesh_release(mesh *m)
{
    free(m->pos);
    free(m->nrm);
    free(m->idx);
    free(m->tri_object);
    memset(m, 0, sizeof *m);
}

static void base_scene(scene *s, int w, int h, vec3 eye, vec3 target, double hfov_deg)
{
    scene_init(s);
    snprintf(s->path, sizeof s->path, "test_povray");
    s->width = w;
    s->height = h;
    s->camera.eye = eye;
    s->camera.target = target;
    s->camera.hfov = (float)(hfov_deg * PI / 180.0);
    s->n_materials = 1;
    s->n_objects = 1;
    s->objects[0].shape = SHAPE_MESH;
    s->objects[0].material = 0;
}

/* ---- an independent pinhole camera (canonical frame, docs/conventions.md) ------ */

typedef struct {
    dvec3 eye, f, r, u;
    double tx, ty;
    int w, h;
} cam;

static cam cam_make(const scene *s)
{
    cam c;
    c.eye = dv3_from(s->camera.eye);
    c.f = dv3_norm(dv3_sub(dv3_from(s->camera.target), c.eye));
    c.r = dv3_norm(dv3_cross(c.f, dv3_from(s->camera.up)));
    c.u = dv3_cross(c.r, c.f);
    c.tx = tan(0.5 * s->camera.hfov);
    c.ty = c.tx * s->height / s->width;
    c.w = s->width;
    c.h = s->height;
    return c;
}

/* Ray direction (not unit; its component along f is 1) through image point (sx, sy) in
 * pixels, x to the right, row 0 at the top. */
static dvec3 cam_dir(const cam *c, double sx, double sy)
{
    double a = (2.0 * sx / c->w - 1.0) * c->tx, b = (1.0 - 2.0 * sy / c->h) * c->ty;
    return dv3_add(c->f, dv3_add(dv3_scale(c->r, a), dv3_scale(c->u, b)));
}

/* Hit of the ray through (sx, sy) with the plane dot(n, x - o) = 0; 0 if it misses. */
static int cam_hit_plane(const cam *c, double sx, double sy, dvec3 o, dvec3 n, dvec3 *x)
{
    dvec3 d = cam_dir(c, sx, sy);
    double den = dv3_dot(n, d);
    /* A ray within 1e-12 of parallel never occurs in these fixtures; treat it as a miss. */
    if (fabs(den) < 1e-12)
        return 0;
    double t = dv3_dot(n, dv3_sub(o, c->eye)) / den;
    if (t <= 0.0)
        return 0;
    *x = dv3_add(c->eye, dv3_scale(d, t));
    return 1;
}

/* ---- running POV-Ray --------------------------------------------------------------- */

/* What the render entry wrote, read back: R, G, B planes (radiance, scale undone). */
typedef struct {
    int width, height, supersample;
    float *rgb[3];
    double seconds;
    char command[2048];
} povray_image;

static void povray_image_free(povray_image *img)
{
    for (int c = 0; c < 3; c++) {
        free(img->rgb[c]);
        img->rgb[c] = NULL;
    }
}

/* Renders through the renderer table's entry, the one production (harness/jobs.c) runs. */
static renderer_result pov_entry(const scene *s, const mesh *m, const povray_options *o, const char *tag, char *exr,
                                 size_t exrlen)
{
    char dir[512], log[600];
    snprintf(dir, sizeof dir, "%s/%s-work", tmpdir, tag);
    mkdir(dir, 0755);
    snprintf(exr, exrlen, "%s/%s.exr", tmpdir, tag);
    snprintf(log, sizeof log, "%s/%s.log", tmpdir, tag);
    renderer_job j = {
        .s = s, .m = m, .role = o->role, .dir = dir, .exr = exr, .log = log, .timeout = 600.0, .options = o};
    renderer_result r = {0};
    registry_row(registry_find("povray"))->render(&j, &r);
    return r;
}

static void pov_render(const scene *s, const mesh *m, const povray_options *o, const char *tag, povray_image *img)
{
    static const char *const names[3] = {"R", "G", "B"};
    char exr[512], log[600], err[512] = "";
    memset(img, 0, sizeof *img);
    renderer_result r = pov_entry(s, m, o, tag, exr, sizeof exr);
    if (r.status != RUNNER_OK)
        fprintf(stderr, "povray entry (%s): %s\n", tag, r.message);
    assert_int_equal(r.status, RUNNER_OK);
    exr_image e;
    if (exr_read(exr, &e, err, sizeof err) != RC_OK)
        fail_msg("exr_read(%s): %s", exr, err);
    assert_int_equal(e.width, s->width);
    assert_int_equal(e.height, s->height);
    size_t np = (size_t)e.width * (size_t)e.height;
    for (int c = 0; c < 3; c++) {
        const float *src = exr_image_channel(&e, names[c]);
        assert_non_null(src);
        img->rgb[c] = malloc(np * sizeof(float));
        assert_non_null(img->rgb[c]);
        memcpy(img->rgb[c], src, np * sizeof(float));
    }
    exr_image_free(&e);
    img->width = s->width;
    img->height = s->height;
    img->supersample = o->supersample > 0 ? o->supersample : (s->supersample > 0 ? s->supersample : 1);
    img->seconds = r.wall_s;
    snprintf(img->command, sizeof img->command, "%s", r.command);
    total_seconds += img->seconds;
    printf("  [%s] %dx%d k=%d: POV-Ray %.3f s (scene and geometry passes): %s\n", tag, img->width, img->height,
           img->supersample, img->seconds, img->command);
    if (!getenv("REFLCHECK_KEEP")) {
        snprintf(log, sizeof log, "%s/%s.log", tmpdir, tag);
        unlink(exr);
        unlink(log);
    }
}

/* Relative-error statistics over the checked pixels. */
typedef struct {
    double *rel;
    int n, cap;
    double max;
} errstat;

static void stat_add(errstat *e, double got, double want)
{
    /* 1e-30 only guards a zero expectation (none of the checked values is below 1e-3). */
    double rel = fabs(got - want) / fmax(fabs(want), 1e-30);
    if (e->n == e->cap) {
        e->cap = e->cap ? 2 * e->cap : 256;
        e->rel = realloc(e->rel, sizeof *e->rel * (size_t)e->cap);
        assert_non_null(e->rel);
    }
    e->rel[e->n++] = rel;
    if (rel > e->max)
        e->max = rel;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static void stat_report(errstat *e, const char *what)
{
    assert_true(e->n > 0);
    qsort(e->rel, (size_t)e->n, sizeof *e->rel, cmp_double);
    printf("  %s: %d values, relative error max %.3g median %.3g\n", what, e->n, e->max, e->rel[e->n / 2]);
    free(e->rel);
    memset(e, 0, sizeof *e);
}

static double chan(vec3 v, int c) { return c == 0 ? v.x : (c == 1 ? v.y : v.z); }

/* ---- tests ------------------------------------------------------------------------- */

/* A Lambert plane under a sun: every pixel is albedo * E/pi * cos(theta), both as the D3D
 * twin (Vd = albedo, colour E/pi) and as the physical material. */
static void test_lambert_sun(void **state)
{
    (void)state;
    scene s;
    base_scene(&s, 40, 30, v3(0.3f, 2.0f, 2.5f), v3(0.1f, 0.0f, -0.2f), 50.0);
    s.materials[0].albedo = v3s(0.5f);
    s.materials[0].d3d.diffuse = v3s(0.5f);
    s.n_lights = 1;
    s.lights[0].kind = LIGHT_SUN;
    s.lights[0].direction = v3_norm(v3(0.3f, -1.0f, 0.2f));
    s.lights[0].intensity = v3s(3.0f);
    mesh m = {0};
    add_plane(&m, v3(0, 0, 0), v3(0, 1, 0), 20.0f, 0);

    double cosl = -(double)s.lights[0].direction.y;
    double want = 0.5 * 3.0 / PI * cosl;
    /* A mirror lobe (roughness 0): the validate physics POV-Ray renders, Lambert plus a delta
     * highlight that no pixel sees. */
    s.materials[0].roughness = 0.0f;
    const comparison_role roles[2] = {ROLE_TWIN, ROLE_VALIDATE};
    for (int ri = 0; ri < 2; ri++) {
        povray_options o = {.role = roles[ri], .threads = 2};
        povray_image img;
        pov_render(&s, &m, &o, ri ? "lambert_sun_validate" : "lambert_sun_twin", &img);
        errstat e = {0};
        for (int c = 0; c < 3; c++)
            for (int i = 0; i < img.width * img.height; i++) {
                stat_add(&e, img.rgb[c][i], want);
                assert_float_equal(img.rgb[c][i], want, HALF_TOL * want);
            }
        stat_report(&e, ri ? "lambert sun (validate)" : "lambert sun (twin)");
        povray_image_free(&img);
    }
    mesh_release(&m);
}

/* A point light over a plane, rendered at k = 2 and box-filtered: each pixel is the mean of
 * albedo * I/pi * cos / d^2 at its four sample points (i + 0.25, i + 0.75). */
static void test_point_light(void **state)
{
    (void)state;
    scene s;
    base_scene(&s, 24, 18, v3(-0.4f, 2.2f, 2.0f), v3(0.2f, 0.0f, -0.3f), 55.0);
    vec3 albedo = v3(0.5f, 0.6f, 0.7f);
    s.materials[0].albedo = albedo;
    s.materials[0].d3d.diffuse = albedo;
    s.n_lights = 1;
    s.lights[0].kind = LIGHT_POINT;
    s.lights[0].position = v3(0.4f, 1.3f, -0.3f);
    s.lights[0].intensity = v3(2.0f, 3.0f, 4.0f);
    s.supersample = 2;
    mesh m = {0};
    add_plane(&m, v3(0, 0, 0), v3(0, 1, 0), 30.0f, 0);

    povray_image img;
    povray_options o = {0};
    pov_render(&s, &m, &o, "point_light", &img);
    cam c = cam_make(&s);
    dvec3 lp = dv3_from(s.lights[0].position);
    /* fade_distance = 1e-3 x the light's height (its nearest geometry): residual (D/d)^2. */
    double resid = 1e-6;
    errstat e = {0};
    for (int j = 0; j < img.height; j++)
        for (int i = 0; i < img.width; i++) {
            double want[3] = {0, 0, 0};
            for (int t = 0; t < 2; t++)
                for (int u = 0; u < 2; u++) {
                    dvec3 x;
                    assert_true(
                        cam_hit_plane(&c, i + 0.25 + 0.5 * u, j + 0.25 + 0.5 * t, dv3(0, 0, 0), dv3(0, 1, 0), &x));
                    dvec3 d = dv3_sub(lp, x);
                    double d2 = dv3_dot(d, d), cosl = d.y / sqrt(d2);
                    for (int ch = 0; ch < 3; ch++)
                        want[ch] += 0.25 * chan(albedo, ch) * chan(s.lights[0].intensity, ch) / PI * cosl / d2;
                }
            for (int ch = 0; ch < 3; ch++) {
                float got = img.rgb[ch][j * img.width + i];
                stat_add(&e, got, want[ch]);
                assert_float_equal(got, want[ch], (HALF_TOL + resid) * want[ch]);
            }
        }
    stat_report(&e, "point light 1/d^2 (k=2)");
    povray_image_free(&img);
    mesh_release(&m);
}

/* A smooth spot (POV-Ray tightness 1): rho * smoothstep between the half-angle cones. */
static void test_spot_light(void **state)
{
    (void)state;
    scene s;
    base_scene(&s, 32, 24, v3(0.0f, 3.0f, 1.5f), v3(0.0f, 0.0f, 0.0f), 60.0);
    s.materials[0].d3d.diffuse = v3s(0.6f);
    s.n_lights = 1;
    light *l = &s.lights[0];
    l->kind = LIGHT_SPOT;
    l->position = v3(0.2f, 1.0f, 0.1f);
    l->direction = v3_norm(v3(-0.1f, -1.0f, 0.05f));
    l->intensity = v3s(2.0f);
    l->inner = (float)(40.0 * PI / 180.0);
    l->outer = (float)(90.0 * PI / 180.0);
    mesh m = {0};
    add_plane(&m, v3(0, 0, 0), v3(0, 1, 0), 30.0f, 0);

    povray_image img;
    povray_options o = {0};
    pov_render(&s, &m, &o, "spot_light", &img);
    cam c = cam_make(&s);
    dvec3 lp = dv3_from(l->position), axis = dv3_from(l->direction);
    double ci = cos(0.5 * l->inner), co = cos(0.5 * l->outer);
    errstat e = {0};
    int n_inside = 0, n_edge = 0;
    for (int j = 0; j < img.height; j++)
        for (int i = 0; i < img.width; i++) {
            dvec3 x;
            assert_true(cam_hit_plane(&c, i + 0.5, j + 0.5, dv3(0, 0, 0), dv3(0, 1, 0), &x));
            dvec3 d = dv3_sub(lp, x);
            double d2 = dv3_dot(d, d), cosl = d.y / sqrt(d2);
            double rho = -dv3_dot(axis, d) / sqrt(d2);
            double tt = (rho - co) / (ci - co), spot;
            if (tt <= 0.0)
                spot = 0.0;
            else if (tt >= 1.0)
                spot = rho;
            else
                spot = rho * tt * tt * (3.0 - 2.0 * tt);
            n_inside += tt >= 1.0;
            n_edge += tt > 0.0 && tt < 1.0;
            double want = 0.6 * 2.0 / PI * spot * cosl / d2;
            float got = img.rgb[1][j * img.width + i];
            if (want < 1e-3) {
                /* Outside the cone, or in the edge's last 1e-3 where relative error is
                 * meaningless: at most that value plus a half-float step. */
                assert_true(got < 2e-3);
                continue;
            }
            stat_add(&e, got, want);
            assert_float_equal(got, want, HALF_TOL * want);
        }
    /* The fixture must exercise the full cone and the smooth edge. */
    assert_true(n_inside > 20);
    assert_true(n_edge > 20);
    stat_report(&e, "spot light (smooth)");
    povray_image_free(&img);
    mesh_release(&m);
}

/* Blinn-Phong: `specular Vs roughness 1/P` is Vs * C * (N.H)^P with the local-viewer H, with
 * no N.L factor; the term mask isolates it, and the full render is diffuse + specular. */
static void test_specular(void **state)
{
    (void)state;
    scene s;
    base_scene(&s, 32, 24, v3(0.0f, 2.0f, 3.0f), v3(-0.3f, 0.0f, 1.4f), 60.0);
    material *mat = &s.materials[0];
    mat->d3d.diffuse = v3s(0.4f);
    mat->d3d.specular = v3s(0.7f);
    mat->d3d.power = 20.0f;
    s.n_lights = 1;
    s.lights[0].kind = LIGHT_SUN;
    s.lights[0].direction = v3_norm(v3(0.2f, -1.0f, 0.6f));
    s.lights[0].intensity = v3s(2.5f);
    mesh m = {0};
    add_plane(&m, v3(0, 0, 0), v3(0, 1, 0), 30.0f, 0);
    cam c = cam_make(&s);
    dvec3 L = dv3_scale(dv3_from(s.lights[0].direction), -1.0), N = dv3(0, 1, 0);
    double C = 2.5 / PI;

    const unsigned terms[2] = {POVRAY_TERM_SPECULAR, POVRAY_TERM_ALL};
    for (int ti = 0; ti < 2; ti++) {
        povray_image img;
        povray_options o = {.term = terms[ti]};
        pov_render(&s, &m, &o, ti ? "specular_all" : "specular_only", &img);
        errstat e = {0};
        double peak = 0.0;
        for (int j = 0; j < img.height; j++)
            for (int i = 0; i < img.width; i++) {
                dvec3 x;
                assert_true(cam_hit_plane(&c, i + 0.5, j + 0.5, dv3(0, 0, 0), N, &x));
                dvec3 V = dv3_norm(dv3_sub(c.eye, x)), H = dv3_norm(dv3_add(V, L));
                double spec = 0.7 * C * pow(dv3_dot(N, H), 20.0);
                double want = spec + (ti ? 0.4 * C * dv3_dot(N, L) : 0.0);
                float got = img.rgb[0][j * img.width + i];
                peak = fmax(peak, spec);
                if (ti == 0 && want < 1e-3) {
                    /* Far from the highlight ((N.H)^20 < 2e-3): an absolute check; 1e-6 is
                     * 1e-3 relative of the largest value skipped here. */
                    assert_float_equal(got, want, 1e-6);
                    continue;
                }
                stat_add(&e, got, want);
                assert_float_equal(got, want, HALF_TOL * want);
            }
        /* The highlight must be in the picture, or the test would prove nothing. */
        assert_true(peak > 0.5 * 0.7 * C);
        stat_report(&e, ti ? "diffuse + specular (P = 20)" : "specular term only (P = 20)");
        povray_image_free(&img);
    }
    mesh_release(&m);
}

/* D3D9Client on a tilted plane with a constant environment and a sun: each pixel is
 * Vd (1 - |lambda|) C (N.L) + (lambda + (s - lambda)(R0 + m (1 - N.V)^p)) * env, and
 * pixels that see past the plane show the environment. */
static void test_d3d9client_reflection(void **state)
{
    (void)state;
    scene s;
    base_scene(&s, 40, 30, v3(0.2f, 1.2f, 3.0f), v3(0.0f, 0.0f, 0.0f), 60.0);
    material *mat = &s.materials[0];
    mat->model = MODEL_D3D9CLIENT;
    mat->d3d.diffuse = v3(0.5f, 0.4f, 0.3f);
    mat->d9.reflect = v3(0.2f, 0.1f, 0.05f);
    mat->d9.fresnel_colour = v3(1.0f, 0.9f, 0.8f);
    mat->d9.r0 = 0.04f;
    mat->d9.m = 0.96f;
    mat->d9.p = 3.0f;
    mat->d9.norm = NORM_MAX;
    s.env.kind = ENV_CONSTANT;
    s.env.radiance = v3(0.6f, 0.9f, 1.2f);
    s.n_lights = 1;
    s.lights[0].kind = LIGHT_SUN;
    s.lights[0].direction = v3_norm(v3(0.3f, -1.0f, -0.4f));
    s.lights[0].intensity = v3s(2.0f);
    /* Tilted away from the camera, so the upper rows see past the plane's horizon. */
    vec3 nf = v3_norm(v3(0.2f, 1.0f, -0.3f));
    mesh m = {0};
    add_plane(&m, v3(0, 0, 0), nf, 50.0f, 0);

    povray_image img;
    povray_options o = {0};
    pov_render(&s, &m, &o, "d3d9client_reflection", &img);
    cam c = cam_make(&s);
    dvec3 N = dv3_from(nf), L = dv3_scale(dv3_from(s.lights[0].direction), -1.0);
    double nl = fmax(dv3_dot(N, L), 0.0), keep = 1.0 - 0.2;
    errstat e = {0};
    double cos_lo = 1.0, cos_hi = 0.0;
    int n_sky = 0;
    for (int j = 0; j < img.height; j++)
        for (int i = 0; i < img.width; i++) {
            dvec3 x;
            int hit = cam_hit_plane(&c, i + 0.5, j + 0.5, dv3(0, 0, 0), N, &x);
            double want[3];
            if (!hit) {
                n_sky++;
                for (int ch = 0; ch < 3; ch++)
                    want[ch] = chan(s.env.radiance, ch);
            } else {
                /* Keep away from the quad's far edge (50 m): coverage there is not the point. */
                dvec3 rel = dv3_sub(x, dv3(0, 0, 0));
                if (dv3_len(rel) > 30.0)
                    continue;
                double nv = dv3_dot(N, dv3_norm(dv3_sub(c.eye, x)));
                cos_lo = fmin(cos_lo, nv);
                cos_hi = fmax(cos_hi, nv);
                double R = 0.04 + 0.96 * pow(1.0 - nv, 3.0);
                for (int ch = 0; ch < 3; ch++) {
                    double lam = chan(mat->d9.reflect, ch), sc = chan(mat->d9.fresnel_colour, ch);
                    want[ch] = chan(mat->d3d.diffuse, ch) * keep * 2.0 / PI * nl +
                               (lam + (sc - lam) * R) * chan(s.env.radiance, ch);
                }
            }
            for (int ch = 0; ch < 3; ch++) {
                float got = img.rgb[ch][j * img.width + i];
                stat_add(&e, got, want[ch]);
                if (fabs(got - want[ch]) > HALF_TOL * want[ch])
                    fail_msg("d3d9client: pixel (%d, %d) channel %d (%s) = %g, expected %g", i, j, ch,
                             hit ? "plane" : "sky", (double)got, want[ch]);
            }
        }
    /* The fixture must span a wide range of N.V (the falloff) and show some sky. */
    assert_true(cos_lo < 0.15 && cos_hi > 0.4);
    assert_true(n_sky > 0);
    printf("  N.V range %.3f .. %.3f, %d sky pixels\n", cos_lo, cos_hi, n_sky);
    stat_report(&e, "d3d9client diffuse + reflection (constant env)");
    povray_image_free(&img);

    /* The reflection term alone on a covered pixel: no diffuse, sky still behind. */
    povray_options o2 = {.term = POVRAY_TERM_REFLECTION};
    pov_render(&s, &m, &o2, "d3d9client_reflection_only", &img);
    dvec3 x;
    int pi = 20, pj = 25;
    assert_true(cam_hit_plane(&c, pi + 0.5, pj + 0.5, dv3(0, 0, 0), N, &x));
    double nv = dv3_dot(N, dv3_norm(dv3_sub(c.eye, x)));
    double R = 0.04 + 0.96 * pow(1.0 - nv, 3.0);
    double want = (0.2 + (1.0 - 0.2) * R) * 0.6;
    assert_float_equal(img.rgb[0][pj * img.width + pi], want, HALF_TOL * want);
    povray_image_free(&img);
    mesh_release(&m);
}

/* Physical dielectric (role validate): exact unpolarised Fresnel of the environment. */
static double fresnel_dielectric(double cosi, double n)
{
    double s2 = (1.0 - cosi * cosi) / (n * n), cost = sqrt(1.0 - s2);
    double rs = (cosi - n * cost) / (cosi + n * cost), rp = (n * cosi - cost) / (n * cosi + cost);
    return 0.5 * (rs * rs + rp * rp);
}

static void test_validate_fresnel(void **state)
{
    (void)state;
    scene s;
    base_scene(&s, 32, 24, v3(0.2f, 0.6f, 3.0f), v3(0.0f, 0.0f, 0.0f), 60.0);
    s.materials[0].albedo = v3s(0.0f);
    s.materials[0].ior = 1.5f;
    s.materials[0].roughness = 0.0f; /* POV-Ray's validate reflects the environment in a mirror only */
    s.env.kind = ENV_CONSTANT;
    s.env.radiance = v3(1.0f, 2.0f, 3.0f);
    mesh m = {0};
    vec3 nf = v3_norm(v3(0.2f, 1.0f, 0.3f));
    add_plane(&m, v3(0, 0, 0), nf, 50.0f, 0);
    povray_image img;
    povray_options o = {.role = ROLE_VALIDATE, .term = POVRAY_TERM_REFLECTION};
    pov_render(&s, &m, &o, "validate_fresnel", &img);
    cam c = cam_make(&s);
    dvec3 N = dv3_from(nf);
    errstat e = {0};
    for (int j = 0; j < img.height; j++)
        for (int i = 0; i < img.width; i++) {
            dvec3 x;
            if (!cam_hit_plane(&c, i + 0.5, j + 0.5, dv3(0, 0, 0), N, &x) || dv3_len(x) > 30.0)
                continue;
            double nv = dv3_dot(N, dv3_norm(dv3_sub(c.eye, x)));
            double want = fresnel_dielectric(nv, 1.5) * 2.0;
            float got = img.rgb[1][j * img.width + i];
            stat_add(&e, got, want);
            assert_float_equal(got, want, HALF_TOL * want);
        }
    stat_report(&e, "validate: dielectric Fresnel n = 1.5");
    povray_image_free(&img);
    mesh_release(&m);
}

/* Camera: a small emissive (and ambient-lit) square up and right of centre whose corners lie on pixel
 * boundaries (cols 20..23, rows 5..8 of 32x24) under our projection; every pixel is then
 * either fully inside or outside by half a pixel at its centre. */
static void test_camera_projection(void **state)
{
    (void)state;
    scene s;
    base_scene(&s, 32, 24, v3(0.3f, 0.2f, 4.0f), v3(0.1f, -0.1f, 0.0f), 45.0);
    /* Lit only by Ve + Va*Ia, which POV-Ray gets as emission / pigment. */
    material *mat = &s.materials[0];
    mat->d3d.diffuse = v3(0.5f, 0.25f, 1.0f);
    mat->d3d.emissive = v3(1.0f, 0.5f, 0.25f);
    mat->d3d.ambient = v3s(0.5f);
    s.global_ambient = v3(0.2f, 0.4f, 0.1f);
    const double flat[3] = {1.0 + 0.1, 0.5 + 0.2, 0.25 + 0.05};
    cam c = cam_make(&s);
    const double dist = 3.0;
    const int c0 = 20, c1 = 24, r0 = 5, r1 = 9;
    vec3 corner[4];
    const double px[4] = {c0, c1, c1, c0}, py[4] = {r1, r1, r0, r0};
    for (int q = 0; q < 4; q++)
        corner[q] = v3_from_d(dv3_add(c.eye, dv3_scale(cam_dir(&c, px[q], py[q]), dist)));
    mesh m = {0};
    add_quad(&m, corner, v3_from_d(dv3_scale(c.f, -1.0)), 0);

    povray_image img;
    povray_options o = {0};
    pov_render(&s, &m, &o, "camera", &img);
    int lit = 0;
    for (int j = 0; j < img.height; j++)
        for (int i = 0; i < img.width; i++) {
            int inside = i >= c0 && i < c1 && j >= r0 && j < r1;
            for (int ch = 0; ch < 3; ch++) {
                double want = inside ? flat[ch] : 0.0;
                float got = img.rgb[ch][j * img.width + i];
                if (fabs(got - want) > HALF_TOL * fmax(want, 1e-3))
                    fail_msg("camera: pixel (%d, %d) channel %d = %g, expected %g", i, j, ch, (double)got, want);
            }
            lit += inside;
        }
    assert_int_equal(lit, (c1 - c0) * (r1 - r0));
    povray_image_free(&img);
    mesh_release(&m);
}

/* Image environment seen directly: a 16x8 equirectangular EXR whose R grows linearly with
 * the column (value i + 1 in column i) and G with the row (j + 1, row 0 at the top), so
 * bilinear filtering with texel centres at +0.5 reproduces R = 16 u + 0.5, G = 8 (1 - v) + 0.5
 * exactly, u = 0.5 + atan2(z, x)/(2 pi), v = 0.5 + asin(y)/pi (docs/conventions.md). The camera
 * looks along +x, away from the seam at -x and the poles; the scale 2 multiplies it all. */
static void test_env_image(void **state)
{
    (void)state;
    enum { EW = 16, EH = 8 };
    static float er[EW * EH], eg[EW * EH], eb[EW * EH];
    for (int j = 0; j < EH; j++)
        for (int i = 0; i < EW; i++) {
            er[j * EW + i] = (float)(i + 1);
            eg[j * EW + i] = (float)(j + 1);
            eb[j * EW + i] = 0.5f;
        }
    char envp[300], err[512];
    snprintf(envp, sizeof envp, "%s/env.exr", tmpdir);
    exr_channel ch[3] = {{"R", er}, {"G", eg}, {"B", eb}};
    assert_int_equal(exr_write(envp, EW, EH, ch, 3, NULL, 0, err, sizeof err), RC_OK);

    scene s;
    base_scene(&s, 24, 16, v3(0.0f, 0.0f, 0.0f), v3(1.0f, 0.1f, 0.15f), 50.0);
    s.n_objects = 0;
    s.env.kind = ENV_IMAGE;
    snprintf(s.env.path, sizeof s.env.path, "%s", envp);
    s.env.radiance = v3s(2.0f);
    mesh m = {0};
    povray_image img;
    povray_options o = {0};
    pov_render(&s, &m, &o, "env_image", &img);
    cam c = cam_make(&s);
    errstat e = {0};
    for (int j = 0; j < img.height; j++)
        for (int i = 0; i < img.width; i++) {
            dvec3 d = dv3_norm(cam_dir(&c, i + 0.5, j + 0.5));
            double u = 0.5 + atan2(d.z, d.x) / (2.0 * PI), v = 0.5 + asin(d.y) / PI;
            double want[3] = {2.0 * (EW * u + 0.5), 2.0 * (EH * (1.0 - v) + 0.5), 1.0};
            for (int k = 0; k < 3; k++) {
                float got = img.rgb[k][j * img.width + i];
                stat_add(&e, got, want[k]);
                if (fabs(got - want[k]) > HALF_TOL * want[k])
                    fail_msg("env: pixel (%d, %d) channel %d = %g, expected %g", i, j, k, (double)got, want[k]);
            }
        }
    stat_report(&e, "image environment (orientation, bilinear, scale)");
    povray_image_free(&img);
    unlink(envp);
}

/* An executable shell script at path running body (a stand-in for povray). */
static void write_script(const char *path, const char *body)
{
    FILE *fp = fopen(path, "w");
    assert_non_null(fp);
    fprintf(fp, "#!/bin/sh\n%s", body);
    assert_int_equal(fclose(fp), 0);
    assert_int_equal(chmod(path, 0755), 0);
}

/* A POV-Ray that cannot run is a failed job with a message, not a crash or a stale image;
 * a POV-Ray that reports an error has its error line passed on. Both through the entry. */
static void test_run_failure(void **state)
{
    (void)state;
    scene s;
    base_scene(&s, 8, 8, v3(0, 1, 3), v3(0, 0, 0), 40.0);
    mesh m = {0};
    add_plane(&m, v3(0, 0, 0), v3(0, 1, 0), 1.0f, 0);
    char exr[512], script[600];
    povray_options o = {.povray = "/nonexistent/povray"};
    renderer_result r = pov_entry(&s, &m, &o, "fail", exr, sizeof exr);
    assert_int_not_equal(r.status, RUNNER_OK);
    assert_non_null(strstr(r.message, "povray"));
    assert_int_equal(access(exr, F_OK), -1);
    /* A stand-in povray that prints an error as POV-Ray does and exits 1. */
    snprintf(script, sizeof script, "%s/fakepov.sh", tmpdir);
    write_script(script, "echo 'Parse Error: No matching } in sphere'\nexit 1\n");
    o.povray = script;
    r = pov_entry(&s, &m, &o, "fail2", exr, sizeof exr);
    assert_int_equal(r.status, RUNNER_FAILED);
    assert_non_null(strstr(r.message, "povray failed (exit status 1, scene and coverage passes)"));
    assert_non_null(strstr(r.message, "Parse Error: No matching }"));
    assert_int_equal(access(exr, F_OK), -1);
    unlink(script);
    mesh_release(&m);
}

/* Both passes in one POV-Ray process (povray.h): a stand-in that logs each start and runs the
 * real povray is started once, and the image still has the scene and its coverage. */
static void test_one_process(void **state)
{
    (void)state;
    scene s;
    base_scene(&s, 8, 6, v3(0, 1, 3), v3(0, 0, 0), 40.0);
    mesh m = {0};
    add_plane(&m, v3(0, 0, 0), v3(0, 1, 0), 1.0f, 0);
    char exr[512], script[600], starts[600], err[512] = "";
    snprintf(script, sizeof script, "%s/countpov.sh", tmpdir);
    snprintf(starts, sizeof starts, "%s/countpov.starts", tmpdir);
    unlink(starts);
    char body[700];
    snprintf(body, sizeof body, "echo \"$*\" >> '%s'\nexec povray \"$@\"\n", starts);
    write_script(script, body);
    povray_options o = {.povray = script, .threads = 1};
    renderer_result r = pov_entry(&s, &m, &o, "one", exr, sizeof exr);
    assert_int_equal(r.status, RUNNER_OK);
    char line[1024];
    int n = 0;
    FILE *fp = fopen(starts, "r");
    assert_non_null(fp);
    while (fgets(line, sizeof line, fp) != NULL)
        n++;
    fclose(fp);
    assert_int_equal(n, 1);
    assert_non_null(strstr(line, "+KFI1 +KFF2"));
    exr_image e;
    if (exr_read(exr, &e, err, sizeof err) != RC_OK)
        fail_msg("exr_read(%s): %s", exr, err);
    /* The camera looks down at the plane's centre: the middle pixel is covered (1, object 0),
     * the top row sees the sky above the 1 m plane's far edge (0, object -1). */
    const float *cov = exr_image_channel(&e, "coverage"), *obj = exr_image_channel(&e, "object");
    assert_non_null(cov);
    assert_non_null(obj);
    size_t mid = (size_t)(s.height / 2) * (size_t)s.width + (size_t)(s.width / 2);
    assert_float_equal(cov[mid], 1.0, 1e-3); /* half-float EXR: 2^-11 relative */
    assert_float_equal(obj[mid], 0.0, 0.0);
    assert_float_equal(cov[0], 0.0, 1e-3);
    assert_float_equal(obj[0], -1.0, 0.0);
    exr_image_free(&e);
    unlink(script);
    unlink(starts);
    mesh_release(&m);
}

/* ---- no POV-Ray needed -------------------------------------------------------------- */

static void test_box_downsample(void **state)
{
    (void)state;
    /* 6x4 samples, k = 2 -> 3x2 pixels; each block's mean worked out by hand. */
    const float src[24] = {
        1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 0, 0, 1, 1, -4, 100, 0, 4, 1, 1, 4, 0,
    };
    float dst[6];
    assert_int_equal(povray_box_downsample(src, 6, 4, 2, dst), RC_OK);
    const float want[6] = {4.5f, 6.5f, 8.5f, 1.0f, 1.0f, 25.0f};
    for (int i = 0; i < 6; i++)
        assert_float_equal(dst[i], want[i], 1e-6); /* exact in float; 1e-6 for the compare */
    /* k = 1 is the identity; a non-multiple size and k = 0 are refused. */
    float one[24];
    assert_int_equal(povray_box_downsample(src, 6, 4, 1, one), RC_OK);
    assert_memory_equal(one, src, sizeof src);
    assert_int_equal(povray_box_downsample(src, 6, 4, 4, dst), RC_ERR_RANGE);
    assert_int_equal(povray_box_downsample(src, 6, 4, 0, dst), RC_ERR_RANGE);
    assert_int_equal(povray_box_downsample(src, 5, 4, 2, dst), RC_ERR_RANGE);
}

static void test_command_line(void **state)
{
    (void)state;
    povray_argv cmd;
    char err[256];
    povray_options o = {.threads = 3};
    /* POV-Ray splits its options at spaces and reads quotes itself: such a path is refused,
     * and the render entry hands it plain names in its work folder instead. */
    const char *bad[] = {"/tmp/a b.pov", "/tmp/\xc3\xbc.pov", "-x.pov", "/tmp/a\"b.pov", "/tmp/a'b.pov"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        assert_int_equal(povray_command(&o, bad[i], "/tmp/out.exr", 32, 24, 2, &cmd, err, sizeof err), RC_ERR_IO);
        assert_non_null(strstr(err, "not a plain path"));
    }
    assert_int_equal(povray_command(&o, "a.pov", "/tmp/a b.exr", 32, 24, 2, &cmd, err, sizeof err), RC_ERR_IO);
    assert_int_equal(povray_command(&o, "/tmp/a_b.pov", "/tmp/out.exr", 32, 24, 2, &cmd, err, sizeof err), RC_OK);
    const char *want[] = {"povray",
                          "+I/tmp/a_b.pov",
                          "+O/tmp/out.exr",
                          "+FE",
                          "+W64",
                          "+H48",
                          "-A",
                          "-J",
                          "-UA",
                          "-D",
                          "-V",
                          "-P",
                          "+Q9",
                          "-GS",
                          "-GR",
                          "+WT3"};
    assert_int_equal(cmd.argc, (int)(sizeof want / sizeof want[0]));
    for (int i = 0; i < cmd.argc; i++)
        assert_string_equal(cmd.argv[i], want[i]);
    assert_null(cmd.argv[cmd.argc]);
    char line[512];
    povray_command_string(&cmd, line, sizeof line);
    assert_string_equal(line, "povray +I/tmp/a_b.pov +O/tmp/out.exr +FE +W64 +H48 -A -J -UA -D "
                              "-V -P +Q9 -GS -GR +WT3");
    const char *odd[] = {"blender", "-P", "/a b/it's.py", NULL};
    renderer_command_string(odd, line, sizeof line);
    assert_string_equal(line, "blender -P '/a b/it'\\''s.py'");
    /* Two frames, an animation: the two options last; a tenth frame's name would need two digits. */
    o.frames = 2;
    assert_int_equal(povray_command(&o, "a.pov", "out.exr", 32, 24, 1, &cmd, err, sizeof err), RC_OK);
    assert_string_equal(cmd.argv[cmd.argc - 2], "+KFI1");
    assert_string_equal(cmd.argv[cmd.argc - 1], "+KFF2");
    o.frames = 10;
    assert_int_equal(povray_command(&o, "a.pov", "out.exr", 32, 24, 1, &cmd, err, sizeof err), RC_ERR_RANGE);
    o.frames = 0;
    assert_int_equal(povray_command(&o, "a.pov", "out.png", 32, 24, 1, &cmd, err, sizeof err), RC_ERR_RANGE);
    assert_int_equal(povray_command(&o, "a.pov", "out.exr", 0, 24, 1, &cmd, err, sizeof err), RC_ERR_RANGE);
}

/* What cannot be translated is refused with a message, and nothing claims success. */
static void test_refusals(void **state)
{
    (void)state;
    scene s;
    base_scene(&s, 8, 8, v3(0, 1, 3), v3(0, 0, 0), 40.0);
    mesh m = {0};
    add_plane(&m, v3(0, 0, 0), v3(0, 1, 0), 1.0f, 0);
    char sdl[300], err[512];
    snprintf(sdl, sizeof sdl, "%s/refused.pov", tmpdir);
    povray_options twin = {0}, val = {.role = ROLE_VALIDATE};

    s.materials[0].model = MODEL_COOK_TORRANCE;
    assert_int_equal(povray_write_scene(&s, &m, &twin, sdl, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "cook_torrance"));
    /* A validate renders the scene's physics, not the model: a rough lobe's highlight is
     * refused by name (POV-Ray has no Beckmann lobe), a mirror of the same material is fine. */
    s.n_lights = 1;
    s.lights[0].kind = LIGHT_SUN;
    assert_int_equal(povray_write_scene(&s, &m, &val, sdl, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "specular_lights: all wanted, none rendered"));
    s.materials[0].roughness = 0.0f;
    assert_int_equal(povray_write_scene(&s, &m, &val, sdl, err, sizeof err), RC_OK);
    s.materials[0].roughness = 0.3f;
    s.n_lights = 0;
    s.lights[0].kind = LIGHT_POINT;

    s.materials[0].model = MODEL_D3D;
    s.materials[0].d3d.specular = v3(0.5f, 0.4f, 0.5f);
    s.materials[0].d3d.power = 10.0f;
    assert_int_equal(povray_write_scene(&s, &m, &twin, sdl, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "cannot be twinned"));
    /* Masking the specular term away makes it representable again. */
    povray_options diff = {.term = POVRAY_TERM_DIFFUSE};
    assert_int_equal(povray_write_scene(&s, &m, &diff, sdl, err, sizeof err), RC_OK);
    s.materials[0].d3d.specular = v3s(0.5f);

    s.materials[0].conductor = 1;
    assert_int_equal(povray_write_scene(&s, &m, &val, sdl, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "conductor"));
    s.materials[0].conductor = 0;

    s.n_lights = 1;
    s.lights[0].kind = LIGHT_POINT;
    s.lights[0].position = v3(0, 1, 0);
    s.lights[0].intensity = v3s(1.0f);
    s.lights[0].a1 = 0.5f;
    assert_int_equal(povray_write_scene(&s, &m, &twin, sdl, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "a1"));
    s.lights[0].a1 = 0.0f;
    s.lights[0].profile = SPOT_D3D;
    s.lights[0].kind = LIGHT_SPOT;
    assert_int_equal(povray_write_scene(&s, &m, &twin, sdl, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "profile"));
    unlink(sdl);
    mesh_release(&m);
}

/* The SDL states what docs/conventions.md requires: every finish term, no_shadow/no_reflection,
 * the camera line and the sky_sphere with the rotation and the scale. */
static void test_sdl_text(void **state)
{
    (void)state;
    scene s;
    base_scene(&s, 40, 20, v3(0, 1, 3), v3(0, 0, 0), 40.0);
    s.env.kind = ENV_IMAGE;
    snprintf(s.env.path, sizeof s.env.path, "/data/env.exr");
    s.env.radiance = v3(2.0f, 2.0f, 2.0f);
    mesh m = {0};
    add_plane(&m, v3(0, 0, 0), v3(0, 1, 0), 1.0f, 0);
    char sdl[300], err[512];
    snprintf(sdl, sizeof sdl, "%s/text.pov", tmpdir);
    povray_options o = {0};
    assert_int_equal(povray_write_scene(&s, &m, &o, sdl, err, sizeof err), RC_OK);
    FILE *fp = fopen(sdl, "r");
    assert_non_null(fp);
    static char text[1 << 16];
    size_t n = fread(text, 1, sizeof text - 1, fp);
    text[n] = '\0';
    fclose(fp);
    /* hfov went through float radians: 40 degrees comes back to within 1e-5. */
    const char *ang = strstr(text, "angle ");
    assert_non_null(ang);
    assert_float_equal(atof(ang + 6), 40.0, 1e-5);
    const char *need[] = {"#version 3.7;",
                          "assumed_gamma 1.0 ambient_light 0 adc_bailout 0",
                          "right -x*2\n",
                          "up y\n",
                          "ambient 0",
                          "diffuse 1",
                          "brilliance 1",
                          "specular 0",
                          "phong 0",
                          "reflection 0",
                          "no_shadow",
                          "no_reflection",
                          "map_type 1 interpolate 2 } rotate y*180",
                          "emission rgb <2, 2, 2>",
                          "vertex_vectors { 4",
                          "face_indices { 2"};
    for (size_t i = 0; i < sizeof need / sizeof need[0]; i++)
        if (!strstr(text, need[i]))
            fail_msg("SDL lacks '%s'", need[i]);
    /* A diffuse-only render has no environment behind it (the AOV background is 0). */
    o.term = POVRAY_TERM_DIFFUSE;
    assert_int_equal(povray_write_scene(&s, &m, &o, sdl, err, sizeof err), RC_OK);
    fp = fopen(sdl, "r");
    assert_non_null(fp);
    n = fread(text, 1, sizeof text - 1, fp);
    text[n] = '\0';
    fclose(fp);
    assert_null(strstr(text, "sky_sphere"));
    unlink(sdl);
    mesh_release(&m);
}

static int group_setup(void **state)
{
    (void)state;
    snprintf(tmpdir, sizeof tmpdir, "/tmp/test_povray_XXXXXX");
    return mkdtemp(tmpdir) ? 0 : -1;
}

static int group_teardown(void **state)
{
    (void)state;
    printf("  POV-Ray wall time in all: %.2f s\n", total_seconds);
    if (!getenv("REFLCHECK_KEEP"))
        rmdir(tmpdir);
    else
        printf("  files kept in %s\n", tmpdir);
    return 0;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_box_downsample),
        cmocka_unit_test(test_command_line),
        cmocka_unit_test(test_refusals),
        cmocka_unit_test(test_sdl_text),
        cmocka_unit_test(test_lambert_sun),
        cmocka_unit_test(test_point_light),
        cmocka_unit_test(test_spot_light),
        cmocka_unit_test(test_specular),
        cmocka_unit_test(test_d3d9client_reflection),
        cmocka_unit_test(test_validate_fresnel),
        cmocka_unit_test(test_camera_projection),
        cmocka_unit_test(test_env_image),
        cmocka_unit_test(test_run_failure),
        cmocka_unit_test(test_one_process),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
