/* madvise and MADV_HUGEPAGE (render_layer_alloc) are not POSIX. */
#define _DEFAULT_SOURCE 1

#include "render.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>
#if defined(__SSE2__)
#include <emmintrin.h> /* render_pixel_uniform */
#endif

#include "d3d.h"
#include "fileio.h"
#include "raster.h"
#include "render_keep.h"
#include "shade.h"
#include "smath.h"

const char *const render_stage_names[RENDER_STAGE_COUNT] = {"rasterize", "queue",      "interpolate",
                                                            "shade",     "background", "resolve"};

const char *const render_channel_names[RENDER_CHANNELS] = {
    "R",
    "G",
    "B",
    "A",
    "diffuse.R",
    "diffuse.G",
    "diffuse.B",
    "specular.R",
    "specular.G",
    "specular.B",
    "reflection.R",
    "reflection.G",
    "reflection.B",
    "emission.R",
    "emission.G",
    "emission.B",
    "coverage",
    "object",
    "ndotv",
    "ndotl",
    "ndoth",
    "var.R",
    "var.G",
    "var.B",
};

void render_camera_make(const scene *s, int width, int height, render_camera *c)
{
    c->eye = s->camera.eye;
    c->forward = v3_norm(v3_sub(s->camera.target, s->camera.eye));
    c->right = v3_norm(v3_cross(c->forward, s->camera.up));
    c->up = v3_cross(c->right, c->forward);
    c->tan_half_x = tanf(0.5f * s->camera.hfov);
    c->tan_half_y = c->tan_half_x * (float)height / (float)width;
    c->width = width;
    c->height = height;
}

/* The ray's direction before normalisation: the environment lookup needs no unit vector. */
static vec3 render_camera_dir(const render_camera *c, float sx, float sy)
{
    float nx = 2.0f * sx / (float)c->width - 1.0f;
    float ny = 1.0f - 2.0f * sy / (float)c->height;
    vec3 d = v3_madd(c->forward, c->right, nx * c->tan_half_x);
    return v3_madd(d, c->up, ny * c->tan_half_y);
}

vec3 render_camera_ray(const render_camera *c, float sx, float sy) { return v3_norm(render_camera_dir(c, sx, sy)); }

raster_vertex render_camera_clip(const render_camera *c, vec3 p)
{
    vec3 d = v3_sub(p, c->eye);
    raster_vertex r = {v3_dot(d, c->right) / c->tan_half_x, v3_dot(d, c->up) / c->tan_half_y, v3_dot(d, c->forward)};
    return r;
}

/* Samples shaded per span (a rectangle of a tile's pixels, the whole tile when it fits): a
 * span's per-sample results, batches and queues are a worker's scratch (about 400 KiB), small
 * enough to stay in L2 while the span is shaded. */
#define RENDER_SPAN       4096
/* The widest SIMD vector in floats (AVX-512); SHADE_BATCH is a multiple of it. */
#define RENDER_LANES      16
/* A plane's length in floats: the span plus one cache line, so that the planes do not start
 * 4 KiB apart. At that spacing the stores of a slot's planes all have the same low 12 address
 * bits, and the loads of the next batch's terms stall behind them (4K aliasing): a third of the
 * frame's time when measured. */
#define RENDER_PLANE      (RENDER_SPAN + 16)
/* Pixels the resolve sums at once, one SIMD vector: a fixed trip count, so each plane's sums are
 * whole vectors with no remainder loop; its running sums (up to 19 per pixel) stay in L1. */
#define RENDER_RESOLVE_PX 16

/* n rounded up to whole SIMD vectors: a batch padded so, with copies of a real lane, never
 * runs a lane loop's scalar remainder, and the copies' results are not read. */
static int render_padded(int n) { return (n + RENDER_LANES - 1) / RENDER_LANES * RENDER_LANES; }

/* The per-sample planes of a span: the sample's beauty (its terms' sum, or the background),
 * its alpha, and, only when the image has those layers, the four terms. */
enum {
    RENDER_P_BEAUTY = 0,
    RENDER_P_ALPHA = 3,
    RENDER_P_TERMS = 4, /* diffuse, specular, reflection, emission: R, G, B each */
    RENDER_PLANES = 16
};

/* A batch's triangle vertices, lane by lane: positions then normals of vertices 0, 1, 2, x y z
 * each. RENDER_LANES of slack: a run's fill may write whole vectors past its end. */
typedef struct {
    float v[18][SHADE_BATCH + RENDER_LANES];
} render_vertex_lanes;

/* An object's samples waiting to be shaded: where they are (triangle and barycentrics) and
 * which slot gets the result. */
typedef struct {
    int n;
    int32_t tri[SHADE_BATCH];
    float b1[SHADE_BATCH], b2[SHADE_BATCH];
    uint16_t slot[SHADE_BATCH];
    /* The entries holding a pixel's centre sample (the angle channels come from them), in queue
     * order: the flush visits these only instead of testing every entry's slot. */
    int n_centre;
    uint8_t centre[SHADE_BATCH];
} render_queue;

/* Opaque centre samples waiting for their angle channels: the inputs copied out of the batches
 * as they are shaded (a batch holds about four), so that render_centre_lanes takes the angles of
 * RENDER_CENTRE_BUF pixels as one lane loop instead of one scalar call per pixel. */
#define RENDER_CENTRE_BUF 64
typedef struct {
    int n;
    float x[3][RENDER_CENTRE_BUF], nrm[3][RENDER_CENTRE_BUF], v[3][RENDER_CENTRE_BUF];
    int px[RENDER_CENTRE_BUF]; /* the pixel in the span */
} render_centre_buf;

typedef struct {
    /* Per slot, one plane per quantity. Slots are sample-major, slot = (t k + s) span_px + pixel,
     * so the resolve adds sample (s, t) of a run of pixels as one vector. Background samples
     * leave alpha and the terms at +0 (adding +0 to a sum that starts at +0 changes no bit). */
    float plane[RENDER_PLANES][RENDER_PLANE];
    render_queue queue[SCENE_MAX_OBJECTS]; /* per object: samples waiting for shading */
    shade_batch_in in;
    render_vertex_lanes verts;                    /* the batch's triangle vertices per lane */
    float bg_sx[SHADE_BATCH], bg_sy[SHADE_BATCH]; /* background samples' screen points */
    shade_vec3_n bg_dir, bg_rad;                  /* their rays and the env_lookup_n result */
    uint16_t bg_slot[SHADE_BATCH];
    int bg_n;
    shade_batch_out res;
    shade_vec3_n beauty;                                  /* the batch's per-sample beauty */
    int span_px;                                          /* pixels in the current span */
    int centre_lo, centre_hi;                             /* slots [lo, hi): the sample nearest each pixel centre */
    int covered[RENDER_SPAN];                             /* per pixel: covered samples */
    unsigned char blend_hit[RENDER_SPAN];                 /* per slot: a blended object covers a background sample */
    int object[RENDER_SPAN];                              /* per pixel: object at the centre sample, -1 for none */
    float centre_nv[RENDER_SPAN], centre_nl[RENDER_SPAN]; /* per pixel: N.V, N.L (first light) there */
    float centre_nh[RENDER_SPAN];                         /* per pixel: N.H (first light) there */
    render_centre_buf centre;                             /* opaque centre samples awaiting their angles */
    int profile;                                          /* 1: add stage times below (render_profile) */
    double stage[RENDER_STAGE_COUNT]; /* seconds; [RENDER_STAGE_RASTER] holds the tiles' whole time */
    render_keep_tile *rec;            /* recording a kept frame: the current tile's record; else NULL */
} render_scratch;

/* One blended object's samples over the whole frame (width k by height k, row-major, top row
 * first): what the rasterizer finds of that object alone, with the scene mesh's triangles. */
typedef struct {
    int obj;
    float depth; /* the view depth of its vertices' mean: the back-to-front order */
    raster_sample *samples;
} render_blend_layer;

typedef struct {
    const scene *s;
    const mesh *m; /* the opaque objects' triangles (all of them when nothing is blended) */
    const render_camera *cam;
    const mesh *m_all;                /* the scene's mesh: the blended layers' triangles index it */
    const raster_vertex *clip;        /* per vertex: clip coordinates, w the view depth */
    const render_blend_layer *layers; /* back to front */
    int n_blend;
    shade_context sc;
    const shade_plan *plans;         /* one per object */
    const shade_terms *vertex_terms; /* Gouraud: per vertex, NULL where per-pixel */
    const unsigned char *per_vertex; /* per object */
    const unsigned char *two_sided;  /* per object: turn the normal toward the viewer (d3d.two_sided) */
    /* Per object, D3DRS_NORMALIZENORMALS off: the length D3D's normal has (mesh.h), NULL where
     * the normal stays unit. */
    const mesh_normal_length *const *normal_length;
    const unsigned char *vertex_colours; /* per object: D3D vertex colours take part (bits of mesh.colours) */
    unsigned term_layers;                /* bit a: the image has term a's layers (RENDER_AOV_* order) */
    render_image *out;
    long long *shaded;       /* per worker */
    render_scratch *scratch; /* per worker */
    render_keep *keep;       /* the frame being kept (render_options.keep), or replayed; else NULL */
    int tile, tiles_x;       /* the rasterizer's tile edge and tiles per row: a tile's place in keep */
} render_job;

static double render_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* The clock, read only when the frame is profiled (a read costs ~20 ns; batches are 64 samples). */
static double render_clock(const render_scratch *w) { return w->profile ? render_now() : 0.0; }

static vec3 render_terms_sum(const shade_terms *t)
{
    return v3_add(v3_add(t->diffuse, t->specular), v3_add(t->reflection, t->emission));
}

/* Gouraud: D3D's per-vertex terms blended with the sample's barycentric weights. */
static void render_blend_vertex(const render_job *j, const raster_sample *rs, shade_terms *t)
{
    const uint32_t *tri = j->m->idx + 3 * (size_t)rs->tri;
    const shade_terms *a = &j->vertex_terms[tri[0]], *b = &j->vertex_terms[tri[1]], *c = &j->vertex_terms[tri[2]];
    float b0 = 1.0f - rs->b1 - rs->b2;
#define RENDER_BLEND(f) v3_add(v3_add(v3_scale(a->f, b0), v3_scale(b->f, rs->b1)), v3_scale(c->f, rs->b2))
    t->diffuse = RENDER_BLEND(diffuse);
    t->specular = RENDER_BLEND(specular);
    t->reflection = RENDER_BLEND(reflection);
    t->emission = RENDER_BLEND(emission);
#undef RENDER_BLEND
    t->alpha = a->alpha * b0 + b->alpha * rs->b1 + c->alpha * rs->b2;
    /* D3D applies the texture stage per pixel, after Gouraud interpolation of Dv and Sv. */
    const shade_plan *p = &j->plans[j->m->tri_object[rs->tri]];
    if (p->textured && j->m->uv != NULL) {
        const float *uv = j->m->uv;
        float u = uv[2 * tri[0]] * b0 + uv[2 * tri[1]] * rs->b1 + uv[2 * tri[2]] * rs->b2;
        float v = uv[2 * tri[0] + 1] * b0 + uv[2 * tri[1] + 1] * rs->b1 + uv[2 * tri[2] + 1] * rs->b2;
        shade_texture_apply(p, u, v, t);
    }
}

/* One sample's terms into slot q of the planes. */
static void render_put_terms(const render_job *j, render_scratch *w, int q, const shade_terms *t)
{
    const vec3 b = render_terms_sum(t);
    w->plane[RENDER_P_BEAUTY][q] = b.x;
    w->plane[RENDER_P_BEAUTY + 1][q] = b.y;
    w->plane[RENDER_P_BEAUTY + 2][q] = b.z;
    w->plane[RENDER_P_ALPHA][q] = t->alpha;
    const vec3 v[4] = {t->diffuse, t->specular, t->reflection, t->emission};
    for (int a = 0; a < 4; a++) {
        if (!(j->term_layers & (1u << a)))
            continue;
        w->plane[RENDER_P_TERMS + 3 * a][q] = v[a].x;
        w->plane[RENDER_P_TERMS + 3 * a + 1][q] = v[a].y;
        w->plane[RENDER_P_TERMS + 3 * a + 2][q] = v[a].z;
    }
}

/* A queue's samples, one per SIMD lane: the interpolated world point, the unit normal (facing
 * the viewer when two_sided, as POV-Ray and Cycles shade; as given otherwise, as D3D's fixed
 * function lights; where opposite vertex normals cancel, the face normal, the only direction
 * left) and the unit direction to the viewer.
 * Queued samples come in runs on one triangle (a pixel's k x k samples, then its neighbours),
 * so the vertices are read once per run and broadcast into the lane arrays, instead of
 * gathered per lane (which GCC emulates with a scalar load per element). */
