/* texture.c - texture images (libpng, libjpeg) and their bilinear, repeat-wrapped lookup.
 *
 * PNG and JPEG are decoded by Debian's libpng 1.6 (simplified API) and libjpeg-turbo, the
 * libraries every engine's tool chain carries. DDS comes through the harness's OpenImageIO shim
 * (scene/image_oiio.h) into texture_from_srgb8 / texture_from_rgba, so this library stays C
 * with no OpenImageIO dependency (docs/cubemaps.md). */
#include "texture.h"

#include <limits.h>
#include <math.h>
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <jpeglib.h>
#include <jerror.h>
#include <png.h>

#include "fileio.h"

float texture_srgb_to_linear(float c)
{
    double x = c;
    /* IEC 61966-2-1: the linear segment below 0.04045, the 2.4 power above. */
    double y = x <= 0.04045 ? x / 12.92 : pow((x + 0.055) / 1.055, 2.4);
    return (float)y;
}

void texture_free(texture *t)
{
    free(t->rgba);
    t->rgba = NULL;
    t->width = t->height = 0;
}

void texture_set_free(texture_set *ts)
{
    for (int m = 0; m < SCENE_MAX_MATERIALS; m++)
        for (int k = 0; k < MAT_TEX_SLOTS; k++)
            texture_free(&ts->map[m][k]);
}

static rc_status texture_check_side(const char *path, long long w, long long h, char *err, size_t errlen)
{
    if (w <= 0 || h <= 0 || w > TEXTURE_MAX_SIDE || h > TEXTURE_MAX_SIDE) {
        status_message(err, errlen, "%s: image is %lld x %lld pixels; give a texture of 1..%d pixels a side", path, w,
                       h, TEXTURE_MAX_SIDE);
        return RC_ERR_RANGE;
    }
    return RC_OK;
}

static rc_status texture_alloc(const char *path, int w, int h, texture *t, char *err, size_t errlen)
{
    rc_status rc = texture_check_side(path, w, h, err, errlen);
    if (rc != RC_OK)
        return rc;
    size_t limit = 0;
    char why[256];
    if (fileio_memory_limit(&limit, why, sizeof why) != RC_OK) {
        status_message(err, errlen, "%s: %s", path, why);
        return RC_ERR_RANGE;
    }
    double need = (double)w * (double)h * 4.0 * sizeof(float);
    if (need > (double)limit) {
        status_message(err, errlen,
                       "%s: a %d x %d texture needs %.2f GiB as float RGBA, over the memory limit; give a smaller "
                       "image or raise REFLCHECK_MEMORY_LIMIT",
                       path, w, h, need / 1073741824.0);
        return RC_ERR_RANGE;
    }
    t->rgba = malloc((size_t)w * (size_t)h * 4 * sizeof(float));
    if (t->rgba == NULL) {
        status_message(err, errlen, "%s: out of memory for a %d x %d texture", path, w, h);
        return RC_ERR_NOMEM;
    }
    t->width = w;
    t->height = h;
    return RC_OK;
}

/* 8-bit sRGB RGBA (or RGB when channels is 3) into linear floats, through a 256-entry table. */
static void texture_decode8(const unsigned char *src, int channels, texture *t)
{
    float lut[256];
    for (int i = 0; i < 256; i++)
        lut[i] = texture_srgb_to_linear((float)i / 255.0f);
    size_t n = (size_t)t->width * (size_t)t->height;
    for (size_t i = 0; i < n; i++) {
        const unsigned char *p = src + i * (size_t)channels;
        float *q = t->rgba + 4 * i;
        q[0] = lut[p[0]];
        q[1] = lut[p[1]];
        q[2] = lut[p[2]];
        q[3] = channels == 4 ? (float)p[3] / 255.0f : 1.0f;
    }
}

/* Deflate's largest expansion: a 258-byte match coded in 2 bits (1-bit length and distance
 * codes), 1032 decoded bytes per byte; PNG's filtered rows are the deflate stream's output. */
#define TEXTURE_DEFLATE_MAX_RATIO 1032.0

/* The bytes a PNG's IDAT stream must inflate to: one filter byte and the packed samples per row
 * (IHDR, which libpng has checked, sits at bytes 16..25; interlacing only adds rows). */
static double texture_png_raw_bytes(const unsigned char *buf)
{
    static const int channels[7] = {1, 0, 3, 1, 2, 0, 4}; /* by colour type */
    double w = (double)((unsigned long)buf[16] << 24 | (unsigned long)buf[17] << 16 | buf[18] << 8 | buf[19]);
    double h = (double)((unsigned long)buf[20] << 24 | (unsigned long)buf[21] << 16 | buf[22] << 8 | buf[23]);
    int bits = buf[24] * (buf[25] < 7 ? channels[buf[25]] : 4);
    return h * (1.0 + ceil(w * bits / 8.0));
}

