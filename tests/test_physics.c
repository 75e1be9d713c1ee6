/* test_physics.c - one physics per scene: every validate reference of a canonical scene renders
 * the scene's physics manifest or refuses with the fields it cannot; two references of one
 * scene never compute two physics; agree compares exactly the two validate renders; a record
 * whose physics differs from the scene's is an error, never a figure.
 * The translators are asked without rendering (their physics functions and job writers); the
 * compare side uses run folders built by hand, 8x4 flat images whose metrics are known.
 * Runs from the repository root. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <glob.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cJSON.h>

#include "cli_exec.h"
#include "exr.h"
#include "frame.h"
#include "jobs.h"
#include "mesh.h"
#include "physical.h"
#include "renderers/cycles/cycles.h"
#include "scene_file.h"

static char dir[256];

static scene *parse_ok(const char *text)
{
    scene *s = malloc(sizeof *s);
    char err[1024] = "";
    assert_non_null(s);
    if (scene_file_parse(text, strlen(text), "mem.yaml", s, err, sizeof err) != RC_OK)
        fail_msg("%s", err);
    return s;
}

/* Every canonical scene: the references its validate and agree comparisons name either
 * render exactly the scene's physics or refuse; those that render agree with each other. The
 * grazing plane's two references must both render (the issue's case). */
static void test_canonical_scenes_one_physics(void **state)
{
    (void)state;
    glob_t g;
    assert_int_equal(glob("scenes/*.yaml", 0, NULL, &g), 0);
    int grazing_rendered = 0;
    for (size_t i = 0; i < g.gl_pathc; i++) {
        scene *s = malloc(sizeof *s);
        char err[1024] = "", want[400], first[400] = "", first_name[32] = "";
        assert_non_null(s);
        if (scene_file_load(g.gl_pathv[i], s, err, sizeof err) != RC_OK)
            fail_msg("%s", err);
        physics_describe(&s->physics, s->n_lights, want, sizeof want);
        for (int k = 0; k < s->n_comparisons; k++) {
            const comparison *c = &s->comparisons[k];
            if (c->role == ROLE_TWIN)
                continue;
            int sides[2] = {c->test, c->reference};
            for (int sd = 0; sd < 2; sd++) {
                const renderer_row *row = registry_row(sides[sd]);
                if (row->physics == NULL)
                    continue;
                physics got;
                char text[400], why[1024];
                rc_status st = row->physics(s, &got, why, sizeof why);
                rc_status chk = renderer_physics_check(row->physics, s, why, sizeof why);
                if (st != RC_OK || chk != RC_OK) {
                    /* A refusal names the file and says why; the comparison is skipped. */
                    assert_non_null(strstr(why, g.gl_pathv[i]));
                    print_message("%s refuses: %s\n", row->name, why);
                    continue;
                }
                physics_describe(&got, s->n_lights, text, sizeof text);
                assert_string_equal(text, want);
                if (first[0] == '\0') {
                    snprintf(first, sizeof first, "%s", text);
                    snprintf(first_name, sizeof first_name, "%s", row->name);
                } else if (strcmp(first, text) != 0) {
                    fail_msg("%s: %s renders '%s', %s renders '%s'", g.gl_pathv[i], first_name, first, row->name, text);
                }
                if (strcmp(s->name, "grazing_plane") == 0)
                    grazing_rendered |= 1 << sides[sd];
            }
        }
        free(s);
    }
    globfree(&g);
    /* POV-Ray and Cycles both render it (other physical references may too). */
    int both = (1 << registry_find("povray")) | (1 << registry_find("cycles"));
    assert_int_equal(grazing_rendered & both, both);
}

/* Refusals name the fields: the environment on the diffuse (POV-Ray has no radiosity), a rough
 * lobe's exact F(V.H) (Cycles tints by F(N.V): it renders nv, a bias), per-microfacet Schlick on
 * a rough lobe, two Fresnel forms on Cycles' one glossy closure, a conductor in POV-Ray. */