SMATH_CLONES
static void render_interpolate(const mesh *m, vec3 eye, const render_queue *restrict qu, int n,
                               const mesh_normal_length *len, int textured, int two_sided,
                               render_vertex_lanes *restrict vl, shade_batch_in *restrict in)
{
    const float *pos = &m->pos[0].x, *nrm = &m->nrm[0].x;
    const uint32_t *idx = m->idx;
    for (int i = 0; i < n;) {
        const int32_t t = qu->tri[i];
        /* The run's end: whole vectors of RENDER_LANES entries compared at once while they all
         * match (at 10^4 triangles runs are a few pixels' samples, tens of entries), then entry by
         * entry. A vector whose last entry differs is not compared whole: at 10^6 triangles most
         * runs are a sample or two, and the vector compare cost more than it skipped. */
        int e = i + 1;
        for (;;) {
            int differ = e + RENDER_LANES > n || qu->tri[e + RENDER_LANES - 1] != t;
            if (!differ) {
#pragma omp simd reduction(| : differ)
                for (int l = 0; l < RENDER_LANES; l++)
                    differ |= qu->tri[e + l] != t;
            }
            if (differ)
                break;
            e += RENDER_LANES;
        }
        while (e < n && qu->tri[e] == t)
            e++;
        /* Quantity c (positions then normals of vertices 0, 1, 2) is src[c / 3][c % 3]: read
         * straight into the broadcasts, without a copy through the stack. */
        const float *src[6];
        for (int c = 0; c < 3; c++) {
            const size_t vi = 3 * (size_t)idx[3 * (size_t)t + (size_t)c];
            src[c] = pos + vi;
            src[3 + c] = nrm + vi;
        }
        /* Whole vectors of RENDER_LANES from i, each a fixed-length loop (one unaligned store
         * per vector, no loop peeling: most runs are a few samples long, at 10^6 triangles a
         * single one); what lies past e is overwritten by the next run. The 18 quantities are
         * unrolled inside the loop over vectors: a run of at most one vector (nearly all: a
         * pixel's samples, or fewer) makes one pass, and a longer one pays the loop's
         * bookkeeping once per vector rather than once per vector and quantity. */
        for (int l0 = i; l0 < e; l0 += RENDER_LANES) {
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC unroll 18
#endif
            for (int c = 0; c < 18; c++) {
                float *restrict dst = vl->v[c] + l0;
                const float x = src[c / 3][c % 3];
#pragma omp simd
                for (int l = 0; l < RENDER_LANES; l++)
                    dst[l] = x;
            }
        }
        i = e;
    }
#pragma omp simd
    for (int i = 0; i < n; i++) {
        float b1 = qu->b1[i], b2 = qu->b2[i], b0 = 1.0f - b1 - b2;
        vec3 p0 = v3(vl->v[0][i], vl->v[1][i], vl->v[2][i]);
        vec3 p1 = v3(vl->v[3][i], vl->v[4][i], vl->v[5][i]);
        vec3 p2 = v3(vl->v[6][i], vl->v[7][i], vl->v[8][i]);
        vec3 n0 = v3(vl->v[9][i], vl->v[10][i], vl->v[11][i]);
        vec3 n1 = v3(vl->v[12][i], vl->v[13][i], vl->v[14][i]);
        vec3 n2 = v3(vl->v[15][i], vl->v[16][i], vl->v[17][i]);
        vec3 x = v3_add(v3_add(v3_scale(p0, b0), v3_scale(p1, b1)), v3_scale(p2, b2));
        vec3 nn = v3_add(v3_add(v3_scale(n0, b0), v3_scale(n1, b1)), v3_scale(n2, b2));
        vec3 face = v3_cross(v3_sub(p1, p0), v3_sub(p2, p0));
        nn = v3_norm(v3_dot(nn, nn) < 1e-12f ? face : nn);
        vec3 v = v3_norm(v3_sub(eye, x));
        nn = two_sided && v3_dot(nn, v) < 0.0f ? v3_neg(nn) : nn;
        shade_batch_set_input(in, i, x, nn, v);
    }
    /* D3DRS_NORMALIZENORMALS off, per pixel: the unit normal at the sample scaled to the
     * length D3D's vertex stage would give a vertex with that normal (1/|S R^T n|). The D3D
     * lanes take any length: N.L and N.H are clamped to [0, 1] as the source says. A loop of its
     * own: the test inside the loop above kept GCC from vectorising it (twice the time). */
    if (len != NULL) {
        for (int i = 0; i < n; i++) {
            vec3 nn = shade_lane_get(&in->nrm, i);
            shade_lane_set(&in->nrm, i, v3_scale(nn, mesh_normal_length_of(len, nn)));
        }
    }
    /* Texture coordinates only for a textured plan: untextured objects skip the gathers. */
    if (m->uv == NULL || !textured)
        return;
    const float *uv = m->uv;
#pragma omp simd
    for (int i = 0; i < n; i++) {
        int t = qu->tri[i];
        int i0 = 2 * (int)idx[3 * t], i1 = 2 * (int)idx[3 * t + 1], i2 = 2 * (int)idx[3 * t + 2];
        float b1 = qu->b1[i], b2 = qu->b2[i], b0 = 1.0f - b1 - b2;
        in->tu[i] = uv[i0] * b0 + uv[i1] * b1 + uv[i2] * b2;
        in->tv[i] = uv[i0 + 1] * b0 + uv[i1 + 1] * b1 + uv[i2 + 1] * b2;
    }
}

/* The material of object obj with the vertex colours (interpolated with the weights b) in place
 * of the colours its D3D colour sources select. */
static void render_vertex_material(const render_job *j, int obj, const uint32_t *tri, float b0, float b1, float b2,
                                   material *out)
{
    const mesh *m = j->m;
    *out = *j->plans[obj].mat;
    vec3 c1 =
        v3_add(v3_add(v3_scale(m->col1[tri[0]], b0), v3_scale(m->col1[tri[1]], b1)), v3_scale(m->col1[tri[2]], b2));
    vec3 c2 =
        v3_add(v3_add(v3_scale(m->col2[tri[0]], b0), v3_scale(m->col2[tri[1]], b1)), v3_scale(m->col2[tri[2]], b2));
    d3d_vertex_colours(&out->d3d, j->vertex_colours[obj], c1, c2, &out->d3d);
}

/* The plan for a vertex-coloured copy of object obj's material: made for its colours, with the
 * object's textures (which the plan finds by the material's place in the scene, not a copy's). */
static void render_vertex_plan(const render_job *j, int obj, const material *vm, shade_plan *vp)
{
    /* Without textures in the context: shade_plan_make would look the copy up among the scene's
     * materials by address. */
    shade_context sc = j->sc;
    sc.tex = NULL;
    shade_plan_make(&sc, vm, vp);
    for (int k = 0; k < MAT_TEX_SLOTS; k++)
        vp->tex[k] = j->plans[obj].tex[k];
    vp->textured = j->plans[obj].textured;
}

/* Per pixel with vertex colours: each sample's material colours are the vertex colours
 * interpolated at it (our per-pixel form of D3D's Gouraud-interpolated vertex lighting), shaded
 * by the scalar path with a plan made for them. */
static void render_shade_vertex_colours(const render_job *j, int obj, const render_queue *qu, const shade_batch_in *in,
                                        shade_batch_out *out)
{
    for (int i = 0; i < in->n; i++) {
        const uint32_t *tri = j->m->idx + 3 * (size_t)qu->tri[i];
        material vm;
        render_vertex_material(j, obj, tri, 1.0f - qu->b1[i] - qu->b2[i], qu->b1[i], qu->b2[i], &vm);
        shade_plan p;
        render_vertex_plan(j, obj, &vm, &p);
        shade_terms t;
        shade_eval_uv(&j->sc, &p, shade_lane_get(&in->x, i), shade_lane_get(&in->nrm, i), shade_lane_get(&in->v, i),
                      p.textured ? in->tu[i] : 0.0f, p.textured ? in->tv[i] : 0.0f, &t);
        shade_batch_set_terms(out, i, &t);
    }
}

/* The batch's per-sample beauty, (d + s) + (r + e) as render_terms_sum forms it. */
SMATH_CLONES
static void render_batch_beauty(const shade_batch_out *restrict r, int n, shade_vec3_n *restrict b)
{
#pragma omp simd
    for (int i = 0; i < n; i++) {
        b->x[i] = (r->diffuse.x[i] + r->specular.x[i]) + (r->reflection.x[i] + r->emission.x[i]);
        b->y[i] = (r->diffuse.y[i] + r->specular.y[i]) + (r->reflection.y[i] + r->emission.y[i]);
        b->z[i] = (r->diffuse.z[i] + r->specular.z[i]) + (r->reflection.z[i] + r->emission.z[i]);
    }
}

/* Lanes [0, n) of three arrays into slots of three planes: plain stores, as AVX-512 scatters
 * are microcoded and slower than them on some cores (AMD Zen 4). */
static void render_scatter3(float (*restrict plane)[RENDER_PLANE], const float *restrict x, const float *restrict y,
                            const float *restrict z, const uint16_t *restrict slot, int n)
{
    float *restrict px = plane[0], *restrict py = plane[1], *restrict pz = plane[2];
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC unroll 4
#endif
    for (int i = 0; i < n; i++) {
        const int q = slot[i];
        px[q] = x[i];
        py[q] = y[i];
        pz[q] = z[i];
    }
}

/* The beauty and alpha of lanes [0, n) into their slots: one pass, each slot read once, where
 * two passes (render_scatter3, then alpha) read every slot twice. */
static void render_scatter_beauty(float (*restrict plane)[RENDER_PLANE], const shade_vec3_n *restrict b,
                                  const float *restrict alpha, const uint16_t *restrict slot, int n)
{
    float *restrict px = plane[RENDER_P_BEAUTY], *restrict py = plane[RENDER_P_BEAUTY + 1],
                    *restrict pz = plane[RENDER_P_BEAUTY + 2], *restrict pa = plane[RENDER_P_ALPHA];
    /* Unrolled: the loop's own counter, compare and branch were a fifth of its instructions
     * (-O2 does not unroll). */
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC unroll 4
#endif
    for (int i = 0; i < n; i++) {
        const int q = slot[i];
        px[q] = b->x[i];
        py[q] = b->y[i];
        pz[q] = b->z[i];
        pa[q] = alpha[i];
    }
}

/* The angle channels at a pixel's centre sample (x, unit normal nn, v): N.V, N.L and N.H of the
 * first light. The scalar form, for the blended flush and the lanes render_centre_lanes hands
 * back. */
static void render_angles_scalar(const scene *s, vec3 x, vec3 nn, vec3 v, float *nv, float *nl, float *nh)
{
    *nv = v3_dot(nn, v);
    *nl = 0.0f;
    *nh = 0.0f;
    if (s->n_lights > 0) {
        vec3 to_l, e_perp;
        float atten;
        shade_light_incident(&s->lights[0], x, &to_l, &e_perp, &atten);
        *nl = v3_dot(nn, to_l);
        /* L + V vanishes only with the light exactly behind the surface point as seen from
         * the eye: no half vector, and no lobe to bin, so N.H stays 0 (no bin). */
        const vec3 hv = v3_add(to_l, v);
        if (v3_dot(hv, hv) > 1e-12f)
            *nh = v3_dot(nn, v3_norm(hv));
    }
}

/* The unit normal of batch lane i as the angle channels want it (they are cosines). */
static vec3 render_centre_normal(const render_job *j, const render_scratch *w, int obj, int i)
{
    vec3 nn = shade_lane_get(&w->in.nrm, i);
    return j->normal_length[obj] != NULL ? v3_norm(nn) : nn;
}

/* The angle channels of sample i in slot q, the sample nearest its pixel's centre (the blended
 * flush). */
static void render_centre_angles(const render_job *j, render_scratch *w, int obj, int i, int q)
{
    const int px = q - w->centre_lo;
    render_angles_scalar(j->s, shade_lane_get(&w->in.x, i), render_centre_normal(j, w, obj, i),
                         shade_lane_get(&w->in.v, i), &w->centre_nv[px], &w->centre_nl[px], &w->centre_nh[px]);
}

/* render_angles_scalar over the buffer's lanes, the first light's kind a constant (0: none,
 * 1: sun, 2: point or spot; to_sun the sun's unit direction), with the same operations: the
 * point light's direction d / sqrt(d^2) as shade_light_incident takes it inside its float band,
 * H = (L + V) / |L + V| as v3_norm. A lane outside that band (shade_light_incident switches to
 * double there) is marked in far for the scalar form. */
