/* test_scene_file.c - YAML scene files: values, defaults, derived defaults, every bad fixture's
 * status and message place, and inputs that must not crash (run it under ASan/UBSan too).
 * Expected numbers are worked out by hand in the comments beside them.
 * Runs from the repository root (fixtures in tests/fixtures/scenes).
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>

#include "jobs.h"
#include "mesh.h"
#include "scene_file.h"

#define FIX "tests/fixtures/scenes/"
#define DEG (3.14159265358979323846 / 180.0)
/* Values pass through float: 1e-6 relative covers one rounding of numbers of order 1..100. */
#define TOL 1e-6

static void assert_v3(vec3 v, double x, double y, double z)
{
    assert_float_equal(v.x, x, TOL * (1 + fabs(x)));
    assert_float_equal(v.y, y, TOL * (1 + fabs(y)));
    assert_float_equal(v.z, z, TOL * (1 + fabs(z)));
}

static scene *load_ok(const char *path)
{
    scene *s = calloc(1, sizeof *s);
    char err[600] = "";
    assert_non_null(s);
    rc_status rc = scene_file_load(path, s, err, sizeof err);
    if (rc != RC_OK)
        print_error("%s\n", err);
    assert_int_equal(rc, RC_OK);
    return s;
}

static char *read_all(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    char *buf = malloc(1 << 20);
    assert_non_null(buf);
    *len = fread(buf, 1, 1 << 20, f);
    fclose(f);
    return buf;
}

static int find_material(const scene *s, const char *name)
{
    for (int i = 0; i < s->n_materials; i++)
        if (strcmp(s->materials[i].name, name) == 0)
            return i;
    fail_msg("material %s not found", name);
    return -1;
}

static void test_hash_vectors(void **state)
{
    (void)state;
    /* Published FNV-1a 64 test vectors. */
    assert_true(scene_file_hash("", 0) == 0xcbf29ce484222325ull);
    assert_true(scene_file_hash("a", 1) == 0xaf63dc4c8601ec8cull);
    assert_true(scene_file_hash("foobar", 6) == 0x85944171f73967e8ull);
}

static void test_good_full(void **state)
{
    (void)state;
    scene *s = load_ok(FIX "good_full.yaml");
    assert_string_equal(s->name, "full_example");
    assert_string_equal(s->path, FIX "good_full.yaml");
    assert_int_equal(s->width, 96);
    assert_int_equal(s->height, 64);
    assert_int_equal(s->supersample, 4);
    assert_int_equal(s->samples, 128);
    assert_v3(s->camera.eye, 0, 1.2, 4);
    assert_v3(s->camera.target, 0, 0.5, 0);
    assert_v3(s->camera.up, 0, 1, 0);
    assert_float_equal(s->camera.hfov, 40 * DEG, TOL);
    assert_v3(s->global_ambient, 0.01, 0.02, 0.03);
    assert_int_equal(s->env.kind, ENV_CONSTANT);
    assert_v3(s->env.radiance, 0.1, 0.2, 0.3);

    assert_int_equal(s->n_lights, 3);
    const light *l = s->lights;
    assert_int_equal(l[0].kind, LIGHT_POINT);
    assert_v3(l[0].position, 2, 4, 3);
    assert_v3(l[0].intensity, 30, 31, 32);
    assert_true(l[0].a0 == 0 && l[0].a1 == 0 && l[0].a2 == 1 && isinf(l[0].range));
    assert_int_equal(l[1].kind, LIGHT_SUN);
    assert_v3(l[1].direction, 0, -1, 0); /* [0, -2, 0] normalised */
    assert_v3(l[1].intensity, 3, 3.5, 4);
    assert_int_equal(l[2].kind, LIGHT_SPOT);
    assert_v3(l[2].position, 1, 3, 1);
    assert_float_equal(l[2].inner, 30 * DEG, TOL);
    assert_float_equal(l[2].outer, 40 * DEG, TOL);
    assert_float_equal(l[2].falloff, 2, TOL);
    assert_int_equal(l[2].profile, SPOT_D3D);
    assert_v3(v3(l[2].a0, l[2].a1, l[2].a2), 0.5, 0.25, 1);
    assert_float_equal(l[2].range, 100, TOL);
    assert_v3(l[2].ambient, 0.1, 0, 0);

    assert_int_equal(s->n_materials, 3);
    const material *w = &s->materials[find_material(s, "white")];
    assert_v3(w->albedo, 0.8, 0.7, 0.6);
    assert_int_equal(w->model, MODEL_D3D);
    assert_v3(w->d3d.specular, 0.2, 0.2, 0.2);
    assert_float_equal(w->d3d.power, 40, TOL);
    assert_int_equal(w->d3d.local_viewer, 0);
    assert_int_equal(w->d3d.per_vertex, 1);
    assert_int_equal(w->d3d.clamp, 1);
    assert_v3(w->d3d.ambient, 0.1, 0.1, 0.1);
    assert_v3(w->d3d.emissive, 0.01, 0, 0);
    assert_v3(w->d3d.diffuse, 0.5, 0.5, 0.5); /* given, so not the albedo */
    assert_float_equal(w->d9.r0, 0.04, TOL);  /* ((1 - 1.5)/(1 + 1.5))^2 */
    assert_float_equal(w->d9.m, 0.96, TOL);
    assert_float_equal(w->ct.m, 0.3, TOL);

    const material *c = &s->materials[find_material(s, "chrome")];
    assert_int_equal(c->model, MODEL_D3D9CLIENT);
    assert_float_equal(c->d9.p, 2.5, TOL);
    assert_float_equal(c->d9.r0, 0.2, TOL);
    assert_float_equal(c->d9.m, 0.5, TOL);
    assert_v3(c->d9.reflect, 0.9, 0.8, 0.7);
    assert_v3(c->d9.fresnel_colour, 1, 0.9, 0.8);
    assert_int_equal(c->d9.norm, NORM_EUCLID);
    assert_int_equal(c->d9.sun_angle, 1);
    assert_v3(c->d3d.diffuse, 0.8, 0.8, 0.8); /* default albedo */

    const material *g = &s->materials[find_material(s, "gold")];
    assert_int_equal(g->conductor, 1);
    assert_v3(g->eta, 0.2, 0.4, 1.4);
    assert_v3(g->k, 3.5, 2.4, 1.8);
    /* F0 = ((eta-1)^2 + k^2)/((eta+1)^2 + k^2): 12.89/13.69, 6.12/7.72, 3.4/9 */
    assert_v3(g->ct.f0, 0.9415632, 0.7927461, 0.3777778);
    assert_float_equal(g->ct.m, 0.25, TOL);
    assert_float_equal(g->roughness, 0.15, TOL);
    assert_v3(g->ct.ks, 1, 0.9, 0.8);
    assert_int_equal(g->ct.norm, CT_CT1982);
    assert_int_equal(g->ct.g, G_SMITH_EXACT);
    assert_int_equal(g->ct.f, F_EXACT);
    assert_int_equal(g->ct.reflection, 0);

    assert_int_equal(s->n_objects, 5);
    const object *o = s->objects;
    assert_int_equal(o[0].shape, SHAPE_SPHERE);
    assert_float_equal(o[0].radius, 0.5, TOL);
    assert_int_equal(o[0].tessellation, 48);
    assert_int_equal(o[0].material, find_material(s, "white"));
    assert_int_equal(o[1].shape, SHAPE_QUAD);
    assert_v3(o[1].size, 4, 0, 3);
    assert_v3(o[1].rotate, 0, 90 * DEG, 0);
    assert_int_equal(o[1].material, find_material(s, "chrome"));
    assert_int_equal(o[2].shape, SHAPE_BOX);
    assert_v3(o[2].size, 0.6, 0.6, 1.2);
    assert_float_equal(o[2].radius, 0.1, TOL);
    assert_int_equal(o[2].tessellation, 8);
    assert_int_equal(o[3].shape, SHAPE_TORUS);
    assert_float_equal(o[3].major, 0.5, TOL);
    assert_float_equal(o[3].radius, 0.125, TOL);
    assert_int_equal(o[4].shape, SHAPE_MESH);
    assert_string_equal(o[4].path, FIX "../meshes/tetra.obj");
    assert_int_equal(o[4].material, find_material(s, "gold"));

    assert_int_equal(s->n_comparisons, 2);
    const comparison *k = s->comparisons;
    assert_int_equal(k[0].test, registry_find("raster"));
    assert_int_equal(k[0].reference, registry_find("povray"));
    assert_int_equal(k[0].role, ROLE_TWIN);
    assert_int_equal(k[0].n_thresholds, 2);
    assert_string_equal(k[0].thresholds[0].metric, "rel_rms");
    assert_float_equal(k[0].thresholds[0].warn, 5e-4, 1e-15);
    assert_float_equal(k[0].thresholds[0].fail, 1e-3, 1e-15);
    assert_non_null(strstr(k[0].thresholds[0].why, "half float"));
    assert_string_equal(k[0].thresholds[1].metric, "psnr");
    assert_float_equal(k[0].thresholds[1].warn, 60, 0);
    assert_int_equal(k[1].test, registry_find("cycles"));
    assert_int_equal(k[1].role, ROLE_AGREE);

    size_t len;
    char *bytes = read_all(FIX "good_full.yaml", &len);
    assert_true(s->hash == scene_file_hash(bytes, len));
    bytes[len / 2] ^= 1; /* one flipped bit changes the hash */
    assert_true(s->hash != scene_file_hash(bytes, len));
    free(bytes);
    free(s);
}

