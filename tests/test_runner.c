/* The renderer runner: every way a child process can end is recorded, none aborts us. */
#include <errno.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>

#include "procs.h"

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
    /* Killed, not waited for: a runner that waited for the group would take the sleeps' 30 s.
     * No tighter bound: how soon the kill lands depends on the machine's load. */
    assert_true(r.wall_s < 30.0);
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

static void test_exit_127_is_a_failure_not_a_skip(void **state)
{
    (void)state;
    /* The program ran and chose 127 (a wrapper script whose library is missing does this):
     * that is a failed render, not an uninstalled renderer. */
    const char *argv[] = {"sh", "-c", "exit 127", NULL};
    runner_result r;
    assert_int_equal(runner_exec(argv, 10.0, NULL, &r), RUNNER_FAILED);
    assert_int_equal(r.exit_code, 127);
    assert_int_equal(r.exec_errno, 0);
    assert_string_equal(runner_status_name(r.status), "failed");
}

static void test_bad_interpreter_is_a_failure(void **state)
{
    (void)state;
    /* Installed (on PATH, executable) but its interpreter is missing: exec fails with ENOENT. */
    char path[128];
    snprintf(path, sizeof path, "/tmp/reflcheck-test-runner-interp-%ld", (long)getpid());
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs("#!/nonexistent/reflcheck-interpreter\n", f);
    fclose(f);
    chmod(path, 0755);
    const char *argv[] = {path, NULL};
    runner_result r;
    runner_status st = runner_exec(argv, 10.0, NULL, &r);
    unlink(path);
    assert_int_equal(st, RUNNER_FAILED);
    assert_int_equal(r.exec_errno, ENOENT);
}

static void test_which(void **state)
{
    (void)state;
    char path[4352];
    assert_true(runner_which("sh", path, sizeof path));
    assert_non_null(strstr(path, "/sh"));
    assert_int_equal(access(path, X_OK), 0);
    assert_false(runner_which("reflcheck-no-such-renderer", path, sizeof path));
    assert_string_equal(path, "");
}

/* A process of ours that waits in runner_exec on a renderer (and a grandchild it started), to
 * be killed with sig: afterwards neither renderer process may be left. */
static void kill_waiting_parent(int sig, int *parent_status, pid_t *renderer, pid_t *grandchild)
{
    char a[128], b[128], script[512];
    snprintf(a, sizeof a, "/tmp/reflcheck-test-runner-%ld-a.pid", (long)getpid());
    snprintf(b, sizeof b, "/tmp/reflcheck-test-runner-%ld-b.pid", (long)getpid());
    unlink(a);
    unlink(b);
    snprintf(script, sizeof script, "sleep 60 & echo $! > %s; echo $$ > %s; wait", b, a);
    pid_t parent = fork();
    assert_true(parent >= 0);
    if (parent == 0) {
        const char *argv[] = {"sh", "-c", script, NULL};
        runner_result r;
        runner_exec(argv, 120.0, NULL, &r);
        _exit(0);
    }
    *renderer = proc_read_pid(a);
    *grandchild = proc_read_pid(b);
    assert_true(*renderer > 0 && *grandchild > 0);
    kill(parent, sig);
    assert_int_equal(waitpid(parent, parent_status, 0), parent);
    unlink(a);
    unlink(b);
}

static void test_sigterm_is_forwarded_to_the_group(void **state)
{
    (void)state;
    int st;
    pid_t renderer, grandchild;
    kill_waiting_parent(SIGTERM, &st, &renderer, &grandchild);
    /* The parent still ends by the signal it got, after taking the renderer's group with it. */
    assert_true(WIFSIGNALED(st));
    assert_int_equal(WTERMSIG(st), SIGTERM);
    assert_true(proc_gone_within(renderer));
    assert_true(proc_gone_within(grandchild));
}

static void test_sigkill_takes_the_renderer(void **state)
{
    (void)state;
    int st;
    pid_t renderer, grandchild;
    kill_waiting_parent(SIGKILL, &st, &renderer, &grandchild);
    assert_true(WIFSIGNALED(st));
    /* PR_SET_PDEATHSIG: the renderer itself dies with us; its own children are out of reach. */
    assert_true(proc_gone_within(renderer));
    kill(grandchild, SIGKILL);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_ok_and_log),
        cmocka_unit_test(test_failed_exit_code),
        cmocka_unit_test(test_crash_is_recorded),
        cmocka_unit_test(test_timeout_kills_the_group),
        cmocka_unit_test(test_missing_program),
        cmocka_unit_test(test_cpu_time),
        cmocka_unit_test(test_exit_127_is_a_failure_not_a_skip),
        cmocka_unit_test(test_bad_interpreter_is_a_failure),
        cmocka_unit_test(test_which),
        cmocka_unit_test(test_sigterm_is_forwarded_to_the_group),
        cmocka_unit_test(test_sigkill_takes_the_renderer),
    };
    return cmocka_run_group_tests_name("runner", tests, NULL, NULL);
}
