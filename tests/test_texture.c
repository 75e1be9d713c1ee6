/* Textures: the sRGB curve against values worked out by hand, the bilinear lookup's texel
 * centres, v direction and repeat wrap on a small image whose texels all differ, PNG and JPEG
 * files written here by libpng/libjpeg and read back, a real JPEG from assimp-testmodels, and
 * the refusals (not an image, a directory, a truncated file). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <jpeglib.h>
#include <png.h>

#include "check.h"
#include "cli_exec.h"
#include "exr.h"
#include "frame.h"
#include "mesh.h"
#include "render.h"
#include "scene_file.h"
#include "shade.h"
#include "texture.h"
#include "tmpdir.h"

static void test_srgb_curve(void **state)
{
    (void)state;
    assert_true(texture_srgb_to_linear(0.0f) == 0.0f);
    close_rel(texture_srgb_to_linear(1.0f), 1.0, 1e-7);
    /* The linear segment's end: 0.04045 / 12.92. */
    close_rel(texture_srgb_to_linear(0.04045f), 0.0031308049535603713, 1e-6);
    /* ((0.5 + 0.055) / 1.055)^2.4 = 0.214041140 (by hand: ln(0.526066) = -0.642328, x 2.4 = -1.541587). */
    close_rel(texture_srgb_to_linear(0.5f), 0.21404114048223255, 1e-6);
    /* 128/255 (an 8-bit mid grey): 0.21586050 */
    close_rel(texture_srgb_to_linear(128.0f / 255.0f), 0.21586050011389926, 1e-6);
}

enum { W = 4, H = 2 };

/* Texel (x, y), row y from the top, holds (x, y, 10 + x + 4 y, 0.1 x). */
static texture make_tex(void)
{
    texture t = {0};
    static float px[W * H * 4];
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            float *p = px + 4 * (y * W + x);
            p[0] = (float)x;
            p[1] = (float)y;
            p[2] = 10.0f + (float)x + 4.0f * (float)y;
            p[3] = 0.1f * (float)x;
        }
    t.width = W;
    t.height = H;
    t.rgba = px;
    return t;
}

static void test_sample_centres(void **state)
{
    (void)state;
    texture t = make_tex();
    float c[4];
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            /* Centre of texel (x, y): u = (x + 0.5)/W, v = 1 - (y + 0.5)/H (v up, row 0 on top). */
            float u = ((float)x + 0.5f) / W, v = 1.0f - ((float)y + 0.5f) / H;
            texture_sample(&t, u, v, c);
            assert_float_equal(c[0], (float)x, 1e-5);
            assert_float_equal(c[1], (float)y, 1e-5);
            assert_float_equal(c[2], 10.0f + (float)x + 4.0f * (float)y, 1e-5);
            assert_float_equal(c[3], 0.1f * (float)x, 1e-6);
        }
    /* Halfway between the centres of columns 1 and 2 in the top row: the mean. */
    texture_sample(&t, 2.0f / W, 0.75f, c);
    assert_float_equal(c[0], 1.5f, 1e-5);
    assert_float_equal(c[1], 0.0f, 1e-6);
    /* A quarter of the way from column 0's centre to column 1's, between the rows. */
    texture_sample(&t, 0.75f / W, 0.5f, c);
    assert_float_equal(c[0], 0.25f, 1e-5);
    assert_float_equal(c[1], 0.5f, 1e-5);
}

static void test_sample_wrap(void **state)
{
    (void)state;
    texture t = make_tex();
    float c[4], d[4];
    /* u = 0 lies between the last column's centre and the first's: repeat mixes them evenly. */
    texture_sample(&t, 0.0f, 0.75f, c);
    assert_float_equal(c[0], 0.5f * (0.0f + (float)(W - 1)), 1e-5);
    /* v = 1 (top edge) lies between the top row and, wrapped, the bottom row. */
    texture_sample(&t, 0.5f / W, 1.0f, c);
    assert_float_equal(c[1], 0.5f, 1e-5);
    /* Whole periods change nothing, either way. */
    const float us[] = {0.1f, 0.37f, 0.9f}, vs[] = {0.2f, 0.61f};
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 2; j++) {
            texture_sample(&t, us[i], vs[j], c);
            texture_sample(&t, us[i] + 3.0f, vs[j] - 2.0f, d);
            for (int k = 0; k < 4; k++)
                assert_float_equal(c[k], d[k], 1e-5);
        }
    /* Non-finite coordinates give a texel, not a crash. */
    texture_sample(&t, NAN, INFINITY, c);
    assert_true(isfinite(c[0]) && isfinite(c[1]));
    /* No texture: white, opaque. */
    texture none = {0};
    texture_sample(&none, 0.3f, 0.3f, c);
    assert_true(c[0] == 1.0f && c[1] == 1.0f && c[2] == 1.0f && c[3] == 1.0f);
    /* The batch form is the scalar one lane by lane. */
    float u[5] = {0.0f, 0.3f, 0.99f, -0.2f, 5.5f}, v[5] = {0.5f, 0.1f, 0.8f, 1.3f, -0.7f};
    float r[5], g[5], b[5], a[5];
    texture_sample_n(&t, 5, u, v, r, g, b, a);
    for (int i = 0; i < 5; i++) {
        texture_sample(&t, u[i], v[i], c);
        assert_true(c[0] == r[i] && c[1] == g[i] && c[2] == b[i] && c[3] == a[i]);
    }
}

