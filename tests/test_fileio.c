/* Crash-safe writes and whole-file reads of the harness's outputs; bounded, non-blocking
 * opens of a user's input files; the memory limit. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <dirent.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include <cmocka.h>

#include "check.h"
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
    expect_no_temp("/tmp", "reflcheck-test-fileio.txt");
    expect_no_temp("/tmp", "reflcheck-test-fileio-copy.txt");
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

/* Inputs: only regular files within the limit; a FIFO is refused at once (the open is
 * non-blocking), a sparse 2 GiB file by its size before any byte is read. */
static void test_open_input(void **state)
{
    (void)state;
    char err[512];
    int fd = -2;
    long long size = -1;
    const char *small = "/tmp/reflcheck-test-input.txt";
    assert_int_equal(fileio_write_atomic(small, "0123456789", err, sizeof err), RC_OK);
    assert_int_equal(fileio_open_input(small, 10, "a test file", &fd, &size, err, sizeof err), RC_OK);
    assert_true(fd >= 0);
    assert_int_equal(size, 10);
    char buf[16];
    assert_int_equal(read(fd, buf, sizeof buf), 10);
    close(fd);
    /* One byte over the limit is refused, naming the size and the limit. */
    assert_int_equal(fileio_open_input(small, 9, "a test file", &fd, &size, err, sizeof err), RC_ERR_RANGE);
    assert_int_equal(fd, -1);
    assert_non_null(strstr(err, "10 bytes is over the limit of 9 bytes"));
    unlink(small);

    const char *fifo = "/tmp/reflcheck-test-input.fifo";
    unlink(fifo);
    assert_int_equal(mkfifo(fifo, 0600), 0);
    /* A regression would block in open(); the child's alarm turns that into a failure. */
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        alarm(20);
        char e[512];
        int f;
        rc_status st = fileio_open_input(fifo, 1 << 20, "a test file", &f, NULL, e, sizeof e);
        _exit(st == RC_ERR_RANGE && strstr(e, "not a regular file (a FIFO)") != NULL ? 0 : 1);
    }
    int ws = 0;
    assert_int_equal(waitpid(pid, &ws, 0), pid);
    assert_true(WIFEXITED(ws));
    assert_int_equal(WEXITSTATUS(ws), 0);
    unlink(fifo);

    const char *kinds[][2] = {{"/dev/zero", "(a character device)"}, {"/tmp", "(a directory)"}};
    for (int i = 0; i < 2; i++) {
        assert_int_equal(fileio_open_input(kinds[i][0], 1 << 20, "a mesh", &fd, NULL, err, sizeof err), RC_ERR_RANGE);
        assert_non_null(strstr(err, kinds[i][1]));
        assert_non_null(strstr(err, "give a path to a mesh"));
    }
    assert_int_equal(fileio_open_input("/nonexistent-dir/m.obj", 1 << 20, "a mesh", &fd, NULL, err, sizeof err),
                     RC_ERR_IO);
    assert_non_null(strstr(err, "No such file or directory"));

    const char *big = "/tmp/reflcheck-test-sparse.obj";
    int w = open(big, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    assert_true(w >= 0);
    assert_int_equal(ftruncate(w, (off_t)2 << 30), 0);
    close(w);
    assert_int_equal(fileio_open_input(big, FILEIO_MESH_MAX_BYTES, "a mesh", &fd, NULL, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "2147483648 bytes is over the limit of 1073741824 bytes"));
    unlink(big);
}

/* fileio_read_all reads regular files only: a FIFO returns NULL at once (it used to block in
 * fopen) and /dev/zero returns NULL instead of being read until memory runs out. */