SMATH_INLINE void render_centre_kernel(const light *l, vec3 to_sun, const render_centre_buf *restrict cb,
                                       float *restrict nv, float *restrict nl, float *restrict nh, int *restrict far,
                                       const int kind)
{
    const vec3 pos = l != NULL ? l->position : v3s(0.0f);
    const int n = cb->n;
#pragma omp simd
    for (int i = 0; i < n; i++) {
        const vec3 x = v3(cb->x[0][i], cb->x[1][i], cb->x[2][i]), nn = v3(cb->nrm[0][i], cb->nrm[1][i], cb->nrm[2][i]),
                   v = v3(cb->v[0][i], cb->v[1][i], cb->v[2][i]);
        nv[i] = v3_dot(nn, v);
        vec3 to_l = to_sun;
        int bad = 0;
        if (kind == 2) {
            const vec3 d = v3_sub(pos, x);
            const float d2 = v3_dot(d, d);
            const int safe = (d2 > SHADE_D2_MIN) & (d2 < SHADE_D2_MAX);
            bad = !safe;
            to_l = v3_scale(d, 1.0f / sqrtf(safe ? d2 : 1.0f));
        }
        far[i] = bad;
        const vec3 hv = v3_add(to_l, v);
        const float hh = v3_dot(hv, hv);
        const int half = hh > 1e-12f;
        const float nh_l = v3_dot(nn, v3_scale(hv, 1.0f / sqrtf(half ? hh : 1.0f)));
        nl[i] = kind ? v3_dot(nn, to_l) : 0.0f;
        nh[i] = kind && half ? nh_l : 0.0f;
    }
}

SMATH_CLONES
static void render_centre_lanes(const scene *s, const render_centre_buf *restrict cb, float *restrict nv,
                                float *restrict nl, float *restrict nh, int *restrict far)
{
    const light *l = s->n_lights > 0 ? &s->lights[0] : NULL;
    if (l == NULL)
        render_centre_kernel(l, v3s(0.0f), cb, nv, nl, nh, far, 0);
    else if (l->kind == LIGHT_SUN)
        render_centre_kernel(l, v3_neg(v3_norm(l->direction)), cb, nv, nl, nh, far, 1);
    else
        render_centre_kernel(l, v3s(0.0f), cb, nv, nl, nh, far, 2);
}

/* The buffered centre samples' angle channels into the span's pixels; the buffer emptied. */
static void render_centre_flush(const render_job *j, render_scratch *w)
{
    render_centre_buf *cb = &w->centre;
    float nv[RENDER_CENTRE_BUF], nl[RENDER_CENTRE_BUF], nh[RENDER_CENTRE_BUF];
    int far[RENDER_CENTRE_BUF];
    render_centre_lanes(j->s, cb, nv, nl, nh, far);
    for (int i = 0; i < cb->n; i++) {
        const int px = cb->px[i];
        if (far[i])
            render_angles_scalar(j->s, v3(cb->x[0][i], cb->x[1][i], cb->x[2][i]),
                                 v3(cb->nrm[0][i], cb->nrm[1][i], cb->nrm[2][i]),
                                 v3(cb->v[0][i], cb->v[1][i], cb->v[2][i]), &nv[i], &nl[i], &nh[i]);
        w->centre_nv[px] = nv[i];
        w->centre_nl[px] = nl[i];
        w->centre_nh[px] = nh[i];
    }
    cb->n = 0;
}

/* The opaque queue's centre samples into the buffer (their angles taken when it is full or the
 * span's opaque objects are done). */
static void render_centre_push(const render_job *j, render_scratch *w, int obj, const render_queue *qu)
{
    render_centre_buf *cb = &w->centre;
    for (int e = 0; e < qu->n_centre; e++) {
        if (cb->n == RENDER_CENTRE_BUF)
            render_centre_flush(j, w);
        const int i = qu->centre[e], b = cb->n++;
        const vec3 x = shade_lane_get(&w->in.x, i), nn = render_centre_normal(j, w, obj, i),
                   v = shade_lane_get(&w->in.v, i);
        cb->x[0][b] = x.x, cb->x[1][b] = x.y, cb->x[2][b] = x.z;
        cb->nrm[0][b] = nn.x, cb->nrm[1][b] = nn.y, cb->nrm[2][b] = nn.z;
        cb->v[0][b] = v.x, cb->v[1][b] = v.y, cb->v[2][b] = v.z;
        cb->px[b] = qu->slot[i] - w->centre_lo;
    }
}

/* An object's queued samples (qu->n > 0) padded to the kernels' batch length, interpolated from
 * mesh m (whose triangles the queue indexes), shaded into w->res (per-vertex colours where
 * vertex_colours) and summed into w->beauty; the two stages' times into w->stage. The opaque
 * and the blended flush differ only in what they do with the result. */
static void render_shade_queue(const render_job *j, render_scratch *w, int obj, const mesh *m, int vertex_colours)
{
    render_queue *qu = &w->queue[obj];
    shade_batch_out *r = &w->res;
    const int n = qu->n;
    w->in.n = render_padded(n);
    for (int i = n; i < w->in.n; i++) {
        qu->tri[i] = qu->tri[n - 1];
        qu->b1[i] = qu->b1[n - 1];
        qu->b2[i] = qu->b2[n - 1];
    }
    double t0 = render_clock(w);
    render_interpolate(m, j->cam->eye, qu, w->in.n, j->normal_length[obj], j->plans[obj].textured, j->two_sided[obj],
                       &w->verts, &w->in);
    double t1 = render_clock(w);
    if (vertex_colours)
        render_shade_vertex_colours(j, obj, qu, &w->in, r);
    else
        shade_eval_n(&j->sc, &j->plans[obj], &w->in, r);
    double t2 = render_clock(w);
    w->stage[RENDER_STAGE_INTERPOLATE] += t1 - t0;
    w->stage[RENDER_STAGE_SHADE] += t2 - t1;
    render_batch_beauty(r, w->in.n, &w->beauty);
}

/* A shaded batch's n inputs and slots into the kept tile (render_keep.h: tag BATCH or BLEND). */
static void render_keep_batch(render_keep_tile *t, int tag, int obj, const uint16_t *slot, const shade_batch_in *in,
                              int n, int textured)
{
    const int h[4] = {tag, obj, n, textured};
    const size_t bytes = (size_t)n * sizeof(float);
    render_keep_put(t, h, sizeof h);
    render_keep_put(t, slot, (size_t)n * sizeof *slot);
    const shade_vec3_n *v[3] = {&in->x, &in->nrm, &in->v};
    for (int a = 0; a < 3; a++) {
        render_keep_put(t, v[a]->x, bytes);
        render_keep_put(t, v[a]->y, bytes);
        render_keep_put(t, v[a]->z, bytes);
    }
    if (textured) {
        render_keep_put(t, in->tu, bytes);
        render_keep_put(t, in->tv, bytes);
    }
}

/* The shaded batch's n lanes (w->res, w->beauty) into their slots. */
static void render_scatter_batch(const render_job *j, render_scratch *w, const uint16_t *slot, int n)
{
    const shade_batch_out *r = &w->res;
    render_scatter_beauty(w->plane, &w->beauty, r->alpha, slot, n);
    const shade_vec3_n *term[4] = {&r->diffuse, &r->specular, &r->reflection, &r->emission};
    for (int a = 0; a < 4; a++)
        if (j->term_layers & (1u << a))
            render_scatter3(&w->plane[RENDER_P_TERMS + 3 * a], term[a]->x, term[a]->y, term[a]->z, slot, n);
}

static void render_flush_object(const render_job *j, render_scratch *w, int obj)
{
    render_queue *qu = &w->queue[obj];
    const int n = qu->n;
    if (n == 0)
        return;
    render_shade_queue(j, w, obj, j->m, j->vertex_colours[obj]);
    if (w->rec != NULL)
        render_keep_batch(w->rec, RENDER_KEEP_BATCH, obj, qu->slot, &w->in, n, j->plans[obj].textured);
    render_scatter_batch(j, w, qu->slot, n);
    render_centre_push(j, w, obj, qu);
    qu->n = 0;
    qu->n_centre = 0;
}

/* The camera rays of n background samples (render_camera_dir, lane by lane). */
SMATH_CLONES
static void render_background_rays(const render_camera *c, const float *restrict sx, const float *restrict sy, int n,
                                   shade_vec3_n *restrict dir)
{
    const float w = (float)c->width, h = (float)c->height, tx = c->tan_half_x, ty = c->tan_half_y;
    const vec3 f = c->forward, r = c->right, u = c->up;
#pragma omp simd
    for (int i = 0; i < n; i++) {
        float nx = 2.0f * sx[i] / w - 1.0f;
        float ny = 1.0f - 2.0f * sy[i] / h;
        vec3 d = v3_madd(v3_madd(f, r, nx * tx), u, ny * ty);
        dir->x[i] = d.x;
        dir->y[i] = d.y;
        dir->z[i] = d.z;
    }
}

static void render_flush_background(const render_job *j, render_scratch *w)
{
    if (w->bg_n == 0)
        return;
    const int n = w->bg_n, padded = render_padded(n);
    for (int i = n; i < padded; i++) {
        w->bg_sx[i] = w->bg_sx[n - 1];
        w->bg_sy[i] = w->bg_sy[n - 1];
    }
    double t0 = render_clock(w);
    render_background_rays(j->cam, w->bg_sx, w->bg_sy, padded, &w->bg_dir);
    env_lookup_n(j->sc.env, padded, w->bg_dir.x, w->bg_dir.y, w->bg_dir.z, w->bg_rad.x, w->bg_rad.y, w->bg_rad.z);
    w->stage[RENDER_STAGE_BACKGROUND] += render_clock(w) - t0;
    if (w->rec != NULL) {
        const int h[2] = {RENDER_KEEP_BG, n};
        const size_t bytes = (size_t)n * sizeof(float);
        render_keep_put(w->rec, h, sizeof h);
        render_keep_put(w->rec, w->bg_slot, (size_t)n * sizeof *w->bg_slot);
        render_keep_put(w->rec, w->bg_rad.x, bytes);
        render_keep_put(w->rec, w->bg_rad.y, bytes);
        render_keep_put(w->rec, w->bg_rad.z, bytes);
    }
    render_scatter3(&w->plane[RENDER_P_BEAUTY], w->bg_rad.x, w->bg_rad.y, w->bg_rad.z, w->bg_slot, n);
    w->bg_n = 0;
}

static void render_span_blend(const render_job *j, const raster_tile *tile, render_scratch *w, int py0, int py1,
                              int px0, int px1);

/* A pixel's first sample in the tile's planes (raster_tile.tri, b1, b2); sample (s, t) of the
 * pixel is place t stride + s of each. */
typedef struct {
    const int32_t *tri;
    const float *b1, *b2;
} render_pix;

static render_pix render_pix_at(const raster_tile *tile, int px, int py)
{
    const size_t o =
        (size_t)((py - tile->y0) * tile->k) * (size_t)(tile->w * tile->k) + (size_t)((px - tile->x0) * tile->k);
    return (render_pix){tile->tri + o, tile->b1 + o, tile->b2 + o};
}

/* Where a span's queueing stands: the pixel's place and the object of the last triangle seen. */
typedef struct {
    int k, c, stride, span_px; /* c: the centre sample's row and column in its pixel */
    float offs[16];            /* a sample's offset in its pixel, ((float)s + 0.5f) / (float)k */
    uint16_t slot_off[16];     /* 4 x 4 samples: sample (s, t)'s slot less the pixel's, (t k + s) span_px */
    int last_tri, obj, per_vertex;
    render_queue *qu;
} render_queue_state;

/* The per-pixel queueing is inlined into render_span_queue, whose k is a constant for the usual
 * 4 x 4 samples: the loops over a pixel's samples then unroll (their bookkeeping was a third of
 * the queueing's instructions). */
#if defined(__GNUC__)
#define RENDER_QUEUE_INLINE static inline __attribute__((always_inline))
#else
#define RENDER_QUEUE_INLINE static inline
#endif

/* The object and queue of triangle tri, looked up only when the triangle changes. */
static void render_queue_switch(const render_job *j, render_scratch *w, render_queue_state *qs, int32_t tri)
{
    if (tri == qs->last_tri)
        return;
    qs->last_tri = tri;
    qs->obj = j->m->tri_object[tri];
    qs->per_vertex = j->per_vertex[qs->obj];
    qs->qu = &w->queue[qs->obj];
}

/* One pixel's samples, each to its object's queue or the background's, flushing a queue when it
 * is full; returns the covered count. The general case (edges, per-vertex objects). */
