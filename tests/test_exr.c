/* test_exr.c - EXR write/read round trips, foreign files (oiiotool, POV-Ray, Blender), and
 * corrupt-file robustness. Every fixture is generated into a private temporary directory. */
#define _POSIX_C_SOURCE 200809L
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "exr.h"

static char g_dir[64];

static const char *tmp_path(char *buf, size_t n, const char *name)
{
    snprintf(buf, n, "%s/%s", g_dir, name);
    return buf;
}

static int run(const char *fmt, ...)
{
    char cmd[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(cmd, sizeof cmd, fmt, ap);
    va_end(ap);
    return system(cmd);
}

/* Read a whole command's stdout into buf; returns the exit status. */
static int capture(char *buf, size_t n, const char *fmt, ...)
{
    char cmd[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(cmd, sizeof cmd, fmt, ap);
    va_end(ap);
    FILE *p = popen(cmd, "r");
    if (!p)
        return -1;
    size_t k = fread(buf, 1, n - 1, p);
    buf[k] = '\0';
    return pclose(p);
}

static long file_size(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return -1;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fclose(f);
    return n;
}

static unsigned char *slurp(const char *path, long *n)
{
    *n = file_size(path);
    if (*n < 0)
        return NULL;
    unsigned char *b = malloc((size_t)*n + 1);
    FILE *f = fopen(path, "rb");
    if (!b || !f || fread(b, 1, (size_t)*n, f) != (size_t)*n) {
        free(b);
        if (f)
            fclose(f);
        return NULL;
    }
    fclose(f);
    return b;
}

static void spit(const char *path, const unsigned char *b, long n)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(b, 1, (size_t)n, f), (size_t)n);
    fclose(f);
}

/* 5x3 fixture: every value distinct, asymmetric, negative and > 1 values included. */
enum { W = 5, H = 3, N = W * H };
static float fx_r[N], fx_g[N], fx_b[N], fx_a[N], fx_d[N];

static void make_fixture(void)
{
    for (int i = 0; i < N; i++) {
        fx_r[i] = 0.125f * (float)i - 0.5f;
        fx_g[i] = 1.0f / (float)(i + 3);
        fx_b[i] = 3.75f + (float)(i * i) * 0.01f;
        fx_a[i] = (i % 4) == 0 ? 0.0f : 1.0f;
        fx_d[i] = 1e-3f * (float)(N - i);
    }
}

/* Write the fixture in a deliberately unsorted channel order. */
static const char *write_fixture(char *buf, size_t n, const char *name)
{
    exr_channel ch[] = {{"G", fx_g}, {"diffuse.R", fx_d}, {"R", fx_r}, {"B", fx_b}, {"A", fx_a}};
    exr_attr at[] = {{"reflcheck.scene_hash", "9f3a"}, {"reflcheck.render_ms", "12.5"}};
    char err[512];
    tmp_path(buf, n, name);
    rc_status st = exr_write(buf, W, H, ch, 5, at, 2, err, sizeof err);
    if (st != RC_OK)
        fail_msg("exr_write: %s", err);
    return buf;
}

static void expect_plane(const exr_image *img, const char *name, const float *want, float tol)
{
    const float *got = exr_image_channel(img, name);
    if (!got)
        fail_msg("channel %s missing", name);
    for (int i = 0; i < img->width * img->height; i++)
        if (!(fabsf(got[i] - want[i]) <= tol))
            fail_msg("channel %s pixel %d: got %.9g want %.9g (tol %g)", name, i, got[i], want[i], tol);
}

static void test_roundtrip(void **state)
{
    (void)state;
    char path[256], err[512];
    write_fixture(path, sizeof path, "rt.exr");
    exr_image img;
    assert_int_equal(exr_read(path, &img, err, sizeof err), RC_OK);
    assert_int_equal(img.width, W);
    assert_int_equal(img.height, H);
    assert_int_equal(img.n_channels, 5);
    /* The file holds the channel list sorted by name whatever order we passed. */
    const char *sorted[] = {"A", "B", "G", "R", "diffuse.R"};
    for (int c = 0; c < 5; c++)
        assert_string_equal(img.names[c], sorted[c]);
    expect_plane(&img, "R", fx_r, 0.0f);
    expect_plane(&img, "G", fx_g, 0.0f);
    expect_plane(&img, "B", fx_b, 0.0f);
    expect_plane(&img, "A", fx_a, 0.0f);
    expect_plane(&img, "diffuse.R", fx_d, 0.0f);
    assert_null(exr_image_channel(&img, "diffuse.G"));
    assert_string_equal(exr_image_attr(&img, "reflcheck.scene_hash"), "9f3a");
    assert_string_equal(exr_image_attr(&img, "reflcheck.render_ms"), "12.5");
    assert_null(exr_image_attr(&img, "reflcheck.absent"));
    exr_image_free(&img);
    assert_null(img.data);
    assert_int_equal(img.n_channels, 0);
}

