/* DDS cube maps and textures (scene/image_oiio.h through harness/frame.c), judged without
 * OpenImageIO's help: the files are written here from Microsoft's DDS_HEADER / DDS_PIXELFORMAT
 * documentation (magic "DDS ", a 124-byte header, DDSCAPS2_CUBEMAP with the six face flags) and
 * the expected texels are worked out here: an uncompressed A8R8G8B8 cube whose texels all differ,
 * decoded with the sRGB formula written out below; a BC1 (DXT1) cube, one 4 x 4 block per face,
 * decoded by hand (565 endpoints, 2-bit indices, the 2/3-1/3 rule and the 3-colour mode); a BC6H
 * cube (mode 11, equal endpoints) as linear half floats; the same faces as six PNG files give the
 * identical env_map, a DDS texture the identical texture, and the rasterizer the identical image;
 * bad input is refused in one line naming the file, the key and the fix. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <png.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "cli_exec.h"
#include "env.h"
#include "exr.h"
#include "frame.h"
#include "image_oiio.h"
#include "scene_file.h"
#include "tmpdir.h"

/* DDS_HEADER.dwFlags, DDS_PIXELFORMAT.dwFlags and dwCaps/dwCaps2 (Microsoft, "DDS_HEADER
 * structure", "DDS_PIXELFORMAT structure"). */
#define DDSD_CAPS                 0x1u
#define DDSD_HEIGHT               0x2u
#define DDSD_WIDTH                0x4u
#define DDSD_PITCH                0x8u
#define DDSD_PIXELFORMAT          0x1000u
#define DDSD_LINEARSIZE           0x80000u
#define DDPF_ALPHAPIXELS          0x1u
#define DDPF_FOURCC               0x4u
#define DDPF_RGB                  0x40u
#define DDSCAPS_COMPLEX           0x8u
#define DDSCAPS_TEXTURE           0x1000u
#define DDSCAPS2_CUBEMAP          0x200u
#define DDSCAPS2_CUBEMAP_ALLFACES 0xfc00u /* POSITIVEX 0x400 ... NEGATIVEZ 0x8000 */
#define DXGI_FORMAT_BC1_UNORM     71u
#define DXGI_FORMAT_BC6H_UF16     95u

typedef enum { PF_A8R8G8B8, PF_DXT1, PF_DX10 } pixel_format;

static void put32(unsigned char *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (unsigned char)(v >> (8 * i));
}

/* The 128 bytes before the data (and the 20-byte DDS_HEADER_DXT10 after them for PF_DX10, whose
 * DXGI format is dxgi); returns the header's length. */
static size_t dds_header(unsigned char *b, int w, int h, int cube, pixel_format pf, uint32_t dxgi)
{
    memset(b, 0, 148);
    memcpy(b, "DDS ", 4);
    put32(b + 4, 124); /* dwSize */
    uint32_t linear_size = pf == PF_DXT1 ? 8u : 16u;
    put32(b + 8,
          DDSD_CAPS | DDSD_HEIGHT | DDSD_WIDTH | DDSD_PIXELFORMAT | (pf == PF_A8R8G8B8 ? DDSD_PITCH : DDSD_LINEARSIZE));
    put32(b + 12, (uint32_t)h);
    put32(b + 16, (uint32_t)w);
    put32(b + 20, pf == PF_A8R8G8B8 ? (uint32_t)w * 4u : linear_size * (uint32_t)((w + 3) / 4 * ((h + 3) / 4)));
    put32(b + 28, 1); /* dwMipMapCount */
    unsigned char *pfp = b + 76;
    put32(pfp, 32); /* DDS_PIXELFORMAT.dwSize */
    if (pf == PF_A8R8G8B8) {
        put32(pfp + 4, DDPF_RGB | DDPF_ALPHAPIXELS);
        put32(pfp + 12, 32);
        put32(pfp + 16, 0x00ff0000u); /* R mask */
        put32(pfp + 20, 0x0000ff00u); /* G */
        put32(pfp + 24, 0x000000ffu); /* B */
        put32(pfp + 28, 0xff000000u); /* A */
    } else {
        put32(pfp + 4, DDPF_FOURCC);
        memcpy(pfp + 8, pf == PF_DXT1 ? "DXT1" : "DX10", 4);
    }
    put32(b + 108, DDSCAPS_TEXTURE | (cube ? DDSCAPS_COMPLEX : 0u));
    put32(b + 112, cube ? DDSCAPS2_CUBEMAP | DDSCAPS2_CUBEMAP_ALLFACES : 0u);
    if (pf != PF_DX10)
        return 128;
    put32(b + 128, dxgi);
    put32(b + 132, 3);                /* D3D10_RESOURCE_DIMENSION_TEXTURE2D */
    put32(b + 136, cube ? 0x4u : 0u); /* DDS_RESOURCE_MISC_TEXTURECUBE */
    put32(b + 140, 1);                /* arraySize */
    return 148;
}

