/* procs.h - watching processes from a unit test (Linux /proc). Include after <cmocka.h>.
 *
 *   proc_alive(pid)        1 while pid exists and is not a zombie (a zombie has ended; only its
 *                          parent's wait is due)
 *   proc_gone_within(pid)  waits up to 20 s for pid to end; 1 if it did
 *   proc_read_pid(path)    waits up to 30 s for a child to write its pid into path; -1 if not
 * The bounds are generous (a renderer gets 2 s of grace after SIGTERM) so that a loaded machine
 * never fails a test that a hang would fail anyway.
 */
#ifndef REFLCHECK_TESTS_PROCS_H
#define REFLCHECK_TESTS_PROCS_H

#include <stdio.h>
#include <string.h>
#include <sys/types.h>
#include <time.h>

static inline int proc_alive(pid_t pid)
{
    char p[64], buf[512];
    snprintf(p, sizeof p, "/proc/%ld/stat", (long)pid);
    FILE *f = fopen(p, "r");
    if (f == NULL)
        return 0;
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = '\0';
    const char *close_paren = strrchr(buf, ')');
    return close_paren != NULL && close_paren[1] == ' ' && close_paren[2] != 'Z';
}

static inline void proc_nap_10ms(void)
{
    struct timespec t = {0, 10 * 1000 * 1000};
    nanosleep(&t, NULL);
}

static inline int proc_gone_within(pid_t pid)
{
    for (int i = 0; i < 2000 && proc_alive(pid); i++)
        proc_nap_10ms();
    return !proc_alive(pid);
}

static inline pid_t proc_read_pid(const char *path)
{
    for (int i = 0; i < 3000; i++) {
        FILE *f = fopen(path, "r");
        long v = 0;
        int got = f != NULL && fscanf(f, "%ld", &v) == 1;
        if (f != NULL)
            fclose(f);
        if (got && v > 0)
            return (pid_t)v;
        proc_nap_10ms();
    }
    return -1;
}

#endif