static void test_png(void **state)
{
    (void)state;
    /* 3 x 2 RGBA, values chosen so every channel differs. */
    unsigned char px[3 * 2 * 4];
    for (int i = 0; i < 6; i++) {
        px[4 * i + 0] = (unsigned char)(40 * i);
        px[4 * i + 1] = (unsigned char)(255 - 30 * i);
        px[4 * i + 2] = (unsigned char)(7 + 11 * i);
        px[4 * i + 3] = (unsigned char)(255 - 50 * i);
    }
    png_image img;
    memset(&img, 0, sizeof img);
    img.version = PNG_IMAGE_VERSION;
    img.width = 3;
    img.height = 2;
    img.format = PNG_FORMAT_RGBA;
    char path[256];
    snprintf(path, sizeof path, "%s/t.png", tmpdir);
    assert_true(png_image_write_to_file(&img, path, 0, px, 0, NULL));
    texture t;
    char err[512];
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_OK);
    assert_int_equal(t.width, 3);
    assert_int_equal(t.height, 2);
    for (int i = 0; i < 6; i++) {
        for (int c = 0; c < 3; c++)
            close_rel(t.rgba[4 * i + c], texture_srgb_to_linear((float)px[4 * i + c] / 255.0f), 1e-6);
        close_rel(t.rgba[4 * i + 3], px[4 * i + 3] / 255.0, 1e-6);
    }
    texture_free(&t);

    /* Cut after the header: refused as corrupt, with the file named. */
    FILE *f = fopen(path, "rb");
    unsigned char buf[4096];
    size_t n = fread(buf, 1, sizeof buf, f);
    fclose(f);
    snprintf(path, sizeof path, "%s/cut.png", tmpdir);
    f = fopen(path, "wb");
    fwrite(buf, 1, n / 2, f);
    fclose(f);
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, "cut.png"));
    assert_null(t.rgba);
}

static void test_jpeg(void **state)
{
    (void)state;
    /* A flat 16 x 8 colour at quality 100: JPEG's DCT keeps a constant block within one code. */
    enum { JW = 16, JH = 8 };
    unsigned char row[JW * 3];
    for (int x = 0; x < JW; x++) {
        row[3 * x] = 200;
        row[3 * x + 1] = 100;
        row[3 * x + 2] = 50;
    }
    char path[256];
    snprintf(path, sizeof path, "%s/t.jpg", tmpdir);
    FILE *f = fopen(path, "wb");
    struct jpeg_compress_struct ci;
    struct jpeg_error_mgr je;
    ci.err = jpeg_std_error(&je);
    jpeg_create_compress(&ci);
    jpeg_stdio_dest(&ci, f);
    ci.image_width = JW;
    ci.image_height = JH;
    ci.input_components = 3;
    ci.in_color_space = JCS_RGB;
    jpeg_set_defaults(&ci);
    jpeg_set_quality(&ci, 100, TRUE);
    jpeg_start_compress(&ci, TRUE);
    while (ci.next_scanline < JH) {
        JSAMPROW r = row;
        jpeg_write_scanlines(&ci, &r, 1);
    }
    jpeg_finish_compress(&ci);
    jpeg_destroy_compress(&ci);
    fclose(f);
    texture t;
    char err[512];
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_OK);
    assert_int_equal(t.width, JW);
    assert_int_equal(t.height, JH);
    const float want[3] = {200.0f, 100.0f, 50.0f};
    for (int i = 0; i < JW * JH; i++) {
        for (int c = 0; c < 3; c++) {
            /* Within 1 code of the written value (YCbCr rounding), decoded through sRGB. */
            float lo = texture_srgb_to_linear((want[c] - 1.0f) / 255.0f);
            float hi = texture_srgb_to_linear((want[c] + 1.0f) / 255.0f);
            assert_true(t.rgba[4 * i + c] >= lo && t.rgba[4 * i + c] <= hi);
        }
        assert_true(t.rgba[4 * i + 3] == 1.0f);
    }
    texture_free(&t);
}

static void test_real_asset(void **state)
{
    (void)state;
    const char *p = "/usr/share/assimp/models/OBJ/SpiderTex.jpg";
    if (access(p, R_OK) != 0)
        fail_msg("%s missing: install assimp-testmodels (ops/deps.sh does)", p);
    texture t;
    char err[512];
    assert_int_equal(texture_load(p, &t, err, sizeof err), RC_OK);
    /* `file` says: JPEG 249 x 250, 3 components. */
    assert_int_equal(t.width, 249);
    assert_int_equal(t.height, 250);
    double sum = 0.0;
    for (int i = 0; i < t.width * t.height * 4; i++) {
        assert_true(t.rgba[i] >= 0.0f && t.rgba[i] <= 1.0f);
        sum += t.rgba[i];
    }
    assert_true(sum > 0.0);
    texture_free(&t);
}

static void test_refusals(void **state)
{
    (void)state;
    texture t;
    char err[512], path[256];
    snprintf(path, sizeof path, "%s/not_an_image.png", tmpdir);
    FILE *f = fopen(path, "w");
    fputs("hello\n", f);
    fclose(f);
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, "not_an_image.png"));
    assert_int_equal(texture_load(tmpdir, &t, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "directory"));
    snprintf(path, sizeof path, "%s/missing.png", tmpdir);
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_ERR_IO);
    assert_int_equal(texture_load("/dev/zero", &t, err, sizeof err), RC_ERR_RANGE);
}

/* A textured material's terms equal those of the same material with the texel's colour folded
 * into its parameters (the models are linear in them): D3D with ambient, emission and a
 * specular map; D3D9Client with eq. 7's alpha; Cook-Torrance; scalar and SIMD lanes. */
