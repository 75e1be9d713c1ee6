/* cycles.h - a reflcheck scene as a Blender 3.4 Cycles render (cycles_render.py, beside this
 * file), and the render entry of the renderer table (harness/renderers/registry.h).
 *
 * Usage:
 *   cycles_options o = {.n_seeds = 2};                            zero = defaults (below)
 *   renderer_job j = {.s = &scn, .m = &msh, .role = ROLE_TWIN, .dir = "work", .exr = "out.exr",
 *                     .log = "out.log", .options = &o};
 *   renderer_result r = {0};
 *   cycles_render_job(&j, &r);        job.json, blender, collect: what production runs too
 * The pieces: cycles_write_job, cycles_command (argv), cycles_collect (raw seed files -> out.exr).
 *
 * The job (JSON) holds the image size, samples, seeds, the camera in the canonical frame,
 * lights converted to Cycles units (point/spot energy P = 4 pi I, sun strength E), the
 * environment, every object's triangles with the per-vertex normals of `msh` (the mesh our
 * rasterizer draws), and one material recipe per scene material for the role:
 *   twin:     the model's own terms (Lambert -> Diffuse BSDF Vd; Cook-Torrance with
 *             G = smith_walter, F = one -> Glossy 'BECKMANN' roughness sqrt(m) colour ks;
 *             D3D9Client reflection -> Glossy 'SHARP' coloured lambda + (s - lambda) R;
 *             Cook-Torrance reflection env(reflect(-V, N)) * Fr(N.V) -> Glossy 'SHARP'
 *             coloured by Fr, Schlick(F0, N.V) as authored).
 *             What Cycles cannot reproduce (Blinn-Phong specular, ambient, per-vertex
 *             shading, clamping, D3D attenuation or spot profile) is an RC_ERR_RANGE error
 *             naming the fix, unless it is a whole term (the Blinn-Phong specular, a Cook-
 *             Torrance lobe without Cycles' switches or beside its own environment term,
 *             which it would see) and options.partial is set: then the term is left out,
 *             listed in the job's "missing" and in options.left_out.
 *   validate, agree (the same render): the scene's physics (model/scene.h) as cycles_physics
 *             says it renders it, refused (RC_ERR_RANGE naming the fields) where the scene
 *             asks otherwise: Lambert albedo (times 1 - F_dielectric(N.V) under diffuse_weight
 *             one_minus_f; conductors none) + Glossy 'BECKMANN' sqrt(roughness) (SHARP at 0)
 *             coloured by the Fresnel form asked, of N.V: on a rough lobe exact is rendered as
 *             nv, the F(N.V) tint (a bias), and per-microfacet Schlick is refused; each lamp
 *             reaches the diffuse and glossy closures its masks say (light ray visibility), the
 *             world those env_diffuse and env_specular say; shadows, inter-reflection and
 *             bounces as asked.
 * Sample positions: by default Cycles jitters its samples over the whole pixel (box filter of
 * width 1), a pixel integral. With options.supersample = k > 1 (cycles_render_job sets the
 * scene's k for a twin) it renders k times the size with a 0.01 sub-pixel Gaussian, so each
 * sub-pixel's samples sit at the model's sample position (i + (s + 0.5)/k, j + (t + 0.5)/k),
 * ceil(samples / k^2) of them, and cycles_collect averages each k x k block: a twin then
 * computes the model's own pixel, the mean of k x k point samples, where an integral and k x k
 * points part (a hard edge or a texture's detail inside a pixel).
 * Noise: a mirror beside a non-zero diffuse closure carries closure-selection noise (Cycles
 * picks one closure per bounce); the "var." channels measure it.
 *
 * cycles_collect writes out.exr (32-bit float) with reflcheck's channel names: R G B A,
 * diffuse.RGB, specular.RGB, reflection.RGB, emission.RGB, background.RGB (the environment
 * seen by camera rays, in no other layer), coverage, object (-1 = background, taken from
 * Cycles' first sample, not the pixel centre). With n_seeds >= 2 every channel is the mean
 * over the seeds and "var.<channel>" holds the estimated variance of that mean
 * (sample variance over seeds / n_seeds). The raw per-seed files OUT.cyc<i>.exr and
 * OUT.timing.json stay beside out.exr unless options.keep_raw is 0 and collection succeeds
 * (then they are removed).
 *
 * All functions return RC_OK or an rc_status with a one-line message in err.
 * Units: lengths in scene units, angles in radians, radiance in the scene's radiometric units.
 */
