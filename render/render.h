/* render.h - the shading loop: a scene's mesh through the rasterizer into linear float layers.
 *
 * Usage:
 *   render_options o = {0};                 zero = all cores, every AOV, scene's own size
 *   render_image img;
 *   render_scene(&scn, &msh, &env, &o, &img, err, sizeof err);
 *   img.chan[RENDER_R][y * img.width + x] ... ; NULL for layers not asked for
 *   render_image_free(&img);
 *   o.reuse_image = 1; render_scene(..., &img, ...) again: the next frame into the same layers
 * The image owns its channel arrays (planar floats, row 0 at the top). Radiance is linear RGB
 * in the scene's radiometric units; each pixel is the box average of its k x k samples.
 * R, G, B = diffuse + specular + reflection + emission, or the environment where no surface is
 * (the background is in no AOV). A = coverage times the model's alpha (D3D9Client eq. 7).
 * Blended objects (a D3D9Client material with `blend`, or render_options.blend) are composited
 * per sample with D3D's SRCALPHA/INVSRCALPHA blend, as a D3D application draws a window pane:
 * the opaque objects first (depth-tested and written), then the blended objects one by one back
 * to front (by the view depth of their vertices' mean), each depth-tested against the opaque
 * depth and never writing depth. Every layer (R, G, B, A and the terms) becomes
 * x a + behind (1 - a), a = render_blend_alpha(the object's alpha); within one blended object
 * only its nearest surface per sample is drawn (a flat or convex pane). object and the angle
 * channels are those of the nearest surface drawn. Without blended objects the frame is
 * bit-identical to one made before blending existed.
 * "object" is the index of the object at the sample nearest the pixel centre, -1 for none;
 * "ndotv", "ndotl" and "ndoth" are N.V, N.L and N.H there, 0 for none: the axes on which the
 * report plots error against angle. L is the first light's direction (the main light: one fixed
 * light, so a pixel's N.L and N.H bins speak of the same lobe), H = (L + V) / |L + V|; without a
 * light, or with L + V = 0, N.L and N.H are 0.
 * "var.R/G/B" bound the variance of each pixel's estimate of its box integral: the sample
 * variance of its k x k samples divided by k^2 (stratified samples do no worse), so that a
 * comparison with a path tracer's pixel integral can tell sampling error from model error.
 * Per-pixel samples are queued per object and shaded SHADE_BATCH at a time through
 * shade_eval_n (one SIMD lane per sample), the background through env_lookup_n.
 * Output is bit-identical for any thread count. Returns RC_OK, RC_ERR_RANGE, RC_ERR_NOMEM.
 * Memory: render_scene first estimates what the frame needs (render_memory_estimate: layers,
 * per-thread buffers, mesh, environment, rasterizer bins) and refuses with RC_ERR_RANGE, before
 * allocating, beyond the limit of core/fileio.h's fileio_memory_limit (half the physical
 * memory, or REFLCHECK_MEMORY_LIMIT, e.g. 8G); the message gives the estimate and the fix.
 *   double bytes; int layers; render_memory_estimate(&scn, &msh, &env, &o, &bytes, &layers);
 * Re-shading a kept frame (a fit's evaluations change material parameters only):
 *   render_keep *k; render_keep_make(&k); o.keep = k;
 *   render_scene(...);                    rendered in full, and what shading needs kept in k
 *   scn.materials[i].d9.p = 3.1; render_scene(...) again: shaded again from k, not rasterized
 *   render_keep_stats ks; render_keep_stats_get(k, &ks);  ks.replayed, ks.why ...
 *   render_keep_free(k);
 * The first frame keeps, per sample and in the order the frame shaded them, each batch's
 * interpolated inputs (x, n, v, texture coordinates) and slots, the background's radiance, and
 * per pixel the coverage count, object and angle channels. A later frame whose key is the same
 * (the mesh's and environment's addresses and sizes, the textures, the size, supersampling,
 * tile, term layers, camera, lights, and per object its sidedness, textured flag, blend flag and
 * D3D normal length) only makes the plans from the materials as they are now, shades the kept
 * batches through them (shade_eval_n), blends the blended objects' batches with their alpha as
 * shaded now, and resolves: every layer bit-identical to a full render_scene of the same
 * parameters, for any thread count. The caller changes materials only (the mesh and the
 * environment are compared by address, not by content). Rendered in full, and not kept
 * (ks.full, ks.why), are frames with an object shaded per vertex (D3D Gouraud: its interpolated
 * terms are the material's) or with D3D vertex colours (each sample's plan is made from them),
 * and frames whose estimate with the keep's bound is over the memory limit; a frame of another
 * key is rendered in full and kept in place of the old one. Blended objects, textures, caller
 * plans (render_options.plans) and users' models are re-shaded. The keep's bound (every sample's
 * inputs, 38 bytes, 46 textured; again per blended layer) is in render_memory_estimate.
 */
#ifndef REFLCHECK_RENDER_H
#define REFLCHECK_RENDER_H

#include <stddef.h>
#include "env.h"
#include "mesh.h"
#include "raster.h"
#include "scene.h"
#include "shade.h"
#include "status.h"
#include "texture.h"

