/* scene.h - the in-memory scene: what a scene file describes, in canonical units.
 *
 * Usage:
 *   scene s; scene_init(&s);         fills every default (see the field comments)
 *   ... fill or parse (harness/scene_file.h) ...
 *   scene_main_light(&s), scene_material_used(&s, mi): rules every renderer shares
 * The struct owns no heap memory: fixed-size arrays, so copying it is fine.
 * Frame: right-handed, +Y up, metres. Angles in the struct are radians (files use degrees).
 * Lights are radiometric: point/spot intensity I [W/sr] with 1/d^2 falloff, sun irradiance
 * E [W/m^2] at normal incidence, environment radiance. A Lambert surface of albedo rho
 * therefore reflects rho*E/pi. The Direct3D model has no 1/pi: it is fed colours I/pi, E/pi.
 * Colours are linear RGB in vec3 (x = R, y = G, z = B).
 */
#ifndef REFLCHECK_SCENE_H
#define REFLCHECK_SCENE_H

#include <stddef.h>
#include <stdint.h>
#include "vec.h"

#define SCENE_NAME_MAX 64
#define SCENE_PATH_MAX 512

typedef enum { LIGHT_POINT, LIGHT_SUN, LIGHT_SPOT } light_kind;
/* Spot cone profile: D3D's power law, or cos(theta)*smoothstep as POV-Ray (tightness 1)
 * and Cycles compute it. Only `smooth` can be matched by the references. */
typedef enum { SPOT_D3D, SPOT_SMOOTH } spot_profile;

typedef struct {
    light_kind kind;
    vec3 position;      /* point, spot */
    vec3 direction;     /* sun, spot: unit direction the light travels (from the light) */
    vec3 intensity;     /* point/spot: I [W/sr]; sun: E [W/m^2] */
    vec3 ambient;       /* D3D La, default 0 */
    float a0, a1, a2;   /* D3D attenuation 1/(a0 + a1 d + a2 d^2); default 0, 0, 1 */
    float range;        /* D3D range; default INFINITY */
    float inner, outer; /* spot: full cone angles theta, phi [rad] */
    float falloff;      /* spot: D3D exponent, default 1 */
    spot_profile profile;
} light;

/* ENV_CUBE: a Direct3D cube map (scene/env.h gives its orientation and filtering). */
typedef enum { ENV_NONE, ENV_CONSTANT, ENV_IMAGE, ENV_CUBE } env_kind;

typedef struct {
    env_kind kind;
    vec3 radiance;                /* constant radiance, or scale for the image (default 1) */
    char path[SCENE_PATH_MAX];    /* equirectangular linear EXR, or a cube map's 4 x 3 cross; resolved
                                     relative to the scene file */
    char cube[6][SCENE_PATH_MAX]; /* cube map: its six face images in D3DCUBEMAP_FACES order
                                     (+X, -X, +Y, -Y, +Z, -Z); all empty when path is a cross */
    float sun_threshold;          /* image: > 0 moves the sun (texels of luminance above it, scale applied)
                                     into a sun light appended to the lights (scene/env.h env_extract_sun);
                                     0 = off (default) */
} environment;

/* MODEL_USER: a user's shading model from a shared object (model/user_model.h). */
typedef enum { MODEL_D3D, MODEL_D3D9CLIENT, MODEL_COOK_TORRANCE, MODEL_USER } model_kind;
typedef enum { NORM_MAX, NORM_MEAN, NORM_LUMINANCE, NORM_EUCLID } colour_norm;
/* d_a of eq. (7) on a textured material: the material alpha times the diffuse texel's alpha
 * (the default), the material alpha alone, or the texel's alpha alone. */
typedef enum { TEXEL_ALPHA_MULTIPLY, TEXEL_ALPHA_MATERIAL, TEXEL_ALPHA_TEXEL } texel_alpha_mode;
typedef enum { CT_WALTER, CT_CT1982 } ct_normalisation;
typedef enum { G_VCAVITY, G_SMITH_WALTER, G_SMITH_EXACT } ct_geometry;
typedef enum { F_SCHLICK, F_ONE, F_EXACT } ct_fresnel;