/* 1 when the chunks from the signature on end with IEND inside the file: libpng's simplified
 * reader stops after the last row and takes a file cut after its pixel data (IEND missing). */
static int texture_png_complete(const unsigned char *buf, size_t len)
{
    size_t at = 8;
    while (len - at >= 12) {
        size_t n = (size_t)buf[at] << 24 | (size_t)buf[at + 1] << 16 | (size_t)buf[at + 2] << 8 | buf[at + 3];
        if (n > len - at - 12)
            return 0;
        if (memcmp(buf + at + 4, "IEND", 4) == 0)
            return 1;
        at += n + 12;
    }
    return 0;
}

static rc_status texture_png(const char *path, const unsigned char *buf, size_t len, texture *t, char *err,
                             size_t errlen)
{
    png_image img;
    memset(&img, 0, sizeof img);
    img.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_memory(&img, buf, len)) {
        status_message(err, errlen, "%s: not a readable PNG (%s); give a valid PNG or JPEG file", path, img.message);
        return RC_ERR_PARSE;
    }
    /* 8-bit sRGB RGBA whatever the file holds (grey, palette, 16 bit): our own decode follows.
     * A gAMA, sRGB or cHRM chunk is honoured; without one, libpng would take 16-bit samples as
     * linear, 8-bit ones as sRGB: the flag makes both sRGB, this project's convention for
     * textures (scenes/FORMAT.md), so the 8- and 16-bit saves of one image give the same texels. */
    img.format = PNG_FORMAT_RGBA;
    img.flags |= PNG_IMAGE_FLAG_16BIT_sRGB;
    double w = img.width, h = img.height;
    rc_status rc = texture_check_side(path, img.width, img.height, err, errlen);
    if (rc == RC_OK)
        rc = fileio_image_budget(path, "PNG", img.width, img.height,
                                 texture_png_raw_bytes(buf) / TEXTURE_DEFLATE_MAX_RATIO, (long long)len,
                                 w * h * (4.0 + 4.0 * sizeof(float)), err, errlen);
    if (rc != RC_OK) {
        png_image_free(&img);
        return rc;
    }
    unsigned char *px = malloc(PNG_IMAGE_SIZE(img));
    if (px == NULL) {
        png_image_free(&img);
        status_message(err, errlen, "%s: out of memory decoding the PNG", path);
        return RC_ERR_NOMEM;
    }
    if (!png_image_finish_read(&img, NULL, px, 0, NULL)) {
        status_message(err, errlen, "%s: corrupt or truncated PNG (%s); give a complete, valid PNG file", path,
                       img.message);
        free(px);
        return RC_ERR_PARSE;
    }
    if (!texture_png_complete(buf, len)) {
        status_message(err, errlen, "%s: truncated PNG (no IEND chunk after the image data); give the complete file",
                       path);
        free(px);
        return RC_ERR_PARSE;
    }
    rc = texture_alloc(path, (int)img.width, (int)img.height, t, err, errlen);
    if (rc == RC_OK)
        texture_decode8(px, 4, t);
    free(px);
    return rc;
}

typedef struct {
    struct jpeg_error_mgr pub;
    jmp_buf jump;
    char msg[JMSG_LENGTH_MAX];
} texture_jpeg_err;

static void texture_jpeg_fail(j_common_ptr cinfo)
{
    texture_jpeg_err *e = (texture_jpeg_err *)cinfo->err;
    (*cinfo->err->format_message)(cinfo, e->msg);
    longjmp(e->jump, 1);
}

/* libjpeg only warns about lost data (a cut file, a bad Huffman code) and fills the rest with
 * grey; here that is an error. Warnings that lose no pixel (stray bytes between segments, an
 * unknown JFIF revision or Adobe transform code, a bad ICC profile, which we do not read) pass,
 * silently; trace messages (level > 0) too. */
static void texture_jpeg_warn(j_common_ptr cinfo, int level)
{
    int code = cinfo->err->msg_code;
    if (level >= 0 || code == JWRN_EXTRANEOUS_DATA || code == JWRN_JFIF_MAJOR || code == JWRN_ADOBE_XFORM ||
        code == JWRN_BOGUS_ICC)
        return;
    texture_jpeg_fail(cinfo);
}

static const char *texture_jpeg_space(J_COLOR_SPACE cs)
{
    switch (cs) {
    case JCS_CMYK: return "CMYK";
    case JCS_YCCK: return "YCCK";
    default: return "unknown";
    }
}

/* Refuses what this reader cannot decode, or a header the file's size cannot back, before
 * jpeg_start_decompress allocates (a progressive file's coefficients: 2 bytes per sample). */