typedef enum {
    RENDER_R,
    RENDER_G,
    RENDER_B,
    RENDER_A,
    RENDER_DIFFUSE_R,
    RENDER_DIFFUSE_G,
    RENDER_DIFFUSE_B,
    RENDER_SPECULAR_R,
    RENDER_SPECULAR_G,
    RENDER_SPECULAR_B,
    RENDER_REFLECTION_R,
    RENDER_REFLECTION_G,
    RENDER_REFLECTION_B,
    RENDER_EMISSION_R,
    RENDER_EMISSION_G,
    RENDER_EMISSION_B,
    RENDER_COVERAGE,
    RENDER_OBJECT,
    RENDER_NDOTV,
    RENDER_NDOTL,
    RENDER_NDOTH,
    RENDER_VAR_R,
    RENDER_VAR_G,
    RENDER_VAR_B,
    RENDER_CHANNELS
} render_channel;

/* Layers beyond R, G, B, A, coverage and object: bits of render_options.aovs. */
enum {
    RENDER_AOV_DIFFUSE = 1,
    RENDER_AOV_SPECULAR = 2,
    RENDER_AOV_REFLECTION = 4,
    RENDER_AOV_EMISSION = 8,
    RENDER_AOV_ALL = 15,
    RENDER_AOV_NONE = 16
};

/* Where a frame's time goes (render_options.profile), in seconds of worker time summed over the
 * workers: the rasterizer's own work (binning, edge functions, coverage; it includes a worker's
 * wait for the others), queueing samples per object, interpolating their attributes, shading
 * them (shade_eval_n), looking up the background, and resolving k x k samples into pixels. */
typedef enum {
    RENDER_STAGE_RASTER,
    RENDER_STAGE_QUEUE,
    RENDER_STAGE_INTERPOLATE,
    RENDER_STAGE_SHADE,
    RENDER_STAGE_BACKGROUND,
    RENDER_STAGE_RESOLVE,
    RENDER_STAGE_COUNT
} render_stage;

typedef struct {
    double seconds[RENDER_STAGE_COUNT];
    double wall; /* the frame's wall time */
    int threads;
} render_profile;

extern const char *const render_stage_names[RENDER_STAGE_COUNT];

/* A kept frame (render_options.keep): render_keep_make, render_keep_free. */
typedef struct render_keep render_keep;
typedef struct {
    int recorded;    /* frames rendered in full and kept */
    int replayed;    /* frames shaded again from the kept one */
    int full;        /* frames rendered in full and not kept */
    const char *why; /* why the last such frame was not kept; "" when none was */
    double bytes;    /* what the kept frame holds */
} render_keep_stats;
rc_status render_keep_make(render_keep **out);
void render_keep_free(render_keep *k);
void render_keep_stats_get(const render_keep *k, render_keep_stats *st);

typedef struct {
    int threads;                 /* 0 = all cores */
    int tile;                    /* 0 = rasterizer default */
    unsigned aovs;               /* 0 = RENDER_AOV_ALL; RENDER_AOV_NONE for beauty only */
    int width, height;           /* 0 = the scene's */
    int supersample;             /* 0 = the scene's */
    int general;                 /* 1 = every object through shade_plan_make_general: the unspecialised
                                    path, for the specialisation benchmark; same output */
    render_profile *profile;     /* NULL = off; else filled with the frame's stage times (a clock read
                                    around each batch: a few per cent slower; same output) */
    const shade_plan *plans;     /* NULL = each object's material through shade_plan_make; else one
                                    plan per object made by the caller (e.g. render/physical.h's
                                    physical model in place of the scene's): shaded per sample,
                                    never per vertex */
    const texture_set *textures; /* the materials' textures (harness/frame.h frame_textures_load);
                                    NULL = none, and then a textured material is refused */
    const unsigned char *blend;  /* NULL = each object's material's d3d9client.blend; else one flag per
                                    object (harness/renderers/exact: its thin sheets) */
    int reuse_image;             /* 1 = out holds an earlier render_scene result (or is zeroed): its
                                    layers of this frame's size are reused (overwritten), as an engine
                                    keeps its framebuffers between frames (first-touch page faults of
                                    fresh layers cost more than the resolve's arithmetic); the others
                                    are freed. 0 = out is overwritten unread. Same output */
    render_keep *keep;           /* NULL = off; else the frame kept there, or shaded again from it when
                                    only materials changed (usage block). Same output */
} render_options;

typedef struct {
    int width, height, supersample;
    float *chan[RENDER_CHANNELS];
    double seconds; /* wall time of render_scene */
    long long shaded_samples;
} render_image;

extern const char *const render_channel_names[RENDER_CHANNELS];

rc_status render_scene(const scene *s, const mesh *m, const env_map *env, const render_options *o, render_image *out,
                       char *err, size_t errlen);
void render_image_free(render_image *img);
/* Bytes render_scene would hold for this frame (env may be NULL), and its layer count. */
void render_memory_estimate(const scene *s, const mesh *m, const env_map *env, const render_options *o, double *bytes,
                            int *layers);

/* The blend unit's source alpha: a clamped to [0, 1] (an alpha above 1 would make 1 - a < 0 and
 * subtract what lies behind, which no fixed-point render target can hold); NaN stays NaN. The
 * colour is not clamped (a float render target). */
float render_blend_alpha(float a);

/* Camera: world point to raster clip coordinates (render/raster.h); and the world ray through a
 * screen point (pixel units, row 0 at the top). Exposed for tests, the translators and the
 * harness's own passes over the same samples (harness/crease.h). */
typedef struct {
    vec3 eye, forward, right, up;
    float tan_half_x, tan_half_y;
    int width, height;
} render_camera;
void render_camera_make(const scene *s, int width, int height, render_camera *c);
vec3 render_camera_ray(const render_camera *c, float sx, float sy);
raster_vertex render_camera_clip(const render_camera *c, vec3 p);

#endif
