/* test_assimp.c - assets through libassimp (model/mesh_assimp.h): geometry, materials, the
 * mapping rule, the scene file's import keys and the child process.
 *
 * Expected values are read from the asset files' text by hand, never from the importer:
 *   BoxTextured.gltf (glTF 2.0, assimp-testmodels): 24 vertices (VEC3 accessors, 24 each), 36
 *     indices = 12 triangles, a TEXCOORD_0, one material "Texture" with baseColorTexture
 *     CesiumLogoFlat.png and metallicFactor 0 (roughness absent: glTF's default 1).
 *   kwxport_test_cubewithvcolors.x (DirectX .x): Material top {0.588235 x3, 1;; 52.999996;
 *     0.78 x3;; 0 x3;;} with texture "C:\...\top.tga"; side: power 57, specular 0.7.
 * Runs from the repository root.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "mesh.h"
#include "mesh_assimp.h"
#include "scene_file.h"
#include "tmpdir.h"

#define ASSETS  "/usr/share/assimp/models"
#define BOX     ASSETS "/glTF2/BoxTextured-glTF/BoxTextured.gltf"
#define CUBE_X  ASSETS "/X/kwxport_test_cubewithvcolors.x"
#define OUT_IDX ASSETS "/glTF2/IndexOutOfRange/AllIndicesOutOfRange.gltf"

/* Colours in .x files are written with 6 decimals and stored as float: 1e-6 covers both. */
#define EPS_FILE 1e-6

static void write_file(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
}

static void test_gltf_geometry(void **state)
{
    (void)state;
    mesh_assimp_soup g;
    char err[1024] = "";
    assert_int_equal(mesh_assimp_load(BOX, "", &g, err, sizeof err), RC_OK);
    assert_int_equal(g.n_verts, 24);
    assert_int_equal(g.n_tris, 12);
    for (int v = 0; v < g.n_verts; v++) {
        assert_int_equal(g.has_uv[v], 1);
        /* The box spans [-0.5, 0.5] on each axis (its POSITION accessor's min and max). */
        for (int k = 0; k < 3; k++)
            assert_true(fabs(g.pos[3 * v + k]) <= 0.5 + EPS_FILE);
    }
    /* The same in this process as through the child. */
    mesh_assimp_soup h;
    assert_int_equal(mesh_assimp_import(BOX, "", &h, err, sizeof err), RC_OK);
    assert_memory_equal(g.pos, h.pos, 3 * sizeof(double) * (size_t)g.n_verts);
    assert_memory_equal(g.idx, h.idx, 3 * sizeof(int) * (size_t)g.n_tris);
    mesh_assimp_soup_free(&g);
    mesh_assimp_soup_free(&h);
}

static void test_gltf_material_rule(void **state)
{
    (void)state;
    mesh_assimp_material a;
    char err[1024] = "";
    assert_int_equal(mesh_assimp_material_load(BOX, "Texture", &a, err, sizeof err), RC_OK);
    assert_int_equal(a.pbr, 1);
    assert_float_equal(a.metallic, 0.0, 0.0);
    assert_float_equal(a.roughness, 1.0, 0.0);
    assert_string_equal(a.texture, ASSETS "/glTF2/BoxTextured-glTF/CesiumLogoFlat.png");
    material m;
    material_init(&m);
    m.model = MODEL_COOK_TORRANCE;
    assert_int_equal(mesh_assimp_material_apply(&a, &m), 1);
    /* Dielectric (metallic 0): albedo = base colour (1, default), F0 = 0.04, m = 1^2. */
    assert_float_equal(m.albedo.x, 1.0, 0.0);
    assert_float_equal(m.ct.f0.y, 0.04, 1e-7);
    assert_float_equal(m.roughness, 1.0, 0.0);
    /* P = 2/m^2 - 2 = 0 < 1: no D3D highlight. */
    assert_float_equal(m.d3d.specular.z, 0.0, 0.0);
    assert_string_equal(m.texture[MAT_TEX_DIFFUSE], a.texture);
}

static void test_x_material_rule(void **state)
{
    (void)state;
    mesh_assimp_material a;
    char err[1024] = "";
    assert_int_equal(mesh_assimp_material_load(CUBE_X, "top", &a, err, sizeof err), RC_OK);
    assert_int_equal(a.pbr, 0);
    material m;
    material_init(&m);
    mesh_assimp_material_apply(&a, &m);
    assert_float_equal(m.albedo.x, 0.588235, EPS_FILE);
    assert_float_equal(m.d3d.specular.y, 0.78, EPS_FILE);
    assert_float_equal(m.d3d.power, 52.999996, 1e-4);
    assert_float_equal(m.d3d.emissive.z, 0.0, 0.0);
    /* The authoring path C:\...\top.tga is found by its base name next to the asset. */
    assert_string_equal(m.texture[MAT_TEX_DIFFUSE], ASSETS "/X/top.tga");
    assert_int_equal(mesh_assimp_material_load(CUBE_X, "nosuch", &a, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "'top'"));
}