/* D3DMATERIALCOLORSOURCE: the current material, the vertex's diffuse colour (colour1) or its
 * specular colour (colour2). */
typedef enum { COLOUR_SOURCE_MATERIAL, COLOUR_SOURCE_COLOUR1, COLOUR_SOURCE_COLOUR2 } colour_source;

typedef struct {
    vec3 ambient;     /* Va, default 0 */
    vec3 diffuse;     /* Vd, default = albedo */
    vec3 specular;    /* Vs, default 0 */
    vec3 emissive;    /* Ve, default 0 */
    float power;      /* P, default 0: ((N.H)+)^0 = 1, so a non-zero Vs then gives a flat highlight */
    int local_viewer; /* D3DRS_LOCALVIEWER, default 1 */
    int per_vertex;   /* Gouraud, default 0 (per pixel) */
    int clamp;        /* clamp Dv + Sv to [0, 1], default 0 */
    /* D3DRS_NORMALIZENORMALS, default 1. With 0 (model d3d only) the world normal is the object
     * normal times the inverse transpose of the object's scale and rotation, not renormalised:
     * N.L and N.H scale with its length (mesh_d3d_normal_length). */
    int normalize_normals;
    /* Two-sided lighting, default 1: the normal is turned toward the viewer where it faces away,
     * as POV-Ray and Cycles shade (and as every image before the key was). 0 (model d3d only) is
     * Direct3D's fixed function with D3DCULL_NONE: both faces drawn, lit with the normal as given,
     * so a back face is lit by the lights on the normal's side (scenes/FORMAT.md, two_sided). */
    int two_sided;
    /* D3DRS_COLORVERTEX (model d3d only): 1 = the mesh's vertex colours replace the material
     * colours the sources below select; default 0 here (D3D's own default is TRUE: a scene says
     * when a file's colours take part). A source whose colour the object's mesh lacks keeps the
     * material colour. Sources default to D3D's: ambient material, diffuse colour1, specular
     * colour2, emissive material (D3DRS_*MATERIALSOURCE). */
    int colour_vertex;
    colour_source ambient_source, diffuse_source, specular_source, emissive_source;
} d3d_params;

typedef struct {
    float p;                      /* fresnel power, default 3 */
    float r0;                     /* offset, default ((1-n)/(1+n))^2 from the material ior */
    float m;                      /* multiplier, default 1 - r0 */
    vec3 reflect;                 /* lambda, metallic reflect colour, default 0 */
    vec3 fresnel_colour;          /* s, default white */
    colour_norm norm;             /* |lambda| and |R_tot|, default max */
    int sun_angle;                /* equation (8), default 0 */
    float alpha;                  /* d_a, the material/texture alpha of equation (7), default 1 */
    texel_alpha_mode texel_alpha; /* how a diffuse texel's alpha enters d_a, default multiply */
    /* 1 = drawn with D3D's SRCALPHA/INVSRCALPHA blend over what lies behind (render/render.h),
     * after the opaque objects, back to front, without depth write; default 0 (opaque: c_a is
     * only written into the image's A layer). */
    int blend;
    /* Dissolve (source 000, docs/dissolve.md): noise scale ("particle size") and strength, both
     * default 0 (off; either 0 turns it off); only on a material with a diffuse texture. */
    float dissolve_scale, dissolve_strength;
} d3d9client_params;

typedef struct {
    float m;               /* Beckmann roughness, default = material roughness */
    vec3 f0;               /* Schlick F0, default from ior (dielectric) or conductor at 0 deg */
    vec3 ks;               /* specular colour scale, default 1 */
    ct_normalisation norm; /* default walter */
    ct_geometry g;         /* default vcavity */
    ct_fresnel f;          /* default schlick */
    int reflection;        /* environment reflection term CM * Fr, default 1 */
} ct_params;