static int render_queue_samples(const render_job *j, render_scratch *w, render_queue_state *qs, render_pix pix, int pi,
                                int px, int py)
{
    const int k = qs->k;
    int covered = 0;
    for (int t = 0; t < k; t++) {
        for (int s = 0; s < k; s++) {
            const size_t o = (size_t)t * (size_t)qs->stride + (size_t)s;
            const raster_sample rs = {pix.tri[o], pix.b1[o], pix.b2[o]};
            const int q = (t * k + s) * qs->span_px + pi;
            const int32_t tri = rs.tri;
            if (tri < 0) {
                const int b = w->bg_n;
                w->bg_sx[b] = (float)px + qs->offs[s];
                w->bg_sy[b] = (float)py + qs->offs[t];
                w->bg_slot[b] = (uint16_t)q;
                w->bg_n = b + 1;
                if (b + 1 == SHADE_BATCH)
                    render_flush_background(j, w);
                continue;
            }
            covered++;
            render_queue_switch(j, w, qs, tri);
            if (qs->per_vertex) {
                shade_terms st;
                render_blend_vertex(j, &rs, &st);
                render_put_terms(j, w, q, &st);
                continue;
            }
            render_queue *qu = qs->qu;
            const int n = qu->n;
            if (t == qs->c && s == qs->c)
                qu->centre[qu->n_centre++] = (uint8_t)n;
            qu->tri[n] = tri;
            qu->b1[n] = rs.b1;
            qu->b2[n] = rs.b2;
            qu->slot[n] = (uint16_t)q;
            qu->n = n + 1;
            if (n + 1 == SHADE_BATCH)
                render_flush_object(j, w, qs->obj);
        }
    }
    return covered;
}

#if defined(__SSE2__)
/* A 4 x 4 pixel's 16 slots, pixel slot pi plus each sample's offset, as two 8-lane 16-bit adds:
 * the scalar path's (uint16_t) of the int sum is the same sum modulo 2^16. */
RENDER_QUEUE_INLINE void render_slots_4x4(uint16_t *dst, const render_queue_state *qs, int pi)
{
    const __m128i pv = _mm_set1_epi16((short)pi);
    for (int h = 0; h < 2; h++)
        _mm_storeu_si128((__m128i *)(dst + 8 * h),
                         _mm_add_epi16(_mm_loadu_si128((const __m128i *)(qs->slot_off + 8 * h)), pv));
}
#endif

/* A pixel whose k x k samples are all of triangle tri, with room for them all in its queue:
 * queued as render_queue_samples would queue them (same order, and the queue fills up at the
 * same sample), the count kept in a register instead of reloaded per sample. */
RENDER_QUEUE_INLINE void render_queue_whole(render_queue *restrict qu, const render_queue_state *qs, render_pix pix,
                                            int pi, int32_t tri, const int k)
{
    int n = qu->n;
    qu->centre[qu->n_centre++] = (uint8_t)(n + qs->c * k + qs->c);
#if defined(__SSE2__)
    /* 4 x 4: each row's four entries as one 16-byte store per array, the slots by
     * render_slots_4x4. */
    if (k == 4) {
        const __m128i tv = _mm_set1_epi32(tri);
        for (int t = 0; t < 4; t++) {
            const size_t o = (size_t)t * (size_t)qs->stride;
            _mm_storeu_si128((__m128i *)(qu->tri + n + 4 * t), tv);
            _mm_storeu_ps(qu->b1 + n + 4 * t, _mm_loadu_ps(pix.b1 + o));
            _mm_storeu_ps(qu->b2 + n + 4 * t, _mm_loadu_ps(pix.b2 + o));
        }
        render_slots_4x4(qu->slot + n, qs, pi);
        qu->n = n + 16;
        return;
    }
#endif
    for (int t = 0; t < k; t++) {
        const size_t o = (size_t)t * (size_t)qs->stride;
        const int q = t * k * qs->span_px + pi;
        for (int s = 0; s < k; s++) {
            qu->tri[n + s] = tri;
            qu->b1[n + s] = pix.b1[o + (size_t)s];
            qu->b2[n + s] = pix.b2[o + (size_t)s];
            qu->slot[n + s] = (uint16_t)(q + s * qs->span_px);
        }
        n += k;
    }
    qu->n = n;
}

/* A pixel no triangle covers, with room for its samples in the background queue. */
RENDER_QUEUE_INLINE void render_queue_background(render_scratch *restrict w, const render_queue_state *qs, int pi,
                                                 int px, int py, const int k)
{
    int b = w->bg_n;
#if defined(__SSE2__)
    /* 4 x 4: a row's four screen points as one vector add (the same single rounding per
     * sample as the scalar sums), the slots as in render_queue_whole. */
    if (k == 4) {
        const __m128 sx = _mm_add_ps(_mm_set1_ps((float)px), _mm_loadu_ps(qs->offs));
        for (int t = 0; t < 4; t++) {
            _mm_storeu_ps(w->bg_sx + b + 4 * t, sx);
            _mm_storeu_ps(w->bg_sy + b + 4 * t, _mm_set1_ps((float)py + qs->offs[t]));
        }
        render_slots_4x4(w->bg_slot + b, qs, pi);
        w->bg_n = b + 16;
        return;
    }
#endif
    for (int t = 0; t < k; t++) {
        const float sy = (float)py + qs->offs[t];
        int q = t * k * qs->span_px + pi;
        for (int s = 0; s < k; s++, b++, q += qs->span_px) {
            w->bg_sx[b] = (float)px + qs->offs[s];
            w->bg_sy[b] = sy;
            w->bg_slot[b] = (uint16_t)q;
        }
    }
    w->bg_n = b;
}

/* 1 when the pixel's k x k triangles (rows stride apart) all equal t0. For 4 x 4 samples, four
 * 16-byte compares: the scalar loop, unrolled, was 16 loads, compares and ands a pixel, about
 * 60 instructions of the queue's ~280 per pixel at 10^4 triangles. */
RENDER_QUEUE_INLINE int render_pixel_uniform(const int32_t *tri, int stride, int32_t t0, const int k)
{
#if defined(__SSE2__)
    if (k == 4) {
        const __m128i want = _mm_set1_epi32(t0);
        __m128i eq = _mm_cmpeq_epi32(_mm_loadu_si128((const __m128i *)tri), want);
        for (int t = 1; t < 4; t++)
            eq = _mm_and_si128(eq, _mm_cmpeq_epi32(_mm_loadu_si128((const __m128i *)(tri + (size_t)t * stride)), want));
        return _mm_movemask_epi8(eq) == 0xffff;
    }
#endif
    int uniform = 1;
    for (int t = 0; t < k; t++)
        for (int s = 0; s < k; s++)
            uniform &= tri[(size_t)t * (size_t)stride + (size_t)s] == t0;
    return uniform;
}

/* One pixel's samples queued; returns the covered count. Most pixels lie wholly inside one
 * triangle or wholly in the background, and take the short paths. */
RENDER_QUEUE_INLINE int render_queue_pixel(const render_job *j, render_scratch *w, render_queue_state *qs,
                                           render_pix pix, int pi, int px, int py, const int k)
{
    const int kk = k * k;
    const int32_t t0 = pix.tri[0];
    const int uniform = render_pixel_uniform(pix.tri, qs->stride, t0, k);
    if (uniform && t0 < 0 && w->bg_n + kk <= SHADE_BATCH) {
        render_queue_background(w, qs, pi, px, py, k);
        if (w->bg_n == SHADE_BATCH)
            render_flush_background(j, w);
        return 0;
    }
    if (uniform && t0 >= 0) {
        render_queue_switch(j, w, qs, t0);
        if (!qs->per_vertex && qs->qu->n + kk <= SHADE_BATCH) {
            render_queue_whole(qs->qu, qs, pix, pi, t0, k);
            if (qs->qu->n == SHADE_BATCH)
                render_flush_object(j, w, qs->obj);
            return kk;
        }
    }
    return render_queue_samples(j, w, qs, pix, pi, px, py);
}

/* Every pixel of the span queued (render_queue_pixel), its angle channels zeroed until its
 * centre sample is shaded and its centre object noted; k = tile->k, a constant where inlined. */
RENDER_QUEUE_INLINE void render_span_queue(const render_job *j, const raster_tile *tile, render_scratch *w,
                                           render_queue_state *qs, int py0, int py1, int px0, int px1, const int k)
{
    const int stride = qs->stride, c = k / 2;
    const int32_t *tri_object = j->m->tri_object;
    for (int py = py0, pi = 0; py < py1; py++)
        for (int px = px0; px < px1; px++, pi++) {
            const render_pix pix = render_pix_at(tile, px, py);
            w->centre_nv[pi] = 0.0f;
            w->centre_nl[pi] = 0.0f;
            w->centre_nh[pi] = 0.0f;
            w->covered[pi] = render_queue_pixel(j, w, qs, pix, pi, px, py, k);
            /* The object at the sample nearest the pixel centre, -1 for the background. */
            const int32_t centre_tri = pix.tri[(size_t)c * (size_t)stride + (size_t)c];
            w->object[pi] = centre_tri < 0 ? -1 : tri_object[centre_tri];
        }
}

/* A span of span_px pixels begun: alpha and the terms cleared (they stay 0 for background
 * samples; the beauty is written for all), the centre samples' slots set. */
static void render_span_begin(const render_job *j, render_scratch *w, int k, int span_px)
{
    const int c = k / 2;
    const size_t n_slots = (size_t)span_px * (size_t)(k * k);
    memset(w->plane[RENDER_P_ALPHA], 0, n_slots * sizeof(float));
    for (int a = 0; a < 4; a++)
        if (j->term_layers & (1u << a))
            for (int ch = 0; ch < 3; ch++)
                memset(w->plane[RENDER_P_TERMS + 3 * a + ch], 0, n_slots * sizeof(float));
    w->span_px = span_px;
    w->centre_lo = (c * k + c) * span_px;
    w->centre_hi = w->centre_lo + span_px;
}

/* Shades every sample of pixels [px0, px1) x [py0, py1) into the scratch planes: per-pixel
 * samples queued per object and shaded a batch at a time, background rays likewise. */
static void render_span_shade(const render_job *j, const raster_tile *tile, render_scratch *w, int py0, int py1,
                              int px0, int px1)
{
    const int k = tile->k, stride = tile->w * k, c = k / 2;
    const int span_w = px1 - px0, span_px = (py1 - py0) * span_w;
    render_span_begin(j, w, k, span_px);
    render_queue_state qs = {.k = k, .c = c, .stride = stride, .span_px = span_px, .last_tri = -1, .qu = &w->queue[0]};
    /* The offsets once per span instead of a division per background sample (same bits). */
    for (int s = 0; s < k; s++)
        qs.offs[s] = ((float)s + 0.5f) / (float)k;
    if (k == 4)
        for (int s = 0; s < 16; s++)
            qs.slot_off[s] = (uint16_t)(s * span_px);
    if (k == 4)
        render_span_queue(j, tile, w, &qs, py0, py1, px0, px1, 4);
    else
        render_span_queue(j, tile, w, &qs, py0, py1, px0, px1, k);
    for (int o = 0; o < j->s->n_objects; o++)
        render_flush_object(j, w, o);
    render_flush_background(j, w);
    /* Before the blended layers: where one covers a centre sample its angles replace these. */
    render_centre_flush(j, w);
    if (j->n_blend > 0)
        render_span_blend(j, tile, w, py0, py1, px0, px1);
}

float render_blend_alpha(float a)
{
    if (isnan(a))
        return a; /* fminf/fmaxf would drop a NaN, which must show in the image */
    return fminf(fmaxf(a, 0.0f), 1.0f);
}

/* The view depth of a sample of triangle tri of m: the world point is linear in the
 * perspective-correct weights, and the view depth w is linear in the world point. */
static float render_sample_depth(const mesh *m, const raster_vertex *clip, int32_t tri, float b1, float b2)
{
    const uint32_t *t = m->idx + 3 * (size_t)tri;
    return clip[t[0]].w * (1.0f - b1 - b2) + clip[t[1]].w * b1 + clip[t[2]].w * b2;
}

/* x a + y (1 - a) into slot q of three planes. */
static void render_blend3(float (*plane)[RENDER_PLANE], int q, float x, float y, float z, float a)
{
    const float b = 1.0f - a;
    plane[0][q] = x * a + plane[0][q] * b;
    plane[1][q] = y * a + plane[1][q] * b;
    plane[2][q] = z * a + plane[2][q] * b;
}

/* A blended object's queued samples: shaded as render_flush_object shades them, then blended
 * over what the slots hold (D3D's SRCALPHA/INVSRCALPHA, the same factors on alpha, as with
 * D3DRS_SEPARATEALPHABLENDENABLE false). */
/* The shaded batch's n lanes of blended object obj over what their slots hold, and its centre
 * samples' angle channels. */
static void render_blend_batch(const render_job *j, render_scratch *w, int obj, const uint16_t *slot, int n)
{
    const shade_batch_out *r = &w->res;
    const shade_vec3_n *term[4] = {&r->diffuse, &r->specular, &r->reflection, &r->emission};
    for (int i = 0; i < n; i++) {
        const int q = slot[i];
        const float a = render_blend_alpha(r->alpha[i]);
        render_blend3(&w->plane[RENDER_P_BEAUTY], q, w->beauty.x[i], w->beauty.y[i], w->beauty.z[i], a);
        w->plane[RENDER_P_ALPHA][q] = a * a + w->plane[RENDER_P_ALPHA][q] * (1.0f - a);
        for (int t = 0; t < 4; t++)
            if (j->term_layers & (1u << t))
                render_blend3(&w->plane[RENDER_P_TERMS + 3 * t], q, term[t]->x[i], term[t]->y[i], term[t]->z[i], a);
        if (q >= w->centre_lo && q < w->centre_hi)
            render_centre_angles(j, w, obj, i, q);
    }
}