static void test_refusals_name_fields(void **state)
{
    (void)state;
    static const char base[] = "image: {width: 8, height: 8}\n"
                               "camera: {eye: [0, 1, 4], target: [0, 0, 0], hfov: 40}\n"
                               "environment: {constant: [0.2, 0.2, 0.2]}\n"
                               "lights:\n  - {type: sun, direction: [0, -1, 0], irradiance: [1, 1, 1]}\n"
                               "objects:\n  - {shape: quad, size: [2, 2], material: m}\n";
    const renderer_row *pov = registry_row(registry_find("povray")), *cyc = registry_row(registry_find("cycles"));
    char text[2048], err[1024];
    struct {
        const char *material, *physics;
        int pov_ok, cyc_ok;
        const char *pov_words, *cyc_words;
    } cases[] = {
        /* A mirror plane, the manifest's defaults: both render it. */
        {"{roughness: 0, albedo: [0.1, 0.1, 0.1]}", "{}", 1, 1, NULL, NULL},
        {"{roughness: 0}", "{env_diffuse: true}", 0, 1, "env_diffuse: 1 wanted, 0 rendered", NULL},
        {"{roughness: 0}", "{diffuse_weight: one_minus_f}", 0, 1, "diffuse_weight: one_minus_f wanted, plain rendered",
         NULL},
        {"{roughness: 0}", "{fresnel_reflection: schlick}", 1, 1, NULL, NULL},
        {"{roughness: 0}", "{diffuse_lights: none}", 1, 1, NULL, NULL},
        {"{roughness: 0.3}", "{}", 0, 0, "specular_lights: all wanted, none rendered",
         "fresnel_specular: exact wanted, nv rendered"},
        {"{roughness: 0.3}", "{fresnel_specular: nv, fresnel_reflection: nv}", 0, 1, "env_specular: 1 wanted, 0", NULL},
        {"{roughness: 0.3}", "{specular_lights: none, env_specular: false}", 1, 1, NULL, NULL},
        {"{roughness: 0.3}", "{fresnel_specular: schlick, fresnel_reflection: schlick}", 0, 0, NULL,
         "no per-microfacet Fresnel"},
        {"{roughness: 0.3}", "{fresnel_specular: one, fresnel_reflection: nv}", 0, 0, NULL, "give both one form"},
        {"{roughness: 0, conductor: {eta: [1, 1, 1], k: [3, 3, 3]}}", "{}", 0, 1, "complex Fresnel", NULL},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        snprintf(text, sizeof text, "%smaterials:\n  m: %s\nphysics: %s\n", base, cases[i].material, cases[i].physics);
        scene *s = parse_ok(text);
        err[0] = '\0';
        rc_status st = renderer_physics_check(pov->physics, s, err, sizeof err);
        if ((st == RC_OK) != cases[i].pov_ok || (cases[i].pov_words && !strstr(err, cases[i].pov_words)))
            fail_msg("case %zu povray: rc %d: %s", i, st, err);
        err[0] = '\0';
        st = renderer_physics_check(cyc->physics, s, err, sizeof err);
        if ((st == RC_OK) != cases[i].cyc_ok || (cases[i].cyc_words && !strstr(err, cases[i].cyc_words)))
            fail_msg("case %zu cycles: rc %d: %s", i, st, err);
        free(s);
    }
}

/* The physics a material gets follows from the material: a d3d floor with no specular and no
 * roughness written has no lobe (the default roughness 0.3 once gave it a Beckmann highlight,
 * a 1e-3..1e-2 error gradient against the model's plain Lambert floor); writing a roughness or a
 * specular colour brings the lobe back. POV-Ray and Cycles render the lobe-less floor's physics
 * exactly, where the lobe made POV-Ray refuse (no Beckmann) and Cycles render F(N.V). */
static void test_no_lobe_without_specular(void **state)
{
    (void)state;
    static const char base[] = "image: {width: 8, height: 8}\n"
                               "camera: {eye: [0, 1, 4], target: [0, 0, 0], hfov: 40}\n"
                               "lights:\n  - {type: point, position: [0, 2, 1], intensity: [4, 4, 4]}\n"
                               "objects:\n  - {shape: quad, size: [2, 2], material: m}\n";
    struct {
        const char *material;
        int lobe;
    } cases[] = {
        {"{albedo: [0.35, 0.45, 0.55], model: d3d}", 0},
        {"{albedo: [0.35, 0.45, 0.55], model: d3d, roughness: 0.3}", 1},
        {"{albedo: [0.35, 0.45, 0.55], model: d3d, d3d: {specular: [0.2, 0.2, 0.2], power: 20}}", 1},
        {"{albedo: [0.35, 0.45, 0.55], model: cook_torrance}", 1},
    };
    const renderer_row *pov = registry_row(registry_find("povray")), *cyc = registry_row(registry_find("cycles"));
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char text[1024], err[1024] = "", why[400] = "";
        snprintf(text, sizeof text, "%smaterials:\n  m: %s\n", base, cases[i].material);
        scene *s = parse_ok(text);
        assert_int_equal(s->materials[0].lobe, cases[i].lobe);
        env_map env = {.kind = ENV_NONE};
        shade_context c;
        shade_plan p;
        shade_context_make(s, &env, &c);
        assert_int_equal(physical_plan_make(&c, &s->materials[0], &s->physics, &p, why, sizeof why), RC_OK);
        assert_int_equal((p.terms & SHADE_TERM_SPECULAR) != 0, cases[i].lobe);
        /* Mirror geometry for the point light: the lobe's peak, where a highlight cannot hide. */
        dvec3 n = dv3(0, 1, 0), v = dv3_norm(dv3(0, 1, 1)), l = dv3_norm(dv3(0, 1, -1));
        dvec3 lobe = physical_lobe(&s->materials[0], PHYS_FRESNEL_EXACT, n, v, l);
        if (cases[i].lobe)
            assert_true(lobe.x > 0.01);
        else
            assert_true(lobe.x == 0.0 && lobe.y == 0.0 && lobe.z == 0.0);
        if (!cases[i].lobe) {
            if (renderer_physics_check(pov->physics, s, err, sizeof err) != RC_OK)
                fail_msg("povray: %s", err);
            if (renderer_physics_check(cyc->physics, s, err, sizeof err) != RC_OK)
                fail_msg("cycles: %s", err);
        }
        free(s);
    }
}

