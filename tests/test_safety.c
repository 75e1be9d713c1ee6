/* Runs that cannot hurt the user's files or the machine, through the command line: an output
 * never lands on an input, a failed write leaves the destination as it was, devices, FIFOs and
 * oversized files are refused before they are read (never read without bound, never waited
 * on), a frame beyond the memory limit is refused up front, and the exit status of render,
 * eval and stability follows the README (0 ok, 1 a run or write failed, 2 bad input).
 * Every command runs under `timeout -s KILL`, so a regression that hangs (a FIFO, the EXR
 * error-path deadlock) fails with status 137 instead of hanging the suite. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <dirent.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include <cmocka.h>

#include "check.h"
#include "cli_exec.h"
#include "exr.h"
#include "mesh.h"
#include "render.h"
#include "scene_file.h"

/* Seconds before a command is killed: long enough for a small render under the sanitizers
 * on a loaded 2-core machine (every command here takes well under a second when nothing
 * hangs); REFLCHECK_TEST_TIMEOUT shortens it when running these tests against an old build
 * that reads /dev/zero without bound. */
#define SAFETY_TIMEOUT "60"

static char dir[256];

/* The reflcheck command under timeout, for sh_exec. */
static const char *rc_cmd(void)
{
    static char buf[600];
    const char *t = getenv("REFLCHECK_TEST_TIMEOUT");
    snprintf(buf, sizeof buf, "timeout -s KILL %s %s", t != NULL && *t ? t : SAFETY_TIMEOUT, cli_bin());
    return buf;
}

static void spit(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    assert_int_equal(fclose(f), 0);
}

/* The whole file, NUL-terminated, for before/after comparisons of small files. */
static char *slurp(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    char *buf = malloc(1 << 20);
    assert_non_null(buf);
    size_t n = fread(buf, 1, (1 << 20) - 1, f);
    fclose(f);
    buf[n] = '\0';
    *len = n;
    return buf;
}

static void expect_same_bytes(const char *path, const char *want, size_t want_len)
{
    size_t len;
    char *got = slurp(path, &len);
    assert_int_equal(len, want_len);
    assert_memory_equal(got, want, want_len);
    free(got);
}

static void path_in(char *out, size_t len, const char *name) { snprintf(out, len, "%s/%s", dir, name); }