static void render_flush_blend(const render_job *j, render_scratch *w, int obj)
{
    render_queue *qu = &w->queue[obj];
    const int n = qu->n;
    if (n == 0)
        return;
    render_shade_queue(j, w, obj, j->m_all, 0);
    if (w->rec != NULL)
        render_keep_batch(w->rec, RENDER_KEEP_BLEND, obj, qu->slot, &w->in, n, j->plans[obj].textured);
    render_blend_batch(j, w, obj, qu->slot, n);
    qu->n = 0;
    qu->n_centre = 0;
}

/* The blended objects over the span's shaded opaque samples, back to front: a sample of a layer
 * is drawn where it lies no farther than the opaque sample (D3DCMP_LESSEQUAL; the background is
 * infinitely far), and writes no depth. */
static void render_span_blend(const render_job *j, const raster_tile *tile, render_scratch *w, int py0, int py1,
                              int px0, int px1)
{
    const int k = tile->k, stride = tile->w * k, c = k / 2;
    const size_t frame_w = (size_t)j->out->width * (size_t)k;
    const int span_w = px1 - px0, span_px = (py1 - py0) * span_w;
    memset(w->blend_hit, 0, (size_t)span_px * (size_t)(k * k));
    for (int l = 0; l < j->n_blend; l++) {
        const int obj = j->layers[l].obj;
        render_queue *qu = &w->queue[obj];
        for (int pi = 0; pi < span_px; pi++) {
            const int py = py0 + pi / span_w, px = px0 + pi % span_w;
            const render_pix pix = render_pix_at(tile, px, py);
            const raster_sample *lay = j->layers[l].samples + (size_t)py * (size_t)k * frame_w + (size_t)px * (size_t)k;
            for (int t = 0; t < k; t++)
                for (int s = 0; s < k; s++) {
                    const raster_sample *bs = &lay[(size_t)t * frame_w + (size_t)s];
                    const size_t o = (size_t)t * (size_t)stride + (size_t)s;
                    const int32_t rt = pix.tri[o];
                    if (bs->tri < 0 || (rt >= 0 && render_sample_depth(j->m_all, j->clip, bs->tri, bs->b1, bs->b2) >
                                                       render_sample_depth(j->m, j->clip, rt, pix.b1[o], pix.b2[o])))
                        continue;
                    const int q = (t * k + s) * span_px + pi;
                    if (rt < 0 && !w->blend_hit[q]) {
                        w->blend_hit[q] = 1;
                        w->covered[pi]++;
                    }
                    if (t == c && s == c)
                        w->object[pi] = obj;
                    qu->tri[qu->n] = bs->tri;
                    qu->b1[qu->n] = bs->b1;
                    qu->b2[qu->n] = bs->b2;
                    qu->slot[qu->n++] = (uint16_t)q;
                    if (qu->n == SHADE_BATCH)
                        render_flush_blend(j, w, obj);
                }
        }
        render_flush_blend(j, w, obj);
    }
}

/* The running sums of the resolve, per pixel: beauty, its square, alpha, then the terms. */
enum { RENDER_S_BEAUTY = 0, RENDER_S_SQ = 3, RENDER_S_ALPHA = 6, RENDER_S_TERMS = 7, RENDER_SUMS = 19 };

/* Sums of the RENDER_RESOLVE_PX pixels from p0 over their k*k samples, in sample order (as the
 * pixel's own loop would add them), one vector per plane. Always the whole width: when fewer
 * pixels are left in the row, the lanes past them sum the next row's slots or the planes'
 * slack (RENDER_PLANE: slot (k*k - 1) span_px + p0 + 15 < RENDER_SPAN + 16), which the store
 * does not read. */
SMATH_CLONES
static void render_resolve_sums(const float (*restrict plane)[RENDER_PLANE], unsigned term_layers, int span_px,
                                int per_px, int p0, float (*restrict sum)[RENDER_RESOLVE_PX])
{
    for (int a = 0; a < RENDER_SUMS; a++)
        for (int i = 0; i < RENDER_RESOLVE_PX; i++)
            sum[a][i] = 0.0f;
    for (int q = 0; q < per_px; q++) {
        const size_t base = (size_t)q * (size_t)span_px + (size_t)p0;
        for (int ch = 0; ch < 3; ch++) {
            const float *restrict b = plane[RENDER_P_BEAUTY + ch] + base;
            float *restrict bs = sum[RENDER_S_BEAUTY + ch], *restrict bq = sum[RENDER_S_SQ + ch];
#pragma omp simd
            for (int i = 0; i < RENDER_RESOLVE_PX; i++) {
                bs[i] += b[i];
                bq[i] += b[i] * b[i];
            }
        }
        {
            const float *restrict a = plane[RENDER_P_ALPHA] + base;
            float *restrict as = sum[RENDER_S_ALPHA];
#pragma omp simd
            for (int i = 0; i < RENDER_RESOLVE_PX; i++)
                as[i] += a[i];
        }
        /* Only the terms the image has: a beauty-only frame (the common case) skips the loop. */
        for (int t = 0; t < 12 && term_layers != 0; t++) {
            if (!(term_layers & (1u << (t / 3))))
                continue;
            const float *restrict src = plane[RENDER_P_TERMS + t] + base;
            float *restrict dst = sum[RENDER_S_TERMS + t];
#pragma omp simd
            for (int i = 0; i < RENDER_RESOLVE_PX; i++)
                dst[i] += src[i];
        }
    }
}

/* max(x, 0) with the bits of glibc's fmaxf(x, 0.0f) for every quiet input (checked over all
 * 2^32 floats: NaN gives +0, -0 stays -0; signalling NaNs differ, and arithmetic never makes
 * one). Written as a select, the loop vectorises; fmaxf itself was a scalar libm call per pixel
 * (its NaN rule is not the SIMD max instruction's). */
static inline float render_clamp0(float x) { return x >= 0.0f ? x : 0.0f; }

/* n pixels from p0, a run within one image row starting at pixel index i0: the layers from the
 * sums. */
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
static inline void
render_resolve_put(render_image *restrict o, const render_scratch *restrict w,
                   const float (*restrict sum)[RENDER_RESOLVE_PX], int k, int p0, int n, size_t i0)
{
    const float inv = 1.0f / (float)(k * k), nk = (float)(k * k);
    /* Unbiased sample variance over nk = k*k samples, divided by nk; 0 for k = 1. */
    const float inv_n = 1.0f / nk, inv_nn = k > 1 ? 1.0f / (nk * (nk - 1.0f)) : 0.0f;
    float *restrict r = o->chan[RENDER_R] + i0, *restrict g = o->chan[RENDER_G] + i0,
                    *restrict b = o->chan[RENDER_B] + i0;
    float *restrict a = o->chan[RENDER_A] + i0, *restrict cov = o->chan[RENDER_COVERAGE] + i0;
    float *restrict obj = o->chan[RENDER_OBJECT] + i0, *restrict nv = o->chan[RENDER_NDOTV] + i0;
    float *restrict nl = o->chan[RENDER_NDOTL] + i0, *restrict nh = o->chan[RENDER_NDOTH] + i0;
    float *restrict vr = o->chan[RENDER_VAR_R] + i0, *restrict vg = o->chan[RENDER_VAR_G] + i0,
                    *restrict vb = o->chan[RENDER_VAR_B] + i0;
    const int *restrict covered = w->covered + p0, *restrict centre_obj = w->object + p0;
    const float *restrict cnv = w->centre_nv + p0, *restrict cnl = w->centre_nl + p0, *restrict cnh = w->centre_nh + p0;
#pragma omp simd
    for (int i = 0; i < n; i++) {
        const float bs_r = sum[RENDER_S_BEAUTY][i], bs_g = sum[RENDER_S_BEAUTY + 1][i],
                    bs_b = sum[RENDER_S_BEAUTY + 2][i];
        r[i] = bs_r * inv;
        g[i] = bs_g * inv;
        b[i] = bs_b * inv;
        a[i] = sum[RENDER_S_ALPHA][i] * inv;
        cov[i] = (float)covered[i] * inv;
        obj[i] = (float)centre_obj[i];
        nv[i] = cnv[i];
        nl[i] = cnl[i];
        nh[i] = cnh[i];
        /* Cancellation can leave a tiny negative: clamp, since a variance is >= 0. */
        vr[i] = render_clamp0((sum[RENDER_S_SQ][i] - bs_r * bs_r * inv_n) * inv_nn);
        vg[i] = render_clamp0((sum[RENDER_S_SQ + 1][i] - bs_g * bs_g * inv_n) * inv_nn);
        vb[i] = render_clamp0((sum[RENDER_S_SQ + 2][i] - bs_b * bs_b * inv_n) * inv_nn);
    }
    for (int t = 0; t < 12; t++) {
        float *restrict dst = o->chan[RENDER_DIFFUSE_R + t];
        if (dst == NULL)
            continue;
        dst += i0;
        const float *restrict src = sum[RENDER_S_TERMS + t];
#pragma omp simd
        for (int i = 0; i < n; i++)
            dst[i] = src[i] * inv;
    }
}

/* A whole vector of pixels (the common case) with the constant width, so its loops have no
 * remainder; a row's last, shorter run with its own n (the lanes past it belong to other pixels,
 * perhaps another worker's). */
SMATH_CLONES
static void render_resolve_store(render_image *restrict o, const render_scratch *restrict w,
                                 const float (*restrict sum)[RENDER_RESOLVE_PX], int k, int p0, int n, size_t i0)
{
    if (n == RENDER_RESOLVE_PX)
        render_resolve_put(o, w, sum, k, p0, RENDER_RESOLVE_PX, i0);
    else
        render_resolve_put(o, w, sum, k, p0, n, i0);
}

/* The span's pixels from the planes: beauty, layers, coverage, object, angles, variance. Each
 * run of pixels lies within one image row, so the layers are written as whole vectors. */
static long long render_resolve(const render_job *j, render_scratch *w, int k, int py0, int px0, int span_w)
{
    render_image *o = j->out;
    const int span_px = w->span_px;
    long long shaded = 0;
    float sum[RENDER_SUMS][RENDER_RESOLVE_PX];
    for (int row = 0; row * span_w < span_px; row++)
        for (int x0 = 0; x0 < span_w; x0 += RENDER_RESOLVE_PX) {
            const int p0 = row * span_w + x0;
            const int n = span_w - x0 < RENDER_RESOLVE_PX ? span_w - x0 : RENDER_RESOLVE_PX;
            render_resolve_sums((const float(*)[RENDER_PLANE])w->plane, j->term_layers, span_px, k * k, p0, sum);
            const size_t i0 = (size_t)(py0 + row) * (size_t)o->width + (size_t)(px0 + x0);
            render_resolve_store(o, w, (const float(*)[RENDER_RESOLVE_PX])sum, k, p0, n, i0);
            for (int i = 0; i < n; i++)
                shaded += w->covered[p0 + i];
        }
    return shaded;
}

/* A tile's spans: pixel rectangles of at most RENDER_SPAN samples, whole rows of the tile when
 * one fits, else parts of one row. */
static void render_tile_spans(int tw, int k, int *cols, int *rows)
{
    const int per_px = k * k;
    *cols = tw * per_px <= RENDER_SPAN ? tw : RENDER_SPAN / per_px;
    *rows = *cols == tw ? RENDER_SPAN / (tw * per_px) : 1;
}

/* The span's per-pixel figures the resolve reads besides the planes, into the kept tile. */
static void render_keep_span_end(render_keep_tile *t, const render_scratch *w)
{
    const int h[2] = {RENDER_KEEP_END, w->span_px};
    const size_t n = (size_t)w->span_px;
    render_keep_put(t, h, sizeof h);
    render_keep_put(t, w->covered, n * sizeof *w->covered);
    render_keep_put(t, w->object, n * sizeof *w->object);
    render_keep_put(t, w->centre_nv, n * sizeof *w->centre_nv);
    render_keep_put(t, w->centre_nl, n * sizeof *w->centre_nl);
    render_keep_put(t, w->centre_nh, n * sizeof *w->centre_nh);
}

/* The kept tile of a raster tile: the keep's tile at its place when the rasterizer's tile is
 * exactly that one (raster.h's default edge, or render_options.tile); else NULL and the keep
 * marked stray, since two workers must never write one record. */
static render_keep_tile *render_keep_tile_of(const render_job *j, const raster_tile *tile)
{
    const int e = j->tile, x0 = tile->x0, y0 = tile->y0;
    const int tw = j->out->width - x0 < e ? j->out->width - x0 : e;
    const int th = j->out->height - y0 < e ? j->out->height - y0 : e;
    if (x0 % e != 0 || y0 % e != 0 || tile->w != tw || tile->h != th) {
        atomic_store(&j->keep->stray, 1);
        return NULL;
    }
    return &j->keep->tiles[y0 / e * j->tiles_x + x0 / e];
}