static void write_file(const char *name, const unsigned char *b, size_t n)
{
    char path[300];
    snprintf(path, sizeof path, "%s/%s", tmpdir, name);
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(b, 1, n, f), n);
    fclose(f);
}

/* The A8R8G8B8 fixture: 4 x 4 faces, every texel of every face different and no face symmetric. */
#define N 4
static unsigned char tex_r(int f, int x, int y) { return (unsigned char)(10 + 40 * f + 7 * x + y); }
static unsigned char tex_g(int f, int x, int y) { return (unsigned char)(230 - 30 * f - 3 * y * y - x); }
static unsigned char tex_b(int f, int x, int y) { return (unsigned char)(17 * x + 29 * y + 5 * f); }

/* Faces (faces 6 or 1) of w x h, as BGRA bytes in the file (A8R8G8B8 little-endian). */
static void write_argb(const char *name, int w, int h, int faces, size_t cut)
{
    unsigned char *b = malloc(148 + (size_t)(w * h * faces) * 4);
    size_t n = dds_header(b, w, h, faces == 6, PF_A8R8G8B8, 0);
    for (int f = 0; f < faces; f++)
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                b[n++] = tex_b(f, x, y);
                b[n++] = tex_g(f, x, y);
                b[n++] = tex_r(f, x, y);
                b[n++] = 255;
            }
    write_file(name, b, cut > 0 ? cut : n);
    free(b);
}

/* IEC 61966-2-1, written out here rather than taken from scene/texture.c. */
static double srgb(double c) { return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4); }

static const char *const scene_head = "image: {width: 24, height: 16}\n"
                                      "camera: {eye: [0, 0, 3], target: [0, 0, 0], hfov: 60}\n"
                                      "materials:\n  a: {model: d3d9client, albedo: [0, 0, 0], "
                                      "d3d9client: {r0: 0, m: 0, reflect: [1, 1, 1]}}\n"
                                      "objects:\n  - {shape: sphere, radius: 1, tessellation: 16, material: a}\n";

static void write_scene(const char *name, const char *env_line)
{
    char path[300];
    snprintf(path, sizeof path, "%s/%s", tmpdir, name);
    FILE *f = fopen(path, "w");
    fprintf(f, "%senvironment: %s\n", scene_head, env_line);
    fclose(f);
}

/* Loads tmpdir/s.yaml with the given environment; the status of the first step that fails. */
static rc_status load_env(const char *env_line, scene *s, env_map *e, float **px, char *err, size_t errlen)
{
    char path[300];
    write_scene("s.yaml", env_line);
    snprintf(path, sizeof path, "%s/s.yaml", tmpdir);
    *px = NULL;
    rc_status st = scene_file_load(path, s, err, errlen);
    return st != RC_OK ? st : frame_env_load(s, e, px, err, errlen);
}

/* The cube map of an environment line that must load; the caller frees *px (e.rgb). */
static env_map must_load(const char *env_line, float **px)
{
    scene *s = malloc(sizeof *s);
    env_map e;
    char err[2048];
    if (load_env(env_line, s, &e, px, err, sizeof err) != RC_OK)
        fail_msg("%s", err);
    free(s);
    return e;
}