/* An agree measures a physical reference by another; an approximation (the model, EEVEE) on
 * either side is refused by the parser, naming the key. */
static void test_agree_refuses_an_approximation(void **state)
{
    (void)state;
    static const char base[] = "image: {width: 8, height: 8}\n"
                               "camera: {eye: [0, 1, 4], target: [0, 0, 0], hfov: 40}\n"
                               "materials:\n  m: {roughness: 0}\n"
                               "objects:\n  - {shape: quad, size: [2, 2], material: m}\n"
                               "comparisons:\n";
    struct {
        const char *cmp;
        int ok;
        const char *words;
    } cases[] = {
        {"  - {test: exact, reference: cycles, role: agree}\n", 1, NULL},
        {"  - {test: eevee, reference: raster, role: agree}\n", 0, "comparisons[0].test: eevee is an approximation"},
        {"  - {reference: cycles, role: agree}\n", 0, "comparisons[0].test: raster is an approximation"},
        {"  - {test: cycles, reference: eevee, role: agree}\n", 0, "comparisons[0].reference: eevee is an approx"},
        {"  - {test: eevee, reference: cycles, role: validate}\n", 1, NULL},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char text[1024], err[1024] = "";
        snprintf(text, sizeof text, "%s%s", base, cases[i].cmp);
        scene *s = malloc(sizeof *s);
        assert_non_null(s);
        rc_status st = scene_file_parse(text, strlen(text), "mem.yaml", s, err, sizeof err);
        if ((st == RC_OK) != cases[i].ok || (cases[i].words && !strstr(err, cases[i].words)))
            fail_msg("case %zu: rc %d: %s", i, st, err);
        if (!cases[i].ok)
            assert_non_null(strstr(err, "mem.yaml:"));
        free(s);
    }
}

/* `reflcheck check` refuses a scene whose validate or agree reference cannot render its physics,
 * naming the comparison and the keys to set; with them set, the scene checks ok. Every canonical
 * scene passes. */
