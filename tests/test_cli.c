/* test_cli.c - the command line's refusals (issue 20, "bad input, third round"): every command
 * names the argument it refuses as typed (an unknown option, a letter inside a group such as
 * "-rf.yaml", an option without its value or with an empty one, an option given twice), never
 * the command; `diff --mask` of another size names the mask, its size and the size it must
 * have; numbers with junk or out of range are refused by the option's name. Each refusal is
 * exit status 2 and one line; nothing is written. Issue 23: every command's --help, the command
 * list and --version. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include <getopt.h>

#include "cli.h"
#include "cli_exec.h"
#include "fileio.h"
#include "jsonio.h"
#include "tmpdir.h"

/* Exactly one line on stderr. */
static void one_line(const char *err)
{
    const char *nl = strchr(err, '\n');
    if (nl == NULL || nl[1] != '\0')
        fail_msg("not one line: %s", err);
}

static void expect_refused(const char *err, int rc, const char *want)
{
    if (rc != 2 || strstr(err, want) == NULL)
        fail_msg("exit %d, want 2 and \"%s\" in: %s", rc, want, err);
    one_line(err);
}

/* Issue 20 item 9: "render -rf.yaml" said "unknown option 'render'". Every getopt command names
 * the argument; renderers and check, which take no options, name it too. */
static void test_unknown_option_names_the_argument(void **state)
{
    (void)state;
    static const char *const cmds[] = {"render", "eval", "run", "plan", "compare", "diff", "stability", "fit"};
    char err[2048];
    for (size_t i = 0; i < sizeof cmds / sizeof cmds[0]; i++) {
        int rc = cli_exec(err, sizeof err, "%s -rf.yaml", cmds[i]);
        expect_refused(err, rc, "'-rf.yaml'");
        char wrong[64];
        snprintf(wrong, sizeof wrong, "option '%s'", cmds[i]);
        if (strstr(err, wrong) != NULL)
            fail_msg("%s names the command: %s", cmds[i], err);
        rc = cli_exec(err, sizeof err, "%s --no-such-option", cmds[i]);
        expect_refused(err, rc, "'--no-such-option'");
    }
    expect_refused(err, cli_exec(err, sizeof err, "renderers -rf.yaml"), "'-rf.yaml'");
    /* a flag given a value it does not take */
    expect_refused(err, cli_exec(err, sizeof err, "fit scenes/d3d9_glass.yaml --small=1"), "'--small=1'");
}

/* A value option last on the line: its name and "needs a value", not "unknown option". */
static void test_missing_value(void **state)
{
    (void)state;
    char err[2048];
    int rc = cli_exec(err, sizeof err, "render scenes/d3d9_glass.yaml -o");
    expect_refused(err, rc, "'-o' needs a value");
    rc = cli_exec(err, sizeof err, "fit scenes/d3d9_glass.yaml --out");
    expect_refused(err, rc, "'--out' needs a value");
    rc = cli_exec(err, sizeof err, "stability --json");
    expect_refused(err, rc, "'--json' needs a value");
}

/* An empty value: `fit --out ""` wrote /<scene>/fit.json at the file system's root, `run --out ""`
 * rendered there, `render -o ""` failed as a write (exit 1) blaming memory. */
static void test_empty_value(void **state)
{
    (void)state;
    char err[2048];
    int rc = cli_exec(err, sizeof err, "fit %s/none.yaml --out ''", tmpdir);
    expect_refused(err, rc, "'--out' (-o) has an empty value");
    rc = cli_exec(err, sizeof err, "run scenes/d3d9_glass.yaml --renderer exact --role validate --small --out ''");
    expect_refused(err, rc, "'--out' (-o) has an empty value");
    rc = cli_exec(err, sizeof err, "render scenes/d3d9_glass.yaml -o ''");
    expect_refused(err, rc, "'--output' (-o) has an empty value");
    rc = cli_exec(err, sizeof err, "compare scenes/d3d9_glass.yaml --run=");
    expect_refused(err, rc, "'--run' has an empty value");
}

