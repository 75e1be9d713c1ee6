/* test_cli.c - the command line's refusals (issue 20, "bad input, third round"): every command
 * names the argument it refuses as typed (an unknown option, a letter inside a group such as
 * "-rf.yaml", an option without its value or with an empty one, an option given twice), never
 * the command; `diff --mask` of another size names the mask, its size and the size it must
 * have; numbers with junk or out of range are refused by the option's name. Each refusal is
 * exit status 2 and one line; nothing is written. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "cli_exec.h"
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

/* Help-like words where a file name goes: taken as the file name and named (held). */
static void test_help_words_as_files(void **state)
{
    (void)state;
    char err[2048];
    expect_refused(err, cli_exec(err, sizeof err, "check --help"), "--help: cannot open");
    expect_refused(err, cli_exec(err, sizeof err, "check -h"), "-h: cannot open");
    /* after "--" an option-like word is a scene file, never an option */
    int rc = cli_exec(err, sizeof err, "render -o %s/h.exr -- --help", tmpdir);
    expect_refused(err, rc, "--help");
    assert_null(strstr(err, "unknown option"));
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
        cmocka_unit_test(test_help_words_as_files),
    };
    return cmocka_run_group_tests(tests, tmpdir_setup, tmpdir_teardown);
}