static void test_check_refuses_unrenderable_physics(void **state)
{
    (void)state;
    static const char base[] = "image: {width: 8, height: 8}\n"
                               "camera: {eye: [0, 1, 4], target: [0, 0, 0], hfov: 40}\n"
                               "environment: {constant: [0.2, 0.2, 0.2]}\n"
                               "lights:\n  - {type: sun, direction: [0, -1, 0], irradiance: [1, 1, 1]}\n"
                               "  - {type: point, position: [0, 2, 1], intensity: [4, 4, 4]}\n"
                               "objects:\n  - {shape: quad, size: [2, 2], material: m}\n";
    struct {
        const char *material, *physics, *cmp, *words;
    } cases[] = {
        /* Cycles tints a rough lobe by F(N.V): the fix is nv on both lobes (one closure). */
        {"{roughness: 0.3}", "{}", "{reference: cycles, role: validate}",
         "comparisons[0].reference: cycles cannot render the scene's physics (fresnel_specular: exact wanted, nv "
         "rendered; fresnel_reflection: exact wanted, nv rendered); allowed: set physics: {fresnel_specular: nv, "
         "fresnel_reflection: nv}"},
        /* POV-Ray lights every diffuse or none: a list of one light is not renderable. */
        {"{roughness: 0, albedo: [0.5, 0.5, 0.5]}", "{diffuse_lights: [1]}",
         "{test: exact, reference: povray, role: agree}",
         "comparisons[0].reference: povray cannot render the scene's physics (diffuse_lights: 1 wanted, all rendered); "
         "allowed: set physics: {diffuse_lights: all}"},
        /* The renderer's own refusal, with the comparison named. */
        {"{roughness: 0.3}", "{fresnel_specular: schlick, fresnel_reflection: schlick}",
         "{reference: cycles, role: validate}",
         "no per-microfacet Fresnel; use fresnel one, or nv (a bias), or the exact reference "
         "(comparisons[0].reference: "
         "cycles, role validate)"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char text[2048], path[300], err[1024] = "";
        snprintf(text, sizeof text, "%smaterials:\n  m: %s\nphysics: %s\ncomparisons:\n  - %s\n", base,
                 cases[i].material, cases[i].physics, cases[i].cmp);
        scene *s = parse_ok(text);
        assert_int_equal(scene_file_physics_check(s, err, sizeof err), RC_ERR_RANGE);
        if (!strstr(err, cases[i].words))
            fail_msg("case %zu: %s", i, err);
        free(s);
        snprintf(path, sizeof path, "%s/check%zu.yaml", dir, i);
        FILE *f = fopen(path, "w");
        assert_non_null(f);
        fputs(text, f);
        fclose(f);
        int rc = cli_exec(err, sizeof err, "check %s", path);
        if (rc != 2 || !strstr(err, cases[i].words) || !strstr(err, path))
            fail_msg("case %zu: check exited %d: %s", i, rc, err);
    }
    /* The fixes the messages name: then check says ok. */
    const char *fixed[] = {
        "physics: {fresnel_specular: nv, fresnel_reflection: nv}\ncomparisons:\n  - {reference: cycles, "
        "role: validate}\nmaterials:\n  m: {roughness: 0.3}\n",
        "physics: {diffuse_lights: all}\ncomparisons:\n  - {test: exact, reference: povray, role: "
        "agree}\nmaterials:\n  m: {roughness: 0, albedo: [0.5, 0.5, 0.5]}\n"};
    for (size_t i = 0; i < 2; i++) {
        char path[300], err[1024];
        snprintf(path, sizeof path, "%s/fixed%zu.yaml", dir, i);
        FILE *f = fopen(path, "w");
        assert_non_null(f);
        fprintf(f, "%s%s", base, fixed[i]);
        fclose(f);
        int rc = cli_exec(err, sizeof err, "check %s", path);
        if (rc != 0)
            fail_msg("fixed %zu: check exited %d: %s", i, rc, err);
    }
    glob_t g;
    assert_int_equal(glob("scenes/*.yaml", 0, NULL, &g), 0);
    for (size_t i = 0; i < g.gl_pathc; i++) {
        scene *s = malloc(sizeof *s);
        char err[1024] = "";
        assert_non_null(s);
        if (scene_file_load(g.gl_pathv[i], s, err, sizeof err) != RC_OK ||
            scene_file_physics_check(s, err, sizeof err) != RC_OK)
            fail_msg("%s", err);
        free(s);
    }
    globfree(&g);
}

static cJSON *read_json(const char *path)
{
    FILE *f = fopen(path, "r");
    if (f == NULL)
        fail_msg("no %s", path);
    static char buf[1 << 22];
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = '\0';
    cJSON *j = cJSON_Parse(buf);
    assert_non_null(j);
    return j;
}

/* The Cycles job of a validate carries the physics: per-lamp closure visibility, the world on
 * the diffuse or not, shadows, bounces; agree writes the very same job as validate. */
static void test_cycles_job_follows_physics(void **state)
{
    (void)state;
    static const char text[] = "image: {width: 8, height: 8}\n"
                               "camera: {eye: [0, 1, 4], target: [0, 0, 0], hfov: 40}\n"
                               "environment: {constant: [0.2, 0.2, 0.2]}\n"
                               "lights:\n  - {type: sun, direction: [0, -1, 0], irradiance: [1, 1, 1]}\n"
                               "  - {type: point, position: [0, 2, 0], intensity: [1, 1, 1]}\n"
                               "materials:\n  m: {roughness: 0.2, albedo: [0.5, 0.5, 0.5]}\n"
                               "objects:\n  - {shape: quad, size: [2, 2], material: m}\n"
                               "physics: {diffuse_lights: [1], specular_lights: [0], env_diffuse: true, "
                               "shadows: true, fresnel_specular: one, fresnel_reflection: one, "
                               "diffuse_weight: one_minus_f}\n";
    scene *s = parse_ok(text);
    mesh m = {0};
    char why[512], pv[600], pa[600], pt[600];
    assert_int_equal(mesh_build(s, &m, why, sizeof why), RC_OK);
    snprintf(pv, sizeof pv, "%s/v.json", dir);
    snprintf(pa, sizeof pa, "%s/a.json", dir);
    snprintf(pt, sizeof pt, "%s/t.json", dir);
    cycles_options ov = {.role = ROLE_VALIDATE}, oa = {.role = ROLE_AGREE}, ot = {.role = ROLE_TWIN};
    assert_int_equal(cycles_write_job(s, &m, &ov, pv, why, sizeof why), RC_OK);
    assert_int_equal(cycles_write_job(s, &m, &oa, pa, why, sizeof why), RC_OK);
    assert_int_equal(cycles_write_job(s, &m, &ot, pt, why, sizeof why), RC_OK);
    cJSON *v = read_json(pv), *a = read_json(pa), *t = read_json(pt);
    assert_true(cJSON_Compare(v, a, 1));
    const cJSON *ph = cJSON_GetObjectItemCaseSensitive(v, "physics");
    const cJSON *lv = cJSON_GetObjectItemCaseSensitive(ph, "light_visibility");
    assert_int_equal(cJSON_GetArraySize(lv), 2);
    assert_true(cJSON_IsFalse(cJSON_GetObjectItem(cJSON_GetArrayItem(lv, 0), "diffuse")));
    assert_true(cJSON_IsTrue(cJSON_GetObjectItem(cJSON_GetArrayItem(lv, 0), "glossy")));
    assert_true(cJSON_IsTrue(cJSON_GetObjectItem(cJSON_GetArrayItem(lv, 1), "diffuse")));
    assert_true(cJSON_IsFalse(cJSON_GetObjectItem(cJSON_GetArrayItem(lv, 1), "glossy")));
    assert_true(cJSON_IsTrue(cJSON_GetObjectItem(ph, "shadows")));
    assert_int_equal(cJSON_GetObjectItem(ph, "bounces")->valueint, 1);
    const cJSON *wv = cJSON_GetObjectItemCaseSensitive(v, "world_visibility");
    assert_true(cJSON_IsTrue(cJSON_GetObjectItem(wv, "diffuse")));
    const cJSON *mat = cJSON_GetArrayItem(cJSON_GetObjectItem(v, "materials"), 0);
    assert_string_equal(
        cJSON_GetObjectItem(cJSON_GetObjectItem(cJSON_GetObjectItem(mat, "glossy"), "fresnel"), "kind")->valuestring,
        "one");
    assert_true(cJSON_IsNumber(cJSON_GetObjectItem(cJSON_GetObjectItem(mat, "diffuse"), "fresnel_ior")));
    /* The twin computes the model: every lamp on every closure, no shadows, no world on the
     * diffuse, whatever the physics says. */
    const cJSON *tph = cJSON_GetObjectItemCaseSensitive(t, "physics");
    assert_true(cJSON_IsTrue(
        cJSON_GetObjectItem(cJSON_GetArrayItem(cJSON_GetObjectItem(tph, "light_visibility"), 0), "diffuse")));
    assert_true(cJSON_IsFalse(cJSON_GetObjectItem(tph, "shadows")));
    assert_true(cJSON_IsFalse(cJSON_GetObjectItem(cJSON_GetObjectItem(t, "world_visibility"), "diffuse")));
    cJSON_Delete(v);
    cJSON_Delete(a);
    cJSON_Delete(t);
    mesh_free(&m);
    free(s);
}

enum { W = 8, H = 4, NP = W * H };

/* A job record (with `physics` when not NULL) and a flat, fully covered image of value v with
 * diffuse and specular layers dif and spec, and pixel `odd` (-1: none) set to odd_v. */
static void put_job_layers(const char *run, const char *name, int r, comparison_role role, const char *physics_text,
                           float v, float dif, float spec, int odd, float odd_v)
{
    char sd[600], path[1024], err[512];
    snprintf(sd, sizeof sd, "%s/%s", run, name);
    mkdir(run, 0755);
    mkdir(sd, 0755);
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "status", "ok");
    cJSON_AddStringToObject(o, "message", "");
    if (physics_text != NULL)
        cJSON_AddStringToObject(o, "physics", physics_text);
    char *txt = cJSON_Print(o);
    job_output_path(run, name, r, role, "json", path, sizeof path);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(txt, f);
    assert_int_equal(fclose(f), 0);
    free(txt);
    cJSON_Delete(o);
    static float rgb[NP], cov[NP], obj[NP], var[NP], dl[NP], sl[NP];
    for (int i = 0; i < NP; i++) {
        rgb[i] = i == odd ? odd_v : v;
        cov[i] = 1.0f;
        obj[i] = 0.0f;
        var[i] = 1e-4f;
        dl[i] = dif;
        sl[i] = spec;
    }
    exr_channel ch[14] = {{"R", rgb},         {"G", rgb},        {"B", rgb},        {"coverage", cov},
                          {"object", obj},    {"var.R", var},    {"var.G", var},    {"var.B", var},
                          {"diffuse.R", dl},  {"diffuse.G", dl}, {"diffuse.B", dl}, {"specular.R", sl},
                          {"specular.G", sl}, {"specular.B", sl}};
    job_output_path(run, name, r, role, "exr", path, sizeof path);
    assert_int_equal(exr_write(path, W, H, ch, 14, NULL, 0, err, sizeof err), RC_OK);
}