static void test_good_minimal_defaults(void **state)
{
    (void)state;
    scene *s = load_ok(FIX "good_minimal.yaml");
    assert_string_equal(s->name, "good_minimal"); /* file base name */
    assert_int_equal(s->width, 32);
    assert_int_equal(s->height, 24);
    assert_int_equal(s->supersample, 1);
    assert_int_equal(s->samples, 64);
    assert_v3(s->camera.up, 0, 1, 0);
    assert_float_equal(s->camera.hfov, 60 * DEG, TOL);
    assert_v3(s->global_ambient, 0, 0, 0);
    assert_int_equal(s->env.kind, ENV_NONE);
    assert_int_equal(s->n_lights + s->n_materials + s->n_objects + s->n_comparisons, 0);
    /* The physics manifest's defaults (scene.h, scenes/FORMAT.md). */
    const physics *p = &s->physics;
    assert_int_equal(p->diffuse_lights, PHYSICS_ALL_LIGHTS);
    assert_int_equal(p->specular_lights, PHYSICS_ALL_LIGHTS);
    assert_int_equal(p->env_diffuse, 0);
    assert_int_equal(p->env_specular, 1);
    assert_int_equal(p->bounces, 1);
    assert_int_equal(p->shadows, 0);
    assert_int_equal(p->interreflection, 0);
    assert_int_equal(p->fresnel_specular, PHYS_FRESNEL_EXACT);
    assert_int_equal(p->fresnel_reflection, PHYS_FRESNEL_EXACT);
    assert_int_equal(p->diffuse_weight, PHYS_DIFFUSE_PLAIN);
    free(s);
}

/* Every physics key read, masks by index, and the canonical text the references compare. */
static void test_physics_manifest(void **state)
{
    (void)state;
    static const char text[] = "image: {width: 8, height: 8}\n"
                               "camera: {eye: [0, 0, 4], target: [0, 0, 0], hfov: 40}\n"
                               "physics: {diffuse_lights: [2, 0], specular_lights: none, env_diffuse: true,\n"
                               "  env_specular: false, bounces: 4, shadows: true, interreflection: true,\n"
                               "  fresnel_specular: nv, fresnel_reflection: schlick, diffuse_weight: one_minus_f}\n"
                               "lights:\n"
                               "  - {type: point, position: [2, 4, 3], intensity: [1, 1, 1]}\n"
                               "  - {type: point, position: [2, 4, 3], intensity: [1, 1, 1]}\n"
                               "  - {type: sun, direction: [0, -1, 0], irradiance: [1, 1, 1]}\n";
    scene *s = malloc(sizeof *s);
    char err[600] = "", buf[400];
    assert_non_null(s);
    rc_status rc = scene_file_parse(text, sizeof text - 1, "mem.yaml", s, err, sizeof err);
    if (rc != RC_OK)
        fail_msg("%s", err);
    const physics *p = &s->physics;
    assert_int_equal(p->diffuse_lights, 5u); /* lights 0 and 2: bits 0b101, listed before `lights:` */
    assert_int_equal(p->specular_lights, 0u);
    assert_int_equal(p->env_diffuse, 1);
    assert_int_equal(p->env_specular, 0);
    assert_int_equal(p->bounces, 4);
    assert_int_equal(p->shadows, 1);
    assert_int_equal(p->interreflection, 1);
    assert_int_equal(p->fresnel_specular, PHYS_FRESNEL_NV);
    assert_int_equal(p->fresnel_reflection, PHYS_FRESNEL_SCHLICK);
    assert_int_equal(p->diffuse_weight, PHYS_DIFFUSE_ONE_MINUS_F);
    assert_string_equal(physics_describe(p, s->n_lights, buf, sizeof buf),
                        "diffuse_lights=0+2 specular_lights=none env_diffuse=1 env_specular=0 bounces=4 shadows=1 "
                        "interreflection=1 fresnel_specular=nv fresnel_reflection=schlick diffuse_weight=one_minus_f");
    /* A mask covering every light of the scene reads as all, whatever bits lie beyond. */
    physics q;
    physics_init(&q);
    q.diffuse_lights = 7u;
    assert_non_null(strstr(physics_describe(&q, 3, buf, sizeof buf), "diffuse_lights=all specular_lights=all"));
    q.diffuse_lights = 2u;
    assert_non_null(strstr(physics_describe(&q, 3, buf, sizeof buf), "diffuse_lights=1 "));
    free(s);
}

/* The default name becomes folders, make targets and page names: characters a name may not
 * hold are made '_' (letters, digits, _ - . stay). */