/* A second implementation (OpenImageIO) must see the same file: 32-bit float, ZIP, the
 * attribute, and the pixel values. */
static void test_written_file_read_by_oiio(void **state)
{
    (void)state;
    char path[256], out[8192];
    write_fixture(path, sizeof path, "oiio.exr");
    assert_int_equal(capture(out, sizeof out, "oiiotool --info -v '%s'", path), 0);
    assert_non_null(strstr(out, "5 x    3, 5 channel, float openexr"));
    assert_non_null(strstr(out, "compression: \"zip\""));
    assert_non_null(strstr(out, "reflcheck.scene_hash: \"9f3a\""));
    /* Pixel (3, 2) is index 13: R = 0.125*13 - 0.5 = 1.125, G = 1/16 = 0.0625. */
    /* OIIO lists R, G, B, A first; its dump prints 9 decimals. */
    assert_int_equal(capture(out, sizeof out, "oiiotool --dumpdata '%s'", path), 0);
    assert_non_null(strstr(out, "Pixel (3, 2): 1.125000000 0.062500000 "));
}

/* Issue 26: chunks are compressed on several threads and written in order. A 7 x 53 image is
 * four ZIP chunks (16 + 16 + 16 + 5 lines): written on 1, 3 and all cores the files are byte for
 * byte the same, and read back (ours and OpenImageIO) every value is the one written, the last,
 * short chunk included. zip_level 6 (zlib's default; ours is 1) writes other bytes and the same
 * values. */
enum { MW = 7, MH = 53, MN = MW * MH };

static void test_threaded_chunks(void **state)
{
    (void)state;
    static float r[MN], g[MN], b[MN];
    for (int i = 0; i < MN; i++) {
        r[i] = 0.25f * (float)(i % 97) - 3.0f;
        g[i] = 1.0f / (float)(i + 1);
        b[i] = (float)(i / MW) * 1000.0f + (float)(i % MW);
    }
    const exr_channel ch[] = {{"R", r}, {"G", g}, {"B", b}};
    const exr_attr at[] = {{"reflcheck.scene", "chunks"}};
    static const int threads[] = {1, 3, 0};
    static char out[1 << 16]; /* the dump: one line a pixel */
    char path[3][256], lvl[256], err[512];
    unsigned char *bytes[3];
    long n[3];
    for (int k = 0; k < 3; k++) {
        char name[32];
        snprintf(name, sizeof name, "mt%d.exr", k);
        exr_write_options o = {.threads = threads[k]};
        if (exr_write_opt(tmp_path(path[k], sizeof path[k], name), MW, MH, ch, 3, at, 1, &o, err, sizeof err) != RC_OK)
            fail_msg("exr_write_opt threads %d: %s", threads[k], err);
        bytes[k] = slurp(path[k], &n[k]);
        assert_non_null(bytes[k]);
    }
    for (int k = 1; k < 3; k++)
        if (n[k] != n[0] || memcmp(bytes[k], bytes[0], (size_t)n[0]) != 0)
            fail_msg("threads %d wrote other bytes than threads 1 (%ld vs %ld bytes)", threads[k], n[k], n[0]);
    exr_write_options slow = {.threads = 2, .zip_level = 6};
    if (exr_write_opt(tmp_path(lvl, sizeof lvl, "lvl6.exr"), MW, MH, ch, 3, at, 1, &slow, err, sizeof err) != RC_OK)
        fail_msg("exr_write_opt zip_level 6: %s", err);
    const char *check[] = {path[2], lvl};
    for (int k = 0; k < 2; k++) {
        exr_image img;
        assert_int_equal(exr_read(check[k], &img, err, sizeof err), RC_OK);
        assert_int_equal(img.width, MW);
        assert_int_equal(img.height, MH);
        expect_plane(&img, "R", r, 0.0f);
        expect_plane(&img, "G", g, 0.0f);
        expect_plane(&img, "B", b, 0.0f);
        exr_image_free(&img);
        /* Pixel (6, 52), index 370, in the short last chunk: R = 0.25 * (370 mod 97 = 79) - 3 =
         * 16.75, G = 1/371, B = 52 * 1000 + 6. */
        assert_int_equal(capture(out, sizeof out, "oiiotool --dumpdata '%s'", check[k]), 0);
        if (strstr(out, "Pixel (6, 52): 16.750000000 0.002695418 52006.000000000") == NULL)
            fail_msg("OpenImageIO reads another pixel (6, 52) from %s", check[k]);
    }
    long nl;
    unsigned char *bl = slurp(lvl, &nl);
    assert_non_null(bl);
    assert_true(nl != n[0] || memcmp(bl, bytes[0], (size_t)nl) != 0);
    free(bl);
    for (int k = 0; k < 3; k++)
        free(bytes[k]);
}

