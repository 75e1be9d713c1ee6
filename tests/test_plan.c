/* reflcheck plan writes make recipes that /bin/sh runs: every path must arrive as exactly
 * one word, whatever it holds (; > $ ' spaces), paths make cannot carry are refused, and two
 * scenes with one name are refused. The plans are run under make with a fake POV-Ray. */
#include <fcntl.h>
#include <limits.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>
#include <cmocka.h>

#include <cJSON.h>

#include "cli_exec.h"
#include "fileio.h"

static char work[128], bin[2 * PATH_MAX], saved_path[8192];

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
}

static int setup(void **state)
{
    (void)state;
    snprintf(work, sizeof work, "/tmp/reflcheck-test-plan-%ld", (long)getpid());
    /* make runs in another folder: the binary by its absolute path. */
    char cwd[PATH_MAX];
    if (getcwd(cwd, sizeof cwd) == NULL)
        return 1;
    snprintf(bin, sizeof bin, "%s%s%s", cli_bin()[0] == '/' ? "" : cwd, cli_bin()[0] == '/' ? "" : "/", cli_bin());
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf %s; mkdir -p %s/bin %s/make", work, work, work);
    if (system(cmd) != 0)
        return 1;
    /* A POV-Ray that renders nothing: its jobs fail quickly, the raster jobs are what we read. */
    char fake[256];
    snprintf(fake, sizeof fake, "%s/bin/povray", work);
    write_text(fake, "#!/bin/sh\ncase \"$1\" in --version) echo 'POV-Ray 3.7.0.10.fake'; exit 0;; esac\nexit 3\n");
    chmod(fake, 0755);
    snprintf(saved_path, sizeof saved_path, "%s", getenv("PATH") ? getenv("PATH") : "");
    char p[8400];
    snprintf(p, sizeof p, "%s/bin:%s", work, saved_path);
    setenv("PATH", p, 1);
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    setenv("PATH", saved_path, 1);
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf %s", work);
    return system(cmd) != 0;
}

/* Runs argv (no shell) in dir with stdout to out_file and stderr to err; the exit status. */
static int run_argv(const char *dir, const char *out_file, char *err, size_t errlen, char *const argv[])
{
    char errfile[256];
    snprintf(errfile, sizeof errfile, "%s/stderr", work);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        int o = open(out_file ? out_file : "/dev/null", O_WRONLY | O_CREAT | O_TRUNC, 0644);
        int e = open(errfile, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (o < 0 || e < 0 || (dir != NULL && chdir(dir) != 0))
            _exit(126);
        dup2(o, 1);
        dup2(e, 2);
        /* Run under `make -j`, a child make would read the outer make's jobserver pipe from
         * MAKEFLAGS, whose descriptors are not ours: it stops ("read jobs pipe") partway. */
        unsetenv("MAKEFLAGS");
        unsetenv("MFLAGS");
        unsetenv("MAKELEVEL");
        execvp(argv[0], argv);
        _exit(127);
    }
    int st;
    assert_int_equal(waitpid(pid, &st, 0), pid);
    char *t = fileio_read_all(errfile, NULL);
    snprintf(err, errlen, "%s", t ? t : "");
    free(t);
    return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
}

/* A one-triangle scene at work/<file>, named `name` (NULL: no name key). */
static void scene_file(const char *file, const char *name, char *path, size_t len)
{
    char obj[256], yaml[1024];
    snprintf(obj, sizeof obj, "%s/tri.obj", work);
    write_text(obj, "v -1 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    snprintf(yaml, sizeof yaml,
             "%s%s%s"
             "image: {width: 8, height: 6}\n"
             "camera: {eye: [0, 0.5, 4], target: [0, 0.5, 0], hfov: 40}\n"
             "materials:\n  white: {}\n"
             "objects:\n  - {shape: mesh, path: tri.obj, material: white}\n"
             "comparisons:\n  - {reference: povray, thresholds: {rel_rms: {warn: 1, fail: 2, why: \"test\"}}}\n",
             name ? "name: " : "", name ? name : "", name ? "\n" : "");
    snprintf(path, len, "%s/%s", work, file);
    write_text(path, yaml);
}

