/* The renderer runner: every way a child process can end is recorded, none aborts us. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "runner.h"

static void test_ok_and_log(void **state)
{
    (void)state;
    const char *argv[] = {"sh", "-c", "echo rendered-42; echo warn >&2", NULL};
    runner_result r;
    assert_int_equal(runner_exec(argv, 10.0, "/tmp/reflcheck-test-runner.log", &r), RUNNER_OK);
    FILE *f = fopen("/tmp/reflcheck-test-runner.log", "r");
    assert_non_null(f);
    char buf[128] = {0};
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    assert_true(n > 0);
    assert_non_null(strstr(buf, "rendered-42"));
    assert_non_null(strstr(buf, "warn"));
}

static void test_failed_exit_code(void **state)
{
    (void)state;
    const char *argv[] = {"sh", "-c", "exit 3", NULL};
    runner_result r;
    assert_int_equal(runner_exec(argv, 10.0, NULL, &r), RUNNER_FAILED);
    assert_int_equal(r.exit_code, 3);
}

static void test_crash_is_recorded(void **state)
{
    (void)state;
    const char *argv[] = {"sh", "-c", "kill -SEGV $$", NULL};
    runner_result r;
    assert_int_equal(runner_exec(argv, 10.0, NULL, &r), RUNNER_CRASHED);
    assert_int_equal(r.signal, 11);
}

static void test_timeout_kills_the_group(void **state)
{
    (void)state;
    /* The child starts a grandchild; both must die with the group. */
    const char *argv[] = {"sh", "-c", "sleep 30 & sleep 30", NULL};
    runner_result r;
    assert_int_equal(runner_exec(argv, 0.3, NULL, &r), RUNNER_TIMEOUT);
    assert_true(r.wall_s < 5.0);
    assert_true(r.wall_s >= 0.3);
}

static void test_missing_program(void **state)
{
    (void)state;
    const char *argv[] = {"reflcheck-no-such-renderer", NULL};
    runner_result r;
    assert_int_equal(runner_exec(argv, 1.0, NULL, &r), RUNNER_MISSING);
    assert_string_equal(runner_status_name(r.status), "skipped");
    assert_false(runner_available("reflcheck-no-such-renderer"));
    assert_true(runner_available("sh"));
}

static void test_cpu_time(void **state)
{
    (void)state;
    const char *argv[] = {"sh", "-c", "i=0; while [ $i -lt 200000 ]; do i=$((i+1)); done", NULL};
    runner_result r;
    assert_int_equal(runner_exec(argv, 60.0, NULL, &r), RUNNER_OK);
    assert_true(r.cpu_s > 0.0);
    assert_true(r.cpu_s <= r.wall_s * 1.5 + 0.05);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_ok_and_log),        cmocka_unit_test(test_failed_exit_code),
        cmocka_unit_test(test_crash_is_recorded), cmocka_unit_test(test_timeout_kills_the_group),
        cmocka_unit_test(test_missing_program),   cmocka_unit_test(test_cpu_time),
    };
    return cmocka_run_group_tests_name("runner", tests, NULL, NULL);
}