/* Files written by another writer: half and uint channels, tiles, other compressions, a data
 * window not at the origin, DWAA through the oiiotool fallback. */
static void test_foreign_variants(void **state)
{
    (void)state;
    char src[256], dst[256], err[512];
    write_fixture(src, sizeof src, "src.exr");
    exr_image img;

    /* The fixture is not half-exact, so compare against values rounded to half: relative
     * half step 2^-11 is the bound (4.9e-4). */
    tmp_path(dst, sizeof dst, "half.exr");
    assert_int_equal(run("oiiotool '%s' -d half -o '%s'", src, dst), 0);
    assert_int_equal(exr_read(dst, &img, err, sizeof err), RC_OK);
    for (int i = 0; i < N; i++)
        assert_true(fabsf(exr_image_channel(&img, "B")[i] - fx_b[i]) <= fx_b[i] * 4.9e-4f);
    assert_float_equal(exr_image_channel(&img, "R")[13], 1.125, 0.0); /* half-exact */
    exr_image_free(&img);

    tmp_path(dst, sizeof dst, "uint.exr");
    assert_int_equal(run("oiiotool '%s' --ch A -d uint32 -o '%s'", src, dst), 0);
    assert_int_equal(exr_read(dst, &img, err, sizeof err), RC_OK);
    assert_int_equal(img.n_channels, 1);
    for (int i = 0; i < N; i++) /* OIIO maps 1.0 to 2^32 - 1, which rounds to 2^32 as float */
        assert_float_equal(img.data[0][i], fx_a[i] * 4294967296.0, 0.0);
    exr_image_free(&img);

    tmp_path(dst, sizeof dst, "tiled.exr");
    assert_int_equal(run("oiiotool '%s' --tile 2 2 -o '%s'", src, dst), 0); /* 3x2 tiles, partial edges */
    assert_int_equal(exr_read(dst, &img, err, sizeof err), RC_OK);
    expect_plane(&img, "R", fx_r, 0.0f);
    expect_plane(&img, "diffuse.R", fx_d, 0.0f);
    exr_image_free(&img);

    tmp_path(dst, sizeof dst, "origin.exr");
    assert_int_equal(run("oiiotool '%s' --origin +2+1 -o '%s'", src, dst), 0);
    assert_int_equal(exr_read(dst, &img, err, sizeof err), RC_OK);
    assert_int_equal(img.width, W);
    assert_int_equal(img.height, H);
    expect_plane(&img, "G", fx_g, 0.0f);
    exr_image_free(&img);

    const char *lossless[] = {"none", "rle", "zips", "piz"};
    for (int k = 0; k < 4; k++) {
        tmp_path(dst, sizeof dst, "comp.exr");
        assert_int_equal(run("oiiotool '%s' --compression %s -o '%s'", src, lossless[k], dst), 0);
        if (exr_read(dst, &img, err, sizeof err) != RC_OK)
            fail_msg("%s: %s", lossless[k], err);
        expect_plane(&img, "R", fx_r, 0.0f);
        expect_plane(&img, "B", fx_b, 0.0f);
        exr_image_free(&img);
    }
    /* PXR24 keeps 15 mantissa bits of a float: relative error below 2^-15. */
    tmp_path(dst, sizeof dst, "pxr24.exr");
    assert_int_equal(run("oiiotool '%s' --compression pxr24 -o '%s'", src, dst), 0);
    assert_int_equal(exr_read(dst, &img, err, sizeof err), RC_OK);
    for (int i = 0; i < N; i++)
        assert_true(fabsf(exr_image_channel(&img, "G")[i] - fx_g[i]) <= fx_g[i] * 3.1e-5f);
    exr_image_free(&img);

    /* DWAA on a smooth 16x40 ramp (DCT blocks need room); lossy, so 1 % of the value. */
    tmp_path(dst, sizeof dst, "dwaa.exr");
    assert_int_equal(run("oiiotool --pattern fill:top=0.2,0.4,0.6:bottom=0.8,0.6,0.3 16x40 3 -d float "
                         "--compression dwaa --attrib reflcheck.tag dwa -o '%s'",
                         dst),
                     0);
    assert_int_equal(exr_read(dst, &img, err, sizeof err), RC_OK);
    assert_int_equal(img.width, 16);
    assert_int_equal(img.height, 40);
    /* OIIO's fill pattern puts top + (bottom - top) * y / (h - 1) in row y. */
    for (int y = 0; y < 40; y += 13) {
        double want = 0.2 + 0.6 * y / 39.0;
        assert_float_equal(exr_image_channel(&img, "R")[y * 16 + 7], want, 0.01 * want);
    }
    assert_string_equal(exr_image_attr(&img, "reflcheck.tag"), "dwa");
    exr_image_free(&img);
}

