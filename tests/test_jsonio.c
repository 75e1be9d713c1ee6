/* test_jsonio.c - the harness's one JSON writer: the text is cJSON's with one newline, a file
 * is whole or absent, and a failed write is reported. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include <cJSON.h>

#include "check.h"
#include "fileio.h"
#include "jsonio.h"

static cJSON *doc_make(void)
{
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "scene", "a \"quoted\" <name>");
    cJSON_AddNumberToObject(o, "rel_rms", 1.25e-4);
    return o;
}

static void test_file_round_trip(void **state)
{
    (void)state;
    char path[128];
    snprintf(path, sizeof path, "/tmp/reflcheck-test-jsonio-%ld.json", (long)getpid());
    cJSON *o = doc_make();
    char err[512];
    assert_int_equal(jsonio_write_file(o, path, err, sizeof err), RC_OK);
    size_t len = 0;
    char *text = fileio_read_all(path, &len);
    assert_non_null(text);
    /* cJSON's formatted text, then exactly one newline. */
    char *want = cJSON_Print(o);
    assert_int_equal(len, strlen(want) + 1);
    assert_memory_equal(text, want, strlen(want));
    assert_int_equal(text[len - 1], '\n');
    cJSON *back = cJSON_Parse(text);
    assert_string_equal(cJSON_GetObjectItemCaseSensitive(back, "scene")->valuestring, "a \"quoted\" <name>");
    close_rel(cJSON_GetObjectItemCaseSensitive(back, "rel_rms")->valuedouble, 1.25e-4, 1e-15);
    cJSON_Delete(back);
    cJSON_free(want);
    free(text);
    cJSON_Delete(o);
    expect_no_temp("/tmp", path + strlen("/tmp/"));
    unlink(path);
}

static void test_failed_writes_reported(void **state)
{
    (void)state;
    cJSON *o = doc_make();
    char err[512] = "";
    assert_int_not_equal(jsonio_write_file(o, "/tmp/reflcheck-no-such-dir/x.json", err, sizeof err), RC_OK);
    assert_non_null(strstr(err, "reflcheck-no-such-dir"));
    /* A stream whose writes fail: an input-only stream refuses fputs at once. */
    FILE *ro = fopen("/dev/null", "r");
    assert_non_null(ro);
    assert_int_equal(jsonio_print(ro, o), -1);
    fclose(ro);
    cJSON_Delete(o);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_file_round_trip),
        cmocka_unit_test(test_failed_writes_reported),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