static rc_status texture_jpeg_check(const char *path, struct jpeg_decompress_struct *ci, size_t len, char *err,
                                    size_t errlen)
{
    J_COLOR_SPACE cs = ci->jpeg_color_space;
    if (cs != JCS_GRAYSCALE && cs != JCS_YCbCr && cs != JCS_RGB) {
        status_message(err, errlen,
                       "%s: unsupported colour space (%s, %d components) in the JPEG header; convert it "
                       "to RGB",
                       path, texture_jpeg_space(cs), ci->num_components);
        return RC_ERR_PARSE;
    }
    /* Arithmetic coding can code a flat block in a small fraction of a bit, so no file size bounds
     * the image; no engine, browser or DCC tool writes it. */
    if (ci->arith_code) {
        status_message(err, errlen,
                       "%s: arithmetic-coded JPEG (SOF%d) is unsupported; re-save it with Huffman "
                       "coding (every encoder's default)",
                       path, ci->progressive_mode ? 10 : 9);
        return RC_ERR_PARSE;
    }
    if (ci->progressive_mode && ci->Ss != 0) {
        status_message(err, errlen,
                       "%s: progressive JPEG whose first scan is not a DC scan: corrupt; give a valid "
                       "JPEG file",
                       path);
        return RC_ERR_PARSE;
    }
    rc_status rc = texture_check_side(path, ci->image_width, ci->image_height, err, errlen);
    if (rc != RC_OK)
        return rc;
    /* The first scan codes every block of its components with a Huffman code of at least one bit
     * (a DC difference, or a bit of DC refinement), so the file holds at least that many bits. */
    double blocks = 0.0;
    for (int i = 0; i < ci->comps_in_scan; i++)
        blocks += (double)ci->cur_comp_info[i]->width_in_blocks * (double)ci->cur_comp_info[i]->height_in_blocks;
    double w = ci->image_width, h = ci->image_height;
    double coef = ci->progressive_mode ? w * h * ci->num_components * 2.0 : 0.0;
    return fileio_image_budget(path, "JPEG", ci->image_width, ci->image_height, blocks / 8.0, (long long)len,
                               w * h * (3.0 + 4.0 * sizeof(float)) + coef, err, errlen);
}

static rc_status texture_jpeg(const char *path, const unsigned char *buf, size_t len, texture *t, char *err,
                              size_t errlen)
{
    struct jpeg_decompress_struct ci;
    texture_jpeg_err je;
    unsigned char *volatile px = NULL;
    ci.err = jpeg_std_error(&je.pub);
    je.pub.error_exit = texture_jpeg_fail;
    je.pub.emit_message = texture_jpeg_warn;
    je.msg[0] = '\0';
    if (setjmp(je.jump)) {
        jpeg_destroy_decompress(&ci);
        free(px);
        texture_free(t);
        int cut = je.pub.msg_code == JWRN_JPEG_EOF || je.pub.msg_code == JERR_INPUT_EOF;
        status_message(err, errlen, "%s: %s JPEG (%s); give a complete, valid PNG or JPEG file", path,
                       cut ? "truncated" : "corrupt", je.msg);
        return RC_ERR_PARSE;
    }
    jpeg_create_decompress(&ci);
    jpeg_mem_src(&ci, buf, (unsigned long)len);
    jpeg_read_header(&ci, TRUE);
    rc_status rc = texture_jpeg_check(path, &ci, len, err, errlen);
    if (rc != RC_OK) {
        jpeg_destroy_decompress(&ci);
        return rc;
    }
    ci.out_color_space = JCS_RGB;
    jpeg_start_decompress(&ci);
    size_t row = (size_t)ci.output_width * 3;
    px = malloc(row * ci.output_height);
    if (px == NULL) {
        jpeg_destroy_decompress(&ci);
        status_message(err, errlen, "%s: out of memory decoding the JPEG", path);
        return RC_ERR_NOMEM;
    }
    while (ci.output_scanline < ci.output_height) {
        JSAMPROW r = px + row * ci.output_scanline;
        jpeg_read_scanlines(&ci, &r, 1);
    }
    jpeg_finish_decompress(&ci);
    int w = (int)ci.output_width, h = (int)ci.output_height;
    jpeg_destroy_decompress(&ci);
    rc = texture_alloc(path, w, h, t, err, errlen);
    if (rc == RC_OK)
        texture_decode8(px, 3, t);
    free(px);
    return rc;
}

