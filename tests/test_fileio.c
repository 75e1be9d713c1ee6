/* Crash-safe writes and whole-file reads of the harness's outputs. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "fileio.h"

static void test_write_read_copy(void **state)
{
    (void)state;
    char err[256];
    const char *path = "/tmp/reflcheck-test-fileio.txt", *copy = "/tmp/reflcheck-test-fileio-copy.txt";
    assert_int_equal(fileio_write_atomic(path, "first\n", err, sizeof err), RC_OK);
    /* A second write replaces the whole file, never appends or leaves a mix. */
    assert_int_equal(fileio_write_atomic(path, "second, longer\n", err, sizeof err), RC_OK);
    size_t len = 0;
    char *text = fileio_read_all(path, &len);
    assert_non_null(text);
    assert_int_equal(len, strlen("second, longer\n"));
    assert_string_equal(text, "second, longer\n");
    free(text);
    assert_int_equal(fileio_copy(path, copy), 0);
    text = fileio_read_all(copy, NULL);
    assert_non_null(text);
    assert_string_equal(text, "second, longer\n");
    free(text);
    /* No temporary file is left behind. */
    char tmp[1100];
    fileio_temp_name(path, tmp, sizeof tmp);
    assert_int_not_equal(access(tmp, F_OK), 0);
    unlink(path);
    unlink(copy);
}

static void test_errors(void **state)
{
    (void)state;
    char err[256];
    assert_int_equal(fileio_write_atomic("/nonexistent-dir/x.json", "x", err, sizeof err), RC_ERR_IO);
    assert_non_null(strstr(err, "/nonexistent-dir/x.json"));
    assert_null(fileio_read_all("/nonexistent-dir/x.json", NULL));
    assert_int_equal(fileio_copy("/nonexistent-dir/x.json", "/tmp/reflcheck-never.txt"), -1);
    assert_int_equal(fileio_copy("/etc/hostname", "/nonexistent-dir/y"), -1);
    /* An empty file reads as an empty string, not as a failure. */
    assert_int_equal(fileio_write_atomic("/tmp/reflcheck-test-empty.txt", "", err, sizeof err), RC_OK);
    size_t len = 7;
    char *text = fileio_read_all("/tmp/reflcheck-test-empty.txt", &len);
    assert_non_null(text);
    assert_int_equal(len, 0);
    free(text);
    unlink("/tmp/reflcheck-test-empty.txt");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_write_read_copy),
        cmocka_unit_test(test_errors),
    };
    return cmocka_run_group_tests_name("fileio", tests, NULL, NULL);
}