static void shade_pair(model_kind model, float tu, float tv)
{
    static scene s, s2;
    scene_init(&s);
    s.camera.eye = v3(0.3f, 1.0f, 2.0f);
    s.camera.target = v3(0, 0, 0);
    s.global_ambient = v3(0.1f, 0.2f, 0.3f);
    s.n_lights = 1;
    light_init(&s.lights[0]);
    s.lights[0].kind = LIGHT_POINT;
    s.lights[0].position = v3(1.0f, 2.0f, 1.5f);
    s.lights[0].intensity = v3(5, 4, 3);
    s.n_materials = 1;
    material *m = &s.materials[0];
    material_init(m);
    m->model = model;
    m->albedo = v3(0.9f, 0.7f, 0.5f);
    m->d3d.diffuse = v3(0.6f, 0.5f, 0.4f);
    m->d3d.ambient = v3(0.3f, 0.3f, 0.3f);
    m->d3d.emissive = v3(0.05f, 0.02f, 0.01f);
    m->d3d.specular = v3(0.5f, 0.4f, 0.3f);
    m->d3d.power = 20.0f;
    m->d9.p = 3;
    m->d9.r0 = 0.04f;
    m->d9.m = 0.96f;
    m->d9.reflect = v3(0.2f, 0.1f, 0.05f);
    m->d9.fresnel_colour = v3s(1.0f);
    m->d9.alpha = 0.8f;
    m->ct.m = 0.3f;
    m->ct.f0 = v3s(0.04f);
    m->ct.ks = v3(1, 1, 1);
    snprintf(m->texture[MAT_TEX_DIFFUSE], SCENE_PATH_MAX, "grid");
    snprintf(m->texture[MAT_TEX_SPECULAR], SCENE_PATH_MAX, "grid");
    texture t = make_tex();
    /* colours within [0, 1]: scale the test image's channels */
    static float px[W * H * 4];
    for (int i = 0; i < W * H * 4; i++)
        px[i] = t.rgba[i] / (i % 4 == 2 ? 20.0f : 4.0f) + (i % 4 == 3 ? 0.2f : 0.0f);
    t.rgba = px;
    static texture_set ts;
    memset(&ts, 0, sizeof ts);
    ts.map[0][MAT_TEX_DIFFUSE] = t;
    ts.map[0][MAT_TEX_SPECULAR] = t;
    env_map env = {.kind = ENV_CONSTANT, .constant = v3(0.5f, 0.6f, 0.7f)};

    float dif[4], spe[4];
    texture_sample(&t, tu, tv, dif);
    texture_sample(&t, tu, tv, spe);
    /* The same material without textures, the texel folded into its parameters. */
    s2 = s;
    material *m2 = &s2.materials[0];
    memset(m2->texture, 0, sizeof m2->texture);
    vec3 dc = v3(dif[0], dif[1], dif[2]), sc = v3(spe[0], spe[1], spe[2]);
    m2->d3d.diffuse = v3_mul(m2->d3d.diffuse, dc);
    m2->d3d.ambient = v3_mul(m2->d3d.ambient, dc);
    m2->d3d.emissive = v3_mul(m2->d3d.emissive, dc);
    m2->albedo = v3_mul(m2->albedo, dc);
    m2->d3d.specular = v3_mul(m2->d3d.specular, sc);
    m2->ct.ks = v3_mul(m2->ct.ks, sc);
    m2->d9.alpha *= dif[3];

    shade_context c, c2;
    shade_context_make(&s, &env, &c);
    c.tex = &ts;
    shade_context_make(&s2, &env, &c2);
    shade_plan p, p2;
    shade_plan_make(&c, m, &p);
    shade_plan_make(&c2, m2, &p2);
    assert_true(p.textured && !p2.textured);
    vec3 x = v3(0.1f, 0.0f, -0.2f), n = v3_norm(v3(0.1f, 1.0f, 0.2f)), v = v3_norm(v3_sub(s.camera.eye, x));
    shade_terms a, b;
    shade_eval_uv(&c, &p, x, n, v, tu, tv, &a);
    shade_eval(&c2, &p2, x, n, v, &b);
    const vec3 *ta[4] = {&a.diffuse, &a.specular, &a.reflection, &a.emission};
    const vec3 *tb[4] = {&b.diffuse, &b.specular, &b.reflection, &b.emission};
    for (int k = 0; k < 4; k++) {
        assert_float_equal(ta[k]->x, tb[k]->x, 2e-6 * fmaxf(1.0f, fabsf(tb[k]->x)));
        assert_float_equal(ta[k]->y, tb[k]->y, 2e-6 * fmaxf(1.0f, fabsf(tb[k]->y)));
        assert_float_equal(ta[k]->z, tb[k]->z, 2e-6 * fmaxf(1.0f, fabsf(tb[k]->z)));
    }
    /* D3D and Cook-Torrance: alpha = the texel's; D3D9Client: eq. 7 with d_a times it. */
    assert_float_equal(a.alpha, b.alpha * (model == MODEL_D3D9CLIENT ? 1.0f : dif[3]), 1e-6);
    assert_true(fabsf(a.diffuse.x) > 0.0f && fabsf(a.specular.x) > 0.0f);

    /* The SIMD lanes, a lane per sample with its own UV, against the scalar path. */
    shade_batch_in in;
    shade_batch_out out;
    memset(&in, 0, sizeof in);
    in.n = 16;
    for (int i = 0; i < in.n; i++) {
        shade_batch_set_input(&in, i, x, n, v);
        in.tu[i] = tu + 0.07f * (float)i;
        in.tv[i] = tv - 0.05f * (float)i;
    }
    shade_eval_n(&c, &p, &in, &out);
    for (int i = 0; i < in.n; i++) {
        shade_terms l, r;
        shade_batch_get_terms(&out, i, &l);
        shade_eval_uv(&c, &p, x, n, v, in.tu[i], in.tv[i], &r);
        /* shade.h's lane bound: 1.3e-5 relative for Blinn powers up to 40 */
        close_rel(l.diffuse.y, r.diffuse.y, 2e-5);
        close_rel(l.specular.z, r.specular.z, 2e-5);
        close_rel(l.alpha, r.alpha, 2e-5);
    }
}

static void test_shade_textured(void **state)
{
    (void)state;
    const model_kind models[3] = {MODEL_D3D, MODEL_D3D9CLIENT, MODEL_COOK_TORRANCE};
    for (int k = 0; k < 3; k++) {
        shade_pair(models[k], 0.3f, 0.7f);
        shade_pair(models[k], 1.0f / W, 0.25f); /* between texels */
    }
}

/* Generated UVs: the quad's corners, the sphere's u = 1 - phi/2pi, v = 1 - theta/pi at every
 * vertex off the seam and poles. */
