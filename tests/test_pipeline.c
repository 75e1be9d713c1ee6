/* End to end through the command line: scene file -> rasterizer -> EXR, and every malformed
 * scene file refused with one line and exit status 2. The binary is $REFLCHECK_BIN
 * (tests/run_unit.sh sets it to the build being tested), else build/reflcheck. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <dirent.h>
#include <cmocka.h>

#include "exr.h"

#define PI 3.14159265358979323846

static const char *bin(void)
{
    const char *b = getenv("REFLCHECK_BIN");
    return b && *b ? b : "build/reflcheck";
}

/* Runs a command line, returns its exit status; stderr is captured into err. */
static int run(const char *args, char *err, size_t errlen)
{
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "%s %s 2>/tmp/reflcheck-test-pipeline.err >/dev/null", bin(), args);
    int st = system(cmd);
    FILE *f = fopen("/tmp/reflcheck-test-pipeline.err", "r");
    size_t n = f ? fread(err, 1, errlen - 1, f) : 0;
    err[n] = '\0';
    if (f)
        fclose(f);
    return WIFEXITED(st) ? WEXITSTATUS(st) : 128;
}

/* A flat Lambert quad, albedo (0.7, 0.5, 0.3), under a sun of E = (2, 3, 4) W/m^2 at 60 deg:
 * every pixel is rho E cos(60)/pi (D3D: Vd = rho, light colour E/pi). */
static void test_lambert_quad_closed_form(void **state)
{
    (void)state;
    const char *yaml = "name: flat\n"
                       "image: {width: 40, height: 24, supersample: 3}\n"
                       "camera: {eye: [0.3, 3, 1.5], target: [0.1, 0, 0], hfov: 30}\n"
                       "lights:\n"
                       "  - {type: sun, direction: [0, -0.5, -0.8660254037844386], irradiance: [2, 3, 4]}\n"
                       "materials:\n"
                       "  m: {albedo: [0.7, 0.5, 0.3], model: d3d}\n"
                       "objects:\n"
                       "  - {shape: quad, center: [0, 0, 0], size: [20, 20], material: m}\n";
    FILE *f = fopen("/tmp/reflcheck-test-flat.yaml", "w");
    assert_non_null(f);
    fputs(yaml, f);
    fclose(f);
    char err[4096];
    assert_int_equal(run("render /tmp/reflcheck-test-flat.yaml -o /tmp/reflcheck-test-flat.exr", err, sizeof err), 0);

    exr_image img;
    assert_int_equal(exr_read("/tmp/reflcheck-test-flat.exr", &img, err, sizeof err), RC_OK);
    assert_int_equal(img.width, 40);
    assert_int_equal(img.height, 24);
    assert_non_null(exr_image_attr(&img, "reflcheck.scene_hash"));
    assert_non_null(exr_image_attr(&img, "reflcheck.render_ms"));
    const double rho[3] = {0.7, 0.5, 0.3}, e[3] = {2, 3, 4}, cos_t = 0.5;
    const char *names[3] = {"R", "G", "B"};
    const float *cov = exr_image_channel(&img, "coverage");
    assert_non_null(cov);
    double worst = 0.0;
    for (int c = 0; c < 3; c++) {
        const float *p = exr_image_channel(&img, names[c]);
        const float *d = exr_image_channel(&img, c == 0 ? "diffuse.R" : (c == 1 ? "diffuse.G" : "diffuse.B"));
        assert_non_null(p);
        assert_non_null(d);
        double want = rho[c] * e[c] * cos_t / PI;
        for (int i = 0; i < img.width * img.height; i++) {
            assert_true(cov[i] == 1.0f);
            double rel = fabs(p[i] - want) / want;
            worst = fmax(worst, rel);
            assert_true(rel < 1e-5);
            assert_true(p[i] == d[i]); /* the beauty is the diffuse layer alone here */
        }
    }
    printf("  flat Lambert quad: worst relative error %.3g over %d pixels x 3\n", worst, img.width * img.height);
    exr_image_free(&img);
}

/* Every malformed scene fixture: exit 2, exactly one line naming the file, no crash. */
static void test_bad_scenes_exit_2(void **state)
{
    (void)state;
    DIR *d = opendir("tests/fixtures/scenes");
    assert_non_null(d);
    struct dirent *de;
    int n = 0;
    while ((de = readdir(d)) != NULL) {
        if (strncmp(de->d_name, "bad_", 4) != 0 && strcmp(de->d_name, "mesh_degenerate.yaml") != 0)
            continue;
        char args[1024], err[4096];
        snprintf(args, sizeof args, "render tests/fixtures/scenes/%s -o /tmp/reflcheck-test-bad.exr", de->d_name);
        int st = run(args, err, sizeof err);
        if (st != 2)
            fprintf(stderr, "%s: exit %d: %s\n", de->d_name, st, err);
        assert_int_equal(st, 2);
        assert_non_null(strstr(err, de->d_name));
        char *nl = strchr(err, '\n');
        assert_non_null(nl);
        assert_true(nl[1] == '\0'); /* one line */
        n++;
    }
    closedir(d);
    assert_true(n >= 30);
}

static void test_bad_command_lines(void **state)
{
    (void)state;
    char err[4096];
    assert_int_equal(run("", err, sizeof err), 2);
    assert_int_equal(run("frobnicate", err, sizeof err), 2);
    assert_non_null(strstr(err, "unknown command"));
    assert_int_equal(run("render scenes/lambert_calibration.yaml", err, sizeof err), 2);
    assert_int_equal(run("render scenes/lambert_calibration.yaml -o /tmp/x.exr --supersample 99", err, sizeof err), 2);
    assert_non_null(strstr(err, "--supersample"));
    assert_int_equal(run("render /nonexistent/scene.yaml -o /tmp/x.exr", err, sizeof err), 2);
    assert_non_null(strstr(err, "/nonexistent/scene.yaml"));
    assert_int_equal(run("eval fresnel --ior nan", err, sizeof err), 2);
    assert_int_equal(run("run scenes/lambert_calibration.yaml --renderer mitsuba", err, sizeof err), 2);
    assert_non_null(strstr(err, "mitsuba"));
    /* An output folder we cannot write is a failure (1), not bad input. */
    assert_int_equal(run("render scenes/lambert_calibration.yaml -o /proc/nope/x.exr", err, sizeof err), 1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_lambert_quad_closed_form),
        cmocka_unit_test(test_bad_scenes_exit_2),
        cmocka_unit_test(test_bad_command_lines),
    };
    return cmocka_run_group_tests_name("pipeline", tests, NULL, NULL);
}
