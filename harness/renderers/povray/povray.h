/* povray.h - a scene as POV-Ray 3.7 SDL, the exact povray command line, the box filter, and
 * the render entry of the renderer table (harness/renderers/registry.h).
 *
 * Usage:
 *   povray_options o = {0};                    zero = twin role, every term, scene's k, all cores
 *   renderer_job j = {.s = &scn, .m = &msh, .role = ROLE_TWIN, .dir = "work", .exr = "out.exr",
 *                     .log = "out.log", .options = &o};
 *   renderer_result r = {0};
 *   povray_render_job(&j, &r);                 what production (harness/jobs.c) runs too
 *   ... out.exr: R, G, B (radiance, output_scale undone, box-filtered from k*W x k*H),
 *       coverage, object (a second, geometry pass), var.R/G/B (each k x k block's variance) ...
 * The pieces: povray_write_scene, povray_command (argv for execvp; antialiasing off),
 * povray_box_downsample per channel.
 * With j.partial in a twin, a scene whose Blinn-Phong highlight POV-Ray cannot express
 * (coloured Vs, infinite viewer) is rendered without it and r.left_out says so.
 *
 * What the SDL reproduces (see harness/CONTRACT.md):
 * - role ROLE_TWIN: the rasterizer's model per material (d3d, d3d9client); cook_torrance and
 *   anything POV-Ray cannot express (coloured Vs, infinite viewer, Gouraud, clamping, eq. 8,
 *   D3D spot profile, D3D ambient La on a distance-attenuated light, a range that cuts through
 *   the geometry, a1 and a2 both non-zero, Ve on a channel whose pigment is 0) -> RC_ERR_RANGE
 *   with a message naming the material or light: the harness skips that comparison.
 * - role ROLE_VALIDATE / ROLE_AGREE: the scene's physics (model/scene.h) as povray_physics
 *   says it renders it; a scene whose physics differs from that -> RC_ERR_RANGE naming the
 *   fields. Lambert albedo and, for dielectric mirrors, the environment's reflection with the
 *   Fresnel form asked (`fresnel on`, `interior { ior }`). Conductors -> RC_ERR_RANGE.
 * - no inter-reflection: every object has no_reflection, so a reflection ray sees only the
 *   environment (sky_sphere); no_shadow too, unless a validate's physics asks for shadows.
 * - a cube map (ENV_CUBE): the faces as cube<f>.exr in cube_dir and the D3D face table as SDL
 *   functions in a sky_sphere pigment (per-face bilinear, clamped at the edge), so the table is
 *   checked by a second implementation; scale as emission.
 * - textures: the diffuse texture as `uv_mapping` `image_map { exr ... interpolate 2 }` over the
 *   mesh's uv_vectors, fed our decoded linear texels (so sRGB decoding is ours in both), times a
 *   grey finish diffuse (POV-Ray's pigment holds the texel; a non-grey material colour with a
 *   texture -> RC_ERR_RANGE); POV-Ray multiplies emission by the pigment as our texture multiplies
 *   the emission term. The texture's alpha is not used (our A layer is not compared). A specular
 *   map has no POV-Ray form -> RC_ERR_RANGE.
 * - lights: colour I/pi (E/pi for a sun); D3D attenuation 1/(a0 + a2 d^2) or 1/(a0 + a1 d) is
 *   exact through fade_distance/fade_power; a0 = 0 uses fade_distance D = fade_ratio * (the
 *   nearest light-to-geometry distance), leaving a relative error (D/d)^2 (fade_power 2) or
 *   D/d (fade_power 1), at most fade_ratio^2 resp. fade_ratio.
 * - background: uncovered pixels show the environment, like the rasterizer's R, G, B. A term
 *   render (o.term) omits the sky_sphere when the reflection term is off, so uncovered pixels
 *   are 0 as in the AOV layers; a term render that includes reflection but not every term
 *   still shows the environment there (mask it with the rasterizer's coverage).
 * POV-Ray's EXR output is half float: values are quantised to 2^-11 relative (4.9e-4) and
 * overflow above 65504; output_scale multiplies every source (lights, emission, ambient,
 * environment) so that HDR scenes fit, and povray_render_job divides it out again.
 * Paths are written into the SDL as given (relative paths are relative to POV-Ray's working
 * directory, the caller's); povray_write_scene refuses paths containing '"' or '\\'.
 * All functions but the entry return RC_OK or an error with one line in err and allocate
 * nothing.
 */
#ifndef REFLCHECK_POVRAY_H
#define REFLCHECK_POVRAY_H

#include <stddef.h>
#include "mesh.h"
#include "scene.h"
#include "status.h"
#include "../renderer.h"

/* Terms for povray_options.term (bits, same meaning as the rasterizer's AOV layers). */
enum {
    POVRAY_TERM_DIFFUSE = 1,    /* lit diffuse plus the D3D ambient terms Va*Ia, Va*La */
    POVRAY_TERM_SPECULAR = 2,   /* D3D Blinn-Phong highlight */
    POVRAY_TERM_REFLECTION = 4, /* environment reflection (D3D9Client eq. 5, Fresnel) */
    POVRAY_TERM_EMISSION = 8,   /* Ve */
    POVRAY_TERM_ALL = 15
};