static void test_default_name_made_safe(void **state)
{
    (void)state;
    static const char text[] = "image: {width: 4, height: 3}\ncamera: {eye: [0, 0, 5], target: [0, 0, 0], hfov: 40}\n";
    scene *s = malloc(sizeof *s);
    char err[512];
    assert_non_null(s);
    assert_int_equal(scene_file_parse(text, sizeof text - 1, "dir.d/<!--<script>.yaml", s, err, sizeof err), RC_OK);
    assert_string_equal(s->name, "__--_script_");
    assert_int_equal(scene_file_parse(text, sizeof text - 1, "x;id>PWNED;.v2.yaml", s, err, sizeof err), RC_OK);
    /* Capitals lowercased: names differing by case are one folder on a case-insensitive disk. */
    assert_string_equal(s->name, "x_id_pwned_");
    /* A leading '-' would read as an option in make and shell commands. */
    assert_int_equal(scene_file_parse(text, sizeof text - 1, "d/-rf.yaml", s, err, sizeof err), RC_OK);
    assert_string_equal(s->name, "_rf");
    /* A base name of 300 bytes is cut to the 63 a name holds (it used to fall back to "scene",
     * so two such files had one name). */
    char longpath[400];
    memset(longpath, 'a', 300);
    strcpy(longpath + 300, ".yaml");
    assert_int_equal(scene_file_parse(text, sizeof text - 1, longpath, s, err, sizeof err), RC_OK);
    assert_int_equal(strlen(s->name), SCENE_NAME_MAX - 1);
    /* A base name that gives no name or a reserved one: the file must say `name:`. */
    static const char *const need_key[] = {"d/.yaml", "d/plots.yaml", "runs.yaml", "d/latest.v1.yaml"};
    for (size_t i = 0; i < sizeof need_key / sizeof *need_key; i++) {
        err[0] = '\0';
        if (scene_file_parse(text, sizeof text - 1, need_key[i], s, err, sizeof err) != RC_ERR_RANGE ||
            !strstr(err, "add name:") || strncmp(err, need_key[i], strlen(need_key[i])) != 0)
            fail_msg("%s: %s", need_key[i], err);
    }
    static const char named[] = "name: ok_name\nimage: {width: 4, height: 3}\n"
                                "camera: {eye: [0, 0, 5], target: [0, 0, 0], hfov: 40}\n";
    assert_int_equal(scene_file_parse(named, sizeof named - 1, "d/plots.yaml", s, err, sizeof err), RC_OK);
    assert_string_equal(s->name, "ok_name");
    free(s);
}

/* scale: the documented bounds 1e-6 and 1e6 pass the parser and then the mesh step (1e-6 used
 * to pass the one and fail the other: (float)1e-6 < 1e-6); the floats next to the bounds
 * outside them (printed with 9 digits, which round-trip a float) are refused with the line. */
static void test_scale_bounds(void **state)
{
    (void)state;
    char lo_out[32], hi_out[32], text[600], err[600];
    snprintf(lo_out, sizeof lo_out, "%.9g", (double)nextafterf((float)1e-6, 0.0f));
    snprintf(hi_out, sizeof hi_out, "%.9g", (double)nextafterf((float)1e6, INFINITY));
    const char *const vals[][2] = {{"1e-6", "ok"},   {"1e6", "ok"},      {"[1e-6, 1e6, 1]", "ok"},
                                   {lo_out, "bad"},  {hi_out, "bad"},    {"[1, 1, 0.0000009999999]", "bad"},
                                   {"1.0e+6", "ok"}, {"0.000001", "ok"}, {"1000000.1", "bad"}};
    scene *s = malloc(sizeof *s);
    assert_non_null(s);
    for (size_t i = 0; i < sizeof vals / sizeof *vals; i++) {
        int n = snprintf(text, sizeof text,
                         "image: {width: 8, height: 6}\ncamera: {eye: [0, 0, 5], target: [0, 0, 0], hfov: 40}\n"
                         "materials: {m: {}}\nobjects:\n  - {shape: sphere, radius: 1, material: m, scale: %s}\n",
                         vals[i][0]);
        err[0] = '\0';
        rc_status rc = scene_file_parse(text, (size_t)n, "mem.yaml", s, err, sizeof err);
        if (strcmp(vals[i][1], "bad") == 0) {
            if (rc != RC_ERR_RANGE || strncmp(err, "mem.yaml:5:", 11) != 0 || !strstr(err, "objects[0].scale") ||
                !strstr(err, "[1e-06, 1e+06]"))
                fail_msg("scale %s: rc %d, %s", vals[i][0], rc, err);
            continue;
        }
        if (rc != RC_OK)
            fail_msg("scale %s refused by the parser: %s", vals[i][0], err);
        mesh m = {0};
        if (mesh_build(s, &m, err, sizeof err) != RC_OK)
            fail_msg("scale %s refused by the mesh step: %s", vals[i][0], err);
        mesh_free(&m);
    }
    free(s);
}

/* A quoted scalar is a string in YAML 1.1 and 1.2: refused for a boolean, number or whole
 * number key, with the line, the key and the fix; the same values unquoted are read. */
static void test_quoted_scalars(void **state)
{
    (void)state;
    /* key text before the value, the value quoted, unquoted, text after it, the value's line */
    static const struct {
        const char *before, *quoted, *plain, *after, *line;
    } cases[] = {
        {"materials: {m: {d3d: {clamp: ", "\"true\"", "true", "}}}\n", "mem.yaml:3:"},
        {"materials: {m: {d3d: {clamp: ", "'false'", "false", "}}}\n", "mem.yaml:3:"},
        {"materials: {m: {d3d: {power: ", "\"8\"", "8", "}}}\n", "mem.yaml:3:"},
        {"materials: {m: {roughness: ", "'0.25'", "0.25", "}}\n", "mem.yaml:3:"},
        {"materials: {m: {albedo: [", "\"0.5\"", "0.5", ", 0.5, 0.5]}}\n", "mem.yaml:3:"},
        {"materials: {m: {d3d: {per_vertex: ", "\"yes\"", "yes", "}}}\n", "mem.yaml:3:"},
        {"materials: {m: {}}\nobjects: [{shape: sphere, radius: 1, material: m, tessellation: ", "\"16\"", "16", "}]\n",
         "mem.yaml:4:"},
    };
    scene *s = malloc(sizeof *s);
    char text[600], err[600];
    assert_non_null(s);
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++)
        for (int quoted = 1; quoted >= 0; quoted--) {
            int n = snprintf(text, sizeof text,
                             "image: {width: 8, height: 6}\ncamera: {eye: [0, 0, 5], target: [0, 0, 0], hfov: "
                             "40}\n%s%s%s",
                             cases[i].before, quoted ? cases[i].quoted : cases[i].plain, cases[i].after);
            err[0] = '\0';
            rc_status rc = scene_file_parse(text, (size_t)n, "mem.yaml", s, err, sizeof err);
            if (quoted && (rc != RC_ERR_PARSE || strncmp(err, cases[i].line, strlen(cases[i].line)) != 0 ||
                           !strstr(err, "quoted") || !strstr(err, "without quotes")))
                fail_msg("%s: rc %d, %s", text, rc, err);
            if (!quoted && rc != RC_OK)
                fail_msg("%s: %s", text, err);
        }
    free(s);
}

/* camera.hfov's lower bound tan(hfov/2) >= 2^-24 N max(1, R/z) (harness/scene_file.c), by
 * hand: 64 samples across, eye 4 from the origin looking at it (R/z = 1): tan = 2^-18, hfov =
 * 2 atan(2^-18) = 2^-17 rad = 7.6293945e-6 rad (x^3/3 is 2e-17, below
 * the digits used) = 4.3713211e-4 degrees.
 * 4 times the samples (supersample 4, or a small variant of 128 x 2) give 4 times that; eye
 * 400 from the origin at distance 4 (R/z = 100) gives 100 times: 4.3713209e-2 (atan's cubic
 * term is 5e-8 relative). The values 1e-30 and 1e-300 of the issue are far below. */