/* A user's model (model/user_model.h, docs/user_models.md): the shared object the scene names and
 * its parameter values. The model pointer is the object's own static description, loaded by
 * scene/user_load.h and never unloaded, so copying the struct is fine. */
#define USER_PARAMS_MAX 8 /* = REFLCHECK_USER_PARAMS_MAX */
struct reflcheck_user_model;
typedef struct {
    char path[SCENE_PATH_MAX]; /* resolved relative to the scene file */
    const struct reflcheck_user_model *model;
    double params[USER_PARAMS_MAX]; /* in the model's order: the scene's value, else its default */
} user_params;

/* The physical intent's microfacet distribution: what `roughness` means to every physical
 * reference. Beckmann m (default), or GGX / Trowbridge-Reitz alpha (Walter et al. 2007). */
typedef enum { DIST_BECKMANN, DIST_GGX } microfacet_distribution;

/* Material texture slots (scene/texture.h): the diffuse colour with alpha multiplies the
 * diffuse and emission terms and the alpha (D3D's texture stage MODULATE of Dv; the D3D9Client
 * "colour of the diffuse material or a texture" and "material/texture alpha" of eqs. 6-7); the
 * specular colour map multiplies the specular term (D3D Vs, Cook-Torrance ks). */
typedef enum { MAT_TEX_DIFFUSE, MAT_TEX_SPECULAR, MAT_TEX_SLOTS } material_texture_slot;

typedef struct {
    char name[SCENE_NAME_MAX];
    /* physical intent */
    vec3 albedo;     /* diffuse albedo rho, default 0.8 grey */
    float ior;       /* dielectric index n, default 1.5 */
    int conductor;   /* 1 if eta/k given */
    vec3 eta, k;     /* conductor complex index per channel */
    float roughness; /* Beckmann m, default 0.3; GGX alpha with distribution ggx */
    /* What roughness means to the references; default beckmann. */
    microfacet_distribution distribution;
    /* 1 = the physics has the material's lobe (Beckmann of roughness, a mirror at 0); 0 = no
     * specular at all: a d3d material without a specular colour and without a roughness written
     * (scene_file.c), so that no reference adds a highlight the user never asked for. Default 1. */
    int lobe;
    /* 1 = a thin dielectric sheet of index ior (a window pane): both faces, every internal
     * reflection, no absorption; what validate references render for a blended pane. Default 0. */
    int thin;
    model_kind model;
    d3d_params d3d; /* also the lit diffuse d of the D3D9Client model */
    d3d9client_params d9;
    ct_params ct;
    /* Model user only. */
    user_params user;
    char texture[MAT_TEX_SLOTS][SCENE_PATH_MAX]; /* image files, resolved like mesh paths; "" = none */
} material;

typedef enum { SHAPE_SPHERE, SHAPE_QUAD, SHAPE_BOX, SHAPE_TORUS, SHAPE_MESH } shape_kind;

typedef struct {
    shape_kind shape;
    vec3 center;
    vec3 rotate;                 /* Euler angles [rad], applied X then Y then Z */
    vec3 scale;                  /* per-axis scale > 0, default 1: applied before rotate and translate */
    float radius;                /* sphere; box edge rounding; torus tube radius */
    float major;                 /* torus ring radius */
    vec3 size;                   /* quad: x, z extents (in its XZ plane, normal +Y); box: full extents */
    int tessellation;            /* segments; default 32 */
    char path[SCENE_PATH_MAX];   /* mesh: OBJ or PLY */
    int material;                /* index into scene.materials */
    char usemtl[SCENE_NAME_MAX]; /* mesh, OBJ only: just the faces after `usemtl NAME`; "" = all */
} object;

/* The physics manifest: what every validate (and agree) reference of the scene renders, written
 * once (scene-file key `physics`, scenes/FORMAT.md) so that two references of one scene compute
 * the same physics or say precisely what they cannot. It describes the reference, never the
 * model under test. Zero is not the default for every field: scene_init fills the defaults. */