static void test_argb_cube(void **state)
{
    (void)state;
    write_argb("c.dds", N, N, 6, 0);
    float *px;
    env_map e = must_load("{cube_dds: c.dds, scale: 2}", &px);
    assert_int_equal(e.kind, ENV_CUBE);
    assert_int_equal(e.width, N);
    /* Face by face, texel by texel: the file's face order is D3DCUBEMAP_FACES', row 0 its top. */
    for (int f = 0; f < 6; f++)
        for (int y = 0; y < N; y++)
            for (int x = 0; x < N; x++) {
                const float *t = e.rgb + 3 * ((size_t)(f * N + y) * N + (size_t)x);
                close_rel(t[0], srgb(tex_r(f, x, y) / 255.0), 1e-6);
                close_rel(t[1], srgb(tex_g(f, x, y) / 255.0), 1e-6);
                close_rel(t[2], srgb(tex_b(f, x, y) / 255.0), 1e-6);
            }
    /* Looked up: canonical (1, 0.25, 0.25) is D3D (1, 0.25, -0.25), face +X with sc = -Z = 0.25,
     * tc = -Y = -0.25, so s = 0.625, t = 0.375: exactly texel (2, 1)'s centre, times the scale. */
    close_rel(env_lookup(&e, v3(1, 0.25f, 0.25f)).x, 2.0 * srgb(tex_r(0, 2, 1) / 255.0), 1e-6);
    free(px);
}

/* BC1: one 4 x 4 block per face. Endpoints as 565, indices 2 bits per texel, texel i = 4 y + x
 * at bits 2i. Faces 0..4 have c0 > c1 (four colours: c2 = 2/3 c0 + 1/3 c1, c3 = 1/3 c0 + 2/3 c1);
 * face 5 has c0 <= c1 (three colours: c2 = (c0 + c1)/2, c3 black). */
static const uint16_t bc1_c0[6] = {0xf940, 0xa2b1, 0x7c1f, 0xffe0, 0x5555, 0x1234};
static const uint16_t bc1_c1[6] = {0x065f, 0x2105, 0x03e0, 0x001f, 0x2aaa, 0x8765};
static const uint32_t bc1_idx[6] = {0xe4e4e4e4u, 0x1b1b1b1bu, 0x9c63d2a7u, 0x0f0f3c3cu, 0x55aaff00u, 0xe4b18d72u};

/* Colour k of face f's palette, channel ch, as an exact value in [0, 1]. */
static double bc1_colour(int f, int k, int ch)
{
    double e[2];
    const uint16_t c[2] = {bc1_c0[f], bc1_c1[f]};
    for (int i = 0; i < 2; i++)
        e[i] = ch == 0 ? (c[i] >> 11) / 31.0 : ch == 1 ? ((c[i] >> 5) & 63) / 63.0 : (c[i] & 31) / 31.0;
    if (k < 2)
        return e[k];
    if (c[0] > c[1])
        return k == 2 ? (2 * e[0] + e[1]) / 3 : (e[0] + 2 * e[1]) / 3;
    return k == 2 ? (e[0] + e[1]) / 2 : 0.0;
}

static void test_bc1_cube(void **state)
{
    (void)state;
    unsigned char b[148 + 6 * 8];
    size_t n = dds_header(b, 4, 4, 1, PF_DXT1, 0);
    for (int f = 0; f < 6; f++) {
        b[n++] = (unsigned char)bc1_c0[f], b[n++] = (unsigned char)(bc1_c0[f] >> 8);
        b[n++] = (unsigned char)bc1_c1[f], b[n++] = (unsigned char)(bc1_c1[f] >> 8);
        put32(b + n, bc1_idx[f]);
        n += 4;
    }
    write_file("bc1.dds", b, n);
    float *px;
    env_map e = must_load("{cube_dds: bc1.dds}", &px);
    assert_int_equal(e.width, 4);
    /* The block decodes to 8 bits: the exact colour rounded either way (Direct3D allows the
     * decoder that much), then sRGB-decoded. */
    for (int f = 0; f < 6; f++)
        for (int i = 0; i < 16; i++) {
            int k = (int)(bc1_idx[f] >> (2 * i)) & 3;
            for (int ch = 0; ch < 3; ch++) {
                double v = 255.0 * bc1_colour(f, k, ch), got = e.rgb[3 * (size_t)(f * 16 + i) + (size_t)ch];
                double lo = srgb(floor(v + 1e-9) / 255.0), hi = srgb(ceil(v - 1e-9) / 255.0);
                if (fabs(got - lo) > 1e-6 * fmax(lo, 1e-6) && fabs(got - hi) > 1e-6 * fmax(hi, 1e-6))
                    fail_msg("face %d texel %d colour %d channel %d: %g, want %g or %g (8-bit %g)", f, i, k, ch, got,
                             lo, hi, v);
            }
        }
    free(px);
}