static void test_generated_uvs(void **state)
{
    (void)state;
    static scene s;
    scene_init(&s);
    s.n_materials = 1;
    material_init(&s.materials[0]);
    s.n_objects = 2;
    object_init(&s.objects[0]);
    s.objects[0].shape = SHAPE_SPHERE;
    s.objects[0].radius = 2.0f;
    s.objects[0].tessellation = 16;
    object_init(&s.objects[1]);
    s.objects[1].shape = SHAPE_QUAD;
    s.objects[1].size = v3(2, 0, 4);
    s.objects[1].center = v3(0, -5, 0);
    mesh m = {0};
    char err[512];
    assert_int_equal(mesh_build(&s, &m, err, sizeof err), RC_OK);
    int checked = 0;
    for (int i = 0; i < m.n_verts; i++) {
        vec3 p = m.pos[i];
        float u = m.uv[2 * i], v = m.uv[2 * i + 1];
        if (p.y < -4.0f) { /* quad: u = x/2 + 0.5, v = 0.5 - z/4 */
            assert_float_equal(u, p.x / 2.0f + 0.5f, 1e-6);
            assert_float_equal(v, 0.5f - p.z / 4.0f, 1e-6);
            checked++;
            continue;
        }
        if (fabsf(p.y) > 1.999f || u == 0.0f)
            continue; /* poles and the seam column */
        double phi = atan2(p.z, p.x);
        if (phi < 0)
            phi += 2 * TEST_PI;
        assert_float_equal(u, 1.0 - phi / (2 * TEST_PI), 1e-5);
        assert_float_equal(v, 0.5 + asin(p.y / 2.0) / TEST_PI, 1e-5);
        checked++;
    }
    assert_true(checked > 100);
    mesh_free(&m);
}

/* Real UVs: cube_uv.ply's `s t` (Blender's names) and an OBJ's vt with usemtl selecting faces. */
static void test_file_uvs(void **state)
{
    (void)state;
    static scene s;
    scene_init(&s);
    s.n_materials = 1;
    material_init(&s.materials[0]);
    s.n_objects = 1;
    object_init(&s.objects[0]);
    s.objects[0].shape = SHAPE_MESH;
    snprintf(s.objects[0].path, SCENE_PATH_MAX, "/usr/share/assimp/models/PLY/cube_uv.ply");
    mesh m = {0};
    char err[512];
    assert_int_equal(mesh_build(&s, &m, err, sizeof err), RC_OK);
    /* The file's third vertex: -1 -1 -1, normal 0 0 -1, s 1 t 1; its fourth -1 1 -1 ... s 0 t 1. */
    int found = 0;
    for (int i = 0; i < m.n_verts; i++)
        if (m.nrm[i].z < -0.99f && m.pos[i].x == -1.0f && m.pos[i].z == -1.0f) {
            assert_float_equal(m.uv[2 * i], m.pos[i].y < 0.0f ? 1.0f : 0.0f, 1e-6);
            assert_float_equal(m.uv[2 * i + 1], 1.0f, 1e-6);
            found++;
        }
    assert_int_equal(found, 2);
    mesh_free(&m);

    char path[256];
    snprintf(path, sizeof path, "%s/two.obj", tmpdir);
    FILE *f = fopen(path, "w");
    fputs("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvt 0.25 0.75\n"
          "usemtl red\nf 1/1 2/2 3/3\nusemtl blue \nf 2/2 4/4 3/3\nf 1 2 4\nusemtl red\nf 3/4 2 4\n",
          f);
    fclose(f);
    snprintf(s.objects[0].path, SCENE_PATH_MAX, "%s", path);
    int counts[3];
    const char *names[3] = {"", "red", "blue"};
    for (int k = 0; k < 3; k++) {
        snprintf(s.objects[0].usemtl, SCENE_NAME_MAX, "%s", names[k]);
        assert_int_equal(mesh_build(&s, &m, err, sizeof err), RC_OK);
        counts[k] = m.n_tris;
        if (k == 2) { /* blue's first face: 2/2 4/4 3/3 */
            assert_float_equal(m.uv[2 * m.idx[1]], 0.25f, 0);
            assert_float_equal(m.uv[2 * m.idx[1] + 1], 0.75f, 0);
        }
        mesh_free(&m);
    }
    assert_int_equal(counts[0], 4);
    assert_int_equal(counts[1], 2);
    assert_int_equal(counts[2], 2);
    snprintf(s.objects[0].usemtl, SCENE_NAME_MAX, "green");
    assert_int_equal(mesh_build(&s, &m, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "usemtl green"));
    /* A textured material on a mesh without UVs is refused by name. */
    s.objects[0].usemtl[0] = '\0';
    snprintf(s.objects[0].path, SCENE_PATH_MAX, "/usr/share/assimp/models/OBJ/box.obj");
    snprintf(s.materials[0].texture[MAT_TEX_DIFFUSE], SCENE_PATH_MAX, "x.png");
    assert_int_equal(mesh_build(&s, &m, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "texture coordinates"));
}

