/* reflcheck - command line.
 *
 *   reflcheck --help | help [COMMAND]     the commands (the table in cli/cli.c), or one command's help
 *   reflcheck COMMAND --help | -h         a command's options with defaults and units, and an example
 *   reflcheck --version                   the version and the git commit it was built from
 * Exit status: 0 ok, 1 a run failed (a job not ok or skipped, a comparison that fails or errors, a
 * write that failed), 2 bad input (command line, scene file, a file it references, an output onto an input).
 */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

/* The project version and the commit the program was built from, from the Makefile (VERSION,
 * git rev-parse); a build without them says so. */
#ifndef REFLCHECK_VERSION
#define REFLCHECK_VERSION "unknown"
#endif
#ifndef REFLCHECK_COMMIT
#define REFLCHECK_COMMIT "unknown"
#endif

int main(int argc, char **argv)
{
    if (argc < 2) {
        cli_usage(stderr);
        return 2;
    }
    if (strcmp(argv[1], "-h") == 0 || strcmp(argv[1], "--help") == 0)
        return cli_find("help")->run(1, argv + 1);
    if (strcmp(argv[1], "--version") == 0) {
        if (printf("reflcheck %s (commit %s)\n", REFLCHECK_VERSION, REFLCHECK_COMMIT) < 0 || fflush(stdout) != 0) {
            fprintf(stderr, "reflcheck: --version: cannot write to standard output\n");
            return 1;
        }
        return 0;
    }
    /* Past a file size limit (ulimit -f) a write must fail with EFBIG and be reported by every
     * command (outputs are temporaries renamed on success), not kill the process with SIGXFSZ
     * and leave a temporary behind. */
    signal(SIGXFSZ, SIG_IGN);
    const cli_command *c = cli_find(argv[1]);
    if (c == NULL) {
        fprintf(stderr, "reflcheck: unknown command '%s'; see reflcheck --help for the commands\n", argv[1]);
        return 2;
    }
    return c->run(argc - 1, argv + 1);
}
