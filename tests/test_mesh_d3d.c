/* test_mesh_d3d.c - object scale with Direct3D's D3DRS_NORMALIZENORMALS off (source 003).
 *
 * The pixel values are worked by hand from the source's formulas: a quad scaled by (2, s_y, 2)
 * has the D3D normal R S^-1 (0, 1, 0) = (0, 1/s_y, 0), so with the unit light L at 60 degrees
 * from the normal and the viewer straight above (H at 30 degrees):
 *   Rd = clamp(0.5 / s_y, 0, 1),  Rs = clamp(cos 30 / s_y, 0, 1)^P.
 * The scene feeds E = pi, so the D3D light colour E/pi is 1, Vd = 0.5, Vs = 0.25, P = 2:
 *   pixel = 0.5 Rd + 0.25 Rs.
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

#include "renderers/cycles/cycles.h"
#include "fileio.h"
#include "mesh.h"
#include "renderers/povray/povray.h"
#include "renderers/registry.h"
#include "render.h"
#include "shade.h"

#define PI 3.14159265358979323846

/* The quad under a sun at 60 degrees, seen from straight above by a 3 x 3 camera whose centre
 * pixel's one sample looks exactly at the quad's centre. */
static void quad_scene(scene *s, float sy, int normalize, int per_vertex)
{
    scene_init(s);
    snprintf(s->path, sizeof s->path, "test_mesh_d3d quad");
    s->width = s->height = 3;
    s->supersample = 1;
    s->camera.eye = v3(0.0f, 5.0f, 0.0f);
    s->camera.target = v3(0.0f, 0.0f, 0.0f);
    s->camera.up = v3(0.0f, 0.0f, -1.0f);
    s->camera.hfov = (float)(2.0 * PI / 180.0);
    s->n_lights = 1;
    s->lights[0].kind = LIGHT_SUN;
    /* The way the light travels: away from L = (sin 60, cos 60, 0). */
    s->lights[0].direction = v3(-(float)sin(PI / 3), -(float)cos(PI / 3), 0.0f);
    s->lights[0].intensity = v3s((float)PI);
    s->n_materials = 1;
    material *m = &s->materials[0];
    m->model = MODEL_D3D;
    m->d3d.diffuse = v3s(0.5f);
    m->d3d.specular = v3s(0.25f);
    m->d3d.power = 2.0f;
    m->d3d.local_viewer = 1;
    m->d3d.normalize_normals = normalize;
    m->d3d.per_vertex = per_vertex;
    s->n_objects = 1;
    object *o = &s->objects[0];
    o->shape = SHAPE_QUAD;
    o->size = v3(1.0f, 1.0f, 1.0f);
    o->scale = v3(2.0f, sy, 2.0f);
    o->material = 0;
}

/* The centre pixel's diffuse and specular layers. */
static void centre_pixel(const scene *s, float *dif, float *spec)
{
    mesh m = {0};
    char err[600];
    assert_int_equal(mesh_build(s, &m, err, sizeof err), RC_OK);
    render_options o = {.threads = 1};
    render_image img;
    if (render_scene(s, &m, NULL, &o, &img, err, sizeof err) != RC_OK)
        fail_msg("render: %s", err);
    int c = 1 * img.width + 1;
    *dif = img.chan[RENDER_DIFFUSE_R][c];
    *spec = img.chan[RENDER_SPECULAR_R][c];
    /* Every layer finite: the clamp keeps a 4x longer normal from anything unbounded. */
    for (int i = 0; i < img.width * img.height; i++)
        assert_true(isfinite(img.chan[RENDER_R][i]));
    render_image_free(&img);
    mesh_free(&m);
}