/* A 2x1 uncompressed scanline EXR written byte by byte (OpenEXR file layout: magic,
 * version 2, attributes, terminator, offset table, chunk), with zero or one float channel. */
static long build_tiny_exr(unsigned char *b, int with_channel)
{
    long n = 0;
#define PUT(s, len) (memcpy(b + n, (s), (len)), n += (long)(len))
#define ATTR(name, type, size)                                                                                         \
    (PUT(name, strlen(name) + 1), PUT(type, strlen(type) + 1), b[n++] = (size)&255, b[n++] = 0, b[n++] = 0, b[n++] = 0)
    const unsigned char box[16] = {0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0}; /* (0,0)-(1,0) */
    const unsigned char one[4] = {0, 0, 0x80, 0x3f}, zero8[8] = {0};
    /* channel "R": type 2 (float), pLinear 0, 3 reserved, x/y sampling 1; list ends with 0 */
    const unsigned char chan[18] = {'R', 0, 2, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};
    PUT("\x76\x2f\x31\x01\x02\x00\x00\x00", 8);
    ATTR("channels", "chlist", with_channel ? 19 : 1);
    if (with_channel)
        PUT(chan, 18);
    b[n++] = 0;
    ATTR("compression", "compression", 1);
    b[n++] = 0;
    ATTR("dataWindow", "box2i", 16);
    PUT(box, 16);
    ATTR("displayWindow", "box2i", 16);
    PUT(box, 16);
    ATTR("lineOrder", "lineOrder", 1);
    b[n++] = 0;
    ATTR("pixelAspectRatio", "float", 4);
    PUT(one, 4);
    ATTR("screenWindowCenter", "v2f", 8);
    PUT(zero8, 8);
    ATTR("screenWindowWidth", "float", 4);
    PUT(one, 4);
    b[n++] = 0;
    /* Offset table (one chunk), then the chunk: y = 0, 8 bytes, 0.5f and 2.0f. */
    uint64_t off = (uint64_t)n + 8;
    for (int i = 0; i < 8; i++)
        b[n++] = (unsigned char)(off >> (8 * i));
    const unsigned char chunk[16] = {0, 0, 0, 0, 8, 0, 0, 0, 0, 0, 0, 0x3f, 0, 0, 0, 0x40};
    PUT(chunk, 16);
#undef ATTR
#undef PUT
    return n;
}