typedef enum {
    PHYS_FRESNEL_EXACT,  /* exact unpolarised F(V.H) per microfacet (= F(N.V) on a mirror) */
    PHYS_FRESNEL_NV,     /* exact F(N.V) tinting the whole lobe: a bias on a rough lobe, never exact */
    PHYS_FRESNEL_ONE,    /* F = 1 */
    PHYS_FRESNEL_SCHLICK /* Schlick's F0 + (1 - F0)(1 - V.H)^5 per microfacet */
} physics_fresnel;
typedef enum {
    PHYS_DIFFUSE_PLAIN,      /* Lambert albedo, not weighted */
    PHYS_DIFFUSE_ONE_MINUS_F /* Lambert albedo * (1 - F_dielectric(N.V)) of the material's ior */
} physics_diffuse_weight;

#define PHYSICS_ALL_LIGHTS 0xffu /* light mask: bit i is scene.lights[i] (SCENE_MAX_LIGHTS = 8) */

typedef struct {
    unsigned diffuse_lights;               /* lights that reach the Lambert term; default all */
    unsigned specular_lights;              /* lights whose highlight the specular lobe reflects; default all */
    int env_diffuse;                       /* the environment lights the Lambert term; default 0 */
    int env_specular;                      /* the specular lobe reflects the environment; default 1 */
    int bounces;                           /* scattering events on a path; default 1 (direct light only) */
    int shadows;                           /* objects block light; default 0 */
    int interreflection;                   /* objects are seen by reflected and diffuse rays; default 0 */
    physics_fresnel fresnel_specular;      /* of the lobe lit by the lights; default exact */
    physics_fresnel fresnel_reflection;    /* of the lobe reflecting the environment; default exact */
    physics_diffuse_weight diffuse_weight; /* default plain; conductors have no Lambert term */
} physics;

typedef enum { ROLE_TWIN, ROLE_VALIDATE, ROLE_AGREE } comparison_role;

#define METRIC_MAX 8
typedef struct {
    char metric[32]; /* e.g. rel_rms, psnr, max_abs, z_fail_share */
    double warn, fail;
    char why[160];
    /* Why the gate may sit more than 3x from its figure (a precision floor, a pixel count's
     * step); "" when it must not (tools/gates.py flags it). */
    char loose[160];
    /* The figure the gate was sized on, at which image size, in which run; sized_size 0 when
     * the file does not say. */
    double sized_figure;
    enum { SIZED_NONE, SIZED_SMALL, SIZED_FULL } sized_size;
    char sized_run[64];
    /* The gate at one image size (scene-file keys small: and full:), [0] small, [1] full: set 0
     * when the file gives none, and then that size is judged by the levels above. Within a set
     * block a field the file leaves out is the one above (warn_set, fail_set, loose ""), and
     * its sized figure (sized 0 = none) was measured at that size. */
    struct {
        int set, warn_set, fail_set, sized;
        double warn, fail, sized_figure;
        char loose[160];
        char sized_run[64];
    } at[2];
} threshold;

typedef struct {
    /* Rows of the renderer table (harness/renderers/registry.h), resolved from the names in
     * the scene file by harness/scene_file.c; the model knows no renderer. */
    int test, reference;
    comparison_role role;
    int n_thresholds;
    threshold thresholds[METRIC_MAX];
} comparison;

#define SCENE_MAX_LIGHTS      8
#define SCENE_MAX_MATERIALS   16
#define SCENE_MAX_OBJECTS     32
#define SCENE_MAX_COMPARISONS 8