static char *record_scene_path(const char *out, const char *name)
{
    char path[512];
    snprintf(path, sizeof path, "%s/%s/raster-twin.json", out, name);
    char *text = fileio_read_all(path, NULL);
    if (text == NULL)
        return NULL;
    cJSON *doc = cJSON_Parse(text);
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(doc, "scene_path");
    char *r = cJSON_IsString(v) ? strdup(v->valuestring) : NULL;
    cJSON_Delete(doc);
    free(text);
    return r;
}

static int no_pwned(void)
{
    char p[3][256];
    snprintf(p[0], sizeof p[0], "%s/PWNED", work);
    snprintf(p[1], sizeof p[1], "%s/make/PWNED", work);
    snprintf(p[2], sizeof p[2], "PWNED");
    return access(p[0], F_OK) != 0 && access(p[1], F_OK) != 0 && access(p[2], F_OK) != 0;
}

/* Plans the scene, runs the plan under make in work/make, and checks the raster job got the
 * path as one word and that nothing the path spells was run. */
static void plan_and_make(const char *file, const char *name)
{
    char scene[512], out[256], cache[256], mk[256], err[2048];
    scene_file(file, name, scene, sizeof scene);
    snprintf(out, sizeof out, "%s/run-%s", work, name);
    snprintf(cache, sizeof cache, "%s/cache", work);
    snprintf(mk, sizeof mk, "%s/jobs-%s.mk", work, name);
    char *plan[] = {bin, "plan", scene, "--out", out, "--cache", cache, "--bin", bin, NULL};
    assert_int_equal(run_argv(NULL, mk, err, sizeof err, plan), 0);
    char *make[] = {"make", "-k", "-s", "-f", mk, NULL};
    char mkdir_[256];
    snprintf(mkdir_, sizeof mkdir_, "%s/make", work);
    /* The POV-Ray job fails on purpose (exit 3): make -k goes on to the raster job. */
    int rc = run_argv(mkdir_, NULL, err, sizeof err, make);
    print_message("make exit %d: %s\n", rc, err);
    assert_true(no_pwned());
    char *got = record_scene_path(out, name);
    assert_non_null(got);
    assert_string_equal(got, scene);
    free(got);
}

static void test_scene_path_is_not_run(void **state)
{
    (void)state;
    plan_and_make("x;id>PWNED;.yaml", "inj");
}

static void test_dollar_quote_and_space_arrive_intact(void **state)
{
    (void)state;
    plan_and_make("it's $HOME $(id>PWNED) `id>PWNED`.yaml", "quoted");
}

static void test_unsafe_names_refused(void **state)
{
    (void)state;
    char scene[512], out[256], err[2048], mk[256];
    snprintf(out, sizeof out, "%s/run-refused", work);
    snprintf(mk, sizeof mk, "%s/refused.mk", work);
    /* No name key: the name is the file's with ; and > made _ and capitals lowercased (model/scene.h
     * scene_name_sanitise), so the target is make-safe. */
    scene_file("x;id>PWNED;.yaml", NULL, scene, sizeof scene);
    char *plan[] = {bin, "plan", scene, "--out", out, NULL};
    assert_int_equal(run_argv(NULL, mk, err, sizeof err, plan), 0);
    char *text = fileio_read_all(mk, NULL);
    assert_non_null(text);
    assert_non_null(strstr(text, "/x_id_pwned_/raster-twin.json:"));
    free(text);
    /* A name key with such characters is refused by the scene format itself. */
    scene_file("named.yaml", "\"x;id\"", scene, sizeof scene);
    char *named[] = {bin, "plan", scene, "--out", out, NULL};
    assert_int_equal(run_argv(NULL, mk, err, sizeof err, named), 2);
    assert_non_null(strstr(err, "not allowed in a name"));
    /* Nothing printed: a refused plan is no plan. */
    text = fileio_read_all(mk, NULL);
    assert_non_null(text);
    assert_string_equal(text, "");
    free(text);
    /* A line break in a path would end the recipe line. */
    char *nl[] = {bin, "plan", "a\nb.yaml", "--out", out, NULL};
    assert_int_equal(run_argv(NULL, mk, err, sizeof err, nl), 2);
    assert_non_null(strstr(err, "line break"));
    /* --out is part of every target. */
    scene_file("ok.yaml", "ok", scene, sizeof scene);
    char *sp[] = {bin, "plan", scene, "--out", "/tmp/run dir", NULL};
    assert_int_equal(run_argv(NULL, mk, err, sizeof err, sp), 2);
    assert_non_null(strstr(err, "--out"));
    char *nlbin[] = {bin, "plan", scene, "--out", out, "--bin", "build/x\nid", NULL};
    assert_int_equal(run_argv(NULL, mk, err, sizeof err, nlbin), 2);
    assert_non_null(strstr(err, "--bin"));
}