static void test_hfov_bound(void **state)
{
    (void)state;
    static const struct {
        const char *image, *eye, *target, *hfov;
        int ok;
    } t[] = {
        {"{width: 64, height: 8}", "[0, 0, 4]", "[0, 0, 0]", "4.3714e-4", 1},
        {"{width: 64, height: 8}", "[0, 0, 4]", "[0, 0, 0]", "4.3712e-4", 0},
        {"{width: 64, height: 8, supersample: 4}", "[0, 0, 4]", "[0, 0, 0]", "1.74853e-3", 1},
        {"{width: 64, height: 8, supersample: 4}", "[0, 0, 4]", "[0, 0, 0]", "1.74852e-3", 0},
        {"{width: 64, height: 8, small: {width: 128, supersample: 2}}", "[0, 0, 4]", "[0, 0, 0]", "1.74853e-3", 1},
        {"{width: 64, height: 8, small: {width: 128, supersample: 2}}", "[0, 0, 4]", "[0, 0, 0]", "1.74852e-3", 0},
        {"{width: 64, height: 8}", "[0, 0, 400]", "[0, 0, 396]", "4.37133e-2", 1},
        {"{width: 64, height: 8}", "[0, 0, 400]", "[0, 0, 396]", "4.37131e-2", 0},
        {"{width: 64, height: 8}", "[0, 0, 4]", "[0, 0, 0]", "1e-30", 0},
        {"{width: 64, height: 8}", "[0, 0, 4]", "[0, 0, 0]", "1e-300", 0},
        {"{width: 64, height: 8}", "[0, 0, 4]", "[0, 0, 0]", "179.9", 1},
    };
    scene *s = malloc(sizeof *s);
    char text[600], err[600];
    assert_non_null(s);
    for (size_t i = 0; i < sizeof t / sizeof *t; i++) {
        int n = snprintf(text, sizeof text, "image: %s\ncamera: {eye: %s, target: %s, hfov: %s}\n", t[i].image,
                         t[i].eye, t[i].target, t[i].hfov);
        err[0] = '\0';
        rc_status rc = scene_file_parse(text, (size_t)n, "mem.yaml", s, err, sizeof err);
        if (t[i].ok ? rc != RC_OK
                    : rc != RC_ERR_RANGE || strncmp(err, "mem.yaml:2:", 11) != 0 || !strstr(err, "camera.hfov") ||
                          !strstr(err, "allowed: degrees in ["))
            fail_msg("%s: rc %d, %s", text, rc, err);
    }
    free(s);
}

/* Scene names become file and folder names of a run (RUN/<name>/, scene-<name>.html): each
 * unsafe or reserved one is refused with the file, line and key, and the rule. */
static void test_scene_names(void **state)
{
    (void)state;
    static const char *const bad[] = {
        "\"..\"", "\".\"",          "index.html", "summary.json",  "thresholds-proposal.html",
        "plots",  "timing",         "slurm",      "render_wall_s", "latest",
        "runs",   "\"\"",           "-x",         "a/b",           "\"a\\0b\"",
        "Foo",    "\"caf\\u00e9\"", "a.b",        "\"a b\"",       "x.yaml",
    };
    scene *s = malloc(sizeof *s);
    char text[700], err[600];
    assert_non_null(s);
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        int n = snprintf(text, sizeof text,
                         "image: {width: 4, height: 3}\nname: %s\n"
                         "camera: {eye: [0, 0, 5], target: [0, 0, 0], hfov: 40}\n",
                         bad[i]);
        err[0] = '\0';
        rc_status rc = scene_file_parse(text, (size_t)n, "mem.yaml", s, err, sizeof err);
        if (rc == RC_OK || strncmp(err, "mem.yaml:2:7: name: ", 20) != 0 || !strstr(err, "allowed: 1..63") ||
            strchr(err, '\n'))
            fail_msg("name %s: rc %d, %s", bad[i], rc, err);
    }
    /* 64 bytes and 300 bytes: one past the limit and far past it; 62 and 63 are allowed. */
    static const int lens[] = {62, 63, 64, 300};
    char longname[301];
    memset(longname, 'a', sizeof longname);
    for (size_t i = 0; i < sizeof lens / sizeof *lens; i++) {
        int n = snprintf(text, sizeof text,
                         "image: {width: 4, height: 3}\nname: %.*s\n"
                         "camera: {eye: [0, 0, 5], target: [0, 0, 0], hfov: 40}\n",
                         lens[i], longname);
        rc_status rc = scene_file_parse(text, (size_t)n, "mem.yaml", s, err, sizeof err);
        if ((rc == RC_OK) != (lens[i] < SCENE_NAME_MAX))
            fail_msg("name of %d bytes: rc %d, %s", lens[i], rc, err);
    }
    static const char *const good[] = {"a", "a-b_c9", "_x", "9lives", "index", "summary", "scene"};
    for (size_t i = 0; i < sizeof good / sizeof *good; i++) {
        int n = snprintf(text, sizeof text,
                         "name: %s\nimage: {width: 4, height: 3}\n"
                         "camera: {eye: [0, 0, 5], target: [0, 0, 0], hfov: 40}\n",
                         good[i]);
        if (scene_file_parse(text, (size_t)n, "mem.yaml", s, err, sizeof err) != RC_OK)
            fail_msg("name %s refused: %s", good[i], err);
        assert_string_equal(s->name, good[i]);
    }
    /* Every reserved name is refused, and the other parts of a run's file names, renderer and
     * role (RUN/<scene>/<renderer>-<role>.json), pass the same check. */
    char why[200];
    for (int i = 0; scene_reserved_names[i]; i++)
        assert_false(scene_name_check(scene_reserved_names[i], why, sizeof why));
    for (int i = 0; i < registry_count(); i++)
        if (!scene_name_check(registry_name(i), why, sizeof why))
            fail_msg("renderer %s: %s", registry_name(i), why);
    for (int i = 0; i < 3; i++)
        if (!scene_name_check(job_role_names[i], why, sizeof why))
            fail_msg("role %s: %s", job_role_names[i], why);
    free(s);
}