static void test_hand_pixel(void **state)
{
    (void)state;
    scene *s = malloc(sizeof *s);
    const double c30 = cos(PI / 6);
    static const struct {
        float sy;
        int normalize;
        double rd, rs;
    } cases[] = {
        {4.0f, 0, 0.5 / 4, 0}, /* scaled up: a quarter-length normal, 4x darker diffuse */
        {0.25f, 0, 1.0, 1.0},  /* scaled down: N.L = 2 and N.H = 3.46, both clamped to 1 */
        {4.0f, 1, 0.5, 0},     /* NORMALIZENORMALS on: the scale changes nothing */
        {1.0f, 0, 0.5, 0},     /* off, unscaled: unit normals, the same as on */
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        double rs = cases[i].rs != 0 ? cases[i].rs : pow(cases[i].normalize || cases[i].sy == 1.0f ? c30 : c30 / 4, 2);
        quad_scene(s, cases[i].sy, cases[i].normalize, 0);
        float dif, spec;
        centre_pixel(s, &dif, &spec);
        print_message("s_y %g normalize %d: diffuse %.7g (hand %.7g), specular %.7g (hand %.7g)\n", cases[i].sy,
                      cases[i].normalize, dif, 0.5 * cases[i].rd, spec, 0.25 * rs);
        /* Float shading of a float quad: a few ulps of each factor. */
        assert_float_equal(dif, 0.5 * cases[i].rd, 2e-6);
        assert_float_equal(spec, 0.25 * rs, 2e-6);
    }
    /* Gouraud (D3D's own per-vertex evaluation): the diffuse is the same at every vertex. */
    quad_scene(s, 4.0f, 0, 1);
    float dif, spec;
    centre_pixel(s, &dif, &spec);
    assert_float_equal(dif, 0.5 * 0.125, 2e-6);
    free(s);
}

/* The SIMD lanes and the scalar path agree on normals of any length (the D3D kernels clamp N.L
 * and N.H and never assume |N| = 1), over lengths from 0.1 to 10 and every light kind. */
static void test_lanes_take_any_length(void **state)
{
    (void)state;
    scene *s = malloc(sizeof *s);
    quad_scene(s, 1.0f, 0, 0);
    s->n_lights = 3;
    s->lights[1] = s->lights[0];
    s->lights[1].kind = LIGHT_POINT;
    s->lights[1].position = v3(0.5f, 2.0f, 0.3f);
    s->lights[1].intensity = v3s(3.0f);
    s->lights[1].ambient = v3s(0.1f);
    s->lights[2] = s->lights[1];
    s->lights[2].kind = LIGHT_SPOT;
    s->lights[2].direction = v3(0.0f, -1.0f, 0.0f);
    s->lights[2].inner = 0.5f;
    s->lights[2].outer = 1.2f;
    s->materials[0].d3d.ambient = v3s(0.2f);
    s->materials[0].d3d.power = 20.0f;
    shade_context c;
    shade_context_make(s, NULL, &c);
    shade_plan p;
    shade_plan_make(&c, &s->materials[0], &p);
    shade_batch_in in;
    shade_batch_out out;
    in.n = SHADE_BATCH;
    srand(7);
    for (int i = 0; i < SHADE_BATCH; i++) {
        vec3 n = v3_norm(v3((float)rand() / RAND_MAX - 0.5f, 1.0f, (float)rand() / RAND_MAX - 0.5f));
        float len = powf(10.0f, 2.0f * (float)i / (SHADE_BATCH - 1) - 1.0f);
        vec3 x = v3((float)rand() / RAND_MAX - 0.5f, 0.0f, (float)rand() / RAND_MAX - 0.5f);
        shade_batch_set_input(&in, i, x, v3_scale(n, len), v3_norm(v3_sub(s->camera.eye, x)));
    }
    memset(&out, 0, sizeof out);
    shade_eval_n(&c, &p, &in, &out);
    int clamped = 0;
    for (int i = 0; i < SHADE_BATCH; i++) {
        shade_terms a, b;
        shade_batch_get_terms(&out, i, &a);
        shade_eval(&c, &p, shade_lane_get(&in.x, i), shade_lane_get(&in.nrm, i), shade_lane_get(&in.v, i), &b);
        /* shade.h's lane bound for Blinn powers up to 40: 1.3e-5 relative. */
        assert_float_equal(a.diffuse.x, b.diffuse.x, 1.3e-5 * fmaxf(fabsf(b.diffuse.x), 1e-3f));
        assert_float_equal(a.specular.x, b.specular.x, 1.3e-5 * fmaxf(fabsf(b.specular.x), 1e-3f));
        clamped += b.specular.x > 0.0f && v3_len(shade_lane_get(&in.nrm, i)) > 2.0f;
    }
    assert_true(clamped > 0); /* lanes where N.H > 1 was clamped were among them */
    free(s);
}

