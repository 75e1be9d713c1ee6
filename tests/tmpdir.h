/* tmpdir.h - one scratch folder per unit-test program: the cmocka group setup makes it, the
 * group teardown removes it with everything the tests wrote into it.
 *
 * Usage:
 *   #include "tmpdir.h"
 *   snprintf(path, sizeof path, "%s/x.exr", tmpdir);            inside a test
 *   return cmocka_run_group_tests(tests, tmpdir_setup, tmpdir_teardown);
 * The folder is /tmp/reflcheck-test-XXXXXX made by mkdtemp (private to the user, unique per run,
 * so two programs or two runs never share one). Setup and teardown return 0, or -1 on failure,
 * which cmocka reports as the group's failure.
 */
#ifndef REFLCHECK_TESTS_TMPDIR_H
#define REFLCHECK_TESTS_TMPDIR_H

#include <stdio.h>
#include <stdlib.h>

static char tmpdir[] = "/tmp/reflcheck-test-XXXXXX";

static int tmpdir_setup(void **state)
{
    (void)state;
    return mkdtemp(tmpdir) == NULL ? -1 : 0;
}

static int tmpdir_teardown(void **state)
{
    (void)state;
    char cmd[sizeof tmpdir + 16];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    return system(cmd) == 0 ? 0 : -1;
}

#endif