#ifndef REFLCHECK_CYCLES_H
#define REFLCHECK_CYCLES_H

#include <stddef.h>
#include "mesh.h"
#include "scene.h"
#include "status.h"
#include "../renderer.h"

typedef struct {
    comparison_role role;      /* ROLE_TWIN (default), ROLE_VALIDATE, ROLE_AGREE (= validate) */
    int samples;               /* per seed; 0 = the scene's samples */
    int n_seeds;               /* renders with seeds seed, seed+1, ...; 0 = 1 */
    unsigned seed;             /* first seed, default 0 */
    int width, height;         /* 0 = the scene's */
    int threads;               /* blender -t; 0 = all cores */
    int partial;               /* nonzero: leave out whole terms Cycles cannot reproduce */
    renderer_result *left_out; /* partial: receives the terms left out and why (may be NULL) */
    int keep_raw;              /* nonzero: keep OUT.cyc<i>.exr and OUT.timing.json */
    const char *blender;       /* executable; NULL = "blender" (searched in PATH) */
    const char *script;        /* NULL = "harness/renderers/cycles/cycles_render.py" */
    const char *texture_dir;   /* folder holding tex<material>_<slot>.exr (renderer_write_textures);
                                  NULL with a textured material -> RC_ERR_RANGE */
    int supersample;           /* k > 1: sample the model's k x k positions (below); 0, 1 = the pixel */
    int env_detail;            /* an environment image's texels around the horizon, for the width of
                                  the world's importance map; 0 = the image's width (at most 4096).
                                  cycles_render_job sets 4 N for an N x N cube map's conversion */
} cycles_options;

rc_status cycles_write_job(const scene *s, const mesh *m, const cycles_options *o, const char *job_json_path, char *err,
                           size_t errlen);

#define CYCLES_ARGV_MAX 16
typedef struct {
    int argc;
    const char *argv[CYCLES_ARGV_MAX + 1]; /* NULL-terminated; points into buf */
    char buf[4096];
} cycles_argv;

/* blender -b --factory-startup --python-exit-code 1 [-t N] -P SCRIPT -- JOB OUT */
rc_status cycles_command(const cycles_options *o, const char *job_json_path, const char *out_exr_path, cycles_argv *out,
                         char *err, size_t errlen);

/* The raw file cycles_render.py writes for seed index i: OUT without ".exr" + ".cyc<i>.exr". */
rc_status cycles_raw_path(const char *out_exr_path, int seed_index, char *buf, size_t len);

/* Reads the raw seed files, writes out_exr_path with reflcheck's channel names. */
rc_status cycles_collect(const cycles_options *o, const char *out_exr_path, char *err, size_t errlen);

/* The raw (Blender) channel name for one of reflcheck's layers: ("", 'R') -> "R",
 * ("diffuse", 'G') -> "diffuse.G", ("coverage", 0) -> "coverage.V". Returns buf. */
const char *cycles_channel_name(const char *aov, char c, char *buf, size_t len);
/* reflcheck's layers and where they come from in the raw file the scripts write: aov "" is the
 * full image, c 0 a one-channel layer. cycles_render.py writes all CYCLES_LAYOUT_N,
 * eevee_render.py all but the last ("object"). */
typedef struct {
    const char *aov;
    char c;
} cycles_layer;
#define CYCLES_LAYOUT_N 21
extern const cycles_layer cycles_layout[CYCLES_LAYOUT_N];
/* reflcheck's name for layer k of cycles_layout in the EXR it writes: ("", 'R') -> "R",
 * ("diffuse", 'G') -> "diffuse.G", ("coverage", 0) -> "coverage". Returns buf. */
const char *cycles_layer_name(int k, char *buf, size_t len);

/* The physics its validate job renders (renderer.h, renderer_physics_fn; see validate above). */
rc_status cycles_physics(const scene *s, physics *rendered, char *err, size_t errlen);

/* The render entry (renderer.h): job, blender, collect into j->exr. Options from j->options
 * (role and partial from j), else seeds, seed and threads from j. Refusals are
 * RUNNER_MISSING ("cycles cannot represent this scene: ..."). */
void cycles_render_job(const renderer_job *j, renderer_result *r);

#endif