static void render_tile(void *user, const raster_tile *tile)
{
    const render_job *j = user;
    render_scratch *w = &j->scratch[tile->thread];
    const int k = tile->k;
    int cols, rows;
    render_tile_spans(tile->w, k, &cols, &rows);
    long long shaded = 0;
    const double t_tile = render_clock(w);
    w->rec = j->keep != NULL ? render_keep_tile_of(j, tile) : NULL;

    for (int py0 = tile->y0; py0 < tile->y0 + tile->h; py0 += rows) {
        int py1 = py0 + rows < tile->y0 + tile->h ? py0 + rows : tile->y0 + tile->h;
        for (int px0 = tile->x0; px0 < tile->x0 + tile->w; px0 += cols) {
            int px1 = px0 + cols < tile->x0 + tile->w ? px0 + cols : tile->x0 + tile->w;
            if (w->rec != NULL) {
                const int h[5] = {RENDER_KEEP_SPAN, py0, py1, px0, px1};
                render_keep_put(w->rec, h, sizeof h);
            }
            render_span_shade(j, tile, w, py0, py1, px0, px1);
            if (w->rec != NULL)
                render_keep_span_end(w->rec, w);
            const double t_resolve = render_clock(w);
            shaded += render_resolve(j, w, k, py0, px0, px1 - px0);
            w->stage[RENDER_STAGE_RESOLVE] += render_clock(w) - t_resolve;
        }
    }
    w->stage[RENDER_STAGE_RASTER] += render_clock(w) - t_tile;
    j->shaded[tile->thread] += shaded;
}

/* A kept batch (tag BATCH or BLEND) read back into the scratch, shaded through the object's plan
 * as the materials are now, and put into the planes as the frame that kept it put it. */
static void render_replay_batch(const render_job *j, render_scratch *w, render_keep_reader *r, int tag)
{
    int h[3];
    render_keep_get(r, h, sizeof h);
    const int obj = h[0], n = h[1], textured = h[2];
    uint16_t *slot = w->queue[obj].slot;
    shade_batch_in *in = &w->in;
    float *lane[11] = {in->x.x, in->x.y, in->x.z, in->nrm.x, in->nrm.y, in->nrm.z,
                       in->v.x, in->v.y, in->v.z, in->tu,    in->tv};
    const int n_lanes = textured ? 11 : 9;
    render_keep_get(r, slot, (size_t)n * sizeof *slot);
    for (int a = 0; a < n_lanes; a++)
        render_keep_get(r, lane[a], (size_t)n * sizeof(float));
    /* Padded as render_shade_queue pads: with copies of the last lane, whose results are not read. */
    in->n = render_padded(n);
    for (int a = 0; a < n_lanes; a++)
        for (int i = n; i < in->n; i++)
            lane[a][i] = lane[a][n - 1];
    const double t0 = render_clock(w);
    shade_eval_n(&j->sc, &j->plans[obj], in, &w->res);
    w->stage[RENDER_STAGE_SHADE] += render_clock(w) - t0;
    render_batch_beauty(&w->res, in->n, &w->beauty);
    if (tag == RENDER_KEEP_BATCH)
        render_scatter_batch(j, w, slot, n);
    else
        render_blend_batch(j, w, obj, slot, n);
}

/* One kept tile shaded again on worker: its spans' batches in the kept order, then each span's
 * resolve, as render_tile did it. */
static void render_replay_tile(void *user, int tile, int worker)
{
    const render_job *j = user;
    render_scratch *w = &j->scratch[worker];
    render_keep_reader r = {&j->keep->tiles[tile], 0};
    const int k = j->out->supersample;
    long long shaded = 0;
    const double t_tile = render_clock(w);
    int tag, span[4] = {0}, h = 0;
    while (render_keep_get(&r, &tag, sizeof tag)) {
        if (tag == RENDER_KEEP_SPAN) {
            render_keep_get(&r, span, sizeof span);
            render_span_begin(j, w, k, (span[1] - span[0]) * (span[3] - span[2]));
        } else if (tag == RENDER_KEEP_BG) {
            render_keep_get(&r, &h, sizeof h);
            render_keep_get(&r, w->bg_slot, (size_t)h * sizeof *w->bg_slot);
            render_keep_get(&r, w->bg_rad.x, (size_t)h * sizeof(float));
            render_keep_get(&r, w->bg_rad.y, (size_t)h * sizeof(float));
            render_keep_get(&r, w->bg_rad.z, (size_t)h * sizeof(float));
            render_scatter3(&w->plane[RENDER_P_BEAUTY], w->bg_rad.x, w->bg_rad.y, w->bg_rad.z, w->bg_slot, h);
        } else if (tag == RENDER_KEEP_BATCH || tag == RENDER_KEEP_BLEND) {
            render_replay_batch(j, w, &r, tag);
        } else {
            render_keep_get(&r, &h, sizeof h);
            render_keep_get(&r, w->covered, (size_t)h * sizeof *w->covered);
            render_keep_get(&r, w->object, (size_t)h * sizeof *w->object);
            render_keep_get(&r, w->centre_nv, (size_t)h * sizeof *w->centre_nv);
            render_keep_get(&r, w->centre_nl, (size_t)h * sizeof *w->centre_nl);
            render_keep_get(&r, w->centre_nh, (size_t)h * sizeof *w->centre_nh);
            const double t_resolve = render_clock(w);
            shaded += render_resolve(j, w, k, span[0], span[2], span[3] - span[2]);
            w->stage[RENDER_STAGE_RESOLVE] += render_clock(w) - t_resolve;
        }
    }
    w->stage[RENDER_STAGE_RASTER] += render_clock(w) - t_tile;
    j->shaded[worker] += shaded;
}

/* Whether each object is blended: the caller's flags, else (the scene's own models) its
 * material's d3d9client.blend; a caller's plans without flags blend nothing. Returns the count. */
static int render_blend_flags(const scene *s, const render_options *o, unsigned char *flags)
{
    int n = 0;
    for (int i = 0; i < s->n_objects; i++) {
        const material *mat = &s->materials[s->objects[i].material];
        if (o->blend != NULL)
            flags[i] = o->blend[i] != 0;
        else
            flags[i] = (unsigned char)(o->plans == NULL && mat->model == MODEL_D3D9CLIENT && mat->d9.blend);
        n += flags[i];
    }
    return n;
}

typedef struct {
    raster_sample *dst;
    const int32_t *tri_map; /* the layer's triangle -> the scene mesh's */
    size_t frame_w;
} render_blend_store;

/* A tile of one blended object's own frame into its layer. */
static void render_blend_store_tile(void *user, const raster_tile *tile)
{
    const render_blend_store *b = user;
    const size_t stride = (size_t)tile->w * (size_t)tile->k;
    for (int y = 0; y < tile->h * tile->k; y++) {
        raster_sample *dst =
            b->dst + ((size_t)tile->y0 * (size_t)tile->k + (size_t)y) * b->frame_w + (size_t)tile->x0 * (size_t)tile->k;
        const raster_sample *src = tile->samples + (size_t)y * stride;
        for (size_t x = 0; x < stride; x++) {
            dst[x] = src[x];
            if (src[x].tri >= 0)
                dst[x].tri = b->tri_map[src[x].tri];
        }
    }
}

static int render_layer_cmp(const void *pa, const void *pb)
{
    const render_blend_layer *a = pa, *b = pb;
    if (a->depth != b->depth)
        return a->depth > b->depth ? -1 : 1; /* farther first */
    return a->obj - b->obj;
}

/* One blended object's layer: its triangles alone through the rasterizer. */
static rc_status render_blend_layer_make(const mesh *m, const raster_vertex *rv, const raster_options *ro, int obj,
                                         uint32_t *idx, int32_t *map, render_blend_layer *out)
{
    int n = 0;
    double depth = 0.0;
    for (int t = 0; t < m->n_tris; t++) {
        if (m->tri_object[t] != obj)
            continue;
        for (int c = 0; c < 3; c++) {
            idx[3 * n + c] = m->idx[3 * (size_t)t + (size_t)c];
            depth += rv[idx[3 * n + c]].w;
        }
        map[n++] = t;
    }
    const size_t frame_w = (size_t)ro->width * (size_t)ro->supersample;
    const size_t count = frame_w * (size_t)ro->height * (size_t)ro->supersample;
    out->obj = obj;
    out->depth = n > 0 ? (float)(depth / (3.0 * n)) : 0.0f;
    out->samples = malloc(count * sizeof *out->samples);
    if (out->samples == NULL)
        return RC_ERR_NOMEM;
    for (size_t i = 0; i < count; i++)
        out->samples[i] = (raster_sample){-1, 0.0f, 0.0f}; /* tiles without triangles are not called */
    render_blend_store st = {out->samples, map, frame_w};
    return raster_draw(rv, m->n_verts, idx, n, ro, render_blend_store_tile, &st);
}

/* The opaque mesh (m's arrays with the opaque triangles only, in their order, so depth ties
 * resolve as before) and one layer per blended object, back to front. On error the caller frees
 * what render_blend_free frees. */
static rc_status render_blend_prepare(const mesh *m, const raster_vertex *rv, const raster_options *ro,
                                      const unsigned char *flags, int n_objects, mesh *opaque,
                                      render_blend_layer *layers, int *n_layers)
{
    *opaque = *m;
    opaque->n_tris = 0;
    size_t nt = (size_t)(m->n_tris > 0 ? m->n_tris : 1);
    opaque->idx = malloc(3 * nt * sizeof *opaque->idx);
    opaque->tri_object = malloc(nt * sizeof *opaque->tri_object);
    uint32_t *idx = malloc(3 * nt * sizeof *idx);
    int32_t *map = malloc(nt * sizeof *map);
    rc_status st = opaque->idx && opaque->tri_object && idx && map ? RC_OK : RC_ERR_NOMEM;
    for (int t = 0; st == RC_OK && t < m->n_tris; t++) {
        if (flags[m->tri_object[t]])
            continue;
        memcpy(opaque->idx + 3 * (size_t)opaque->n_tris, m->idx + 3 * (size_t)t, 3 * sizeof *idx);
        opaque->tri_object[opaque->n_tris++] = m->tri_object[t];
    }
    for (int o = 0; st == RC_OK && o < n_objects; o++)
        if (flags[o])
            st = render_blend_layer_make(m, rv, ro, o, idx, map, &layers[(*n_layers)++]);
    free(idx);
    free(map);
    if (st == RC_OK)
        qsort(layers, (size_t)*n_layers, sizeof *layers, render_layer_cmp);
    return st;
}

static void render_blend_free(mesh *opaque, render_blend_layer *layers, int n_layers)
{
    free(opaque->idx);
    free(opaque->tri_object);
    for (int i = 0; i < n_layers; i++)
        free(layers[i].samples);
}

void render_image_free(render_image *img)
{
    for (int c = 0; c < RENDER_CHANNELS; c++) {
        free(img->chan[c]);
        img->chan[c] = NULL;
    }
}

/* Layers from this size up are placed on 2 MiB boundaries and offered to the kernel as huge
 * pages: a fresh 1024^2 layer (4 MiB) then costs 2 page faults instead of 1024, which were a
 * tenth of a one-frame render (reflcheck render) when measured. */
#define RENDER_HUGE_PAGE ((size_t)2 << 20)

/* One layer of n floats, uninitialised: the resolve writes every pixel of every layer. */
static float *render_layer_alloc(size_t n)
{
    const size_t bytes = n * sizeof(float);
    if (bytes < RENDER_HUGE_PAGE)
        return malloc(bytes > 0 ? bytes : 1);
    void *p = NULL;
    if (posix_memalign(&p, RENDER_HUGE_PAGE, bytes) != 0)
        return NULL;
#ifdef MADV_HUGEPAGE
    /* Advice only: where transparent huge pages are off, the layer stays in 4 KiB pages. */
    (void)madvise(p, bytes, MADV_HUGEPAGE);
#endif
    return p;
}

/* The frame's layers into out: prev's of the same size taken (prev is an earlier result, or
 * zeroed), the rest allocated; what prev still holds afterwards is freed. Neither is cleared:
 * the tiles cover the image and the resolve writes every pixel of every layer it has. */
static rc_status render_alloc(render_image *out, render_image *prev, unsigned aovs, char *err, size_t errlen)
{
    size_t n = (size_t)out->width * (size_t)out->height;
    int same = prev->width == out->width && prev->height == out->height;
    rc_status st = RC_OK;
    for (int c = 0; c < RENDER_CHANNELS && st == RC_OK; c++) {
        int a = c - RENDER_DIFFUSE_R;
        if (a >= 0 && c < RENDER_COVERAGE && !(aovs & (1u << (a / 3))))
            continue;
        if (same && prev->chan[c] != NULL) {
            out->chan[c] = prev->chan[c];
            prev->chan[c] = NULL;
            continue;
        }
        out->chan[c] = render_layer_alloc(n);
        if (out->chan[c] == NULL) {
            render_image_free(out);
            snprintf(err, errlen, "render: out of memory for a %dx%d image; render smaller", out->width, out->height);
            st = RC_ERR_NOMEM;
        }
    }
    render_image_free(prev);
    return st;
}