/* A value option given twice: the last won silently (render wrote only b.exr). */
static void test_option_twice(void **state)
{
    (void)state;
    char err[2048], a[300], b[300];
    snprintf(a, sizeof a, "%s/a.exr", tmpdir);
    snprintf(b, sizeof b, "%s/b.exr", tmpdir);
    int rc = cli_exec(err, sizeof err, "render scenes/d3d9_glass.yaml -o %s --output %s --width 8 --height 6", a, b);
    expect_refused(err, rc, "'--output' (-o) given twice");
    assert_int_equal(access(a, F_OK), -1);
    assert_int_equal(access(b, F_OK), -1);
    rc = cli_exec(err, sizeof err, "fit scenes/d3d9_glass.yaml --bounds=wide --bounds seed");
    expect_refused(err, rc, "'--bounds' given twice");
    rc = cli_exec(err, sizeof err, "eval fresnel --p 3 --p 5");
    expect_refused(err, rc, "'--p' given twice");
}

/* Numbers: a sign, a range, trailing junk, hexadecimal, exponent forms and NaN, each refused by
 * the option's name with its range (held: these were right, kept by this test). */
static void test_numbers(void **state)
{
    (void)state;
    static const char *const bad[] = {"--threads -1",      "--threads 99999", "--width 2x",  "--width 0x10",
                                      "--supersample 1e1", "--height ' 7'",   "--width '7 '"};
    char err[2048];
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        int rc = cli_exec(err, sizeof err, "render scenes/d3d9_glass.yaml -o %s/n.exr %s", tmpdir, bad[i]);
        char opt[32];
        snprintf(opt, sizeof opt, "%.*s '", (int)strcspn(bad[i], " "), bad[i]);
        expect_refused(err, rc, opt);
    }
    expect_refused(err, cli_exec(err, sizeof err, "eval fresnel --ior nan"), "--ior 'nan'");
    expect_refused(err, cli_exec(err, sizeof err, "fit scenes/d3d9_glass.yaml --starts 0"), "--starts '0'");
    char n[300];
    snprintf(n, sizeof n, "%s/n.exr", tmpdir);
    assert_int_equal(access(n, F_OK), -1);
}

/* Issue 20 item 15: a mask of another size named the two images; it must name the mask, its
 * size and the size it must have. */
static void test_diff_mask_size(void **state)
{
    (void)state;
    char err[2048];
    assert_int_equal(
        cli_exec(err, sizeof err, "render scenes/d3d9_glass.yaml -o %s/t.exr --width 16 --height 12 -q", tmpdir), 0);
    assert_int_equal(
        cli_exec(err, sizeof err, "render scenes/d3d9_glass.yaml -o %s/m.exr --width 8 --height 6 -q", tmpdir), 0);
    int rc = cli_exec(err, sizeof err, "diff %s/t.exr %s/t.exr --mask %s/m.exr", tmpdir, tmpdir, tmpdir);
    expect_refused(err, rc, "m.exr is 8x6");
    assert_non_null(strstr(err, "16x12"));
    /* the same mask size passes */
    assert_int_equal(cli_exec(err, sizeof err, "diff %s/t.exr %s/t.exr --mask %s/t.exr", tmpdir, tmpdir, tmpdir), 0);
}

/* `diff --pairs`: one process gives, pair by pair and in order, the metrics `diff` alone gives
 * (three renders of two scenes, one pair leaving a term out, one without a mask), and for a
 * pair diff alone refuses, its message and exit status; a line without TEST and REF is exit 2. */