static void put_job(const char *run, const char *name, int r, comparison_role role, const char *physics_text, float v)
{
    put_job_layers(run, name, r, role, physics_text, v, v, 0.0f, -1, 0.0f);
}

static const cJSON *comparison_at(const cJSON *j, int i)
{
    const cJSON *c = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(j, "comparisons"), i);
    assert_non_null(c);
    return c;
}

static const char *jstr(const cJSON *o, const char *key)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
    return cJSON_IsString(v) ? v->valuestring : "";
}

/* agree reads the validate renders (there are no agree files at all), records the manifest,
 * and a reference whose recorded physics differs from the scene's makes the comparison an
 * error naming both. */
static void test_compare_holds_records_to_the_physics(void **state)
{
    (void)state;
    char scn[512], run[512], err[2048], want[400], path[1024];
    snprintf(scn, sizeof scn, "%s/ph.yaml", dir);
    snprintf(run, sizeof run, "%s/run", dir);
    FILE *f = fopen(scn, "w");
    assert_non_null(f);
    fputs("name: ph\nimage: {width: 8, height: 4}\ncamera: {eye: [0, 0, 4], target: [0, 0, 0], hfov: 40}\n"
          "lights:\n  - {type: sun, direction: [0, 0, -1], irradiance: [1, 1, 1]}\n"
          "materials:\n  m: {roughness: 0}\n"
          "objects:\n  - {shape: quad, size: [10, 10], rotate: [90, 0, 0], material: m}\n"
          "comparisons:\n"
          "  - {reference: cycles, role: validate, thresholds: {nrmse: {warn: 0.1, fail: 0.2, why: \"t\"}}}\n"
          "  - {test: povray, reference: cycles, role: agree,\n"
          "     thresholds: {nrmse: {warn: 0.1, fail: 0.2, why: \"t\"}}}\n",
          f);
    assert_int_equal(fclose(f), 0);
    scene *s = malloc(sizeof *s);
    assert_non_null(s);
    assert_int_equal(scene_file_load(scn, s, err, sizeof err), RC_OK);
    physics_describe(&s->physics, s->n_lights, want, sizeof want);
    free(s);
    int raster = registry_find("raster"), pov = registry_find("povray"), cyc = registry_find("cycles");
    put_job(run, "ph", raster, ROLE_VALIDATE, NULL, 0.5f);
    put_job(run, "ph", pov, ROLE_VALIDATE, want, 0.5f);
    put_job(run, "ph", cyc, ROLE_VALIDATE, want, 0.5f);
    job_output_path(run, "ph", cyc, ROLE_AGREE, "json", path, sizeof path);
    assert_int_not_equal(access(path, F_OK), 0);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), 0);
    snprintf(path, sizeof path, "%s/ph/compare.json", run);
    cJSON *j = read_json(path);
    for (int i = 0; i < 2; i++) {
        assert_string_equal(jstr(comparison_at(j, i), "status"), "pass");
        assert_string_equal(jstr(comparison_at(j, i), "physics"), want);
    }
    /* The validate stands beside its agree; the agree itself lists none. */
    const cJSON *agrees = cJSON_GetObjectItemCaseSensitive(comparison_at(j, 0), "agrees");
    assert_int_equal(cJSON_GetArraySize(agrees), 1);
    assert_string_equal(cJSON_GetArrayItem(agrees, 0)->valuestring, "povray-vs-cycles-agree");
    assert_null(cJSON_GetObjectItemCaseSensitive(comparison_at(j, 0), "agree_none"));
    assert_null(cJSON_GetObjectItemCaseSensitive(comparison_at(j, 1), "agrees"));
    cJSON_Delete(j);

    /* Without the agree the validate says plainly that it has none. */
    char lone[512];
    snprintf(lone, sizeof lone, "%s/lone.yaml", dir);
    f = fopen(lone, "w");
    assert_non_null(f);
    fputs("name: ph\nimage: {width: 8, height: 4}\ncamera: {eye: [0, 0, 4], target: [0, 0, 0], hfov: 40}\n"
          "lights:\n  - {type: sun, direction: [0, 0, -1], irradiance: [1, 1, 1]}\n"
          "materials:\n  m: {roughness: 0}\n"
          "objects:\n  - {shape: quad, size: [10, 10], rotate: [90, 0, 0], material: m}\n"
          "comparisons:\n"
          "  - {reference: cycles, role: validate, thresholds: {nrmse: {warn: 0.1, fail: 0.2, why: \"t\"}}}\n",
          f);
    assert_int_equal(fclose(f), 0);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", lone, run), 0);
    j = read_json(path);
    assert_int_equal(cJSON_GetArraySize(cJSON_GetObjectItemCaseSensitive(comparison_at(j, 0), "agrees")), 0);
    assert_non_null(strstr(jstr(comparison_at(j, 0), "agree_none"), "cycles alone renders this physics"));
    /* The material's kind, for the report's one physics per kind. */
    const cJSON *kinds = cJSON_GetObjectItemCaseSensitive(comparison_at(j, 0), "material_kinds");
    assert_string_equal(jstr(kinds, "m"), "d3d dielectric");
    cJSON_Delete(j);

    /* POV-Ray's record says it lit the diffuse with the environment: not the scene's physics. */
    char other[400];
    snprintf(other, sizeof other, "%s", want);
    char *p = strstr(other, "env_diffuse=0");
    assert_non_null(p);
    p[strlen("env_diffuse=")] = '1';
    put_job(run, "ph", pov, ROLE_VALIDATE, other, 0.5f);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), 1);
    j = read_json(path);
    assert_string_equal(jstr(comparison_at(j, 0), "status"), "pass"); /* raster vs cycles */
    assert_string_equal(jstr(comparison_at(j, 1), "status"), "error");
    assert_non_null(strstr(jstr(comparison_at(j, 1), "reason"), "povray validate rendered physics"));
    assert_non_null(strstr(jstr(comparison_at(j, 1), "reason"), "env_diffuse=1"));
    cJSON_Delete(j);

    /* A record without physics (an older run) is no figure either. */
    put_job(run, "ph", pov, ROLE_VALIDATE, NULL, 0.5f);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), 1);
    j = read_json(path);
    assert_non_null(strstr(jstr(comparison_at(j, 1), "reason"), "(not recorded)"));
    cJSON_Delete(j);
}