static void test_derived_defaults(void **state)
{
    (void)state;
    scene *s = load_ok(FIX "good_derived.yaml");
    const material *m = &s->materials[find_material(s, "glass2")];
    /* ior 2 given after the d3d9client block: r0 = (1/3)^2 = 1/9, m = 8/9. */
    assert_float_equal(m->d9.r0, 1.0 / 9.0, TOL);
    assert_float_equal(m->d9.m, 8.0 / 9.0, TOL);
    assert_float_equal(m->d9.p, 2, TOL);
    assert_v3(m->ct.f0, 1.0 / 9.0, 1.0 / 9.0, 1.0 / 9.0);
    assert_float_equal(m->ct.m, 0.05, TOL); /* = roughness */
    assert_v3(m->ct.ks, 0.5, 0.5, 0.5);
    assert_v3(m->d3d.diffuse, 0.2, 0.4, 0.6); /* = albedo */

    m = &s->materials[find_material(s, "given_r0")];
    assert_float_equal(m->d9.r0, 0.25, TOL); /* given wins over ior 4 */
    assert_float_equal(m->d9.m, 0.75, TOL);  /* 1 - the given r0 */
    assert_v3(m->ct.f0, 0.36, 0.36, 0.36);   /* ((1-4)/(1+4))^2, ct.f0 still follows ior */

    m = &s->materials[find_material(s, "metal")];
    assert_int_equal(m->conductor, 1);
    assert_v3(m->ct.f0, 0.9, 0.8, 0.7);       /* given */
    assert_v3(m->d3d.diffuse, 0.1, 0.1, 0.1); /* given */
    assert_float_equal(m->d9.r0, 0.04, TOL);  /* from the default ior 1.5 */

    m = &s->materials[find_material(s, "plain")];
    assert_v3(m->albedo, 0.8, 0.8, 0.8);
    assert_float_equal(m->ior, 1.5, TOL);
    assert_float_equal(m->roughness, 0.3, TOL);
    assert_int_equal(m->model, MODEL_D3D);
    assert_v3(m->d3d.diffuse, 0.8, 0.8, 0.8);
    assert_v3(m->d3d.specular, 0, 0, 0);
    assert_float_equal(m->d3d.power, 0, 0);
    assert_int_equal(m->d3d.local_viewer, 1);
    assert_int_equal(m->d3d.per_vertex, 0);
    assert_float_equal(m->d9.p, 3, TOL);
    assert_float_equal(m->d9.r0, 0.04, TOL);
    assert_float_equal(m->d9.m, 0.96, TOL);
    assert_v3(m->d9.reflect, 0, 0, 0);
    assert_v3(m->d9.fresnel_colour, 1, 1, 1);
    assert_int_equal(m->d9.norm, NORM_MAX);
    assert_float_equal(m->ct.m, 0.3, TOL);
    assert_v3(m->ct.f0, 0.04, 0.04, 0.04);
    assert_v3(m->ct.ks, 1, 1, 1);
    assert_int_equal(m->ct.norm, CT_WALTER);
    assert_int_equal(m->ct.g, G_VCAVITY);
    assert_int_equal(m->ct.f, F_SCHLICK);
    assert_int_equal(m->ct.reflection, 1);

    assert_int_equal(s->objects[0].shape, SHAPE_BOX);
    assert_float_equal(s->objects[0].radius, 0, 0); /* a box is sharp unless rounded */
    assert_int_equal(s->objects[0].tessellation, 32);
    assert_v3(s->objects[0].center, 0, 0, 0);
    assert_v3(s->objects[0].rotate, 0, 0, 0);
    const light *l = &s->lights[0];
    assert_int_equal(l->profile, SPOT_SMOOTH);
    assert_float_equal(l->falloff, 1, 0);
    assert_true(l->a0 == 0 && l->a1 == 0 && l->a2 == 1 && isinf(l->range));
    assert_v3(l->ambient, 0, 0, 0);
    assert_float_equal(l->inner, 20 * DEG, TOL);
    free(s);
}

typedef struct {
    const char *file;
    rc_status rc;
    const char *place; /* "LINE:COL: key.path" */
    const char *words; /* a piece of the problem or the allowed list */
} bad_case;

static const bad_case bad_cases[] = {
    {"bad_attenuation.yaml", RC_ERR_RANGE, "4:75: lights[0].attenuation", "not all 0"},
    {"bad_box_radius.yaml", RC_ERR_RANGE, "5:45: objects[0].radius", "radius <= 0.2"},
    {"bad_comparison.yaml", RC_ERR_RANGE, "4:17: comparisons[0].reference", "different"},
    {"bad_deep.yaml", RC_ERR_PARSE, "3:", "nesting"},
    {"bad_direction.yaml", RC_ERR_RANGE, "4:28: lights[0].direction", "zero-length"},
    {"bad_duplicate.yaml", RC_ERR_PARSE, "3:1: image", "duplicate key (first at line 1)"},
    {"bad_empty.yaml", RC_ERR_PARSE, "1:1:", "empty"},
    {"bad_enum.yaml", RC_ERR_PARSE, "4:14: materials.m.model", "allowed: d3d, d3d9client, cook_torrance"},
    {"bad_env_both.yaml", RC_ERR_PARSE, "3:14: environment", "exactly one"},
    {"bad_eye_target.yaml", RC_ERR_RANGE, "2:34: camera.target", "equals camera.eye"},
    {"bad_float_int.yaml", RC_ERR_PARSE, "1:16: image.width", "whole number"},
    {"bad_height_big.yaml", RC_ERR_RANGE, "1:28: image.height", "allowed: 1..16384"},
    {"bad_hfov.yaml", RC_ERR_RANGE, "2:51: camera.hfov", "(0, 180)"},
    {"bad_inf.yaml", RC_ERR_RANGE, "4:55: lights[0].intensity[1]", "not finite"},
    {"bad_ior_conductor.yaml", RC_ERR_PARSE, "6:5: materials.m.conductor", "both"},
    {"bad_light_key.yaml", RC_ERR_PARSE, "5:63: lights[1].position", "sun"},
    {"bad_list_for_map.yaml", RC_ERR_PARSE, "1:8: image", "got a list"},
    {"bad_m_negative.yaml", RC_ERR_RANGE, "5:27: materials.m.d3d9client.m", ">= 0"},
    {"bad_material_name.yaml", RC_ERR_RANGE, "7:42: objects[1].material", "'whit'; allowed: white"},
    {"bad_mesh_missing.yaml", RC_ERR_IO, "5:25: objects[0].path", "does_not_exist.obj"},
    {"bad_missing_camera.yaml", RC_ERR_PARSE, "1:1: camera", "missing required key"},
    {"bad_nan.yaml", RC_ERR_RANGE, "4:20: materials.white.albedo[0]", "NaN"},
    {"bad_neg_albedo.yaml", RC_ERR_RANGE, "4:21: materials.a.albedo[1]", ">= 0"},
    {"bad_neg_intensity.yaml", RC_ERR_RANGE, "4:55: lights[0].intensity[1]", ">= 0"},
    {"bad_neg_roughness.yaml", RC_ERR_RANGE, "5:16: materials.rough.roughness", ">= 0"},
    {"bad_physics_bounces.yaml", RC_ERR_RANGE, "3:20: physics.bounces", "interreflection: true"},
    {"bad_physics_fresnel.yaml", RC_ERR_PARSE, "4:21: physics.fresnel_specular", "allowed: exact, nv, one, schlick"},
    {"bad_physics_light.yaml", RC_ERR_RANGE, "5:31: physics.diffuse_lights[1]", "allowed: 0..0"},
    {"bad_normalize_model.yaml", RC_ERR_RANGE, "6:30: materials.m.d3d.normalize_normals", "model: d3d"},
    {"bad_quad_radius.yaml", RC_ERR_PARSE, "5:33: objects[0].radius", "not used by a quad"},
    {"bad_r0.yaml", RC_ERR_RANGE, "5:22: materials.m.d3d9client.r0", "[0, 1]"},
    {"bad_scale.yaml", RC_ERR_RANGE, "5:43: objects[0].scale[1]", "no mirroring"},
    {"bad_spot_cone.yaml", RC_ERR_RANGE, "4:91: lights[0].inner", "inner <= outer"},
    {"bad_supersample.yaml", RC_ERR_RANGE, "1:45: image.supersample", "1..16"},
    {"bad_syntax.yaml", RC_ERR_PARSE, "4:59:", "flow sequence"},
    {"bad_tessellation.yaml", RC_ERR_RANGE, "5:46: objects[0].tessellation", "4..1024"},
    {"bad_top_list.yaml", RC_ERR_PARSE, "1:1:", "expected a map"},
    /* libyaml puts the end of a file without a final newline at the start of the next line. */
    {"bad_truncated.yaml", RC_ERR_PARSE, "3:1:", "flow mapping"},
    {"bad_two_docs.yaml", RC_ERR_PARSE, "4:1:", "one document"},
    {"bad_type.yaml", RC_ERR_PARSE, "1:16: image.width", "whole number"},
    {"bad_unknown_key.yaml", RC_ERR_PARSE, "5:3: camera.fov", "allowed: eye, target, up, hfov"},
    {"bad_up_parallel.yaml", RC_ERR_RANGE, "2:9: camera.up", "parallel"},
    {"bad_width.yaml", RC_ERR_RANGE, "1:16: image.width", "1..16384"},
};