/* A small scene with a mesh and an environment image beside it, so that all three inputs exist. */
static void write_scene(void)
{
    char p[400];
    path_in(p, sizeof p, "tetra.obj");
    spit(p, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n");
    float px[4 * 2 * 3];
    for (int i = 0; i < 24; i++)
        px[i] = 0.25f;
    exr_channel ch[] = {{"R", px}, {"G", px + 8}, {"B", px + 16}};
    char err[512];
    path_in(p, sizeof p, "env.exr");
    assert_int_equal(exr_write(p, 4, 2, ch, 3, NULL, 0, err, sizeof err), RC_OK);
    path_in(p, sizeof p, "v.yaml");
    spit(p, "image: {width: 16, height: 8}\n"
            "camera: {eye: [0, 1, 4], target: [0, 0.3, 0], hfov: 40}\n"
            "environment: {image: env.exr}\n"
            "lights:\n  - {type: sun, direction: [0, -1, -1], irradiance: [3, 3, 3]}\n"
            "materials: {w: {albedo: [0.5, 0.5, 0.5]}}\n"
            "objects:\n  - {shape: mesh, path: tetra.obj, material: w}\n");
}

/* A fresh folder per test, so a test that fails (an old build overwriting the scene) does
 * not hide what the next one checks. */
static int setup(void **state)
{
    (void)state;
    snprintf(dir, sizeof dir, "/tmp/reflcheck-safety-%ld", (long)getpid());
    if (mkdir(dir, 0755) != 0)
        return -1;
    write_scene();
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    return system(cmd) == 0 ? 0 : -1;
}

/* render v.yaml -o v.yaml used to overwrite the scene with an EXR, also through a symlink;
 * the mesh and environment image it references are inputs too. */
static void test_output_onto_input(void **state)
{
    (void)state;
    static const char *const inputs[] = {"v.yaml", "tetra.obj", "env.exr"};
    static const char *const says[] = {"scene file", "mesh", "environment image"};
    char err[2048], in[400], lnk[400], hard[400];
    for (int i = 0; i < 3; i++) {
        path_in(in, sizeof in, inputs[i]);
        size_t len;
        char *before = slurp(in, &len);
        snprintf(lnk, sizeof lnk, "%s/link-%d.exr", dir, i);
        snprintf(hard, sizeof hard, "%s/hard-%d.exr", dir, i);
        unlink(lnk);
        unlink(hard);
        assert_int_equal(symlink(in, lnk), 0);
        assert_int_equal(link(in, hard), 0);
        const char *outs[] = {in, lnk, hard};
        for (int o = 0; o < 3; o++) {
            int rc = sh_exec(err, sizeof err, "%s render %s/v.yaml -o %s", rc_cmd(), dir, outs[o]);
            if (rc != 2 || strstr(err, says[i]) == NULL || strstr(err, "give another -o path") == NULL)
                fail_msg("render -o %s (%s): exit %d, want 2 naming the %s; stderr: %s", outs[o], inputs[i], rc,
                         says[i], err);
            expect_same_bytes(in, before, len);
        }
        free(before);
        unlink(lnk);
        unlink(hard);
    }
    /* A symlink to an ordinary output is followed: the file it points to gets the image and
     * the link stays a link. */
    char out[400];
    path_in(out, sizeof out, "real.exr");
    path_in(lnk, sizeof lnk, "link-out.exr");
    spit(out, "old");
    unlink(lnk);
    assert_int_equal(symlink(out, lnk), 0);
    assert_int_equal(sh_exec(err, sizeof err, "%s render %s/v.yaml -o %s", rc_cmd(), dir, lnk), 0);
    struct stat st;
    assert_int_equal(lstat(lnk, &st), 0);
    assert_true(S_ISLNK(st.st_mode));
    exr_image img;
    assert_int_equal(exr_read(out, &img, err, sizeof err), RC_OK);
    assert_int_equal(img.width, 16);
    exr_image_free(&img);
}

/* A write that fails (file size limit: EFBIG once SIGXFSZ is ignored) must report the error,
 * exit 1 and leave the existing destination byte for byte, with no temporary file. Before:
 * the destination was truncated and then deleted (or SIGXFSZ killed the process with a
 * truncated EXR in place), and on a full disk the EXR error callback deadlocked. */
static void test_failed_write_keeps_destination(void **state)
{
    (void)state;
    char err[2048], out[400];
    path_in(out, sizeof out, "dest.exr");
    const char *precious = "precious bytes the user already had\n";
    spit(out, precious);
    /* dash counts ulimit -f in 512-byte blocks: 2 KiB takes the EXR header but not the image. */
    int rc =
        sh_exec(err, sizeof err, "ulimit -f 4; %s render %s/v.yaml -o %s --width 64 --height 64", rc_cmd(), dir, out);
    if (rc != 1 || strstr(err, "dest.exr") == NULL || strstr(err, "File too large") == NULL)
        fail_msg("render under ulimit -f: exit %d, want 1 with the system's reason; stderr: %s", rc, err);
    expect_same_bytes(out, precious, strlen(precious));
    expect_no_temp(dir, "dest.exr");
    /* The same through stability's JSON and CSV outputs. */
    rc = sh_exec(err, sizeof err, "ulimit -f 4; %s stability --samples 16 --quiet --json %s", rc_cmd(), out);
    if (rc != 1 || strstr(err, "File too large") == NULL)
        fail_msg("stability under ulimit -f: exit %d, want 1; stderr: %s", rc, err);
    expect_same_bytes(out, precious, strlen(precious));
    expect_no_temp(dir, "dest.exr");
    /* An output folder that does not exist is a failed write, not bad input. */
    rc = sh_exec(err, sizeof err, "%s render %s/v.yaml -o %s/no-such-dir/x.exr", rc_cmd(), dir, dir);
    if (rc != 1 || strstr(err, "No such file or directory") == NULL)
        fail_msg("render into a missing folder: exit %d, want 1; stderr: %s", rc, err);
}

/* Devices, FIFOs and directories are refused as outputs (exit 2) before anything is rendered;
 * render -o /dev/full used to hang forever. The device is a private copy of /dev/full
 * (mknod, as root in CI): a regression that removes or renames over its output must not
 * destroy the system's /dev/full (fixing the hang alone did: exr_write removed the path it
 * failed to write). Without mknod permission the device case is left out. */
static void test_non_regular_outputs(void **state)
{
    (void)state;
    char err[2048], fifo[400], full[400], cmd[600];
    path_in(fifo, sizeof fifo, "out.fifo");
    assert_int_equal(mkfifo(fifo, 0600), 0);
    path_in(full, sizeof full, "full");
    snprintf(cmd, sizeof cmd, "mknod %s c 1 7 2>/dev/null", full);
    int have_device = system(cmd) == 0;
    const char *outs[] = {fifo, dir, full};
    const char *kinds[] = {"a FIFO", "a directory", "a character device"};
    for (int i = 0; i < (have_device ? 3 : 2); i++) {
        int rc = sh_exec(err, sizeof err, "%s render %s/v.yaml -o %s", rc_cmd(), dir, outs[i]);
        if (rc != 2 || strstr(err, kinds[i]) == NULL)
            fail_msg("render -o %s: exit %d, want 2 naming %s; stderr: %s", outs[i], rc, kinds[i], err);
        rc = sh_exec(err, sizeof err, "%s stability --samples 16 --quiet --csv %s", rc_cmd(), outs[i]);
        if (rc != 2 || strstr(err, kinds[i]) == NULL)
            fail_msg("stability --csv %s: exit %d, want 2 naming %s; stderr: %s", outs[i], rc, kinds[i], err);
    }
    struct stat st;
    assert_int_equal(stat(fifo, &st), 0);
    assert_true(S_ISFIFO(st.st_mode));
    if (have_device) {
        assert_int_equal(stat(full, &st), 0);
        assert_true(S_ISCHR(st.st_mode));
    }
}

/* Writes scene NAME.yaml whose mesh path is MESH. */
static void mesh_scene(const char *name, const char *mesh_path)
{
    char p[400], text[1024];
    path_in(p, sizeof p, name);
    snprintf(text, sizeof text,
             "image: {width: 8, height: 8}\n"
             "camera: {eye: [0, 1, 4], target: [0, 0, 0], hfov: 40}\n"
             "materials: {w: {albedo: [0.5, 0.5, 0.5]}}\n"
             "objects:\n  - {shape: mesh, path: %s, material: w}\n",
             mesh_path);
    spit(p, text);
}

/* Inputs that used to be read without bound (/dev/zero: 24 GB and the OOM killer), waited on
 * forever (a FIFO without a writer) or read whole before being refused (a 2 GB file) are
 * refused by kind or size before the first byte, exit 2, with the kind or size named. */
static void test_unbounded_inputs(void **state)
{
    (void)state;
    char err[2048], p[400], q[400];
    path_in(p, sizeof p, "zero.obj");
    assert_int_equal(symlink("/dev/zero", p), 0);
    path_in(p, sizeof p, "fifo.obj");
    assert_int_equal(mkfifo(p, 0600), 0);
    /* Sparse: 2 GiB of size, no data blocks. */
    path_in(p, sizeof p, "big.obj");
    int fd = open(p, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    assert_true(fd >= 0);
    assert_int_equal(ftruncate(fd, (off_t)2 << 30), 0);
    close(fd);
    path_in(p, sizeof p, "sub.obj");
    assert_int_equal(mkdir(p, 0755), 0);
    const char *meshes[] = {"zero.obj", "fifo.obj", "big.obj", "sub.obj"};
    const char *why[] = {"a character device", "a FIFO", "over the limit of 1073741824 bytes", "a directory"};
    for (int i = 0; i < 4; i++) {
        snprintf(q, sizeof q, "m%d.yaml", i);
        mesh_scene(q, meshes[i]);
        const char *cmds[] = {"render", "check"};
        for (int c = 0; c < 2; c++) {
            int rc = sh_exec(err, sizeof err, "%s %s %s/%s%s", rc_cmd(), cmds[c], dir, q,
                             c == 0 ? " -o /tmp/reflcheck-safety-never.exr" : "");
            if (rc != 2 || strstr(err, why[i]) == NULL || strstr(err, meshes[i]) == NULL)
                fail_msg("%s with mesh %s: exit %d, want 2 naming '%s'; stderr: %s", cmds[c], meshes[i], rc, why[i],
                         err);
        }
    }
    /* The scene file itself and an environment image. */
    path_in(p, sizeof p, "scene.fifo.yaml");
    assert_int_equal(mkfifo(p, 0600), 0);
    int rc = sh_exec(err, sizeof err, "%s check %s", rc_cmd(), p);
    if (rc != 2 || strstr(err, "a FIFO") == NULL)
        fail_msg("check on a FIFO: exit %d, want 2; stderr: %s", rc, err);
    rc = sh_exec(err, sizeof err, "%s check /dev/zero", rc_cmd());
    if (rc != 2 || strstr(err, "a character device") == NULL)
        fail_msg("check /dev/zero: exit %d, want 2; stderr: %s", rc, err);
    path_in(p, sizeof p, "envfifo.exr");
    assert_int_equal(mkfifo(p, 0600), 0);
    path_in(q, sizeof q, "e.yaml");
    spit(q, "image: {width: 8, height: 8}\ncamera: {eye: [0, 1, 4], target: [0, 0, 0], hfov: 40}\n"
            "environment: {image: envfifo.exr}\n");
    rc = sh_exec(err, sizeof err, "%s render %s -o %s/e.exr", rc_cmd(), q, dir);
    if (rc != 2 || strstr(err, "a FIFO") == NULL || strstr(err, "environment.image") == NULL)
        fail_msg("render with a FIFO environment: exit %d, want 2; stderr: %s", rc, err);
}

/* A 16384^2 frame at k = 16 used to map 23 GiB with no estimate; now it is refused before any
 * allocation with the estimate and the fix in the message. */
static void test_memory_limit(void **state)
{
    (void)state;
    char err[2048];
    int rc = sh_exec(err, sizeof err,
                     "REFLCHECK_MEMORY_LIMIT=1G %s render %s/v.yaml -o %s/huge.exr --width 16384 --height 16384 "
                     "--supersample 16",
                     rc_cmd(), dir, dir);
    /* 24 layers (with ndoth, 1090b29) of 16384^2 floats are 24 GiB before anything else. */
    if (rc != 2 || strstr(err, "24.") == NULL || strstr(err, "GiB") == NULL || strstr(err, "--width") == NULL ||
        strstr(err, "REFLCHECK_MEMORY_LIMIT") == NULL)
        fail_msg("16384^2 k=16 under a 1 GiB limit: exit %d, want 2 with the estimate; stderr: %s", rc, err);
    rc = sh_exec(err, sizeof err, "REFLCHECK_MEMORY_LIMIT=lots %s render %s/v.yaml -o %s/x.exr", rc_cmd(), dir, dir);
    if (rc != 2 || strstr(err, "REFLCHECK_MEMORY_LIMIT='lots'") == NULL)
        fail_msg("a malformed REFLCHECK_MEMORY_LIMIT: exit %d, want 2; stderr: %s", rc, err);
    rc = sh_exec(err, sizeof err, "REFLCHECK_MEMORY_LIMIT=64M %s render %s/v.yaml -o %s/x.exr", rc_cmd(), dir, dir);
    if (rc != 0)
        fail_msg("a 16x8 frame under 64 MiB: exit %d, want 0; stderr: %s", rc, err);

    /* The estimate itself: at least the layers (24 with every AOV, 12 with none: R, G, B, A,
     * coverage, object, ndotv, ndoth, ndotl, var.R/G/B), and what a scene file cannot hold adds
     * little. */
    char p[400];
    path_in(p, sizeof p, "v.yaml");
    scene s;
    mesh m = {0};
    assert_int_equal(scene_file_load(p, &s, err, sizeof err), RC_OK);
    assert_int_equal(mesh_build(&s, &m, err, sizeof err), RC_OK);
    render_options o = {.width = 1000, .height = 500, .threads = 2};
    double bytes = 0;
    int layers = 0;
    render_memory_estimate(&s, &m, NULL, &o, &bytes, &layers);
    assert_int_equal(layers, 24);
    double fb = 24.0 * 1000 * 500 * 4;
    if (!(bytes >= fb && bytes <= fb + 64.0 * 1048576))
        fail_msg("estimate %.0f bytes, want the 24 layers' %.0f plus at most 64 MiB of buffers", bytes, fb);
    o.aovs = RENDER_AOV_NONE;
    render_memory_estimate(&s, &m, NULL, &o, &bytes, &layers);
    assert_int_equal(layers, 12);
    assert_true(bytes >= 12.0 * 1000 * 500 * 4);
    /* render_scene refuses through the same estimate, so the job runner gets it too. */
    setenv("REFLCHECK_MEMORY_LIMIT", "1M", 1);
    render_image img;
    o.aovs = 0;
    assert_int_equal(render_scene(&s, &m, NULL, &o, &img, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "memory limit"));
    assert_null(img.chan[RENDER_R]);
    unsetenv("REFLCHECK_MEMORY_LIMIT");
    mesh_free(&m);
}

/* The exit status of render, eval and stability: 0 ok, 1 a write failed, 2 bad input. */
static void test_exit_codes(void **state)
{
    (void)state;
    char err[2048];
    struct {
        const char *args;
        int want;
    } cases[] = {
        {"eval fresnel --steps 4", 0},
        {"eval fresnel --steps 0", 2},
        {"eval nonsense", 2},
        {"eval fresnel --bogus 1", 2},
        {"eval beckmann >/dev/full", 1},
        {"stability --samples 16 --quiet", 0},
        {"stability --samples 16 >/dev/full", 1},
        {"stability --samples 3", 2},
        {"stability extra", 2},
        {"render", 2},
        {"render DIR/v.yaml", 2},
        {"render DIR/v.yaml -o DIR/ok.exr --width 0", 2},
        {"render DIR/no-such.yaml -o DIR/ok.exr", 2},
        {"render DIR/v.yaml -o DIR/ok.exr", 0},
        {"render DIR/v.yaml -o DIR/ok.exr >/dev/full", 1},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char args[1024] = "";
        const char *a = cases[i].args, *d;
        while ((d = strstr(a, "DIR")) != NULL) {
            strncat(args, a, (size_t)(d - a));
            strcat(args, dir);
            a = d + 3;
        }
        strcat(args, a);
        int rc = sh_exec(err, sizeof err, "%s %s", rc_cmd(), args);
        if (rc != cases[i].want)
            fail_msg("reflcheck %s: exit %d, want %d; stderr: %s", args, rc, cases[i].want, err);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_output_onto_input, setup, teardown),
        cmocka_unit_test_setup_teardown(test_failed_write_keeps_destination, setup, teardown),
        cmocka_unit_test_setup_teardown(test_non_regular_outputs, setup, teardown),
        cmocka_unit_test_setup_teardown(test_unbounded_inputs, setup, teardown),
        cmocka_unit_test_setup_teardown(test_memory_limit, setup, teardown),
        cmocka_unit_test_setup_teardown(test_exit_codes, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