/* A sky whose sun is split into a light, and no light of the scene's own: the renderers see one
 * light (the sun), so "specular_lights: none" reads "none" in their records; compare must
 * read the scene's mask against that same count (it printed "all" for zero lights, and every
 * such validate was an error). */
static void test_compare_split_sun_light_masks(void **state)
{
    (void)state;
    char scn[512], run[512], err[2048], want[400], path[1024], cwd[PATH_MAX], envp[PATH_MAX + 32];
    assert_non_null(getcwd(cwd, sizeof cwd)); /* the unit tests run from the tree's root */
    snprintf(envp, sizeof envp, "%s/scenes/envs/city.exr", cwd);
    snprintf(scn, sizeof scn, "%s/sunph.yaml", dir);
    snprintf(run, sizeof run, "%s/run-sun", dir);
    FILE *f = fopen(scn, "w");
    assert_non_null(f);
    fprintf(f,
            "name: sunph\nimage: {width: 8, height: 4}\ncamera: {eye: [0, 0, 4], target: [0, 0, 0], hfov: 40}\n"
            "environment: {image: \"%s\", sun_threshold: 50}\n"
            "physics: {specular_lights: none}\n"
            "materials:\n  m: {roughness: 0}\n"
            "objects:\n  - {shape: quad, size: [10, 10], rotate: [90, 0, 0], material: m}\n"
            "comparisons:\n"
            "  - {reference: cycles, role: validate, thresholds: {nrmse: {warn: 0.1, fail: 0.2, why: \"t\"}}}\n",
            envp);
    assert_int_equal(fclose(f), 0);
    scene *s = malloc(sizeof *s);
    assert_non_null(s);
    assert_int_equal(scene_file_load(scn, s, err, sizeof err), RC_OK);
    assert_int_equal(s->n_lights, 0);
    assert_int_equal(frame_light_count(s), 1);
    /* The renderer's side: the frame after the split, as jobs.c describes it. */
    env_map e;
    float *pixels = NULL;
    assert_int_equal(frame_env_load(s, &e, &pixels, err, sizeof err), RC_OK);
    assert_int_equal(frame_env_split_sun(s, pixels, &e, NULL, err, sizeof err), RC_OK);
    assert_int_equal(s->n_lights, 1);
    physics_describe(&s->physics, s->n_lights, want, sizeof want);
    free(pixels);
    free(s);
    assert_non_null(strstr(want, "specular_lights=none"));
    put_job(run, "sunph", registry_find("raster"), ROLE_VALIDATE, NULL, 0.5f);
    put_job(run, "sunph", registry_find("cycles"), ROLE_VALIDATE, want, 0.5f);
    if (cli_exec(err, sizeof err, "compare %s --run %s", scn, run) != 0)
        fail_msg("compare: %s", err);
    snprintf(path, sizeof path, "%s/sunph/compare.json", run);
    cJSON *j = read_json(path);
    assert_string_equal(jstr(comparison_at(j, 0), "status"), "pass");
    assert_string_equal(jstr(comparison_at(j, 0), "physics"), want);
    cJSON_Delete(j);
}

