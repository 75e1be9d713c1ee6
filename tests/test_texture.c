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
#include "texture.h"

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

static char tmpdir[] = "/tmp/reflcheck_texture_XXXXXX";

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

static int setup(void **state)
{
    (void)state;
    return mkdtemp(tmpdir) == NULL ? -1 : 0;
}

static int teardown(void **state)
{
    (void)state;
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    return system(cmd) == 0 ? 0 : -1;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_srgb_curve), cmocka_unit_test(test_sample_centres), cmocka_unit_test(test_sample_wrap),
        cmocka_unit_test(test_png),        cmocka_unit_test(test_jpeg),           cmocka_unit_test(test_real_asset),
        cmocka_unit_test(test_refusals),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