static void test_read_all_bounded(void **state)
{
    (void)state;
    const char *fifo = "/tmp/reflcheck-test-readall.fifo";
    unlink(fifo);
    assert_int_equal(mkfifo(fifo, 0600), 0);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        alarm(20);
#ifndef __SANITIZE_ADDRESS__
        /* An unbounded read of /dev/zero fails here instead of meeting the OOM killer. */
        struct rlimit rl = {.rlim_cur = (rlim_t)2 << 30, .rlim_max = (rlim_t)2 << 30};
        setrlimit(RLIMIT_AS, &rl);
#endif
        int ok = fileio_read_all(fifo, NULL) == NULL && fileio_read_all("/dev/zero", NULL) == NULL &&
                 fileio_read_all("/tmp", NULL) == NULL;
        _exit(ok ? 0 : 1);
    }
    int ws = 0;
    assert_int_equal(waitpid(pid, &ws, 0), pid);
    assert_true(WIFEXITED(ws));
    assert_int_equal(WEXITSTATUS(ws), 0);
    unlink(fifo);
}

static void test_memory_limit(void **state)
{
    (void)state;
    char err[512];
    size_t bytes = 0;
    struct {
        const char *text;
        size_t want;
    } ok[] = {
        {"12345", 12345}, {"3K", 3u << 10}, {"64M", (size_t)64 << 20}, {"2G", (size_t)2 << 30}, {"1t", (size_t)1 << 40},
    };
    for (size_t i = 0; i < sizeof ok / sizeof ok[0]; i++) {
        setenv("REFLCHECK_MEMORY_LIMIT", ok[i].text, 1);
        assert_int_equal(fileio_memory_limit(&bytes, err, sizeof err), RC_OK);
        assert_int_equal(bytes, ok[i].want);
    }
    const char *bad[] = {"lots", "-1G", "0", "8GB", "1.5G", "99999999999999999999"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        setenv("REFLCHECK_MEMORY_LIMIT", bad[i], 1);
        if (fileio_memory_limit(&bytes, err, sizeof err) != RC_ERR_RANGE)
            fail_msg("REFLCHECK_MEMORY_LIMIT=%s accepted as %zu", bad[i], bytes);
        assert_non_null(strstr(err, bad[i]));
    }
    /* Unset: half the physical memory, worked out here from the same two sysconf values. */
    unsetenv("REFLCHECK_MEMORY_LIMIT");
    assert_int_equal(fileio_memory_limit(&bytes, err, sizeof err), RC_OK);
    size_t want = (size_t)sysconf(_SC_PHYS_PAGES) / 2 * (size_t)sysconf(_SC_PAGESIZE);
    assert_int_equal(bytes, want);
}

/* Outputs: a device, FIFO or directory is refused; a symlink leads to its target; a failed
 * write leaves the destination as it was and removes the temporary file. */