static void test_diff_pairs_as_alone(void **state)
{
    (void)state;
    char err[2048], path[400];
    assert_int_equal(
        cli_exec(err, sizeof err, "render scenes/d3d9_glass.yaml -o %s/pa.exr --width 16 --height 12 -q", tmpdir), 0);
    assert_int_equal(
        cli_exec(err, sizeof err, "render scenes/d3d_spot.yaml -o %s/pb.exr --width 16 --height 12 -q", tmpdir), 0);
    assert_int_equal(
        cli_exec(err, sizeof err, "render scenes/stiff_blinn.yaml -o %s/pc.exr --width 16 --height 12 -q", tmpdir), 0);
    static const char *const pairs[][4] = {
        {"pa", "pb", "pc", ""}, {"pb", "pa", "pa", "specular"}, {"pc", "pa", "", ""}, {"pa", "nosuch", "pa", ""}};
    enum { N = sizeof pairs / sizeof pairs[0] };
    snprintf(path, sizeof path, "%s/pairs.txt", tmpdir);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    for (int i = 0; i < N; i++) {
        char m[300] = "", lo[64] = "";
        if (pairs[i][2][0] != '\0')
            snprintf(m, sizeof m, " --mask %s/%s.exr", tmpdir, pairs[i][2]);
        if (pairs[i][3][0] != '\0')
            snprintf(lo, sizeof lo, " --leave-out %s", pairs[i][3]);
        sh_exec(err, sizeof err, "%s diff %s/%s.exr %s/%s.exr%s%s > %s/alone%d.json", cli_bin(), tmpdir, pairs[i][0],
                tmpdir, pairs[i][1], m, lo, tmpdir, i);
        fprintf(f, "%s/%s.exr\t%s/%s.exr\t", tmpdir, pairs[i][0], tmpdir, pairs[i][1]);
        if (pairs[i][2][0] != '\0')
            fprintf(f, "%s/%s.exr", tmpdir, pairs[i][2]);
        fprintf(f, "\t%s\n", pairs[i][3]);
    }
    fclose(f);
    assert_int_equal(sh_exec(err, sizeof err, "%s diff --pairs %s > %s/pairs.out", cli_bin(), path, tmpdir), 0);
    snprintf(path, sizeof path, "%s/pairs.out", tmpdir);
    char *text = fileio_read_all(path, NULL);
    assert_non_null(text);
    const char *at = text;
    for (int i = 0; i < N; i++) {
        const char *end = NULL;
        cJSON *got = cJSON_ParseWithOpts(at, &end, 0);
        assert_non_null(got);
        at = end;
        if (i < N - 1) {
            snprintf(path, sizeof path, "%s/alone%d.json", tmpdir, i);
            char *want_text = fileio_read_all(path, NULL);
            cJSON *want = cJSON_Parse(want_text);
            assert_non_null(want);
            assert_true(cJSON_Compare(got, want, 1));
            cJSON_Delete(want);
            free(want_text);
        } else {
            assert_non_null(strstr(cJSON_GetStringValue(cJSON_GetObjectItem(got, "error")), "nosuch.exr"));
            assert_int_equal(cJSON_GetNumberValue(cJSON_GetObjectItem(got, "exit")), 2);
        }
        cJSON_Delete(got);
    }
    free(text);
    int rc = sh_exec(err, sizeof err, "printf 'only-one\\n' | %s diff --pairs -", cli_bin());
    expect_refused(err, rc, "line 1: no TEST and REF");
}

/* After "--" an option-like word is a file name, never the help option. */
static void test_help_words_as_files(void **state)
{
    (void)state;
    char err[2048];
    int rc = cli_exec(err, sizeof err, "render -o %s/h.exr -- --help", tmpdir);
    expect_refused(err, rc, "--help");
    assert_null(strstr(err, "unknown option"));
}

/* The whole stdout of `reflcheck ARGS` into out (NUL-ended), its stderr into err; the exit status. */
static int cli_output(char *out, size_t outlen, char *err, size_t errlen, const char *args)
{
    char path[600];
    snprintf(path, sizeof path, "%s/stdout.txt", tmpdir);
    int rc = sh_exec(err, errlen, "%s %s > '%s'", cli_bin(), args, path);
    FILE *f = fopen(path, "r");
    size_t n = f != NULL ? fread(out, 1, outlen - 1, f) : 0;
    out[n] = '\0';
    if (f != NULL)
        fclose(f);
    return rc;
}

/* "--name" as a whole word of the help: followed by a space or a line end, not a longer name. */
static int names_option(const char *help, const char *name)
{
    char want[80];
    snprintf(want, sizeof want, "--%s", name);
    for (const char *p = strstr(help, want); p != NULL; p = strstr(p + 1, want)) {
        char after = p[strlen(want)];
        if (after == ' ' || after == '\n')
            return 1;
    }
    return 0;
}

/* Issue 23 item 5: `render --help` was "unknown option '--help'" (exit 2) and `check --help` tried
 * to open a file. Every command of the table, by --help and -h: exit 0, nothing on stderr, its
 * usage, an example, and every option its parser's table holds, each with a help text. A new
 * option without help fails here. */