static void test_bad_fixtures(void **state)
{
    (void)state;
    scene *s = malloc(sizeof *s), *before = malloc(sizeof *s);
    assert_non_null(s);
    assert_non_null(before);
    memset(before, 0xA5, sizeof *before);
    for (size_t i = 0; i < sizeof bad_cases / sizeof *bad_cases; i++) {
        const bad_case *b = &bad_cases[i];
        char path[256], want[400], err[600] = "";
        snprintf(path, sizeof path, FIX "%s", b->file);
        memcpy(s, before, sizeof *s);
        rc_status rc = scene_file_load(path, s, err, sizeof err);
        snprintf(want, sizeof want, "%s:%s", path, b->place);
        if (rc != b->rc || strncmp(err, want, strlen(want)) != 0 || !strstr(err, b->words) || !strstr(err, "allowed") ||
            strchr(err, '\n'))
            fail_msg("%s: rc %d (want %d), message:\n  %s\nwant prefix '%s' and '%s'", b->file, rc, b->rc, err, want,
                     b->words);
        assert_memory_equal(s, before, sizeof *s); /* untouched on failure */
    }
    free(s);
    free(before);
}

/* Every good fixture is also listed here, so a new bad_*.yaml without a case is caught. */
static void test_fixture_list_complete(void **state)
{
    (void)state;
    FILE *p = popen("ls tests/fixtures/scenes/bad_*.yaml", "r");
    char line[300];
    int n = 0;
    assert_non_null(p);
    while (fgets(line, sizeof line, p)) {
        int found = 0;
        line[strcspn(line, "\n")] = '\0';
        for (size_t i = 0; i < sizeof bad_cases / sizeof *bad_cases; i++)
            found |= strcmp(strrchr(line, '/') + 1, bad_cases[i].file) == 0;
        if (!found)
            fail_msg("%s has no expectation in bad_cases", line);
        n++;
    }
    pclose(p);
    assert_int_equal(n, (int)(sizeof bad_cases / sizeof *bad_cases));
}

static rc_status parse_text(const char *text, size_t len, scene *s, char *err, size_t errlen)
{
    return scene_file_parse(text, len, "mem.yaml", s, err, errlen);
}

static void expect_fail(const char *text, size_t len, rc_status want)
{
    scene *s = malloc(sizeof *s);
    char err[600] = "";
    assert_non_null(s);
    rc_status rc = parse_text(text, len, s, err, sizeof err);
    if (rc != want || strncmp(err, "mem.yaml:", 9) != 0)
        fail_msg("rc %d (want %d): %s", rc, want, err);
    free(s);
}

/* image.samples auto is stored as 0 (Cycles takes the gates' noise, cycles_samples.h); quoted
 * "auto" is text, and other words are refused naming auto as an answer. */
#define CAMERA "camera: {eye: [0, 0, 5], target: [0, 0, 0], hfov: 60}\n"
static void test_samples_auto(void **state)
{
    (void)state;
    scene *s = malloc(sizeof *s);
    char err[600] = "";
    assert_non_null(s);
    const char *ok = "image: {width: 8, height: 4, samples: auto}\n" CAMERA;
    assert_int_equal(parse_text(ok, strlen(ok), s, err, sizeof err), RC_OK);
    assert_int_equal(s->samples, 0);
    const char *num = "image: {width: 8, height: 4, samples: 48}\n" CAMERA;
    assert_int_equal(parse_text(num, strlen(num), s, err, sizeof err), RC_OK);
    assert_int_equal(s->samples, 48);
    free(s);
    const char *quoted = "image: {width: 8, height: 4, samples: \"auto\"}\n" CAMERA;
    expect_fail(quoted, strlen(quoted), RC_ERR_PARSE);
    const char *word = "image: {width: 8, height: 4, samples: many}\n" CAMERA;
    expect_fail(word, strlen(word), RC_ERR_PARSE);
    s = malloc(sizeof *s);
    assert_non_null(s);
    assert_int_equal(parse_text(word, strlen(word), s, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, "or auto"));
    free(s);
}

/* image.samples {auto: true, bias: b, why: text}: auto with the z-tests' bias stated, stored as
 * samples 0 and samples_bias b; the key's line is kept for the refusal's message. bias outside
 * (0, 1], auto false, or no why are refused. */
static void test_samples_auto_bias(void **state)
{
    (void)state;
    scene *s = malloc(sizeof *s);
    char err[600] = "";
    assert_non_null(s);
    const char *ok = "image: {width: 8, height: 4,\n  samples: {auto: true, bias: 0.25, why: \"a quarter\"}}\n" CAMERA;
    assert_int_equal(parse_text(ok, strlen(ok), s, err, sizeof err), RC_OK);
    assert_int_equal(s->samples, 0);
    assert_true(s->samples_bias == 0.25);
    assert_int_equal(s->samples_line, 2);
    const char *plain = "image: {width: 8, height: 4, samples: auto}\n" CAMERA;
    assert_int_equal(parse_text(plain, strlen(plain), s, err, sizeof err), RC_OK);
    assert_true(s->samples_bias == 0.0);
    assert_int_equal(s->samples_line, 1);
    free(s);
    const char *zero = "image: {width: 8, height: 4, samples: {auto: true, bias: 0, why: \"x\"}}\n" CAMERA;
    expect_fail(zero, strlen(zero), RC_ERR_RANGE);
    const char *big = "image: {width: 8, height: 4, samples: {auto: true, bias: 1.5, why: \"x\"}}\n" CAMERA;
    expect_fail(big, strlen(big), RC_ERR_RANGE);
    const char *off = "image: {width: 8, height: 4, samples: {auto: false, bias: 0.1, why: \"x\"}}\n" CAMERA;
    expect_fail(off, strlen(off), RC_ERR_RANGE);
    const char *nowhy = "image: {width: 8, height: 4, samples: {auto: true, bias: 0.1}}\n" CAMERA;
    expect_fail(nowhy, strlen(nowhy), RC_ERR_PARSE);
}