static void test_errors(void **state)
{
    (void)state;
    char path[256], err[512];
    exr_image img;

    tmp_path(path, sizeof path, "missing.exr");
    assert_int_equal(exr_read(path, &img, err, sizeof err), RC_ERR_IO);
    assert_non_null(strstr(err, path));
    assert_null(strchr(err, '\n'));

    tmp_path(path, sizeof path, "text.exr");
    spit(path, (const unsigned char *)"P3\n1 1\n255\n0 0 0\n", 17);
    assert_int_equal(exr_read(path, &img, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, path));

    tmp_path(path, sizeof path, "short.exr");
    spit(path, (const unsigned char *)"hello\n", 6);
    assert_int_equal(exr_read(path, &img, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, path));

    tmp_path(path, sizeof path, "empty.exr");
    spit(path, (const unsigned char *)"", 0);
    assert_int_equal(exr_read(path, &img, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, path));

    /* A hand-built file with an empty channel list must fail; the same bytes with one
     * channel R and its chunk must read, so the failure is the channel count. */
    for (int with_channel = 0; with_channel < 2; with_channel++) {
        unsigned char b[512];
        long n = build_tiny_exr(b, with_channel);
        tmp_path(path, sizeof path, with_channel ? "onechan.exr" : "nochan.exr");
        spit(path, b, n);
        if (!with_channel) {
            assert_int_equal(exr_read(path, &img, err, sizeof err), RC_ERR_PARSE);
            assert_non_null(strstr(err, path));
            assert_non_null(strstr(err, "channel"));
        } else {
            if (exr_read(path, &img, err, sizeof err) != RC_OK)
                fail_msg("%s", err);
            assert_int_equal(img.n_channels, 1);
            assert_float_equal(img.data[0][0], 0.5, 0.0);
            assert_float_equal(img.data[0][1], 2.0, 0.0);
            exr_image_free(&img);
        }
    }

    /* Writer errors. */
    float px[2] = {1, 2};
    exr_channel ch[] = {{"R", px}, {"R", px}};
    tmp_path(path, sizeof path, "dup.exr");
    assert_int_equal(exr_write(path, 2, 1, ch, 2, NULL, 0, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "'R'"));
    assert_int_equal(file_size(path), -1);
    assert_int_equal(exr_write("/nonexistent-dir/x.exr", 2, 1, ch, 1, NULL, 0, err, sizeof err), RC_ERR_IO);
    assert_non_null(strstr(err, "/nonexistent-dir/x.exr"));
    exr_attr bad[] = {{"compression", "none"}};
    tmp_path(path, sizeof path, "badattr.exr");
    assert_int_not_equal(exr_write(path, 2, 1, ch, 1, bad, 1, err, sizeof err), RC_OK);
    assert_non_null(strstr(err, "compression"));
    assert_int_equal(exr_write(path, 0, 1, ch, 1, NULL, 0, err, sizeof err), RC_ERR_RANGE);
}

/* Runs exr_write of a 64x64 RGB image to path in a child whose file size limit is limit bytes
 * (SIGXFSZ ignored, so writes fail with EFBIG as on a full disk); returns the child's exit
 * status: the rc_status, 100 + the first bytes of err matching want, or 128 + a signal. The
 * child's alarm turns the old error-callback deadlock into SIGALRM instead of a hang. */
static int write_limited(const char *path, long limit, const char *want)
{
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        alarm(30);
        signal(SIGXFSZ, SIG_IGN);
        struct rlimit rl = {.rlim_cur = (rlim_t)limit, .rlim_max = (rlim_t)limit};
        setrlimit(RLIMIT_FSIZE, &rl);
        static float px[64 * 64];
        for (int i = 0; i < 64 * 64; i++)
            px[i] = (float)i * 0.37f;
        exr_channel ch[] = {{"R", px}, {"G", px}, {"B", px}};
        char err[512] = "";
        rc_status st = exr_write(path, 64, 64, ch, 3, NULL, 0, err, sizeof err);
        _exit(st != RC_OK && strstr(err, want) == NULL ? 100 : (int)st);
    }
    int ws = 0;
    assert_int_equal(waitpid(pid, &ws, 0), pid);
    return WIFEXITED(ws) ? WEXITSTATUS(ws) : 128 + (WIFSIGNALED(ws) ? WTERMSIG(ws) : 0);
}

/* A write that fails (in the header, or in the pixels) returns RC_ERR_IO with the system's
 * reason, never hangs (the error callback used to wait on a lock the header write held),
 * never truncates or deletes an existing destination and leaves no temporary file. A device
 * is refused as a destination before anything is written. */
static void test_failed_writes(void **state)
{
    (void)state;
    char path[256], err[512];
    tmp_path(path, sizeof path, "kept.exr");
    const char *precious = "the user's file";
    /* 16 bytes: inside the header; 2 KiB: past the header, inside the pixel chunks. */
    const long limits[] = {16, 2048};
    for (int i = 0; i < 2; i++) {
        spit(path, (const unsigned char *)precious, (long)strlen(precious));
        int rc = write_limited(path, limits[i], "File too large");
        if (rc != RC_ERR_IO)
            fail_msg("limit %ld: child exit %d, want %d (RC_ERR_IO with the reason)", limits[i], rc, RC_ERR_IO);
        assert_int_equal(file_size(path), (long)strlen(precious));
        FILE *f = fopen(path, "rb");
        char back[64] = "";
        assert_non_null(f);
        assert_int_equal(fread(back, 1, sizeof back, f), strlen(precious));
        fclose(f);
        assert_memory_equal(back, precious, strlen(precious));
        char cmd[400];
        snprintf(cmd, sizeof cmd, "ls %s | grep -q 'kept.exr.tmp'", g_dir);
        assert_int_not_equal(system(cmd), 0);
    }
    /* Without a limit the same write replaces the file with the image. */
    assert_int_equal(write_limited(path, (long)RLIM_INFINITY, ""), RC_OK);
    exr_image img;
    assert_int_equal(exr_read(path, &img, err, sizeof err), RC_OK);
    assert_int_equal(img.width, 64);
    exr_image_free(&img);

    /* A FIFO of our own as the non-regular destination, never /dev/full: a regression that
     * removes its failed output (as exr_write did) would delete the system's device. */
    tmp_path(path, sizeof path, "out.fifo");
    assert_int_equal(mkfifo(path, 0600), 0);
    assert_int_equal(write_limited(path, (long)RLIM_INFINITY, "(a FIFO)"), RC_ERR_RANGE);
    struct stat st;
    assert_int_equal(lstat(path, &st), 0);
    assert_true(S_ISFIFO(st.st_mode));
}