static void test_every_command_help(void **state)
{
    (void)state;
    static char out[65536], out_h[65536];
    char err[2048], args[128];
    assert_true(cli_command_count() >= 11);
    for (int i = 0; i < cli_command_count(); i++) {
        const cli_command *c = cli_command_at(i);
        snprintf(args, sizeof args, "%s --help", c->name);
        int rc = cli_output(out, sizeof out, err, sizeof err, args);
        if (rc != 0 || err[0] != '\0')
            fail_msg("%s: exit %d, stderr: %s", args, rc, err);
        char usage[64];
        snprintf(usage, sizeof usage, "usage: reflcheck %s ", c->name);
        if (strncmp(out, usage, strlen(usage)) != 0 || strstr(out, "\nexample:\n  reflcheck ") == NULL)
            fail_msg("%s: no usage line or example:\n%s", args, out);
        assert_null(strstr(out, "(no help"));
        int n = 0;
        for (const struct option *o = c->longopts; o->name != NULL; o++, n++) {
            if (!names_option(out, o->name))
                fail_msg("%s does not name --%s:\n%s", args, o->name, out);
            const cli_option_help *h = c->options;
            while (h->name != NULL && strcmp(h->name, o->name) != 0)
                h++;
            if (h->name == NULL || h->text == NULL || strlen(h->text) < 10)
                fail_msg("%s: --%s has no help text in its cli_option_help table", c->name, o->name);
            /* a value option's help says its default or that it is required */
            if (o->has_arg == required_argument && strstr(h->text, "default") == NULL &&
                strstr(h->text, "required") == NULL)
                fail_msg("%s --%s: the help gives no default: %s", c->name, o->name, h->text);
        }
        assert_true(n >= 1); /* at least --help */
        snprintf(args, sizeof args, "%s -h", c->name);
        assert_int_equal(cli_output(out_h, sizeof out_h, err, sizeof err, args), 0);
        assert_string_equal(out_h, out);
        snprintf(args, sizeof args, "help %s", c->name);
        assert_int_equal(cli_output(out_h, sizeof out_h, err, sizeof err, args), 0);
        assert_string_equal(out_h, out);
    }
    /* --help after other arguments, as getopt reads it; a value is never taken for it */
    assert_int_equal(cli_output(out, sizeof out, err, sizeof err, "render scenes/d3d9_glass.yaml --help"), 0);
    assert_non_null(strstr(out, "usage: reflcheck render"));
    assert_int_equal(cli_output(out, sizeof out, err, sizeof err, "check scenes/d3d9_glass.yaml -h"), 0);
    assert_non_null(strstr(out, "usage: reflcheck check"));
    int rc = cli_exec(err, sizeof err, "eval fresnel --steps --help");
    expect_refused(err, rc, "--steps '--help'");
    expect_refused(err, cli_exec(err, sizeof err, "help nosuch"), "unknown command 'nosuch'");
}

/* `reflcheck --help` and `reflcheck help` list every command of the table with its summary. */
static void test_top_help(void **state)
{
    (void)state;
    static char out[65536], out2[65536];
    char err[2048];
    assert_int_equal(cli_output(out, sizeof out, err, sizeof err, "--help"), 0);
    assert_int_equal(cli_output(out2, sizeof out2, err, sizeof err, "help"), 0);
    assert_string_equal(out, out2);
    assert_int_equal(cli_output(out2, sizeof out2, err, sizeof err, "-h"), 0);
    assert_string_equal(out, out2);
    for (int i = 0; i < cli_command_count(); i++) {
        char line[64];
        snprintf(line, sizeof line, "\n  %-11s", cli_command_at(i)->name);
        if (strstr(out, line) == NULL)
            fail_msg("reflcheck --help does not list %s:\n%s", cli_command_at(i)->name, out);
    }
    assert_non_null(strstr(out, "REFLCHECK_DATA_DIR"));
    /* no command: the list on stderr, exit 2 */
    assert_int_equal(cli_output(out, sizeof out, err, sizeof err, ""), 2);
    assert_non_null(strstr(err, "usage: reflcheck COMMAND"));
}

/* `reflcheck --version`: "reflcheck VERSION (commit ID)", VERSION as the Makefile defines it and ID
 * a commit of this repository (with "-dirty" when built from a changed tree). */