typedef struct {
    char name[SCENE_NAME_MAX];
    char path[SCENE_PATH_MAX]; /* the scene file, for messages */
    int width, height, supersample;
    int samples; /* Cycles samples per pixel, default 64; 0 = auto (image.samples: auto) */
    /* image.samples {auto: true, bias: b}: the smallest error per pixel, as a fraction of the
     * surface's mean radiance, that the z-test gates judging a Cycles render must catch; 0 =
     * not stated. samples_line: the key's line in the file (1-based), for messages. */
    double samples_bias;
    int samples_line;
    /* The small variant `make test` renders (all renderers): 0 = derived from the full size
     * (width at most 96, aspect kept, supersample at most 2, samples at most 32). */
    struct {
        int width, height, supersample, samples;
        int active; /* 1: this copy is the small variant (harness/jobs.c), its gates the small ones */
    } small;
    float timeout; /* seconds one reference render may take, 0 = 600 */
    struct {
        vec3 eye, target, up;
        float hfov;
    } camera;            /* hfov [rad] */
    vec3 global_ambient; /* D3D Ia, default 0 */
    environment env;
    physics physics; /* what the validate references render */
    int n_lights, n_materials, n_objects, n_comparisons;
    light lights[SCENE_MAX_LIGHTS];
    material materials[SCENE_MAX_MATERIALS];
    object objects[SCENE_MAX_OBJECTS];
    comparison comparisons[SCENE_MAX_COMPARISONS];
    uint64_t hash; /* FNV-1a of the scene file's bytes */
} scene;

/* Names that become file or folder names of a run (a scene's name is its folder RUN/<name>, its
 * page scene-<name>.html, its make targets and plot files): checked here, in one place.
 * Allowed: 1..SCENE_NAME_MAX-1 bytes of a-z 0-9 _ -, not starting with '-' (a command-line
 * option), and none of the names a run folder holds itself (model/reserved_names.def). No '.'
 * (so neither "." nor ".." nor a file name of the report, index.html or summary.json) and no
 * capitals (two names differing only by case are one folder on a case-insensitive disk).
 * Returns 1 when allowed, else 0 with the problem in why (one line; callers add SCENE_NAME_RULE as
 * the fix). */
#define SCENE_NAME_RULE "1..63 characters of a-z 0-9 _ -, not starting with '-', not a run folder's own name"
int scene_name_check(const char *name, char *why, size_t whylen);
/* A name made from any n bytes of text (a scene file's base name): capitals lowercased, other
 * characters outside a-z 0-9 _ - made '_', a leading '-' made '_', cut at SCENE_NAME_MAX-1
 * bytes; the result still goes through scene_name_check (it may be empty or reserved). */
void scene_name_sanitise(const char *text, size_t n, char out[SCENE_NAME_MAX]);
/* The reserved names (model/reserved_names.def), NULL-terminated. */
extern const char *const scene_reserved_names[];

void scene_init(scene *s);
void light_init(light *l);
void material_init(material *m);
void object_init(object *o);
void physics_init(physics *p);

/* The main light of D3D9Client's equation (8), one rule for the rasterizer's kernels and every
 * translator: the first sun, else the first light, else NULL. */
const light *scene_main_light(const scene *s);
/* 1 when an object uses material mi: unused materials are left out of every translation. */
int scene_material_used(const scene *s, int mi);

/* The file words of the enums above, indexed by value. */
extern const char *const physics_fresnel_names[4];        /* exact, nv, one, schlick */
extern const char *const physics_diffuse_weight_names[2]; /* plain, one_minus_f */

/* The manifest as one canonical line ("diffuse_lights=all specular_lights=all env_diffuse=0 ...",
 * keys in struct order, masks restricted to the scene's n_lights as all, none or 0+2): equal
 * physics give equal text, so references compare manifests by string. Returns buf. */
const char *physics_describe(const physics *p, int n_lights, char *buf, size_t len);

/* The fields in which `rendered` differs from `want`, as "env_diffuse: 1 wanted, 0 rendered; ..."
 * in buf (empty when equal). Returns the number of differing fields. */
int physics_diff(const physics *want, const physics *rendered, int n_lights, char *buf, size_t len);

#endif