/* Inputs are opened as regular files only: a device or a FIFO is refused at once (a FIFO
 * open used to block forever), and a header whose planes exceed the memory limit is refused
 * before they are allocated. */
static void test_bounded_reads(void **state)
{
    (void)state;
    char path[256], err[512];
    exr_image img;
    assert_int_equal(exr_read("/dev/zero", &img, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "(a character device)"));
    assert_int_equal(exr_read(g_dir, &img, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "(a directory)"));
    tmp_path(path, sizeof path, "in.fifo");
    assert_int_equal(mkfifo(path, 0600), 0);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        alarm(20);
        char e[512];
        exr_image im;
        _exit(exr_read(path, &im, e, sizeof e) == RC_ERR_RANGE && strstr(e, "(a FIFO)") != NULL ? 0 : 1);
    }
    int ws = 0;
    assert_int_equal(waitpid(pid, &ws, 0), pid);
    assert_true(WIFEXITED(ws));
    assert_int_equal(WEXITSTATUS(ws), 0);

    /* 64x64 with 3 float channels decodes to 48 KiB: refused under 40K, read under 64K. */
    tmp_path(path, sizeof path, "mem.exr");
    assert_int_equal(write_limited(path, (long)RLIM_INFINITY, ""), RC_OK);
    setenv("REFLCHECK_MEMORY_LIMIT", "40K", 1);
    assert_int_equal(exr_read(path, &img, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "memory limit"));
    setenv("REFLCHECK_MEMORY_LIMIT", "64K", 1);
    assert_int_equal(exr_read(path, &img, err, sizeof err), RC_OK);
    exr_image_free(&img);
    unsetenv("REFLCHECK_MEMORY_LIMIT");
}

/* Truncate a valid file at every length and flip every byte: each read must either fail
 * with a message naming the file, or succeed with the right size. Run under ASan to prove
 * no out-of-bounds access. */
static void test_corrupt_files(void **state)
{
    (void)state;
    char src[256], bad[256], err[512];
    write_fixture(src, sizeof src, "good.exr");
    long n;
    unsigned char *b = slurp(src, &n);
    assert_non_null(b);
    assert_true(n > 100);
    tmp_path(bad, sizeof bad, "bad.exr");
    exr_image img;
    int truncated_ok = 0;
    for (long len = 0; len < n; len++) {
        spit(bad, b, len);
        rc_status st = exr_read(bad, &img, err, sizeof err);
        if (st == RC_OK) {
            truncated_ok++;
            exr_image_free(&img);
        } else {
            assert_non_null(strstr(err, bad));
        }
    }
    /* Every truncation loses part of the last chunk or more: none may pass as a full image. */
    assert_int_equal(truncated_ok, 0);

    long flipped_ok = 0;
    unsigned char *c = malloc(n > 0 ? (size_t)n : 1u);
    assert_non_null(c);
    for (long i = 0; i < n; i++) {
        for (int pattern = 0; pattern < 2; pattern++) {
            memcpy(c, b, (size_t)n);
            c[i] ^= pattern ? 0x01 : 0xff;
            spit(bad, c, n);
            rc_status st = exr_read(bad, &img, err, sizeof err);
            if (st == RC_OK) {
                flipped_ok++;
                assert_true(img.width > 0 && img.height > 0 && img.n_channels > 0);
                exr_image_free(&img);
            } else {
                assert_non_null(strstr(err, bad));
                assert_null(strchr(err, '\n'));
            }
        }
    }
    /* Random multi-byte damage with a fixed LCG seed. */
    uint32_t s = 12345u;
    for (int trial = 0; trial < 300; trial++) {
        memcpy(c, b, (size_t)n);
        for (int k = 0; k < 6; k++) {
            s = s * 1664525u + 1013904223u;
            long i = (long)(s % (uint32_t)n);
            s = s * 1664525u + 1013904223u;
            c[i] = (unsigned char)(s >> 24);
        }
        spit(bad, c, n);
        if (exr_read(bad, &img, err, sizeof err) == RC_OK)
            exr_image_free(&img);
        else
            assert_non_null(strstr(err, bad));
    }
    print_message("corrupt: %ld bytes, %ld of %ld single-byte flips still read\n", n, flipped_ok, 2 * n);
    free(c);
    free(b);
}