/* Layers render_alloc makes for these AOV bits: the 12 always there, 3 per AOV term. */
static int render_layer_count(unsigned aovs)
{
    int n = RENDER_CHANNELS - 12;
    for (int a = 0; a < 4; a++)
        n += (aovs & (1u << a)) ? 3 : 0;
    return n;
}

static unsigned render_aov_bits(const render_options *o)
{
    return o->aovs == 0 ? RENDER_AOV_ALL : (o->aovs & RENDER_AOV_ALL);
}

/* What a kept frame's bound depends on (render_keep_tile_bound). */
typedef struct {
    int width, height, k, tile, tiles_x, n_objects, n_blend, textured;
} render_keep_shape;

/* The bound of tile t of the frame (user: a render_keep_shape). */
static double render_keep_bound_of(void *user, int t)
{
    const render_keep_shape *sh = user;
    const int x = t % sh->tiles_x * sh->tile, y = t / sh->tiles_x * sh->tile;
    const int tw = sh->width - x < sh->tile ? sh->width - x : sh->tile;
    const int th = sh->height - y < sh->tile ? sh->height - y : sh->tile;
    int cols, rows;
    render_tile_spans(tw, sh->k, &cols, &rows);
    const int spans = ((th + rows - 1) / rows) * ((tw + cols - 1) / cols);
    return render_keep_tile_bound(tw, th, sh->k, spans, sh->n_objects, sh->n_blend, sh->textured);
}

static int render_keep_tiles(const render_keep_shape *sh)
{
    return sh->tiles_x * ((sh->height + sh->tile - 1) / sh->tile);
}

/* A frame's keep shape: its size, the rasterizer's tile (raster.h: 0 = RASTER_TILE_DEFAULT) and objects. */
static void render_keep_shape_make(const scene *s, int width, int height, int k, const render_options *opt, int n_blend,
                                   render_keep_shape *sh)
{
    sh->width = width;
    sh->height = height;
    sh->k = k;
    sh->tile = opt->tile > 0 ? opt->tile : RASTER_TILE_DEFAULT;
    sh->tiles_x = (width + sh->tile - 1) / sh->tile;
    sh->n_objects = s->n_objects;
    sh->n_blend = n_blend;
    sh->textured = opt->textures != NULL;
}

void render_memory_estimate(const scene *s, const mesh *m, const env_map *env, const render_options *opt, double *bytes,
                            int *layers)
{
    static const render_options defaults = {0};
    if (opt == NULL)
        opt = &defaults;
    double w = opt->width > 0 ? opt->width : s->width, h = opt->height > 0 ? opt->height : s->height;
    double k = opt->supersample > 0 ? opt->supersample : s->supersample;
    int n_layers = render_layer_count(render_aov_bits(opt));
    double total = (double)n_layers * w * h * sizeof(float);
    /* Per worker: the shading scratch and the tile's sample, depth and row buffers
     * (the tile edge, RASTER_TILE_DEFAULT by default, times k per axis). */
    raster_options ro = {.threads = opt->threads};
    double tsn = (double)(opt->tile > 0 ? opt->tile : RASTER_TILE_DEFAULT) * k;
    double per_thread =
        sizeof(render_scratch) + tsn * tsn * (sizeof(raster_sample) + sizeof(double)) + 2.0 * tsn * sizeof(double);
    total += raster_thread_count(&ro) * per_thread;
    /* The inputs stay resident: the mesh and the environment's float RGB. */
    double nv = m->n_verts, nt = m->n_tris;
    total += nv * (2.0 * sizeof(vec3) + 2.0 * sizeof(float)) + nt * (3.0 * sizeof(uint32_t) + sizeof(int));
    for (int i = 0; opt->textures != NULL && i < s->n_materials; i++)
        for (int t = 0; t < MAT_TEX_SLOTS; t++)
            total += (double)opt->textures->map[i][t].width * opt->textures->map[i][t].height * 4.0 * sizeof(float);
    if (env != NULL && (env->kind == ENV_IMAGE || env->kind == ENV_CUBE))
        total += (env->kind == ENV_CUBE ? 6.0 : 1.0) * env->width * env->height * 3.0 * sizeof(float);
    /* Projected vertices (and Gouraud terms at most one per vertex); the rasterizer's tile
     * range per triangle and its bins, counting each triangle in one tile (small triangles,
     * the common case; a large one adds 4 bytes per further tile); its chunk bookkeeping is
     * bounded by raster.c's RASTER_MAX_CHUNK_CELLS (1 << 22 cells of 12 bytes). */
    total += nv * (sizeof(raster_vertex) + sizeof(shade_terms));
    total += nt * (4.0 * sizeof(uint16_t) + sizeof(uint32_t));
    double tiles = ceil(w / 16.0) * ceil(h / 16.0);
    total += fmin(tiles * 16.0 * raster_thread_count(&ro), (double)(1 << 22)) * 12.0 + tiles * sizeof(size_t);
    /* Blended objects: a frame of samples each, the opaque triangles' copy and a layer's list. */
    unsigned char blend[SCENE_MAX_OBJECTS];
    int n_blend = render_blend_flags(s, opt, blend);
    if (n_blend > 0)
        total += n_blend * w * k * h * k * sizeof(raster_sample) +
                 nt * (2.0 * 3.0 * sizeof(uint32_t) + sizeof(int) + sizeof(int32_t));
    /* A kept frame: its bound (render_keep.h), held between frames. */
    if (opt->keep != NULL) {
        render_keep_shape sh;
        render_keep_shape_make(s, (int)w, (int)h, (int)k, opt, n_blend, &sh);
        for (int t = 0, n = render_keep_tiles(&sh); t < n; t++)
            total += render_keep_bound_of(&sh, t);
    }
    *bytes = total;
    if (layers != NULL)
        *layers = n_layers;
}

/* Step 1 of a frame: its size, checked against the memory limit, and its layers allocated
 * (reusing PREV's when the caller asked). */
static rc_status render_frame_alloc(const scene *s, const mesh *m, const env_map *env, const render_options *opt,
                                    render_image *out, render_image *prev, char *err, size_t errlen)
{
    out->width = opt->width > 0 ? opt->width : s->width;
    out->height = opt->height > 0 ? opt->height : s->height;
    out->supersample = opt->supersample > 0 ? opt->supersample : s->supersample;
    if (out->width <= 0 || out->height <= 0 || out->supersample <= 0 || out->supersample > 16) {
        snprintf(err, errlen, "%s: image %dx%d with supersample %d; width and height must be > 0, supersample 1..16",
                 s->path, out->width, out->height, out->supersample);
        render_image_free(prev); /* an error leaves out empty, reused or not */
        return RC_ERR_RANGE;
    }
    /* Refuse up front what would not fit, instead of mapping tens of GiB and meeting the
     * kernel's OOM killer halfway through. */
    size_t limit = 0;
    char why[256];
    if (fileio_memory_limit(&limit, why, sizeof why) != RC_OK) {
        snprintf(err, errlen, "%s: %s", s->path, why);
        render_image_free(prev); /* an error leaves out empty, reused or not */
        return RC_ERR_RANGE;
    }
    double need = 0.0;
    int layers = 0;
    render_memory_estimate(s, m, env, opt, &need, &layers);
    if (need > (double)limit) {
        snprintf(err, errlen,
                 "%s: a %dx%d render at supersample %d with %d layers needs about %.2f GiB, over the "
                 "memory limit of %.2f GiB (half the physical memory unless REFLCHECK_MEMORY_LIMIT is set); render "
                 "smaller (--width, --height), with fewer layers (--aovs none) or raise REFLCHECK_MEMORY_LIMIT",
                 s->path, out->width, out->height, out->supersample, layers, need / 1073741824.0,
                 (double)limit / 1073741824.0);
        render_image_free(prev); /* an error leaves out empty, reused or not */
        return RC_ERR_RANGE;
    }
    return render_alloc(out, prev, render_aov_bits(opt), err, errlen);
}

/* Every texture a material names must be loaded, with UVs on the mesh to read it by. */
static rc_status render_textures_check(const scene *s, const mesh *m, const render_options *opt, char *err,
                                       size_t errlen)
{
    for (int i = 0; i < s->n_materials; i++)
        for (int k = 0; k < MAT_TEX_SLOTS; k++)
            if (s->materials[i].texture[k][0] != '\0' &&
                (opt->textures == NULL || opt->textures->map[i][k].width <= 0 || m->uv == NULL)) {
                snprintf(err, errlen,
                         "%s: materials '%s': texture %s is not loaded (or the mesh has no UVs); load it with "
                         "frame_textures_load and pass it in render_options.textures",
                         s->path, s->materials[i].name, s->materials[i].texture[k]);
                return RC_ERR_RANGE;
            }
    return RC_OK;
}

/* Each object's shading: its plan, Gouraud or per sample, sidedness, vertex colours and the
 * unnormalised normal's length (D3D with NORMALIZENORMALS off). */
typedef struct {
    shade_plan plans[SCENE_MAX_OBJECTS];
    mesh_normal_length lengths[SCENE_MAX_OBJECTS];
    const mesh_normal_length *normal_length[SCENE_MAX_OBJECTS];
    unsigned char vertex_colours[SCENE_MAX_OBJECTS];
    unsigned char per_vertex[SCENE_MAX_OBJECTS];
    unsigned char two_sided[SCENE_MAX_OBJECTS];
} render_objects;

/* Step 2: the objects' shading, set into J; 1 when any object is shaded per vertex. */
static int render_objects_make(const render_options *opt, render_objects *ob, render_job *j)
{
    const scene *s = j->s;
    const mesh *m = j->m;
    int any_per_vertex = 0;
    for (int i = 0; i < s->n_objects; i++) {
        const material *mat = &s->materials[s->objects[i].material];
        if (opt->plans != NULL)
            ob->plans[i] = opt->plans[i];
        else if (opt->general)
            shade_plan_make_general(&j->sc, mat, &ob->plans[i]);
        else
            shade_plan_make(&j->sc, mat, &ob->plans[i]);
        /* Gouraud belongs to the D3D model; a caller's plan is another model, shaded per sample. */
        ob->per_vertex[i] = (unsigned char)(opt->plans == NULL && mat->d3d.per_vertex != 0);
        /* One-sided is D3D fixed-function state (scene_file.c refuses it on the shaders). */
        ob->two_sided[i] = (unsigned char)(opt->plans != NULL || mat->model != MODEL_D3D || mat->d3d.two_sided != 0);
        ob->normal_length[i] = NULL;
        ob->vertex_colours[i] = (unsigned char)(opt->plans == NULL && mat->model == MODEL_D3D &&
                                                        d3d_uses_vertex_colours(&mat->d3d, m->colours[i])
                                                    ? m->colours[i]
                                                    : 0);
        if (opt->plans == NULL && mat->model == MODEL_D3D && !mat->d3d.normalize_normals) {
            mesh_normal_length_make(&s->objects[i], &ob->lengths[i]);
            ob->normal_length[i] = &ob->lengths[i];
        }
        any_per_vertex |= ob->per_vertex[i];
    }
    j->plans = ob->plans;
    j->normal_length = ob->normal_length;
    j->vertex_colours = ob->vertex_colours;
    j->per_vertex = ob->per_vertex;
    j->two_sided = ob->two_sided;
    return any_per_vertex;
}

/* Step 3, Gouraud: D3D evaluates the lighting once per vertex (source 003); a vertex shared by
 * objects does not exist, as mesh_build never merges objects. */
static void render_gouraud(render_job *j, const render_camera *cam, shade_terms *vt)
{
    const mesh *m = j->m;
    for (int t = 0; t < m->n_tris; t++) {
        int obj = m->tri_object[t];
        if (!j->per_vertex[obj])
            continue;
        for (int c = 0; c < 3; c++) {
            uint32_t vi = m->idx[3 * (size_t)t + (size_t)c];
            vec3 x = m->pos[vi];
            vec3 v = v3_norm(v3_sub(cam->eye, x));
            vec3 n = m->nrm[vi];
            if (j->two_sided[obj] && v3_dot(n, v) < 0.0f)
                n = v3_neg(n);
            /* D3D per vertex with NORMALIZENORMALS off: exactly its unnormalised normal. */
            if (j->normal_length[obj] != NULL)
                n = v3_scale(n, mesh_normal_length_of(j->normal_length[obj], n));
            /* Per vertex: the lighting only; the texture is applied per sample. */
            if (j->vertex_colours[obj]) {
                /* D3D's own case: the vertex's colours in the lighting of that vertex. */
                uint32_t one[3] = {vi, vi, vi};
                material vm;
                render_vertex_material(j, obj, one, 1.0f, 0.0f, 0.0f, &vm);
                shade_plan vp;
                render_vertex_plan(j, obj, &vm, &vp);
                vp.fn(&j->sc, &vp, x, n, v, &vt[vi]);
            } else {
                j->plans[obj].fn(&j->sc, &j->plans[obj], x, n, v, &vt[vi]);
            }
        }
    }
}