static void test_version(void **state)
{
    (void)state;
    static char out[4096], want[256], id[64];
    char err[2048];
    assert_int_equal(cli_output(out, sizeof out, err, sizeof err, "--version"), 0);
    assert_int_equal(sh_exec(err, sizeof err, "sed -n 's/^VERSION := //p' Makefile > %s/v.txt", tmpdir), 0);
    char path[600];
    snprintf(path, sizeof path, "%s/v.txt", tmpdir);
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    char version[64] = "";
    assert_non_null(fgets(version, sizeof version, f));
    fclose(f);
    version[strcspn(version, "\n")] = '\0';
    assert_true(version[0] != '\0');
    snprintf(want, sizeof want, "reflcheck %s (commit ", version);
    if (strncmp(out, want, strlen(want)) != 0)
        fail_msg("--version printed '%s', want it to start '%s'", out, want);
    if (sscanf(out + strlen(want), "%63[0-9a-f]", id) != 1 || strlen(id) < 7)
        fail_msg("--version names no commit: %s", out);
    /* the id is a commit of this repository */
    assert_int_equal(sh_exec(err, sizeof err, "git cat-file -e %s^{commit}", id), 0);
    const char *rest = out + strlen(want) + strlen(id);
    if (strcmp(rest, ")\n") != 0 && strcmp(rest, "-dirty)\n") != 0)
        fail_msg("--version: '%s' after the commit", rest);
}

/* Issue 22: `check --json` gives tools/sweep/ the scene facts it read with regular expressions.
 * Expected values read by hand from scenes/d3d9_glass.yaml: image {256, 192, 4, samples auto,
 * which check --json writes as 0}; six
 * comparisons, the fourth `test: povray` (not the model), the sixth `test: exact_point`, the rest
 * the default test (the model, raster). */
static void test_check_json_scene_facts(void **state)
{
    (void)state;
    static char out[1 << 17];
    char err[4096];
    assert_int_equal(cli_output(out, sizeof out, err, sizeof err, "check --json scenes/d3d9_glass.yaml"), 0);
    cJSON *doc = cJSON_Parse(out);
    assert_non_null(doc);
    const cJSON *img = cJSON_GetObjectItem(doc, "image");
    static const char *const ik[] = {"width", "height", "supersample", "samples"};
    static const int iv[] = {256, 192, 4, 0};
    for (int i = 0; i < 4; i++)
        assert_int_equal(cJSON_GetNumberValue(cJSON_GetObjectItem(img, ik[i])), iv[i]);
    static const char *const want[][3] = {
        {"raster", "povray", "twin"},  {"raster", "cycles", "twin"},    {"raster", "povray", "validate"},
        {"povray", "cycles", "agree"}, {"raster", "exact", "validate"}, {"exact_point", "povray", "agree"},
    };
    const cJSON *list = cJSON_GetObjectItem(doc, "comparisons");
    assert_int_equal(cJSON_GetArraySize(list), 6);
    for (int i = 0; i < 6; i++) {
        const cJSON *c = cJSON_GetArrayItem(list, i);
        assert_string_equal(cJSON_GetStringValue(cJSON_GetObjectItem(c, "test")), want[i][0]);
        assert_string_equal(cJSON_GetStringValue(cJSON_GetObjectItem(c, "reference")), want[i][1]);
        assert_string_equal(cJSON_GetStringValue(cJSON_GetObjectItem(c, "role")), want[i][2]);
        assert_int_equal(cJSON_IsTrue(cJSON_GetObjectItem(c, "test_is_model")), i != 3 && i != 5);
    }
    cJSON_Delete(doc);
}

/* Issue 26: `render --stats FILE` says where the command's time went, phase by phase, for a user
 * and for `make bench`'s CLI ratios. Checked without trusting the figures' values: every phase
 * is there with non-negative wall, CPU and page-fault figures, their sum is the total given, and
 * render_scene's own clock (render_ms) lies inside the render phase (it starts after the call and
 * stops before the return). The size is the one asked for. */