/* A half float's bits as a number (normal and zero values, which is all the test makes). */
static double half_value(unsigned h)
{
    int ex = (int)(h >> 10) & 31;
    return ex == 0 ? ldexp(h & 1023, -24) : ldexp(1.0 + (h & 1023) / 1024.0, ex - 15);
}

/* BC6H unsigned, mode 11 (5 mode bits 00011, then 10-bit endpoints RW GW BW RX GX BX, then
 * indices): with equal endpoints every texel is the endpoint, unquantized as the BC6H
 * specification does ((x << 16) + 0x8000) >> 10, scaled by 31/64, as half-float bits. */
static void test_bc6h_linear(void **state)
{
    (void)state;
    static const unsigned ep[3] = {512, 300, 1000};
    unsigned char blk[16] = {0};
    uint64_t bits[2] = {3, 0};
    for (int k = 0; k < 6; k++) {
        int at = 5 + 10 * k;
        for (int i = 0; i < 10; i++)
            if (ep[k % 3] >> i & 1)
                bits[(at + i) / 64] |= (uint64_t)1 << ((at + i) % 64);
    }
    for (int i = 0; i < 16; i++)
        blk[i] = (unsigned char)(bits[i / 8] >> (8 * (i % 8)));
    unsigned char b[148 + 6 * 16];
    size_t n = dds_header(b, 4, 4, 1, PF_DX10, DXGI_FORMAT_BC6H_UF16);
    for (int f = 0; f < 6; f++, n += 16)
        memcpy(b + n, blk, 16);
    write_file("bc6h.dds", b, n);
    float *px;
    env_map e = must_load("{cube_dds: bc6h.dds}", &px);
    for (int ch = 0; ch < 3; ch++) {
        unsigned q = (unsigned)((((uint32_t)ep[ch] << 16) + 0x8000u) >> 10);
        double want = half_value((q * 31u) >> 6); /* 1.5146, 0.017136, 42208: linear, no sRGB */
        for (int i = 0; i < 6 * 16; i++)
            close_rel(e.rgb[3 * i + ch], want, 0);
    }
    free(px);
}

/* The fixture's faces as PNG files (libpng), named like the six-face keys. */
static void write_pngs(void)
{
    static const char *const key[6] = {"px", "nx", "py", "ny", "pz", "nz"};
    for (int f = 0; f < 6; f++) {
        unsigned char px[N * N * 4];
        for (int y = 0; y < N; y++)
            for (int x = 0; x < N; x++) {
                unsigned char *p = px + 4 * (y * N + x);
                p[0] = tex_r(f, x, y), p[1] = tex_g(f, x, y), p[2] = tex_b(f, x, y), p[3] = 255;
            }
        png_image img;
        memset(&img, 0, sizeof img);
        img.version = PNG_IMAGE_VERSION;
        img.width = N;
        img.height = N;
        img.format = PNG_FORMAT_RGBA;
        char path[300];
        snprintf(path, sizeof path, "%s/%s.png", tmpdir, key[f]);
        assert_true(png_image_write_to_file(&img, path, 0, px, 0, NULL));
    }
}

#define SIX_PNG "{px: px.png, nx: nx.png, py: py.png, ny: ny.png, pz: pz.png, nz: nz.png}"

/* The same faces as a DDS and as six PNGs: the same env_map, bit for bit; a 2D DDS texture and
 * the PNG of the same texels: the same texture. */