/* No reference renders unnormalised normals: both translators refuse a twin, naming the key;
 * a validate (the physical scene) is written. */
static void test_translators_refuse_twin(void **state)
{
    (void)state;
    scene *s = malloc(sizeof *s);
    quad_scene(s, 4.0f, 0, 0);
    s->materials[0].d3d.specular = v3s(0.0f);
    mesh m = {0};
    char err[1024] = "";
    assert_int_equal(mesh_build(s, &m, err, sizeof err), RC_OK);
    assert_true(mesh_material_unnormalised(s, 0));
    povray_options po = {0};
    assert_int_equal(povray_write_scene(s, &m, &po, "/tmp/reflcheck_mesh_d3d.pov", err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "normalize_normals false"));
    assert_non_null(strstr(err, "role validate"));
    po.role = ROLE_VALIDATE;
    s->physics.specular_lights = 0; /* POV-Ray's validate has no highlight of lamps (the manifest says so) */
    if (povray_write_scene(s, &m, &po, "/tmp/reflcheck_mesh_d3d.pov", err, sizeof err) != RC_OK)
        fail_msg("%s", err);
    cycles_options co = {.width = 4, .height = 4}; /* Cycles' smallest image */
    assert_int_equal(cycles_write_job(s, &m, &co, "/tmp/reflcheck_mesh_d3d.json", err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "normalize_normals false"));
    co.role = ROLE_VALIDATE;
    assert_int_equal(cycles_write_job(s, &m, &co, "/tmp/reflcheck_mesh_d3d.json", err, sizeof err), RC_OK);
    /* EEVEE through its render entry (it refuses before starting Blender; xvfb-run is installed
     * by ops/deps.sh as its row's package needs). */
    renderer_job ej = {.s = s, .m = &m, .role = ROLE_TWIN, .dir = "/tmp", .exr = "/tmp/reflcheck_mesh_d3d.exr"};
    renderer_result er = {0};
    registry_row(registry_find("eevee"))->render(&ej, &er);
    assert_int_equal(er.status, RUNNER_MISSING);
    if (strstr(er.message, "normalize_normals false") == NULL)
        fail_msg("eevee: %s", er.message);
    /* Unscaled, "off" changes nothing, and the twin is written. */
    s->objects[0].scale = v3s(1.0f);
    assert_false(mesh_material_unnormalised(s, 0));
    po.role = ROLE_TWIN;
    mesh_free(&m);
    assert_int_equal(mesh_build(s, &m, err, sizeof err), RC_OK);
    if (povray_write_scene(s, &m, &po, "/tmp/reflcheck_mesh_d3d.pov", err, sizeof err) != RC_OK)
        fail_msg("%s", err);
    remove("/tmp/reflcheck_mesh_d3d.pov");
    remove("/tmp/reflcheck_mesh_d3d.json");
    mesh_free(&m);
    free(s);
}

/* Vertex colours as the files give them: a real OBJ (assimp-testmodels), a uchar/float PLY. */
static void test_vertex_colours_read(void **state)
{
    (void)state;
    scene *s = malloc(sizeof *s);
    scene_init(s);
    s->n_materials = 1;
    s->n_objects = 1;
    s->objects[0].shape = SHAPE_MESH;
    snprintf(s->objects[0].path, sizeof s->objects[0].path, "/usr/share/assimp/models/OBJ/cube_with_vertexcolors.obj");
    mesh m = {0};
    char err[600];
    if (mesh_build(s, &m, err, sizeof err) != RC_OK)
        fail_msg("%s (apt-get install assimp-testmodels)", err);
    assert_int_equal(m.colours[0], 1);
    int seen = 0;
    for (int i = 0; i < m.n_verts; i++)
        if (m.pos[i].x == 0.0f && m.pos[i].y == 0.0f && m.pos[i].z == 0.0f) { /* its line 3 */
            assert_float_equal(m.col1[i].x, 0.48627, 1e-7);
            assert_float_equal(m.col1[i].y, 0.43137, 1e-7);
            assert_float_equal(m.col1[i].z, 0.47059, 1e-7);
            seen++;
        }
    assert_true(seen > 0);
    mesh_free(&m);

    snprintf(s->objects[0].path, sizeof s->objects[0].path, "tests/fixtures/meshes/colour_tri.ply");
    assert_int_equal(mesh_build(s, &m, err, sizeof err), RC_OK);
    assert_int_equal(m.colours[0], 3);
    for (int i = 0; i < m.n_verts; i++)
        if (m.pos[i].x == 0.0f && m.pos[i].y == 0.0f) {
            assert_float_equal(m.col1[i].x, 1.0, 0);
            assert_float_equal(m.col1[i].z, 51.0 / 255.0, 1e-7);
            assert_float_equal(m.col2[i].x, 0.5, 0);
            assert_float_equal(m.col2[i].y, 0.25, 0);
        }
    mesh_free(&m);

    snprintf(s->objects[0].path, sizeof s->objects[0].path, "tests/fixtures/meshes/colour_partial.obj");
    assert_int_equal(mesh_build(s, &m, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, "1 of 3 vertices carry a colour"));
    free(s);
}