/* The scene keys, the loader, and a render that refuses textures it was not given. */
static void test_scene_keys(void **state)
{
    (void)state;
    char path[256], err[1024];
    snprintf(path, sizeof path, "%s/t.png", tmpdir); /* written by test_png */
    char text[2048];
    snprintf(text, sizeof text,
             "image: {width: 8, height: 8}\ncamera: {eye: [0, 0, 3], target: [0, 0, 0], hfov: 40}\n"
             "materials:\n  a: {texture: {diffuse: %s}}\n"
             "objects:\n  - {shape: quad, size: [1, 1], rotate: [90, 0, 0], material: a}\n",
             path);
    static scene s;
    assert_int_equal(scene_file_parse(text, strlen(text), "t.yaml", &s, err, sizeof err), RC_OK);
    assert_string_equal(s.materials[0].texture[MAT_TEX_DIFFUSE], path);
    assert_true(s.materials[0].texture[MAT_TEX_SPECULAR][0] == '\0');
    texture_set ts;
    assert_int_equal(frame_textures_load(&s, &ts, err, sizeof err), RC_OK);
    assert_int_equal(ts.map[0][MAT_TEX_DIFFUSE].width, 3);
    mesh m = {0};
    assert_int_equal(mesh_build(&s, &m, err, sizeof err), RC_OK);
    render_options o = {.threads = 1};
    render_image img;
    assert_int_equal(render_scene(&s, &m, NULL, &o, &img, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "not loaded"));
    o.textures = &ts;
    assert_int_equal(render_scene(&s, &m, NULL, &o, &img, err, sizeof err), RC_OK);
    render_image_free(&img);
    mesh_free(&m);
    texture_set_free(&ts);

    /* Refusals, each one line naming the key. */
    const char *bad[] = {"{texture: {diffuse: x.bmp}}", "{texture: {normal: x.png}}", "{texture: {diffuse: nope.png}}"};
    const char *want[] = {"unsupported extension", "normal", "nope.png"};
    for (int i = 0; i < 3; i++) {
        snprintf(text, sizeof text,
                 "image: {width: 8, height: 8}\ncamera: {eye: [0, 0, 3], target: [0, 0, 0], hfov: 40}\n"
                 "materials:\n  a: %s\nobjects:\n  - {shape: quad, size: [1, 1], material: a}\n",
                 bad[i]);
        assert_int_not_equal(scene_file_parse(text, strlen(text), "t.yaml", &s, err, sizeof err), RC_OK);
        assert_non_null(strstr(err, want[i]));
        assert_non_null(strstr(err, "materials.a.texture"));
    }
    snprintf(text, sizeof text,
             "image: {width: 8, height: 8}\ncamera: {eye: [0, 0, 3], target: [0, 0, 0], hfov: 40}\n"
             "materials:\n  a: {}\nobjects:\n  - {shape: mesh, path: /usr/share/assimp/models/PLY/cube_uv.ply, "
             "usemtl: x, material: a}\n");
    assert_int_equal(scene_file_parse(text, strlen(text), "t.yaml", &s, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, "usemtl"));
}

/* A linear EXR texture through frame_textures_load (R, G, B and A kept as written), a negative
 * texel refused by name, and the CLI refusing to write its output over a texture. */
static void test_exr_and_cli(void **state)
{
    (void)state;
    char path[256], err[1024], text[1024];
    float r[6] = {0.5f, 2.0f, 0.0f, 1.0f, 0.25f, 3.0f}, g[6] = {1, 1, 1, 1, 1, 1},
          b[6] = {0, 0.1f, 0.2f, 0.3f, 0.4f, 0.5f};
    float a[6] = {1, 0.5f, 0, 1, 1, 1};
    snprintf(path, sizeof path, "%s/lin.exr", tmpdir);
    exr_channel ch[4] = {{"R", r}, {"G", g}, {"B", b}, {"A", a}};
    assert_int_equal(exr_write(path, 3, 2, ch, 4, NULL, 0, err, sizeof err), RC_OK);
    snprintf(text, sizeof text,
             "image: {width: 8, height: 8}\ncamera: {eye: [0, 0, 3], target: [0, 0, 0], hfov: 40}\n"
             "materials:\n  a: {texture: {specular: %s}}\n"
             "objects:\n  - {shape: quad, size: [1, 1], rotate: [90, 0, 0], material: a}\n",
             path);
    static scene s;
    assert_int_equal(scene_file_parse(text, strlen(text), "t.yaml", &s, err, sizeof err), RC_OK);
    texture_set ts;
    assert_int_equal(frame_textures_load(&s, &ts, err, sizeof err), RC_OK);
    const texture *t = &ts.map[0][MAT_TEX_SPECULAR];
    assert_int_equal(t->width, 3);
    for (int i = 0; i < 6; i++) {
        assert_float_equal(t->rgba[4 * i], r[i], 0); /* linear: no sRGB curve on EXR */
        assert_float_equal(t->rgba[4 * i + 2], b[i], 0);
        assert_float_equal(t->rgba[4 * i + 3], a[i], 0);
    }
    texture_set_free(&ts);
    r[4] = -1.0f;
    assert_int_equal(exr_write(path, 3, 2, ch, 4, NULL, 0, err, sizeof err), RC_OK);
    assert_int_equal(frame_textures_load(&s, &ts, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "materials.a.texture.specular"));
    assert_non_null(strstr(err, "(x 1, y 1) channel R"));

    /* render -o onto the scene's own texture: exit 2, the file untouched. */
    char scn[256], png[256];
    snprintf(png, sizeof png, "%s/t.png", tmpdir);
    snprintf(scn, sizeof scn, "%s/s.yaml", tmpdir);
    FILE *f = fopen(scn, "w");
    fprintf(f, "image: {width: 8, height: 8}\ncamera: {eye: [0, 0, 3], target: [0, 0, 0], hfov: 40}\n"
               "materials:\n  a: {texture: {diffuse: t.png}}\n"
               "objects:\n  - {shape: quad, size: [1, 1], rotate: [90, 0, 0], material: a}\n");
    fclose(f);
    FILE *p = fopen(png, "rb");
    fseek(p, 0, SEEK_END);
    long before = ftell(p);
    fclose(p);
    assert_int_equal(cli_exec(err, sizeof err, "render %s -o %s", scn, png), 2);
    assert_non_null(strstr(err, "a texture of the scene"));
    p = fopen(png, "rb");
    fseek(p, 0, SEEK_END);
    assert_int_equal(ftell(p), before);
    fclose(p);
    snprintf(path, sizeof path, "%s/out.exr", tmpdir);
    assert_int_equal(cli_exec(err, sizeof err, "render %s -o %s", scn, path), 0);
}

/* ---- bad input, third round (issue 20): every file below is written here, then damaged. */

static void put_file(const char *path, const void *buf, size_t n)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(buf, 1, n, f), n);
    fclose(f);
}