static void test_dds_equals_png(void **state)
{
    (void)state;
    write_argb("c.dds", N, N, 6, 0);
    write_pngs();
    float *pa, *pb;
    env_map a = must_load("{cube_dds: c.dds}", &pa), b = must_load("{cube: " SIX_PNG "}", &pb);
    assert_int_equal(a.width, b.width);
    assert_memory_equal(a.rgb, b.rgb, sizeof(float) * 3 * 6 * N * N);
    free(pa);
    free(pb);

    /* Material textures: face 2 of the fixture as a 2D DDS and as a PNG. */
    write_argb("t.dds", N, N, 1, 0);
    char path[300];
    snprintf(path, sizeof path, "%s/t.yaml", tmpdir);
    FILE *f = fopen(path, "w");
    fprintf(f, "image: {width: 8, height: 8}\ncamera: {eye: [0, 0, 3], target: [0, 0, 0], hfov: 40}\n"
               "materials:\n  d: {texture: {diffuse: t.dds}}\n  p: {texture: {diffuse: px.png}}\n"
               "objects:\n  - {shape: sphere, radius: 1, material: d}\n  - {shape: quad, size: [1, 1], material: p}\n");
    fclose(f);
    scene *s = malloc(sizeof *s);
    char err[2048];
    if (scene_file_load(path, s, err, sizeof err) != RC_OK)
        fail_msg("%s", err);
    texture_set *ts = malloc(sizeof *ts);
    if (frame_textures_load(s, ts, err, sizeof err) != RC_OK)
        fail_msg("%s", err);
    const texture *td = &ts->map[0][MAT_TEX_DIFFUSE], *tp = &ts->map[1][MAT_TEX_DIFFUSE];
    assert_int_equal(td->width, N);
    assert_int_equal(tp->width, N);
    assert_memory_equal(td->rgba, tp->rgba, sizeof(float) * 4 * N * N);
    texture_set_free(ts);
    free(ts);
    free(s);
}

/* The rasterizer under the DDS cube and under the six PNGs: the same image, bit for bit. */
static void test_render_equal(void **state)
{
    (void)state;
    write_argb("c.dds", N, N, 6, 0);
    write_pngs();
    write_scene("rd.yaml", "{cube_dds: c.dds, scale: 3}");
    write_scene("rp.yaml", "{cube: " SIX_PNG ", scale: 3}");
    char err[2048], in[2][300], out[2][300];
    exr_image img[2];
    for (int i = 0; i < 2; i++) {
        snprintf(in[i], sizeof in[i], "%s/%s.yaml", tmpdir, i ? "rp" : "rd");
        snprintf(out[i], sizeof out[i], "%s/%s.exr", tmpdir, i ? "rp" : "rd");
        if (cli_exec(err, sizeof err, "render %s -o %s", in[i], out[i]) != 0)
            fail_msg("render %s: %s", in[i], err);
        assert_int_equal(exr_read(out[i], &img[i], err, sizeof err), RC_OK);
    }
    size_t n = (size_t)img[0].width * (size_t)img[0].height;
    double sum = 0;
    for (int c = 0; c < 3; c++) {
        const char *name = "RGB" + c;
        char ch[2] = {*name, '\0'};
        const float *p = exr_image_channel(&img[0], ch), *q = exr_image_channel(&img[1], ch);
        assert_non_null(p);
        assert_non_null(q);
        assert_memory_equal(p, q, n * sizeof *p);
        for (size_t i = 0; i < n; i++)
            sum += p[i];
    }
    assert_true(sum > 0); /* the cube was seen */
    exr_image_free(&img[0]);
    exr_image_free(&img[1]);
}