/* A header whose data window promises more than the file holds is refused before the planes are
 * allocated or oiiotool is started (issue 20): uncompressed, 16384 x 16384 float R is 1 GiB of
 * samples in a file of a few hundred bytes; as DWAA (no ratio bound) its 512 chunks still need a
 * 4 KiB offset table. */
static void test_header_lies(void **state)
{
    (void)state;
    unsigned char b[512];
    long n = build_tiny_exr(b, 1);
    char path[256], err[512];
    exr_image img;
    tmp_path(path, sizeof path, "tiny.exr");
    spit(path, b, n);
    assert_int_equal(exr_read(path, &img, err, sizeof err), RC_OK);
    exr_image_free(&img);
    /* dataWindow's box follows its name, type and 4-byte size: max x and y to 16383. */
    unsigned char *box = NULL;
    for (long i = 0; i + 30 < n && box == NULL; i++)
        if (memcmp(b + i, "dataWindow\0box2i\0", 17) == 0)
            box = b + i + 17 + 4;
    assert_non_null(box);
    box[8] = box[12] = 0xff;
    box[9] = box[13] = 0x3f;
    box[10] = box[11] = box[14] = box[15] = 0;
    tmp_path(path, sizeof path, "huge.exr");
    spit(path, b, n);
    assert_int_equal(exr_read(path, &img, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, "huge.exr"));
    assert_non_null(strstr(err, "16384 x 16384"));
    assert_non_null(strstr(err, "truncated or its header is corrupt"));
    for (long i = 0; i + 30 < n; i++)
        if (memcmp(b + i, "compression\0compression\0", 24) == 0) {
            b[i + 24 + 4] = 8; /* DWAA_COMPRESSION */
            break;
        }
    tmp_path(path, sizeof path, "huge_dwa.exr");
    spit(path, b, n);
    assert_int_equal(exr_read(path, &img, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, "huge_dwa.exr"));
    assert_non_null(strstr(err, "truncated or its header is corrupt"));
}

/* ---- renderer outputs (povray and blender are always installed in CI) ---- */

static void test_renderer_povray_half_exr(void **state)
{
    (void)state;
    char pov[256], exr[256], err[512];
    tmp_path(pov, sizeof pov, "scene.pov");
    tmp_path(exr, sizeof exr, "pov.exr");
    FILE *f = fopen(pov, "w");
    assert_non_null(f);
    fputs("#version 3.7;\nglobal_settings{assumed_gamma 1.0 ambient_light 0}\n"
          "background{rgb <0.25,0.5,0.75>}\ncamera{location <0,0,-3> look_at 0}\n"
          "light_source{<1,1,-3> rgb 1}\nsphere{0,1 pigment{rgb 1} finish{ambient 0 diffuse 1}}\n",
          f);
    fclose(f);
    assert_int_equal(run("povray +I'%s' +O'%s' +FE +W16 +H8 -D -A >/dev/null 2>&1", pov, exr), 0);
    exr_image img;
    assert_int_equal(exr_read(exr, &img, err, sizeof err), RC_OK);
    assert_int_equal(img.width, 16);
    assert_int_equal(img.height, 8);
    const float *r = exr_image_channel(&img, "R"), *g = exr_image_channel(&img, "G"), *b = exr_image_channel(&img, "B");
    assert_non_null(r);
    assert_non_null(g);
    assert_non_null(b);
    /* Corner: background, all three values exact in half. */
    assert_float_equal(r[0], 0.25, 0.0);
    assert_float_equal(g[0], 0.5, 0.0);
    assert_float_equal(b[0], 0.75, 0.0);
    /* Near the centre: the white sphere lit from the upper right front, N.L about 0.8
     * at the front, grey (R = G = B). */
    int c = 4 * 16 + 8;
    assert_true(r[c] > 0.5f && r[c] < 1.0f);
    assert_float_equal(r[c], g[c], 0.0);
    assert_float_equal(g[c], b[c], 0.0);
    assert_non_null(strstr(exr_image_attr(&img, "software"), "POV-Ray"));
    exr_image_free(&img);
}