/* The scene file: the asset's mesh through model/mesh.c's dispatch, one material's faces, the
 * material's keys from the asset and the file's own keys over them. */
static void test_scene_keys(void **state)
{
    (void)state;
    char path[600], err[1024] = "";
    snprintf(path, sizeof path, "%s/x.yaml", tmpdir);
    write_file(path, "name: x\nimage: {width: 8, height: 6}\n"
                     "camera: {eye: [0, 0, 5], target: [0, 0, 0], hfov: 40}\n"
                     "lights: [{type: point, position: [0, 0, 5], intensity: [1, 1, 1]}]\n"
                     "materials:\n"
                     "  side:\n"
                     "    asset: {path: " CUBE_X ", material: side, texture: false}\n"
                     "    d3d: {power: 9}\n"
                     "objects:\n"
                     "  - {shape: mesh, path: " CUBE_X ", usemtl: side, material: side}\n");
    scene s;
    rc_status rc = scene_file_load(path, &s, err, sizeof err);
    if (rc != RC_OK)
        puts(err);
    assert_int_equal(rc, RC_OK);
    assert_float_equal(s.materials[0].d3d.specular.x, 0.7, EPS_FILE);
    assert_float_equal(s.materials[0].d3d.power, 9.0, 0.0);
    assert_string_equal(s.materials[0].texture[MAT_TEX_DIFFUSE], "");
    mesh m = {0};
    assert_int_equal(mesh_build(&s, &m, err, sizeof err), RC_OK);
    /* The cube's side faces: 4 of its 6 quads = 8 triangles (its MeshMaterialList). */
    assert_int_equal(m.n_tris, 8);
    mesh_free(&m);
}

/* Extensions in capitals (Testwuson.X, teapots.DAE in the test models) are the same formats. */
static void test_upper_case_extension(void **state)
{
    (void)state;
    char path[600], err[1024] = "";
    snprintf(path, sizeof path, "%s/u.yaml", tmpdir);
    write_file(path, "name: u\nimage: {width: 8, height: 6}\n"
                     "camera: {eye: [0, 0, 5], target: [0, 0, 0], hfov: 40}\n"
                     "lights: [{type: point, position: [0, 0, 5], intensity: [1, 1, 1]}]\n"
                     "materials: {m: {model: d3d}}\n"
                     "objects: [{shape: mesh, path: " ASSETS "/X/Testwuson.X, material: m}]\n");
    scene s;
    rc_status rc = scene_file_load(path, &s, err, sizeof err);
    if (rc != RC_OK)
        puts(err);
    assert_int_equal(rc, RC_OK);
}

/* A refused asset: one line naming the file, and the process goes on. */
static void test_refused_asset(void **state)
{
    (void)state;
    mesh_assimp_soup g;
    char err[1024] = "";
    assert_int_not_equal(mesh_assimp_load(OUT_IDX, "", &g, err, sizeof err), RC_OK);
    assert_non_null(strstr(err, OUT_IDX));
    assert_null(strchr(err, '\n'));
    char path[600];
    snprintf(path, sizeof path, "%s/bad.gltf", tmpdir);
    write_file(path, "{\"asset\": {\"version\": \"2.0\"}, \"meshes\": [{\"primitives\": [{\"attributes\": {}}]}]}");
    assert_int_not_equal(mesh_assimp_load(path, "", &g, err, sizeof err), RC_OK);
    assert_non_null(strstr(err, path));
    assert_null(strchr(err, '\n'));
    assert_int_equal(g.n_verts, 0);
}

/* An importer asking for far more memory than the limit (invalid/OutOfMemory.off of the test
 * models: libassimp sizes its arrays from a header count) fails in the child at the limit, as one
 * line, instead of paging the machine; this process is untouched. */
static void test_child_memory_limit(void **state)
{
    (void)state;
    mesh_assimp_soup g;
    char err[1024] = "";
    setenv("REFLCHECK_MEMORY_LIMIT", "256M", 1);
    rc_status rc = mesh_assimp_load(ASSETS "/invalid/OutOfMemory.off", "", &g, err, sizeof err);
    unsetenv("REFLCHECK_MEMORY_LIMIT");
    assert_int_not_equal(rc, RC_OK);
    assert_non_null(strstr(err, "OutOfMemory.off"));
    assert_null(strchr(err, '\n'));
    /* The next import still works. */
    assert_int_equal(mesh_assimp_load(BOX, "", &g, err, sizeof err), RC_OK);
    mesh_assimp_soup_free(&g);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_gltf_geometry),        cmocka_unit_test(test_gltf_material_rule),
        cmocka_unit_test(test_x_material_rule),      cmocka_unit_test(test_scene_keys),
        cmocka_unit_test(test_refused_asset),        cmocka_unit_test(test_child_memory_limit),
        cmocka_unit_test(test_upper_case_extension),
    };
    return cmocka_run_group_tests(tests, tmpdir_setup, tmpdir_teardown);
}