/* Bad DDS input: one line naming the scene's key, the file and the fix. */
static void test_refusals(void **state)
{
    (void)state;
    write_argb("c.dds", N, N, 6, 0);
    write_argb("cut.dds", N, N, 6, 128 + 4 * N * N * 3 + 5); /* three faces and a few bytes */
    write_argb("flat.dds", N, N, 1, 0);
    write_argb("rect.dds", 4, 2, 6, 0);
    unsigned char b[148 + 6 * 8] = {0};
    size_t n = dds_header(b, 4, 4, 1, PF_DX10, DXGI_FORMAT_BC1_UNORM);
    write_file("dx10bc1.dds", b, n + 6 * 8);
    unsigned char text[200];
    memset(text, 'x', sizeof text); /* longer than a header, and no "DDS " */
    write_file("notdds.dds", text, sizeof text);
    static const struct {
        const char *env;
        rc_status st;
        const char *msg[3];
    } c[] = {
        {"{cube_dds: cut.dds}", RC_ERR_PARSE, {"environment.cube_dds: ", "cut.dds: truncated", "give a complete DDS"}},
        {"{cube_dds: flat.dds}",
         RC_ERR_RANGE,
         {"environment.cube_dds: ", "flat.dds: a DDS 2D image (4x4), not a cube map",
          "give a DDS cube map with all six faces"}},
        {"{cube_dds: nothere.dds}", RC_ERR_IO, {"environment.cube_dds", "nothere.dds", "allowed: a regular file"}},
        {"{cube_dds: rect.dds}",
         RC_ERR_RANGE,
         {"environment.cube_dds: ", "rect.dds: a DDS cube map whose faces are 4x2, not square",
          "give a cube map with square faces"}},
        {"{cube_dds: dx10bc1.dds}",
         RC_ERR_PARSE,
         {"environment.cube_dds: ", "dx10bc1.dds: not a DDS file OpenImageIO", "re-save it as"}},
        {"{cube_dds: notdds.dds}",
         RC_ERR_PARSE,
         {"environment.cube_dds: ", "Invalid DDS header", "give a valid DDS file"}},
        {"{cube_dds: c.png}", RC_ERR_RANGE, {"environment.cube_dds", "unsupported extension", ".dds"}},
        {"{cube_cross: c.dds}", RC_ERR_RANGE, {"environment.cube_cross", "unsupported extension", ".exr"}},
        {"{cube_dds: c.dds, cube_cross: c.dds}", RC_ERR_PARSE, {"environment", "exactly one of", "cube_dds"}},
        {"{cube_dds: c.dds, sun_threshold: 5}",
         RC_ERR_PARSE,
         {"sun_threshold", "not used by a cube map", "environment"}},
        {"{cube: {px: c.dds, nx: c.dds, py: c.dds, ny: c.dds, pz: c.dds, nz: c.dds}}",
         RC_ERR_RANGE,
         {"environment.cube.px: ", "c.dds: a DDS cube map, not a 2D image", "goes under environment.cube_dds"}},
    };
    scene *s = malloc(sizeof *s);
    env_map e;
    float *px;
    char err[2048];
    for (size_t i = 0; i < sizeof c / sizeof c[0]; i++) {
        rc_status st = load_env(c[i].env, s, &e, &px, err, sizeof err);
        if (st != c[i].st || !strstr(err, c[i].msg[0]) || !strstr(err, c[i].msg[1]) || !strstr(err, c[i].msg[2]) ||
            strchr(err, '\n') != NULL)
            fail_msg("case %zu (%s): status %d, message: %s", i, c[i].env, (int)st, err);
        assert_null(px);
    }
    free(s);
}

/* A header that promises more than the file holds is refused before the texels are allocated
 * (issue 20): BC1 8192 x 8192 needs 2048 x 2048 blocks of 8 bytes, 32 MiB, not 8 bytes. A cube
 * map cut inside its first face is refused the same way. */
static void test_header_lies(void **state)
{
    (void)state;
    unsigned char b[148 + 8] = {0};
    size_t n = dds_header(b, 8192, 8192, 0, PF_DXT1, 0);
    write_file("huge.dds", b, n + 8);
    char path[300], err[1024];
    snprintf(path, sizeof path, "%s/huge.dds", tmpdir);
    image_dds d;
    assert_int_equal(image_dds_read(path, IMAGE_DDS_2D, 1 << 20, 16384, &d, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, "huge.dds"));
    assert_non_null(strstr(err, "8192 x 8192"));
    assert_non_null(strstr(err, "truncated or its header is corrupt"));
    assert_null(d.rgba8);
    write_argb("cut1.dds", 64, 64, 6, 128 + 100);
    snprintf(path, sizeof path, "%s/cut1.dds", tmpdir);
    assert_int_equal(image_dds_read(path, IMAGE_DDS_CUBE, 1 << 20, 16384, &d, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, "cut1.dds"));
    /* An empty file. */
    write_file("empty.dds", b, 0);
    snprintf(path, sizeof path, "%s/empty.dds", tmpdir);
    assert_int_equal(image_dds_read(path, IMAGE_DDS_CUBE, 1 << 20, 16384, &d, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, "empty.dds"));
}

/* What this OpenImageIO reads and refuses, printed for docs/cubemaps.md (and asserted, so a
 * new libOpenImageIO that reads more shows here). */