/* The whole of a small file into a malloc'd buffer; *n its size. */
static unsigned char *get_file(const char *path, size_t *n)
{
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    fseek(f, 0, SEEK_END);
    long len = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *buf = malloc((size_t)len);
    assert_non_null(buf);
    assert_int_equal(fread(buf, 1, (size_t)len, f), (size_t)len);
    fclose(f);
    *n = (size_t)len;
    return buf;
}

/* A PNG through libpng's full API, so that no gAMA or sRGB chunk is written unless gamma > 0
 * (the simplified writer always adds one). rows: h rows of packed samples, big-endian for 16 bit. */
static void write_png(const char *path, int w, int h, int depth, int colour, const unsigned char *rows, size_t stride,
                      double gamma, int interlace)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    png_structp p = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
    png_infop info = png_create_info_struct(p);
    assert_true(p != NULL && info != NULL);
    if (setjmp(png_jmpbuf(p)))
        fail_msg("libpng could not write %s", path);
    png_init_io(p, f);
    png_set_IHDR(p, info, (png_uint_32)w, (png_uint_32)h, depth, colour,
                 interlace ? PNG_INTERLACE_ADAM7 : PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
                 PNG_FILTER_TYPE_DEFAULT);
    if (colour == PNG_COLOR_TYPE_PALETTE) {
        /* Entry 0 red and half transparent, entry 1 a blue at 128. */
        png_color pal[2] = {{255, 0, 0}, {0, 0, 128}};
        png_byte trans[1] = {128};
        png_set_PLTE(p, info, pal, 2);
        png_set_tRNS(p, info, trans, 1, NULL);
    }
    if (gamma > 0.0)
        png_set_gAMA(p, info, gamma);
    png_write_info(p, info);
    int passes = interlace ? png_set_interlace_handling(p) : 1;
    for (int pass = 0; pass < passes; pass++)
        for (int y = 0; y < h; y++)
            png_write_row(p, rows + (size_t)y * stride);
    png_write_end(p, info);
    png_destroy_write_struct(&p, &info);
    fclose(f);
}

/* A w x h JPEG of pseudo-random texels (so that it does not compress to nothing), quality 90. */
static void write_jpeg(const char *path, int w, int h, int comps, J_COLOR_SPACE cs, int progressive, int arith)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    struct jpeg_compress_struct ci;
    struct jpeg_error_mgr je;
    ci.err = jpeg_std_error(&je);
    jpeg_create_compress(&ci);
    jpeg_stdio_dest(&ci, f);
    ci.image_width = (JDIMENSION)w;
    ci.image_height = (JDIMENSION)h;
    ci.input_components = comps;
    ci.in_color_space = cs;
    jpeg_set_defaults(&ci);
    jpeg_set_quality(&ci, 90, TRUE);
    if (progressive)
        jpeg_simple_progression(&ci);
    ci.arith_code = arith ? TRUE : FALSE;
    jpeg_start_compress(&ci, TRUE);
    unsigned char *row = malloc((size_t)w * (size_t)comps);
    unsigned s = 12345u;
    while (ci.next_scanline < ci.image_height) {
        for (int i = 0; i < w * comps; i++) {
            s = s * 1103515245u + 12345u;
            row[i] = (unsigned char)(s >> 16);
        }
        JSAMPROW r = row;
        jpeg_write_scanlines(&ci, &r, 1);
    }
    jpeg_finish_compress(&ci);
    jpeg_destroy_compress(&ci);
    free(row);
    fclose(f);
}

static void test_png16_is_srgb(void **state)
{
    (void)state;
    /* One row of three RGB texels, 8 bit and 16 bit (v x 257 is v in 16 bits), no gAMA chunk. */
    static const unsigned char v8[9] = {0, 128, 255, 64, 200, 10, 1, 2, 254};
    unsigned char row8[9], row16[18];
    for (int i = 0; i < 9; i++) {
        row8[i] = v8[i];
        row16[2 * i] = row16[2 * i + 1] = v8[i];
    }
    char p8[256], p16[256], err[512];
    snprintf(p8, sizeof p8, "%s/g8.png", tmpdir);
    snprintf(p16, sizeof p16, "%s/g16.png", tmpdir);
    write_png(p8, 3, 1, 8, PNG_COLOR_TYPE_RGB, row8, sizeof row8, 0.0, 0);
    write_png(p16, 3, 1, 16, PNG_COLOR_TYPE_RGB, row16, sizeof row16, 0.0, 0);
    texture a, b;
    assert_int_equal(texture_load(p8, &a, err, sizeof err), RC_OK);
    assert_int_equal(texture_load(p16, &b, err, sizeof err), RC_OK);
    for (int i = 0; i < 3; i++)
        for (int c = 0; c < 3; c++) {
            float want = texture_srgb_to_linear((float)v8[3 * i + c] / 255.0f);
            close_rel(a.rgba[4 * i + c], want, 1e-6);
            /* 128 x 257: the issue's 0.216 (8 bit) against 0.491 (16 bit read as linear). */
            assert_float_equal(b.rgba[4 * i + c], want, 1e-6);
        }
    texture_free(&a);
    texture_free(&b);

    /* 32768 lies between the 8-bit codes 127 and 128: the texel between theirs. */
    unsigned char mid[6] = {0x80, 0x00, 0x80, 0x00, 0x80, 0x00};
    write_png(p16, 1, 1, 16, PNG_COLOR_TYPE_RGB, mid, sizeof mid, 0.0, 0);
    assert_int_equal(texture_load(p16, &b, err, sizeof err), RC_OK);
    assert_true(b.rgba[0] >= texture_srgb_to_linear(127.0f / 255.0f) - 1e-6f);
    assert_true(b.rgba[0] <= texture_srgb_to_linear(128.0f / 255.0f) + 1e-6f);
    texture_free(&b);
    /* A gAMA chunk of 1.0 says linear, and is honoured: 0.5, less libpng's re-encoding to 8 bits
     * with a pure 1/2.2 power rather than the IEC curve: 0.5^(1/2.2) x 255 = 186.1, code 186,
     * which decodes to 0.4910 (a 2 % error the 8-bit reduction brings, not the file). */
    write_png(p16, 1, 1, 16, PNG_COLOR_TYPE_RGB, mid, sizeof mid, 1.0, 0);
    assert_int_equal(texture_load(p16, &b, err, sizeof err), RC_OK);
    assert_float_equal(b.rgba[0], 0.5f, 0.01f);
    texture_free(&b);
}