typedef struct {
    comparison_role role;    /* ROLE_TWIN (0, default), ROLE_VALIDATE, ROLE_AGREE (= validate) */
    unsigned term;           /* POVRAY_TERM_* mask, 0 = POVRAY_TERM_ALL */
    int supersample;         /* k, 0 = the scene's supersample (at least 1) */
    int threads;             /* +WT<n>; 0 = POV-Ray's default (all cores) */
    int max_trace_level;     /* 0 = 2: the camera ray plus one reflection ray to the sky */
    double fade_ratio;       /* fade_distance / nearest light distance when a0 = 0; 0 = 1e-3 */
    double output_scale;     /* multiplies every radiance source; 0 = 1 */
    const char *povray;      /* executable, NULL = "povray" (found on PATH) */
    const char *texture_dir; /* folder holding tex<material>_<slot>.exr, the materials' textures as
                                linear float (povray_render_job writes them from j->tex); NULL with a
                                textured material -> RC_ERR_RANGE */
    int coverage;            /* nonzero: a geometry pass instead: no lights, black background,
                                every object emits rgb <1, object index + 1, 0>, so the box-
                                filtered R is coverage and G/R the object index + 1 */
    const char *cube_dir;    /* folder holding cube0.exr .. cube5.exr, a cube map's faces in
                                D3DCUBEMAP_FACES order as linear float (povray_render_job writes them
                                from j->env); NULL with a cube map -> RC_ERR_RANGE */
    int cube_size;           /* their side N */
    const char *env_file;    /* the environment image as the SDL names it (povray_render_job stages it
                                in the work folder), NULL = the scene's environment.image */
    float cube_max[3];       /* the largest texel value per channel over the six faces */
    int frames;              /* n > 1: an animation of frames 1..n (+KFI1 +KFF<n>, n <= 9), written to
                                <exr stem><frame>.exr; the SDL's frame_number picks what each renders;
                                0 = one frame */
} povray_options;

/* Writes the SDL file. m must be the scene's mesh (mesh_build): one mesh2 per object, the
 * same triangles and per-vertex normals the rasterizer draws (printed with %.9g, exact for
 * floats). Objects without triangles are skipped. Every file name it writes into an SDL string
 * (environment, texture and cube folders) must be plain (povray_plain_path); another is
 * RC_ERR_IO naming it: povray_render_job stages such files (renderer_stage) under plain names. */
rc_status povray_write_scene(const scene *s, const mesh *m, const povray_options *o, const char *sdl_path, char *err,
                             size_t errlen);

#define POVRAY_ARGV_MAX 24
#define POVRAY_ARGV_BUF 4096
typedef struct {
    int argc;
    char *argv[POVRAY_ARGV_MAX + 1]; /* NULL-terminated, pointing into buf */
    char buf[POVRAY_ARGV_BUF];
} povray_argv;

/* 1 when POV-Ray 3.7 takes path as it is, on its command line (+I, +O: words are split at
 * spaces and quotes are its own) and in an SDL string (backslash escapes, and bytes over 127
 * read in the scene's charset): only letters, digits and "/._-+", and no leading '-'. */
int povray_plain_path(const char *path);

/* The command that renders sdl_path into exr_out (half-float EXR, no alpha) at
 * k*width_px x k*height_px, without antialiasing, display, verbose output or pausing:
 *   povray +I<sdl> +O<exr> +FE +W<kW> +H<kH> -A -J -UA -D -V -P +Q9 -GS -GR [+WT<n>] [+KFI1 +KFF<n>]
 * Returns RC_ERR_RANGE for non-positive sizes or k or frames over 9, RC_ERR_IO for a path that is not plain
 * (povray_plain_path: run POV-Ray in the folder, runner_exec_in, with plain names), RC_ERR_NOMEM
 * if the paths do not fit. */
rc_status povray_command(const povray_options *o, const char *sdl_path, const char *exr_out, int width_px,
                         int height_px, int supersample, povray_argv *cmd, char *err, size_t errlen);

/* The command as one shell-quoted line (for logs and reports). */
void povray_command_string(const povray_argv *cmd, char *buf, size_t buflen);

/* Exact box filter: dst[(j * kw/k) + i] = mean of the k x k block of src (kw x kh, row-major)
 * whose top-left sample is (i*k, j*k). One channel. RC_ERR_RANGE if k < 1 or kw, kh are not
 * positive multiples of k. Sums in double, so the result is the float nearest the exact mean
 * up to one rounding of each sample's addition (k*k <= 65536). */
rc_status povray_box_downsample(const float *src, int kw, int kh, int k, float *dst);

/* The physics its validate SDL renders (renderer.h, renderer_physics_fn): Lambert albedo lit by
 * all lights or none, never by the environment (no radiosity), unweighted; a mirror reflection
 * of the environment with the Fresnel form asked (exact = `fresnel on`, Schlick through
 * falloff 5, F = 1); no rough lobe (no highlight, no environment on it); shadows as asked; no
 * inter-reflection. Conductors -> RC_ERR_RANGE. */
rc_status povray_physics(const scene *s, physics *rendered, char *err, size_t errlen);

/* The render entry (renderer.h): SDL, POV-Ray, box filter and the geometry pass into j->exr.
 * Both passes run in one POV-Ray process, as frames 1 (the scene) and 2 (the geometry) of an
 * animation: POV-Ray 3.7 spends about 0.75 s of wall time per process waiting on its own
 * threads' polls whatever the scene, so one process instead of two saves that per job.
 * Refusals are RUNNER_MISSING ("povray cannot represent this scene: ..."). */
void povray_render_job(const renderer_job *j, renderer_result *r);

#endif