static void test_formats(void **state)
{
    (void)state;
    static const struct {
        uint32_t dxgi;
        const char *name;
        int read;
    } c[] = {
        {71, "BC1_UNORM (DX10)", 0},   {72, "BC1_UNORM_SRGB", 0},    {74, "BC2_UNORM", 0},
        {77, "BC3_UNORM", 0},          {80, "BC4_UNORM", 1},         {83, "BC5_UNORM", 1},
        {95, "BC6H_UF16", 1},          {96, "BC6H_SF16", 1},         {98, "BC7_UNORM", 1},
        {99, "BC7_UNORM_SRGB", 0},     {28, "R8G8B8A8_UNORM", 0},    {87, "B8G8R8A8_UNORM", 0},
        {10, "R16G16B16A16_FLOAT", 0}, {2, "R32G32B32A32_FLOAT", 0},
    };
    char err[1024], path[300];
    printf("OpenImageIO %s, DX10 header:", image_oiio_version());
    for (size_t i = 0; i < sizeof c / sizeof c[0]; i++) {
        unsigned char b[148 + 6 * 16 * 16] = {0};
        size_t n = dds_header(b, 4, 4, 1, PF_DX10, c[i].dxgi);
        snprintf(path, sizeof path, "f%zu.dds", i);
        write_file(path, b, n + 6 * 16 * 16);
        snprintf(path, sizeof path, "%s/f%zu.dds", tmpdir, i);
        image_dds d;
        rc_status st = image_dds_read(path, IMAGE_DDS_CUBE, 1 << 20, 64, &d, err, sizeof err);
        /* Read means decoded or refused only for its channel count (BC4, BC5 are not colour). */
        int read = st == RC_OK || strstr(err, "not colour") != NULL;
        printf(" %s %s;", c[i].name, read ? "read" : "refused");
        image_dds_free(&d);
        if (read != c[i].read)
            fail_msg("%s: %s", c[i].name, st == RC_OK ? "read" : err);
    }
    /* Legacy headers whose fourCC is a D3DFORMAT number: the float formats a float cube would use. */
    static const struct {
        uint32_t d3dfmt;
        const char *name;
    } l[] = {{113, "D3DFMT_A16B16G16R16F"}, {116, "D3DFMT_A32B32G32R32F"}};
    printf(" legacy header:");
    for (size_t i = 0; i < sizeof l / sizeof l[0]; i++) {
        unsigned char b[128 + 6 * 16 * 16] = {0};
        size_t n = dds_header(b, 4, 4, 1, PF_DXT1, 0);
        put32(b + 84, l[i].d3dfmt);
        write_file("legacy.dds", b, n + 6 * 16 * 16);
        snprintf(path, sizeof path, "%s/legacy.dds", tmpdir);
        image_dds d;
        rc_status st = image_dds_read(path, IMAGE_DDS_CUBE, 1 << 20, 64, &d, err, sizeof err);
        printf(" %s %s;", l[i].name, st == RC_OK ? "read" : "refused");
        image_dds_free(&d);
        if (st == RC_OK)
            fail_msg("%s is read now: docs/limits.md says it is not", l[i].name);
    }
    printf("\n");
}

/* LeakSanitizer (GCC 12) crashes in its exit-time tracer ("Tracer caught signal 11") in a process
 * that has dlopened OpenImageIO, whose thread-local storage is then dynamic TLS; a sanitizer build
 * of this program and of the CLI it runs would fail on that, not on a leak. So leak detection is
 * off for this program and its children only; address and undefined-behaviour checks stay on, and
 * every other unit program keeps leak detection. */
const char *__asan_default_options(void);
const char *__asan_default_options(void) { return "detect_leaks=0"; }

int main(void)
{
    const char *asan = getenv("ASAN_OPTIONS");
    char opts[512];
    snprintf(opts, sizeof opts, "%s%sdetect_leaks=0", asan != NULL ? asan : "", asan != NULL && asan[0] ? ":" : "");
    setenv("ASAN_OPTIONS", opts, 1);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_argb_cube),      cmocka_unit_test(test_bc1_cube),     cmocka_unit_test(test_bc6h_linear),
        cmocka_unit_test(test_dds_equals_png), cmocka_unit_test(test_render_equal), cmocka_unit_test(test_refusals),
        cmocka_unit_test(test_formats),        cmocka_unit_test(test_header_lies),
    };
    return cmocka_run_group_tests(tests, tmpdir_setup, tmpdir_teardown);
}