static void test_render_stats(void **state)
{
    (void)state;
    char err[2048], path[600], text[8192];
    assert_int_equal(cli_exec(err, sizeof err,
                              "render scenes/d3d9_glass.yaml -o %s/s.exr --width 20 --height 14 -q --stats %s/s.json",
                              tmpdir, tmpdir),
                     0);
    snprintf(path, sizeof path, "%s/s.json", tmpdir);
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    size_t n = fread(text, 1, sizeof text - 1, f);
    fclose(f);
    text[n] = '\0';
    cJSON *doc = cJSON_Parse(text);
    assert_non_null(doc);
    assert_int_equal(cJSON_GetNumberValue(cJSON_GetObjectItem(doc, "width")), 20);
    assert_int_equal(cJSON_GetNumberValue(cJSON_GetObjectItem(doc, "height")), 14);
    assert_true(cJSON_GetNumberValue(cJSON_GetObjectItem(doc, "triangles")) > 0);
    static const char *const phase[] = {"scene", "mesh", "inputs", "render", "write", "free"};
    const cJSON *ph = cJSON_GetObjectItem(doc, "phases");
    double sum = 0.0;
    for (int i = 0; i < 6; i++) {
        const cJSON *p = cJSON_GetObjectItem(ph, phase[i]);
        if (p == NULL)
            fail_msg("--stats has no phase %s: %s", phase[i], text);
        double w = cJSON_GetNumberValue(cJSON_GetObjectItem(p, "wall_ms"));
        assert_true(w >= 0.0);
        assert_true(cJSON_GetNumberValue(cJSON_GetObjectItem(p, "cpu_ms")) >= 0.0);
        assert_true(cJSON_GetNumberValue(cJSON_GetObjectItem(p, "minor_faults")) >= 0.0);
        sum += w;
    }
    /* Each figure is printed to 6 significant digits: the sum of six roundings. */
    double total = cJSON_GetNumberValue(cJSON_GetObjectItem(doc, "phases_wall_ms"));
    assert_true(fabs(sum - total) <= 1e-5 * 6.0 * total + 1e-9);
    double frame = cJSON_GetNumberValue(cJSON_GetObjectItem(doc, "render_ms"));
    double call = cJSON_GetNumberValue(cJSON_GetObjectItem(cJSON_GetObjectItem(ph, "render"), "wall_ms"));
    if (!(frame > 0.0 && frame <= call * (1.0 + 1e-5)))
        fail_msg("render_ms %g is not inside the render phase's %g ms", frame, call);
    cJSON_Delete(doc);
}

/* --stats may not overwrite the image or a scene input, and an unwritable --stats path fails
 * after the image was written, naming the option. */
static void test_render_stats_refusals(void **state)
{
    (void)state;
    char err[2048];
    int rc = cli_exec(err, sizeof err, "render scenes/d3d9_glass.yaml -o %s/r.exr --stats %s/r.exr -W 8 -H 6", tmpdir,
                      tmpdir);
    expect_refused(err, rc, "--stats");
    rc = cli_exec(err, sizeof err, "render scenes/d3d9_glass.yaml -o %s/r.exr --stats scenes/d3d9_glass.yaml -W 8 -H 6",
                  tmpdir);
    expect_refused(err, rc, "give another --stats path");
    rc = cli_exec(err, sizeof err, "render scenes/d3d9_glass.yaml -o %s/r.exr --stats %s/no/such/dir/s.json -W 8 -H 6",
                  tmpdir, tmpdir);
    if (rc != 1 || strstr(err, "--stats") == NULL)
        fail_msg("exit %d, want 1 and --stats named: %s", rc, err);
    one_line(err);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_unknown_option_names_the_argument),
        cmocka_unit_test(test_missing_value),
        cmocka_unit_test(test_empty_value),
        cmocka_unit_test(test_option_twice),
        cmocka_unit_test(test_numbers),
        cmocka_unit_test(test_diff_mask_size),
        cmocka_unit_test(test_diff_pairs_as_alone),
        cmocka_unit_test(test_help_words_as_files),
        cmocka_unit_test(test_every_command_help),
        cmocka_unit_test(test_top_help),
        cmocka_unit_test(test_version),
        cmocka_unit_test(test_check_json_scene_facts),
        cmocka_unit_test(test_render_stats),
        cmocka_unit_test(test_render_stats_refusals),
    };
    return cmocka_run_group_tests(tests, tmpdir_setup, tmpdir_teardown);
}