static void test_output_target(void **state)
{
    (void)state;
    char err[512], target[FILEIO_PATH_MAX];
    assert_int_equal(fileio_output_target("/dev/full", target, sizeof target, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "(a character device)"));
    assert_int_equal(fileio_output_target("/tmp", target, sizeof target, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "(a directory)"));
    /* Writes go to a FIFO of our own, never to /dev/full: a regression renaming over its
     * destination would replace the system's device. The child's alarm catches a blocking open. */
    const char *fifo = "/tmp/reflcheck-test-output.fifo";
    unlink(fifo);
    assert_int_equal(mkfifo(fifo, 0600), 0);
    pid_t child = fork();
    assert_true(child >= 0);
    if (child == 0) {
        alarm(20);
        char e[512];
        _exit(fileio_write_atomic(fifo, "x", e, sizeof e) == RC_ERR_RANGE && strstr(e, "(a FIFO)") != NULL &&
                      fileio_copy("/etc/hostname", fifo) == -1
                  ? 0
                  : 1);
    }
    int cs = 0;
    assert_int_equal(waitpid(child, &cs, 0), child);
    assert_true(WIFEXITED(cs));
    assert_int_equal(WEXITSTATUS(cs), 0);
    struct stat fst;
    assert_int_equal(lstat(fifo, &fst), 0);
    assert_true(S_ISFIFO(fst.st_mode));
    unlink(fifo);

    const char *real = "/tmp/reflcheck-test-target.txt", *lnk = "/tmp/reflcheck-test-target-link.txt";
    unlink(lnk);
    assert_int_equal(fileio_write_atomic(real, "old", err, sizeof err), RC_OK);
    assert_int_equal(symlink(real, lnk), 0);
    assert_int_equal(fileio_output_target(lnk, target, sizeof target, err, sizeof err), RC_OK);
    assert_string_equal(target, real);
    assert_true(fileio_same_file(lnk, real));
    assert_false(fileio_same_file(lnk, "/etc/hostname"));
    assert_false(fileio_same_file("/nonexistent-dir/a", "/nonexistent-dir/a"));
    /* Writing through the link replaces the target's contents and keeps the link. */
    assert_int_equal(fileio_write_atomic(lnk, "new", err, sizeof err), RC_OK);
    char *text = fileio_read_all(real, NULL);
    assert_string_equal(text, "new");
    free(text);
    struct stat st;
    assert_int_equal(lstat(lnk, &st), 0);
    assert_true(S_ISLNK(st.st_mode));

    /* A failed write (file size limit, in a child) keeps "new" and leaves no temporary. */
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        alarm(20);
        signal(SIGXFSZ, SIG_IGN);
        struct rlimit rl = {.rlim_cur = 16, .rlim_max = 16};
        setrlimit(RLIMIT_FSIZE, &rl);
        char e[512];
        rc_status s = fileio_write_atomic(real, "a text longer than the sixteen bytes allowed", e, sizeof e);
        _exit(s == RC_ERR_IO && strstr(e, "File too large") != NULL ? 0 : 1);
    }
    int ws = 0;
    assert_int_equal(waitpid(pid, &ws, 0), pid);
    assert_true(WIFEXITED(ws));
    assert_int_equal(WEXITSTATUS(ws), 0);
    text = fileio_read_all(real, NULL);
    assert_string_equal(text, "new");
    free(text);
    expect_no_temp("/tmp", "reflcheck-test-target.txt");
    unlink(lnk);
    unlink(real);
}

/* The image readers' shared check: a header that needs more coded bytes than the file has is
 * PARSE (cut or lying), one whose decoded size exceeds the memory limit RANGE, both one line
 * naming the file; exactly enough bytes, or exactly the limit, passes. */
static void test_image_budget(void **state)
{
    (void)state;
    char err[512];
    setenv("REFLCHECK_MEMORY_LIMIT", "1K", 1);
    assert_int_equal(fileio_image_budget("a.png", "PNG", 16384, 16384, 32513.0, 689, 100.0, err, sizeof err),
                     RC_ERR_PARSE);
    assert_non_null(strstr(err, "a.png: the PNG header says 16384 x 16384"));
    assert_non_null(strstr(err, "at least 32513 bytes"));
    assert_non_null(strstr(err, "has 689"));
    assert_null(strchr(err, '\n'));
    assert_int_equal(fileio_image_budget("a.png", "PNG", 4, 4, 689.0, 689, 1024.0, err, sizeof err), RC_OK);
    assert_int_equal(fileio_image_budget("b.jpg", "JPEG", 64, 64, 10.0, 689, 1025.0, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "b.jpg: a 64 x 64 JPEG"));
    assert_non_null(strstr(err, "REFLCHECK_MEMORY_LIMIT"));
    setenv("REFLCHECK_MEMORY_LIMIT", "nonsense", 1);
    assert_int_equal(fileio_image_budget("b.jpg", "JPEG", 64, 64, 10.0, 689, 1.0, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "b.jpg: REFLCHECK_MEMORY_LIMIT"));
    unsetenv("REFLCHECK_MEMORY_LIMIT");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_write_read_copy), cmocka_unit_test(test_errors),
        cmocka_unit_test(test_open_input),      cmocka_unit_test(test_read_all_bounded),
        cmocka_unit_test(test_memory_limit),    cmocka_unit_test(test_output_target),
        cmocka_unit_test(test_image_budget),
    };
    return cmocka_run_group_tests_name("fileio", tests, NULL, NULL);
}
