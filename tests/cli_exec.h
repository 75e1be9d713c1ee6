/* cli_exec.h - run the reflcheck command line from a unit test. Include after <cmocka.h>.
 *
 *   cli_bin()                                    $REFLCHECK_BIN (set by tests/run_unit.sh), else build/reflcheck
 *   int rc = cli_exec(err, sizeof err, "render %s -o %s", in, out);
 *       runs `reflcheck ARGS` through /bin/sh with stdout discarded; returns the exit status
 *       (128 + signal if it was killed) and the first errlen - 1 bytes of stderr in err.
 *   int rc = sh_exec(err, sizeof err, "ulimit -f 4; %s render ...", cli_bin());   any shell command
 * Arguments are pasted into a shell command: quote paths that may hold spaces yourself.
 */
#ifndef REFLCHECK_TESTS_CLI_EXEC_H
#define REFLCHECK_TESTS_CLI_EXEC_H

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

static inline const char *cli_bin(void)
{
    const char *b = getenv("REFLCHECK_BIN");
    return b && *b ? b : "build/reflcheck";
}

/* Runs the shell command (printf format) with stdout to /dev/null unless the command redirects
 * it; returns its exit status (128 + signal when killed) and the first errlen - 1 bytes of its
 * stderr in err. The stderr file is per process, so test programs run side by side do not mix. */
__attribute__((format(printf, 3, 4))) static inline int sh_exec(char *err, size_t errlen, const char *fmt, ...)
{
    char cmd[8192], full[8400], errfile[64];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(cmd, sizeof cmd, fmt, ap);
    va_end(ap);
    snprintf(errfile, sizeof errfile, "/tmp/reflcheck-cli-%ld.err", (long)getpid());
    snprintf(full, sizeof full, "exec >/dev/null 2>%s; %s", errfile, cmd);
    int st = system(full);
    FILE *f = fopen(errfile, "r");
    size_t n = f != NULL ? fread(err, 1, errlen - 1, f) : 0;
    err[n] = '\0';
    if (f != NULL)
        fclose(f);
    unlink(errfile);
    if (st == -1)
        return -1;
    return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + (WIFSIGNALED(st) ? WTERMSIG(st) : 0);
}

/* `reflcheck ARGS` through sh_exec. */
__attribute__((format(printf, 3, 4))) static inline int cli_exec(char *err, size_t errlen, const char *fmt, ...)
{
    char args[4096];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(args, sizeof args, fmt, ap);
    va_end(ap);
    return sh_exec(err, errlen, "%s %s", cli_bin(), args);
}

#endif