static void test_renderer_blender_float_exr(void **state)
{
    (void)state;
    char script[256], err[512];
    tmp_path(script, sizeof script, "scene.py");
    FILE *f = fopen(script, "w");
    assert_non_null(f);
    fprintf(f,
            "import bpy\n"
            "s = bpy.context.scene\n"
            "s.render.engine = 'CYCLES'\n"
            "s.cycles.samples = 1\n"
            "s.cycles.use_denoising = False\n"
            "s.render.resolution_x = 8\n"
            "s.render.resolution_y = 4\n"
            "s.render.resolution_percentage = 100\n"
            "w = bpy.data.worlds['World']\n"
            "w.use_nodes = True\n"
            "bg = w.node_tree.nodes['Background']\n"
            "bg.inputs[0].default_value = (0.25, 0.5, 0.75, 1)\n"
            "bg.inputs[1].default_value = 1.0\n"
            "for o in list(bpy.data.objects):\n"
            "    if o.type != 'CAMERA':\n"
            "        bpy.data.objects.remove(o)\n"
            "s.view_layers[0].use_pass_normal = True\n"
            "bpy.ops.render.render()\n"
            "im = s.render.image_settings\n"
            "for fmt, codec, name in [('OPEN_EXR', 'ZIP', 'b_zip'), ('OPEN_EXR_MULTILAYER', 'PIZ', 'b_piz'),\n"
            "                         ('OPEN_EXR_MULTILAYER', 'DWAA', 'b_dwaa')]:\n"
            "    im.file_format = fmt\n"
            "    im.exr_codec = codec\n"
            "    im.color_depth = '32'\n"
            "    bpy.data.images['Render Result'].save_render('%s/' + name + '.exr', scene=s)\n",
            g_dir);
    fclose(f);
    assert_int_equal(run("blender -b --factory-startup --python-exit-code 1 --python '%s' >/dev/null 2>&1", script), 0);

    struct {
        const char *file, *prefix;
        double tol;
    } cases[] = {
        {"b_zip.exr", "", 1e-6},
        {"b_piz.exr", "ViewLayer.Combined.", 1e-6},
        {"b_dwaa.exr", "ViewLayer.Combined.", 2e-3}, /* lossy: about one half-float step */
    };
    for (int k = 0; k < 3; k++) {
        char path[256], name[64];
        exr_image img;
        tmp_path(path, sizeof path, cases[k].file);
        if (exr_read(path, &img, err, sizeof err) != RC_OK)
            fail_msg("%s", err);
        assert_int_equal(img.width, 8);
        assert_int_equal(img.height, 4);
        const double want[4] = {0.25, 0.5, 0.75, 1.0};
        for (int c = 0; c < 4; c++) {
            snprintf(name, sizeof name, "%s%c", cases[k].prefix, "RGBA"[c]);
            const float *p = exr_image_channel(&img, name);
            if (!p)
                fail_msg("%s: channel %s missing", cases[k].file, name);
            for (int i = 0; i < 32; i += 5)
                assert_float_equal(p[i], want[c], cases[k].tol);
        }
        if (cases[k].prefix[0]) /* the normal pass is a separate layer in the same part */
            assert_non_null(exr_image_channel(&img, "ViewLayer.Normal.X"));
        assert_string_equal(exr_image_attr(&img, "Scene"), "Scene");
        exr_image_free(&img);
    }
}

int main(void)
{
    snprintf(g_dir, sizeof g_dir, "/tmp/test_exr_XXXXXX");
    if (!mkdtemp(g_dir)) {
        perror("mkdtemp");
        return 1;
    }
    make_fixture();
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_roundtrip),
        cmocka_unit_test(test_written_file_read_by_oiio),
        cmocka_unit_test(test_threaded_chunks),
        cmocka_unit_test(test_foreign_variants),
        cmocka_unit_test(test_errors),
        cmocka_unit_test(test_header_lies),
        cmocka_unit_test(test_failed_writes),
        cmocka_unit_test(test_bounded_reads),
        cmocka_unit_test(test_corrupt_files),
        cmocka_unit_test(test_renderer_povray_half_exr),
        cmocka_unit_test(test_renderer_blender_float_exr),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    run("rm -rf '%s'", g_dir);
    return rc;
}