static void test_jpeg_truncated(void **state)
{
    (void)state;
    char path[256], err[512];
    snprintf(path, sizeof path, "%s/whole.jpg", tmpdir);
    write_jpeg(path, 64, 64, 3, JCS_RGB, 0, 0);
    texture t;
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_OK);
    texture_free(&t);
    size_t n;
    unsigned char *buf = get_file(path, &n);
    /* 75 %, as in the issue: libjpeg warned "Premature end of JPEG file" and filled grey rows. */
    snprintf(path, sizeof path, "%s/cut75.jpg", tmpdir);
    put_file(path, buf, n * 3 / 4);
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, "cut75.jpg"));
    assert_non_null(strstr(err, "truncated JPEG"));
    assert_null(strchr(err, '\n'));
    assert_null(t.rgba);
    /* Only the EOI marker missing: every pixel is there, but the file is cut all the same. */
    put_file(path, buf, n - 2);
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_ERR_PARSE);
    /* Progressive: the same cut is found when the scans are absorbed. */
    snprintf(path, sizeof path, "%s/prog.jpg", tmpdir);
    write_jpeg(path, 64, 64, 3, JCS_RGB, 1, 0);
    free(buf);
    buf = get_file(path, &n);
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_OK);
    assert_int_equal(t.width, 64);
    texture_free(&t);
    put_file(path, buf, n * 3 / 4);
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, "truncated JPEG"));
    free(buf);
}

/* Sets a JPEG's SOF0 height and width (2 bytes each, 5 and 7 bytes after the marker). */
static void jpeg_patch_size(unsigned char *buf, size_t n, int w, int h)
{
    for (size_t i = 2; i + 9 < n; i++)
        if (buf[i] == 0xff && buf[i + 1] == 0xc0) {
            buf[i + 5] = (unsigned char)(h >> 8);
            buf[i + 6] = (unsigned char)h;
            buf[i + 7] = (unsigned char)(w >> 8);
            buf[i + 8] = (unsigned char)w;
            return;
        }
    fail_msg("no SOF0 marker");
}

static void test_jpeg_header_lies(void **state)
{
    (void)state;
    char path[256], err[512];
    snprintf(path, sizeof path, "%s/small.jpg", tmpdir);
    write_jpeg(path, 16, 16, 3, JCS_RGB, 0, 0);
    size_t n;
    unsigned char *buf = get_file(path, &n);
    /* The issue's file: under a kilobyte claiming 16384 x 16384 (was 13 s and 5.0 GB resident).
     * 4:2:0 chroma alone is 1024 x 1024 blocks of at least a bit each: 131072 bytes. */
    jpeg_patch_size(buf, n, 16384, 16384);
    snprintf(path, sizeof path, "%s/huge.jpg", tmpdir);
    put_file(path, buf, n);
    texture t;
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, "huge.jpg"));
    assert_non_null(strstr(err, "16384 x 16384"));
    assert_non_null(strstr(err, "truncated or its header is corrupt"));
    /* 4096 x 4096 needs 4:2:0 chroma's 256 x 256 blocks: 8192 bytes, still more than the file. */
    jpeg_patch_size(buf, n, 4096, 4096);
    put_file(path, buf, n);
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_ERR_PARSE);
    /* 64 x 64: few enough blocks for the file, and then the missing rows are found. */
    jpeg_patch_size(buf, n, 64, 64);
    put_file(path, buf, n);
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, "JPEG"));
    free(buf);
}

static void test_jpeg_unsupported(void **state)
{
    (void)state;
    char path[256], err[512];
    texture t;
    snprintf(path, sizeof path, "%s/cmyk.jpg", tmpdir);
    write_jpeg(path, 16, 16, 4, JCS_CMYK, 0, 0);
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, "cmyk.jpg"));
    assert_non_null(strstr(err, "unsupported colour space (CMYK"));
    assert_non_null(strstr(err, "convert it to RGB"));
    snprintf(path, sizeof path, "%s/arith.jpg", tmpdir);
    write_jpeg(path, 16, 16, 3, JCS_RGB, 0, 1);
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, "arithmetic-coded"));
    /* Grey JPEGs are fine. */
    snprintf(path, sizeof path, "%s/grey.jpg", tmpdir);
    write_jpeg(path, 16, 16, 1, JCS_GRAYSCALE, 0, 0);
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_OK);
    assert_true(t.rgba[0] == t.rgba[1] && t.rgba[1] == t.rgba[2]);
    texture_free(&t);
}

/* PNG's CRC-32 (ISO 3309), bit by bit: fixtures only. */
static unsigned long crc32_png(const unsigned char *p, size_t n)
{
    unsigned long c = 0xffffffffUL;
    for (size_t i = 0; i < n; i++) {
        c ^= p[i];
        for (int k = 0; k < 8; k++)
            c = (c >> 1) ^ (0xedb88320UL & (0UL - (c & 1UL)));
    }
    return c ^ 0xffffffffUL;
}

