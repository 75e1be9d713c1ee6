/* check.h - helpers the unit tests share. Include after <cmocka.h>.
 *
 *   close_rel(got, want, 1e-6);   fails with both values printed unless |got - want| <= rel |want|
 *   deg(30.0)                      degrees to radians
 *   expect_no_temp("/tmp", "x.exr")   fails if a temporary x.exr.tmp* of an atomic write is left
 */
#ifndef REFLCHECK_TESTS_CHECK_H
#define REFLCHECK_TESTS_CHECK_H

#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#define TEST_PI 3.14159265358979323846

static inline double deg(double d) { return d * TEST_PI / 180.0; }

static inline void close_rel(double got, double want, double rel)
{
    /* 1e-300 keeps a zero expectation from demanding an exact zero through a zero tolerance
     * while still being far below any value the tests compare. */
    double tol = rel * fmax(fabs(want), 1e-300);
    if (!(fabs(got - want) <= tol))
        fail_msg("got %.17g, want %.17g (relative tolerance %g)", got, want, rel);
}

static inline void expect_no_temp(const char *dir, const char *name)
{
    DIR *d = opendir(dir);
    if (d == NULL)
        fail_msg("cannot list %s", dir);
    char prefix[300];
    snprintf(prefix, sizeof prefix, "%s.tmp", name);
    struct dirent *e;
    while ((e = readdir(d)) != NULL)
        if (strncmp(e->d_name, prefix, strlen(prefix)) == 0)
            fail_msg("temporary file %s/%s left behind", dir, e->d_name);
    closedir(d);
}

#endif
