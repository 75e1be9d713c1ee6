/* reflcheck compare: measure each listed comparison of the scenes on one run's renders.
 * reflcheck diff: the metrics of one image pair; exit 0 ok, 1 the value gate fails or the
 * metrics cannot be written, 2 bad input (command line, an image that cannot be read or does
 * not match). */
#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "compare.h"

int cli_compare(int argc, char **argv)
{
    static const struct option longopts[] = {{"run", required_argument, NULL, 'r'}, {NULL, 0, NULL, 0}};
    const char *run = NULL;
    int c;
    optind = 1;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "", longopts, NULL)) != -1) {
        if (c != 'r') {
            fprintf(stderr, "reflcheck: compare: unknown option '%s'; usage: reflcheck compare SCENE... --run DIR\n",
                    argv[optind - 1]);
            return CLI_BAD_INPUT;
        }
        run = optarg;
    }
    if (run == NULL || optind >= argc) {
        fprintf(stderr, "reflcheck: usage: reflcheck compare SCENE... --run DIR\n");
        return CLI_BAD_INPUT;
    }
    int failed = 0, worst = CLI_OK;
    for (int i = optind; i < argc; i++) {
        compare_summary sum;
        char err[1024];
        rc_status st = compare_scene(argv[i], run, &sum, err, sizeof err);
        if (st != RC_OK) {
            fprintf(stderr, "reflcheck: %s\n", err);
            worst = cli_exit_status(st);
            continue;
        }
        printf("%-40s pass %d  warn %d  fail %d  skipped %d  error %d\n", argv[i], sum.pass, sum.warn, sum.fail,
               sum.skipped, sum.error);
        if (sum.fail > 0 || sum.error > 0) {
            failed = 1;
            if (sum.first_failure[0])
                fprintf(stderr, "FAIL %s\n", sum.first_failure);
        }
    }
    return worst != CLI_OK ? worst : (failed ? CLI_FAILED : CLI_OK);
}

/* reflcheck diff TEST.exr REF.exr [--mask GEO.exr]: the metrics of one image pair as JSON. */
int cli_diff(int argc, char **argv)
{
    static const struct option longopts[] = {{"mask", required_argument, NULL, 'm'}, {NULL, 0, NULL, 0}};
    const char *mask = NULL;
    int c;
    optind = 1;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "", longopts, NULL)) != -1) {
        if (c != 'm') {
            fprintf(stderr, "reflcheck: diff: unknown option '%s'; usage: reflcheck diff TEST.exr REF.exr [--mask GEO.exr]\n",
                    argv[optind - 1]);
            return CLI_BAD_INPUT;
        }
        mask = optarg;
    }
    if (optind != argc - 2) {
        fprintf(stderr, "reflcheck: usage: reflcheck diff TEST.exr REF.exr [--mask GEO.exr]\n");
        return CLI_BAD_INPUT;
    }
    char err[1024];
    int gate_failed = 0;
    rc_status st = compare_images(argv[optind], argv[optind + 1], mask, stdout, &gate_failed, err, sizeof err);
    if (st != RC_OK) {
        /* Every image here is the user's input: one that cannot be read or does not match is
         * bad input; only running out of memory is ours. */
        fprintf(stderr, "reflcheck: %s\n", err);
        return st == RC_ERR_NOMEM ? CLI_FAILED : CLI_BAD_INPUT;
    }
    if (fflush(stdout) != 0 || ferror(stdout)) {
        fprintf(stderr, "reflcheck: diff: cannot write the metrics to standard output: %s\n", strerror(errno));
        return CLI_FAILED;
    }
    if (gate_failed) {
        fprintf(stderr, "reflcheck: diff %s %s: %s\n", argv[optind], argv[optind + 1], err);
        return CLI_FAILED;
    }
    return CLI_OK;
}