/* The four colour sources by hand on colour_quad.obj under the quad scene's light (Rd = 0.5,
 * Rs = cos^2 30 = 0.75, light colour 1): at the centre the interpolated colour1 is
 * c = (0.2, 0.4, 0.6) and the file has no colour2. */
static void test_vertex_colour_sources(void **state)
{
    (void)state;
    scene *s = malloc(sizeof *s);
    static const struct {
        int on, per_vertex;
        colour_source amb, dif, spec, emis;
        double d[3], sp[3], e[3];
    } cases[] = {
        /* D3D's default sources: diffuse from colour1, specular from colour2 (absent: material). */
        {1,
         0,
         COLOUR_SOURCE_MATERIAL,
         COLOUR_SOURCE_COLOUR1,
         COLOUR_SOURCE_COLOUR2,
         COLOUR_SOURCE_MATERIAL,
         {0.1, 0.2, 0.3},
         {0.1875, 0.1875, 0.1875},
         {0, 0, 0}},
        /* D3DRS_COLORVERTEX off: the material alone. */
        {0,
         0,
         COLOUR_SOURCE_MATERIAL,
         COLOUR_SOURCE_COLOUR1,
         COLOUR_SOURCE_COLOUR2,
         COLOUR_SOURCE_MATERIAL,
         {0.25, 0.25, 0.25},
         {0.1875, 0.1875, 0.1875},
         {0, 0, 0}},
        /* Specular and emissive from colour1. */
        {1,
         0,
         COLOUR_SOURCE_MATERIAL,
         COLOUR_SOURCE_MATERIAL,
         COLOUR_SOURCE_COLOUR1,
         COLOUR_SOURCE_COLOUR1,
         {0.25, 0.25, 0.25},
         {0.15, 0.3, 0.45},
         {0.2, 0.4, 0.6}},
        /* Gouraud, D3D's own case: lit colours interpolated, the same at the centre (linear). */
        {1,
         1,
         COLOUR_SOURCE_MATERIAL,
         COLOUR_SOURCE_COLOUR1,
         COLOUR_SOURCE_COLOUR2,
         COLOUR_SOURCE_MATERIAL,
         {0.1, 0.2, 0.3},
         {-1, -1, -1},
         {0, 0, 0}},
    };
    for (size_t k = 0; k < sizeof cases / sizeof *cases; k++) {
        quad_scene(s, 1.0f, 1, cases[k].per_vertex);
        object *o = &s->objects[0];
        o->shape = SHAPE_MESH;
        o->scale = v3s(1.0f);
        snprintf(o->path, sizeof o->path, "tests/fixtures/meshes/colour_quad.obj");
        d3d_params *d = &s->materials[0].d3d;
        d->colour_vertex = cases[k].on;
        d->ambient_source = cases[k].amb;
        d->diffuse_source = cases[k].dif;
        d->specular_source = cases[k].spec;
        d->emissive_source = cases[k].emis;
        mesh m = {0};
        char err[600];
        assert_int_equal(mesh_build(s, &m, err, sizeof err), RC_OK);
        assert_int_equal(mesh_material_vertex_coloured(s, &m, 0), cases[k].on);
        render_options ro = {.threads = 1};
        render_image img;
        if (render_scene(s, &m, NULL, &ro, &img, err, sizeof err) != RC_OK)
            fail_msg("render: %s", err);
        int c = img.width + 1;
        for (int ch = 0; ch < 3; ch++) {
            print_message("case %zu ch %d: diffuse %.7g specular %.7g emission %.7g\n", k, ch,
                          img.chan[RENDER_DIFFUSE_R + ch][c], img.chan[RENDER_SPECULAR_R + ch][c],
                          img.chan[RENDER_EMISSION_R + ch][c]);
            /* Float colours and factors: a few ulps. */
            assert_float_equal(img.chan[RENDER_DIFFUSE_R + ch][c], cases[k].d[ch], 3e-6);
            if (cases[k].sp[ch] >= 0)
                assert_float_equal(img.chan[RENDER_SPECULAR_R + ch][c], cases[k].sp[ch], 3e-6);
            assert_float_equal(img.chan[RENDER_EMISSION_R + ch][c], cases[k].e[ch], 3e-6);
        }
        render_image_free(&img);
        /* No reference translates vertex colours: each says so. */
        if (cases[k].on) {
            povray_options po = {.role = ROLE_VALIDATE};
            assert_int_equal(povray_write_scene(s, &m, &po, "/tmp/reflcheck_mesh_vc.pov", err, sizeof err),
                             RC_ERR_RANGE);
            assert_non_null(strstr(err, "vertex colours"));
            cycles_options co = {.width = 4, .height = 4, .role = ROLE_VALIDATE};
            assert_int_equal(cycles_write_job(s, &m, &co, "/tmp/reflcheck_mesh_vc.json", err, sizeof err),
                             RC_ERR_RANGE);
            assert_non_null(strstr(err, "vertex colours"));
            /* The twins take the diffuse source alone from the vertex (case 0: a colour attribute
             * for Cycles, a texture_list for POV-Ray); specular or emissive from it (case 2) is
             * refused. Cycles is partial here: no Blinn lobe. */
            co.role = ROLE_TWIN;
            co.partial = 1;
            po.role = ROLE_TWIN;
            /* Gouraud (case 3) has no twin at all. */
            rc_status want =
                cases[k].dif == COLOUR_SOURCE_COLOUR1 && cases[k].spec != COLOUR_SOURCE_COLOUR1 && !cases[k].per_vertex
                    ? RC_OK
                    : RC_ERR_RANGE;
            if (cycles_write_job(s, &m, &co, "/tmp/reflcheck_mesh_vc.json", err, sizeof err) != want)
                fail_msg("case %zu cycles twin: %s", k, err);
            if (want == RC_OK) {
                char *json = fileio_read_all("/tmp/reflcheck_mesh_vc.json", NULL);
                assert_non_null(json);
                assert_non_null(strstr(json, "\"vertex_colour\""));
                assert_non_null(strstr(json, "\"colours\""));
                free(json);
            }
            if (povray_write_scene(s, &m, &po, "/tmp/reflcheck_mesh_vc.pov", err, sizeof err) != want)
                fail_msg("case %zu povray twin: %s", k, err);
            renderer_job ej = {.s = s, .m = &m, .role = ROLE_VALIDATE, .exr = "/tmp/reflcheck_mesh_vc.exr"};
            renderer_result er = {0};
            registry_row(registry_find("exact"))->render(&ej, &er);
            assert_int_equal(er.status, RUNNER_MISSING);
            assert_non_null(strstr(er.message, "vertex colours"));
            for (int role = 0; role < 2; role++) {
                renderer_job vj = {.s = s,
                                   .m = &m,
                                   .role = role ? ROLE_VALIDATE : ROLE_TWIN,
                                   .dir = "/tmp",
                                   .exr = "/tmp/reflcheck_mesh_vc.exr"};
                renderer_result vr = {0};
                registry_row(registry_find("eevee"))->render(&vj, &vr);
                assert_int_equal(vr.status, RUNNER_MISSING);
                if (role == 0 && strstr(vr.message, "vertex colours") == NULL)
                    fail_msg("eevee twin: %s", vr.message);
            }
        }
        mesh_free(&m);
    }
    free(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_hand_pixel),
        cmocka_unit_test(test_lanes_take_any_length),
        cmocka_unit_test(test_translators_refuse_twin),
        cmocka_unit_test(test_vertex_colours_read),
        cmocka_unit_test(test_vertex_colour_sources),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