static double jnum(const cJSON *o, const char *key)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
    if (!cJSON_IsNumber(v))
        fail_msg("%s is not a number", key);
    return v->valuedouble;
}

/* The robust figures and the error by term in compare.json, and thresholds on them. 32
 * surface pixels of 0.5 on both sides but one raster pixel at 1.5: sum e = 3 (1 per channel),
 * nrmse = sqrt(3 / 96) / 0.5; k = ceil(0.32) = 1 trims that pixel: nrmse_trim1 = 0, its share
 * of the squared error 1; per-pixel relative errors are 31 zeros and 2 (1 / 0.5), so the
 * median and the 95th percentile (rank ceil(30.4) = 31) are 0. Terms: raster diffuse 0.3 and
 * specular 0.2, Cycles 0.2 and 0.3: each nrmse 0.1 / 0.5 (the whole reference's mean). */
static void test_compare_robust_and_terms(void **state)
{
    (void)state;
    char scn[512], run[512], err[2048], path[1024];
    snprintf(scn, sizeof scn, "%s/rb.yaml", dir);
    snprintf(run, sizeof run, "%s/run-rb", dir);
    FILE *f = fopen(scn, "w");
    assert_non_null(f);
    fputs("name: rb\nimage: {width: 8, height: 4}\ncamera: {eye: [0, 0, 4], target: [0, 0, 0], hfov: 40}\n"
          "materials:\n  m: {roughness: 0}\n"
          "objects:\n  - {shape: quad, size: [10, 10], rotate: [90, 0, 0], material: m}\n"
          "comparisons:\n"
          "  - reference: cycles\n    role: validate\n    thresholds:\n"
          "      nrmse_trim1: {warn: 0.01, fail: 0.02, why: \"t\"}\n"
          "      diffuse.nrmse: {warn: 0.3, fail: 0.4, why: \"t\"}\n"
          "      glossy.nrmse: {warn: 0.1, fail: 0.15, why: \"the glossy term\"}\n",
          f);
    assert_int_equal(fclose(f), 0);
    scene *s = malloc(sizeof *s);
    char want[400];
    assert_non_null(s);
    assert_int_equal(scene_file_load(scn, s, err, sizeof err), RC_OK);
    physics_describe(&s->physics, s->n_lights, want, sizeof want);
    free(s);
    put_job_layers(run, "rb", registry_find("raster"), ROLE_VALIDATE, NULL, 0.5f, 0.3f, 0.2f, 5, 1.5f);
    put_job_layers(run, "rb", registry_find("cycles"), ROLE_VALIDATE, want, 0.5f, 0.2f, 0.3f, -1, 0.0f);
    assert_int_equal(cli_exec(err, sizeof err, "compare %s --run %s", scn, run), 1);
    snprintf(path, sizeof path, "%s/rb/compare.json", run);
    cJSON *j = read_json(path);
    const cJSON *c = comparison_at(j, 0);
    const cJSON *surf = cJSON_GetObjectItem(cJSON_GetObjectItem(c, "regions"), "surface");
    assert_int_equal((int)jnum(surf, "n_pixels"), 32);
    assert_float_equal(jnum(surf, "nrmse"), sqrt(3.0 / 96.0) / 0.5, 1e-9);
    assert_float_equal(jnum(surf, "nrmse_trim1"), 0.0, 0.0);
    assert_float_equal(jnum(surf, "worst1_share"), 1.0, 1e-12);
    assert_float_equal(jnum(surf, "rel_median"), 0.0, 0.0);
    assert_float_equal(jnum(surf, "rel_p95"), 0.0, 0.0);
    assert_int_equal((int)jnum(surf, "trim1_n"), 1);
    const cJSON *terms = cJSON_GetObjectItem(c, "terms");
    const cJSON *d = cJSON_GetObjectItem(terms, "diffuse"), *g = cJSON_GetObjectItem(terms, "glossy");
    /* Float layers: 0.3f and 0.2f hold 1e-7 relative rounding. */
    assert_float_equal(jnum(d, "test_mean"), 0.3, 1e-7);
    assert_float_equal(jnum(d, "ref_mean"), 0.2, 1e-7);
    assert_float_equal(jnum(d, "nrmse"), 0.2, 1e-6);
    assert_float_equal(jnum(g, "nrmse"), 0.2, 1e-6);
    assert_null(cJSON_GetObjectItem(terms, "specular")); /* validate: glossy, not the model's split */
    assert_string_equal(jstr(c, "status"), "fail");
    assert_non_null(strstr(err, "glossy.nrmse"));
    cJSON_Delete(j);
}

static int setup(void **state)
{
    (void)state;
    snprintf(dir, sizeof dir, "/tmp/reflcheck-physics-%ld", (long)getpid());
    mkdir(dir, 0755);
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    return system(cmd) == 0 ? 0 : -1;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_canonical_scenes_one_physics),
        cmocka_unit_test(test_refusals_name_fields),
        cmocka_unit_test(test_no_lobe_without_specular),
        cmocka_unit_test(test_agree_refuses_an_approximation),
        cmocka_unit_test(test_check_refuses_unrenderable_physics),
        cmocka_unit_test(test_cycles_job_follows_physics),
        cmocka_unit_test(test_compare_holds_records_to_the_physics),
        cmocka_unit_test(test_compare_robust_and_terms),
        cmocka_unit_test(test_compare_split_sun_light_masks),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