static void test_duplicate_names_refused(void **state)
{
    (void)state;
    char a[512], b[512], c[512], out[256], err[2048], mk[256];
    snprintf(out, sizeof out, "%s/run-dup", work);
    snprintf(mk, sizeof mk, "%s/dup.mk", work);
    scene_file("a.yaml", "same", a, sizeof a);
    scene_file("b.yaml", "other", b, sizeof b);
    scene_file("c.yaml", "same", c, sizeof c);
    char *plan[] = {bin, "plan", a, b, c, "--out", out, NULL};
    assert_int_equal(run_argv(NULL, mk, err, sizeof err, plan), 2);
    assert_non_null(strstr(err, a));
    assert_non_null(strstr(err, c));
    assert_non_null(strstr(err, "'same'"));
    char *text = fileio_read_all(mk, NULL);
    assert_non_null(text);
    assert_string_equal(text, "");
    free(text);
    /* Different names: planned. */
    char *ok[] = {bin, "plan", a, b, "--out", out, NULL};
    assert_int_equal(run_argv(NULL, mk, err, sizeof err, ok), 0);
}

/* The POV-Ray jobs are in the group wait, every other job in cpu, and all holds both: the
 * nightly runs `make cpu` and `make wait` side by side, each with its own slots. */
static void test_povray_jobs_in_wait_group(void **state)
{
    (void)state;
    char scene[512], out[256], err[2048], mk[256], line[600];
    snprintf(out, sizeof out, "%s/run-groups", work);
    snprintf(mk, sizeof mk, "%s/groups.mk", work);
    scene_file("groups.yaml", "grp", scene, sizeof scene);
    char *plan[] = {bin, "plan", scene, "--out", out, "--bin", bin, NULL};
    assert_int_equal(run_argv(NULL, mk, err, sizeof err, plan), 0);
    char *text = fileio_read_all(mk, NULL);
    assert_non_null(text);
    /* Each line is "GROUP: OUT/grp/RENDERER-twin.json"; a group listed for the other renderer
     * is a line that must not be there. */
    const char *want[][2] = {{"all", "povray"}, {"wait", "povray"}, {"all", "raster"}, {"cpu", "raster"}};
    for (size_t k = 0; k < sizeof want / sizeof want[0]; k++) {
        snprintf(line, sizeof line, "%s: %s/grp/%s-twin.json\n", want[k][0], out, want[k][1]);
        assert_non_null(strstr(text, line));
    }
    const char *never[][2] = {{"cpu", "povray"}, {"wait", "raster"}};
    for (size_t k = 0; k < sizeof never / sizeof never[0]; k++) {
        snprintf(line, sizeof line, "%s: %s/grp/%s-twin.json\n", never[k][0], out, never[k][1]);
        assert_null(strstr(text, line));
    }
    free(text);
    /* make runs the wait group alone: the POV-Ray job (the fake fails at once, but its record is
     * written) and not the raster one. */
    char dir[300];
    snprintf(dir, sizeof dir, "%s/make", work);
    char *mkwait[] = {"make", "-k", "-s", "-f", mk, "wait", NULL};
    run_argv(dir, NULL, err, sizeof err, mkwait);
    char rec[512];
    snprintf(rec, sizeof rec, "%s/grp/povray-twin.json", out);
    assert_int_equal(access(rec, F_OK), 0);
    snprintf(rec, sizeof rec, "%s/grp/raster-twin.json", out);
    assert_int_not_equal(access(rec, F_OK), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_scene_path_is_not_run),     cmocka_unit_test(test_dollar_quote_and_space_arrive_intact),
        cmocka_unit_test(test_unsafe_names_refused),      cmocka_unit_test(test_duplicate_names_refused),
        cmocka_unit_test(test_povray_jobs_in_wait_group),
    };
    return cmocka_run_group_tests_name("plan", tests, setup, teardown);
}