static void test_hostile_inputs(void **state)
{
    (void)state;
    /* 10 MB of garbage: refused by size before parsing. */
    size_t big = 10u << 20;
    char *buf = malloc(big);
    assert_non_null(buf);
    srand(12345);
    for (size_t i = 0; i < big; i++)
        buf[i] = (char)(rand() & 0xff);
    expect_fail(buf, big, RC_ERR_RANGE);
    /* Just under the limit: random bytes reach libyaml and are rejected, not crashed on. */
    expect_fail(buf, SCENE_FILE_MAX_BYTES - 1, RC_ERR_PARSE);
    /* Printable garbage. */
    for (size_t i = 0; i < SCENE_FILE_MAX_BYTES; i++)
        buf[i] = (char)(' ' + rand() % 95);
    {
        scene *s = malloc(sizeof *s);
        char err[600] = "";
        rc_status rc = parse_text(buf, SCENE_FILE_MAX_BYTES, s, err, sizeof err);
        assert_true(rc == RC_ERR_PARSE || rc == RC_ERR_RANGE);
        free(s);
    }
    /* Deep nesting, which libyaml alone parses in quadratic time: must fail fast. */
    clock_t t0 = clock();
    memset(buf, '[', 500000);
    expect_fail(buf, 500000, RC_ERR_PARSE);
    for (size_t i = 0; i < 200000; i++)
        buf[i] = i % 2 ? ':' : 'a'; /* a:a:a:... one long plain scalar */
    expect_fail(buf, 200000, RC_ERR_PARSE);
    /* Block nesting: "a:\n a:\n  a:\n..." 200 levels. */
    size_t n = 0;
    for (int d = 0; d < 200; d++) {
        for (int k = 0; k < d; k++)
            buf[n++] = ' ';
        memcpy(buf + n, "a:\n", 3);
        n += 3;
    }
    expect_fail(buf, n, RC_ERR_PARSE);
    assert_true((double)(clock() - t0) / CLOCKS_PER_SEC < 10.0);
    free(buf);

    expect_fail("", 0, RC_ERR_PARSE);
    expect_fail(NULL, 0, RC_ERR_PARSE);
    expect_fail("---\n...\n", 8, RC_ERR_PARSE);
    expect_fail("[1, 2, 3]\n", 10, RC_ERR_PARSE);
    expect_fail("just text\n", 10, RC_ERR_PARSE);
    expect_fail("? [a, b]\n: 1\n", 13, RC_ERR_PARSE);                      /* a list as a key */
    expect_fail("image: {width: \"\\0\", height: 1}\n", 32, RC_ERR_PARSE); /* NUL in a scalar */
    const char *hdr = "image: {width: 8, height: 8}\ncamera: {eye: [0,0,1], target: [0,0,0], hfov: 30}\n";
    char text[4096];
    /* Alias bomb: the walk is bounded by the schema, so it ends at once. */
    snprintf(text, sizeof text,
             "%sa: &a [1,1,1,1,1,1,1,1,1]\nb: &b [*a,*a,*a,*a,*a,*a,*a,*a]\n"
             "c: &c [*b,*b,*b,*b,*b,*b,*b,*b]\nd: [*c,*c,*c,*c,*c,*c,*c,*c]\n",
             hdr);
    expect_fail(text, strlen(text), RC_ERR_PARSE);
    snprintf(text, sizeof text, "%sambient: &x [1, 1, 1]\nlights: [{type: point, position: *x, intensity: *x}]\n", hdr);
    {
        scene *s = malloc(sizeof *s);
        char err[600] = "";
        assert_int_equal(parse_text(text, strlen(text), s, err, sizeof err), RC_OK);
        assert_v3(s->lights[0].position, 1, 1, 1); /* aliases are plain YAML and work */
        free(s);
    }
    /* Too many lights, a list where a map is expected at each level. */
    snprintf(
        text, sizeof text, "%slights: [%s]\n", hdr,
        "{type: sun, direction: [0,-1,0], irradiance: [1,1,1]},{type: sun, direction: [0,-1,0], irradiance: [1,1,1]},"
        "{type: sun, direction: [0,-1,0], irradiance: [1,1,1]},{type: sun, direction: [0,-1,0], irradiance: [1,1,1]},"
        "{type: sun, direction: [0,-1,0], irradiance: [1,1,1]},{type: sun, direction: [0,-1,0], irradiance: [1,1,1]},"
        "{type: sun, direction: [0,-1,0], irradiance: [1,1,1]},{type: sun, direction: [0,-1,0], irradiance: [1,1,1]},"
        "{type: sun, direction: [0,-1,0], irradiance: [1,1,1]}");
    expect_fail(text, strlen(text), RC_ERR_RANGE);
    static const char *const lists[] = {
        "lights: {type: point}\n",
        "lights: [[1, 2]]\n",
        "materials: [a, b]\n",
        "materials: {a: [1]}\n",
        "materials: {a: {d3d: [1]}}\n",
        "objects: [[sphere]]\n",
        "objects: {a: 1}\n",
        "comparisons: [[povray]]\n",
        "comparisons: [{reference: povray, thresholds: [1]}]\n",
        "comparisons: [{reference: povray, thresholds: {rel_rms: [1, 2]}}]\n",
        "environment: [1, 1, 1]\n",
        "ambient: {r: 1}\n",
        "ambient: [1, 1]\n",
        "ambient: 1\n",
        "name: [a]\n",
        "name: \"a b\"\n",
        "materials: {a: {albedo: [1, 1, [1]]}}\n",
        "lights: [{type: [point]}]\n",
        "lights: [{}]\n",
        "materials: {a: {d3d: {local_viewer: maybe}}}\n",
        "materials: {a: {d3d9client: {norm: 2}}}\n",
        "comparisons: [{reference: povray, thresholds: {Bad-Name: {warn: 1, fail: 2}}}]\n",
        "comparisons: [{reference: povray, thresholds: {rel_rms: {warn: 1}}}]\n",
        "materials: {a: {}, a: {}}\n",
        "environment: {image: nothing_here.exr}\n",
        "environment: {image: sky.png}\n",
        "objects: [{shape: cone, material: a}]\n",
    };
    for (size_t i = 0; i < sizeof lists / sizeof *lists; i++) {
        scene *s = malloc(sizeof *s);
        char err[600] = "";
        snprintf(text, sizeof text, "%s%s", hdr, lists[i]);
        rc_status rc = parse_text(text, strlen(text), s, err, sizeof err);
        if (rc == RC_OK || strncmp(err, "mem.yaml:", 9) != 0 || !strstr(err, "allowed"))
            fail_msg("accepted or bad message for '%s': rc %d, %s", lists[i], rc, err);
        free(s);
    }
}

/* Per-size gates: small: and full: blocks override the threshold's own levels for that size
 * only, field by field; a size without a block keeps the shared levels. */