rc_status texture_load(const char *path, texture *t, char *err, size_t errlen)
{
    memset(t, 0, sizeof *t);
    unsigned char *buf = NULL;
    size_t len = 0;
    rc_status rc = fileio_read_input(path, TEXTURE_MAX_BYTES, "a PNG or JPEG texture", &buf, &len, err, errlen);
    if (rc != RC_OK)
        return rc;
    static const unsigned char png_sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    /* By content, not by name: a .jpg that holds a PNG still loads. */
    if (len >= 8 && memcmp(buf, png_sig, 8) == 0)
        rc = texture_png(path, buf, len, t, err, errlen);
    else if (len >= 3 && buf[0] == 0xff && buf[1] == 0xd8 && buf[2] == 0xff)
        rc = texture_jpeg(path, buf, len, t, err, errlen);
    else {
        status_message(err, errlen, "%s: neither a PNG nor a JPEG file; give a PNG, JPEG or linear EXR texture", path);
        rc = RC_ERR_PARSE;
    }
    free(buf);
    return rc;
}

rc_status texture_from_srgb8(int w, int h, const unsigned char *rgba, texture *t, char *err, size_t errlen)
{
    memset(t, 0, sizeof *t);
    rc_status rc = texture_alloc("texture", w, h, t, err, errlen);
    if (rc == RC_OK)
        texture_decode8(rgba, 4, t);
    return rc;
}

rc_status texture_from_rgba(int w, int h, const float *rgba, texture *t, char *err, size_t errlen)
{
    memset(t, 0, sizeof *t);
    rc_status rc = texture_alloc("texture", w, h, t, err, errlen);
    if (rc == RC_OK)
        memcpy(t->rgba, rgba, (size_t)w * (size_t)h * 4 * sizeof *rgba);
    return rc;
}

rc_status texture_from_planes(int w, int h, const float *r, const float *g, const float *b, const float *a, texture *t,
                              char *err, size_t errlen)
{
    memset(t, 0, sizeof *t);
    rc_status rc = texture_alloc("texture", w, h, t, err, errlen);
    if (rc != RC_OK)
        return rc;
    size_t n = (size_t)w * (size_t)h;
    for (size_t i = 0; i < n; i++) {
        float *q = t->rgba + 4 * i;
        q[0] = r[i];
        q[1] = g[i];
        q[2] = b[i];
        q[3] = a != NULL ? a[i] : 1.0f;
    }
    return RC_OK;
}

/* The texel column (or row) pair and weight of coordinate s in [0, 1) over n texels: centres
 * at (i + 0.5)/n, repeat wrap. */
static inline void texture_axis(float s, int n, int *i0, int *i1, float *f)
{
    float x = s * (float)n - 0.5f;
    float fl = floorf(x);
    int i = (int)fl;
    *f = x - fl;
    /* x is in [-0.5, n - 0.5): i is -1 .. n - 1, so one wrap each way suffices. */
    *i0 = i < 0 ? i + n : i;
    *i1 = i + 1 >= n ? i + 1 - n : i + 1;
}

/* u, v to [0, 1) image coordinates with v flipped to rows from the top; a non-finite input
 * goes to 0 (floorf of Inf would give NaN and an index out of the image). */
static inline float texture_frac(float s)
{
    float f = s - floorf(s);
    /* s - floor(s) rounds up to 1.0 for tiny negative s (-1e-9 + 1 in float). */
    return (f >= 0.0f && f < 1.0f) ? f : 0.0f;
}

void texture_sample(const texture *t, float u, float v, float out[4])
{
    if (t == NULL || t->width <= 0 || t->rgba == NULL) {
        out[0] = out[1] = out[2] = out[3] = 1.0f;
        return;
    }
    int x0, x1, y0, y1;
    float fx, fy;
    texture_axis(texture_frac(u), t->width, &x0, &x1, &fx);
    texture_axis(texture_frac(1.0f - texture_frac(v)), t->height, &y0, &y1, &fy);
    const float *p00 = t->rgba + 4 * ((size_t)y0 * (size_t)t->width + (size_t)x0);
    const float *p10 = t->rgba + 4 * ((size_t)y0 * (size_t)t->width + (size_t)x1);
    const float *p01 = t->rgba + 4 * ((size_t)y1 * (size_t)t->width + (size_t)x0);
    const float *p11 = t->rgba + 4 * ((size_t)y1 * (size_t)t->width + (size_t)x1);
    for (int c = 0; c < 4; c++) {
        float top = p00[c] + (p10[c] - p00[c]) * fx;
        float bot = p01[c] + (p11[c] - p01[c]) * fx;
        out[c] = top + (bot - top) * fy;
    }
}

void texture_sample_n(const texture *t, int n, const float *u, const float *v, float *r, float *g, float *b, float *a)
{
    for (int i = 0; i < n; i++) {
        float c[4];
        texture_sample(t, u[i], v[i], c);
        r[i] = c[0];
        g[i] = c[1];
        b[i] = c[2];
        a[i] = c[3];
    }
}
