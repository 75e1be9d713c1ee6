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
        fail_msg("%s missing: install assimp-testmodels (harness/deps.sh does)", p);
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

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_srgb_curve), cmocka_unit_test(test_sample_centres), cmocka_unit_test(test_sample_wrap),
        cmocka_unit_test(test_png),        cmocka_unit_test(test_jpeg),           cmocka_unit_test(test_real_asset),
        cmocka_unit_test(test_refusals),   cmocka_unit_test(test_shade_textured), cmocka_unit_test(test_generated_uvs),
        cmocka_unit_test(test_file_uvs),   cmocka_unit_test(test_scene_keys),     cmocka_unit_test(test_exr_and_cli),
    };
    return cmocka_run_group_tests(tests, tmpdir_setup, tmpdir_teardown);
}