/* Step 5, the profile: per worker, the tiles' time less what the stages inside took is
 * queueing; the workers' share of the draw's wall time outside tiles is the rasterizer's (and
 * waiting). */
static void render_profile_put(render_profile *p, const render_scratch *scratch, int n_threads, double t_draw)
{
    memset(p, 0, sizeof *p);
    double in_tiles = 0.0;
    for (int i = 0; i < n_threads; i++) {
        const double *g = scratch[i].stage;
        in_tiles += g[RENDER_STAGE_RASTER];
        double inner = 0.0;
        for (int k = RENDER_STAGE_INTERPOLATE; k < RENDER_STAGE_COUNT; k++) {
            p->seconds[k] += g[k];
            inner += g[k];
        }
        p->seconds[RENDER_STAGE_QUEUE] += g[RENDER_STAGE_RASTER] - inner;
    }
    p->seconds[RENDER_STAGE_RASTER] = fmax((double)n_threads * t_draw - in_tiles, 0.0);
    p->threads = n_threads;
}

/* Step 4: the blended objects' layers, then the frame's draw. Blended objects are each
 * rasterized alone into their layer first; the frame's own draw then holds the opaque
 * triangles only, and every span blends the layers over them. */
static rc_status render_draw(render_job *j, const render_options *opt, raster_vertex *rv, const raster_options *ro,
                             double *t_draw)
{
    const scene *s = j->s;
    const mesh *m = j->m_all;
    unsigned char blend[SCENE_MAX_OBJECTS];
    render_blend_layer blend_layers[SCENE_MAX_OBJECTS];
    mesh opaque = *m;
    rc_status st = RC_OK;
    int n_layers = 0, any_blend = render_blend_flags(s, opt, blend) > 0;
    if (any_blend)
        st = render_blend_prepare(m, rv, ro, blend, s->n_objects, &opaque, blend_layers, &n_layers);
    j->m = &opaque;
    j->clip = rv;
    j->layers = blend_layers;
    j->n_blend = n_layers;

    /* render_tile reads the tiles' planes only. */
    raster_options planes = *ro;
    planes.planes_only = 1;
    *t_draw = render_now();
    if (st == RC_OK)
        st = raster_draw(rv, m->n_verts, opaque.idx, opaque.n_tris, &planes, render_tile, j);
    *t_draw = render_now() - *t_draw;
    if (any_blend)
        render_blend_free(&opaque, blend_layers, n_layers);
    /* The opaque mesh and the layers were this step's own: J points back at the scene's mesh. */
    j->m = m;
    j->layers = NULL;
    j->n_blend = 0;
    return st;
}

/* The frame's options without the keep when the keep's bound would take it over the memory limit
 * (the frame is then rendered in full and nothing kept; the old keep is dropped, which would not
 * be shaded again); else opt itself. */
static const render_options *render_keep_admit(const scene *s, const mesh *m, const env_map *env,
                                               const render_options *opt, render_options *local)
{
    size_t limit = 0;
    char why[256];
    double need = 0.0;
    if (opt->keep == NULL || fileio_memory_limit(&limit, why, sizeof why) != RC_OK)
        return opt;
    render_memory_estimate(s, m, env, opt, &need, NULL);
    if (need <= (double)limit)
        return opt;
    render_keep_clear(opt->keep);
    opt->keep->stats.full++;
    opt->keep->stats.why = "the frame with the keep's bound is over the memory limit";
    *local = *opt;
    local->keep = NULL;
    return local;
}

/* The key of the frame J is about to render (render_keep.h): all its shading inputs depend on
 * besides the materials' parameters. */
static void render_keep_key_make(const render_job *j, const render_objects *ob, const render_options *opt,
                                 const unsigned char *blend, render_keep_key *key)
{
    const scene *s = j->s;
    const mesh *m = j->m_all;
    render_keep_key_clear(key);
    key->m = m;
    key->pos = m->pos;
    key->nrm = m->nrm;
    key->n_verts = m->n_verts;
    key->n_tris = m->n_tris;
    key->env = j->sc.env;
    key->tex = opt->textures;
    key->width = j->out->width;
    key->height = j->out->height;
    key->k = j->out->supersample;
    key->tile = j->tile;
    key->term_layers = j->term_layers;
    key->eye = s->camera.eye;
    key->target = s->camera.target;
    key->up = s->camera.up;
    key->hfov = s->camera.hfov;
    key->n_lights = s->n_lights;
    memcpy(key->lights, s->lights, (size_t)s->n_lights * sizeof *s->lights);
    key->n_objects = s->n_objects;
    for (int i = 0; i < s->n_objects; i++) {
        key->two_sided[i] = ob->two_sided[i];
        key->textured[i] = (unsigned char)j->plans[i].textured;
        key->blend[i] = blend[i];
        key->has_length[i] = ob->normal_length[i] != NULL;
        if (ob->normal_length[i] != NULL)
            key->length[i] = *ob->normal_length[i];
    }
}

/* What the frame does with opt->keep: nothing (none given, or an object it cannot shade again:
 * Gouraud, whose interpolated terms are the material's, or D3D vertex colours, whose plans are
 * made per sample), shade again from it (same key), or keep the frame (j->keep set, the keep
 * begun: RC_OK; RC_ERR_NOMEM leaves the frame unkept). */
enum { RENDER_KEEP_OFF, RENDER_KEEP_RECORD, RENDER_KEEP_REPLAY };
static int render_keep_mode(render_job *j, const render_objects *ob, const render_options *opt)
{
    render_keep *k = opt->keep;
    if (k == NULL)
        return RENDER_KEEP_OFF;
    const scene *s = j->s;
    for (int i = 0; i < s->n_objects; i++)
        if (ob->per_vertex[i] || ob->vertex_colours[i]) {
            k->stats.full++;
            k->stats.why = "an object is shaded per vertex (D3D Gouraud) or with D3D vertex colours";
            return RENDER_KEEP_OFF;
        }
    unsigned char blend[SCENE_MAX_OBJECTS];
    const int n_blend = render_blend_flags(s, opt, blend);
    render_keep_shape sh;
    render_keep_shape_make(s, j->out->width, j->out->height, j->out->supersample, opt, n_blend, &sh);
    j->tile = sh.tile;
    j->tiles_x = sh.tiles_x;
    render_keep_key key;
    render_keep_key_make(j, ob, opt, blend, &key);
    j->keep = k;
    if (render_keep_matches(k, &key))
        return RENDER_KEEP_REPLAY;
    if (render_keep_begin(k, &key, render_keep_tiles(&sh), render_keep_bound_of, &sh) == RC_OK)
        return RENDER_KEEP_RECORD;
    j->keep = NULL;
    k->stats.full++;
    k->stats.why = "out of memory for the keep";
    return RENDER_KEEP_OFF;
}

/* The kept frame's recording finished (st: the draw's status): counted kept, or not and why. */
static void render_keep_done(render_keep *k, rc_status st)
{
    if (st == RC_OK && render_keep_end(k)) {
        k->stats.recorded++;
        return;
    }
    render_keep_clear(k);
    k->stats.full++;
    k->stats.why = st == RC_OK ? "a tile's record outgrew its bound, or a tile was not the keep's" : "the frame failed";
}

/* A frame's wall time into the image and the profile. */
static void render_scene_done(const render_options *opt, render_image *out, double t0)
{
    out->seconds = render_now() - t0;
    if (opt->profile != NULL)
        opt->profile->wall = out->seconds;
}

/* A kept frame shaded again (render_keep_mode said so): the kept tiles on the frame's workers,
 * no rasterizing. */
static rc_status render_replay(render_job *j, const render_options *opt, int n_threads, char *err, size_t errlen)
{
    long long *shaded = calloc((size_t)n_threads, sizeof *shaded);
    render_scratch *scratch = calloc((size_t)n_threads, sizeof *scratch);
    rc_status st = shaded != NULL && scratch != NULL ? RC_OK : RC_ERR_NOMEM;
    j->shaded = shaded;
    j->scratch = scratch;
    for (int i = 0; st == RC_OK && i < n_threads; i++)
        scratch[i].profile = opt->profile != NULL;
    const double t_draw = render_now();
    if (st == RC_OK)
        st = render_keep_run(n_threads, j->keep->n_tiles, render_replay_tile, j);
    for (int i = 0; st == RC_OK && i < n_threads; i++)
        j->out->shaded_samples += shaded[i];
    if (opt->profile != NULL && st == RC_OK)
        render_profile_put(opt->profile, scratch, n_threads, render_now() - t_draw);
    free(shaded);
    free(scratch);
    if (st != RC_OK) {
        render_image_free(j->out);
        snprintf(err, errlen, "%s: out of memory shading a kept frame again", j->s->path);
        return st;
    }
    j->keep->stats.replayed++;
    return RC_OK;
}

rc_status render_scene(const scene *s, const mesh *m, const env_map *env, const render_options *opt, render_image *out,
                       char *err, size_t errlen)
{
    static const render_options defaults = {0};
    if (opt == NULL)
        opt = &defaults;
    render_options local;
    opt = render_keep_admit(s, m, env, opt, &local);
    double t0 = render_now();
    render_image prev = {0};
    if (opt->reuse_image)
        prev = *out;
    memset(out, 0, sizeof *out);
    rc_status st = render_frame_alloc(s, m, env, opt, out, &prev, err, errlen);
    if (st != RC_OK)
        return st;

    render_camera cam;
    render_camera_make(s, out->width, out->height, &cam);
    render_job j = {.s = s, .m = m, .m_all = m, .cam = &cam, .out = out};
    for (int a = 0; a < 4; a++)
        if (out->chan[RENDER_DIFFUSE_R + 3 * a] != NULL)
            j.term_layers |= 1u << a;
    shade_context_make(s, env, &j.sc);
    j.sc.tex = opt->textures;
    if ((st = render_textures_check(s, m, opt, err, errlen)) != RC_OK) {
        render_image_free(out);
        return st;
    }
    render_objects ob = {0};
    int any_per_vertex = render_objects_make(opt, &ob, &j);
    const int keep_mode = render_keep_mode(&j, &ob, opt);

    raster_options ro = {.width = out->width,
                         .height = out->height,
                         .supersample = out->supersample,
                         .threads = opt->threads,
                         .tile = opt->tile};
    const int n_threads = raster_thread_count(&ro);
    if (keep_mode == RENDER_KEEP_REPLAY) {
        if ((st = render_replay(&j, opt, n_threads, err, errlen)) == RC_OK)
            render_scene_done(opt, out, t0);
        return st;
    }
    /* Only a frame that is rasterized needs its vertices in clip space (and Gouraud terms). */
    raster_vertex *rv = malloc((size_t)(m->n_verts > 0 ? m->n_verts : 1) * sizeof *rv);
    shade_terms *vt = any_per_vertex ? malloc((size_t)m->n_verts * sizeof *vt) : NULL;
    long long *shaded = calloc((size_t)n_threads, sizeof *shaded);
    render_scratch *scratch = calloc((size_t)n_threads, sizeof *scratch);
    if (rv == NULL || (any_per_vertex && vt == NULL) || shaded == NULL || scratch == NULL) {
        free(rv);
        free(vt);
        free(shaded);
        free(scratch);
        render_image_free(out);
        snprintf(err, errlen, "render: out of memory for %d vertices", m->n_verts);
        return RC_ERR_NOMEM;
    }
    for (int i = 0; i < m->n_verts; i++)
        rv[i] = render_camera_clip(&cam, m->pos[i]);
    if (any_per_vertex)
        render_gouraud(&j, &cam, vt);
    j.vertex_terms = vt;
    j.shaded = shaded;
    j.scratch = scratch;
    for (int i = 0; i < n_threads; i++)
        scratch[i].profile = opt->profile != NULL;

    double t_draw = 0.0;
    st = render_draw(&j, opt, rv, &ro, &t_draw);
    if (keep_mode == RENDER_KEEP_RECORD)
        render_keep_done(j.keep, st);
    for (int i = 0; i < n_threads; i++)
        out->shaded_samples += shaded[i];
    if (opt->profile != NULL && st == RC_OK)
        render_profile_put(opt->profile, scratch, n_threads, t_draw);
    free(rv);
    free(vt);
    free(shaded);
    free(scratch);
    if (st != RC_OK) {
        render_image_free(out);
        snprintf(err, errlen, "%s: the rasterizer refused the frame (status %d)", s->path, (int)st);
        return st;
    }
    render_scene_done(opt, out, t0);
    return RC_OK;
}