static void test_threshold_sizes(void **state)
{
    (void)state;
    static const char text[] =
        "image: {width: 8, height: 8}\ncamera: {eye: [0,0,1], target: [0,0,0], hfov: 30}\n"
        "comparisons: [{reference: povray, thresholds: {\n"
        "  nrmse: {warn: 0.02, fail: 0.03, why: w, loose: shared, sized: {figure: 0.011, size: small, run: s1},\n"
        "          full: {fail: 0.002, sized: {figure: 7.1e-4, run: n1}}},\n"
        "  rel_rms: {warn: 1, fail: 2, small: {warn: 0.5, fail: 0.7, loose: floor}}}}]\n";
    scene *s = malloc(sizeof *s);
    char err[600] = "";
    threshold_gate g;
    assert_non_null(s);
    if (parse_text(text, strlen(text), s, err, sizeof err) != RC_OK)
        fail_msg("%s", err);
    const threshold *t = s->comparisons[0].thresholds;
    /* nrmse at full size: fail from the block, warn the shared 0.02, sized on its own figure. */
    threshold_gate_at(&t[0], 1, &g);
    assert_int_equal(g.own, 1);
    assert_float_equal(g.fail, 0.002, 0);
    assert_float_equal(g.warn, 0.02, 0);
    assert_string_equal(g.loose, "shared");
    assert_int_equal(g.sized_size, SIZED_FULL);
    assert_float_equal(g.sized_figure, 7.1e-4, 0);
    assert_string_equal(g.sized_run, "n1");
    /* nrmse small: no block, so the shared levels and the shared sized (small, s1). */
    threshold_gate_at(&t[0], 0, &g);
    assert_int_equal(g.own, 0);
    assert_float_equal(g.fail, 0.03, 0);
    assert_int_equal(g.sized_size, SIZED_SMALL);
    assert_float_equal(g.sized_figure, 0.011, 0);
    /* rel_rms: small has its own levels and reason, full the shared ones and none. */
    threshold_gate_at(&t[1], 0, &g);
    assert_float_equal(g.warn, 0.5, 0);
    assert_float_equal(g.fail, 0.7, 0);
    assert_string_equal(g.loose, "floor");
    threshold_gate_at(&t[1], 1, &g);
    assert_float_equal(g.warn, 1, 0);
    assert_float_equal(g.fail, 2, 0);
    assert_string_equal(g.loose, "");
    assert_int_equal(g.sized_size, SIZED_NONE);
    /* Refused: an empty block, a size the block already names, a key outside the block's. */
    static const struct {
        const char *gate, *message;
    } bad[] = {
        {"{warn: 1, fail: 2, full: {}}", "thresholds.rel_rms.full: empty block"},
        {"{warn: 1, fail: 2, full: {sized: {figure: 1, run: r, size: full}}}", "full.sized.size: unknown key"},
        {"{warn: 1, fail: 2, full: {fail: 1, why: x}}", "full.why: unknown key; allowed: warn, fail, loose, sized"},
        {"{warn: 1, fail: 2, full: {sized: {figure: 1}}}", "full.sized.run"},
        {"{warn: 1, fail: 2, medium: {fail: 1}}", "allowed: warn, fail, why, loose, sized, small, full"},
        {"{warn: 1, fail: 2, small: {fail: .nan}}", "small.fail"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        char buf[600];
        snprintf(buf, sizeof buf,
                 "image: {width: 8, height: 8}\ncamera: {eye: [0,0,1], target: [0,0,0], hfov: 30}\n"
                 "comparisons: [{reference: povray, thresholds: {rel_rms: %s}}]\n",
                 bad[i].gate);
        err[0] = '\0';
        rc_status rc = parse_text(buf, strlen(buf), s, err, sizeof err);
        if (rc == RC_OK || strncmp(err, "mem.yaml:3:", 11) != 0 || !strstr(err, bad[i].message) || strchr(err, '\n'))
            fail_msg("'%s': rc %d, %s (want %s)", bad[i].gate, rc, err, bad[i].message);
    }
    free(s);
}

/* Every prefix of the full fixture, and random byte edits of it: any status, never a crash,
 * and a failure always comes with a one-line message naming the file. */
static void test_truncations_and_mutations(void **state)
{
    (void)state;
    size_t len;
    char *orig = read_all(FIX "good_full.yaml", &len);
    char *buf = malloc(len + 1);
    scene *s = malloc(sizeof *s);
    char err[600];
    int ok = 0, failed = 0;
    assert_non_null(buf);
    assert_non_null(s);
    for (size_t cut = 0; cut <= len; cut++) {
        err[0] = '\0';
        rc_status rc = scene_file_parse(orig, cut, FIX "good_full.yaml", s, err, sizeof err);
        if (rc == RC_OK) {
            ok++;
        } else {
            failed++;
            assert_true(strncmp(err, FIX "good_full.yaml:", strlen(FIX "good_full.yaml:")) == 0);
            assert_null(strchr(err, '\n'));
        }
    }
    assert_true(ok >= 1); /* at least the whole file */
    assert_true(failed > (int)len / 2);
    srand(777);
    static const char pool[] = "[]{}:,-#&*!|>'\"%@`\n \t0123456789.eE+naNINF";
    for (int it = 0; it < 4000; it++) {
        memcpy(buf, orig, len);
        int edits = 1 + rand() % 4;
        for (int e = 0; e < edits; e++) {
            size_t at = (size_t)rand() % len;
            buf[at] = rand() % 4 ? pool[rand() % (int)(sizeof pool - 1)] : (char)(rand() & 0xff);
        }
        err[0] = '\0';
        rc_status rc = scene_file_parse(buf, len, FIX "good_full.yaml", s, err, sizeof err);
        if (rc != RC_OK)
            assert_true(err[0] != '\0' && !strchr(err, '\n'));
    }
    free(orig);
    free(buf);
    free(s);
}

static void test_environment_image_paths(void **state)
{
    (void)state;
    char dir[] = "/tmp/reflcheck_scene_XXXXXX", path[600], sub[600], exr[600], err[600] = "";
    assert_non_null(mkdtemp(dir));
    snprintf(sub, sizeof sub, "%s/envs", dir);
    assert_int_equal(mkdir(sub, 0700), 0);
    snprintf(exr, sizeof exr, "%s/envs/sky.exr", dir);
    FILE *f = fopen(exr, "wb");
    assert_non_null(f);
    fputs("not checked here", f);
    fclose(f);
    snprintf(path, sizeof path, "%s/scene.yaml", dir);
    const char *text = "image: {width: 8, height: 8}\ncamera: {eye: [0,0,1], target: [0,0,0], hfov: 30}\n"
                       "environment: {image: envs/sky.exr, scale: 2}\n";
    scene *s = malloc(sizeof *s);
    assert_int_equal(scene_file_parse(text, strlen(text), path, s, err, sizeof err), RC_OK);
    assert_int_equal(s->env.kind, ENV_IMAGE);
    assert_string_equal(s->env.path, exr);
    assert_v3(s->env.radiance, 2, 2, 2);
    assert_string_equal(s->name, "scene");
    /* Relative to the scene file, not the working directory. */
    assert_int_equal(scene_file_parse(text, strlen(text), "elsewhere/scene.yaml", s, err, sizeof err), RC_ERR_IO);
    assert_non_null(strstr(err, "elsewhere/scene.yaml:3:"));
    assert_non_null(strstr(err, "environment.image"));
    remove(exr);
    rmdir(sub);
    rmdir(dir);
    free(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_hash_vectors),
        cmocka_unit_test(test_good_full),
        cmocka_unit_test(test_good_minimal_defaults),
        cmocka_unit_test(test_samples_auto),
        cmocka_unit_test(test_samples_auto_bias),
        cmocka_unit_test(test_default_name_made_safe),
        cmocka_unit_test(test_scene_names),
        cmocka_unit_test(test_scale_bounds),
        cmocka_unit_test(test_quoted_scalars),
        cmocka_unit_test(test_hfov_bound),
        cmocka_unit_test(test_derived_defaults),
        cmocka_unit_test(test_physics_manifest),
        cmocka_unit_test(test_bad_fixtures),
        cmocka_unit_test(test_threshold_sizes),
        cmocka_unit_test(test_fixture_list_complete),
        cmocka_unit_test(test_hostile_inputs),
        cmocka_unit_test(test_truncations_and_mutations),
        cmocka_unit_test(test_environment_image_paths),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