static void test_png_header_lies(void **state)
{
    (void)state;
    char path[256], err[512];
    unsigned char rows[4 * 3] = {0};
    snprintf(path, sizeof path, "%s/small.png", tmpdir);
    write_png(path, 4, 1, 8, PNG_COLOR_TYPE_RGB, rows, sizeof rows, 0.0, 0);
    size_t n;
    unsigned char *buf = get_file(path, &n);
    /* IHDR claims 16384 x 16384 RGB, its CRC made right: 805 MB of rows cannot come from under
     * a hundred bytes (deflate: at most 1032 bytes out per byte in). */
    buf[18] = buf[22] = 0x40;
    buf[19] = buf[23] = 0;
    buf[16] = buf[17] = buf[20] = buf[21] = 0;
    unsigned long crc = crc32_png(buf + 12, 17);
    for (int k = 0; k < 4; k++)
        buf[29 + k] = (unsigned char)(crc >> (24 - 8 * k));
    snprintf(path, sizeof path, "%s/huge.png", tmpdir);
    put_file(path, buf, n);
    texture t;
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, "huge.png"));
    assert_non_null(strstr(err, "16384 x 16384"));
    /* A bad CRC in IDAT: refused. */
    free(buf);
    snprintf(path, sizeof path, "%s/small.png", tmpdir);
    buf = get_file(path, &n);
    for (size_t i = 8; i + 8 < n; i++)
        if (memcmp(buf + i, "IDAT", 4) == 0) {
            buf[i + 4] ^= 0x01;
            break;
        }
    snprintf(path, sizeof path, "%s/crc.png", tmpdir);
    put_file(path, buf, n);
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, "crc.png"));
    /* Cut after the pixel data, IEND lost (libpng's simplified reader stops at the last row):
     * refused; bytes after IEND are not a cut and are ignored. */
    free(buf);
    snprintf(path, sizeof path, "%s/small.png", tmpdir);
    buf = get_file(path, &n);
    snprintf(path, sizeof path, "%s/noiend.png", tmpdir);
    put_file(path, buf, n - 12);
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, "noiend.png: truncated PNG"));
    unsigned char *tail = malloc(n + 8);
    memcpy(tail, buf, n);
    memcpy(tail + n, "trailing", 8);
    snprintf(path, sizeof path, "%s/tail.png", tmpdir);
    put_file(path, tail, n + 8);
    free(tail);
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_OK);
    texture_free(&t);
    free(buf);
    /* 1 x 65535 black: within the file's bound, refused for its side alone. */
    unsigned char *tall = calloc(65535, 3);
    snprintf(path, sizeof path, "%s/tall.png", tmpdir);
    write_png(path, 1, 65535, 8, PNG_COLOR_TYPE_RGB, tall, 3, 0.0, 0);
    free(tall);
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_ERR_RANGE); /* over 16384 a side */
    assert_non_null(strstr(err, "1 x 65535"));
    /* A valid flat image compresses nearly at deflate's limit (zlib: 1022 bytes out per byte of
     * this file, measured) and still loads: the bound must never refuse a complete file. */
    unsigned char *flat = calloc(16384, 3);
    snprintf(path, sizeof path, "%s/flat.png", tmpdir);
    write_png(path, 16384, 256, 8, PNG_COLOR_TYPE_RGB, flat, 0, 0.0, 0);
    free(flat);
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_OK);
    texture_free(&t);
}

static void test_png_kinds(void **state)
{
    (void)state;
    char path[256], err[512];
    texture t;
    /* Interlaced grey + alpha, 3 x 3: texel i is (10 i, 255 - 20 i). */
    unsigned char ga[3 * 6];
    for (int i = 0; i < 9; i++) {
        ga[2 * i] = (unsigned char)(10 * i);
        ga[2 * i + 1] = (unsigned char)(255 - 20 * i);
    }
    snprintf(path, sizeof path, "%s/ga.png", tmpdir);
    write_png(path, 3, 3, 8, PNG_COLOR_TYPE_GRAY_ALPHA, ga, 6, 0.0, 1);
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_OK);
    for (int i = 0; i < 9; i++) {
        close_rel(t.rgba[4 * i], texture_srgb_to_linear((float)(10 * i) / 255.0f), 1e-6);
        close_rel(t.rgba[4 * i + 2], t.rgba[4 * i], 1e-6);
        close_rel(t.rgba[4 * i + 3], (255.0 - 20.0 * i) / 255.0, 1e-6);
    }
    texture_free(&t);
    /* Palette with tRNS: index 0 red at alpha 128/255, index 1 opaque blue 128. */
    unsigned char idx[2] = {0, 1};
    snprintf(path, sizeof path, "%s/pal.png", tmpdir);
    write_png(path, 2, 1, 8, PNG_COLOR_TYPE_PALETTE, idx, 2, 0.0, 0);
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_OK);
    close_rel(t.rgba[0], 1.0, 1e-6);
    close_rel(t.rgba[3], 128.0 / 255.0, 1e-6);
    close_rel(t.rgba[6], texture_srgb_to_linear(128.0f / 255.0f), 1e-6);
    close_rel(t.rgba[7], 1.0, 1e-6);
    texture_free(&t);
    /* An empty file is no image. */
    snprintf(path, sizeof path, "%s/empty.png", tmpdir);
    put_file(path, "", 0);
    assert_int_equal(texture_load(path, &t, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, "empty.png"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_srgb_curve),
        cmocka_unit_test(test_sample_centres),
        cmocka_unit_test(test_sample_wrap),
        cmocka_unit_test(test_png),
        cmocka_unit_test(test_jpeg),
        cmocka_unit_test(test_real_asset),
        cmocka_unit_test(test_refusals),
        cmocka_unit_test(test_shade_textured),
        cmocka_unit_test(test_generated_uvs),
        cmocka_unit_test(test_file_uvs),
        cmocka_unit_test(test_scene_keys),
        cmocka_unit_test(test_exr_and_cli),
        cmocka_unit_test(test_png16_is_srgb),
        cmocka_unit_test(test_jpeg_truncated),
        cmocka_unit_test(test_jpeg_header_lies),
        cmocka_unit_test(test_jpeg_unsupported),
        cmocka_unit_test(test_png_header_lies),
        cmocka_unit_test(test_png_kinds),
    };
    return cmocka_run_group_tests(tests, tmpdir_setup, tmpdir_teardown);
}
